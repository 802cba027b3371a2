// The comparison logic (harness/compare.hpp) on synthetic runs: the pass rule and where it is
// evaluated, attitudes (q and -q), tolerance lookup, exclusions with reasons, drift, failed and
// missing engines, and the analytic pseudo-engine's columns.
#include <catch2/catch.hpp>

#include "core/scene/scene.hpp"
#include "harness/compare.hpp"
#include "harness/report.hpp"
#include "tests/harness/synthetic.hpp"
#include "tests/support/close.hpp"
#include "tests/support/paths.hpp"

#include <cmath>
#include <algorithm>
#include <set>

using crossdyn::RunFailure;
using crossdyn::RunResult;
using crossdyn::System;
using crossdyn::Tolerance;
using crossdyn::harness::Check;
using crossdyn::harness::CheckStatus;
using crossdyn::harness::compare_runs;
using crossdyn::harness::compare_scene;
using crossdyn::harness::CompareOptions;
using crossdyn::harness::EngineRun;
using crossdyn::harness::SceneComparison;
using crossdyn::test::baseline;
using crossdyn::test::engine_run;
using crossdyn::test::find_checks;
using crossdyn::test::make_run;
using crossdyn::test::two_body_system;

namespace {

// Run "b" is the baseline; run "a" adds `offset` to `column` at `row`.
SceneComparison compare_offset(const System& s, const std::string& column, std::size_t row,
                               double offset) {
  auto a = [&](const std::string& c, std::size_t r) {
    return baseline(c, r) + (c == column && r == row ? offset : 0.0);
  };
  return compare_runs(s, {engine_run("b", make_run(s)), engine_run("a", make_run(s, a))});
}

}  // namespace

TEST_CASE("compare: identical runs pass every check and the reference is the earlier run") {
  const System s = two_body_system();
  const SceneComparison c =
      compare_runs(s, {engine_run("first", make_run(s)), engine_run("second", make_run(s))});
  CHECK(c.passed());
  CHECK(c.count(CheckStatus::Fail) == 0);
  // Per pair: 2 bodies x (3 w + attitude) + hinge angle + rate + H + E = 12, and issue 26's
  // 2 bodies x 3 positions + CM 3 + H vector 3 + hinge loads 6 + P + M 3 = 22; 2 runs; drift 2 x 2.
  CHECK(find_checks(c, "base.wx").size() == 1);
  CHECK(find_checks(c, "base.wx")[0].a == "second");
  CHECK(find_checks(c, "base.wx")[0].b == "first");
  CHECK(find_checks(c, "arm.attitude").size() == 1);
  CHECK(find_checks(c, "hinge.angle").size() == 1);
  CHECK(find_checks(c, "hinge.rate").size() == 1);
  CHECK(find_checks(c, "H.drift").size() == 2);
  CHECK(find_checks(c, "E.drift").size() == 2);
  CHECK(find_checks(c, "run").size() == 2);
  CHECK(find_checks(c, "hinge.Mz").size() == 1);
  CHECK(find_checks(c, "hinge.Mz")[0].group == "load");
  CHECK(find_checks(c, "arm.y")[0].group == "position");
  CHECK(find_checks(c, "CMz")[0].group == "position");
  CHECK(find_checks(c, "root.Fx").empty());  // the free joint carries no load
  CHECK(c.checks.size() == 34 + 2 * 2 + 2);
}

TEST_CASE("compare: pass rule is |a - b| <= atol + rtol * max|b|, evaluated at its boundary") {
  System s = two_body_system();
  // Binary fractions so that the boundary is exact: max|b| of hinge.rate is 1, bound 0.5.
  s.compare.tolerances.push_back({"hinge.rate", Tolerance{0.25, 0.25}});
  const SceneComparison at = compare_offset(s, "hinge.rate", 2, 0.5);
  const Check k = find_checks(at, "hinge.rate")[0];
  CHECK(k.status == CheckStatus::Pass);
  CHECK(k.error == 0.5);
  CHECK(k.bound == 0.5);
  CHECK(k.scale == 1.0);
  CHECK(k.normalised == 1.0);
  CHECK(k.tolerance_key == "hinge.rate");
  CHECK_FALSE(k.first_exceeded);

  const SceneComparison over = compare_offset(s, "hinge.rate", 2, 0.5 + std::ldexp(1.0, -30));
  const Check f = find_checks(over, "hinge.rate")[0];
  CHECK(f.status == CheckStatus::Fail);
  CHECK_FALSE(over.passed());
  CHECK(f.time == 0.5);  // row 2
  REQUIRE(f.first_exceeded);
  CHECK(*f.first_exceeded == 0.5);
}

