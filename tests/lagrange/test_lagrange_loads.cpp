// The Lagrange engine's issue-26 outputs (docs/conventions.md "Positions, momentum, power and joint
// loads"): joint loads, power P, external moment, the test_damper_scale hook. Physics checks at
// random states of the committed scenes:
//   - the loads close every rigid body's Newton-Euler equations (Greenwood, "Advanced Dynamics"
//     2003, Ch. 1 and Euler's equations: m a_CM = sum F, d/dt(I w) = sum M about the CM) with the
//     engine's own accelerations(), and every flexible body's force equation with its deformed CM's
//     acceleration (Kane & Levinson 1985, Sec. 2.3 for a point moving on a body);
//   - a revolute joint's moment along its axis (prismatic: force along its axis; universal: along
//     each current axis) is the joint's torque (system.hpp "Loads");
//   - P = dE/dt and M = dH/dt along the motion, by central differences of the engine's own E and H;
//   - test_damper_scale = 0 changes the accelerations and not P;
//   - statics: the worked example of docs/conventions.md (a rod hinged to a base held still).
#include <catch2/catch.hpp>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "core/scene/scene.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "tests/lagrange/scenes.hpp"
#include "tests/support/paths.hpp"

using namespace crossdyn;
using crossdyn::lagrange::LagrangeEngine;

namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

// A random state: any base attitude and rates, joint angles and rates of order one, small modal
// coordinates with rates of order one tenth (prescribed joints come from their profiles at t).
TreeState random_tree_state(const System& system, std::mt19937& g) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&](double scale) -> Vec3 { return Vec3(u(g), u(g), u(g)) * scale; };
  TreeState s = TreeState::initial(system);
  s.p_NoBo_N = vec(2.0);
  s.q_NB = test::random_quaternion(g);
  s.v_NBo_N = vec(0.5);
  s.w_NB_B = vec(0.5);
  for (std::size_t j = 0; j < system.joints.size(); ++j) {
    TreeState::JointState& J = s.joints[j];
    if (system.joints[j].type == JointType::Prismatic) {
      J.angle += 0.3 * u(g);
      J.rate = 0.3 * u(g);
    } else {
      J.angle = 1.5 * u(g);
      J.rate = u(g);
    }
    J.angle2 = 1.0 * u(g);
    J.rate2 = u(g);
    J.q_J = test::random_quaternion(g);
    J.w_PC_C = vec(0.5);
  }
  for (std::size_t b = 0; b < system.bodies.size(); ++b)
    for (Eigen::Index k = 0; k < s.eta[b].size(); ++k) {
      s.eta[b](k) = 0.02 * u(g);
      s.eta_rate[b](k) = 0.1 * u(g);
    }
  return s;
}

// One evaluation of the engine at (t, x): its row, xdot and accelerations.
struct At {
  double t = 0;
  std::vector<double> x, xdot, row;
  TreeAccel a;
};

At evaluate_at(LagrangeEngine& e, double t, const std::vector<double>& x) {
  At r;
  r.t = t;
  r.x = x;
  r.xdot.resize(x.size());
  r.row.resize(e.layout().size());
  e.rhs(t, x.data(), r.xdot.data());
  e.output_row(t, x.data(), r.row.data());
  e.accelerations(t, x.data(), r.a);
  return r;
}

At random_at(LagrangeEngine& e, const System& s, double t, std::mt19937& g) {
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(random_tree_state(s, g), x.data());
  return evaluate_at(e, t, x);
}

