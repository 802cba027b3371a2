// Issue 28 in the Kane engine: the environment's loads (core/system.hpp, struct Environment;
// formulations/kane/gravity.cpp).  Every check is physics the engine does not use to compute
// itself: free fall, a pendulum's closed-form angular acceleration and its hinge carrying the
// weight, Euler's equations with the gravity-gradient torque, the pitch libration frequency
// n sqrt(3 (Ix - Iz) / Iy) of a rigid body and of a composite (parallel-axis terms included),
// conservation of E (uniform field) and of the Jacobi integral J (orbit), the generalised forces
// of gravity against the potential's rate (dV/dt = -sum F_r u_r at fixed t) on rigid and flexible
// trees, and the external moment column against dH/dt.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "core/orbit.hpp"
#include "formulations/kane/kane_engine.hpp"
#include "tests/kane/kane_flex_systems.hpp"

using namespace crossdyn;
using namespace crossdyn::test::kane;
using crossdyn::kane::KaneEngine;
using crossdyn::kane::KaneSolver;
using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

namespace {

const Vector3d kG(0.3, -9.81, 0.2);  // a uniform field not along an axis

Environment uniform(const Vector3d& g = kG) {
  Environment e;
  e.kind = Environment::Kind::Uniform;
  e.g_N = g;
  return e;
}

// A circular orbit with n = 1 rad/s (mu = 1, R = 1: the engine uses the second-order field only,
// so only n and the orbit frame matter), optionally inclined.
Environment orbit(double inclination = 0, double raan = 0, double u0 = 0) {
  Environment e;
  e.kind = Environment::Kind::Orbit;
  e.mu = 1.0;
  e.radius = 1.0;
  e.inclination = inclination;
  e.raan = raan;
  e.latitude0 = u0;
  return e;
}

std::vector<double> row_of(Engine& e, double t, const std::vector<double>& x) {
  std::vector<double> row(e.layout().size());
  e.output_row(t, x.data(), row.data());
  return row;
}

// One classical RK4 step of h (any sign) from (t, x).
std::vector<double> rk4_step(Engine& e, double t, const std::vector<double>& x, double h) {
  std::vector<double> y(x);
  rk4(e, y, t, h, 1, [](double, const std::vector<double>&) {});
  return y;
}

// Times of the zero crossings of column c (linear interpolation between rows).
std::vector<double> zero_crossings(const std::vector<std::vector<double>>& rows, int c) {
  std::vector<double> z;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    const double a = rows[i - 1][static_cast<std::size_t>(c)], b = rows[i][static_cast<std::size_t>(c)];
    if ((a < 0) != (b < 0) && a != b) {
      const double ta = rows[i - 1][0], tb = rows[i][0];
      z.push_back(ta + (tb - ta) * a / (a - b));
    }
  }
  return z;
}

// Runs the engine with RK4 (step dt) from its initial state for `duration`, the rows every step.
std::vector<std::vector<double>> run_rows(KaneEngine& e, const System& s, double dt,
                                          double duration, const TreeState* state = nullptr) {
  std::vector<double> x = packed(e, state ? *state : TreeState::initial(s));
  std::vector<std::vector<double>> rows;
  rk4(e, x, 0.0, dt, static_cast<int>(std::lround(duration / dt)),
      [&](double t, const std::vector<double>& xs) { rows.push_back(row_of(e, t, xs)); });
  return rows;
}

// Frequency (rad/s) of an oscillating column from its first and last zero crossings.
double crossing_frequency(const std::vector<std::vector<double>>& rows, int c) {
  const std::vector<double> z = zero_crossings(rows, c);
  REQUIRE(z.size() >= 4);
  return M_PI * static_cast<double>(z.size() - 1) / (z.back() - z.front());
}

double max_relative_change(const std::vector<std::vector<double>>& rows, int c) {
  const double v0 = rows.front()[static_cast<std::size_t>(c)];
  double d = 0;
  for (const auto& r : rows) d = std::max(d, std::abs(r[static_cast<std::size_t>(c)] - v0));
  return d / std::abs(v0);
}

