// What verify writes for machines: JUnit XML (parsed back with Boost.PropertyTree and checked for
// the testsuites/testsuite/testcase/failure structure and counts CI systems read) and the JSON
// summary (parsed back with nlohmann-json).
#include <catch2/catch.hpp>

#include "harness/report.hpp"
#include "harness/verify.hpp"
#include "tests/harness/synthetic.hpp"

#include <boost/property_tree/ptree.hpp>
#include <boost/property_tree/xml_parser.hpp>
#include <nlohmann/json.hpp>

#include <map>
#include <sstream>

using crossdyn::RunFailure;
using crossdyn::RunResult;
using crossdyn::System;
using crossdyn::harness::CheckStatus;
using crossdyn::harness::compare_runs;
using crossdyn::harness::EngineRun;
using crossdyn::harness::SceneComparison;
using crossdyn::harness::SceneOutcome;
using crossdyn::test::baseline;
using crossdyn::test::engine_run;
using crossdyn::test::make_run;
using crossdyn::test::two_body_system;
namespace pt = boost::property_tree;

namespace {

// Four scenes: all pass; a tolerance failure and a failed run; unreadable; skipped and excluded.
std::vector<SceneOutcome> outcomes() {
  std::vector<SceneOutcome> out;
  System good = two_body_system();
  good.name = "good";
  out.push_back({"scenarios/good.yaml", good,
                 compare_runs(good, {engine_run("kane", make_run(good)), engine_run("lagrange", make_run(good))}),
                 ""});
  // A scene warning: not a failure; a property and the suite's <system-err> in JUnit.
  crossdyn::SceneWarning w;
  w.file = "scenarios/good.yaml";
  w.code = "cm-inboard";
  w.subject = "hinge";
  w.message = "hinge: arm's CM is inboard of the joint, inside hub's box: check the sign of <child_point>";
  out.back().warnings.push_back(w);

  System bad = two_body_system();
  bad.name = "bad";
  auto off = [](const std::string& c, std::size_t r) { return baseline(c, r) + (c == "hinge.rate" && r == 2 ? 1e-3 : 0.0); };
  RunResult broken = make_run(bad);
  broken.data.resize(broken.columns.size());
  broken.failure = RunFailure("newton-euler", 0.125, "arm.wx", "step-size underflow");
  EngineRun failed = engine_run("newton-euler", broken);
  failed.state = EngineRun::State::Failed;
  failed.note = broken.failure->what();
  out.push_back({"scenarios/bad.yaml", bad,
                 compare_runs(bad, {engine_run("kane", make_run(bad)), engine_run("lagrange", make_run(bad, off)), failed}),
                 ""});

  out.push_back({"scenarios/broken.yaml", std::nullopt, std::nullopt,
                 "scenarios/broken.yaml:3:5: bodies[0].mass: expected a positive mass, found -1 kg"});

  System partial = two_body_system();
  partial.name = "partial";
  partial.compare.excluded = {{"hinge.angle", "the <angle> & \"rate\" are not comparable"}};
  EngineRun missing;
  missing.label = missing.engine = "newton-euler";
  missing.state = EngineRun::State::NotBuilt;
  missing.note = "engine newton-euler not built yet";
  out.push_back({"scenarios/partial.yaml", partial,
                 compare_runs(partial, {engine_run("kane", make_run(partial)), engine_run("lagrange", make_run(partial)), missing}),
                 ""});
  return out;
}

int attr_int(const pt::ptree& node, const std::string& name) {
  return node.get<int>("<xmlattr>." + name);
}

}  // namespace

