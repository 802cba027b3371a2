// Prismatic and universal joints in the Lagrange engine (core/system.hpp; README.md "Joint types",
// "Kinematics"): a sliding spring against the two-body closed form, a prescribed slider's force
// against the reduced mass, energy balances of prescribed motion, motors and dampers, the gimbal's
// small-angle frequencies against the payload's inertia about each axis through the joint point,
// conservation of H and E in 3-D motions, linear momentum under internal loads, and accelerations()
// against rhs() and finite differences. Systems are built in code.
#include <catch2/catch.hpp>
#include <cmath>
#include <string>
#include <vector>

#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "tests/lagrange/run_checks.hpp"
#include "tests/lagrange/scenes.hpp"

using namespace crossdyn;
using namespace crossdyn::test;  // scenes.hpp, run_checks.hpp
using crossdyn::lagrange::LagrangeEngine;

namespace {

Joint prismatic(const std::string& name, int parent, int child, const Eigen::Vector3d& p_PoJ_P,
                const Eigen::Vector3d& p_CoJ_C, const Eigen::Vector3d& axis_P) {
  Joint j;
  j.name = name;
  j.type = JointType::Prismatic;
  j.parent = parent;
  j.child = child;
  j.p_PoJ_P = p_PoJ_P;
  j.p_CoJ_C = p_CoJ_C;
  j.axis_P = axis_P.normalized();
  return j;
}

Joint universal(const std::string& name, int parent, int child, const Eigen::Vector3d& p_PoJ_P,
                const Eigen::Vector3d& p_CoJ_C, const Eigen::Vector3d& axis_P,
                const Eigen::Vector3d& axis2_P) {
  Joint j = prismatic(name, parent, child, p_PoJ_P, p_CoJ_C, axis_P);
  j.type = JointType::Universal;
  j.axis2_P = axis2_P.normalized();
  return j;
}

System two_bodies(const std::string& name, const Body& base, const Body& other,
                  const Eigen::Vector3d& w0, const Joint& joint, double duration,
                  double output_step) {
  System s;
  s.name = name;
  s.bodies = {base, other};
  s.joints = {free_joint(0, w0), joint};
  s.run.duration = duration;
  s.run.output_step = output_step;
  return s;
}

RunResult run(const System& s, double tol = 1e-12) {
  LagrangeEngine e(s, {});
  IntegratorSettings settings = IntegratorSettings::from(s.run);
  settings.method = "dop853";
  settings.rtol = settings.atol = tol;
  return simulate(e, s, TreeState::initial(s), settings);
}

// max over rows of |c(row) - c(0)| / |c(0)|, and of |c(row) - c(0)| when scale is given.
double drift(const RunResult& r, const std::string& column, double scale = 0) {
  const double c0 = col(r, 0, column);
  double d = 0;
  for (std::size_t k = 0; k < r.rows(); ++k) d = std::max(d, std::abs(col(r, k, column) - c0));
  return d / (scale > 0 ? scale : std::abs(c0));
}

// max over rows of |c(row) - c(0)|: how much a coordinate moved.
double excursion(const RunResult& r, const std::string& column) {
  return drift(r, column, 1.0);
}

// sum_b m_b a_NBo_N(b): zero when every load is internal (Newton's second law for the system).
Eigen::Vector3d total_force(const System& s, const TreeAccel& a) {
  Eigen::Vector3d f = Eigen::Vector3d::Zero();
  for (std::size_t b = 0; b < s.bodies.size(); ++b) f += s.bodies[b].mass * a.a_NBo_N[b];
  return f;
}

// Dampers: over 4 s, E(t) - E(0) is the integral of their power (power(r, row) < 0), and H is
// conserved (internal loads).
template <class Power>
void check_dissipation(System s, const Power& power) {
  s.run.duration = 4.0;
  s.run.output_step = 0.005;
  const RunResult r = run(s);
  REQUIRE_FALSE(r.failure);
  const auto [err, W] = energy_balance(r, [&](std::size_t k) { return power(r, k); });
  INFO("dampers: max |E - E0 - W| = " << err << " J of " << W << " J");
  CHECK(W > 0.05);
  CHECK(err < 1e-8 * W);
  CHECK(drift(r, "H") < 1e-10);
}

// accelerations() at the initial state, at time t.
TreeAccel initial_accelerations(const System& s, double t) {
  LagrangeEngine e(s, {});
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(TreeState::initial(s), x.data());
  TreeAccel a;
  e.accelerations(t, x.data(), a);
  return a;
}

// A spinning hub (free) with a slider on an axis off every principal direction, offset from the
// hub's CM and from the slider's: a genuinely 3-D motion.
System hub_and_slider() {
  Body hub = make_body("hub", 100, {40, 50, 60});
  hub.I_BBo_B(0, 1) = hub.I_BBo_B(1, 0) = 2.0;
  Joint j = prismatic("slide", 0, 1, {0.8, 0.1, 0.2}, {-0.3, 0.0, 0.05}, {1.0, 0.2, 0.1});
  j.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(0, 1, 1).normalized()));
  j.angle0 = 0.1;
  j.rate0 = 0.3;
  return two_bodies("hub_slider", hub, make_body("slider", 5, {0.5, 0.6, 0.7}),
                    {0.05, -0.03, 0.6}, j, 10.0, 0.01);
}

