// Flexible Systems built in code for the Lagrange engine's tests (docs/flexible-bodies.md): small,
// readable bodies with a known structure, random bodies with realistic deformations, and a tree
// with every kind of joint at nodes.
#pragma once

#include <Eigen/Geometry>
#include <random>
#include <string>
#include <vector>

#include "core/engine.hpp"
#include "core/system.hpp"
#include "tests/lagrange/scenes.hpp"

namespace crossdyn::test {

// A flexible Body from its nodes, K and D: mass and inertia are the node sums (as the reader sets
// them), mode names q1 .. qn.
inline Body flex_body(const std::string& name, std::vector<FlexNode> nodes, const Eigen::MatrixXd& K,
                      const Eigen::MatrixXd& D) {
  FlexBody f;
  f.nodes = std::move(nodes);
  f.K = K;
  f.D = D;
  for (Eigen::Index k = 0; k < K.rows(); ++k) f.mode_names.push_back("q" + std::to_string(k + 1));
  f.origin = "built in code";
  Body b;
  b.name = name;
  b.mass = 0;
  b.I_BBo_B.setZero();
  for (const FlexNode& n : f.nodes) {
    b.mass += n.mass;
    b.I_BBo_B += n.J_Ni_B +
                 n.mass * (n.p_BoNi_B.squaredNorm() * Eigen::Matrix3d::Identity() -
                           n.p_BoNi_B * n.p_BoNi_B.transpose());
  }
  b.flex = std::move(f);
  return b;
}

inline FlexNode node(const std::string& name, double mass, const Eigen::Vector3d& p, int modes) {
  FlexNode n;
  n.name = name;
  n.mass = mass;
  n.p_BoNi_B = p;
  n.Phi_B = Eigen::Matrix3Xd::Zero(3, modes);
  n.Psi_B = Eigen::Matrix3Xd::Zero(3, modes);
  return n;
}

// A random flexible body: `nodes` nodes within `size` of the origin, recentred so that
// sum m_i p_i = 0, small rigid inertias, shapes and slopes of order one (so eta = 0.1 moves a node
// by about 0.1 m and turns it by about 0.1 rad), K = A A^T + k0 1 and D = damping * 1.
inline Body random_flex_body(const std::string& name, int nodes, int modes, double size,
                             std::mt19937& g, double k0 = 20.0, double damping = 0.0) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), mass(0.5, 2.0);
  std::vector<FlexNode> ns;
  double m = 0;
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  for (int i = 0; i < nodes; ++i) {
    FlexNode n = node(name + "_n" + std::to_string(i), mass(g),
                      size * Eigen::Vector3d(u(g), u(g), u(g)), modes);
    const Eigen::Matrix3d R = random_quaternion(g).toRotationMatrix();
    n.J_Ni_B = 0.05 * R * Eigen::Vector3d(1 + 0.5 * u(g), 1 + 0.5 * u(g), 1 + 0.5 * u(g)).asDiagonal() *
               R.transpose();
    for (int k = 0; k < modes; ++k) {
      n.Phi_B.col(k) = Eigen::Vector3d(u(g), u(g), u(g));
      n.Psi_B.col(k) = Eigen::Vector3d(u(g), u(g), u(g));
    }
    m += n.mass;
    s += n.mass * n.p_BoNi_B;
    ns.push_back(n);
  }
  for (FlexNode& n : ns) n.p_BoNi_B -= s / m;
  Eigen::MatrixXd A(modes, modes);
  for (int r = 0; r < modes; ++r)
    for (int c = 0; c < modes; ++c) A(r, c) = 3.0 * u(g);
  const Eigen::MatrixXd K = A * A.transpose() + k0 * Eigen::MatrixXd::Identity(modes, modes);
  return flex_body(name, ns, K, damping * Eigen::MatrixXd::Identity(modes, modes));
}

// A joint from parent to child attached at the given nodes (-1: a rigid attachment at `point`).
inline Joint joint_at(const System& s, const std::string& name, JointType type, int parent,
                      int child, int parent_node, int child_node,
                      const Eigen::Vector3d& parent_point = Eigen::Vector3d::Zero(),
                      const Eigen::Vector3d& child_point = Eigen::Vector3d::Zero()) {
  Joint j;
  j.name = name;
  j.type = type;
  j.parent = parent;
  j.child = child;
  j.parent_node = parent_node;
  j.child_node = child_node;
  j.p_PoJ_P = parent_node >= 0
                  ? s.bodies[static_cast<std::size_t>(parent)].flex->nodes[static_cast<std::size_t>(
                                                                             parent_node)]
                        .p_BoNi_B
                  : parent_point;
  j.p_CoJ_C = child_node >= 0
                  ? s.bodies[static_cast<std::size_t>(child)].flex->nodes[static_cast<std::size_t>(
                                                                            child_node)]
                        .p_BoNi_B
                  : child_point;
  return j;
}

