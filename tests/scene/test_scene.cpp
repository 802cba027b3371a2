// Scene reader: the committed scenes (values, round trip), the formats and units it accepts, the
// joint reordering, and the fuzz regression inputs. Error messages: test_scene_errors.cpp.
#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "core/units.hpp"
#include "tests/scene/system_equal.hpp"
#include "tests/support/close.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <vector>

using namespace crossdyn;
using crossdyn::test::close;

namespace {

constexpr double kPi = std::numbers::pi;
// Unit conversions are one multiplication: allow a few ulps.
constexpr double kUlps = 4 * std::numeric_limits<double>::epsilon();

std::vector<std::filesystem::path> files_in(const std::string& dir, const std::string& ext) {
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.is_regular_file() && (ext.empty() || e.path().extension() == ext))
      files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

const Joint& joint(const System& s, const std::string& name) {
  for (const Joint& j : s.joints)
    if (j.name == name) return j;
  throw std::runtime_error("no joint " + name);
}

const Body& body(const System& s, const std::string& name) {
  const int b = s.body_index(name);
  if (b < 0) throw std::runtime_error("no body " + name);
  return s.bodies[static_cast<std::size_t>(b)];
}

// A small valid scene exercising every optional feature of the format.
const char* kRichScene = R"(
name: rich
description: |
  Every feature: "quotes", colons: yes, # not a comment, unicode µ°, tabs	and
  several lines.
source: made up for the round-trip test
zero_linear_momentum: false
bodies:
  - name: hub
    mass: 1 kg
    inertia: [[10, 1, 0.5], [1, 20, 0.25], [0.5, 0.25, 25]]
    torque:
      frame: inertial
      profile:
        - {t: 0, value: [1, 0, 0]}
        - {t: 0.5 min, value: {value: [0, -2, 0], unit: N*m}}
  - name: arm
    mass: 500 g
    inertia: {value: [1, 1, 1.5, 0.1, 0, 0], unit: kg m^2}
  - name: tip
    mass: 0.25 kg
    inertia: [0.1, 0.1, 0.1]
  - name: cap
    mass: 0.1 kg
    inertia: [0.01, 0.01, 0.01]
joints:
  - name: base
    type: free
    child: hub
    initial:
      position: {value: [1, 2, 3], unit: km}
      attitude: {axis: [1, 1, 0], angle: 30 deg}
      angular_velocity: [0.1, 0.2, 0.3]
      velocity: [1 m/s, 0, 0]
  - name: hinge
    type: revolute
    parent: hub
    child: arm
    parent_point: [1, 0, 0]
    child_point: [-100 cm, 0, 0]
    axis: [0, 3, 4]
    offset: [0.7071067811865476, 0, 0, 0.7071067811865476]
    spring: {stiffness: 2 N m/rad, neutral_angle: 5 deg}
    damper: {damping: 0.5 N*m*s/rad}
    motor: {profile: [{t: 0, value: 1 N m}, {t: 2 s, value: -1}]}
    initial: {angle: 10 deg, rate: 30 rpm}
  - name: ball
    type: spherical
    parent: arm
    child: tip
    parent_point: [0.5, 0, 0]
    child_point: [-0.5, 0, 0]
    offset: {axis: [0, 0, 1], angle: 90 deg}
    spring: {stiffness: 1}
    damper: {damping: 0.1}
    motor: {profile: [{t: 1 s, value: [0, 0, 0.5]}]}
    initial:
      attitude: [0.9998, 0.02, 0, 0]
      angular_velocity: {value: [0, 0, 10], unit: deg/s}
  - name: weld
    type: fixed
    parent: tip
    child: cap
    parent_point: [0.1, 0, 0]
    child_point: [0, 0, 0]
run:
  duration: 2 min
  output_step: 500 ms
  integrator: dopri5
  rtol: 1e-9
  atol: 1e-12
  dt: 1 ms
compare:
  tolerances:
    H: {atol: 1e-6}
    default: {atol: 1e-7, rtol: 1e-6}
    hinge.angle: {atol: 1e-5, rtol: 0}
  exclude:
    - {quantity: E, reason: "the dampers dissipate energy"}
)";

}  // namespace

