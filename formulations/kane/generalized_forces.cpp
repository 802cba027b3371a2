// Pass 6 of the Kane engine (README.md "Generalised forces"): f = F_r + F_r*|_{u'=0}, the
// generalised active forces (hinge springs, dampers and motors, body loads through the subtree
// sums, modal stiffness and damping) plus the remainder part of the generalised inertia forces;
// and the torque of each prescribed joint from Kane's equation of its speed.
#include "formulations/kane/kane_internal.hpp"

#include "core/rotation.hpp"

namespace crossdyn::kane {

// ------------------------------------------------------------------------------------------------
// Pass 6. subtree sums, hinge loads, modal stiffness and damping => f = F_r + F_r*|_{u'=0}.
//   Twist part of speed r: W_r . M_k + V_r . F_k (joint speeds: V_r = 0 but for a sliding joint,
//   prismatic, where W_r = 0 and V_r = axis_N, so f_r = axis_N . F_k + F).  Base: f(w) = R_NB^T M_0 (W_r = b_r),
//   f(v) = F_0 (V_r = n_r).  Joint speeds: f_r = W_r . M_k plus the hinge's own spring, damper
//   and motor (the only speeds its action-reaction pair works on, README.md).
//   Modal speed l of C, elastic part (paper Eq. (40), [KRB]):
//     g_l = sum_i R Phi_il . (-m_i a_t,i) = -(S_l . a_B + alpha_B . A_l + w_B^T N_l w_B
//           - |w_B|^2 tr N_l + 2 w_B . Ce_l)   (body components of a_t, alpha_t, w)
//     plus Wp_c,l . M_c + Vp_c,l . F_c for every attached child c, and -(K eta + D eta')_l
//     (the generalised active forces of the strain energy and the modal damping, [KLL] Ch. 4).

double KaneEngine::hinge_torque_revolute(const Node& n, double t, const double* x) const {
  if (!n.hinge_load) return 0;
  const Joint& J = system_.joints[static_cast<std::size_t>(n.joint)];
  double tau = 0;
  if (J.stiffness != 0) tau -= J.stiffness * (x[n.q0] - J.neutral_angle);
  if (J.damping != 0) tau -= J.damping * x[n_q_ + n.u0];
  if (!J.motor_revolute.empty()) tau += J.motor_revolute.value(t)(0);
  return tau;
}

Vector3d KaneEngine::hinge_torque_spherical(const Node& n, double t, const double* x) const {
  if (!n.hinge_load) return Vector3d::Zero();
  const Joint& J = system_.joints[static_cast<std::size_t>(n.joint)];
  Vector3d tau = Vector3d::Zero();
  if (J.stiffness != 0) tau -= J.stiffness * rot::rotation_vector(read_quat(x, n.q0));
  if (J.damping != 0) tau -= J.damping * Eigen::Map<const Vector3d>(x + n_q_ + n.u0);
  if (!J.motor_spherical.empty()) tau += J.motor_spherical.value(t);
  return tau;
}

void KaneEngine::generalized_force_pass(double t, const double* x) {
  const NodeWork& base = work_[0];
  if (nodes_[0].shape == JointShape::Base6) {
    f_.segment<3>(nodes_[0].u0).noalias() = base.R_NB.transpose() * base.M_sub_N;
    f_.segment<3>(nodes_[0].u0 + 3) = base.F_sub_N;
  }
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    const NodeWork& w = work_[k];
    switch (n.shape) {
      case JointShape::Axis1:
        if (!n.prescribed) f_(n.u0) = w.W_N.col(0).dot(w.M_sub_N) + hinge_torque_revolute(n, t, x);
        break;
      case JointShape::Rotation3:
        f_.segment<3>(n.u0).noalias() =
            w.W_N.transpose() * w.M_sub_N + hinge_torque_spherical(n, t, x);
        break;
      case JointShape::Base6:  // above
        break;
      default:  // every other joint: f_r = W_r . M_k + V_r . F_k + its unit's hinge forces
        for (int i = 0; i < n.nuj; ++i) {
          f_(n.u0 + i) = w.W_N.col(i).dot(w.M_sub_N);
          if (n.slides) f_(n.u0 + i) += w.V_N.col(i).dot(w.F_sub_N);
        }
        if (n.nuj > 0 && n.hinge_load)
          n.unit->hinge(n, system_.joints[k], t, x, x + n_q_, f_.data() + n.u0);
        break;
    }
    if (n.nm == 0) continue;
    const FlexModel& F = flex_[static_cast<std::size_t>(n.flex)];
    const FlexWork& fw = flex_work_[static_cast<std::size_t>(n.flex)];
    const double* eta = x + n.q0 + n.nqj;
    const double* eta_rate = x + n_q_ + n.u0 + n.nuj;
    const Vector3d a_B = w.R_NB.transpose() * w.a_t_N;
    const Vector3d alpha_B = w.R_NB.transpose() * w.alpha_t_N;
    const Vector3d w_B = w.R_NB.transpose() * w.w_NB_N;
    const double w2 = w_B.squaredNorm();
    for (int l = 0; l < n.nm; ++l) {
      const Matrix3d& N = fw.N_B[static_cast<std::size_t>(l)];
      const Eigen::Matrix3Xd& S = F.stiff ? fw.S_B : F.S;  // S~ with stiffening
      double g = -(S.col(l).dot(a_B) + alpha_B.dot(fw.A_B.col(l)) + w_B.dot(N * w_B) -
                   w2 * N.trace() + 2.0 * w_B.dot(fw.Ce_B.col(l)));
      if (F.stiff) g -= fw.bgen(l);  // -sum m_i Phi~_il . b_i
      if (gravity_) g += fw.Q_grav(l);  // sum_i R Phi~_il . F_i of gravity (gravity.cpp)
      if (n.child_attach) g += w.Wm_N.col(l).dot(w.M_sub_N) + w.Vm_N.col(l).dot(w.F_sub_N);
      for (int c : n.attached_children) {
        const NodeWork& cw = work_[static_cast<std::size_t>(c)];
        g += cw.Wp_N.col(l).dot(cw.M_sub_N) + cw.Vp_N.col(l).dot(cw.F_sub_N);
      }
      for (int m = 0; m < n.nm; ++m) g -= F.K(l, m) * eta[m] + F.D(l, m) * eta_rate[m];
      f_(n.u0 + n.nuj + l) = g;
    }
  }
}

