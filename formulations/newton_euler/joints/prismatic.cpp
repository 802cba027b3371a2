// The prismatic joint (and the prescribed prismatic joint): the child slides along the axis a_P
// (fixed in P) with its attitude locked at R_PC = R_PJ0 (core/system.hpp, "prismatic"). Its unit
// (joint_unit.hpp) implements, from joint_constraints.hpp, "prismatic": its own point rows 0-1
// (the separation of the joint points normal to the axis is zero), the fixed joint's attitude
// lock in rows 2-4 (lock_rotation_rows, joints/fixed.cpp; Shuster 1993, Eq. 305) and, prescribed,
// row 5 (the position, a rheonomic driving constraint: Haug 1989, "Computer Aided Kinematics and
// Dynamics of Mechanical Systems", Sec. 6.3), whose multiplier is the joint's force. From
// core/system.hpp: the spring, damper and motor force along the axis at the joint point, its
// energy, s'' and the output columns. The point's kinematics in the moving frame P: Kane, Likins
// & Levinson 1983, "Spacecraft Dynamics", Sec. 2.7. Not at a node of a flexible body (validate),
// so the joint frames are the body frames: F = P, G = C.
#include "formulations/newton_euler/joints/joint_unit.hpp"

#include "core/errors.hpp"
#include "core/rotation.hpp"

#include <algorithm>
#include <cmath>

