// The Lagrange engine's environment loads (issue 28; core/system.hpp Environment, core/orbit.hpp;
// formulations/lagrange/gravity.cpp). Physics, each check able to fail:
//   - uniform gravity on a free rigid body: the CM accelerates at g, the rotation is untouched, E
//     (with -m g . p) is constant;
//   - a pendulum on a base held still: theta'' = -m g d sin(phi) / I_pivot (phi from hanging), E
//     conserved over a run, the hinge carries the weight at rest, the held base all of it;
//   - orbit, one rigid body: Euler's equations with the gravity-gradient torque
//     3 n^2 zhat x (I zhat) (Hughes 2004, "Spacecraft Attitude Dynamics", Sec. 8.1) and the tidal
//     force m T r at a random state; test_gravity_gradient_sign flips exactly the torque; the pitch
//     libration frequency n sqrt(3 (Ix - Iz) / Iy) (Hughes Sec. 9.3) from the output's pitch
//     column; J constant;
//   - orbit, a hub and a boom: J constant on a hinge; held by a fixed joint, the composite librates
//     at the frequency of the composite inertia about the system CM (parallel-axis terms: the tidal
//     forces on the CM offsets), not at that of the bodies' own inertias;
//   - flexible bodies: E (uniform) and J (orbit) conserved;
//   - the outputs stay consistent: the external moment Mx My Mz (gravity's included) is dH/dt by
//     central differences along the motion, and a rod's hinge load plus its weight is m a_CM.
#include <catch2/catch.hpp>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "core/integrate.hpp"
#include "core/orbit.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "tests/lagrange/flex_scenes.hpp"
#include "tests/lagrange/scenes.hpp"

using namespace crossdyn;
using crossdyn::lagrange::LagrangeEngine;

namespace {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
constexpr double kPi = std::numbers::pi;

RunResult run(const System& s, const TreeState& initial, double tol,
              const EngineOptions& options = {}) {
  LagrangeEngine e(s, options);
  IntegratorSettings settings = IntegratorSettings::from(s.run);
  settings.method = "rkf78";
  settings.rtol = settings.atol = tol;
  RunResult r = simulate(e, s, initial, settings);
  REQUIRE_FALSE(r.failure);
  return r;
}

double value(const RunResult& r, std::size_t row, const std::string& name) {
  const int c = r.column(name);
  REQUIRE(c >= 0);
  return r.at(row, static_cast<std::size_t>(c));
}

// max_t |X(t) - X(0)| / |X(0)| of a column.
double drift(const RunResult& r, const std::string& name) {
  const double x0 = value(r, 0, name);
  double d = 0;
  for (std::size_t k = 0; k < r.rows(); ++k) d = std::max(d, std::abs(value(r, k, name) - x0));
  return d / std::abs(x0);
}

// The angular frequency of a column's oscillation about zero from its zero crossings (linear
// interpolation between rows; the first and last crossings span whole half periods).
double crossing_frequency(const RunResult& r, const std::string& name) {
  std::vector<double> times;
  for (std::size_t k = 1; k < r.rows(); ++k) {
    const double a = value(r, k - 1, name), b = value(r, k, name);
    if ((a < 0) != (b < 0)) {
      const double ta = value(r, k - 1, "t"), tb = value(r, k, "t");
      times.push_back(ta + (tb - ta) * a / (a - b));
    }
  }
  REQUIRE(times.size() >= 3);
  return kPi * static_cast<double>(times.size() - 1) / (times.back() - times.front());
}

Environment uniform(const Vec3& g) {
  Environment env;
  env.kind = Environment::Kind::Uniform;
  env.g_N = g;
  return env;
}

// A circular orbit with mean motion n (rad/s) at radius 7000 km (mu = n^2 R^3).
Environment orbit(double n, double inclination = 0.0, double raan = 0.0, double latitude0 = 0.0) {
  Environment env;
  env.kind = Environment::Kind::Orbit;
  env.radius = 7.0e6;
  env.mu = n * n * env.radius * env.radius * env.radius;
  env.inclination = inclination;
  env.raan = raan;
  env.latitude0 = latitude0;
  return env;
}

System one_body(const Vec3& inertia, const Environment& env) {
  System s;
  s.name = "one_body";
  s.bodies = {test::make_body("sat", 40.0, inertia)};
  s.joints = {test::free_joint(0, Vec3::Zero())};
  s.environment = env;
  return s;
}

// Euler's equations I w' = tau - w x I w (Kane & Levinson 1985, Sec. 6.4).
Vec3 euler_wdot(const Mat3& I, const Vec3& w, const Vec3& tau) {
  return I.ldlt().solve(tau - w.cross(I * w));
}

}  // namespace

