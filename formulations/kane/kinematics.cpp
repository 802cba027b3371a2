// Passes 1 and 2 of the Kane engine (README.md "Kinematics"): positions, attitudes and partial
// angular velocities from q (position_pass, with flexible bodies' modal integrals at eta,
// flex_position), then velocities as sums of partial velocities times u (velocity_pass,
// flex_velocity).
#include "formulations/kane/kane_internal.hpp"

#include <cmath>

namespace crossdyn::kane {

// ------------------------------------------------------------------------------------------------
// Pass 1. q => R_NB, I_BBo_N, W_N (partial angular velocities), p_B0oBo_N, p_B0oOk_N, and
// at nodes of flexible bodies the twists of the modal speeds.
// Joint kinematics of core/system.hpp and docs/flexible-bodies.md "Joints at nodes":
//   R_NJp = R_NP E_Pj,  R_NJc = R_NJp R_PJ0 R_J,  R_NC = R_NJc E_Cj^T  (E = exp([psi x]));
//   the joint point is common to P and C: p_Ok = p_Po + R_NP r_Pj = p_Co + R_NC r_Cj, r = p + u.
//   Parent side (w_Jp = w_P + Wp eta_P', v_Ok = v_Po + w_P x (p_Ok - p_Po) + Vp eta_P'):
//     Wp = R_NP Jl(psi_Pj) Psi_Pj,  Vp = R_NP Phi_Pj.
//   A prismatic joint moves the child-side point: r_Pj += s axis_P (joints/prismatic.cpp), and
//   its speed's partial velocity V_r = R_NJp axis_P (V_N); every joint whose speeds' shape the
//   switch below does not inline (Node::shape, declared by its unit; kane_engine.hpp) sets R_NJc,
//   W_N and V_N by its unit (JointUnit::position).
//   Child side (w_C = w_Jc + Wm eta_C', v_Co = v_Ok + w_C x (p_Co - p_Ok) + Vm eta_C'):
//     Wm = -R_NC Jl(psi_Cj) Psi_Cj,  Vm = -R_NC Phi_Cj   (README.md, partial velocities).

void KaneEngine::position_pass(const double* x, bool rigid_inertia) {
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    if (n.shape == JointShape::Base6) {
      // W_r = b_r for u_r = w_NB_B,r (r = 1..3): the passes read R_NB itself (W_N is not formed);
      // Bo = Ok = B0o, so p_B0oBo_N, p_B0oOk_N, p_PoOk_N and p_OkBo_N stay zero (constructor).
      w.R_NB = read_quat(x, n.q0 + 3).toRotationMatrix();
    } else {
      // A prescribed base's parent is N (ground_: at rest, origin No, so that the positions of
      // such a tree are measured from No; docs/prescribed-motion.md "A prescribed base").
      const NodeWork& P = n.parent >= 0 ? work_[static_cast<std::size_t>(n.parent)] : ground_;
      Vector3d r_Pj = n.p_PoJ_P;
      // Frames by pointer so that a rigid attachment copies no matrix: R_NJp is R_NP, and R_NJc
      // is written straight into R_NB.
      const Matrix3d* R_NJp = &P.R_NB;
      Matrix3d R_NJp_node;
      if (n.parent_attach) {
        const Node& pn = nodes_[static_cast<std::size_t>(n.parent)];
        const double* eta_P = x + pn.q0 + pn.nqj;
        w.rot_P.set(combine(n.Psi_Pj, eta_P));
        r_Pj += combine(n.Phi_Pj, eta_P);
        // Geometric stiffening: u = Phi eta + e (1/2 eta^T G eta), partial velocities
        // Phi_l + e (G eta)_l (docs/flexible-bodies.md "Geometric stiffening").
        if (n.stiff_P) r_Pj += n.e_Pj * stiff_g(n.G_Pj, eta_P, w.gP);
        R_NJp_node.noalias() = P.R_NB * w.rot_P.R();
        R_NJp = &R_NJp_node;
        const Matrix3d RJl = P.R_NB * w.rot_P.Jl();
        for (int l = 0; l < n.pm; ++l) {
          w.Wp_N.col(l).noalias() = RJl * n.Psi_Pj.col(l);
          if (n.stiff_P)
            w.Vp_N.col(l).noalias() = P.R_NB * (n.Phi_Pj.col(l) + n.e_Pj * w.gP(l));
          else
            w.Vp_N.col(l).noalias() = P.R_NB * n.Phi_Pj.col(l);
        }
      }
      const Matrix3d* R_NJ0 = R_NJp;
      Matrix3d R_NJ0_offset;
      if (n.has_offset) {
        R_NJ0_offset.noalias() = *R_NJp * n.R_PJ0;
        R_NJ0 = &R_NJ0_offset;
      }
      Matrix3d R_NJc_node;
      Matrix3d& R_NJc = n.child_attach ? R_NJc_node : w.R_NB;
      switch (n.shape) {
        case JointShape::Axis1:
        {
          const double half = 0.5 * (n.prescribed ? w.pres_angle : x[n.q0]);
          const double sh = std::sin(half), ch = std::cos(half);  // one sincos
          w.sin_half = sh;
          w.cos_half = ch;
          if (n.axis_index >= 0) {
            // axis_J = sign e_i: R_J e_i = e_i, and with (i, j, l) cyclic R_J e_j = c e_j + s e_l,
            // R_J e_l = c e_l - s e_j (Rodrigues' formula, axis_angle_matrix in kane_internal.hpp,
            // with [e_i x] e_j = e_l, s = sign sin(a), c = cos(a) = 1 - 2 sh^2), so R_NJ0 R_J
            // turns two columns of R_NJ0.
            const int i = n.axis_index, j = i == 2 ? 0 : i + 1, l = i == 0 ? 2 : i - 1;
            const double sa = n.axis_sign * 2.0 * sh * ch, ca = 1.0 - 2.0 * sh * sh;
            const Matrix3d& R0 = *R_NJ0;
            R_NJc.col(i) = R0.col(i);
            R_NJc.col(j) = ca * R0.col(j) + sa * R0.col(l);
            R_NJc.col(l) = ca * R0.col(l) - sa * R0.col(j);
            // W_r = axis (fixed in Jp and in Jc): R_NJp axis_P = R_NJ0 axis_J.
            w.W_N.col(0) = n.axis_sign * R0.col(i);
          } else {
            R_NJc.noalias() = *R_NJ0 * axis_angle_matrix(n.axis_J, sh, ch);
            w.W_N.col(0).noalias() = *R_NJp * n.axis_P;  // W_r = axis (fixed in Jp and in Jc)
          }
        }
          break;
        case JointShape::Rotation3:
          R_NJc.noalias() = *R_NJ0 * read_quat(x, n.q0).toRotationMatrix();
          w.W_N = R_NJc;  // W_r = j_r for u_r = w_PC,r in Jc components
          break;
        default:  // every other shape by its unit (fixed, prismatic, universal; joints/)
          n.unit->position(n, x, *R_NJp, *R_NJ0, R_NJc, w, r_Pj);
          break;
      }
      w.p_PoOk_N.noalias() = P.R_NB * r_Pj;
      w.p_B0oOk_N = P.p_B0oBo_N + w.p_PoOk_N;
      Vector3d r_Cj = n.p_CoJ_C;
      if (n.child_attach) {
        const double* eta = x + n.q0 + n.nqj;
        w.rot_C.set(combine(n.Psi_Cj, eta));
        r_Cj += combine(n.Phi_Cj, eta);
        if (n.stiff_C) r_Cj += n.e_Cj * stiff_g(n.G_Cj, eta, w.gC);  // as on the parent side
        w.R_NB.noalias() = R_NJc * w.rot_C.R().transpose();
        const Matrix3d RJl = -(w.R_NB * w.rot_C.Jl());
        for (int l = 0; l < n.nm; ++l) {
          w.Wm_N.col(l).noalias() = RJl * n.Psi_Cj.col(l);
          if (n.stiff_C)
            w.Vm_N.col(l).noalias() = -(w.R_NB * (n.Phi_Cj.col(l) + n.e_Cj * w.gC(l)));
          else
            w.Vm_N.col(l).noalias() = -(w.R_NB * n.Phi_Cj.col(l));
        }
      }
      w.p_OkBo_N.noalias() = -(w.R_NB * r_Cj);
      w.p_B0oBo_N = w.p_B0oOk_N + w.p_OkBo_N;
    }
    // An isotropic rigid body's I_BBo_N is I_BBo_B, set once in the constructor.
    if (n.flex >= 0)
      flex_position(n, w, x + n.q0 + n.nqj);
    else if (rigid_inertia && n.inertia != Node::Inertia::Isotropic)
      rotate_inertia(w.I_BBo_N, w.R_NB, n.I_BBo_B, n.inertia == Node::Inertia::Diagonal);
  }
}

