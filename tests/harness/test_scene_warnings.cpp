// Scene warnings (harness/scene_warnings.hpp): each check fires on the mistake it is for, with the
// drawing's wording, and not on the correct scene; the reader's warnings keep their line; every
// committed scene's warnings are known and reviewed; the geometry document carries them.
#include <catch2/catch.hpp>

#include "core/scene/scene.hpp"
#include "harness/scene_geometry.hpp"
#include "harness/scene_warnings.hpp"
#include "tests/support/paths.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <map>

namespace h = crossdyn::harness;
using crossdyn::SceneWarning;
using crossdyn::System;

namespace {

std::string source(const std::string& rel) { return crossdyn::test::source_dir() + "/" + rel; }

std::vector<std::string> codes(const std::vector<SceneWarning>& w) {
  std::vector<std::string> out;
  for (const SceneWarning& x : w) out.push_back(x.code);
  return out;
}

// Every kind of warning a scene can have: a unitless angle above 2 pi (line 21), a torque step
// after the run's end (line 8), a child folded into its parent (elbow), mirror-image panels on
// hinges about one axis (hinge1, hinge2).
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

std::vector<SceneWarning> warnings_of_text(const std::string& text, const std::string& label = "w.yaml") {
  std::vector<SceneWarning> reader;
  const System s = crossdyn::read_scene_text(text, label, &reader);
  return h::scene_warnings(s, reader);
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  REQUIRE(at != std::string::npos);
  return text.replace(at, from.size(), to);
}

}  // namespace

TEST_CASE("scene warnings: every kind a scene can have, in order, with code, subject, line and the drawing's words") {
  const std::vector<SceneWarning> w = warnings_of_text(kWarned);
  REQUIRE(codes(w) == std::vector<std::string>{"angle-unitless-large", "profile-after-end", "cm-inboard",
                                               "mirror-axes"});
  CHECK(w[0].subject == "joints[1].spring.neutral_angle");
  CHECK(w[0].line == 21);
  CHECK(w[0].detail() == "line 21: joints[1].spring.neutral_angle: 7 has no unit and is read as 7 rad = "
                         "401.1 deg; write '7 deg' or '7 rad'");
  CHECK(w[1].subject == "bodies[0].torque.profile[1].t");
  CHECK(w[1].line == 8);
  CHECK(w[1].detail() == "line 8: bodies[0].torque.profile[1].t: this step at t = 5 s is after the run's "
                         "end (run.duration 0.5 s), so it is never applied");
  CHECK(w[2].subject == "elbow");
  CHECK(w[2].line == 0);
  CHECK(w[2].detail() == "elbow: arm's CM is inboard of the joint, inside hub's box: check the sign of "
                         "child_point and the offset");
  CHECK(w[3].subject == "hinge1 and hinge2");
  CHECK(w[3].detail() == "hinge1 and hinge2 carry identical bodies at mirror-image points of hub, yet a "
                         "positive angle moves them other than as mirror images (panel1 towards N +z, "
                         "panel2 towards N -z)");
  for (const SceneWarning& x : w) {
    CHECK(x.file == "w.yaml");
    CHECK(h::warning_line(x) == "crossdyn: warning: w.yaml: " + x.detail());
  }
  // Each fixed alone, its warning goes and the others stay.
  CHECK(codes(warnings_of_text(replaced(kWarned, "neutral_angle: 7}", "neutral_angle: 7 deg}"))) ==
        std::vector<std::string>{"profile-after-end", "cm-inboard", "mirror-axes"});
  CHECK(codes(warnings_of_text(replaced(kWarned, "{t: 5 s,", "{t: 0.25 s,"))) ==
        std::vector<std::string>{"angle-unitless-large", "cm-inboard", "mirror-axes"});
  CHECK(codes(warnings_of_text(replaced(kWarned, "child_point: [0.3, 0, 0]", "child_point: [-0.3, 0, 0]"))) ==
        std::vector<std::string>{"angle-unitless-large", "profile-after-end", "mirror-axes"});
  CHECK(codes(warnings_of_text(replaced(kWarned, "child_point: [0, 1, 0], axis: [1, 0, 0]",
                                        "child_point: [0, 1, 0], axis: [-1, 0, 0]"))) ==
        std::vector<std::string>{"angle-unitless-large", "profile-after-end", "cm-inboard"});
}

