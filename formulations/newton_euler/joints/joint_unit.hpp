// One joint type of the Newton-Euler engine: a JointUnit, the same verbs for every type, one file
// per type (joints/free.cpp, revolute.cpp, spherical.cpp, fixed.cpp, prismatic.cpp,
// universal.cpp; rows shared by two types: fixed.cpp's lock_rotation_rows, joints/axis_row.hpp). The unit of a joint is
// chosen once, from the scene's JointType, when its JointModel is built (joint_unit(), in
// joints/dispatch.cpp: the engine's one switch on JointType); the engine and the constraint code
// then call m.unit->verb(...) and never test the type. A verb a type does not have is nullptr
// (the caller skips it: one test of a pointer, no call); every unit has `model`.
//
// The equations of each verb are in joint_constraints.hpp (rows, gamma) and newton_euler.hpp
// (state, outputs); each unit file says which of them it implements.
//
// Verbs, in the order the engine uses them:
//   model            (Joint, JointModel) => rows, prescribed, has_angle, unwraps, translates and
//                    the type's constants (model building, after the common fields are set)
//   validate         (Joint, key) => throws InputError for a joint the type cannot take
//   relative         (model, P, C body states, jk with R_FG, w_FG_F) => jk.angle_wrapped, rate
//                    (and angle2_wrapped, rate2; a translation's r_PoJ_F, v_PoJ_F): the joint's
//                    own relative coordinates; nullptr: all 0
//   point_rows       (model, P, C, jk) => the joint's translation rows, in place of the common
//                    rows 0-2 (point coincidence) and of the node-frame chain rule (a unit with
//                    point_rows refuses nodes in its validate); nullptr: the common rows
//   rotation_rows    (model, jk) => the rotation rows of J_P, J_C (w.r.t. w_F, w_G), g, gdot,
//                    gamma (rows 3.. after the common point rows); nullptr: none (spherical, free)
//   track            (joint, model, t, jk, rows) => the joint's coordinates at this state
//                    (angles unwrapped against angle_ref) and a prescribed joint's time terms
//   load             (joint, model, jk, coordinates, t) => T_P, the torque of the spring, damper
//                    and motor on the child-side frame in P body components, and (a unit with
//                    JointModel::translates) F_P, the force on the child at its joint point in P
//                    components (the reaction on the parent at the same point); false: no load.
//                    The damper is JointModel::damping, damping2 (EngineOptions::
//                    test_damper_scale's); the engine applies the load in force_pass() and adds
//                    it to the joint's output load (<joint>.Fx .. .Mz, joint_load())
//   pack             (model, TreeState joint) => q_J, w_FG_G, the joint point's offset r_F and its
//                    F-frame rate v_F along a translation, and angle_ref (the engine-neutral
//                    coordinates in maximal ones)
//   accelerations    (joint, model, JointAccelInputs, t) => TreeAccel's angle_ddot, angle2_ddot
//                    or wdot_PC_C of joint j
//   potential        (joint, model, jk, coordinates) => e += the joint spring's energy (called
//                    only for a non-zero stiffness or stiffness2)
//   output           (joint, model, jk, coordinates, torque, t) => the pinned joint columns
//                    (core/output_layout.hpp: angle, rate, torque; w_PC_C; position, force;
//                    angle1, angle2, rate1, rate2)
//   violation        (model, jk, rows) => the largest violations (constraint.pos and .vel of a
//                    unit with point_rows, constraint.ang and constraint.angvel,
//                    newton_euler.hpp)
//   power            (joint, model, jk, torque, t) => the power of the joint's non-conservative
//                    loads, from the scene's Joint values (never test_damper_scale's): motor and
//                    damper (motor - damping rate) rate per coordinate (spherical: (motor -
//                    damping w_PC_C) . w_PC_C), a prescribed joint's drive torque (force) times
//                    its prescribed rate theta'(t) (the P column, newton_euler.hpp "Power");
//                    nullptr: none (fixed, free)
// A joint's coordinates are a JointCoords (joint_constraints.hpp): the angle (a prismatic joint's
// position) and a universal joint's second angle. The engine's state layout and its extra output
// columns do not depend on the joint type.
#pragma once

#include "core/engine.hpp"
#include "core/output_layout.hpp"
#include "core/system.hpp"
#include "formulations/newton_euler/cx_row_writer.hpp"
#include "formulations/newton_euler/joint_constraints.hpp"

#include <Eigen/Geometry>

#include <string>

