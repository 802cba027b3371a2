// Issue 26's outputs of the Kane engine (README.md "Joint loads, power and external moment"): the
// load every joint passes from its parent to its child, the power of the non-conservative loads
// and the external moment about the system CM, for output_row (diagnostics.cpp) and the rigid
// path's row (rigid_fast_path.cpp).
//
// Joint loads. Kane's method eliminates the noncontributing forces; this engine brings them into
// evidence by the momentum balance of the child's subtree S(k) with its own accelerations (of the
// two routes the issue names, the simpler one; the other, auxiliary generalised speeds ([KL85]
// Ch. 4, "bringing noncontributing forces into evidence"; section number not checked here), gives
// the same six equations: the partial velocities of six auxiliary speeds that let S(k) move
// rigidly away from its parent at Ok are the twists of S(k) about Ok, and Kane's equation
// F_r + F_r* = 0 of each is one component of the balance below, d'Alembert's principle for S(k)):
//   every force on S(k) is either its inertia force (-m_i a_i at each mass point, -d/dt(J_i w)
//   per rigid inertia), an external torque, an internal load (cancels: action and reaction,
//   elastic forces included), or the load (F, M about Ok) from the parent through joint k, so
//     F + F_sub = 0,   M + M_sub = 0,
//   with F_sub, M_sub the resultant and the moment about Ok of the inertia forces and external
//   torques of S(k): Pass 4's subtree sums with the full accelerations (subtree_pass(t, true),
//   subtree_sums.cpp; the same sums prescribed_torque_pass takes a prescribed joint's torque
//   from). Ok is the joint point (kinematics.cpp: the node's displaced point at a node of a
//   flexible body, the point on the child for a prismatic joint), so
//     F_N = -F_sub_N,  M_J_N = -M_sub_N,  F_C = R_NC^T F_N,  M_J_C = R_NC^T M_J_N
//   (docs/conventions.md "Joint loads"). One backward pass gives every joint's load.
#include "formulations/kane/kane_internal.hpp"

