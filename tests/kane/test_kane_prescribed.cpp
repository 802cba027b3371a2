// Issue 13 in the Kane engine: prescribed revolute joints (inside the tree and as the base) and
// geometric stiffening (docs/prescribed-motion.md, docs/flexible-bodies.md "Geometric
// stiffening").  Every check is physics the engine does not use to compute itself: the work of
// the reported joint torque against the energy, the angular momentum of a free system, a rigid
// body's torque I theta'', the small-motion frequencies of a spinning clamped beam from its
// Lagrangian, and the conservation of E and H with the second-order displacement field.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <complex>
#include <string>
#include <vector>

#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "core/scene/scene.hpp"
#include "formulations/kane/kane_engine.hpp"
#include "tests/kane/kane_flex_systems.hpp"
#include "tests/support/linalg.hpp"

using namespace crossdyn;
using namespace crossdyn::test::kane;
using Eigen::Matrix3d;
using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;

namespace {

// The issue-13 scenes (their bodies and joints; durations set per test).
const char* kScanPlatform = R"(
name: scan_platform
bodies:
  - name: bus
    mass: 800 kg
    inertia: [600, 500, 400]
  - name: platform
    mass: 60 kg
    inertia: [2.6, 5.8, 6.8]
joints:
  - name: base
    type: free
    child: bus
    initial:
      angular_velocity: [0.01, -0.02, 0.005]
  - name: scan
    type: revolute
    parent: bus
    parent_point: [0.5, 0, 0]
    child: platform
    child_point: [-0.3, 0, 0]
    axis: [1, 0, 0]
    offset: {axis: [0, 1, 0], angle: 10 deg}
    prescribed: {profile: spin-up, rate: 2 rad/s, ramp_time: 5 s}
run:
  duration: 10 s
  output_step: 0.05 s
  integrator: dop853
  rtol: 1e-12
  atol: 1e-12
)";

// Kane, Ryan and Banerjee's spin-up beam; STIFF, RATE, RAMP and DURATION replaced per test.
const char* kSpinupBeam = R"(
name: spinup_beam
bodies:
  - name: hub
    mass: 100 kg
    inertia: [10, 10, 10]
  - name: beam
    flexible:
      beam:
        length: 10 m
        axis: x
        mass_per_length: 1.2
        section: [0, 0.02 m, 0.02 m]
        bending:
          y: {modes: 3, EI: 14000}
        boundary: clamped-bottom
        slices: 50
        geometric_stiffening: STIFF
joints:
  - name: spin
    type: revolute
    child: hub
    parent_point: [0, 0, 0]
    child_point: [0, 0, 0]
    axis: [0, 0, 1]
    prescribed: {profile: spin-up, rate: RATE rad/s, ramp_time: RAMP s}
  - name: root
    type: fixed
    parent: hub
    parent_point: [0, 0, 0]
    child: beam
    child_node: bottom
run:
  duration: DURATION s
  output_step: 0.05 s
  integrator: dop853
  rtol: 1e-12
  atol: 1e-12
)";

std::string replaced(std::string s, const std::vector<std::pair<std::string, std::string>>& r) {
  for (const auto& [from, to] : r) {
    const std::size_t i = s.find(from);
    REQUIRE(i != std::string::npos);
    s.replace(i, from.size(), to);
  }
  return s;
}

System spinup_beam(bool stiff, double rate = 10, double ramp = 15, double duration = 20) {
  return read_scene_text(replaced(kSpinupBeam, {{"STIFF", stiff ? "true" : "false"},
                                                {"RATE", std::to_string(rate)},
                                                {"RAMP", std::to_string(ramp)},
                                                {"DURATION", std::to_string(duration)}}),
                         "spinup_beam (test)");
}

int column(const Engine& e, const std::string& name) {
  const auto& c = e.columns();
  for (std::size_t i = 0; i < c.size(); ++i)
    if (c[i] == name) return static_cast<int>(i);
  FAIL("no column " << name);
  return -1;
}

