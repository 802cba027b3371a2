// `crossdyn stability` made fast (issue 24, item 4; harness/stability.hpp, "How the work is
// done"): the runs on several threads give the same map as on one, the cheaper reference (two
// independent runs) states its own error truthfully, and a run stopped early by its pace keeps
// the class it would have earned by running to its limit.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <memory>
#include <set>
#include <string>

#include "core/engine.hpp"
#include "core/integrate.hpp"
#include "core/scene/scene.hpp"
#include "harness/engines.hpp"
#include "harness/stability.hpp"
#include "harness/study.hpp"
#include "tests/harness/run_program.hpp"
#include "tests/support/paths.hpp"

using namespace crossdyn;
using namespace crossdyn::harness;

namespace {

bool stopped_early(const StabilityCell& c) {
  return c.facts.failure.find("stopped early") != std::string::npos;
}

// Every cell's class, reason, error and counts equal (the CPU times aside): the same runs.
void require_same_map(const StabilityMap& a, const StabilityMap& b) {
  REQUIRE(a.cells.size() == b.cells.size());
  for (std::size_t i = 0; i < a.cells.size(); ++i) {
    const StabilityCell& x = a.cells[i];
    const StabilityCell& y = b.cells[i];
    CAPTURE(i, x.engine, x.integrator, x.setting_text(), x.column);
    CHECK(x.engine == y.engine);
    CHECK(x.integrator == y.integrator);
    CHECK(x.setting == y.setting);
    CHECK(x.column == y.column);
    CHECK(x.result.cls == y.result.cls);
    CHECK(x.result.why == y.result.why);
    // Bit for bit: one run, the same arithmetic on any thread (NaN for a run that failed).
    CHECK((x.history_error == y.history_error ||
           (std::isnan(x.history_error) && std::isnan(y.history_error))));
    CHECK(x.steps == y.steps);
    CHECK(x.rhs_calls == y.rhs_calls);
  }
  REQUIRE(a.columns.size() == b.columns.size());
  for (std::size_t c = 0; c < a.columns.size(); ++c) {
    CHECK(a.columns[c].reference == b.columns[c].reference);
    CHECK(a.columns[c].reference_note == b.columns[c].reference_note);
  }
  CHECK(a.notes == b.notes);
  CHECK(a.findings == b.findings);
}

}  // namespace

TEST_CASE("stability --jobs: two threads give the same map as one, cell for cell and digit for digit") {
  // hinge1's spring from soft to stiff: accurate, inaccurate and diverged rk4 cells, adaptive
  // cells, a reference per value. No wall-clock limit (timeout 0), so that nothing depends on
  // the machine's speed.
  System s = read_scene(test::scene_path("hub_two_panels"));
  s.run.duration = 2;
  const Knob k = parse_knob(s, "hinge1.stiffness");
  StabilityOptions o;
  o.integrators = {"rk4", "dopri5", "cvode-bdf"};
  o.tolerances = {1e-3, 1e-6, 1e-9};
  o.dts = {0.05, 0.0125};
  o.timeout = 0;
  o.jobs = 1;
  const StabilityMap one = stability_scene(s, k, {500, 5e4, 5e6}, o);
  o.jobs = 2;
  const StabilityMap two = stability_scene(s, k, {500, 5e4, 5e6}, o);
  require_same_map(one, two);
  // The map has more than one class, and a reference at every value.
  std::set<StabilityClass> classes;
  for (const StabilityCell& c : one.cells) classes.insert(c.result.cls);
  CHECK(classes.count(StabilityClass::Accurate) == 1);
  CHECK(classes.count(StabilityClass::Diverged) == 1);
  for (const StabilityColumn& c : one.columns) CHECK(c.reference);
}

