// Issue 13 in the Newton-Euler engine: prescribed revolute joints (inside the tree and as the
// base), and geometric stiffening of clamped beams. Physics checks: the work-energy balance of
// the prescribed joint, conservation of H with a free base, the analytic torque of a rigid body
// turned about a principal axis, the small-motion frequencies of a spinning stiffened beam
// against the discrete model's own linearisation, boundedness (and the linear model's
// divergence) on the spin-up beam, and conservation of E and H with stiffening and no prescribed
// motion (the exactness of the second-order terms).
#include "formulations/newton_euler/newton_euler.hpp"

#include "core/integrate.hpp"
#include "core/scene/scene.hpp"
#include "tests/newton_euler/ne_prescribed_scenes.hpp"
#include "tests/newton_euler/ne_systems.hpp"
#include "tests/support/linalg.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

using namespace crossdyn;
using namespace crossdyn::test::ne;
using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;

namespace {

RunResult run(const System& s, const TreeState& ts, double duration, double output_step,
              const EngineOptions& o = {}, bool allow_failure = false) {
  auto e = make_newton_euler_engine(s, o);
  IntegratorSettings st;
  st.method = "dop853";
  st.rtol = st.atol = 1e-12;
  st.duration = duration;
  st.output_step = output_step;
  st.dt = 1e-3;
  RunResult r = simulate(*e, s, ts, st);
  if (r.failure && !allow_failure) FAIL(r.failure->what());
  REQUIRE(r.rows() > 1);
  return r;
}

double col(const RunResult& r, std::size_t row, const std::string& name) {
  const int i = r.column(name);
  REQUIRE(i >= 0);
  return r.at(row, static_cast<std::size_t>(i));
}

// E(t) - E(0) against the joint's work integral_0^t torque * rate dt, by Simpson's rule on pairs
// of output intervals (equal steps; error O(h^4)), compared at every second row: the largest
// difference and the final energy change.
struct Balance {
  double max_error = 0, final_dE = 0, final_work = 0;
};
Balance energy_balance(const RunResult& r, const std::string& joint) {
  Balance b;
  const double E0 = col(r, 0, "E");
  auto power = [&](std::size_t k) { return col(r, k, joint + ".torque") * col(r, k, joint + ".rate"); };
  double work = 0, dE = 0;
  for (std::size_t k = 2; k < r.rows(); k += 2) {
    const double h = 0.5 * (col(r, k, "t") - col(r, k - 2, "t"));
    work += h / 3.0 * (power(k - 2) + 4.0 * power(k - 1) + power(k));
    dE = col(r, k, "E") - E0;
    b.max_error = std::max(b.max_error, std::abs(dE - work));
  }
  b.final_dE = dE;
  b.final_work = work;
  return b;
}

// Sum of the beam's modal coordinates: the tip's in-plane deflection (shapes unit at the tip).
double max_tip(const RunResult& r) {
  double m = 0;
  for (std::size_t k = 0; k < r.rows(); ++k)
    m = std::max(m, std::abs(col(r, k, "beam.qy1") + col(r, k, "beam.qy2") + col(r, k, "beam.qy3")));
  return m;
}

}  // namespace

TEST_CASE("newton-euler prescribed joint: E(t) - E(0) is the joint's work, H is conserved",
          "[newton_euler][prescribed]") {
  const System s = read_scene_text(scan_platform_text(), "scan_platform_test");
  const RunResult r = run(s, TreeState::initial(s), 10.0, 0.002);
  const Balance b = energy_balance(r, "scan");
  INFO("max |dE - W| " << b.max_error << " J, final dE " << b.final_dE << " J");
  CHECK(b.final_dE > 5.0);                      // the spin-up does work: a real test
  CHECK(b.max_error < 1e-7 * std::abs(b.final_dE));
  // A wrong torque sign would give dE = -W: far outside the tolerance above.
  CHECK(std::abs(b.final_dE + b.final_work) > 1.0);
  // An internal joint: the total angular momentum stays as it started.
  double dH = 0;
  const double H0 = col(r, 0, "H");
  for (std::size_t k = 0; k < r.rows(); ++k) dH = std::max(dH, std::abs(col(r, k, "H") - H0));
  INFO("max |H - H0| " << dH);
  CHECK(dH < 1e-10 * H0);
  // The output angle and rate are the profile's; the bodies follow them.
  const PrescribedMotion& pm = *s.joints[1].prescribed;
  for (std::size_t k = 0; k < r.rows(); k += 250) {
    const double t = col(r, k, "t");
    CHECK(col(r, k, "scan.angle") == Approx(s.joints[1].angle0 + pm.angle(t)).margin(1e-15));
    CHECK(col(r, k, "scan.rate") == Approx(pm.velocity(t)).margin(1e-15));
    CHECK(col(r, k, "constraint.ang") < 1e-9);
    CHECK(col(r, k, "constraint.angvel") < 1e-9);
  }
}

