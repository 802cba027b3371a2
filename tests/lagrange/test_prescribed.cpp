// Prescribed revolute joints (inside the tree and as the base) and geometric stiffening in the
// Lagrange engine (docs/prescribed-motion.md; docs/flexible-bodies.md "Geometric stiffening"):
// energy balance against the joint's work, momentum conservation, the analytic torque of a rigid
// rotor, the small-motion stiffness of a spinning clamped beam derived from the model, and the
// bounded (stiffened) versus divergent (linear) spin-up of Kane, Ryan and Banerjee's beam.
#include <catch2/catch.hpp>
#include <cmath>
#include <string>
#include <vector>

#include "core/integrate.hpp"
#include "core/scene/scene.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "tests/lagrange/run_checks.hpp"
#include "tests/support/linalg.hpp"

using namespace crossdyn;
using crossdyn::lagrange::LagrangeEngine;
using crossdyn::test::col;

namespace {

// The scan platform of issue 13: a free bus, a platform spun up by a prescribed hinge.
const char* kScan = R"(name: scan_test
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
    child_point: [-0.3, 0.1, 0]
    axis: [1, 0, 0]
    offset: {axis: [0, 1, 0], angle: 10 deg}
    prescribed: {profile: spin-up, rate: 2 rad/s, ramp_time: 5 s}
run:
  duration: 10 s
  output_step: 0.005 s
  integrator: dop853
  rtol: 1e-12
  atol: 1e-12
)";

// Kane, Ryan and Banerjee's spin-up beam (issue 13 scene spinup_beam), SLICES and STIFF replaced.
std::string spinup_beam(int slices, bool stiff, double duration, double output_step) {
  return R"(name: spinup_test
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
        slices: )" +
         std::to_string(slices) + R"(
        geometric_stiffening: )" +
         (stiff ? "true" : "false") + R"(
joints:
  - name: spin
    type: revolute
    child: hub
    parent_point: [0, 0, 0]
    child_point: [0, 0, 0]
    axis: [0, 0, 1]
    prescribed: {profile: spin-up, rate: 10 rad/s, ramp_time: 15 s}
  - name: root
    type: fixed
    parent: hub
    parent_point: [0, 0, 0]
    child: beam
    child_node: bottom
run:
  duration: )" +
         std::to_string(duration) + R"( s
  output_step: )" +
         std::to_string(output_step) + R"( s
  integrator: dop853
  rtol: 1e-12
  atol: 1e-12
)";
}

RunResult run(const System& s, const TreeState& initial, double tol = 1e-12) {
  LagrangeEngine e(s, {});
  IntegratorSettings settings = IntegratorSettings::from(s.run);
  settings.method = "dop853";
  settings.rtol = settings.atol = tol;
  return simulate(e, s, initial, settings);
}

// Energy balance of a prescribed joint: E(t) - E(0) = integral_0^t torque rate dt (run_checks.hpp).
std::pair<double, double> energy_balance(const RunResult& r, const std::string& joint) {
  return test::energy_balance(
      r, [&](std::size_t k) { return col(r, k, joint + ".torque") * col(r, k, joint + ".rate"); });
}

// Tip deflection of the spin-up beam: the sum of its modal coordinates (shapes unit at the tip).
double max_tip(const RunResult& r) {
  double m = 0;
  for (std::size_t k = 0; k < r.rows(); ++k)
    m = std::max(m, std::abs(col(r, k, "beam.qy1") + col(r, k, "beam.qy2") + col(r, k, "beam.qy3")));
  return m;
}

}  // namespace

