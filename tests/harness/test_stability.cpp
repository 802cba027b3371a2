// `crossdyn stability` (harness/stability.hpp): the classifier on constructed cases, the scene
// parameters it sweeps, the rk4 stability limit h |lambda|max ~ 2.8 found on a real scene, and the
// command line and report folder.
#include <catch2/catch.hpp>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "harness/stability.hpp"
#include "tests/harness/run_program.hpp"
#include "tests/support/paths.hpp"

using namespace crossdyn;
using namespace crossdyn::harness;

namespace {

CellFacts finished(double error) {
  CellFacts f;
  f.ok = true;
  f.history_error = error;
  f.drift_H = f.drift_E = 0;
  f.H_conserved = f.E_conserved = true;
  return f;
}

CellFacts failed(const std::string& why) {
  CellFacts f;
  f.ok = false;
  f.failure = why;
  return f;
}

}  // namespace

TEST_CASE("stability: the classifier, one constructed case per class and the order of the rules") {
  ClassLimits lim;
  lim.tolerance = 1e-8;
  lim.drift_limit = 1e-6;
  lim.diverged_error = 10.0;
  CHECK(classify(finished(5e-9), lim).cls == StabilityClass::Accurate);
  CHECK(classify(finished(1e-8), lim).cls == StabilityClass::Accurate);  // the limit is inclusive
  CHECK(classify(finished(2e-8), lim).cls == StabilityClass::Inaccurate);
  CHECK(classify(finished(1.9), lim).cls == StabilityClass::Inaccurate);  // a wrong phase, not growth
  CHECK(classify(finished(30.0), lim).cls == StabilityClass::Diverged);   // grown far beyond the motion
  CHECK(classify(finished(std::nan("")), lim).cls == StabilityClass::Diverged);
  // Drift: only where the scene conserves the quantity, and before the accuracy rule.
  CellFacts d = finished(1e-9);
  d.drift_E = 1e-4;
  CHECK(classify(d, lim).cls == StabilityClass::Drift);
  CHECK(classify(d, lim).why.find("E drifts by 1.0e-04") != std::string::npos);
  d.orbit = true;  // on an orbit the energy-like quantity is the Jacobi integral (issue 28)
  CHECK(classify(d, lim).why.find("J drifts by 1.0e-04") != std::string::npos);
  d.orbit = false;
  d.E_conserved = false;
  CHECK(classify(d, lim).cls == StabilityClass::Accurate);
  d = finished(1e-9);
  d.drift_H = std::nan("");  // a non-finite drift of a conserved H is drift, not accurate
  CHECK(classify(d, lim).cls == StabilityClass::Drift);
  // Failed runs, by the integrator's or engine's reason.
  CHECK(classify(failed("engine lagrange failed at t = 1 s (main.theta): main is at the singularity "
                        "of its 3-2-1 Euler angles"), lim).cls == StabilityClass::Singular);
  CHECK(classify(failed("engine lagrange failed at t = 3.1 s (body.euler2 (3-2-1)): attitude of body 'body' "
                        "reached gimbal lock of its 3-2-1 Euler angles"), lim).cls == StabilityClass::Singular);
  CHECK(classify(failed("engine kane failed at t = 2 s: step limit reached (1000 steps)"), lim).cls ==
        StabilityClass::TooCostly);
  CHECK(classify(failed("engine kane failed: time limit of 20 s reached"), lim).cls == StabilityClass::TooCostly);
  CHECK(classify(failed("engine kane failed at t = 2 s (main.wx): non-finite derivative"), lim).cls ==
        StabilityClass::Diverged);
  CHECK(classify(failed("engine kane failed at t = 2 s: step-size underflow (step 1e-20 s)"), lim).cls ==
        StabilityClass::Diverged);
  CHECK(classify(failed("engine kane failed at t = 2 s (mass matrix): not positive definite"), lim).cls ==
        StabilityClass::Diverged);
  CellFacts none;
  none.reference = false;
  none.ok = true;
  none.history_error = 0;
  CHECK(classify(none, lim).cls == StabilityClass::NoReference);
  // Every class has a name, and the names are distinct.
  std::set<std::string> names;
  for (StabilityClass c : kStabilityClasses) names.insert(class_name(c));
  CHECK(names.size() == 7);
}

