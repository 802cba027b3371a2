// The drawing geometry of the scene pictures (harness/scene_geometry.hpp): equivalent-inertia boxes,
// the placement of bodies from attitudes and joints, the joint frames and offsets, and the later
// configurations taken from a kane run. What a picture shows must be what the engines simulate:
// joint points coincide in N, a revolute axis stays fixed in both bodies, and the joint rotation
// recovered from the bodies' attitudes is the engine's own joint angle.
#include <catch2/catch.hpp>

#include "core/integrate.hpp"
#include "core/orbit.hpp"
#include "core/rotation.hpp"
#include "core/scene/scene.hpp"
#include "harness/engines.hpp"
#include "harness/scene_geometry.hpp"
#include "tests/support/paths.hpp"

#include <nlohmann/json.hpp>

#include <cmath>

namespace g = crossdyn::harness::geometry;
using crossdyn::Body;
using crossdyn::Joint;
using crossdyn::JointType;
using crossdyn::System;
using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kTight = 1e-12;  // exact formulas in double precision (a few ulps of O(1) values)

std::string scene(const std::string& name) { return crossdyn::test::source_dir() + "/" + name; }

// The scenes the checks run on: revolute with offsets, spherical, a chain, a rotor.
const char* const kScenes[] = {"tests/harness/scenes/hinged_panels.yaml", "scenarios/hub_two_panels.yaml",
                               "scenarios/spear1_case1_spherical.yaml", "scenarios/chain5.yaml",
                               "scenarios/dual_spin.yaml", "scenarios/spear1_case2.yaml"};

// Every joint point seen from the parent and from the child is one point of N.
void check_points_coincide(const System& s, const g::Configuration& c) {
  for (std::size_t j = 1; j < s.joints.size(); ++j) {
    const Joint& J = s.joints[j];
    const g::BodyPose& P = c.bodies[J.parent];
    const g::BodyPose& C = c.bodies[J.child];
    const Vector3d from_parent = P.p_NoBo_N + P.R_NB * J.p_PoJ_P;
    const Vector3d from_child = C.p_NoBo_N + C.R_NB * J.p_CoJ_C;
    INFO("joint " << J.name << " at t = " << c.t);
    CHECK((from_parent - from_child).norm() <= kTight * (1 + from_parent.norm()));
    CHECK((c.joints[j].p_NoJ_N_parent - from_parent).norm() <= kTight * (1 + from_parent.norm()));
    CHECK(c.joints[j].p_NoJ_N_child.isApprox(from_child, 1e-12));
  }
}

// The centre of mass of the placed bodies is where the configuration says.
Vector3d system_cm(const System& s, const g::Configuration& c) {
  Vector3d sum = Vector3d::Zero();
  double m = 0;
  for (std::size_t b = 0; b < s.bodies.size(); ++b) {
    sum += s.bodies[b].mass * c.bodies[b].p_NoBo_N;
    m += s.bodies[b].mass;
  }
  return sum / m;
}

}  // namespace

TEST_CASE("scene geometry: the equivalent box of a uniform box is the box itself") {
  // A 12 kg box 3 x 2 x 1 m: I = m (b^2 + c^2) / 12 ... = (5, 10, 13) kg m^2.
  Body b;
  b.mass = 12;
  b.I_BBo_B = Vector3d(5, 10, 13).asDiagonal();
  const g::EquivalentBox box = g::equivalent_box(b);
  CHECK(box.size_m.isApprox(Vector3d(3, 2, 1), kTight));
  CHECK(box.R_BX.isApprox(Matrix3d::Identity(), 0));

  // The same box turned by 30 deg about (1, 2, 2)/3: the box axes are the turned axes, the sides the same.
  const Matrix3d R = Eigen::AngleAxisd(kPi / 6, Vector3d(1, 2, 2) / 3).toRotationMatrix();
  b.I_BBo_B = R * b.I_BBo_B * R.transpose();
  const g::EquivalentBox turned = g::equivalent_box(b);
  CHECK(turned.size_m.isApprox(Vector3d(3, 2, 1), 1e-9));
  for (int k = 0; k < 3; ++k) CHECK(std::abs(turned.R_BX.col(k).dot(R.col(k))) == Approx(1).epsilon(1e-12));
  CHECK(turned.R_BX.determinant() == Approx(1).epsilon(1e-12));

  // A flat plate (Basilisk's panel: diag(100, 50, 50) for 100 kg) has no thickness along x.
  Body plate;
  plate.mass = 100;
  plate.I_BBo_B = Vector3d(100, 50, 50).asDiagonal();
  const g::EquivalentBox p = g::equivalent_box(plate);
  CHECK(p.size_m.x() == 0);
  CHECK(p.size_m.y() == Approx(std::sqrt(6.0)).epsilon(1e-14));
  CHECK(p.size_m.z() == Approx(std::sqrt(6.0)).epsilon(1e-14));
}