TEST_CASE("stability --jobs: out of range is exit 2, and the sharded path takes it too") {
  for (const char* bad : {"0", "-1", "257"}) {
    CAPTURE(bad);
    const test::ProgramResult r = test::run_crossdyn(
        std::string("stability hub_two_panels --vary duration --values 1 -q --jobs ") + bad);
    CAPTURE(r.output);
    CHECK(r.status == 2);
    CHECK_THAT(r.output, Catch::Contains("--jobs"));
  }
  const test::ProgramResult r = test::run_crossdyn(
      "stability torque_free_asymmetric --vary duration --values 1,2 --engines kane --integrators "
      "dopri5 --tolerances 1e-6 -q --jobs 2");
  CAPTURE(r.output);
  CHECK(r.status == 0);
  CHECK_THAT(r.output, Catch::Contains("Findings:"));
}

TEST_CASE("stability: the reference is two independent runs at 1e-6 x the accuracy limit, and the "
          "error it states bounds its true error") {
  System s = read_scene(test::scene_path("hub_two_panels"));
  s.run.duration = 5;
  const Knob k = parse_knob(s, "hinge1.stiffness");
  StabilityOptions o;
  o.integrators = {"dopri5"};
  o.tolerances = {1e-6};
  o.tolerance = 1e-6;  // the accuracy limit: the reference runs at 1e-12
  o.jobs = 1;
  const StabilityMap m = stability_scene(s, k, {5e4}, o);
  REQUIRE(m.columns.size() == 1);
  const std::string& note = m.columns[0].reference_note;
  INFO(note);
  CHECK_THAT(note, Catch::Contains("the mean of 2 runs (kane + dop853 and newton-euler + rkf78 at "
                                   "rtol 1e-12, atol 1e-16), which agree to "));
  const bool said = std::any_of(m.notes.begin(), m.notes.end(), [](const std::string& n) {
    return n.find("the reference at each value is the mean of two independent runs") != std::string::npos;
  });
  CHECK(said);

  // The same two runs, and the tight reference of `crossdyn study` (every engine with rkf78 and
  // dop853 at rtol 1e-13, atol 1e-17): the cheap reference's true error is at most the agreement it states, and
  // well inside the limit.
  const System v = apply_knob(s, k, 5e4);
  StudyOptions cheap;
  cheap.engines = {"kane"};
  cheap.integrators = {"dopri5"};
  cheap.tolerances = {1e-6};
  cheap.reference_engines = {{"kane", "kane", {}}, {"newton-euler", "newton-euler", {}}};
  cheap.reference_integrators = {"dop853", "rkf78"};
  cheap.reference_run_limit = 2;
  cheap.reference_tolerance = kReferenceTolerancePerLimit * 1e-6;
  cheap.reference_agreement = 0.5e-6;
  const StudySetup cu = study_setup(v, cheap);
  REQUIRE(cu.reference_runs.size() == 2);
  std::vector<History> cheap_runs{study_reference_run(cu, 0), study_reference_run(cu, 1)};
  const StudyBaseline cb = study_baseline(cu, cheap_runs);
  CHECK_THAT(note, Catch::Contains("which agree to " + sci(cb.reference.agreement)));

  StudyOptions tight = cheap;
  tight.engines = {};
  tight.reference_engines = {};
  tight.reference_integrators = {"rkf78", "dopri5"};
  tight.reference_run_limit = 0;
  tight.reference_tolerance = 1e-13;
  tight.reference_agreement = 1e-9;
  const StudySetup tu = study_setup(v, tight);
  REQUIRE(tu.reference_runs.size() == 6);
  std::vector<History> tight_runs;
  for (std::size_t i = 0; i < tu.reference_runs.size(); ++i) tight_runs.push_back(study_reference_run(tu, i));
  const StudyBaseline tb = study_baseline(tu, tight_runs);
  const ErrorMetric metric(v, tb.history);
  const double true_error = metric.error(cb.history).history;
  INFO("cheap reference: agreement " << cb.reference.agreement << ", error against the tight one "
                                     << true_error << " (the tight one agrees to " << tb.reference.agreement << ")");
  CHECK(true_error <= cb.reference.agreement + tb.reference.agreement);
  CHECK(cb.reference.agreement <= kReferenceRetry * 1e-6);
}

