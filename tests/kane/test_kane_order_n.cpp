// The Kane engine's order-N solver (formulations/kane/kane_order_n.cpp) against its composite
// solver (mass matrix + L^T D L), both inside the Kane engine: the same Kane's equations solved two
// ways must give the same accelerations; an order-N run conserves H and E; the automatic choice.
#include <catch2/catch.hpp>

#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "core/scene/scene.hpp"
#include "formulations/kane/kane_engine.hpp"
#include "tests/kane/kane_flex_systems.hpp"
#include "tests/kane/kane_systems.hpp"
#include "tests/support/linalg.hpp"
#include "tests/support/paths.hpp"

#include <algorithm>
#include <filesystem>
#include <random>

using namespace crossdyn;
using namespace crossdyn::test::kane;
using kane::KaneEngine;
using kane::KaneSolver;

namespace {

// Every load the engine knows on a rigid tree: dampers and motors on every hinge, body torques
// in both frames (springs come with mixed_tree).
System loaded(System s) {
  for (Joint& j : s.joints) {
    if (j.type == JointType::Revolute) {
      j.damping = 0.4;
      j.motor_revolute.times = {0.0};
      j.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(0.8)};
    }
    if (j.type == JointType::Spherical) {
      j.damping = 0.3;
      j.stiffness = 2.0;
      j.motor_spherical.times = {0.0};
      j.motor_spherical.values = {Eigen::Vector3d(0.2, -0.5, 0.1)};
    }
  }
  s.bodies.front().torque.times = {0.0};
  s.bodies.front().torque.values = {Eigen::Vector3d(1.0, 2.0, -0.5)};
  s.bodies.front().torque_frame = Body::Frame::Body;
  s.bodies.back().torque.times = {0.0};
  s.bodies.back().torque.values = {Eigen::Vector3d(-0.3, 0.1, 0.6)};
  s.bodies.back().torque_frame = Body::Frame::Inertial;
  return s;
}

// A branched tree deep enough for the automatic choice to take order-N: a hub with three arms
// (revolute, spherical and mixed chains with fixed joints, offsets and asymmetric inertias).
System branched_tree() {
  using Eigen::Vector3d;
  System s;
  s.name = "branched_tree";
  s.bodies.push_back(
      rigid_body("hub", 150, turned_inertia(80, 95, 120, quat_from_axis(0.3, {1, 2, 0}))));
  s.joints.push_back(free_joint("base", 0, Vector3d(0.1, -0.3, 0.2), quat_from_axis(0.5, {0, 1, 1})));
  const JointType kinds[3][6] = {
      {JointType::Revolute, JointType::Revolute, JointType::Revolute, JointType::Revolute,
       JointType::Revolute, JointType::Revolute},
      {JointType::Spherical, JointType::Spherical, JointType::Spherical, JointType::Spherical,
       JointType::Spherical, JointType::Spherical},
      {JointType::Revolute, JointType::Fixed, JointType::Spherical, JointType::Revolute,
       JointType::Fixed, JointType::Spherical}};
  for (int arm = 0; arm < 3; ++arm) {
    int parent = 0;
    for (int k = 0; k < 6; ++k) {
      const int child = static_cast<int>(s.bodies.size());
      const std::string name = "a" + std::to_string(arm) + "_" + std::to_string(k);
      s.bodies.push_back(rigid_body(
          name, 4.0 + arm + 0.5 * k,
          turned_inertia(0.3 + 0.1 * k, 0.5 + 0.05 * arm, 0.6 + 0.07 * k,
                         quat_from_axis(0.2 + 0.3 * k, {1.0 * arm, 1, -1}))));
      const Vector3d out = k == 0 ? Vector3d(std::cos(2.1 * arm), std::sin(2.1 * arm), 0.2)
                                  : Vector3d(0.9, 0.1 * arm, -0.05 * k);
      Joint j = joint("j" + name, kinds[arm][k], parent, child, out, Vector3d(-0.7, 0.05, 0.1));
      j.axis_P = Vector3d(0.2 * k, 1.0, 0.3 * arm).normalized();
      j.q_PJ0 = quat_from_axis(0.1 * (k + arm), {1, 0, 1});
      j.rate0 = 0.2 - 0.05 * k;
      j.w_PC_C0 = Vector3d(0.1, -0.1 * arm, 0.05 * k);
      s.joints.push_back(j);
      parent = child;
    }
  }
  return s;
}

bool is_rigid(const System& s) {
  return std::none_of(s.bodies.begin(), s.bodies.end(), [](const Body& b) { return b.flex; });
}

// Every rigid test system: the committed rigid scenes, chainN (N = 2, 7, 30), trees built in
// code, each also with every load.
std::vector<System> rigid_systems() {
  std::vector<System> out;
  std::vector<std::string> files;
  for (const auto& f :
       std::filesystem::directory_iterator(crossdyn::test::source_dir() + "/scenarios"))
    if (f.path().extension() == ".yaml") files.push_back(f.path().string());
  std::sort(files.begin(), files.end());
  for (const std::string& f : files) {
    System s = read_scene(f);
    // The order-N solver declines prescribed joints (composite only): not its systems.
    const bool prescribed = std::any_of(s.joints.begin(), s.joints.end(),
                                        [](const Joint& j) { return j.prescribed.has_value(); });
    if (is_rigid(s) && !prescribed) out.push_back(std::move(s));
  }
  REQUIRE(out.size() >= 5);
  for (const System& s : {chain(2), chain(7), chain(30), mixed_tree(), branched_tree()}) {
    out.push_back(s);
    out.push_back(loaded(s));
    out.back().name += "_loaded";
  }
  return out;
}