TEST_CASE("every committed scene reads, and reads back equal from what the writer writes") {
  const auto scenes = files_in(test::source_dir() + "/scenarios", ".yaml");
  for (const char* name : {"spear1_case1", "spear1_case2", "spear1_case1_spherical", "chain5",
                           "torque_free_axisymmetric", "torque_free_asymmetric", "hub_two_panels",
                           "dual_spin", "chain_motor"})
    CHECK(std::filesystem::exists(test::scene_path(name)));
  for (const auto& path : scenes) {
    INFO(path.string());
    const System s = read_scene(path.string());
    CHECK(s.file == path.string());
    CHECK(s.name == path.stem().string());  // committed scenes are named after their files
    CHECK(!s.description.empty());
    CHECK(!s.source.empty());
    const std::string written = write_scene_text(s);
    const System back = read_scene_text(written, path.string());
    CHECK(test::system_difference(s, back) == "");
    CHECK(write_scene_text(back) == written);  // the written form is a fixed point
  }
}

TEST_CASE("the rich scene with every optional feature round-trips") {
  const System s = read_scene_text(kRichScene, "rich.yaml");
  const std::string written = write_scene_text(s);
  INFO(written);
  const System back = read_scene_text(written, "rich.yaml");
  CHECK(test::system_difference(s, back) == "");
  CHECK(write_scene_text(back) == written);
}

TEST_CASE("spear1_case1 is converted to SI exactly as pinned") {
  const System s = read_scene(test::scene_path("spear1_case1"));
  CHECK(s.name == "spear1_case1");
  REQUIRE(s.bodies.size() == 3);
  REQUIRE(s.joints.size() == 3);
  const Body& main = body(s, "main");
  CHECK(main.mass == 300.0);  // integers in the file are exact doubles
  CHECK(main.I_BBo_B.isApprox(Eigen::Vector3d(100, 400, 400).asDiagonal().toDenseMatrix(), 0.0));
  CHECK(body(s, "boom1").mass == 10.0);
  CHECK(body(s, "boom2").I_BBo_B == Eigen::Matrix3d::Identity() * 10.0);
  // joints[0] is the base's free joint; 90 deg/s about x.
  REQUIRE(s.joints[0].type == JointType::Free);
  CHECK(s.joints[0].child == s.body_index("main"));
  CHECK(s.joints[0].parent == -1);
  CHECK(close(s.joints[0].w_NB_B0.x(), kPi / 2, 0, kUlps));
  CHECK(s.joints[0].w_NB_B0.y() == 0.0);
  CHECK(s.joints[0].w_NB_B0.z() == 0.0);
  CHECK(s.joints[0].q_NB0.coeffs() == Eigen::Quaterniond::Identity().coeffs());
  for (const char* name : {"hinge1", "hinge2"}) {
    const Joint& h = joint(s, name);
    CHECK(h.type == JointType::Revolute);
    CHECK(h.parent == s.body_index("main"));
    CHECK(h.p_PoJ_P == Eigen::Vector3d(6, 0, 0));
    CHECK(h.p_CoJ_C == Eigen::Vector3d(-2, 0, 0));
    CHECK(h.axis_P == Eigen::Vector3d::UnitZ());
    CHECK(h.angle0 == 0.0);
    CHECK(h.stiffness == 0.0);
    CHECK(h.motor_revolute.empty());
  }
  CHECK(joint(s, "hinge1").child == s.body_index("boom1"));
  CHECK(joint(s, "hinge2").child == s.body_index("boom2"));
  CHECK(close(joint(s, "hinge1").rate0, kPi / 18, 0, kUlps));   // +10 deg/s
  CHECK(close(joint(s, "hinge2").rate0, -kPi / 18, 0, kUlps));  // -10 deg/s
  CHECK(s.run.duration == 5.0);
  CHECK(s.run.output_step == 0.05);
  CHECK(s.run.integrator == "rkf78");
  CHECK(s.run.rtol == 1e-10);
  CHECK(s.run.atol == 1e-10);
  CHECK(s.zero_linear_momentum);
  CHECK(s.analytic.empty());
  CHECK(s.breakpoints().empty());
}