TEST_CASE("newton-euler prescribed joint: every stabilisation holds the prescribed angle and rate",
          "[newton_euler][prescribed]") {
  const System s = read_scene_text(scan_platform_text(), "scan_platform_test");
  for (auto stab : {ConstraintStabilization::Projection, ConstraintStabilization::Baumgarte,
                    ConstraintStabilization::None}) {
    EngineOptions o;
    o.stabilization = stab;
    const RunResult r = run(s, TreeState::initial(s), 10.0, 0.1, o);
    double ang = 0, angvel = 0;
    for (std::size_t k = 0; k < r.rows(); ++k) {
      ang = std::max(ang, col(r, k, "constraint.ang"));
      angvel = std::max(angvel, col(r, k, "constraint.angvel"));
    }
    INFO("stabilisation " << static_cast<int>(stab) << ": angle error " << ang << ", rate error " << angvel);
    CHECK(ang < 1e-8);
    CHECK(angvel < 1e-8);
    CHECK(energy_balance(r, "scan").max_error < 1e-4);  // coarse rows: quadrature error only
  }
}

TEST_CASE("newton-euler prescribed base: a rigid body turned about a principal axis",
          "[newton_euler][prescribed]") {
  // torque = (I_axis + m d^2) theta'' exactly (d: the CM's distance from the axis), and
  // w_NB_B = theta' axis_J.
  for (double d : {0.0, 0.4}) {
    System s;
    s.name = "turntable";
    s.bodies.push_back(make_body("table", 3.0, Vector3d(2.0, 3.0, 5.0).asDiagonal()));
    Joint j;
    j.name = "spin";
    j.type = JointType::Revolute;
    j.parent = -1;
    j.child = 0;
    j.p_PoJ_P = Vector3d(1.0, 2.0, -0.5);                       // a point fixed in N
    j.p_CoJ_C = Vector3d(d, 0.0, 0.0);                          // the axis point from the CM
    j.axis_P = Vector3d::UnitZ();                               // in N
    j.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi / 2, Vector3d::UnitX()));
    j.angle0 = 0.3;
    j.prescribed = PrescribedMotion{PrescribedMotion::Profile::SpinUp, 2.0, 3.0};
    s.joints.push_back(j);
    s.zero_linear_momentum = false;
    const Vector3d axis_J = j.q_PJ0.conjugate() * j.axis_P;    // body +y (principal, I = 3)
    REQUIRE(axis_J.isApprox(Vector3d::UnitY(), 1e-15));
    const double I_axis = 3.0 + 3.0 * d * d;
    const RunResult r = run(s, TreeState::initial(s), 5.0, 0.05);
    const PrescribedMotion& pm = *s.joints[0].prescribed;
    double worst_torque = 0, worst_w = 0;
    for (std::size_t k = 0; k < r.rows(); ++k) {
      const double t = col(r, k, "t");
      worst_torque = std::max(worst_torque, std::abs(col(r, k, "spin.torque") - I_axis * pm.accel(t)));
      const Vector3d w(col(r, k, "table.wx"), col(r, k, "table.wy"), col(r, k, "table.wz"));
      worst_w = std::max(worst_w, (w - pm.velocity(t) * axis_J).norm());
    }
    INFO("d = " << d << ": torque error " << worst_torque << " N m, w error " << worst_w);
    CHECK(worst_torque < 1e-9);
    CHECK(worst_w < 1e-10);
    // At t = 1.5 (the middle of the ramp) theta'' = Omega_s / T * 2: a non-trivial torque.
    CHECK(I_axis * pm.accel(1.5) == Approx(I_axis * 2.0 / 3.0 * 2.0));
  }
}

