// One joint type of the Lagrange engine (free, revolute, spherical, fixed): its coordinates and
// quasi-velocities, their labels, its Euler-angle set, its initial state, its output columns and
// accelerations. One unit file per type (free.cpp, revolute.cpp, spherical.cpp, fixed.cpp), chosen
// once per joint when the model is built (dispatch.cpp: joint_unit(); Model::JointM::unit).
// README.md "Joint types". Internal header (formulations/lagrange/*.cpp only).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <functional>
#include <string>
#include <vector>

#include "core/engine.hpp"
#include "core/output_layout.hpp"
#include "formulations/lagrange/model.hpp"

namespace crossdyn::lagrange {

// An Euler-angle set's angles from an attitude, its chart chosen (pack(), state.cpp).
using SetAngles = std::function<void(int set, const Eigen::Quaterniond& q, double* angles)>;
// The quaternion of the joint's Euler set from its three angles in the set's current chart.
using EulerQ = std::function<Eigen::Quaterniond(const double* angles)>;

struct JointUnit {
  int dof;                 // coordinates in q* (and quasi-velocities in pi'), before the modes
  int euler_offset;        // index of its Euler set's first angle in its block, -1: none
  int translations;        // its first coordinates that translate the child along N's axes
  bool at_nodes;           // may attach at a node of a flexible body (all but the free joint)
  bool prescribable;       // may be prescribed (docs/prescribed-motion.md)
  bool absolute_attitude;  // attitude() is the child's R_NB itself (free), else R_J

  // State labels of its q* and pi' block (joint coordinates only; the child's modes follow).
  void (*coordinate_labels)(const std::string& joint, const std::string& body,
                            std::vector<std::string>& out);
  void (*rate_labels)(const std::string& joint, const std::string& body,
                      std::vector<std::string>& out);
  // Its Euler set's owner and description (euler_offset >= 0).
  void (*euler_set)(const std::string& joint, const std::string& body, Model::EulerSetM& es);
  // pack(): its block of q* and pi' from the TreeState.
  void (*pack)(const Model::JointM& J, const TreeState& s, const TreeState::JointState& js,
               double* qj, double* uj, const SetAngles& set_angles);
  // Outputs: its attitude quaternion (R_J, or R_NB when absolute_attitude) from its coordinates.
  Eigen::Quaterniond (*attitude)(const Model::JointM& J, const double* qj, const EulerQ& euler_q);
  // Its output columns (angle, rate, w_PC_C) and accelerations.
  void (*columns)(RowWriter& out, int j, const double* qj, const double* uj);
  void (*accelerations)(TreeAccel& a, std::size_t j, const Eigen::VectorXd& udot, int i0);
};

// The unit of a joint type: the one dispatch on JointType (dispatch.cpp; each unit file defines
// its `extern const JointUnit k<Type>Joint`).
const JointUnit& joint_unit(JointType type);

}  // namespace crossdyn::lagrange
