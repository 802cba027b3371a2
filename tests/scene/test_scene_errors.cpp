// Scene validation (issue 6): one case per class of error. Each starts from a small valid scene,
// breaks one thing, and asserts that read_scene_text throws InputError whose message starts
// "bad.yaml:<line>:" (the line of the offending text), names the key path and says what is wrong.
#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "tests/scene/system_equal.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>
#include <sys/wait.h>
#include <unistd.h>

using namespace crossdyn;

namespace {

const std::string kBase = R"(name: tiny
bodies:
  - name: hub
    mass: 100 kg
    inertia: [10, 20, 25]
  - name: arm
    mass: 5 kg
    inertia: [1, 1, 1]
joints:
  - name: base
    type: free
    child: hub
    initial:
      angular_velocity: [0, 0, 1]
  - name: hinge
    type: revolute
    parent: hub
    child: arm
    parent_point: [1, 0, 0]
    child_point: [-1, 0, 0]
    axis: [0, 0, 1]
    initial: {angle: 0, rate: 0.1}
run:
  duration: 10 s
  output_step: 0.1 s
)";

// kBase with `from` (which must occur exactly once) replaced by `to`.
std::string edit(const std::string& from, const std::string& to, const std::string& base = kBase) {
  const std::size_t at = base.find(from);
  REQUIRE(at != std::string::npos);
  REQUIRE(base.find(from, at + 1) == std::string::npos);
  return base.substr(0, at) + to + base.substr(at + from.size());
}

// 1-based line of the first occurrence of `needle` in `text`.
int line_of(const std::string& text, const std::string& needle) {
  const std::size_t at = text.find(needle);
  REQUIRE(at != std::string::npos);
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

// The same scene through the program: `crossdyn run FILE --output OUT` must exit with status 2,
// print a message naming the file, the line and the key on stderr, and create no output file.
void expect_cli_rejects(const std::string& text, int line, const std::string& key) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("crossdyn_cli_errors_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path scene = dir / "bad.yaml", out = dir / "out.csv", err = dir / "stderr.txt";
  std::ofstream(scene) << text;
  std::ostringstream cmd;  // (a stream: GCC 12 warns falsely on chained string concatenation)
  cmd << "'" << test::binary_dir() << "/crossdyn' run '" << scene.string() << "' --output '"
      << out.string() << "' 2> '" << err.string() << "'";
  const int status = std::system(cmd.str().c_str());
  std::stringstream message;
  message << std::ifstream(err).rdbuf();
  INFO("crossdyn printed: " << message.str());
  CHECK(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 2);
  CHECK(message.str().find(scene.string() + ":" + std::to_string(line) + ":") != std::string::npos);
  CHECK(message.str().find(key) != std::string::npos);
  CHECK_FALSE(fs::exists(out));
  fs::remove_all(dir);
}

// Asserts the scene is rejected with a message "bad.yaml:<line>:<column>: ..." that contains
// `key` and `phrase`, by the reader and by the program (expect_cli_rejects).
void expect_error(const std::string& text, int line, const std::string& key,
                  const std::string& phrase) {
  INFO(text);
  try {
    (void)read_scene_text(text, "bad.yaml");
    FAIL("the scene was accepted");
  } catch (const InputError& e) {
    const std::string message = e.what();
    INFO(message);
    CHECK(message.rfind("bad.yaml:" + std::to_string(line) + ":", 0) == 0);
    CHECK(message.find(key) != std::string::npos);
    CHECK(message.find(phrase) != std::string::npos);
  }
  expect_cli_rejects(text, line, key == "bad.yaml" ? "" : key);
}

// Replace `from` by `to` and expect an error at the line of `to`'s first line.
void expect_edit_error(const std::string& from, const std::string& to, const std::string& key,
                       const std::string& phrase, const std::string& line_marker = "") {
  const std::string text = edit(from, to);
  expect_error(text, line_of(text, line_marker.empty() ? to : line_marker), key, phrase);
}

}  // namespace

TEST_CASE("the base scene of these tests is valid") {
  const System s = read_scene_text(kBase, "bad.yaml");
  CHECK(s.joints.size() == 2);
}

TEST_CASE("errors: malformed YAML names the position") {
  expect_error(edit("inertia: [10, 20, 25]", "inertia: [10, 20, 25"), 6, "bad.yaml",
               "malformed YAML");
  // yaml-cpp reports where it notices the flow mapping is not closed.
  expect_error(edit("run:", "run: {duration: 1"), 24, "bad.yaml",
               "malformed YAML: end of map flow not found");
}

TEST_CASE("errors: unknown keys, with a suggestion for typos") {
  expect_edit_error("    inertia: [10, 20, 25]", "    inertai: [10, 20, 25]", "bodies[0].inertai",
                    "did you mean 'inertia'?");
  expect_edit_error("    inertia: [1, 1, 1]", "    inertia: [1, 1, 1]\n    flexibel: {}",
                    "bodies[1].flexibel", "unknown key 'flexibel' in a body (did you mean "
                    "'flexible'?)", "flexibel");
  expect_edit_error("name: tiny", "name: tiny\ndurationn: 1", "durationn", "unknown key",
                    "durationn");
  expect_edit_error("  duration: 10 s", "  duraton: 10 s", "run.duraton",
                    "did you mean 'duration'?");
}

TEST_CASE("errors: duplicate keys") {
  expect_edit_error("    mass: 5 kg", "    mass: 5 kg\n    mass: 6 kg", "bodies[1].mass",
                    "duplicate key 'mass'", "mass: 6 kg");
}

TEST_CASE("errors: missing required keys") {
  // Reported at the mapping that lacks the key.
  expect_edit_error("  - name: arm\n    mass: 5 kg\n", "  - name: arm\n", "bodies[1]",
                    "missing required key 'mass'", "  - name: arm");
  expect_edit_error("    axis: [0, 0, 1]\n", "", "joints[1]", "missing required key 'axis'",
                    "  - name: hinge");
  expect_error(edit("name: tiny\n", ""), 1, "the scene", "missing required key 'name'");
  expect_edit_error("  output_step: 0.1 s\n", "", "run", "missing required key 'output_step'",
                    "  duration");
}

