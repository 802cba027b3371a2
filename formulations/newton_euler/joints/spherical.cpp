// The spherical joint: the joint point only (joint_constraints.hpp, "spherical: rows 0-2 only", no
// rotation rows). Its unit (joint_unit.hpp) implements, from newton_euler.hpp and core/system.hpp,
// the relative attitude q_J and angular velocity w_PC_C (= w_FG_G) of the state and outputs, the
// spring (about the rotation vector of q_PJ0^* q_FG), damper and motor torque, and wdot_PC_C.
#include "formulations/newton_euler/joints/joint_unit.hpp"

#include "core/rotation.hpp"

namespace crossdyn::newton_euler {

using Eigen::Quaterniond;
using Eigen::Vector3d;

namespace {

void model(const Joint& /*joint*/, JointModel& m) { m.rows = 3; }

// Spring, damper and motor in G (core/system.hpp), on the child-side frame, in P.
bool load(const Joint& J, const JointModel& m, const JointKinematics& jk,
          const JointCoords& /*coords*/, double t, Vector3d& T_P, Vector3d& /*F_P*/) {
  Vector3d tau_G = -m.damping * jk.w_FG_G;
  if (J.stiffness != 0) tau_G -= J.stiffness * rot::rotation_vector(m.q_PJ0.conjugate() * jk.q_FG);
  if (!J.motor_spherical.empty()) tau_G += J.motor_spherical.value(t);
  const Vector3d T_C = m.C.modes > 0 ? Vector3d(jk.G.E * tau_G) : tau_G;
  T_P = jk.R_PC * T_C;
  return true;
}

void pack(const JointModel& /*m*/, const TreeState::JointState& js, Quaterniond& q_J,
          Vector3d& w_FG_G, Vector3d& /*r_F*/, Vector3d& /*v_F*/, JointCoords& /*coords_ref*/) {
  q_J = js.q_J.normalized();
  w_FG_G = js.w_PC_C;
}

void accelerations(const Joint& /*J*/, const JointModel& /*m*/, const JointAccelInputs& in,
                   double /*t*/, TreeAccel& a, int j) {
  // G-frame derivative of w_FG_G = w_G - R_GF w_F, with d/dt R_GF = -[w_FG_G x] R_GF.
  const JointKinematics& jk = in.jk;
  const Vector3d w_F_G = jk.R_FG.transpose() * jk.w_F;
  a.wdot_PC_C[static_cast<std::size_t>(j)] =
      in.wdot_G - jk.R_FG.transpose() * in.wdot_F + jk.w_FG_G.cross(w_F_G);
}

void potential(const Joint& J, const JointModel& m, const JointKinematics& jk,
               const JointCoords& /*coords*/, double& e) {
  const Vector3d phi = rot::rotation_vector(m.q_PJ0.conjugate() * jk.q_FG);
  e += 0.5 * J.stiffness * phi.squaredNorm();
}

void output(RowWriter& out, int j, const Joint& /*J*/, const JointModel& /*m*/,
            const JointKinematics& jk, const JointCoords& /*coords*/, double /*torque*/,
            double /*t*/) {
  out.spherical(j, jk.w_FG_G);
}

// Power of the motor and damper (the scene's values): the torque tau_G on the child-side frame G
// and its reaction on F work at w_FG_G (= the output w_PC_C): (motor - damping w_PC_C) . w_PC_C;
// the spring's part is -dV/dt (in E).
double power(const Joint& J, const JointModel& /*m*/, const JointKinematics& jk, double /*torque*/,
             double t) {
  Vector3d tau_G = -J.damping * jk.w_FG_G;
  if (!J.motor_spherical.empty()) tau_G += J.motor_spherical.value(t);
  return tau_G.dot(jk.w_FG_G);
}

}  // namespace

const JointUnit kSphericalJoint{"spherical", model,   nullptr,       nullptr,   nullptr,
                                nullptr,     nullptr, load,          pack,      accelerations,
                                potential,   output,  nullptr,       power};

}  // namespace crossdyn::newton_euler
