// Output helpers: number formatting and files that appear only when complete.
#pragma once

#include <ostream>
#include <string>
#include <vector>

namespace crossdyn {

// 17 significant digits, so a value read back is the same double ("%.17g").
std::string format_value(double v);

void write_csv_header(std::ostream& out, const std::vector<std::string>& columns);
void write_csv_row(std::ostream& out, const double* row, std::size_t n);

// Writes to a temporary file in the target's folder; commit() renames it into place, so readers
// see the previous file or the complete new one, never a half-written one. Destroying an
// uncommitted AtomicFile removes the temporary. Throws InputError when the folder is not writable.
class AtomicFile {
 public:
  explicit AtomicFile(std::string path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  std::ostream& stream();
  void commit();
  const std::string& path() const { return path_; }

 private:
  std::string path_, tmp_;
  struct Impl;
  Impl* impl_;
};

// Writes `content` to `path` atomically (AtomicFile in one call).
void write_file_atomic(const std::string& path, const std::string& content);

}  // namespace crossdyn