TEST_CASE("lagrange gravity: uniform gravity on a free rigid body", "[lagrange][gravity]") {
  const Vec3 g(0.3, -9.81, 1.2);
  System s = one_body({2.0, 3.0, 4.5}, uniform(g));
  s.joints[0].w_NB_B0 = {0.4, -0.7, 0.25};
  s.joints[0].q_NB0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.9, Vec3(1, 2, -1).normalized()));
  s.joints[0].p_NoBo_N0 = {1.0, 2.0, -3.0};
  s.zero_linear_momentum = false;
  s.joints[0].v_NBo_N0 = {0.5, 0.1, -0.2};
  System s0 = s;
  s0.environment = Environment{};
  LagrangeEngine e(s, {}), e0(s0, {});
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(TreeState::initial(s), x.data());
  TreeAccel a, a0;
  e.accelerations(0.2, x.data(), a);
  e0.accelerations(0.2, x.data(), a0);
  CHECK((a.a_NBo_N[0] - g).norm() < 1e-14 * g.norm());
  // The rotation is the torque-free one: no moment about the CM.
  CHECK((a.wdot_NB_B[0] - a0.wdot_NB_B[0]).norm() <= 1e-15 * a0.wdot_NB_B[0].norm());
  const Mat3 I = Vec3(2.0, 3.0, 4.5).asDiagonal();
  CHECK((a.wdot_NB_B[0] - euler_wdot(I, s.joints[0].w_NB_B0, Vec3::Zero())).norm() < 1e-14);
  // E = T - m g . p over a run (the CM falls, T grows, E stays).
  s.run.duration = 5;
  s.run.output_step = 0.1;
  const RunResult r = run(s, TreeState::initial(s), 1e-12);
  CHECK(drift(r, "E") < 1e-11);
  // The external moment about the CM is zero; the CM's path is the parabola.
  const std::size_t last = r.rows() - 1;
  const double t = value(r, last, "t");
  const Vec3 p_expected = s.joints[0].p_NoBo_N0 + s.joints[0].v_NBo_N0 * t + 0.5 * g * t * t;
  const Vec3 p(value(r, last, "sat.x"), value(r, last, "sat.y"), value(r, last, "sat.z"));
  CHECK((p - p_expected).norm() < 1e-9 * p_expected.norm());
  CHECK(std::abs(value(r, last, "Mx")) + std::abs(value(r, last, "My")) +
            std::abs(value(r, last, "Mz")) <
        1e-13 * 40.0 * g.norm());
}

namespace {

// A ground held still (a prescribed revolute joint to N at rate 0) carrying a rod on a revolute
// hinge about z, the rod's CM at d from the hinge along its x axis; gravity -g0 y in N. The rod's
// angle theta turns its x axis from N's x: the CM is at height d sin(theta), hanging at
// theta = -pi/2.
struct Pendulum {
  double m = 3.0, d = 0.8, Ic = 0.4, g0 = 9.81, mg = 50.0;
  System s;
  Pendulum(double theta0, double rate0) {
    s.name = "pendulum";
    s.bodies = {test::make_body("ground", mg, {4, 5, 6}),
                test::make_body("rod", m, {0.05, Ic, Ic})};
    Joint hold;
    hold.name = "hold";
    hold.type = JointType::Revolute;
    hold.parent = -1;
    hold.child = 0;
    hold.axis_P = Vec3::UnitZ();
    hold.prescribed = PrescribedMotion{};
    hold.prescribed->rate = 0.0;
    Joint hinge;
    hinge.name = "hinge";
    hinge.type = JointType::Revolute;
    hinge.parent = 0;
    hinge.child = 1;
    hinge.p_PoJ_P = {0.3, -0.2, 0.1};
    hinge.p_CoJ_C = {-d, 0, 0};
    hinge.axis_P = Vec3::UnitZ();
    hinge.angle0 = theta0;
    hinge.rate0 = rate0;
    s.joints = {hold, hinge};
    s.zero_linear_momentum = false;
    s.environment = uniform({0.0, -g0, 0.0});
  }
  double I_pivot() const { return Ic + m * d * d; }
};

}  // namespace