TEST_CASE("stability: the scene parameters, their values and their errors") {
  const System s = read_scene(test::scene_path("hub_two_panels"));
  const Knob k = parse_knob(s, "hinge1.stiffness");
  CHECK(apply_knob(s, k, 1234).joints[static_cast<std::size_t>(k.index)].stiffness == 1234);
  const Knob r = parse_knob(s, "hinge2.rate");
  CHECK(apply_knob(s, r, 0.5).joints[static_cast<std::size_t>(r.index)].rate0 == 0.5);
  const Knob d = parse_knob(s, "duration");
  const System longer = apply_knob(s, d, 1e4);
  CHECK(longer.run.duration == 1e4);
  CHECK(longer.run.duration / longer.run.output_step <= 2000 * (1 + 1e-12));  // rows kept bounded
  CHECK_THROWS_WITH(apply_knob(s, k, -1), Catch::Contains("a stiffness must be >= 0"));
  CHECK_THROWS_WITH(parse_knob(s, "hinge9.stiffness"),
                    Catch::Contains("no joint or body 'hinge9'") && Catch::Contains("hinge1.stiffness"));
  CHECK_THROWS_WITH(parse_knob(s, "hub.modal_stiffness"), Catch::Contains("body 'hub' has no"));
  CHECK_THROWS_WITH(parse_knob(s, "links"), Catch::Contains("needs a chainN scene"));
  const System flex = read_scene(test::scene_path("hub_flex_array"));
  const Knob m = parse_knob(flex, "array.modal_stiffness");
  const System stiff = apply_knob(flex, m, 1e4);
  const int b = flex.body_index("array");
  CHECK(stiff.bodies[static_cast<std::size_t>(b)].flex->K(0, 0) ==
        1e4 * flex.bodies[static_cast<std::size_t>(b)].flex->K(0, 0));
  // A damping ratio: D_k = 2 zeta sqrt(K_k M_k), M_k the node-sum modal mass (so that every mode
  // decays at zeta omega_k); --set applies a second parameter before the sweep.
  const System damped = apply_setting(apply_setting(flex, "array.modal_stiffness=1000"), "array.modal_damping=0.5");
  const FlexBody& f = *damped.bodies[static_cast<std::size_t>(b)].flex;
  for (int k = 0; k < f.modes(); ++k) {
    double M = 0;
    for (const FlexNode& node : f.nodes) M += node.mass * node.Phi_B.col(k).squaredNorm();
    const double omega = std::sqrt(f.K(k, k) / M);
    CHECK(std::abs(f.D(k, k) / (2 * M * omega) - 0.5) <= 1e-12);
    CHECK(f.K(k, k) == 1000 * flex.bodies[static_cast<std::size_t>(b)].flex->K(k, k));
  }
  CHECK_THROWS_WITH(apply_setting(flex, "array.modal_damping"), Catch::Contains("expected KNOB=VALUE"));
  CHECK_THROWS_WITH(apply_setting(flex, "array.modal_damping=x"), Catch::Contains("'x' is not a number"));
  CHECK_THROWS_WITH(apply_setting(flex, "array.modal_damping=-1"), Catch::Contains("from 0 to 100"));
  const System chain = read_scene(test::scene_path("chain5"));
  CHECK(apply_knob(chain, parse_knob(chain, "links"), 3).bodies.size() == 3);
  // A free base's initial angular velocity, one body-frame component at a time.
  const System lock = read_scene(test::scene_path("gimbal_lock"));
  const Knob wz = parse_knob(lock, "base.wz");
  CHECK(wz.component == 2);
  const System still = apply_setting(apply_knob(lock, wz, 0.0), "base.wx=0");
  CHECK(still.joints[0].w_NB_B0 == Eigen::Vector3d(0, 0.5, 0));
  CHECK_THROWS_WITH(apply_knob(lock, wz, 2e4), Catch::Contains("at most 1e4 rad/s"));
  CHECK_THROWS_WITH(parse_knob(lock, "base.wq"), Catch::Contains("joint 'base' has no 'wq'") &&
                                                     Catch::Contains("base.wx, base.wy, base.wz"));
  CHECK_THROWS_WITH(parse_knob(s, "hinge1.wx"), Catch::Contains("joint 'hinge1' has no 'wx'"));
}