// A tree with every kind of attachment: a flexible base `beam`; a revolute joint at a beam node to
// the rigid `panel` (offset, spring); a spherical joint from a beam node to a node of the flexible
// `arm` (flexible parent and child); a fixed joint from an arm node to the rigid `tip`; a revolute
// joint from the rigid panel to a node of the flexible `flap`. With loads: hinge springs, dampers
// and motors on both revolutes and the spherical joint, body torques on the beam (body frame) and
// the arm (inertial frame), modal damping on the flap.
inline System flex_tree(bool loads, unsigned seed = 7) {
  std::mt19937 g(seed);
  System s;
  s.name = loads ? "flex_tree_loads" : "flex_tree";
  s.bodies.push_back(random_flex_body("beam", 6, 3, 2.0, g));
  s.bodies.push_back(make_body("panel", 4, {0.6, 0.3, 0.8}));
  s.bodies.push_back(random_flex_body("arm", 4, 2, 1.0, g, 10.0));
  s.bodies.push_back(make_body("tip", 1, {0.05, 0.07, 0.06}));
  s.bodies.push_back(random_flex_body("flap", 3, 2, 0.7, g, 8.0, loads ? 0.3 : 0.0));
  s.joints.push_back(free_joint(0, {0.3, -0.2, 0.4}));
  Joint hinge = joint_at(s, "hinge", JointType::Revolute, 0, 1, 1, -1, {}, {-0.7, 0.1, 0.0});
  hinge.axis_P = Eigen::Vector3d(0.3, 1.0, -0.2).normalized();
  hinge.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 0, 1).normalized()));
  hinge.angle0 = 0.3;
  hinge.rate0 = 0.5;
  hinge.stiffness = 2.0;
  hinge.neutral_angle = 0.1;
  Joint ball = joint_at(s, "ball", JointType::Spherical, 0, 2, 3, 0);
  ball.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(-0.6, Eigen::Vector3d(0, 1, 1).normalized()));
  ball.q_J0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.8, Eigen::Vector3d(1, -1, 2).normalized()));
  ball.w_PC_C0 = {0.2, -0.3, 0.1};
  ball.stiffness = 1.5;
  Joint weld = joint_at(s, "weld", JointType::Fixed, 2, 3, 2, -1, {}, {0.2, 0.0, -0.1});
  weld.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(1.1, Eigen::Vector3d(0, 0, 1)));
  Joint flap = joint_at(s, "flap_hinge", JointType::Revolute, 1, 4, -1, 1, {0.5, 0.2, 0.1});
  flap.axis_P = Eigen::Vector3d(1.0, 0.2, 0.1).normalized();
  flap.angle0 = -0.4;
  flap.rate0 = -0.3;
  flap.stiffness = 1.0;
  if (loads) {
    hinge.damping = 0.2;
    hinge.motor_revolute.times = {0.0, 0.7};
    hinge.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(0.4),
                                   Eigen::Matrix<double, 1, 1>(-0.2)};
    ball.damping = 0.3;
    ball.motor_spherical.times = {0.0};
    ball.motor_spherical.values = {Eigen::Vector3d(0.1, -0.2, 0.05)};
    flap.motor_revolute.times = {0.0};
    flap.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(0.15)};
    s.bodies[0].torque.times = {0.0};
    s.bodies[0].torque.values = {Eigen::Vector3d(0.3, -0.1, 0.2)};
    s.bodies[2].torque_frame = Body::Frame::Inertial;
    s.bodies[2].torque.times = {0.0};
    s.bodies[2].torque.values = {Eigen::Vector3d(-0.1, 0.2, 0.1)};
  }
  s.joints.insert(s.joints.end(), {hinge, ball, weld, flap});
  s.run.duration = 4;
  s.run.output_step = 0.1;
  return s;
}

// The same system with geometric stiffening on every flexible body (system.hpp FlexBody): each node
// gets a random unit direction e_i and a random symmetric G_i of order one.
inline System with_stiffening(System s, unsigned seed = 3) {
  std::mt19937 g(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (Body& b : s.bodies) {
    if (!b.flex) continue;
    b.flex->geometric_stiffening = true;
    const int n = b.flex->modes();
    for (FlexNode& nd : b.flex->nodes) {
      nd.e_B = Eigen::Vector3d(u(g), u(g), u(g)).normalized();
      Eigen::MatrixXd G(n, n);
      for (int k = 0; k < n; ++k)
        for (int l = 0; l < n; ++l) G(k, l) = u(g);
      nd.G = 0.5 * (G + G.transpose());
    }
  }
  s.name += "_stiffening";
  return s;
}

// Random modal coordinates up to eta_max (so that node displacements reach about eta_max metres
// and node rotations about eta_max radians) and rates up to rate_max, on top of random_state().
inline TreeState random_flex_state(const System& system, std::mt19937& g, double eta_max = 0.1,
                                   double rate_max = 0.5) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  TreeState s = random_state(system, g);
  for (std::size_t b = 0; b < system.bodies.size(); ++b)
    for (Eigen::Index k = 0; k < s.eta[b].size(); ++k) {
      s.eta[b](k) = eta_max * u(g);
      s.eta_rate[b](k) = rate_max * u(g);
    }
  return s;
}

}  // namespace crossdyn::test
