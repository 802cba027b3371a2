// The conditioning of each engine's linear solve and the deviation of its accelerations from the
// other engines' (harness/conditioning.hpp), and what `crossdyn study --scaling` reports of them.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>

#include "core/scene/scene.hpp"
#include "harness/conditioning.hpp"
#include "harness/engines.hpp"
#include "harness/study.hpp"
#include "tests/support/paths.hpp"

using namespace crossdyn;
using namespace crossdyn::harness;

TEST_CASE("conditioning: kappa_2 of known matrices (symmetric, indefinite, general, singular)") {
  Eigen::MatrixXd D = Eigen::Vector3d(2.0, 1e-3, 0.5).asDiagonal();
  CHECK(condition_number(D) == Approx(2e3).epsilon(1e-12));
  // A KKT-like symmetric indefinite matrix: |eigenvalues| 1 and 3 (eigenvalues 1, -1, 3, -3).
  Eigen::MatrixXd K(4, 4);
  K << 0, 0, 1, 0,  //
      0, 0, 0, 3,   //
      1, 0, 0, 0,   //
      0, 3, 0, 0;
  CHECK(condition_number(K) == Approx(3.0).epsilon(1e-12));
  // Not symmetric: [[1, a], [0, 1]] has kappa = (a + sqrt(a^2 + 4))^2 / 4 (its singular values are
  // (sqrt(a^2 + 4) +- a) / 2).
  const double a = 100;
  Eigen::MatrixXd U(2, 2);
  U << 1, a, 0, 1;
  CHECK(condition_number(U) == Approx(std::pow(a + std::sqrt(a * a + 4), 2) / 4).epsilon(1e-10));
  Eigen::MatrixXd S(2, 2);
  S << 1, 2, 2, 4;
  CHECK(std::isinf(condition_number(S)));
  CHECK(std::isnan(condition_number(Eigen::MatrixXd())));
  CHECK(std::isnan(condition_number(Eigen::MatrixXd::Ones(2, 3))));
}

TEST_CASE("conditioning: the engines' accelerations agree on chain5, and a wrong one stands out") {
  const System s = read_scene(test::scene_path("chain5"));  // a tumbling chain: accelerations != 0
  const std::vector<std::string> engines{"kane", "lagrange", "newton-euler"};
  const std::vector<double> ok = acceleration_deviation(s, engines);
  REQUIRE(ok.size() == 3);
  for (double d : ok) {
    CHECK(d > 0);  // not exactly equal: independent formulations round differently
    CHECK(d <= 1e-12);
  }
  // Each engine in turn with its inertia 1 % too large: it is the one that stands out, and the
  // two that agree stay at rounding (each is closest to the other).
  for (std::size_t w = 0; w < engines.size(); ++w) {
    std::vector<EngineOptions> wrong(3);
    wrong[w].test_inertia_scale = 1.01;
    const std::vector<double> bad = acceleration_deviation(s, engines, wrong);
    CAPTURE(engines[w], bad[0], bad[1], bad[2]);
    for (std::size_t e = 0; e < engines.size(); ++e) {
      if (e == w) CHECK(bad[e] > 1e-4);
      else CHECK(bad[e] <= 1e-12);
    }
  }
  // One engine has nothing to be compared with.
  for (double d : acceleration_deviation(s, {"kane"})) CHECK(std::isnan(d));
}

TEST_CASE("conditioning: every engine gives the system it solves, and the scaling study reports it") {
  const System s = read_scene(test::scene_path("spear1_case1"));
  for (const std::string& name : engine_names()) {
    CAPTURE(name);
    std::unique_ptr<Engine> e = make_engine(name, s, {});
    std::vector<double> x(static_cast<std::size_t>(e->state_size()));
    e->pack(TreeState::initial(s), x.data());
    const SolveConditioning c = solve_conditioning(*e, 0.0, x.data());
    CHECK(c.size > 0);
    CHECK(!c.what.empty());
    CHECK(std::isfinite(c.condition));
    CHECK(c.condition >= 1);
  }
  ScalingOptions o;
  o.max_links = 4;
  o.budget = 0.001;
  o.min_batches = 1;
  const ScalingStudy st = scaling_study(o);
  REQUIRE(st.lines.size() == engine_names().size());
  for (const ScalingLine& l : st.lines) {
    CAPTURE(l.engine);
    CHECK(!l.system.empty());
    REQUIRE(l.points.size() == st.links.size());
    for (const ScalingPoint& p : l.points) {
      CAPTURE(p.links);
      CHECK(std::isfinite(p.condition));
      CHECK(p.system_size > 0);
      CHECK(p.accel_deviation <= 1e-12);  // short chains: the engines agree to rounding
    }
  }
  // The text and the CSV carry them.
  CHECK(format_scaling(st).find("kane kappa") != std::string::npos);
  CHECK(scaling_csv(st).rfind("engine,links,us_per_call,calls,exponent,condition,system_size,"
                              "accel_deviation,condition_exponent\n",
                              0) == 0);
}

// A backward-stable solve of A z = b loses at most about kappa(A) eps of z (Golub & Van Loan,
// Sec. 3.5.1); an engine whose accelerations are further from the closest other engine's than
// that (with a factor 100 for the forming of A and b) loses digits somewhere its solve's
// conditioning does not explain. On chainN, N = 2 ... 32, kappa grows to 1e8 (kane, lagrange)
// and the rule must hold for every engine.
TEST_CASE("conditioning: no engine loses more digits on chainN than its solve's conditioning explains") {
  ScalingOptions o;
  o.max_links = 32;
  o.budget = 0.0005;
  o.min_batches = 1;
  const ScalingStudy st = scaling_study(o);
  const double eps = std::numeric_limits<double>::epsilon();
  for (const ScalingLine& l : st.lines)
    for (const ScalingPoint& p : l.points) {
      CAPTURE(l.engine, p.links, p.condition, p.accel_deviation);
      REQUIRE(std::isfinite(p.condition));
      REQUIRE(std::isfinite(p.accel_deviation));
      CHECK(p.accel_deviation <= 100 * p.condition * eps);
    }
}
