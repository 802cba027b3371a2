// The environment's loads in the Newton-Euler engine (issue 28; core/system.hpp "Environment"):
// uniform gravity and the gravity gradient of a circular orbit, on rigid and flexible bodies,
// checked against closed forms (free fall, a pendulum, Euler's equations with the gravity-gradient
// torque of Hughes 2004, "Spacecraft Attitude Dynamics", Sec. 8.1, pitch libration at
// n sqrt(3 (Ix - Iz) / Iy), Hughes Sec. 9.3) and conservation (E, or the Jacobi integral J).
#include "core/orbit.hpp"
#include "core/scene/scene.hpp"
#include "formulations/newton_euler/newton_euler.hpp"
#include "tests/newton_euler/ne_prescribed_scenes.hpp"
#include "tests/newton_euler/ne_run.hpp"
#include "tests/newton_euler/ne_systems.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

namespace {

using namespace crossdyn;
using namespace crossdyn::test::ne;
using Eigen::Matrix3d;
using Eigen::Vector3d;

Matrix3d diag(double a, double b, double c) { return Vector3d(a, b, c).asDiagonal(); }

Environment uniform(const Vector3d& g_N) {
  Environment e;
  e.kind = Environment::Kind::Uniform;
  e.g_N = g_N;
  return e;
}

// A low Earth orbit (n = 1.08e-3 rad/s), inclined, so that no axis of N is special.
Environment leo() {
  Environment e;
  e.kind = Environment::Kind::Orbit;
  e.mu = 3.986004418e14;
  e.body_radius = 6.378e6;
  e.radius = 7.0e6;
  e.inclination = 0.9;
  e.raan = 0.4;
  e.latitude0 = 0.3;
  return e;
}

double max_rel_change(const std::vector<double>& v, double scale) {
  return max_abs_change(v) / scale;
}

// The frequency (rad/s) of a sampled oscillation from its zero crossings (linear interpolation
// between rows: the step is small against the period, and a sine is straight at its zeros).
double crossing_frequency(const std::vector<double>& t, const std::vector<double>& y) {
  std::vector<double> zeros;
  for (std::size_t k = 1; k < y.size(); ++k)
    if ((y[k - 1] < 0) != (y[k] < 0))
      zeros.push_back(t[k - 1] - y[k - 1] * (t[k] - t[k - 1]) / (y[k] - y[k - 1]));
  REQUIRE(zeros.size() >= 3);
  const double half_period = (zeros.back() - zeros.front()) / static_cast<double>(zeros.size() - 1);
  return std::numbers::pi / half_period;
}

// One free rigid body aligned with the orbit frame at t = 0 (principal x, y, z along o1, o2, o3)
// but for a pitch offset, turning with the frame (w_NB = w_NO).
void align_with_orbit(Joint& base, const Environment& env, double pitch) {
  const OrbitFrame of = orbit_frame(env, 0.0);
  const Matrix3d R_NB = of.R_NO * from_roll_pitch_yaw(Vector3d(0, pitch, 0));
  base.q_NB0 = Eigen::Quaterniond(R_NB);
  base.w_NB_B0 = R_NB.transpose() * of.w_NO_N;
}

// A hub and a long boom along the hub's z (nadir at t = 0) joined at the hub's face: a fixed joint
// (rigidly held: one composite body) or a revolute joint about y (the pitch axis, with a spring).
System hub_boom(bool fixed) {
  System s;
  s.name = fixed ? "hub_boom_fixed" : "hub_boom_hinge";
  const double m_boom = 8, L = 10;
  s.bodies = {make_body("hub", 100, diag(30, 40, 25)),
              make_body("boom", m_boom, diag(m_boom * L * L / 12, m_boom * L * L / 12, 0.02))};
  s.joints.push_back(free_joint(0));
  Joint j;
  j.name = "hinge";
  j.type = fixed ? JointType::Fixed : JointType::Revolute;
  j.parent = 0;
  j.child = 1;
  j.p_PoJ_P = Vector3d(0, 0, 0.6);
  j.p_CoJ_C = Vector3d(0, 0, -L / 2);
  j.axis_P = Vector3d::UnitY();
  if (!fixed) {
    j.stiffness = 2e-3;
    j.angle0 = 0.02;
  }
  s.joints.push_back(j);
  s.environment = leo();
  return s;
}

}  // namespace