// A spinning base with a gimbaled payload: non-perpendicular axes, an orientation offset, large
// angles and rates.
System gimbal_3d() {
  Body base = make_body("base", 50, {20, 25, 30});
  Joint j =
      universal("gimbal", 0, 1, {0.5, 0.3, 1.0}, {0.1, 0.0, -0.6}, {1, 0, 0.1}, {0.3, 1, 0.2});
  j.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, -1, 2).normalized()));
  j.angle0 = 0.8;
  j.angle2_0 = -0.6;
  j.rate0 = 0.5;
  j.rate2_0 = -0.7;
  j.stiffness = 1.5;
  j.neutral_angle = 0.2;
  j.stiffness2 = 0.8;
  j.neutral_angle2 = -0.1;
  return two_bodies("gimbal_3d", base, make_body("payload", 4, {0.3, 0.5, 0.6}),
                    {0.3, -0.2, 0.8}, j, 10.0, 0.01);
}

}  // namespace

TEST_CASE("lagrange new joints: prismatic spring between two free bodies, closed form",
          "[lagrange][prismatic]") {
  // The axis passes through both CMs and nothing turns: the relative coordinate s oscillates with
  // the reduced mass mu = m1 m2 / (m1 + m2), omega = sqrt(k / mu):
  //   s(t) - neutral = (s0 - neutral) cos(omega t) + (s0' / omega) sin(omega t).
  const double m1 = 10, m2 = 2, k = 50, neutral = 0.2, s0 = 0.3, v0 = 0.4;
  Joint j = prismatic("slide", 0, 1, {1, 0, 0}, {-0.5, 0, 0}, {1, 0, 0});
  j.stiffness = k;
  j.neutral_angle = neutral;
  j.angle0 = s0;
  j.rate0 = v0;
  const System s = two_bodies("slider_spring", make_body("box", m1, {1, 2, 3}),
                              make_body("slider", m2, {0.1, 0.2, 0.3}), {0, 0, 0}, j, 3.0, 0.01);
  const double mu = m1 * m2 / (m1 + m2), omega = std::sqrt(k / mu);
  const RunResult r = run(s);
  INFO((r.failure ? r.failure->what() : "ok"));
  REQUIRE_FALSE(r.failure);
  double err = 0, werr = 0;
  for (std::size_t row = 0; row < r.rows(); ++row) {
    const double t = col(r, row, "t");
    const double exact =
        neutral + (s0 - neutral) * std::cos(omega * t) + v0 / omega * std::sin(omega * t);
    err = std::max(err, std::abs(col(r, row, "slide.position") - exact));
    for (const char* c : {"box.wx", "box.wy", "box.wz", "slider.wx", "slider.wy", "slider.wz"})
      werr = std::max(werr, std::abs(col(r, row, c)));
  }
  INFO("max |s - closed form| = " << err << " m, max |w| = " << werr);
  CHECK(err < 1e-9);
  CHECK(werr < 1e-12);
  // The spring energy is in E: E = mu s'^2 / 2 + k (s - neutral)^2 / 2 (CM at rest).
  const double E0 = 0.5 * mu * v0 * v0 + 0.5 * k * (s0 - neutral) * (s0 - neutral);
  CHECK(std::abs(col(r, 0, "E") - E0) < 1e-12 * E0);
  CHECK(drift(r, "E") < 1e-10);
  // accelerations() at t = 0: s'' = -k (s0 - neutral) / mu, the slider's CM accelerates by s''
  // relative to the box's, and m1 a1 + m2 a2 = 0.
  REQUIRE(LagrangeEngine(s, {}).state_size() == 14);
  const TreeAccel a = initial_accelerations(s, 0.0);
  const double sdd = -k * (s0 - neutral) / mu;
  CHECK(std::abs(a.angle_ddot[1] - sdd) < 1e-12 * std::abs(sdd));
  CHECK((a.a_NBo_N[1] - a.a_NBo_N[0] - Eigen::Vector3d(sdd, 0, 0)).norm() < 1e-12);
  CHECK(total_force(s, a).norm() < 1e-12);
}

