// `crossdyn study`: the reference rule, the error falling at the rate of each method's order, the
// Pareto front, the exponent fit, the command line and the report folder (harness/study.hpp).
#include <catch2/catch.hpp>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "harness/engines.hpp"
#include "harness/study.hpp"
#include "core/integrate.hpp"

#include <Eigen/Geometry>
#include "tests/harness/run_program.hpp"
#include "tests/support/paths.hpp"

using namespace crossdyn;
using namespace crossdyn::harness;

namespace {

System scene(const std::string& name, double duration, double output_step) {
  System s = read_scene(test::scene_path(name));
  s.run.duration = duration;
  s.run.output_step = output_step;
  return s;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST_CASE("study: a reference the engines do not agree on is refused, with the pair and the "
          "difference") {
  const System s = scene("spear1_case1", 0.5, 0.1);
  StudyOptions o;
  o.engines = {"kane"};
  o.integrators = {"dopri5"};
  o.tolerances = {1e-6};
  o.repeat = 1;
  o.reference_integrators = {"rkf78"};
  SECTION("engines that agree make the reference") {
    o.reference_engines = {{"kane", "kane", {}}, {"lagrange", "lagrange", {}}};
    const SceneStudy st = study_scene(s, o);
    CHECK(st.reference.kind == "engines");
    CHECK(st.reference.runs.size() == 2);
    CHECK(st.reference.agreement <= 1e-11);
    REQUIRE(st.rows.size() == 1);
    CHECK(st.rows[0].ok);
    CHECK(st.rows[0].error.end > 0);
  }
  SECTION("an engine with 0.1 % more inertia is refused (exit status 1)") {
    EngineOptions wrong;
    wrong.test_inertia_scale = 1.001;
    o.reference_engines = {{"kane", "kane", {}}, {"kane*1.001", "kane", wrong}};
    try {
      study_scene(s, o);
      FAIL("the study accepted a reference the engines disagree on");
    } catch (const StudyRefused& r) {
      const std::string what = r.what();
      CHECK(r.exit_status() == kExitCheckFailed);
      CHECK(what.find("do not agree") != std::string::npos);
      CHECK(what.find("kane*1.001 + rkf78 at 1e-13 vs kane + rkf78 at 1e-13") != std::string::npos);
      CHECK(what.find("> 1.00e-05") != std::string::npos);  // only where no target could be measured
      CHECK(what.find("(largest on ") != std::string::npos);  // and on which quantity
    }
  }
}

TEST_CASE("study: a reference good to less than the targets states its error and declines the "
          "targets below ten times it, measuring the others (issue 24)") {
  const System s = scene("spear1_case1", 4, 1.0);
  StudyOptions o;
  o.engines = {"kane", "lagrange"};
  o.integrators = {"dop853"};
  o.tolerances = {1e-3, 1e-5, 1e-7};
  o.repeat = 1;
  SECTION("loose reference runs: a spread between 1e-10 and 1e-5") {
    // The reference runs themselves only good to about that (they end a step at every output
    // time: with outputs every 0.1 s they agreed to 4.8e-14 even at 1e-4).
    o.reference_tolerance = 1e-7;
    const SceneStudy st = study_scene(s, o);
    REQUIRE(st.reference.kind == "engines");
    INFO(st.reference.description);
    CHECK(st.reference.agreement > 1e-10);
    CHECK(st.reference.agreement <= 1e-5);
    // The reference from the engines studied only: kane and lagrange at rkf78 and dop853.
    CHECK(st.reference.runs.size() == 4);
    for (const std::string& r : st.reference.runs) CHECK(r.find("newton-euler") == std::string::npos);
    CHECK(st.reference.description.find("the reference is good to about") != std::string::npos);
    // End-state targets against the spread at the end, history targets against the spread over
    // the run (never less).
    CHECK(st.reference.agreement_end <= st.reference.agreement);
    CHECK(st.reference.agreement_end > 0);
    const double smallest = smallest_supported_target(st);
    CHECK(smallest == Approx(kReferenceMargin * st.reference.agreement_end));
    CHECK(smallest_supported_target(st, true) == Approx(kReferenceMargin * st.reference.agreement));
    int declined = 0, measured = 0;
    for (double t : recommendation_targets()) {
      const std::string text = recommendation(st, t);
      INFO(t << ": " << text);
      if (t < smallest) {
        ++declined;
        CHECK(text.find("not measured: the reference is good to") != std::string::npos);
        CHECK(text.find(" use ") == std::string::npos);
      } else {
        ++measured;
        CHECK(text.find("not measured") == std::string::npos);
      }
    }
    CHECK(declined >= 1);  // 1e-10 at least
    CHECK(measured >= 1);  // 1e-4 at least
    CHECK(format_study(st).find("not measured: the reference is good to") != std::string::npos);
  }
  SECTION("one engine named: the reference is that engine at two integrators") {
    o.engines = {"newton-euler"};
    const SceneStudy st = study_scene(s, o);
    REQUIRE(st.reference.runs.size() == 2);
    CHECK(st.reference.runs[0].rfind("newton-euler + ", 0) == 0);
    CHECK(st.reference.runs[1].rfind("newton-euler + ", 0) == 0);
    CHECK(st.reference.agreement <= 1e-10);  // tight reference: every target measured
    for (double t : recommendation_targets()) CHECK(recommendation(st, t).find("not measured") == std::string::npos);
  }
}

TEST_CASE("study: a row whose steps the output times set is marked, in the table and in the "
          "recommendation, but not dense methods nor rkf78 with sparse outputs (issue 24)") {
  StudyOptions o;
  o.engines = {"kane"};
  o.integrators = {"rkf78", "dop853"};
  o.tolerances = {1e-4, 1e-10};
  o.repeat = 1;
  SECTION("output every 0.05 s: rkf78 steps every output time whatever its tolerance") {
    const SceneStudy st = study_scene(scene("spear1_case1", 2, 0.05), o);
    REQUIRE(st.rows.size() == 4);
    for (const StudyRow& r : st.rows) {
      INFO(r.integrator << " " << r.setting() << ": " << r.steps << " steps");
      REQUIRE(r.ok);
      CHECK(step_set_by_output_times(st, r) == (r.integrator == "rkf78"));
    }
    // rkf78 at rtol 1e-4 reaches the error of rtol 1e-10: the output step, not the tolerance.
    const std::string table = format_study(st);
    CHECK(table.find("rtol 1e-04*") != std::string::npos);
    CHECK(table.find("* step set by the output times") != std::string::npos);
    bool said = false;
    for (double t : recommendation_targets()) {
      const auto best = cheapest_within(st, t);
      if (best && st.rows[*best].integrator == "rkf78") {
        said = true;
        CHECK(recommendation(st, t).find("its step was set by the output step (0.05 s)") != std::string::npos);
      }
    }
    CHECK((said || table.find("set by the output step") == std::string::npos));
  }
  SECTION("one output interval: rkf78 takes the steps its tolerance allows") {
    const SceneStudy st = study_scene(scene("spear1_case1", 2, 2), o);
    for (const StudyRow& r : st.rows) {
      INFO(r.integrator << " " << r.setting() << ": " << r.steps << " steps");
      CHECK_FALSE(step_set_by_output_times(st, r));
    }
    CHECK(format_study(st).find("* step set by the output times") == std::string::npos);
  }
  SECTION("rk4: a step above the output step is the output step") {
    o.integrators = {"rk4"};
    o.dts = {0.1, 0.025};
    const SceneStudy st = study_scene(scene("spear1_case1", 1, 0.05), o);
    REQUIRE(st.rows.size() == 2);
    CHECK(step_set_by_output_times(st, st.rows[0]));        // dt 0.1 > 0.05
    CHECK_FALSE(step_set_by_output_times(st, st.rows[1]));  // dt 0.025
  }
}

TEST_CASE("study: an rk4 run with a shorter step than one past the step limit is not made, and "
          "says why, while adaptive methods are always run (issue 24)") {
  StudyOptions o;
  o.engines = {"kane"};
  o.repeat = 1;
  o.max_steps = 150;
  o.reference_max_steps = 10000000;  // the limit is the configurations' only
  SECTION("rk4, given out of order: shorter than a failed step is not run, longer is") {
    o.integrators = {"rk4"};
    o.dts = {0.01, 0.05, 0.002};  // 200 (over the limit), 40, 1000 steps over 2 s
    const SceneStudy st = study_scene(scene("spear1_case1", 2, 0.05), o);
    REQUIRE(st.rows.size() == 3);
    INFO(st.rows[0].failure << " | " << st.rows[1].failure << " | " << st.rows[2].failure);
    CHECK_FALSE(st.rows[0].ok);
    CHECK(st.rows[0].failure.find("step limit") != std::string::npos);
    CHECK(st.rows[0].steps > 0);  // it ran
    CHECK(st.rows[1].ok);         // longer than the failed step: run
    CHECK_FALSE(st.rows[2].ok);
    CHECK(st.rows[2].failure.rfind("not run: dt 0.01 already failed (", 0) == 0);
    CHECK(st.rows[2].failure.find("a shorter step takes more steps") != std::string::npos);
    CHECK(st.rows[2].steps == 0);  // it did not run
  }
  SECTION("an adaptive method is run at every tolerance, even after a looser one failed") {
    o.integrators = {"dop853"};
    o.tolerances = {1e-4, 1e-10, 1e-12};
    o.max_steps = 5;  // dop853 takes 3 steps at 1e-4, 10 at 1e-10, 16 at 1e-12 (spear1_case1, 2 s)
    const SceneStudy st = study_scene(scene("spear1_case1", 2, 0.05), o);
    REQUIRE(st.rows.size() == 3);
    CHECK(st.rows[0].ok);
    for (std::size_t i : {1, 2}) {
      INFO(st.rows[i].failure);
      CHECK(st.rows[i].failure.find("step limit") != std::string::npos);
      CHECK(st.rows[i].failure.find("not run") == std::string::npos);
      CHECK(st.rows[i].steps > 0);
    }
  }
}

TEST_CASE("study: --duration and --output-step override every scene's run block, reference too, and "
          "are checked like run's") {
  const test::ProgramResult r = test::run_crossdyn(
      "study spear1_case1 -q --engines kane --integrators dop853 --tolerances 1e-6 --repeat 1 "
      "--duration 0.7 --output-step 0.35");
  INFO(r.output);
  CHECK(r.status == 0);
  CHECK(r.output.find("0.7 s, output every 0.35 s") != std::string::npos);
  const test::ProgramResult bad = test::run_crossdyn("study spear1_case1 -q --duration -1");
  INFO(bad.output);
  CHECK(bad.status == 2);
  CHECK(bad.output.find("--duration") != std::string::npos);
  const test::ProgramResult coarse = test::run_crossdyn("study spear1_case1 -q --duration 1 --output-step 2");
  INFO(coarse.output);
  CHECK(coarse.status == 2);
  CHECK(coarse.output.find("--output-step") != std::string::npos);
}

TEST_CASE("study: on the analytic torque-free scenes rk4's error falls 16-fold when its step "
          "halves (order 4)") {
  for (const char* name : {"torque_free_asymmetric", "torque_free_axisymmetric"}) {
    CAPTURE(name);
    const System s = scene(name, 10, 0.5);
    StudyOptions o;
    o.engines = {"kane", "newton-euler"};
    o.integrators = {"rk4"};
    o.dts = {0.1, 0.05, 0.025};
    o.repeat = 1;
    const SceneStudy st = study_scene(s, o);
    CHECK(st.reference.kind == "analytic");
    REQUIRE(st.rows.size() == 6);
    for (std::size_t k = 0; k < st.rows.size(); ++k) REQUIRE(st.rows[k].ok);
    for (std::size_t e = 0; e < 2; ++e)
      for (std::size_t k = 0; k + 1 < 3; ++k) {
        const StudyRow& a = st.rows[3 * e + k];
        const StudyRow& b = st.rows[3 * e + k + 1];
        CAPTURE(a.engine, a.dt, a.error.history, b.error.history);
        CHECK(b.dt == Approx(a.dt / 2));
        const double ratio = a.error.history / b.error.history;
        CHECK(ratio > 12);
        CHECK(ratio < 21);
        CHECK(b.rhs_calls == Approx(2.0 * static_cast<double>(a.rhs_calls)).epsilon(0.01));
      }
  }
}

TEST_CASE("study: an adaptive method's error falls with its tolerance, decade by decade") {
  // dopri5 (dense output: its steps are not cut at the output times). rkf78 and bulirsch-stoer
  // step to every output time today, so at loose tolerances their error is that of one step per
  // output interval, whatever the tolerance (issue 12 item 3; the study shows it).
  const System s = scene("torque_free_asymmetric", 20, 0.5);
  StudyOptions o;
  o.engines = {"kane"};
  o.integrators = {"dopri5"};
  o.tolerances = parse_values("1e-5..1e-10", "--tolerances", true);
  o.repeat = 1;
  const SceneStudy st = study_scene(s, o);
  REQUIRE(st.rows.size() == 6);
  for (std::size_t k = 0; k < 6; ++k) {
    const StudyRow& r = st.rows[k];
    CAPTURE(r.integrator, r.tolerance, r.error.end, r.error.history);
    REQUIRE(r.ok);
    // Roughly tracks the tolerance: within three decades of it either way.
    CHECK(r.error.history < 1e3 * r.tolerance);
    CHECK(r.error.history > 1e-3 * r.tolerance);
    if (k > 0) {
      CHECK(r.error.history < st.rows[k - 1].error.history);
      CHECK(r.rhs_calls > st.rows[k - 1].rhs_calls);
    }
  }
  // Over five decades of tolerance the error falls by at least three decades.
  CHECK(st.rows[0].error.history / st.rows[5].error.history > 1e3);
}

TEST_CASE("study: the error metric") {
  System s = read_scene(test::scene_path("torque_free_asymmetric"));  // I = diag(100, 200, 300)
  // Columns t, body.wx wy wz, body.qw qx qy qz, H, E. w = (3, 0, 4): |w| = 5, H = |I w| = 1236.9,
  // E = (100 * 9 + 300 * 16) / 2 = 2850. The scales: w 5; H max(1236.9, I_b |w|) = 1500 and E
  // max(2850, I_b |w|^2 / 2) = 3750, with I_b = trace(I) / 2 = 300 (study.hpp).
  History ref, run;
  ref.columns = run.columns = 10;
  const double angle = 1e-3;
  ref.data = {0, 3, 0, 4, 1, 0, 0, 0, 1236.9, 2850,   //
              1, 3, 0, 4, 1, 0, 0, 0, 1236.9, 2850};
  run.data = {0, 3, 0, 4, 1, 0, 0, 0, 1236.9, 2850,   //
              1, 3, 0.05, 4, std::cos(angle / 2), std::sin(angle / 2), 0, 0, 1236.9, 2850 + 37.5};
  const ErrorMetric m(s, ref);
  CHECK(m.scale("body.wy") == Approx(5));
  CHECK(m.scale("H") == Approx(1500));
  CHECK(m.scale("E") == Approx(3750));
  CHECK(m.scale("body.attitude") == Approx(5));  // it turned 5 rad: |w| = 5 rad/s for 1 s
  CHECK(std::isnan(m.scale("nothing")));
  const StudyError e = m.error(run);
  // w: 0.05 / |w| = 0.05 / 5; E: 37.5 / 3750; attitude: 1e-3 rad / 5 rad.
  CHECK(e.end == Approx(0.01));
  CHECK(e.history == Approx(0.01));
  CHECK((e.end_quantity == "body.wy" || e.end_quantity == "E"));
  run.data[12] = 0;              // wy as the reference's
  run.data[19] = 2850 - 187.5;   // E off by 5 % of its scale at the end
  CHECK(m.error(run).end == Approx(0.05));
  CHECK(m.error(run).end_quantity == "E");
  run.data[19] = 2850;  // E back: the attitude's 1e-3 rad of 5 rad is the largest
  CHECK(m.error(run).end == Approx(angle / 5));
  CHECK(m.error(run).end_quantity == "body.attitude");
  CHECK(m.error(ref).history == 0);
}

TEST_CASE("study: an angle is judged against how far it turned, at least 1 rad: a fast rotor by "
          "its travel, a slow body absolutely (issue 24)") {
  System s = read_scene(test::scene_path("torque_free_asymmetric"));
  History ref, run;
  ref.columns = run.columns = 10;
  const double angle = 1e-6;
  const Eigen::Quaterniond off(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()));
  for (const double w : {0.3, 200.0}) {  // |w| of the body along x, rad/s, for 2 s
    ref.data = {0, w, 0, 0, 1, 0, 0, 0, 1, 1,  //
                1, w, 0, 0, 1, 0, 0, 0, 1, 1,  //
                2, w, 0, 0, 1, 0, 0, 0, 1, 1};
    run.data = ref.data;
    run.data[24] = off.w();
    run.data[27] = off.z();
    const ErrorMetric m(s, ref);
    INFO("|w| = " << w);
    const double travel = 2 * w;  // the integral of |w| over 2 s
    CHECK(m.scale("body.attitude") == Approx(std::max(1.0, travel)));
    CHECK(m.error(run).end == Approx(angle / std::max(1.0, travel)));
    CHECK(m.error(run).end_quantity == "body.attitude");
  }
  // A joint angle: its largest distance from where it started. dual_spin's rotor at 1000 rpm
  // (104.7 rad/s) for 1 s turns 104.7 rad; the platform's w is about 0.02 rad/s.
  System d = read_scene(test::scene_path("dual_spin"));
  d.run.duration = 1;
  d.run.output_step = 0.05;
  {
    auto e = make_engine("kane", d, {});
    IntegratorSettings is;
    is.method = "dop853";
    is.rtol = is.atol = 1e-10;
    is.duration = d.run.duration;
    is.output_step = d.run.output_step;
    const History h = pinned_history(d, simulate(*e, d, TreeState::initial(d), is));
    const ErrorMetric m(d, h);
    CHECK(m.scale("bearing.angle") == Approx(1000 * 2 * M_PI / 60).epsilon(1e-3));
    CHECK(m.scale("rotor.attitude") == Approx(1000 * 2 * M_PI / 60).epsilon(1e-2));
    CHECK(m.scale("platform.attitude") == 1);
  }
}

TEST_CASE("study: a quantity that is zero in the physics is judged against the motion's scale, "
          "not its rounding noise (H of a scene at zero momentum, issue 24)") {
  System s = read_scene(test::scene_path("torque_free_asymmetric"));
  History ref, run;
  ref.columns = run.columns = 10;
  // H at rounding level (the motion is a counter-rotation elsewhere): 3e-13 and 9e-13 N m s.
  ref.data = {0, 3, 0, 4, 1, 0, 0, 0, 3e-13, 2850, 1, 3, 0, 4, 1, 0, 0, 0, 2e-13, 2850};
  run.data = {0, 3, 0, 4, 1, 0, 0, 0, 3e-13, 2850, 1, 3, 0, 4, 1, 0, 0, 0, 9e-13, 2850};
  const ErrorMetric m(s, ref);
  CHECK(m.scale("H") == Approx(1500));
  CHECK(m.error(run).history == Approx(7e-13 / 1500));
  // The committed scene with zero angular momentum is studied (was refused: its reference runs
  // "differ by 7.3e-01, largest on H", noise over noise).
  System flex = read_scene(test::scene_path("pointing_flex"));
  flex.run.duration = 5;
  StudyOptions o;
  o.engines = {"kane"};
  o.integrators = {"dop853"};
  o.tolerances = {1e-6};
  o.repeat = 1;
  const SceneStudy st = study_scene(flex, o);
  CHECK(st.reference.agreement < 1e-9);
  REQUIRE(st.rows.size() == 1);
  CHECK(st.rows[0].error.history < 1e-3);
}

TEST_CASE("study: the Pareto front of hand-made points") {
  // (cost, error): a is fastest; b is slower but more accurate; c is dominated by b; d is the most
  // accurate; e ties b's cost with a larger error; f failed (NaN); g equals a (neither dominates).
  const std::vector<double> cost{1, 2, 3, 5, 2, std::nan(""), 1};
  const std::vector<double> error{1e-3, 1e-6, 1e-5, 1e-9, 1e-4, 1e-12, 1e-3};
  const std::vector<bool> f = pareto_front(cost, error);
  CHECK(f == std::vector<bool>{true, true, false, true, false, false, true});
  // Errors below the floor are equal: the slower of two "exact" points is not on the front.
  CHECK(pareto_front({1, 2}, {0, 1e-18}) == std::vector<bool>{true, false});

  SceneStudy st;
  st.scene = "hand";
  for (std::size_t i = 0; i < 5; ++i) {
    StudyRow r;
    r.engine = "e" + std::to_string(i);
    r.integrator = "dopri5";
    r.tolerance = 1e-6;
    r.ok = true;
    r.cpu_median = cost[i] * 1e-3;
    r.error.end = r.error.history = error[i];
    st.rows.push_back(r);
  }
  mark_fronts(st);
  CHECK(st.rows[0].front_end);
  CHECK_FALSE(st.rows[2].front_end);
  REQUIRE(cheapest_within(st, 1e-5));
  CHECK(*cheapest_within(st, 1e-5) == 1);
  CHECK(*cheapest_within(st, 1e-8) == 3);
  CHECK_FALSE(cheapest_within(st, 1e-10));
  CHECK(recommendation(st, 1e-8) ==
        "for 1e-08 end-state error on hand use e3 + dopri5 at rtol 1e-06: 5 ms of integration CPU "
        "(end-state error 1.0e-09, 0 right-hand sides)");
  CHECK(recommendation(st, 1e-10).find("no configuration reached") == 0);
  CHECK(recommendation(st, 1e-10).find("(the smallest: 1.0e-09 with e3 + dopri5") != std::string::npos);
  // Class 11 (issue 23): a recommendation says what happened: when every run failed, not a
  // "smallest error" that no run has.
  for (StudyRow& r : st.rows) {
    r.ok = false;
    r.failure = "timed out after 1 s";
  }
  CHECK(recommendation(st, 1e-8) ==
        "no configuration reached 1e-08 end-state error on hand (no configuration ran to the end)");
}

TEST_CASE("study: the fitted exponent uses the upper half of N") {
  std::vector<double> n, y;
  for (int k : scaling_links(128)) {
    n.push_back(k);
    // N^2.5 above N = 12, a constant overhead below (the lower half does not count).
    y.push_back(k >= 16 ? 3e-7 * std::pow(k, 2.5) : 1.0);
  }
  CHECK(scaling_links(128).front() == 2);
  CHECK(scaling_links(128).back() == 128);
  CHECK(scaling_links(128).size() == 13);
  CHECK(fit_exponent(n, y) == Approx(2.5).epsilon(1e-9));
  CHECK(std::isnan(fit_exponent({4}, {1})));
  // The chainN text reads to N bodies and N joints.
  const System c = read_scene_text(chain_scene_text(7), "chain7");
  CHECK(c.bodies.size() == 7);
  CHECK(c.joints.size() == 7);
}

TEST_CASE("study: --tolerances ranges and lists") {
  CHECK(parse_values("1e-4..1e-13", "--tolerances", true).size() == 10);
  CHECK(parse_values("1e-4..1e-13", "--tolerances", true)[9] == Approx(1e-13));
  // Every value of a range is the double its decimal spelling names, so it prints as written.
  CHECK(parse_values("1e-4..1e-13", "--tolerances", true) ==
        std::vector<double>{1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13});
  CHECK(parse_values("2e-3..2e-7", "--tolerances", true) ==
        std::vector<double>{2e-3, 2e-4, 2e-5, 2e-6, 2e-7});
  CHECK(parse_values("1e-8..1e-6", "--tolerances", true) == std::vector<double>{1e-8, 1e-7, 1e-6});
  CHECK(parse_values("0.1,0.05", "--dts", false) == std::vector<double>{0.1, 0.05});
  CHECK_THROWS_WITH(parse_values("1e-4..3e-9", "--tolerances", true), Catch::Contains("one value per decade"));
  CHECK_THROWS_WITH(parse_values("1e-4,-1", "--tolerances", true), Catch::Contains("positive"));
  CHECK_THROWS_WITH(parse_values("abc", "--dts", false), Catch::Contains("'abc' is not a number"));
  CHECK_THROWS_WITH(parse_values("0.1..0.01", "--dts", false), Catch::Contains("not a range"));
}

TEST_CASE("study: bad arguments exit 2 with a clear message") {
  const struct {
    const char* args;
    const char* message;
  } cases[] = {
      {"study", "give at least one scene, or --scaling"},
      {"study torque_free_asymmetric --integrators rk45", "--integrators: unknown integrator 'rk45'"},
      {"study torque_free_asymmetric --engines kane,foo", "--engines: unknown engine 'foo'"},
      {"study torque_free_asymmetric --tolerances 1e-4..2e-9", "one value per decade"},
      {"study torque_free_asymmetric --repeat 0", "--repeat: must be from 1 to 1000"},
      {"study no_such_scene_here", "no_such_scene_here"},
      {"study --scaling --max-links 1", "--max-links: must be from 2 to 1024"},
  };
  for (const auto& c : cases) {
    CAPTURE(c.args);
    const test::ProgramResult r = test::run_crossdyn(std::string(c.args) + " -q");
    CAPTURE(r.output);
    CHECK(r.status == 2);
    CHECK(r.output.find(c.message) != std::string::npos);
  }
}

TEST_CASE("study: a tiny study writes its table, CSV and report (pages, PNG, CSV, links)") {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("crossdyn_study_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string csv = (dir / "all.csv").string();
  const std::string report = (dir / "report").string();
  const test::ProgramResult r = test::run_crossdyn(
      "study torque_free_axisymmetric --engines kane --integrators dopri5,rk4 --tolerances "
      "1e-4..1e-6 --dts 0.5,0.25 --repeat 1 -q --csv '" + csv + "' --report '" + report +
      "' --scaling --max-links 3 --budget 0.002");
  CAPTURE(r.output);
  REQUIRE(r.status == 0);
  CHECK(r.output.find("for 1e-04 end-state error on torque_free_axisymmetric use kane + ") !=
        std::string::npos);
  std::istringstream lines(r.output);
  for (std::string line; std::getline(lines, line);) {
    CAPTURE(line);
    CHECK(line.size() <= 100);
  }
  const std::string table = slurp(csv);
  CHECK(table.rfind(study_csv_header(), 0) == 0);
  CHECK(std::count(table.begin(), table.end(), '\n') == 1 + 5);
  for (const char* f : {"index.html", "torque_free_axisymmetric-study.html", "torque_free_axisymmetric-study.png",
                        "torque_free_axisymmetric-study.csv", "scaling.html", "scaling.png", "scaling.csv",
                        "conditioning.png", "study.json"}) {
    CAPTURE(f);
    CHECK(fs::is_regular_file(fs::path(report) / f));
  }
  const std::string index = slurp(report + "/index.html");
  CHECK(index.find("href=\"torque_free_axisymmetric-study.html\"") != std::string::npos);
  CHECK(index.find("href=\"scaling.html\"") != std::string::npos);
  const std::string page = slurp(report + "/torque_free_axisymmetric-study.html");
  CHECK(page.find("src=\"torque_free_axisymmetric-study.png\"") != std::string::npos);
  CHECK(page.find("href=\"torque_free_axisymmetric-study.csv\"") != std::string::npos);
  const std::string scaling = slurp(report + "/scaling.html");
  CHECK(scaling.find("src=\"conditioning.png\"") != std::string::npos);
  CHECK(scaling.find("<b>kane</b> solves Kane") != std::string::npos);
  // A second study may replace the report; a folder of other files is refused (exit 2).
  CHECK(test::run_crossdyn("study torque_free_axisymmetric --engines kane --integrators dopri5 "
                           "--tolerances 1e-4 --repeat 1 -q --report '" + report + "'").status == 0);
  const test::ProgramResult other = test::run_crossdyn(
      "study torque_free_axisymmetric --engines kane --integrators dopri5 --tolerances 1e-4 "
      "--repeat 1 -q --report '" + dir.string() + "'");
  CHECK(other.status == 2);
  CHECK(other.output.find("neither empty nor a crossdyn study report") != std::string::npos);
  fs::remove_all(dir);
}

TEST_CASE("the accuracy asked has one name in study and stability: study --accuracy sets the "
          "recommendations, stability --accuracy the accurate class, neither the compare "
          "tolerances (issue 24)") {
  // study: a recommendation for each accuracy asked, and only for those; said in the header.
  auto r = test::run_crossdyn("study spear1_case1 --engines kane --integrators dop853 "
                              "--tolerances 1e-4..1e-9 --repeat 1 --accuracy 1e-3,1e-5 -q");
  CHECK(r.status == 0);
  CHECK_THAT(r.output, Catch::Contains("accuracy asked (--accuracy): 1e-03, 1e-05") &&
                           Catch::Contains("compare tolerances are not used here") &&
                           Catch::Contains("for 1e-03 end-state error") &&
                           Catch::Contains("for 1e-05 end-state error") &&
                           !Catch::Contains("for 1e-04 end-state error") &&
                           !Catch::Contains("1e-10 end-state error"));
  // In process: the targets are the study's, and a row recommended is within its target.
  System s = read_scene(test::scene_path("spear1_case1"));
  StudyOptions o;
  o.engines = {"kane"};
  o.integrators = {"dop853"};
  o.tolerances = {1e-4, 1e-6, 1e-8};
  o.repeat = 1;
  o.targets = {1e-2, 1e-7};
  const SceneStudy st = study_scene(s, o);
  CHECK(st.targets == o.targets);
  for (double t : st.targets) {
    const auto best = cheapest_within(st, t);
    REQUIRE(best);
    CHECK(st.rows[*best].error.end <= t);
  }
  for (const char* bad : {"0", "1", "2", "-1e-3", "nan", "1e-3,1e-3"}) {
    r = test::run_crossdyn(std::string("study spear1_case1 --engines kane -q --accuracy ") + bad);
    INFO(bad << ": " << r.output);
    CHECK(r.status == 2);
    CHECK_THAT(r.output, Catch::Contains("--accuracy"));
  }

  // stability: the accurate class's limit is --accuracy (default 1e-6), whatever the scene's
  // compare block says: the same cells are accurate at 1e-6 and not at 1e-12.
  const std::string map = "stability spear1_case1 --vary duration --values 1 --engines kane "
                          "--integrators dop853 --tolerances 1e-3,1e-6,1e-9 -q";
  r = test::run_crossdyn(map);
  CHECK(r.status == 0);
  CHECK_THAT(r.output, Catch::Contains("accurate: history error <= 1.0e-06 (--accuracy") &&
                           Catch::Contains("not the scene's compare tolerances"));
  r = test::run_crossdyn(map + " --accuracy 1e-12");
  CHECK(r.status == 0);
  CHECK_THAT(r.output, Catch::Contains("accurate: history error <= 1.0e-12 (--accuracy") &&
                           !Catch::Contains("accurate up to"));
  for (const char* bad : {"0", "1", "-1", "nan"}) {
    r = test::run_crossdyn(map + " --accuracy " + bad);
    INFO(bad << ": " << r.output);
    CHECK(r.status == 2);
    CHECK_THAT(r.output, Catch::Contains("--accuracy"));
  }
}

// Issue 28 (a user's rig under gravity): a conserved E that starts at zero (kinetic + a potential
// zero at the start) and a held base's drive torque that is zero but for rounding were judged
// against their own noise (study found "no reference" on iftomm_pendulum: 1.55 relative on
// frame.torque, then 1.2e-6 on E). Their scales now include the bodies' CM motion (E) and the
// joints' loads (torque).
TEST_CASE("study: a pendulum's E and its held base's torque are judged against the scene's own "
          "energy and loads, not their rounding") {
  const System s = read_scene(test::scene_path("iftomm_pendulum"));
  auto e = make_engine("kane", s);
  IntegratorSettings set = IntegratorSettings::from(s.run);
  const RunResult r = simulate(*e, s, TreeState::initial(s), set);
  REQUIRE_FALSE(r.failure);
  const History h = pinned_history(s, r);
  const ErrorMetric m(s, h);
  // The bob's largest kinetic energy is m g L = 9.81 J (at the bottom); its largest speed is
  // sampled every 10 ms, so a little less. The weight's moment about the hinge: m g L = 9.81 N m.
  CHECK(m.scale("E") > 0.99 * 9.81);
  CHECK(m.scale("E") < 1.01 * 9.81);
  CHECK(m.scale("frame.torque") >= 9.81 * (1 - 1e-9));
  // And a study of it finds its reference (the engines agree to 1e-10 and better).
  StudyOptions o;
  o.engines = {"kane"};
  o.integrators = {"dop853"};
  o.targets = {1e-6};
  const SceneStudy st = study_scene(s, o);
  CHECK(st.reference.agreement < 1e-8);
}

// On an orbit E changes with the turning gravity-gradient potential; the drift a study row reports
// (and stability's drift class reads) is the Jacobi integral's, which the orbit conserves.
TEST_CASE("study: on an orbit a row's energy drift is the Jacobi integral's") {
  const System s = read_scene(test::scene_path("gg_libration"));
  StudyOptions o;
  o.engines = {"kane"};
  o.integrators = {"dop853"};
  o.targets = {1e-6};
  const SceneStudy st = study_scene(s, o);
  REQUIRE_FALSE(st.rows.empty());
  for (const StudyRow& r : st.rows) {
    INFO(r.setting() << ": drift " << r.drift_E);
    if (r.ok && r.tolerance <= 1e-10) CHECK(r.drift_E < 1e-9);  // E itself changes by 1e-4 relative
  }
}
