// Prismatic and universal (two-axis gimbal) joints in the Newton-Euler engine (core/system.hpp,
// "prismatic", "universal"; formulations/newton_euler/joints/prismatic.cpp, universal.cpp).
// Physics checks: a two-body spring slider against its closed form (reduced mass), conservation
// of H and E with offsets, oblique axes and a spinning base, the work of a prescribed deployment's
// joint force, momentum balance under internal motor loads, the gimbal's small-angle frequencies
// about each axis through the joint point, and accelerations() against finite differences of the
// output rates along rhs().
#include "formulations/newton_euler/newton_euler.hpp"

#include "core/errors.hpp"
#include "tests/newton_euler/ne_run.hpp"
#include "tests/newton_euler/ne_systems.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

using namespace crossdyn;
using namespace crossdyn::test::ne;
using Eigen::Matrix3d, Eigen::Quaterniond, Eigen::Vector3d;

// The joints below are written as designated initialisers (Joint is an aggregate); the members
// they leave out (motors, prescribed) keep their empty defaults.
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"

namespace {

Matrix3d diag(double a, double b, double c) { return Vector3d(a, b, c).asDiagonal(); }

RunResult run(const System& s, double duration, double output_step) {
  return run_ne(s, TreeState::initial(s), "dop853", 1e-12, duration, output_step);
}

// At rest, the base not turning, no springs on joint 1: only the motors act.
System motors_only(System s) {
  s.joints[0].w_NB_B0.setZero();
  Joint& j = s.joints[1];
  j.stiffness = j.stiffness2 = 0;
  j.rate0 = j.rate2_0 = 0;
  return s;
}

// Every joint closed at every row: the columns constraint.pos, .vel, .ang and .angvel below tol.
void check_closed(const RunResult& r, double tol) {
  for (const char* c : {"constraint.pos", "constraint.vel", "constraint.ang", "constraint.angvel"}) {
    INFO(c);
    CHECK(max_of(series(r, c)) < tol);
  }
}

// A free base (hub) and a slider on a prismatic joint, with offsets, an oblique axis, an offset
// attitude and full inertia tensors; the hub spins about all three axes.
System hub_slider() {
  System s;
  s.name = "hub_slider";
  Matrix3d I_hub, I_sl;
  I_hub << 40, 2, -1, 2, 55, 3, -1, 3, 70;
  I_sl << 0.6, 0.05, 0, 0.05, 0.8, -0.1, 0, -0.1, 0.5;
  s.bodies = {make_body("hub", 120, I_hub), make_body("slider", 6, I_sl)};
  Joint base = free_joint(0);
  base.w_NB_B0 = Vector3d(0.2, -0.15, 0.9);
  base.q_NB0 = Quaterniond(Eigen::AngleAxisd(0.3, Vector3d(1, -1, 2).normalized()));
  s.joints.push_back(base);
  s.joints.push_back(Joint{.name = "slide",
                           .type = JointType::Prismatic,
                           .parent = 0,
                           .child = 1,
                           .p_PoJ_P = Vector3d(0.8, 0.3, -0.2),
                           .p_CoJ_C = Vector3d(-0.2, 0.1, 0.15),
                           .axis_P = Vector3d(1, 0.3, -0.1).normalized(),
                           .q_PJ0 = Quaterniond(Eigen::AngleAxisd(0.5, Vector3d(0, 1, 1).normalized())),
                           .stiffness = 40,
                           .neutral_angle = 0.6,
                           .angle0 = 0.3,
                           .rate0 = 0.4});
  return s;
}

// A base and a payload on a universal joint: the payload's CM 0.5 m above the joint point along
// the payload's z; axis 1 = x, axis 2 = y of the base (both through the joint point).
System gimbal(double base_scale) {
  System s;
  s.name = "gimbal";
  s.bodies = {make_body("base", 50 * base_scale, base_scale * diag(10, 12, 15)),
              make_body("payload", 2, diag(0.1, 0.2, 0.3))};
  s.joints.push_back(free_joint(0));
  s.joints.push_back(Joint{.name = "gimbal",
                           .type = JointType::Universal,
                           .parent = 0,
                           .child = 1,
                           .p_PoJ_P = Vector3d(0, 0, 1),
                           .p_CoJ_C = Vector3d(0, 0, -0.5),
                           .axis_P = Vector3d::UnitX(),
                           .axis2_P = Vector3d::UnitY()});
  return s;
}

// The gimbal at large angles, oblique non-perpendicular axes, offsets and a spinning base.
System spinning_gimbal() {
  System s = gimbal(1.0);
  Matrix3d I_pl;
  I_pl << 0.3, 0.02, 0.01, 0.02, 0.4, -0.03, 0.01, -0.03, 0.5;
  s.bodies[1] = make_body("payload", 3, I_pl);
  s.joints[0].w_NB_B0 = Vector3d(0.3, -0.2, 1.0);
  s.joints[1] = Joint{.name = "gimbal",
                      .type = JointType::Universal,
                      .parent = 0,
                      .child = 1,
                      .p_PoJ_P = Vector3d(0.5, 0.3, 1.0),
                      .p_CoJ_C = Vector3d(0.1, -0.2, -0.6),
                      .axis_P = Vector3d(1, 0.2, 0).normalized(),
                      .axis2_P = Vector3d(0.1, 1, 0.3).normalized(),
                      .q_PJ0 = Quaterniond(Eigen::AngleAxisd(0.4, Vector3d(1, 2, -1).normalized())),
                      .stiffness = 2,
                      .neutral_angle = 0.1,
                      .stiffness2 = 3,
                      .neutral_angle2 = -0.2,
                      .angle0 = 0.8,
                      .rate0 = 0.5,
                      .angle2_0 = -0.6,
                      .rate2_0 = -0.7};
  return s;
}

// accelerations() against central differences of the output rates along the flow of rhs() (step
// 1e-6 s: truncation ~1e-12, round-off ~1e-10), at the packed initial state at time t: each pair
// is an output column and the TreeAccel value it must be the derivative of.
using AccelOf = double (*)(const TreeAccel&);
void check_accelerations(const System& s, double t,
                         const std::vector<std::pair<std::string, AccelOf>>& checks) {
  auto e = make_newton_euler_engine(s, {});
  const auto n = static_cast<std::size_t>(e->state_size());
  std::vector<double> x(n), xdot(n), xp(n), xm(n), rp(e->columns().size()), rm(rp.size());
  e->pack(TreeState::initial(s), x.data());
  e->rhs(t, x.data(), xdot.data());
  TreeAccel a;
  e->accelerations(t, x.data(), a);
  const double h = 1e-6;
  for (std::size_t i = 0; i < n; ++i) {
    xp[i] = x[i] + h * xdot[i];
    xm[i] = x[i] - h * xdot[i];
  }
  e->output_row(t + h, xp.data(), rp.data());
  e->output_row(t - h, xm.data(), rm.data());
  for (const auto& [c, accel] : checks) {
    const auto i = static_cast<std::size_t>(column(*e, c));
    const double fd = (rp[i] - rm[i]) / (2 * h), value = accel(a);
    INFO(s.name << ": d/dt " << c << " " << fd << ", accelerations() " << value);
    CHECK(std::abs(value) > 1e-3);  // not trivially zero
    CHECK(std::abs(fd - value) <= 1e-7 * (1 + std::abs(value)));
  }
}

}  // namespace

