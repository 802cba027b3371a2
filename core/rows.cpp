// Row storage in memory or an anonymous temporary file (see rows.hpp).
#include "core/rows.hpp"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <unistd.h>

namespace crossdyn {

namespace {

std::atomic<std::size_t> g_budget{kDefaultRowMemoryBudget};
std::atomic<std::size_t> g_in_use{0};

bool try_reserve(std::size_t bytes) {
  std::size_t used = g_in_use.load();
  do {
    if (bytes > g_budget.load() || used > g_budget.load() - bytes) return false;
  } while (!g_in_use.compare_exchange_weak(used, used + bytes));
  return true;
}

void release(std::size_t bytes) { g_in_use.fetch_sub(bytes); }

// Rows per block when writing to or reading from the file: about 1 MiB.
std::size_t block_rows(std::size_t columns) {
  return std::max<std::size_t>(1, (std::size_t{1} << 20) / (sizeof(double) * std::max<std::size_t>(1, columns)));
}

std::string temp_dir() {
  const char* t = std::getenv("TMPDIR");
  return t && *t ? t : "/tmp";
}

std::string why() { return std::strerror(errno); }

}  // namespace

std::size_t row_memory_budget() { return g_budget.load(); }
void set_row_memory_budget(std::size_t bytes) { g_budget.store(bytes); }
std::size_t row_memory_in_use() { return g_in_use.load(); }

RowFile::~RowFile() { ::close(fd_); }

void RowFile::read(std::size_t first, std::size_t count, double* out) const {
  const std::size_t bytes = count * columns_ * sizeof(double);
  auto offset = static_cast<off_t>(first * columns_ * sizeof(double));
  auto* p = reinterpret_cast<char*>(out);
  std::size_t done = 0;
  while (done < bytes) {
    const ssize_t n = ::pread(fd_, p + done, bytes - done, offset + static_cast<off_t>(done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw RowStorageError("cannot read rows back from the temporary file in '" + dir_ + "': " +
                            (n < 0 ? why() : std::string("file shorter than expected")));
    done += static_cast<std::size_t>(n);
  }
}

RowStore::RowStore(std::size_t columns) : columns_(columns) {}

RowStore::~RowStore() { release(reserved_); }

void RowStore::append(const double* row) {
  if (!file_) {
    const std::size_t need = (data_.size() + columns_) * sizeof(double);
    if (need > reserved_) {
      // Grow the reservation geometrically (at least 64 KiB), or by what is needed when the
      // budget is nearly used up; the vector's capacity never exceeds the reservation.
      const std::size_t want = std::max({need, 2 * reserved_, std::size_t{64} << 10});
      std::size_t got = 0;
      if (try_reserve(want - reserved_)) got = want;
      else if (try_reserve(need - reserved_)) got = need;
      if (got > 0) {
        reserved_ = got;
        data_.reserve(reserved_ / sizeof(double));
      } else {
        spill();
      }
    }
  }
  if (file_) {
    buffer_.insert(buffer_.end(), row, row + columns_);
    if (buffer_.size() >= block_rows(columns_) * columns_) flush();
  } else {
    data_.insert(data_.end(), row, row + columns_);
  }
  ++rows_;
}

void RowStore::spill() {
  const std::string dir = temp_dir();
  int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (fd < 0) {  // a file system without O_TMPFILE: a named file, unlinked at once
    std::string name = dir + "/crossdyn-rows-XXXXXX";
    fd = ::mkostemp(name.data(), O_CLOEXEC);
    if (fd >= 0) ::unlink(name.c_str());
  }
  if (fd < 0)
    throw RowStorageError("the rows do not fit the memory budget (" +
                          std::to_string(row_memory_budget() >> 20) +
                          " MiB) and no temporary file can be created in '" + dir + "': " + why());
  file_.reset(new RowFile(fd, columns_, dir));
  buffer_.reserve(block_rows(columns_) * columns_);
  buffer_.swap(data_);  // the rows so far are the first to be written
  data_.clear();
  data_.shrink_to_fit();
  release(reserved_);
  reserved_ = 0;
  flush();
}

void RowStore::flush() {
  const auto* p = reinterpret_cast<const char*>(buffer_.data());
  const std::size_t bytes = buffer_.size() * sizeof(double);
  std::size_t done = 0;
  while (done < bytes) {
    const ssize_t n = ::write(file_->fd_, p + done, bytes - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw RowStorageError("cannot write rows to a temporary file in '" + file_->dir_ +
                            "': " + (n < 0 ? why() : std::string("nothing written")));
    done += static_cast<std::size_t>(n);
  }
  file_->rows_ += buffer_.size() / std::max<std::size_t>(1, columns_);
  buffer_.clear();
  if (buffer_.capacity() > block_rows(columns_) * columns_ * 2) {
    buffer_.shrink_to_fit();
    buffer_.reserve(block_rows(columns_) * columns_);
  }
}

RowStore::Rows RowStore::finish() {
  Rows r;
  if (file_) {
    flush();
    r.file = std::move(file_);
  } else {
    r.data = std::move(data_);
    const std::size_t bytes = reserved_;
    reserved_ = 0;
    if (bytes > 0) r.reservation = std::shared_ptr<const void>(nullptr, [bytes](const void*) { release(bytes); });
  }
  data_.clear();
  buffer_.clear();
  rows_ = 0;
  return r;
}

RowReader::RowReader(const std::vector<double>* data, std::shared_ptr<const RowFile> file,
                     std::size_t columns)
    : data_(data), file_(std::move(file)), columns_(columns),
      rows_(file_ ? file_->rows() : (columns == 0 || !data ? 0 : data->size() / columns)) {}

const double* RowReader::next() {
  if (next_ >= rows_) return nullptr;
  if (!file_) return data_->data() + columns_ * next_++;
  if (next_ >= buffer_first_ + buffer_count_) {
    buffer_first_ = next_;
    buffer_count_ = std::min(block_rows(columns_), rows_ - next_);
    buffer_.resize(buffer_count_ * columns_);
    file_->read(buffer_first_, buffer_count_, buffer_.data());
  }
  return buffer_.data() + columns_ * (next_++ - buffer_first_);
}

}  // namespace crossdyn