// Row readers (core/output_layout.hpp).
struct Row {
  const OutputLayout& L;
  const std::vector<double>& r;
  double at(int c) const { return r[static_cast<std::size_t>(c)]; }
  Vec3 v3(int c) const { return Vec3(at(c), at(c + 1), at(c + 2)); }
  Mat3 R(int b) const {  // R_NB from q_NB
    const int c = L.body_q(b);
    const Eigen::Quaterniond q(at(c), at(c + 1), at(c + 2), at(c + 3));
    return q.normalized().toRotationMatrix();
  }
  Vec3 w(int b) const { return v3(L.body_w(b)); }
  Vec3 p(int b) const { return v3(L.body_position(b)); }
  Vec3 F_C(int j) const { return v3(L.joint_load(j)); }
  Vec3 M_C(int j) const { return v3(L.joint_load(j) + 3); }
  Eigen::VectorXd eta(int b, int nm) const {
    Eigen::VectorXd e(nm);
    for (int k = 0; k < nm; ++k) e(k) = at(L.modal_first(b) + k);
    return e;
  }
  Eigen::VectorXd eta_rate(int b, int nm) const {
    Eigen::VectorXd e(nm);
    for (int k = 0; k < nm; ++k) e(k) = at(L.modal_first(b) + nm + k);
    return e;
  }
};

Vec3 external_torque_N(const Body& B, double t, const Mat3& R_NB) {
  if (B.torque.empty()) return Vec3::Zero();
  const Vec3 tau = B.torque.value(t);
  return B.torque_frame == Body::Frame::Inertial ? tau : Vec3(R_NB * tau);
}

int joint_of(const System& s, int body) {
  for (std::size_t j = 0; j < s.joints.size(); ++j)
    if (s.joints[j].child == body) return static_cast<int>(j);
  return -1;
}

// A node's displaced point p_i + Phi_i eta (+ e_i eta^T G_i eta / 2 with geometric stiffening),
// body frame (system.hpp, FlexBody).
Vec3 node_point(const FlexBody& f, int node, const Eigen::VectorXd& eta) {
  const FlexNode& n = f.nodes[static_cast<std::size_t>(node)];
  Vec3 r = n.p_BoNi_B + n.Phi_B * eta;
  if (f.geometric_stiffening && n.G.size() > 0) r += n.e_B * (0.5 * eta.dot(n.G * eta));
  return r;
}

