// The scene schema (core/scene/schema.hpp) is the one owner of the format: these tests hold the
// reader, the writer, the fuzz dictionary and the rest of the code to it.
#include "core/integrate.hpp"
#include "core/scene/scene.hpp"
#include "core/scene/schema.hpp"
#include "core/scene/text.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <set>
#include <sstream>

using namespace crossdyn;
using scene::Key;
using scene::Type;

namespace {

// The scenes that between them hold every key of the schema (tests/scene/test_scene.cpp's rich
// scene without its comments, a single-body analytic scene, and one with the conveniences).
const char* kRich = R"(
name: rich
description: every feature
source: made up
zero_linear_momentum: false
bodies:
  - name: hub
    mass: 1 kg
    inertia: [[10, 1, 0.5], [1, 20, 0.25], [0.5, 0.25, 25]]
    torque:
      frame: inertial
      profile:
        - {t: 0, value: [1, 0, 0]}
        - {t: 0.5 min, value: {value: [0, -2, 0], unit: N*m}}
  - name: arm
    mass: 500 g
    inertia: {value: [1, 1, 1.5, 0.1, 0, 0], unit: kg m^2}
    center_of_mass: [0.5, 0, 0]
  - name: tip
    mass: 0.25 kg
    inertia: [0.1, 0.1, 0.1]
  - name: cap
    mass: 0.1 kg
    inertia: [0.01, 0.01, 0.01]
  - {name: slider, mass: 0.5 kg, inertia: [0.01, 0.02, 0.02]}
  - {name: pusher, mass: 0.5 kg, inertia: [0.01, 0.02, 0.02]}
  - {name: ram, mass: 0.5 kg, inertia: [0.01, 0.02, 0.02]}
  - {name: camera, mass: 0.5 kg, inertia: [0.01, 0.02, 0.03]}
  - {name: flap, mass: 0.5 kg, inertia: [0.01, 0.02, 0.02]}
  - name: boom
    mass: 2 kg
    flexible:
      beam:
        length: 2 m
        axis: x
        mass_per_length: 1
        section: [0, 10 cm, 0.1]
        bending:
          y: {modes: 1, EI: 10}
          z: {modes: 0, EI: 0}
        boundary: clamped-bottom
        slices: 8
        normalisation: mass
        damping: {alpha: 0.1, beta: 0.01}
  - name: mast
    flexible:
      beam:
        length: 3
        mass_per_length: 2
        section: [0.1, 0.1, 0]
        bending: {x: {modes: 1, EI: 20}, y: {modes: 0}}
        boundary: clamped-bottom
        geometric_stiffening: true
        damping: {ratios: [0.02]}
  - name: panel
    flexible:
      nodes: )" CROSSDYN_SOURCE_DIR R"(/scenarios/data/panel_nodes.csv
      modes: )" CROSSDYN_SOURCE_DIR R"(/scenarios/data/panel_modes.csv
joints:
  - name: base
    type: free
    child: hub
    initial:
      position: {value: [1, 2, 3], unit: km}
      attitude: {axis: [1, 1, 0], angle: 30 deg}
      angular_velocity: [0.1, 0.2, 0.3]
      velocity: [1 m/s, 0, 0]
  - name: hinge
    type: revolute
    parent: hub
    child: arm
    parent_point: [1, 0, 0]
    child_point: [-50 cm, 0, 0]
    axis: [0, 3, 4]
    offset: [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    spring: {stiffness: 2 N m/rad, neutral_angle: 5 deg}
    damper: {damping: 0.5 N*m*s/rad}
    motor: {profile: [{t: 0, value: 1 N m}, {t: 2 s, value: -1}]}
    initial: {angle: 10 deg, rate: 30 rpm}
  - name: ball
    type: spherical
    parent: arm
    child: tip
    parent_point: [1, 0, 0]
    child_point: [-0.5, 0, 0]
    offset: {axis: [0, 0, 1], angle: 90 deg}
    spring: {stiffness: 1}
    damper: {damping: 0.1}
    motor: {profile: [{t: 1 s, value: [0, 0, 0.5]}]}
    initial:
      attitude: [0.9998, 0.02, 0, 0]
      angular_velocity: {value: [0, 0, 10], unit: deg/s}
  - name: weld
    type: fixed
    parent: tip
    child: cap
    parent_point: [0.1, 0, 0]
    child_point: [0, 0, 0]
    offset: [1, 0, 0, 0]
  - name: slide
    type: prismatic
    parent: hub
    child: slider
    parent_point: [0, 1, 0]
    child_point: [0, -10 cm, 0]
    axis: [0, 1, 0]
    offset: {axis: [0, 1, 0], angle: 15 deg}
    spring: {stiffness: 30 N/m, neutral_position: 5 cm}
    damper: {damping: 0.5 N s/m}
    motor: {profile: [{t: 0, value: 2 N}, {t: 3 s, value: 0}]}
    initial: {position: 2 cm, rate: 1 cm/s}
  - name: push
    type: prismatic
    parent: hub
    child: pusher
    parent_point: [0, -1, 0]
    child_point: [0, 0.1, 0]
    axis: [0, -1, 0]
    prescribed: {profile: spin-up, rate: 1 cm/s, ramp_time: 2 s}
  - name: drive
    type: prismatic
    parent: hub
    child: ram
    parent_point: [0, 0, -1]
    child_point: [0, 0, 0.1]
    axis: [0, 0, -1]
    prescribed: {profile: deploy, travel: 50 cm, ramp_time: 5 s}
    initial: {position: 1 cm}
  - name: gimbal
    type: universal
    parent: hub
    child: camera
    parent_point: [-1, 0, 0]
    child_point: [0.1, 0, 0]
    axis: [0, 0, 1]
    axis2: [0, 1, 0]
    offset: {axis: [1, 0, 0], angle: 5 deg}
    spring: {stiffness: [1, 2 N m/rad], neutral_angle: {value: [1, -2], unit: deg}}
    damper: {damping: [0.1, 0.2]}
    motor: {profile: [{t: 0, value: [0.1, 0]}, {t: 1 s, value: {value: [0, 5], unit: mN m}}]}
    initial: {angle: [5 deg, 0], rate: {value: [1, 2], unit: deg/s}}
  - name: unfold
    type: revolute
    parent: arm
    child: flap
    parent_point: [0, 0.2, 0]
    child_point: [0, -0.1, 0]
    axis: [1, 0, 0]
    prescribed: {profile: deploy, travel: 90 deg, ramp_time: 4 s}
  - name: boom_root
    type: fixed
    parent: hub
    parent_point: [0, 0, 1]
    child: boom
    child_node: bottom
  - name: mast_hinge
    type: revolute
    parent: boom
    parent_node: top
    child: mast
    child_node: bottom
    axis: [0, 0, 1]
    prescribed: {profile: spin-up, rate: 1 rad/s, ramp_time: 2 s}
  - name: panel_root
    type: fixed
    parent: mast
    parent_node: top
    child: panel
    child_node: root
run:
  duration: 2 min
  output_step: 500 ms
  integrator: dopri5
  rtol: 1e-9
  atol: 1e-12
  dt: 1 ms
compare:
  tolerances:
    H: {atol: 1e-6}
    default: {atol: 1e-7, rtol: 1e-6}
  exclude:
    - {quantity: E, reason: "the dampers dissipate energy"}
)";

const char* kAnalytic = R"(
name: one
analytic: torque-free
bodies: [{name: b, mass: 1, inertia: [1, 2, 2.5]}]
joints: [{name: base, type: free, child: b}]
run: {duration: 1, output_step: 0.1}
)";