TEST_CASE("scene geometry: a hinge with an offset places the panel as worked out by hand") {
  // Basilisk's panel 1: hinge at (0.5, 0, 0) m of the hub's CM, hinge frame turned 180 deg about z,
  // panel CM 1.5 m along the hinge frame's -x, turning about the hinge frame's y (= -y of the hub).
  // R_PC = Rz(180) Ry(theta), so the CM is at (0.5 + 1.5 cos theta, 0, 1.5 sin theta): a positive
  // angle lifts the panel towards +z.
  const System s = crossdyn::read_scene(scene("tests/harness/scenes/hinged_panels.yaml"));
  const double theta = 5 * kPi / 180;
  const g::Configuration c = g::initial_configuration(s);
  const int panel1 = s.body_index("panel1"), panel2 = s.body_index("panel2"), hub = s.body_index("hub");
  CHECK(c.bodies[hub].p_NoBo_N.norm() == 0);
  CHECK(c.bodies[panel1].p_NoBo_N.isApprox(Vector3d(0.5 + 1.5 * std::cos(theta), 0, 1.5 * std::sin(theta)), kTight));
  CHECK(c.bodies[panel1].R_NB.isApprox(
      Eigen::AngleAxisd(kPi, Vector3d::UnitZ()).toRotationMatrix() *
          Eigen::AngleAxisd(theta, Vector3d::UnitY()).toRotationMatrix(), kTight));
  CHECK(c.bodies[panel2].p_NoBo_N.isApprox(Vector3d(-2, 0, 0), kTight));
  // The revolute axis in N, from either body, and the joint rotation recovered from the attitudes.
  const int hinge1 = 1;
  REQUIRE(s.joints[hinge1].name == "hinge1");
  CHECK(c.joints[hinge1].axis_N_parent.isApprox(Vector3d(0, -1, 0), kTight));
  CHECK(c.joints[hinge1].axis_N_child.isApprox(Vector3d(0, -1, 0), kTight));
  CHECK(c.joints[hinge1].phi_J.isApprox(theta * Vector3d::UnitY(), kTight));
  CHECK(g::revolute_axis_in_child(s.joints[hinge1]).isApprox(Vector3d::UnitY(), kTight));

  // The flipped child_point puts the panel's CM on the hub's side of the hinge.
  const System flipped = crossdyn::read_scene(scene("tests/harness/scenes/hinged_panels_flipped_child_point.yaml"));
  const g::Configuration f = g::initial_configuration(flipped);
  CHECK(f.bodies[panel1].p_NoBo_N.isApprox(Vector3d(0.5 - 1.5 * std::cos(theta), 0, -1.5 * std::sin(theta)), kTight));
  // The flipped axis turns the panel the other way: down.
  const System axis = crossdyn::read_scene(scene("tests/harness/scenes/hinged_panels_flipped_axis.yaml"));
  CHECK(g::initial_configuration(axis).bodies[panel1].p_NoBo_N.z() == Approx(-1.5 * std::sin(theta)).epsilon(1e-14));
}

TEST_CASE("scene geometry: a 90 deg offset turns the hinge frame, and the axis stays in the parent frame") {
  // Offset Rz(90), axis x of the parent: R_PC = Rz(90) Rot(axis_J, theta) with axis_J = Rz(90)^T x
  // = -y. The arm's CM, 1 m along the arm's x from the hinge at (1, 0, 0), starts along the
  // parent's y (the offset) and turns about the parent's x by theta: (1, cos theta, sin theta).
  const System s = crossdyn::read_scene_text(R"(name: offset90
bodies:
  - {name: hub, mass: 10, inertia: [1, 1, 1]}
  - {name: arm, mass: 1, inertia: [0.1, 0.1, 0.1]}
joints:
  - {name: base, type: free, child: hub}
  - name: hinge
    type: revolute
    parent: hub
    child: arm
    parent_point: [1, 0, 0]
    child_point: [-1, 0, 0]
    axis: [1, 0, 0]
    offset: {axis: [0, 0, 1], angle: 90 deg}
    initial: {angle: 30 deg}
run: {duration: 1, output_step: 0.1}
)", "offset90.yaml");
  const double theta = kPi / 6;
  const g::Configuration c = g::initial_configuration(s);
  CHECK(c.bodies[1].p_NoBo_N.isApprox(Vector3d(1, std::cos(theta), std::sin(theta)), kTight));
  CHECK(g::revolute_axis_in_child(s.joints[1]).isApprox(-Vector3d::UnitY(), kTight));
  CHECK(c.joints[1].axis_N_parent.isApprox(Vector3d::UnitX(), kTight));
  CHECK(c.joints[1].axis_N_child.isApprox(Vector3d::UnitX(), kTight));
  CHECK(c.joints[1].phi_J.isApprox(-theta * Vector3d::UnitY(), kTight));
  // The arm's x axis (towards its hinge end is -x) points from the hinge to its CM: R_NC (1, 0, 0).
  CHECK((c.bodies[1].R_NB * Vector3d::UnitX()).isApprox(Vector3d(0, std::cos(theta), std::sin(theta)), kTight));
}