// Flexible body at eta => FlexWork (body frame, then N), I_BBo_N (README.md "Flexible bodies"):
//   c = c0 + S eta;  N_k = G_k^T + sum_l eta_l Q_kl;  A_k = Hs_k + sum_l eta_l C_lk;
//   dS = sum_k eta_k (G_k + N_k) = sum m_i (r_i r_i^T - p_i p_i^T);  I = I0 + tr(dS) 1 - dS.
// Geometric stiffening (FlexModel::stiff): the same quantities summed over the nodes, exactly, with
//   r_i = p_i + Phi_i eta + e_i w_i,  w_i = 1/2 eta^T G_i eta,  Phi~_i = Phi_i + e_i (G_i eta)^T
//   (d r_i / d eta = Phi~_i: docs/flexible-bodies.md "Geometric stiffening"; [KRB] Eq. (8)):
//   c = sum m_i r_i,  dS = sum m_i (r_i r_i^T - p_i p_i^T),  S~ = sum m_i Phi~_i,
//   N_k = sum m_i Phi~_ik r_i^T,  A_k = sum m_i r_i x Phi~_ik,  Mm~ = sum m_i Phi~_i^T Phi~_i.
void KaneEngine::flex_position(const Node& n, NodeWork& w, const double* eta) {
  const FlexModel& F = flex_[static_cast<std::size_t>(n.flex)];
  FlexWork& fw = flex_work_[static_cast<std::size_t>(n.flex)];
  const int m = F.n;
  fw.c_B = F.c0;
  Matrix3d dS = Matrix3d::Zero();
  if (F.stiff) {
    fw.S_B.setZero();
    fw.Mm.setZero();
    fw.A_B.setZero();
    for (int k = 0; k < m; ++k) fw.N_B[static_cast<std::size_t>(k)].setZero();
    for (std::size_t i = 0; i < F.sn.size(); ++i) {
      const FlexModel::StiffNode& sn = F.sn[i];
      const double wi = stiff_g(sn.G, eta, fw.g[i]);
      const Vector3d u = combine(sn.Phi, eta) + sn.e * wi;
      const Vector3d r = sn.p + u;
      fw.r[i] = r;
      fw.c_B += sn.m * u;
      dS.noalias() += sn.m * (r * r.transpose() - sn.p * sn.p.transpose());
      Eigen::Matrix3Xd& Pt = fw.Phit[i];
      for (int k = 0; k < m; ++k) Pt.col(k) = sn.Phi.col(k) + sn.e * fw.g[i](k);
      for (int k = 0; k < m; ++k) {
        fw.S_B.col(k) += sn.m * Pt.col(k);
        fw.N_B[static_cast<std::size_t>(k)].noalias() += sn.m * Pt.col(k) * r.transpose();
        fw.A_B.col(k) += sn.m * r.cross(Pt.col(k));
        for (int l = 0; l < m; ++l) fw.Mm(k, l) += sn.m * Pt.col(k).dot(Pt.col(l));
      }
    }
  }
  for (int k = 0; k < m && !F.stiff; ++k) {
    const std::size_t ks = static_cast<std::size_t>(k);
    fw.c_B += F.S.col(k) * eta[k];
    Matrix3d N = F.G[ks].transpose();
    Vector3d A = F.Hs.col(k);
    for (int l = 0; l < m; ++l) {
      N += eta[l] * F.Q[ks * static_cast<std::size_t>(m) + static_cast<std::size_t>(l)];
      A += eta[l] * F.C[static_cast<std::size_t>(l * m + k)];
    }
    dS += eta[k] * (F.G[ks] + N);
    fw.N_B[ks] = N;
    fw.A_B.col(k) = A;
  }
  fw.I_B = F.I0 - dS;
  fw.I_B.diagonal().array() += dS.trace();
  const Matrix3d& R = w.R_NB;
  fw.c_N.noalias() = R * fw.c_B;
  w.I_BBo_N.noalias() = R * fw.I_B * R.transpose();
  const Eigen::Matrix3Xd& S = F.stiff ? fw.S_B : F.S;
  for (int k = 0; k < m; ++k) {
    fw.S_N.col(k).noalias() = R * S.col(k);
    fw.A_N.col(k).noalias() = R * fw.A_B.col(k);
  }
}