TEST_CASE("lagrange prescribed: scan platform energy balance and constant H", "[lagrange][prescribed]") {
  const System s = read_scene_text(kScan, "scan_test");
  const RunResult r = run(s, TreeState::initial(s));
  INFO((r.failure ? r.failure->what() : "ok") << ", " << r.stats.rhs_calls << " rhs calls");
  REQUIRE_FALSE(r.failure);
  const auto [err, Wmax] = energy_balance(r, "scan");
  INFO("energy balance: max |E - E0 - W| = " << err << " J, max |W| = " << Wmax << " J");
  // The platform ends at 2 rad/s: W is a few J; a wrong sign gives an error of 2 |W|, a missing
  // term (say the platform's own inertia) of order |W|.
  CHECK(Wmax > 1.0);
  CHECK(err < 1e-9 * Wmax);
  // An internal joint: H is conserved (free bus, no external load).
  double H0 = col(r, 0, "H"), dH = 0;
  for (std::size_t k = 0; k < r.rows(); ++k) dH = std::max(dH, std::abs(col(r, k, "H") - H0));
  INFO("H drift " << dH << " of " << H0);
  CHECK(dH < 1e-10 * H0);
  // The platform's rate and angle are the profile's (angle0 = 0).
  const PrescribedMotion& p = *s.joints[1].prescribed;
  for (std::size_t k : {std::size_t{0}, r.rows() / 4, r.rows() / 2, r.rows() - 1}) {
    const double t = col(r, k, "t");
    CHECK(std::abs(col(r, k, "scan.angle") - p.angle(t)) < 1e-14 * (1 + std::abs(p.angle(t))));
    CHECK(col(r, k, "scan.rate") == p.velocity(t));
  }
  // accelerations(): the prescribed joint's theta''.
  LagrangeEngine e(s, {});
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  REQUIRE(e.state_size() == 12);  // free base: 6 + 6; the hinge is not in the state
  e.pack(TreeState::initial(s), x.data());
  TreeAccel a;
  e.accelerations(2.5, x.data(), a);
  CHECK(a.angle_ddot[1] == p.accel(2.5));
}

TEST_CASE("lagrange prescribed: rigid rotor on a prescribed base, torque = I theta''",
          "[lagrange][prescribed]") {
  // Offset: 90 deg about x, so axis_J = R_NJ0^T z = y, a principal axis through the CM (the child
  // point is the CM): torque = I_yy theta'' exactly, w_NB_B = theta' y (docs/prescribed-motion.md).
  const System s = read_scene_text(R"(name: rotor_test
bodies:
  - name: rotor
    mass: 5 kg
    inertia: [1, 2, 3]
joints:
  - name: spin
    type: revolute
    child: rotor
    parent_point: [0.3, -0.2, 0.1]
    child_point: [0, 0, 0]
    axis: [0, 0, 1]
    offset: {axis: [1, 0, 0], angle: 90 deg}
    prescribed: {profile: spin-up, rate: 3 rad/s, ramp_time: 2 s}
run:
  duration: 3 s
  output_step: 0.1 s
)",
                                   "rotor_test");
  REQUIRE_FALSE(s.base_is_free());
  LagrangeEngine e(s, {});
  REQUIRE(e.state_size() == 0);
  std::vector<double> x(1, 0.0);  // no state at all
  const PrescribedMotion& p = *s.joints[0].prescribed;
  std::vector<double> row(e.layout().size());
  for (double t : {0.0, 0.3, 1.0, 1.7, 2.0, 2.6}) {
    const double tau = e.prescribed_torques(t, x.data())[0];
    INFO("t = " << t << ": torque " << tau << ", I theta'' " << 2.0 * p.accel(t));
    CHECK(std::abs(tau - 2.0 * p.accel(t)) < 1e-13);
    e.output_row(t, x.data(), row.data());
    const auto w = static_cast<std::size_t>(e.layout().body_w(0));
    CHECK(std::abs(row[w]) < 1e-15);
    CHECK(std::abs(row[w + 1] - p.velocity(t)) < 1e-14);
    CHECK(std::abs(row[w + 2]) < 1e-15);
    CHECK(row[static_cast<std::size_t>(e.layout().joint_first(0)) + 2] == tau);
    CHECK(std::abs(row[static_cast<std::size_t>(e.layout().E())] -
                   0.5 * 2.0 * p.velocity(t) * p.velocity(t)) < 1e-13);
    TreeAccel a;
    e.accelerations(t, x.data(), a);
    CHECK((a.wdot_NB_B[0] - Eigen::Vector3d(0, p.accel(t), 0)).norm() < 1e-14);
    CHECK(a.a_NBo_N[0].norm() < 1e-14);  // the CM is on the fixed axis
  }
  // Off the CM: the rotor's CM 0.4 m from the axis adds m d^2 (parallel axes) to the torque.
  System off = s;
  off.joints[0].p_CoJ_C = Eigen::Vector3d(0.4, 0, 0);  // perpendicular to axis_J = y
  LagrangeEngine eo(off, {});
  for (double t : {0.3, 1.0, 1.7})
    CHECK(std::abs(eo.prescribed_torques(t, x.data())[0] - (2.0 + 5.0 * 0.16) * p.accel(t)) < 1e-12);
}