TEST_CASE("newton-euler gravity: a free rigid body falls at g, w unchanged, E constant",
          "[newton_euler][gravity]") {
  System s;
  s.name = "falling";
  s.bodies = {make_body("box", 3, diag(0.5, 0.7, 0.9))};
  s.joints.push_back(free_joint(0));
  s.joints[0].p_NoBo_N0 = Vector3d(1, 2, 3);
  s.joints[0].v_NBo_N0 = Vector3d(0.3, -0.2, 1.5);
  s.joints[0].w_NB_B0 = Vector3d(0, 0, 0.8);  // about a principal axis: a steady spin
  s.joints[0].q_NB0 = Eigen::Quaterniond(0.9, 0.1, -0.3, 0.2).normalized();
  s.zero_linear_momentum = false;
  const Vector3d g_N(0.4, -9.81, 1.2);
  s.environment = uniform(g_N);

  auto e = make_newton_euler_engine(s, {});
  std::vector<double> x(static_cast<std::size_t>(e->state_size()));
  e->pack(TreeState::initial(s), x.data());
  TreeAccel a;
  e->accelerations(0.0, x.data(), a);
  CHECK((a.a_NBo_N[0] - g_N).norm() < 1e-14);
  CHECK(a.wdot_NB_B[0].norm() < 1e-14);

  const double T = 3.0;
  const RunResult r = run_ne(s, TreeState::initial(s), "rkf78", 1e-12, T, 0.1);
  const std::vector<double> E = series(r, "E");
  const double scale = 3 * g_N.norm() * 20;  // m g times the height fallen
  CHECK(max_rel_change(E, scale) < 1e-12);
  CHECK(std::abs(E.front() - (0.5 * 3 * s.joints[0].v_NBo_N0.squaredNorm() + 0.5 * 0.9 * 0.64 -
                              3 * g_N.dot(Vector3d(1, 2, 3)))) < 1e-12);
  const std::size_t last = r.rows() - 1;
  const double t = r.at(last, 0);
  const Vector3d p = Vector3d(1, 2, 3) + s.joints[0].v_NBo_N0 * t + 0.5 * g_N * t * t;
  CHECK(std::abs(series(r, "box.x").back() - p.x()) < 1e-10);
  CHECK(std::abs(series(r, "box.y").back() - p.y()) < 1e-10);
  CHECK(std::abs(series(r, "box.z").back() - p.z()) < 1e-10);
  CHECK(max_abs_change(series(r, "box.wz")) < 1e-12);
  CHECK(max_abs_change(series(r, "box.wx")) < 1e-12);
  // Uniform gravity has no moment about the system's CM.
  for (const char* c : {"Mx", "My", "Mz"}) {
    const std::vector<double> M = series(r, c);
    CHECK(std::max(max_of(M), -min_of(M)) < 1e-12);
  }
}

namespace {

// A rod (mass m, CM a distance d below its hinge at angle 0) on a revolute hinge about z, carried
// by a ground body held by N (a prescribed base at rate 0), gravity along -y.
System pendulum(double angle0) {
  System s;
  s.name = "pendulum";
  s.bodies = {make_body("ground", 50, diag(5, 6, 7)), make_body("rod", 2, diag(0.4, 0.05, 0.4))};
  Joint base;
  base.name = "anchor";
  base.type = JointType::Revolute;
  base.parent = -1;
  base.child = 0;
  base.p_PoJ_P = Vector3d(0.2, -0.1, 0.3);
  base.p_CoJ_C = Vector3d::Zero();
  base.axis_P = Vector3d::UnitZ();
  base.prescribed = PrescribedMotion{PrescribedMotion::Profile::SpinUp, 0.0, 1.0, 0.0};
  s.joints.push_back(base);
  Joint h;
  h.name = "hinge";
  h.type = JointType::Revolute;
  h.parent = 0;
  h.child = 1;
  h.p_PoJ_P = Vector3d(0.5, 0, 0);
  h.p_CoJ_C = Vector3d(0, 0.75, 0);  // the rod's CM 0.75 m below the hinge at angle 0
  h.axis_P = Vector3d::UnitZ();
  h.angle0 = angle0;
  s.joints.push_back(h);
  s.environment = uniform(Vector3d(0, -9.81, 0));
  return s;
}

}  // namespace