// Power of the prescribed joints, sum torque * rate, and E, from one output row.
struct PowerRow {
  double P = 0, E = 0;
};
PowerRow power_row(kane::KaneEngine& e, const System& s, double t, const double* x) {
  std::vector<double> row(e.columns().size());
  e.output_row(t, x, row.data());
  PowerRow r;
  r.E = row[static_cast<std::size_t>(e.layout().E())];
  for (const Joint& j : s.joints)
    if (j.prescribed)
      r.P += row[static_cast<std::size_t>(column(e, j.name + ".torque"))] *
             row[static_cast<std::size_t>(column(e, j.name + ".rate"))];
  return r;
}

// Classical RK4 (fixed step dt) of the engine's state together with the joints' work
// W' = sum torque * rate (the energy balance E(t) - E(0) = integral_0^t torque rate dt,
// docs/prescribed-motion.md): max_t |E - E0 - W|, max_t |E - E0| and max_t |E - E0 + W| (what a
// torque of the wrong sign would give).
struct Balance {
  double err = 0, dE = 0, wrong_sign = 0;
};
Balance energy_balance(const System& s, double duration, double dt) {
  kane::KaneEngine e(s, {});
  const std::size_t n = static_cast<std::size_t>(e.state_size());
  std::vector<double> x(n + 1), k1(n + 1), k2(n + 1), k3(n + 1), k4(n + 1), y(n + 1);
  e.pack(TreeState::initial(s), x.data());
  x[n] = 0;
  auto f = [&](double t, const std::vector<double>& z, std::vector<double>& dz) {
    e.rhs(t, z.data(), dz.data());
    dz[n] = power_row(e, s, t, z.data()).P;
  };
  const double E0 = power_row(e, s, 0, x.data()).E;
  Balance b;
  const long steps = std::lround(duration / dt);
  for (long i = 0; i < steps; ++i) {
    const double t = static_cast<double>(i) * dt;
    f(t, x, k1);
    for (std::size_t j = 0; j <= n; ++j) y[j] = x[j] + 0.5 * dt * k1[j];
    f(t + 0.5 * dt, y, k2);
    for (std::size_t j = 0; j <= n; ++j) y[j] = x[j] + 0.5 * dt * k2[j];
    f(t + 0.5 * dt, y, k3);
    for (std::size_t j = 0; j <= n; ++j) y[j] = x[j] + dt * k3[j];
    f(t + dt, y, k4);
    for (std::size_t j = 0; j <= n; ++j)
      x[j] += dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
    e.after_step(t + dt, x.data());
    const double dE = power_row(e, s, t + dt, x.data()).E - E0;
    b.err = std::max(b.err, std::abs(dE - x[n]));
    b.dE = std::max(b.dE, std::abs(dE));
    b.wrong_sign = std::max(b.wrong_sign, std::abs(dE + x[n]));
  }
  return b;
}

IntegratorSettings dop853(double duration, double output_step) {
  IntegratorSettings st;
  st.method = "dop853";
  st.rtol = st.atol = 1e-12;
  st.duration = duration;
  st.output_step = output_step;
  return st;
}

// A flexible tree (tests/kane/kane_flex_systems.hpp) with its revolute joints prescribed (the
// shoulder at a node of the flexible base, the elbow at a node of a flexible child); a
// prescribed joint has no spring, damper or motor.
System prescribed_flex_tree(bool stiff) {
  System s = stiff ? stiffened(flex_tree(false)) : flex_tree(false);
  double rate = 0.8;
  for (std::size_t j = 1; j < s.joints.size(); ++j) {
    Joint& J = s.joints[j];
    if (J.type != JointType::Revolute) continue;
    J.prescribed = PrescribedMotion{PrescribedMotion::Profile::SpinUp, rate, 1.5};
    J.stiffness = J.damping = 0;
    J.motor_revolute = {};
    J.rate0 = 0;
    rate = -1.3;
  }
  return s;
}

}  // namespace