namespace crossdyn::newton_euler {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

namespace {

void model(const Joint& joint, JointModel& m) {
  m.prescribed = joint.prescribed.has_value();
  m.rows = joint.prescribed ? 6 : 5;
  m.has_angle = true;
  m.translates = true;
}

void validate(const Joint& joint, const std::string& key) {
  if (joint.axis_P.norm() < 1e-12) throw InputError(key + ": axis must be a non-zero vector");
  if (joint.parent_node >= 0 || joint.child_node >= 0)
    throw InputError(key + ": a prismatic joint cannot be attached at a node of a flexible body");
}

// D_F = R_NP^T (p_NoCo_N + R_NC s_C - p_NoPo_N) and u = R_NP^T (v_C - v_P) + R_PC (w_C x s_C)
// (joint_constraints.hpp, "prismatic"); s = a_P . (D_F - s_P), s' = a_P . u + (w_P x a_P) . D_F.
void relative(const JointModel& m, const BodyKinematics& P, const BodyKinematics& C,
              JointKinematics& jk) {
  const Vector3d& s_C = jk.G.s_B;
  jk.r_PoJ_F.noalias() = P.R_NB.transpose() * (C.p_NoBo_N + C.R_NB * s_C - P.p_NoBo_N);
  jk.v_PoJ_F.noalias() = P.R_NB.transpose() * (C.v_NBo_N - P.v_NBo_N);
  jk.v_PoJ_F.noalias() += jk.R_PC * C.w_NB_B.cross(s_C);
  jk.angle_wrapped = m.a_P.dot(jk.r_PoJ_F - jk.F.s_B);
  jk.rate = m.a_P.dot(jk.v_PoJ_F) + P.w_NB_B.cross(m.a_P).dot(jk.r_PoJ_F);
}

// Row i: c . (separation of the joint points), c a unit vector fixed in P (joint_constraints.hpp,
// "prismatic").
void point_row(const BodyKinematics& P, const BodyKinematics& C, const JointKinematics& jk,
               const Vector3d& c, int i, ConstraintRows& out) {
  const Vector3d& s_C = jk.G.s_B;
  const Vector3d& D = jk.r_PoJ_F;
  const Vector3d& u = jk.v_PoJ_F;
  const Vector3d& w_P = P.w_NB_B;
  const Vector3d& w_C = C.w_NB_B;
  const Vector3d c_N = P.R_NB * c;
  const Vector3d c_C = jk.R_PC.transpose() * c;
  const Vector3d wc = w_P.cross(c);
  out.J_C.block<1, 3>(i, 0) = c_N.transpose();
  out.J_C.block<1, 3>(i, 3) = s_C.cross(c_C).transpose();
  out.J_P.block<1, 3>(i, 0) = -c_N.transpose();
  out.J_P.block<1, 3>(i, 3) = c.cross(D).transpose();
  out.g(i) = c.dot(D - jk.F.s_B);
  out.gdot(i) = c.dot(u) + wc.dot(D);
  out.gamma(i) = -(w_P.cross(wc).dot(D) + 2.0 * wc.dot(u) + c_C.dot(w_C.cross(w_C.cross(s_C))));
}

void point_rows(const JointModel& m, const BodyKinematics& P, const BodyKinematics& C,
                const JointKinematics& jk, ConstraintRows& out) {
  point_row(P, C, jk, m.b1_P, 0, out);
  point_row(P, C, jk, m.b2_P, 1, out);
  if (m.prescribed) point_row(P, C, jk, m.a_P, 5, out);  // s (track subtracts the profile)
}

void rotation_rows(const JointModel& m, const JointKinematics& jk, ConstraintRows& out) {
  lock_rotation_rows(m, jk, 2, out);  // R_PC = R_PJ0 (joints/fixed.cpp)
}

// A prescribed joint's row 5: g_5 = s - (angle0 + theta(t)), g_5' = s' - theta'(t),
// gamma_5 += theta''(t) (Haug 1989, Sec. 6.3). Otherwise the position itself.
void track(const Joint& J, const JointModel& m, double t, const JointKinematics& jk,
           ConstraintRows& cr, JointCoords& coords, const JointCoords& /*coords_ref*/) {
  if (m.prescribed) {
    coords(0) = J.angle0 + J.prescribed->angle(t);
    cr.g(5) = jk.angle_wrapped - coords(0);
    cr.gdot(5) -= J.prescribed->velocity(t);
    cr.gamma(5) += J.prescribed->accel(t);
  } else {
    coords(0) = jk.angle_wrapped;
  }
}

// Spring, damper and motor force along the axis on the child (core/system.hpp), in P; the engine
// applies it at the child's joint point and the reaction on the parent at the same point.
bool load(const Joint& J, const JointModel& m, const JointKinematics& jk, const JointCoords& coords,
          double t, Vector3d& T_P, Vector3d& F_P) {
  const double F = -J.stiffness * (coords(0) - J.neutral_angle) - m.damping * jk.rate +
                   (J.motor_revolute.empty() ? 0.0 : J.motor_revolute.value(t)(0));
  if (F == 0) return false;
  T_P.setZero();
  F_P = F * m.a_P;
  return true;
}

void pack(const JointModel& m, const TreeState::JointState& js, Quaterniond& q_J, Vector3d& w_FG_G,
          Vector3d& r_F, Vector3d& v_F, JointCoords& coords_ref) {
  q_J.setIdentity();
  w_FG_G.setZero();
  r_F = js.angle * m.a_P;
  v_F = js.rate * m.a_P;
  coords_ref(0) = js.angle;
}

// s'' = J_row nu' - gamma_row of the axial row (c = a_P), by g'' = J nu' - gamma.
void accelerations(const Joint& J, const JointModel& m, const JointAccelInputs& in, double t,
                   TreeAccel& a, int j) {
  double& s_ddot = a.angle_ddot[static_cast<std::size_t>(j)];
  if (m.prescribed) {
    s_ddot = J.prescribed->accel(t);
    return;
  }
  ConstraintRows row;
  point_row(in.P, in.C, in.jk, m.a_P, 0, row);
  s_ddot = row.J_P.row(0).dot(in.nudot_P) + row.J_C.row(0).dot(in.nudot_C) - row.gamma(0);
}

// Position and rate (a prescribed joint's from its profile, then its force: row 5's multiplier).
void output(RowWriter& out, int j, const Joint& J, const JointModel& m, const JointKinematics& jk,
            const JointCoords& coords, double force, double t) {
  one_coordinate_output(&RowWriter::prismatic, out, j, J, m, jk, coords, force, t);
}

// The separation normal to the axis and its rate (constraint.pos, .vel), the attitude away from
// the offset and the relative angular velocity (.ang, .angvel); a prescribed joint adds its
// position and rate away from the profile to .pos and .vel.
void violation(const JointModel& m, const JointKinematics& jk, const ConstraintRows& cr,
               double& pos_violation, double& vel_violation, double& ang_violation,
               double& angvel_violation) {
  pos_violation = std::max(pos_violation, cr.g.head<2>().norm());
  vel_violation = std::max(vel_violation, cr.gdot.head<2>().norm());
  ang_violation = std::max(ang_violation, rot::angle_between(m.q_PJ0, jk.q_FG));
  angvel_violation = std::max(angvel_violation, jk.w_FG_G.norm());
  if (m.prescribed) {
    pos_violation = std::max(pos_violation, std::abs(cr.g(5)));
    vel_violation = std::max(vel_violation, std::abs(cr.gdot(5)));
  }
}

}  // namespace

const JointUnit kPrismaticJoint{"prismatic", model,         validate,      relative,  point_rows,
                                rotation_rows, track,       load,          pack,      accelerations,
                                one_coordinate_potential, output, violation,
                                one_coordinate_power};

}  // namespace crossdyn::newton_euler