TEST_CASE("newton-euler gravity: a pendulum's angular acceleration, energy and hinge load",
          "[newton_euler][gravity]") {
  const double m = 2, d = 0.75, g = 9.81, I_pivot = 0.4 + m * d * d;
  for (const double angle : {0.3, 1.2, -2.5}) {
    const System s = pendulum(angle);
    auto e = make_newton_euler_engine(s, {});
    std::vector<double> x(static_cast<std::size_t>(e->state_size()));
    e->pack(TreeState::initial(s), x.data());
    TreeAccel a;
    e->accelerations(0.0, x.data(), a);
    INFO("angle " << angle);
    CHECK(std::abs(a.angle_ddot[1] - (-m * g * d * std::sin(angle) / I_pivot)) < 1e-12);
    CHECK(a.wdot_NB_B[0].norm() < 1e-12);  // the ground is held
  }

  SECTION("E (kinetic + potential) is conserved") {
    const System s = pendulum(1.2);
    const RunResult r = run_ne(s, TreeState::initial(s), "rkf78", 1e-12, 10.0, 0.05);
    const std::vector<double> E = series(r, "E"), angle = series(r, "hinge.angle");
    CHECK(max_of(angle) > 1.19);
    CHECK(min_of(angle) < -1.19);  // it swings through
    CHECK(max_rel_change(E, m * g * d) < 1e-10);
    // E at t = 0: potential only, -sum m g . p (the rod's CM; the ground's at its anchor).
    const Vector3d p_rod(0.2 + 0.5 + d * std::sin(1.2), -0.1 - d * std::cos(1.2), 0.3);
    CHECK(std::abs(E.front() - (m * g * p_rod.y() + 50 * g * (-0.1))) < 1e-12);
  }

  SECTION("at rest hanging, the hinge carries the weight; the anchor carries both bodies") {
    const System s = pendulum(0.0);
    auto e = make_newton_euler_engine(s, {});
    std::vector<double> x(static_cast<std::size_t>(e->state_size())), row(e->columns().size());
    e->pack(TreeState::initial(s), x.data());
    e->output_row(0.0, x.data(), row.data());
    auto col = [&](const char* name) { return row[static_cast<std::size_t>(column(*e, name))]; };
    // The child frame is N's at angle 0: F along -g (up), magnitude m g; no moment about the hinge.
    CHECK(std::abs(col("hinge.Fx")) < 1e-12);
    CHECK(std::abs(col("hinge.Fy") - m * g) < 1e-12);
    CHECK(std::abs(col("hinge.Fz")) < 1e-12);
    CHECK(std::abs(col("hinge.Mx")) + std::abs(col("hinge.My")) + std::abs(col("hinge.Mz")) < 1e-12);
    CHECK(std::abs(col("anchor.Fy") - (50 + m) * g) < 1e-10);
    // The external moment about the system CM: N's load plus gravity's, sum zero at rest.
    CHECK(std::abs(col("Mx")) + std::abs(col("My")) + std::abs(col("Mz")) < 1e-10);
    // Off the vertical, gravity's moment about the hinge is what the hinge does not carry.
    const System s2 = pendulum(0.7);
    auto e2 = make_newton_euler_engine(s2, {});
    e2->pack(TreeState::initial(s2), x.data());
    e2->output_row(0.0, x.data(), row.data());
    CHECK(std::abs(row[static_cast<std::size_t>(column(*e2, "hinge.Mz"))]) < 1e-12);
    const double Fy = row[static_cast<std::size_t>(column(*e2, "hinge.Fy"))];
    CHECK(Fy > 0.1);
    CHECK(Fy < m * g);  // the rod accelerates: the hinge holds less than its weight
  }

  SECTION("dH/dt = M about the system CM (gravity's moment and N's reaction)") {
    const System s = pendulum(1.2);
    const RunResult r = run_ne(s, TreeState::initial(s), "rkf78", 1e-12, 2.0, 0.001);
    const std::vector<double> Hz = series(r, "Hz"), Mz = series(r, "Mz");
    double worst = 0, top = 0;
    for (std::size_t k = 1; k + 1 < Hz.size(); ++k) {
      worst = std::max(worst, std::abs((Hz[k + 1] - Hz[k - 1]) / 0.002 - Mz[k]));
      top = std::max(top, std::abs(Mz[k]));
    }
    CHECK(top > 1.0);
    CHECK(worst < 1e-4 * top);
  }
}