// ------------------------------------------------------------------------------------------------
// Pass 2. (q, u) => w_NB_N, v_NBo_N, w_PC_N, w_NJp_N (velocities as sums of partial velocities
// times u), the attachment terms and the flexible bodies' rate terms.
//   w_Jp = w_P + Wp eta_P';  w_C = w_Jp + w_PC + Wm eta_C' (addition theorem, [KLL] Sec. 1.16);
//   v_Ok = v_Po + w_P x p_PoOk + Vp eta_P' (+ v_PC = sum V_r u_r, a sliding joint);  v_Co = v_Ok + w_C x p_OkCo + Vm eta_C'
//   (a point fixed on, or moving in, a rigid frame, [KLL] Secs. 1.17-1.18).
//   Node-frame rates: psi' = Psi eta', and (d/dt Jl) psi' for the remainder pass.

void KaneEngine::velocity_pass(const double* u) {
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    if (n.shape == JointShape::Base6) {
      const Eigen::Map<const Vector3d> w_NB_B(u + n.u0), v_NBo_N(u + n.u0 + 3);
      w.w_NB_N.noalias() = w.R_NB * w_NB_B;
      w.v_NBo_N = v_NBo_N;
      w.w_PC_N = w.w_NB_N;
    } else {
      const NodeWork& P = n.parent >= 0 ? work_[static_cast<std::size_t>(n.parent)] : ground_;
      const Vector3d& p_OkCo_N = w.p_OkBo_N;
      Vector3d v_Ok = P.v_NBo_N + P.w_NB_N.cross(w.p_PoOk_N);
      w.w_NJp_N = P.w_NB_N;
      if (n.parent_attach) {
        const Node& pn = nodes_[static_cast<std::size_t>(n.parent)];
        const double* eta_rate = u + pn.u0 + pn.nuj;
        w.w_att_N = combine(w.Wp_N, eta_rate);
        w.v_att_N = combine(w.Vp_N, eta_rate);
        w.jdot_att_N.noalias() = P.R_NB * w.rot_P.Jl_dot_times(combine(n.Psi_Pj, eta_rate));
        if (n.stiff_P) w.b_att_N.noalias() = P.R_NB * n.e_Pj * stiff_quad(n.G_Pj, eta_rate);
        w.w_NJp_N += w.w_att_N;
        v_Ok += w.v_att_N;
      }
      switch (n.shape) {
        case JointShape::Axis1:  // a prescribed joint: its rate theta'(t)
          w.w_PC_N = w.W_N.col(0) * (n.prescribed ? w.pres_rate : u[n.u0]);
          break;
        case JointShape::Rotation3:
          w.w_PC_N.noalias() = w.W_N * Eigen::Map<const Vector3d>(u + n.u0);
          break;
        default:  // by the joint's unit: w_PC = sum W_r u_r, v_PC = sum V_r u_r
          n.unit->velocity(n, u, w);
          break;
      }
      if (n.slides) v_Ok += w.v_PC_N;  // Ok moves in Jp ([KL85] Sec. 2.8)
      w.w_NB_N = w.w_NJp_N + w.w_PC_N;
      if (n.child_attach) {
        const double* eta_rate = u + n.u0 + n.nuj;
        w.w_m_N = combine(w.Wm_N, eta_rate);
        w.v_m_N = combine(w.Vm_N, eta_rate);
        w.jdot_m_N.noalias() = w.R_NB * w.rot_C.Jl_dot_times(combine(n.Psi_Cj, eta_rate));
        if (n.stiff_C) w.b_m_N.noalias() = -(w.R_NB * n.e_Cj) * stiff_quad(n.G_Cj, eta_rate);
        w.w_NB_N += w.w_m_N;
      }
      w.v_NBo_N = v_Ok + w.w_NB_N.cross(p_OkCo_N);
      if (n.child_attach) w.v_NBo_N += w.v_m_N;
    }
    if (n.flex >= 0) flex_velocity(n, w, u + n.u0 + n.nuj);
  }
}