// The loads' residuals of body b's Newton-Euler equations, relative to their scale:
// {force, moment}: a rigid body's moment equation about its CM, a flexible body's about its origin
// Bo (the undeformed CM) summed over its nodes.
struct Closure {
  double force = 0, moment = 0, F_scale = 0, M_scale = 0;
};
Closure newton_euler(const System& s, const OutputLayout& L, const At& at, int b) {
  const Row row{L, at.row};
  const Body& B = s.bodies[static_cast<std::size_t>(b)];
  const Mat3 R_b = row.R(b);
  const int j_own = joint_of(s, b);
  const Joint& own = s.joints[static_cast<std::size_t>(j_own)];
  Vec3 F = Vec3::Zero(), M = Vec3::Zero();  // about the body's CM (rigid), N components
  double F_scale = 0, M_scale = 0;
  // The own joint's load on b, at its point (a rigid child: p_CoJ_C; a node of a flexible one:
  // its displaced point, used for the force only).
  if (own.type != JointType::Free) {
    const Vec3 F_own = R_b * row.F_C(j_own), M_own = R_b * row.M_C(j_own);
    F += F_own;
    const Vec3 arm =
        R_b * (own.child_node >= 0 ? node_point(*B.flex, own.child_node,
                                                row.eta(b, B.flex->modes()))
                                   : own.p_CoJ_C);
    M += M_own + arm.cross(F_own);
    F_scale = std::max(F_scale, F_own.norm());
    M_scale = std::max({M_scale, M_own.norm(), arm.cross(F_own).norm()});
  }
  // The child joints' reactions on b: -F, -M at their points; on a rigid parent the point is
  // p_PoJ_P (+ s axis_P on a prismatic joint: the point on the child, which slides).
  for (std::size_t k = 0; k < s.joints.size(); ++k) {
    const Joint& J = s.joints[k];
    if (J.parent != b) continue;
    const int c = J.child;
    const Mat3 R_c = row.R(c);
    const Vec3 F_k = R_c * row.F_C(static_cast<int>(k)), M_k = R_c * row.M_C(static_cast<int>(k));
    Vec3 r_P = J.parent_node >= 0 ? node_point(*B.flex, J.parent_node, row.eta(b, B.flex->modes()))
                                  : J.p_PoJ_P;
    if (J.type == JointType::Prismatic)
      r_P += row.at(L.joint_first(static_cast<int>(k))) * J.axis_P.normalized();
    const Vec3 arm = R_b * r_P;
    F -= F_k;
    M -= M_k + arm.cross(F_k);
    F_scale = std::max(F_scale, F_k.norm());
    M_scale = std::max({M_scale, M_k.norm(), arm.cross(F_k).norm()});
  }
  const Vec3 T = external_torque_N(B, at.t, R_b);
  M += T;
  M_scale = std::max(M_scale, T.norm());
  Closure out;
  if (!B.flex) {
    // m a_CM = F; R (I w' + w x I w) = M about the CM (Euler's equations in body axes).
    const Vec3 ma = B.mass * at.a.a_NBo_N[static_cast<std::size_t>(b)];
    const Vec3 w = row.w(b), wd = at.a.wdot_NB_B[static_cast<std::size_t>(b)];
    const Vec3 Iwd = R_b * (B.I_BBo_B * wd), gyro = R_b * w.cross(B.I_BBo_B * w);
    F_scale = std::max(F_scale, ma.norm());
    M_scale = std::max({M_scale, Iwd.norm(), gyro.norm()});
    out.force = (ma - F).norm();
    out.moment = (Iwd + gyro - M).norm();
  } else {
    // sum m_i a_i = m a of the deformed CM s / m, s = sum m_i r_i (body components, r_i =
    // p_i + Phi_i eta + e_i eta^T G_i eta / 2): a_cm = a_Bo + R (w' x s + w x (w x s) + 2 w x s' +
    // s'') / m (Kane & Levinson 1985, Sec. 2.3).
    const FlexBody& f = *B.flex;
    const int nm = f.modes();
    const Eigen::VectorXd eta = row.eta(b, nm), ed = row.eta_rate(b, nm),
                          edd = at.a.eta_ddot[static_cast<std::size_t>(b)];
    Vec3 sB = Vec3::Zero(), sd = Vec3::Zero(), sdd = Vec3::Zero();
    double m = 0;
    for (const FlexNode& n : f.nodes) {
      m += n.mass;
      Vec3 r = n.p_BoNi_B + n.Phi_B * eta, v = n.Phi_B * ed, a = n.Phi_B * edd;
      if (f.geometric_stiffening && n.G.size() > 0) {
        r += n.e_B * (0.5 * eta.dot(n.G * eta));
        v += n.e_B * eta.dot(n.G * ed);
        a += n.e_B * (ed.dot(n.G * ed) + eta.dot(n.G * edd));
      }
      sB += n.mass * r;
      sd += n.mass * v;
      sdd += n.mass * a;
    }
    const Vec3 w = row.w(b), wd = at.a.wdot_NB_B[static_cast<std::size_t>(b)];
    const Vec3 ma = m * at.a.a_NBo_N[static_cast<std::size_t>(b)] +
                    R_b * (wd.cross(sB) + w.cross(w.cross(sB)) + 2.0 * w.cross(sd) + sdd);
    F_scale = std::max(F_scale, ma.norm());
    out.force = (ma - F).norm();
    // About Bo: sum_i r_i x m_i a_i + sum_i (J_i w' + w x J_i w), body components, with the node's
    // acceleration a_i = a_Bo + w' x r_i + w x (w x r_i) + 2 w x u_i' + u_i'' (Kane & Levinson
    // 1985, Sec. 2.3).
    const Vec3 a_Bo_B = R_b.transpose() * at.a.a_NBo_N[static_cast<std::size_t>(b)];
    Vec3 H_B = Vec3::Zero();
    double H_scale = 0;
    for (const FlexNode& n : f.nodes) {
      Vec3 r = n.p_BoNi_B + n.Phi_B * eta, v = n.Phi_B * ed, a = n.Phi_B * edd;
      if (f.geometric_stiffening && n.G.size() > 0) {
        r += n.e_B * (0.5 * eta.dot(n.G * eta));
        v += n.e_B * eta.dot(n.G * ed);
        a += n.e_B * (ed.dot(n.G * ed) + eta.dot(n.G * edd));
      }
      const Vec3 a_i = a_Bo_B + wd.cross(r) + w.cross(w.cross(r)) + 2.0 * w.cross(v) + a;
      const Vec3 term = n.mass * r.cross(a_i) + n.J_Ni_B * wd + w.cross(n.J_Ni_B * w);
      H_B += term;
      H_scale = std::max(H_scale, term.norm());
    }
    M_scale = std::max(M_scale, H_scale);
    out.moment = (R_b * H_B - M).norm();
  }
  out.F_scale = F_scale;
  out.M_scale = M_scale;
  return out;
}

