// Issue 26's outputs of the Newton-Euler engine, checked against physics written here from
// scratch: the joint loads <joint>.Fx .. .Mz close every body's Newton-Euler equations (each
// body's mass elements with the engine's accelerations, TreeAccel), a revolute joint's moment about
// its axis is its torque, P is dE/dt and M is dH/dt along the engine's own flow, the damper test
// hook scales the equations of motion and not P, and a motor-driven rod at rest matches the hand
// solution of docs/conventions.md's worked example.
//
// The balances (Newton and Euler for a system of particles, Kane, Likins & Levinson 1983,
// "Spacecraft Dynamics", Sec. 4.5; Featherstone 2008, "Rigid Body Dynamics Algorithms", Sec. 2.8,
// Eq. 2.26, for moving a moment to another point, M_Q = M_P + (p_P - p_Q) x F): for body B with
// mass elements i (a rigid body: its CM with its inertia I; a flexible body: its nodes, at
// r_i = p_i + u_i from Bo, with their rigid inertias J_i fixed in B), all in N,
//   sum_i m_i a_i = F_own - sum_{children k} F_k + 0 (no external forces in the model)
//   sum_i (R r_i) x m_i a_i + R sum_i (J_i alpha + w x J_i w)
//        = M_own + (R s_own) x F_own - sum_k [M_k + (p_Jk - p_Bo) x F_k] + T_ext
// with (F_own, M_own) B's own joint's load at its joint point s_own (from Bo, body frame, the
// node's displaced point), (F_k, M_k) child joint k's load on its child at its joint point p_Jk
// (the reaction on B is -F_k, -M_k at the same point), and the node accelerations in B components
// (modal_body.hpp's kinematics, with geometric stiffening u_i = Phi_i eta + e_i 1/2 eta^T G_i eta):
//   R^T a_i = R^T a_Bo + alpha x r_i + w x (w x r_i) + 2 w x u_i' + Phi~_i eta'' + e_i eta'^T G_i eta',
//   u_i' = Phi~_i eta', Phi~_i = Phi_i + e_i (G_i eta)^T.
#include "formulations/newton_euler/newton_euler.hpp"

#include "core/scene/scene.hpp"
#include "tests/newton_euler/ne_systems.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace crossdyn::test::ne {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using Eigen::VectorXd;

std::size_t at(int i) { return static_cast<std::size_t>(i); }

// The engine at one state (t, x): its row and accelerations.
struct Eval {
  std::unique_ptr<Engine> e;
  std::vector<double> x, row;
  double t = 0;
  double col(const std::string& name) const { return row[at(column(*e, name))]; }
  Vector3d vec(const std::string& a, const std::string& b, const std::string& c) const {
    return Vector3d(col(a), col(b), col(c));
  }
  void output() { e->output_row(t, x.data(), row.data()); }
};

Eval evaluate(const System& s, const TreeState& ts, double t, const EngineOptions& o = {}) {
  Eval v;
  v.e = make_newton_euler_engine(s, o);
  v.t = t;
  v.x.resize(at(v.e->state_size()));
  v.row.resize(v.e->columns().size());
  v.e->pack(ts, v.x.data());
  v.output();
  return v;
}

// A random state at time t: free base pose and velocity, joint coordinates and rates (a prismatic
// joint near its initial position), modal coordinates up to eta_max and rates up to rate_max;
// prescribed joints (and a prescribed base) on their profiles at t (core/engine.hpp).
TreeState random_scene_state(const System& s, std::mt19937& rng, double t, double eta_max,
                             double rate_max) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&] { return Vector3d(u(rng), u(rng), u(rng)); };
  auto quat = [&] { return Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized(); };
  TreeState ts = TreeState::initial(s);
  if (s.base_is_free()) {
    ts.p_NoBo_N = vec();
    ts.q_NB = quat();
    ts.v_NBo_N = vec();
    ts.w_NB_B = 0.5 * vec();
  }
  for (std::size_t j = 0; j < s.joints.size(); ++j) {
    const Joint& J = s.joints[j];
    TreeState::JointState& js = ts.joints[j];
    if (J.prescribed) {
      js.angle = J.angle0 + J.prescribed->angle(t);
      js.rate = J.prescribed->velocity(t);
      if (j == 0) ts.place_prescribed_base(J, js.angle, js.rate);
      continue;
    }
    if (j == 0) continue;
    if (J.type == JointType::Prismatic) {
      js.angle = J.angle0 + 0.2 * u(rng);
      js.rate = 0.3 * u(rng);
    } else {
      js.angle = 3.0 * u(rng);
      js.rate = u(rng);
      js.angle2 = 1.0 * u(rng);
      js.rate2 = u(rng);
      js.q_J = quat();
      js.w_PC_C = vec();
    }
  }
  deform(s, ts, rng, eta_max, rate_max);
  return ts;
}