TEST_CASE("errors: wrong types") {
  expect_edit_error("run:\n  duration: 10 s\n  output_step: 0.1 s\n", "run: [10, 0.1]\n", "run",
                    "expected the run block (a mapping of keys), found a list");
  expect_edit_error("joints:\n", "joints:\n  - just a joint\n", "joints[0]",
                    "expected a joint (a mapping of keys)", "  - just");
  expect_edit_error("    mass: 100 kg", "    mass: [100]", "bodies[0].mass", "expected a mass");
  expect_edit_error("    mass: 100 kg", "    mass: heavy", "bodies[0].mass", "found 'heavy'");
  expect_edit_error("      angular_velocity: [0, 0, 1]", "      angular_velocity: [0, 1]",
                    "joints[0].initial.angular_velocity", "found 2 elements");
  expect_edit_error("    inertia: [10, 20, 25]", "    inertia: [10, 20, 25, 1]",
                    "bodies[0].inertia", "6 numbers (xx, yy, zz, xy, xz, yz)");
  expect_edit_error("  - name: arm", "  - name: [arm]", "bodies[1].name",
                    "expected body name, found a list");
  expect_edit_error("    mass: 100 kg", "    mass:", "bodies[0].mass", "found no value");
}

TEST_CASE("errors: non-finite and absurd numbers") {
  expect_edit_error("    mass: 5 kg", "    mass: .nan", "bodies[1].mass", "non-finite");
  expect_edit_error("    mass: 5 kg", "    mass: -.inf", "bodies[1].mass", "non-finite");
  expect_edit_error("    mass: 5 kg", "    mass: 1e999", "bodies[1].mass", "out of range");
  expect_edit_error("    parent_point: [1, 0, 0]", "    parent_point: [1e13, 0, 0]",
                    "joints[1].parent_point", "absurd value");
  expect_edit_error("    mass: 5 kg", "    mass: 2e9 kg", "bodies[1].mass", "absurd mass");
}

TEST_CASE("errors: zero or negative mass") {
  expect_edit_error("    mass: 5 kg", "    mass: 0 kg", "bodies[1].mass", "mass must be positive");
  expect_edit_error("    mass: 5 kg", "    mass: -5 kg", "bodies[1].mass", "mass must be positive");
}

TEST_CASE("errors: inertia not symmetric positive definite, or violating the triangle inequality") {
  expect_edit_error("    inertia: [1, 1, 1]", "    inertia: [1, 1, 0]", "bodies[1].inertia",
                    "not positive definite");
  expect_edit_error("    inertia: [1, 1, 1]", "    inertia: [1, 1, -1]", "bodies[1].inertia",
                    "not positive definite");
  expect_edit_error("    inertia: [1, 1, 1]", "    inertia: [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]",
                    "bodies[1].inertia", "not symmetric");
  expect_edit_error("    inertia: [10, 20, 25]", "    inertia: [10, 20, 31]", "bodies[0].inertia",
                    "triangle inequality");
  // Products of inertia that make it indefinite: eigenvalues of [[1, 2], [2, 1]] are -1 and 3.
  expect_edit_error("    inertia: [1, 1, 1]", "    inertia: [1, 1, 1, 2, 0, 0]",
                    "bodies[1].inertia", "not positive definite");
  // The triangle inequality's boundary (a thin plate) is accepted.
  CHECK_NOTHROW(read_scene_text(edit("inertia: [10, 20, 25]", "inertia: [10, 20, 30]"), "ok.yaml"));
}

TEST_CASE("errors: zero axis") {
  expect_edit_error("    axis: [0, 0, 1]", "    axis: [0, 0, 0]", "joints[1].axis", "zero axis");
  expect_edit_error("      angular_velocity: [0, 0, 1]",
                    "      attitude: {axis: [0, 0, 0], angle: 1}",
                    "joints[0].initial.attitude.axis", "zero axis");
}

TEST_CASE("errors: duplicate body or joint names") {
  expect_error(edit("  - name: arm", "  - name: hub"), 6, "bodies[1].name",
               "duplicate body name 'hub' (first at line 3)");
  expect_error(edit("  - name: hinge", "  - name: base"), 15, "joints[1].name",
               "duplicate joint name 'base'");
  expect_error(edit("  - name: hinge", "  - name: arm"), 15, "joints[1].name", "also a body name");
}

TEST_CASE("errors: a joint naming an unknown body") {
  expect_edit_error("    child: arm", "    child: amr", "joints[1].child",
                    "unknown body 'amr' (did you mean 'arm'?)");
  expect_edit_error("    parent: hub", "    parent: nobody", "joints[1].parent",
                    "unknown body 'nobody'");
}

TEST_CASE("errors: topology") {
  const std::string third_body =
      edit("joints:", "  - name: tip\n    mass: 1\n    inertia: [1, 1, 1]\njoints:");
  const std::string hinge2 =
      "  - name: hinge2\n    type: revolute\n    parent: PARENT\n    child: CHILD\n    "
      "parent_point: [1, 0, 0]\n"
      "    child_point: [0, 0, 0]\n    axis: [0, 0, 1]\n";
  auto with_hinge2 = [&](const std::string& parent, const std::string& child) {
    return edit("run:", edit("CHILD", child, edit("PARENT", parent, hinge2)) + "run:", third_body);
  };
  SECTION("a body with two parents") {
    const std::string text = with_hinge2("hub", "arm");
    expect_error(text,
                 line_of(text, "    child: arm\n    parent_point: [1, 0, 0]\n    child_point: [0"),
                 "joints[2].child", "already has a parent joint 'hinge'");
  }
  SECTION("a body without a joint") {
    expect_error(third_body, line_of(third_body, "  - name: tip"), "bodies[2]",
                 "body 'tip' has no joint");
  }
  SECTION("a joint connecting a body to itself") {
    const std::string text = with_hinge2("tip", "tip");
    expect_error(text, line_of(text, "    parent: tip"), "joints[2].parent", "to itself");
  }
  SECTION("a cycle, which leaves bodies not connected to the base") {
    // hinge: hub -> arm; make arm's parent tip and tip's parent arm: arm -> tip -> arm.
    std::string text = with_hinge2("arm", "tip");
    text = edit("    parent: hub\n    child: arm", "    parent: tip\n    child: arm", text);
    expect_error(text, line_of(text, "    parent: tip"), "joints[1].parent",
                 "not connected to the base body 'hub'");
    expect_error(text, line_of(text, "    parent: tip"), "joints[1].parent",
                 "cycle of parents (arm -> tip -> arm)");
  }
  SECTION("no free joint") {
    const std::string text =
        edit("    type: free\n    child: hub\n    initial:\n      angular_velocity: [0, 0, 1]",
             "    type: revolute\n    parent: arm\n    child: hub\n    parent_point: [0, 0, 0]\n"
             "    child_point: [0, 0, 0]\n    axis: [1, 0, 0]");
    expect_error(text, line_of(text, "  - name: base"), "joints", "no free joint");
  }
  SECTION("more than one free joint") {
    const std::string text =
        edit("run:", "  - {name: base2, type: free, child: tip}\nrun:", third_body);
    expect_error(text, line_of(text, "base2"), "joints[2].type",
                 "a second free joint (the first is 'base')");
  }
}