// A time for the random states of a scene: inside its first motor window or prescribed ramp.
double probe_time(int trial) { return 0.3 + 0.45 * trial; }

}  // namespace

TEST_CASE("lagrange loads: the joint loads close every body's Newton-Euler equations",
          "[lagrange][loads]") {
  std::mt19937 g(2606);
  for (const std::string& path : test::committed_scenes()) {
    const System s = read_scene(path);
    // No field in this closure: gravity's loads are checked by test_lagrange_gravity.cpp and,
    // between engines, tests/cross/test_gravity.cpp.
    if (!s.environment.none()) continue;
    LagrangeEngine e(s, {});
    double worst_F = 0, worst_M = 0, worst_flex = 0, worst_flex_M = 0;
    for (int trial = 0; trial < 3; ++trial) {
      const At at = random_at(e, s, probe_time(trial), g);
      for (std::size_t b = 0; b < s.bodies.size(); ++b) {
        Closure c = newton_euler(s, e.layout(), at, static_cast<int>(b));
        // A body with no load and no acceleration (a lone free body) closes exactly.
        c.F_scale = std::max(c.F_scale, 1e-300);
        c.M_scale = std::max(c.M_scale, 1e-300);
        if (s.bodies[b].flex) {
          worst_flex = std::max(worst_flex, c.force / c.F_scale);
          worst_flex_M = std::max(worst_flex_M, c.moment / c.M_scale);
        } else {
          worst_F = std::max(worst_F, c.force / c.F_scale);
          worst_M = std::max(worst_M, c.moment / c.M_scale);
        }
      }
    }
    std::printf("NE closure %-24s rigid force %.1e moment %.1e, flexible force %.1e moment %.1e\n",
                s.name.c_str(), worst_F, worst_M, worst_flex, worst_flex_M);
    CHECK(worst_F < 1e-10);
    CHECK(worst_M < 1e-10);
    CHECK(worst_flex < 1e-9);
    CHECK(worst_flex_M < 1e-9);
  }
}