TEST_CASE("compare: the scale is max|b| over the whole run, not |b| at the worst time") {
  System s = two_body_system();
  s.compare.tolerances.push_back({"hinge.angle", Tolerance{0.0, 0.5}});
  // b = hinge.angle = t, max |b| = 1 at t = 1; a differs by 0.5 at t = 0 where b = 0: passes.
  const Check k = find_checks(compare_offset(s, "hinge.angle", 0, 0.5), "hinge.angle")[0];
  CHECK(k.scale == 1.0);
  CHECK(k.bound == 0.5);
  CHECK(k.status == CheckStatus::Pass);
  CHECK(k.time == 0.0);
}

TEST_CASE("compare: reports the largest error, its time and the first time over the bound") {
  const System s = two_body_system();  // default tolerance atol = rtol = 1e-8
  auto a = [](const std::string& c, std::size_t r) {
    const double bump = r == 1 ? 1e-6 : r == 3 ? 4e-6 : 0.0;  // over at t = 0.25, worst at 0.75
    return baseline(c, r) + (c == "arm.wy" ? bump : 0.0);
  };
  const SceneComparison c = compare_runs(s, {engine_run("b", make_run(s)), engine_run("a", make_run(s, a))});
  const Check k = find_checks(c, "arm.wy")[0];
  CHECK(k.status == CheckStatus::Fail);
  CHECK(crossdyn::test::close(k.error, 4e-6, 1e-20, 1e-9));
  CHECK(k.time == 0.75);
  REQUIRE(k.first_exceeded);
  CHECK(*k.first_exceeded == 0.25);
  CHECK(k.scale == 2.0);
  CHECK(crossdyn::test::close(k.bound, 1e-8 + 1e-8 * 2.0, 0, 1e-15));
  CHECK(crossdyn::test::close(k.normalised, 4e-6 / 3e-8, 0, 1e-9));
  // Every other quantity still passes.
  CHECK(c.count(CheckStatus::Fail) == 1);
}

TEST_CASE("compare: attitudes compare as rotations, so q and -q agree") {
  const System s = two_body_system();
  const Eigen::Quaterniond q(Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, 2, 2).normalized()));
  auto with_q = [q](double sign, double extra_angle) {
    const Eigen::Quaterniond r = q * Eigen::Quaterniond(Eigen::AngleAxisd(extra_angle, Eigen::Vector3d::UnitZ()));
    return [=](const std::string& c, std::size_t row) {
      if (c == "base.qw") return sign * r.w();
      if (c == "base.qx") return sign * r.x();
      if (c == "base.qy") return sign * r.y();
      if (c == "base.qz") return sign * r.z();
      return baseline(c, row);
    };
  };
  const SceneComparison flipped =
      compare_runs(s, {engine_run("b", make_run(s, with_q(1, 0))), engine_run("a", make_run(s, with_q(-1, 0)))});
  const Check k = find_checks(flipped, "base.attitude")[0];
  CHECK(k.status == CheckStatus::Pass);
  CHECK(k.error < 1e-15);
  CHECK(k.scale == 1.0);

  const SceneComparison turned =
      compare_runs(s, {engine_run("b", make_run(s, with_q(1, 0))), engine_run("a", make_run(s, with_q(-1, 1e-3)))});
  const Check t = find_checks(turned, "base.attitude")[0];
  CHECK(t.status == CheckStatus::Fail);
  CHECK(crossdyn::test::close(t.error, 1e-3, 0, 1e-9));
}

TEST_CASE("compare: tolerance lookup goes quantity, vector, group, default") {
  System s = two_body_system();
  s.compare.default_tolerance = Tolerance{1e-3, 0};
  s.compare.tolerances = {{"base.wx", Tolerance{1e-4, 0}}, {"base.w", Tolerance{1e-5, 0}},
                          {"w", Tolerance{1e-6, 0}}, {"attitude", Tolerance{1e-7, 0}}};
  const SceneComparison c = compare_runs(s, {engine_run("b", make_run(s)), engine_run("a", make_run(s))});
  auto key = [&c](const std::string& q) { return find_checks(c, q)[0].tolerance_key; };
  auto atol = [&c](const std::string& q) { return find_checks(c, q)[0].tolerance.atol; };
  CHECK(key("base.wx") == "base.wx");
  CHECK(atol("base.wx") == 1e-4);
  CHECK(key("base.wy") == "base.w");
  CHECK(atol("base.wy") == 1e-5);
  CHECK(key("arm.wz") == "w");
  CHECK(atol("arm.wz") == 1e-6);
  CHECK(key("arm.attitude") == "attitude");
  CHECK(key("hinge.rate") == "default");
  CHECK(atol("hinge.rate") == 1e-3);
  CHECK(c.notes.empty());
}