// Two bodies joined by a prismatic spring along the line of their CMs, no rotation: the relative
// coordinate oscillates as a mass mu = m1 m2 / (m1 + m2) on the spring k, about the neutral length.
TEST_CASE("newton-euler prismatic: a spring slider on a free base oscillates at sqrt(k/mu)",
          "[newton_euler][new_joints]") {
  System s;
  s.name = "slider_pair";
  const double m1 = 10, m2 = 2, k = 50, s_n = 0.1, s0 = 0.35;
  s.bodies = {make_body("box", m1, diag(1, 2, 3)), make_body("slider", m2, diag(0.1, 0.2, 0.3))};
  s.joints.push_back(free_joint(0));
  s.joints.push_back(Joint{.name = "slide",
                           .type = JointType::Prismatic,
                           .parent = 0,
                           .child = 1,
                           .axis_P = Vector3d::UnitX(),
                           .stiffness = k,
                           .neutral_angle = s_n,
                           .angle0 = s0});
  const RunResult r = run(s, 5.0, 0.01);
  const double omega = std::sqrt(k / (m1 * m2 / (m1 + m2)));
  const auto t = series(r, "t"), pos = series(r, "slide.position"), rate = series(r, "slide.rate");
  double err = 0, err_rate = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    err = std::max(err, std::abs(pos[i] - (s_n + (s0 - s_n) * std::cos(omega * t[i]))));
    err_rate = std::max(err_rate, std::abs(rate[i] + omega * (s0 - s_n) * std::sin(omega * t[i])));
  }
  INFO("max position error " << err << " m, rate error " << err_rate << " m/s");
  CHECK(err < 1e-9);
  CHECK(err_rate < 1e-8);
  CHECK(max_of(series(r, "box.wx")) == 0.0);  // a force through both CMs turns nothing
  CHECK(max_abs_change(series(r, "E")) < 1e-9 * r.at(0, static_cast<std::size_t>(r.column("E"))));
}

