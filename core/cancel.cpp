// Interrupts, deadlines and the forced-exit safety net (see cancel.hpp for the design).
#include "core/cancel.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <mutex>
#include <poll.h>
#include <thread>
#include <time.h>
#include <unistd.h>
#include <vector>

namespace crossdyn::cancel {

namespace detail {
std::atomic<bool> g_interrupted{false};
constinit thread_local const Deadline* t_deadline = nullptr;
}  // namespace detail

namespace {

static_assert(std::atomic<bool>::is_always_lock_free && std::atomic<long long>::is_always_lock_free &&
                  std::atomic<int>::is_always_lock_free,
              "the signal handler needs lock-free atomics");

long long now_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);  // async-signal-safe
  return static_cast<long long>(ts.tv_sec) * 1'000'000'000LL + ts.tv_nsec;
}

std::atomic<long long> g_signal_ns{0};      // monotonic time of the first signal
std::atomic<bool> g_forced_exit_armed{false};  // install_signal_handlers() was called
std::atomic<bool> g_acknowledged{false};
std::atomic<int> g_wake_fd{-1};
std::atomic<int> g_hold{0};                  // HoldForcedExit objects alive
std::atomic<bool> g_exit_pending{false};     // a forced exit waited for the hold to end              // write end of the watchdog's pipe
char g_message[160] = "interrupted\n";
std::atomic<std::size_t> g_message_size{12};

// Registered temporary files: fixed slots, so the forced exit reads them without locks.
// state: 0 free, 1 being written, 2 in use.
struct TempSlot {
  std::atomic<int> state{0};
  char path[4096];
};
TempSlot g_temps[64];
std::atomic<pid_t> g_children[16];

// Deadlines, checked by the watchdog thread. Never destroyed (the detached thread may outlive
// static destruction at exit).
struct Registry {
  std::mutex mutex;
  std::vector<std::pair<long long, std::atomic<bool>*>> deadlines;  // (time due, its flag)
};
Registry& registry() {
  static Registry* r = new Registry;
  return *r;
}

void wake() {
  const int fd = g_wake_fd.load(std::memory_order_acquire);
  if (fd >= 0) {
    const char c = 'w';
    [[maybe_unused]] const ssize_t n = ::write(fd, &c, 1);  // a full pipe is already awake
  }
}

void watchdog_loop(int read_fd) {
  constexpr long long kDelayNs = static_cast<long long>(kForcedExitDelay * 1e9);
  for (;;) {
    long long wait_ns = -1;  // infinite
    const long long now = now_ns();
    if (g_forced_exit_armed.load() && detail::g_interrupted.load()) {
      const long long signal_ns = g_signal_ns.load();
      const long long due = (signal_ns > 0 ? signal_ns : now) + kDelayNs;
      if (now >= due) {
        if (g_hold.load() == 0) forced_exit();
        g_exit_pending.store(true);  // ~HoldForcedExit exits; look again soon in any case
        wait_ns = 10'000'000;
      } else {
        wait_ns = due - now;
      }
    }
    {
      Registry& r = registry();
      std::lock_guard<std::mutex> lock(r.mutex);
      for (auto& [due, expired] : r.deadlines) {
        if (now >= due) {
          expired->store(true);  // valid while registered: ~Deadline removes it under the mutex
        } else {
          wait_ns = wait_ns < 0 ? due - now : std::min(wait_ns, due - now);
        }
      }
    }
    pollfd p{read_fd, POLLIN, 0};
    const int timeout_ms =
        wait_ns < 0 ? -1 : static_cast<int>(std::min<long long>(wait_ns / 1'000'000 + 1, 60'000));
    const int rc = ::poll(&p, 1, timeout_ms);
    if (rc > 0) {
      char buf[64];
      while (::read(read_fd, buf, sizeof buf) > 0) {
      }
    }
  }
}

void start_watchdog() {
  static std::once_flag once;
  std::call_once(once, [] {
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC | O_NONBLOCK) != 0) {
      std::perror("crossdyn: cannot create the watchdog's pipe");
      return;  // poll() still works; only deadlines and the forced exit are lost
    }
    std::thread(watchdog_loop, fds[0]).detach();
    g_wake_fd.store(fds[1], std::memory_order_release);
  });
}

extern "C" void on_signal(int) {
  const int saved = errno;
  if (detail::g_interrupted.exchange(true)) {  // the second signal: stop now (or after the hold)
    if (g_hold.load() == 0) forced_exit();
    g_exit_pending.store(true);
  }
  long long expected = 0;
  g_signal_ns.compare_exchange_strong(expected, now_ns());
  wake();
  errno = saved;
}