namespace crossdyn::newton_euler {

// What a unit's accelerations verb reads, after the solve: the bodies' states and accelerations
// (rigid columns: a_NBo_N, wdot_NB_B) and the frames' d/dt w_F, d/dt w_G (joint_constraints.hpp).
template <class S>
struct JointAccelInputsT {
  const BodyKinematicsT<S>& P;
  const BodyKinematicsT<S>& C;
  const JointKinematicsT<S>& jk;
  Vec3<S> wdot_F, wdot_G;
  Vec6<S> nudot_P, nudot_C;
};
using JointAccelInputs = JointAccelInputsT<double>;

// The exact tangent (issue 27; newton_euler.cpp, accelerations_tangent()): a unit's verbs on
// S = Cx (scalar.hpp), the same templates as its double verbs (rigid or flexible sides).
// TreeState::JointState on S, and a joint's TreeAccel entries on S:
template <class S>
struct JointStateT {
  S angle = 0, rate = 0, angle2 = 0, rate2 = 0;
  Quat<S> q_J = Quat<S>::Identity();
  Vec3<S> w_PC_C = Vec3<S>::Zero();
};
template <class S>
struct JointAccelT {
  S angle_ddot = 0, angle2_ddot = 0;
  Vec3<S> wdot_PC_C = Vec3<S>::Zero();
};
struct JointVerbsCx {
  // The joints of the type these verbs cover (e.g. a spherical joint without a spring);
  // accelerations_tangent() returns false for a system with any other.
  bool (*covers)(const Joint& joint);
  void (*relative)(const JointModel& m, const BodyKinematicsT<Cx>& P, const BodyKinematicsT<Cx>& C,
                   JointKinematicsT<Cx>& jk);
  void (*point_rows)(const JointModel& m, const BodyKinematicsT<Cx>& P,
                     const BodyKinematicsT<Cx>& C, const JointKinematicsT<Cx>& jk,
                     ConstraintRowsT<Cx>& out);
  void (*rotation_rows)(const JointModel& m, const JointKinematicsT<Cx>& jk, ConstraintRowsT<Cx>& out);
  void (*track)(const Joint& joint, const JointModel& m, double t, const JointKinematicsT<Cx>& jk,
                ConstraintRowsT<Cx>& cr, JointCoordsT<Cx>& coords, const JointCoords& coords_ref);
  bool (*load)(const Joint& joint, const JointModel& m, const JointKinematicsT<Cx>& jk,
               const JointCoordsT<Cx>& coords, double t, Vec3<Cx>& T_P, Vec3<Cx>& F_P);
  void (*pack)(const JointModel& m, const JointStateT<Cx>& js, Quat<Cx>& q_J, Vec3<Cx>& w_FG_G,
               Vec3<Cx>& r_F, Vec3<Cx>& v_F);
  void (*accelerations)(const Joint& joint, const JointModel& m, const JointAccelInputsT<Cx>& in,
                        double t, JointAccelT<Cx>& a);
  // The output verbs on Cx (output_row_tangent(); the same templates as the double verbs):
  // the spring's energy, the pinned joint columns (through CxRowWriter), the power.
  void (*potential)(const Joint& joint, const JointModel& m, const JointKinematicsT<Cx>& jk,
                    const JointCoordsT<Cx>& coords, Cx& e);
  void (*output)(CxRowWriter& out, int j, const Joint& joint, const JointModel& m,
                 const JointKinematicsT<Cx>& jk, const JointCoordsT<Cx>& coords, Cx torque, double t);
  Cx (*power)(const Joint& joint, const JointModel& m, const JointKinematicsT<Cx>& jk, Cx torque,
              double t);
};

struct JointUnit {
  const char* name;
  void (*model)(const Joint& joint, JointModel& m);
  void (*validate)(const Joint& joint, const std::string& key);
  void (*relative)(const JointModel& m, const BodyKinematics& P, const BodyKinematics& C,
                   JointKinematics& jk);
  void (*point_rows)(const JointModel& m, const BodyKinematics& P, const BodyKinematics& C,
                     const JointKinematics& jk, ConstraintRows& out);
  void (*rotation_rows)(const JointModel& m, const JointKinematics& jk, ConstraintRows& out);
  void (*track)(const Joint& joint, const JointModel& m, double t, const JointKinematics& jk,
                ConstraintRows& cr, JointCoords& coords, const JointCoords& coords_ref);
  bool (*load)(const Joint& joint, const JointModel& m, const JointKinematics& jk,
               const JointCoords& coords, double t, Eigen::Vector3d& T_P, Eigen::Vector3d& F_P);
  void (*pack)(const JointModel& m, const TreeState::JointState& js, Eigen::Quaterniond& q_J,
               Eigen::Vector3d& w_FG_G, Eigen::Vector3d& r_F, Eigen::Vector3d& v_F,
               JointCoords& coords_ref);
  void (*accelerations)(const Joint& joint, const JointModel& m, const JointAccelInputs& in,
                        double t, TreeAccel& a, int j);
  void (*potential)(const Joint& joint, const JointModel& m, const JointKinematics& jk,
                    const JointCoords& coords, double& e);
  void (*output)(RowWriter& out, int j, const Joint& joint, const JointModel& m,
                 const JointKinematics& jk, const JointCoords& coords, double torque, double t);
  void (*violation)(const JointModel& m, const JointKinematics& jk, const ConstraintRows& cr,
                    double& pos, double& vel, double& ang, double& angvel);
  double (*power)(const Joint& joint, const JointModel& m, const JointKinematics& jk,
                  double torque, double t);
  const JointVerbsCx* cx;  // the verbs on Cx (nullptr: the type is not covered by the tangent)
};

// The verbs that joint_kinematics() and constraint_rows() call, on S.
template <class S>
auto relative_verb(const JointUnit& u) {
  if constexpr (kIsReal<S>) return u.relative;
  else return u.cx ? u.cx->relative : nullptr;
}
template <class S>
auto point_rows_verb(const JointUnit& u) {
  if constexpr (kIsReal<S>) return u.point_rows;
  else return u.cx ? u.cx->point_rows : nullptr;
}
template <class S>
auto rotation_rows_verb(const JointUnit& u) {
  if constexpr (kIsReal<S>) return u.rotation_rows;
  else return u.cx ? u.cx->rotation_rows : nullptr;
}

// The verbs the output code (newton_euler.cpp, write_outputs()) calls, on S.
template <class S>
auto load_verb(const JointUnit& u) {
  if constexpr (kIsReal<S>) return u.load;
  else return u.cx ? u.cx->load : nullptr;
}
template <class S>
auto potential_verb(const JointUnit& u) {
  if constexpr (kIsReal<S>) return u.potential;
  else return u.cx ? u.cx->potential : nullptr;
}
template <class S>
auto output_verb(const JointUnit& u) {
  if constexpr (kIsReal<S>) return u.output;
  else return u.cx ? u.cx->output : nullptr;
}
template <class S>
auto power_verb(const JointUnit& u) {
  if constexpr (kIsReal<S>) return u.power;
  else return u.cx ? u.cx->power : nullptr;
}

// The units (one file each) and the choice among them (joints/dispatch.cpp).
extern const JointUnit kFreeJoint;
extern const JointUnit kRevoluteJoint;
extern const JointUnit kSphericalJoint;
extern const JointUnit kFixedJoint;
extern const JointUnit kPrismaticJoint;
extern const JointUnit kUniversalJoint;
const JointUnit& joint_unit(JointType type);

// Verbs shared by the units of one coordinate (revolute, prismatic), joints/revolute.cpp: the
// spring energy stiffness (coords(0) - neutral_angle)^2 / 2 (a `potential`), and the pinned
// columns of the coordinate and its rate written by `write` (RowWriter::revolute or ::prismatic),
// a prescribed joint's from its profile followed by its torque (force) column.
void one_coordinate_potential(const Joint& joint, const JointModel& m, const JointKinematics& jk,
                              const JointCoords& coords, double& e);
// The power of a one-coordinate joint's motor and damper, (motor - damping rate) rate, or of a
// prescribed one's drive, torque (force) theta'(t) (joints/revolute.cpp; a `power`).
double one_coordinate_power(const Joint& joint, const JointModel& m, const JointKinematics& jk,
                            double torque, double t);
void one_coordinate_output(void (RowWriter::*write)(int, double, double), RowWriter& out, int j,
                           const Joint& joint, const JointModel& m, const JointKinematics& jk,
                           const JointCoords& coords, double torque, double t);
// The three above on the scalar S with the writer W (RowWriter on double, CxRowWriter on Cx),
// instantiated in joints/revolute.cpp; the double functions call them.
template <class S>
void one_coordinate_potential_t(const Joint& joint, const JointModel& m, const JointKinematicsT<S>& jk,
                                const JointCoordsT<S>& coords, S& e);
template <class S>
S one_coordinate_power_t(const Joint& joint, const JointModel& m, const JointKinematicsT<S>& jk,
                         S torque, double t);
template <class W, class S>
void one_coordinate_output_t(void (W::*write)(int, S, S), W& out, int j, const Joint& joint,
                             const JointModel& m, const JointKinematicsT<S>& jk,
                             const JointCoordsT<S>& coords, S torque, double t);

// The fixed joint's relative attitude lock (joint_constraints.hpp, "fixed") in rows row0..row0+2
// (fixed: 3; prismatic: 2), joints/fixed.cpp. The revolute row shared with the universal joint is
// joints/axis_row.hpp.
template <class S>
void lock_rotation_rows(const JointModel& m, const JointKinematicsT<S>& jk, int row0,
                        ConstraintRowsT<S>& out);

}  // namespace crossdyn::newton_euler