TEST_CASE("scene geometry: at t = 0 every joint point coincides and the joint rotation is the scene's") {
  for (const char* name : kScenes) {
    INFO(name);
    const System s = crossdyn::read_scene(scene(name));
    const g::Configuration c = g::initial_configuration(s);
    check_points_coincide(s, c);
    CHECK(c.p_NoScm_N.isApprox(system_cm(s, c), 1e-12));
    for (std::size_t j = 1; j < s.joints.size(); ++j) {
      const Joint& J = s.joints[j];
      INFO("joint " << J.name);
      if (J.type == JointType::Revolute) {
        CHECK((c.joints[j].phi_J - J.angle0 * g::revolute_axis_in_child(J)).norm() <= kTight);
        CHECK((c.joints[j].axis_N_parent - c.joints[j].axis_N_child).norm() <= kTight);
      } else if (J.type == JointType::Spherical) {
        CHECK((c.joints[j].phi_J - crossdyn::rot::rotation_vector(J.q_J0)).norm() <= kTight);
      }
    }
  }
}

TEST_CASE("scene geometry: the later configurations of a kane run keep the joints together") {
  // Attitudes from kane's output columns; positions from the joints; CM at the origin. Kane's
  // attitudes must keep each revolute axis fixed in both bodies, and the joint rotation recovered
  // from them must be kane's own angle column (to the integrator's accuracy, not to round-off:
  // the attitudes and the angle are separate states of the engine).
  for (const char* name : kScenes) {
    INFO(name);
    const System s = crossdyn::read_scene(scene(name));
    std::unique_ptr<crossdyn::Engine> kane = crossdyn::make_engine("kane", s);
    crossdyn::IntegratorSettings settings = crossdyn::IntegratorSettings::from(s.run);
    const crossdyn::RunResult run = crossdyn::simulate(*kane, s, crossdyn::TreeState::initial(s), settings);
    REQUIRE_FALSE(run.failure);
    const std::vector<g::Configuration> frames = g::motion_frames(s, run.columns, run.data, settings.duration);
    REQUIRE(frames.size() == 4);
    CHECK(frames.front().t == 0);
    CHECK(frames.back().t == Approx(settings.duration).epsilon(1e-12));
    CHECK(frames[1].t == Approx(settings.duration / 3).margin(settings.output_step / 2));
    for (const g::Configuration& c : frames) {
      check_points_coincide(s, c);
      CHECK(system_cm(s, c).norm() <= 1e-12 * (1 + c.bodies[0].p_NoBo_N.norm()));
      const std::size_t row = static_cast<std::size_t>(std::lround(c.t / settings.output_step));
      for (std::size_t j = 1; j < s.joints.size(); ++j) {
        const Joint& J = s.joints[j];
        INFO("joint " << J.name << " at t = " << c.t);
        if (J.type != JointType::Revolute) continue;
        CHECK((c.joints[j].axis_N_parent - c.joints[j].axis_N_child).norm() <= 1e-8);
        const double angle = run.at(row, run.column(J.name + ".angle"));
        const Vector3d expected = angle * g::revolute_axis_in_child(J);
        // The rotation vector wraps at pi: compare as rotations.
        CHECK(crossdyn::rot::angle_between(crossdyn::rot::from_rotation_vector(c.joints[j].phi_J),
                                           crossdyn::rot::from_rotation_vector(expected)) <= 1e-8);
      }
    }
  }
}