std::string format_seconds(double s) {
  char b[64];
  std::snprintf(b, sizeof b, "%.6g", s);
  return b;
}

}  // namespace

Cancelled::Cancelled(Reason reason, double limit_seconds)
    : reason_(reason), limit_(limit_seconds),
      what_(reason == Reason::Interrupt ? std::string("interrupted")
                                        : "timed out after " + format_seconds(limit_seconds) + " s") {}

namespace detail {
void throw_cancelled() {
  if (g_interrupted.load(std::memory_order_relaxed)) throw Cancelled(Reason::Interrupt, 0);
  throw Cancelled(Reason::Timeout, t_deadline ? t_deadline->seconds() : 0);
}
void reset_interrupt_for_tests() {
  g_interrupted.store(false);
  g_signal_ns.store(0);
}
}  // namespace detail

void request_interrupt() {
  detail::g_interrupted.store(true);
  long long expected = 0;
  g_signal_ns.compare_exchange_strong(expected, now_ns());
  wake();
}

void install_signal_handlers(const char* program) {
  const int n = std::snprintf(g_message, sizeof g_message, "%s: interrupted\n", program);
  g_message_size.store(n > 0 ? std::min(static_cast<std::size_t>(n), sizeof g_message - 1) : 0);
  start_watchdog();
  g_forced_exit_armed.store(true);
  struct sigaction sa{};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  ::sigaction(SIGINT, &sa, nullptr);
  ::sigaction(SIGTERM, &sa, nullptr);
}

HoldForcedExit::HoldForcedExit() { g_hold.fetch_add(1); }

HoldForcedExit::~HoldForcedExit() {
  if (g_hold.fetch_sub(1) == 1 && g_exit_pending.load()) forced_exit();
}

void test_interrupt_point(const char* phase) {
  const char* at = std::getenv("CROSSDYN_TEST_INTERRUPT_AT");
  if (at != nullptr && std::strcmp(at, phase) == 0) request_interrupt();
}

void acknowledge_interrupt() { g_acknowledged.store(true); }

void forced_exit() {
  if (!g_acknowledged.exchange(true)) {
    [[maybe_unused]] const ssize_t n = ::write(STDERR_FILENO, g_message, g_message_size.load());
  }
  for (TempSlot& s : g_temps)
    if (s.state.load(std::memory_order_acquire) == 2) ::unlink(s.path);
  for (std::atomic<pid_t>& c : g_children) {
    const pid_t pid = c.load();
    if (pid > 0) ::kill(pid, SIGTERM);
  }
  ::_exit(130);
}

Deadline::Deadline(double seconds) : seconds_(seconds), outer_(detail::t_deadline) {
  if (seconds > 0 && std::isfinite(seconds)) {
    start_watchdog();
    const long long due = now_ns() + static_cast<long long>(std::min(seconds, 1e9) * 1e9);
    {
      Registry& r = registry();
      std::lock_guard<std::mutex> lock(r.mutex);
      r.deadlines.emplace_back(due, &expired_);
    }
    registered_ = true;
    wake();
  }
  detail::t_deadline = this;
}

Deadline::~Deadline() {
  if (registered_) {
    Registry& r = registry();
    std::lock_guard<std::mutex> lock(r.mutex);
    std::erase_if(r.deadlines, [this](const auto& e) { return e.second == &expired_; });
  }
  detail::t_deadline = outer_;
}

int register_temporary(const std::string& path) {
  if (path.size() >= sizeof(TempSlot::path)) return -1;
  for (int i = 0; i < static_cast<int>(std::size(g_temps)); ++i) {
    int expected = 0;
    if (g_temps[i].state.compare_exchange_strong(expected, 1)) {
      std::memcpy(g_temps[i].path, path.c_str(), path.size() + 1);
      g_temps[i].state.store(2, std::memory_order_release);
      return i;
    }
  }
  return -1;
}

void unregister_temporary(int handle) {
  if (handle >= 0 && handle < static_cast<int>(std::size(g_temps))) g_temps[handle].state.store(0);
}

int register_child(pid_t pid) {
  for (int i = 0; i < static_cast<int>(std::size(g_children)); ++i) {
    pid_t expected = 0;
    if (g_children[i].compare_exchange_strong(expected, pid)) return i;
  }
  return -1;
}

void unregister_child(int handle) {
  if (handle >= 0 && handle < static_cast<int>(std::size(g_children))) g_children[handle].store(0);
}

}  // namespace crossdyn::cancel