// The rk4 limit on a real scene: hub_two_panels' hinge springs set |lambda|max; a step with
// h |lambda|max below 2.5 must not diverge and one above 3.2 must (rk4's stability region
// reaches 2.8 on the imaginary axis, 2.83, and on the real one, 2.79).
TEST_CASE("stability: rk4 diverges where h |lambda|max passes its stability limit, ~2.8") {
  System s = read_scene(test::scene_path("hub_two_panels"));
  s.run.duration = 4;
  const Knob k = parse_knob(s, "hinge1.stiffness");
  StabilityOptions o;
  o.engines = {"kane"};
  o.integrators = {"rk4", "dop853"};
  o.tolerances = {1e-12};
  o.dts = {0.05, 0.025, 0.0125};
  const StabilityMap m = stability_scene(s, k, {5e3, 1e6}, o);
  REQUIRE(m.columns.size() == 2);
  CHECK(m.columns[1].lambda_max[0] > 3 * m.columns[0].lambda_max[0]);  // stiffer spring, faster mode
  int below = 0, above = 0;
  for (const StabilityCell& c : m.cells) {
    CAPTURE(c.engine, c.integrator, c.setting_text(), c.column, c.h_lambda, c.result.why);
    if (!c.fixed_step) {
      CHECK(c.result.cls == StabilityClass::Accurate);  // dop853 at 1e-12 takes what it needs
      continue;
    }
    REQUIRE(std::isfinite(c.h_lambda));
    if (c.h_lambda < 2.5) {
      CHECK(c.result.cls != StabilityClass::Diverged);
      ++below;
    }
    if (c.h_lambda > 3.2) {
      CHECK(c.result.cls == StabilityClass::Diverged);
      ++above;
    }
  }
  CHECK(below >= 4);
  CHECK(above >= 1);
  // The findings say where and why, with the remedy.
  bool said = false;
  for (const std::string& f : m.findings)
    if (f.rfind("kane + rk4:", 0) == 0) {
      said = true;
      CHECK(f.find("diverged") != std::string::npos);
      CHECK(f.find("h |lambda|max below 2.8") != std::string::npos);
    }
  CHECK(said);
}