TEST_CASE("the other pinned scenes hold the data of SCENARIOS.md") {
  const System c2 = read_scene(test::scene_path("spear1_case2"));
  CHECK(close(joint(c2, "hinge1").rate0, kPi / 18, 0, kUlps));
  CHECK(close(joint(c2, "hinge2").rate0, -kPi / 36, 0, kUlps));  // -5 deg/s
  CHECK(close(c2.joints[0].w_NB_B0.x(), kPi / 2, 0, kUlps));

  const System sph = read_scene(test::scene_path("spear1_case1_spherical"));
  for (const char* name : {"hinge1", "hinge2"}) {
    const Joint& h = joint(sph, name);
    CHECK(h.type == JointType::Spherical);
    CHECK(h.p_PoJ_P == Eigen::Vector3d(6, 0, 0));
    CHECK(h.p_CoJ_C == Eigen::Vector3d(-2, 0, 0));
  }
  CHECK(close(joint(sph, "hinge1").w_PC_C0.z(), kPi / 18, 0, kUlps));
  CHECK(close(joint(sph, "hinge2").w_PC_C0.z(), -kPi / 18, 0, kUlps));
  CHECK(joint(sph, "hinge1").w_PC_C0.head<2>().isZero(0.0));

  const System chain = read_scene(test::scene_path("chain5"));
  REQUIRE(chain.bodies.size() == 5);
  REQUIRE(chain.joints.size() == 5);
  CHECK(chain.joints[0].w_NB_B0 == Eigen::Vector3d(0.3, 0.2, 0.5));
  for (int k = 2; k <= 5; ++k) {
    const Joint& j = joint(chain, "joint" + std::to_string(k));
    CHECK(j.type == JointType::Spherical);
    CHECK(j.parent == chain.body_index("link" + std::to_string(k - 1)));
    CHECK(j.child == chain.body_index("link" + std::to_string(k)));
    CHECK(j.p_PoJ_P == Eigen::Vector3d(1, 0, 0));
    CHECK(j.p_CoJ_C == Eigen::Vector3d(-1, 0, 0));
    CHECK(j.w_PC_C0 == Eigen::Vector3d(0.1, -0.2, 0.3));
  }
  CHECK(chain.run.duration == 10.0);
  CHECK(chain.run.output_step == 0.1);

  for (const char* name : {"torque_free_axisymmetric", "torque_free_asymmetric"}) {
    const System tf = read_scene(test::scene_path(name));
    CHECK(tf.analytic == "torque-free");
    CHECK(tf.bodies.size() == 1);
    CHECK(tf.run.duration == 100.0);
    CHECK(tf.run.output_step == 0.5);
  }

  const System motor = read_scene(test::scene_path("chain_motor"));
  const Joint& m = joint(motor, "joint2");
  CHECK(m.motor_revolute.value(0.5)[0] == 2.0);
  CHECK(m.motor_revolute.value(1.5)[0] == -2.0);
  CHECK(m.motor_revolute.value(3.0)[0] == 0.0);
  CHECK(motor.breakpoints() == std::vector<double>{1.0, 2.0});

  const System spin = read_scene(test::scene_path("dual_spin"));
  CHECK(close(joint(spin, "bearing").rate0, 1000 * 2 * kPi / 60, 0, kUlps));  // 1000 rpm

  const System panels = read_scene(test::scene_path("hub_two_panels"));
  CHECK(joint(panels, "hinge1").stiffness == 500.0);
  CHECK(joint(panels, "hinge2").damping == 5.0);
  CHECK(close(joint(panels, "hinge2").angle0, -3 * kPi / 180, 0, kUlps));
}