TEST_CASE("errors: keys and initial conditions a joint type does not have") {
  expect_edit_error("    type: free\n    child: hub",
                    "    type: free\n    parent: arm\n    child: hub", "joints[0].parent",
                    "'parent' does not apply to a free joint", "    parent: arm");
  expect_edit_error("    initial: {angle: 0, rate: 0.1}",
                    "    initial: {angle: 0, angular_velocity: [0, 0, 1]}",
                    "joints[1].initial.angular_velocity", "initial conditions of a revolute joint");
  // The same scene with type fixed:
  std::string fixed = edit("    type: revolute", "    type: fixed");
  fixed = edit("    axis: [0, 0, 1]\n", "", fixed);
  expect_error(fixed, line_of(fixed, "    initial: {angle"), "joints[1].initial",
               "no initial conditions");
  expect_edit_error("      angular_velocity: [0, 0, 1]", "      angle: 1",
                    "joints[0].initial.angle", "initial conditions of a free joint");
  // The base velocity is derived when zero_linear_momentum holds.
  expect_edit_error("      angular_velocity: [0, 0, 1]", "      velocity: [1, 0, 0]",
                    "joints[0].initial.velocity", "zero_linear_momentum");
}

TEST_CASE("errors: unknown units and units of the wrong dimension") {
  expect_edit_error("    mass: 5 kg", "    mass: 5 kgs", "bodies[1].mass",
                    "unknown unit 'kgs' (did you mean 'kg'?)");
  expect_edit_error("  duration: 10 s", "  duration: 10 deg", "run.duration",
                    "unit 'deg' is an angle, but this key expects a time");
  expect_edit_error("    initial: {angle: 0, rate: 0.1}", "    initial: {angle: 0, rate: 0.1 rad}",
                    "joints[1].initial.rate", "expects an angular rate");
  expect_edit_error("      angular_velocity: [0, 0, 1]",
                    "      angular_velocity: {value: [0, 0, 1], unit: m/s}",
                    "joints[0].initial.angular_velocity.unit", "is a velocity");
  expect_edit_error("      angular_velocity: [0, 0, 1]", "      attitude: [1 deg, 0, 0, 0]",
                    "joints[0].initial.attitude[0]", "takes no unit");
}

TEST_CASE("errors: run block") {
  expect_edit_error("  duration: 10 s", "  duration: 0 s", "run.duration",
                    "duration must be positive");
  expect_edit_error("  output_step: 0.1 s", "  output_step: -0.1 s", "run.output_step",
                    "output_step must be positive");
  expect_edit_error("  output_step: 0.1 s", "  output_step: 20 s", "run.output_step",
                    "longer than the duration");
  expect_edit_error("  output_step: 0.1 s", "  output_step: 0.1 s\n  integrator: rk45",
                    "run.integrator", "unknown integrator 'rk45'", "  integrator");
  expect_edit_error("  output_step: 0.1 s", "  output_step: 0.1 s\n  rtol: -1e-9", "run.rtol",
                    "negative tolerance", "  rtol");
  expect_edit_error("  output_step: 0.1 s", "  output_step: 0.1 s\n  dt: 0", "run.dt",
                    "dt must be positive", "  dt");
  expect_edit_error("  output_step: 0.1 s", "  output_step: 1e-7 s", "run.output_step",
                    "output rows");
}

TEST_CASE("errors: compare block") {
  const std::string text = kBase + "compare:\n  tolerances:\n    H: {atol: -1}\n";
  expect_error(text, line_of(text, "    H:"), "compare.tolerances.H.atol", "negative tolerance");
  const std::string excl = kBase + "compare:\n  exclude:\n    - {quantity: E}\n";
  expect_error(excl, line_of(excl, "    - {quantity"), "compare.exclude[0]",
               "missing required key 'reason'");
}

TEST_CASE("errors: motor and torque profiles") {
  const std::string motor =
      "    motor:\n      profile:\n        - {t: 0, value: 1}\n        - {t: 2 s, value: 0}\n"
      "        - {t: 1 s, value: -1}\n";
  const std::string text = edit("    initial: {angle", motor + "    initial: {angle");
  expect_error(text, line_of(text, "{t: 1 s"), "joints[1].motor.profile[2].t",
               "times must increase strictly");
  expect_edit_error("    initial: {angle",
                    "    motor: {profile: [{t: -1, value: 1}]}\n    initial: {angle",
                    "joints[1].motor.profile[0].t", "negative", "    motor:");
  expect_edit_error("    initial: {angle",
                    "    motor: {profile: [{t: 0, value: [1, 0, 0]}]}\n    initial: {angle",
                    "joints[1].motor.profile[0].value", "expected a torque", "    motor:");
  expect_edit_error("    inertia: [1, 1, 1]",
                    "    inertia: [1, 1, 1]\n    torque: {frame: world, profile: []}",
                    "bodies[1].torque.frame", "unknown torque frame 'world'", "    torque");
}

// The reader skips its second YAML pass when the first document is certainly the only one (a
// block mapping in column 0 and no line that starts a directive, a document or a document end):
// every other way a second document can follow must still be refused where it starts.
TEST_CASE("errors: a second YAML document in every form, with or without the quick check") {
  const std::string phrase = "a second YAML document";
  // A document start, a document end followed by more text, a directive.
  expect_error(kBase + "---\nname: other\n", 26, "bad.yaml", phrase);
  expect_error(kBase + "...\nname: other\n", 27, "bad.yaml", phrase);
  expect_error(kBase + "%YAML 1.2\n---\nname: other\n", 27, "bad.yaml", phrase);
  // The whole scene indented: a key in column 0 after it ends the first document.
  std::string indented;
  for (std::size_t at = 0; at < kBase.size();) {
    const std::size_t end = kBase.find('\n', at);
    indented += "  " + kBase.substr(at, end - at + 1);
    at = end + 1;
  }
  expect_error(indented + "extra: 1\n", 26, "bad.yaml", phrase);
  // A flow mapping at the top, then another.
  expect_error("{name: tiny}\n{name: other}\n", 2, "bad.yaml", phrase);
  // Not a second document: an end marker alone, a "---" or "%" that is not at a line's start.
  CHECK(read_scene_text(kBase + "...\n", "bad.yaml").joints.size() == 2);
  CHECK(read_scene_text("---\n" + kBase, "bad.yaml").joints.size() == 2);
  CHECK(read_scene_text(edit("name: tiny", "name: tiny  # --- 100%"), "bad.yaml").joints.size() == 2);
  CHECK(read_scene_text(indented, "bad.yaml").joints.size() == 2);
}

