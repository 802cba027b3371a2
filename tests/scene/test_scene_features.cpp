// Conveniences of the scene format (issue 10 item 4): center_of_mass in a body's own frame, a
// rotation matrix as an offset, and the warning for a bare angle above 2 pi, through the reader
// and through the program.
#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "tests/harness/run_program.hpp"
#include "tests/scene/system_equal.hpp"
#include "tests/support/close.hpp"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <numbers>

using namespace crossdyn;

namespace {

constexpr double kPi = std::numbers::pi;

// A hub with its CM at (0, 0, 1) of its frame, a panel hinged at (0.5, 0, 1) of the hub's frame
// whose CM is 1.5 m from the hinge, and a tip on the panel. Every value is exact in binary, so
// the shifted points can be compared bit for bit.
const std::string kWithCenters = R"(name: centers
bodies:
  - name: hub
    mass: 750 kg
    inertia: [900, 800, 600]
    center_of_mass: [0, 0, 1]
  - name: panel
    mass: 100 kg
    inertia: [100, 50, 50]
    center_of_mass: {value: [-25, 0, 50], unit: cm}
  - name: tip
    mass: 1 kg
    inertia: [1, 1, 1]
joints:
  - {name: base, type: free, child: hub, initial: {position: [1, 2, 3]}}
  - name: hinge
    type: revolute
    parent: hub
    child: panel
    parent_point: [0.5, 0, 1]
    child_point: [1.25, 0, 0.5]
    axis: [0, 1, 0]
  - name: weld
    type: fixed
    parent: panel
    child: tip
    parent_point: [-2.25, 0, 0.5]
    child_point: [0.5, 0, 0]
run: {duration: 1, output_step: 0.5}
)";

// The same scene with every point measured from the CMs by hand.
const std::string kShifted = R"(name: centers
bodies:
  - {name: hub, mass: 750 kg, inertia: [900, 800, 600]}
  - {name: panel, mass: 100 kg, inertia: [100, 50, 50]}
  - {name: tip, mass: 1 kg, inertia: [1, 1, 1]}
joints:
  - {name: base, type: free, child: hub, initial: {position: [1, 2, 3]}}
  - name: hinge
    type: revolute
    parent: hub
    child: panel
    parent_point: [0.5, 0, 0]
    child_point: [1.5, 0, 0]
    axis: [0, 1, 0]
  - name: weld
    type: fixed
    parent: panel
    child: tip
    parent_point: [-2, 0, 0]
    child_point: [0.5, 0, 0]
run: {duration: 1, output_step: 0.5}
)";

const Joint& joint(const System& s, const std::string& name) {
  for (const Joint& j : s.joints)
    if (j.name == name) return j;
  throw std::runtime_error("no joint " + name);
}

// A two-body scene whose hinge takes `offset`.
std::string with_offset(const std::string& offset) {
  return "name: o\nbodies:\n  - {name: a, mass: 1, inertia: [1, 1, 1]}\n"
         "  - {name: b, mass: 1, inertia: [1, 1, 1]}\njoints:\n"
         "  - {name: base, type: free, child: a}\n"
         "  - name: h\n    type: revolute\n    parent: a\n    child: b\n"
         "    parent_point: [1, 0, 0]\n    child_point: [-1, 0, 0]\n    axis: [0, 0, 1]\n"
         "    offset: " +
         offset + "\nrun: {duration: 1, output_step: 0.5}\n";
}