// The torque a prescribed joint applies to its child about its axis (docs/prescribed-motion.md):
// Kane's equation of its speed, kept as a known function of time (Kane and Levinson 1985,
// Sec. 6.1), F_r + F_r* + tau = 0, where the speed's partial velocities move the subtree S(k)
// rigidly about Ok with W_r = the axis, so F_r + F_r* = W_r . M_k, the moment about Ok of every
// external and inertia force on S(k) with the full accelerations (hinge torques below k and the
// elastic forces are internal to S(k) and cancel):  tau = -W_r . M_k.  A prescribed prismatic
// joint likewise: V_r = axis_N, W_r = 0, so its force along the axis is -V_r . F_k.
void KaneEngine::prescribed_torque_pass(double t) {
  acceleration_pass(udot_.data());
  subtree_pass(t, /*full=*/true);
  for (const Node& n : nodes_)
    if (n.prescribed) {
      const NodeWork& w = work_[static_cast<std::size_t>(n.joint)];
      double& tau = prescribed_torque_[static_cast<std::size_t>(n.joint)];
      tau = -w.W_N.col(0).dot(w.M_sub_N);
      if (n.slides) tau -= w.V_N.col(0).dot(w.F_sub_N);  // prismatic: the force along the axis
    }
}

}  // namespace crossdyn::kane
