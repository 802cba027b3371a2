// Scene warnings reach the terminal and CI (issue 24, item 5): run, compare, draw and verify print
// each of a scene's warnings on stderr exactly once ("crossdyn: warning: <file>: <message>"),
// --quiet or not, and exit 0; --strict makes that exit status 1 after writing every output;
// verify's table, JSON summary, JUnit XML and report carry them; merge of verify's parts carries
// them and refuses a part without them; a clean committed scene prints none.
#include <catch2/catch.hpp>

#include "tests/cli/cli_helpers.hpp"

#include <nlohmann/json.hpp>

#include <sstream>
#include <string>
#include <vector>

using namespace crossdyn::test;

namespace {

// Every kind of warning a scene can have (tests/harness/test_scene_warnings.cpp has the same).
const char* const kWarned = R"(name: warned
description: Every kind of scene warning a scene can have, for tests.
source: crossdyn tests.
bodies:
  - name: hub
    mass: 100
    inertia: [10, 20, 25]
    torque: {profile: [{t: 0, value: [0, 0, 0]}, {t: 5 s, value: [0, 0, 0.1]}]}
  - {name: panel1, mass: 5, inertia: [1, 1, 1]}
  - {name: panel2, mass: 5, inertia: [1, 1, 1]}
  - {name: arm, mass: 2, inertia: [0.1, 0.1, 0.1]}
joints:
  - {name: base, type: free, child: hub, initial: {angular_velocity: [0.1, 0, 0.2]}}
  - name: hinge1
    type: revolute
    parent: hub
    child: panel1
    parent_point: [0, 1, 0]
    child_point: [0, -1, 0]
    axis: [1, 0, 0]
    spring: {stiffness: 10, neutral_angle: 7}
  - {name: hinge2, type: revolute, parent: hub, child: panel2, parent_point: [0, -1, 0], child_point: [0, 1, 0], axis: [1, 0, 0], spring: {stiffness: 10}}
  - {name: elbow, type: revolute, parent: hub, child: arm, parent_point: [0.5, 0, 0], child_point: [0.3, 0, 0], axis: [0, 0, 1]}
run: {duration: 0.5, output_step: 0.05}
)";

// What crossdyn prints for kWarned written as `file`, and the codes, in order.
std::vector<std::string> warned_lines(const std::string& file) {
  const std::string p = "crossdyn: warning: " + file + ": ";
  return {p + "line 21: joints[1].spring.neutral_angle: 7 has no unit and is read as 7 rad = 401.1 deg; "
              "write '7 deg' or '7 rad'",
          p + "line 8: bodies[0].torque.profile[1].t: this step at t = 5 s is after the run's end "
              "(run.duration 0.5 s), so it is never applied",
          p + "elbow: arm's CM is inboard of the joint, inside hub's box: check the sign of child_point "
              "and the offset",
          p + "hinge1 and hinge2 carry identical bodies at mirror-image points of hub, yet a positive "
              "angle moves them other than as mirror images (panel1 towards N +z, panel2 towards N -z)"};
}
const std::vector<std::string> kCodes{"angle-unitless-large", "profile-after-end", "cm-inboard", "mirror-axes"};

std::size_t count(const std::string& text, const std::string& part) {
  std::size_t n = 0;
  for (std::size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + part.size())) ++n;
  return n;
}

// Every line of stderr that is a warning.
std::vector<std::string> warning_lines(const std::string& err) {
  std::vector<std::string> out;
  std::istringstream in(err);
  for (std::string line; std::getline(in, line);)
    if (line.find("warning") != std::string::npos) out.push_back(line);
  return out;
}

// The commands as a CI job runs them, each writing its outputs in the scratch folder.
const std::vector<std::string> kCommands{"run SCENE -o out.csv", "compare SCENE --json c.json",
                                         "draw SCENE -o p.png --no-motion --geometry g.json",
                                         "verify SCENE --no-converge --json v.json --junit v.xml"};