TEST_CASE("compare: excluded quantities carry their reason and cannot fail") {
  System s = two_body_system();
  s.compare.excluded = {{"hinge.rate", "rate sensor not modelled"}, {"w", "angular velocities excluded"}};
  auto a = [](const std::string& c, std::size_t r) {
    return baseline(c, r) + (c == "hinge.rate" || c.find(".w") != std::string::npos ? 1.0 : 0.0);
  };
  const SceneComparison c = compare_runs(s, {engine_run("b", make_run(s)), engine_run("a", make_run(s, a))});
  CHECK(c.passed());
  const Check rate = find_checks(c, "hinge.rate")[0];
  CHECK(rate.status == CheckStatus::Excluded);
  CHECK(rate.note == "rate sensor not modelled");
  for (const char* q : {"base.wx", "base.wy", "base.wz", "arm.wx", "arm.wy", "arm.wz"}) {
    INFO(q);
    CHECK(find_checks(c, q)[0].status == CheckStatus::Excluded);
    CHECK(find_checks(c, q)[0].note == "angular velocities excluded");
  }
  CHECK(find_checks(c, "hinge.angle")[0].status == CheckStatus::Pass);
}

TEST_CASE("compare: drift of H and E from their initial values, per engine") {
  System s = two_body_system();
  // H drifts by 2e-8 relative: fails the default 1e-9, passes an H.drift tolerance of 1e-7.
  auto drifting = [](const std::string& c, std::size_t r) {
    return c == "H" ? 10.0 * (1 + 2e-8 * static_cast<double>(r == 3)) : baseline(c, r);
  };
  const SceneComparison strict =
      compare_runs(s, {engine_run("steady", make_run(s)), engine_run("drifty", make_run(s, drifting))});
  const Check d = find_checks(strict, "H.drift", "drifty")[0];
  CHECK(d.status == CheckStatus::Fail);
  CHECK(crossdyn::test::close(d.error, 2e-7, 0, 1e-6));
  CHECK(d.scale == 10.0);
  CHECK(d.time == 0.75);
  CHECK(d.tolerance.rtol == crossdyn::harness::kDefaultDriftTolerance);
  CHECK(find_checks(strict, "H.drift", "steady")[0].status == CheckStatus::Pass);
  CHECK(find_checks(strict, "E.drift", "drifty")[0].status == CheckStatus::Pass);

  s.compare.tolerances.push_back({"H.drift", Tolerance{0, 1e-7}});
  s.compare.tolerances.push_back({"H", Tolerance{0, 1e-7}});
  const SceneComparison loose =
      compare_runs(s, {engine_run("steady", make_run(s)), engine_run("drifty", make_run(s, drifting))});
  CHECK(loose.passed());
  CHECK(find_checks(loose, "H.drift", "drifty")[0].tolerance_key == "H.drift");
}

TEST_CASE("compare: E is balanced against the integral of P, not drift-checked, with motors or dampers") {
  System s = two_body_system();
  s.joints[1].damping = 0.5;
  s.joints[1].motor_revolute.times = {0.0};
  s.joints[1].motor_revolute.values = {Eigen::Matrix<double, 1, 1>(1.0)};
  // E loses 4 J/s (rows 0.25 s apart); the honest engine reports P = -4 W, the other P = 0 (its
  // damper's load left out of its power: what a balance exists to catch).
  auto losing = [](const std::string& c, std::size_t r) {
    return c == "E" ? 5.0 - static_cast<double>(r) : c == "P" ? -4.0 : baseline(c, r);
  };
  auto unpowered = [&losing](const std::string& c, std::size_t r) { return c == "P" ? 0.0 : losing(c, r); };
  const SceneComparison c =
      compare_runs(s, {engine_run("x", make_run(s, losing)), engine_run("y", make_run(s, unpowered))});
  CHECK(find_checks(c, "E.drift").empty());
  const Check e = find_checks(c, "E.balance", "x")[0];
  CHECK(e.status == CheckStatus::Pass);
  CHECK(e.error <= 1e-14);  // the rule integrates a constant exactly, up to rounding
  CHECK(e.note.rfind("not conserved (joint dampers and motors): E(t) - E(0) against the integral of P", 0) == 0);
  CHECK(e.group == "E.balance");
  const Check f = find_checks(c, "E.balance", "y")[0];
  CHECK(f.status == CheckStatus::Fail);
  CHECK(f.error == 4.0);
  CHECK(f.time == 1.0);
  CHECK(f.first_exceeded == 0.25);
  CHECK(f.scale == 5.0);  // max(max |E|, integral of |P|)
  // P itself is compared between engines like any quantity.
  CHECK(find_checks(c, "P")[0].status == CheckStatus::Fail);
  CHECK(find_checks(c, "H.drift", "x")[0].status == CheckStatus::Pass);
  CHECK(find_checks(c, "H.balance").empty());
  CHECK(crossdyn::harness::energy_not_conserved_reason(s) == "scene has joint dampers and motors");
  CHECK(crossdyn::harness::momentum_not_conserved_reason(s).empty());
}

