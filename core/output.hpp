// Output helpers: number formatting, checked writes, and files that appear only when complete.
//
// What an output path may be (docs/outputs.md "Outputs: special files, symbolic links,
// read-only files"):
//   does not exist     created (mode 0666 & ~umask) when complete; its folder must exist
//   regular file       replaced atomically when complete (mode and, for root, owner kept); a
//                      read-only file (no write bit in its mode, whoever runs crossdyn) is refused
//   symbolic link      followed: the file it points to is written (or replaced) as above, the link
//                      stays; a dangling link creates its target; a loop is refused
//   "-"                standard output
//   character device   written directly (/dev/null, /dev/stdout, a terminal): never replaced
//   FIFO               written directly, after waiting (Ctrl-C stops the wait) for a reader
//   directory, socket, block device: refused before anything runs
// Refusals are InputError (exit 2), raised when the AtomicFile is constructed, i.e. before the
// work starts. A write that fails later (disk full, I/O error, a reader that went away) is an
// OutputError (exit 3).
//
// The temporary file is created exclusively (O_CREAT | O_EXCL, so never through a planted link)
// in the target's folder, named `.<name>.crossdyn-<pid>-XXXXXX.tmp`, and removed on every failure
// path. A run killed outright (SIGKILL, power loss) leaves it behind: the next AtomicFile for the
// same name in that folder removes such temporaries of the current user whose process <pid> no
// longer exists.
#pragma once

#include <cstddef>
#include <memory>
#include <ostream>
#include <stdexcept>
#include <streambuf>
#include <string>
#include <vector>

namespace crossdyn {

// A write that failed: "cannot write '<target>': <reason>" (exit 3). broken_pipe() when the
// reader of a pipe went away (EPIPE).
class OutputError : public std::runtime_error {
 public:
  OutputError(const std::string& target, int error_number);
  int error_number() const { return errno_; }
  bool broken_pipe() const;
  const std::string& target() const { return target_; }  // "standard output" or "'<path>'"

 private:
  std::string target_;
  int errno_;
};

// CSV numbers: the shortest text that reads back as the same double (std::to_chars without a
// precision: the fewest characters, scientific notation with at most 17 significant digits or
// fixed notation when that is no longer; "0.05" rather than %.17g's "0.050000000000000003", "-0",
// "1e-300", "inf", "nan"). strtod, Python's float() and numpy read every value back bit for bit.
// The digits come from fmt's Dragonbox and the text is byte for byte std::to_chars's (csv_format.cpp).
// The longest value is 24 characters ("-2.2250738585072014e-308"); the formatter writes with
// fixed-size stores that may reach past the value's end, so it needs 48 bytes of room.
inline constexpr std::size_t kMaxValueChars = 48;
// Writes v at `first` (room for kMaxValueChars: bytes past the returned end may be overwritten)
// and returns the end; no terminating NUL.
char* format_value_to(char* first, double v);
std::string format_value(double v);

void write_csv_header(std::ostream& out, const std::vector<std::string>& columns);
void write_csv_row(std::ostream& out, const double* row, std::size_t n);

// A stream buffer on a file descriptor that remembers the first failed write (errno). Once a
// write has failed, every later write fails too, so a file never gets a hole in the middle.
class FdStreamBuf : public std::streambuf {
 public:
  FdStreamBuf(int fd, std::string name);  // name: for messages ("standard output", "'out.csv'")
  ~FdStreamBuf() override;
  int error() const { return error_; }    // 0 while every write succeeded
  const std::string& name() const { return name_; }
  int fd() const { return fd_; }

 protected:
  int_type overflow(int_type ch) override;
  std::streamsize xsputn(const char* s, std::streamsize n) override;
  int sync() override;

 private:
  bool flush_buffer();
  bool write_all(const char* p, std::size_t n);
  int fd_;
  std::string name_;
  int error_ = 0;
  // Not zeroed (a std::vector<char> of 64 KiB was: 2 x 65 k instructions and the page faults of
  // a `crossdyn run`'s start-up, for the checked stdout and the output file).
  std::unique_ptr<char[]> buffer_;
};

// Throws OutputError when a write to `out` has failed (after flushing it). The message names the
// target when `out` writes through an FdStreamBuf.
void check_written(std::ostream& out);

// For the lifetime of this object std::cout writes through a checked FdStreamBuf on descriptor 1
// (so a full disk or a closed pipe is seen); check_written(std::cout) then reports it.
class CheckedStdout {
 public:
  CheckedStdout();
  ~CheckedStdout();
  CheckedStdout(const CheckedStdout&) = delete;
  CheckedStdout& operator=(const CheckedStdout&) = delete;