// A rigid body whose principal axes x, y, z lie along the orbit frame's o1, o2, o3 at t = 0,
// pitched by `pitch` about y, turning with the orbit (w_NB_B = R_BO w_NO_O = (0, -n, 0)).
void align_with_orbit(Joint& base, const Environment& env, double pitch) {
  const OrbitFrame o = orbit_frame(env, 0.0);
  const Matrix3d R_NB = o.R_NO * from_roll_pitch_yaw(Vector3d(0, pitch, 0));
  base.q_NB0 = Quaterniond(R_NB);
  base.w_NB_B0 = R_NB.transpose() * o.w_NO_N;
}

// The ground (a prescribed revolute joint to N at rate 0: it never moves) and a rigid rod hanging
// from it on a revolute hinge about z; with the rod's angle 0 its CM is d below the hinge along
// -y (child_point (0, d, 0)).
System pendulum(double m, double d, double Izz, double angle0) {
  System s;
  s.name = "pendulum";
  s.bodies.push_back(rigid_body("ground", 50.0, diag(5, 6, 7)));
  s.bodies.push_back(rigid_body("rod", m, diag(0.4, 0.05, Izz)));
  Joint g = joint("ground_joint", JointType::Revolute, -1, 0, Vector3d(0.2, 0.1, -0.3),
                  Vector3d::Zero());
  g.axis_P = Vector3d(0, 0, 1);
  g.prescribed = PrescribedMotion{PrescribedMotion::Profile::SpinUp, 0.0, 1.0, 0.0};
  s.joints.push_back(g);
  Joint h = joint("hinge", JointType::Revolute, 0, 1, Vector3d(0.1, 0.0, 0.0), Vector3d(0, d, 0));
  h.axis_P = Vector3d(0, 0, 1);
  h.angle0 = angle0;
  s.joints.push_back(h);
  s.zero_linear_momentum = false;
  s.environment = uniform(Vector3d(0, -9.81, 0));
  return s;
}

// Gravity's generalised active forces at (t, x): f with the environment minus f without.
Eigen::VectorXd gravity_forces(const System& s, double t, const std::vector<double>& x) {
  System bare = s;
  bare.environment = Environment{};
  KaneEngine with(s, EngineOptions{}, KaneSolver::Composite);
  KaneEngine without(bare, EngineOptions{}, KaneSolver::Composite);
  return with.generalized_forces(t, x.data()) - without.generalized_forces(t, x.data());
}

// dV/dt at fixed t along the motion (x + h xdot) against -sum_r F_r u_r (Kane's generalised
// active forces of a conservative field are -dV/dq through the kinematical equations).
// (Linear momentum kept: a uniform field does no work on a system with none, g . P = 0.)
void check_forces_against_potential(System s, const TreeState& st, double t) {
  s.zero_linear_momentum = false;
  KaneEngine e(s, EngineOptions{}, KaneSolver::Composite);
  const std::vector<double> x = packed(e, st);
  std::vector<double> xdot(x.size());
  e.rhs(t, x.data(), xdot.data());
  const double dV = derivative(
      [&](double h) {
        const std::vector<double> y = along(x, xdot, h);
        return e.gravity_potential_energy(t, y.data());
      },
      1e-4);
  const Eigen::VectorXd F = gravity_forces(s, t, x);
  const Eigen::Map<const Eigen::VectorXd> u(x.data() + e.position_size(), e.speed_size());
  const double power = F.dot(u);
  INFO("dV/dt = " << dV << ", -F.u = " << -power);
  CHECK(std::abs(dV + power) <= 1e-7 * (std::abs(dV) + F.norm() * u.norm()));
  CHECK(std::abs(dV) > 1e-6 * F.norm() * u.norm());  // not trivially zero
}

}  // namespace

