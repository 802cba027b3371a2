// Issue 26 in the Kane engine: the joint loads, the momentum vector, the power P and the external
// moment (docs/conventions.md "Positions, momentum, power and joint loads"), checked against
// physics the engine does not use to compute them:
//   - each rigid body's own Newton-Euler equations with the engine's accelerations()
//     (m a = F_own - sum of the children's F; I w' + w x I w = the moments about the CM), and each
//     flexible body's momentum balance (its nodes' linear momentum and angular momentum about No,
//     differentiated along xdot);
//   - a revolute joint's moment about its axis (prismatic: force along it) against its spring,
//     damper and motor, a prescribed one's against its <joint>.torque column;
//   - P = dE/dt and M = dH/dt along the engine's own motion (central differences);
//   - test_damper_scale = 0 changes the accelerations and not P;
//   - a rod on a motor at rest on a free base against the hand solution.
#include <catch2/catch.hpp>

#include "core/scene/scene.hpp"
#include "formulations/kane/kane_engine.hpp"
#include "tests/kane/kane_flex_systems.hpp"
#include "tests/kane/kane_systems.hpp"
#include "tests/support/paths.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

using namespace crossdyn;
using namespace crossdyn::test::kane;
using Eigen::Matrix3d;
using Eigen::Vector3d;
using kane::BodyMotion;
using kane::KaneEngine;

