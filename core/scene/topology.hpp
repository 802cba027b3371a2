// The joint tree's topology, checked in one place for the reader and for engines.
//
// A scene's joints must form a tree rooted in the inertial frame N:
//   - exactly one base joint, the free joint or a prescribed revolute joint whose parent is N
//     (its child is the base body; `free` below means either);
//   - every body is the child of exactly one joint (one parent per body, no body left out);
//   - no joint joins a body to itself, and no chain of parents is a cycle (so every body is
//     connected to the base);
//   - in a System, joints are in tree order: joints[0] is the free joint, and every other joint's
//     parent is the child of an earlier joint.
//
// order_joints() is the algorithm; the reader calls it on the joints as listed in the file (and
// turns a problem into a message with the file's line), check_topology() on a finished System.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "core/system.hpp"

namespace crossdyn {

// One joint as the topology sees it: parent -1 means N (only for the base joint).
struct JointEdge {
  bool free = false;
  int parent = -1;
  int child = -1;
};

// What is wrong with a set of joints, found by order_joints().
struct TopologyProblem {
  enum class Kind {
    SelfLoop,      // joint `joint` has parent == child
    SecondFree,    // joint `joint` is free, and joint `other` was free before it
    SecondParent,  // joint `joint`'s child already has the parent joint `other`
    NoFree,        // no free joint
    NoJoint,       // body `body` is the child of no joint
    Cycle,         // body `body` is on a cycle of parents `cycle` (body indices, closed)
  };
  Kind kind;
  int joint = -1, other = -1, body = -1;
  std::vector<int> cycle;
  // The message, with names: "body 'tip' has no joint: ...". (Without file or line.)
  std::string describe(const std::vector<std::string>& body_names,
                       const std::vector<std::string>& joint_names) const;
};

// Tree order of `joints` over `body_count` bodies: the free joint first, then Kahn's algorithm
// always taking the ready joint listed first, so joints already in tree order keep their order.
// Returns the order (indices into `joints`), or the first problem found, checked in the order of
// the Kind list above (self loops and second free joints or parents in listing order).
struct TopologyResult {
  std::vector<int> order;
  std::optional<TopologyProblem> problem;
};
TopologyResult order_joints(int body_count, const std::vector<JointEdge>& joints);

// Checks a System's topology, including that its joints are already in tree order and that
// every body and joint index is in range; throws InputError
// "<file or name>: joints[k] '<joint>': <what is wrong>" (or "bodies[b] ..."). Engines call it
// instead of checking the tree their own way.
void check_topology(const System& system);

}  // namespace crossdyn