TEST_CASE("lagrange gravity: a pendulum under uniform gravity", "[lagrange][gravity]") {
  SECTION("angular acceleration: -m g d sin(phi) / I_pivot") {
    for (const double theta : {-kPi / 2 + 0.3, 0.7, 2.5, -2.9}) {
      Pendulum p(theta, 0.6);
      LagrangeEngine e(p.s, {});
      std::vector<double> x(static_cast<std::size_t>(e.state_size()));
      e.pack(TreeState::initial(p.s), x.data());
      TreeAccel a;
      e.accelerations(0.4, x.data(), a);
      const double phi = theta + kPi / 2;  // from hanging
      const double expected = -p.m * p.g0 * p.d * std::sin(phi) / p.I_pivot();
      INFO("theta " << theta);
      CHECK(a.angle_ddot[1] == Approx(expected).epsilon(1e-13));
    }
  }
  SECTION("E conserved over a run") {
    Pendulum p(0.3, 1.1);
    p.s.run.duration = 10;
    p.s.run.output_step = 0.05;
    const RunResult r = run(p.s, TreeState::initial(p.s), 1e-13);
    // E against the scale m g d of its swing.
    const double E0 = value(r, 0, "E");
    double d = 0, swing = 0;
    for (std::size_t k = 0; k < r.rows(); ++k) {
      d = std::max(d, std::abs(value(r, k, "E") - E0));
      swing = std::max(swing, std::abs(value(r, k, "hinge.angle") - 0.3));
    }
    CHECK(swing > 1.0);  // it swings (through hanging)
    CHECK(d < 1e-10 * p.m * p.g0 * p.d);
  }
  SECTION("at rest hanging, the hinge carries the weight, the held base all of it") {
    Pendulum p(-kPi / 2, 0.0);
    LagrangeEngine e(p.s, {});
    std::vector<double> x(static_cast<std::size_t>(e.state_size())), row(e.layout().size());
    e.pack(TreeState::initial(p.s), x.data());
    TreeAccel a;
    e.accelerations(0.0, x.data(), a);
    CHECK(std::abs(a.angle_ddot[1]) < 1e-14);  // m g d cos(-pi/2) / I_pivot, cos(-pi/2) = 6e-17
    e.output_row(0.0, x.data(), row.data());
    const OutputLayout& L = e.layout();
    auto v3 = [&](int c) {
      return Vec3(row[static_cast<std::size_t>(c)], row[static_cast<std::size_t>(c + 1)],
                  row[static_cast<std::size_t>(c + 2)]);
    };
    // The rod's frame at theta = -pi/2: R_NC = Rot(z, -pi/2); -g (up) in it.
    const Mat3 R_NC = Eigen::AngleAxisd(-kPi / 2, Vec3::UnitZ()).toRotationMatrix();
    const Vec3 up_C = R_NC.transpose() * Vec3::UnitY();
    const Vec3 F_C = v3(L.joint_load(1)), M_C = v3(L.joint_load(1) + 3);
    CHECK((F_C - p.m * p.g0 * up_C).norm() < 1e-13 * p.m * p.g0);
    CHECK(M_C.norm() < 1e-13 * p.m * p.g0 * p.d);  // the weight's line passes through the hinge
    // The held base: N carries both weights, and the moment of the rod's weight about the base
    // joint (the origin): the rod's CM at hinge + d (0, -1, 0).
    const Vec3 F0 = v3(L.joint_load(0));
    CHECK((F0 - (p.m + p.mg) * p.g0 * Vec3::UnitY()).norm() < 1e-13 * (p.m + p.mg) * p.g0);
    const Vec3 cm_rod(0.3, -0.2 - p.d, 0.1);
    const Vec3 M0_expected = -cm_rod.cross(p.m * Vec3(0, -p.g0, 0));  // what N must add
    CHECK((v3(L.joint_load(0) + 3) - M0_expected).norm() < 1e-13 * p.m * p.g0);
    // The system is at rest: the external moment about its CM (gravity's and the base's reaction)
    // is zero.
    CHECK(v3(L.external_moment()).norm() < 1e-12 * p.m * p.g0 * p.d);
  }
}