TEST_CASE("newton-euler prescribed base: spin-up beam energy balance and tip deflection",
          "[newton_euler][prescribed][stiffening]") {
  const System s = read_scene_text(spinup_beam_text(true), "spinup_beam_test");
  const RunResult r = run(s, TreeState::initial(s), 20.0, 0.002);
  const Balance b = energy_balance(r, "spin");
  INFO("max |dE - W| " << b.max_error << " J of " << b.final_dE << " J");
  CHECK(b.final_dE > 1e4);
  CHECK(b.max_error < 1e-9 * b.final_dE);
  // Geometric stiffening keeps the spinning beam's tip deflection bounded...
  const double tip = max_tip(r);
  INFO("max |tip| with stiffening " << tip << " m");
  CHECK(tip < 1.0);
  CHECK(tip > 0.1);  // ...but it does bend during the spin-up
  // ...while the linear modal model diverges past the first bending frequency (3.8 rad/s).
  const System lin = read_scene_text(spinup_beam_text(false), "spinup_beam_linear_test");
  const RunResult rl = run(lin, TreeState::initial(lin), 9.0, 0.05);
  const double tip_linear = max_tip(rl);
  INFO("max |tip| without stiffening (9 s) " << tip_linear << " m");
  CHECK(tip_linear > 10.0);
}

TEST_CASE("newton-euler geometric stiffening: small-motion frequencies of a spinning clamped beam",
          "[newton_euler][stiffening]") {
  // The beam's frame turns at the constant rate W about z through the clamp (a prescribed base
  // after its ramp). With the frame's motion given, the modal Lagrangian to second order in
  // (eta, eta') (docs/flexible-bodies.md; rho_i = p_i - p_clamp, P = diag(1, 1, 0), e_i, G_i of
  // the node, u_i = Phi_i eta + e_i 1/2 eta^T G_i eta):
  //   T = 1/2 sum m_i |u_i' + W z x (rho_i + u_i)|^2
  //     = 1/2 eta'^T M_ee eta' + 1/2 W^2 eta^T (M_soft - K_G) eta + (terms without effect here:
  //       constant, or linear in eta' with constant coefficients, or gyroscopic terms that vanish
  //       for in-plane (y) shapes: Phi_i . (z x Phi_i) = 0),
  //   M_ee = sum m_i Phi_i^T Phi_i,  M_soft = sum m_i Phi_i^T P Phi_i,
  //   K_G = -sum m_i (e_i . P rho_i) G_i      (from 1/2 W^2 |P r_i|^2 with r_i's e_i w_i term),
  // so M_ee eta'' = -(K + W^2 (K_G - M_soft)) eta: the engine's d eta'' / d eta must be
  // -M_ee^{-1} (K + W^2 (K_G - M_soft)). The rotary inertias J_i of the slices do not enter
  // (w is constant).
  for (bool stiffening : {true, false}) {
    const double W = 10.0, t = 20.0;
    const System s = read_scene_text(spinup_beam_text(stiffening, W, 15.0), "spin");
    auto e = make_newton_euler_engine(s, {});
    const FlexBody& flex = *s.bodies[1].flex;
    const int n = flex.modes();
    const Vector3d p_clamp = flex.nodes[static_cast<std::size_t>(flex.node_index("bottom"))].p_BoNi_B;
    MatrixXd Mee = MatrixXd::Zero(n, n), Msoft = MatrixXd::Zero(n, n), KG = MatrixXd::Zero(n, n);
    const Eigen::Matrix3d P = Vector3d(1, 1, 0).asDiagonal();
    for (const FlexNode& node : flex.nodes) {
      Mee += node.mass * node.Phi_B.transpose() * node.Phi_B;
      Msoft += node.mass * node.Phi_B.transpose() * P * node.Phi_B;
      if (stiffening) KG -= node.mass * node.e_B.dot(P * (node.p_BoNi_B - p_clamp)) * node.G;
    }
    const MatrixXd K_eff = flex.K + W * W * (KG - Msoft);
    const MatrixXd A_model = -test::ldlt_solve(Mee, K_eff);

    // The state at time t: hub and beam turned by the profile's angle, spinning at W; eta = +-h e_k.
    const double angle = s.joints[0].prescribed->angle(t);
    REQUIRE(s.joints[0].prescribed->velocity(t) == W);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(angle, Vector3d::UnitZ()));
    std::vector<double> x(static_cast<std::size_t>(e->state_size()), 0.0);
    auto set3 = [&](const std::string& label, const Vector3d& v) {
      const int i = label_index(*e, label);
      for (int c = 0; c < 3; ++c) x[static_cast<std::size_t>(i + c)] = v(c);
    };
    auto setq = [&](const std::string& body) {
      const int i = label_index(*e, body + ".qw");
      x[static_cast<std::size_t>(i)] = q.w();
      set3(body + ".qx", q.vec());
    };
    const Vector3d p_beam = -(q * p_clamp);  // the clamp on the axis at the origin
    setq("hub");
    set3("hub.wx", W * Vector3d::UnitZ());
    setq("beam");
    set3("beam.x", p_beam);
    set3("beam.vx", (W * Vector3d::UnitZ()).cross(p_beam));
    set3("beam.wx", W * Vector3d::UnitZ());
    const int eta0 = label_index(*e, "beam.qy1");
    TreeAccel acc;
    MatrixXd A_engine(n, n);
    const double h = 1e-5;
    for (int k = 0; k < n; ++k) {
      VectorXd plus, minus;
      x[static_cast<std::size_t>(eta0 + k)] = h;
      e->accelerations(t, x.data(), acc);
      plus = acc.eta_ddot[1];
      x[static_cast<std::size_t>(eta0 + k)] = -h;
      e->accelerations(t, x.data(), acc);
      minus = acc.eta_ddot[1];
      x[static_cast<std::size_t>(eta0 + k)] = 0.0;
      A_engine.col(k) = (plus - minus) / (2 * h);
    }
    const VectorXd w2_model =
        test::eigenvalues(-A_model, /*compute_eigenvectors=*/false).real().cwiseMax(-1e300);
    INFO("stiffening " << stiffening << ": model d eta''/d eta\n" << A_model << "\nengine\n" << A_engine
                       << "\nomega^2 (model) " << w2_model.transpose());
    CHECK((A_engine - A_model).norm() < 1e-6 * A_model.norm());
    // What it means: spun at 10 rad/s, above the first bending frequency (3.8 rad/s), the linear
    // model has a negative stiffness (divergence); the stiffened one stays stable.
    if (stiffening) CHECK(w2_model.minCoeff() > 0);
    else CHECK(w2_model.minCoeff() < 0);
  }
}