namespace {

// A random state of the scene (random_flex_state, with a universal joint's second angle and rate
// too), packed by the engine.
std::vector<double> random_x(KaneEngine& e, const System& s, std::mt19937& g) {
  TreeState st = random_flex_state(s, g, 0.1);
  std::normal_distribution<double> n;
  for (std::size_t j = 1; j < s.joints.size(); ++j) {
    st.joints[j].angle2 = n(g);
    st.joints[j].rate2 = n(g);
    if (s.joints[j].type == JointType::Prismatic) st.joints[j].angle *= 0.3;  // a short slide
  }
  return packed(e, st);
}

std::vector<double> row_at(KaneEngine& e, double t, const std::vector<double>& x) {
  std::vector<double> row(e.layout().size());
  e.output_row(t, x.data(), row.data());
  return row;
}

Vector3d col3(const std::vector<double>& row, int c) {
  const std::size_t i = static_cast<std::size_t>(c);
  return Vector3d(row[i], row[i + 1], row[i + 2]);
}

// The load joint j passes from its parent to its child, in N, with its point (the child-side
// joint point); zero for the free joint.
struct LoadN {
  Vector3d F = Vector3d::Zero(), M = Vector3d::Zero(), p = Vector3d::Zero();
};
LoadN load_N(const KaneEngine& e, const std::vector<double>& row, const std::vector<BodyMotion>& bm,
             const std::vector<kane::JointFrames>& jf, const System& s, int j) {
  LoadN l;
  const int c = e.layout().joint_load(j);
  if (c < 0) return l;
  const Matrix3d& R_NC = bm[static_cast<std::size_t>(s.joints[static_cast<std::size_t>(j)].child)].R_NB;
  l.F = R_NC * col3(row, c);
  l.M = R_NC * col3(row, c + 3);
  l.p = jf[static_cast<std::size_t>(j)].p_NoJ_N_child;
  return l;
}

Vector3d torque_N(const Body& b, const Matrix3d& R_NB, double t) {
  if (b.torque.empty()) return Vector3d::Zero();
  return b.torque_frame == Body::Frame::Body ? Vector3d(R_NB * b.torque.value(t)) : b.torque.value(t);
}

// Newton-Euler residuals of every body at (t, x), relative to the scale of the loads in them.
struct Closure {
  double rigid_force = 0, rigid_moment = 0;  // worst relative residual over rigid bodies
  double flex_force = 0, flex_moment = 0;    // over flexible bodies (differences, h^4 error)
  int rigid = 0, flex = 0;                   // bodies checked
};

void closure(KaneEngine& e, const System& s, double t, const std::vector<double>& x,
             Closure& out) {
  const std::vector<double> row = row_at(e, t, x);
  TreeAccel acc;
  e.accelerations(t, x.data(), acc);
  e.set_time(t);
  const std::vector<BodyMotion> bm = e.body_motion(x.data());
  const std::vector<kane::JointFrames> jf = e.joint_frames(x.data());
  const int nb = static_cast<int>(s.bodies.size());
  // xdot for the flexible bodies' momentum derivatives.
  std::vector<double> xdot(x.size());
  e.rhs(t, x.data(), xdot.data());
  for (int b = 0; b < nb; ++b) {
    const Body& B = s.bodies[static_cast<std::size_t>(b)];
    const BodyMotion& m = bm[static_cast<std::size_t>(b)];
    const int own = s.joint_of_body(b);
    const LoadN L = load_N(e, row, bm, jf, s, own);
    // Sum of the loads on b: its own joint's, minus what it passes to each child (the reaction
    // -F, -M at the child's joint point), plus its external torque. Force and moment about No.
    Vector3d F = L.F, M_No = L.M + L.p.cross(L.F);
    double Fscale = L.F.norm(), Mscale = L.M.norm() + L.p.norm() * L.F.norm();
    for (std::size_t j = 0; j < s.joints.size(); ++j) {
      if (s.joints[j].parent != b) continue;
      const LoadN c = load_N(e, row, bm, jf, s, static_cast<int>(j));
      F -= c.F;
      M_No -= c.M + c.p.cross(c.F);
      Fscale = std::max(Fscale, c.F.norm());
      Mscale = std::max(Mscale, c.M.norm() + c.p.norm() * c.F.norm());
    }
    const Vector3d T_N = torque_N(B, m.R_NB, t);
    M_No += T_N;
    Mscale = std::max(Mscale, T_N.norm());
    if (!B.flex) {
      // Newton: m a_Bo = F.  Euler about the CM Bo: I alpha + w x I w = M_No - p_Bo x F.
      const Vector3d ma = B.mass * acc.a_NBo_N[static_cast<std::size_t>(b)];
      const Matrix3d I_N = m.R_NB * B.I_BBo_B * m.R_NB.transpose();
      const Vector3d w_N = m.R_NB * m.w_NB_B;
      const Vector3d alpha_N = m.R_NB * acc.wdot_NB_B[static_cast<std::size_t>(b)];
      const Vector3d Ia = I_N * alpha_N, wIw = w_N.cross(I_N * w_N);
      const Vector3d M_Bo = M_No - m.p_NoBo_N.cross(F);
      Fscale = std::max({Fscale, ma.norm(), 1e-300});
      Mscale = std::max({Mscale, Ia.norm(), wIw.norm(), m.p_NoBo_N.norm() * F.norm(), 1e-300});
      out.rigid_force = std::max(out.rigid_force, (ma - F).norm() / Fscale);
      out.rigid_moment = std::max(out.rigid_moment, (Ia + wIw - M_Bo).norm() / Mscale);
      ++out.rigid;
      continue;
    }
    // A flexible body: d/dt sum m_i v_i = F, d/dt (sum m_i x_i x v_i + J_i w) = M_No, the
    // momenta from the engine's mass points (node by node, no modal integrals) along xdot.
    auto momenta = [&](double h) {
      const std::vector<double> y = along(x, xdot, h);
      e.set_time(t + h);
      const std::vector<kane::MassPoint> pts = e.mass_points(y.data());
      const std::vector<BodyMotion> bmh = e.body_motion(y.data());
      const Vector3d w_N = bmh[static_cast<std::size_t>(b)].R_NB * bmh[static_cast<std::size_t>(b)].w_NB_B;
      Eigen::Matrix<double, 6, 1> P = Eigen::Matrix<double, 6, 1>::Zero();
      for (const kane::MassPoint& p : pts) {
        if (p.body != b) continue;
        P.head<3>() += p.mass * p.v_NP_N;
        P.tail<3>() += p.p_NoP_N.cross(p.mass * p.v_NP_N) + p.J_N * w_N;
      }
      return P;
    };
    const Eigen::Matrix<double, 6, 1> dP = derivative(momenta, 1e-3);
    e.set_time(t);
    Fscale = std::max({Fscale, dP.head<3>().norm(), 1e-300});
    Mscale = std::max({Mscale, dP.tail<3>().norm(), 1e-300});
    out.flex_force = std::max(out.flex_force, (dP.head<3>() - F).norm() / Fscale);
    out.flex_moment = std::max(out.flex_moment, (dP.tail<3>() - M_No).norm() / Mscale);
    ++out.flex;
  }
}

System scene(const std::string& name) { return read_scene(crossdyn::test::scene_path(name)); }

}  // namespace