TEST_CASE("lagrange gravity: one rigid body on an orbit, the gravity-gradient torque",
          "[lagrange][gravity][orbit]") {
  const Vec3 Id(8.0, 10.0, 4.0);
  const Mat3 I = Id.asDiagonal();
  const Environment env = orbit(1.1e-3, 0.5, 0.3, 0.2);
  System s = one_body(Id, env);
  s.joints[0].p_NoBo_N0 = {1.0, -2.0, 0.5};  // O = this point
  std::mt19937 g(5);
  TreeState st = TreeState::initial(s);
  st.q_NB = test::random_quaternion(g);
  st.w_NB_B = {0.01, -0.02, 0.015};
  st.p_NoBo_N = Vec3(1.0, -2.0, 0.5) + Vec3(3.0, -4.0, 2.0);  // 5.4 m from O
  st.v_NBo_N = {0.01, 0.0, -0.02};
  const double t = 123.0;
  const OrbitFrame of = orbit_frame(env, t);
  const double n2 = of.n * of.n;
  const Mat3 R = st.q_NB.toRotationMatrix();
  const Vec3 z_B = R.transpose() * of.zenith_N;
  const Vec3 tau_B = 3.0 * n2 * z_B.cross(I * z_B);
  const Vec3 r = st.p_NoBo_N - Vec3(1.0, -2.0, 0.5);
  const Vec3 a_expected = n2 * (3.0 * of.zenith_N.dot(r) * of.zenith_N - r);

  LagrangeEngine e(s, {});
  CHECK((e.orbit_reference_N() - Vec3(1.0, -2.0, 0.5)).norm() < 1e-15);
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(st, x.data());
  TreeAccel a;
  e.accelerations(t, x.data(), a);
  const Vec3 wdot_expected = euler_wdot(I, st.w_NB_B, tau_B);
  // The gravity-gradient share of wdot is ~ 3 n^2 ~ 4e-6: the torque must be there, exactly.
  CHECK(tau_B.norm() > 1e-6);
  CHECK((a.wdot_NB_B[0] - wdot_expected).norm() < 1e-13 * wdot_expected.norm());
  CHECK((a.a_NBo_N[0] - a_expected).norm() < 1e-13 * a_expected.norm());

  SECTION("test_gravity_gradient_sign flips the torque only, not E or J") {
    EngineOptions flip;
    flip.test_gravity_gradient_sign = -1.0;
    LagrangeEngine ef(s, flip);
    std::vector<double> xf(x.size());
    ef.pack(st, xf.data());
    CHECK(xf == x);
    TreeAccel af;
    ef.accelerations(t, xf.data(), af);
    const Vec3 wdot_flipped = euler_wdot(I, st.w_NB_B, -tau_B);
    CHECK((af.wdot_NB_B[0] - wdot_flipped).norm() < 1e-13 * wdot_flipped.norm());
    CHECK((af.wdot_NB_B[0] - a.wdot_NB_B[0]).norm() > 0.5 * (I.inverse() * tau_B).norm());
    CHECK((af.a_NBo_N[0] - a.a_NBo_N[0]).norm() == 0.0);
    std::vector<double> row(e.layout().size()), rowf(row.size());
    e.output_row(t, x.data(), row.data());
    ef.output_row(t, xf.data(), rowf.data());
    CHECK(row[static_cast<std::size_t>(e.layout().E())] ==
          rowf[static_cast<std::size_t>(ef.layout().E())]);
    CHECK(row[static_cast<std::size_t>(e.layout().J())] ==
          rowf[static_cast<std::size_t>(ef.layout().J())]);
  }
  SECTION("J constant along a tumbling run") {
    System s2 = s;
    s2.run.duration = 3000;
    s2.run.output_step = 20;
    st.w_NB_B = {0.003, -0.002, 0.0025};
    const RunResult r = run(s2, st, 1e-12);
    CHECK(drift(r, "J") < 1e-10);
    // E alone is not conserved on an orbit (zhat turns): the check above is not empty.
    CHECK(drift(r, "E") > 1e3 * drift(r, "J"));
  }
}