TEST_CASE("newton-euler geometric stiffening: a free spinning hub and beam conserve E and H",
          "[newton_euler][stiffening]") {
  const System s = read_scene_text(free_spinning_beam_text(), "free_spinning_beam_test");
  TreeState ts = TreeState::initial(s);
  ts.eta[1] << 0.08, -0.03, 0.01, 0.05, -0.02;        // large enough for the second-order terms
  ts.eta_rate[1] << 0.2, 0.5, -0.3, -0.4, 0.1;
  const RunResult r = run(s, ts, 5.0, 0.05);
  double dE = 0, dH = 0;
  const double E0 = col(r, 0, "E"), H0 = col(r, 0, "H");
  for (std::size_t k = 0; k < r.rows(); ++k) {
    dE = std::max(dE, std::abs(col(r, k, "E") - E0));
    dH = std::max(dH, std::abs(col(r, k, "H") - H0));
  }
  INFO("E0 " << E0 << " J, max |E - E0| " << dE << "; H0 " << H0 << ", max |H - H0| " << dH);
  CHECK(dE < 1e-9 * E0);
  CHECK(dH < 1e-9 * H0);
}

TEST_CASE("newton-euler geometric stiffening: a joint at a foreshortened node (the beam's tip)",
          "[newton_euler][stiffening][prescribed]") {
  // The joint point moves with u = Phi eta + e 1/2 eta^T G eta: with a spring hinge E and H are
  // conserved; with a prescribed hinge H is conserved and E(t) - E(0) is the hinge's work.
  for (bool prescribed : {false, true}) {
    const System s = read_scene_text(beam_with_tip_text(prescribed), "beam_with_tip_test");
    TreeState ts = TreeState::initial(s);
    ts.eta[1] << 0.08, -0.03, 0.01, 0.05, -0.02;
    ts.eta_rate[1] << 0.2, 0.5, -0.3, -0.4, 0.1;
    const RunResult r = run(s, ts, 4.0, 0.0005);
    double dE = 0, dH = 0, pos = 0;
    const double E0 = col(r, 0, "E"), H0 = col(r, 0, "H");
    for (std::size_t k = 0; k < r.rows(); ++k) {
      dE = std::max(dE, std::abs(col(r, k, "E") - E0));
      dH = std::max(dH, std::abs(col(r, k, "H") - H0));
      pos = std::max(pos, col(r, k, "constraint.pos"));
    }
    INFO("prescribed " << prescribed << ": E0 " << E0 << " J, max |E - E0| " << dE << ", max |H - H0| "
                       << dH << " of " << H0 << ", joint gap " << pos << " m");
    CHECK(dH < 1e-9 * H0);
    CHECK(pos < 1e-10);
    if (!prescribed) {
      CHECK(dE < 1e-9 * E0);
    } else {
      const Balance b = energy_balance(r, "wrist");
      INFO("max |dE - W| " << b.max_error << " J, final dE " << b.final_dE << " J");
      CHECK(std::abs(b.final_dE) > 1.0);
      CHECK(b.max_error < 1e-7 * dE);
    }
  }
}
