// The Lagrange engine integrated with crossdyn::simulate: conservation laws, symmetry, and the
// torque-free body against its closed-form solution.
#include <catch2/catch.hpp>

#include "analytic/torque_free.hpp"
#include "core/integrate.hpp"
#include "core/rotation.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "tests/lagrange/scenes.hpp"
#include "tests/support/close.hpp"

using namespace crossdyn;
using crossdyn::lagrange::LagrangeEngine;
using crossdyn::test::close;

namespace {

RunResult run(const System& s, double tol, const std::string& method = "rkf78",
              const EngineOptions& options = {}) {
  LagrangeEngine e(s, options);
  IntegratorSettings settings = IntegratorSettings::from(s.run);
  settings.method = method;
  settings.rtol = settings.atol = tol;
  return simulate(e, s, TreeState::initial(s), settings);
}

// max over rows of |c(row) - c(0)| / |c(0)|.
double relative_drift(const RunResult& r, const std::string& column) {
  const int c = r.column(column);
  REQUIRE(c >= 0);
  const double c0 = r.at(0, static_cast<std::size_t>(c));
  double d = 0;
  for (std::size_t k = 0; k < r.rows(); ++k)
    d = std::max(d, std::abs(r.at(k, static_cast<std::size_t>(c)) - c0) / std::abs(c0));
  return d;
}

}  // namespace

TEST_CASE("lagrange runs: energy and angular momentum are conserved on torque-free scenes",
          "[lagrange][run]") {
  // Springs are conservative and internal: E = T + V and H stay constant. Bound: 1e-10 relative
  // with integrator tolerances 1e-12.
  System springy = test::mixed_tree(false);
  springy.joints[1].stiffness = 3.0;
  springy.joints[2].stiffness = 2.0;
  springy.joints[2].neutral_angle = 0.2;
  springy.joints[4].stiffness = 0.5;
  springy.name = "mixed_tree_springs";
  for (const System& s : {test::spear1(), test::spear1(-5), test::spear1(-10, true), test::chain(5),
                          test::mixed_tree(false), springy}) {
    const RunResult r = run(s, 1e-12);
    INFO("scene " << s.name << ": " << (r.failure ? r.failure->what() : "ok") << ", "
                  << r.stats.steps << " steps, " << r.stats.restarts << " restarts");
    REQUIRE_FALSE(r.failure);
    REQUIRE(r.rows() ==
            static_cast<std::size_t>(std::lround(s.run.duration / s.run.output_step)) + 1);
    const double dH = relative_drift(r, "H"), dE = relative_drift(r, "E");
    INFO("H drift " << dH << ", E drift " << dE);
    CHECK(dH < 1e-10);
    CHECK(dE < 1e-10);
  }
}

TEST_CASE("lagrange runs: dampers only dissipate: H is still conserved", "[lagrange][run]") {
  System s = test::mixed_tree(false);
  s.joints[1].damping = 0.4;
  s.joints[2].damping = 0.3;
  s.joints[2].stiffness = 1.0;
  const RunResult r = run(s, 1e-12);
  REQUIRE_FALSE(r.failure);
  const int E = r.column("E");
  for (std::size_t k = 1; k < r.rows(); ++k)
    CHECK(r.at(k, static_cast<std::size_t>(E)) <= r.at(k - 1, static_cast<std::size_t>(E)) + 1e-12);
  CHECK(r.at(r.rows() - 1, static_cast<std::size_t>(E)) <
        0.99 * r.at(0, static_cast<std::size_t>(E)));
  CHECK(relative_drift(r, "H") < 1e-10);
}

TEST_CASE("lagrange runs: SPEAR-1 symmetric deployment stays symmetric", "[lagrange][run]") {
  const System s = test::spear1();
  const RunResult r = run(s, 1e-12);
  REQUIRE_FALSE(r.failure);
  const auto col = [&](const char* n) { return static_cast<std::size_t>(r.column(n)); };
  double asym = 0, off_axis = 0;
  for (std::size_t k = 0; k < r.rows(); ++k) {
    asym = std::max(asym, std::abs(r.at(k, col("hinge1.angle")) + r.at(k, col("hinge2.angle"))));
    off_axis =
        std::max({off_axis, std::abs(r.at(k, col("main.wy"))), std::abs(r.at(k, col("main.wz")))});
  }
  CHECK(asym < 1e-12);
  CHECK(off_axis < 1e-12);
  // The booms swing out and the spin slows (H = I w with a growing I).
  CHECK(r.at(r.rows() - 1, col("hinge1.angle")) > 0.5);
  CHECK(r.at(r.rows() - 1, col("main.wx")) < r.at(0, col("main.wx")));
}

TEST_CASE("lagrange runs: a torque-free asymmetric body follows the closed-form solution",
          "[lagrange][run]") {
  System s;
  s.name = "free_body";
  s.bodies = {test::make_body("B", 5, {2.0, 3.0, 4.5})};
  s.joints = {test::free_joint(0, {0.4, 1.1, -0.7})};
  s.joints[0].q_NB0 =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.6, Eigen::Vector3d(1, -2, 0.5).normalized()));
  s.run.duration = 20;
  s.run.output_step = 0.1;
  const RunResult r = run(s, 1e-12);
  REQUIRE_FALSE(r.failure);
  const analytic::TorqueFreeBody ref(s.bodies[0].I_BBo_B, s.joints[0].w_NB_B0, s.joints[0].q_NB0);
  double dw = 0, dq = 0;
  for (std::size_t k = 0; k < r.rows(); ++k) {
    const analytic::TorqueFreeState a = ref.at(r.at(k, 0));
    const Eigen::Vector3d w(r.at(k, 1), r.at(k, 2), r.at(k, 3));
    const Eigen::Quaterniond q(r.at(k, 4), r.at(k, 5), r.at(k, 6), r.at(k, 7));
    dw = std::max(dw, (w - a.w_NB_B).norm());
    dq = std::max(dq, rot::angle_between(q, a.q_NB));
  }
  INFO("max |w - w_ref| " << dw << " rad/s, max attitude error " << dq << " rad");
  CHECK(dw < 1e-9);
  CHECK(dq < 1e-9);
}