std::string with_scene(std::string command, const std::string& scene) {
  return command.replace(command.find("SCENE"), 5, scene);
}

void remove_outputs(const Scratch& s) {
  for (const char* f : {"out.csv", "c.json", "p.png", "g.json", "v.json", "v.xml"}) fs::remove(s.dir() / f);
}

}  // namespace

TEST_CASE("scene warnings: run, compare, draw and verify print each warning once on stderr and exit 0, --quiet too") {
  Scratch s("warned");
  s.write("warned.yaml", kWarned);
  for (const std::string& command : kCommands)
    for (const char* quiet : {"", " -q"}) {
      if (*quiet && contains(command, "draw ")) continue;  // draw prints no progress, has no --quiet
      remove_outputs(s);
      const Run r = run_in(s.dir(), with_scene(command, "warned.yaml") + quiet);
      INFO(command << quiet << "\n" << r.out << r.err);
      CHECK(r.status == 0);
      CHECK(warning_lines(r.err) == warned_lines("warned.yaml"));  // each once, in order, nothing else
    }
  // A scene named twice in one verify is two scenes: its warnings twice, once per scene.
  const Run r = run_in(s.dir(), "verify warned.yaml warned.yaml --no-converge -q --json v.json");
  INFO(r.out << r.err);
  CHECK(r.status == 0);
  for (const std::string& line : warned_lines("warned.yaml")) CHECK(count(r.err, line + "\n") == 2);
}

TEST_CASE("scene warnings: --strict exits with status 1 after writing every output, and only then") {
  Scratch s("strict");
  s.write("warned.yaml", kWarned);
  s.write("clean.yaml", kSmallScene);
  for (const std::string& command : kCommands) {
    remove_outputs(s);
    Run r = run_in(s.dir(), with_scene(command, "warned.yaml") + " --strict");
    INFO(command << "\n" << r.out << r.err);
    CHECK(r.status == 1);
    CHECK(warning_lines(r.err) == warned_lines("warned.yaml"));
    // The work was done and its outputs written as usual.
    for (const char* f : {"out.csv", "c.json", "p.png", "g.json", "v.json", "v.xml"})
      if (contains(command, std::string(" ") + f)) CHECK(fs::file_size(s.dir() / f) > 0);
    // A scene without warnings: 0.
    r = run_in(s.dir(), with_scene(command, "clean.yaml") + " --strict");
    CHECK(r.status == 0);
    CHECK(warning_lines(r.err).empty());
  }
  // A worse status stands: a failed check is 1, bad input 2, whatever the warnings.
  Run r = run_in(s.dir(), "compare warned.yaml -q --strict --test-inertia-scale kane=1.01");
  CHECK(r.status == 1);
  CHECK(contains(r.out, "FAIL"));
  s.write("bad.yaml", "name: [unclosed\n");
  r = run_in(s.dir(), "verify warned.yaml bad.yaml -q --no-converge --strict --json v.json");
  CHECK(r.status == 2);
  CHECK(warning_lines(r.err).size() == 4);
  // The help says what --strict does.
  for (const char* command : {"run", "compare", "draw", "verify", "merge"}) {
    r = run_in(s.dir(), std::string(command) + " --help");
    INFO(command << "\n" << r.out);
    CHECK(contains(r.out, "--strict"));
  }
}