// A spinning hub and a sliding mass with a spring, everything offset and oblique: the motion is
// genuinely three-dimensional; H (internal loads only) and E (kinetic + spring) are conserved.
TEST_CASE("newton-euler prismatic: H and E are conserved with a spinning hub and an oblique slider",
          "[newton_euler][new_joints]") {
  const System s = hub_slider();
  const RunResult r = run(s, 20.0, 0.05);
  const auto H = series(r, "H"), E = series(r, "E"), pos = series(r, "slide.position");
  INFO("H change " << max_abs_change(H) / H.front() << ", E change " << max_abs_change(E) / E.front());
  CHECK(max_abs_change(H) <= 1e-9 * H.front());
  CHECK(max_abs_change(E) <= 1e-9 * E.front());
  CHECK(max_of(pos) - min_of(pos) > 0.2);  // the slider did move
  check_closed(r, 1e-10);
  // The slider's attitude is the hub's turned by the offset, at every row.
  const auto hq = series(r, "hub.qw"), sq = series(r, "slider.qw");
  const auto hx = series(r, "hub.qx"), hy = series(r, "hub.qy"), hz = series(r, "hub.qz");
  const auto sx = series(r, "slider.qx"), sy = series(r, "slider.qy"), sz = series(r, "slider.qz");
  for (std::size_t i = 0; i < hq.size(); i += 40) {
    const Quaterniond expected = Quaterniond(hq[i], hx[i], hy[i], hz[i]) * s.joints[1].q_PJ0;
    CHECK(std::abs(std::abs(expected.dot(Quaterniond(sq[i], sx[i], sy[i], sz[i]))) - 1) < 1e-12);
  }
}

