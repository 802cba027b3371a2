// The joint tree's topology in one place (core/scene/topology.hpp): order_joints on joint lists,
// and check_topology, which engines call, on Systems.
#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>

#include <filesystem>

using namespace crossdyn;
using Kind = TopologyProblem::Kind;

namespace {

// hub (base) -> arm -> tip, and hub -> leg: a valid System in tree order.
System tree() {
  return read_scene_text(R"(name: tree
bodies:
  - {name: hub, mass: 1, inertia: [1, 1, 1]}
  - {name: arm, mass: 1, inertia: [1, 1, 1]}
  - {name: tip, mass: 1, inertia: [1, 1, 1]}
  - {name: leg, mass: 1, inertia: [1, 1, 1]}
joints:
  - {name: base, type: free, child: hub}
  - {name: shoulder, type: revolute, parent: hub, child: arm, parent_point: [1, 0, 0], child_point: [0, 0, 0], axis: [0, 0, 1]}
  - {name: wrist, type: spherical, parent: arm, child: tip, parent_point: [1, 0, 0], child_point: [0, 0, 0]}
  - {name: hip, type: fixed, parent: hub, child: leg, parent_point: [0, 1, 0], child_point: [0, 0, 0]}
run: {duration: 1, output_step: 0.5}
)",
                         "tree.yaml");
}

std::string problem_of(const System& s) {
  try {
    check_topology(s);
  } catch (const InputError& e) {
    return e.what();
  }
  return "accepted";
}

}  // namespace

TEST_CASE("check_topology accepts every committed scene and a valid tree") {
  CHECK(problem_of(tree()) == "accepted");
  REQUIRE(!test::committed_scenes().empty());
  for (const std::string& path : test::committed_scenes()) {
    INFO(path);
    CHECK(problem_of(read_scene(path)) == "accepted");
  }
}

TEST_CASE("check_topology names the joint and what is wrong, one case per class") {
  System s = tree();
  SECTION("a body with two parents") {
    s.joints[3].child = 2;  // hip now also holds tip
    CHECK(problem_of(s) ==
          "tree.yaml: joints[3] 'hip': body 'tip' already has a parent joint 'wrist'; a body has "
          "exactly one parent");
  }
  SECTION("a body without a joint") {
    s.joints.pop_back();
    CHECK(problem_of(s) ==
          "tree.yaml: body 'leg' has no joint: every body is the child of exactly one joint");
  }
  SECTION("a joint that joins a body to itself") {
    s.joints[2].parent = 2;
    CHECK(problem_of(s) == "tree.yaml: joints[2] 'wrist': joint 'wrist' connects body 'tip' to "
                           "itself");
  }
  SECTION("a cycle") {
    s.joints[1].parent = 2;  // arm's parent tip, tip's parent arm
    CHECK(problem_of(s) ==
          "tree.yaml: joints[1] 'shoulder': body 'arm' is not connected to the base body 'hub': "
          "the joints form a cycle of parents (arm -> tip -> arm)");
  }
  SECTION("no free joint, or two") {
    s.joints[0].type = JointType::Fixed;
    s.joints[0].parent = 3;
    CHECK(problem_of(s).find("tree.yaml: no free joint") == 0);
    s = tree();
    s.joints[3].type = JointType::Free;
    s.joints[3].parent = -1;
    CHECK(problem_of(s) == "tree.yaml: joints[3] 'hip': a second free joint (the first is "
                           "'base'); exactly one joint, the base body's, is free (or a prescribed "
                           "revolute joint without a parent)");
  }
  SECTION("joints out of tree order") {
    std::swap(s.joints[1], s.joints[2]);  // wrist (parent arm) before shoulder (child arm)
    CHECK(problem_of(s) ==
          "tree.yaml: joints[1] 'wrist': its parent body 'arm' is not the child of an earlier "
          "joint (joints must be in tree order)");
    s = tree();
    std::swap(s.joints[0], s.joints[3]);
    CHECK(problem_of(s).find("joints[0] 'hip': the first joint must be the free joint") !=
          std::string::npos);
  }
  SECTION("indices out of range") {
    s.joints[2].child = 7;
    CHECK(problem_of(s) ==
          "tree.yaml: joints[2] 'wrist': child body index 7 is out of range (4 bodies)");
    s = tree();
    s.joints[0].parent = 0;
    CHECK(problem_of(s).find("joints[0] 'base': parent body index 0 on the free joint") !=
          std::string::npos);
  }
}

TEST_CASE("order_joints: the free joint first, then the first ready joint in listing order") {
  // Bodies 0..3; listed: 2's joint (parent 1), 3's (parent 0), 1's (parent 0), the free joint (0).
  const std::vector<JointEdge> edges{{false, 1, 2}, {false, 0, 3}, {false, 0, 1}, {true, -1, 0}};
  const TopologyResult r = order_joints(4, edges);
  REQUIRE_FALSE(r.problem);
  CHECK(r.order == std::vector<int>{3, 1, 2, 0});
  // A list already in tree order keeps its order.
  const std::vector<JointEdge> sorted{{true, -1, 0}, {false, 0, 1}, {false, 1, 2}, {false, 0, 3}};
  CHECK(order_joints(4, sorted).order == std::vector<int>{0, 1, 2, 3});
  // Problems come in a fixed order: self loops before everything else.
  const std::vector<JointEdge> bad{{false, 1, 1}, {true, -1, 0}, {true, -1, 2}};
  REQUIRE(order_joints(3, bad).problem);
  CHECK(order_joints(3, bad).problem->kind == Kind::SelfLoop);
}