// A flexible body's node i at (eta, eta'): position r from Bo, its body-frame rate, Phi~ (3 x n)
// and the second-order acceleration term e eta'^T G eta' (header).
struct NodeKin {
  Vector3d r, rdot, a2;
  Eigen::Matrix3Xd Phit;
};
NodeKin node_kin(const FlexBody& flex, const FlexNode& nd, const VectorXd& eta, const VectorXd& rate) {
  NodeKin k;
  k.Phit = nd.Phi_B;
  k.r = nd.p_BoNi_B + nd.Phi_B * eta;
  k.a2.setZero();
  if (flex.geometric_stiffening && nd.G.rows() == eta.size() && eta.size() > 0) {
    const VectorXd g = nd.G * eta;
    k.r += 0.5 * eta.dot(g) * nd.e_B;
    k.Phit += nd.e_B * g.transpose();
    k.a2 = rate.dot(nd.G * rate) * nd.e_B;
  }
  k.rdot = k.Phit * rate;
  return k;
}

// A joint's point on its child, from the child's origin, body frame (the node's displaced point).
Vector3d child_point(const System& s, const Engine& e, const double* x, const Joint& J) {
  const Body& C = s.bodies[at(J.child)];
  if (J.child_node < 0 || !C.flex) return J.p_CoJ_C;
  const auto [eta, rate] = modal_state(e, x, s, J.child);
  return node_kin(*C.flex, C.flex->nodes[at(J.child_node)], eta, rate).r;
}
// The same for the parent side's frame: exp([psi x]) of the parent's node (identity without one).
Matrix3d parent_node_frame(const System& s, const Engine& e, const double* x, const Joint& J) {
  if (J.parent < 0 || J.parent_node < 0) return Matrix3d::Identity();
  const FlexNode& nd = s.bodies[at(J.parent)].flex->nodes[at(J.parent_node)];
  if (nd.Psi_B.cols() == 0) return Matrix3d::Identity();
  const Vector3d psi = nd.Psi_B * modal_state(e, x, s, J.parent).first;
  if (psi.norm() == 0) return Matrix3d::Identity();
  return Eigen::AngleAxisd(psi.norm(), psi.normalized()).toRotationMatrix();
}

// The worst residuals of one state, relative to the load scale of each balance.
struct Closure {
  double force = 0, moment = 0;
};

