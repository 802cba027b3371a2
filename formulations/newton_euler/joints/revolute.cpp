// The revolute joint (and the prescribed revolute joint): one rotation about the axis a_P (in F) =
// a_C (in G). Its unit (joint_unit.hpp) implements, from joint_constraints.hpp, the "revolute"
// rows 3-4 and the "prescribed revolute" row 5 (Haug 1989, "Computer Aided Kinematics and Dynamics
// of Mechanical Systems", Sec. 6.3: a rheonomic driving constraint), and from newton_euler.hpp the
// joint's angle (continuous, unwrapped against the last step's), its spring, damper and motor
// torque (core/system.hpp), its angle'' and its output columns (docs/prescribed-motion.md).
#include "formulations/newton_euler/joints/joint_unit.hpp"
#include "formulations/newton_euler/joints/axis_row.hpp"

#include "core/errors.hpp"

#include <algorithm>
#include <cmath>

namespace crossdyn::newton_euler {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

template <class S>
S revolute_angle_wrapped(const JointModel& m, const Mat3<S>& R_FG) {
  // R_J = R_PJ0^T R_FG = Rot(a_C, angle), so R_J e1 = cos(angle) e1 + sin(angle) (a_C x e1).
  const Vec3<S> Re1 = m.R_PJ0.transpose() * (R_FG * m.e1_C);
  return tatan2(tdot<S>(m.e2_C, Re1), tdot<S>(m.e1_C, Re1));
}
template double revolute_angle_wrapped(const JointModel&, const Mat3<double>&);
template Cx revolute_angle_wrapped(const JointModel&, const Mat3<Cx>&);

namespace {

void model(const Joint& joint, JointModel& m) {
  m.prescribed = joint.prescribed.has_value();
  m.rows = joint.prescribed ? 6 : 5;
  m.has_angle = true;
  m.unwraps = !m.prescribed;
}

void validate(const Joint& joint, const std::string& key) {
  if (joint.axis_P.norm() < 1e-12) throw InputError(key + ": axis must be a non-zero vector");
}

template <class S>
void relative(const JointModel& m, const BodyKinematicsT<S>& /*P*/, const BodyKinematicsT<S>& /*C*/,
              JointKinematicsT<S>& jk) {
  jk.angle_wrapped = revolute_angle_wrapped<S>(m, jk.R_FG);
  jk.rate = tdot<S>(m.a_P, jk.w_FG_F);
}

// joint_constraints.hpp, "revolute" and "prescribed revolute".
template <class S>
void rotation_rows(const JointModel& m, const JointKinematicsT<S>& jk, ConstraintRowsT<S>& out) {
  const Vec3<S>& w_G = jk.w_G;
  const Vec3<S> u = jk.R_FG * m.a_C;                 // the child's axis, in F
  const Vec3<S> u_dot = tcross<S>(jk.w_FG_F, u);     // F-frame derivative of u
  const Vec3<S> transport_F = jk.R_FG * tcross<S>(jk.w_FG_G, w_G);
  axis_row<S>(jk, u, u_dot, transport_F, m.b1_P, 3, out);  // joints/axis_row.hpp
  axis_row<S>(jk, u, u_dot, transport_F, m.b2_P, 4, out);
  if (m.prescribed) {  // row 5: the angle (header; the time terms are track()'s)
    out.g(5) = jk.angle_wrapped;
    out.J_C.template block<1, 3>(5, 3).noalias() = m.a_P.transpose() * jk.R_FG;
    out.J_P.template block<1, 3>(5, 3) = -m.a_P.transpose();
    out.gdot(5) = jk.rate;
    out.gamma(5) = -tdot<S>(m.a_P, transport_F);
  }
}

// A prescribed joint's row 5 gets its time terms here (rheonomic constraint, Haug 1989, Sec. 6.3;
// docs/prescribed-motion.md "The motion"): g_5 = angle - (angle0 + theta(t)) (wrapped to
// (-pi, pi]), g_5' = rate - theta'(t), gamma_5 += theta''(t), so that projection and Baumgarte
// drive the joint to the prescribed angle and rate at t. Otherwise the continuous angle.
template <class S>
void track(const Joint& J, const JointModel& m, double t, const JointKinematicsT<S>& jk,
           ConstraintRowsT<S>& cr, JointCoordsT<S>& coords, const JointCoords& coords_ref) {
  if (m.prescribed) {
    const double angle = J.angle0 + J.prescribed->angle(t);
    coords(0) = angle;
    cr.g(5) = unwrap_angle(jk.angle_wrapped - angle, 0.0);
    cr.gdot(5) -= J.prescribed->velocity(t);
    cr.gamma(5) += J.prescribed->accel(t);
  } else {
    coords(0) = unwrap_angle(jk.angle_wrapped, coords_ref(0));
  }
}

// Spring, damper and motor about the axis (core/system.hpp), on the child-side frame, in P.
template <class S>
bool load(const Joint& J, const JointModel& m, const JointKinematicsT<S>& jk,
          const JointCoordsT<S>& coords, double t, Vec3<S>& T_P, Vec3<S>& /*F_P*/) {
  const S tau = -J.stiffness * (coords(0) - J.neutral_angle) - m.damping * jk.rate +
                (J.motor_revolute.empty() ? 0.0 : J.motor_revolute.value(t)(0));
  if (tau == S(0)) return false;
  T_P = tau * m.a_P;  // in F
  if (m.P.modes > 0) T_P = jk.F.E * T_P;
  return true;
}

template <class S>
void pack_t(const JointModel& m, const JointStateT<S>& js, Quat<S>& q_J, Vec3<S>& w_FG_G,
            Vec3<S>& /*r_F*/, Vec3<S>& /*v_F*/) {
  q_J = Quat<S>(Eigen::AngleAxis<S>(js.angle, m.a_C.cast<S>()));
  w_FG_G = js.rate * m.a_C;
}

void pack(const JointModel& m, const TreeState::JointState& js, Quaterniond& q_J, Vector3d& w_FG_G,
          Vector3d& r_F, Vector3d& v_F, JointCoords& coords_ref) {
  pack_t<double>(m, JointStateT<double>{js.angle, js.rate, js.angle2, js.rate2, js.q_J, js.w_PC_C},
                 q_J, w_FG_G, r_F, v_F);
  coords_ref(0) = js.angle;
}

template <class S>
void accelerations_t(const Joint& J, const JointModel& m, const JointAccelInputsT<S>& in, double t,
                     JointAccelT<S>& a) {
  if (m.prescribed) {
    a.angle_ddot = J.prescribed->accel(t);
  } else {
    // angle'' = a_P . d/dt(w_FG_F) (F-frame derivative; d/dt R_FG = R_FG [w_FG_G x]).
    const JointKinematicsT<S>& jk = in.jk;
    a.angle_ddot = tdot<S>(m.a_P, Vec3<S>(jk.R_FG * in.wdot_G - in.wdot_F +
                                          jk.R_FG * tcross<S>(jk.w_FG_G, jk.w_G)));
  }
}

void accelerations(const Joint& J, const JointModel& m, const JointAccelInputs& in, double t,
                   TreeAccel& a, int j) {
  JointAccelT<double> aj;
  accelerations_t<double>(J, m, in, t, aj);
  a.angle_ddot[static_cast<std::size_t>(j)] = aj.angle_ddot;
}

// Every revolute joint (spring, damper, motor, prescribed) is covered by the tangent.
bool covers(const Joint& /*J*/) { return true; }

void output_cx(CxRowWriter& out, int j, const Joint& J, const JointModel& m,
               const JointKinematicsT<Cx>& jk, const JointCoordsT<Cx>& coords, Cx torque, double t) {
  one_coordinate_output_t(&CxRowWriter::revolute, out, j, J, m, jk, coords, torque, t);
}

const JointVerbsCx kCx{covers,
                       relative<Cx>,
                       nullptr,
                       rotation_rows<Cx>,
                       track<Cx>,
                       load<Cx>,
                       pack_t<Cx>,
                       accelerations_t<Cx>,
                       one_coordinate_potential_t<Cx>,
                       output_cx,
                       one_coordinate_power_t<Cx>};

void output(RowWriter& out, int j, const Joint& J, const JointModel& m, const JointKinematics& jk,
            const JointCoords& coords, double torque, double t) {
  one_coordinate_output(&RowWriter::revolute, out, j, J, m, jk, coords, torque, t);
}

// The angle between the two copies of the axis, the forbidden relative angular velocity; a
// prescribed joint adds its angle and rate away from the profile.
void violation(const JointModel& m, const JointKinematics& jk, const ConstraintRows& cr,
               double& /*pos_violation*/, double& /*vel_violation*/, double& ang_violation,
               double& angvel_violation) {
  const Vector3d u = jk.R_FG * m.a_C;
  ang_violation = std::max(ang_violation, std::atan2(m.a_P.cross(u).norm(), m.a_P.dot(u)));
  angvel_violation = std::max(angvel_violation, (jk.w_FG_F - m.a_P.dot(jk.w_FG_F) * m.a_P).norm());
  if (m.prescribed) {  // and the angle and rate away from the profile
    ang_violation = std::max(ang_violation, std::abs(cr.g(5)));
    angvel_violation = std::max(angvel_violation, std::abs(cr.gdot(5)));
  }
}

}  // namespace

template <class S>
void one_coordinate_potential_t(const Joint& J, const JointModel& /*m*/, const JointKinematicsT<S>& /*jk*/,
                                const JointCoordsT<S>& coords, S& e) {
  const S d = coords(0) - J.neutral_angle;
  e += 0.5 * J.stiffness * d * d;
}
template void one_coordinate_potential_t(const Joint&, const JointModel&, const JointKinematicsT<double>&,
                                         const JointCoordsT<double>&, double&);
template void one_coordinate_potential_t(const Joint&, const JointModel&, const JointKinematicsT<Cx>&,
                                         const JointCoordsT<Cx>&, Cx&);

void one_coordinate_potential(const Joint& J, const JointModel& m, const JointKinematics& jk,
                              const JointCoords& coords, double& e) {
  one_coordinate_potential_t<double>(J, m, jk, coords, e);
}

template <class W, class S>
void one_coordinate_output_t(void (W::*write)(int, S, S), W& out, int j, const Joint& J,
                             const JointModel& m, const JointKinematicsT<S>& jk,
                             const JointCoordsT<S>& coords, S torque, double t) {
  if (m.prescribed) {  // docs/prescribed-motion.md: angle and rate from the profile
    const PrescribedMotion& pm = *J.prescribed;
    (out.*write)(j, S(J.angle0 + pm.angle(t)), S(pm.velocity(t)));
    out.joint_torque(j, torque);
  } else {
    (out.*write)(j, coords(0), jk.rate);
  }
}
template void one_coordinate_output_t(void (RowWriter::*)(int, double, double), RowWriter&, int,
                                      const Joint&, const JointModel&, const JointKinematicsT<double>&,
                                      const JointCoordsT<double>&, double, double);
template void one_coordinate_output_t(void (CxRowWriter::*)(int, Cx, Cx), CxRowWriter&, int,
                                      const Joint&, const JointModel&, const JointKinematicsT<Cx>&,
                                      const JointCoordsT<Cx>&, Cx, double);

void one_coordinate_output(void (RowWriter::*write)(int, double, double), RowWriter& out, int j,
                           const Joint& J, const JointModel& m, const JointKinematics& jk,
                           const JointCoords& coords, double torque, double t) {
  one_coordinate_output_t<RowWriter, double>(write, out, j, J, m, jk, coords, torque, t);
}

// Power (docs/conventions.md "Power and external moment"): the load tau = -k (angle - neutral) -
// c rate + motor about the axis does the work tau rate (its torque T on the child-side frame and
// -T on the parent-side one: T . (w_G - w_F) = tau a . w_FG_F = tau rate); the spring's part is
// -dV/dt, in E, so P keeps (motor - c rate) rate with the scene's c. A prescribed joint's drive
// (row 5's multiplier, the torque about the axis) works at the prescribed rate theta'(t): the
// other rows' multipliers do no work on a state that satisfies the velocity constraints
// (lambda^T J nu = lambda_5 rate; Haug 1989, Sec. 6.3). Prismatic likewise, with a force along the
// axis at the child's joint point and the reaction at the same point: F . (relative velocity of
// the point) = F s'.
template <class S>
S one_coordinate_power_t(const Joint& J, const JointModel& m, const JointKinematicsT<S>& jk, S torque,
                         double t) {
  if (m.prescribed) return torque * J.prescribed->velocity(t);
  const double motor = J.motor_revolute.empty() ? 0.0 : J.motor_revolute.value(t)(0);
  return (motor - J.damping * jk.rate) * jk.rate;
}
template double one_coordinate_power_t(const Joint&, const JointModel&, const JointKinematicsT<double>&,
                                       double, double);
template Cx one_coordinate_power_t(const Joint&, const JointModel&, const JointKinematicsT<Cx>&, Cx,
                                   double);

double one_coordinate_power(const Joint& J, const JointModel& m, const JointKinematics& jk,
                            double torque, double t) {
  return one_coordinate_power_t<double>(J, m, jk, torque, t);
}

const JointUnit kRevoluteJoint{"revolute",
                               model,
                               validate,
                               relative<double>,
                               nullptr,
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