TEST_CASE("newton-euler gravity: orbit, one rigid body: gravity-gradient torque, tidal force, libration, J",
          "[newton_euler][gravity][orbit]") {
  const Environment env = leo();
  const double n = env.mean_motion();
  Matrix3d I;
  I << 300, 12, -7, 12, 200, 5, -7, 5, 100;
  System s;
  s.name = "satellite";
  s.bodies = {make_body("sat", 500, I)};
  s.joints.push_back(free_joint(0));
  s.environment = env;

  SECTION("accelerations at a random attitude and an offset from O") {
    auto e = make_newton_euler_engine(s, {});  // O = the body's CM at t = 0: the origin
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int trial = 0; trial < 5; ++trial) {
      TreeState ts = TreeState::initial(s);
      ts.q_NB = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
      ts.w_NB_B = 1e-3 * Vector3d(u(rng), u(rng), u(rng));
      ts.p_NoBo_N = 20 * Vector3d(u(rng), u(rng), u(rng));
      std::vector<double> x(static_cast<std::size_t>(e->state_size()));
      e->pack(ts, x.data());
      const double t = 1000 * (1 + u(rng));
      TreeAccel a;
      e->accelerations(t, x.data(), a);
      const OrbitFrame of = orbit_frame(env, t);
      const Matrix3d R_NB = ts.q_NB.toRotationMatrix();
      const Vector3d z_B = R_NB.transpose() * of.zenith_N, w = ts.w_NB_B;
      const Vector3d tau_gg_B = 3 * n * n * z_B.cross(I * z_B);
      const Vector3d wdot = I.inverse() * (tau_gg_B - w.cross(I * w));
      const Vector3d r = ts.p_NoBo_N;
      const Vector3d a_tidal = n * n * (3 * of.zenith_N * of.zenith_N.dot(r) - r);
      CHECK((a.wdot_NB_B[0] - wdot).norm() < 1e-12 * wdot.norm());
      CHECK((a.a_NBo_N[0] - a_tidal).norm() < 1e-12 * a_tidal.norm());
      CHECK(tau_gg_B.norm() > 1e-5);
    }
  }

  SECTION("pitch libration at n sqrt(3 (Ix - Iz) / Iy); J constant") {
    System p = s;
    p.bodies[0].I_BBo_B = diag(300, 200, 100);
    align_with_orbit(p.joints[0], env, 1e-5);
    const double w_lib = n * std::sqrt(3.0 * (300 - 100) / 200);
    const double duration = 4 * 2 * std::numbers::pi / w_lib;
    const RunResult r = run_ne(p, TreeState::initial(p), "rkf78", 1e-13, duration, 1.0);
    const std::vector<double> t = series(r, "t"), pitch = series(r, "sat.pitch");
    CHECK(max_of(pitch) > 0.99e-5);
    CHECK(max_abs_change(series(r, "sat.roll")) < 1e-9);
    const double w_measured = crossing_frequency(t, pitch);
    CHECK(std::abs(w_measured / w_lib - 1) < 1e-6);
    const std::vector<double> J = series(r, "J");
    CHECK(max_rel_change(J, std::abs(J.front())) < 1e-10);
    // E itself is not conserved on an orbit (the field turns with zhat), J is.
    INFO("E change " << max_abs_change(series(r, "E")) << ", J " << J.front());
  }

  SECTION("J constant from a tumbling, offset start") {
    System p = s;
    p.joints[0].w_NB_B0 = Vector3d(2e-3, -1e-3, 3e-3);
    p.joints[0].q_NB0 = Eigen::Quaterniond(0.3, -0.5, 0.2, 0.7).normalized();
    const RunResult r = run_ne(p, TreeState::initial(p), "rkf78", 1e-13, 6000, 20);
    const std::vector<double> J = series(r, "J"), E = series(r, "E");
    CHECK(max_rel_change(J, std::abs(J.front())) < 1e-10);
    CHECK(max_abs_change(E) > 1e3 * max_abs_change(J));  // E alone is not an integral here
  }
}