TEST_CASE("compare: H with external torques is balanced as a vector against the integral of M") {
  System s = two_body_system();
  s.bodies[0].torque.times = {0.0};
  s.bodies[0].torque.values = {Eigen::Vector3d(0, 2, 0)};
  auto torqued = [](const std::string& c, std::size_t r) {
    const double t = 0.25 * static_cast<double>(r);
    return c == "Hy" ? 2 * t : c == "My" ? 2.0 : c == "P" ? 0.0 : baseline(c, r);
  };
  // The same moment about another axis: |H| would balance, the vector does not.
  auto turned = [&torqued](const std::string& c, std::size_t r) {
    return c == "My" ? 0.0 : c == "Mz" ? 2.0 : torqued(c, r);
  };
  const SceneComparison c =
      compare_runs(s, {engine_run("x", make_run(s, torqued)), engine_run("y", make_run(s, turned))});
  CHECK(find_checks(c, "H.drift").empty());
  const Check h = find_checks(c, "H.balance", "x")[0];
  CHECK(h.status == CheckStatus::Pass);
  CHECK(h.error <= 1e-14);
  const Check g = find_checks(c, "H.balance", "y")[0];
  CHECK(g.status == CheckStatus::Fail);
  CHECK(crossdyn::test::close(g.error, std::sqrt(8.0), 1e-15, 0));  // |(0, 2, -2)| at t = 1
}

// The quadrature of the balance on the output times: third order, with its estimated error in
// the bound, so a smooth power sampled coarsely passes and a power wrong by a factor fails.
TEST_CASE("compare: a balance's quadrature of a smooth rate on coarse output times, its estimate in the bound") {
  System s = two_body_system();
  s.joints[1].damping = 0.5;
  auto smooth = [](double factor) {
    return [factor](const std::string& c, std::size_t r) {
      const double t = 0.25 * static_cast<double>(r);
      return c == "E" ? 5 + std::sin(3 * t) : c == "P" ? factor * 3 * std::cos(3 * t) : baseline(c, r);
    };
  };
  const SceneComparison c = compare_runs(
      s, {engine_run("x", make_run(s, smooth(1.0))), engine_run("y", make_run(s, smooth(2.0)))});
  const Check e = find_checks(c, "E.balance", "x")[0];
  CHECK(e.status == CheckStatus::Pass);
  CHECK(e.error > 0);           // the rule is not exact for a sine ...
  CHECK(e.error < 0.05);        // ... but third order in h w = 0.75, a coarse grid
  CHECK(e.note.find("quadrature of the output times: estimated error") != std::string::npos);
  CHECK(e.bound > e.error);
  CHECK(e.bound < 0.2);
  CHECK(find_checks(c, "E.balance", "y")[0].status == CheckStatus::Fail);
}

