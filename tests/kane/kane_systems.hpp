// Systems built in code for the Kane engine's tests, a fixed-step RK4 loop and random states.
// The mass and geometry values of mixed_tree() are arbitrary, chosen only to be asymmetric (no
// principal axes aligned, non-zero offsets everywhere) so that no term can cancel by symmetry.
#pragma once

#include "core/engine.hpp"
#include "core/system.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace crossdyn::test::kane {

inline Eigen::Quaterniond quat_from_axis(double angle, Eigen::Vector3d axis) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis.normalized()));
}

inline Body rigid_body(const std::string& name, double mass, const Eigen::Matrix3d& I_BBo_B) {
  Body b;
  b.name = name;
  b.mass = mass;
  b.I_BBo_B = I_BBo_B;
  return b;
}

inline Eigen::Matrix3d diag(double a, double b, double c) {
  return Eigen::Vector3d(a, b, c).asDiagonal();
}

// A symmetric positive definite inertia with the given principal moments, turned by q.
inline Eigen::Matrix3d turned_inertia(double a, double b, double c, const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d R = q.toRotationMatrix();
  return R * diag(a, b, c) * R.transpose();
}

inline Joint free_joint(const std::string& name, int child, const Eigen::Vector3d& w_NB_B0,
                        const Eigen::Quaterniond& q_NB0 = Eigen::Quaterniond::Identity()) {
  Joint j;
  j.name = name;
  j.type = JointType::Free;
  j.parent = -1;
  j.child = child;
  j.w_NB_B0 = w_NB_B0;
  j.q_NB0 = q_NB0;
  return j;
}

inline Joint joint(const std::string& name, JointType type, int parent, int child,
                   const Eigen::Vector3d& p_PoJ_P, const Eigen::Vector3d& p_CoJ_C) {
  Joint j;
  j.name = name;
  j.type = type;
  j.parent = parent;
  j.child = child;
  j.p_PoJ_P = p_PoJ_P;
  j.p_CoJ_C = p_CoJ_C;
  return j;
}

// One free rigid body.
inline System single_body(const Eigen::Matrix3d& I_BBo_B, const Eigen::Vector3d& w_NB_B0,
                          double mass = 10.0) {
  System s;
  s.name = "single_body";
  s.bodies.push_back(rigid_body("body", mass, I_BBo_B));
  s.joints.push_back(free_joint("base", 0, w_NB_B0));
  return s;
}

// docs/scenarios.md "Scene 1", spear1_case1, built in code (same data as the scene file).
inline System spear1_case1() {
  const double deg = M_PI / 180.0;
  System s;
  s.name = "spear1_case1_code";
  s.bodies.push_back(rigid_body("main", 300, diag(100, 400, 400)));
  s.bodies.push_back(rigid_body("boom1", 10, diag(10, 10, 10)));
  s.bodies.push_back(rigid_body("boom2", 10, diag(10, 10, 10)));
  s.joints.push_back(free_joint("base", 0, Eigen::Vector3d(90 * deg, 0, 0)));
  for (int i = 1; i <= 2; ++i) {
    Joint h = joint("hinge" + std::to_string(i), JointType::Revolute, 0, i,
                    Eigen::Vector3d(6, 0, 0), Eigen::Vector3d(-2, 0, 0));
    h.axis_P = Eigen::Vector3d::UnitZ();
    h.rate0 = (i == 1 ? 10 : -10) * deg;
    s.joints.push_back(h);
  }
  s.run.duration = 5;
  s.run.output_step = 0.05;
  return s;
}