TEST_CASE("newton-euler gravity: orbit, hub and boom: composite libration with parallel-axis terms, J",
          "[newton_euler][gravity][orbit]") {
  const Environment env = leo();
  const double n = env.mean_motion();

  SECTION("rigidly held (fixed joint)") {
    System s = hub_boom(true);
    align_with_orbit(s.joints[0], env, 1e-5);
    // Composite inertia about the composite CM (all offsets along z: principal axes x, y, z).
    const double m_hub = 100, m_boom = 8, z_boom = 0.6 + 5.0;
    const double z_cm = m_boom * z_boom / (m_hub + m_boom);
    const double par = m_hub * z_cm * z_cm + m_boom * (z_boom - z_cm) * (z_boom - z_cm);
    const double Ix = 30 + m_boom * 100 / 12.0 + par, Iy = 40 + m_boom * 100 / 12.0 + par,
                 Iz = 25 + 0.02;
    const double w_lib = n * std::sqrt(3 * (Ix - Iz) / Iy);
    // Without the parallel-axis terms (each body's own inertia only), visibly different.
    const double w_own = n * std::sqrt(3 * (Ix - par - Iz) / (Iy - par));
    REQUIRE(std::abs(w_own / w_lib - 1) > 1e-2);
    const double duration = 3 * 2 * std::numbers::pi / w_lib;
    const RunResult r = run_ne(s, TreeState::initial(s), "rkf78", 1e-13, duration, 1.0);
    const double w_measured = crossing_frequency(series(r, "t"), series(r, "hub.pitch"));
    CHECK(std::abs(w_measured / w_lib - 1) < 1e-6);
    const std::vector<double> J = series(r, "J");
    CHECK(max_rel_change(J, std::abs(J.front())) < 1e-10);
  }

  SECTION("on a hinge with a spring: J constant") {
    System s = hub_boom(false);
    align_with_orbit(s.joints[0], env, 0.01);
    s.joints[0].w_NB_B0 += Vector3d(1e-3, 0, -2e-3);
    const RunResult r = run_ne(s, TreeState::initial(s), "rkf78", 1e-13, 4000, 10);
    const std::vector<double> J = series(r, "J");
    CHECK(max_abs_change(series(r, "hinge.angle")) > 1e-3);
    CHECK(max_rel_change(J, std::abs(J.front())) < 1e-10);

    // dH_Scm/dt = M_Scm (the external moment column: the gravity-gradient torques and the tidal
    // forces' moments about the system CM), by central differences over 1 s rows.
    const RunResult h = run_ne(s, TreeState::initial(s), "rkf78", 1e-13, 300, 1.0);
    double worst = 0, top = 0;
    for (const char* c : {"x", "y", "z"}) {
      const std::vector<double> H = series(h, std::string("H") + c), M = series(h, std::string("M") + c);
      for (std::size_t k = 1; k + 1 < H.size(); ++k) {
        worst = std::max(worst, std::abs((H[k + 1] - H[k - 1]) / 2.0 - M[k]));
        top = std::max(top, std::abs(M[k]));
      }
    }
    CHECK(top > 1e-4);
    CHECK(worst < 1e-5 * top);
  }
}