TEST_CASE("lagrange new joints: spinning hub with a free 3-D slider conserves H and E",
          "[lagrange][prismatic]") {
  System s = hub_and_slider();
  s.joints[1].stiffness = 20;
  s.joints[1].neutral_angle = 0.15;
  const RunResult r = run(s);
  INFO((r.failure ? r.failure->what() : "ok") << ", " << r.stats.steps << " steps");
  REQUIRE_FALSE(r.failure);
  const double dH = drift(r, "H"), dE = drift(r, "E");
  INFO("H drift " << dH << ", E drift " << dE << ", slide excursion "
                  << excursion(r, "slide.position") << " m, hub wz excursion "
                  << excursion(r, "hub.wz"));
  CHECK(dH < 1e-9);
  CHECK(dE < 1e-9);
  // Not a trivial motion: the slider moves and the hub's spin exchanges with it.
  CHECK(excursion(r, "slide.position") > 0.05);
  CHECK(excursion(r, "hub.wz") > 1e-4);
}

TEST_CASE("lagrange new joints: prescribed prismatic force is mu s'' between two free bodies",
          "[lagrange][prismatic][prescribed]") {
  // Axis through both CMs, nothing turns: the force the joint applies to the slider is the
  // reduced mass times the prescribed acceleration, F = mu s''(t).
  const double m1 = 10, m2 = 2;
  Joint j = prismatic("slide", 0, 1, {0, 0, 1}, {0, 0, -0.5}, {0, 0, 1});
  PrescribedMotion p;
  p.profile = PrescribedMotion::Profile::Deploy;
  p.travel = 1.5;
  p.ramp_time = 4.0;
  j.prescribed = p;
  j.angle0 = 0.2;
  const System s = two_bodies("slider_prescribed", make_body("box", m1, {1, 2, 3}),
                              make_body("slider", m2, {0.1, 0.2, 0.3}), {0, 0, 0}, j, 5.0, 0.1);
  LagrangeEngine e(s, {});
  REQUIRE(e.state_size() == 12);  // the prescribed slider is not in the state
  std::vector<double> x(12);
  e.pack(TreeState::initial(s), x.data());
  const double mu = m1 * m2 / (m1 + m2);
  std::vector<double> row(e.layout().size());
  const auto force = static_cast<std::size_t>(e.layout().joint_first(1)) + 2;
  for (double t : {0.0, 0.5, 1.3, 2.0, 3.1, 4.5}) {
    const double F = e.prescribed_torques(t, x.data())[1];
    INFO("t = " << t << ": F = " << F << ", mu s'' = " << mu * p.accel(t));
    CHECK(std::abs(F - mu * p.accel(t)) < 1e-12);
    e.output_row(t, x.data(), row.data());
    CHECK(row[force] == F);
    CHECK(std::abs(row[force - 2] - (0.2 + p.angle(t))) < 1e-15);
    CHECK(row[force - 1] == p.velocity(t));
  }
}