TEST_CASE("kane loads: every body's Newton-Euler equations close with the joint loads, every "
          "committed scene, random states") {
  double worst_rf = 0, worst_rm = 0, worst_ff = 0, worst_fm = 0;
  for (const std::string& path : crossdyn::test::committed_scenes()) {
    const System s = read_scene(path);
    // The closure here has no field: gravity's loads on the bodies are checked by
    // test_kane_gravity.cpp and, between engines, tests/cross/test_gravity.cpp.
    if (!s.environment.none()) continue;
    KaneEngine e(s, EngineOptions{});
    std::mt19937 g(2026);
    Closure c;
    for (int trial = 0; trial < 3; ++trial) {
      const double t = 0.7 + 1.3 * trial;  // prescribed profiles mid-ramp
      closure(e, s, t, random_x(e, s, g), c);
    }
    const std::string name = std::filesystem::path(path).stem().string();
    INFO(name << ": rigid force " << c.rigid_force << ", rigid moment " << c.rigid_moment
              << ", flexible force " << c.flex_force << ", flexible moment " << c.flex_moment);
    CHECK(c.rigid + c.flex == 3 * static_cast<int>(s.bodies.size()));
    CHECK(c.rigid_force < 1e-10);
    CHECK(c.rigid_moment < 1e-10);
    CHECK(c.flex_force < 1e-7);
    CHECK(c.flex_moment < 1e-7);
    worst_rf = std::max(worst_rf, c.rigid_force);
    worst_rm = std::max(worst_rm, c.rigid_moment);
    worst_ff = std::max(worst_ff, c.flex_force);
    worst_fm = std::max(worst_fm, c.flex_moment);
  }
  WARN("worst relative closure: rigid force " << worst_rf << ", rigid moment " << worst_rm
                                              << ", flexible force " << worst_ff
                                              << ", flexible moment " << worst_fm);
}