// The environment's keys (issue 28): uniform gravity; a central body with an orbit by altitude
// and a base given relative to the orbit frame; an orbit by its radius.
const char* kUniform = R"(
name: pendulum
environment: {gravity: {value: [0, 0, -1], unit: g0}}
bodies: [{name: b, mass: 1, inertia: [1, 2, 2.5]}]
joints: [{name: base, type: free, child: b}]
run: {duration: 1, output_step: 0.1}
)";
const char* kOrbitAltitude = R"(
name: on_orbit
environment:
  central_body: {mu: 398600.4418 km^3/s^2, radius: 6378.137 km}
  orbit: {altitude: 500 km, inclination: 98 deg, raan: 10 deg, argument_of_latitude: 30 deg}
bodies: [{name: b, mass: 1, inertia: [1, 2, 2.5]}]
joints:
  - name: base
    type: free
    child: b
    initial: {frame: lvlh, attitude: {axis: [0, 1, 0], angle: 1 deg}, angular_velocity: [0, 0, 0]}
run: {duration: 1, output_step: 0.1}
)";
const char* kOrbitRadius = R"(
name: on_orbit2
environment:
  central_body: {mu: 3.986004418e14}
  orbit: {radius: 7000 km}
bodies: [{name: b, mass: 1, inertia: [1, 2, 2.5]}]
joints: [{name: base, type: free, child: b}]
run: {duration: 1, output_step: 0.1}
)";