TEST_CASE("scene warnings: the hinged panels, and the copies with a flipped axis or child_point") {
  const auto of = [](const std::string& name) {
    return h::read_checked_scene(source("tests/harness/scenes/" + name + ".yaml")).warnings;
  };
  CHECK(of("hinged_panels").empty());
  const std::vector<SceneWarning> axis = of("hinged_panels_flipped_axis");
  REQUIRE(codes(axis) == std::vector<std::string>{"mirror-axes"});
  CHECK(axis[0].message == "hinge1 and hinge2 carry identical bodies at mirror-image points of hub, yet a "
                           "positive angle moves them other than as mirror images (panel1 towards N -z, "
                           "panel2 towards N +z)");
  const std::vector<SceneWarning> point = of("hinged_panels_flipped_child_point");
  REQUIRE(codes(point) == std::vector<std::string>{"cm-inboard", "mirror-axes"});
  CHECK(point[0].message == "hinge1: panel1's CM is inboard of the joint, inside hub's box: check the sign "
                            "of child_point and the offset");
  CHECK(point[0].file == source("tests/harness/scenes/hinged_panels_flipped_child_point.yaml"));
}

TEST_CASE("scene warnings: a rotor about its own CM inside its parent, and a child outboard, are not folded") {
  // The hub's equivalent box is a 2 m cube (100 kg, 66.67 kg m^2 about each axis).
  const std::string base = R"(name: fold
description: A hub and an arm, for the folded-child check.
source: crossdyn tests.
bodies:
  - {name: hub, mass: 100, inertia: [66.6666666667, 66.6666666667, 66.6666666667]}
  - {name: arm, mass: 1, inertia: [0.1, 0.1, 0.1]}
joints:
  - {name: base, type: free, child: hub}
  - {name: hinge, type: revolute, parent: hub, child: arm, parent_point: [0.5, 0, 0], child_point: CP, axis: [0, 0, 1]}
run: {duration: 0.5, output_step: 0.05}
)";
  const auto with = [&base](const std::string& cp) { return codes(warnings_of_text(replaced(base, "CP", cp))); };
  CHECK(with("[0.3, 0, 0]") == std::vector<std::string>{"cm-inboard"});   // CM at 0.2 m: inside, inboard
  CHECK(with("[-0.3, 0, 0]").empty());                                     // outboard
  CHECK(with("[0, 0, 0]").empty());                                        // a rotor: CM on the joint
  CHECK(with("[1.7, 0, 0]").empty());  // CM at -1.2 m: inboard, but outside the hub's box (half side 1)
  CHECK(with("[1.4, 0, 0]") == std::vector<std::string>{"cm-inboard"});  // at -0.9 m: inside
  CHECK(with("[0.1, 0.8, 0]").empty());  // mostly sideways of the joint: not back into the parent
  // The threshold: more than 0.3 of the way back (cosine of the angle to the way out below -0.3).
  CHECK(with("[0.3, 0.4, 0]") == std::vector<std::string>{"cm-inboard"});  // cosine -0.6
  CHECK(with("[0.1, 0.49, 0]").empty());                                    // cosine -0.2
}

TEST_CASE("scene warnings: joint-gap and axis-mismatch on a configuration whose joint points or axes disagree") {
  const System s = crossdyn::read_scene(source("tests/harness/scenes/hinged_panels.yaml"));
  namespace g = h::geometry;
  g::Configuration c = g::initial_configuration(s);
  CHECK(h::configuration_warnings(s, c).empty());
  CHECK(h::geometry_warnings(s).empty());
  c.joints[2].p_NoJ_N_child += Eigen::Vector3d(0, 0, 0.25);
  c.joints[1].axis_N_child = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()) * c.joints[1].axis_N_parent;
  const std::vector<SceneWarning> w = h::configuration_warnings(s, c);
  REQUIRE(codes(w) == std::vector<std::string>{"axis-mismatch", "joint-gap"});
  CHECK(w[0].message == "hinge1: the axis fixed in the child is 5.73 deg off the parent's");
  CHECK(w[0].subject == "hinge1");
  CHECK(w[1].message == "hinge2: the parent's and the child's joint points are 0.25 m apart");
}