// Every body's Newton-Euler equations (header) at the evaluated state.
Closure closure(const System& s, Eval& v) {
  TreeAccel a;
  v.e->accelerations(v.t, v.x.data(), a);
  const Engine& e = *v.e;
  const double* x = v.x.data();
  const int nb = static_cast<int>(s.bodies.size());
  // Each joint's load in N: F_N, M_N (about its point), and the point p_NoJ_N.
  struct Load {
    Vector3d F, M, p;
  };
  std::vector<Load> load(s.joints.size());
  for (std::size_t j = 0; j < s.joints.size(); ++j) {
    const Joint& J = s.joints[j];
    if (J.type == JointType::Free) continue;
    const BodyState c = body_state(e, x, s.bodies[at(J.child)].name);
    const Vector3d F_C = v.vec(J.name + ".Fx", J.name + ".Fy", J.name + ".Fz");
    const Vector3d M_C = v.vec(J.name + ".Mx", J.name + ".My", J.name + ".Mz");
    load[j] = {c.R_NB * F_C, c.R_NB * M_C, c.p_N + c.R_NB * child_point(s, e, x, J)};
  }
  Closure worst;
  for (int b = 0; b < nb; ++b) {
    const Body& body = s.bodies[at(b)];
    const BodyState B = body_state(e, x, body.name);
    const Vector3d& alpha = a.wdot_NB_B[at(b)];
    const Vector3d& w = B.w_B;
    Vector3d F_inertia = Vector3d::Zero(), M_inertia_B = Vector3d::Zero();
    double scale_F = 0, scale_M = 0;
    if (!body.flex) {
      F_inertia = body.mass * a.a_NBo_N[at(b)];
      M_inertia_B = body.I_BBo_B * alpha + w.cross(body.I_BBo_B * w);
      scale_M = std::max({scale_M, (body.I_BBo_B * alpha).norm(), w.cross(body.I_BBo_B * w).norm()});
    } else {
      const auto [eta, rate] = modal_state(e, x, s, b);
      const VectorXd& eta_dd = a.eta_ddot[at(b)];
      const Vector3d a_Bo_B = B.R_NB.transpose() * a.a_NBo_N[at(b)];
      Vector3d sum_ma = Vector3d::Zero();
      for (const FlexNode& nd : body.flex->nodes) {
        const NodeKin k = node_kin(*body.flex, nd, eta, rate);
        const Vector3d a_i = a_Bo_B + alpha.cross(k.r) + w.cross(w.cross(k.r)) + 2.0 * w.cross(k.rdot) +
                             k.Phit * eta_dd + k.a2;
        sum_ma += nd.mass * a_i;
        const Vector3d m_i = k.r.cross(nd.mass * a_i) + nd.J_Ni_B * alpha + w.cross(nd.J_Ni_B * w);
        M_inertia_B += m_i;
        scale_M = std::max(scale_M, m_i.norm());
      }
      F_inertia = B.R_NB * sum_ma;
    }
    scale_F = std::max(scale_F, F_inertia.norm());
    Vector3d F = Vector3d::Zero(), M = Vector3d::Zero();  // loads on b, moments about Bo, N
    for (std::size_t j = 0; j < s.joints.size(); ++j) {
      const Joint& J = s.joints[j];
      if (J.type == JointType::Free || (J.child != b && J.parent != b)) continue;
      const double sign = J.child == b ? 1.0 : -1.0;  // the reaction on the parent
      const Vector3d M_j = sign * (load[j].M + (load[j].p - B.p_N).cross(load[j].F));
      F += sign * load[j].F;
      M += M_j;
      scale_F = std::max(scale_F, load[j].F.norm());
      scale_M = std::max({scale_M, load[j].M.norm(), M_j.norm()});
    }
    if (!body.torque.empty()) {
      const Vector3d T = body.torque.value(v.t);
      M += body.torque_frame == Body::Frame::Body ? Vector3d(B.R_NB * T) : T;
    }
    // A body with no load and no acceleration (a lone free body) has scales 0 and residuals 0.
    const double rf = (F_inertia - F).norm() / std::max(scale_F, 1e-300);
    const double rm = (B.R_NB * M_inertia_B - M).norm() / std::max(scale_M, 1e-300);
    INFO("body " << body.name << ": force residual " << rf << " moment residual " << rm
                 << " (relative to " << scale_F << " N, " << scale_M << " N m)");
    CHECK(rf <= 1e-10);
    CHECK(rm <= 1e-10);
    worst.force = std::max(worst.force, rf);
    worst.moment = std::max(worst.moment, rm);
  }
  return worst;
}

// Scene name => the time at which it is evaluated (motors and torques on, prescribed joints
// inside their ramps).
double eval_time(const std::string& name) { return name.rfind("spinup_beam", 0) == 0 ? 6.0 : 0.3; }

std::string stem(const std::string& path) { return std::filesystem::path(path).stem().string(); }

// d/dt of the columns `names` along the engine's flow at (t, x): central differences D(h) along
// x +- h xdot, t +- h (the xddot terms cancel: D(h) = f' + c h^2 + O(h^4)), extrapolated:
// (4 D(h) - D(2h)) / 3 = f' + O(h^4) (Richardson). h = 1e-4 s: truncation ~1e-16 of the fifth
// derivative, round-off ~eps |f| / h ~ 1e-12 |f|.
std::vector<double> flow_rate(Eval& v, const std::vector<std::string>& names, double h = 1e-4) {
  const std::size_t n = v.x.size();
  std::vector<double> xdot(n), xp(n), xm(n), rp(v.row.size()), rm(v.row.size());
  v.e->rhs(v.t, v.x.data(), xdot.data());
  auto central = [&](double step) {
    for (std::size_t i = 0; i < n; ++i) {
      xp[i] = v.x[i] + step * xdot[i];
      xm[i] = v.x[i] - step * xdot[i];
    }
    v.e->output_row(v.t + step, xp.data(), rp.data());
    v.e->output_row(v.t - step, xm.data(), rm.data());
    std::vector<double> d;
    for (const std::string& c : names) {
      const auto i = at(column(*v.e, c));
      d.push_back((rp[i] - rm[i]) / (2 * step));
    }
    return d;
  };
  const std::vector<double> d1 = central(h), d2 = central(2 * h);
  std::vector<double> d;
  for (std::size_t k = 0; k < d1.size(); ++k) d.push_back((4 * d1[k] - d2[k]) / 3);
  v.output();  // the row back at (t, x)
  return d;
}

// The prescribed joints' drive power at the evaluated state: torque (force) column times theta'(t).
double drive_power(const System& s, const Eval& v) {
  double p = 0;
  for (const Joint& J : s.joints)
    if (J.prescribed)
      p += v.col(J.name + (J.type == JointType::Revolute ? ".torque" : ".force")) *
           J.prescribed->velocity(v.t);
  return p;
}