// The schema rows a scene text uses, found by walking its YAML as the schema describes it
// (rows of each joint by that joint's type; value forms where a value is written as a mapping).
void collect(const YAML::Node& n, const std::string& path, unsigned joints,
             std::set<const Key*>& used) {
  const Key* row = scene::find(path, joints);
  REQUIRE(row != nullptr);
  used.insert(row);
  const std::string prefix = path.empty() ? "" : path + ".";
  if (row->type == Type::Map && n.IsMap()) {
    if (path == "joints[]") {
      for (const scene::JointTypeInfo& t : scene::joint_types())
        if (n["type"].Scalar() == t.name) joints = t.bit;
    }
    for (const auto& kv : n) {
      const std::string key = kv.first.Scalar();
      collect(kv.second, prefix + (path == "compare.tolerances" ? "<quantity>" : key), joints,
              used);
    }
  } else if (row->type == Type::List && n.IsSequence() && scene::find(path + "[]", joints)) {
    for (const auto& item : n) collect(item, path + "[]", joints, used);
  } else if (n.IsMap()) {  // a value form
    const std::string form = row->type == Type::Attitude ? "(axis-angle)" : "(list with unit)";
    used.insert(scene::find(form));
    for (const auto& kv : n) used.insert(scene::find(form + "." + kv.first.Scalar()));
  }
}

