// The universal joint (a two-axis gimbal): R_PC = Rot(n1, a1) Rot(n2, a2) R_PJ0 (core/system.hpp,
// "universal"), n1 = axis_P fixed in P, n2 = axis2_P at zero angles, turned by a1 (so fixed in
// C: n2_G = R_PJ0^T n2). Its unit (joint_unit.hpp) implements, from joint_constraints.hpp, the
// common point rows 0-2 and the "universal" row 3 (the revolute's axis row, joints/axis_row.hpp,
// with b = n1 and u = R_FG n2_G: the angle between the two axes is constant), and from
// core/system.hpp the two angles and rates, the per-axis spring, damper and motor torques, their
// energy, a1'' and a2'' and the output columns.
//   Angles (Rot(k, t) v = (k.v) k + cos t (v - (k.v) k) + sin t k x v; Kane, Likins & Levinson
//   1983, "Spacecraft Dynamics", Sec. 1.2): with R = R_FG R_PJ0^T = Rot(n1, a1) Rot(n2, a2),
//     R n2 = Rot(n1, a1) n2    =>  a1 = atan2((n1 x n2) . R n2,   (n2 - (n1.n2) n1) . R n2)
//     R^T n1 = Rot(n2, -a2) n1 =>  a2 = atan2((n1 x n2) . R^T n1, (n1 - (n1.n2) n2) . R^T n1)
//   Rates: w_FG_F = n1 a1' + u a2' (u = R n2, the current second axis), n = n1 x u normal to both:
//     a1' = w . (u x n) / |n|^2,  a2' = w . (n x n1) / |n|^2  (the dual basis of (n1, u, n)).
//   Accelerations: d/dt w_FG_F (F frame) = n1 a1'' + u a2'' + (w_FG_F x u) a2', so a1'', a2'' are
//   the same dual components of d/dt w_FG_F - (w_FG_F x u) a2'.
//   Loads: tau_k is the generalised force of angle k (the spring's -stiffness_k (a_k - neutral_k)
//   is that of V): the torque on the child (reaction on the parent) is T = tau_1 e1 + tau_2 e2
//   with e1 = (u x n) / |n|^2, e2 = (n x n1) / |n|^2 the dual vectors above, so that its power is
//   T . w_FG_F = tau_1 a1' + tau_2 a2'. The constraint keeps n1 . u = n1 . n2, so for
//   perpendicular axes e1 = n1, e2 = u: the torques tau_1 n1 + tau_2 u about the two axes.
// Not at a node of a flexible body (validate), so F = P and G = C.
#include "formulations/newton_euler/joints/joint_unit.hpp"

#include "core/errors.hpp"
#include "formulations/newton_euler/joints/axis_row.hpp"

#include <algorithm>
#include <cmath>