// The joint dampers' and modal dampers' power at the evaluated state with the scene's values:
// -c rate^2 per coordinate (spherical -c |w_PC_C|^2), -eta'^T D eta'.
double damper_power(const System& s, const Eval& v) {
  double p = 0;
  for (const Joint& J : s.joints) {
    switch (J.type) {
      case JointType::Revolute:
      case JointType::Prismatic:
        if (!J.prescribed) p -= J.damping * std::pow(v.col(J.name + ".rate"), 2);
        break;
      case JointType::Universal:
        p -= J.damping * std::pow(v.col(J.name + ".rate1"), 2) +
             J.damping2 * std::pow(v.col(J.name + ".rate2"), 2);
        break;
      case JointType::Spherical:
        p -= J.damping * v.vec(J.name + ".wx", J.name + ".wy", J.name + ".wz").squaredNorm();
        break;
      default: break;
    }
  }
  for (std::size_t b = 0; b < s.bodies.size(); ++b) {
    const Body& body = s.bodies[b];
    if (!body.flex || body.flex->D.size() == 0) continue;
    const VectorXd rate = modal_state(*v.e, v.x.data(), s, static_cast<int>(b)).second;
    p -= rate.dot(body.flex->D * rate);
  }
  return p;
}

TEST_CASE("newton-euler loads: the joint loads close every body's Newton-Euler equations on every "
          "committed scene", "[newton_euler][loads]") {
  std::mt19937 rng(26);
  Closure worst;
  for (const std::string& path : committed_scenes()) {
    const System s = read_scene(path);
    // No field in this closure: gravity's loads are checked by test_ne_gravity.cpp and, between
    // engines, tests/cross/test_gravity.cpp.
    if (!s.environment.none()) continue;
    const double t = eval_time(s.name);
    for (int trial = 0; trial < 3; ++trial) {
      INFO("scene " << stem(path) << " trial " << trial << " t " << t);
      Eval v = evaluate(s, random_scene_state(s, rng, t, 0.05, 0.2), t);
      const Closure c = closure(s, v);
      worst.force = std::max(worst.force, c.force);
      worst.moment = std::max(worst.moment, c.moment);
    }
  }
  WARN("worst Newton-Euler closure over the committed scenes: force " << worst.force
                                                                      << ", moment " << worst.moment
                                                                      << " (relative to the load scale)");
}

// ne_systems.hpp's trees with every joint type at nodes of flexible parents and children (a
// revolute joint at a flexible child's node, a spherical one too), given dampers, motors and
// modal damping here, so that the joints' own loads act on node frames: the closure, and P and M
// against dE/dt and dH/dt.
System loaded(System s) {
  for (std::size_t j = 1; j < s.joints.size(); ++j) {
    Joint& J = s.joints[j];
    J.damping = 0.7 + 0.1 * static_cast<double>(j);
    if (J.type == JointType::Revolute) {
      J.motor_revolute.times = {0.0};
      J.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(1.5 - static_cast<double>(j))};
    } else if (J.type == JointType::Spherical) {
      J.motor_spherical.times = {0.0};
      J.motor_spherical.values = {Vector3d(0.3, -0.8, 1.1)};
    }
  }
  for (Body& b : s.bodies)
    if (b.flex) b.flex->D = 0.05 * Eigen::MatrixXd::Identity(b.flex->modes(), b.flex->modes());
  s.bodies[0].torque.times = {0.0};
  s.bodies[0].torque.values = {Vector3d(2.0, -1.0, 0.5)};
  s.bodies[0].torque_frame = Body::Frame::Inertial;
  return s;
}

TEST_CASE("newton-euler loads: closure, P and M on code-built trees with loads at nodes",
          "[newton_euler][loads]") {
  std::mt19937 rng(17);
  for (const System& s : {loaded(flexible_tree()), loaded(mixed_tree()), loaded(flexible_chain(4)),
                          flexible_tree()}) {
    for (int trial = 0; trial < 3; ++trial) {
      INFO("system " << s.name << " trial " << trial);
      Eval v = evaluate(s, random_scene_state(s, rng, 0.3, 0.05, 0.3), 0.3);
      closure(s, v);
      const std::vector<double> d = flow_rate(v, {"E", "Hx", "Hy", "Hz"});
      const double P = v.col("P"), E = v.col("E");
      const Vector3d M = v.vec("Mx", "My", "Mz"), H = v.vec("Hx", "Hy", "Hz");
      CHECK(std::abs(d[0] - P) <= 1e-6 * (std::abs(P) + std::abs(damper_power(s, v)) + 1e-4 * std::abs(E)));
      CHECK((Vector3d(d[1], d[2], d[3]) - M).norm() <= 1e-6 * (M.norm() + 1e-4 * H.norm()));
    }
  }
}

