// `crossdyn run` end to end: the CSV users and other tools read, and what happens when things go
// wrong (issue 6: clear message, non-zero exit, no half-written file).
#include <catch2/catch.hpp>

#include "core/output_layout.hpp"
#include "core/system.hpp"
#include "core/scene/scene.hpp"
#include "tests/support/paths.hpp"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <sys/wait.h>
#include <unistd.h>

using namespace crossdyn;
namespace fs = std::filesystem;

namespace {

struct Outcome {
  int status = -1;
  std::string out, err;
};

// Runs `crossdyn ARGS` and returns the exit status, stdout and stderr.
Outcome run_program(const std::string& args) {
  const fs::path dir = fs::temp_directory_path() / ("crossdyn_cli_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ostringstream cmd;
  cmd << "'" << test::binary_dir() << "/crossdyn' " << args << " > '" << (dir / "out").string()
      << "' 2> '" << (dir / "err").string() << "'";
  const int raw = std::system(cmd.str().c_str());
  Outcome o;
  o.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  std::stringstream a, b;
  a << std::ifstream(dir / "out").rdbuf();
  b << std::ifstream(dir / "err").rdbuf();
  o.out = a.str();
  o.err = b.str();
  fs::remove_all(dir);
  return o;
}

std::vector<std::string> lines(const std::string& s) {
  std::vector<std::string> v;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) v.push_back(l);
  return v;
}

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> v;
  std::istringstream in(s);
  for (std::string c; std::getline(in, c, ',');) v.push_back(c);
  return v;
}

// A hinge spring of 1e9 N m/rad on a 1 kg m^2 panel: a 3e4 rad/s mode, far beyond what rk4 at a
// 0.01 s step can follow (stable only for omega dt < 2.8), so every engine's run must blow up.
const char* kDiverging = R"(name: diverging
description: An absurdly stiff hinge spring integrated with rk4 at a large step, to force divergence.
source: crossdyn test (tests/cli/test_run_cli.cpp).
bodies:
  - {name: hub, mass: 100, inertia: [10, 20, 25]}
  - {name: panel, mass: 5, inertia: [1, 1, 1]}
joints:
  - {name: base, type: free, child: hub, initial: {angular_velocity: [0, 0, 0.1]}}
  - name: hinge
    type: revolute
    parent: hub
    child: panel
    parent_point: [1, 0, 0]
    child_point: [-1, 0, 0]
    axis: [0, 0, 1]
    spring: {stiffness: 1e9}
    initial: {angle: 0.1, rate: 0}
run: {duration: 10, output_step: 0.1, integrator: rk4, dt: 0.01}
)";

}  // namespace

TEST_CASE("run writes the pinned columns, 101 rows from 0 to 5 s, in shortest round-trip numbers") {
  const Outcome o = run_program("run '" + test::scene_path("spear1_case1") +
                             "' --engine kane --integrator rkf78 --rtol 1e-12 --atol 1e-12");
  REQUIRE(o.status == 0);
  const auto rows = lines(o.out);
  REQUIRE(rows.size() == 102);  // header + 101
  const auto header = split(rows[0]);
  const System system = read_scene(test::scene_path("spear1_case1"));
  const auto pinned = pinned_columns(system);
  REQUIRE(header.size() >= pinned.size());
  CHECK(std::vector<std::string>(header.begin(), header.begin() + static_cast<long>(pinned.size())) == pinned);
  CHECK(std::stod(split(rows[1])[0]) == 0.0);
  CHECK(std::stod(split(rows.back())[0]) == 5.0);
  CHECK(split(rows[2])[0] == "0.05");  // shortest round trip (%.17g wrote 0.050000000000000003)
  const auto h = static_cast<std::size_t>(std::find(header.begin(), header.end(), "H") - header.begin());
  const double h0 = std::stod(split(rows[1])[h]);
  for (std::size_t i = 1; i < rows.size(); ++i)
    CHECK(std::abs(std::stod(split(rows[i])[h]) - h0) <= 1e-10 * h0);
}

