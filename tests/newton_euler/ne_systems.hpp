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
#include <utility>
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

// chainN of docs/scenarios.md "Scene 3": N links of 10 kg, diag(0.1, 3.4, 3.4) kg m^2, 2 m
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

// SPEAR-1 case I (docs/scenarios.md "Scene 1"), for tests that must not wait for files.
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

inline int label_index(const Engine& e, const std::string& label);

// ---- flexible bodies -----------------------------------------------------------------------

// Sets a flexible body's mass and rigid inertia to its node sums (as the scene reader does).
inline void set_node_sums(Body& b) {
  b.mass = 0;
  b.I_BBo_B.setZero();
  for (const FlexNode& n : b.flex->nodes) {
    b.mass += n.mass;
    b.I_BBo_B += n.J_Ni_B + n.mass * (n.p_BoNi_B.squaredNorm() * Eigen::Matrix3d::Identity() -
                                      n.p_BoNi_B * n.p_BoNi_B.transpose());
  }
}

// A uniform flexible beam along z (length L, mass m) carried by `slices` nodes at the slice
// centres (each with the rigid inertia of a thin slice, J = m_i diag(w^2/12 + ..)), plus massless
// nodes "bottom" (z = -L/2), "mid" (z = 0) and "top" (z = +L/2) for joints. Its modes are
// deflections in x (nx of them) and then in y (ny), shaped as Legendre polynomials P_{k+1}(2z/L)
// (not eigenmodes: the model takes any shapes; P2, P3, ... are nearly free of momentum), with the
// exact slopes: a deflection u_x(z) turns the section by du_x/dz about +y, u_y(z) by -du_y/dz
// about +x. K = diag(stiffness), D = 0.
inline Body flexible_beam(const std::string& name, double mass, double length, int slices, int nx,
                          int ny, const std::vector<double>& stiffness) {
  const int n = nx + ny;
  auto P = [](int k, double z) {  // Legendre P_k and its derivative, k = 2..4
    switch (k) {
      case 2: return std::pair{(3 * z * z - 1) / 2, 3 * z};
      case 3: return std::pair{(5 * z * z * z - 3 * z) / 2, (15 * z * z - 3) / 2};
      default: return std::pair{(35 * z * z * z * z - 30 * z * z + 3) / 8, (140 * z * z * z - 60 * z) / 8};
    }
  };
  Body b;
  b.name = name;
  FlexBody f;
  for (int k = 0; k < nx; ++k) f.mode_names.push_back("qx" + std::to_string(k + 1));
  for (int k = 0; k < ny; ++k) f.mode_names.push_back("qy" + std::to_string(k + 1));
  auto node = [&](const std::string& node_name, double z, double m) {
    FlexNode nd;
    nd.name = node_name;
    nd.mass = m;
    nd.p_BoNi_B = Eigen::Vector3d(0, 0, z);
    const double h = length / slices, w = 0.2 * length / slices + 0.05;
    nd.J_Ni_B = m * Eigen::Vector3d((w * w + h * h) / 12, (w * w + h * h) / 12, w * w / 6)
                        .asDiagonal()
                        .toDenseMatrix();
    nd.Phi_B = Eigen::Matrix3Xd::Zero(3, n);
    nd.Psi_B = Eigen::Matrix3Xd::Zero(3, n);
    const double zeta = 2 * z / length, dzeta = 2 / length;
    for (int k = 0; k < nx; ++k) {
      const auto [v, d] = P(k + 2, zeta);
      nd.Phi_B(0, k) = v;
      nd.Psi_B(1, k) = d * dzeta;
    }
    for (int k = 0; k < ny; ++k) {
      const auto [v, d] = P(k + 2, zeta);
      nd.Phi_B(1, nx + k) = v;
      nd.Psi_B(0, nx + k) = -d * dzeta;
    }
    f.nodes.push_back(nd);
  };
  for (int i = 0; i < slices; ++i)
    node("s" + std::to_string(i), -length / 2 + (i + 0.5) * length / slices, mass / slices);
  node("bottom", -length / 2, 0);
  node("mid", 0, 0);
  node("top", length / 2, 0);
  f.K = Eigen::MatrixXd::Zero(n, n);
  for (int k = 0; k < n; ++k) f.K(k, k) = stiffness[static_cast<std::size_t>(k)];
  f.D = Eigen::MatrixXd::Zero(n, n);
  f.origin = "test beam";
  b.flex = f;
  set_node_sums(b);
  return b;
}