TEST_CASE("newton-euler gravity: a flexible body conserves E (uniform) and J (orbit)",
          "[newton_euler][gravity][flexible]") {
  System s;
  s.name = "flex_gravity";
  s.bodies = {flexible_beam("beam", 12, 3, 6, 2, 1, {30, 200, 50}),
              make_body("tip", 2, diag(0.05, 0.05, 0.02))};
  s.joints.push_back(free_joint(0));
  Joint j;
  j.name = "tip_joint";
  j.type = JointType::Revolute;
  j.parent = 0;
  j.child = 1;
  j.parent_node = node_of(s, 0, "top");
  j.p_PoJ_P = Vector3d(0, 0, 1.5);
  j.p_CoJ_C = Vector3d(0, 0, -0.3);
  j.axis_P = Vector3d::UnitX();
  j.stiffness = 5;
  j.angle0 = 0.2;
  s.joints.push_back(j);
  s.joints[0].q_NB0 = Eigen::Quaterniond(0.8, 0.3, -0.2, 0.4).normalized();
  s.joints[0].w_NB_B0 = Vector3d(0.05, -0.1, 0.2);
  TreeState ts = TreeState::initial(s);
  ts.eta[0] << 0.05, -0.03, 0.04;
  ts.eta_rate[0] << 0.1, 0.0, -0.2;

  SECTION("uniform") {
    System u = s;
    u.environment = uniform(Vector3d(1.0, -9.81, 2.0));
    const RunResult r = run_ne(u, ts, "rkf78", 1e-12, 4.0, 0.02);
    const std::vector<double> E = series(r, "E");
    CHECK(max_abs_change(series(r, "beam.qx1")) > 1e-3);
    CHECK(max_rel_change(E, 14 * 9.81 * 4) < 1e-10);
    // Without the modal generalised force of gravity the beam's CM and the body's would differ:
    // the CM accelerates at g exactly (internal loads cancel).
    const std::vector<double> cx = series(r, "CMx"), cy = series(r, "CMy");
    const double t = r.at(r.rows() - 1, 0);
    CHECK(std::abs(cx.back() - (cx.front() + 0.5 * 1.0 * t * t)) < 1e-9);
    CHECK(std::abs(cy.back() - (cy.front() - 0.5 * 9.81 * t * t)) < 1e-9);
  }

  SECTION("orbit") {
    System o = s;
    o.environment = leo();
    o.joints[0].w_NB_B0 = Vector3d(2e-3, -1e-3, 1.5e-3);
    TreeState to = TreeState::initial(o);
    to.eta = ts.eta;
    to.eta_rate = ts.eta_rate;
    const RunResult r = run_ne(o, to, "rkf78", 1e-13, 300.0, 1.0);
    const std::vector<double> J = series(r, "J");
    CHECK(max_abs_change(series(r, "E")) > 1e3 * max_abs_change(J));  // gravity's work shows in E
    CHECK(max_abs_change(series(r, "beam.qx1")) > 1e-3);
    // J's scale: the kinetic energy of the deformation, and n^2 times the inertia.
    CHECK(max_rel_change(J, std::abs(J.front())) < 1e-10);
  }
}

namespace {

// A free flexible beam; with `stiffening`, every node also carries the second-order displacement
// e_i (1/2 eta^T G_i eta) along the beam (foreshortening).
System free_beam(bool stiffening) {
  System s;
  s.name = stiffening ? "beam_stiffened" : "beam_linear";
  s.bodies = {flexible_beam("beam", 12, 3, 6, 2, 1, {30, 200, 50})};
  if (stiffening) {
    FlexBody& f = *s.bodies[0].flex;
    f.geometric_stiffening = true;
    for (FlexNode& nd : f.nodes) {
      const double z = nd.p_BoNi_B.z();
      nd.e_B = Vector3d(0, 0, z < 0 ? 1.0 : -1.0);
      nd.G = -(nd.Phi_B.transpose() * nd.Phi_B) / 3.0 +
             0.1 * z * Eigen::MatrixXd::Ones(3, 3);  // symmetric, some coupling
    }
  }
  s.joints.push_back(free_joint(0));
  return s;
}

}  // namespace

