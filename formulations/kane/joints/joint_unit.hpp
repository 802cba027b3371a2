// One unit per joint type (free, revolute, spherical, fixed): what the kane engine does
// differently for each joint type outside its passes' hot loops, in one file per type
// (free.cpp, revolute.cpp, spherical.cpp, fixed.cpp), chosen once per node by
// joint_unit(JointType) (dispatch.cpp) when the model is built (model_building.cpp) and kept
// as Node::unit.  README.md "Joint units" lists the verbs and how to add a joint type.
#pragma once

#include "core/engine.hpp"
#include "core/output_layout.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace crossdyn::kane {

struct Node;
struct NodeWork;

struct JointUnit {
  // The joint's own positions and speeds (the first nqj, nuj of its node's block; a prescribed
  // joint has none).
  void (*sizes)(bool prescribed, int& nqj, int& nuj);
  // Offset in the joint's positions of a quaternion that after_step() renormalises; -1: none.
  int quat_offset;
  // State labels of the joint's positions (labels[q0 + i]) and speeds (labels[n_q + u0 + i]);
  // body and joint are the child body's and the joint's names.
  void (*labels)(const Node& n, int n_q, const std::string& body, const std::string& joint,
                 std::vector<std::string>& labels);
  // The kinematical equations: the joint's positions' rates q' from x and u (x, u, xdot the
  // engine's full arrays; KaneEngine::rhs).
  void (*q_rates)(const Node& n, const double* x, const double* u, double* xdot);
  // TreeState => the joint's positions and speeds (KaneEngine::pack).
  void (*pack)(const Node& n, const TreeState& s, const TreeState::JointState& js, double* x,
               double* u);
  // The joint's accelerations in TreeAccel from u' (KaneEngine::accelerations).
  void (*accel)(const Node& n, const NodeWork& w, const Eigen::VectorXd& udot, TreeAccel& a);
  // The hinge spring's potential energy 1/2 k |angle - neutral|^2 at x (KaneEngine::
  // potential_energy; zero for a joint with no free rotation).
  double (*spring_energy)(const Node& n, double stiffness, double neutral_angle, const double* x);
  // The joint's output columns (KaneEngine::output_row): w its node's workspace, torque a
  // prescribed joint's torque.
  void (*output)(const Node& n, const NodeWork& w, double torque, const double* x,
                 const double* u, RowWriter& out);
};

const JointUnit& free_joint_unit();
const JointUnit& revolute_joint_unit();
const JointUnit& spherical_joint_unit();
const JointUnit& fixed_joint_unit();

// The one dispatch on JointType.
const JointUnit& joint_unit(JointType type);

}  // namespace crossdyn::kane