TEST_CASE("kane prescribed: energy balance E(t) - E(0) = integral of torque * rate") {
  // RK4 with the work integrated alongside; the error is the integrator's, far below the
  // energy change, while a torque of the wrong sign (or a missing term) misses by O(dE).
  struct Case {
    std::string name;
    System system;
    double duration, dt, tol;
  };
  const std::vector<Case> cases = {
      {"scan_platform", read_scene_text(kScanPlatform, "scan_platform (test)"), 10.0, 2e-3, 1e-10},
      {"spinup_beam (stiffening, 4 rad/s in 3 s)", spinup_beam(true, 4, 3, 4), 4.0, 1e-3, 1e-8},
      {"spinup_beam_linear (2 rad/s in 3 s)", spinup_beam(false, 2, 3, 4), 4.0, 1e-3, 1e-8},
      {"flexible tree, prescribed joints at nodes", prescribed_flex_tree(false), 2.0, 1e-3, 1e-8},
      {"flexible tree, stiffened, prescribed joints at nodes", prescribed_flex_tree(true), 2.0,
       1e-3, 1e-8},
  };
  for (const Case& c : cases) {
    const Balance b = energy_balance(c.system, c.duration, c.dt);
    INFO(c.name << ": max |E - E0| = " << b.dE << " J, max |E - E0 - W| = " << b.err
                << " J, with the torque's sign flipped " << b.wrong_sign << " J");
    CHECK(b.dE > 1e-3);
    CHECK(b.err <= c.tol * b.dE);
    CHECK(b.wrong_sign >= 0.1 * b.dE);
  }
}

TEST_CASE("kane prescribed: a free base with an internal prescribed joint keeps H (dop853)") {
  for (const System& s : {read_scene_text(kScanPlatform, "scan_platform (test)"),
                          prescribed_flex_tree(false), prescribed_flex_tree(true)}) {
    kane::KaneEngine e(s, {});
    const RunResult r =
        simulate(e, s, TreeState::initial(s), dop853(s.name == "scan_platform" ? 10 : 3, 0.05));
    REQUIRE_FALSE(r.failure.has_value());
    double dH = 0, H0 = 0;
    const int hx = r.column("kane.H_N.x");
    for (int i = 0; i < 3; ++i)
      H0 = std::max(H0, std::abs(r.at(0, static_cast<std::size_t>(hx + i))));
    for (std::size_t k = 0; k < r.rows(); ++k)
      for (int i = 0; i < 3; ++i)
        dH = std::max(dH, std::abs(r.at(k, static_cast<std::size_t>(hx + i)) -
                                   r.at(0, static_cast<std::size_t>(hx + i))));
    // The bus counter-rotates: the motion is not trivial.
    INFO(s.name << ": max |H - H0| = " << dH << " with |H0| ~ " << H0);
    CHECK(H0 > 0);
    CHECK(dH <= 1e-9 * H0);
  }
}

TEST_CASE(
    "kane prescribed: a rigid body on a prescribed base about a principal axis through "
    "its CM needs torque I theta'' and turns at w_NB_B = theta' axis") {
  // The base turns about its principal axis k = R_NJ0 axis_J fixed in N: H = I_k theta' k, so
  // the torque about the axis is I_k theta'' exactly (Euler's equation with w x I w = 0); with
  // the CM at a distance d from the axis, (I_k + m d^2) theta'' (the parallel-axis theorem).
  const PrescribedMotion pm{PrescribedMotion::Profile::SpinUp, 3.0, 2.0};
  for (double d : {0.0, 0.7}) {
    System s;
    s.name = "prescribed_rigid";
    s.bodies.push_back(rigid_body("body", 5.0, diag(2.0, 3.0, 4.5)));
    Joint j = joint("drive", JointType::Revolute, -1, 0, Vector3d(1, -2, 3), Vector3d(0, -d, 0));
    j.axis_P = Vector3d(1, 1, 1).normalized();  // in N; the offset turns body z onto it
    j.q_PJ0 = Eigen::Quaterniond::FromTwoVectors(Vector3d::UnitZ(), j.axis_P);
    j.prescribed = pm;
    j.angle0 = 0.3;
    s.joints.push_back(j);
    kane::KaneEngine e(s, {});
    REQUIRE(e.state_size() == 0);
    std::vector<double> x(1, 0.0), row(e.columns().size());
    e.pack(TreeState::initial(s), x.data());
    for (double t : {0.0, 0.3, 1.0, 1.7, 2.0, 3.5}) {
      e.output_row(t, x.data(), row.data());
      const double torque = row[static_cast<std::size_t>(column(e, "drive.torque"))];
      const double expected = (4.5 + 5.0 * d * d) * pm.accel(t);
      const Vector3d w(row[0 + 1], row[0 + 2], row[0 + 3]);
      INFO("d = " << d << ", t = " << t << ": torque " << torque << ", I theta'' " << expected
                  << ", w_NB_B " << w.transpose());
      CHECK(std::abs(torque - expected) <= 1e-12 * (1.0 + std::abs(expected)));
      CHECK((w - pm.velocity(t) * Vector3d::UnitZ()).norm() <= 1e-14 * (1.0 + pm.velocity(t)));
      CHECK(row[static_cast<std::size_t>(column(e, "drive.angle"))] ==
            Approx(0.3 + pm.angle(t)).epsilon(1e-15));
      TreeAccel a;
      e.accelerations(t, x.data(), a);
      CHECK(a.angle_ddot[0] == pm.accel(t));
      CHECK((a.wdot_NB_B[0] - pm.accel(t) * Vector3d::UnitZ()).norm() <=
            1e-14 * (1.0 + pm.accel(t)));
      // The CM moves on a circle of radius d about the axis: a = alpha x r + w x (w x r).
      const Vector3d k = j.axis_P;
      const Vector3d r_N = e.body_motion(x.data())[0].p_NoBo_N - j.p_PoJ_P;
      const Vector3d a_ref =
          pm.accel(t) * k.cross(r_N) + pm.velocity(t) * pm.velocity(t) * k.cross(k.cross(r_N));
      CHECK((a.a_NBo_N[0] - a_ref).norm() <= 1e-13 * (1.0 + a_ref.norm()));
      CHECK(std::abs(r_N.norm() - d) <= 1e-14);
    }
  }
}

