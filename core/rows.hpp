// Where a run's output rows live: in memory while the program-wide row budget allows, otherwise
// in an anonymous temporary file. A long `compare` or `verify` therefore holds at most
// row_memory_budget() bytes of rows in memory (default 512 MiB, about 0.6 million rows of a
// 100-column run) however many rows its runs write; the rest goes to disk ($TMPDIR, else /tmp).
//
// The temporary file is created unlinked (O_TMPFILE, or mkstemp and unlink at once), so nothing
// is left behind however the program ends, even killed. Rows are written once (RowStore) and
// then read back in order any number of times (RowReader), which is all `compare` needs.
#pragma once

#include <cstddef>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace crossdyn {

// Writing or reading the temporary file failed (disk full, I/O error). The message names the
// folder and the reason.
class RowStorageError : public std::runtime_error {
 public:
  explicit RowStorageError(const std::string& message) : std::runtime_error(message) {}
};

// Bytes of rows all runs of the program may hold in memory together.
inline constexpr std::size_t kDefaultRowMemoryBudget = std::size_t{512} << 20;
std::size_t row_memory_budget();
void set_row_memory_budget(std::size_t bytes);  // takes effect for later reservations
std::size_t row_memory_in_use();                 // bytes reserved now

// Rows moved to a temporary file (read-only once the writer is finished).
class RowFile {
 public:
  RowFile(const RowFile&) = delete;
  RowFile& operator=(const RowFile&) = delete;
  ~RowFile();
  std::size_t rows() const { return rows_; }
  std::size_t columns() const { return columns_; }
  // Reads rows [first, first + count) into out (count * columns() values).
  void read(std::size_t first, std::size_t count, double* out) const;

 private:
  friend class RowStore;
  RowFile(int fd, std::size_t columns, std::string dir)
      : fd_(fd), columns_(columns), dir_(std::move(dir)) {}
  int fd_;
  std::size_t columns_;
  std::size_t rows_ = 0;
  std::string dir_;
};

// Appends rows: into memory within the budget, to a RowFile beyond it.
class RowStore {
 public:
  explicit RowStore(std::size_t columns);
  ~RowStore();
  RowStore(const RowStore&) = delete;
  RowStore& operator=(const RowStore&) = delete;
  void append(const double* row);  // columns() values; throws RowStorageError
  std::size_t rows() const { return rows_; }
  std::size_t columns() const { return columns_; }
  bool spilled() const { return file_ != nullptr; }

  // The finished rows: exactly one of `data` (row-major, in memory) and `file` holds them;
  // `reservation` keeps their share of the budget until the last copy is destroyed.
  struct Rows {
    std::vector<double> data;
    std::shared_ptr<const RowFile> file;
    std::shared_ptr<const void> reservation;
  };
  Rows finish();  // throws RowStorageError; the writer is empty afterwards

 private:
  void spill();
  void flush();
  std::size_t columns_;
  std::size_t rows_ = 0;
  std::vector<double> data_;
  std::size_t reserved_ = 0;  // bytes of the budget held for data_
  std::shared_ptr<RowFile> file_;
  std::vector<double> buffer_;  // rows waiting to be written to file_
};

// Reads rows in order from memory or a RowFile.
class RowReader {
 public:
  RowReader(const std::vector<double>* data, std::shared_ptr<const RowFile> file,
            std::size_t columns);
  std::size_t rows() const { return rows_; }
  // The next row (columns values), or nullptr after the last. Valid until the next call.
  const double* next();
  void rewind() { next_ = 0; buffer_first_ = buffer_count_ = 0; }

 private:
  const std::vector<double>* data_;
  std::shared_ptr<const RowFile> file_;
  std::size_t columns_, rows_;
  std::size_t next_ = 0;
  std::vector<double> buffer_;
  std::size_t buffer_first_ = 0, buffer_count_ = 0;
};

}  // namespace crossdyn