TEST_CASE("units: every spelling converts to SI") {
  using units::Dimension;
  struct Case {
    const char* text;
    Dimension dimension;
    double si;
  };
  const Case cases[] = {
      {"rad", Dimension::Angle, 1},
      {"deg", Dimension::Angle, kPi / 180},
      {"rad/s", Dimension::AngularRate, 1},
      {"deg/s", Dimension::AngularRate, kPi / 180},
      {"rpm", Dimension::AngularRate, kPi / 30},
      {"m", Dimension::Length, 1},
      {"mm", Dimension::Length, 1e-3},
      {"cm", Dimension::Length, 1e-2},
      {"km", Dimension::Length, 1e3},
      {"kg", Dimension::Mass, 1},
      {"g", Dimension::Mass, 1e-3},
      {"s", Dimension::Time, 1},
      {"ms", Dimension::Time, 1e-3},
      {"min", Dimension::Time, 60},
      {"kg m^2", Dimension::Inertia, 1},
      {"kg*m^2", Dimension::Inertia, 1},
      {"N m", Dimension::Torque, 1},
      {"N*m", Dimension::Torque, 1},
      {"N m/rad", Dimension::Stiffness, 1},
      {"N * m / rad", Dimension::Stiffness, 1},
      {"N m s/rad", Dimension::Damping, 1},
      {"N*m*s/rad", Dimension::Damping, 1},
      {"m/s", Dimension::Velocity, 1},
      // Millinewton metres, per degree (1 N m/deg = 180/pi N m/rad), angular accelerations.
      {"mN m", Dimension::Torque, 1e-3},
      {"mN*m", Dimension::Torque, 1e-3},
      {"mNm", Dimension::Torque, 1e-3},
      {"N m/deg", Dimension::Stiffness, 180 / kPi},
      {"Nm/deg", Dimension::Stiffness, 180 / kPi},
      {"N*m / deg", Dimension::Stiffness, 180 / kPi},
      {"mN m/rad", Dimension::Stiffness, 1e-3},
      {"mN m/deg", Dimension::Stiffness, 1e-3 * 180 / kPi},
      {"mNm/deg", Dimension::Stiffness, 1e-3 * 180 / kPi},
      {"N m s/deg", Dimension::Damping, 180 / kPi},
      {"Nms/deg", Dimension::Damping, 180 / kPi},
      {"mN m s/rad", Dimension::Damping, 1e-3},
      {"mN m s/deg", Dimension::Damping, 1e-3 * 180 / kPi},
      {"rad/s^2", Dimension::AngularAcceleration, 1},
      {"deg/s^2", Dimension::AngularAcceleration, kPi / 180},
  };
  for (const Case& c : cases) {
    INFO(c.text);
    const auto u = units::find_unit(c.text);
    REQUIRE(u);
    CHECK(u->dimension == c.dimension);
    CHECK(close(u->to_si, c.si, 0, kUlps));
  }
  CHECK_FALSE(units::find_unit("MN m"));  // a meganewton metre is no spacecraft torque
  CHECK_FALSE(units::find_unit("furlong"));
  CHECK_FALSE(units::find_unit("Deg"));  // units are case-sensitive (mN vs MN)
  CHECK(units::normalise_unit("  N  *  m /  rad ") == "N m/rad");
}