double max_abs(const std::vector<double>& v, std::size_t from) {
  double m = 0;
  for (std::size_t i = from; i < v.size(); ++i) m = std::max(m, std::abs(v[i]));
  return m;
}

}  // namespace

TEST_CASE("kane order-N: u' solves Kane's equations M u' = f and equals the composite solver's") {
  // At random states of every rigid system: both solvers' u' satisfy M u' = f (M, f of the
  // composite sums) to a relative residual of 1e-12 (backward error), and they agree to 1e-12
  // relative where M is well conditioned; the slender-link chains' M (axial inertia 0.1 against
  // 3.4 and 10 kg at 1 m) is ill conditioned, so there the agreement bound is the forward error
  // the two backward errors allow, 10 kappa_2(M) (res_c + res_o) (Higham, Accuracy and Stability
  // of Numerical Algorithms, 2nd ed., 2002, Sec. 7.1).
  std::mt19937 g(20261123);
  for (const System& s : rigid_systems()) {
    KaneEngine composite(s, {}, KaneSolver::Composite), order_n(s, {}, KaneSolver::OrderN);
    REQUIRE(composite.solver() == KaneSolver::Composite);
    REQUIRE(order_n.solver() == KaneSolver::OrderN);
    const std::size_t nq = static_cast<std::size_t>(composite.position_size());
    const Eigen::Index nu = composite.speed_size();
    for (int trial = 0; trial < 5; ++trial) {
      const TreeState state = random_state(s, g);
      const std::vector<double> x = packed(composite, state);
      REQUIRE(packed(order_n, state) == x);
      std::vector<double> xd_c(x.size()), xd_o(x.size());
      const double t = 0.3 * trial;
      composite.rhs(t, x.data(), xd_c.data());
      order_n.rhs(t, x.data(), xd_o.data());
      const Eigen::MatrixXd M = composite.mass_matrix(x.data());
      const Eigen::VectorXd f = composite.generalized_forces(t, x.data());
      const Eigen::Map<const Eigen::VectorXd> ud_c(xd_c.data() + nq, nu), ud_o(xd_o.data() + nq, nu);
      auto residual = [&](const Eigen::VectorXd& ud) {
        return (M * ud - f).cwiseAbs().maxCoeff() /
               (M.cwiseAbs().rowwise().sum().maxCoeff() * ud.cwiseAbs().maxCoeff() +
                f.cwiseAbs().maxCoeff());
      };
      const double res_c = residual(ud_c), res_o = residual(ud_o);
      const Eigen::VectorXd ev = test::symmetric_eigenvalues(M);
      const double kappa = ev.maxCoeff() / ev.minCoeff();
      const double scale = ud_c.cwiseAbs().maxCoeff();
      double err = 0;  // positions' rates too (the same kinematical equations)
      for (std::size_t i = 0; i < x.size(); ++i) err = std::max(err, std::abs(xd_c[i] - xd_o[i]));
      const double bound = 1e-12 + 10.0 * kappa * (res_c + res_o);
      INFO(s.name << ", trial " << trial << ": residual of M u' = f: order-N " << res_o
                  << ", composite " << res_c << "; kappa(M) = " << kappa
                  << "; max |u'_orderN - u'_composite| / max |u'| = " << err / scale
                  << " (bound " << bound << ")");
      CHECK(scale > 0);
      CHECK(res_o <= 1e-12);
      CHECK(res_c <= 1e-12);
      CHECK(err <= bound * scale);
      if (kappa < 1e3) CHECK(err <= 1e-12 * scale);
      // The engine-neutral accelerations (the acceleration pass after each solver) agree too.
      TreeAccel a_c, a_o;
      composite.accelerations(t, x.data(), a_c);
      order_n.accelerations(t, x.data(), a_o);
      double da = 0, amax = 0;
      for (std::size_t b = 0; b < a_c.a_NBo_N.size(); ++b) {
        da = std::max({da, (a_c.a_NBo_N[b] - a_o.a_NBo_N[b]).cwiseAbs().maxCoeff(),
                       (a_c.wdot_NB_B[b] - a_o.wdot_NB_B[b]).cwiseAbs().maxCoeff()});
        amax = std::max({amax, a_c.a_NBo_N[b].cwiseAbs().maxCoeff(),
                         a_c.wdot_NB_B[b].cwiseAbs().maxCoeff()});
      }
      INFO("body accelerations: max difference " << da << ", max " << amax);
      CHECK(da <= bound * amax);
    }
  }
}