// Every joint type's dampers and motors count (a universal joint keeps its second axis's damper
// and its motors in fields of its own): a gimbal with only a motor is not an E drift failure.
TEST_CASE("compare: dampers and motors of every joint type make E not conserved") {
  using crossdyn::harness::energy_not_conserved_reason;
  System s = two_body_system();
  s.joints[1].type = crossdyn::JointType::Universal;
  CHECK(energy_not_conserved_reason(s).empty());
  s.joints[1].damping2 = 0.1;
  CHECK(energy_not_conserved_reason(s) == "scene has joint dampers");
  s.joints[1].damping2 = 0;
  s.joints[1].motor_universal.times = {0.0};
  s.joints[1].motor_universal.values = {Eigen::Vector2d(0.05, 0.02)};
  CHECK(energy_not_conserved_reason(s) == "scene has motors");
  // Through the program on such a scene: passes, E balanced against each engine's P.
  const System g = crossdyn::read_scene_text(R"(name: gmotor
bodies:
  - {name: hub, mass: 120 kg, inertia: [40, 55, 60]}
  - {name: eye, mass: 2 kg, inertia: [0.03, 0.05, 0.04]}
joints:
  - {name: base, type: free, child: hub}
  - {name: gimbal, type: universal, parent: hub, child: eye, parent_point: [0, -0.6, 0.3],
     child_point: [0, 0.1, 0], axis: [0, 1, 0], axis2: [0, 0, 1],
     motor: {profile: [{t: 0, value: [0.05, 0.02]}]}}
run: {duration: 2 s, output_step: 0.05 s}
)", "gmotor.yaml");
  const SceneComparison c = crossdyn::harness::compare_scene(g, crossdyn::harness::CompareOptions{});
  CHECK(c.passed());
  CHECK(find_checks(c, "E.balance", "kane")[0].status == CheckStatus::Pass);
  CHECK(find_checks(c, "E.drift").empty());
}

TEST_CASE("compare: the E balance names joint dampers and modal damping apart") {
  using crossdyn::harness::energy_not_conserved_reason;
  // scenarios/hub_nodal_panel.yaml: 0.5 % modal damping and no joint damper.
  const System panel = crossdyn::read_scene(crossdyn::test::scene_path("hub_nodal_panel"));
  CHECK(energy_not_conserved_reason(panel) == "scene has modal damping");
  const SceneComparison c = compare_runs(
      panel, {engine_run("x", make_run(panel)), engine_run("y", make_run(panel))});
  const Check e = find_checks(c, "E.balance", "x")[0];
  CHECK(e.status == CheckStatus::Pass);
  CHECK(e.note.rfind("not conserved (modal damping): E(t) - E(0) against the integral of P", 0) == 0);

  System s = two_body_system();
  CHECK(energy_not_conserved_reason(s).empty());
  s.joints[1].damping = 0.5;
  CHECK(energy_not_conserved_reason(s) == "scene has joint dampers");
  s.bodies[1].flex = crossdyn::FlexBody{};
  s.bodies[1].flex->D = Eigen::MatrixXd::Zero(2, 2);  // modes without damping dissipate nothing
  CHECK(energy_not_conserved_reason(s) == "scene has joint dampers");
  s.bodies[1].flex->D(1, 1) = 0.01;
  CHECK(energy_not_conserved_reason(s) == "scene has joint dampers and modal damping");
  s.joints[1].damping = 0;
  CHECK(energy_not_conserved_reason(s) == "scene has modal damping");
}

TEST_CASE("compare: a failed engine run is a failure with engine, time and reason") {
  const System s = two_body_system();
  RunResult broken = make_run(s);
  broken.data.resize(2 * broken.columns.size());  // rows before the failure stay
  broken.failure = RunFailure("wobbly", 0.3, "arm.wx", "non-finite derivative");
  EngineRun w = engine_run("wobbly", broken);
  w.state = EngineRun::State::Failed;
  w.note = broken.failure->what();
  const SceneComparison c = compare_runs(s, {engine_run("good", make_run(s)), w, engine_run("fine", make_run(s))});
  CHECK_FALSE(c.passed());
  const Check run = find_checks(c, "run", "wobbly")[0];
  CHECK(run.status == CheckStatus::Fail);
  CHECK(run.time == 0.3);
  CHECK(run.note.find("non-finite derivative") != std::string::npos);
  CHECK(run.note.find("wobbly") != std::string::npos);
  // The others are still compared with each other; the failed one is left out.
  CHECK(find_checks(c, "base.wx", "fine", "good").size() == 1);
  for (const Check& k : c.checks)
    if (k.group != "run") {
      CHECK(k.a != "wobbly");
      CHECK(k.b != "wobbly");
    }
  CHECK(c.count(CheckStatus::Fail) == 1);
}