// A deployment driven at the joint (cycloidal rest-to-rest travel along a radial axis) on a
// spinning hub: the joint force is internal, so H holds; E changes by its work, integral F s' dt.
TEST_CASE("newton-euler prescribed prismatic: E(t) - E(0) is the work of the joint force, H holds",
          "[newton_euler][new_joints]") {
  System s = hub_slider();
  s.joints[0].w_NB_B0 = Vector3d(0.05, 0.02, 1.0);
  Joint& p = s.joints[1];
  p.stiffness = 0;
  p.rate0 = 0;
  p.prescribed = PrescribedMotion{PrescribedMotion::Profile::Deploy, 0.0, 4.0, 1.5};
  const RunResult r = run(s, 6.0, 0.002);
  const auto t = series(r, "t"), E = series(r, "E"), H = series(r, "H");
  const auto F = series(r, "slide.force"), v = series(r, "slide.rate");
  const auto pos = series(r, "slide.position");
  // Simpson's rule on pairs of output intervals.
  double work = 0, err = 0;
  for (std::size_t k = 2; k < t.size(); k += 2) {
    const double h = 0.5 * (t[k] - t[k - 2]);
    work += h / 3.0 * (F[k - 2] * v[k - 2] + 4.0 * F[k - 1] * v[k - 1] + F[k] * v[k]);
    err = std::max(err, std::abs(E[k] - E[0] - work));
  }
  const double dE = E.back() - E.front();
  INFO("dE " << dE << " J, work " << work << " J, max |dE - W| " << err);
  CHECK(std::abs(dE) > 1.0);  // moving mass outwards on a spinning hub takes work
  CHECK(err < 1e-7 * std::abs(dE));
  CHECK(std::abs(dE + work) > 1.0);  // a wrong sign of the force would give dE = -W
  CHECK(max_abs_change(H) <= 1e-10 * H.front());
  for (double f : F) CHECK(std::isfinite(f));
  const PrescribedMotion& pm = *p.prescribed;
  for (std::size_t k = 0; k < t.size(); k += 200) {
    CHECK(pos[k] == Approx(p.angle0 + pm.angle(t[k])).margin(1e-15));
    CHECK(v[k] == Approx(pm.velocity(t[k])).margin(1e-15));
  }
  check_closed(r, 1e-10);
}

// A constant motor force from rest, no spring: the pair's total linear momentum stays zero and so
// does H (an internal force, applied at one point to both bodies); all the work F (s - s0) becomes
// kinetic energy.
TEST_CASE("newton-euler prismatic: a motor force keeps the momenta at zero and does work F ds",
          "[newton_euler][new_joints]") {
  System s = motors_only(hub_slider());
  Joint& p = s.joints[1];
  const double F = 5.0;
  p.motor_revolute.times = {0.0};
  p.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(F)};
  auto e = make_newton_euler_engine(s, {});
  IntegratorSettings st;
  st.method = "dop853";
  st.rtol = st.atol = 1e-12;
  st.duration = 3.0;
  st.output_step = 0.05;
  const RunResult r = simulate(*e, s, TreeState::initial(s), st);
  if (r.failure) FAIL(r.failure->what());
  const auto E = series(r, "E"), pos = series(r, "slide.position"), H = series(r, "H");
  CHECK(pos.back() - pos.front() > 0.1);
  for (std::size_t k = 0; k < E.size(); ++k)
    CHECK(std::abs(E[k] - F * (pos[k] - pos.front())) <= 1e-9 * F * (pos.back() - pos.front()));
  // H = 0 to the integration error, on the scale of the bodies' own angular momenta: the
  // slider's m |v| r_lever, |v| = sqrt(2 E_max / m) at most, r ~ 1 m.
  const double h_scale = s.bodies[1].mass * std::sqrt(2 * max_of(E) / s.bodies[1].mass);
  INFO("max H " << max_of(H) << " kg m^2/s, scale " << h_scale);
  CHECK(max_of(H) < 1e-10 * h_scale);
  // Linear momentum at a state of the run (pack and the engine's own state after rhs steps).
  std::vector<double> x(static_cast<std::size_t>(e->state_size())), xdot(x.size());
  e->pack(TreeState::initial(s), x.data());
  for (int step = 0; step < 200; ++step) {  // explicit Euler: momentum is linear in the steps
    e->rhs(0.01 * step, x.data(), xdot.data());
    for (std::size_t i = 0; i < x.size(); ++i) x[i] += 0.01 * xdot[i];
  }
  Vector3d momentum = Vector3d::Zero();
  for (const Body& b : s.bodies) momentum += b.mass * body_state(*e, x.data(), b.name).v_N;
  const double speed = body_state(*e, x.data(), "slider").v_N.norm();
  INFO("momentum " << momentum.transpose() << ", slider speed " << speed);
  CHECK(speed > 0.1);
  CHECK(momentum.norm() < 1e-12 * s.bodies[1].mass * speed);
}

