// Flexible Systems built in code for the Kane engine's tests (docs/flexible-bodies.md model).
// The modal data of random_flex_body() are arbitrary numbers, not the modes of any structure: the
// model is exact for any shapes and slopes, so random, asymmetric data leave no term a chance to
// cancel by symmetry.  Body::mass and I_BBo_B are the node sums, as the scene reader sets them.
#pragma once

#include "tests/kane/kane_systems.hpp"

#include <random>
#include <string>
#include <vector>

namespace crossdyn::test::kane {

// A flexible body from its nodes, K and D (mass and rigid inertia: the node sums).
inline Body flex_body(const std::string& name, const std::vector<FlexNode>& nodes,
                      const Eigen::MatrixXd& K, const Eigen::MatrixXd& D) {
  Body b;
  b.name = name;
  b.flex = FlexBody{};
  b.flex->nodes = nodes;
  b.flex->K = K;
  b.flex->D = D;
  b.flex->origin = "built in code";
  const int n = static_cast<int>(K.rows());
  for (int k = 1; k <= n; ++k) b.flex->mode_names.push_back("q" + std::to_string(k));
  b.mass = 0;
  b.I_BBo_B.setZero();
  for (const FlexNode& nd : nodes) {
    b.mass += nd.mass;
    b.I_BBo_B += nd.J_Ni_B + nd.mass * (nd.p_BoNi_B.squaredNorm() * Eigen::Matrix3d::Identity() -
                                        nd.p_BoNi_B * nd.p_BoNi_B.transpose());
  }
  return b;
}

inline FlexNode flex_node(const std::string& name, double mass, const Eigen::Vector3d& p,
                          const Eigen::Matrix3d& J, const Eigen::Matrix3Xd& Phi,
                          const Eigen::Matrix3Xd& Psi) {
  FlexNode nd;
  nd.name = name;
  nd.mass = mass;
  nd.p_BoNi_B = p;
  nd.J_Ni_B = J;
  nd.Phi_B = Phi;
  nd.Psi_B = Psi;
  return nd;
}

// `nodes` nodes with random masses (1..3 kg), positions (spread ~size, shifted so that sum m p =
// 0), small random node inertias, shapes (~shape m per unit) and slopes (~slope rad per unit); K
// diagonal with the given stiffness per mode, D = damping * K.
inline Body random_flex_body(const std::string& name, int nodes, int modes, std::mt19937& g,
                             double size = 1.0, double shape = 0.6, double slope = 0.8,
                             double stiffness = 30.0, double damping = 0.0) {
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::vector<FlexNode> nd;
  Eigen::Vector3d first_moment = Eigen::Vector3d::Zero();
  double mass = 0;
  for (int i = 0; i < nodes; ++i) {
    Eigen::Matrix3Xd Phi(3, modes), Psi(3, modes);
    for (int k = 0; k < modes; ++k) {
      Phi.col(k) = shape * Eigen::Vector3d(U(g), U(g), U(g));
      Psi.col(k) = slope * Eigen::Vector3d(U(g), U(g), U(g));
    }
    const double m = 2.0 + U(g);
    const Eigen::Vector3d p = size * Eigen::Vector3d(U(g), U(g), U(g));
    const Eigen::Matrix3d J =
        turned_inertia(0.02 + 0.01 * U(g), 0.03 + 0.01 * U(g), 0.04 + 0.01 * U(g),
                       quat_from_axis(U(g), Eigen::Vector3d(U(g), U(g), 1.0)));
    nd.push_back(flex_node(name + "_n" + std::to_string(i), m, p, J, Phi, Psi));
    first_moment += m * p;
    mass += m;
  }
  for (FlexNode& n : nd) n.p_BoNi_B -= first_moment / mass;
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(modes, modes);
  for (int k = 0; k < modes; ++k) K(k, k) = stiffness * (1.0 + 0.5 * k);
  // A little coupling, still symmetric positive definite.
  for (int k = 0; k + 1 < modes; ++k) K(k, k + 1) = K(k + 1, k) = 0.2 * stiffness;
  return flex_body(name, nd, K, damping * K);
}

inline Eigen::Vector3d node_position(const System& s, int body, int node) {
  return s.bodies[static_cast<std::size_t>(body)]
      .flex->nodes[static_cast<std::size_t>(node)]
      .p_BoNi_B;
}

// Flexible bodies everywhere in the tree, joints of every kind at nodes:
//   bus (flexible base) -+- arm (rigid; revolute at bus node 2, spring) -- boom (flexible; revolute
//                        |     at boom node 1) -- antenna (rigid; spherical at boom node 3)
//                        +- panel (flexible; spherical from bus node 4 to panel node 0) -+-
//                              tip (rigid; fixed at panel node 3)
//                              +- probe (flexible; fixed from panel node 2 to probe node 0)
// Without loads other than the hinge springs and K (energy conserving), unless `loaded`: then
// hinge dampers and motors, modal damping D and body torques too.
inline System flex_tree(bool loaded = false, unsigned seed = 11) {
  using Eigen::Vector3d;
  std::mt19937 g(seed);
  const double damping = loaded ? 0.05 : 0.0;
  System s;
  s.name = loaded ? "flex_tree_loaded" : "flex_tree";
  s.bodies.push_back(random_flex_body("bus", 6, 3, g, 1.2, 0.5, 0.7, 60.0, damping));
  s.bodies.push_back(
      rigid_body("arm", 6, turned_inertia(0.4, 0.9, 1.1, quat_from_axis(0.5, {1, 2, -1}))));
  s.bodies.push_back(random_flex_body("panel", 5, 2, g, 0.8, 0.5, 0.9, 25.0, damping));
  s.bodies.push_back(
      rigid_body("tip", 1.5, turned_inertia(0.02, 0.03, 0.035, quat_from_axis(0.9, {0, 1, 1}))));
  s.bodies.push_back(random_flex_body("boom", 4, 2, g, 0.7, 0.4, 0.6, 20.0, damping));
  s.bodies.push_back(random_flex_body("probe", 3, 1, g, 0.4, 0.3, 0.5, 10.0, damping));
  s.bodies.push_back(
      rigid_body("antenna", 2, turned_inertia(0.05, 0.06, 0.08, quat_from_axis(-0.7, {2, 0, 1}))));

  s.joints.push_back(
      free_joint("base", 0, Vector3d(0.3, -0.2, 0.4), quat_from_axis(0.6, {1, 1, 0})));
  s.joints.back().p_NoBo_N0 = Vector3d(1, 2, 3);

  Joint shoulder = joint("shoulder", JointType::Revolute, 0, 1, node_position(s, 0, 2),
                         Vector3d(-0.6, 0.1, 0.05));
  shoulder.parent_node = 2;
  shoulder.axis_P = Vector3d(0.2, 0.5, 0.8).normalized();
  shoulder.q_PJ0 = quat_from_axis(0.3, {0, 1, 1});
  shoulder.stiffness = 8;
  shoulder.neutral_angle = -0.1;
  shoulder.angle0 = 0.4;
  shoulder.rate0 = 0.5;
  s.joints.push_back(shoulder);

  Joint hinge =
      joint("gimbal", JointType::Spherical, 0, 2, node_position(s, 0, 4), node_position(s, 2, 0));
  hinge.parent_node = 4;
  hinge.child_node = 0;
  hinge.q_PJ0 = quat_from_axis(-0.4, {1, 0, 2});
  hinge.stiffness = 4;
  hinge.q_J0 = quat_from_axis(0.3, {1, -1, 2});
  hinge.w_PC_C0 = Vector3d(0.2, 0.1, -0.3);
  s.joints.push_back(hinge);

  Joint weld =
      joint("weld", JointType::Fixed, 2, 3, node_position(s, 2, 3), Vector3d(0.1, 0, -0.1));
  weld.parent_node = 3;
  weld.q_PJ0 = quat_from_axis(0.8, {1, 1, 1});
  s.joints.push_back(weld);

  Joint elbow =
      joint("elbow", JointType::Revolute, 1, 4, Vector3d(0.7, -0.1, 0.2), node_position(s, 4, 1));
  elbow.child_node = 1;
  elbow.axis_P = Vector3d(1, -0.3, 0.4).normalized();
  elbow.angle0 = -0.3;
  elbow.rate0 = -0.4;
  s.joints.push_back(elbow);

  Joint clamp =
      joint("clamp", JointType::Fixed, 2, 5, node_position(s, 2, 2), node_position(s, 5, 0));
  clamp.parent_node = 2;
  clamp.child_node = 0;
  clamp.q_PJ0 = quat_from_axis(-1.1, {0, 1, -1});
  s.joints.push_back(clamp);

  Joint feed =
      joint("feed", JointType::Spherical, 4, 6, node_position(s, 4, 3), Vector3d(0.0, 0.2, -0.15));
  feed.parent_node = 3;
  feed.stiffness = 1.5;
  feed.q_J0 = quat_from_axis(-0.5, {0, 2, 1});
  feed.w_PC_C0 = Vector3d(-0.1, 0.3, 0.2);
  s.joints.push_back(feed);

  if (loaded) {
    for (Joint& j : s.joints) {
      if (j.type == JointType::Revolute) {
        j.damping = 0.3;
        j.motor_revolute.times = {0.0};
        j.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(0.7)};
      }
      if (j.type == JointType::Spherical) {
        j.damping = 0.2;
        j.motor_spherical.times = {0.0};
        j.motor_spherical.values = {Vector3d(0.3, -0.4, 0.2)};
      }
    }
    s.bodies[0].torque.times = {0.0};
    s.bodies[0].torque.values = {Vector3d(0.5, -1.0, 0.8)};
    s.bodies[2].torque.times = {0.0};
    s.bodies[2].torque.values = {Vector3d(-0.2, 0.3, 0.1)};
    s.bodies[2].torque_frame = Body::Frame::Inertial;
  }
  // Initial deformation and rates are set through TreeState (flex_state).
  return s;
}

