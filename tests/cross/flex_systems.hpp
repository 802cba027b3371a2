// Flexible Systems built in code for the cross-engine tests (docs/flexible-bodies.md model), so
// that the tests do not depend on the scene reader's flexible keys:
//   pointing_flex_system()  docs/scenarios.md "Scene 2" (paper Example 2, Table 3): the beam from
//                           the beam generator (core/flex/beam.hpp), payloads hinged at its ends;
//   hub_array_system()      a rigid hub with a cantilevered beam (clamped at its bottom node) on a
//                           fixed joint: the classic flexible solar array;
//   random_flex_tree()      arbitrary modal data (not the modes of any structure: the model is exact
//                           for any shapes and slopes, so random asymmetric data leave no term a
//                           chance to cancel by symmetry) on every joint type, joints at nodes on
//                           both sides, offsets, springs, dampers, motors, modal damping.
// Body::mass and I_BBo_B are the node sums, as the scene reader sets them.
#pragma once

#include "core/flex/beam.hpp"
#include "core/system.hpp"

#include <random>
#include <string>

namespace crossdyn::test {

inline Body beam_body(const std::string& name, const flex::BeamSpec& spec) {
  const flex::FlexModel m = flex::make_beam(spec, name);
  Body b;
  b.name = name;
  b.mass = m.mass;
  b.I_BBo_B = m.I_BBo_B;
  b.flex = m.flex;
  return b;
}

inline Body rigid_body(const std::string& name, double mass, const Eigen::Vector3d& I_diag) {
  Body b;
  b.name = name;
  b.mass = mass;
  b.I_BBo_B = I_diag.asDiagonal();
  return b;
}

inline Joint free_joint(int child) {
  Joint j;
  j.name = "base";
  j.type = JointType::Free;
  j.child = child;
  return j;
}

// The beam of Scene 2: 10 m along z, 50 kg/m (500 kg), 2 x 2 m section, EI = 100 N m^2 in both
// planes, `modes` free-free modes per plane normalised to unit displacement at the top end.
inline flex::BeamSpec scene2_beam(int modes = 2, int slices = 100) {
  flex::BeamSpec s;
  s.length = 10.0;
  s.axis = 2;
  s.mass_per_length = 50.0;
  s.section = {2.0, 2.0, 0.0};
  s.bending[0] = {modes, 100.0};
  s.bending[1] = {modes, 100.0};
  s.boundary = flex::BeamBoundary::FreeFree;
  s.slices = slices;
  s.normalisation = flex::BeamNormalisation::Top;
  return s;
}

// docs/scenarios.md "Scene 2": payload1 hinged at the beam's top node, payload2 at its bottom
// node, about the beam's local y, each payload's CM 1 m from its hinge along +x; hinge motor
// torques +1 N m for 0 <= t < 5 s, -1 N m for 5 <= t < 10 s, then 0 (on the payload, about +y).
inline System pointing_flex_system(int modes = 2, int slices = 100) {
  System s;
  s.name = "pointing_flex (built in code)";
  s.bodies.push_back(beam_body("beam", scene2_beam(modes, slices)));
  s.bodies.push_back(rigid_body("payload1", 100.0, {12.5, 39.6, 39.6}));
  s.bodies.push_back(rigid_body("payload2", 100.0, {12.5, 39.6, 39.6}));
  s.joints.push_back(free_joint(0));
  const FlexBody& f = *s.bodies[0].flex;
  for (int k = 1; k <= 2; ++k) {
    Joint j;
    j.name = "joint" + std::to_string(k);
    j.type = JointType::Revolute;
    j.parent = 0;
    j.child = k;
    j.parent_node = f.node_index(k == 1 ? "top" : "bottom");
    j.p_PoJ_P = f.nodes[static_cast<std::size_t>(j.parent_node)].p_BoNi_B;
    j.p_CoJ_C = Eigen::Vector3d(-1.0, 0.0, 0.0);
    j.axis_P = Eigen::Vector3d::UnitY();
    j.motor_revolute.times = {0.0, 5.0, 10.0};
    j.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(1.0), Eigen::Matrix<double, 1, 1>(-1.0),
                               Eigen::Matrix<double, 1, 1>(0.0)};
    s.joints.push_back(j);
  }
  s.run.duration = 60.0;
  s.run.output_step = 0.1;
  s.run.integrator = "rkf78";
  s.run.rtol = s.run.atol = 1e-12;
  return s;
}

