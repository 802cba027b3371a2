// One joint type of the Newton-Euler engine: a JointUnit, the same verbs for every type, one file
// per type (joints/free.cpp, revolute.cpp, spherical.cpp, fixed.cpp). The unit of a joint is
// chosen once, from the scene's JointType, when its JointModel is built (joint_unit(), in
// joints/dispatch.cpp: the engine's one switch on JointType); the engine and the constraint code
// then call m.unit->verb(...) and never test the type. A verb a type does not have is nullptr
// (the caller skips it: one test of a pointer, no call); every unit has `model`.
//
// The equations of each verb are in joint_constraints.hpp (rows, gamma) and newton_euler.hpp
// (state, outputs); each unit file says which of them it implements.
//
// Verbs, in the order the engine uses them:
//   model            (Joint, JointModel) => rows, prescribed, has_angle, unwraps (model building)
//   validate         (Joint, key) => throws InputError for a joint the type cannot take
//   relative         (model, jk with R_FG, w_FG_F) => jk.angle_wrapped, jk.rate (the joint's own
//                    relative coordinates; nullptr: both 0)
//   rotation_rows    (model, jk) => rows 3.. of J_P, J_C (w.r.t. w_F, w_G), g, gdot, gamma; the
//                    rows 0-2 (point coincidence) and the node-frame chain rule are common
//                    (constraint_rows()); nullptr: no rotation rows (spherical, free)
//   track            (joint, model, t, jk, rows) => the joint's angle at this state (unwrapped
//                    against angle_ref) and a prescribed joint's time terms in its rows
//   load             (joint, model, jk, angle, t) => T_P, the torque of the spring, damper and
//                    motor on the child-side frame in P body components; false: no load
//   pack             (model, TreeState joint) => q_J, w_FG_G and angle_ref (the engine-neutral
//                    coordinates in maximal ones)
//   accelerations    (joint, model, jk, d/dt w_F, d/dt w_G, t) => angle_ddot or wdot_PC_C
//   potential        (joint, model, jk, angle) => e += the joint spring's energy (called only
//                    for a non-zero stiffness)
//   output           (joint, model, jk, angle, torque, t) => the pinned joint columns
//                    (core/output_layout.hpp: angle, rate, torque; w_PC_C)
//   violation        (model, jk, rows) => the largest angular violations (constraint.ang and
//                    constraint.angvel, newton_euler.hpp)
// The engine's state layout and its extra output columns do not depend on the joint type.
#pragma once

#include "core/engine.hpp"
#include "core/output_layout.hpp"
#include "core/system.hpp"
#include "formulations/newton_euler/joint_constraints.hpp"

#include <Eigen/Geometry>

#include <string>

namespace crossdyn::newton_euler {

struct JointUnit {
  const char* name;
  void (*model)(const Joint& joint, JointModel& m);
  void (*validate)(const Joint& joint, const std::string& key);
  void (*relative)(const JointModel& m, JointKinematics& jk);
  void (*rotation_rows)(const JointModel& m, const JointKinematics& jk, ConstraintRows& out);
  void (*track)(const Joint& joint, const JointModel& m, double t, const JointKinematics& jk,
                ConstraintRows& cr, double& angle, double angle_ref);
  bool (*load)(const Joint& joint, const JointModel& m, const JointKinematics& jk, double angle,
               double t, Eigen::Vector3d& T_P);
  void (*pack)(const JointModel& m, const TreeState::JointState& js, Eigen::Quaterniond& q_J,
               Eigen::Vector3d& w_FG_G, double& angle_ref);
  void (*accelerations)(const Joint& joint, const JointModel& m, const JointKinematics& jk,
                        const Eigen::Vector3d& wdot_F, const Eigen::Vector3d& wdot_G, double t,
                        double& angle_ddot, Eigen::Vector3d& wdot_PC_C);
  void (*potential)(const Joint& joint, const JointModel& m, const JointKinematics& jk,
                    double angle, double& e);
  void (*output)(RowWriter& out, int j, const Joint& joint, const JointModel& m,
                 const JointKinematics& jk, double angle, double torque, double t);
  void (*violation)(const JointModel& m, const JointKinematics& jk, const ConstraintRows& cr,
                    double& ang, double& angvel);
};

// The units (one file each) and the choice among them (joints/dispatch.cpp).
extern const JointUnit kFreeJoint;
extern const JointUnit kRevoluteJoint;
extern const JointUnit kSphericalJoint;
extern const JointUnit kFixedJoint;
const JointUnit& joint_unit(JointType type);

}  // namespace crossdyn::newton_euler