 private:
  FdStreamBuf buf_;
  std::streambuf* previous_;
};

// Writes to a temporary file in the target's folder; commit() renames it into place, so readers
// see the previous file or the complete new one, never a half-written one. Destroying an
// uncommitted AtomicFile removes the temporary. Special files are written directly (see the top
// of this file). `label` names the option in messages ("--output"); it may be empty.
class AtomicFile {
 public:
  explicit AtomicFile(std::string path, std::string label = "");
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  std::ostream& stream();
  void check();   // OutputError if a write has failed so far
  void commit();  // OutputError if a write, the flush, fsync, close or rename fails
  // commit() in two steps, for commit_together: prepare() flushes, syncs and closes (every
  // failure that can happen on the way); publish() renames the temporary into place.
  void prepare();
  void publish();
  const std::string& path() const { return path_; }
  const std::string& temporary() const { return tmp_; }  // "" when written directly
  bool direct() const { return tmp_.empty(); }

 private:
  void fail_commit(int error_number);
  std::string path_, label_, target_, tmp_;
  int fd_ = -1;
  bool owns_fd_ = false;
  bool done_ = false;
  bool prepared_ = false;
  int cancel_handle_ = -1;  // the temporary, registered for the forced exit (core/cancel.hpp)
  std::unique_ptr<FdStreamBuf> buf_;
  std::unique_ptr<std::ostream> out_;
};

// Something committed with the files of commit_together (a report folder swapped in).
class StagedOutput {
 public:
  virtual ~StagedOutput() = default;
  virtual void prepare() {}  // may throw: nothing is replaced yet
  virtual void publish() = 0;
};

// All outputs of one command, committed together at its end, so that a failure or Ctrl-C leaves
// every old output or every new one, never a mix:
//   1. Ctrl-C already seen (cancel::interrupted()): RunFailure "interrupted" (exit 130), nothing
//      is replaced; the temporaries are removed by the AtomicFiles' destructors.
//   2. every file is prepared (flushed, synced, closed; OutputError on failure, nothing replaced)
//      and every staged output (a report folder) prepared;
//   3. with the forced exit of Ctrl-C/SIGTERM held off (cancel::HoldForcedExit), the staged
//      outputs and then the files are published (renames within their folders).
// Null pointers are skipped. Special files (stdout, FIFOs, devices) are written directly and
// cannot be held back: they are flushed in step 2.
void commit_together(const std::vector<AtomicFile*>& files,
                     const std::vector<StagedOutput*>& staged = {});

// Writes `content` to `path` atomically (AtomicFile in one call).
void write_file_atomic(const std::string& path, const std::string& content,
                       const std::string& label = "");

// The temporary-file name an AtomicFile uses for `name`, without its random part:
// ".<name>.crossdyn-<pid>-" (name shortened to 100 bytes). For tests and documentation.
std::string temporary_prefix(const std::string& name, long pid);

// Removes `folder`'s temporaries of `name` (see temporary_prefix) left by processes that no
// longer exist and that belong to the current user; returns how many were removed.
int remove_stale_temporaries(const std::string& folder, const std::string& name);

// ---- An output must never be an input ----
// A file the command reads or writes: its role in messages ("the scene file", "--json") and path.
struct NamedPath {
  std::string role;
  std::string path;  // "-" : standard output (descriptor 1)
};
// Throws InputError (exit 2) naming both when an output that exists is the same file (device and
// inode, symbolic links followed) as an input, when two outputs are the same file, or when a
// folder the command fills (`folders`: --report DIR) holds an input anywhere inside it (or is
// one). Outputs that do not exist yet cannot be inputs; they are compared by their absolute path
// with symbolic links resolved.
void check_outputs_are_not_inputs(const std::vector<NamedPath>& outputs,
                                  const std::vector<NamedPath>& inputs,
                                  const std::vector<NamedPath>& folders = {});

}  // namespace crossdyn
