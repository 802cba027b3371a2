// The harness catches a wrong engine: the Kane engine with every inertia scaled by 1.001
// (EngineOptions::test_inertia_scale) compared with the correct Kane engine on SPEAR-1 case I must
// fail, on the right scene, the right quantities and at the right times:
//   - the spin rate main.wx and the deployment rates: both runs start from the same angular
//     velocities, so they agree at t = 0 and first leave the tolerance at the first output time
//     after it (0.05 s); the largest difference is where the reported time says it is;
//   - H: the wrong inertia changes H at t = 0 already, so it is over the tolerance from t = 0.
// An unscaled copy passes, so the failure is the inertia's doing and not the harness's.
#include <catch2/catch.hpp>

#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "harness/compare.hpp"
#include "tests/harness/run_program.hpp"
#include "tests/harness/synthetic.hpp"
#include "tests/support/paths.hpp"

#include <cmath>

using crossdyn::harness::Check;
using crossdyn::harness::CheckStatus;
using crossdyn::harness::CompareOptions;
using crossdyn::harness::EngineRun;
using crossdyn::harness::SceneComparison;
using crossdyn::test::find_checks;

namespace {

constexpr double kOutputStep = 0.05;  // s, spear1_case1's output step (SCENARIOS.md Scene 1)

CompareOptions kane_pair(double scale) {
  CompareOptions o;
  crossdyn::EngineOptions wrong;
  wrong.test_inertia_scale = scale;
  o.engines = {{"kane", "kane", {}}, {"kane*wrong", "kane", wrong}};
  return o;
}

const EngineRun& run_of(const SceneComparison& c, const std::string& label) {
  for (const EngineRun& r : c.runs)
    if (r.label == label) return r;
  throw std::runtime_error("no run " + label);
}

// Recomputes max |a - b| of a column and the time of its first occurrence from the runs.
std::pair<double, double> worst_from_runs(const SceneComparison& c, const std::string& column) {
  const crossdyn::RunResult& a = run_of(c, "kane*wrong").result;
  const crossdyn::RunResult& b = run_of(c, "kane").result;
  const auto col = [](const crossdyn::RunResult& r, const std::string& n) {
    return static_cast<std::size_t>(std::find(r.columns.begin(), r.columns.end(), n) - r.columns.begin());
  };
  double worst = -1, when = 0;
  for (std::size_t k = 0; k < a.rows(); ++k) {
    const double d = std::abs(a.at(k, col(a, column)) - b.at(k, col(b, column)));
    if (d > worst) {
      worst = d;
      when = a.at(k, 0);
    }
  }
  return {worst, when};
}

}  // namespace

TEST_CASE("wrong engine: inertia scaled by 1.001 fails on the right scene, quantity and time") {
  const crossdyn::System s = crossdyn::read_scene(crossdyn::test::scene_path("spear1_case1"));
  const SceneComparison c = crossdyn::harness::compare_scene(s, kane_pair(1.001));
  REQUIRE(run_of(c, "kane").state == EngineRun::State::Ok);
  REQUIRE(run_of(c, "kane*wrong").state == EngineRun::State::Ok);
  CHECK(c.scene == "spear1_case1");
  CHECK_FALSE(c.passed());

  for (const char* q : {"main.wx", "hinge1.rate", "hinge2.rate"}) {
    INFO(q);
    REQUIRE(find_checks(c, q, "kane*wrong", "kane").size() == 1);
    const Check k = find_checks(c, q, "kane*wrong", "kane")[0];
    CHECK(k.status == CheckStatus::Fail);
    CHECK(k.normalised > 100);  // far outside, not a marginal failure
    const auto [worst, when] = worst_from_runs(c, q);
    CHECK(k.error == worst);
    CHECK(k.time == when);
    CHECK(k.time > 0);
    REQUIRE(k.first_exceeded);
    CHECK(std::abs(*k.first_exceeded - kOutputStep) < 1e-12);
  }
  const Check H = find_checks(c, "H", "kane*wrong", "kane")[0];
  CHECK(H.status == CheckStatus::Fail);
  REQUIRE(H.first_exceeded);
  CHECK(*H.first_exceeded == 0.0);
  // Each engine alone still conserves its own H and E: the drift checks cannot see this error.
  CHECK(find_checks(c, "H.drift", "kane*wrong")[0].status == CheckStatus::Pass);
  CHECK(find_checks(c, "E.drift", "kane*wrong")[0].status == CheckStatus::Pass);
}

TEST_CASE("wrong engine: an unscaled copy of the engine passes every check") {
  const crossdyn::System s = crossdyn::read_scene(crossdyn::test::scene_path("spear1_case1"));
  const SceneComparison c = crossdyn::harness::compare_scene(s, kane_pair(1.0));
  CHECK(c.passed());
  CHECK(c.count(CheckStatus::Pass) == static_cast<int>(c.checks.size()));
}

TEST_CASE("wrong engine: crossdyn compare --test-inertia-scale exits 1 and names what failed") {
  const auto r = crossdyn::test::run_crossdyn(
      "compare scenarios/spear1_case1.yaml --engines kane --test-inertia-scale kane=1.001 --failures");
  INFO(r.output);
  CHECK(r.status == 1);
  CHECK(r.output.find("scene spear1_case1") != std::string::npos);
  CHECK(r.output.find("main.wx         kane*1.001 vs kane") != std::string::npos);
  CHECK(r.output.find("FAIL") != std::string::npos);
}

TEST_CASE("compare: bad input exits 2 with a message naming the problem") {
  auto r = crossdyn::test::run_crossdyn("compare scenarios/no_such_scene.yaml");
  CHECK(r.status == 2);
  CHECK(r.output.find("no_such_scene.yaml") != std::string::npos);
  r = crossdyn::test::run_crossdyn("compare scenarios/spear1_case1.yaml --engines kane,hamilton");
  CHECK(r.status == 2);
  CHECK(r.output.find("--engines: unknown engine 'hamilton'") != std::string::npos);
  r = crossdyn::test::run_crossdyn("compare scenarios/spear1_case1.yaml --engines kane --test-inertia-scale kane=big");
  CHECK(r.status == 2);
  CHECK(r.output.find("'big' is not a number") != std::string::npos);
  r = crossdyn::test::run_crossdyn("compare scenarios/spear1_case1.yaml --engines kane --integrator euler");
  CHECK(r.status == 2);
  CHECK(r.output.find("euler") != std::string::npos);
}
