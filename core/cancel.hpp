// Stopping work early: Ctrl-C and SIGTERM (the whole program stops, exit status 130) and per-run
// time limits (one engine run stops and is recorded as a failed run; the others go on).
//
// How it works:
//   * A signal handler (install_signal_handlers) only sets an atomic flag and wakes the watchdog
//     thread through a pipe: both async-signal-safe. Handlers use SA_RESTART, so a system call
//     that was blocked (open() or read() of a FIFO given as a scene) is not turned into a bogus
//     "cannot read" error.
//   * Long loops call poll(): one or two relaxed atomic loads. When the program was interrupted,
//     or the calling thread's run is past its Deadline, poll() throws Cancelled. The integrator
//     turns it into RunFailure(engine, t, "", "interrupted" or "timed out after 30 s"); the
//     commands turn an interrupt into "interrupted" and exit status 130.
//   * The safety net: code that never polls (a blocking read, one long Eigen factorisation, a
//     child process) cannot delay the exit. The watchdog thread waits kForcedExitDelay after the
//     first signal; if the program is still running it removes the registered temporary files,
//     prints "<program>: interrupted" (unless the program already said so) and calls _exit(130).
//     A second signal exits the same way at once.
//   * Deadlines are set by the watchdog thread too: it flips the run's flag when the time is up,
//     so poll() never reads a clock.
//
// Engines may call poll() anywhere outside their own invariants (it throws); they must not catch
// Cancelled. Nothing here allocates in poll() or in the signal handler.
#pragma once

#include <atomic>
#include <exception>
#include <string>
#include <sys/types.h>

namespace crossdyn::cancel {

enum class Reason { Interrupt, Timeout };

// Thrown by poll(). Not a RunFailure (the integrator adds the engine and the time) and not an
// InputError.
class Cancelled : public std::exception {
 public:
  Cancelled(Reason reason, double limit_seconds);
  Reason reason() const { return reason_; }
  double limit_seconds() const { return limit_; }  // the Deadline's limit (Timeout only)
  // "interrupted", or "timed out after 30 s".
  const char* what() const noexcept override { return what_.c_str(); }

 private:
  Reason reason_;
  double limit_;
  std::string what_;
};

// A time limit for the work of the calling thread while this object lives (a scope; nested
// deadlines: the innermost is polled). seconds <= 0 or infinite: no limit, and poll() only sees
// interrupts. The limit counts from construction.
class Deadline {
 public:
  explicit Deadline(double seconds);
  ~Deadline();
  Deadline(const Deadline&) = delete;
  Deadline& operator=(const Deadline&) = delete;
  bool expired() const { return expired_.load(std::memory_order_relaxed); }
  double seconds() const { return seconds_; }

 private:
  double seconds_;
  std::atomic<bool> expired_{false};
  const Deadline* outer_;
  bool registered_ = false;
};

namespace detail {
extern std::atomic<bool> g_interrupted;
// The calling thread's innermost Deadline (null when none). constinit: no TLS wrapper call.
extern constinit thread_local const Deadline* t_deadline;
[[noreturn]] void throw_cancelled();
// Tests only: forget an interrupt (request_interrupt) so later tests in the process can run.
void reset_interrupt_for_tests();
}  // namespace detail

// Throws Cancelled when the program was interrupted or this thread's Deadline has passed.
inline void poll() {
  const Deadline* d = detail::t_deadline;
  if (detail::g_interrupted.load(std::memory_order_relaxed) ||
      (d != nullptr && d->expired()))
    detail::throw_cancelled();
}

// Was the program interrupted (SIGINT, SIGTERM or request_interrupt())?
inline bool interrupted() { return detail::g_interrupted.load(std::memory_order_relaxed); }

// Asks the whole program to stop (what the signal handler does; async-signal-safe). Without
// install_signal_handlers() there is no forced exit: only poll() reacts.
void request_interrupt();

// Installs the SIGINT and SIGTERM handlers and starts the watchdog thread. `program` prefixes
// the watchdog's message ("crossdyn: interrupted"). Call once, early in main().
void install_signal_handlers(const char* program);

// Seconds between the first signal and the forced exit.
inline constexpr double kForcedExitDelay = 0.5;

// The program has reported the interrupt itself: the watchdog's forced exit stays silent.
void acknowledge_interrupt();

// Removes the registered temporary files and calls _exit(130) (what the watchdog and a second
// signal do). Async-signal-safe. For tests of the safety net.
[[noreturn]] void forced_exit();

// Temporary files that a forced exit must remove (an AtomicFile's temporary, a spill file that
// has a name). Returns a handle for unregister_temporary, or -1 when the table (64 entries) is
// full or the path is too long (4096 bytes); the file is then not removed by a forced exit.
int register_temporary(const std::string& path);
void unregister_temporary(int handle);

// While a HoldForcedExit lives (outputs being renamed into place, core/output.hpp
// commit_together), neither the watchdog nor a second signal exits: the forced exit waits until
// the last HoldForcedExit is destroyed, so a command's outputs are all old or all new. The
// interrupt itself is still recorded (interrupted() is true).
class HoldForcedExit {
 public:
  HoldForcedExit();
  ~HoldForcedExit();
  HoldForcedExit(const HoldForcedExit&) = delete;
  HoldForcedExit& operator=(const HoldForcedExit&) = delete;
};

// Test hook (documented in docs/outputs.md, "All outputs of one command are committed
// together"): when the environment variable CROSSDYN_TEST_INTERRUPT_AT equals `phase`, acts as if
// Ctrl-C arrived now (request_interrupt).
// Phases: "report" (a report or drawing script was just started), "before-commit" (every output
// prepared, none renamed yet), "during-commit" (after the first output was renamed into place).
void test_interrupt_point(const char* phase);

// Child processes that a forced exit must stop (SIGTERM), for example the report script.
// Returns a handle, or -1 when the table (16 entries) is full.
int register_child(pid_t pid);
void unregister_child(int handle);

}  // namespace crossdyn::cancel