namespace crossdyn::newton_euler {

using Eigen::Quaterniond;
using Eigen::Vector2d;
using Eigen::Vector3d;

namespace {

void model(const Joint& joint, JointModel& m) {
  m.rows = 4;
  m.has_angle = true;
  m.unwraps = true;
  m.a2_P = joint.axis2_P.normalized();
  m.a2_C = m.R_PJ0.transpose() * m.a2_P;
  m.a12 = m.a_P.dot(m.a2_P);
}

void validate(const Joint& joint, const std::string& key) {
  if (joint.axis_P.norm() < 1e-12 || joint.axis2_P.norm() < 1e-12)
    throw InputError(key + ": axis and axis2 must be non-zero vectors");
  if (joint.axis_P.normalized().cross(joint.axis2_P.normalized()).norm() < 1e-6)
    throw InputError(key + ": axis and axis2 must not be parallel");
  if (joint.prescribed) throw InputError(key + ": a universal joint cannot be prescribed");
  if (joint.parent_node >= 0 || joint.child_node >= 0)
    throw InputError(key + ": a universal joint cannot be attached at a node of a flexible body");
}

// The dual vectors e1, e2 of (n1, u) in the basis (n1, u, n = n1 x u) (header): e_k . n1, e_k . u
// = the identity, e_k . n = 0.
template <class S>
void dual(const Vector3d& n1, const Vec3<S>& u, Vec3<S>& e1, Vec3<S>& e2) {
  const Vec3<S> n = tcross<S>(n1, u);
  const S nn = tsquared_norm<S>(n);
  e1 = tcross<S>(u, n) / nn;
  e2 = tcross<S>(n, n1) / nn;
}

// The components of v on n1 and u (v = n1 x_1 + u x_2 + n x_3).
template <class S>
Eigen::Matrix<S, 2, 1> split(const Vec3<S>& v, const Vector3d& n1, const Vec3<S>& u) {
  Vec3<S> e1, e2;
  dual<S>(n1, u, e1, e2);
  return Eigen::Matrix<S, 2, 1>(tdot<S>(v, e1), tdot<S>(v, e2));
}

template <class S>
void relative(const JointModel& m, const BodyKinematicsT<S>& /*P*/, const BodyKinematicsT<S>& /*C*/,
              JointKinematicsT<S>& jk) {
  const Vector3d& n1 = m.a_P;
  const Vector3d& n2 = m.a2_P;
  const Vector3d n12 = n1.cross(n2);
  const Vec3<S> u = jk.R_FG * m.a2_C;                           // R n2
  const Vec3<S> v = m.R_PJ0 * (jk.R_FG.transpose() * n1);       // R^T n1
  jk.angle_wrapped = tatan2(tdot<S>(n12, u), tdot<S>(Vector3d(n2 - m.a12 * n1), u));
  jk.angle2_wrapped = tatan2(tdot<S>(n12, v), tdot<S>(Vector3d(n1 - m.a12 * n2), v));
  const Eigen::Matrix<S, 2, 1> rates = split<S>(jk.w_FG_F, n1, u);
  jk.rate = rates(0);
  jk.rate2 = rates(1);
}

// joint_constraints.hpp, "universal": row 3.
template <class S>
void rotation_rows(const JointModel& m, const JointKinematicsT<S>& jk, ConstraintRowsT<S>& out) {
  const Vec3<S> u = jk.R_FG * m.a2_C;
  const Vec3<S> u_dot = tcross<S>(jk.w_FG_F, u);
  const Vec3<S> transport_F = jk.R_FG * tcross<S>(jk.w_FG_G, jk.w_G);
  axis_row<S>(jk, u, u_dot, transport_F, m.a_P, 3, out);
  out.g(3) -= m.a12;
}

template <class S>
void track(const Joint& /*J*/, const JointModel& /*m*/, double /*t*/, const JointKinematicsT<S>& jk,
           ConstraintRowsT<S>& /*cr*/, JointCoordsT<S>& coords, const JointCoords& coords_ref) {
  coords(0) = unwrap_angle(jk.angle_wrapped, coords_ref(0));
  coords(1) = unwrap_angle(jk.angle2_wrapped, coords_ref(1));
}

template <class S>
bool load(const Joint& J, const JointModel& m, const JointKinematicsT<S>& jk,
          const JointCoordsT<S>& coords, double t, Vec3<S>& T_P, Vec3<S>& /*F_P*/) {
  const Vector2d motor = J.motor_universal.empty() ? Vector2d::Zero() : J.motor_universal.value(t);
  const S tau1 = -J.stiffness * (coords(0) - J.neutral_angle) - m.damping * jk.rate + motor(0);
  const S tau2 = -J.stiffness2 * (coords(1) - J.neutral_angle2) - m.damping2 * jk.rate2 + motor(1);
  if (tau1 == S(0) && tau2 == S(0)) return false;
  Vec3<S> e1, e2;
  dual<S>(m.a_P, Vec3<S>(jk.R_FG * m.a2_C), e1, e2);
  T_P = tau1 * e1 + tau2 * e2;
  return true;
}

// R_J = R_PJ0^T R_FG = Rot(n1_G, a1) Rot(n2_G, a2) (n1_G = a_C), w_FG_G = R_J^T (n1_G a1' +
// Rot(n1_G, a1) n2_G a2') = Rot(n2_G, -a2) n1_G a1' + n2_G a2'.
template <class S>
void pack_t(const JointModel& m, const JointStateT<S>& js, Quat<S>& q_J, Vec3<S>& w_FG_G,
            Vec3<S>& /*r_F*/, Vec3<S>& /*v_F*/) {
  const Vec3<S> a_C = m.a_C.cast<S>(), a2_C = m.a2_C.cast<S>();
  q_J = Quat<S>(Eigen::AngleAxis<S>(js.angle, a_C)) * Quat<S>(Eigen::AngleAxis<S>(js.angle2, a2_C));
  w_FG_G = Eigen::AngleAxis<S>(-js.angle2, a2_C) * a_C * js.rate + a2_C * js.rate2;
}

void pack(const JointModel& m, const TreeState::JointState& js, Quaterniond& q_J, Vector3d& w_FG_G,
          Vector3d& r_F, Vector3d& v_F, JointCoords& coords_ref) {
  pack_t<double>(m, JointStateT<double>{js.angle, js.rate, js.angle2, js.rate2, js.q_J, js.w_PC_C},
                 q_J, w_FG_G, r_F, v_F);
  coords_ref = JointCoords(js.angle, js.angle2);
}

template <class S>
void accelerations_t(const Joint& /*J*/, const JointModel& m, const JointAccelInputsT<S>& in,
                     double /*t*/, JointAccelT<S>& a) {
  const JointKinematicsT<S>& jk = in.jk;
  const Vec3<S> u = jk.R_FG * m.a2_C;
  const Vec3<S> wdot = jk.R_FG * in.wdot_G - in.wdot_F + jk.R_FG * tcross<S>(jk.w_FG_G, jk.w_G);
  const Eigen::Matrix<S, 2, 1> dd =
      split<S>(Vec3<S>(wdot - tcross<S>(jk.w_FG_F, u) * jk.rate2), m.a_P, u);
  a.angle_ddot = dd(0);
  a.angle2_ddot = dd(1);
}

void accelerations(const Joint& J, const JointModel& m, const JointAccelInputs& in, double t,
                   TreeAccel& a, int j) {
  JointAccelT<double> aj;
  accelerations_t<double>(J, m, in, t, aj);
  a.angle_ddot[static_cast<std::size_t>(j)] = aj.angle_ddot;
  a.angle2_ddot[static_cast<std::size_t>(j)] = aj.angle2_ddot;
}

// Every universal joint is covered by the tangent.
bool covers(const Joint& /*J*/) { return true; }

template <class S>
void potential_t(const Joint& J, const JointModel& /*m*/, const JointKinematicsT<S>& /*jk*/,
                 const JointCoordsT<S>& coords, S& e) {
  const S d1 = coords(0) - J.neutral_angle, d2 = coords(1) - J.neutral_angle2;
  e += 0.5 * J.stiffness * d1 * d1 + 0.5 * J.stiffness2 * d2 * d2;
}

void potential(const Joint& J, const JointModel& m, const JointKinematics& jk, const JointCoords& coords,
               double& e) {
  potential_t<double>(J, m, jk, coords, e);
}

template <class W, class S>
void output_t(W& out, int j, const Joint& /*J*/, const JointModel& /*m*/, const JointKinematicsT<S>& jk,
              const JointCoordsT<S>& coords, S /*torque*/, double /*t*/) {
  out.universal(j, coords(0), coords(1), jk.rate, jk.rate2);
}

void output(RowWriter& out, int j, const Joint& J, const JointModel& m, const JointKinematics& jk,
            const JointCoords& coords, double torque, double t) {
  output_t<RowWriter, double>(out, j, J, m, jk, coords, torque, t);
}

// The change of the angle between the axes (row 3 over |n1 x n2|, ~ rad) and the forbidden
// relative angular velocity along n = n1 x u.
void violation(const JointModel& m, const JointKinematics& jk, const ConstraintRows& cr,
               double& /*pos_violation*/, double& /*vel_violation*/, double& ang_violation,
               double& angvel_violation) {
  const Vector3d n = m.a_P.cross(jk.R_FG * m.a2_C);
  ang_violation = std::max(ang_violation, std::abs(cr.g(3)) / m.a_P.cross(m.a2_P).norm());
  angvel_violation = std::max(angvel_violation, std::abs(n.dot(jk.w_FG_F)) / n.norm());
}

// Power of the motors and dampers (the scene's values): T . w_FG_F = tau_1 a1' + tau_2 a2' (the
// dual basis, header), of which the springs' parts are -dV/dt (in E): sum_k (motor_k - damping_k
// rate_k) rate_k.
template <class S>
S power_t(const Joint& J, const JointModel& /*m*/, const JointKinematicsT<S>& jk, S /*torque*/, double t) {
  const Vector2d motor = J.motor_universal.empty() ? Vector2d::Zero() : J.motor_universal.value(t);
  return (motor(0) - J.damping * jk.rate) * jk.rate + (motor(1) - J.damping2 * jk.rate2) * jk.rate2;
}

double power(const Joint& J, const JointModel& m, const JointKinematics& jk, double torque, double t) {
  return power_t<double>(J, m, jk, torque, t);
}

const JointVerbsCx kCx{covers,
                       relative<Cx>,
                       nullptr,
                       rotation_rows<Cx>,
                       track<Cx>,
                       load<Cx>,
                       pack_t<Cx>,
                       accelerations_t<Cx>,
                       potential_t<Cx>,
                       output_t<CxRowWriter, Cx>,
                       power_t<Cx>};

}  // namespace

const JointUnit kUniversalJoint{"universal",          model,         validate,
                                relative<double>,     nullptr,       rotation_rows<double>,
                                track<double>,        load<double>,  pack,
                                accelerations,        potential,     output,
                                violation,            power,         &kCx};

}  // namespace crossdyn::newton_euler