TEST_CASE("lagrange new joints: prescribed prismatic deploy on a spinning hub, H and work",
          "[lagrange][prismatic][prescribed]") {
  System s = hub_and_slider();
  s.joints[1].rate0 = 0;
  PrescribedMotion p;
  p.profile = PrescribedMotion::Profile::Deploy;
  p.travel = 2.0;
  p.ramp_time = 8.0;
  s.joints[1].prescribed = p;
  s.run.output_step = 0.005;
  const RunResult r = run(s);
  INFO((r.failure ? r.failure->what() : "ok") << ", " << r.stats.steps << " steps");
  REQUIRE_FALSE(r.failure);
  // The joint's work: E(t) - E(0) = integral F s' dt.
  const auto [err, Wmax] = energy_balance(
      r, [&](std::size_t k) { return col(r, k, "slide.force") * col(r, k, "slide.rate"); });
  INFO("energy balance: max |E - E0 - W| = " << err << " J, max |W| = " << Wmax << " J");
  CHECK(Wmax > 0.1);
  CHECK(err < 1e-8 * Wmax);
  bool finite = true;
  for (std::size_t k = 0; k < r.rows(); ++k)
    finite = finite && std::isfinite(col(r, k, "slide.force"));
  CHECK(finite);
  // An internal joint on a free system: H is conserved.
  const double dH = drift(r, "H");
  INFO("H drift " << dH);
  CHECK(dH < 1e-10);
  for (std::size_t k : {std::size_t{0}, r.rows() / 3, r.rows() - 1}) {
    const double t = col(r, k, "t");
    CHECK(std::abs(col(r, k, "slide.position") - (0.1 + p.angle(t))) < 1e-14);
    CHECK(col(r, k, "slide.rate") == p.velocity(t));
  }
}

TEST_CASE("lagrange new joints: prismatic motor and damper, work and momenta",
          "[lagrange][prismatic]") {
  // A constant motor force F along the axis does the work F (s - s0): E - E0 = F (s - s0); it is
  // internal (F on the slider, -F on the hub at the same point), so H is conserved and
  // sum m a = 0.
  System s = hub_and_slider();
  const double F = 3.0;
  s.joints[1].motor_revolute.times = {0.0};
  s.joints[1].motor_revolute.values = {Eigen::Matrix<double, 1, 1>(F)};
  s.run.duration = 4.0;
  const RunResult r = run(s);
  INFO((r.failure ? r.failure->what() : "ok"));
  REQUIRE_FALSE(r.failure);
  const auto [err, Wmax] =
      work_balance(r, [&](std::size_t k) { return F * (col(r, k, "slide.position") - 0.1); });
  INFO("max |E - E0 - F (s - s0)| = " << err << " J of " << Wmax
                                       << " J; H drift " << drift(r, "H"));
  CHECK(Wmax > 1.0);
  CHECK(err < 1e-9 * Wmax);
  CHECK(drift(r, "H") < 1e-10);
  const TreeAccel a = initial_accelerations(s, 1.0);
  CHECK(total_force(s, a).norm() < 1e-12 * F);
  CHECK(std::abs(a.angle_ddot[1]) > 0.1);

  // A damper dissipates d s'^2: E - E0 = -integral d s'^2 dt.
  System d = hub_and_slider();
  d.joints[1].damping = 2.0;
  d.joints[1].stiffness = 20;
  check_dissipation(d, [](const RunResult& rd, std::size_t k) {
    const double v = col(rd, k, "slide.rate");
    return -2.0 * v * v;
  });
}