TEST_CASE("kane loads: a revolute joint's moment about its axis is its spring, damper and motor "
          "(prescribed: its torque column), a prismatic joint's force along its axis likewise") {
  int checked = 0;
  double worst = 0;
  for (const std::string& path : crossdyn::test::committed_scenes()) {
    const System s = read_scene(path);
    KaneEngine e(s, EngineOptions{});
    std::mt19937 g(7);
    for (int trial = 0; trial < 3; ++trial) {
      const double t = 0.4 + 2.1 * trial;
      const std::vector<double> x = random_x(e, s, g);
      const std::vector<double> row = row_at(e, t, x);
      e.set_time(t);
      const std::vector<BodyMotion> bm = e.body_motion(x.data());
      const std::vector<kane::JointFrames> jf = e.joint_frames(x.data());
      for (std::size_t j = 0; j < s.joints.size(); ++j) {
        const Joint& J = s.joints[j];
        if (J.type != JointType::Revolute && J.type != JointType::Prismatic) continue;
        // The axis, fixed in Jp, in the child's body frame.
        const Vector3d axis_C = bm[static_cast<std::size_t>(J.child)].R_NB.transpose() *
                                (jf[j].R_NJp * J.axis_P.normalized());
        const int lc = e.layout().joint_load(static_cast<int>(j));
        const Vector3d load = col3(row, J.type == JointType::Revolute ? lc + 3 : lc);
        const int q = e.layout().joint_first(static_cast<int>(j));
        double expected;
        if (J.prescribed) {
          expected = row[static_cast<std::size_t>(q + 2)];  // <joint>.torque / .force
        } else {
          const double angle = row[static_cast<std::size_t>(q)], rate = row[static_cast<std::size_t>(q + 1)];
          expected = -J.stiffness * (angle - J.neutral_angle) - J.damping * rate +
                     (J.motor_revolute.empty() ? 0.0 : J.motor_revolute.value(t)(0));
        }
        // A joint that carries a force but no moment about its axis (a hanging pendulum's held
        // base): its moment is rounding of the force times the lever, so the force (times 1 m)
        // joins the scale.
        const double scale = std::max({load.norm(), std::abs(expected), col3(row, lc).norm(), 1e-12});
        INFO(s.name << " joint " << J.name << " at t " << t << ": " << load.dot(axis_C)
                    << " expected " << expected);
        CHECK(std::abs(load.dot(axis_C) - expected) < 1e-10 * scale);
        worst = std::max(worst, std::abs(load.dot(axis_C) - expected) / scale);
        ++checked;
      }
    }
  }
  CHECK(checked > 30);
  WARN("revolute/prismatic axis load: worst relative error " << worst << " over " << checked);
}

TEST_CASE("kane loads: P = dE/dt and M = dH/dt along the engine's own motion (scenes with "
          "motors, dampers, modal damping, prescribed joints, body torques)") {
  double worst_P = 0, worst_M = 0;
  for (const char* name : {"chain_motor", "hub_two_panels", "spinup_beam", "scan_platform",
                           "pointing_flex", "hub_flex_array", "gimbal_payload",
                           "telescoping_boom", "dual_spin", "basilisk_hinged_panels",
                           "free_beam_payload", "spear1_case1_spherical", "chain5"}) {
    const System s = scene(name);
    KaneEngine e(s, EngineOptions{});
    const OutputLayout& L = e.layout();
    std::mt19937 g(99);
    for (int trial = 0; trial < 3; ++trial) {
      const double t = 0.9 + 1.7 * trial;
      const std::vector<double> x = random_x(e, s, g);
      std::vector<double> xdot(x.size());
      e.rhs(t, x.data(), xdot.data());
      const std::vector<double> row = row_at(e, t, x);
      // E and H_N at (t + h, x + h xdot): the state along its own motion, time included.
      auto EH = [&](double h) {
        const std::vector<double> r = row_at(e, t + h, along(x, xdot, h));
        Eigen::Vector4d v;
        v << r[static_cast<std::size_t>(L.E())], col3(r, L.H_vector());
        return v;
      };
      const Eigen::Vector4d d = derivative(EH, 1e-4);
      const double P = row[static_cast<std::size_t>(L.P())];
      const Vector3d M = col3(row, L.external_moment());
      // Scales: the power and moment of the loads, and the rates E and H would have at the
      // state's speeds (so that a state where P or M is near zero is judged fairly).
      const double Escale = std::max({std::abs(P), std::abs(d(0)), 1e-3 * std::abs(row[static_cast<std::size_t>(L.E())])});
      const double Hscale = std::max({M.norm(), d.tail<3>().norm(), 1e-3 * row[static_cast<std::size_t>(L.H())]});
      const double eP = std::abs(d(0) - P) / Escale, eM = (d.tail<3>() - M).norm() / Hscale;
      INFO(name << " t " << t << ": P " << P << " dE/dt " << d(0) << "; M " << M.transpose()
                << " dH/dt " << d.tail<3>().transpose());
      CHECK(eP < 1e-6);
      CHECK(eM < 1e-6);
      worst_P = std::max(worst_P, eP);
      worst_M = std::max(worst_M, eM);
    }
  }
  WARN("P against dE/dt: worst relative error " << worst_P << "; M against dH/dt " << worst_M);
}