TEST_CASE("compare: an engine that is not built yet is skipped with a note, not failed") {
  const System s = two_body_system();
  EngineRun missing;
  missing.label = missing.engine = "future";
  missing.state = EngineRun::State::NotBuilt;
  missing.note = "engine future not built yet";
  const SceneComparison c = compare_runs(s, {engine_run("only", make_run(s)), missing});
  CHECK(c.passed());
  CHECK(find_checks(c, "run", "future")[0].status == CheckStatus::Skipped);
  REQUIRE(c.notes.size() >= 2);
  CHECK(c.notes[0] == "future skipped: engine future not built yet");
  CHECK(c.notes[1] == "only only finished: no pairwise comparison");
}

TEST_CASE("compare: missing columns fail, extra columns count only when named, typos are noted") {
  System s = two_body_system();
  RunResult lacking = make_run(s);
  const auto at = std::find(lacking.columns.begin(), lacking.columns.end(), "hinge.rate") - lacking.columns.begin();
  lacking.columns[static_cast<std::size_t>(at)] = "hinge.speed";
  const SceneComparison c = compare_runs(s, {engine_run("b", make_run(s)), engine_run("a", lacking)});
  const Check k = find_checks(c, "hinge.rate")[0];
  CHECK(k.status == CheckStatus::Fail);
  CHECK(k.note == "column 'hinge.rate' missing from a's output");

  auto extra = [](const std::string& c2, std::size_t r) { return c2 == "arm.torque" ? 1.0 * r : baseline(c2, r); };
  auto extra2 = [](const std::string& c2, std::size_t r) { return c2 == "arm.torque" ? 2.0 * r : baseline(c2, r); };
  const SceneComparison unnamed = compare_runs(
      s, {engine_run("b", make_run(s, extra, {"arm.torque"})), engine_run("a", make_run(s, extra2, {"arm.torque"}))});
  CHECK(unnamed.passed());
  CHECK(find_checks(unnamed, "arm.torque").empty());
  s.compare.tolerances.push_back({"arm.torque", Tolerance{0.1, 0}});
  s.compare.tolerances.push_back({"arm.wq", Tolerance{0.1, 0}});
  const SceneComparison named = compare_runs(
      s, {engine_run("b", make_run(s, extra, {"arm.torque"})), engine_run("a", make_run(s, extra2, {"arm.torque"}))});
  REQUIRE(find_checks(named, "arm.torque").size() == 1);
  CHECK(find_checks(named, "arm.torque")[0].group == "extra");
  CHECK(find_checks(named, "arm.torque")[0].status == CheckStatus::Fail);
  CHECK(find_checks(named, "arm.torque")[0].error == 4.0);
  CHECK(std::find(named.notes.begin(), named.notes.end(),
                  "tolerance 'arm.wq' matches no compared quantity or column") != named.notes.end());
}

TEST_CASE("compare: runs sampled at different times fail the output-time check") {
  const System s = two_body_system();
  auto shifted = [](const std::string& c, std::size_t r) { return c == "t" ? 0.25 * r + 0.01 : baseline(c, r); };
  const SceneComparison c = compare_runs(s, {engine_run("b", make_run(s)), engine_run("a", make_run(s, shifted))});
  REQUIRE(find_checks(c, "t").size() == 1);
  CHECK(find_checks(c, "t")[0].status == CheckStatus::Fail);
  CHECK_FALSE(c.passed());
}

TEST_CASE("compare: the analytic pseudo-engine writes the pinned columns of a torque-free body") {
  System s = two_body_system();
  s.bodies.pop_back();
  s.joints.pop_back();
  s.analytic = "torque-free";
  s.joints[0].w_NB_B0 = Eigen::Vector3d(0.1, 1.0, 0.1);
  const RunResult r = crossdyn::harness::analytic_run(s, {0.0, 0.5, 1.0});
  CHECK(r.columns == crossdyn::pinned_columns(s));
  REQUIRE(r.rows() == 3);
  const Eigen::Matrix3d I = s.bodies[0].I_BBo_B;
  const Eigen::Vector3d w0 = s.joints[0].w_NB_B0;
  CHECK(crossdyn::test::close(r.at(0, 1), w0.x(), 1e-14, 1e-13));
  const auto col = [&r](const char* name) { return static_cast<std::size_t>(r.column(name)); };
  CHECK(crossdyn::test::close(r.at(2, col("H")), (I * w0).norm(), 0, 1e-14));
  CHECK(crossdyn::test::close(r.at(2, col("E")), 0.5 * w0.dot(I * w0), 0, 1e-14));
  CHECK(r.at(1, 4) >= 0);  // qw, canonical sign
  // The momentum vector in N is constant and its norm is H; no loads: P and M are zero; the CM
  // stays where it started.
  const Eigen::Vector3d H0 = s.joints[0].q_NB0 * (I * w0);
  for (std::size_t k = 0; k < 3; ++k) {
    const Eigen::Vector3d H(r.at(k, col("Hx")), r.at(k, col("Hy")), r.at(k, col("Hz")));
    CHECK((H - H0).norm() <= 1e-12 * H0.norm());
    CHECK(r.at(k, col("P")) == 0);
    CHECK(r.at(k, col("Mz")) == 0);
    CHECK(r.at(k, col("CMx")) == r.at(0, col("base.x")));
  }
}