TEST_CASE("units: a scene's stiffness, damping and torque per degree and in mN m") {
  const std::string text = R"(name: per_degree
bodies:
  - {name: hub, mass: 100 kg, inertia: [10, 20, 25]}
  - {name: arm, mass: 5 kg, inertia: [1, 1, 1]}
  - {name: rod, mass: 5 kg, inertia: [1, 1, 1]}
joints:
  - {name: base, type: free, child: hub}
  - name: hinge
    type: revolute
    parent: hub
    child: arm
    parent_point: [1, 0, 0]
    child_point: [-1, 0, 0]
    axis: [0, 0, 1]
    spring: {stiffness: 2 N m/deg}
    damper: {damping: 0.5 N m s/deg}
    motor: {profile: [{t: 0, value: 5 mN m}, {t: 1 s, value: -3 mNm}]}
  - name: ball
    type: spherical
    parent: hub
    child: rod
    parent_point: [-1, 0, 0]
    child_point: [1, 0, 0]
    spring: {stiffness: 40 mN m/deg}
    damper: {damping: 7 mN m s/rad}
run: {duration: 2 s, output_step: 0.1 s}
)";
  const System s = read_scene_text(text, "per_degree.yaml");
  const Joint& hinge = joint(s, "hinge");
  CHECK(close(hinge.stiffness, 2 * 180 / kPi, 0, kUlps));  // 114.59 N m/rad
  CHECK(close(hinge.damping, 0.5 * 180 / kPi, 0, kUlps));
  CHECK(close(hinge.motor_revolute.value(0.5)[0], 5e-3, 0, kUlps));
  CHECK(close(hinge.motor_revolute.value(1.5)[0], -3e-3, 0, kUlps));
  const Joint& ball = joint(s, "ball");
  CHECK(close(ball.stiffness, 40e-3 * 180 / kPi, 0, kUlps));
  CHECK(close(ball.damping, 7e-3, 0, kUlps));
}

TEST_CASE("quantities with units in a scene are converted to SI") {
  const System s = read_scene_text(kRichScene, "rich.yaml");
  const Body& arm = body(s, "arm");
  CHECK(close(arm.mass, 0.5, 0, kUlps));  // 500 g
  Eigen::Matrix3d I_arm;
  I_arm << 1, 0.1, 0, 0.1, 1, 0, 0, 0, 1.5;  // 6-number form: xx, yy, zz, xy, xz, yz
  CHECK(arm.I_BBo_B == I_arm);
  Eigen::Matrix3d I_hub;
  I_hub << 10, 1, 0.5, 1, 20, 0.25, 0.5, 0.25, 25;
  CHECK(body(s, "hub").I_BBo_B == I_hub);
  CHECK(body(s, "hub").torque_frame == Body::Frame::Inertial);
  CHECK(body(s, "hub").torque.times == std::vector<double>{0, 30});  // 0.5 min
  CHECK(body(s, "hub").torque.value(40) == Eigen::Vector3d(0, -2, 0));
  const Joint& base = s.joints[0];
  CHECK(base.p_NoBo_N0 == Eigen::Vector3d(1000, 2000, 3000));  // km
  const Eigen::Quaterniond q30(Eigen::AngleAxisd(kPi / 6, Eigen::Vector3d(1, 1, 0).normalized()));
  CHECK(test::all_close(base.q_NB0.coeffs(), q30.coeffs(), 1e-15, 0));
  CHECK(base.v_NBo_N0 == Eigen::Vector3d(1, 0, 0));
  CHECK_FALSE(s.zero_linear_momentum);
  const Joint& hinge = joint(s, "hinge");
  CHECK(test::all_close(hinge.axis_P, Eigen::Vector3d(0, 0.6, 0.8), 1e-15, 0));  // normalised
  CHECK(close(hinge.p_CoJ_C.x(), -1, 0, kUlps));                                 // -100 cm
  CHECK(close(hinge.neutral_angle, kPi / 36, 0, kUlps));
  CHECK(close(hinge.rate0, kPi, 0, kUlps));  // 30 rpm
  CHECK(hinge.damping == 0.5);
  CHECK(hinge.motor_revolute.value(2.5)[0] == -1.0);
  const Joint& ball = joint(s, "ball");
  CHECK(test::all_close(ball.q_PJ0.coeffs(), Eigen::Vector4d(0, 0, std::sqrt(0.5), std::sqrt(0.5)),
                        1e-15, 0));
  CHECK(close(ball.q_J0.norm(), 1, 0, kUlps));  // [0.9998, 0.02, 0, 0] normalised
  CHECK(ball.motor_spherical.value(0.5) == Eigen::Vector3d::Zero());  // zero before the first time
  CHECK(joint(s, "weld").type == JointType::Fixed);
  CHECK(s.run.duration == 120.0);
  CHECK(s.run.output_step == 0.5);
  CHECK(s.run.dt == 1e-3);
  CHECK(s.run.integrator == "dopri5");
  CHECK(s.compare.default_tolerance.atol == 1e-7);
  REQUIRE(s.compare.tolerances.size() == 2);
  CHECK(s.compare.tolerances[0].first == "H");
  CHECK(s.compare.tolerances[0].second.atol == 1e-6);
  CHECK(s.compare.tolerances[0].second.rtol == 1e-6);  // from default, whatever the key order
  CHECK(s.compare.excluded.size() == 1);
  CHECK(s.breakpoints() == std::vector<double>{1, 2, 30});
}

