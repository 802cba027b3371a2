// One unit per joint type (free, revolute, spherical, fixed, prismatic, universal): what the kane
// engine does differently for each joint type, in one file per type (free.cpp, revolute.cpp,
// spherical.cpp, fixed.cpp, prismatic.cpp, universal.cpp), chosen once per node by
// joint_unit(JointType) (dispatch.cpp) when the model is built (model_building.cpp) and kept
// as Node::unit, with its shape as Node::shape.  dispatch.cpp alone switches on JointType: the
// passes read the node's facts the unit sets (Node::shape, slides, axis_rates, the axes) and
// call its verbs.  README.md "Joint units" lists the verbs and how to add a type.
#pragma once

#include "core/engine.hpp"
#include "core/output_layout.hpp"
#include "formulations/kane/kane_engine.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace crossdyn::kane {

// What every joint speed is to the passes (README.md "Joint units"): speed r of node k moves the
// subtree S(k) with a rigid twist about Ok (the child-side joint point), its partial angular
// velocity W_r (NodeWork::W_N, column r) and the partial velocity V_r of the point of S(k) at Ok
// (NodeWork::V_N; Kane and Levinson 1985 [KL85] Secs. 2.14, 2.16, 5.4), so that every point of S(k)
// has V_r + W_r x (p - p_Ok).  Revolute and spherical speeds are rotations (V_r = 0), a prismatic
// speed a translation (W_r = 0, V_r = axis_N), a universal joint's two speeds rotations about
// axis_N and the turned second axis.  The unit says which terms its joint has (Node::slides: some
// V_r != 0; Node::axis_rates: some W_r turns with the joint's own coordinates), and the passes add
// those terms only where the flag is set.
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
  // potential_energy; zero for a joint with no spring).
  double (*spring_energy)(const Node& n, const Joint& J, const double* x);
  // The joint's output columns (KaneEngine::output_row): w its node's workspace, torque a
  // prescribed joint's torque (prismatic: force).
  void (*output)(const Node& n, const NodeWork& w, double torque, const double* x,
                 const double* u, RowWriter& out);
  // Model building (model_building.cpp): validates the joint (jname names it in messages) and sets
  // its facts in the node (axes, prescribed motion, Node::slides, Node::axis_rates).
  void (*build)(const Joint& J, Node& n, const std::string& jname);
  // Pass 1 (kinematics.cpp, position_pass), for the joints whose kinematics the passes do not
  // inline (every shape but Base6, Axis1 and Rotation3, whose units leave it null): R_NJc from
  // the child-side joint frame at zero coordinates R_NJ0 = R_NJp R_PJ0; the speeds' W_N and V_N
  // columns; r_Pj (the joint point from Po, parent frame) moved by the joint's own translation.
  void (*position)(const Node& n, const double* x, const Eigen::Matrix3d& R_NJp,
                   const Eigen::Matrix3d& R_NJ0, Eigen::Matrix3d& R_NJc, NodeWork& w,
                   Eigen::Vector3d& r_Pj);
  // Pass 2 (velocity_pass), likewise: w_PC_N = sum W_r u_r, v_PC_N = sum V_r u_r (slides) and the
  // remainder alpha_PC_t_N of the relative angular acceleration beyond w_Jp x w_PC (axis_rates).
  void (*velocity)(const Node& n, const double* u, NodeWork& w);
  // Pass 6: adds the hinge's generalised active forces (spring, damper, motor) to f[0..nuj), for
  // the joints whose hinge the passes do not inline (null: none, or inlined).
  void (*hinge)(const Node& n, const Joint& J, double t, const double* x, const double* u,
                double* f);
  // q_J of R_J for output_row's attitudes (q_NC = q_NJp q_PJ0 q_J); null: the identity (or
  // inlined: shapes Axis1 and Rotation3).
  Eigen::Quaterniond (*joint_quat)(const Node& n, const double* x);
  // The shape of the joint's speeds (kane_engine.hpp), copied to Node::shape when the model is
  // built: the passes switch on it (the inlined cases Base6, Axis1, Rotation3; any other shape
  // by the verbs above).
  JointShape shape;
};

// The fused rigid path (rigid_fast_path.cpp) has a branch for these shapes only (the inlined
// free base, hinge and ball, and no speed); a scene with a joint of any other shape takes the
// general passes (dynamics(), output_row()). Derived from the shape, so a new joint type cannot
// claim the fused path without a branch there.
constexpr bool fused_shape(JointShape s) {
  return s == JointShape::Base6 || s == JointShape::Axis1 || s == JointShape::Rotation3 ||
         s == JointShape::None;
}

// The generalised active force of a scalar hinge: -k (q - neutral) - c q' + motor (a revolute
// torque, a prismatic force along the axis, one universal axis's torque).
inline double scalar_hinge(double stiffness, double neutral, double damping, double q, double qd,
                           double motor) {
  double f = 0;
  if (stiffness != 0) f -= stiffness * (q - neutral);
  if (damping != 0) f -= damping * qd;
  return f + motor;
}

// Verbs shared by the one-coordinate joints (revolute, prismatic; revolute.cpp): one position and
// one speed, none when prescribed; q' = u; TreeState angle, rate; TreeAccel angle_ddot.
void scalar_joint_sizes(bool prescribed, int& nqj, int& nuj);
void scalar_joint_q_rates(const Node& n, const double* x, const double* u, double* xdot);
void scalar_joint_pack(const Node& n, const TreeState& s, const TreeState::JointState& js,
                       double* x, double* u);
void scalar_joint_accel(const Node& n, const NodeWork& w, const Eigen::VectorXd& udot,
                        TreeAccel& a);
double scalar_joint_spring_energy(const Node& n, const Joint& J, const double* x);
// Labels "<joint><position>" and "<joint>.rate"; output columns through `write` (RowWriter::
// revolute or prismatic), and a prescribed joint's load.
void scalar_joint_labels(const Node& n, int n_q, const std::string& joint, const char* position,
                         std::vector<std::string>& out);
void scalar_joint_output(const Node& n, const NodeWork& w, double load, const double* x,
                         const double* u, void (RowWriter::*write)(int, double, double),
                         RowWriter& out);

const JointUnit& free_joint_unit();
const JointUnit& revolute_joint_unit();
const JointUnit& spherical_joint_unit();
const JointUnit& fixed_joint_unit();
const JointUnit& prismatic_joint_unit();
const JointUnit& universal_joint_unit();

// The one dispatch on JointType.
const JointUnit& joint_unit(JointType type);

}  // namespace crossdyn::kane