TEST_CASE("kane order-N: a wrong articulated inertia is caught (the comparison can fail)") {
  // test_inertia_scale changes every inertia of one engine: the order-N accelerations must then
  // differ from the unscaled composite ones far beyond the tolerance above.
  const System s = chain(7);
  EngineOptions scaled;
  scaled.test_inertia_scale = 1.01;
  KaneEngine composite(s, {}, KaneSolver::Composite), order_n(s, scaled, KaneSolver::OrderN);
  std::mt19937 g(7);
  const std::vector<double> x = packed(composite, random_state(s, g));
  std::vector<double> xd_c(x.size()), xd_o(x.size());
  composite.rhs(0, x.data(), xd_c.data());
  order_n.rhs(0, x.data(), xd_o.data());
  const std::size_t nq = static_cast<std::size_t>(composite.position_size());
  double err = 0;
  for (std::size_t i = nq; i < x.size(); ++i) err = std::max(err, std::abs(xd_c[i] - xd_o[i]));
  CHECK(err > 1e-6 * max_abs(xd_c, nq));
}

TEST_CASE("kane order-N: H and E are conserved by order-N runs (rkf78, 1e-12)") {
  for (const System& base : {chain(30), branched_tree(), mixed_tree()}) {
    System s = base;
    s.run.duration = 5;
    s.run.output_step = 0.1;
    s.run.integrator = Integrator::Rkf78;
    s.run.rtol = 1e-12;
    s.run.atol = 1e-12;
    KaneEngine e(s, {}, KaneSolver::OrderN);
    const RunResult r = simulate(e, s, TreeState::initial(s), IntegratorSettings::from(s.run));
    INFO(s.name << (r.failure ? std::string(": ") + r.failure->what() : std::string()));
    REQUIRE_FALSE(r.failure.has_value());
    for (const char* q : {"H", "E"}) {
      const int c = r.column(q);
      REQUIRE(c >= 0);
      const double ref = r.at(0, static_cast<std::size_t>(c));
      double d = 0;
      for (std::size_t i = 0; i < r.rows(); ++i)
        d = std::max(d, std::abs(r.at(i, static_cast<std::size_t>(c)) - ref));
      INFO(q << ": max |X - X0| / |X0| = " << d / std::abs(ref));
      CHECK(std::abs(ref) > 0);
      CHECK(d <= 1e-9 * std::abs(ref));
    }
  }
}

TEST_CASE("kane: the automatic choice takes order-N from kOrderNMinDepth speeds on, rigid only") {
  // chainN has one path of 6 + 3 (N - 1) speeds.
  for (int n = 1; n <= 60; ++n) {
    const System s = chain(n);
    KaneEngine e(s, {});
    const int depth = 6 + 3 * (n - 1);
    INFO("chain" << n);
    REQUIRE(e.max_speed_depth() == depth);
    CHECK(e.solver() ==
          (depth >= KaneEngine::kOrderNMinDepth ? KaneSolver::OrderN : KaneSolver::Composite));
  }
  CHECK(KaneEngine(chain(80), {}).solver() == KaneSolver::OrderN);
  CHECK(KaneEngine(branched_tree(), {}).solver() == KaneSolver::OrderN);
  CHECK(KaneEngine(spear1_case1(), {}).solver() == KaneSolver::Composite);
  // Depth, not size: a hub with many one-joint appendages stays on the composite solver.
  System wide = spear1_case1();
  for (int i = 0; i < 30; ++i) {
    wide.bodies.push_back(rigid_body("panel" + std::to_string(i), 1, diag(0.1, 0.2, 0.3)));
    Joint j = joint("h" + std::to_string(i), JointType::Revolute, 0,
                    static_cast<int>(wide.bodies.size()) - 1, Eigen::Vector3d(1, 0.1 * i, 0),
                    Eigen::Vector3d(-0.5, 0, 0));
    wide.joints.push_back(j);
  }
  CHECK(KaneEngine(wide, {}).solver() == KaneSolver::Composite);
  // A flexible body keeps the composite solver, and forcing order-N on it is refused.
  const System flexible = flex_tree();
  CHECK(KaneEngine(flexible, {}).solver() == KaneSolver::Composite);
  CHECK_THROWS_AS(KaneEngine(flexible, {}, KaneSolver::OrderN), InputError);
  // A prescribed joint keeps the composite solver (the order-N one declines it), and forcing
  // order-N on it is refused.
  System driven = chain(60);
  driven.joints[3].type = JointType::Revolute;
  driven.joints[3].axis_P = Eigen::Vector3d::UnitY();
  driven.joints[3].prescribed = PrescribedMotion{PrescribedMotion::Profile::SpinUp, 1.0, 2.0};
  CHECK(KaneEngine(driven, {}).solver() == KaneSolver::Composite);
  CHECK_THROWS_AS(KaneEngine(driven, {}, KaneSolver::OrderN), InputError);
  // Either solver can be forced where both apply.
  CHECK(KaneEngine(chain(80), {}, KaneSolver::Composite).solver() == KaneSolver::Composite);
  CHECK(KaneEngine(spear1_case1(), {}, KaneSolver::OrderN).solver() == KaneSolver::OrderN);
}