TEST_CASE("a diverging run names engine, time and reason, exits 3 and leaves no partial CSV") {
  const fs::path dir = fs::temp_directory_path() / ("crossdyn_diverge_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path scene = dir / "diverging.yaml", out = dir / "out.csv";
  std::ofstream(scene) << kDiverging;
  for (const char* engine : {"kane", "lagrange", "newton-euler"}) {
    const Outcome o = run_program("run '" + scene.string() + "' --engine " + engine + " --output '" +
                               out.string() + "'");
    INFO(engine << ": " << o.err);
    CHECK(o.status == 3);
    CHECK(o.err.find(std::string("engine ") + engine + " failed at t = ") != std::string::npos);
    CHECK((o.err.find("diverged") != std::string::npos || o.err.find("non-finite") != std::string::npos));
    CHECK_FALSE(fs::exists(out));
  }
  // A failed run leaves the previous file as it was.
  std::ofstream(out) << "previous\n";
  const Outcome o = run_program("run '" + scene.string() + "' --output '" + out.string() + "'");
  CHECK(o.status == 3);
  std::stringstream content;
  content << std::ifstream(out).rdbuf();
  CHECK(content.str() == "previous\n");
  CHECK(std::distance(fs::directory_iterator(dir), fs::directory_iterator()) == 2);  // no temporaries
  fs::remove_all(dir);
}

TEST_CASE("unknown engines, integrators and options are clear errors with exit status 2") {
  const std::string scene = "'" + test::scene_path("spear1_case1") + "'";
  Outcome o = run_program("run " + scene + " --engine hamilton");
  CHECK(o.status == 2);
  CHECK(o.err.find("unknown engine 'hamilton'") != std::string::npos);
  o = run_program("run " + scene + " --integrator euler");
  CHECK(o.status == 2);
  CHECK(o.err.find("unknown integrator 'euler'") != std::string::npos);
  o = run_program("run " + scene + " --frobnicate");
  CHECK(o.status == 2);
  CHECK(o.err.find("frobnicate") != std::string::npos);
  o = run_program("run '/nonexistent/scene.yaml'");
  CHECK(o.status == 2);
  CHECK(o.err.find("/nonexistent/scene.yaml") != std::string::npos);
  o = run_program("");
  CHECK(o.status == 2);
}

TEST_CASE("--help explains every run option") {
  const Outcome o = run_program("run --help");
  CHECK(o.status == 0);
  for (const char* option : {"--engine", "--integrator", "--rtol", "--atol", "--dt", "--output",
                             "--stabilization", "--baumgarte-alpha", "--no-rechart"})
    CHECK(o.out.find(option) != std::string::npos);
}

TEST_CASE("Ctrl-C ends a long run cleanly: status 130, a message, and no output file") {
  const fs::path dir = fs::temp_directory_path() / ("crossdyn_sigint_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path out = dir / "out.csv", err = dir / "err", status = dir / "status";
  // A run of a million seconds, interrupted after half a second.
  std::ostringstream cmd;
  cmd << "'" << test::binary_dir() << "/crossdyn' run '" << test::scene_path("chain5")
      << "' --duration 1e6 --output-step 10 --output '" << out.string() << "' 2> '" << err.string()
      << "' & pid=$!; sleep 0.5; kill -INT $pid; wait $pid; echo $? > '" << status.string() << "'";
  REQUIRE(std::system(cmd.str().c_str()) == 0);  // std::system runs the line with sh -c
  std::stringstream code, message;
  code << std::ifstream(status).rdbuf();
  message << std::ifstream(err).rdbuf();
  INFO(message.str());
  CHECK(std::stoi(code.str()) == 130);
  CHECK(message.str().find("interrupted") != std::string::npos);
  CHECK_FALSE(fs::exists(out));
  CHECK(std::distance(fs::directory_iterator(dir), fs::directory_iterator()) == 2);  // err, status
  fs::remove_all(dir);
}
