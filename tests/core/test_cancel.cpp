// Cancellation (core/cancel.hpp): interrupts and per-run deadlines seen by poll() and turned into
// run failures by simulate(), and the safety net that ends a process that never polls.
//
// Bounds on time: a forced exit must happen within cancel::kForcedExitDelay (0.5 s) of the
// signal; the tests allow kExitBound = 3 s, generous for a loaded CI machine, so that they fail
// only when the safety net does not work at all, not when the machine is slow.
#include <catch2/catch.hpp>

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "core/output_layout.hpp"
#include "tests/support/child_process.hpp"
#include "tests/support/paths.hpp"

#include <atomic>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

using namespace crossdyn;
namespace fs = std::filesystem;

namespace {

constexpr double kExitBound = 3.0;  // s; see the note at the top

// Polls until poll() throws or `seconds` pass (a safety cap, not a timing assertion).
std::optional<cancel::Cancelled> poll_until_cancelled(double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    try {
      cancel::poll();
    } catch (const cancel::Cancelled& c) {
      return c;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return std::nullopt;
}

// x' = -x; rhs polls (as an engine's long loop would) and may sleep to make a run slow.
class SlowDecay : public Engine {
 public:
  const char* name() const override { return "slow"; }
  int state_size() const override { return 1; }
  std::string state_label(int) const override { return "x"; }
  void pack(const TreeState&, double* x) override { x[0] = 1; }
  void rhs(double, const double* x, double* xdot) override {
    cancel::poll();
    if (sleep_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(sleep_ms));
    xdot[0] = -x[0];
  }
  void accelerations(double, const double*, TreeAccel&) override {}
  const OutputLayout& layout() const override { return layout_; }
  void output_row(double t, const double* x, double* row) override {
    row[0] = t;
    row[1] = x[0];
  }
  int sleep_ms = 0;

 private:
  OutputLayout layout_ = [] {  // not a scene's layout: two plain columns
    OutputLayout l;
    l.add_extra("t", "s");
    l.add_extra("x", "");
    return l;
  }();
};

IntegratorSettings long_run() {
  IntegratorSettings s;
  s.method = "rk4";
  s.dt = 1e-3;
  s.duration = 1e6;
  s.output_step = 1.0;
  s.keep_rows = false;
  return s;
}

std::string child_program() { return test::binary_dir() + "/tests/core/cancel_child"; }

}  // namespace

TEST_CASE("cancel: poll() is silent until an interrupt, then throws Cancelled(\"interrupted\")") {
  CHECK_NOTHROW(cancel::poll());
  CHECK_FALSE(cancel::interrupted());
  cancel::request_interrupt();
  CHECK(cancel::interrupted());
  try {
    cancel::poll();
    FAIL("poll() did not throw after an interrupt");
  } catch (const cancel::Cancelled& c) {
    CHECK(c.reason() == cancel::Reason::Interrupt);
    CHECK(std::string(c.what()) == "interrupted");
  }
  cancel::detail::reset_interrupt_for_tests();
  CHECK_NOTHROW(cancel::poll());
}

TEST_CASE("cancel: a Deadline ends only the calling thread's work, with \"timed out after N s\"") {
  std::atomic<bool> other_cancelled{false};
  std::atomic<bool> stop_other{false};
  std::thread other([&] {  // no deadline here: must keep running
    while (!stop_other) {
      try {
        cancel::poll();
      } catch (const cancel::Cancelled&) {
        other_cancelled = true;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });
  {
    cancel::Deadline d(0.05);
    const auto c = poll_until_cancelled(60);
    REQUIRE(c);
    CHECK(d.expired());
    CHECK(c->reason() == cancel::Reason::Timeout);
    CHECK(c->limit_seconds() == 0.05);
    CHECK(std::string(c->what()) == "timed out after 0.05 s");
  }
  CHECK_NOTHROW(cancel::poll());  // the scope ended: no deadline any more
  stop_other = true;
  other.join();
  CHECK_FALSE(other_cancelled);
}

TEST_CASE("cancel: nested deadlines poll the innermost: no limit for 0, negative or infinite") {
  cancel::Deadline outer(1000);
  for (double none : {0.0, -1.0, std::numeric_limits<double>::infinity()}) {
    cancel::Deadline d(none);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    CHECK_FALSE(d.expired());
    CHECK_NOTHROW(cancel::poll());
  }
  {
    cancel::Deadline inner(0.01);
    CHECK(poll_until_cancelled(60));
  }
  CHECK_FALSE(outer.expired());
  CHECK_NOTHROW(cancel::poll());
}

TEST_CASE("cancel: simulate() turns an interrupt into the run failure \"interrupted\" at its time") {
  SlowDecay e;
  System s;
  // The interrupt arrives after the step that passes t = 0.5 s (as Ctrl-C would, at any time).
  const RunResult r = simulate(e, s, TreeState{}, long_run(), {}, [](double t, const RunStats&) {
    if (t > 0.5) cancel::request_interrupt();
  });
  cancel::detail::reset_interrupt_for_tests();
  REQUIRE(r.failure);
  INFO(r.failure->what());
  CHECK(r.failure->engine() == "slow");
  CHECK(r.failure->reason() == "interrupted");
  CHECK(r.failure->time() > 0.5);
  CHECK(r.failure->time() < 0.5 + 2e-3);  // stopped before the next step
}

TEST_CASE("cancel: a Deadline around simulate() fails that run with \"timed out after N s\"") {
  SlowDecay e;
  e.sleep_ms = 1;  // inside the right-hand side: the deadline is seen within one rhs call
  System s;
  cancel::Deadline d(0.2);
  const RunResult r = simulate(e, s, TreeState{}, long_run());
  REQUIRE(r.failure);
  CHECK(r.failure->reason() == "timed out after 0.2 s");
  CHECK(std::string(r.failure->what()).rfind("engine slow failed at t = ", 0) == 0);
}

TEST_CASE("forced exit: a process that never polls exits 130 after a signal and removes its "
          "registered temporary files") {
  for (int sig : {SIGINT, SIGTERM}) {
    const fs::path tmp = fs::temp_directory_path() /
                         ("crossdyn_forced_" + std::to_string(::getpid()) + "_" + std::to_string(sig));
    test::ChildProcess p({child_program(), "block", tmp.string()});
    REQUIRE(p.wait_for("ready", 60, false));
    REQUIRE(fs::exists(tmp));
    p.signal(sig);
    const auto status = p.wait_exit(kExitBound);
    INFO("signal " << sig << ", stderr: " << p.err());
    REQUIRE(status);
    CHECK(*status == 130);
    CHECK(p.err() == "cancel_child: interrupted\n");
    CHECK_FALSE(fs::exists(tmp));
  }
}

TEST_CASE("forced exit: a second signal exits at once: an acknowledged interrupt is not "
          "reported twice") {
  {
    test::ChildProcess p({child_program(), "ack"});
    REQUIRE(p.wait_for("ready", 60, false));
    p.signal(SIGINT);
    REQUIRE(p.wait_for("acknowledged", kExitBound));
    p.signal(SIGINT);  // the second signal
    const auto status = p.wait_exit(kExitBound);
    REQUIRE(status);
    CHECK(*status == 130);
    CHECK(p.err() == "acknowledged\n");
  }
  {
    test::ChildProcess p({child_program(), "poll"});
    REQUIRE(p.wait_for("ready", 60, false));
    p.signal(SIGTERM);
    const auto status = p.wait_exit(kExitBound);
    REQUIRE(status);
    CHECK(*status == 130);
    CHECK(p.err() == "caught: interrupted\n");  // the normal path, before the watchdog
  }
}

TEST_CASE("forced exit: registered child processes are stopped") {
  test::ChildProcess p({child_program(), "child"});
  REQUIRE(p.wait_for("ready", 60, false));
  const auto at = p.out().find("pid ");
  REQUIRE(at != std::string::npos);
  const int child = std::stoi(p.out().substr(at + 4));
  p.signal(SIGINT);
  REQUIRE(p.wait_exit(kExitBound) == std::optional<int>(130));
  // The orphaned `sleep` got SIGTERM: gone, or a zombie waiting for its new parent to reap it.
  bool stopped = false;
  for (int i = 0; i < 300 && !stopped; ++i) {
    std::ifstream stat("/proc/" + std::to_string(child) + "/stat");
    std::string line;
    if (!std::getline(stat, line)) {
      stopped = true;
    } else {
      const auto close = line.rfind(')');
      stopped = close != std::string::npos && line.size() > close + 2 && line[close + 2] == 'Z';
    }
    if (!stopped) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  CHECK(stopped);
}

TEST_CASE("class 2, outputs are renamed whole: the forced exit of a second Ctrl-C waits for HoldForcedExit") {
  // cancel_child hold: two SIGINTs and more than the forced-exit delay inside the hold; the
  // process must still reach the end of the hold (stderr "held") and only then exit with 130.
  const std::string err = (fs::temp_directory_path() / ("crossdyn_hold_" + std::to_string(::getpid()))).string();
  const int raw = std::system((child_program() + " hold > /dev/null 2> " + err).c_str());
  std::stringstream text;
  text << std::ifstream(err).rdbuf();
  fs::remove(err);
  INFO(text.str());
  REQUIRE(WIFEXITED(raw));
  CHECK(WEXITSTATUS(raw) == 130);
  CHECK(text.str().find("held\n") == 0);
  CHECK(text.str().find("not exited") == std::string::npos);
  CHECK(text.str().find("interrupted") != std::string::npos);
}