TEST_CASE("kane gravity: a free rigid body falls at g, its rotation unchanged, E constant",
          "[kane][gravity]") {
  System s = single_body(turned_inertia(3, 5, 7, quat_from_axis(0.4, Vector3d(1, 2, 3))),
                         Vector3d(0.3, -0.7, 1.1), 4.0);
  s.joints[0].p_NoBo_N0 = Vector3d(1, 2, 3);
  System bare = s;
  s.environment = uniform();
  KaneEngine e(s, EngineOptions{});
  KaneEngine e0(bare, EngineOptions{});
  const std::vector<double> x = packed(e, TreeState::initial(s));
  TreeAccel a, a0;
  e.accelerations(0.5, x.data(), a);
  e0.accelerations(0.5, x.data(), a0);
  CHECK((a.a_NBo_N[0] - kG).norm() < 1e-14 * kG.norm());
  CHECK((a.wdot_NB_B[0] - a0.wdot_NB_B[0]).norm() < 1e-14 * (1 + a0.wdot_NB_B[0].norm()));
  // The fused rigid path (rhs) agrees.
  std::vector<double> xd(x.size());
  e.rhs(0.5, x.data(), xd.data());
  for (int i = 0; i < 3; ++i) CHECK(xd[x.size() - 3 + static_cast<std::size_t>(i)] == Approx(kG(i)).epsilon(1e-14));

  // E = T - m g . p over a run; the CM moves on the parabola.
  std::vector<double> xr = x;
  const double m = 4.0;
  double E0 = 0, scale = 0, dE = 0;
  rk4(e, xr, 0.0, 1e-2, 300, [&](double t, const std::vector<double>& xs) {
    const std::vector<double> row = row_of(e, t, xs);
    const double E = row[static_cast<std::size_t>(e.layout().E())];
    if (t == 0) {
      E0 = E;
      scale = std::abs(e.kinetic_energy(xs.data())) + m * kG.norm() * 3.0;
    }
    dE = std::max(dE, std::abs(E - E0));
  });
  CHECK(dE < 1e-11 * scale);
  const Vector3d p(xr[0], xr[1], xr[2]);
  CHECK((p - (Vector3d(1, 2, 3) + 0.5 * kG * 9.0)).norm() < 1e-10);
  // No moment about the CM from a uniform field.
  const std::vector<double> row = row_of(e, 3.0, xr);
  for (int i = 0; i < 3; ++i)
    CHECK(std::abs(row[static_cast<std::size_t>(e.layout().external_moment() + i)]) < 1e-12);
}

TEST_CASE("kane gravity: a pendulum on a fixed ground (closed form, E, the hinge carries the "
          "weight)",
          "[kane][gravity]") {
  const double m = 2.0, d = 0.8, Izz = 0.3, g = 9.81;
  const double I_pivot = Izz + m * d * d;
  for (double angle : {0.0, 0.3, 1.2, -2.5}) {
    System s = pendulum(m, d, Izz, angle);
    KaneEngine e(s, EngineOptions{});
    const std::vector<double> x = packed(e, TreeState::initial(s));
    TreeAccel a;
    e.accelerations(0.4, x.data(), a);
    INFO("angle " << angle);
    CHECK(a.angle_ddot[1] == Approx(-m * g * d * std::sin(angle) / I_pivot).margin(1e-13));
    CHECK(a.wdot_NB_B[0].norm() == 0.0);  // the ground does not move
  }

  // E conserved over a run (a large swing).
  {
    System s = pendulum(m, d, Izz, 2.0);
    KaneEngine e(s, EngineOptions{});
    std::vector<double> x = packed(e, TreeState::initial(s));
    double E0 = 0, dE = 0;
    bool first = true;
    const double scale = m * g * d;
    double max_rate = 0;
    rk4(e, x, 0.0, 1e-3, 5000, [&](double t, const std::vector<double>& xs) {
      const double E = row_of(e, t, xs)[static_cast<std::size_t>(e.layout().E())];
      if (first) E0 = E;
      first = false;
      dE = std::max(dE, std::abs(E - E0));
      max_rate = std::max(max_rate, std::abs(xs[static_cast<std::size_t>(e.position_size())]));
    });
    CHECK(max_rate > 3.0);  // it swings
    CHECK(dE < 1e-10 * scale);
  }

  // Hanging at rest: the hinge carries the rod's weight, the ground joint both weights; no moment
  // about the hinge; the external moment (gravity plus N's reaction) is zero.
  {
    System s = pendulum(m, d, Izz, 0.0);
    KaneEngine e(s, EngineOptions{});
    const std::vector<double> x = packed(e, TreeState::initial(s));
    const std::vector<double> row = row_of(e, 0.0, x);
    const int L = e.layout().joint_load(1), L0 = e.layout().joint_load(0);
    const Vector3d F_C(row[L], row[L + 1], row[L + 2]), M_C(row[L + 3], row[L + 4], row[L + 5]);
    CHECK((F_C - Vector3d(0, m * g, 0)).norm() < 1e-12);  // child frame = N here, -g direction
    CHECK(M_C.norm() < 1e-12);
    const Vector3d F0(row[L0], row[L0 + 1], row[L0 + 2]);
    CHECK((F0 - Vector3d(0, (m + 50.0) * g, 0)).norm() < 1e-11);
    const int M = e.layout().external_moment();
    CHECK(Vector3d(row[M], row[M + 1], row[M + 2]).norm() < 1e-11);
  }

  // Displaced, at an angle turning the child frame: F_C = R_NC^T (m a - m g), still in the plane;
  // the external moment is dH/dt (H's rate from RK4 steps either side).
  {
    const double angle = 0.9;
    System s = pendulum(m, d, Izz, angle);
    s.joints[1].rate0 = 0.7;
    KaneEngine e(s, EngineOptions{});
    const std::vector<double> x = packed(e, TreeState::initial(s));
    const std::vector<double> row = row_of(e, 0.0, x);
    const int L = e.layout().joint_load(1);
    const Vector3d F_C(row[L], row[L + 1], row[L + 2]);
    TreeAccel a;
    e.accelerations(0.0, x.data(), a);
    const Matrix3d R_NC = Eigen::AngleAxisd(angle, Vector3d::UnitZ()).toRotationMatrix();
    const Vector3d expected = R_NC.transpose() * (m * a.a_NBo_N[1] - m * Vector3d(0, -g, 0));
    CHECK((F_C - expected).norm() < 1e-12 * m * g);
    const int Hc = e.layout().H_vector(), M = e.layout().external_moment();
    const double dHz = derivative(
        [&](double h) { return row_of(e, h, rk4_step(e, 0.0, x, h))[static_cast<std::size_t>(Hc + 2)]; },
        1e-3);
    CHECK(row[M + 2] == Approx(dHz).epsilon(1e-8));
    CHECK(std::abs(row[M + 2]) > 1.0);
  }
}