// Flexible body's rate terms => FlexWork:  cdot_N = R S eta',  hdef_N = R A eta',
//   L = sum_k eta_k' N_k^T = sum m_i r_i (Phi_i eta')^T,  Ce_k = sum_l eta_l' C_lk.
// Geometric stiffening: Ce_k = sum m_i (Phi~_i eta') x Phi~_ik by node sums, and the nodes'
// second-order accelerations b_i = e_i (eta'^T G_i eta') (d2u_i/dt2 = Phi~_i eta'' + b_i,
// docs/flexible-bodies.md) summed into bsum, bmom and bgen (FlexWork).
void KaneEngine::flex_velocity(const Node& n, NodeWork& w, const double* eta_rate) {
  const FlexModel& F = flex_[static_cast<std::size_t>(n.flex)];
  FlexWork& fw = flex_work_[static_cast<std::size_t>(n.flex)];
  const int m = F.n;
  fw.cdot_N = combine(fw.S_N, eta_rate);
  fw.hdef_N = combine(fw.A_N, eta_rate);
  fw.L_B.setZero();
  if (F.stiff) {
    for (int k = 0; k < m; ++k)
      fw.L_B.noalias() += eta_rate[k] * fw.N_B[static_cast<std::size_t>(k)].transpose();
    fw.Ce_B.setZero();
    fw.bgen.setZero();
    Vector3d bsum = Vector3d::Zero(), bmom = Vector3d::Zero();
    for (std::size_t i = 0; i < F.sn.size(); ++i) {
      const FlexModel::StiffNode& sn = F.sn[i];
      const Eigen::Matrix3Xd& Pt = fw.Phit[i];
      const Vector3d v = combine(Pt, eta_rate);
      const double q = sn.m * stiff_quad(sn.G, eta_rate);
      for (int k = 0; k < m; ++k) {
        fw.Ce_B.col(k) += sn.m * v.cross(Pt.col(k));
        fw.bgen(k) += q * Pt.col(k).dot(sn.e);
      }
      bsum += q * sn.e;
      bmom += q * fw.r[i].cross(sn.e);
    }
    fw.bsum_N.noalias() = w.R_NB * bsum;
    fw.bmom_N.noalias() = w.R_NB * bmom;
    return;
  }
  for (int k = 0; k < m; ++k) {
    fw.L_B.noalias() += eta_rate[k] * fw.N_B[static_cast<std::size_t>(k)].transpose();
    Vector3d c = Vector3d::Zero();
    for (int l = 0; l < m; ++l) c += eta_rate[l] * F.C[static_cast<std::size_t>(l * m + k)];
    fw.Ce_B.col(k) = c;
  }
}

}  // namespace crossdyn::kane