TEST_CASE("junit: testsuites / testsuite / testcase structure with consistent counts") {
  const std::vector<SceneOutcome> scenes = outcomes();
  const std::string xml = crossdyn::harness::junit_xml(scenes);
  REQUIRE(xml.rfind("<?xml version=\"1.0\" encoding=\"UTF-8\"?>", 0) == 0);
  std::istringstream in(xml);
  pt::ptree doc;
  REQUIRE_NOTHROW(pt::read_xml(in, doc));
  REQUIRE(doc.size() == 1);
  REQUIRE(doc.front().first == "testsuites");
  const pt::ptree& root = doc.front().second;

  int suites = 0, tests = 0, failures = 0, errors = 0, skipped = 0;
  std::map<std::string, const pt::ptree*> suite_by_name;
  for (const auto& [tag, suite] : root) {
    if (tag == "<xmlattr>") continue;
    REQUIRE(tag == "testsuite");
    ++suites;
    suite_by_name[suite.get<std::string>("<xmlattr>.name")] = &suite;
    int n = 0, f = 0, e = 0, s = 0;
    for (const auto& [ctag, tc] : suite) {
      if (ctag == "<xmlattr>" || ctag == "properties" || ctag == "system-err") continue;
      REQUIRE(ctag == "testcase");
      ++n;
      CHECK(tc.get<std::string>("<xmlattr>.classname").rfind("crossdyn.verify.", 0) == 0);
      CHECK_FALSE(tc.get<std::string>("<xmlattr>.name").empty());
      f += static_cast<int>(tc.count("failure"));
      e += static_cast<int>(tc.count("error"));
      s += static_cast<int>(tc.count("skipped"));
    }
    CHECK(attr_int(suite, "tests") == n);
    CHECK(attr_int(suite, "failures") == f);
    CHECK(attr_int(suite, "errors") == e);
    CHECK(attr_int(suite, "skipped") == s);
    tests += n;
    failures += f;
    errors += e;
    skipped += s;
  }
  CHECK(suites == 4);
  CHECK(attr_int(root, "tests") == tests);
  CHECK(attr_int(root, "failures") == failures);
  CHECK(attr_int(root, "errors") == errors);
  CHECK(attr_int(root, "skipped") == skipped);
  // One case per engine run and per quantity: 2 runs + 12 pair quantities + 2 drifts, and issue
  // 26's 22 (2 bodies x 3 positions, CM 3, H vector 3, the hinge's 6 loads, P, M 3).
  CHECK(attr_int(*suite_by_name.at("good"), "tests") == 38);
  CHECK(attr_int(*suite_by_name.at("good"), "failures") == 0);
  // The warning: a property of its scene's suite, and the line crossdyn printed in <system-err>;
  // the other suites have neither.
  std::vector<std::string> warning_properties;
  for (const auto& [tag, p] : suite_by_name.at("good")->get_child("properties"))
    if (p.get<std::string>("<xmlattr>.name") == "warning") warning_properties.push_back(p.get<std::string>("<xmlattr>.value"));
  CHECK(warning_properties == std::vector<std::string>{
                                  "cm-inboard: hinge: arm's CM is inboard of the joint, inside hub's box: "
                                  "check the sign of <child_point>"});
  CHECK(suite_by_name.at("good")->get<std::string>("system-err") ==
        "crossdyn: warning: scenarios/good.yaml: hinge: arm's CM is inboard of the joint, inside hub's box: "
        "check the sign of <child_point>\n");
  CHECK(suite_by_name.at("bad")->count("system-err") == 0);
  CHECK(suite_by_name.at("bad")->get_child("properties").size() == 1);
  // bad: hinge.rate fails (lagrange vs kane) and newton-euler's run fails.
  CHECK(attr_int(*suite_by_name.at("bad"), "failures") == 2);
  CHECK(attr_int(*suite_by_name.at("broken"), "errors") == 1);
  // partial: newton-euler skipped, hinge.angle excluded.
  CHECK(attr_int(*suite_by_name.at("partial"), "skipped") == 2);

  // The failures carry the numbers: quantity, pair, error, time, bound.
  bool saw_rate = false, saw_run = false;
  for (const auto& [tag, tc] : *suite_by_name.at("bad")) {
    if (tag != "testcase" || !tc.count("failure")) continue;
    const std::string name = tc.get<std::string>("<xmlattr>.name");
    const std::string message = tc.get<std::string>("failure.<xmlattr>.message");
    if (name == "hinge.rate") {
      saw_rate = true;
      CHECK(message.find("hinge.rate, lagrange vs kane: max error 1.000e-03 at t = 0.5 s > bound") != std::string::npos);
      CHECK(tc.get<std::string>("failure.<xmlattr>.type") == "tolerance");
    }
    if (name == "run newton-euler") {
      saw_run = true;
      CHECK(message.find("run failed at t = 0.125 s") != std::string::npos);
      CHECK(message.find("step-size underflow") != std::string::npos);
      CHECK(tc.get<std::string>("failure.<xmlattr>.type") == "RunFailure");
    }
  }
  CHECK(saw_rate);
  CHECK(saw_run);
  // Special characters survive escaping.
  bool saw_reason = false;
  for (const auto& [tag, tc] : *suite_by_name.at("partial"))
    if (tag == "testcase" && tc.get<std::string>("<xmlattr>.name") == "hinge.angle") {
      saw_reason = true;
      CHECK(tc.get<std::string>("skipped.<xmlattr>.message") ==
            "excluded: the <angle> & \"rate\" are not comparable");
    }
  CHECK(saw_reason);
}

