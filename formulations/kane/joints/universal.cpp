// The universal joint (two-axis gimbal; core/system.hpp): R_PC = Rot(axis_P, a1) Rot(axis2_P, a2)
// R_PJ0 = R_PJ0 Rot(axis_J, a1) Rot(axis2_J, a2) (axis_J = R_PJ0^T axis_P, axis2_J = R_PJ0^T
// axis2_P), the first axis fixed in P, the second turning with a1; the joint point is common to
// P and C.  Positions a1, a2, speeds a1', a2'.
//
// Partial angular velocities (Kane and Levinson 1985 [KL85] Sec. 2.14; README.md "Joint units"):
// w_PC = W_1 a1' + W_2 a2' with W_1 = R_NJp axis_P and W_2 = R_NJp Rot(axis_P, a1) axis2_P
// (the addition theorem, [KL85] Sec. 2.4, through the intermediate frame turned by a1); both
// speeds are rotations about Ok (V_r = 0).  W_1 is fixed in Jp and W_2 in the intermediate frame,
// which turns with w_Jp + W_1 a1', so sum_r (d/dt W_r) u_r = w_Jp x w_PC + a1' a2' W_1 x W_2:
// the last term is the joint's own remainder (NodeWork::alpha_PC_t_N, Node::axis_rates).
// Hinge loads: tau_k = -k_k (a_k - neutral_k) - c_k a_k' + motor_k are the generalised active
// forces of the two speeds ([KL85] Sec. 4.x: -dV/da_k for the spring energy
// V = sum_k k_k (a_k - neutral_k)^2 / 2; for perpendicular axes, the torques tau_k about axis k).
#include "formulations/kane/kane_internal.hpp"

#include "core/errors.hpp"

#include <cmath>

namespace crossdyn::kane {
namespace {

void sizes(bool /*prescribed*/, int& nqj, int& nuj) {
  nqj = 2;
  nuj = 2;
}

void labels(const Node& n, int n_q, const std::string& /*b*/, const std::string& j,
            std::vector<std::string>& out) {
  for (int i = 0; i < 2; ++i) {
    out[static_cast<std::size_t>(n.q0 + i)] = j + ".angle" + "12"[i];
    out[static_cast<std::size_t>(n_q + n.u0 + i)] = j + ".rate" + "12"[i];
  }
}

void q_rates(const Node& n, const double* /*x*/, const double* u, double* xdot) {
  xdot[n.q0] = u[n.u0];
  xdot[n.q0 + 1] = u[n.u0 + 1];
}

void pack(const Node& n, const TreeState& /*s*/, const TreeState::JointState& js, double* x,
          double* u) {
  x[n.q0] = js.angle;
  x[n.q0 + 1] = js.angle2;
  u[n.u0] = js.rate;
  u[n.u0 + 1] = js.rate2;
}

void accel(const Node& n, const NodeWork& /*w*/, const Eigen::VectorXd& udot, TreeAccel& a) {
  a.angle_ddot[static_cast<std::size_t>(n.joint)] = udot(n.u0);
  a.angle2_ddot[static_cast<std::size_t>(n.joint)] = udot(n.u0 + 1);
}

double spring_energy(const Node& n, const Joint& J, const double* x) {
  const double d1 = x[n.q0] - J.neutral_angle, d2 = x[n.q0 + 1] - J.neutral_angle2;
  return 0.5 * J.stiffness * d1 * d1 + 0.5 * J.stiffness2 * d2 * d2;
}

void output(const Node& n, const NodeWork&, double, const double* x, const double* u,
            RowWriter& out) {
  out.universal(n.joint, x[n.q0], x[n.q0 + 1], u[n.u0], u[n.u0 + 1]);
}

void build(const Joint& J, Node& n, const std::string& jname) {
  if (n.parent < 0) throw InputError(jname + ": a universal joint cannot be the base joint");
  if (J.parent_node >= 0 || J.child_node >= 0)
    throw InputError(jname + ": a universal joint at a node of a flexible body is not supported");
  if (J.prescribed) throw InputError(jname + ": a universal joint cannot be prescribed");
  if (!(J.axis_P.norm() > 0) || !(J.axis2_P.norm() > 0))
    throw InputError(jname + ": universal axes must be non-zero");
  n.axis_P = J.axis_P.normalized();
  const Eigen::Vector3d axis2_P = J.axis2_P.normalized();
  if (!(n.axis_P.cross(axis2_P).norm() > 1e-6))
    throw InputError(jname + ": universal axes must not be parallel");
  n.axis_J = n.R_PJ0.transpose() * n.axis_P;
  n.axis2_J = n.R_PJ0.transpose() * axis2_P;
  n.axis_rates = true;
}

// R_1 = R_NJ0 Rot(axis_J, a1) (the intermediate frame), W_1 = R_NJp axis_P, W_2 = R_1 axis2_J,
// R_NJc = R_1 Rot(axis2_J, a2).
void position(const Node& n, const double* x, const Eigen::Matrix3d& R_NJp,
              const Eigen::Matrix3d& R_NJ0, Eigen::Matrix3d& R_NJc, NodeWork& w,
              Eigen::Vector3d& /*r_Pj*/) {
  const double h1 = 0.5 * x[n.q0], h2 = 0.5 * x[n.q0 + 1];
  Eigen::Matrix3d R_1;
  R_1.noalias() = R_NJ0 * axis_angle_matrix(n.axis_J, std::sin(h1), std::cos(h1));
  w.W_N.col(0).noalias() = R_NJp * n.axis_P;
  w.W_N.col(1).noalias() = R_1 * n.axis2_J;
  R_NJc.noalias() = R_1 * axis_angle_matrix(n.axis2_J, std::sin(h2), std::cos(h2));
}

void velocity(const Node& n, const double* u, NodeWork& w) {
  const double u1 = u[n.u0], u2 = u[n.u0 + 1];
  w.w_PC_N = w.W_N.col(0) * u1 + w.W_N.col(1) * u2;
  w.alpha_PC_t_N = (u1 * u2) * w.W_N.col(0).cross(w.W_N.col(1));
}

void hinge(const Node& n, const Joint& J, double t, const double* x, const double* u, double* f) {
  Eigen::Vector2d motor = Eigen::Vector2d::Zero();
  if (!J.motor_universal.empty()) motor = J.motor_universal.value(t);
  f[0] += scalar_hinge(J.stiffness, J.neutral_angle, J.damping, x[n.q0], u[n.u0], motor(0));
  f[1] += scalar_hinge(J.stiffness2, J.neutral_angle2, J.damping2, x[n.q0 + 1], u[n.u0 + 1],
                       motor(1));
}

// q_J = q(axis_J, a1) q(axis2_J, a2).
Eigen::Quaterniond joint_quat(const Node& n, const double* x) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(x[n.q0], n.axis_J)) *
         Eigen::Quaterniond(Eigen::AngleAxisd(x[n.q0 + 1], n.axis2_J));
}

}  // namespace

const JointUnit& universal_joint_unit() {
  static const JointUnit unit{sizes,  -1,    labels,   q_rates,  pack,  accel,      spring_energy,
                              output, build, position, velocity, hinge, joint_quat, JointShape::Gimbal2};
  return unit;
}

}  // namespace crossdyn::kane