// A rigid 1000 kg hub (the base) spinning slowly, with a 6 m cantilevered array (clamped at its
// bottom node) on a fixed joint at the hub's +x face, the array's long axis along the hub's +x;
// modal damping 0.5 % per mode; a torque on the hub for the first second.
inline System hub_array_system(int modes = 2) {
  System s;
  s.name = "hub_array (built in code)";
  Body hub = rigid_body("hub", 1000.0, {400.0, 500.0, 600.0});
  hub.torque.times = {0.0, 1.0};
  hub.torque.values = {Eigen::Vector3d(0.0, 5.0, 20.0), Eigen::Vector3d::Zero()};
  s.bodies.push_back(hub);
  flex::BeamSpec a;
  a.length = 6.0;
  a.axis = 2;
  a.mass_per_length = 5.0;
  a.section = {2.0, 0.05, 0.0};
  a.bending[0] = {modes, 2000.0};
  a.bending[1] = {modes, 500.0};
  a.boundary = flex::BeamBoundary::ClampedBottom;
  a.slices = 60;
  a.damping.kind = flex::BeamDamping::Kind::Ratio;
  a.damping.ratios = {0.005};
  s.bodies.push_back(beam_body("array", a));
  s.joints.push_back(free_joint(0));
  s.joints[0].w_NB_B0 = Eigen::Vector3d(0.0, 0.0, 0.05);
  Joint j;
  j.name = "root";
  j.type = JointType::Fixed;
  j.parent = 0;
  j.child = 1;
  j.child_node = s.bodies[1].flex->node_index("bottom");
  j.p_PoJ_P = Eigen::Vector3d(1.0, 0.0, 0.0);
  j.p_CoJ_C = s.bodies[1].flex->nodes[static_cast<std::size_t>(j.child_node)].p_BoNi_B;
  // The array's z (long) axis along the hub's x: a quarter turn about the hub's y.
  j.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()));
  s.joints.push_back(j);
  s.run.duration = 20.0;
  s.run.output_step = 0.1;
  s.run.integrator = "rkf78";
  s.run.rtol = s.run.atol = 1e-12;
  return s;
}

// A flexible body with `nodes` nodes of random mass (1..3 kg), positions spread ~1 m (shifted so
// that sum m p = 0), random node inertias, shapes and slopes, K diagonal (stiffness per mode
// 30..60 N/m), D = damping * K.
inline Body random_flex_body(const std::string& name, int nodes, int modes, std::mt19937& g,
                             double damping) {
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  Body b;
  b.name = name;
  b.flex = FlexBody{};
  FlexBody& f = *b.flex;
  Eigen::Vector3d first_moment = Eigen::Vector3d::Zero();
  double mass = 0;
  for (int i = 0; i < nodes; ++i) {
    FlexNode n;
    n.name = "n" + std::to_string(i + 1);
    n.mass = 2.0 + U(g);
    n.p_BoNi_B = Eigen::Vector3d(U(g), U(g), U(g));
    const Eigen::Matrix3d A = Eigen::Matrix3d::Random() * 0.05;
    n.J_Ni_B = A * A.transpose() + 0.01 * Eigen::Matrix3d::Identity();
    n.Phi_B = Eigen::Matrix3Xd::Random(3, modes) * 0.6;
    n.Psi_B = Eigen::Matrix3Xd::Random(3, modes) * 0.8;
    first_moment += n.mass * n.p_BoNi_B;
    mass += n.mass;
    f.nodes.push_back(n);
  }
  for (FlexNode& n : f.nodes) n.p_BoNi_B -= first_moment / mass;
  f.K = Eigen::MatrixXd::Zero(modes, modes);
  for (int k = 0; k < modes; ++k) f.K(k, k) = 45.0 + 15.0 * U(g);
  f.D = damping * f.K;
  for (int k = 1; k <= modes; ++k) f.mode_names.push_back("q" + std::to_string(k));
  f.origin = "random, built in code";
  b.mass = 0;
  b.I_BBo_B.setZero();
  for (const FlexNode& n : f.nodes) {
    b.mass += n.mass;
    b.I_BBo_B += n.J_Ni_B + n.mass * (n.p_BoNi_B.squaredNorm() * Eigen::Matrix3d::Identity() -
                                      n.p_BoNi_B * n.p_BoNi_B.transpose());
  }
  return b;
}