TEST_CASE("errors: text-level guards before parsing") {
  expect_error(kBase + "---\nname: other\n", 26, "bad.yaml", "a second YAML document");
  expect_error(std::string("name: ti\xffny\n"), 1, "bad.yaml", "not valid UTF-8");
  expect_error(std::string("name: tiny\n\x01"), 2, "bad.yaml", "control character 1");
  expect_error("", 1, "bad.yaml", "the scene is empty");
  expect_error(std::string(2 << 20, ' '), 1, "bad.yaml", "larger than the limit of 1048576 bytes");
  // Deep nesting: yaml-cpp's own depth guard stops it; the reader turns it into an InputError.
  expect_error("name: " + std::string(100000, '['), 1, "bad.yaml", "nesting too deep");
  std::string dashes;
  for (int i = 0; i < 20000; ++i) dashes += "- ";
  expect_error(dashes + "x", 1, "bad.yaml", "nesting too deep");
  // Free text with control characters (by escape) and invalid names.
  expect_edit_error("name: tiny", "name: tiny\ndescription: \"a\\x01b\"", "description",
                    "control character", "description");
  expect_edit_error("name: tiny", "name: 1tiny", "name", "invalid scene name");
  expect_edit_error("  - name: arm", "  - name: arm.x", "bodies[1].name", "invalid body name");
  expect_edit_error("name: tiny", "name: tiny\nzero_linear_momentum: maybe", "zero_linear_momentum",
                    "expected true or false", "zero_linear");
  expect_edit_error("name: tiny", "name: tiny\nanalytic: torque-free", "analytic",
                    "single free rigid body", "analytic");
}

TEST_CASE("errors: files that cannot be read") {
  try {
    (void)read_scene("/nonexistent/scene.yaml");
    FAIL("accepted");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).rfind("/nonexistent/scene.yaml:1:1: cannot open", 0) == 0);
  }
}

TEST_CASE("errors: a scene file over the size limit") {
  const std::string path = test::binary_dir() + "/tests/scene/too_large.yaml";
  {
    std::ofstream out(path, std::ios::binary);
    out << "name: big\ndescription: |\n";
    for (int i = 0; i < 40000; ++i)
      out << "  a line of text that makes the scene file larger than one MiB\n";
  }
  try {
    (void)read_scene(path);
    FAIL("accepted");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).rfind(path + ":1:1: the scene is larger than the limit", 0) == 0);
  }
  std::remove(path.c_str());
}

// Prescribed joints (docs/prescribed-motion.md): one case per class of mistake.
TEST_CASE("errors: prescribed joints name the key and what is wrong") {
  const std::string prescribed = "    prescribed: {profile: spin-up, rate: 2 rad/s, ramp_time: 5 s}\n";
  const std::string with = edit("    initial: {angle: 0, rate: 0.1}\n", prescribed);
  CHECK(read_scene_text(with, "bad.yaml").joints[1].prescribed.has_value());
  // Loads on a prescribed joint: its torque is what the motion takes.
  for (const std::string load : {"spring: {stiffness: 1}", "damper: {damping: 1}",
                                 "motor: {profile: [{t: 0, value: 1}]}"}) {
    const std::string text = edit(prescribed, prescribed + "    " + load + "\n", with);
    expect_error(text, line_of(text, "    " + load), load.substr(0, load.find(':')),
                 "a prescribed joint takes no");
  }
  {  // An initial rate: the profile gives it.
    const std::string text = edit(prescribed, prescribed + "    initial: {rate: 1}\n", with);
    expect_error(text, line_of(text, "    initial: {rate: 1}"), "rate", "remove initial.rate");
  }
  {  // Bad profile values.
    const std::string text = edit("ramp_time: 5 s", "ramp_time: 0 s", with);
    expect_error(text, line_of(text, "ramp_time: 0 s"), "ramp_time", "must be positive");
    const std::string fast = edit("rate: 2 rad/s", "rate: 2e5 rad/s", with);
    expect_error(fast, line_of(fast, "rate: 2e5"), "rate", "at most 1e4 rad/s");
    const std::string word = edit("profile: spin-up", "profile: spin-down", with);
    expect_error(word, line_of(word, "spin-down"), "profile", "spin-up");
    // The schema's noun keeps its article for "expected a motion profile"; "unknown" drops it.
    expect_error(word, line_of(word, "spin-down"), "profile", "unknown motion profile 'spin-down'");
    const std::string frame = edit("      angular_velocity: [0, 0, 1]\n", "      angular_velocity: [0, 0, 1]\n      frame: body\n");
    expect_error(frame, line_of(frame, "frame: body"), "frame", "unknown frame 'body'");
  }
  // A joint without a parent must be prescribed (it then holds the base, replacing the free
  // joint); a missing parent on any other joint is the old error with the reason.
  expect_edit_error("    parent: hub\n", "", "joints[1]", "missing required key 'parent'",
                    "  - name: hinge");
}

TEST_CASE("a prescribed base: a revolute joint without a parent replaces the free joint") {
  const std::string base = R"(name: spin
bodies:
  - name: hub
    mass: 100 kg
    inertia: [10, 10, 10]
  - name: arm
    mass: 5 kg
    inertia: [1, 1, 1]
joints:
  - name: spin
    type: revolute
    child: hub
    parent_point: [0, 0, 1]
    axis: [0, 0, 1]
    child_point: [0, 0, 0]
    prescribed: {profile: spin-up, rate: 10 rad/s, ramp_time: 15 s}
  - name: hinge
    type: revolute
    parent: hub
    child: arm
    parent_point: [1, 0, 0]
    child_point: [-1, 0, 0]
    axis: [0, 0, 1]
run:
  duration: 10 s
  output_step: 0.1 s
)";
  const System s = read_scene_text(base, "bad.yaml");
  CHECK_FALSE(s.base_is_free());
  CHECK(s.joints[0].parent == -1);
  CHECK(s.joints[0].p_PoJ_P == Eigen::Vector3d(0, 0, 1));
  CHECK(s.breakpoints() == std::vector<double>{15.0});
  // Round trip: the writer leaves out the parent and writes the profile.
  const std::string written = write_scene_text(s);
  CHECK(written.find("prescribed") != std::string::npos);
  CHECK(test::system_difference(read_scene_text(written, "bad.yaml"), s).empty());
  // Not prescribed: a parent is required.
  {
    const std::string text = edit("    prescribed: {profile: spin-up, rate: 10 rad/s, ramp_time: 15 s}\n", "", base);
    expect_error(text, line_of(text, "  - name: spin"), "joints[0]", "missing required key 'parent'");
  }
  // Its parent is N, without nodes.
  {
    const std::string text = edit("    parent_point: [0, 0, 1]\n", "    parent_node: top\n", base);
    expect_error(text, line_of(text, "    parent_node: top"), "parent_node", "no nodes");
  }
}