TEST_CASE("stability: a run stopped early by its pace keeps the class it earns at its limit") {
  // A 10,000 rpm wheel: newton-euler + cvode-bdf restarts its history after every step (the
  // constraint projection), so it covers a few ms of the 5 s in 20000 steps at a steady pace.
  System s = read_scene(test::scene_path("dual_spin"));
  s.run.duration = 5;
  const Knob k = parse_knob(s, "bearing.rate");
  StabilityOptions o;
  o.engine_specs = parse_engine_variants("newton-euler,kane", "--engines");
  o.integrators = {"cvode-bdf"};
  o.tolerances = {1e-6, 1e-12};
  o.tolerance = 1e-6;
  o.max_steps = 20000;
  o.timeout = 0;  // the step limit alone: deterministic
  o.jobs = 2;
  o.give_up_factor = 0;
  const StabilityMap full = stability_scene(s, k, {1047}, o);
  o.give_up_factor = kGiveUpFactor;
  const StabilityMap early = stability_scene(s, k, {1047}, o);
  REQUIRE(full.cells.size() == early.cells.size());
  int stopped = 0;
  for (std::size_t i = 0; i < full.cells.size(); ++i) {
    const StabilityCell& a = full.cells[i];
    const StabilityCell& b = early.cells[i];
    CAPTURE(a.engine, a.integrator, a.setting_text(), a.result.why, b.result.why);
    CHECK(a.result.cls == b.result.cls);
    if (stopped_early(b)) {
      ++stopped;
      CHECK(b.result.cls == StabilityClass::TooCostly);
      CHECK_THAT(b.result.why, Catch::Contains("step limit: stopped early after") &&
                                   Catch::Contains(" x the ") && Catch::Contains("steps left"));
      CHECK(b.steps < a.steps);  // the point: fewer steps for the same class
    } else {
      CHECK(a.result.why == b.result.why);  // not stopped: the same run
      CHECK(a.steps == b.steps);
    }
  }
  CHECK(stopped >= 1);
  const bool said = std::any_of(early.notes.begin(), early.notes.end(), [](const std::string& n) {
    return n.find("was stopped early as too costly") != std::string::npos;
  });
  CHECK(said);
}

TEST_CASE("the pace prediction never stops a run that finishes within its step limit at a steady pace") {
  // kane + rk4: exactly duration / dt steps. With the limit just above them the run finishes;
  // just below, it reaches the limit, and the prediction (more than 2 x what is left) stays
  // silent, so the failure is the limit's own.
  const System s = read_scene(test::scene_path("spear1_case1"));
  IntegratorSettings st = IntegratorSettings::from(s.run);
  st.method = "rk4";
  st.dt = 1e-3;
  st.keep_rows = false;
  st.give_up_factor = kGiveUpFactor;
  const long steps = std::lround(st.duration / st.dt);
  st.max_steps = steps + 1;
  std::unique_ptr<Engine> e = make_engine("kane", s, EngineOptions{});
  RunResult r = simulate(*e, s, TreeState::initial(s), st);
  CHECK_FALSE(r.failure);
  st.max_steps = steps - 10;
  e = make_engine("kane", s, EngineOptions{});
  r = simulate(*e, s, TreeState::initial(s), st);
  REQUIRE(r.failure);
  CHECK_THAT(r.failure->what(), Catch::Contains("step limit reached"));
  // A limit of a tenth of the steps needed: at the second tenth of it (2 % of the way) the pace
  // says 98 % of the steps, 9.8 x the limit, are still to come, more than 5 x the 0.8 x left:
  // stopped early there.
  st.max_steps = steps / 10;
  e = make_engine("kane", s, EngineOptions{});
  r = simulate(*e, s, TreeState::initial(s), st);
  REQUIRE(r.failure);
  CHECK_THAT(r.failure->what(), Catch::Contains("step limit: stopped early after"));
  CHECK(r.stats.steps <= steps / 10 * 2 / 10 + 1);
}