TEST_CASE("newton-euler gravity: a flexible body's generalised gravity forces are -dV/dq",
          "[newton_euler][gravity][flexible]") {
  for (const bool stiffening : {false, true}) {
    for (const bool orbit : {false, true}) {
      System s = free_beam(stiffening);
      System none = s;
      s.environment = orbit ? leo() : uniform(Vector3d(0.7, -9.81, 1.9));
      auto e = make_newton_euler_engine(s, {});
      auto e0 = make_newton_euler_engine(none, {});
      TreeState ts = TreeState::initial(s);
      ts.p_NoBo_N = Vector3d(3, -2, 5);  // away from O (the initial CM, the origin)
      ts.q_NB = Eigen::Quaterniond(0.8, 0.3, -0.2, 0.4).normalized();
      ts.eta[0] << 0.3, -0.2, 0.25;
      const int nx = e->state_size();
      std::vector<double> x(static_cast<std::size_t>(nx)), row(e->columns().size()),
          row0(e0->columns().size());
      e->pack(ts, x.data());
      const double t = 1234.5;
      // V = E with gravity - E without, at zero velocity (the strain energy cancels).
      auto V = [&](const std::vector<double>& xs) {
        e->output_row(t, xs.data(), row.data());
        e0->output_row(t, xs.data(), row0.data());
        return row[static_cast<std::size_t>(column(*e, "E"))] -
               row0[static_cast<std::size_t>(column(*e0, "E"))];
      };
      const Eigen::VectorXd f = e->linear_system(t, x.data()).b - e0->linear_system(t, x.data()).b;
      const int q0 = label_index(*e, "beam.qw");
      const double h = orbit ? 1e-4 : 1e-6;
      // dV along each unknown's virtual displacement: p (N), a body-axis rotation, each eta.
      Eigen::VectorXd dV(f.size());
      for (int i = 0; i < static_cast<int>(f.size()); ++i) {
        std::vector<double> xp = x, xm = x;
        if (i < 3) {
          xp[static_cast<std::size_t>(i)] += h;
          xm[static_cast<std::size_t>(i)] -= h;
        } else if (i < 6) {
          const Eigen::Quaterniond q(x[static_cast<std::size_t>(q0)], x[static_cast<std::size_t>(q0 + 1)],
                                     x[static_cast<std::size_t>(q0 + 2)], x[static_cast<std::size_t>(q0 + 3)]);
          for (const double sgn : {1.0, -1.0}) {
            const Eigen::Quaterniond r =
                q * Eigen::Quaterniond(Eigen::AngleAxisd(sgn * h, Vector3d::Unit(i - 3)));
            std::vector<double>& xs = sgn > 0 ? xp : xm;
            xs[static_cast<std::size_t>(q0)] = r.w();
            xs[static_cast<std::size_t>(q0 + 1)] = r.x();
            xs[static_cast<std::size_t>(q0 + 2)] = r.y();
            xs[static_cast<std::size_t>(q0 + 3)] = r.z();
          }
        } else {
          xp[static_cast<std::size_t>(q0 + 4 + (i - 6))] += h;
          xm[static_cast<std::size_t>(q0 + 4 + (i - 6))] -= h;
        }
        dV(i) = (V(xp) - V(xm)) / (2 * h);
      }
      INFO("stiffening " << stiffening << ", orbit " << orbit << "\nf_grav " << f.transpose()
                         << "\n-dV/dq " << -dV.transpose());
      CHECK((f + dV).norm() < 1e-6 * f.norm());
      CHECK(f.tail(3).norm() > 1e-3 * f.norm());  // the modal forces are there, and checked
    }
  }
}

TEST_CASE("newton-euler gravity: a flexible beam spun up under gravity: E(t) - E(0) = integral of P",
          "[newton_euler][gravity][flexible]") {
  // A prescribed base spins a clamped beam about z while gravity (tilted off the axis) bends it and
  // does work as it turns: E holds the potential, P only the drive's power (gravity is
  // conservative), so their balance checks the joint loads (the drive carries gravity's moment) and
  // the potential together. Linear and geometrically stiffened beams.
  for (const bool stiffening : {false, true}) {
    System s = read_scene_text(spinup_beam_text(stiffening, 2.0, 4.0), "spinup_gravity");
    s.environment = uniform(Vector3d(0, -3.0, -9.81));
    const double dt = 0.0025;  // Simpson's error, O(dt^4): 1e-7 of the work at 0.01 s
    const RunResult r = run_ne(s, TreeState::initial(s), "dop853", 1e-12, 6.0, dt);
    const std::vector<double> E = series(r, "E"), P = series(r, "P");
    double work = 0, worst = 0, swing = 0;
    for (std::size_t k = 2; k < E.size(); k += 2) {  // Simpson's rule on pairs of rows
      work += dt / 3.0 * (P[k - 2] + 4.0 * P[k - 1] + P[k]);
      worst = std::max(worst, std::abs(E[k] - E.front() - work));
      swing = std::max(swing, std::abs(work));
    }
    INFO("stiffening " << stiffening << ": max |dE - W| " << worst << " J, max |W| " << swing);
    CHECK(swing > 10.0);
    CHECK(worst < 1e-8 * swing);
    CHECK(max_abs_change(series(r, "beam.qy1")) > 1e-4);  // the beam bends
  }
}
