// Pass 4 of the Kane engine (README.md "Composite-body sums"): per tree node k, the sums over its
// subtree S(k) about Ok of the mass properties and of the residual loads, i.e. the inertia forces
// of Eq. (36) at u' = 0 and the external loads of Eq. (35), from which Passes 5 and 6 form the
// generalised inertia and active forces.
#include "formulations/kane/kane_internal.hpp"

namespace crossdyn::kane {

// ------------------------------------------------------------------------------------------------
// Pass 4 (backward, leaves first). => per node k the sums over its subtree S(k), about Ok:
//   m_sub, s_sub = sum m (p - p_Ok), J_sub = inertia about Ok (mass properties for M), and the
//   residual loads of Eq. (36) at u' = 0 plus the external torques of Eq. (35):
//   rigid body:  R_B = -m a_t at Bo,  T_B = T_ext - I alpha_t - w x I w;
//   flexible body, summed over its nodes with a_t,i = a_t + alpha_t x R r_i + w x (w x R r_i)
//   + 2 w x R Phi_i eta' (the remainder acceleration of node i, [KLL] Sec. 1.18) and the modal
//   integrals (c, I, L of FlexWork; identities sum m r x (a x r) = I_m a, sum m r x (w x (w x r))
//   = w x I_m w, sum m r x (w x v) = w tr(L) - L^T w):
//     R_B = -(m a_t + alpha_t x c + w x (w x c) + 2 w x cdot),
//     T_B = T_ext - c x a_t - I alpha_t - w x I w - 2 R (w_B tr L - L^T w_B)   (about Bo);
//   F_sub = sum R_B,  M_sub = sum T_B + (p_Bo - p_Ok) x R_B.
// A child's sums move to its parent's point Op with e = p_Ok - p_Op (add_moved_inertia);
// M' = M + e x F.

//   full (prescribed joints' torques): a_t, alpha_t replaced by the full a, alpha and, for a
//   flexible body, the nodes' R Phi_i eta'' added: R_B -= R S eta'', T_B -= R A eta''.
void KaneEngine::subtree_pass(double t, bool full) {
  // No zeroing: every sum starts with its first term (Node::sums_start, parent_start; x = 0 + x,
  // so the sums are those of zeroed accumulators, bit for bit).
  for (std::size_t kk = nodes_.size(); kk-- > 0;) {
    const Node& n = nodes_[kk];
    NodeWork& w = work_[kk];

    // This node's own body.
    const bool start = n.sums_start;
    const Vector3d& d = w.p_OkBo_N;
    const Vector3d& a_t = full ? w.a_N : w.a_t_N;
    const Vector3d& alpha_t = full ? w.alpha_N : w.alpha_t_N;
    put(start, w.m_sub, n.mass);
    Vector3d R_B, T_B;
    if (n.flex < 0 && n.shape == JointShape::Base6) {
      // A rigid free base: Bo = Ok (d = 0), and its remainder accelerations are zero.
      if (start) w.s_sub_N.setZero();
      put(start, w.J_sub_N, w.I_BBo_N);
      if (full) {
        R_B = -n.mass * a_t;
        T_B = rigid_residual_torque(n, w, alpha_t);
      } else {
        R_B.setZero();
        T_B = Vector3d::Zero();  // -I alpha_t - w x I w with alpha_t = 0
        if (n.inertia != Node::Inertia::Isotropic)
          T_B.noalias() -= gyro_sign_ * w.w_NB_N.cross(w.I_BBo_N * w.w_NB_N);
      }
      if (n.body_torque) add_body_torque(n, w, t, T_B);
      if (gravity_) {  // the environment's loads at Bo = Ok (gravity.cpp)
        R_B += F_grav_N_[kk];
        T_B += tau_grav_N_[kk];
      }
      put(start, w.F_sub_N, R_B);
      put(start, w.M_sub_N, T_B);
      continue;  // the root
    }
    if (n.flex < 0) {
      put(start, w.s_sub_N, n.mass * d);
      // A rigid leaf's inertia about Ok is not formed (Node::leaf_rigid): see the move below.
      if (!n.leaf_rigid) add_shifted_inertia(w.J_sub_N, w.I_BBo_N, n.mass, d, start);
      R_B = -n.mass * a_t;
      T_B = rigid_residual_torque(n, w, alpha_t);
    } else {
      const FlexWork& fw = flex_work_[static_cast<std::size_t>(n.flex)];
      const Vector3d& c = fw.c_N;
      const Vector3d& wN = w.w_NB_N;
      put(start, w.s_sub_N, n.mass * d + c);
      add_moved_inertia(w.J_sub_N, w.I_BBo_N, n.mass, c, d, start);
      R_B = -(n.mass * a_t + alpha_t.cross(c) + wN.cross(wN.cross(c)) +
              2.0 * wN.cross(fw.cdot_N));
      const Vector3d w_B = w.R_NB.transpose() * wN;
      const Vector3d cor_B = w_B * fw.L_B.trace() - fw.L_B.transpose() * w_B;
      T_B = -c.cross(a_t) - w.I_BBo_N * alpha_t - gyro_sign_ * wN.cross(w.I_BBo_N * wN) -
            2.0 * (w.R_NB * cor_B);
      if (flex_[static_cast<std::size_t>(n.flex)].stiff) {  // -sum m_i R b_i, its moment
        R_B -= fw.bsum_N;
        T_B -= fw.bmom_N;
      }
      if (full) {
        const double* eta_dd = udot_.data() + n.u0 + n.nuj;
        R_B -= combine(fw.S_N, eta_dd);
        T_B -= combine(fw.A_N, eta_dd);
      }
    }
    if (n.body_torque) add_body_torque(n, w, t, T_B);
    if (gravity_) {  // the environment's loads: resultant at Bo, moment about Bo (gravity.cpp)
      R_B += F_grav_N_[kk];
      T_B += tau_grav_N_[kk];
    }
    put(start, w.F_sub_N, R_B);
    put(start, w.M_sub_N, T_B + d.cross(R_B));

    // Move the finished subtree sums to the parent's reference point.
    if (n.parent < 0) continue;
    NodeWork& P = work_[static_cast<std::size_t>(n.parent)];
    const bool first = n.parent_start;
    const Vector3d e = w.p_B0oOk_N - P.p_B0oOk_N;
    put(first, P.m_sub, w.m_sub);
    put(first, P.s_sub_N, w.s_sub_N + w.m_sub * e);
    if (n.leaf_rigid)  // the body's central inertia shifted straight from Bo to Op (d + e)
      add_shifted_inertia(P.J_sub_N, w.I_BBo_N, n.mass, d + e, first);
    else
      add_moved_inertia(P.J_sub_N, w.J_sub_N, w.m_sub, w.s_sub_N, e, first);
    put(first, P.F_sub_N, w.F_sub_N);
    put(first, P.M_sub_N, w.M_sub_N + e.cross(w.F_sub_N));
  }
}

// A rigid body's residual torque about Bo, T_B = -I alpha - w x I w (the inertia torque of
// Eq. (36) of the paper; Pass 4 above).  Isotropic I: I w is parallel to w, so the gyroscopic
// term is zero.
Vector3d KaneEngine::rigid_residual_torque(const Node& n, const NodeWork& w,
                                           const Vector3d& alpha) const {
  if (n.inertia == Node::Inertia::Isotropic) return -(n.I_BBo_B(0, 0) * alpha);
  return -(w.I_BBo_N * alpha) - gyro_sign_ * w.w_NB_N.cross(w.I_BBo_N * w.w_NB_N);
}

// The body's external torque at t (Eq. (35): it works through W_r), added to T_B in N components.
void KaneEngine::add_body_torque(const Node& n, const NodeWork& w, double t, Vector3d& T_B) const {
  const Body& body = system_.bodies[static_cast<std::size_t>(n.body)];
  const Vector3d T = body.torque.value(t);
  if (body.torque_frame == Body::Frame::Body)
    T_B.noalias() += w.R_NB * T;
  else
    T_B += T;
}

}  // namespace crossdyn::kane
