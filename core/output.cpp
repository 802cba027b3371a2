// Checked writes and atomic files (see output.hpp for what each kind of path does).
#include "core/output.hpp"

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/integrate.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <optional>

namespace crossdyn {

namespace fs = std::filesystem;

namespace {

constexpr std::size_t kBufferBytes = 1 << 16;
constexpr int kMaxSymlinks = 40;              // Linux's own limit (MAXSYMLINKS)
constexpr std::size_t kMaxNameInTemporary = 100;

std::string display_name(const std::string& path) { return path == "-" ? "standard output" : "'" + path + "'"; }

// "--output 'x.csv'" or "'x.csv'".
std::string who(const std::string& label, const std::string& path) {
  return label.empty() ? display_name(path) : label + " " + display_name(path);
}

std::string errno_text(int e) { return std::strerror(e); }

std::string parent_of(const std::string& path) {
  const auto slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  if (slash == 0) return "/";
  return path.substr(0, slash);
}

std::string base_of(const std::string& path) {
  const auto slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

// Follows symbolic links at `path` itself (not in its folders, which open() follows anyway) and
// returns the path of the file finally named. Throws InputError on a loop.
std::string follow_links(const std::string& path, const std::string& label) {
  std::string p = path;
  for (int i = 0; i <= kMaxSymlinks; ++i) {
    struct stat st {};
    if (::lstat(p.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return p;
    std::vector<char> buf(static_cast<std::size_t>(std::max<off_t>(st.st_size, 0)) + PATH_MAX + 1);
    const ssize_t n = ::readlink(p.c_str(), buf.data(), buf.size() - 1);
    if (n < 0) throw InputError("cannot write " + who(label, path) + ": " + errno_text(errno));
    const std::string link(buf.data(), static_cast<std::size_t>(n));
    p = !link.empty() && link[0] == '/' ? link : parent_of(p) + "/" + link;
  }
  throw InputError("cannot write " + who(label, path) +
                   ": too many levels of symbolic links (a symbolic link loop)");
}

bool is_digit(char c) { return c >= '0' && c <= '9'; }

// The descriptor a path names (/dev/stdout, /dev/stderr, /dev/fd/N, /proc/self/fd/N), or -1.
int descriptor_of(const std::string& path) {
  if (path == "/dev/stdout") return STDOUT_FILENO;
  if (path == "/dev/stderr") return STDERR_FILENO;
  for (const char* prefix : {"/dev/fd/", "/proc/self/fd/"}) {
    const std::string p(prefix);
    if (path.size() > p.size() && path.compare(0, p.size(), p) == 0 && path.size() - p.size() <= 6 &&
        std::all_of(path.begin() + static_cast<long>(p.size()), path.end(), is_digit))
      return std::stoi(path.substr(p.size()));
  }
  return -1;
}

mode_t current_umask() {
  const mode_t m = ::umask(0);
  ::umask(m);
  return m;
}

bool process_exists(long pid) {
  if (pid <= 0 || pid > INT_MAX) return false;
  return ::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM;
}

}  // namespace

// ---------------------------------------------------------------- errors
// (CSV numbers and rows: csv_format.cpp)

OutputError::OutputError(const std::string& target, int error_number)
    : std::runtime_error("cannot write " + target + ": " +
                         (error_number ? errno_text(error_number) : std::string("write failed"))),
      target_(target), errno_(error_number) {}

bool OutputError::broken_pipe() const { return errno_ == EPIPE; }

// ---------------------------------------------------------------- FdStreamBuf

FdStreamBuf::FdStreamBuf(int fd, std::string name)
    : fd_(fd), name_(std::move(name)), buffer_(new char[kBufferBytes]) {
  setp(buffer_.get(), buffer_.get() + kBufferBytes);
}

FdStreamBuf::~FdStreamBuf() { flush_buffer(); }

bool FdStreamBuf::write_all(const char* p, std::size_t n) {
  if (error_) return false;
  while (n > 0) {
    const ssize_t w = ::write(fd_, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      error_ = errno;
      return false;
    }
    if (w == 0) {
      error_ = EIO;
      return false;
    }
    p += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}

bool FdStreamBuf::flush_buffer() {
  const std::size_t n = static_cast<std::size_t>(pptr() - pbase());
  const bool ok = write_all(pbase(), n);
  setp(buffer_.get(), buffer_.get() + kBufferBytes);
  return ok;
}

FdStreamBuf::int_type FdStreamBuf::overflow(int_type ch) {
  if (!flush_buffer()) return traits_type::eof();
  if (!traits_type::eq_int_type(ch, traits_type::eof())) {
    *pptr() = traits_type::to_char_type(ch);
    pbump(1);
  }
  return traits_type::not_eof(ch);
}

std::streamsize FdStreamBuf::xsputn(const char* s, std::streamsize n) {
  if (error_) return 0;
  const auto room = epptr() - pptr();
  if (n <= room) {
    std::memcpy(pptr(), s, static_cast<std::size_t>(n));
    pbump(static_cast<int>(n));
    return n;
  }
  if (!flush_buffer()) return 0;
  if (n >= static_cast<std::streamsize>(kBufferBytes))
    return write_all(s, static_cast<std::size_t>(n)) ? n : 0;
  std::memcpy(pptr(), s, static_cast<std::size_t>(n));
  pbump(static_cast<int>(n));
  return n;
}

int FdStreamBuf::sync() { return flush_buffer() ? 0 : -1; }

void check_written(std::ostream& out) {
  out.flush();
  auto* buf = dynamic_cast<FdStreamBuf*>(out.rdbuf());
  if (buf && buf->error()) throw OutputError(buf->name(), buf->error());
  if (!out) throw OutputError(buf ? buf->name() : std::string("the output"), buf ? buf->error() : 0);
}

CheckedStdout::CheckedStdout()
    : buf_(STDOUT_FILENO, "standard output"), previous_(std::cout.rdbuf(&buf_)) {
  std::cout.clear();
}

CheckedStdout::~CheckedStdout() {
  std::cout.flush();
  std::cout.rdbuf(previous_);
  std::cout.clear();
}

// ---------------------------------------------------------------- temporaries

std::string temporary_prefix(const std::string& name, long pid) {
  return "." + name.substr(0, kMaxNameInTemporary) + ".crossdyn-" + std::to_string(pid) + "-";
}

int remove_stale_temporaries(const std::string& folder, const std::string& name) {
  const std::string head = "." + name.substr(0, kMaxNameInTemporary) + ".crossdyn-";
  DIR* d = ::opendir(folder.c_str());
  if (!d) return 0;
  int removed = 0;
  while (const dirent* e = ::readdir(d)) {
    const std::string entry = e->d_name;
    // .<name>.crossdyn-<pid>-XXXXXX.tmp
    if (entry.size() < head.size() + 13 || entry.compare(0, head.size(), head) != 0 ||
        entry.compare(entry.size() - 4, 4, ".tmp") != 0)
      continue;
    const std::string rest = entry.substr(head.size(), entry.size() - head.size() - 4);
    const auto dash = rest.find('-');
    if (dash == std::string::npos || dash == 0 || rest.size() - dash - 1 != 6) continue;
    const std::string digits = rest.substr(0, dash);
    if (digits.size() > 9 || !std::all_of(digits.begin(), digits.end(), is_digit)) continue;
    const long pid = std::stol(digits);
    if (process_exists(pid)) continue;
    const std::string path = folder + "/" + entry;
    struct stat st {};
    if (::lstat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode) || st.st_uid != ::geteuid())
      continue;
    if (::unlink(path.c_str()) == 0) ++removed;
  }
  ::closedir(d);
  return removed;
}

// ---------------------------------------------------------------- AtomicFile

AtomicFile::AtomicFile(std::string path, std::string label)
    : path_(std::move(path)), label_(std::move(label)) {
  const std::string me = who(label_, path_);
  if (path_.empty()) throw InputError((label_.empty() ? "output" : label_) + ": empty file name");
  if (path_ == "-") {
    fd_ = STDOUT_FILENO;
    owns_fd_ = false;
  } else {
    struct stat st {};
    bool exists = ::stat(path_.c_str(), &st) == 0;
    if (!exists && errno == ELOOP)
      throw InputError("cannot write " + me +
                       ": too many levels of symbolic links (a symbolic link loop)");
    if (!exists && errno != ENOENT)
      throw InputError("cannot write " + me + ": " + errno_text(errno));
    // An existing file: its real path (links resolved); none yet: where a dangling link points.
    if (exists) {
      char* real = ::realpath(path_.c_str(), nullptr);
      target_ = real ? real : path_;
      std::free(real);
    } else {
      target_ = follow_links(path_, label_);
      exists = ::stat(target_.c_str(), &st) == 0;
    }
    const int descriptor = descriptor_of(path_);
    if (exists && S_ISDIR(st.st_mode))
      throw InputError("cannot write " + me + ": it is a directory (name a file in it)");
    if (exists && S_ISSOCK(st.st_mode))
      throw InputError("cannot write " + me + ": it is a socket");
    if (exists && S_ISBLK(st.st_mode))
      throw InputError("cannot write " + me + ": it is a block device (crossdyn writes its "
                       "outputs only to regular files, character devices, FIFOs and stdout)");
    if (descriptor >= 0) {
      // /dev/stdout, /dev/fd/N: the descriptor itself (its offset and append mode are kept).
      fd_ = ::fcntl(descriptor, F_DUPFD_CLOEXEC, 3);
      if (fd_ < 0) throw InputError("cannot write " + me + ": " + errno_text(errno));
      owns_fd_ = true;
    } else if (exists && (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode))) {
      // Written in place. A FIFO's open waits for a reader: poll, so that Ctrl-C ends the wait.
      const bool fifo = S_ISFIFO(st.st_mode);
      for (;;) {
        fd_ = ::open(target_.c_str(), O_WRONLY | O_CLOEXEC | O_NOCTTY | (fifo ? O_NONBLOCK : 0));
        if (fd_ >= 0) break;
        if (errno == EINTR) continue;
        if (fifo && errno == ENXIO) {  // no reader yet
          if (interrupt_requested())
            throw RunFailure("output", 0.0, "", "interrupted");
          ::poll(nullptr, 0, 50);
          continue;
        }
        throw InputError("cannot write " + me + ": " + errno_text(errno));
      }
      if (fifo) ::fcntl(fd_, F_SETFL, ::fcntl(fd_, F_GETFL) & ~O_NONBLOCK);
      owns_fd_ = true;
    } else {
      // A regular file, or none yet: a temporary in the same folder, renamed over it on commit.
      const std::string folder = parent_of(target_);
      struct stat fst {};
      if (::stat(folder.c_str(), &fst) != 0)
        throw InputError("cannot write " + me + ": folder '" + folder + "': " + errno_text(errno));
      if (!S_ISDIR(fst.st_mode))
        throw InputError("cannot write " + me + ": '" + folder + "' is not a folder");
      // As for files, the mode bits decide for every user (root may create files anywhere): a
      // folder nobody may write into is one the user protected, and crossdyn creates nothing in it.
      if ((fst.st_mode & 0222) == 0) {
        char mode[16];
        std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(fst.st_mode & 07777));
        throw InputError("cannot write " + me + ": folder '" + folder + "' is read-only (mode " +
                         mode + "); crossdyn creates nothing in read-only folders");
      }
      if (exists) {
        // The mode bits are checked explicitly (root may write anything): a file nobody may write
        // is one the user protected, and crossdyn does not replace it.
        if ((st.st_mode & 0222) == 0) {
          char mode[16];
          std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
          throw InputError("cannot write " + me + ": the file is read-only (mode " + mode +
                           "); crossdyn does not replace read-only files");
        }
        if (::faccessat(AT_FDCWD, target_.c_str(), W_OK, AT_EACCESS) != 0)
          throw InputError("cannot write " + me + ": " + errno_text(errno));
      }
      remove_stale_temporaries(folder, base_of(target_));
      std::string tmpl = folder + "/" + temporary_prefix(base_of(target_), ::getpid()) + "XXXXXX.tmp";
      std::vector<char> name(tmpl.begin(), tmpl.end());
      name.push_back('\0');
      // mkostemps: O_CREAT | O_EXCL (never through an existing name or link), mode 0600.
      fd_ = ::mkostemps(name.data(), 4, O_CLOEXEC);
      if (fd_ < 0)
        throw InputError("cannot write " + me + ": cannot create a temporary file in '" + folder +
                         "': " + errno_text(errno));
      tmp_ = name.data();
      owns_fd_ = true;
      // A forced exit (a second Ctrl-C, or a command that does not stop in time) removes it too.
      cancel_handle_ = cancel::register_temporary(tmp_);
      // The mode of the file being replaced, or what a new file would get; and its owner (root).
      if (exists) {
        ::fchmod(fd_, st.st_mode & 07777);
        if (::geteuid() == 0 && ::fchown(fd_, st.st_uid, st.st_gid) != 0) {
          // keeping the owner is best effort
        }
      } else {
        ::fchmod(fd_, 0666 & ~current_umask());
      }
    }
  }
  buf_ = std::make_unique<FdStreamBuf>(fd_, display_name(path_));
  out_ = std::make_unique<std::ostream>(buf_.get());
}

AtomicFile::~AtomicFile() {
  if (cancel_handle_ >= 0) cancel::unregister_temporary(cancel_handle_);
  if (done_) return;
  if (buf_) {
    out_.reset();
    buf_.reset();
  }
  if (owns_fd_ && fd_ >= 0) ::close(fd_);
  if (!tmp_.empty()) ::unlink(tmp_.c_str());
}

std::ostream& AtomicFile::stream() { return *out_; }

void AtomicFile::check() {
  if (buf_->error()) fail_commit(buf_->error());
}

void AtomicFile::fail_commit(int error_number) {
  out_.reset();
  buf_.reset();
  if (owns_fd_ && fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (!tmp_.empty()) ::unlink(tmp_.c_str());
  done_ = true;
  throw OutputError(display_name(path_), error_number);
}

void AtomicFile::prepare() {
  if (done_ || prepared_) return;
  out_->flush();
  if (buf_->error()) fail_commit(buf_->error());
  if (!tmp_.empty() && ::fsync(fd_) != 0) fail_commit(errno);
  out_.reset();
  buf_.reset();
  if (owns_fd_) {
    const int rc = ::close(fd_);
    fd_ = -1;
    if (rc != 0 && errno != EINTR) fail_commit(errno);
  }
  prepared_ = true;
}

void AtomicFile::publish() {
  if (done_) return;
  prepare();
  if (!tmp_.empty() && ::rename(tmp_.c_str(), target_.c_str()) != 0) fail_commit(errno);
  done_ = true;
}

void AtomicFile::commit() {
  prepare();
  publish();
}

void commit_together(const std::vector<AtomicFile*>& files, const std::vector<StagedOutput*>& staged) {
  if (cancel::interrupted()) throw RunFailure("output", 0.0, "", "interrupted");
  for (AtomicFile* f : files)
    if (f) f->prepare();
  for (StagedOutput* s : staged)
    if (s) s->prepare();
  cancel::test_interrupt_point("before-commit");
  if (cancel::interrupted()) throw RunFailure("output", 0.0, "", "interrupted");
  const cancel::HoldForcedExit hold;
  bool first = true;
  auto after_first = [&first] {
    if (first) cancel::test_interrupt_point("during-commit");
    first = false;
  };
  for (StagedOutput* s : staged)
    if (s) {
      s->publish();
      after_first();
    }
  for (AtomicFile* f : files)
    if (f) {
      f->publish();
      after_first();
    }
}

void write_file_atomic(const std::string& path, const std::string& content, const std::string& label) {
  AtomicFile f(path, label);
  f.stream() << content;
  f.commit();
}

// ---------------------------------------------------------------- outputs are not inputs

namespace {

struct Identity {
  dev_t dev;
  ino_t ino;
  bool regular_or_dir;
  bool operator==(const Identity& o) const { return dev == o.dev && ino == o.ino; }
};

std::optional<Identity> identity(const std::string& path) {
  struct stat st {};
  const int rc = path == "-" ? ::fstat(STDOUT_FILENO, &st) : ::stat(path.c_str(), &st);
  if (rc != 0) return std::nullopt;
  return Identity{st.st_dev, st.st_ino, S_ISREG(st.st_mode) || S_ISDIR(st.st_mode)};
}

std::string describe(const NamedPath& p) {
  return p.path == "-" ? p.role : p.role + " '" + p.path + "'";
}

// Absolute, with symbolic links resolved as far as the path exists.
std::string resolved(const std::string& path) {
  std::error_code ec;
  fs::path a = fs::absolute(path, ec).lexically_normal();
  // A dangling symbolic link names the file it would create: follow it (a loop: give up).
  for (int hops = 0; hops < 40 && fs::is_symlink(fs::symlink_status(a, ec)); ++hops) {
    const fs::path target = fs::read_symlink(a, ec);
    if (ec) break;
    a = (target.is_absolute() ? target : a.parent_path() / target).lexically_normal();
  }
  ec.clear();
  fs::path p = fs::weakly_canonical(a, ec);
  return ec ? a.string() : p.string();
}

}  // namespace

void check_outputs_are_not_inputs(const std::vector<NamedPath>& outputs,
                                  const std::vector<NamedPath>& inputs,
                                  const std::vector<NamedPath>& folders) {
  auto same_as_input = [&inputs](const NamedPath& out, const Identity& id) {
    for (const NamedPath& in : inputs)
      if (const auto iid = identity(in.path); iid && *iid == id)
        throw InputError(describe(out) + " is the same file as " + describe(in) +
                         ": an output must never overwrite an input (nothing was written)");
  };
  for (std::size_t i = 0; i < outputs.size(); ++i) {
    const NamedPath& out = outputs[i];
    const auto id = identity(out.path);
    // Only regular files can lose data by being replaced; /dev/null may be read and written.
    if (id && id->regular_or_dir) same_as_input(out, *id);
    for (std::size_t j = 0; j < i; ++j) {
      const NamedPath& other = outputs[j];
      const auto oid = identity(other.path);
      const bool same = id && oid ? (*id == *oid && id->regular_or_dir)
                                  : !id && !oid && out.path != "-" && other.path != "-" &&
                                        resolved(out.path) == resolved(other.path);
      if (same)
        throw InputError(describe(out) + " and " + describe(other) +
                         " are the same file: give each output its own file");
    }
  }
  // An output file in a folder the command fills (--csv DIR/x.csv with --report DIR): the
  // report replaces its folder as a whole.
  for (const NamedPath& folder : folders) {
    const fs::path dir = resolved(folder.path);
    for (const NamedPath& out : outputs) {
      if (out.path == "-") continue;
      const fs::path o = resolved(out.path);
      for (fs::path p = o; !p.empty(); p = p.parent_path()) {
        if (p == dir)
          throw InputError(describe(out) + (p == o ? " is " : " is inside ") + describe(folder) +
                           ": the report replaces its folder as a whole; write it elsewhere");
        if (p == p.root_path()) break;
      }
    }
  }
  for (const NamedPath& folder : folders) {
    const auto fid = identity(folder.path);
    if (!fid) continue;  // created later: it holds nothing yet
    if (fid->regular_or_dir) same_as_input(folder, *fid);
    // Walk up from each input: is the folder one of its ancestors?
    for (const NamedPath& in : inputs) {
      std::error_code ec;
      fs::path p = fs::canonical(in.path, ec);
      if (ec) continue;
      for (p = p.parent_path(); !p.empty(); p = p.parent_path()) {
        if (const auto pid = identity(p.string()); pid && *pid == *fid)
          throw InputError(describe(folder) + " holds " + describe(in) +
                           ": the report folder is rewritten and must not contain an input; "
                           "choose another folder");
        if (p == p.root_path()) break;
      }
    }
  }
}

}  // namespace crossdyn