TEST_CASE("scene geometry: a run that ended early gives only the pictures it reached") {
  // One free body spinning about z at 1 rad/s; rows every 0.1 s up to 0.45 s of a 1 s scene.
  System s;
  s.name = "spinner";
  Body b;
  b.name = "body";
  b.mass = 1;
  b.I_BBo_B = Vector3d(1, 1, 1).asDiagonal();
  s.bodies.push_back(b);
  Joint free;
  free.name = "base";
  free.type = JointType::Free;
  free.child = 0;
  s.joints.push_back(free);
  const std::vector<std::string> columns{"t", "body.qw", "body.qx", "body.qy", "body.qz"};
  g::FramePicker picker(columns, 1.0, 4);
  for (int k = 0; k <= 4; ++k) {
    const double t = 0.1 * k;
    const double row[] = {t, std::cos(t / 2), 0, 0, std::sin(t / 2)};
    picker.add(row);
  }
  std::vector<g::Configuration> frames = picker.frames(s);
  // Wanted 0, 1/3, 2/3, 1: only 0 and 1/3 (nearest row 0.3 s) lie within the run.
  REQUIRE(frames.size() == 2);
  CHECK(frames[0].t == 0);
  CHECK(frames[1].t == Approx(0.3).epsilon(1e-15));
  CHECK(frames[1].bodies[0].R_NB.isApprox(Eigen::AngleAxisd(0.3, Vector3d::UnitZ()).toRotationMatrix(), 1e-14));
  // A column the drawing needs is missing: a clear error naming it.
  g::FramePicker bad({"t", "body.qw"}, 1.0, 2);
  const double row[] = {0, 1};
  bad.add(row);
  CHECK_THROWS_WITH(bad.frames(s), "the run has no column 'body.qx' to draw from");
}

TEST_CASE("scene geometry: the geometry document has what the drawing script reads") {
  const System s = crossdyn::read_scene(scene("tests/harness/scenes/hinged_panels.yaml"));
  g::MotionSource source;
  source.engine = "kane";
  source.state = "failed";
  source.note = "kane: failed at t = 1 s";
  source.duration = 10;
  const nlohmann::json j = nlohmann::json::parse(
      g::geometry_json(s, g::initial_configuration(s), {}, source, {}));
  CHECK(j["format"] == "crossdyn scene geometry");
  CHECK(j["version"] == 1);
  REQUIRE(j["bodies"].size() == 3);
  CHECK(j["bodies"][0]["is_base"] == true);
  CHECK(j["bodies"][1]["shape"]["type"] == "box");
  CHECK(j["bodies"][1]["nodes"].is_array());  // flexible bodies' nodes go here
  REQUIRE(j["joints"].size() == 3);
  CHECK(j["joints"][1]["has_offset"] == true);
  CHECK(j["joints"][2]["has_offset"] == false);
  CHECK(j["joints"][1]["prescribed"] == false);
  CHECK(j["joints"][1]["axis_P"] == nlohmann::json::array({0.0, -1.0, 0.0}));
  CHECK(j["initial"]["joints"][1]["gap_m"] == 0.0);
  CHECK(j["motion"]["state"] == "failed");
  CHECK(j["motion"]["frames"].empty());
}