// The closure holds under Baumgarte stabilisation at a state whose velocities violate the
// constraints: its terms -alpha g' change the accelerations and the multipliers together, and
// the loads are the multipliers' reading at that state. (The positions stay on the manifold, so
// that the two copies of each joint point coincide and "the reaction at the same point" has one
// meaning.)
TEST_CASE("newton-euler loads: closure with Baumgarte stabilisation, velocities off the manifold",
          "[newton_euler][loads]") {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 1e-3);
  auto is_velocity = [](const std::string& label) {
    const std::string tail = label.substr(label.rfind('.') + 1);
    return tail.size() > 5 ? tail.substr(tail.size() - 5) == "_rate"
                           : tail == "vx" || tail == "vy" || tail == "vz" || tail == "wx" ||
                                 tail == "wy" || tail == "wz";
  };
  for (const char* name : {"telescoping_boom", "free_beam_payload", "gimbal_payload", "spinup_beam"}) {
    const System s = read_scene(scene_path(name));
    EngineOptions o;
    o.stabilization = "baumgarte";
    const double t = eval_time(s.name);
    Eval v = evaluate(s, random_scene_state(s, rng, t, 0.05, 0.2), t, o);
    for (int i = 0; i < v.e->state_size(); ++i)
      if (is_velocity(v.e->state_label(i))) v.x[at(i)] += noise(rng);
    v.output();
    INFO("scene " << name);
    CHECK(std::max(v.col("constraint.vel"), v.col("constraint.angvel")) > 1e-5);
    CHECK(v.col("constraint.pos") <= 1e-12);
    closure(s, v);
  }
}

// A revolute joint's moment about its axis (child frame) is its torque: -k (angle - neutral) -
// c rate + motor (a prescribed one: its torque column); a prismatic joint's force along its axis
// likewise; a universal joint's moment has the components tau_1 on the first axis and tau_2 on
// the second (the constraint couple is along their normal; for these perpendicular axes the dual
// basis is the axes themselves, joints/universal.cpp).
TEST_CASE("newton-euler loads: a joint's load along its own axis is the joint's torque or force",
          "[newton_euler][loads]") {
  std::mt19937 rng(3);
  int revolute = 0, prismatic = 0, universal = 0;
  double worst = 0;
  std::vector<System> systems;
  for (const std::string& path : committed_scenes()) systems.push_back(read_scene(path));
  systems.push_back(loaded(flexible_tree()));  // revolute joints at a parent's and a child's node
  systems.push_back(loaded(flexible_chain(4)));
  for (const System& s : systems) {
    const double t = eval_time(s.name);
    for (int trial = 0; trial < 2; ++trial) {
      Eval v = evaluate(s, random_scene_state(s, rng, t, 0.05, 0.2), t);
      const double* x = v.x.data();
      for (const Joint& J : s.joints) {
        if (J.type != JointType::Revolute && J.type != JointType::Prismatic &&
            J.type != JointType::Universal)
          continue;
        const Matrix3d R_NP =
            J.parent < 0 ? Matrix3d::Identity() : body_state(*v.e, x, s.bodies[at(J.parent)].name).R_NB;
        const Matrix3d R_NC = body_state(*v.e, x, s.bodies[at(J.child)].name).R_NB;
        const Matrix3d R_CF = R_NC.transpose() * R_NP * parent_node_frame(s, *v.e, x, J);
        const Vector3d axis_C = R_CF * J.axis_P.normalized();
        const Vector3d F_C = v.vec(J.name + ".Fx", J.name + ".Fy", J.name + ".Fz");
        const Vector3d M_C = v.vec(J.name + ".Mx", J.name + ".My", J.name + ".Mz");
        const double scale = 1 + M_C.norm() + F_C.norm();
        INFO("scene " << s.name << " joint " << J.name);
        if (J.type == JointType::Universal) {
          const Eigen::Vector2d motor = J.motor_universal.empty() ? Eigen::Vector2d::Zero() : J.motor_universal.value(t);
          const double tau1 = -J.stiffness * (v.col(J.name + ".angle1") - J.neutral_angle) -
                              J.damping * v.col(J.name + ".rate1") + motor(0);
          const double tau2 = -J.stiffness2 * (v.col(J.name + ".angle2") - J.neutral_angle2) -
                              J.damping2 * v.col(J.name + ".rate2") + motor(1);
          // The second axis is fixed in the child: R_PC = Rot(n1, a1) Rot(n2, a2) R_PJ0 turns
          // n2 by a1 only, and R_PJ0^T n2 is its child-frame copy.
          const Vector3d axis2_C = J.q_PJ0.conjugate() * J.axis2_P.normalized();
          REQUIRE(std::abs(J.axis_P.normalized().dot(J.axis2_P.normalized())) < 1e-12);
          CHECK(std::abs(M_C.dot(axis_C) - tau1) <= 1e-11 * scale);
          CHECK(std::abs(M_C.dot(axis2_C) - tau2) <= 1e-11 * scale);
          worst = std::max({worst, std::abs(M_C.dot(axis_C) - tau1) / scale,
                            std::abs(M_C.dot(axis2_C) - tau2) / scale});
          ++universal;
          continue;
        }
        double load = 0;
        if (J.prescribed) {
          load = v.col(J.name + (J.type == JointType::Revolute ? ".torque" : ".force"));
        } else {
          const std::string c = J.type == JointType::Revolute ? ".angle" : ".position";
          load = -J.stiffness * (v.col(J.name + c) - J.neutral_angle) - J.damping * v.col(J.name + ".rate") +
                 (J.motor_revolute.empty() ? 0.0 : J.motor_revolute.value(t)(0));
        }
        const double along = J.type == JointType::Revolute ? M_C.dot(axis_C) : F_C.dot(axis_C);
        CHECK(std::abs(along - load) <= 1e-11 * scale);
        worst = std::max(worst, std::abs(along - load) / scale);
        ++(J.type == JointType::Revolute ? revolute : prismatic);
      }
    }
  }
  CHECK(revolute > 10);
  CHECK(prismatic >= 2);
  CHECK(universal >= 1);
  WARN("worst joint torque (force) along its axis vs its law: " << worst << " of the load scale");
}

