// Reading an input file without blocking on a special file (see input_file.hpp).
#include "core/input_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace crossdyn {

namespace {

// Why open() failed, as a sentence about the path.
std::string open_failure(const std::string& path, int e) {
  switch (e) {
    case ENOENT: {
      struct stat lst {};
      return ::lstat(path.c_str(), &lst) == 0 ? "it is a symbolic link to a file that does not exist"
                                             : "no such file";
    }
    case ELOOP: return "too many levels of symbolic links (a symbolic link loop)";
    case EACCES: return "permission denied";
    case ENOTDIR: return "a part of the path is not a folder";
    case ENXIO: {  // a socket (or a device with nothing behind it)
      struct stat st {};
      return ::stat(path.c_str(), &st) == 0 && S_ISSOCK(st.st_mode)
                 ? "it is a socket, not a regular file"
                 : "it is a device with nothing behind it, not a regular file";
    }
    case ENAMETOOLONG: return "the name is too long";
    case EMFILE: case ENFILE: return "too many files are open";
    default: return std::strerror(e);
  }
}

// Why a file of this type is not read ("" when it is).
std::string type_problem(mode_t mode, Pipes pipes, const char* noun) {
  if (S_ISREG(mode)) return "";
  if (S_ISDIR(mode)) return std::string("it is a directory, not a ") + noun;
  if (S_ISFIFO(mode))
    return pipes == Pipes::Allow ? "" : "it is a named pipe (FIFO), not a regular file";
  if (S_ISSOCK(mode)) return "it is a socket, not a regular file";
  if (S_ISCHR(mode)) return "it is a character device (such as /dev/zero or a terminal), not a regular file";
  if (S_ISBLK(mode)) return "it is a block device, not a regular file";
  return "it is not a regular file";
}

struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

// Opens `path` without blocking and checks its type on the descriptor.
std::string open_checked(const std::string& path, Pipes pipes, const char* noun, Fd& f, struct stat& st) {
  if (path.empty()) return "the file name is empty";
  do f.fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  while (f.fd < 0 && errno == EINTR);
  if (f.fd < 0) return open_failure(path, errno);
  if (::fstat(f.fd, &st) != 0) return std::strerror(errno);
  return type_problem(st.st_mode, pipes, noun);
}

}  // namespace

InputFile read_input_file(const std::string& path, std::size_t max_bytes, Pipes pipes, const char* noun) {
  InputFile out;
  Fd f;
  struct stat st {};
  out.problem = open_checked(path, pipes, noun, f, st);
  if (!out.problem.empty()) return out;
  out.pipe = S_ISFIFO(st.st_mode);
  if (out.pipe) {  // read a pipe in blocking mode: its writer may not have written yet
    const int flags = ::fcntl(f.fd, F_GETFL);
    if (flags < 0 || ::fcntl(f.fd, F_SETFL, flags & ~O_NONBLOCK) != 0) {
      out.problem = std::strerror(errno);
      return out;
    }
  }
  const std::size_t limit = max_bytes + 1;  // one byte more tells "too large"
  if (!out.pipe && st.st_size > 0)
    out.text.reserve(static_cast<std::size_t>(st.st_size) < limit ? static_cast<std::size_t>(st.st_size) : limit);
  char buf[65536];
  while (out.text.size() < limit) {
    const std::size_t want = std::min(sizeof buf, limit - out.text.size());
    const ssize_t n = ::read(f.fd, buf, want);
    if (n < 0) {
      if (errno == EINTR) continue;
      out.problem = errno == EISDIR ? std::string("it is a directory, not a ") + noun : std::strerror(errno);
      out.text.clear();
      return out;
    }
    if (n == 0) break;
    out.text.append(buf, static_cast<std::size_t>(n));
  }
  return out;
}

std::string input_file_problem(const std::string& path, Pipes pipes, const char* noun) {
  Fd f;
  struct stat st {};
  return open_checked(path, pipes, noun, f, st);
}

}  // namespace crossdyn