TEST_CASE("newton-euler prismatic: accelerations are the time derivatives of the rates",
          "[newton_euler][new_joints]") {
  System s = hub_slider();
  s.joints[1].motor_revolute.times = {0.0};
  s.joints[1].motor_revolute.values = {Eigen::Matrix<double, 1, 1>(3.0)};
  s.joints[1].damping = 2.0;
  check_accelerations(s, 0.0, {{"slide.rate", [](const TreeAccel& a) { return a.angle_ddot[1]; }},
                               {"hub.wz", [](const TreeAccel& a) { return a.wdot_NB_B[0].z(); }}});
}

// Small angles on a base a million times heavier than the payload: each axis is a torsion
// pendulum of the payload's inertia about that axis through the joint point, I_k = I_kk + m d^2
// (d = 0.5 m from the joint point to the payload's CM, normal to both axes), omega_k = sqrt(k_k / I_k).
TEST_CASE("newton-euler universal: small-angle frequencies about each axis are sqrt(k / I)",
          "[newton_euler][new_joints]") {
  const double k1 = 3, k2 = 5, A = 1e-4, m = 2, d = 0.5;
  const double I1 = 0.1 + m * d * d, I2 = 0.2 + m * d * d;
  for (int axis = 0; axis < 2; ++axis) {
    System s = gimbal(1e6);
    Joint& u = s.joints[1];
    u.stiffness = k1;
    u.stiffness2 = k2;
    (axis == 0 ? u.angle0 : u.angle2_0) = A;
    const double omega = axis == 0 ? std::sqrt(k1 / I1) : std::sqrt(k2 / I2);
    const RunResult r = run(s, 3 * 2 * std::numbers::pi / omega, 0.01);
    const auto t = series(r, "t");
    const auto a = series(r, axis == 0 ? "gimbal.angle1" : "gimbal.angle2");
    const auto other = series(r, axis == 0 ? "gimbal.angle2" : "gimbal.angle1");
    double err = 0, cross = 0;
    for (std::size_t i = 0; i < t.size(); ++i) {
      err = std::max(err, std::abs(a[i] - A * std::cos(omega * t[i])));
      cross = std::max(cross, std::abs(other[i]));
    }
    INFO("axis " << axis + 1 << ": max |a - A cos(omega t)| " << err / A << " A, other axis "
                 << cross / A << " A");
    // A 0.01 % error in omega is a phase error of 2e-3 rad after three periods.
    CHECK(err < 1e-4 * A);
    CHECK(cross < 1e-3 * A);
  }
}

// Large angles, oblique non-perpendicular axes, springs on both, a spinning base: H and E hold.
TEST_CASE("newton-euler universal: H and E are conserved at large angles on a spinning base",
          "[newton_euler][new_joints]") {
  const System s = spinning_gimbal();
  const RunResult r = run(s, 20.0, 0.05);
  const auto H = series(r, "H"), E = series(r, "E");
  const auto a1 = series(r, "gimbal.angle1"), a2 = series(r, "gimbal.angle2");
  INFO("H change " << max_abs_change(H) / H.front() << ", E change " << max_abs_change(E) / E.front());
  CHECK(max_abs_change(H) <= 1e-9 * H.front());
  CHECK(max_abs_change(E) <= 1e-9 * E.front());
  CHECK(max_of(a1) - min_of(a1) > 0.5);  // large motions on both axes
  CHECK(max_of(a2) - min_of(a2) > 0.5);
  check_closed(r, 1e-10);
}

