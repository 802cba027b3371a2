#include "core/output.hpp"

#include "core/errors.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <unistd.h>

namespace crossdyn {

std::string format_value(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

void write_csv_header(std::ostream& out, const std::vector<std::string>& columns) {
  for (std::size_t i = 0; i < columns.size(); ++i) out << (i ? "," : "") << columns[i];
  out << '\n';
}

void write_csv_row(std::ostream& out, const double* row, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) out << (i ? "," : "") << format_value(row[i]);
  out << '\n';
}

struct AtomicFile::Impl {
  std::ofstream out;
};

AtomicFile::AtomicFile(std::string path)
    : path_(std::move(path)), tmp_(path_ + ".tmp." + std::to_string(::getpid())), impl_(new Impl) {
  impl_->out.open(tmp_, std::ios::binary | std::ios::trunc);
  if (!impl_->out) {
    const std::string why = std::strerror(errno);
    delete impl_;
    throw InputError("cannot write '" + path_ + "': " + why);
  }
}

AtomicFile::~AtomicFile() {
  if (impl_) {
    impl_->out.close();
    std::remove(tmp_.c_str());
    delete impl_;
  }
}

std::ostream& AtomicFile::stream() { return impl_->out; }

void AtomicFile::commit() {
  impl_->out.flush();
  const bool ok = static_cast<bool>(impl_->out);
  impl_->out.close();
  if (!ok || std::rename(tmp_.c_str(), path_.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    std::remove(tmp_.c_str());
    delete impl_;
    impl_ = nullptr;
    throw InputError("cannot write '" + path_ + "': " + why);
  }
  delete impl_;
  impl_ = nullptr;
}

void write_file_atomic(const std::string& path, const std::string& content) {
  AtomicFile f(path);
  f.stream() << content;
  f.commit();
}

}  // namespace crossdyn