TEST_CASE("joints are put in topological order with the free joint first") {
  const char* text = R"(
name: shuffled
bodies:
  - {name: c, mass: 1, inertia: [1, 1, 1]}
  - {name: a, mass: 1, inertia: [1, 1, 1]}
  - {name: b, mass: 1, inertia: [1, 1, 1]}
  - {name: d, mass: 1, inertia: [1, 1, 1]}
joints:
  - {name: jc, type: revolute, parent: b, child: c, parent_point: [1, 0, 0], child_point: [0, 0, 0], axis: [0, 0, 1]}
  - {name: jd, type: spherical, parent: a, child: d, parent_point: [0, 1, 0], child_point: [0, 0, 0]}
  - {name: jb, type: revolute, parent: a, child: b, parent_point: [1, 0, 0], child_point: [0, 0, 0], axis: [0, 0, 1]}
  - {name: base, type: free, child: a}
run: {duration: 1, output_step: 0.1}
)";
  const System s = read_scene_text(text, "shuffled.yaml");
  std::vector<std::string> order;
  for (const Joint& j : s.joints) order.push_back(j.name);
  // base first; then the ready joints in file order (jd and jb hang on a; jc waits for b).
  CHECK(order == std::vector<std::string>{"base", "jd", "jb", "jc"});
  CHECK(s.base_body() == s.body_index("a"));
  for (std::size_t j = 1; j < s.joints.size(); ++j) {
    bool parent_placed = false;
    for (std::size_t k = 0; k < j; ++k)
      parent_placed = parent_placed || s.joints[k].child == s.joints[j].parent;
    CHECK(parent_placed);
  }
  // Bodies keep their file order; indices are consistent.
  CHECK(s.bodies[0].name == "c");
  CHECK(s.joints[3].child == 0);
  CHECK(s.joints[3].parent == s.body_index("b"));
}

TEST_CASE("every fuzz regression input is read or rejected with InputError, never anything else") {
  const auto inputs = files_in(test::source_dir() + "/tests/scene/fuzz_regressions", "");
  REQUIRE(!inputs.empty());
  for (const auto& path : inputs) {
    INFO(path.string());
    const std::string text = slurp(path);
    try {
      const System s = read_scene_text(text, "fuzz.yaml");
      const System back = read_scene_text(write_scene_text(s), "fuzz.yaml");
      CHECK(test::system_difference(s, back) == "");
    } catch (const InputError& e) {
      const std::string message = e.what();
      CHECK(message.rfind("fuzz.yaml:", 0) == 0);
    }
  }
}