namespace {

// The small-motion in-plane frequencies of the clamped beam spinning at the constant rate W about
// z (the base's prescribed axis through the clamp): with rho_i = p_i - p_clamp + u_i the node
// positions from the axis (in the turning frame) and u_i = Phi_i eta + e_i 1/2 eta^T G_i eta,
//   T = 1/2 sum m_i |rho_i' + W z x rho_i|^2,  V = 1/2 eta^T K eta,
// and about eta = 0 (an equilibrium: the in-plane shapes are normal to the radial rho_i),
// to second order in (eta, eta'):
//   T2 = 1/2 eta'^T Mm eta' + W eta'^T (sum m_i Phi_i^T [z x] Phi_i) eta
//        + 1/2 W^2 eta^T (sum m_i Phi_i^T P Phi_i + sum m_i (P rho0_i . e_i) G_i) eta,
// P = 1 - z z^T (|z x v|^2 = v^T P v; the G term is 2 (P rho0_i) . e_i w_i).  Lagrange's equations:
//   Mm eta'' + Gy eta' + (K + W^2 (K_G - M_soft)) eta = 0,
//   K_G = -sum m_i (P rho0_i . e_i) G_i,  M_soft = sum m_i Phi_i^T P Phi_i,
//   Gy = W sum m_i (Phi_i^T [z x] Phi_i - ([z x] Phi_i)^T Phi_i)  (skew; zero for shapes along y).
// Returns the eigenvalues of the first-order system [0 1; -Mm^-1 Keff, -Mm^-1 Gy].
std::vector<std::complex<double>> spinning_beam_eigenvalues(const System& s, double W) {
  const FlexBody& fb = *s.bodies[1].flex;
  const int n = fb.modes();
  const Vector3d z = Vector3d::UnitZ();
  const Matrix3d P = Matrix3d::Identity() - z * z.transpose();
  const Matrix3d Z = (Matrix3d() << 0, -1, 0, 1, 0, 0, 0, 0, 0).finished();  // [z x]
  const Vector3d p_clamp = fb.nodes[static_cast<std::size_t>(s.joints[1].child_node)].p_BoNi_B;
  MatrixXd Mm = MatrixXd::Zero(n, n), Ms = Mm, KG = Mm, Gy = Mm;
  for (const FlexNode& nd : fb.nodes) {
    const Vector3d rho0 = nd.p_BoNi_B - p_clamp;
    Mm += nd.mass * nd.Phi_B.transpose() * nd.Phi_B;
    Ms += nd.mass * nd.Phi_B.transpose() * P * nd.Phi_B;
    Gy +=
        W * nd.mass * (nd.Phi_B.transpose() * Z * nd.Phi_B - (Z * nd.Phi_B).transpose() * nd.Phi_B);
    if (fb.geometric_stiffening) KG -= nd.mass * (P * rho0).dot(nd.e_B) * nd.G;
  }
  const MatrixXd Keff = fb.K + W * W * (KG - Ms);
  MatrixXd A = MatrixXd::Zero(2 * n, 2 * n);
  A.topRightCorner(n, n).setIdentity();
  A.bottomLeftCorner(n, n) = -test::ldlt_solve(Mm, Keff);
  A.bottomRightCorner(n, n) = -test::ldlt_solve(Mm, Gy);
  const Eigen::VectorXcd ev = test::eigenvalues(A);
  return {ev.data(), ev.data() + ev.size()};
}

// The engine's eigenvalues: its rhs linearised about x = 0 (eta = eta' = 0) at time t by central
// differences.
std::vector<std::complex<double>> engine_eigenvalues(const System& s, double t) {
  kane::KaneEngine e(s, {});
  const int n = e.state_size();
  std::vector<double> x(static_cast<std::size_t>(n), 0.0), xp(x), xm(x), fp(x), fm(x);
  MatrixXd A(n, n);
  const double h = 1e-6;
  for (int j = 0; j < n; ++j) {
    xp = x;
    xm = x;
    xp[static_cast<std::size_t>(j)] += h;
    xm[static_cast<std::size_t>(j)] -= h;
    e.rhs(t, xp.data(), fp.data());
    e.rhs(t, xm.data(), fm.data());
    for (int i = 0; i < n; ++i)
      A(i, j) = (fp[static_cast<std::size_t>(i)] - fm[static_cast<std::size_t>(i)]) / (2 * h);
  }
  const Eigen::VectorXcd ev = test::eigenvalues(A);
  return {ev.data(), ev.data() + ev.size()};
}

}  // namespace

