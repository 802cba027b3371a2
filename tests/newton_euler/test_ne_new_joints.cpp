// Prismatic and universal (two-axis gimbal) joints in the Newton-Euler engine (core/system.hpp,
// "prismatic", "universal"; formulations/newton_euler/joints/prismatic.cpp, universal.cpp).
// Physics checks: a two-body spring slider against its closed form (reduced mass), conservation
// of H and E with offsets, oblique axes and a spinning base, the work of a prescribed deployment's
// joint force, momentum balance under internal motor loads, the gimbal's small-angle frequencies
// about each axis through the joint point, and accelerations() against finite differences of the
// output rates along rhs().
#include "formulations/newton_euler/newton_euler.hpp"

#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "tests/newton_euler/ne_systems.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

using namespace crossdyn;
using namespace crossdyn::test::ne;
using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

namespace {

Matrix3d diag(double a, double b, double c) { return Vector3d(a, b, c).asDiagonal(); }

RunResult run(const System& s, double duration, double output_step, double tol = 1e-12) {
  auto e = make_newton_euler_engine(s, {});
  IntegratorSettings st;
  st.method = "dop853";
  st.rtol = st.atol = tol;
  st.duration = duration;
  st.output_step = output_step;
  st.dt = 1e-3;
  RunResult r = simulate(*e, s, TreeState::initial(s), st);
  if (r.failure) FAIL(r.failure->what());
  REQUIRE(r.rows() > 1);
  return r;
}

std::vector<double> series(const RunResult& r, const std::string& c) {
  const int i = r.column(c);
  REQUIRE(i >= 0);
  std::vector<double> v;
  for (std::size_t k = 0; k < r.rows(); ++k) v.push_back(r.at(k, static_cast<std::size_t>(i)));
  return v;
}

double max_abs_change(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::abs(x - v.front()));
  return m;
}

double max_of(const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); }
double min_of(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }

Joint joint(const std::string& name, JointType type, int parent, int child) {
  Joint j;
  j.name = name;
  j.type = type;
  j.parent = parent;
  j.child = child;
  return j;
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
  Joint p = joint("slide", JointType::Prismatic, 0, 1);
  p.p_PoJ_P = Vector3d(0.8, 0.3, -0.2);
  p.p_CoJ_C = Vector3d(-0.2, 0.1, 0.15);
  p.axis_P = Vector3d(1, 0.3, -0.1).normalized();
  p.q_PJ0 = Quaterniond(Eigen::AngleAxisd(0.5, Vector3d(0, 1, 1).normalized()));
  p.stiffness = 40;
  p.neutral_angle = 0.6;
  p.angle0 = 0.3;
  p.rate0 = 0.4;
  s.joints.push_back(p);
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
  Joint p = joint("slide", JointType::Prismatic, 0, 1);
  p.axis_P = Vector3d::UnitX();
  p.stiffness = k;
  p.neutral_angle = s_n;
  p.angle0 = s0;
  s.joints.push_back(p);
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
  CHECK(max_of(series(r, "constraint.pos")) < 1e-10);
  CHECK(max_of(series(r, "constraint.vel")) < 1e-10);
  CHECK(max_of(series(r, "constraint.ang")) < 1e-10);
  CHECK(max_of(series(r, "constraint.angvel")) < 1e-10);
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
  CHECK(max_of(series(r, "constraint.pos")) < 1e-10);
  CHECK(max_of(series(r, "constraint.vel")) < 1e-10);
}

// A constant motor force from rest, no spring: the pair's total linear momentum stays zero and so
// does H (an internal force, applied at one point to both bodies); all the work F (s - s0) becomes
// kinetic energy.
TEST_CASE("newton-euler prismatic: a motor force keeps the momenta at zero and does work F ds",
          "[newton_euler][new_joints]") {
  System s = hub_slider();
  s.joints[0].w_NB_B0.setZero();
  Joint& p = s.joints[1];
  p.stiffness = 0;
  p.rate0 = 0;
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
}