// P and M against the engine's own E and H along its own flow, at random states of scenes with
// motors, dampers, prescribed joints (a prescribed base too), external torques and modal damping.
TEST_CASE("newton-euler loads: P is dE/dt and M is dH/dt along the flow", "[newton_euler][loads]") {
  std::mt19937 rng(11);
  double worst_P = 0, worst_M = 0, worst_P_rel = 0, worst_M_rel = 0;
  for (const char* name : {"chain_motor", "hub_two_panels", "spinup_beam", "scan_platform",
                           "pointing_flex", "hub_flex_array", "free_beam_payload", "gimbal_payload",
                           "telescoping_boom", "dual_spin", "chain5"}) {
    const System s = read_scene(scene_path(name));
    const double t = eval_time(s.name);
    for (int trial = 0; trial < 3; ++trial) {
      Eval v = evaluate(s, random_scene_state(s, rng, t, 0.05, 0.2), t);
      const std::vector<double> d = flow_rate(v, {"E", "Hx", "Hy", "Hz"});
      const double P = v.col("P"), E = v.col("E");
      const Vector3d M = v.vec("Mx", "My", "Mz"), H = v.vec("Hx", "Hy", "Hz");
      const Vector3d dH(d[1], d[2], d[3]);
      // Scales: the power of the loads that act (|P|, the dampers' part), and room for the
      // round-off of the difference, eps |E| / h ~ 1e-12 |E| (1e-6 of 1e-4 |E|); likewise for H.
      const double scale_P = std::abs(P) + std::abs(damper_power(s, v)) + 1e-4 * std::abs(E);
      const double scale_M = M.norm() + 1e-4 * H.norm();
      const double rP = std::abs(d[0] - P) / scale_P, rM = (dH - M).norm() / scale_M;
      INFO(name << " trial " << trial << ": P " << P << " dE/dt " << d[0] << " (E " << E << "); M "
                << M.transpose() << " dH/dt " << dH.transpose() << " (|H| " << H.norm() << ")");
      CHECK(rP <= 1e-6);
      CHECK(rM <= 1e-6);
      worst_P = std::max(worst_P, rP);
      worst_M = std::max(worst_M, rM);
      // Relative to the loads alone, where they are well above the difference's round-off.
      const double loads_P = std::abs(P) + std::abs(damper_power(s, v));
      if (loads_P > 1e-3 * std::abs(E)) worst_P_rel = std::max(worst_P_rel, std::abs(d[0] - P) / loads_P);
      if (M.norm() > 1e-3 * H.norm()) worst_M_rel = std::max(worst_M_rel, (dH - M).norm() / M.norm());
    }
  }
  WARN("where the loads are > 1e-3 of E (H): |dE/dt - P| / (|P| + |dampers' power|) " << worst_P_rel
       << ", |dH/dt - M| / |M| " << worst_M_rel);
  WARN("worst |dE/dt - P| " << worst_P << ", |dH/dt - M| " << worst_M << " (relative to their scales)");
}