TEST_CASE("kane gravity: orbit, one rigid body's accelerations are Euler's equations with the "
          "gravity-gradient torque, its CM moves under T r",
          "[kane][gravity][orbit]") {
  std::mt19937 rng(7);
  const Matrix3d I_B = turned_inertia(3, 5, 8, quat_from_axis(0.6, Vector3d(0.2, 1, -0.4)));
  for (int trial = 0; trial < 3; ++trial) {
    System s = single_body(I_B, Vector3d::Zero(), 6.0);
    s.environment = orbit(0.4 + trial, 0.3 * trial, 0.2);
    for (KaneSolver solver : {KaneSolver::Composite, KaneSolver::OrderN}) {
      KaneEngine e(s, EngineOptions{}, solver);
      REQUIRE(e.orbit_origin_N().norm() == 0.0);  // the initial CM
      const TreeState st = random_state(s, rng);  // random attitude, position, rates
      const std::vector<double> x = packed(e, st);
      const double t = 0.9;
      TreeAccel a;
      e.accelerations(t, x.data(), a);
      const OrbitFrame o = orbit_frame(s.environment, t);
      const double n2 = o.n * o.n;
      const Matrix3d R_NB = st.q_NB.toRotationMatrix();
      const Vector3d z_B = R_NB.transpose() * o.zenith_N;
      const Vector3d w = st.w_NB_B;
      const Vector3d tau_B = 3.0 * n2 * z_B.cross(I_B * z_B);
      const Vector3d wdot = I_B.ldlt().solve(tau_B - w.cross(I_B * w));
      CHECK((a.wdot_NB_B[0] - wdot).norm() < 1e-13 * wdot.norm());
      CHECK(tau_B.norm() > 0.1);  // the torque matters here
      const Matrix3d T = n2 * (3.0 * o.zenith_N * o.zenith_N.transpose() - Matrix3d::Identity());
      const Vector3d acc = T * st.p_NoBo_N;
      CHECK((a.a_NBo_N[0] - acc).norm() < 1e-13 * acc.norm());
      std::vector<double> xd(x.size());
      e.rhs(t, x.data(), xd.data());  // the fused path (composite) or order-N
      const Eigen::Map<const Vector3d> wdot_rhs(xd.data() + e.position_size());
      CHECK((wdot_rhs - wdot).norm() < 1e-13 * wdot.norm());
    }
  }
}