// docs/scenarios.md "Scene 3", chainN, built in code.
inline System chain(int links) {
  System s;
  s.name = "chain" + std::to_string(links);
  for (int k = 1; k <= links; ++k)
    s.bodies.push_back(rigid_body("link" + std::to_string(k), 10, diag(0.1, 3.4, 3.4)));
  s.joints.push_back(free_joint("base", 0, Eigen::Vector3d(0.3, 0.2, 0.5)));
  for (int k = 2; k <= links; ++k) {
    Joint j = joint("joint" + std::to_string(k), JointType::Spherical, k - 2, k - 1,
                    Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(-1, 0, 0));
    j.w_PC_C0 = Eigen::Vector3d(0.1, -0.2, 0.3);
    s.joints.push_back(j);
  }
  return s;
}

// Every joint type, with orientation offsets, off-axis joint points, non-diagonal inertias and
// hinge springs; a fixed joint below the base and one below a spherical joint.
//   core (free) -+- arm (revolute, spring) -- wrist (spherical, spring) -+- tip (revolute)
//                |                                                       +- sensor (fixed)
//                +- plate (fixed) -- antenna (spherical)
inline System mixed_tree() {
  using Eigen::Vector3d;
  System s;
  s.name = "mixed_tree";
  s.bodies.push_back(
      rigid_body("core", 200, turned_inertia(120, 150, 180, quat_from_axis(0.4, {1, 2, 3}))));
  s.bodies.push_back(
      rigid_body("arm", 15, turned_inertia(2, 3, 4, quat_from_axis(0.7, {-1, 0, 2}))));
  s.bodies.push_back(
      rigid_body("wrist", 5, turned_inertia(0.5, 0.6, 0.9, quat_from_axis(1.1, {0, 1, 1}))));
  s.bodies.push_back(
      rigid_body("tip", 2, turned_inertia(0.1, 0.2, 0.25, quat_from_axis(0.3, {1, 1, 0}))));
  s.bodies.push_back(
      rigid_body("sensor", 1.5, turned_inertia(0.05, 0.07, 0.08, quat_from_axis(0.9, {2, -1, 1}))));
  s.bodies.push_back(
      rigid_body("plate", 8, turned_inertia(1, 1.5, 2.2, quat_from_axis(-0.5, {0, 0, 1}))));
  s.bodies.push_back(
      rigid_body("antenna", 3, turned_inertia(0.3, 0.35, 0.5, quat_from_axis(0.6, {1, -2, 0}))));

  s.joints.push_back(
      free_joint("base", 0, Vector3d(0.2, -0.1, 0.5), quat_from_axis(0.8, {1, -1, 2})));
  s.joints.back().p_NoBo_N0 = Vector3d(3, -4, 5);

  Joint arm = joint("shoulder", JointType::Revolute, 0, 1, {1.0, 0.5, -0.2}, {-0.8, 0.1, 0.05});
  arm.axis_P = Vector3d(0.3, 0.4, 0.866).normalized();
  arm.q_PJ0 = quat_from_axis(0.25, {0, 1, 0});
  arm.stiffness = 20;
  arm.neutral_angle = 0.1;
  arm.angle0 = 0.3;
  arm.rate0 = 0.4;
  s.joints.push_back(arm);

  Joint wrist = joint("wristj", JointType::Spherical, 1, 2, {0.9, 0.0, 0.1}, {-0.5, 0.2, 0.0});
  wrist.q_PJ0 = quat_from_axis(-0.6, {1, 0, 1});
  wrist.stiffness = 5;
  wrist.q_J0 = quat_from_axis(0.5, {2, 1, -1});
  wrist.w_PC_C0 = Vector3d(0.3, -0.2, 0.1);
  s.joints.push_back(wrist);

  Joint tip = joint("finger", JointType::Revolute, 2, 3, {0.4, -0.1, 0.2}, {-0.3, 0.0, 0.1});
  tip.axis_P = Vector3d(1, -1, 0.5).normalized();
  tip.angle0 = -0.2;
  tip.rate0 = -0.6;
  s.joints.push_back(tip);

  Joint sensor = joint("mount", JointType::Fixed, 2, 4, {-0.1, 0.3, 0.0}, {0.1, -0.2, 0.05});
  sensor.q_PJ0 = quat_from_axis(1.2, {0, 1, -1});
  s.joints.push_back(sensor);

  Joint plate = joint("bolt", JointType::Fixed, 0, 5, {0.0, -1.2, 0.3}, {0.2, 0.3, 0.0});
  plate.q_PJ0 = quat_from_axis(0.7, {1, 0, 0});
  s.joints.push_back(plate);

  Joint antenna = joint("gimbal", JointType::Spherical, 5, 6, {0.5, 0.0, 0.4}, {0.0, 0.0, -0.6});
  antenna.stiffness = 3;
  antenna.q_J0 = quat_from_axis(-0.4, {0, 1, 2});
  antenna.w_PC_C0 = Vector3d(-0.2, 0.4, 0.3);
  s.joints.push_back(antenna);
  return s;
}