TEST_CASE("lagrange loads: a joint's moment (force) along its axis is the joint's torque (force)",
          "[lagrange][loads]") {
  std::mt19937 g(2607);
  int checked = 0;
  for (const std::string& path : test::committed_scenes()) {
    const System s = read_scene(path);
    LagrangeEngine e(s, {});
    const OutputLayout& L = e.layout();
    double worst = 0;
    for (int trial = 0; trial < 3; ++trial) {
      const At at = random_at(e, s, probe_time(trial), g);
      const Row row{L, at.row};
      for (std::size_t j = 0; j < s.joints.size(); ++j) {
        const Joint& J = s.joints[j];
        const int jj = static_cast<int>(j);
        if (J.type != JointType::Revolute && J.type != JointType::Prismatic &&
            J.type != JointType::Universal)
          continue;
        // The parent side's frame in N (N itself for a prescribed base), turned by the node's slope
        // exp([psi x]), psi = Psi eta, at a node of a flexible parent (system.hpp).
        Mat3 R_NJp = J.parent >= 0 ? row.R(J.parent) : Mat3::Identity();
        if (J.parent_node >= 0) {
          const FlexBody& f = *s.bodies[static_cast<std::size_t>(J.parent)].flex;
          const Vec3 psi = f.nodes[static_cast<std::size_t>(J.parent_node)].Psi_B *
                           row.eta(J.parent, f.modes());
          if (psi.norm() > 0)
            R_NJp = R_NJp * Eigen::AngleAxisd(psi.norm(), psi.normalized()).toRotationMatrix();
        }
        const Mat3 R_CN = row.R(J.child).transpose();
        const Vec3 F_C = row.F_C(jj), M_C = row.M_C(jj);
        const int c0 = L.joint_first(jj);
        const Vec3 m1 = J.motor_revolute.empty() ? Vec3::Zero()
                                                 : Vec3(J.motor_revolute.value(at.t)(0), 0, 0);
        if (J.type == JointType::Universal) {
          // T . a_k = tau_k on the current axes: a_1 fixed in the parent, a_2 = R_PJ0^T axis2_P
          // in the child (system.hpp).
          const Vec3 a1 = R_CN * R_NJp * J.axis_P.normalized();
          const Vec3 a2 = J.q_PJ0.toRotationMatrix().transpose() * J.axis2_P.normalized();
          const Eigen::Vector2d mot =
              J.motor_universal.empty() ? Eigen::Vector2d::Zero() : J.motor_universal.value(at.t);
          const double tau1 = -J.stiffness * (row.at(c0) - J.neutral_angle) -
                              J.damping * row.at(c0 + 2) + mot(0);
          const double tau2 = -J.stiffness2 * (row.at(c0 + 1) - J.neutral_angle2) -
                              J.damping2 * row.at(c0 + 3) + mot(1);
          const double scale = std::max({M_C.norm(), std::abs(tau1), std::abs(tau2), 1e-12});
          worst = std::max({worst, std::abs(M_C.dot(a1) - tau1) / scale,
                            std::abs(M_C.dot(a2) - tau2) / scale});
          ++checked;
          continue;
        }
        const Vec3 axis_C = R_CN * R_NJp * J.axis_P.normalized();
        // -k (q - neutral) - c q' + motor, or the prescribed drive's column.
        const double spring_damper_motor = -J.stiffness * (row.at(c0) - J.neutral_angle) -
                                           J.damping * row.at(c0 + 1) + m1(0);
        const double expected = J.prescribed ? row.at(c0 + 2) : spring_damper_motor;
        const Vec3& load = J.type == JointType::Revolute ? M_C : F_C;
        // A joint that carries a force but no moment about its axis (a hanging pendulum's held
        // base): its moment is rounding of the force times the lever (force times 1 m in the scale).
        const double scale = std::max({load.norm(), std::abs(expected), F_C.norm(), 1e-12});
        worst = std::max(worst, std::abs(load.dot(axis_C) - expected) / scale);
        ++checked;
      }
    }
    std::printf("axis load %-34s worst %.1e\n", s.name.c_str(), worst);
    CHECK(worst < 1e-10);
  }
  CHECK(checked > 20);
}