TEST_CASE("lagrange prescribed: spin-up beam energy balance (stiffened and linear)",
          "[lagrange][prescribed][flex]") {
  for (bool stiff : {true, false}) {
    const System s = read_scene_text(spinup_beam(20, stiff, 16.0, 0.004), "spinup_test");
    const RunResult r = run(s, TreeState::initial(s));
    INFO("stiffening " << stiff << ": " << (r.failure ? r.failure->what() : "ok") << ", "
                       << r.stats.rhs_calls << " rhs calls");
    REQUIRE_FALSE(r.failure);
    const auto [err, Wmax] = energy_balance(r, "spin");
    INFO("energy balance: max |E - E0 - W| = " << err << " J, max |W| = " << Wmax << " J");
    CHECK(Wmax > 1e3);
    CHECK(err < 1e-8 * Wmax);
    // After the ramp the hub turns at Omega_s.
    CHECK(col(r, r.rows() - 1, "spin.rate") == 10.0);
  }
}

TEST_CASE("lagrange stiffening: spinning clamped beam's small-motion stiffness K + W^2 (K_G - M_soft)",
          "[lagrange][prescribed][flex]") {
  // The model (docs/flexible-bodies.md): the beam (body frame B = hub frame) turns at the constant
  // rate W about z through the root; node i is at a_i + Phi_i eta + e_i w_i from the axis,
  // a_i = p_i - p_root, w_i = 1/2 eta^T G_i eta. In B, with P = diag(1, 1, 0),
  //   T = 1/2 sum m_i |W z x r_i + du_i/dt|^2,  V = 1/2 eta^T K eta.
  // To second order in (eta, eta'), for in-plane modes (Phi_i along y, e_i along x):
  //   the centrifugal part 1/2 W^2 sum m_i |P r_i|^2 = const + 1/2 W^2 eta^T M_soft eta
  //     + W^2 sum_i m_i (e_i . P a_i) w_i,    M_soft = sum m_i Phi_i^T P Phi_i;
  //   the Coriolis part W (z x r_i) . du_i/dt has no term linear in both (y . (z x y) = 0);
  // so the linearised equations are M_ee eta'' + (K + W^2 (K_G - M_soft)) eta = 0 with
  //   K_G = - sum_i m_i (e_i . P a_i) G_i,    M_ee = sum m_i Phi_i^T Phi_i;
  // and K_G = 0 for the linear model. Checked against the engine's eta'' by central differences.
  const double W = 10.0;
  for (bool stiff : {true, false}) {
    const System s = read_scene_text(spinup_beam(30, stiff, 20.0, 0.1), "spinup_test");
    const FlexBody& f = *s.bodies[1].flex;
    const int n = f.modes();
    const Eigen::Vector3d p_root = f.nodes[static_cast<std::size_t>(s.joints[1].child_node)].p_BoNi_B;
    Eigen::MatrixXd Mee = Eigen::MatrixXd::Zero(n, n), Msoft = Mee, KG = Mee;
    const Eigen::Matrix3d P = Eigen::Vector3d(1, 1, 0).asDiagonal();
    for (const FlexNode& nd : f.nodes) {
      Mee += nd.mass * nd.Phi_B.transpose() * nd.Phi_B;
      Msoft += nd.mass * nd.Phi_B.transpose() * P * nd.Phi_B;
      if (stiff) KG -= nd.mass * nd.e_B.dot(P * (nd.p_BoNi_B - p_root)) * nd.G;
    }
    const Eigen::MatrixXd Keff = f.K + W * W * (KG - Msoft);
    const Eigen::MatrixXd A_model = -test::ldlt_solve(Mee, Keff);

    LagrangeEngine e(s, {});
    REQUIRE(e.state_size() == 2 * n);
    const double t = 18.0;  // after the ramp: rate W, theta'' = 0
    std::vector<double> x(static_cast<std::size_t>(2 * n), 0.0);
    TreeAccel a;
    e.accelerations(t, x.data(), a);
    CHECK(a.eta_ddot[1].norm() < 1e-12);  // eta = 0 is an equilibrium
    const double h = 1e-5;
    Eigen::MatrixXd A(n, n), Bv(n, n);
    for (int k = 0; k < n; ++k) {
      for (int part : {0, 1}) {  // eta, then eta'
        const auto i = static_cast<std::size_t>(k + part * n);
        x[i] = h;
        e.accelerations(t, x.data(), a);
        const Eigen::VectorXd plus = a.eta_ddot[1];
        x[i] = -h;
        e.accelerations(t, x.data(), a);
        x[i] = 0.0;
        (part == 0 ? A : Bv).col(k) = (plus - a.eta_ddot[1]) / (2 * h);
      }
    }
    const double rel = (A - A_model).norm() / A_model.norm();
    const Eigen::VectorXd omega2_model = test::generalized_symmetric_eigenvalues(Keff, Mee);
    INFO("stiffening " << stiff << ": model omega^2 " << omega2_model.transpose()
                       << ", engine vs model " << rel);
    CHECK(rel < 1e-7);
    CHECK(Bv.norm() < 1e-8 * A.norm());  // no gyroscopic coupling in the plane
    if (stiff) {
      CHECK(omega2_model.minCoeff() > 0.0);  // stiffened: stable at W above omega_1
    } else {
      CHECK(omega2_model.minCoeff() < 0.0);  // linear model: softened through zero
    }
  }
}