namespace crossdyn::kane {

void KaneEngine::load_pass(double t) {
  prescribed_torque_pass(t);  // acceleration_pass(u'), subtree_pass(t, full = true)
  for (const Node& n : nodes_) {
    const std::size_t k = static_cast<std::size_t>(n.joint);
    if (n.shape == JointShape::Base6) continue;  // the free joint carries nothing
    const NodeWork& w = work_[k];
    F_N_[k] = -w.F_sub_N;
    M_J_N_[k] = -w.M_sub_N;
    F_C_[k].noalias() = w.R_NB.transpose() * F_N_[k];
    M_J_C_[k].noalias() = w.R_NB.transpose() * M_J_N_[k];
  }
}

// Power of the non-conservative loads (docs/conventions.md "Power and external moment"), each
// load times the velocity it works through (the power of a torque on a rigid body T . w, of a
// force on a point F . v; an action-reaction pair in a joint works on the relative motion only:
// the torque tau on C and -tau on P give tau . (w_C - w_P) = tau . w_PC; [KL85] Ch. 4, the
// generalised active forces of such pairs, whose rates are the relative speeds):
//   revolute, prismatic  (motor - c q') q'             (q' the relative rate of the joint)
//   universal            sum over both axes (motor_k - c_k q_k') q_k'
//   spherical            (motor - c w_PC_C) . w_PC_C   (w_PC in Jc components, as the torque)
//   prescribed joint     tau q'(t), tau its drive (<joint>.torque / .force, load_pass)
//   modal damping        -eta'^T D eta'  (the scene's D)
//   external torque      T . w_NB  (body frame: T_B . w_NB_B; N: T_N . w_NB_N)
// with the scene's dampers (Node::damping_P, FlexModel::D_P), never test_damper_scale's.
// Springs and elastic forces have a potential (E), so they are not in P.
// External moment about the system CM (dH_Scm/dt = M: the angular momentum principle for a
// system of particles about its mass centre, in which internal loads cancel in pairs;
// docs/conventions.md "Power and external moment"): the external torques in N, and for a prescribed base
// the load N exerts on the base through joint 0 (F_N, M_J_N at its joint point J), moved to
// the CM: M_J_N + (p_J - p_cm) x F_N.
void KaneEngine::write_issue26_columns(double t, const double* x, const Vector3d& p_NoB0o_N,
                                       const Vector3d& p_NoScm_N, RowWriter& out) const {
  const double* u = x + n_q_;
  double P = 0;
  Vector3d M_ext_N = Vector3d::Zero();
  for (const Node& n : nodes_) {
    const std::size_t k = static_cast<std::size_t>(n.joint);
    const NodeWork& w = work_[k];
    const Joint& J = system_.joints[k];
    out.body_position(n.body, p_NoB0o_N + w.p_B0oBo_N);
    if (n.shape != JointShape::Base6) out.joint_load(n.joint, F_C_[k], M_J_C_[k]);
    // The joint's motors, dampers and drive.
    if (n.prescribed) {
      P += prescribed_torque_[k] * w.pres_rate;
    } else {
      switch (n.shape) {
        case JointShape::Axis1:
        case JointShape::Slide1: {
          const double rate = u[n.u0];
          const double motor = J.motor_revolute.empty() ? 0.0 : J.motor_revolute.value(t)(0);
          P += (motor - n.damping_P * rate) * rate;
          break;
        }
        case JointShape::Gimbal2: {
          Eigen::Vector2d motor = Eigen::Vector2d::Zero();
          if (!J.motor_universal.empty()) motor = J.motor_universal.value(t);
          const double r1 = u[n.u0], r2 = u[n.u0 + 1];
          P += (motor(0) - n.damping_P * r1) * r1 + (motor(1) - n.damping2_P * r2) * r2;
          break;
        }
        case JointShape::Rotation3: {
          const Eigen::Map<const Vector3d> w_PC_C(u + n.u0);
          Vector3d motor = Vector3d::Zero();
          if (!J.motor_spherical.empty()) motor = J.motor_spherical.value(t);
          P += (motor - n.damping_P * w_PC_C).dot(w_PC_C);
          break;
        }
        default:  // free base, fixed: no joint load does work
          break;
      }
    }
    // Modal damping.
    if (n.nm > 0) {
      const double* eta_rate = u + n.u0 + n.nuj;  // summed in place: no temporary vector
      const Eigen::MatrixXd& D = flex_[static_cast<std::size_t>(n.flex)].D_P;
      for (int l = 0; l < n.nm; ++l)
        for (int m = 0; m < n.nm; ++m) P -= eta_rate[l] * D(l, m) * eta_rate[m];
    }
    // External torque.
    if (n.body_torque) {
      const Body& body = system_.bodies[static_cast<std::size_t>(n.body)];
      const Vector3d T = body.torque.value(t);
      if (body.torque_frame == Body::Frame::Body) {
        P += T.dot(w.w_NB_B);
        M_ext_N.noalias() += w.R_NB * T;
      } else {
        P += T.dot(w.w_NB_N);
        M_ext_N += T;
      }
    }
  }
  const Node& base = nodes_[0];
  if (base.shape != JointShape::Base6) {  // a prescribed base: N's load on it, moved to the CM
    const NodeWork& w = work_[0];
    M_ext_N += M_J_N_[0] + (p_NoB0o_N + w.p_B0oOk_N - p_NoScm_N).cross(F_N_[0]);
  }
  // The environment's loads (issue 28; gravity.cpp): sum over bodies (p_Bo - p_cm) x F + tau.
  if (gravity_) M_ext_N += gravity_moment(p_NoB0o_N, p_NoScm_N);
  out.system_cm(p_NoScm_N);
  out.power(P);
  out.external_moment(M_ext_N);
}

}  // namespace crossdyn::kane