TEST_CASE("lagrange loads: P = dE/dt and M = dH/dt along the motion", "[lagrange][loads]") {
  std::mt19937 g(2608);
  for (const std::string& path : test::committed_scenes()) {
    const System s = read_scene(path);
    // On an orbit dE/dt has the potential's turning, which P leaves out (docs/environment.md).
    if (s.environment.orbit()) continue;
    LagrangeEngine e(s, {});
    const OutputLayout& L = e.layout();
    double worst_P = 0, worst_H = 0, max_P = 0;
    for (int trial = 0; trial < 3; ++trial) {
      const At at = random_at(e, s, probe_time(trial), g);
      // Central differences of fourth order along the motion's tangent, x + k h xdot at t + k h
      // (k = +-1, +-2): d/dt f = (8 (f_1 - f_-1) - (f_2 - f_-2)) / (12 h) + O(h^4).
      const double h = 1e-3;
      auto moved = [&](double k) {
        std::vector<double> y = at.x;
        for (std::size_t i = 0; i < y.size(); ++i) y[i] += k * h * at.xdot[i];
        std::vector<double> r(L.size());
        e.output_row(at.t + k * h, y.data(), r.data());
        return r;
      };
      const std::vector<double> u1 = moved(1), d1 = moved(-1), u2 = moved(2), d2 = moved(-2);
      const Row row{L, at.row};
      auto rate = [&](int c) {
        const auto f = [&](const std::vector<double>& r) { return r[static_cast<std::size_t>(c)]; };
        return (8.0 * (f(u1) - f(d1)) - (f(u2) - f(d2))) / (12.0 * h);
      };
      const double dE = rate(L.E());
      const Vec3 dH(rate(L.H_vector()), rate(L.H_vector() + 1), rate(L.H_vector() + 2));
      const double P = row.at(L.P());
      const Vec3 M = row.v3(L.external_moment());
      // Scales: the power and moment themselves, floored by the kinetic energy's and momentum's
      // rates of order |E| / 1 s and |H| / 1 s times 1e-3 (states where nothing works).
      const double P_scale = std::max({std::abs(P), std::abs(dE), 1e-3 * std::abs(row.at(L.E()))});
      const double H_scale = std::max({M.norm(), dH.norm(), 1e-3 * row.v3(L.H_vector()).norm()});
      worst_P = std::max(worst_P, std::abs(P - dE) / P_scale);
      worst_H = std::max(worst_H, (M - dH).norm() / H_scale);
      max_P = std::max(max_P, std::abs(P));
      // The H columns: Hx Hy Hz and their norm H.
      CHECK(row.v3(L.H_vector()).norm() == Approx(row.at(L.H())).epsilon(1e-14));
    }
    std::printf("balance %-34s |P - dE/dt| %.1e, |M - dH/dt| %.1e (max |P| %.2e)\n",
                s.name.c_str(), worst_P, worst_H, max_P);
    CHECK(worst_P < 1e-6);
    CHECK(worst_H < 1e-6);
  }
}

TEST_CASE("lagrange loads: test_damper_scale changes the accelerations, not P",
          "[lagrange][loads]") {
  for (const char* name : {"hub_two_panels", "free_beam_payload", "gimbal_payload"}) {
    const System s = read_scene(test::scene_path(name));
    EngineOptions zero;
    zero.test_damper_scale = 0.0;
    LagrangeEngine e1(s, {}), e0(s, zero);
    std::mt19937 g(2609);
    const TreeState st = random_tree_state(s, g);
    std::vector<double> x(static_cast<std::size_t>(e1.state_size()));
    e1.pack(st, x.data());
    const At a1 = evaluate_at(e1, 0.3, x), a0 = evaluate_at(e0, 0.3, x);
    double diff = 0, norm = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      diff = std::max(diff, std::abs(a1.xdot[i] - a0.xdot[i]));
      norm = std::max(norm, std::abs(a1.xdot[i]));
    }
    INFO(name);
    CHECK(diff > 1e-6 * norm);
    const int P = e1.layout().P();
    CHECK(a1.row[static_cast<std::size_t>(P)] == a0.row[static_cast<std::size_t>(P)]);
    CHECK(a1.row[static_cast<std::size_t>(P)] != 0.0);
  }
}