TEST_CASE("scene warnings: a profile step at or after the run's end, once per profile, motors too") {
  const std::string base = R"(name: prof
description: A hub and a motorised arm, for the profile check.
source: crossdyn tests.
bodies:
  - {name: hub, mass: 100, inertia: [10, 20, 25], torque: {profile: HUB}}
  - {name: arm, mass: 1, inertia: [0.1, 0.1, 0.1]}
joints:
  - {name: base, type: free, child: hub}
  - {name: hinge, type: revolute, parent: hub, child: arm, parent_point: [0.5, 0, 0], child_point: [-0.5, 0, 0], axis: [0, 0, 1], motor: {profile: MOTOR}}
run: {duration: 10 s, output_step: 0.5 s}
)";
  const auto with = [&base](const std::string& hub, const std::string& motor) {
    return warnings_of_text(replaced(replaced(base, "HUB", hub), "MOTOR", motor));
  };
  const std::string before = "[{t: 0, value: [0, 0, 1]}, {t: 9.99, value: [0, 0, 0]}]";
  CHECK(with(before, "[{t: 0, value: 1}]").empty());
  // At the end exactly: "at"; after, with the later steps counted.
  std::vector<SceneWarning> w = with("[{t: 0, value: [0, 0, 1]}, {t: 10 s, value: [0, 0, 0]}]",
                                     "[{t: 0, value: 1}, {t: 20, value: 0}, {t: 30, value: 1}, {t: 40, value: 0}]");
  REQUIRE(codes(w) == std::vector<std::string>{"profile-after-end", "profile-after-end"});
  CHECK(w[0].key == "bodies[0].torque.profile[1].t");
  CHECK(w[0].message == "this step at t = 10 s is at the run's end (run.duration 10 s), so it is never applied");
  CHECK(w[1].key == "joints[1].motor.profile[1].t");
  CHECK(w[1].message == "this step at t = 20 s is after the run's end (run.duration 10 s), so it is never "
                        "applied (nor are the 2 steps after it)");
  w = with(before, "[{t: 12, value: 1}, {t: 13, value: 0}]");
  REQUIRE(w.size() == 1);
  CHECK(w[0].message == "this step at t = 12 s is after the run's end (run.duration 10 s), so it is never "
                        "applied (nor is the 1 step after it)");
}

TEST_CASE("scene warnings: every committed scene's warnings are known (hub_two_panels and pointing_flex: mirror-axes, by design)") {
  // A new warning on a committed scene fails here until someone has looked at it: either the
  // scene is wrong (fix it) or the check is (fix the check), or it is the design (list it here).
  const std::map<std::string, std::vector<std::string>> expected{
      // Both hinges turn about the hub's +x: a positive angle lifts panel1 (+y side) and lowers
      // panel2 (-y side); the scene's initial angles (+5 deg, -3 deg) are written for that.
      {"hub_two_panels", {"mirror-axes"}},
      {"hub_two_panels_spin", {"mirror-axes"}},
      // The paper's Example 2: both payloads hinge about the beam's +y and take the same motor
      // torque, so they swing the same way, not as mirror images.
      {"pointing_flex", {"mirror-axes"}}};
  for (const std::string& file : crossdyn::test::committed_scenes()) {
    const std::string name = std::filesystem::path(file).stem().string();
    INFO(name);
    const h::CheckedScene c = h::read_checked_scene(file);
    const auto it = expected.find(name);
    CHECK(codes(c.warnings) == (it == expected.end() ? std::vector<std::string>{} : it->second));
  }
  CHECK(h::read_checked_scene(crossdyn::test::scene_path("spear1_case1")).warnings.empty());
}

TEST_CASE("scene warnings: the geometry document carries them, as the JSON outputs write them") {
  std::vector<SceneWarning> reader;
  const System s = crossdyn::read_scene_text(kWarned, "w.yaml", &reader);
  const std::vector<SceneWarning> w = h::scene_warnings(s, reader);
  namespace g = h::geometry;
  const nlohmann::json doc = nlohmann::json::parse(
      g::geometry_json(s, g::initial_configuration(s), {}, g::MotionSource{}, w));
  REQUIRE(doc["warnings"].size() == 4);
  CHECK(doc["warnings"][0]["code"] == "angle-unitless-large");
  CHECK(doc["warnings"][0]["line"] == 21);
  CHECK(doc["warnings"][0]["message"] == w[0].detail());
  CHECK(doc["warnings"][3]["code"] == "mirror-axes");
  CHECK(doc["warnings"][3]["subject"] == "hinge1 and hinge2");
  CHECK(doc["warnings"][3]["line"].is_null());
  CHECK(doc["warnings"][3]["message"] == w[3].message);
  CHECK(nlohmann::json::parse(h::warnings_json(w).dump()) == doc["warnings"]);
}

TEST_CASE("scene warnings: --strict makes only a status 0 a 1") {
  CHECK(h::strict_status(0, true, 1) == 1);
  CHECK(h::strict_status(0, true, 0) == 0);
  CHECK(h::strict_status(0, false, 3) == 0);
  CHECK(h::strict_status(2, true, 1) == 2);
  CHECK(h::strict_status(3, true, 1) == 3);
  CHECK(h::strict_status(1, true, 1) == 1);
}
