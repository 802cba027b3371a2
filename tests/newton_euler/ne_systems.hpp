// Systems built in code for the Newton-Euler engine's tests, and helpers to read the engine's
// state through its public labels (never through its internals).
#pragma once

#include "core/engine.hpp"
#include "core/errors.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace crossdyn::test::ne {

inline Body make_body(const std::string& name, double mass, const Eigen::Matrix3d& I) {
  Body b;
  b.name = name;
  b.mass = mass;
  b.I_BBo_B = I;
  return b;
}

inline Joint free_joint(int child) {
  Joint j;
  j.name = "base";
  j.type = JointType::Free;
  j.child = child;
  return j;
}

// chainN of ../shared/SCENARIOS.md "Scene 3": N links of 10 kg, diag(0.1, 3.4, 3.4) kg m^2, 2 m
// long along x, spherical joints from (1, 0, 0) of link k-1 to (-1, 0, 0) of link k; link1 spins at
// (0.3, 0.2, 0.5) rad/s, every joint at (0.1, -0.2, 0.3) rad/s in the child frame.
inline System chain(int n) {
  System s;
  s.name = "chain" + std::to_string(n);
  for (int k = 1; k <= n; ++k)
    s.bodies.push_back(make_body("link" + std::to_string(k), 10.0,
                                 Eigen::Vector3d(0.1, 3.4, 3.4).asDiagonal().toDenseMatrix()));
  Joint base = free_joint(0);
  base.w_NB_B0 = Eigen::Vector3d(0.3, 0.2, 0.5);
  s.joints.push_back(base);
  for (int k = 2; k <= n; ++k) {
    Joint j;
    j.name = "joint" + std::to_string(k);
    j.type = JointType::Spherical;
    j.parent = k - 2;
    j.child = k - 1;
    j.p_PoJ_P = Eigen::Vector3d(1, 0, 0);
    j.p_CoJ_C = Eigen::Vector3d(-1, 0, 0);
    j.w_PC_C0 = Eigen::Vector3d(0.1, -0.2, 0.3);
    s.joints.push_back(j);
  }
  return s;
}

// SPEAR-1 case I (../shared/SCENARIOS.md "Scene 1"), for tests that must not wait for files.
inline System spear1() {
  System s;
  s.name = "spear1_case1_code";
  s.bodies.push_back(make_body("main", 300, Eigen::Vector3d(100, 400, 400).asDiagonal().toDenseMatrix()));
  s.bodies.push_back(make_body("boom1", 10, 10 * Eigen::Matrix3d::Identity()));
  s.bodies.push_back(make_body("boom2", 10, 10 * Eigen::Matrix3d::Identity()));
  Joint base = free_joint(0);
  base.w_NB_B0 = Eigen::Vector3d(std::numbers::pi / 2, 0, 0);  // 90 deg/s
  s.joints.push_back(base);
  for (int k = 1; k <= 2; ++k) {
    Joint j;
    j.name = "hinge" + std::to_string(k);
    j.type = JointType::Revolute;
    j.parent = 0;
    j.child = k;
    j.p_PoJ_P = Eigen::Vector3d(6, 0, 0);
    j.p_CoJ_C = Eigen::Vector3d(-2, 0, 0);
    j.axis_P = Eigen::Vector3d::UnitZ();
    j.rate0 = (k == 1 ? 1 : -1) * 10.0 * std::numbers::pi / 180;
    s.joints.push_back(j);
  }
  return s;
}