TEST_CASE("scene warnings: verify's table, JSON summary and JUnit XML carry each scene's warnings, not as failures") {
  Scratch s("verify_warned");
  s.write("warned.yaml", kWarned);
  const Run r = run_in(s.dir(), "verify warned.yaml " + quote(scene_path("spear1_case1")) +
                                    " -q --no-converge --json v.json --junit v.xml");
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  // The table: every warning under its scene with its code, and the count in the totals line.
  CHECK(contains(r.out, "\nscene warnings (not failures):\n"));
  const std::vector<std::string> lines = warned_lines("warned.yaml");
  for (std::size_t i = 0; i < lines.size(); ++i)
    CHECK(contains(r.out, "  warned: " + lines[i].substr(std::string("crossdyn: warning: warned.yaml: ").size()) +
                              " [" + kCodes[i] + "]\n"));
  CHECK(contains(r.out, " 0 skipped; 4 scene warnings\n"));
  // JSON: a "warnings" list per scene (the clean one's empty), the count; "passed" unchanged.
  const auto j = nlohmann::json::parse(read_file(s.path("v.json")));
  CHECK(j["passed"] == true);
  CHECK(j["counts"]["warnings"] == 4);
  REQUIRE(j["scenes"].size() == 2);
  REQUIRE(j["scenes"][0]["warnings"].size() == 4);
  for (std::size_t i = 0; i < 4; ++i) {
    CHECK(j["scenes"][0]["warnings"][i]["code"] == kCodes[i]);
    CHECK("crossdyn: warning: warned.yaml: " + j["scenes"][0]["warnings"][i]["message"].get<std::string>() == lines[i]);
  }
  CHECK(j["scenes"][0]["warnings"][0]["line"] == 21);
  CHECK(j["scenes"][0]["warnings"][2]["subject"] == "elbow");
  CHECK(j["scenes"][1]["warnings"] == nlohmann::json::array());
  // JUnit: a property per warning and the printed lines in the scene's <system-err>; no failure.
  const std::string xml = read_file(s.path("v.xml"));
  CHECK(count(xml, "<property name=\"warning\" value=\"") == 4);
  CHECK(contains(xml, "<property name=\"warning\" value=\"cm-inboard: elbow: arm&apos;s CM is inboard"));
  CHECK(count(xml, "<system-err>") == 1);
  CHECK(contains(xml, "<system-err>crossdyn: warning: warned.yaml: line 21: joints[1].spring.neutral_angle"));
  CHECK(contains(xml, "failures=\"0\" errors=\"0\""));
  CHECK_FALSE(contains(xml, "<failure"));
}

TEST_CASE("scene warnings: the verify report lists them on the index and the scene's page") {
  Scratch s("report_warned");
  s.write("warned.yaml", kWarned);
  const Run r = run_in(s.dir(), "verify warned.yaml -q --no-converge --report=out");
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  const std::string index = read_file(s.path("out/index.html"));
  CHECK(contains(index, "<h2 id=\"warnings\">Scene warnings</h2>"));
  CHECK(contains(index, "4 scene warnings: look at the picture"));
  CHECK(contains(index, "elbow: arm&#39;s CM is inboard of the joint"));
  CHECK(contains(index, "[mirror-axes]"));
  const std::string page = read_file(s.path("out/warned.html"));
  CHECK(contains(page, "id=\"warnings\""));
  CHECK(count(page, "<li>") >= 4);
  CHECK(contains(page, "line 8: bodies[0].torque.profile[1].t: this step at t = 5 s is after the run"));
  // The picture is drawn from the geometry that holds the same warnings.
  const auto geometry = nlohmann::json::parse(read_file(s.path("out/data/warned/geometry.json")));
  REQUIRE(geometry["warnings"].size() == 4);
  CHECK(geometry["warnings"][3]["code"] == "mirror-axes");
}