// A group missing from group_order() would leave its checks out of verify's table and the
// report's columns: every group a comparison makes must be in it. The scenes here hold every kind
// of pinned column (revolute, spherical, prismatic and universal joints, a prescribed joint's
// torque and force, modes, loads) and every drift and balance check.
TEST_CASE("compare: every check's group is a column of verify's table (group_order)") {
  using namespace crossdyn;
  using namespace crossdyn::harness;
  const auto& order = group_order();
  std::set<std::string> seen;
  for (const char* scene : {"telescoping_boom", "gimbal_payload", "scan_platform", "chain5",
                            "hub_nodal_panel", "torque_free_asymmetric"}) {
    const System s = read_scene(crossdyn::test::scene_path(scene));
    CompareOptions o;
    o.analytic = true;
    const SceneComparison c = compare_scene(s, o);
    for (const Check& k : c.checks) {
      INFO(scene << ": " << k.quantity << " in group '" << k.group << "'");
      CHECK(std::find(order.begin(), order.end(), k.group) != order.end());
      seen.insert(k.group);
    }
    // and each of those groups shows in the scene's summary
    std::size_t summarised = 0;
    for (const GroupSummary& g : summarise_groups(c)) summarised += static_cast<std::size_t>(g.checks);
    CHECK(summarised == c.checks.size());
  }
  for (const char* g : {"position", "angle", "rate", "torque", "modal", "attitude", "load", "H.drift",
                        "E.drift", "E.balance"})
    CHECK(seen.count(g) == 1);
}

// Loads follow the accelerations: a stiff mode amplifies an integration error in them. When they
// alone fail, compare says how to tell integration from physics.
TEST_CASE("compare: joint loads that fail while the motions agree get a note on how to tell integration from physics") {
  System s = two_body_system();
  auto off = [](const std::string& c, std::size_t r) { return baseline(c, r) + (c == "hinge.Mx" && r == 2 ? 1.0 : 0.0); };
  const SceneComparison c = compare_runs(s, {engine_run("b", make_run(s)), engine_run("a", make_run(s, off))});
  CHECK_FALSE(c.passed());
  CHECK(find_checks(c, "hinge.Mx")[0].status == CheckStatus::Fail);
  const auto noted = [](const SceneComparison& x) {
    return std::any_of(x.notes.begin(), x.notes.end(),
                       [](const std::string& n) { return n.rfind("joint loads differ while the motions agree", 0) == 0; });
  };
  CHECK(noted(c));
  // The same comparison again at tighter tolerances (diagnose: what compare_scene does with it):
  // where the difference stays, it is not integration error; where it falls 10-fold or more, it
  // is, with both figures; the advice above is replaced by the measurement.
  const auto diagnosed = [&](double tight_off) {
    auto tighter = [tight_off](const std::string& col, std::size_t r) {
      return baseline(col, r) + (col == "hinge.Mx" && r == 2 ? tight_off : 0.0);
    };
    SceneComparison x = c;
    crossdyn::harness::diagnose(
        x, compare_runs(s, {engine_run("b", make_run(s)), engine_run("a", make_run(s, tighter))}), 1e-12, 1e-12);
    CHECK_FALSE(noted(x));
    const auto n = std::find_if(x.notes.begin(), x.notes.end(),
                                [](const std::string& t) { return t.starts_with("tolerances 100 times tighter"); });
    REQUIRE(n != x.notes.end());
    return *n;
  };
  CHECK_THAT(diagnosed(1.0), Catch::StartsWith("tolerances 100 times tighter (--rtol 1.0e-12 --atol 1.0e-12): "
                                               "hinge.Mx (a vs b) is 1.0e+00, was 1.0e+00: it does not fall") &&
                                 Catch::Contains("not integration error"));
  CHECK_THAT(diagnosed(0.5), Catch::Contains("it does not fall with the tolerances"));
  CHECK_THAT(diagnosed(1e-3), Catch::Contains("every failed check's difference falls at least 10-fold, the "
                                              "largest, hinge.Mx (a vs b), from 1.0e+00 to 1.0e-03") &&
                                  Catch::Contains("integration error, not physics; joint loads follow") &&
                                  Catch::Contains("Some still fail there: tighten"));
  CHECK_THAT(diagnosed(1e-10), Catch::Contains("from 1.0e+00 to 1.0e-10") && Catch::Contains("Every check passes there"));
  // A motion that fails too: no such note (the loads are not the first thing wrong).
  auto both = [&off](const std::string& col, std::size_t r) { return off(col, r) + (col == "hinge.rate" && r == 2 ? 1.0 : 0.0); };
  const SceneComparison d = compare_runs(s, {engine_run("b", make_run(s)), engine_run("a", make_run(s, both))});
  CHECK_FALSE(noted(d));
}