// The power column is physical, not the engine's generalised forces: a scene whose loads are all
// internal and conservative at a state where they do no work has P = 0 exactly (chain5: spherical
// joints without springs, dampers or motors); a torque-only scene's P is T . w.
TEST_CASE("newton-euler loads: P and M vanish without non-conservative or external loads",
          "[newton_euler][loads]") {
  std::mt19937 rng(5);
  for (const char* name : {"chain5", "spear1_case1", "torque_free_asymmetric"}) {
    const System s = read_scene(scene_path(name));
    Eval v = evaluate(s, random_scene_state(s, rng, 0.3, 0.0, 0.0), 0.3);
    INFO(name);
    CHECK(v.col("P") == 0.0);
    CHECK(v.vec("Mx", "My", "Mz").norm() == 0.0);
  }
}

// EngineOptions::test_damper_scale: 0 removes the dampers from the equations of motion (the
// accelerations change, dE/dt loses the dampers' power) and not from P; 1 is the default exactly.
// (A prescribed joint's drive power is torque theta', and its torque, a multiplier, follows the
// equations of motion: on telescoping_boom P's other terms are compared.)
TEST_CASE("newton-euler loads: test_damper_scale changes the accelerations and not P",
          "[newton_euler][loads]") {
  std::mt19937 rng(9);
  for (const char* name : {"hub_two_panels", "free_beam_payload", "gimbal_payload", "telescoping_boom",
                           "hub_flex_array"}) {
    const System s = read_scene(scene_path(name));
    const double t = eval_time(s.name);
    const TreeState ts = random_scene_state(s, rng, t, 0.05, 0.2);
    EngineOptions zero, one;
    zero.test_damper_scale = 0.0;
    one.test_damper_scale = 1.0;
    Eval v = evaluate(s, ts, t), v0 = evaluate(s, ts, t, zero), v1 = evaluate(s, ts, t, one);
    INFO(name);
    CHECK(v1.row == v.row);  // bitwise: the default
    if (drive_power(s, v) == 0) {
      CHECK(v0.col("P") == v.col("P"));
    } else {
      CHECK(drive_power(s, v0) != drive_power(s, v));
      CHECK(std::abs((v0.col("P") - drive_power(s, v0)) - (v.col("P") - drive_power(s, v))) <=
            1e-14 * std::abs(v.col("P")));
    }
    CHECK(v0.col("E") == v.col("E"));
    const double damp = damper_power(s, v);
    CHECK(damp < 0);
    TreeAccel a, a0;
    v.e->accelerations(t, v.x.data(), a);
    v0.e->accelerations(t, v0.x.data(), a0);
    double change = 0;
    for (std::size_t b = 0; b < s.bodies.size(); ++b) {
      change = std::max({change, (a.a_NBo_N[b] - a0.a_NBo_N[b]).norm(), (a.wdot_NB_B[b] - a0.wdot_NB_B[b]).norm()});
      if (a.eta_ddot[b].size() > 0) change = std::max(change, (a.eta_ddot[b] - a0.eta_ddot[b]).norm());
    }
    CHECK(change > 1e-6);
    // Without the dampers in the equations, E changes by P minus the dampers' power.
    const double dE0 = flow_rate(v0, {"E"})[0];
    CHECK(std::abs(dE0 - (v0.col("P") - damp)) <=
          1e-6 * (std::abs(v0.col("P")) + std::abs(damp) + 1e-4 * std::abs(v.col("E"))));
  }
  EngineOptions bad;
  bad.test_damper_scale = std::nan("");
  CHECK_THROWS_AS(make_newton_euler_engine(read_scene(scene_path("hub_two_panels")), bad), InputError);
}