TEST_CASE("kane gravity: orbit, pitch libration of a rigid body at n sqrt(3 (Ix - Iz) / Iy), J "
          "constant",
          "[kane][gravity][orbit]") {
  const double Ix = 3, Iy = 4, Iz = 2;
  System s = single_body(diag(Ix, Iy, Iz), Vector3d::Zero(), 5.0);
  s.environment = orbit(0.5, 0.7, 0.3);  // an inclined orbit: nothing along N's axes
  align_with_orbit(s.joints[0], s.environment, 1e-5);
  KaneEngine e(s, EngineOptions{});
  const double n = s.environment.mean_motion();
  const double expected = n * std::sqrt(3.0 * (Ix - Iz) / Iy);
  const auto rows = run_rows(e, s, 2e-3, 5.0 * 2.0 * M_PI / expected);
  const int pitch = e.layout().lvlh(0) + 1;
  const double measured = crossing_frequency(rows, pitch);
  INFO("pitch frequency " << measured << ", expected " << expected);
  CHECK(std::abs(measured - expected) < 1e-6 * expected);
  // roll and yaw stay zero (planar libration), the pitch amplitude stays 1e-5.
  double roll = 0, amp = 0;
  for (const auto& r : rows) {
    roll = std::max({roll, std::abs(r[static_cast<std::size_t>(pitch - 1)]),
                     std::abs(r[static_cast<std::size_t>(pitch + 1)])});
    amp = std::max(amp, std::abs(r[static_cast<std::size_t>(pitch)]));
  }
  CHECK(roll < 1e-12);
  CHECK(amp == Approx(1e-5).epsilon(1e-5));
  CHECK(max_relative_change(rows, e.layout().J()) < 1e-10);
}

TEST_CASE("kane gravity: orbit, hub and boom: J constant on a hinge, and held rigidly, the composite "
          "librates at the frequency of its composite inertia (parallel-axis terms included)",
          "[kane][gravity][orbit]") {
  const double m1 = 100, m2 = 10, L = 5;  // boom CM 5 m from the hub's along z (nadir)
  const Matrix3d I1 = diag(40, 50, 30), I2 = diag(20, 20, 0.2);
  auto hub_boom = [&](JointType type) {
    System s;
    s.name = "hub_boom";
    s.bodies.push_back(rigid_body("hub", m1, I1));
    s.bodies.push_back(rigid_body("boom", m2, I2));
    s.joints.push_back(free_joint("base", 0, Vector3d::Zero()));
    Joint j = joint("hinge", type, 0, 1, Vector3d(0, 0, 1), Vector3d(0, 0, 1 - L));
    j.axis_P = Vector3d(0, 1, 0);  // pitch axis: the boom swings in the orbit plane
    if (type == JointType::Revolute) j.stiffness = 40.0;
    s.joints.push_back(j);
    s.environment = orbit(0.2, 1.1, 0.0);
    return s;
  };
  // Hinge: J constant while the boom swings (hinge spring, tidal loads, CM offsets).
  {
    System s = hub_boom(JointType::Revolute);
    align_with_orbit(s.joints[0], s.environment, 0.02);
    s.joints[1].angle0 = 0.1;
    s.joints[1].rate0 = 0.05;
    KaneEngine e(s, EngineOptions{});
    const auto rows = run_rows(e, s, 2e-3, 20.0);
    CHECK(max_relative_change(rows, e.layout().J()) < 1e-10);
    // E alone is not conserved (the field turns with the orbit): the check above is not vacuous.
    CHECK(max_relative_change(rows, e.layout().E()) > 1e-4);
  }
  // Fixed joint: the composite's pitch frequency.
  {
    System s = hub_boom(JointType::Fixed);
    align_with_orbit(s.joints[0], s.environment, 1e-5);
    KaneEngine e(s, EngineOptions{});
    const double mu = m1 * m2 / (m1 + m2);
    const Matrix3d I = I1 + I2 + mu * L * L * diag(1, 1, 0);  // about the composite CM
    const double n = s.environment.mean_motion();
    const double expected = n * std::sqrt(3.0 * (I(0, 0) - I(2, 2)) / I(1, 1));
    const double no_parallel = n * std::sqrt(3.0 * ((I1 + I2)(0, 0) - (I1 + I2)(2, 2)) / (I1 + I2)(1, 1));
    const auto rows = run_rows(e, s, 2e-3, 5.0 * 2.0 * M_PI / expected);
    const double measured = crossing_frequency(rows, e.layout().lvlh(0) + 1);
    INFO("measured " << measured << ", composite " << expected << ", without parallel-axis "
                     << no_parallel);
    CHECK(std::abs(measured - expected) < 1e-6 * expected);
    CHECK(std::abs(no_parallel - expected) > 0.05 * expected);
    CHECK(max_relative_change(rows, e.layout().J()) < 1e-10);
    // O is the composite's CM at t = 0 (hub at the origin): (m2 / (m1 + m2)) of the boom's offset.
    const OrbitFrame o = orbit_frame(s.environment, 0.0);
    const Matrix3d R_NB = o.R_NO * from_roll_pitch_yaw(Vector3d(0, 1e-5, 0));
    CHECK((e.orbit_origin_N() - R_NB * Vector3d(0, 0, L * m2 / (m1 + m2))).norm() < 1e-14);
  }
}