TEST_CASE("kane stiffening: a clamped beam spinning at W vibrates with K + W^2 (K_G - M_soft)") {
  // After the ramp (t > T) the base turns at the constant rate W.  With stiffening the
  // frequencies rise with W; without it (the linear model) the first mode goes unstable once W
  // passes its frequency (3.8 rad/s): a real eigenvalue pair, the published divergence.
  for (bool stiff : {true, false}) {
    for (double W : {2.0, 10.0}) {
      const System s = spinup_beam(stiff, W, 1.0, 5.0);
      const auto ref = spinning_beam_eigenvalues(s, W);
      const auto eng = engine_eigenvalues(s, 3.0);
      REQUIRE(eng.size() == ref.size());
      double worst = 0, scale = 0, max_real = 0;
      for (const auto& r : ref) {
        double best = 1e300;
        for (const auto& v : eng) best = std::min(best, std::abs(v - r));
        worst = std::max(worst, best);
        scale = std::max(scale, std::abs(r));
        max_real = std::max(max_real, r.real());
      }
      INFO((stiff ? "stiffening" : "linear")
           << ", W = " << W << ": max |lambda_engine - "
           << "lambda_Lagrange| = " << worst << " (|lambda| up to " << scale
           << "), max Re lambda = " << max_real);
      CHECK(worst <= 1e-6 * scale);
      if (stiff || W < 3.8) CHECK(max_real <= 1e-6 * scale);  // oscillatory: stable
      if (!stiff && W > 3.8) CHECK(max_real > 0.1);           // diverges
    }
  }
  // The stiffening raises the first in-plane frequency above the non-rotating one (K alone):
  // 3.80 -> 5.33 rad/s at 10 rad/s (the one-mode Southwell estimate from the non-rotating shape,
  // coefficient ~1.19, minus W^2 in the plane of rotation, is sqrt(3.8^2 + 0.19 W^2) = 5.8 rad/s;
  // three modes lower it, as Rayleigh-Ritz does).
  const System s = spinup_beam(true, 10.0, 1.0, 5.0);
  const auto spinning = spinning_beam_eigenvalues(s, 10.0), still = spinning_beam_eigenvalues(s, 0);
  auto lowest = [](const std::vector<std::complex<double>>& v) {
    double m = 1e300;
    for (const auto& c : v) m = std::min(m, std::abs(c));
    return m;
  };
  INFO("first frequency: " << lowest(still) << " rad/s at rest, " << lowest(spinning)
                           << " rad/s spinning at 10 rad/s");
  CHECK(lowest(spinning) > 1.3 * lowest(still));
}