// Constant motor torques on both axes from rest, no springs: H stays zero (internal torques) and
// E is their work, tau_1 (a1 - a1(0)) + tau_2 (a2 - a2(0)).
TEST_CASE("newton-euler universal: motor torques keep H at zero and do work tau_k da_k",
          "[newton_euler][new_joints]") {
  System s = motors_only(spinning_gimbal());
  Joint& u = s.joints[1];
  const double tau1 = 0.4, tau2 = -0.3;
  u.motor_universal.times = {0.0};
  u.motor_universal.values = {Eigen::Vector2d(tau1, tau2)};
  const RunResult r = run(s, 3.0, 0.05);
  const auto E = series(r, "E"), H = series(r, "H");
  const auto a1 = series(r, "gimbal.angle1"), a2 = series(r, "gimbal.angle2");
  CHECK(a1.back() - a1.front() > 0.1);  // each angle moves the way its torque turns it
  CHECK(a2.back() - a2.front() < -0.1);
  const double W_end = tau1 * (a1.back() - a1.front()) + tau2 * (a2.back() - a2.front());
  for (std::size_t k = 0; k < E.size(); ++k)
    CHECK(std::abs(E[k] - tau1 * (a1[k] - a1.front()) - tau2 * (a2[k] - a2.front())) <=
          1e-9 * W_end);
  const double h_scale = std::sqrt(2 * max_of(E) * 1.0);  // ~ the payload's I w, I ~ 1 kg m^2
  INFO("max H " << max_of(H) << " kg m^2/s, scale " << h_scale);
  CHECK(max_of(H) < 1e-10 * h_scale);
}

TEST_CASE("newton-euler universal: accelerations are the time derivatives of the rates",
          "[newton_euler][new_joints]") {
  System s = spinning_gimbal();
  s.joints[1].damping = 0.3;
  s.joints[1].motor_universal.times = {0.0};
  s.joints[1].motor_universal.values = {Eigen::Vector2d(0.2, 0.5)};
  check_accelerations(s, 0.0,
                      {{"gimbal.rate1", [](const TreeAccel& a) { return a.angle_ddot[1]; }},
                       {"gimbal.rate2", [](const TreeAccel& a) { return a.angle2_ddot[1]; }},
                       {"base.wx", [](const TreeAccel& a) { return a.wdot_NB_B[0].x(); }}});
}

// The angles come back from the packed attitude: output angles and rates equal the TreeState's.
TEST_CASE("newton-euler universal: pack and output agree on the angles and rates",
          "[newton_euler][new_joints]") {
  System s = spinning_gimbal();
  for (const auto& [a1, a2] : {std::pair{0.8, -0.6}, std::pair{3.0, 1.2}, std::pair{-2.5, -3.0}}) {
    s.joints[1].angle0 = a1;
    s.joints[1].angle2_0 = a2;
    auto e = make_newton_euler_engine(s, {});
    std::vector<double> x(static_cast<std::size_t>(e->state_size())), row(e->columns().size());
    e->pack(TreeState::initial(s), x.data());
    e->output_row(0.0, x.data(), row.data());
    auto at = [&](const char* c) { return row[static_cast<std::size_t>(column(*e, c))]; };
    INFO("a1 " << a1 << ", a2 " << a2);
    CHECK(at("gimbal.angle1") == Approx(a1).margin(1e-13));
    CHECK(at("gimbal.angle2") == Approx(a2).margin(1e-13));
    CHECK(at("gimbal.rate1") == Approx(s.joints[1].rate0).margin(1e-13));
    CHECK(at("gimbal.rate2") == Approx(s.joints[1].rate2_0).margin(1e-13));
    CHECK(at("constraint.ang") < 1e-14);
    CHECK(at("constraint.angvel") < 1e-14);
    CHECK(at("constraint.pos") < 1e-14);
  }
}

TEST_CASE("newton-euler prismatic and universal: joints at flexible-body nodes are refused",
          "[newton_euler][new_joints]") {
  System s = flexible_tree();
  for (JointType type : {JointType::Prismatic, JointType::Universal}) {
    System t = s;
    for (Joint& j : t.joints)
      if (j.parent_node >= 0 || j.child_node >= 0) {
        j.type = type;
        break;
      }
    CHECK_THROWS_AS(make_newton_euler_engine(t, {}), InputError);
  }
  System parallel = gimbal(1.0);
  parallel.joints[1].axis2_P = -parallel.joints[1].axis_P;
  CHECK_THROWS_AS(make_newton_euler_engine(parallel, {}), InputError);
  CHECK_NOTHROW(make_newton_euler_engine(gimbal(1.0), {}));
}