TEST_CASE("kane gravity: the generalised forces are -dV/dq on rigid and flexible trees (uniform "
          "and orbit, with stiffening)",
          "[kane][gravity]") {
  std::mt19937 rng(3);
  for (const Environment& env : {uniform(), orbit(0.7, 0.2, 0.4)}) {
    {
      System s = mixed_tree();
      s.environment = env;
      check_forces_against_potential(s, random_state(s, rng), 0.6);
    }
    for (bool stiff : {false, true}) {
      System s = flex_tree();
      if (stiff) s = stiffened(s);
      s.environment = env;
      INFO("orbit " << env.orbit() << ", stiffening " << stiff);
      check_forces_against_potential(s, random_flex_state(s, rng), 0.6);
    }
  }
}

TEST_CASE("kane gravity: flexible tree, E constant under uniform gravity, J on an orbit",
          "[kane][gravity][flex]") {
  for (bool on_orbit : {false, true}) {
    System s = flex_tree();
    s.environment = on_orbit ? orbit(0.3, 0.5, 0.1) : uniform();
    KaneEngine e(s, EngineOptions{});
    TreeState st = flex_state(s, 0.05, 0.2);
    st.w_NB_B = Vector3d(0.3, -0.5, 0.8);
    st.p_NoBo_N = Vector3d(0.5, 3.0, 0.3);  // (uniform: V = -m g . p > 0, no cancellation in E)
    const auto rows = run_rows(e, s, 1e-3, 2.0, &st);
    const int c = on_orbit ? e.layout().J() : e.layout().E();
    INFO("orbit " << on_orbit);
    CHECK(max_relative_change(rows, c) < 1e-9);
  }
}

TEST_CASE("kane gravity: the order-N, fused and composite solvers agree under gravity",
          "[kane][gravity]") {
  std::mt19937 rng(5);
  System s = chain(5);  // order-N by default
  for (const Environment& env : {uniform(), orbit(0.9, 0.1, 0.3)}) {
    s.environment = env;
    KaneEngine on(s, EngineOptions{}, KaneSolver::OrderN);
    KaneEngine comp(s, EngineOptions{}, KaneSolver::Composite);
    const TreeState st = random_state(s, rng);
    const std::vector<double> x = packed(on, st);
    std::vector<double> a(x.size()), b(x.size());
    on.rhs(0.3, x.data(), a.data());
    comp.rhs(0.3, x.data(), b.data());
    const Eigen::VectorXd composite = comp.composite_udot(0.3, x.data(), false);
    for (int r = 0; r < on.speed_size(); ++r) {
      const std::size_t i = static_cast<std::size_t>(on.position_size() + r);
      CHECK(a[i] == Approx(b[i]).margin(1e-11));
      CHECK(composite(r) == Approx(b[i]).margin(1e-11));
    }
  }
}