TEST_CASE("lagrange new joints: universal small-angle frequencies about each axis",
          "[lagrange][universal]") {
  // A heavy base (mass and inertia 1e6 times the payload's) barely moves: each gimbal axis
  // oscillates at omega_k = sqrt(k_k / I_k), I_k the payload's inertia about axis k through the
  // joint point: I_xx + m d^2 and I_yy + m d^2 with the CM d = 0.5 m from the joint along z.
  const double m = 3, d = 0.5, k1 = 2, k2 = 3, a0 = 1e-3;
  const Eigen::Vector3d I(0.2, 0.3, 0.4);
  const double I1 = I(0) + m * d * d, I2 = I(1) + m * d * d;
  for (int axis : {1, 2}) {
    Joint j = universal("gimbal", 0, 1, {0, 0, 1}, {0, 0, -d}, {1, 0, 0}, {0, 1, 0});
    j.stiffness = k1;
    j.stiffness2 = k2;
    (axis == 1 ? j.angle0 : j.angle2_0) = a0;
    const double omega = axis == 1 ? std::sqrt(k1 / I1) : std::sqrt(k2 / I2);
    const double two_periods = 4.0 * std::acos(-1.0) / omega;
    const System s = two_bodies("gimbal_small", make_body("base", 3e6, {1e6, 1.2e6, 1.4e6}),
                                make_body("payload", m, I), {0, 0, 0}, j, two_periods, 0.01);
    const RunResult r = run(s);
    INFO("axis " << axis << ": " << (r.failure ? r.failure->what() : "ok"));
    REQUIRE_FALSE(r.failure);
    const std::string moving = axis == 1 ? "gimbal.angle1" : "gimbal.angle2";
    const std::string still = axis == 1 ? "gimbal.angle2" : "gimbal.angle1";
    double err = 0, other = 0;
    for (std::size_t row = 0; row < r.rows(); ++row) {
      const double t = col(r, row, "t");
      err = std::max(err, std::abs(col(r, row, moving) - a0 * std::cos(omega * t)));
      other = std::max(other, std::abs(col(r, row, still)));
    }
    INFO("two periods: max |a - a0 cos(omega t)| = " << err << " rad (a0 = " << a0
                                                      << "), other axis " << other);
    CHECK(err < 1e-4 * a0);
    CHECK(other < 1e-3 * a0);
  }
}

TEST_CASE("lagrange new joints: universal at large angles on a spinning base conserves H and E",
          "[lagrange][universal]") {
  const System s = gimbal_3d();
  const RunResult r = run(s);
  INFO((r.failure ? r.failure->what() : "ok") << ", " << r.stats.steps << " steps");
  REQUIRE_FALSE(r.failure);
  const double dH = drift(r, "H"), dE = drift(r, "E");
  INFO("H drift " << dH << ", E drift " << dE);
  CHECK(dH < 1e-9);
  CHECK(dE < 1e-9);
  CHECK(excursion(r, "gimbal.angle1") > 0.3);
  CHECK(excursion(r, "gimbal.angle2") > 0.3);
}

TEST_CASE("lagrange new joints: universal motors and dampers, work and momenta",
          "[lagrange][universal]") {
  // Perpendicular axes: the motor torques tau_1 axis_1 + tau_2 axis_2 are an internal pair (H
  // conserved, sum m a = 0) whose generalised forces are tau_1, tau_2: E - E0 = tau_1 (a1 - a1_0)
  // + tau_2 (a2 - a2_0) for constant motors.
  System s = gimbal_3d();
  Joint& j = s.joints[1];
  j.axis2_P = Eigen::Vector3d(0, 1, 0);
  j.axis_P = Eigen::Vector3d(1, 0, 0);
  const double t1 = 0.2, t2 = -0.3;
  j.motor_universal.times = {0.0};
  j.motor_universal.values = {Eigen::Vector2d(t1, t2)};
  s.run.duration = 5.0;
  const RunResult r = run(s);
  INFO((r.failure ? r.failure->what() : "ok"));
  REQUIRE_FALSE(r.failure);
  const auto [err, Wmax] = work_balance(r, [&](std::size_t k) {
    return t1 * (col(r, k, "gimbal.angle1") - 0.8) + t2 * (col(r, k, "gimbal.angle2") + 0.6);
  });
  INFO("max |E - E0 - W| = " << err << " J of " << Wmax << " J; H drift " << drift(r, "H"));
  CHECK(Wmax > 0.1);
  CHECK(err < 1e-9 * Wmax);
  CHECK(drift(r, "H") < 1e-10);
  CHECK(total_force(s, initial_accelerations(s, 1.0)).norm() < 1e-12);

  // Dampers on both axes dissipate d1 a1'^2 + d2 a2'^2.
  System d = gimbal_3d();
  d.joints[1].damping = 0.3;
  d.joints[1].damping2 = 0.5;
  check_dissipation(d, [](const RunResult& rd, std::size_t k) {
    const double v1 = col(rd, k, "gimbal.rate1"), v2 = col(rd, k, "gimbal.rate2");
    return -0.3 * v1 * v1 - 0.5 * v2 * v2;
  });
}