TEST_CASE("kane stiffening: spinup_beam's tip stays bounded, spinup_beam_linear's diverges") {
  // The tip's in-plane deflection is the sum of the modal coordinates (each shape is unit at the
  // tip); Kane, Ryan and Banerjee 1987: bounded with the foreshortening terms, unbounded without.
  double tip_max[2] = {0, 0};
  double torque_at[2][2] = {{0, 0}, {0, 0}};
  for (int stiff = 0; stiff < 2; ++stiff) {
    const System s = spinup_beam(stiff == 1);
    kane::KaneEngine e(s, {});
    const RunResult r = simulate(e, s, TreeState::initial(s), IntegratorSettings::from(s.run));
    REQUIRE_FALSE(r.failure.has_value());
    const int q = r.column("beam.qy1"), tq = r.column("spin.torque");
    for (std::size_t k = 0; k < r.rows(); ++k) {
      double tip = 0;
      for (int l = 0; l < 3; ++l) tip += r.at(k, static_cast<std::size_t>(q + l));
      tip_max[stiff] = std::max(tip_max[stiff], std::abs(tip));
      const double t = r.at(k, 0);
      if (std::abs(t - 7.5) < 1e-9) torque_at[stiff][0] = r.at(k, static_cast<std::size_t>(tq));
      if (std::abs(t - 20.0) < 1e-9) torque_at[stiff][1] = r.at(k, static_cast<std::size_t>(tq));
    }
  }
  INFO("max |tip|: stiffening " << tip_max[1] << " m, linear " << tip_max[0]
                                << " m; spin.torque at 7.5 s and 20 s: stiffening "
                                << torque_at[1][0] << ", " << torque_at[1][1] << " N m; linear "
                                << torque_at[0][0] << ", " << torque_at[0][1] << " N m");
  CHECK(tip_max[1] < 1.0);
  CHECK(tip_max[0] > 1.0);
}

TEST_CASE("kane stiffening: a free hub with a spinning clamped beam conserves E and H") {
  // No prescribed motion: a free hub carrying a clamped beam bent both ways with stiffening,
  // spinning and tumbling; every term second order in eta must be exact for E and H to stay.
  std::string text =
      replaced(kSpinupBeam, {{"STIFF", "true"}, {"RATE", "1"}, {"RAMP", "1"}, {"DURATION", "4"}});
  text = replaced(text, {{"          y: {modes: 3, EI: 14000}",
                          "          y: {modes: 2, EI: 14000}\n          z: {modes: 2, EI: 9000}"},
                         {R"(  - name: spin
    type: revolute
    child: hub
    parent_point: [0, 0, 0]
    child_point: [0, 0, 0]
    axis: [0, 0, 1]
    prescribed: {profile: spin-up, rate: 1 rad/s, ramp_time: 1 s})",
                          R"(  - name: spin
    type: free
    child: hub
    initial:
      angular_velocity: [0.4, -0.3, 3.0])"}});
  const System s = read_scene_text(text, "free spinning beam (test)");
  kane::KaneEngine e(s, {});
  // Start bent and moving (eta = 0.3, eta' = 0.5 per mode) so the second-order terms matter.
  TreeState st = TreeState::initial(s);
  st.eta[1] = VectorXd::Constant(4, 0.3);
  st.eta_rate[1] = VectorXd::Constant(4, 0.5);
  const RunResult r = simulate(e, s, st, dop853(4, 0.02));
  REQUIRE_FALSE(r.failure.has_value());
  double dE = 0, dH = 0;
  const std::size_t cE = static_cast<std::size_t>(r.column("E")),
                    cH = static_cast<std::size_t>(r.column("H"));
  for (std::size_t k = 0; k < r.rows(); ++k) {
    dE = std::max(dE, std::abs(r.at(k, cE) - r.at(0, cE)) / r.at(0, cE));
    dH = std::max(dH, std::abs(r.at(k, cH) - r.at(0, cH)) / r.at(0, cH));
  }
  INFO("max |E - E0| / E0 = " << dE << ", max |H - H0| / H0 = " << dH);
  CHECK(dE <= 1e-9);
  CHECK(dH <= 1e-9);
}