namespace {

// A body aligned with the orbit frame (principal x along o1, z along o3) turned in pitch by
// pitch0 about o2, turning with the orbit frame (w_NB_B = w_NO in body axes = (0, -n, 0)).
TreeState aligned_state(const System& s, double pitch0) {
  TreeState st = TreeState::initial(s);
  const OrbitFrame of = orbit_frame(s.environment, 0.0);
  const Mat3 R_NB = of.R_NO * from_roll_pitch_yaw(Vec3(0.0, pitch0, 0.0));
  st.q_NB = Eigen::Quaterniond(R_NB);
  st.w_NB_B = R_NB.transpose() * of.w_NO_N;
  return st;
}

double libration_frequency(double n, const Mat3& I) {
  return n * std::sqrt(3.0 * (I(0, 0) - I(2, 2)) / I(1, 1));
}

}  // namespace

TEST_CASE("lagrange gravity: pitch libration of one rigid body", "[lagrange][gravity][orbit]") {
  const Vec3 Id(8.0, 10.0, 4.0);
  const double n = 1.1e-3;
  System s = one_body(Id, orbit(n, 0.4, 0.7, 0.1));
  const double w_p = libration_frequency(n, Mat3(Id.asDiagonal()));
  s.run.duration = 4.0 * 2.0 * kPi / w_p;  // four libration periods
  s.run.output_step = 5.0;
  const RunResult r = run(s, aligned_state(s, 1e-5), 1e-13);
  const double measured = crossing_frequency(r, "sat.pitch");
  INFO("measured " << measured << ", n sqrt(3 (Ix - Iz) / Iy) " << w_p);
  CHECK(std::abs(measured - w_p) < 1e-6 * w_p);
  CHECK(drift(r, "J") < 1e-10);
  // Roll and yaw stay zero (the pitch motion is planar).
  double off = 0;
  for (std::size_t k = 0; k < r.rows(); ++k)
    off = std::max({off, std::abs(value(r, k, "sat.roll")), std::abs(value(r, k, "sat.yaw"))});
  CHECK(off < 1e-9);
  SECTION("the flipped gravity-gradient sign does not librate at that frequency") {
    // With the torque reversed the aligned attitude is unstable in pitch: the pitch runs away.
    const RunResult rf = run(s, aligned_state(s, 1e-5), 1e-13,
                             [] {
                               EngineOptions o;
                               o.test_gravity_gradient_sign = -1.0;
                               return o;
                             }());
    double big = 0;
    for (std::size_t k = 0; k < rf.rows(); ++k)
      big = std::max(big, std::abs(value(rf, k, "sat.pitch")));
    CHECK(big > 1e-3);
  }
}

namespace {

// A hub and a long boom along the hub's z (the nadir when aligned), on a hinge about the hub's y
// (the pitch axis) or welded.
System hub_boom(const Environment& env, JointType type) {
  System s;
  s.name = "hub_boom";
  s.bodies = {test::make_body("hub", 100.0, {30.0, 40.0, 20.0}),
              test::make_body("boom", 10.0, {21.0, 21.0, 0.2})};
  s.joints = {test::free_joint(0, Vec3::Zero())};
  Joint j;
  j.name = "hinge";
  j.type = type;
  j.parent = 0;
  j.child = 1;
  j.p_PoJ_P = {0.0, 0.0, 1.0};
  j.p_CoJ_C = {0.0, 0.0, -5.0};
  j.axis_P = Vec3::UnitY();
  s.joints.push_back(j);
  s.environment = env;
  return s;
}

}  // namespace

