// Pass 3 of the Kane engine (README.md "Kinematics"): the remainder accelerations alpha_t, a_t
// (every u' = 0) and, given u', the full accelerations (propagate_accelerations).
#include "formulations/kane/kane_internal.hpp"

namespace crossdyn::kane {

// ------------------------------------------------------------------------------------------------
// Pass 3. (q, u) => alpha_t_N, a_t_N: the accelerations with every u' = 0 (the remainder terms of
// alpha_B = sum W_r u_r' + alpha_t, a_Bo = sum V_r u_r' + a_t); with u' given (accelerations()),
// the full alpha_N, a_N.  Time derivatives of the velocity-pass sums ([KLL] Secs. 1.17-1.18,
// Eqs. (37)-(38) of the paper):
//   a_Ok = a_Po + alpha_P x p_PoOk + w_P x (w_P x p_PoOk) + 2 w_P x v_att + Vp eta_P''
//   alpha_Jp = alpha_P + w_P x w_att + R_NP (d/dt Jl) psi_Pj' + Wp eta_P''
//     (d/dt (R_NP Jl Psi eta') with R_NP' = [w_P x] R_NP);
//   alpha_Jc = alpha_Jp + w_Jp x w_PC + sum W_r u_r'  (W_r fixed in Jp (revolute axis) or in Jc
//     (spherical); either way d/dt(W_r) u_r sums to w_Jp x w_PC);
//     A universal joint's second axis turns with the first angle: + a1' a2' W_1 x W_2
//     (alpha_PC_t_N, joints/universal.cpp).  A sliding joint (prismatic) moves Ok in Jp:
//     a_Ok += 2 w_Jp x v_PC + sum V_r u_r' (V_r fixed in Jp; [KL85] Sec. 2.8);
//   alpha_C = alpha_Jc + w_C x w_m - R_NC (d/dt Jl) psi_Cj' + Wm eta_C''
//     (w_m = -R_NC Jl Psi eta' with R_NC' = [w_C x] R_NC);
//   a_Co = a_Ok + alpha_C x p_OkCo + w_C x (w_C x p_OkCo) + 2 w_C x v_m + Vm eta_C''.
//   Base: alpha = R_NB w_NB_B' (w x w = 0), a = v_NBo_N'; the remainder values are zero.

void KaneEngine::propagate_accelerations(const double* udot, bool full) {
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    Vector3d& alpha = full ? w.alpha_N : w.alpha_t_N;
    Vector3d& acc = full ? w.a_N : w.a_t_N;
    if (n.shape == JointShape::Base6) {
      if (full) {
        alpha.noalias() = w.R_NB * Eigen::Map<const Vector3d>(udot + n.u0);
        acc = Eigen::Map<const Vector3d>(udot + n.u0 + 3);
      } else {
        alpha.setZero();
        acc.setZero();
      }
      continue;
    }
    const NodeWork& P = n.parent >= 0 ? work_[static_cast<std::size_t>(n.parent)] : ground_;
    const Vector3d& alpha_P = full ? P.alpha_N : P.alpha_t_N;
    const Vector3d& a_P = full ? P.a_N : P.a_t_N;
    const Vector3d& p_PoOk_N = w.p_PoOk_N;
    const Vector3d& p_OkCo_N = w.p_OkBo_N;
    Vector3d a_Ok, alpha_C;
    if (n.parent_free_base && !full) {  // a free base's remainder accelerations are zero
      a_Ok.noalias() = P.w_NB_N.cross(P.w_NB_N.cross(p_PoOk_N));
      alpha_C.setZero();
    } else {
      a_Ok = a_P + alpha_P.cross(p_PoOk_N) + P.w_NB_N.cross(P.w_NB_N.cross(p_PoOk_N));
      alpha_C = alpha_P;
    }
    if (n.parent_attach) {
      a_Ok += 2.0 * P.w_NB_N.cross(w.v_att_N) + w.b_att_N;  // b: stiffening's R e eta'^T G eta'
      alpha_C += P.w_NB_N.cross(w.w_att_N) + w.jdot_att_N;
      if (full) {
        const Node& pn = nodes_[static_cast<std::size_t>(n.parent)];
        const double* eta_dd = udot + pn.u0 + pn.nuj;
        a_Ok += combine(w.Vp_N, eta_dd);
        alpha_C += combine(w.Wp_N, eta_dd);
      }
    }
    alpha_C += w.w_NJp_N.cross(w.w_PC_N);
    if (n.axis_rates) alpha_C += w.alpha_PC_t_N;  // the universal joint's a1' a2' W_1 x W_2
    if (n.slides) {
      // Ok moves in Jp with v_PC = sum V_r u_r, V_r fixed in Jp: 2 w_Jp x v_PC + sum V_r u_r'.
      a_Ok += 2.0 * w.w_NJp_N.cross(w.v_PC_N);
      if (n.prescribed) a_Ok += w.V_N.col(0) * w.pres_accel;
      if (full)
        for (int i = 0; i < n.nuj; ++i) a_Ok += w.V_N.col(i) * udot[n.u0 + i];
    }
    // A prescribed joint's W_r theta''(t) is known: part of the remainder (and of the full)
    // acceleration, the "u_r' known function of time" of Kane and Levinson 1985, Sec. 6.1.
    if (n.prescribed) alpha_C += w.W_N.col(0) * w.pres_accel;
    if (full)
      for (int i = 0; i < n.nuj; ++i) alpha_C += w.W_N.col(i) * udot[n.u0 + i];
    if (n.child_attach) {
      alpha_C += w.w_NB_N.cross(w.w_m_N) - w.jdot_m_N;
      if (full) alpha_C += combine(w.Wm_N, udot + n.u0 + n.nuj);
    }
    acc = a_Ok + alpha_C.cross(p_OkCo_N) + w.w_NB_N.cross(w.w_NB_N.cross(p_OkCo_N));
    if (n.child_attach) {
      acc += 2.0 * w.w_NB_N.cross(w.v_m_N) + w.b_m_N;
      if (full) acc += combine(w.Vm_N, udot + n.u0 + n.nuj);
    }
    alpha = alpha_C;
  }
}

void KaneEngine::remainder_pass() { propagate_accelerations(nullptr, false); }

// ------------------------------------------------------------------------------------------------
// u' => alpha_N, a_N (full accelerations, for accelerations()): the remainder-pass recursion
// with the sums W_r u_r' and V_r u_r' added (propagate_accelerations).

// (full is explicit: with no speed at all, a prescribed base's rigid tree, udot is null.)
void KaneEngine::acceleration_pass(const double* udot) { propagate_accelerations(udot, true); }

}  // namespace crossdyn::kane
