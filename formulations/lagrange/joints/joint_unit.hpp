// One joint type of the Lagrange engine (free, revolute, spherical, fixed, prismatic, universal):
// its coordinates and quasi-velocities, what each coordinate does to the child (the kinematic
// properties the passes of rhs() read from Model::JointM), its loads, their labels, its Euler-angle
// set, its initial state, its output columns and accelerations. One unit file per type
// (free.cpp, revolute.cpp, spherical.cpp, fixed.cpp, prismatic.cpp, universal.cpp), chosen once per
// joint when the model is built (dispatch.cpp: joint_unit(); Model::JointM::unit).
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
  // What its coordinates do (README.md "Kinematics"), copied into Model::JointM for the pose and
  // twist passes (kinematics.hpp), which read these instead of the type:
  int axis_rotations;  // its first coordinates each turn the child about an axis fixed in the
                       // frame before it: R_J = Rot(n_1, q_1) Rot(n_2, q_2) (revolute 1, universal
                       // 2; at most 2), quasi-velocities their rates
  int slides;          // the next slide the joint point along axis_P: r_P = p_PoJ_P + s axis_P
                       // (prismatic 1; at most 1), quasi-velocity its rate
  // Why it may not attach at a node (at_nodes false): the InputError's reason.
  const char* no_nodes;

  // State labels of its q* and pi' block (joint coordinates only; the child's modes follow).
  void (*coordinate_labels)(const std::string& joint, const std::string& body,
                            std::vector<std::string>& out);
  void (*rate_labels)(const std::string& joint, const std::string& body,
                      std::vector<std::string>& out);
  // Its Euler set's owner and description (euler_offset >= 0).
  void (*euler_set)(const std::string& joint, const std::string& body, Model::EulerSetM& es);
  // Its hinge loads into the model (Model::JointM: springs per coordinate, dampers and motors per
  // quasi-velocity; system.hpp "Loads").
  void (*loads)(const Joint& joint, Model::JointM& J);
  // pack(): its block of q* and pi' from the TreeState.
  void (*pack)(const Model::JointM& J, const TreeState& s, const TreeState::JointState& js,
               double* qj, double* uj, const SetAngles& set_angles);
  // Outputs: its attitude quaternion (R_J, or R_NB when absolute_attitude) from its coordinates.
  Eigen::Quaterniond (*attitude)(const Model::JointM& J, const double* qj, const EulerQ& euler_q);
  // Its output columns (angle, rate, w_PC_C) and accelerations.
  void (*columns)(RowWriter& out, int j, const double* qj, const double* uj);
  void (*accelerations)(TreeAccel& a, std::size_t j, const Eigen::VectorXd& udot, int i0);
};

// Shared by the units of one scalar coordinate (revolute, prismatic; revolute.cpp): pack() of the
// coordinate (a prescribed one from its profile at t = 0), its loads (one spring, damper and motor
// along or about the axis) and its acceleration.
void pack_one_coordinate(const Model::JointM& J, const TreeState& s,
                         const TreeState::JointState& js, double* qj, double* uj,
                         const SetAngles& set_angles);
void one_coordinate_loads(const Joint& joint, Model::JointM& J);
void one_coordinate_acceleration(TreeAccel& a, std::size_t j, const Eigen::VectorXd& udot, int i0);
// No loads (free, fixed).
void no_loads(const Joint& joint, Model::JointM& J);

// The unit of a joint type: the one dispatch on JointType (dispatch.cpp; each unit file defines
// its `extern const JointUnit k<Type>Joint`).
const JointUnit& joint_unit(JointType type);

}  // namespace crossdyn::lagrange