// flexA (base, 6 nodes, 3 modes) --revolute at node n2, offset--> rigid B
//   B --spherical--> flexC (5 nodes, 2 modes) at C's node n4
//   flexA --fixed at node n5, offset--> rigid D
//   flexC --revolute at node n1 (both sides flexible: flexE's node n3)--> flexE (4 nodes, 1 mode)
inline System random_flex_tree(unsigned seed = 7) {
  std::mt19937 g(seed);
  std::srand(seed);  // Eigen's Random()
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  auto vec = [&](double s) -> Eigen::Vector3d { return Eigen::Vector3d(U(g), U(g), U(g)) * s; };
  auto quat = [&]() {
    return Eigen::Quaterniond(1.0 + U(g), U(g), U(g), U(g)).normalized();
  };
  System s;
  s.name = "random flexible tree (built in code)";
  s.bodies.push_back(random_flex_body("flexA", 6, 3, g, 0.02));
  s.bodies.push_back(rigid_body("B", 4.0, {0.3, 0.5, 0.6}));
  s.bodies.push_back(random_flex_body("flexC", 5, 2, g, 0.0));
  s.bodies.push_back(rigid_body("D", 2.0, {0.2, 0.25, 0.3}));
  s.bodies.push_back(random_flex_body("flexE", 4, 1, g, 0.05));
  auto node_pos = [&](int body, int node) {
    return s.bodies[static_cast<std::size_t>(body)].flex->nodes[static_cast<std::size_t>(node)].p_BoNi_B;
  };
  s.joints.push_back(free_joint(0));
  s.joints[0].w_NB_B0 = vec(0.5);
  Joint ab;
  ab.name = "jB";
  ab.type = JointType::Revolute;
  ab.parent = 0;
  ab.child = 1;
  ab.parent_node = 1;
  ab.p_PoJ_P = node_pos(0, 1);
  ab.p_CoJ_C = vec(0.5);
  ab.axis_P = vec(1.0).normalized();
  ab.q_PJ0 = quat();
  ab.stiffness = 3.0;
  ab.neutral_angle = 0.2;
  ab.damping = 0.4;
  ab.motor_revolute.times = {0.0, 0.3};
  ab.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(0.7), Eigen::Matrix<double, 1, 1>(-0.2)};
  ab.angle0 = 0.3;
  ab.rate0 = -0.4;
  s.joints.push_back(ab);
  Joint bc;
  bc.name = "jC";
  bc.type = JointType::Spherical;
  bc.parent = 1;
  bc.child = 2;
  bc.child_node = 3;
  bc.p_PoJ_P = vec(0.4);
  bc.p_CoJ_C = node_pos(2, 3);
  bc.q_PJ0 = quat();
  bc.stiffness = 2.0;
  bc.damping = 0.3;
  bc.motor_spherical.times = {0.0};
  bc.motor_spherical.values = {Eigen::Vector3d(0.1, -0.2, 0.05)};
  bc.q_J0 = quat();
  bc.w_PC_C0 = vec(0.3);
  s.joints.push_back(bc);
  Joint ad;
  ad.name = "jD";
  ad.type = JointType::Fixed;
  ad.parent = 0;
  ad.child = 3;
  ad.parent_node = 4;
  ad.p_PoJ_P = node_pos(0, 4);
  ad.p_CoJ_C = vec(0.3);
  ad.q_PJ0 = quat();
  s.joints.push_back(ad);
  Joint ce;
  ce.name = "jE";
  ce.type = JointType::Revolute;
  ce.parent = 2;
  ce.child = 4;
  ce.parent_node = 0;
  ce.child_node = 2;
  ce.p_PoJ_P = node_pos(2, 0);
  ce.p_CoJ_C = node_pos(4, 2);
  ce.axis_P = vec(1.0).normalized();
  ce.q_PJ0 = quat();
  ce.damping = 0.2;
  ce.angle0 = -0.5;
  ce.rate0 = 0.6;
  s.joints.push_back(ce);
  s.run.duration = 3.0;
  s.run.output_step = 0.05;
  s.run.integrator = "rkf78";
  s.run.rtol = s.run.atol = 1e-12;
  return s;
}

}  // namespace crossdyn::test
