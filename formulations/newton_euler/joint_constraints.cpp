#include "formulations/newton_euler/joint_constraints.hpp"

#include "core/rotation.hpp"

#include <cmath>
#include <numbers>

namespace crossdyn::newton_euler {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;
using rot::skew;

JointModel JointModel::from(const Joint& joint) {
  JointModel m;
  m.type = joint.type;
  m.parent = joint.parent;
  m.child = joint.child;
  switch (joint.type) {
    case JointType::Free: m.rows = 0; break;
    case JointType::Spherical: m.rows = 3; break;
    case JointType::Revolute: m.rows = 5; break;
    case JointType::Fixed: m.rows = 6; break;
  }
  m.r_P = joint.p_PoJ_P;
  m.r_C = joint.p_CoJ_C;
  m.q_PJ0 = joint.q_PJ0.normalized();
  m.R_PJ0 = m.q_PJ0.toRotationMatrix();
  m.a_P = joint.axis_P.normalized();
  m.a_C = m.R_PJ0.transpose() * m.a_P;  // system.hpp: axis_J = R_PJ0^T axis_P
  m.b1_P = m.a_P.unitOrthogonal();
  m.b2_P = m.a_P.cross(m.b1_P);
  m.e1_C = m.a_C.unitOrthogonal();
  m.e2_C = m.a_C.cross(m.e1_C);
  return m;
}

double revolute_angle_wrapped(const JointModel& m, const Matrix3d& R_PC) {
  // R_J = R_PJ0^T R_PC = Rot(a_C, angle), so R_J e1 = cos(angle) e1 + sin(angle) (a_C x e1).
  const Vector3d Re1 = m.R_PJ0.transpose() * (R_PC * m.e1_C);
  return std::atan2(m.e2_C.dot(Re1), m.e1_C.dot(Re1));
}

double unwrap_angle(double wrapped, double reference) {
  constexpr double two_pi = 2.0 * std::numbers::pi;
  return wrapped + two_pi * std::round((reference - wrapped) / two_pi);
}

void joint_kinematics(const JointModel& m, const BodyKinematics& P, const BodyKinematics& C,
                      JointKinematics& out) {
  out.q_PC = P.q_NB.conjugate() * C.q_NB;
  out.R_PC.noalias() = P.R_NB.transpose() * C.R_NB;
  out.w_PC_C = C.w_NB_B - out.R_PC.transpose() * P.w_NB_B;
  out.w_PC_P = out.R_PC * C.w_NB_B - P.w_NB_B;
  if (m.type == JointType::Revolute) {
    out.angle_wrapped = revolute_angle_wrapped(m, out.R_PC);
    out.rate = m.a_P.dot(out.w_PC_P);
  } else {
    out.angle_wrapped = 0;
    out.rate = 0;
  }
}

void constraint_rows(const JointModel& m, const BodyKinematics& P, const BodyKinematics& C,
                     const JointKinematics& jk, ConstraintRows& out) {
  out.J_P.setZero();
  out.J_C.setZero();
  out.g.setZero();
  out.gdot.setZero();
  out.gamma.setZero();
  if (m.type == JointType::Free) return;

  // Rows 0-2: the joint point J is the same point of P and C (system.hpp, "Joint kinematics").
  const Vector3d& w_P = P.w_NB_B;
  const Vector3d& w_C = C.w_NB_B;
  const Vector3d s_P_N = P.R_NB * m.r_P;  // p_PoJ_N
  const Vector3d s_C_N = C.R_NB * m.r_C;  // p_CoJ_N
  out.g.head<3>() = C.p_NoBo_N + s_C_N - P.p_NoBo_N - s_P_N;
  out.J_C.block<3, 3>(0, 0).setIdentity();
  out.J_C.block<3, 3>(0, 3).noalias() = -C.R_NB * skew(m.r_C);
  out.J_P.block<3, 3>(0, 0) = -Matrix3d::Identity();
  out.J_P.block<3, 3>(0, 3).noalias() = P.R_NB * skew(m.r_P);
  out.gdot.head<3>() = C.v_NBo_N + C.R_NB * w_C.cross(m.r_C) - P.v_NBo_N -
                       P.R_NB * w_P.cross(m.r_P);
  out.gamma.head<3>() = -(C.R_NB * w_C.cross(w_C.cross(m.r_C)) -
                          P.R_NB * w_P.cross(w_P.cross(m.r_P)));

  if (m.type == JointType::Revolute) {
    const Vector3d u = jk.R_PC * m.a_C;            // the child's axis, in P
    const Vector3d u_dot = jk.w_PC_P.cross(u);     // P-frame derivative of u
    const Vector3d transport_P = jk.R_PC * jk.w_PC_C.cross(w_C);
    const Vector3d* b[2] = {&m.b1_P, &m.b2_P};
    for (int k = 0; k < 2; ++k) {
      const Vector3d c = u.cross(*b[k]);
      out.g(3 + k) = b[k]->dot(u);
      out.J_C.block<1, 3>(3 + k, 3).noalias() = c.transpose() * jk.R_PC;
      out.J_P.block<1, 3>(3 + k, 3) = -c.transpose();
      out.gdot(3 + k) = c.dot(jk.w_PC_P);
      out.gamma(3 + k) = -(u_dot.cross(*b[k]).dot(jk.w_PC_P) + c.dot(transport_P));
    }
  } else if (m.type == JointType::Fixed) {
    const Quaterniond q_e = m.q_PJ0.conjugate() * jk.q_PC;
    const double s = q_e.w() < 0 ? -1.0 : 1.0;
    const Vector3d& w = jk.w_PC_C;
    const Matrix3d E = s * (q_e.w() * Matrix3d::Identity() + skew(q_e.vec()));
    const double qw_dot = -0.5 * q_e.vec().dot(w);
    const Vector3d qv_dot = 0.5 * (q_e.w() * w + q_e.vec().cross(w));
    const Matrix3d E_dot = s * (qw_dot * Matrix3d::Identity() + skew(qv_dot));
    const Matrix3d R_CP = jk.R_PC.transpose();
    out.g.tail<3>() = 2.0 * s * q_e.vec();
    out.J_C.block<3, 3>(3, 3) = E;
    out.J_P.block<3, 3>(3, 3).noalias() = -E * R_CP;
    out.gdot.tail<3>() = E * w;
    out.gamma.tail<3>() = -(E_dot * w + E * w.cross(R_CP * w_P));
  }
}

}  // namespace crossdyn::newton_euler
