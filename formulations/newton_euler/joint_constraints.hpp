// Joint constraints of the Newton-Euler (maximal-coordinate) formulation: for one joint between a
// parent body P and a child body C, the position-level constraint g(x) = 0, its Jacobian
// J = [J_P J_C] with g' = J nu exactly, and the acceleration-level right-hand side gamma with
// g'' = J nu' - gamma, i.e. J nu' = gamma on the motion (gamma = -Jdot nu).
//
// Notation (Drake monogram, see core/system.hpp): R_NP, R_NC body attitudes; p_NoPo_N, p_NoCo_N
// CM positions; w_NP_P, w_NC_C inertial angular velocities in body axes; r_P = p_PoJ_P,
// r_C = p_CoJ_C the joint point in each body. A body's generalised velocity is
// nu_B = [v_NBo_N; w_NB_B] (CM velocity in N, angular velocity in B), as in paper Eqs. (1), (2).
//
// Constraint rows (Kane, Likins & Levinson 1983, Sec. 2.4 and 2.6 for the kinematics; Haug 1989,
// "Computer Aided Kinematics and Dynamics of Mechanical Systems", Sec. 3.3 and 6.3 for the form
// J nu' = gamma):
//   rows 0-2, every joint (point coincidence, in N):
//     g = p_NoCo_N + R_NC r_C - p_NoPo_N - R_NP r_P
//     J_C = [ I, -R_NC [r_C x] ],  J_P = [ -I, R_NP [r_P x] ]
//     gamma = -( R_NC (w_C x (w_C x r_C)) - R_NP (w_P x (w_P x r_P)) )
//   revolute, rows 3-4 (the child's copy of the axis stays on the parent's axis):
//     u = R_PC a_C (a_C = the axis in C, constant), b_1, b_2 unit vectors fixed in P, normal to a_P;
//     g_k = b_k . u;  g_k' = c_k . w_PC_P with c_k = u x b_k, w_PC_P = R_PC w_C - w_P
//     J_C = c_k^T R_PC,  J_P = -c_k^T
//     gamma_k = -( (u' x b_k) . w_PC_P + c_k . R_PC (w_PC_C x w_C) ),  u' = w_PC_P x u
//     (the P-frame derivative of w_PC_P is R_PC w_C' - w_P' + R_PC (w_PC_C x w_C), because
//      d/dt R_PC = R_PC [w_PC_C x]).
//   fixed, rows 3-5 (relative attitude stays at the offset q_PJ0):
//     q_e = q_PJ0^* (x) q_PC, s = sign(q_e.w);  g = 2 s vec(q_e)
//     g' = E w_PC_C with E = s (q_e.w I + [vec(q_e) x])  (Shuster 1993 Eq. 305),
//     w_PC_C = w_C - R_CP w_P,  J_C = E, J_P = -E R_CP
//     gamma = -( E' w_PC_C + E (w_PC_C x R_CP w_P) )
//   spherical: rows 0-2 only.
// Rows beyond rows() are zero (TreeKkt pads every joint block to 6 rows).
#pragma once

#include "core/system.hpp"
#include "formulations/newton_euler/tree_kkt.hpp"

#include <Eigen/Geometry>

namespace crossdyn::newton_euler {

// The constant description of one joint (built once from System::joints[j]).
struct JointModel {
  JointType type = JointType::Revolute;
  int parent = -1, child = -1;
  int rows = 0;                       // 3 (spherical), 5 (revolute), 6 (fixed), 0 (free)
  Eigen::Vector3d r_P = Eigen::Vector3d::Zero();   // p_PoJ_P
  Eigen::Vector3d r_C = Eigen::Vector3d::Zero();   // p_CoJ_C
  Eigen::Quaterniond q_PJ0 = Eigen::Quaterniond::Identity();
  Eigen::Matrix3d R_PJ0 = Eigen::Matrix3d::Identity();
  Eigen::Vector3d a_P = Eigen::Vector3d::UnitZ();  // revolute axis in P
  Eigen::Vector3d a_C = Eigen::Vector3d::UnitZ();  // the same axis in C (= R_PJ0^T a_P, constant)
  Eigen::Vector3d b1_P, b2_P;         // unit, fixed in P, (a_P, b1_P, b2_P) right-handed
  Eigen::Vector3d e1_C, e2_C;         // unit, in C (J0) axes, (a_C, e1_C, e2_C) right-handed

  static JointModel from(const Joint& joint);
};

// One body's kinematic state, read from the engine's state vector.
struct BodyKinematics {
  Eigen::Quaterniond q_NB = Eigen::Quaterniond::Identity();  // unit
  Eigen::Matrix3d R_NB = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_NoBo_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_NBo_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d w_NB_B = Eigen::Vector3d::Zero();
};

// Relative kinematics of a joint's child C in its parent P.
struct JointKinematics {
  Eigen::Quaterniond q_PC = Eigen::Quaterniond::Identity();
  Eigen::Matrix3d R_PC = Eigen::Matrix3d::Identity();
  Eigen::Vector3d w_PC_C = Eigen::Vector3d::Zero();  // w_C - R_CP w_P
  Eigen::Vector3d w_PC_P = Eigen::Vector3d::Zero();  // R_PC w_C - w_P
  double angle_wrapped = 0;  // revolute: in (-pi, pi], the rotation of C about the axis
  double rate = 0;           // revolute: a_P . w_PC_P
};

// The constraint rows of one joint at one state.
struct ConstraintRows {
  Matrix6d J_P = Matrix6d::Zero();
  Matrix6d J_C = Matrix6d::Zero();
  Vector6d g = Vector6d::Zero();      // position violation (rows 0-2 m, 3-5 rad-like)
  Vector6d gdot = Vector6d::Zero();   // J nu: velocity violation
  Vector6d gamma = Vector6d::Zero();  // -Jdot nu
};

// (P, C body states) => relative kinematics of joint `m`.
void joint_kinematics(const JointModel& m, const BodyKinematics& P, const BodyKinematics& C,
                      JointKinematics& out);

// (P, C body states, relative kinematics) => constraint rows. No allocation.
void constraint_rows(const JointModel& m, const BodyKinematics& P, const BodyKinematics& C,
                     const JointKinematics& jk, ConstraintRows& out);

// Angle of a revolute joint's child about its axis: atan2 of the rotated e1 in (e1, e2).
double revolute_angle_wrapped(const JointModel& m, const Eigen::Matrix3d& R_PC);

// The branch of `wrapped` (+ 2 pi k) nearest to `reference`.
double unwrap_angle(double wrapped, double reference);

}  // namespace crossdyn::newton_euler