namespace {

// The message of the InputError that reading `text` throws (a test failure when it is accepted).
std::string error_of(const std::string& text) {
  try {
    (void)read_scene_text(text, "bad.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  FAIL("the scene was accepted:\n" << text);
  return "";
}

std::vector<std::string> lines_of(const std::string& message) {
  std::vector<std::string> lines;
  std::istringstream in(message);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

}  // namespace

// yaml-cpp 0.7 cannot read "inertia: [10, 20, 25] kg m^2" (after ']' the value is over): it says
// "end of map not found" in a block mapping and "end of map flow not found" in a flow one. The
// reader names the key and what to write instead (docs/scene-format.md "Values").
TEST_CASE("errors: a unit after a list names the key and how to write it") {
  {  // Block mapping: the whole message, at the unit's line and column.
    const std::string text = edit("    inertia: [10, 20, 25]", "    inertia: [10, 20, 25] kg m^2");
    CHECK(error_of(text) ==
          "bad.yaml:5:27: bodies[0].inertia: a unit after a list is not read (YAML ends the value "
          "at ']'): write {value: [10, 20, 25], unit: kg m^2} (one unit for all) or [10 kg m^2, "
          "20 kg m^2, 25 kg m^2] (each element with its unit); a bare [10, 20, 25] is in kg m^2 "
          "(SI)");
    expect_error(text, 5, "bodies[0].inertia", "a unit after a list is not read");
  }
  // Block mapping, a point; and a unit written without a space.
  expect_edit_error("    parent_point: [1, 0, 0]", "    parent_point: [1, 0, 0] m",
                    "joints[1].parent_point",
                    "write {value: [1, 0, 0], unit: m} (one unit for all) or [1 m, 0 m, 0 m] (each "
                    "element with its unit); a bare [1, 0, 0] is in m (SI)");
  expect_edit_error("    child_point: [-1, 0, 0]", "    child_point: [-1, 0, 0]mm",
                    "joints[1].child_point", "{value: [-1, 0, 0], unit: mm}");
  // Flow mappings: the unit last, and followed by another key.
  expect_edit_error("    initial:\n      angular_velocity: [0, 0, 1]",
                    "    initial: {angular_velocity: [0, 0, 10] deg/s}",
                    "joints[0].initial.angular_velocity",
                    "a unit after a list is not read (YAML ends the value at ']'): write {value: "
                    "[0, 0, 10], unit: deg/s} (one unit for all) or [0 deg/s, 0 deg/s, 10 deg/s]");
  {  // In a mapping the reader does not read (an unknown key): reported at the key as written.
    const std::string text =
        edit("    parent_point: [1, 0, 0]\n    child_point: [-1, 0, 0]\n",
             "    points: {parent_point: [1, 0, 0] m, child_point: [-1, 0, 0] m}\n");
    const std::vector<std::string> lines = lines_of(error_of(text));
    INFO(error_of(text));
    REQUIRE(lines.size() == 5);
    CHECK(lines[0].rfind("bad.yaml:15:5: joints[1]: missing required key 'parent_point'", 0) == 0);
    CHECK(lines[1].rfind("bad.yaml:15:5: joints[1]: missing required key 'child_point'", 0) == 0);
    CHECK(lines[2].rfind("bad.yaml:19:5: joints[1].points: unknown key 'points'", 0) == 0);
    CHECK(lines[3].rfind("bad.yaml:19:38: parent_point: a unit after a list is not read", 0) == 0);
    CHECK(lines[4].rfind("bad.yaml:19:65: child_point: a unit after a list is not read", 0) == 0);
  }
  {  // The same in a flow joint, where both points are real keys: both reported.
    const std::string text = edit(
        "  - name: hinge\n    type: revolute\n    parent: hub\n    child: arm\n"
        "    parent_point: [1, 0, 0]\n    child_point: [-1, 0, 0]\n    axis: [0, 0, 1]\n"
        "    initial: {angle: 0, rate: 0.1}\n",
        "  - {name: hinge, type: revolute, parent: hub, child: arm, parent_point: [1, 0, 0] m,\n"
        "     child_point: [-1, 0, 0] m, axis: [0, 0, 1]}\n");
    const std::vector<std::string> lines = lines_of(error_of(text));
    INFO(error_of(text));
    REQUIRE(lines.size() == 2);
    CHECK(lines[0].rfind("bad.yaml:15:84: ", 0) == 0);
    CHECK(lines[0].find("joints[1].parent_point: a unit after a list is not read") !=
          std::string::npos);
    CHECK(lines[1].rfind("bad.yaml:16:30: ", 0) == 0);
    CHECK(lines[1].find("joints[1].child_point: a unit after a list is not read") !=
          std::string::npos);
  }
  // A key that takes bare numbers, the value of {value, unit}, a unit of the wrong kind, a
  // nested inertia (no element form), a profile.
  expect_edit_error("    axis: [0, 0, 1]", "    axis: [0, 0, 1] m", "joints[1].axis",
                    "a unit after a list is not read (YAML ends the value at ']'): this key takes "
                    "bare numbers, without a unit: write [0, 0, 1]");
  expect_edit_error("      angular_velocity: [0, 0, 1]",
                    "      angular_velocity: {value: [0, 0, 1] deg/s, unit: deg/s}",
                    "joints[0].initial.angular_velocity.value",
                    "write the unit in `unit`: {value: [0, 0, 1], unit: deg/s}");
  expect_edit_error("    parent_point: [1, 0, 0]", "    parent_point: [1, 0, 0] deg",
                    "joints[1].parent_point",
                    "; and 'deg' is an angle, but this key expects a length (m, mm, cm, km)");
  expect_edit_error("    inertia: [1, 1, 1]",
                    "    inertia: [[1, 0, 0], [0, 1, 0], [0, 0, 1]] g",
                    "bodies[1].inertia",
                    "write {value: [[1, 0, 0], [0, 1, 0], [0, 0, 1]], unit: g} (one unit for all); "
                    "a bare [[1, 0, 0], [0, 1, 0], [0, 0, 1]] is in kg m^2 (SI); and 'g' is a "
                    "mass");
  expect_edit_error("    inertia: [1, 1, 1]",
                    "    inertia: [1, 1, 1]\n    torque: {profile: [{t: 0, value: [0, 0, 1]}] N m}",
                    "bodies[1].torque.profile",
                    "write the unit with each value inside the list ({t: 2 s, value: 0.1 N m})",
                    "    torque:");
  {  // A YAML error after it stops the reading there; units before it are reported by their key
     // as written (no key path: the file was not read), the YAML error as yaml-cpp says it.
    const std::string text = edit("    inertia: [10, 20, 25]", "    inertia: [10, 20, 25] kg m^2",
                                  edit("run:", "run: {duration: 1"));
    const std::vector<std::string> lines = lines_of(error_of(text));
    REQUIRE(lines.size() == 2);
    CHECK(lines[0].rfind("bad.yaml:5:27: inertia: a unit after a list is not read", 0) == 0);
    CHECK(lines[1] == "bad.yaml:24:11: malformed YAML: end of map flow not found");
  }
  // Where no list belongs: what the key takes instead (and not also "found a list").
  {
    std::string text = edit("name: tiny\n", "name: tiny\ndescription: [draft] A hub\n");
    text = edit("    mass: 5 kg", "    mass: [5] kg", text);
    text = edit("  duration: 10 s", "  duration: 10 s\n  rtol: [1] e", text);
    const std::vector<std::string> lines = lines_of(error_of(text));
    INFO(error_of(text));
    REQUIRE(lines.size() == 3);
    CHECK(lines[0] == "bad.yaml:2:22: description: '[' begins a list in YAML, which ends at ']': "
                      "put the whole value in quotes, \"[draft] A hub\"");
    CHECK(lines[1] == "bad.yaml:8:15: bodies[1].mass: a list is not read here: this key takes one "
                      "number and its unit, 5 kg");
    CHECK(lines[2] == "bad.yaml:26:13: run.rtol: a list is not read here: this key takes one bare "
                      "number");
  }
  // What is not a unit after a list keeps yaml-cpp's message.
  expect_error(edit("    inertia: [10, 20, 25]", "    inertia: [10, 20, 25] 3"), 5, "bad.yaml",
               "malformed YAML: end of map not found");
  expect_error(edit("    inertia: [10, 20, 25]", "    inertia: [10, 20, 25]]"), 5, "bad.yaml",
               "malformed YAML: ");
  CHECK(error_of(edit("    inertia: [10, 20, 25]", "    inertia: [10, 20, 25] 3"))
            .find("unit after a list") == std::string::npos);
}

TEST_CASE("errors: units per degree, in mN m and angular accelerations are refused for another "
          "kind of key") {
  const std::string spring = "    axis: [0, 0, 1]\n    spring: {stiffness: 2 N m/deg}\n";
  CHECK(read_scene_text(edit("    axis: [0, 0, 1]\n", spring), "bad.yaml").joints[1].stiffness ==
        2 * (180 / std::numbers::pi));
  expect_edit_error("    axis: [0, 0, 1]\n",
                    "    axis: [0, 0, 1]\n    spring: {stiffness: 2 N m}\n",
                    "joints[1].spring.stiffness",
                    "unit 'N m' is a torque, but this key expects a rotational stiffness (N m/rad, "
                    "N m/deg, mN m/rad, mN m/deg, Nm/rad, Nm/deg, mNm/rad, mNm/deg)",
                    "    spring:");
  expect_edit_error("    axis: [0, 0, 1]\n",
                    "    axis: [0, 0, 1]\n    damper: {damping: 0.5 N m/deg}\n",
                    "joints[1].damper.damping",
                    "unit 'N m/deg' is a rotational stiffness, but this key expects a rotational "
                    "damping",
                    "    damper:");
  expect_edit_error("    axis: [0, 0, 1]\n",
                    "    axis: [0, 0, 1]\n    motor: {profile: [{t: 0, value: 5 mN m s/deg}]}\n",
                    "joints[1].motor.profile[0].value",
                    "unit 'mN m s/deg' is a rotational damping, but this key expects a torque "
                    "(N m, mN m, Nm, mNm)",
                    "    motor:");
  expect_edit_error("    initial: {angle: 0, rate: 0.1}",
                    "    initial: {angle: 0, rate: 2 deg/s^2}",
                    "joints[1].initial.rate",
                    "unit 'deg/s^2' is an angular acceleration, but this key expects an angular "
                    "rate (rad/s, deg/s, rpm)");
  expect_edit_error("    initial: {angle: 0, rate: 0.1}",
                    "    initial: {angle: 0, rate: 0.1}\n"
                    "    prescribed: {profile: spin-up, rate: 1 rad/s^2, ramp_time: 5 s}",
                    "joints[1].prescribed.rate", "is an angular acceleration, but this key "
                    "expects an angular rate", "    prescribed:");
  expect_edit_error("  duration: 10 s", "  duration: 10 mN m", "run.duration",
                    "unit 'mN m' is a torque, but this key expects a time");
}

// The reader goes on after an error whose cause does not touch the rest (each body, each joint,
// each key of a body, a joint and the run block), and reports them all, in file order.
TEST_CASE("errors: several errors in one file are reported together, in file order") {
  std::string text = edit("    mass: 100 kg", "    mass: -100 kg");
  text = edit("    mass: 5 kg", "    mas: 5 kg", text);
  text = edit("    axis: [0, 0, 1]", "    axis: [0, 0, 0]", text);
  text = edit("    initial: {angle: 0, rate: 0.1}", "    initial: {angle: 0, rate: 0.1 deg}", text);
  text = edit("  output_step: 0.1 s", "  output_step: 0.1 s\n  integrator: rk5", text);
  text = edit("  duration: 10 s", "  duration: 10 deg", text);
  text = edit("    parent_point: [1, 0, 0]", "    parent_point: [1, 0, 0] m", text);
  const std::string message = error_of(text);
  INFO(message);
  const std::vector<std::string> lines = lines_of(message);
  const std::vector<std::pair<std::string, std::string>> expected = {
      {"bad.yaml:4:11: bodies[0].mass: ", "mass must be positive, found -100 kg"},
      {"bad.yaml:7:5: bodies[1].mas: ", "unknown key 'mas' in a body (did you mean 'mass'?)"},
      {"bad.yaml:19:29: joints[1].parent_point: ", "a unit after a list is not read"},
      {"bad.yaml:21:11: joints[1].axis: ", "zero axis"},
      {"bad.yaml:22:31: joints[1].initial.rate: ", "unit 'deg' is an angle"},
      {"bad.yaml:24:13: run.duration: ", "unit 'deg' is an angle, but this key expects a time"},
      {"bad.yaml:26:15: run.integrator: ", "unknown integrator 'rk5'"},
  };
  REQUIRE(lines.size() == expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    CHECK(lines[i].rfind(expected[i].first, 0) == 0);
    CHECK(lines[i].find(expected[i].second) != std::string::npos);
  }
  // The program prints them all (the first after "crossdyn: error: ").
  expect_cli_rejects(text, 4, "bodies[0].mass");

  // At most 20, then how many more.
  std::string many = "name: many\nbodies:\n";
  for (int i = 0; i < 25; ++i)
    many += "  - {name: b" + std::to_string(i) + ", mass: -1, inertia: [1, 1, 1]}\n";
  many += "joints:\n  - {name: base, type: free, child: b0}\n"
          "run: {duration: 1, output_step: 0.1}\n";
  const std::vector<std::string> capped = lines_of(error_of(many));
  REQUIRE(capped.size() == 21);
  CHECK(capped[0].rfind("bad.yaml:3:", 0) == 0);
  CHECK(capped[19].rfind("bad.yaml:22:", 0) == 0);
  CHECK(capped[20] == "... and 5 more errors");
}

TEST_CASE("errors: what depends on an error is not reported with it") {
  // A YAML syntax error stops at the first.
  {
    std::string text = edit("inertia: [10, 20, 25]", "inertia: [10, 20, 25");
    text = edit("run:", "run: {duration: 1", text);
    CHECK(lines_of(error_of(text)).size() == 1);
  }
  // A body with errors keeps its name: the joint naming it is read, not "unknown body".
  {
    const std::string text = edit("    mass: 5 kg", "    mass: 5 kg\n    color: red");
    const std::vector<std::string> lines = lines_of(error_of(text));
    REQUIRE(lines.size() == 1);
    CHECK(lines[0].find("bodies[1].color: unknown key") != std::string::npos);
  }
  // A mistyped key is unknown, not also a missing one; every key of the mapping is checked.
  {
    std::string text = edit("    mass: 5 kg", "    mas: 5 kg\n    color: red");
    text = edit("    inertia: [1, 1, 1]", "    inertia: [1, 1, -1]", text);
    const std::vector<std::string> lines = lines_of(error_of(text));
    INFO(error_of(text));
    REQUIRE(lines.size() == 3);
    CHECK(lines[0].rfind("bad.yaml:7:5: bodies[1].mas: unknown key 'mas' in a body (did you mean "
                         "'mass'?)", 0) == 0);
    CHECK(lines[1].rfind("bad.yaml:8:5: bodies[1].color: unknown key 'color'", 0) == 0);
    CHECK(lines[2].rfind("bad.yaml:9:14: bodies[1].inertia: inertia is not positive definite", 0) ==
          0);
    // A mistyped `flexible`: not also the mass and inertia of a rigid body.
    const std::string flexibel =
        edit("    mass: 5 kg\n    inertia: [1, 1, 1]\n",
             "    flexibel: {beam: {length: 1 m, mass_per_length: 1, section: [0.1, 0.1, 0]}}\n");
    const std::vector<std::string> flex_lines = lines_of(error_of(flexibel));
    INFO(error_of(flexibel));
    REQUIRE(flex_lines.size() == 1);
    CHECK(flex_lines[0].find("bodies[1].flexibel: unknown key 'flexibel' in a body (did you mean "
                             "'flexible'?)") != std::string::npos);
    // Keys of another joint type, each.
    const std::string ball = edit("    type: revolute", "    type: spherical");
    const std::vector<std::string> joint_lines = lines_of(error_of(ball));
    INFO(error_of(ball));
    REQUIRE(joint_lines.size() == 3);
    CHECK(joint_lines[0].find("joints[1].axis: 'axis' does not apply to a spherical joint") !=
          std::string::npos);
    CHECK(joint_lines[1].find("joints[1].initial.angle: unknown key 'angle' in the initial "
                              "conditions of a spherical joint") != std::string::npos);
    CHECK(joint_lines[2].find("joints[1].initial.rate: unknown key 'rate'") != std::string::npos);
  }
  // A body without a readable name: a joint naming a body that is not found is not an error
  // of its own (it may name that body); its other errors are.
  {
    std::string text = edit("  - name: arm\n", "  - name: 1arm\n");
    text = edit("    axis: [0, 0, 1]", "    axis: [0, 0, 0]", text);
    const std::vector<std::string> lines = lines_of(error_of(text));
    REQUIRE(lines.size() == 3);
    CHECK(lines[0].find("bodies[1].name: invalid body name '1arm'") != std::string::npos);
    CHECK(lines[1].find("joints[1].child: invalid body name") == std::string::npos);
    CHECK(lines[2].find("joints[1].axis: zero axis") != std::string::npos);
  }
  // A flexible body whose block has an error: a joint at one of its nodes is not checked.
  {
    const std::string text =
        edit("  - name: arm\n    mass: 5 kg\n    inertia: [1, 1, 1]\n",
             "  - name: arm\n    flexible:\n      beam: {length: 0 m, mass_per_length: 1, "
             "section: [0.1, 0.1, 0], bending: {x: {modes: 1, EI: 10}}}\n",
             edit("    child_point: [-1, 0, 0]", "    child_node: bottom"));
    const std::vector<std::string> lines = lines_of(error_of(text));
    INFO(error_of(text));
    REQUIRE(lines.size() == 1);
    CHECK(lines[0].find("bodies[1].flexible.beam.length") != std::string::npos);
  }
  // The topology is checked only when nothing else is wrong: a joint joining a body to itself
  // and a negative mass report the mass alone.
  {
    std::string text = edit("    child: arm\n", "    child: hub\n");
    CHECK(error_of(text).find("connects body 'hub' to itself") != std::string::npos);
    text = edit("    mass: 100 kg", "    mass: -100 kg", text);
    const std::vector<std::string> lines = lines_of(error_of(text));
    REQUIRE(lines.size() == 1);
    CHECK(lines[0].find("bodies[0].mass: mass must be positive") != std::string::npos);
  }
}

// Prismatic and universal joints (issue 25): one case per class of mistake, each at its key.
TEST_CASE("errors: prismatic and universal joints name the key and what is wrong") {
  const std::string hinge =
      "    type: revolute\n    parent: hub\n    child: arm\n    parent_point: [1, 0, 0]\n"
      "    child_point: [-1, 0, 0]\n    axis: [0, 0, 1]\n    initial: {angle: 0, rate: 0.1}\n";
  const std::string slider =
      "    type: prismatic\n    parent: hub\n    child: arm\n    parent_point: [1, 0, 0]\n"
      "    child_point: [-1, 0, 0]\n    axis: [1, 0, 0]\n";
  const std::string gimbal =
      "    type: universal\n    parent: hub\n    child: arm\n    parent_point: [1, 0, 0]\n"
      "    child_point: [-1, 0, 0]\n    axis: [1, 0, 0]\n    axis2: [0, 1, 0]\n";
  const std::string with_slider = edit(hinge, slider), with_gimbal = edit(hinge, gimbal);
  {
    const System s = read_scene_text(with_slider + "", "bad.yaml");
    CHECK(s.joints[1].type == JointType::Prismatic);
    CHECK(s.joints[1].dof() == 1);
    const System g = read_scene_text(with_gimbal, "bad.yaml");
    CHECK(g.joints[1].type == JointType::Universal);
    CHECK(g.joints[1].dof() == 2);
  }
  auto add = [](const std::string& base, const std::string& line) {
    return base.substr(0, base.find("run:")) + line + "\n" + base.substr(base.find("run:"));
  };
  auto expect_added = [&](const std::string& base, const std::string& line, const std::string& key,
                          const std::string& phrase) {
    const std::string text = add(base, line);
    expect_error(text, line_of(text, line), key, phrase);
  };
  // Units of the joint's own kind: a prismatic spring in N/m, not N m/rad.
  expect_added(with_slider, "    spring: {stiffness: 2 N m/rad}", "stiffness", "N/m");
  expect_added(with_slider, "    spring: {stiffness: -2}", "stiffness", "negative stiffness");
  expect_added(with_slider, "    damper: {damping: 1 N m s/rad}", "damping", "N s/m");
  expect_added(with_slider, "    initial: {position: 10 deg}", "position", "length");
  expect_added(with_slider, "    spring: {stiffness: 1, neutral_angle: 0.1}", "neutral_angle",
               "neutral_position");
  expect_added(with_slider, "    axis2: [0, 1, 0]", "axis2", "prismatic");
  // A universal joint's values are pairs; its axes are not parallel.
  expect_added(with_gimbal, "    spring: {stiffness: 2}", "stiffness", "2 numbers");
  expect_added(with_gimbal, "    damper: {damping: [1, 2, 3]}", "damping", "found 3 elements");
  expect_added(with_gimbal, "    spring: {stiffness: [1, -1]}", "stiffness", "negative stiffness");
  expect_added(with_gimbal, "    motor: {profile: [{t: 0, value: 1}]}", "value", "2 numbers");
  expect_added(with_gimbal, "    prescribed: {profile: deploy, travel: 1, ramp_time: 1}",
               "prescribed", "universal");
  {
    const std::string text = edit("axis2: [0, 1, 0]", "axis2: [1, 0.001, 0]", with_gimbal);
    expect_error(text, line_of(text, "axis2: [1, 0.001"), "axis2", "at least 1 deg apart");
    const std::string missing = edit("    axis2: [0, 1, 0]\n", "", with_gimbal);
    expect_error(missing, line_of(missing, "  - name: hinge"), "axis2", "missing required key");
  }
  // Not at a node yet: said at the key, with the way out.
  expect_added(with_slider, "    child_node: tip", "child_node", "child_point");
  // Prescribed profiles: each takes its own value, in the joint's units.
  expect_added(with_slider, "    prescribed: {profile: deploy, ramp_time: 5 s}", "travel",
               "missing required key 'travel'");
  expect_added(with_slider, "    prescribed: {profile: deploy, rate: 1 m/s, ramp_time: 5 s}",
               "rate", "takes `travel`");
  expect_added(with_slider, "    prescribed: {profile: spin-up, travel: 1 m, ramp_time: 5 s}",
               "travel", "takes `rate`");
  expect_added(with_slider, "    prescribed: {profile: deploy, travel: 90 deg, ramp_time: 5 s}",
               "travel", "length");
  expect_added(with_slider, "    prescribed: {profile: deploy, travel: 2e7 m, ramp_time: 5 s}",
               "travel", "at most 1e6 m");
  {
    const std::string text = add(with_slider, "    prescribed: {profile: deploy, travel: 1 m, "
                                              "ramp_time: 5 s}\n    motor: {profile: [{t: 0, value: 1}]}");
    expect_error(text, line_of(text, "    motor:"), "motor", "force (output <joint>.force)");
  }
  // A prismatic joint cannot hold the base (only a prescribed revolute joint may leave out its
  // parent).
  {
    const std::string text =
        edit("    parent: hub\n", "", add(with_slider, "    prescribed: {profile: deploy, "
                                                     "travel: 1 m, ramp_time: 5 s}"));
    expect_error(text, line_of(text, "  - name: hinge"), "parent", "missing required key 'parent'");
  }
  // A deploy profile on a revolute joint is an angle.
  {
    const std::string text = add(kBase, "    prescribed: {profile: deploy, travel: 2 m, ramp_time: 5 s}");
    const std::string no_rate = edit("    initial: {angle: 0, rate: 0.1}\n", "", text);
    expect_error(no_rate, line_of(no_rate, "travel: 2 m"), "travel", "angle");
  }
}

// Issue 28: the environment block's bad values, each refused at its key with what is wrong.
TEST_CASE("errors: the environment block (gravity, central body, orbit, frame: lvlh)") {
  const std::string env = "name: tiny\nenvironment:\n";
  auto with = [&](const std::string& block) { return edit("name: tiny\n", env + block); };
  // Both fields; an orbit without a body; a body without an orbit; an empty block.
  expect_error(with("  gravity: [0, 0, -9.81]\n  central_body: {mu: 4e14}\n"), 4,
               "environment.central_body", "not both");
  expect_error(with("  orbit: {radius: 7000 km}\n"), 3, "environment.orbit", "needs a `central_body`");
  expect_error(with("  central_body: {mu: 4e14}\n"), 3, "environment", "orbit");
  expect_error(edit("name: tiny\n", "name: tiny\nenvironment: {}\n"), 2, "environment", "empty");
  // Values: mu, radii, altitude, inclination; a unit of the wrong kind.
  expect_error(with("  central_body: {mu: -4e14}\n  orbit: {radius: 7000 km}\n"), 3,
               "environment.central_body.mu", "must be > 0");
  expect_error(with("  central_body: {mu: 4e14, radius: 6378 km}\n  orbit: {radius: 6000 km}\n"), 4,
               "environment.orbit.radius", "exceed the central body's radius");
  expect_error(with("  central_body: {mu: 4e14}\n  orbit: {altitude: 500 km}\n"), 4,
               "environment.orbit.altitude", "needs the central body's `radius`");
  expect_error(with("  central_body: {mu: 4e14, radius: 6378 km}\n  orbit: {altitude: 500 km, radius: 7000 km}\n"),
               4, "environment.orbit.altitude", "not both");
  expect_error(with("  central_body: {mu: 4e14}\n  orbit: {radius: 7000 km, inclination: 200 deg}\n"), 4,
               "environment.orbit.inclination", "between 0 and 180 deg");
  expect_error(with("  central_body: {mu: 4e14}\n  orbit: {inclination: 10 deg}\n"), 4, "environment.orbit",
               "radius");
  expect_error(with("  gravity: {value: [0, 0, -9.81], unit: m/s}\n"), 3, "environment.gravity",
               "this key expects an acceleration");
  expect_error(with("  central_body: {mu: 4e14 kg}\n  orbit: {radius: 7000 km}\n"), 3,
               "environment.central_body.mu", "gravitational parameter");
  expect_error(with("  gravity: [0, 0, -9.81]\n  orbitt: {}\n"), 4, "environment.orbitt", "did you mean 'orbit'");
  // frame: lvlh needs an orbit.
  expect_edit_error("      angular_velocity: [0, 0, 1]", "      angular_velocity: [0, 0, 1]\n      frame: lvlh",
                    "joints[0].initial.frame", "no orbit", "      frame: lvlh");
}