TEST_CASE("scene warnings: merge of verify's parts carries them, prints them once, --strict, and a part without them is refused") {
  Scratch s("merge_warned");
  s.write("warned.yaml", kWarned);
  s.write("clean.yaml", kSmallScene);
  const std::string scenes = " warned.yaml clean.yaml --no-converge -q";
  for (int k = 0; k < 2; ++k) {
    const Run r = run_in(s.dir(), "verify" + scenes + " --shard " + std::to_string(k) + "/2 --part p" +
                                      std::to_string(k) + ".json");
    INFO(r.out << r.err);
    REQUIRE(r.status == 0);
  }
  const Run whole = run_in(s.dir(), "verify" + scenes + " --json whole.json --junit whole.xml");
  REQUIRE(whole.status == 0);
  Run r = run_in(s.dir(), "merge p0.json p1.json -q --json m.json --junit m.xml");
  INFO(r.out << r.err);
  CHECK(r.status == 0);
  CHECK(warning_lines(r.err) == warned_lines("warned.yaml"));
  // The table, warnings and totals included (the lines naming the output files differ).
  const auto table = [](const std::string& out) { return out.substr(0, out.find("\nJSON summary: ")); };
  CHECK(table(r.out) == table(whole.out));
  CHECK(contains(table(r.out), "\nscene warnings (not failures):\n"));
  const auto m = nlohmann::json::parse(read_file(s.path("m.json")));
  const auto w = nlohmann::json::parse(read_file(s.path("whole.json")));
  CHECK(m["counts"]["warnings"] == 4);
  CHECK(m["scenes"][0]["warnings"] == w["scenes"][0]["warnings"]);
  CHECK(m["scenes"][1]["warnings"] == nlohmann::json::array());
  // JUnit: the same properties and <system-err> (the run times are each run's own).
  const auto warning_parts = [](const std::string& xml) {
    std::vector<std::string> out;
    std::istringstream in(xml);
    for (std::string line; std::getline(in, line);)
      if (contains(line, "name=\"warning\"") || contains(line, "system-err") || contains(line, "crossdyn: warning"))
        out.push_back(line);
    return out;
  };
  CHECK(warning_parts(read_file(s.path("m.xml"))) == warning_parts(read_file(s.path("whole.xml"))));
  CHECK(warning_parts(read_file(s.path("m.xml"))).size() == 9);  // 4 properties, 4 lines, </system-err>
  CHECK(run_in(s.dir(), "merge p0.json p1.json -q --strict --json m.json").status == 1);

  // A part without the warnings (an older crossdyn's) is refused, naming the field and why.
  std::string part = "p1.json";
  const nlohmann::json p0 = nlohmann::json::parse(read_file(s.path("p0.json")));
  for (const auto& o : p0["outcomes"])
    if (o["path"] == "warned.yaml") part = "p0.json";
  auto j = nlohmann::json::parse(read_file(s.path(part)));
  REQUIRE(j["outcomes"].size() == 1);
  REQUIRE(j["outcomes"][0]["warnings"].size() == 4);
  nlohmann::json old = j;
  for (auto& o : old["outcomes"]) o.erase("warnings");
  s.write("old.json", old.dump());
  const std::string other = part == "p0.json" ? "p1.json" : "p0.json";
  r = run_in(s.dir(), "merge old.json " + other + " -q --json m.json");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "/warnings' is missing: the part was written by an older crossdyn, which did "
                        "not carry the scenes' warnings; run that shard again"));
  // A geometry warning edited: refused, as an edited check is.
  nlohmann::json edited = j;
  for (auto& o : edited["outcomes"])
    for (auto& x : o["warnings"])
      if (x["code"] == "cm-inboard") x["message"] = "elbow: nothing to see";
  s.write("edited.json", edited.dump());
  r = run_in(s.dir(), "merge edited.json " + other + " -q --json m.json");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "field 'warnings' is not what its scene gives"));
}

TEST_CASE("scene warnings: a clean committed scene (spear1_case1) prints none") {
  Scratch s("clean_committed");
  const std::string scene = quote(scene_path("spear1_case1"));
  for (const std::string& command : {"run " + scene + " -o out.csv --strict", "compare " + scene + " --strict",
                                     "draw " + scene + " -o p.png --no-motion --strict",
                                     "verify " + scene + " --no-converge --json v.json --strict"}) {
    const Run r = run_in(s.dir(), command);
    INFO(command << "\n" << r.out << r.err);
    CHECK(r.status == 0);
    CHECK(warning_lines(r.err).empty());
  }
}
