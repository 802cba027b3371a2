// Stopping and bounding runs, as a user meets them (docs/stopping.md):
// Ctrl-C (SIGINT) and SIGTERM at every phase of `run`, `compare` and `verify` (and `stability`
// on several threads), per-run --timeout and --max-steps, the progress line on a terminal (and
// nothing on a pipe), and a stiff but solvable scene whose first trial step blows up.
//
// Bound on time: after the signal, crossdyn must exit with status 130 within kExitBound = 3 s.
// crossdyn itself exits within about cancel::kForcedExitDelay (0.5 s) even where nothing polls;
// the bound is six times that, generous for a loaded CI machine, so these tests fail only when
// cancellation does not work, not when the machine is slow.
#include <catch2/catch.hpp>

#include "tests/support/child_process.hpp"
#include "tests/support/paths.hpp"

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <sys/stat.h>
#include <thread>

namespace fs = std::filesystem;
using crossdyn::test::ChildProcess;

namespace {

constexpr double kExitBound = 3.0;      // s, see above
constexpr double kPhaseTimeout = 600;   // s to reach a phase (a slow machine builds chain1000 slowly)

std::string program() { return crossdyn::test::binary_dir() + "/crossdyn"; }

// A fresh folder per test, removed at the end.
struct Folder {
  explicit Folder(const std::string& name)
      : path(fs::temp_directory_path() / ("crossdyn_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~Folder() { fs::remove_all(path); }
  std::string operator/(const std::string& f) const { return (path / f).string(); }
  std::vector<std::string> entries() const {
    std::vector<std::string> v;
    for (const auto& e : fs::directory_iterator(path)) v.push_back(e.path().filename().string());
    std::sort(v.begin(), v.end());
    return v;
  }
  fs::path path;
};

// chainN of docs/scenarios.md Scene 3 (the generator scripts/make_chain.py writes the same).
std::string chain_scene(int n, double duration = 10, double output_step = 0.1) {
  std::ostringstream s;
  s << "name: chain" << n << "\ndescription: " << n << " links joined by spherical joints.\n"
    << "source: crossdyn test (chainN, SCENARIOS.md Scene 3).\nbodies:\n"
    << "  - {name: link1, mass: 10, inertia: &I [0.1, 3.4, 3.4]}\n";
  for (int k = 2; k <= n; ++k) s << "  - {name: link" << k << ", mass: 10, inertia: *I}\n";
  s << "joints:\n  - {name: joint1, type: free, child: link1, initial: {angular_velocity: [0.3, 0.2, 0.5]}}\n";
  for (int k = 2; k <= n; ++k) {
    s << "  - {name: joint" << k << ", type: spherical, parent: link" << k - 1 << ", child: link" << k;
    s << (k == 2 ? ", parent_point: &P [1, 0, 0], child_point: &C [-1, 0, 0], initial: &W "
                   "{angular_velocity: [0.1, -0.2, 0.3]}}\n"
                 : ", parent_point: *P, child_point: *C, initial: *W}\n");
  }
  s << "run: {duration: " << duration << ", output_step: " << output_step
    << ", integrator: rkf78, rtol: 1e-10, atol: 1e-10}\n";
  return s.str();
}

std::string write(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
  return path;
}

std::string read(const std::string& path) {
  std::stringstream s;
  s << std::ifstream(path).rdbuf();
  return s.str();
}

std::string wchan(pid_t pid) { return read("/proc/" + std::to_string(pid) + "/wchan"); }

// Waits until the process sleeps in the kernel function `where` (e.g. blocked opening a FIFO).
bool wait_wchan(pid_t pid, const std::string& where, double seconds) {
  for (int i = 0; i < static_cast<int>(seconds * 100); ++i) {
    if (wchan(pid).find(where) != std::string::npos) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

// Sends `sig`, then requires exit status 130 within the bound and the message "interrupted".
void require_interrupted(ChildProcess& p, int sig) {
  p.signal(sig);
  const auto status = p.wait_exit(kExitBound);
  INFO("signal " << sig << "; stderr: " << p.err());
  REQUIRE(status);  // exited within kExitBound
  CHECK(*status == 130);
  CHECK(p.err().find("crossdyn: interrupted") != std::string::npos);
}

// The largest step count on the progress line so far.
long progress_steps(const std::string& err) {
  static const std::regex steps("  ([0-9]+) steps");
  long most = -1;
  for (auto it = std::sregex_iterator(err.begin(), err.end(), steps); it != std::sregex_iterator(); ++it)
    most = std::max(most, std::stol((*it)[1]));
  return most;
}

}  // namespace

TEST_CASE("Ctrl-C while reading a FIFO as the scene: exit 130 within the bound, no output") {
  Folder d("fifo");
  const std::string fifo = d / "scene.yaml";
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  SECTION("no writer yet: never waited on (issue 23 class 3), an empty scene at once") {
    ChildProcess p({program(), "run", fifo, "--output", d / "out.csv"});
    const std::optional<int> status = p.wait_exit(60);
    REQUIRE(status);
    CHECK(*status == 2);
    CHECK(p.err().find("nothing was written to the pipe") != std::string::npos);
    CHECK_FALSE(fs::exists(d / "out.csv"));
  }
  SECTION("blocked in read(): a writer that sent half a scene and stays") {
    const int w = ::open(fifo.c_str(), O_RDWR | O_NONBLOCK);  // never blocks, keeps the FIFO open
    REQUIRE(w >= 0);
    REQUIRE(::write(w, "name: x\n", 8) == 8);
    ChildProcess p({program(), "run", fifo, "--output", d / "out.csv"});
    REQUIRE(wait_wchan(p.pid(), "pipe_read", 60));
    require_interrupted(p, SIGTERM);
    ::close(w);
  }
  CHECK(d.entries() == std::vector<std::string>{"scene.yaml"});
}

TEST_CASE("Ctrl-C during `run`: engine set-up, inside one long right-hand side, between steps") {
  Folder d("sigrun");
  const std::string chain1000 = write(d / "chain1000.yaml", chain_scene(1000));
  const std::string chain100 = write(d / "chain100.yaml", chain_scene(100, 1e6, 10));
  SECTION("set-up of the lagrange engine for 1000 links") {
    ChildProcess p({program(), "run", chain1000, "--engine", "lagrange", "--output", d / "out.csv"},
                   ChildProcess::Stderr::Terminal);
    REQUIRE(p.wait_for("setting up the engine", kPhaseTimeout));
    require_interrupted(p, SIGINT);
  }
  SECTION("kane on 400 links, inside the first steps (one right-hand side takes about 0.5 s)") {
    // Kane's O(n^3) right-hand side: 6.7 s for rkf78's first 13-stage trial step on 400 links
    // (measured: crossdyn run chain400.yaml --engine kane --max-steps 1). Three seconds after the
    // set-up began, the signal lands inside a right-hand side (or a late set-up).
    const std::string chain400 = write(d / "chain400.yaml", chain_scene(400));
    ChildProcess p({program(), "run", chain400, "--engine", "kane", "--output", d / "out.csv"},
                   ChildProcess::Stderr::Terminal);
    REQUIRE(p.wait_for("setting up the engine", kPhaseTimeout));
    p.wait_for("\x01", 3.0);  // never printed: waits 3 s
    require_interrupted(p, SIGTERM);
    fs::remove(chain400);
  }
  SECTION("newton-euler on 100 links, a million-second run, between steps") {
    ChildProcess p({program(), "run", chain100, "--engine", "newton-euler", "--output", d / "out.csv"},
                   ChildProcess::Stderr::Terminal);
    for (int i = 0; i < kPhaseTimeout * 10 && progress_steps(p.err()) <= 0; ++i) p.wait_for("\x01", 0.1);
    REQUIRE(progress_steps(p.err()) > 0);
    require_interrupted(p, SIGINT);
    CHECK(p.err().find("engine newton-euler at t = ") != std::string::npos);
  }
  // Neither the output nor its temporary file is left behind.
  CHECK(d.entries() == std::vector<std::string>{"chain100.yaml", "chain1000.yaml"});
}

TEST_CASE("Ctrl-C during `compare` and `verify`: between engines, during a run, during the report") {
  Folder d("sigcmp");
  // 30 links for 5 s: kane (first) finishes in about 3 s, so that the signal reaches the second
  // engine (lagrange, about 7 s: the signal arrives during it). Measured with `crossdyn run
  // --stats` on scripts/make_chain.py 30 --duration 0.5: kane 0.30 s, lagrange 0.64 s.
  const std::string chain30 = write(d / "chain30.yaml", chain_scene(30, 5, 0.1));
  SECTION("compare, while the second engine runs") {
    ChildProcess p({program(), "compare", chain30, "--json", d / "c.json"}, ChildProcess::Stderr::Terminal);
    REQUIRE(p.wait_for("chain30 lagrange", kPhaseTimeout));
    require_interrupted(p, SIGINT);
  }
  SECTION("verify, during the first run") {
    ChildProcess p({program(), "verify", chain30, crossdyn::test::scene_path("spear1_case1"),
                    "--json", d / "v.json", "--junit", d / "v.xml"},
                   ChildProcess::Stderr::Terminal);
    REQUIRE(p.wait_for("chain30 kane", kPhaseTimeout));
    require_interrupted(p, SIGTERM);
  }
  SECTION("verify, while the report script runs") {
    // The script marks that it started (the report is built in a staging folder, so d/report
    // appears only at the end), then sleeps until it is stopped.
    const std::string started = d / "python_started";
    const std::string python =
        write(d / "slow_python.sh", "#!/bin/sh\n: > '" + started + "'\nexec sleep 1000\n");
    fs::permissions(python, fs::perms::owner_all);
    ChildProcess p({program(), "verify", crossdyn::test::scene_path("spear1_case1"), "--python",
                    python, "--report=" + d / "report"});
    REQUIRE(p.wait_for("verify: ", kPhaseTimeout));  // the scene is done; the report comes next
    for (int i = 0; i < kPhaseTimeout * 10 && !fs::exists(started); ++i) p.wait_for("\x01", 0.1);
    REQUIRE(fs::exists(started));  // the signal lands while the report script runs
    require_interrupted(p, SIGINT);
    // No report, not half of one, and no staging folder left behind.
    CHECK(d.entries() == std::vector<std::string>{"chain30.yaml", "python_started", "slow_python.sh"});
  }
  for (const char* f : {"c.json", "v.json", "v.xml"}) CHECK_FALSE(fs::exists(d / f));
}

TEST_CASE("Ctrl-C during `stability --jobs 2`: every thread's run stops, exit 130 within the bound, no output") {
  Folder d("sigstab");
  // chain30 for 5 s (as above: kane about 3 s, lagrange about 7 s at the scene's tolerance): the
  // reference runs of two values, four at once on two threads, last several seconds each.
  const std::string chain30 = write(d / "chain30.yaml", chain_scene(30, 5, 0.1));
  ChildProcess p({program(), "stability", chain30, "--vary", "duration", "--values", "5,4", "--jobs", "2",
                  "--csv", d / "s.csv", "--report", d / "report"},
                 ChildProcess::Stderr::Terminal);
  REQUIRE(p.wait_for("reference run", kPhaseTimeout));
  require_interrupted(p, SIGINT);
  CHECK(d.entries() == std::vector<std::string>{"chain30.yaml"});
}

TEST_CASE("per-run limits: --timeout and --max-steps fail only the run that hits them: other engines and scenes go on") {
  Folder d("limits");
  const std::string chain100 = write(d / "chain100.yaml", chain_scene(100, 1e6, 10));
  {
    ChildProcess p({program(), "verify", chain100, crossdyn::test::scene_path("spear1_case1"),
                    "--timeout", "1", "--quiet", "--json", d / "v.json"});
    const auto status = p.wait_exit(kPhaseTimeout);
    INFO(p.out() << p.err());
    REQUIRE(status);
    CHECK(*status == 1);  // a check failed: the runs that timed out
    for (const char* engine : {"kane", "lagrange", "newton-euler"})
      CHECK(p.out().find(std::string("engine ") + engine) != std::string::npos);
    CHECK(p.out().find("timed out after 1 s") != std::string::npos);
    CHECK(std::regex_search(p.out(), std::regex("spear1_case1 .* PASS\\n")));  // the next scene ran
  }
  {
    ChildProcess p({program(), "compare", chain100, "--max-steps", "30", "--quiet"});
    const auto status = p.wait_exit(kPhaseTimeout);
    INFO(p.out() << p.err());
    REQUIRE(status);
    CHECK(*status == 1);
    std::size_t n = 0;
    for (std::size_t at = 0; (at = p.out().find("step limit reached (30 steps)", at)) != std::string::npos; ++at) ++n;
    CHECK(n >= 3);  // each engine's run line (and its check)
  }
}

TEST_CASE("per-run limits: --timeout and --max-steps are validated: zero, negative, NaN and infinity are exit 2") {
  const std::string scene = crossdyn::test::scene_path("spear1_case1");
  for (const char* command : {"compare", "verify"})
    for (const std::vector<std::string>& bad :
         {std::vector<std::string>{"--timeout", "0"}, {"--timeout", "-1"}, {"--timeout", "nan"},
          {"--timeout", "inf"}, {"--max-steps", "0"}, {"--max-steps", "-5"}, {"--max-steps", "nan"},
          {"--max-steps", "1.5"}}) {
      ChildProcess p({program(), command, scene, bad[0], bad[1]});
      const auto status = p.wait_exit(kPhaseTimeout);
      INFO(command << " " << bad[0] << " " << bad[1] << ": " << p.err());
      REQUIRE(status);
      CHECK(*status == 2);
      CHECK(p.err().find(bad[0]) != std::string::npos);
      CHECK(p.out().empty());
    }
}

TEST_CASE("progress: shown on a terminal, redrawn in place and erased: nothing on a pipe or with "
          "--quiet, and the output is byte-identical") {
  Folder d("progress");
  const std::string scene = write(d / "chain20.yaml", chain_scene(20, 4, 0.5));
  std::string csv_terminal, csv_pipe;
  {
    ChildProcess p({program(), "run", scene, "--output", d / "a.csv"}, ChildProcess::Stderr::Terminal);
    REQUIRE(p.wait_exit(kPhaseTimeout) == std::optional<int>(0));
    INFO(p.err());
    CHECK(p.err().find("\rchain20 kane: ") != std::string::npos);
    CHECK(std::regex_search(p.err(), std::regex("[0-9.]+%  t = [0-9.e+-]+ of 4 s  [0-9]+ steps  [0-9]+ s elapsed")));
    CHECK(p.err().size() >= 6);
    CHECK(p.err().substr(p.err().size() - 4) == "\r\x1b[K");  // erased at the end
    csv_terminal = read(d / "a.csv");
  }
  {
    ChildProcess p({program(), "run", scene, "--output", d / "b.csv"});
    REQUIRE(p.wait_exit(kPhaseTimeout) == std::optional<int>(0));
    CHECK(p.err().empty());
    csv_pipe = read(d / "b.csv");
  }
  CHECK(!csv_pipe.empty());
  CHECK(csv_terminal == csv_pipe);
  {
    ChildProcess p({program(), "run", scene, "--quiet", "--output", d / "c.csv"}, ChildProcess::Stderr::Terminal);
    REQUIRE(p.wait_exit(kPhaseTimeout) == std::optional<int>(0));
    CHECK(p.err().empty());
  }
  for (const char* command : {"compare", "verify"}) {
    ChildProcess terminal({program(), command, scene, "--json", d / "s.json"}, ChildProcess::Stderr::Terminal);
    REQUIRE(terminal.wait_exit(kPhaseTimeout));
    INFO(command << ": " << terminal.err());
    for (const char* engine : {"kane", "lagrange", "newton-euler"})
      CHECK(terminal.err().find(std::string("chain20 ") + engine + ": ") != std::string::npos);
    ChildProcess pipe({program(), command, scene, "--json", d / "s.json"});
    REQUIRE(pipe.wait_exit(kPhaseTimeout));
    CHECK(pipe.err().find('\r') == std::string::npos);
    CHECK(pipe.err().find("chain20 kane: ") == std::string::npos);
    ChildProcess quiet({program(), command, scene, "--quiet", "--json", d / "s.json"},
                       ChildProcess::Stderr::Terminal);
    REQUIRE(quiet.wait_exit(kPhaseTimeout));
    CHECK(quiet.err().empty());
  }
}

TEST_CASE("a stiff but solvable scene whose first trial step blows up runs with every adaptive "
          "method and agrees with the analytic solution") {
  // A free body spinning at about 1e5 rad/s: the gyroscopic term (quadratic in the rates) makes
  // the stages of a first trial step of 1 ms diverge past 1e100; shorter steps are fine.
  Folder d("stiff");
  const std::string scene = write(d / "fast_spin.yaml", R"(name: fast_spin
description: An asymmetric rigid body spinning at about 1e5 rad/s, torque free, for 10 ms.
source: crossdyn test (tests/cli/test_cancel_cli.cpp); issue 9, a trial step is not a failure.
analytic: torque-free
bodies:
  - {name: body, mass: 10, inertia: [1, 2, 3]}
joints:
  - {name: base, type: free, child: body, initial: {angular_velocity: [1e5, 5e4, 7e4]}}
run: {duration: 0.01, output_step: 0.001, integrator: rkf78, rtol: 1e-10, atol: 1e-10}
compare:
  tolerances:
    default: {atol: 1e-5, rtol: 1e-5}
    drift: {atol: 1e-6, rtol: 1e-7}
)");
  for (const char* method : {"rkf78", "dopri5", "bulirsch-stoer"}) {
    ChildProcess p({program(), "compare", scene, "--integrator", method, "--quiet"});
    const auto status = p.wait_exit(kPhaseTimeout);
    INFO(method << ": " << p.out() << p.err());
    REQUIRE(status);
    CHECK(*status == 0);  // every engine ran to the end and agrees with the analytic solution
    CHECK(p.out().find("FAILED") == std::string::npos);
  }
}