// A user's scene (written from docs/writing-a-scene.md): a slowly turning bus, a sprung telescoping
// mast and a sprung two-axis gimbal. At the default tolerances (rkf78, 1e-10) the three engines'
// motions agree but the slider's and gimbal's forces differ by ~6e-8 N, 4.7 times their bound;
// compare runs the scene again 100 times tighter and says, with the figures, that the difference
// falls (integration error), and that every load passes there.
TEST_CASE("compare: loads that differ by integration error are measured as such, at tolerances 100 times tighter") {
  const System s = crossdyn::read_scene(crossdyn::test::source_dir() + "/tests/harness/scenes/telescope_gimbal.yaml");
  const SceneComparison c = compare_scene(s, {});
  CHECK_FALSE(c.passed());
  for (const Check& k : c.checks)
    if (k.status == CheckStatus::Fail) CHECK(k.group == "load");
  const auto note = std::find_if(c.notes.begin(), c.notes.end(),
                                 [](const std::string& n) { return n.starts_with("tolerances 100 times tighter"); });
  REQUIRE(note != c.notes.end());
  INFO(*note);
  CHECK_THAT(*note, Catch::StartsWith("tolerances 100 times tighter (--rtol 1.0e-12 --atol 1.0e-12): every failed "
                                      "check's difference falls at least 10-fold, the largest, slider.Fx"));
  CHECK_THAT(*note, Catch::Contains("integration error, not physics; joint loads follow"));
  CHECK_THAT(*note, Catch::Contains("Every check passes there"));
  // And so it is: at those tolerances nothing fails.
  CompareOptions tight;
  tight.rtol = 1e-12;
  tight.atol = 1e-12;
  CHECK(compare_scene(s, tight).passed());
}

// A user's scene (tests/harness/scenes/telescoping_flex.yaml): a prescribed slider pushes a free-free
// flexible boom out from a spinning bus. Nothing forces its modes (uniform and linear loads are
// orthogonal to free-free modes), so they hold integration noise, and their rates that noise times
// ~89 rad/s: boom.qy2_rate failed at the default tolerances by 12 times its bound. The class is not
// the loads': any failure whose difference falls with the tolerances is integration error, and
// compare says so with the figures.
TEST_CASE("compare: any failure that falls with the tolerances is measured as integration error (a flexible boom's unforced modal rates)") {
  const System s = crossdyn::read_scene(crossdyn::test::source_dir() + "/tests/harness/scenes/telescoping_flex.yaml");
  const SceneComparison c = compare_scene(s, {});
  CHECK_FALSE(c.passed());
  for (const Check& k : c.checks)
    if (k.status == CheckStatus::Fail) CHECK(k.group == "modal");
  const auto note = std::find_if(c.notes.begin(), c.notes.end(),
                                 [](const std::string& n) { return n.starts_with("tolerances 100 times tighter"); });
  REQUIRE(note != c.notes.end());
  INFO(*note);
  CHECK_THAT(*note, Catch::Contains("every failed check's difference falls at least 10-fold, the largest, boom.qy"));
  CHECK_THAT(*note, Catch::Contains("integration error, not physics. Every check passes there"));
  // With the diagnosis off: only the failures.
  CompareOptions off;
  off.diagnose = false;
  const SceneComparison d = compare_scene(s, off);
  CHECK_FALSE(d.passed());
  CHECK(std::none_of(d.notes.begin(), d.notes.end(),
                     [](const std::string& n) { return n.starts_with("tolerances 100 times tighter"); }));
}