// The findings say each outcome once: neighbouring values with the same outcome are one range,
// and a value whose outcome differs keeps its own entry (a hand-made map: two engines, one
// integrator, two tolerances, five values).
TEST_CASE("stability: the findings group neighbouring values with the same outcome") {
  StabilityMap m;
  m.knob.spec = "base.wx";
  m.knob.unit = "rad/s";
  m.engines = {"kane", "lagrange"};
  m.integrators = {"dop853"};
  for (double v : {0.1, 0.01, 0.001, 1e-4, 0.0}) {
    StabilityColumn c;
    c.value = v;
    m.columns.push_back(c);
  }
  // kane: accurate at 1e-9 and inaccurate at 1e-6 everywhere; lagrange: the same but singular at
  // every setting at 1e-3 (the middle value).
  for (const std::string e : {"kane", "lagrange"})
    for (std::size_t col = 0; col < m.columns.size(); ++col)
      for (double tol : {1e-6, 1e-9}) {
        StabilityCell cell;
        cell.engine = e;
        cell.integrator = "dop853";
        cell.setting = tol;
        cell.column = col;
        cell.result.cls = tol < 1e-8 ? StabilityClass::Accurate : StabilityClass::Inaccurate;
        if (e == "lagrange" && col == 2) cell.result.cls = StabilityClass::Singular;
        m.cells.push_back(cell);
      }
  const std::vector<std::string> f = stability_findings(m);
  REQUIRE(f.size() == 2);
  CHECK(f[0] ==
        "kane + dop853: base.wx 0.1 ... 0 rad/s (5 values): accurate up to rtol 1e-09, else "
        "inaccurate. Fails in 5 of 10 measured cells: 5 inaccurate. Remedy: a tighter tolerance: "
        "rtol 1e-09 or less was accurate wherever it was inaccurate.");
  CHECK(f[1] ==
        "lagrange + dop853: base.wx 0.1 ... 0.01 rad/s (2 values): accurate up to rtol 1e-09, else "
        "inaccurate; base.wx 0.001 rad/s: never accurate, else singular; base.wx 0.0001 ... 0 "
        "rad/s (2 values): accurate up to rtol 1e-09, else inaccurate. Fails in 6 of 10 measured "
        "cells: 2 singular, 4 inaccurate. Remedy: singular: turn Euler-angle re-charting on "
        "(lagrange's default) or use an engine with quaternions (kane, newton-euler); inaccurate: "
        "a tighter tolerance: rtol 1e-09 or less was accurate wherever it was inaccurate.");
}

namespace {

// A hand-made map: one engine (kane) and integrator per call, columns x settings of classes.
struct HandCell {
  std::size_t column;
  double setting;
  StabilityClass cls;
  std::string why = "";
  double h_lambda = std::numeric_limits<double>::quiet_NaN();
};

StabilityMap hand_map(const std::vector<bool>& reference, const std::string& integrator,
                      const std::vector<HandCell>& cells) {
  StabilityMap m;
  m.knob.spec = "hinge.stiffness";
  m.knob.unit = "N m/rad";
  m.engines = {"kane"};
  m.integrators = {integrator};
  for (std::size_t c = 0; c < reference.size(); ++c) {
    StabilityColumn col;
    col.value = std::pow(10.0, static_cast<double>(c));
    col.reference = reference[c];
    col.reference_note = reference[c] ? "the mean of 6 runs"
                                      : "s.yaml: no reference: the reference run kane + rkf78 at "
                                        "1e-13 failed: timed out after 600 s (the reference runs' "
                                        "own time budget, not the per-run timeout)";
    m.columns.push_back(col);
  }
  for (const HandCell& h : cells) {
    StabilityCell c;
    c.engine = "kane";
    c.integrator = integrator;
    c.fixed_step = integrator == "rk4";
    c.setting = h.setting;
    c.column = h.column;
    c.result.cls = m.columns[h.column].reference ? h.cls : StabilityClass::NoReference;
    c.result.why = h.why;
    c.h_lambda = h.h_lambda;
    m.cells.push_back(c);
  }
  return m;
}

// Every cell of `classes` (per column) at settings 1e-3 (coarse) and 1e-9 (fine).
std::vector<HandCell> two_settings(const std::vector<std::pair<StabilityClass, StabilityClass>>& classes,
                                   const std::string& why = "") {
  std::vector<HandCell> out;
  for (std::size_t c = 0; c < classes.size(); ++c) {
    out.push_back({c, 1e-3, classes[c].first, why});
    out.push_back({c, 1e-9, classes[c].second, why});
  }
  return out;
}

std::string joined(const std::vector<std::string>& f) {
  std::string all;
  for (const std::string& x : f) all += x + "\n";
  return all;
}

}  // namespace

