#include "core/scene/topology.hpp"

#include <algorithm>
#include <functional>
#include <queue>

#include "core/errors.hpp"

namespace crossdyn {

std::string TopologyProblem::describe(const std::vector<std::string>& body_names,
                                      const std::vector<std::string>& joint_names) const {
  auto body = [&](int b) { return "'" + body_names.at(static_cast<std::size_t>(b)) + "'"; };
  auto joint = [&](int j) { return "'" + joint_names.at(static_cast<std::size_t>(j)) + "'"; };
  switch (kind) {
    case Kind::SelfLoop:
      return "joint " + joint(this->joint) + " connects body " + body(this->body) + " to itself";
    case Kind::SecondFree:
      return "a second free joint (the first is " + joint(other) +
             "); exactly one joint, the base body's, is free (or a prescribed revolute joint "
             "without a parent)";
    case Kind::SecondParent:
      return "body " + body(this->body) + " already has a parent joint " + joint(other) +
             "; a body has exactly one parent";
    case Kind::NoFree:
      return "no free joint: exactly one joint must be of type free (it holds the base body), or "
             "a prescribed revolute joint without a parent (a base turned about an axis fixed in N)";
    case Kind::NoJoint:
      return "body " + body(this->body) +
             " has no joint: every body is the child of exactly one joint";
    case Kind::Cycle: {
      std::string c;
      for (int b : cycle)
        c += (c.empty() ? "" : " -> ") + body_names.at(static_cast<std::size_t>(b));
      return "body " + body(this->body) + " is not connected to the base body " + body(other) +
             ": the joints form a cycle of parents (" + c + ")";
    }
  }
  return "?";
}

TopologyResult order_joints(int body_count, const std::vector<JointEdge>& joints) {
  using Kind = TopologyProblem::Kind;
  const auto nb = static_cast<std::size_t>(body_count);
  const int nj = static_cast<int>(joints.size());
  auto at = [&](int k) -> const JointEdge& { return joints[static_cast<std::size_t>(k)]; };
  auto problem = [](Kind kind, int joint, int other, int body) {
    return TopologyResult{{}, TopologyProblem{kind, joint, other, body, {}}};
  };

  for (int k = 0; k < nj; ++k)
    if (!at(k).free && at(k).parent == at(k).child)
      return problem(Kind::SelfLoop, k, -1, at(k).child);

  // One parent per body, one free joint.
  std::vector<int> joint_of(nb, -1);
  int free_joint = -1;
  for (int k = 0; k < nj; ++k) {
    if (at(k).free) {
      if (free_joint >= 0) return problem(Kind::SecondFree, k, free_joint, at(k).child);
      free_joint = k;
    }
    int& owner = joint_of[static_cast<std::size_t>(at(k).child)];
    if (owner >= 0) return problem(Kind::SecondParent, k, owner, at(k).child);
    owner = k;
  }
  if (free_joint < 0) return problem(Kind::NoFree, -1, -1, -1);
  for (std::size_t b = 0; b < nb; ++b)
    if (joint_of[b] < 0) return problem(Kind::NoJoint, -1, -1, static_cast<int>(b));

  // Every body has one parent, so a body not connected to the base lies on or below a cycle:
  // walk up from each body until the base (connected) or a body already on this walk (cycle).
  const int base = at(free_joint).child;
  std::vector<int> state(nb, 0);  // 0 unseen, 1 on the current walk, 2 connected to the base
  state[static_cast<std::size_t>(base)] = 2;
  for (std::size_t b0 = 0; b0 < nb; ++b0) {
    std::vector<int> walk;
    int b = static_cast<int>(b0);
    while (state[static_cast<std::size_t>(b)] == 0) {
      state[static_cast<std::size_t>(b)] = 1;
      walk.push_back(b);
      b = at(joint_of[static_cast<std::size_t>(b)]).parent;
    }
    if (state[static_cast<std::size_t>(b)] == 1) {
      TopologyResult r = problem(Kind::Cycle, joint_of[static_cast<std::size_t>(b)], base, b);
      r.problem->cycle.assign(std::find(walk.begin(), walk.end(), b), walk.end());
      r.problem->cycle.push_back(b);
      return r;
    }
    for (int w : walk) state[static_cast<std::size_t>(w)] = 2;
  }

  // Kahn's algorithm, always taking the ready joint listed first.
  std::vector<std::vector<int>> children(nb);
  for (int k = 0; k < nj; ++k)
    if (!at(k).free) children[static_cast<std::size_t>(at(k).parent)].push_back(k);
  std::priority_queue<int, std::vector<int>, std::greater<>> ready;
  ready.push(free_joint);
  TopologyResult r;
  while (!ready.empty()) {
    const int k = ready.top();
    ready.pop();
    r.order.push_back(k);
    for (int c : children[static_cast<std::size_t>(at(k).child)]) ready.push(c);
  }
  return r;
}

void check_topology(const System& s) {
  const std::string where = !s.file.empty() ? s.file : !s.name.empty() ? s.name : "the system";
  const int nb = static_cast<int>(s.bodies.size());
  auto fail_joint = [&](std::size_t k, const std::string& what) {
    throw InputError(where + ": joints[" + std::to_string(k) + "] '" + s.joints[k].name +
                     "': " + what);
  };
  std::vector<JointEdge> edges;
  for (std::size_t k = 0; k < s.joints.size(); ++k) {
    const Joint& j = s.joints[k];
    // The base joint: the free joint, or a prescribed revolute joint whose parent is N.
    const bool prescribed_base =
        j.type == JointType::Revolute && j.prescribed.has_value() && j.parent == -1;
    const bool free = j.type == JointType::Free || prescribed_base;
    if (j.child < 0 || j.child >= nb)
      fail_joint(k, "child body index " + std::to_string(j.child) + " is out of range (" +
                        std::to_string(nb) + " bodies)");
    if (free ? j.parent != -1 : (j.parent < 0 || j.parent >= nb))
      fail_joint(k, "parent body index " + std::to_string(j.parent) +
                        (free ? " on the free joint; its parent is N (-1)"
                              : " is out of range (" + std::to_string(nb) + " bodies)"));
    edges.push_back({free, j.parent, j.child});
  }
  const TopologyResult r = order_joints(nb, edges);
  if (r.problem) {
    std::vector<std::string> bodies, joints;
    for (const Body& b : s.bodies) bodies.push_back(b.name);
    for (const Joint& j : s.joints) joints.push_back(j.name);
    const std::string what = r.problem->describe(bodies, joints);
    if (r.problem->joint >= 0) fail_joint(static_cast<std::size_t>(r.problem->joint), what);
    throw InputError(where + ": " + what);
  }
  // Tree order: the free joint first; every other joint's parent is an earlier joint's child.
  for (std::size_t k = 0; k < s.joints.size(); ++k) {
    if (k == 0 && s.joints[0].parent != -1)
      fail_joint(0, "the first joint must be the free joint of the base body, or a prescribed "
                    "revolute joint without a parent (tree order)");
    if (k == 0 && s.joints[0].parent_node >= 0)
      fail_joint(0, "the base joint's parent is N, which has no nodes");
    if (k == 0) continue;
    bool placed = false;
    for (std::size_t e = 0; e < k && !placed; ++e) placed = s.joints[e].child == s.joints[k].parent;
    if (!placed)
      fail_joint(k, "its parent body '" +
                        s.bodies[static_cast<std::size_t>(s.joints[k].parent)].name +
                        "' is not the child of an earlier joint (joints must be in tree order)");
  }
}

}  // namespace crossdyn
