// Systems built in code for the Lagrange engine's tests (the pinned scenes of
// docs/scenarios.md where the tests need them without the scene reader, plus small cases).
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include "core/engine.hpp"
#include "core/system.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"

namespace crossdyn::test {

inline constexpr double kDegree = std::numbers::pi / 180.0;

inline Body make_body(const std::string& name, double mass, const Eigen::Vector3d& inertia) {
  Body b;
  b.name = name;
  b.mass = mass;
  b.I_BBo_B = inertia.asDiagonal();
  return b;
}

inline Joint free_joint(int child, const Eigen::Vector3d& w0) {
  Joint j;
  j.name = "base";
  j.type = JointType::Free;
  j.child = child;
  j.w_NB_B0 = w0;
  return j;
}

// SPEAR-1 (Scene 1): rate2 = -10 deg/s for case 1, -5 deg/s for case 2.
inline System spear1(double rate2_deg = -10.0, bool spherical = false) {
  System s;
  s.name = spherical ? "spear1_case1_spherical" : "spear1_case1";
  s.bodies = {make_body("main", 300, {100, 400, 400}), make_body("boom1", 10, {10, 10, 10}),
              make_body("boom2", 10, {10, 10, 10})};
  s.joints.push_back(free_joint(0, {90 * kDegree, 0, 0}));
  for (int k = 1; k <= 2; ++k) {
    Joint j;
    j.name = "hinge" + std::to_string(k);
    j.type = spherical ? JointType::Spherical : JointType::Revolute;
    j.parent = 0;
    j.child = k;
    j.p_PoJ_P = {6, 0, 0};
    j.p_CoJ_C = {-2, 0, 0};
    j.axis_P = Eigen::Vector3d::UnitZ();
    const double rate = (k == 1 ? 10.0 : rate2_deg) * kDegree;
    j.rate0 = rate;
    j.w_PC_C0 = {0, 0, rate};
    s.joints.push_back(j);
  }
  s.run.duration = 5;
  s.run.output_step = 0.05;
  return s;
}

// chainN (Scene 3): N links joined by spherical joints.
inline System chain(int links) {
  System s;
  s.name = "chain" + std::to_string(links);
  for (int k = 1; k <= links; ++k)
    s.bodies.push_back(make_body("link" + std::to_string(k), 10, {0.1, 3.4, 3.4}));
  s.joints.push_back(free_joint(0, {0.3, 0.2, 0.5}));
  for (int k = 2; k <= links; ++k) {
    Joint j;
    j.name = "joint" + std::to_string(k);
    j.type = JointType::Spherical;
    j.parent = k - 2;
    j.child = k - 1;
    j.p_PoJ_P = {1, 0, 0};
    j.p_CoJ_C = {-1, 0, 0};
    j.w_PC_C0 = {0.1, -0.2, 0.3};
    s.joints.push_back(j);
  }
  s.run.duration = 10;
  s.run.output_step = 0.1;
  return s;
}

// A tree with every feature the engine supports: a revolute joint with a fixed orientation
// offset, spring, damper and motor; spherical joints with springs, dampers and motors; a fixed
// joint; a full (non-diagonal) inertia; body torques in both frames.
inline System mixed_tree(bool loads) {
  System s;
  s.name = "mixed_tree";
  s.bodies = {make_body("core", 50, {8, 11, 14}), make_body("arm", 5, {0.4, 2.0, 2.1}),
              make_body("hand", 2, {0.1, 0.2, 0.25}), make_body("panel", 3, {1.0, 0.5, 1.4}),
              make_body("tip", 1, {0.05, 0.06, 0.07})};
  s.bodies[0].I_BBo_B(0, 1) = s.bodies[0].I_BBo_B(1, 0) = 0.7;
  s.bodies[0].I_BBo_B(1, 2) = s.bodies[0].I_BBo_B(2, 1) = -0.4;
  s.joints.push_back(free_joint(0, {0.2, -0.1, 0.3}));
  Joint arm;
  arm.name = "shoulder";
  arm.type = JointType::Spherical;
  arm.parent = 0;
  arm.child = 1;
  arm.p_PoJ_P = {1.0, 0.2, 0.0};
  arm.p_CoJ_C = {-0.8, 0.0, 0.1};
  arm.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()));
  arm.q_J0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(-1, 0.5, 2).normalized()));
  arm.w_PC_C0 = {0.1, 0.4, -0.2};
  Joint hand;
  hand.name = "wrist";
  hand.type = JointType::Revolute;
  hand.parent = 1;
  hand.child = 2;
  hand.p_PoJ_P = {0.8, 0.0, 0.0};
  hand.p_CoJ_C = {-0.3, 0.05, 0.0};
  hand.axis_P = Eigen::Vector3d(0.2, 1.0, 0.3).normalized();
  hand.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(-0.3, Eigen::Vector3d(0, 0, 1)));
  hand.angle0 = 0.5;
  hand.rate0 = -0.6;
  Joint panel;
  panel.name = "mount";
  panel.type = JointType::Fixed;
  panel.parent = 0;
  panel.child = 3;
  panel.p_PoJ_P = {-1.0, 0.0, 0.5};
  panel.p_CoJ_C = {0.6, 0.0, 0.0};
  panel.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.9, Eigen::Vector3d(0, 1, 0)));
  Joint tip;
  tip.name = "knuckle";
  tip.type = JointType::Spherical;
  tip.parent = 2;
  tip.child = 4;
  tip.p_PoJ_P = {0.3, 0.0, 0.0};
  tip.p_CoJ_C = {-0.2, 0.0, 0.0};
  tip.q_J0 = Eigen::Quaterniond(Eigen::AngleAxisd(1.2, Eigen::Vector3d(0.3, 1, 0).normalized()));
  tip.w_PC_C0 = {-0.3, 0.2, 0.5};
  if (loads) {
    arm.stiffness = 3.0;
    arm.damping = 0.4;
    arm.motor_spherical.times = {0.0, 1.0};
    arm.motor_spherical.values = {Eigen::Vector3d(0.2, -0.1, 0.05), Eigen::Vector3d(0, 0, 0)};
    hand.stiffness = 2.0;
    hand.neutral_angle = 0.2;
    hand.damping = 0.3;
    hand.motor_revolute.times = {0.0, 0.5};
    hand.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(0.3),
                                  Eigen::Matrix<double, 1, 1>(-0.1)};
    tip.stiffness = 0.5;
    s.bodies[0].torque.times = {0.0};
    s.bodies[0].torque.values = {Eigen::Vector3d(0.5, -0.2, 0.1)};
    s.bodies[2].torque_frame = Body::Frame::Inertial;
    s.bodies[2].torque.times = {0.0};
    s.bodies[2].torque.values = {Eigen::Vector3d(-0.1, 0.3, 0.2)};
  }
  s.joints.push_back(arm);
  s.joints.push_back(hand);
  s.joints.push_back(panel);
  s.joints.push_back(tip);
  s.run.duration = 4;
  s.run.output_step = 0.1;
  return s;
}

inline Eigen::Quaterniond random_quaternion(std::mt19937& g) {
  std::normal_distribution<double> n;
  return Eigen::Quaterniond(n(g), n(g), n(g), n(g)).normalized();
}

// A random state of the tree: any attitude, rates of order one.
inline TreeState random_state(const System& system, std::mt19937& g) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&](double scale) -> Eigen::Vector3d {
    return Eigen::Vector3d(u(g), u(g), u(g)) * scale;
  };
  TreeState s = TreeState::initial(system);
  s.p_NoBo_N = vec(5.0);
  s.q_NB = random_quaternion(g);
  s.v_NBo_N = vec(1.0);
  s.w_NB_B = vec(2.0);
  for (std::size_t j = 0; j < system.joints.size(); ++j) {
    s.joints[j].angle = 3.0 * u(g);
    s.joints[j].rate = 2.0 * u(g);
    s.joints[j].q_J = random_quaternion(g);
    s.joints[j].w_PC_C = vec(1.0);
  }
  return s;
}

}  // namespace crossdyn::test