TEST_CASE("lagrange gravity: a hub and a boom on an orbit", "[lagrange][gravity][orbit]") {
  const double n = 1.1e-3;
  SECTION("on a hinge with a spring: J constant") {
    System s = hub_boom(orbit(n, 0.2, 0.0, 0.5), JointType::Revolute);
    s.joints[1].stiffness = 0.05;
    s.joints[1].angle0 = 0.2;
    s.joints[1].rate0 = 0.01;
    s.joints[0].w_NB_B0 = {0.001, -0.002, 0.0005};
    s.run.duration = 4000;
    s.run.output_step = 20;
    const RunResult r = run(s, TreeState::initial(s), 1e-12);
    CHECK(drift(r, "J") < 1e-10);
  }
  SECTION("welded: the composite librates at its own frequency") {
    System s = hub_boom(orbit(n, 0.0, 0.0, 0.0), JointType::Fixed);
    // The composite inertia about the system CM (parallel axes: Kane & Levinson 1985, Sec. 3.8):
    // the hub's CM at 0, the boom's at (0, 0, 6) in the hub frame.
    const double m_hub = 100.0, m_boom = 10.0, M = m_hub + m_boom;
    const Vec3 c_boom(0.0, 0.0, 6.0), cm = m_boom * c_boom / M;
    auto shift = [](double m, const Vec3& d) {
      return Mat3(m * (d.squaredNorm() * Mat3::Identity() - d * d.transpose()));
    };
    const Mat3 I_hub = Vec3(30.0, 40.0, 20.0).asDiagonal();
    const Mat3 I_boom = Vec3(21.0, 21.0, 0.2).asDiagonal();
    const Mat3 I_c = I_hub + shift(m_hub, -cm) + I_boom + shift(m_boom, c_boom - cm);
    const double w_composite = libration_frequency(n, I_c);
    const double w_own = libration_frequency(n, I_hub + I_boom);  // without the CM offsets' share
    REQUIRE(std::abs(w_composite - w_own) > 1e-2 * w_composite);
    s.run.duration = 4.0 * 2.0 * kPi / w_composite;
    s.run.output_step = 5.0;
    const RunResult r = run(s, aligned_state(s, 1e-5), 1e-13);
    const double measured = crossing_frequency(r, "hub.pitch");
    INFO("measured " << measured << ", composite " << w_composite << ", own " << w_own);
    CHECK(std::abs(measured - w_composite) < 1e-6 * w_composite);
    CHECK(drift(r, "J") < 1e-10);
  }
}

TEST_CASE("lagrange gravity: flexible bodies conserve E (uniform) and J (orbit)",
          "[lagrange][gravity][flex]") {
  std::mt19937 g(11);
  SECTION("uniform") {
    System s = test::flex_tree(false);
    s.environment = uniform({0.5, -9.81, 2.0});
    s.run.duration = 2;
    s.run.output_step = 0.05;
    const RunResult r = run(s, test::random_flex_state(s, g), 1e-12);
    // E against the work gravity does over the run (T grows by it, M g times the CM's fall).
    const double E0 = value(r, 0, "E");
    double d = 0;
    for (std::size_t k = 0; k < r.rows(); ++k) d = std::max(d, std::abs(value(r, k, "E") - E0));
    const std::size_t last = r.rows() - 1;
    const Vec3 fall(value(r, last, "CMx") - value(r, 0, "CMx"),
                    value(r, last, "CMy") - value(r, 0, "CMy"),
                    value(r, last, "CMz") - value(r, 0, "CMz"));
    double M = 0;
    for (const Body& b : s.bodies) M += b.mass;
    const double work = M * s.environment.g_N.dot(fall);
    CHECK(work > 100.0);  // it fell
    CHECK(d < 1e-10 * work);
  }
  SECTION("orbit (a strong gradient: n = 0.5 rad/s)") {
    System s = test::flex_tree(false);
    s.environment = orbit(0.5, 0.3, 0.2, 0.1);
    s.run.duration = 4;
    s.run.output_step = 0.05;
    const RunResult r = run(s, test::random_flex_state(s, g), 1e-12);
    CHECK(drift(r, "J") < 1e-10);
    CHECK(drift(r, "E") > 1e3 * drift(r, "J"));
    // The check can fail: with the gravity-gradient torques flipped (the rigid panel's and tip's,
    // the nodes' own inertias') J drifts.
    EngineOptions flip;
    flip.test_gravity_gradient_sign = -1.0;
    const RunResult rf = run(s, test::random_flex_state(s, g), 1e-12, flip);
    CHECK(drift(rf, "J") > 1e-6);
  }
  SECTION("geometric stiffening: the node sums, uniform and orbit") {
    for (const Environment& env : {uniform({0.5, -9.81, 2.0}), orbit(0.5, 0.3, 0.2, 0.1)}) {
      System s = test::with_stiffening(test::flex_tree(false));
      s.environment = env;
      s.run.duration = 2;
      s.run.output_step = 0.05;
      const RunResult r = run(s, test::random_flex_state(s, g, 0.05), 1e-12);
      INFO((env.orbit() ? "orbit" : "uniform"));
      CHECK(drift(r, env.orbit() ? "J" : "E") < 1e-10);
    }
  }
}