TEST_CASE("kane loads: test_damper_scale = 0 changes the accelerations, not P, and 1 changes "
          "nothing") {
  for (const char* name : {"hub_two_panels", "gimbal_payload", "telescoping_boom", "free_beam_payload", "hub_flex_array"}) {
    const System s = scene(name);
    bool damped = false;
    for (const Joint& j : s.joints) damped = damped || j.damping != 0 || j.damping2 != 0;
    for (const Body& b : s.bodies)
      damped = damped || (b.flex && b.flex->D.size() && b.flex->D.cwiseAbs().maxCoeff() > 0);
    REQUIRE(damped);
    EngineOptions off, one;
    off.test_damper_scale = 0;
    one.test_damper_scale = 1;
    KaneEngine e(s, EngineOptions{}), e0(s, off), e1(s, one);
    std::mt19937 g(5);
    const std::vector<double> x = random_x(e, s, g);
    std::vector<double> xd(x.size()), xd0(x.size()), xd1(x.size());
    e.rhs(1.0, x.data(), xd.data());
    e0.rhs(1.0, x.data(), xd0.data());
    e1.rhs(1.0, x.data(), xd1.data());
    INFO(name);
    CHECK(xd1 == xd);  // bit for bit
    double change = 0;
    for (std::size_t i = 0; i < x.size(); ++i) change = std::max(change, std::abs(xd0[i] - xd[i]));
    CHECK(change > 1e-6);
    const std::vector<double> r = row_at(e, 1.0, x), r0 = row_at(e0, 1.0, x);
    const std::size_t P = static_cast<std::size_t>(e.layout().P());
    CHECK(r[P] != 0);
    // A prescribed joint's drive (telescoping_boom's) does work that depends on the
    // accelerations, so without it: P less each drive's torque (its column) times its rate.
    double drive = 0, drive0 = 0;
    for (std::size_t j = 0; j < s.joints.size(); ++j)
      if (s.joints[j].prescribed) {
        const std::size_t q = static_cast<std::size_t>(e.layout().joint_first(static_cast<int>(j)));
        drive += r[q + 2] * r[q + 1];  // <joint>.torque (.force) times <joint>.rate
        drive0 += r0[q + 2] * r0[q + 1];
      }
    if (drive == 0)
      CHECK(r0[P] == r[P]);  // bit for bit
    else
      CHECK(std::abs((r0[P] - drive0) - (r[P] - drive)) < 1e-12 * (std::abs(r[P]) + std::abs(drive)));
  }
}

