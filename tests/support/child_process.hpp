// A program started by a test, with its stdout and stderr captured (stderr optionally on a
// pseudo-terminal, as a user's terminal), signals sent to it, and its exit awaited with a bound.
// The child runs in its own process group; the destructor kills the whole group, so a test never
// leaves processes behind (a report script, a `sleep`).
#pragma once

#include <chrono>
#include <csignal>
#include <cstring>
#include <fcntl.h>
#include <optional>
#include <poll.h>
#include <pty.h>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

namespace crossdyn::test {

class ChildProcess {
 public:
  enum class Stderr { Pipe, Terminal };

  // Starts argv[0] with argv. stdout goes to a pipe (or to `stdout_file` when given); stderr to a
  // pipe or a pseudo-terminal; stdin is /dev/null.
  ChildProcess(const std::vector<std::string>& argv, Stderr err = Stderr::Pipe,
               const std::string& stdout_file = "") {
    int out[2] = {-1, -1}, errp[2] = {-1, -1};
    if (stdout_file.empty() && ::pipe(out) != 0) return;
    if (err == Stderr::Terminal) {
      winsize ws{};
      ws.ws_col = 200;
      ws.ws_row = 24;
      if (::openpty(&errp[0], &errp[1], nullptr, nullptr, &ws) != 0) return;
    } else if (::pipe(errp) != 0) {
      return;
    }
    pid_ = ::fork();
    if (pid_ == 0) {
      ::setpgid(0, 0);
      const int in = ::open("/dev/null", O_RDONLY);
      ::dup2(in, 0);
      if (stdout_file.empty()) {
        ::dup2(out[1], 1);
      } else {
        const int f = ::open(stdout_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        ::dup2(f, 1);
      }
      ::dup2(errp[1], 2);
      for (int fd = 3; fd < 1024; ++fd) ::close(fd);
      std::vector<char*> args;
      for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      ::execv(args[0], args.data());
      ::_exit(127);
    }
    ::setpgid(pid_, pid_);  // both sides, so the group exists before either continues
    if (out[1] >= 0) ::close(out[1]);
    ::close(errp[1]);
    out_fd_ = out[0];
    err_fd_ = errp[0];
  }

  ~ChildProcess() {
    if (pid_ > 0) {
      ::kill(-pid_, SIGKILL);
      if (!status_) ::waitpid(pid_, nullptr, 0);
    }
    if (out_fd_ >= 0) ::close(out_fd_);
    if (err_fd_ >= 0) ::close(err_fd_);
  }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }
  const std::string& out() const { return out_; }
  const std::string& err() const { return err_; }

  void signal(int sig) const { ::kill(pid_, sig); }

  // Reads output until `needle` appears in stderr (or stdout) or `seconds` pass; true when found.
  bool wait_for(const std::string& needle, double seconds, bool in_stderr = true) {
    const auto end = clock::now() + std::chrono::duration<double>(seconds);
    for (;;) {
      if ((in_stderr ? err_ : out_).find(needle) != std::string::npos) return true;
      if (clock::now() >= end || !drain(50)) {
        return (in_stderr ? err_ : out_).find(needle) != std::string::npos;
      }
    }
  }

  // Waits up to `seconds` for the exit (reading output meanwhile). The exit status, 128 + signal
  // when killed by one, or nullopt when it is still running.
  std::optional<int> wait_exit(double seconds) {
    const auto end = clock::now() + std::chrono::duration<double>(seconds);
    while (!status_) {
      int st = 0;
      const pid_t r = ::waitpid(pid_, &st, WNOHANG);
      if (r == pid_) {
        status_ = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
        break;
      }
      if (clock::now() >= end) return std::nullopt;
      drain(10);
    }
    while (drain(0)) {
    }
    return status_;
  }

 private:
  using clock = std::chrono::steady_clock;

  // Reads what is available within `ms`; false when both streams are closed.
  bool drain(int ms) {
    pollfd p[2] = {{out_fd_, POLLIN, 0}, {err_fd_, POLLIN, 0}};
    if (out_fd_ < 0 && err_fd_ < 0) {
      if (ms > 0) ::usleep(static_cast<useconds_t>(ms) * 1000);
      return false;
    }
    if (::poll(p, 2, ms) <= 0) return true;
    bool open = false;
    for (int i = 0; i < 2; ++i) {
      int& fd = i == 0 ? out_fd_ : err_fd_;
      if (fd < 0) continue;
      if (p[i].revents & (POLLIN | POLLHUP | POLLERR)) {
        char buf[4096];
        const ssize_t n = ::read(fd, buf, sizeof buf);
        if (n > 0) {
          (i == 0 ? out_ : err_).append(buf, static_cast<std::size_t>(n));
        } else {  // EOF (a pty gives EIO once the child closed it)
          ::close(fd);
          fd = -1;
          continue;
        }
      }
      open = true;
    }
    return open || out_fd_ >= 0 || err_fd_ >= 0;
  }

  pid_t pid_ = -1;
  int out_fd_ = -1, err_fd_ = -1;
  std::string out_, err_;
  std::optional<int> status_;
};

}  // namespace crossdyn::test