namespace {

// A row of outputs at (t, x).
std::vector<double> row_at(LagrangeEngine& e, double t, const std::vector<double>& x) {
  std::vector<double> row(e.layout().size());
  e.output_row(t, x.data(), row.data());
  return row;
}
Vec3 v3(const std::vector<double>& row, int c) {
  const auto k = static_cast<std::size_t>(c);
  return Vec3(row[k], row[k + 1], row[k + 2]);
}

// dH/dt along the motion at (t, x): H_Scm_N at (t + h, x + h xdot), fourth-order central
// difference in h, against the row's external moment M_Scm_N. Returns {|M - dH/dt|, |M|}.
std::pair<double, double> moment_balance(LagrangeEngine& e, double t, const std::vector<double>& x,
                                         double h) {
  std::vector<double> xdot(x.size()), y(x.size());
  e.rhs(t, x.data(), xdot.data());
  auto H = [&](double s) {
    for (std::size_t i = 0; i < x.size(); ++i) y[i] = x[i] + s * xdot[i];
    return v3(row_at(e, t + s, y), e.layout().H_vector());
  };
  const Vec3 dH = (-H(2 * h) + 8.0 * H(h) - 8.0 * H(-h) + H(-2 * h)) / (12.0 * h);
  const Vec3 M = v3(row_at(e, t, x), e.layout().external_moment());
  return {(M - dH).norm(), M.norm()};
}

}  // namespace

TEST_CASE("lagrange gravity: the external moment is dH/dt, the hinge load closes the rod's forces",
          "[lagrange][gravity][loads]") {
  std::mt19937 g(21);
  SECTION("a pendulum on a held base, uniform gravity: M = dH/dt, m a = F_hinge + m g") {
    Pendulum p(0.9, -1.3);
    LagrangeEngine e(p.s, {});
    std::vector<double> x(static_cast<std::size_t>(e.state_size()));
    e.pack(TreeState::initial(p.s), x.data());
    const auto [err, M] = moment_balance(e, 0.3, x, 1e-3);
    INFO("|M - dH/dt| " << err << ", |M| " << M);
    CHECK(M > 1.0);
    CHECK(err < 1e-9 * M);
    TreeAccel a;
    e.accelerations(0.3, x.data(), a);
    const std::vector<double> row = row_at(e, 0.3, x);
    const Mat3 R_NC = Eigen::AngleAxisd(0.9, Vec3::UnitZ()).toRotationMatrix();
    const Vec3 F_N = R_NC * v3(row, e.layout().joint_load(1));
    const Vec3 ma = p.m * a.a_NBo_N[1];
    CHECK((ma - F_N - p.m * Vec3(0, -p.g0, 0)).norm() < 1e-13 * p.m * p.g0);
  }
  SECTION("free systems on a strong orbit: M (gravity's moment about the CM) = dH/dt") {
    for (System s : {test::spear1(), test::flex_tree(false),
                     test::with_stiffening(test::flex_tree(false))}) {
      s.environment = orbit(0.5, 0.3, 0.2, 0.1);
      LagrangeEngine e(s, {});
      std::vector<double> x(static_cast<std::size_t>(e.state_size()));
      TreeState st = test::random_flex_state(s, g, 0.05);
      st.p_NoBo_N = Vec3(2.0, -1.0, 1.5);  // away from O
      e.pack(st, x.data());
      const auto [err, M] = moment_balance(e, 0.7, x, 1e-3);
      INFO(s.name << ": |M - dH/dt| " << err << ", |M| " << M);
      CHECK(M > 1e-2);
      CHECK(err < 1e-8 * M);
    }
  }
}