TEST_CASE("lagrange new joints: accelerations() against rhs() and finite differences",
          "[lagrange][prismatic][universal]") {
  // A hub with a slider, and a gimbaled payload on the slider: joint accelerations are rhs()'s
  // pi''; body angular accelerations the central differences of the output w along the motion
  // (RK4 steps of rhs() itself, h = 1e-4 s); sum m a = 0 (springs and motors are internal).
  System s = hub_and_slider();
  s.joints[1].stiffness = 20;
  s.joints[1].motor_revolute.times = {0.0};
  s.joints[1].motor_revolute.values = {Eigen::Matrix<double, 1, 1>(1.5)};
  s.bodies.push_back(make_body("payload", 2, {0.2, 0.25, 0.3}));
  Joint g = gimbal_3d().joints[1];
  g.parent = 1;
  g.child = 2;
  g.motor_universal.times = {0.0};
  g.motor_universal.values = {Eigen::Vector2d(0.1, 0.05)};
  s.joints.push_back(g);
  LagrangeEngine e(s, {});
  const int ns = e.state_size(), nf = ns / 2;
  REQUIRE(nf == 9);  // base 6, slide 1, gimbal 2
  CHECK(e.state_label(6) == "slide.position");
  CHECK(e.state_label(7) == "gimbal.angle1");
  CHECK(e.state_label(nf + 8) == "gimbal.rate2");
  std::vector<double> x(static_cast<std::size_t>(ns)), xd(x.size());
  e.pack(TreeState::initial(s), x.data());
  const double t = 0.5;
  e.rhs(t, x.data(), xd.data());
  TreeAccel a;
  e.accelerations(t, x.data(), a);
  CHECK(a.angle_ddot[1] == xd[static_cast<std::size_t>(nf + 6)]);
  CHECK(a.angle_ddot[2] == xd[static_cast<std::size_t>(nf + 7)]);
  CHECK(a.angle2_ddot[2] == xd[static_cast<std::size_t>(nf + 8)]);
  CHECK(a.angle2_ddot[1] == 0.0);
  CHECK(std::abs(a.angle_ddot[1]) > 1e-3);
  CHECK(total_force(s, a).norm() < 1e-12);
  auto rk4 = [&](double t0, std::vector<double> y, double h) {
    std::vector<double> k1(y.size()), k2(y.size()), k3(y.size()), k4(y.size()), z(y.size());
    auto stage = [&](const std::vector<double>& k, double c) {
      for (std::size_t i = 0; i < y.size(); ++i) z[i] = y[i] + c * h * k[i];
    };
    e.rhs(t0, y.data(), k1.data());
    stage(k1, 0.5);
    e.rhs(t0 + 0.5 * h, z.data(), k2.data());
    stage(k2, 0.5);
    e.rhs(t0 + 0.5 * h, z.data(), k3.data());
    stage(k3, 1.0);
    e.rhs(t0 + h, z.data(), k4.data());
    for (std::size_t i = 0; i < y.size(); ++i)
      y[i] += h / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
    return y;
  };
  const double h = 1e-4;
  const std::vector<double> xp = rk4(t, x, h), xm = rk4(t, x, -h);
  std::vector<double> rp(e.layout().size()), rm(rp.size());
  e.output_row(t + h, xp.data(), rp.data());
  e.output_row(t - h, xm.data(), rm.data());
  for (int b = 0; b < 3; ++b) {
    const auto w = static_cast<std::size_t>(e.layout().body_w(b));
    const Eigen::Vector3d fd((rp[w] - rm[w]) / (2 * h), (rp[w + 1] - rm[w + 1]) / (2 * h),
                             (rp[w + 2] - rm[w + 2]) / (2 * h));
    INFO("body " << b << ": wdot " << a.wdot_NB_B[static_cast<std::size_t>(b)].transpose()
                 << ", finite differences " << fd.transpose());
    CHECK((a.wdot_NB_B[static_cast<std::size_t>(b)] - fd).norm() < 1e-7 * (1 + fd.norm()));
  }
  // Kinematics: every body's w_NB_B (twist pass) is the rate of its attitude quaternion (output,
  // from the joints' own rotations, joints/*.cpp): w = 2 vec(q^* q') (Kane, Likins & Levinson
  // 1983, Sec. 1.13), q' by central differences.
  std::vector<double> r0(rp.size());
  e.output_row(t, x.data(), r0.data());
  for (int b = 0; b < 3; ++b) {
    const auto w = static_cast<std::size_t>(e.layout().body_w(b));
    auto quat = [&](const std::vector<double>& row) {
      return Eigen::Quaterniond(row[w + 3], row[w + 4], row[w + 5], row[w + 6]);
    };
    const Eigen::Quaterniond q = quat(r0), qp = quat(rp), qm = quat(rm);
    const Eigen::Quaterniond qd((qp.coeffs() - qm.coeffs()) / (2 * h));
    const Eigen::Vector3d w_fd = 2.0 * (q.conjugate() * qd).vec();
    const Eigen::Vector3d w_out(r0[w], r0[w + 1], r0[w + 2]);
    INFO("body " << b << ": w " << w_out.transpose() << ", from q' " << w_fd.transpose());
    CHECK((w_out - w_fd).norm() < 1e-7 * (1 + w_out.norm()));
  }
  // The joint columns' rates against the accelerations, the same way.
  const auto js = static_cast<std::size_t>(e.layout().joint_first(1));
  const auto jg = static_cast<std::size_t>(e.layout().joint_first(2));
  CHECK(std::abs((rp[js + 1] - rm[js + 1]) / (2 * h) - a.angle_ddot[1]) < 1e-7);
  CHECK(std::abs((rp[jg + 2] - rm[jg + 2]) / (2 * h) - a.angle_ddot[2]) < 1e-7);
  CHECK(std::abs((rp[jg + 3] - rm[jg + 3]) / (2 * h) - a.angle2_ddot[2]) < 1e-7);
}