// The scene's initial state with the given modal coordinates and rates on every flexible body.
inline TreeState flex_state(const System& s, double eta, double eta_rate) {
  TreeState st = TreeState::initial(s);
  for (std::size_t b = 0; b < s.bodies.size(); ++b)
    if (s.bodies[b].flex) {
      const Eigen::Index n = s.bodies[b].flex->modes();
      for (Eigen::Index k = 0; k < n; ++k) {
        st.eta[b](k) = eta * (k % 2 ? -1.0 : 1.0) * (1.0 + 0.3 * static_cast<double>(k));
        st.eta_rate[b](k) = eta_rate * (k % 2 ? 1.0 : -1.0);
      }
    }
  return st;
}

// A random state (random_state) with random modal coordinates of size ~eta (so node
// displacements and rotations of order 0.1 m and 0.1 rad for the shapes above) and rates ~1.
inline TreeState random_flex_state(const System& system, std::mt19937& g, double eta = 0.15) {
  TreeState s = random_state(system, g);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (std::size_t b = 0; b < system.bodies.size(); ++b)
    if (system.bodies[b].flex)
      for (Eigen::Index k = 0; k < s.eta[b].size(); ++k) {
        s.eta[b](k) = eta * U(g);
        s.eta_rate[b](k) = U(g);
      }
  return s;
}

// The same system with geometric stiffening on every flexible body (docs/flexible-bodies.md):
// every node gets a random unit e_i and a random symmetric G_i (entries ~ size), so the
// second-order displacement e_i (1/2 eta^T G_i eta) moves every node, joint nodes included.
inline System stiffened(System s, unsigned seed = 5, double size = 0.5) {
  std::mt19937 g(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (Body& b : s.bodies) {
    if (!b.flex) continue;
    b.flex->geometric_stiffening = true;
    const int n = b.flex->modes();
    for (FlexNode& nd : b.flex->nodes) {
      nd.e_B = Eigen::Vector3d(U(g), U(g), U(g)).normalized();
      Eigen::MatrixXd G(n, n);
      for (int k = 0; k < n; ++k)
        for (int l = 0; l < n; ++l) G(k, l) = size * U(g);
      nd.G = 0.5 * (G + G.transpose());
    }
  }
  return s;
}

}  // namespace crossdyn::test::kane