inline int node_of(const System& s, int body, const std::string& node) {
  return s.bodies[static_cast<std::size_t>(body)].flex->node_index(node);
}

// A tree with flexible bodies everywhere (every joint type at a node of a flexible parent, and
// flexible children attached at their own nodes), springs on the hinges, no dampers:
//   beam (free, 3 modes) -top-> payload (rigid, revolute about y, spring)
//   beam -bottom-> arm (flexible, 2 modes, spherical at the arm's "top" node, spring)
//   arm -bottom-> tip (rigid, fixed, offset)
//   payload -> panel (flexible, 1 mode, revolute at the panel's "bottom" node, oblique axis)
//   beam -mid-> box (rigid, revolute, the joint at the beam's mid node)
inline System flexible_tree() {
  System s;
  s.name = "flexible_tree";
  Eigen::Matrix3d I_payload, I_tip, I_box;
  I_payload << 4, 0.3, 0, 0.3, 5, -0.2, 0, -0.2, 3;
  I_tip << 0.5, 0, 0.05, 0, 0.4, 0, 0.05, 0, 0.3;
  I_box << 1.0, 0.1, 0, 0.1, 1.2, 0, 0, 0, 0.8;
  s.bodies = {flexible_beam("beam", 60, 4, 8, 2, 1, {40, 300, 60}),
              make_body("payload", 20, I_payload),
              flexible_beam("arm", 6, 2, 5, 1, 1, {25, 15}),
              make_body("tip", 3, I_tip),
              flexible_beam("panel", 4, 1.5, 4, 1, 0, {8}),
              make_body("box", 5, I_box)};
  Joint base = free_joint(0);
  base.q_NB0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, -1, 2).normalized()));
  base.w_NB_B0 = Eigen::Vector3d(0.4, -0.3, 0.6);
  s.joints.push_back(base);

  Joint hinge;  // beam.top -> payload
  hinge.name = "hinge";
  hinge.type = JointType::Revolute;
  hinge.parent = 0;
  hinge.child = 1;
  hinge.parent_node = node_of(s, 0, "top");
  hinge.p_PoJ_P = Eigen::Vector3d(0, 0, 2);
  hinge.p_CoJ_C = Eigen::Vector3d(-0.6, 0.1, -0.2);
  hinge.axis_P = Eigen::Vector3d(0, 1, 0);
  hinge.stiffness = 20;
  hinge.angle0 = 0.5;
  hinge.rate0 = 0.7;
  s.joints.push_back(hinge);

  Joint ball;  // beam.bottom -> arm.top
  ball.name = "ball";
  ball.type = JointType::Spherical;
  ball.parent = 0;
  ball.child = 2;
  ball.parent_node = node_of(s, 0, "bottom");
  ball.child_node = node_of(s, 2, "top");
  ball.p_PoJ_P = Eigen::Vector3d(0, 0, -2);
  ball.p_CoJ_C = Eigen::Vector3d(0, 0, 1);
  ball.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(2.8, Eigen::Vector3d(1, 0.2, 0).normalized()));
  ball.stiffness = 6;
  ball.q_J0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, -1).normalized()));
  ball.w_PC_C0 = Eigen::Vector3d(0.3, -0.5, 0.2);
  s.joints.push_back(ball);

  Joint weld;  // arm.bottom -> tip
  weld.name = "weld";
  weld.type = JointType::Fixed;
  weld.parent = 2;
  weld.child = 3;
  weld.parent_node = node_of(s, 2, "bottom");
  weld.p_PoJ_P = Eigen::Vector3d(0, 0, -1);
  weld.p_CoJ_C = Eigen::Vector3d(0.1, 0, 0.3);
  weld.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.6, Eigen::Vector3d(0, 1, 1).normalized()));
  s.joints.push_back(weld);

  Joint flap;  // payload -> panel.bottom
  flap.name = "flap";
  flap.type = JointType::Revolute;
  flap.parent = 1;
  flap.child = 4;
  flap.child_node = node_of(s, 4, "bottom");
  flap.p_PoJ_P = Eigen::Vector3d(0.5, 0.2, 0.1);
  flap.p_CoJ_C = Eigen::Vector3d(0, 0, -0.75);
  flap.axis_P = Eigen::Vector3d(0.2, 1, 0.3).normalized();
  flap.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.9, Eigen::Vector3d(1, 0, 0)));
  flap.stiffness = 4;
  flap.angle0 = -0.3;
  flap.rate0 = 1.1;
  s.joints.push_back(flap);

  Joint side;  // beam.mid -> box
  side.name = "side";
  side.type = JointType::Revolute;
  side.parent = 0;
  side.child = 5;
  side.parent_node = node_of(s, 0, "mid");
  side.p_PoJ_P = Eigen::Vector3d(0, 0, 0);
  side.p_CoJ_C = Eigen::Vector3d(-0.4, 0, 0);
  side.axis_P = Eigen::Vector3d(0, 0, 1);
  side.angle0 = 1.0;
  side.rate0 = -0.5;
  s.joints.push_back(side);
  s.zero_linear_momentum = true;
  return s;
}