// Fixed-step classical Runge-Kutta (Hairer, Norsett & Wanner I, Table 1.2) over `steps` steps of
// dt, calling engine.after_step() after each step and observe(t, x) at the start and after each.
template <typename Observe>
void rk4(Engine& engine, std::vector<double>& x, double t0, double dt, int steps, Observe observe) {
  const std::size_t n = x.size();
  std::vector<double> k1(n), k2(n), k3(n), k4(n), y(n);
  double t = t0;
  observe(t, x);
  for (int s = 0; s < steps; ++s) {
    engine.rhs(t, x.data(), k1.data());
    for (std::size_t i = 0; i < n; ++i) y[i] = x[i] + 0.5 * dt * k1[i];
    engine.rhs(t + 0.5 * dt, y.data(), k2.data());
    for (std::size_t i = 0; i < n; ++i) y[i] = x[i] + 0.5 * dt * k2[i];
    engine.rhs(t + 0.5 * dt, y.data(), k3.data());
    for (std::size_t i = 0; i < n; ++i) y[i] = x[i] + dt * k3[i];
    engine.rhs(t + dt, y.data(), k4.data());
    for (std::size_t i = 0; i < n; ++i) x[i] += dt / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
    t = t0 + (s + 1) * dt;
    engine.after_step(t, x.data());
    observe(t, x);
  }
}

// A random tree state for `system` (uniform random attitudes, speeds of order 1).
inline TreeState random_state(const System& system, std::mt19937& g) {
  std::normal_distribution<double> n;
  auto quat = [&] { return Eigen::Quaterniond(n(g), n(g), n(g), n(g)).normalized(); };
  auto vec = [&] { return Eigen::Vector3d(n(g), n(g), n(g)); };
  TreeState s = TreeState::initial(system);
  s.p_NoBo_N = vec();
  s.q_NB = quat();
  s.v_NBo_N = vec();
  s.w_NB_B = vec();
  for (std::size_t j = 1; j < system.joints.size(); ++j) {
    s.joints[j].angle = n(g);
    s.joints[j].rate = n(g);
    s.joints[j].q_J = quat();
    s.joints[j].w_PC_C = vec();
  }
  return s;
}

// The engine's state vector for a tree state.
inline std::vector<double> packed(Engine& e, const TreeState& s) {
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(s, x.data());
  return x;
}

// x + h xdot (a step along the motion; the engine normalises quaternions where it reads them).
inline std::vector<double> along(const std::vector<double>& x, const std::vector<double>& xdot,
                                 double h) {
  std::vector<double> y(x);
  for (std::size_t i = 0; i < y.size(); ++i) y[i] += h * xdot[i];
  return y;
}

// d/dh f(h) at h = 0 by the five-point central difference (error O(h^4)).
template <typename F>
auto derivative(F f, double h) -> decltype(f(h)) {
  using Value = decltype(f(h));  // evaluated (Eigen expressions must not outlive their operands)
  const Value d = (8.0 * (f(h) - f(-h)) - (f(2 * h) - f(-2 * h))) / (12.0 * h);
  return d;
}

}  // namespace crossdyn::test::kane