TEST_CASE("lagrange stiffening: spin-up beam tip stays bounded only with stiffening",
          "[lagrange][prescribed][flex]") {
  const System on = read_scene_text(spinup_beam(50, true, 20.0, 0.05), "spinup_beam");
  const System off = read_scene_text(spinup_beam(50, false, 20.0, 0.05), "spinup_beam_linear");
  const RunResult ron = run(on, TreeState::initial(on));
  const RunResult roff = run(off, TreeState::initial(off));
  REQUIRE_FALSE(ron.failure);
  REQUIRE_FALSE(roff.failure);
  const double tip_on = max_tip(ron), tip_off = max_tip(roff);
  INFO("max |tip|: stiffened " << tip_on << " m, linear " << tip_off << " m; torque at 7.5 s "
                               << col(ron, 150, "spin.torque") << ", at 20 s "
                               << col(ron, 400, "spin.torque"));
  CHECK(tip_on < 1.0);
  CHECK(tip_off > 1.0);
  // After the ramp, the stiffened beam's torque is a small residual vibration, well below the
  // ramp's peak I theta'' (about 410 kg m^2 x 1.33 rad/s^2).
  CHECK(std::abs(col(ron, 400, "spin.torque")) < 50.0);
  CHECK(std::abs(col(ron, 150, "spin.torque") - 410.0 * 4.0 / 3.0) < 20.0);
}

TEST_CASE("lagrange stiffening: free hub with a spinning stiffened beam conserves E and H",
          "[lagrange][flex]") {
  const System s = read_scene_text(R"(name: free_spinner
bodies:
  - name: hub
    mass: 50 kg
    inertia: [8, 9, 10]
  - name: beam
    flexible:
      beam:
        length: 4 m
        axis: x
        mass_per_length: 1.5
        section: [0, 0.02 m, 0.03 m]
        bending:
          y: {modes: 2, EI: 900}
          z: {modes: 2, EI: 1500}
        boundary: clamped-bottom
        slices: 20
        geometric_stiffening: true
joints:
  - name: base
    type: free
    child: hub
    initial:
      angular_velocity: [0.2, -0.1, 3.0]
  - name: root
    type: fixed
    parent: hub
    parent_point: [0.5, 0, 0]
    child: beam
    child_node: bottom
run:
  duration: 4 s
  output_step: 0.02 s
  integrator: dop853
  rtol: 1e-12
  atol: 1e-12
)",
                                   "free_spinner");
  TreeState init = TreeState::initial(s);
  init.eta[1] = Eigen::Vector4d(0.15, -0.05, 0.1, 0.03);
  init.eta_rate[1] = Eigen::Vector4d(0.2, 0.4, -0.3, 0.1);
  const RunResult r = run(s, init);
  INFO((r.failure ? r.failure->what() : "ok") << ", " << r.stats.rhs_calls << " rhs calls");
  REQUIRE_FALSE(r.failure);
  const double E0 = col(r, 0, "E"), H0 = col(r, 0, "H");
  double dE = 0, dH = 0, amp = 0;
  for (std::size_t k = 0; k < r.rows(); ++k) {
    dE = std::max(dE, std::abs(col(r, k, "E") - E0));
    dH = std::max(dH, std::abs(col(r, k, "H") - H0));
    amp = std::max(amp, std::abs(col(r, k, "beam.qy1")));
  }
  INFO("E drift " << dE << " of " << E0 << ", H drift " << dH << " of " << H0 << ", max |qy1| " << amp);
  CHECK(amp > 0.05);  // the beam does bend (the second-order terms matter)
  CHECK(dE < 1e-10 * E0);
  CHECK(dH < 1e-10 * H0);
}