TEST_CASE("class 11, findings say what happened: no-reference columns are a finding with their "
          "reason, never a failure class, and get no remedy") {
  using C = StabilityClass;
  const C A = C::Accurate, I = C::Inaccurate, Q = C::NoReference;
  SECTION("no reference anywhere") {
    const StabilityMap m = hand_map({false, false, false}, "dop853", two_settings({{Q, Q}, {Q, Q}, {Q, Q}}));
    const std::vector<std::string> f = stability_findings(m);
    INFO(joined(f));
    REQUIRE(f.size() == 2);
    CHECK(f[0] == "No reference at hinge.stiffness 1 ... 100 N m/rad (3 values): the reference run "
                  "kane + rkf78 at 1e-13 failed: timed out after 600 s (the reference runs' own time "
                  "budget, not the per-run timeout). The cells there ('?') measure nothing: they "
                  "count in no class below and have no remedy.");
    CHECK(f[1] == "kane + dop853: no reference at any value tried, so nothing was measured.");
    CHECK(joined(f).find("Remedy") == std::string::npos);
    CHECK(joined(f).find("inaccurate") == std::string::npos);
  }
  SECTION("no reference at one value, accurate at the others") {
    const StabilityMap m = hand_map({true, false, true}, "dop853", two_settings({{A, A}, {Q, Q}, {A, A}}));
    const std::vector<std::string> f = stability_findings(m);
    INFO(joined(f));
    REQUIRE(f.size() == 2);
    CHECK(f[0].rfind("No reference at hinge.stiffness 10 N m/rad: the reference run", 0) == 0);
    CHECK(f[1] == "kane + dop853: accurate at every setting tried at the 2 values with a reference "
                  "(hinge.stiffness 1 N m/rad: accurate up to rtol 0.001; hinge.stiffness 10 N "
                  "m/rad: no reference; hinge.stiffness 100 N m/rad: accurate up to rtol 0.001).");
    CHECK(joined(f).find("Remedy") == std::string::npos);
  }
  SECTION("no reference at one value, inaccurate at a coarse setting elsewhere: counted over the "
          "measured cells only") {
    const StabilityMap m = hand_map({false, true, true}, "dop853", two_settings({{Q, Q}, {I, A}, {I, A}}));
    const std::vector<std::string> f = stability_findings(m);
    INFO(joined(f));
    REQUIRE(f.size() == 2);
    CHECK(f[1] == "kane + dop853: hinge.stiffness 1 N m/rad: no reference; hinge.stiffness 10 ... "
                  "100 N m/rad (2 values): accurate up to rtol 1e-09, else inaccurate. Fails in 2 "
                  "of 4 measured cells: 2 inaccurate. Remedy: a tighter tolerance: rtol 1e-09 or "
                  "less was accurate wherever it was inaccurate.");
  }
  SECTION("an engine left out at the values with a reference: not run, not accurate") {
    StabilityMap m = hand_map({false, true}, "dop853", {{0, 1e-3, Q}, {0, 1e-9, Q}});
    const std::vector<std::string> f = stability_findings(m);
    INFO(joined(f));
    REQUIRE(f.size() == 2);
    CHECK(f[1] == "kane + dop853: not run at any value with a reference, so nothing was measured "
                  "(hinge.stiffness 1 N m/rad: no reference; hinge.stiffness 10 N m/rad: not run; "
                  "the notes say why).");
    // Run at one value with a reference, left out at another: that value is "not run".
    m = hand_map({true, true}, "dop853", {{0, 1e-3, I}, {0, 1e-9, A}});
    const std::vector<std::string> g = stability_findings(m);
    INFO(joined(g));
    REQUIRE(g.size() == 1);
    CHECK_THAT(g[0], Catch::Contains("hinge.stiffness 10 N m/rad: not run.") &&
                         Catch::Contains("Fails in 1 of 2 measured cells: 1 inaccurate"));
  }
  SECTION("two reasons, said per value range") {
    StabilityMap m = hand_map({false, false, true}, "dop853", two_settings({{Q, Q}, {Q, Q}, {A, A}}));
    m.columns[1].reference_note = "s.yaml: no reference: the engines do not agree at the tightest settings";
    const std::vector<std::string> f = stability_findings(m);
    INFO(joined(f));
    CHECK(f[0].rfind("No reference at hinge.stiffness 1 N m/rad: the reference run kane + rkf78 at "
                     "1e-13 failed: timed out after 600 s",
                     0) == 0);
    CHECK_THAT(f[0], Catch::Contains("; at hinge.stiffness 10 N m/rad: the engines do not agree at the "
                                     "tightest settings. The cells there"));
  }
}