// A tree with every joint type, joint offsets, an oblique revolute axis, full inertia tensors,
// springs on the revolute and spherical joints (no damping, so energy is conserved):
//   hub (free) -> arm (revolute, oblique axis, offset) -> ball (spherical, offset) -> tip (revolute)
//   hub -> plate (fixed, offset)
inline System mixed_tree() {
  System s;
  s.name = "mixed_tree";
  Eigen::Matrix3d I_hub, I_arm, I_ball, I_plate, I_tip;
  I_hub << 50, 2, -1, 2, 60, 3, -1, 3, 70;
  I_arm << 4, 0.5, 0.2, 0.5, 3, -0.3, 0.2, -0.3, 2;
  I_ball << 1.5, 0, 0.1, 0, 1.2, 0, 0.1, 0, 1.0;
  I_plate << 8, -0.4, 0, -0.4, 5, 0.6, 0, 0.6, 10;
  I_tip << 0.3, 0.05, 0, 0.05, 0.4, 0, 0, 0, 0.5;
  s.bodies = {make_body("hub", 200, I_hub), make_body("arm", 20, I_arm),
              make_body("ball", 8, I_ball), make_body("plate", 30, I_plate),
              make_body("tip", 2, I_tip)};
  Joint base = free_joint(0);
  base.q_NB0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()));
  base.w_NB_B0 = Eigen::Vector3d(0.2, -0.1, 0.3);
  s.joints.push_back(base);

  Joint arm;
  arm.name = "shoulder";
  arm.type = JointType::Revolute;
  arm.parent = 0;
  arm.child = 1;
  arm.p_PoJ_P = Eigen::Vector3d(1.0, 0.5, -0.2);
  arm.p_CoJ_C = Eigen::Vector3d(-0.8, 0.1, 0.05);
  arm.axis_P = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
  arm.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(0, 1, 1).normalized()));
  arm.stiffness = 30;
  arm.neutral_angle = 0.3;
  arm.angle0 = 2.5;
  arm.rate0 = 0.8;
  s.joints.push_back(arm);

  Joint ball;
  ball.name = "wrist";
  ball.type = JointType::Spherical;
  ball.parent = 1;
  ball.child = 2;
  ball.p_PoJ_P = Eigen::Vector3d(0.9, -0.1, 0.0);
  ball.p_CoJ_C = Eigen::Vector3d(-0.3, 0.0, 0.1);
  ball.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(-0.5, Eigen::Vector3d(1, 0, 1).normalized()));
  ball.stiffness = 5;
  ball.q_J0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.6, Eigen::Vector3d(1, -1, 2).normalized()));
  ball.w_PC_C0 = Eigen::Vector3d(0.3, -0.4, 0.5);
  s.joints.push_back(ball);

  Joint plate;
  plate.name = "mount";
  plate.type = JointType::Fixed;
  plate.parent = 0;
  plate.child = 3;
  plate.p_PoJ_P = Eigen::Vector3d(-1.0, 0.0, 0.7);
  plate.p_CoJ_C = Eigen::Vector3d(0.4, 0.3, 0.0);
  plate.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(1.1, Eigen::Vector3d(2, 1, 0).normalized()));
  s.joints.push_back(plate);

  Joint tip;
  tip.name = "finger";
  tip.type = JointType::Revolute;
  tip.parent = 2;
  tip.child = 4;
  tip.p_PoJ_P = Eigen::Vector3d(0.3, 0.2, 0.0);
  tip.p_CoJ_C = Eigen::Vector3d(-0.25, 0.0, 0.0);
  tip.axis_P = Eigen::Vector3d(0, 1, 0);
  tip.stiffness = 2;
  tip.angle0 = -0.4;
  tip.rate0 = -1.5;
  s.joints.push_back(tip);
  s.zero_linear_momentum = false;
  return s;
}

// A random engine-neutral state for `system` (angles over several turns, unit quaternions).
inline TreeState random_state(const System& system, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&] { return Eigen::Vector3d(u(rng), u(rng), u(rng)); };
  auto quat = [&] {
    return Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
  };
  TreeState s = TreeState::initial(system);
  s.p_NoBo_N = vec();
  s.q_NB = quat();
  s.v_NBo_N = vec();
  s.w_NB_B = vec();
  for (std::size_t j = 1; j < system.joints.size(); ++j) {
    s.joints[j].angle = 6.0 * u(rng);
    s.joints[j].rate = 2.0 * u(rng);
    s.joints[j].q_J = quat();
    s.joints[j].w_PC_C = vec();
  }
  return s;
}

// One body's maximal coordinates, read from an engine state through its labels.
struct BodyState {
  Eigen::Vector3d p_N, v_N, w_B;
  Eigen::Quaterniond q_NB;
  Eigen::Matrix3d R_NB;
};

inline int label_index(const Engine& e, const std::string& label) {
  for (int i = 0; i < e.state_size(); ++i)
    if (e.state_label(i) == label) return i;
  throw std::runtime_error("no state label " + label);
}

inline BodyState body_state(const Engine& e, const double* x, const std::string& body) {
  const int ip = label_index(e, body + ".x"), iq = label_index(e, body + ".qw");
  const int iv = label_index(e, body + ".vx"), iw = label_index(e, body + ".wx");
  BodyState b;
  b.p_N = Eigen::Vector3d(x[ip], x[ip + 1], x[ip + 2]);
  b.q_NB = Eigen::Quaterniond(x[iq], x[iq + 1], x[iq + 2], x[iq + 3]).normalized();
  b.R_NB = b.q_NB.toRotationMatrix();
  b.v_N = Eigen::Vector3d(x[iv], x[iv + 1], x[iv + 2]);
  b.w_B = Eigen::Vector3d(x[iw], x[iw + 1], x[iw + 2]);
  return b;
}

inline int column(const Engine& e, const std::string& name) {
  const auto& c = e.columns();
  for (std::size_t i = 0; i < c.size(); ++i)
    if (c[i] == name) return static_cast<int>(i);
  throw std::runtime_error("no column " + name);
}

}  // namespace crossdyn::test::ne