// n flexible beams (10 kg, 2 m, 6 slices, one bending mode per plane) joined node to node: the
// "top" node of beam k-1 to the "bottom" node of beam k, by spherical joints (even k) and revolute
// joints about x (odd k). The base spins; every joint moves.
inline System flexible_chain(int n) {
  System s;
  s.name = "flexible_chain" + std::to_string(n);
  for (int k = 1; k <= n; ++k)
    s.bodies.push_back(flexible_beam("beam" + std::to_string(k), 10, 2, 6, 1, 1, {30, 50}));
  Joint base = free_joint(0);
  base.w_NB_B0 = Eigen::Vector3d(0.3, 0.2, 0.5);
  s.joints.push_back(base);
  for (int k = 2; k <= n; ++k) {
    Joint j;
    j.name = "joint" + std::to_string(k);
    j.type = k % 2 == 0 ? JointType::Spherical : JointType::Revolute;
    j.parent = k - 2;
    j.child = k - 1;
    j.parent_node = node_of(s, k - 2, "top");
    j.child_node = node_of(s, k - 1, "bottom");
    j.p_PoJ_P = Eigen::Vector3d(0, 0, 1);
    j.p_CoJ_C = Eigen::Vector3d(0, 0, -1);
    j.axis_P = Eigen::Vector3d::UnitX();
    j.rate0 = 0.4;
    j.w_PC_C0 = Eigen::Vector3d(0.1, -0.2, 0.3);
    s.joints.push_back(j);
  }
  return s;
}

// A state of `system` with deformation: eta and eta' of every flexible body uniform in
// [-eta_max, eta_max] and [-rate_max, rate_max].
inline void deform(const System& system, TreeState& ts, std::mt19937& rng, double eta_max,
                   double rate_max) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (std::size_t b = 0; b < system.bodies.size(); ++b) {
    if (!system.bodies[b].flex) continue;
    for (Eigen::Index k = 0; k < ts.eta[b].size(); ++k) {
      ts.eta[b](k) = eta_max * u(rng);
      ts.eta_rate[b](k) = rate_max * u(rng);
    }
  }
}

// The modal coordinates and rates of a body, read from an engine state through its labels.
inline std::pair<Eigen::VectorXd, Eigen::VectorXd> modal_state(const Engine& e, const double* x,
                                                                const System& s, int body) {
  const Body& b = s.bodies[static_cast<std::size_t>(body)];
  const int n = b.flex ? b.flex->modes() : 0;
  Eigen::VectorXd eta(n), rate(n);
  for (int k = 0; k < n; ++k) {
    const std::string m = b.name + "." + b.flex->mode_names[static_cast<std::size_t>(k)];
    eta(k) = x[label_index(e, m)];
    rate(k) = x[label_index(e, m + "_rate")];
  }
  return {eta, rate};
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