TEST_CASE("class 11, findings say what happened: every failure class and combination counted, "
          "each with the remedy its cells support") {
  using C = StabilityClass;
  const C A = C::Accurate, I = C::Inaccurate, Q = C::NoReference, D = C::Drift, X = C::Diverged,
          S = C::Singular, T = C::TooCostly;
  struct Case {
    const char* label;
    std::vector<bool> reference;
    const char* integrator;
    std::vector<HandCell> cells;
    const char* counts;                 // "Fails in ...: ..."
    std::vector<const char*> remedies;  // each must appear
    std::vector<const char*> absent;    // none may appear
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Case> cases = {
      {"inaccurate, never accurate at one value", {true, true}, "dop853",
       two_settings({{I, A}, {I, I}}), "Fails in 3 of 4 measured cells: 3 inaccurate.",
       {"a tighter tolerance than any tried, or another method: no setting tried was accurate at "
        "hinge.stiffness 10 N m/rad"},
       {"or less was accurate"}},
      {"rk4 diverged beyond its stability limit", {true}, "rk4",
       {{0, 0.1, X, "non-finite state", 3.5}, {0, 0.01, A, "", 0.35}},
       "Fails in 1 of 2 measured cells: 1 diverged (first diverging step has h |lambda|max = 3.5).",
       {"take h |lambda|max below 2.8"}, {"inaccurate", "; "}},
      {"rk4 diverged inside its stability region", {true}, "rk4",
       {{0, 0.1, X, "non-finite state", 1.5}, {0, 0.01, A, "", 0.15}},
       "Fails in 1 of 2 measured cells: 1 diverged", {"a shorter step, or an adaptive method"},
       {"below 2.8 (rk4's"}},
      {"adaptive diverged", {true}, "dopri5", two_settings({{X, A}}),
       "Fails in 1 of 2 measured cells: 1 diverged.", {"tighten the tolerance"}, {"h |lambda|"}},
      {"singular", {true}, "dopri5", two_settings({{S, S}}), "Fails in 2 of 2 measured cells: 2 singular.",
       {"re-charting"}, {"tolerance"}},
      {"too costly by the time limit", {true}, "dop853",
       two_settings({{A, T}}, "timed out after 0.001 s"),
       "Fails in 1 of 2 measured cells: 1 too costly.",
       {"allow each run more time (--timeout: every too costly run here was stopped by it)"},
       {"--max-steps", "is stiff", "cvode-bdf"}},
      {"too costly by the step limit, adaptive", {true}, "dop853",
       two_settings({{A, T}}, "step limit 200000 reached"),
       "Fails in 1 of 2 measured cells: 1 too costly.", {"implicit cvode-bdf", "(--max-steps)"},
       {"--timeout"}},
      {"too costly by the step limit, rk4", {true}, "rk4",
       {{0, 0.1, A, "", nan}, {0, 1e-6, T, "step limit 200000 reached", nan}},
       "Fails in 1 of 2 measured cells: 1 too costly.", {"a longer step", "(--max-steps)"},
       {"--timeout", "cvode-bdf"}},
      {"drift", {true}, "dopri5", two_settings({{D, A}}), "Fails in 1 of 2 measured cells: 1 drift.",
       {"tighten the tolerance"}, {"inaccurate", "projection"}},
      {"drift, rk4", {true}, "rk4", {{0, 0.1, D}, {0, 0.01, A}}, "Fails in 1 of 2 measured cells: 1 drift.",
       {"a shorter step"}, {"tolerance"}},
      {"every class at once, and a value without a reference", {true, true, true, false}, "dopri5",
       {{0, 1e-3, X}, {0, 1e-9, A}, {1, 1e-3, S}, {1, 1e-9, S}, {2, 1e-3, T, "timed out after 1 s"},
        {2, 1e-6, D}, {2, 1e-9, I}, {2, 1e-12, A}, {3, 1e-3, Q}, {3, 1e-9, Q}},
       "Fails in 6 of 8 measured cells: 1 diverged, 2 singular, 1 too costly, 1 drift, 1 inaccurate.",
       {"diverged: tighten the tolerance", "singular: turn Euler-angle", "too costly: allow each run more time (--timeout",
        "drift: tighten the tolerance", "inaccurate: a tighter tolerance: rtol 1e-12 or less was accurate"},
       {"no reference:", "Fails mostly"}},
  };
  for (const Case& c : cases) {
    CAPTURE(c.label);
    const StabilityMap m = hand_map(c.reference, c.integrator, c.cells);
    const std::vector<std::string> f = stability_findings(m);
    INFO(joined(f));
    const std::string& mine = f.back();
    CHECK_THAT(mine, Catch::Contains(c.counts));
    for (const char* r : c.remedies) CHECK_THAT(mine, Catch::Contains(r));
    for (const char* r : c.absent) CHECK_THAT(mine, !Catch::Contains(r));
    const bool any_missing = std::find(c.reference.begin(), c.reference.end(), false) != c.reference.end();
    CHECK((f.size() == 2) == any_missing);  // the no-reference finding exactly when a value has none
  }
}

TEST_CASE("class 11, the reference runs have their own budget: a tiny --timeout makes cells too "
          "costly, never the reference, and a reference that still cannot be made is a finding with "
          "its reason") {
  // The shortest --timeout allowed (1 ms; issue 23 class 8) against a run of about 25 ms.
  const std::string common =
      "stability chain_motor --vary duration --values 20 --engines newton-euler --integrators dopri5 "
      "--tolerances 1e-12 -q";
  test::ProgramResult r = test::run_crossdyn(common + " --timeout 0.001");
  INFO(r.output);
  REQUIRE(r.status == 0);
  CHECK_THAT(r.output, !Catch::Contains("No reference") && !Catch::Contains("no reference at any"));
  CHECK_THAT(r.output, Catch::Contains("1 too costly") &&
                           Catch::Contains("allow each run more time (--timeout: every too costly run"));
  CHECK_THAT(r.output, !Catch::Contains("is stiff"));
  CHECK_THAT(r.output, Catch::Contains("note: the reference runs had their own time budget, 600 s "
                                       "each (--reference-timeout), independent of the per-run "
                                       "--timeout (0.001 s)"));
  r = test::run_crossdyn(common + " --reference-timeout 1e-9");
  INFO(r.output);
  REQUIRE(r.status == 0);
  CHECK_THAT(r.output, Catch::Contains("No reference at duration 20 s: the reference run") &&
                           Catch::Contains("timed out") &&
                           Catch::Contains("(the reference runs' own time budget, not the per-run timeout)"));
  CHECK_THAT(r.output, Catch::Contains("newton-euler + dopri5: no reference at any value tried, so "
                                       "nothing was measured."));
  CHECK_THAT(r.output, !Catch::Contains("Remedy") && !Catch::Contains("inaccurate."));
  // Each '?' cell of the CSV carries the reason too.
  const std::string csv = std::filesystem::temp_directory_path().string() + "/crossdyn_class11_" +
                          std::to_string(::getpid()) + ".csv";
  r = test::run_crossdyn(common + " --reference-timeout 1e-9 --csv '" + csv + "'");
  REQUIRE(r.status == 0);
  std::ifstream in(csv);
  std::stringstream text;
  text << in.rdbuf();
  std::filesystem::remove(csv);
  CHECK_THAT(text.str(), Catch::Contains(",no reference,\"no reference at this parameter value (the "
                                         "reference run ") &&
                             Catch::Contains("timed out"));
  r = test::run_crossdyn(common + " --reference-timeout -1");
  CHECK(r.status == 2);
  CHECK_THAT(r.output, Catch::Contains("--reference-timeout: must be a finite number of seconds"));
}

TEST_CASE("stability: bad arguments exit 2, a tiny map writes its table, CSV and report") {
  const struct {
    const char* args;
    const char* message;
  } cases[] = {
      {"stability hub_two_panels --values 1,2", "--vary: give the scene parameter"},
      {"stability hub_two_panels --vary hinge1.stifness --values 1", "no 'stifness' to vary"},
      {"stability hub_two_panels --vary hinge1.stiffness --values 1,x", "'x' is not a number"},
      {"stability hub_two_panels --vary hinge1.stiffness --values -5", "a stiffness must be >= 0"},
      {"stability hub_two_panels --vary duration --values 1 --engines foo", "unknown engine 'foo'"},
  };
  for (const auto& c : cases) {
    CAPTURE(c.args);
    const test::ProgramResult r = test::run_crossdyn(std::string(c.args) + " -q");
    CAPTURE(r.output);
    CHECK(r.status == 2);
    CHECK(r.output.find(c.message) != std::string::npos);
  }
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("crossdyn_stability_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string report = (dir / "report").string(), csv = (dir / "map.csv").string();
  const test::ProgramResult r = test::run_crossdyn(
      "stability torque_free_asymmetric --vary duration --values 1,2 --engines kane --integrators "
      "rk4,dopri5 --dts 0.1 --tolerances 1e-6 -q --csv '" + csv + "' --report '" + report + "'");
  CAPTURE(r.output);
  REQUIRE(r.status == 0);
  CHECK(r.output.find("Findings:") != std::string::npos);
  std::ifstream in(csv);
  std::stringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  CHECK(std::count(text.begin(), text.end(), '\n') == 1 + 2 * 2);
  for (const char* f : {"index.html", "torque_free_asymmetric-duration.html",
                        "torque_free_asymmetric-duration.png", "torque_free_asymmetric-duration.csv",
                        "stability.json"}) {
    CAPTURE(f);
    CHECK(fs::is_regular_file(fs::path(report) / f));
  }
  fs::remove_all(dir);
}

// Why newton-euler pays more on fast rotors: its maximal coordinates integrate the rotor's
// attitude, whose rate the Jacobian sees; kane's and lagrange's generalised coordinates carry only
// the rotor angle, whose rate is constant (issue 13, "fast rotors").
TEST_CASE("stability: |lambda|max per engine sees a fast rotor in newton-euler's state only") {
  const System s = read_scene(test::scene_path("dual_spin"));
  const Knob k = parse_knob(s, "bearing.rate");
  const System fast = apply_knob(s, k, 1047.0);  // 10,000 rpm
  const double ne = jacobian_spectral_radius(fast, "newton-euler");
  const double kane = jacobian_spectral_radius(fast, "kane");
  const double lagrange = jacobian_spectral_radius(fast, "lagrange");
  INFO("|lambda|max at 10,000 rpm: newton-euler " << ne << ", kane " << kane << ", lagrange " << lagrange);
  CHECK(ne > 500.0);   // of the order of the rotor's rate, 1047 rad/s
  CHECK(kane < 50.0);  // the nutation and the gyroscopic coupling only
  CHECK(lagrange < 50.0);
}