TEST_CASE("kane gravity: flexible trees, the external moment is dH/dt and a prescribed base's "
          "load is dP/dt - M g (uniform and orbit)",
          "[kane][gravity][flex]") {
  // A free flexible tree on an orbit (gravity's moment about the CM, tidal terms of the
  // deformed bodies), and a stiffened flexible tree on a prescribed base under each field.
  System free_tree = flex_tree();
  free_tree.environment = orbit(0.3, 0.5, 0.1);
  System driven = stiffened(flex_tree());
  driven.joints[0].type = JointType::Revolute;
  driven.joints[0].axis_P = Vector3d(0.3, 0.2, 1.0).normalized();
  driven.joints[0].prescribed = PrescribedMotion{PrescribedMotion::Profile::SpinUp, 1.0, 1.0, 0.0};
  driven.zero_linear_momentum = false;
  System driven_orbit = driven;
  driven.environment = uniform();
  driven_orbit.environment = orbit(1.1, 0.4, 0.2);
  for (const System* s : {&free_tree, &driven, &driven_orbit}) {
    KaneEngine e(*s, EngineOptions{});
    TreeState st = flex_state(*s, 0.08, 0.3);
    if (s->base_is_free()) st.w_NB_B = Vector3d(0.3, -0.5, 0.8);
    const std::vector<double> x = packed(e, st);
    const double t = 0.4;
    const std::vector<double> row = row_of(e, t, x);
    const OutputLayout& L = e.layout();
    int Pc = -1;
    for (std::size_t c = 0; c < L.names().size(); ++c)
      if (L.names()[c] == "kane.P_N.x") Pc = static_cast<int>(c);
    REQUIRE(Pc >= 0);
    auto column3 = [&](double h, int c) {
      const std::vector<double> r = row_of(e, t + h, rk4_step(e, t, x, h));
      return Vector3d(r[static_cast<std::size_t>(c)], r[static_cast<std::size_t>(c + 1)],
                      r[static_cast<std::size_t>(c + 2)]);
    };
    const Vector3d dH = derivative([&](double h) { return column3(h, L.H_vector()); }, 1e-3);
    const int M = L.external_moment();
    const Vector3d M_ext(row[M], row[M + 1], row[M + 2]);
    INFO(s->name << ", orbit " << s->environment.orbit() << ": M " << M_ext.transpose()
                 << ", dH/dt " << dH.transpose());
    CHECK((M_ext - dH).norm() < 1e-7 * (1.0 + dH.norm()));
    if (s->base_is_free()) {
      // Gravity's moment about the CM on an orbit is not zero (the check is not vacuous).
      CHECK(M_ext.norm() > 1e-3);
      continue;
    }
    // N's load on the base (joint 0), in N: F_N = dP/dt - (the field's resultant).
    const Vector3d dP = derivative([&](double h) { return column3(h, Pc); }, 1e-3);
    const int J0 = L.joint_load(0);
    e.set_time(t);  // body_motion and mass_points take the prescribed angle at the last set_time
    const Matrix3d R_NB = e.body_motion(x.data())[0].R_NB;
    const Vector3d F_N = R_NB * Vector3d(row[J0], row[J0 + 1], row[J0 + 2]);
    Vector3d F_field = Vector3d::Zero();
    for (const kane::MassPoint& p : e.mass_points(x.data())) {
      if (s->environment.uniform()) {
        F_field += p.mass * kG;
      } else {
        const OrbitFrame o = orbit_frame(s->environment, t);
        const Matrix3d T =
            o.n * o.n * (3.0 * o.zenith_N * o.zenith_N.transpose() - Matrix3d::Identity());
        F_field += p.mass * T * (p.p_NoP_N - e.orbit_origin_N());
      }
    }
    INFO("F_N " << F_N.transpose() << ", dP/dt - F_field " << (dP - F_field).transpose());
    CHECK((F_N - (dP - F_field)).norm() < 1e-7 * (1.0 + dP.norm() + F_field.norm()));
    CHECK(F_field.norm() > 1e-3);
  }
}