std::set<const Key*> rows_used(const std::string& text) {
  std::set<const Key*> used;
  collect(YAML::Load(text), "", scene::kAnyJoint, used);
  return used;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST_CASE("schema: every row is well formed") {
  std::set<std::pair<std::string_view, unsigned>> joint_rows;
  for (const Key& k : scene::keys()) {
    INFO(k.path);
    CHECK(!k.doc.empty());
    if (k.required) CHECK(k.default_value.empty());
    if (k.type == Type::Map || k.type == Type::List || k.type == Type::Word ||
        k.type == Type::Name)
      CHECK(!k.noun.empty());
    CHECK((k.type == Type::Word) == !k.words.empty());
    // A word's noun follows "unknown" in the reader's message, without its article ("unknown a
    // motion profile" was a slip): what remains is a bare noun.
    if (k.type == Type::Word) {
      const std::string bare = scene::without_article(std::string(k.noun));
      CHECK(!bare.empty());
      CHECK(!bare.starts_with("a "));
      CHECK(!bare.starts_with("an "));
      CHECK(!bare.starts_with("the "));
    }
    const bool dimensional = k.type == Type::Quantity || k.type == Type::Vector ||
                             k.type == Type::Pair || k.type == Type::Inertia;
    CHECK(dimensional == (k.dimension != units::Dimension::None));
    // Rows outside joints[] apply to every joint type; rows of one path do not overlap.
    if (!k.path.starts_with("joints[]")) CHECK(k.joints == scene::kAnyJoint);
    for (const auto& [path, bits] : joint_rows)
      if (path == k.path) CHECK((bits & k.joints) == 0);
    joint_rows.insert({k.path, k.joints});
    // Every row but the scene's own sits in a mapping (or a list item) of the schema.
    if (k.path.empty() || (k.path.starts_with('(') && k.path.find('.') == std::string::npos))
      continue;
    std::string parent(k.path.substr(0, k.path.rfind('.') == std::string_view::npos
                                            ? 0
                                            : k.path.rfind('.')));
    if (k.path.ends_with("[]")) parent = std::string(k.path.substr(0, k.path.size() - 2));
    const Key* p = scene::find(parent, k.joints);
    REQUIRE(p != nullptr);
    CHECK((p->type == Type::Map || (p->type == Type::List && k.path.ends_with("[]"))));
  }
}

TEST_CASE("schema: joint types and integrators agree with the rest of the code") {
  for (const scene::JointTypeInfo& t : scene::joint_types()) {
    Joint j;
    j.type = t.type;
    CHECK(t.dof == j.dof());
  }
  CHECK(scene::joint_types().size() == 6);
  CHECK(scene::words(*scene::find("run.integrator")) == integrator_names());
  CHECK(scene::find("run.integrator")->default_value == RunSpec{}.integrator);
  CHECK(scene::joint_keys(JointType::Free) ==
        std::vector<std::string>{"name", "type", "child", "initial"});
  CHECK(scene::initial_keys(JointType::Revolute) == std::vector<std::string>{"angle", "rate"});
  CHECK(scene::initial_keys(JointType::Fixed).empty());
  CHECK(scene::initial_keys(JointType::Prismatic) == std::vector<std::string>{"position", "rate"});
  CHECK(scene::initial_keys(JointType::Universal) == std::vector<std::string>{"angle", "rate"});
  CHECK(scene::joint_keys(JointType::Universal) ==
        std::vector<std::string>{"name", "type", "parent", "child", "parent_point", "child_point",
                                 "axis", "axis2", "offset", "spring", "damper", "motor",
                                 "initial"});
}

TEST_CASE("schema: the reader accepts every key of the schema, and the writer writes each one "
          "it may") {
  std::set<const Key*> read, written;
  for (const char* text : {kRich, kAnalytic, kUniform, kOrbitAltitude, kOrbitRadius}) {
    const System s = read_scene_text(text, "all.yaml");
    const std::set<const Key*> r = rows_used(text);
    const std::set<const Key*> w = rows_used(write_scene_text(s));
    read.insert(r.begin(), r.end());
    written.insert(w.begin(), w.end());
  }
  for (const Key& k : scene::keys()) {
    INFO(k.path << " (joint types " << k.joints << ")");
    CHECK(read.count(&k) == 1);
    CHECK(written.count(&k) == (k.written ? 1u : 0u));
  }
}

TEST_CASE("schema: fuzz/scene.dict is generated from the schema") {
  const std::string committed = slurp(test::source_dir() + "/fuzz/scene.dict");
  INFO("regenerate: build/tests/scene/crossdyn_scene_doc --write-dict fuzz/scene.dict");
  CHECK(committed == scene::fuzz_dictionary());
  // Every key name is there, spelled as a key.
  for (const Key& k : scene::keys()) {
    const std::size_t dot = k.path.rfind('.');
    const std::string_view name = dot == std::string_view::npos ? k.path : k.path.substr(dot + 1);
    if (name.empty() || name.starts_with('(') || name.starts_with('<') || name.ends_with("[]"))
      continue;
    CHECK(committed.find("\"" + std::string(name) + ":\"") != std::string::npos);
  }
}

// scene::find looks rows up by hashing (wildcard rows one by one): it must give what a scan of
// the table in order gives, for every row's path, every set of joint types, wildcard paths and
// paths that are not in the table.
TEST_CASE("schema: find gives the first matching row in table order, as a scan does") {
  auto component_match = [](std::string_view pattern, std::string_view path) {
    while (true) {
      const std::size_t pd = pattern.find('.'), qd = path.find('.');
      const std::string_view a = pattern.substr(0, pd), b = path.substr(0, qd);
      if (!(a == b || (a.starts_with('<') && a.ends_with('>') && !b.empty()))) return false;
      if (pd == std::string_view::npos || qd == std::string_view::npos)
        return pd == std::string_view::npos && qd == std::string_view::npos;
      pattern.remove_prefix(pd + 1);
      path.remove_prefix(qd + 1);
    }
  };
  auto scan = [&](std::string_view path, unsigned joints) -> const Key* {
    for (const Key& k : scene::keys())
      if ((k.joints & joints) != 0 && component_match(k.path, path)) return &k;
    return nullptr;
  };
  std::vector<std::string> paths;
  for (const Key& k : scene::keys()) {
    std::string p(k.path);
    for (std::size_t at; (at = p.find("<quantity>")) != std::string::npos;) p.replace(at, 10, "spin");
    paths.push_back(std::string(k.path));
    paths.push_back(p);
    paths.push_back(p + ".nope");
    paths.push_back(p + "x");
  }
  for (const char* p : {"", "compare.tolerances", "compare.tolerances.a.atol", "compare.tolerances..atol",
                        "joints[].initial.angle", "joints[].nope", "nope"})
    paths.emplace_back(p);
  std::size_t found = 0, wildcard = 0;
  for (const std::string& path : paths)
    for (unsigned joints = 0; joints <= scene::kAnyJoint; ++joints) {
      const Key* expected = scan(path, joints);
      INFO(path << " joints " << joints);
      CHECK(scene::find(path, joints) == expected);
      found += expected != nullptr;
      wildcard += expected != nullptr && expected->path.find('<') != std::string_view::npos;
    }
  CHECK(found > 500);
  CHECK(wildcard > 20);
}