TEST_CASE("scene geometry: a joint at a flexible body's node moves and turns with the node") {
  // A flexible beam (base) with a node at (2, 0, 0) whose one mode moves it by (0, 0.1, 0) per unit
  // eta and turns it by 0.05 rad about z per unit eta; a tip mass hinged there about z, its CM 1 m
  // further along its own x. With eta = 2 and both attitudes identity the joint point is at
  // (2, 0.2, 0), the tip's CM at (3, 0.2, 0), and the joint rotation is -0.1 rad about z (the
  // node turned, the tip did not).
  System s;
  s.name = "flex";
  Body beam;
  beam.name = "beam";
  beam.mass = 10;
  beam.I_BBo_B = Vector3d(1, 10, 10).asDiagonal();
  crossdyn::FlexBody flex;
  flex.mode_names = {"m1"};
  crossdyn::FlexNode node;
  node.name = "tip";
  node.mass = 1;
  node.p_BoNi_B = Vector3d(2, 0, 0);
  node.Phi_B = Eigen::Matrix3Xd(3, 1);
  node.Phi_B << 0, 0.1, 0;
  node.Psi_B = Eigen::Matrix3Xd(3, 1);
  node.Psi_B << 0, 0, 0.05;
  flex.nodes.push_back(node);
  beam.flex = flex;
  Body mass;
  mass.name = "mass";
  mass.mass = 1;
  mass.I_BBo_B = Vector3d(0.1, 0.1, 0.1).asDiagonal();
  s.bodies = {beam, mass};
  Joint free;
  free.name = "base";
  free.type = JointType::Free;
  free.child = 0;
  Joint hinge;
  hinge.name = "hinge";
  hinge.type = JointType::Revolute;
  hinge.parent = 0;
  hinge.child = 1;
  hinge.parent_node = 0;
  hinge.p_PoJ_P = Vector3d(2, 0, 0);
  hinge.p_CoJ_C = Vector3d(-1, 0, 0);
  hinge.axis_P = Vector3d::UnitZ();
  s.joints = {free, hinge};
  const std::vector<Matrix3d> R(2, Matrix3d::Identity());
  g::ModalCoordinates eta(2);
  eta[0] = Eigen::VectorXd::Constant(1, 2.0);
  const g::Configuration c = g::place_bodies(s, R, Vector3d::Zero(), 0.5, eta);
  CHECK(c.joints[1].p_NoJ_N_parent.isApprox(Vector3d(2, 0.2, 0), kTight));
  CHECK(c.joints[1].p_NoJ_N_child.isApprox(Vector3d(2, 0.2, 0), kTight));
  CHECK(c.bodies[1].p_NoBo_N.isApprox(Vector3d(3, 0.2, 0), kTight));
  REQUIRE(c.nodes_N[0].size() == 1);
  CHECK(c.nodes_N[0][0].isApprox(Vector3d(2, 0.2, 0), kTight));
  CHECK(c.nodes_N[1].empty());
  CHECK(c.joints[1].phi_J.isApprox(Vector3d(0, 0, -0.1), kTight));
  // Undeformed (no modal coordinates): the rigid placement.
  const g::Configuration u = g::place_bodies(s, R, Vector3d::Zero());
  CHECK(u.bodies[1].p_NoBo_N.isApprox(Vector3d(3, 0, 0), kTight));
  CHECK(u.joints[1].phi_J.norm() == 0);
  // From an output row: the modal column <body>.<mode> is read.
  const std::vector<std::string> columns{"t", "beam.qw", "beam.qx", "beam.qy", "beam.qz",
                                         "mass.qw", "mass.qx", "mass.qy", "mass.qz", "beam.m1"};
  const double row[] = {0.5, 1, 0, 0, 0, 1, 0, 0, 0, 2.0};
  const g::Configuration r = g::configuration_from_row(s, columns, row);
  CHECK((r.bodies[1].p_NoBo_N - r.bodies[0].p_NoBo_N).isApprox(Vector3d(3, 0.2, 0), kTight));
}

// On an orbit the picture shows the orbit frame O (LVLH) at every configuration's time: boom_on_orbit's
// boom is set along nadir (o3) relative to O, pitched by 0.001 rad, so at t = 0 the boom's axis from
// the hub must make that angle with R_NO's third column; off an orbit there is no R_NO.
TEST_CASE("scene geometry: a scene on an orbit carries the orbit frame O at each configuration's time") {
  const System s = crossdyn::read_scene(scene("scenarios/boom_on_orbit.yaml"));
  REQUIRE(s.environment.orbit());
  g::MotionSource source;
  source.engine = "kane";
  source.state = "ok";
  source.duration = s.run.duration;
  const g::Configuration c0 = g::initial_configuration(s);
  g::Configuration later = c0;
  later.t = 1500;
  const nlohmann::json j = nlohmann::json::parse(g::geometry_json(s, c0, {later}, source, {}));
  REQUIRE(j.contains("orbit"));
  const auto R = [](const nlohmann::json& m) {
    Eigen::Matrix3d r;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) r(a, b) = m[static_cast<std::size_t>(a)][static_cast<std::size_t>(b)];
    return r;
  };
  for (const auto& [frame, t] : {std::pair{j["initial"], 0.0}, std::pair{j["motion"]["frames"][0], 1500.0}}) {
    INFO("t = " << t);
    REQUIRE(frame.contains("R_NO"));
    CHECK(R(frame["R_NO"]).isApprox(crossdyn::orbit_frame(s.environment, t).R_NO, 1e-15));
  }
  // The boom (body 1) hangs from the hub along nadir at t = 0, pitched by the scene's 0.001 rad.
  const Vector3d down = c0.bodies[1].p_NoBo_N - c0.bodies[0].p_NoBo_N;
  CHECK(std::acos(down.normalized().dot(R(j["initial"]["R_NO"]).col(2))) == Approx(0.001).epsilon(1e-6));
  // Off an orbit: none.
  const System flat = crossdyn::read_scene(scene("tests/harness/scenes/hinged_panels.yaml"));
  const nlohmann::json k = nlohmann::json::parse(
      g::geometry_json(flat, g::initial_configuration(flat), {}, source, {}));
  CHECK_FALSE(k.contains("orbit"));
  CHECK_FALSE(k["initial"].contains("R_NO"));
}