// docs/conventions.md's worked example: a rod (mass m, length L, x along the rod, CM at x = L/2
// from the hinge) on a revolute joint about z at point (d, 0, 0) of a base held still by a
// prescribed base joint to N (spin-up at rate 0: the base never turns).
//   At rest with a motor torque tau: the rod turns about the hinge, which does not move, so its
//   Euler equation about the hinge is (m L^2 / 3) theta'' = tau; its CM accelerates at
//   (L/2) theta'' along y, so F_C = m (L/2) tau / (m L^2 / 3) y = (0, 3 tau / (2 L), 0) and
//   M_J_C = (0, 0, tau) (the pin's moment normal to the axis is zero: the rod is planar and at
//   rest). The base is at rest: N's load on it balances the rod's reaction, F_0 = F_C (base axes =
//   N = the rod's axes at angle 0) and, about the base joint point (the base's CM, the origin),
//   M_0 = M_J_C + (d, 0, 0) x F_C = (0, 0, tau + 3 d tau / (2 L)), which is also the base's drive
//   torque (its .torque column) and, moved to the system CM c = (m (d + L/2) / (M + m), 0, 0),
//   the external moment M_N = M_0 - c x F_0 (dH/dt about the CM).
//   Turning at rate w with no load instead: F_C = (-m w^2 L / 2, 0, 0), the centripetal pull,
//   and M_J_C = 0.
TEST_CASE("newton-euler loads: a motor-driven rod on a held base matches the hand solution",
          "[newton_euler][loads]") {
  const double M = 50, m = 3, L = 2, d = 0.7, tau = 4, w = 1.5;
  System s;
  s.name = "held_rod";
  s.bodies = {make_body("base", M, Vector3d(5, 6, 7).asDiagonal()),
              make_body("rod", m, Vector3d(0.001, m * L * L / 12, m * L * L / 12).asDiagonal())};
  Joint base;
  base.name = "hold";
  base.type = JointType::Revolute;
  base.parent = -1;
  base.child = 0;
  base.axis_P = Vector3d::UnitZ();
  base.prescribed = PrescribedMotion{};  // spin-up to rate 0: theta = 0 at all times
  base.prescribed->rate = 0;
  Joint hinge;
  hinge.name = "hinge";
  hinge.type = JointType::Revolute;
  hinge.parent = 0;
  hinge.child = 1;
  hinge.p_PoJ_P = Vector3d(d, 0, 0);
  hinge.p_CoJ_C = Vector3d(-L / 2, 0, 0);
  hinge.axis_P = Vector3d::UnitZ();
  hinge.motor_revolute.times = {0.0};
  hinge.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(tau)};
  s.joints = {base, hinge};
  s.zero_linear_momentum = false;

  Eval v = evaluate(s, TreeState::initial(s), 0.0);
  const double tol = 1e-12;
  const Vector3d F = v.vec("hinge.Fx", "hinge.Fy", "hinge.Fz"), Mj = v.vec("hinge.Mx", "hinge.My", "hinge.Mz");
  INFO("F " << F.transpose() << " M " << Mj.transpose());
  CHECK((F - Vector3d(0, 3 * tau / (2 * L), 0)).norm() <= tol);
  CHECK((Mj - Vector3d(0, 0, tau)).norm() <= tol);
  const Vector3d F0 = v.vec("hold.Fx", "hold.Fy", "hold.Fz"), M0 = v.vec("hold.Mx", "hold.My", "hold.Mz");
  const double M0z = tau + 3 * d * tau / (2 * L);
  CHECK((F0 - F).norm() <= tol);
  CHECK((M0 - Vector3d(0, 0, M0z)).norm() <= tol);
  CHECK(std::abs(v.col("hold.torque") - M0z) <= tol);
  const Vector3d c(m * (d + L / 2) / (M + m), 0, 0);
  CHECK((v.vec("CMx", "CMy", "CMz") - c).norm() <= tol);
  CHECK((v.vec("Mx", "My", "Mz") - (M0 - c.cross(F0))).norm() <= tol);
  CHECK(v.col("P") == 0.0);  // at rest: no joint or drive moves
  TreeAccel a;
  v.e->accelerations(0.0, v.x.data(), a);
  CHECK(std::abs(a.angle_ddot[1] - tau / (m * L * L / 3)) <= tol);

  // Turning at rate w, no motor: the centripetal pull.
  s.joints[1].motor_revolute = {};
  TreeState ts = TreeState::initial(s);
  ts.joints[1].rate = w;
  Eval u = evaluate(s, ts, 0.0);
  CHECK((u.vec("hinge.Fx", "hinge.Fy", "hinge.Fz") - Vector3d(-m * w * w * L / 2, 0, 0)).norm() <= tol);
  CHECK(u.vec("hinge.Mx", "hinge.My", "hinge.Mz").norm() <= tol);
}

// The old extra columns <joint>.fx .. .mz (constraint wrench, parent frame) are gone: the pinned
// total loads <joint>.Fx .. .Mz supersede them; constraint.* stay.
TEST_CASE("newton-euler loads: no lower-case wrench extras, constraint extras kept",
          "[newton_euler][loads]") {
  const System s = read_scene(scene_path("spear1_case1"));
  auto e = make_newton_euler_engine(s, {});
  for (const std::string& c : e->columns())
    for (const char* old : {".fx", ".fy", ".fz", ".mx", ".my", ".mz"})
      CHECK(c.find(old) == std::string::npos);
  for (const char* c : {"hinge1.Fx", "hinge2.Mz", "P", "Mx", "CMz", "Hx", "constraint.pos",
                        "constraint.vel", "constraint.ang", "constraint.angvel"})
    CHECK_NOTHROW(column(*e, c));
}

}  // namespace
}  // namespace crossdyn::test::ne