TEST_CASE("lagrange new joints: joints at flexible-body nodes and parallel gimbal axes are refused",
          "[lagrange][prismatic][universal]") {
  // A flexible child at node 0 (the reader refuses it too; the engine names the joint).
  System s = hub_and_slider();
  FlexBody f;
  f.mode_names = {"q1"};
  FlexNode n0;
  n0.name = "root";
  n0.mass = 2.5;
  n0.p_BoNi_B = {-0.5, 0, 0};
  n0.Phi_B = Eigen::Matrix3Xd::Zero(3, 1);
  n0.Psi_B = Eigen::Matrix3Xd::Zero(3, 1);
  n0.J_Ni_B = 0.1 * Eigen::Matrix3d::Identity();
  FlexNode n1 = n0;
  n1.name = "tip";
  n1.p_BoNi_B = {0.5, 0, 0};
  n1.Phi_B(1, 0) = 1.0;
  f.nodes = {n0, n1};
  f.K = Eigen::MatrixXd::Identity(1, 1);
  f.D = Eigen::MatrixXd::Zero(1, 1);
  s.bodies[1].flex = f;
  s.joints[1].p_CoJ_C = n0.p_BoNi_B;
  s.joints[1].child_node = 0;
  for (JointType type : {JointType::Prismatic, JointType::Universal}) {
    s.joints[1].type = type;
    try {
      LagrangeEngine e(s, {});
      FAIL("no InputError");
    } catch (const InputError& err) {
      const std::string what = err.what();
      INFO(what);
      CHECK(what.find("joint 'slide'") != std::string::npos);
      CHECK(what.find("cannot attach at a node") != std::string::npos);
    }
  }
  // A universal joint's axes may not be parallel.
  System g = gimbal_3d();
  g.joints[1].axis2_P = -g.joints[1].axis_P;
  CHECK_THROWS_AS(LagrangeEngine(g, {}), InputError);
  // At node -1 (the body frame) a flexible child is allowed: the slider joint runs.
  s.joints[1].type = JointType::Prismatic;
  s.joints[1].child_node = -1;
  s.run.duration = 1.0;
  const RunResult r = run(s);
  INFO((r.failure ? r.failure->what() : "ok"));
  REQUIRE_FALSE(r.failure);
  CHECK(drift(r, "H") < 1e-9);
  CHECK(drift(r, "E") < 1e-9);
}