// A rod of mass m, length L on a revolute joint (axis z) with a motor torque tau at the end of a
// free base (mass M, central inertia Jb about z, the joint at (d, 0, 0) from its CM), everything at
// rest at t = 0, the rod along the base's x axis. Planar: with f = F_y the joint's force on the
// rod (rod frame = base frame at angle 0; F_x = 0 since nothing moves along x):
//   rod   m a_R = f,          (m L^2 / 12) alpha_R = tau - (L / 2) f   (moment about its CM)
//   base  M a_B = -f,         Jb alpha_B = -tau - d f
//   kinematics at rest  a_R = a_B + d alpha_B + (L / 2) alpha_R
// => f (4 / m + 1 / M + d^2 / Jb) = tau (6 / (m L) - d / Jb), and M_J_C = (0, 0, tau). With the
// base held still (M, Jb -> infinity) f = 3 tau / (2 L): docs/conventions.md's worked example.
TEST_CASE("kane loads: a motor-driven rod at rest on a free base against the hand solution") {
  const double m = 3.0, L = 2.0, M = 50.0, Jb = 7.0, d = 0.8, tau = 1.7;
  System s;
  s.name = "rod_on_base";
  s.bodies.push_back(rigid_body("base", M, diag(5.0, 6.0, Jb)));
  s.bodies.push_back(rigid_body("rod", m, diag(0.01, m * L * L / 12, m * L * L / 12)));
  s.joints.push_back(free_joint("free", 0, Vector3d::Zero()));
  Joint j = joint("hinge", JointType::Revolute, 0, 1, Vector3d(d, 0, 0), Vector3d(-L / 2, 0, 0));
  j.axis_P = Vector3d::UnitZ();
  j.motor_revolute.times = {0.0};
  j.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(tau)};
  s.joints.push_back(j);
  for (bool held : {false, true}) {
    System sh = s;
    if (held) {  // a base a million times heavier: the worked example's limit
      sh.bodies[0].mass *= 1e6;
      sh.bodies[0].I_BBo_B *= 1e6;
    }
    KaneEngine e(sh, EngineOptions{});
    const std::vector<double> x = packed(e, TreeState::initial(sh));
    const std::vector<double> row = row_at(e, 0.0, x);
    const int c = e.layout().joint_load(1);
    const double Mb = sh.bodies[0].mass, Jz = sh.bodies[0].I_BBo_B(2, 2);
    const double f = tau * (6 / (m * L) - d / Jz) / (4 / m + 1 / Mb + d * d / Jz);
    INFO((held ? "held base" : "free base") << ": F " << col3(row, c).transpose() << " M "
                                              << col3(row, c + 3).transpose() << " f " << f);
    CHECK((col3(row, c) - Vector3d(0, f, 0)).norm() < 1e-12 * std::abs(f));
    CHECK((col3(row, c + 3) - Vector3d(0, 0, tau)).norm() < 1e-12 * tau);
    if (held) CHECK(std::abs(f - 3 * tau / (2 * L)) < 1e-5 * f);
    // At rest, no power; no external moment (a free system).
    CHECK(row[static_cast<std::size_t>(e.layout().P())] == 0);
    CHECK(col3(row, e.layout().external_moment()).norm() == 0);
  }
}

TEST_CASE("kane loads: positions, CM and H vector columns agree with the engine's own bodies") {
  for (const char* name : {"spinup_beam", "free_beam_payload", "telescoping_boom", "chain5"}) {
    const System s = scene(name);
    KaneEngine e(s, EngineOptions{});
    std::mt19937 g(3);
    const std::vector<double> x = random_x(e, s, g);
    const std::vector<double> row = row_at(e, 1.5, x);
    const std::vector<BodyMotion> bm = e.body_motion(x.data());
    const std::vector<kane::MassPoint> pts = e.mass_points(x.data());
    INFO(name);
    for (std::size_t b = 0; b < s.bodies.size(); ++b)
      CHECK((col3(row, e.layout().body_position(static_cast<int>(b))) - bm[b].p_NoBo_N).norm() <
            1e-12 * (1 + bm[b].p_NoBo_N.norm()));
    // The CM and H about it from the mass points (each node where it is).
    double mass = 0;
    Vector3d first = Vector3d::Zero(), P = Vector3d::Zero();
    for (const kane::MassPoint& p : pts) {
      mass += p.mass;
      first += p.mass * p.p_NoP_N;
      P += p.mass * p.v_NP_N;
    }
    const Vector3d cm = first / mass;
    Vector3d H = Vector3d::Zero();
    for (const kane::MassPoint& p : pts) {
      const BodyMotion& m = bm[static_cast<std::size_t>(p.body)];
      H += (p.p_NoP_N - cm).cross(p.mass * p.v_NP_N) + p.J_N * (m.R_NB * m.w_NB_B);
    }
    CHECK((col3(row, e.layout().cm()) - cm).norm() < 1e-12 * (1 + cm.norm()));
    CHECK((col3(row, e.layout().H_vector()) - H).norm() < 1e-10 * (1 + H.norm()));
    CHECK(row[static_cast<std::size_t>(e.layout().H())] == col3(row, e.layout().H_vector()).norm());
  }
}