// docs/conventions.md's worked example: a rod of mass m and length L (child frame x along the rod,
// CM at x = L/2, hinge axis z) hinged at one end, at (d, 0, 0) of a base held still (a prescribed
// base at rate 0), angle 0.
//  - A motor torque tau at rest: the rod's moment of inertia about the hinge is m L^2/3 (parallel
//    axes: m L^2/12 + m (L/2)^2), so alpha = tau / (m L^2/3); its CM accelerates by (L/2) alpha
//    along y, so F_C = (0, m (L/2) alpha, 0) = (0, 3 tau / (2 L), 0), and about the hinge
//    M_J_C = (L/2 x) x (m (L/2) alpha y) + (m L^2/12) alpha z = (0, 0, tau). What N exerts on the
//    base (the base does not move) is the rod's m a_CM at the base joint point (the origin):
//    F = (0, 3 tau / (2 L), 0) and M = ((d + L/2) m (L/2) alpha + m L^2/12 alpha) z
//    = tau (1 + 3 d / (2 L)) z, which is also the prescribed base's torque column.
//  - Turning at rate w, no load: the centripetal pull F_C = (-m w^2 L/2, 0, 0), M_J_C = 0.
TEST_CASE("lagrange loads: statics of a rod hinged to a base held still (worked example)",
          "[lagrange][loads]") {
  const double m = 3.0, L = 2.0, d = 0.5, tau = 1.7, wr = 0.8;
  System s;
  s.name = "rod_statics";
  s.bodies = {test::make_body("base", 50, {4, 5, 6}),
              test::make_body("rod", m, {1e-3, m * L * L / 12, m * L * L / 12})};
  Joint base;
  base.name = "hold";
  base.type = JointType::Revolute;
  base.parent = -1;
  base.child = 0;
  base.axis_P = Vec3::UnitZ();
  base.prescribed = PrescribedMotion{};
  base.prescribed->rate = 0.0;
  Joint hinge;
  hinge.name = "hinge";
  hinge.type = JointType::Revolute;
  hinge.parent = 0;
  hinge.child = 1;
  hinge.p_PoJ_P = {d, 0, 0};
  hinge.p_CoJ_C = {-L / 2, 0, 0};
  hinge.axis_P = Vec3::UnitZ();
  s.joints = {base, hinge};
  s.zero_linear_momentum = false;
  s.run.duration = 1;
  s.run.output_step = 0.1;

  SECTION("motor torque at rest") {
    s.joints[1].motor_revolute.times = {0.0};
    s.joints[1].motor_revolute.values = {Eigen::Matrix<double, 1, 1>(tau)};
    LagrangeEngine e(s, {});
    std::vector<double> x(static_cast<std::size_t>(e.state_size()));
    e.pack(TreeState::initial(s), x.data());
    const At at = evaluate_at(e, 0.0, x);
    const Row row{e.layout(), at.row};
    const double alpha = tau / (m * L * L / 3);
    CHECK(at.a.angle_ddot[1] == Approx(alpha).epsilon(1e-13));
    const Vec3 F_expected(0, 3 * tau / (2 * L), 0), M_expected(0, 0, tau);
    CHECK((row.F_C(1) - F_expected).norm() < 1e-13 * F_expected.norm());
    CHECK((row.M_C(1) - M_expected).norm() < 1e-13 * tau);
    const Vec3 M0_expected(0, 0, tau * (1 + 3 * d / (2 * L)));
    CHECK((row.F_C(0) - F_expected).norm() < 1e-13 * F_expected.norm());
    CHECK((row.M_C(0) - M0_expected).norm() < 1e-13 * tau);
    CHECK(row.at(e.layout().joint_first(0) + 2) == Approx(M0_expected.z()).epsilon(1e-13));
    // P: the motor at rest does no work; the base is held: none either.
    CHECK(row.at(e.layout().P()) == 0.0);
  }
  SECTION("turning at rate w, no load") {
    s.joints[1].rate0 = wr;
    LagrangeEngine e(s, {});
    std::vector<double> x(static_cast<std::size_t>(e.state_size()));
    e.pack(TreeState::initial(s), x.data());
    const At at = evaluate_at(e, 0.0, x);
    const Row row{e.layout(), at.row};
    const Vec3 F_expected(-m * wr * wr * L / 2, 0, 0);
    CHECK((row.F_C(1) - F_expected).norm() < 1e-13 * F_expected.norm());
    CHECK(row.M_C(1).norm() < 1e-13 * F_expected.norm() * L);
  }
}
