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
template <class S>
void relative(const JointModel& m, const BodyKinematicsT<S>& P, const BodyKinematicsT<S>& C,
              JointKinematicsT<S>& jk) {
  const Vec3<S>& s_C = jk.G.s_B;
  jk.r_PoJ_F.noalias() = P.R_NB.transpose() * (C.p_NoBo_N + C.R_NB * s_C - P.p_NoBo_N);
  jk.v_PoJ_F.noalias() = P.R_NB.transpose() * (C.v_NBo_N - P.v_NBo_N);
  jk.v_PoJ_F.noalias() += jk.R_PC * tcross<S>(C.w_NB_B, s_C);
  jk.angle_wrapped = tdot<S>(m.a_P, Vec3<S>(jk.r_PoJ_F - jk.F.s_B));
  jk.rate = tdot<S>(m.a_P, jk.v_PoJ_F) + tdot<S>(tcross<S>(P.w_NB_B, m.a_P), jk.r_PoJ_F);
}

// Row i: c . (separation of the joint points), c a unit vector fixed in P (joint_constraints.hpp,
// "prismatic").
template <class S>
void point_row(const BodyKinematicsT<S>& P, const BodyKinematicsT<S>& C, const JointKinematicsT<S>& jk,
               const Vector3d& c, int i, ConstraintRowsT<S>& out) {
  const Vec3<S>& s_C = jk.G.s_B;
  const Vec3<S>& D = jk.r_PoJ_F;
  const Vec3<S>& u = jk.v_PoJ_F;
  const Vec3<S>& w_P = P.w_NB_B;
  const Vec3<S>& w_C = C.w_NB_B;
  const Vec3<S> c_N = P.R_NB * c;
  const Vec3<S> c_C = jk.R_PC.transpose() * c;
  const Vec3<S> wc = tcross<S>(w_P, c);
  out.J_C.template block<1, 3>(i, 0) = c_N.transpose();
  out.J_C.template block<1, 3>(i, 3) = tcross<S>(s_C, c_C).transpose();
  out.J_P.template block<1, 3>(i, 0) = -c_N.transpose();
  out.J_P.template block<1, 3>(i, 3) = tcross<S>(c, D).transpose();
  out.g(i) = tdot<S>(c, Vec3<S>(D - jk.F.s_B));
  out.gdot(i) = tdot<S>(c, u) + tdot<S>(wc, D);
  out.gamma(i) = -(tdot<S>(tcross<S>(w_P, wc), D) + 2.0 * tdot<S>(wc, u) +
                   tdot<S>(c_C, tcross<S>(w_C, tcross<S>(w_C, s_C))));
}

template <class S>
void point_rows(const JointModel& m, const BodyKinematicsT<S>& P, const BodyKinematicsT<S>& C,
                const JointKinematicsT<S>& jk, ConstraintRowsT<S>& out) {
  point_row<S>(P, C, jk, m.b1_P, 0, out);
  point_row<S>(P, C, jk, m.b2_P, 1, out);
  if (m.prescribed) point_row<S>(P, C, jk, m.a_P, 5, out);  // s (track subtracts the profile)
}

template <class S>
void rotation_rows(const JointModel& m, const JointKinematicsT<S>& jk, ConstraintRowsT<S>& out) {
  lock_rotation_rows<S>(m, jk, 2, out);  // R_PC = R_PJ0 (joints/fixed.cpp)
}

// A prescribed joint's row 5: g_5 = s - (angle0 + theta(t)), g_5' = s' - theta'(t),
// gamma_5 += theta''(t) (Haug 1989, Sec. 6.3). Otherwise the position itself.
template <class S>
void track(const Joint& J, const JointModel& m, double t, const JointKinematicsT<S>& jk,
           ConstraintRowsT<S>& cr, JointCoordsT<S>& coords, const JointCoords& /*coords_ref*/) {
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
template <class S>
bool load(const Joint& J, const JointModel& m, const JointKinematicsT<S>& jk,
          const JointCoordsT<S>& coords, double t, Vec3<S>& T_P, Vec3<S>& F_P) {
  const S F = -J.stiffness * (coords(0) - J.neutral_angle) - m.damping * jk.rate +
              (J.motor_revolute.empty() ? 0.0 : J.motor_revolute.value(t)(0));
  if (F == S(0)) return false;
  T_P.setZero();
  F_P = F * m.a_P;
  return true;
}

template <class S>
void pack_t(const JointModel& m, const JointStateT<S>& js, Quat<S>& q_J, Vec3<S>& w_FG_G,
            Vec3<S>& r_F, Vec3<S>& v_F) {
  q_J.setIdentity();
  w_FG_G.setZero();
  r_F = js.angle * m.a_P;
  v_F = js.rate * m.a_P;
}

void pack(const JointModel& m, const TreeState::JointState& js, Quaterniond& q_J, Vector3d& w_FG_G,
          Vector3d& r_F, Vector3d& v_F, JointCoords& coords_ref) {
  pack_t<double>(m, JointStateT<double>{js.angle, js.rate, js.angle2, js.rate2, js.q_J, js.w_PC_C},
                 q_J, w_FG_G, r_F, v_F);
  coords_ref(0) = js.angle;
}

// s'' = J_row nu' - gamma_row of the axial row (c = a_P), by g'' = J nu' - gamma.
template <class S>
void accelerations_t(const Joint& J, const JointModel& m, const JointAccelInputsT<S>& in, double t,
                     JointAccelT<S>& a) {
  if (m.prescribed) {
    a.angle_ddot = J.prescribed->accel(t);
    return;
  }
  ConstraintRowsT<S> row;
  point_row<S>(in.P, in.C, in.jk, m.a_P, 0, row);
  a.angle_ddot = tdot<S>(row.J_P.row(0), in.nudot_P) + tdot<S>(row.J_C.row(0), in.nudot_C) -
                 row.gamma(0);
}

void accelerations(const Joint& J, const JointModel& m, const JointAccelInputs& in, double t,
                   TreeAccel& a, int j) {
  JointAccelT<double> aj;
  accelerations_t<double>(J, m, in, t, aj);
  a.angle_ddot[static_cast<std::size_t>(j)] = aj.angle_ddot;
}

// Every prismatic joint is covered by the tangent.
bool covers(const Joint& /*J*/) { return true; }

void output_cx(CxRowWriter& out, int j, const Joint& J, const JointModel& m,
               const JointKinematicsT<Cx>& jk, const JointCoordsT<Cx>& coords, Cx force, double t) {
  one_coordinate_output_t(&CxRowWriter::prismatic, out, j, J, m, jk, coords, force, t);
}

const JointVerbsCx kCx{covers,
                       relative<Cx>,
                       point_rows<Cx>,
                       rotation_rows<Cx>,
                       track<Cx>,
                       load<Cx>,
                       pack_t<Cx>,
                       accelerations_t<Cx>,
                       one_coordinate_potential_t<Cx>,
                       output_cx,
                       one_coordinate_power_t<Cx>};

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

const JointUnit kPrismaticJoint{"prismatic",
                                model,
                                validate,
                                relative<double>,
                                point_rows<double>,
                                rotation_rows<double>,
                                track<double>,
                                load<double>,
                                pack,
                                accelerations,
                                one_coordinate_potential,
                                output,
                                violation,
                                one_coordinate_power,
                                &kCx};

}  // namespace crossdyn::newton_euler