TEST_CASE("json summary: counts, every check with its numbers, scene data, unreadable scenes") {
  const std::vector<SceneOutcome> scenes = outcomes();
  const nlohmann::json j = nlohmann::json::parse(crossdyn::harness::json_summary(scenes));
  CHECK(j["passed"] == false);
  CHECK(j["counts"]["scenes"] == 4);
  CHECK(j["counts"]["scenes_failed"] == 1);
  CHECK(j["counts"]["scenes_unreadable"] == 1);
  int checks = 0, failed = 0;
  for (const SceneOutcome& s : scenes)
    if (s.comparison) {
      checks += static_cast<int>(s.comparison->checks.size());
      failed += s.comparison->count(CheckStatus::Fail);
    }
  CHECK(j["counts"]["checks"] == checks);
  CHECK(j["counts"]["checks_failed"] == failed);
  // The scenes' warnings: a list per scene (empty for none, and for an unreadable scene), counted;
  // not failures.
  CHECK(j["counts"]["warnings"] == 1);
  CHECK(j["scenes"][0]["passed"] == true);
  REQUIRE(j["scenes"][0]["warnings"].size() == 1);
  CHECK(j["scenes"][0]["warnings"][0]["code"] == "cm-inboard");
  CHECK(j["scenes"][0]["warnings"][0]["subject"] == "hinge");
  CHECK(j["scenes"][0]["warnings"][0]["line"].is_null());
  CHECK(j["scenes"][0]["warnings"][0]["message"] ==
        "hinge: arm's CM is inboard of the joint, inside hub's box: check the sign of <child_point>");
  for (int i : {1, 2, 3}) CHECK(j["scenes"][i]["warnings"] == nlohmann::json::array());
  REQUIRE(j["scenes"].size() == 4);

  const nlohmann::json& bad = j["scenes"][1];
  CHECK(bad["scene"] == "bad");
  CHECK(bad["passed"] == false);
  CHECK(bad["page"] == "bad.html");
  CHECK(bad["checks"].size() == scenes[1].comparison->checks.size());
  bool saw = false;
  for (const nlohmann::json& c : bad["checks"])
    if (c["quantity"] == "hinge.rate") {
      saw = true;
      CHECK(c["status"] == "FAIL");
      CHECK(c["a"] == "lagrange");
      CHECK(c["b"] == "kane");
      CHECK(c["time"] == 0.5);
      CHECK(c["first_exceeded"] == 0.5);
      CHECK(c["error"].get<double>() == Approx(1e-3).epsilon(1e-9));
      CHECK(c["bound"].get<double>() == Approx(2e-8).epsilon(1e-12));
    } else if (c["quantity"] == "run" && c["a"] == "newton-euler") {
      CHECK(c["status"] == "FAIL");
      CHECK(c["error"].is_null());  // infinite: not a JSON number
      CHECK(c["time"] == 0.125);
    }
  CHECK(saw);
  CHECK(bad["runs"][2]["state"] == "failed");
  CHECK(bad["runs"][2]["failure"]["reason"] == "step-size underflow");
  CHECK(bad["system"]["bodies"][0]["mass_kg"] == 10.0);
  CHECK(bad["system"]["joints"][1]["type"] == "revolute");
  bool rate_group = false;
  for (const nlohmann::json& g : bad["groups"])
    if (g["group"] == "rate") {
      rate_group = true;
      CHECK(g["status"] == "FAIL");
      CHECK(g["worst"].get<double>() > 1);
      CHECK(g["worst_check"] == "hinge.rate lagrange vs kane");
    }
  CHECK(rate_group);

  CHECK(j["scenes"][2]["input_error"].get<std::string>().find("expected a positive mass") != std::string::npos);
  CHECK(j["scenes"][3]["runs"][2]["state"] == "skipped");
  CHECK(j["scenes"][0]["passed"] == true);
}

TEST_CASE("verify: exit status 0 all pass, 1 a check failed, 2 a scene could not be read") {
  std::vector<SceneOutcome> scenes = outcomes();
  crossdyn::harness::VerifyResult r;
  r.scenes = {scenes[0], scenes[3]};
  CHECK(r.exit_code() == 0);
  r.scenes.push_back(scenes[1]);
  CHECK(r.exit_code() == 1);
  r.scenes.push_back(scenes[2]);
  CHECK(r.exit_code() == 2);
  const std::string table = crossdyn::harness::format_verify_table(r);
  CHECK(table.find("BAD INPUT") != std::string::npos);
  CHECK(table.find("bad: hinge.rate, lagrange vs kane: max error") != std::string::npos);
  CHECK(table.find("4 scenes") != std::string::npos);
}