std::string message_of(const std::string& text) {
  try {
    (void)read_scene_text(text, "bad.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "accepted";
}

// A revolute joint with `initial` (line 9 of the text).
std::string with_initial(const std::string& initial, const std::string& spring = "") {
  return "name: w\nbodies:\n  - {name: a, mass: 1, inertia: [1, 1, 1]}\n"
         "  - {name: b, mass: 1, inertia: [1, 1, 1]}\njoints:\n"
         "  - {name: base, type: free, child: a}\n"
         "  - {name: h, type: revolute, parent: a, child: b, parent_point: [1, 0, 0],\n"
         "     child_point: [-1, 0, 0], axis: [0, 0, 1],\n"
         "     initial: " +
         initial + spring + "}\nrun: {duration: 1, output_step: 0.5}\n";
}

}  // namespace

TEST_CASE("center_of_mass: points given from a body's reference origin are moved to its CM") {
  const System given = read_scene_text(kWithCenters, "c.yaml");
  const System shifted = read_scene_text(kShifted, "c.yaml");
  CHECK(test::system_difference(given, shifted) == "");
  // The inertia stays about the CM, and the base's initial position is its CM's.
  CHECK(given.bodies[0].I_BBo_B == Eigen::Vector3d(900, 800, 600).asDiagonal().toDenseMatrix());
  CHECK(given.joints[0].p_NoBo_N0 == Eigen::Vector3d(1, 2, 3));
  // The writer writes the converted System, without center_of_mass; it reads back equal.
  const std::string written = write_scene_text(given);
  CHECK(written.find("center_of_mass") == std::string::npos);
  CHECK(test::system_difference(read_scene_text(written, "c.yaml"), given) == "");
}

TEST_CASE("center_of_mass: errors name the key") {
  std::string text = kWithCenters;
  text.replace(text.find("center_of_mass: [0, 0, 1]"), 25, "center_of_mass: [0, 1]");
  CHECK(message_of(text).find("bad.yaml:6:21: bodies[0].center_of_mass: expected a point (a list "
                              "of 3 numbers), found 2 elements") == 0);
  text = kWithCenters;
  text.replace(text.find("center_of_mass: [0, 0, 1]"), 25, "center_of_mass: [0, 0, 1 kg]");
  CHECK(message_of(text).find("bad.yaml:6:28: bodies[0].center_of_mass[2]: unit 'kg' is a mass, "
                              "but this key expects a length") == 0);
}

TEST_CASE("offset: a rotation matrix (rows) reads as the same rotation as a quaternion") {
  // 180 deg about z (Basilisk's panel hinge frame dcm_HB = diag(-1, -1, 1)): exact.
  const Eigen::Quaterniond flip = joint(read_scene_text(with_offset("[[-1, 0, 0], [0, -1, 0], [0, 0, 1]]"), "o.yaml"), "h").q_PJ0;
  CHECK(flip.coeffs() == Eigen::Quaterniond(0, 0, 0, 1).coeffs());
  // 90 deg about z: the child's x axis is the parent's y axis (the first COLUMN of R).
  const Eigen::Quaterniond q90 = joint(read_scene_text(with_offset("[[0, -1, 0], [1, 0, 0], [0, 0, 1]]"), "o.yaml"), "h").q_PJ0;
  const Eigen::Quaterniond axis_angle =
      joint(read_scene_text(with_offset("{axis: [0, 0, 1], angle: 90 deg}"), "o.yaml"), "h").q_PJ0;
  CHECK(test::all_close(q90.coeffs(), axis_angle.coeffs(), 1e-15, 0));
  CHECK(test::all_close(q90 * Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 1e-15, 0));
  // Seven significant digits are enough (within the 1e-6 tolerance), and normalised.
  const Eigen::Quaterniond q45 =
      joint(read_scene_text(with_offset("[[0.7071068, -0.7071068, 0], [0.7071068, 0.7071068, 0], "
                                        "[0, 0, 1]]"),
                            "o.yaml"),
            "h")
          .q_PJ0;
  CHECK(test::close(q45.norm(), 1, 0, 4e-16));
  CHECK(test::all_close(q45.coeffs(),
                        Eigen::Quaterniond(Eigen::AngleAxisd(kPi / 4, Eigen::Vector3d::UnitZ())).coeffs(),
                        1e-7, 0));
}

TEST_CASE("offset: a matrix that is not a rotation is an error naming the line") {
  CHECK(message_of(with_offset("[[1, 0.001, 0], [0, 1, 0], [0, 0, 1]]"))
            .find("bad.yaml:14:13: joints[1].offset: rotation matrix is not orthonormal: max "
                  "|R^T R - I| = 0.001 (tolerance 1e-6)") == 0);
  CHECK(message_of(with_offset("[[1, 0, 0], [0, 1, 0], [0, 0, -1]]"))
            .find("bad.yaml:14:13: joints[1].offset: rotation matrix has determinant -1: it is a "
                  "reflection, not a rotation") == 0);
  CHECK(message_of(with_offset("[[1, 0, 0], [0, 1, 0]]"))
            .find("joints[1].offset: expected a rotation matrix (3 rows of 3 numbers), found 2 "
                  "rows") != std::string::npos);
  CHECK(message_of(with_offset("[[1, 0, 0], [0, 1], [0, 0, 1]]"))
            .find("joints[1].offset[1]: expected a row (a list of 3 numbers), found 2 elements") !=
        std::string::npos);
  CHECK(message_of(with_offset("[[1, 0, 0], [0, 1, 0], [0, 0, 1 deg]]"))
            .find("joints[1].offset[2][2]: this value is a pure number and takes no unit") !=
        std::string::npos);
}

TEST_CASE("a bare angle above 2 pi draws a warning naming the file, line and key") {
  std::vector<SceneWarning> w;
  const System s = read_scene_text(with_initial("{angle: 7, rate: 0}"), "w.yaml", &w);
  REQUIRE(w.size() == 1);
  CHECK(w[0].text() ==
        "w.yaml:9:23: warning: joints[1].initial.angle: 7 has no unit and is read as 7 rad = "
        "401.1 deg; write '7 deg' or '7 rad'");
  CHECK(w[0].code == "angle-unitless-large");
  CHECK(w[0].subject == "joints[1].initial.angle");
  CHECK(w[0].detail() == "line 9: joints[1].initial.angle: 7 has no unit and is read as 7 rad = 401.1 "
                         "deg; write '7 deg' or '7 rad'");
  CHECK(joint(s, "h").angle0 == 7.0);  // still read as radians
  // Below a full turn, with a unit, or not an angle: no warning.
  for (const char* initial :
       {"{angle: 5, rate: 0}", "{angle: 6.28, rate: 0}", "{angle: -6.28, rate: 0}", "{angle: 400 deg, rate: 100}",
        "{angle: 7 rad, rate: 0}", "{angle: 0, rate: 50}"}) {
    INFO(initial);
    w.clear();
    (void)read_scene_text(with_initial(initial), "w.yaml", &w);
    CHECK(w.empty());
  }
  // Every key of dimension angle: the spring's neutral angle and an axis-angle's angle.
  w.clear();
  (void)read_scene_text(with_initial("{rate: 0}", ", spring: {stiffness: 1, neutral_angle: -7}"),
                        "w.yaml", &w);
  REQUIRE(w.size() == 1);
  CHECK(w[0].key == "joints[1].spring.neutral_angle");
  CHECK(w[0].message.find("-7 has no unit and is read as -7 rad = -401.1 deg; write") == 0);
  w.clear();
  (void)read_scene_text(with_offset("{axis: [0, 0, 1], angle: 90}"), "w.yaml", &w);
  REQUIRE(w.size() == 1);
  CHECK(w[0].key == "joints[1].offset.angle");
  CHECK(w[0].line == 14);
}

TEST_CASE("the writer writes an angle above 2 pi with its unit, so it reads back silently") {
  std::vector<SceneWarning> w;
  const System s = read_scene_text(with_initial("{angle: 400 deg, rate: 0}"), "w.yaml", &w);
  const std::string written = write_scene_text(s);
  CHECK(written.find("angle: 6.981317007977318 rad") != std::string::npos);
  const System back = read_scene_text(written, "w.yaml", &w);
  CHECK(w.empty());
  CHECK(test::system_difference(s, back) == "");
}

TEST_CASE("the program prints scene warnings on stderr and still runs the scene") {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("crossdyn_warn_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path scene = dir / "warn.yaml", out = dir / "out.csv";
  std::ofstream(scene) << with_initial("{angle: 7, rate: 0}");
  for (const std::string command : {"run", "compare"}) {
    INFO(command);
    const std::string args = command + " '" + scene.string() + "'" +
                             (command == "run" ? " --output '" + out.string() + "'" : "");
    const test::ProgramResult r = test::run_crossdyn(args);
    INFO(r.output);
    CHECK(r.status == 0);
    CHECK(r.output.find("crossdyn: warning: " + scene.string() +
                        ": line 9: joints[1].initial.angle: 7 has no unit and is read as 7 "
                        "rad = 401.1 deg; write '7 deg' or '7 rad'\n") != std::string::npos);
  }
  CHECK(fs::exists(out));
  fs::remove_all(dir);
}
