// Pass 5 of the Kane engine (README.md "Mass matrix"): the mass matrix M (lower triangle) from the
// subtree sums of Pass 4, the coefficients of u' in the generalised inertia forces F_r*.
#include "formulations/kane/kane_internal.hpp"

#include "core/cancel.hpp"

namespace crossdyn::kane {

// ------------------------------------------------------------------------------------------------
// Pass 5. subtree sums => M (lower triangle).  M_rs = sum over the particles of S(k) of m V_r.V_s
// plus sum over frames W_r . J W_s ([KLL] Sec. 5.x generalised inertia forces, linear in u').
//   Speed r of node k moves S(k) with its twist (W_r, V_r) about Ok (plus, for a modal speed, the
//   elastic part); p_r and h_r (about Ok) are the linear and angular momentum of S(k) in that
//   partial motion.  Twist part: p = m_k V_r + W_r x s_k, h = s_k x V_r + J_k W_r.
//   M_rs = W_s . h_r + V_s . p_r for every twist s that moves all of S(k) (speeds of k and of
//   its ancestors a, with h moved to Oa: h + (p_Ok - p_Oa) x p), plus, for a modal speed s, its
//   elastic part's work against the motion r:
//     on C's nodes:  sum m_i R Phi_is . V_r(node i) = S_s . V_r + W_r . h^C_s + Mm_sr
//                    (h^C_s = (p_Co - p_Ok) x R S_s + R A_s, V_r(node i) = V_r + W_r x (x_i -
//                    p_Ok) + R Phi_ir);
//     on an attached child c's subtree:  Wp_c,s . h_c + Vp_c,s . p_c, (p_c, h_c) the momenta of
//                    S(c) about Oc in the motion r.
//   Joint speeds: V_r = 0 but for a sliding joint (prismatic: W_r = 0, V_r = axis_N).
//   Base block: M(w, w) = R^T J_0 R;  M(v_i, w_j) = n_i . (b_j x s_0);  M(v, v) = m 1.

// mass_matrix_ancestor_joint and subtree_inertia_times: kane_internal.hpp.

void KaneEngine::mass_matrix_ancestors(const Node& n, int r, const Vector3d& p, const Vector3d& h) {
  const NodeWork& w = work_[static_cast<std::size_t>(n.joint)];
  for (const Node::Ancestor& an : n.speed_ancestors) {
    const Node& A = nodes_[static_cast<std::size_t>(an.node)];
    const NodeWork& wa = work_[static_cast<std::size_t>(an.node)];
    const Vector3d h_a = mass_matrix_ancestor_joint(w, an, r, p, h);
    if (A.nm == 0) continue;
    // The ancestor's modal speeds: their twist (if A hangs at one of its nodes) and their elastic
    // twist at the node where the path to k leaves A (node `via`).
    const Node& V = nodes_[static_cast<std::size_t>(an.via)];
    const NodeWork& wv = work_[static_cast<std::size_t>(an.via)];
    const Vector3d h_v = h + (w.p_B0oOk_N - wv.p_B0oOk_N).cross(p);
    for (int s = 0; s < A.nm; ++s) {
      double m = 0;
      if (A.child_attach) m += wa.Wm_N.col(s).dot(h_a) + wa.Vm_N.col(s).dot(p);
      if (V.parent_attach) m += wv.Wp_N.col(s).dot(h_v) + wv.Vp_N.col(s).dot(p);
      M_(r, A.u0 + A.nuj + s) = m;
    }
  }
}

void KaneEngine::mass_matrix_pass() {
  if (nodes_[0].shape == JointShape::Base6) {
    // Lower triangle only (what solve() reads): M(w_i, w_j) = b_i . J_0 b_j with b_j = R_NB e_j,
    // M(v_i, w_j) = n_i . (b_j x s_0), i.e. column j is R_NB e_j x s_0.
    const NodeWork& base = work_[0];
    const int r0 = nodes_[0].u0;
    const Matrix3d& R = base.R_NB;
    Matrix3d JR;
    JR.noalias() = base.J_sub_N * R;
    for (int j = 0; j < 3; ++j) {
      for (int i = j; i < 3; ++i) M_(r0 + i, r0 + j) = R.col(i).dot(JR.col(j));
      M_.block<3, 1>(r0 + 3, r0 + j) = R.col(j).cross(base.s_sub_N);
    }
    M_.block<3, 3>(r0 + 3, r0 + 3) = Matrix3d::Identity() * base.m_sub;
  }
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    cancel::poll();
    const Node& n = nodes_[k];
    const NodeWork& w = work_[k];
    if (k > 0)
      for (int i = 0; i < n.nuj; ++i) {
        const int r = n.u0 + i;
        const Vector3d W_r = w.W_N.col(i);
        Vector3d p_r = W_r.cross(w.s_sub_N);
        Vector3d h_r = subtree_inertia_times(n, w, W_r);
        if (n.slides) {  // the twist's translation V_r at Ok: p += m V_r, h += s x V_r
          const Vector3d V_r = w.V_N.col(i);
          p_r += w.m_sub * V_r;
          h_r += w.s_sub_N.cross(V_r);
          for (int j = 0; j <= i; ++j)
            M_(r, n.u0 + j) = w.W_N.col(j).dot(h_r) + w.V_N.col(j).dot(p_r);
        } else {
          for (int j = 0; j <= i; ++j) M_(r, n.u0 + j) = w.W_N.col(j).dot(h_r);
        }
        mass_matrix_ancestors(n, r, p_r, h_r);
      }
    if (n.nm == 0) continue;

    // Modal speeds of this node's flexible body.
    const FlexModel& F = flex_[static_cast<std::size_t>(n.flex)];
    FlexWork& fw = flex_work_[static_cast<std::size_t>(n.flex)];
    const Vector3d& d = w.p_OkBo_N;
    // Momenta of each attached child's subtree, about its Oc, in the elastic twists.
    for (int c : n.attached_children) {
      NodeWork& cw = work_[static_cast<std::size_t>(c)];
      for (int l = 0; l < n.nm; ++l) {
        cw.pp_N.col(l) = cw.m_sub * cw.Vp_N.col(l) + cw.Wp_N.col(l).cross(cw.s_sub_N);
        cw.hp_N.col(l) = cw.s_sub_N.cross(cw.Vp_N.col(l)) + cw.J_sub_N * cw.Wp_N.col(l);
      }
    }
    // Momenta of S(k) about Ok per modal speed: elastic part on C's nodes and on the attached
    // subtrees, plus the twist part.
    for (int l = 0; l < n.nm; ++l) {
      Vector3d p = fw.S_N.col(l);
      Vector3d h = d.cross(fw.S_N.col(l)) + fw.A_N.col(l);
      if (n.child_attach) {
        p += w.m_sub * w.Vm_N.col(l) + w.Wm_N.col(l).cross(w.s_sub_N);
        h += w.s_sub_N.cross(w.Vm_N.col(l)) + w.J_sub_N * w.Wm_N.col(l);
      }
      for (int c : n.attached_children) {
        const NodeWork& cw = work_[static_cast<std::size_t>(c)];
        p += cw.pp_N.col(l);
        h += cw.hp_N.col(l) + (cw.p_B0oOk_N - w.p_B0oOk_N).cross(cw.pp_N.col(l));
      }
      fw.pm_N.col(l) = p;
      fw.hm_N.col(l) = h;
    }
    for (int l = 0; l < n.nm; ++l) {
      const int r = n.u0 + n.nuj + l;
      const Vector3d p = fw.pm_N.col(l), h = fw.hm_N.col(l);
      // Against the joint's own speeds (pure twists).
      if (n.shape == JointShape::Base6) {
        M_.block<1, 3>(r, n.u0).noalias() = (w.R_NB.transpose() * h).transpose();
        M_.block<1, 3>(r, n.u0 + 3) = p.transpose();
      } else {
        for (int j = 0; j < n.nuj; ++j) M_(r, n.u0 + j) = w.W_N.col(j).dot(h);
        if (n.slides)
          for (int j = 0; j < n.nuj; ++j) M_(r, n.u0 + j) += w.V_N.col(j).dot(p);
      }
      // Against the modal speeds s <= l: twist part of s, and its elastic part on C's nodes.
      for (int s = 0; s <= l; ++s) {
        double m = F.stiff ? fw.Mm(s, l) : F.Mm(s, l);
        if (n.child_attach) {
          const Vector3d hC_s = d.cross(fw.S_N.col(s)) + fw.A_N.col(s);
          m += w.Wm_N.col(s).dot(h) + w.Vm_N.col(s).dot(p) + fw.S_N.col(s).dot(w.Vm_N.col(l)) +
               w.Wm_N.col(l).dot(hC_s);
        }
        M_(r, n.u0 + n.nuj + s) = m;
      }
      // The elastic part of s on each attached subtree S(c), which moves in the motion r with
      // the twist (W, V) about Oc: r's twist carried to Oc plus r's own elastic twist there.
      for (int c : n.attached_children) {
        const NodeWork& cw = work_[static_cast<std::size_t>(c)];
        Vector3d p_c = cw.pp_N.col(l), h_c = cw.hp_N.col(l);
        if (n.child_attach) {
          const Vector3d W = w.Wm_N.col(l);
          const Vector3d V = w.Vm_N.col(l) + W.cross(cw.p_B0oOk_N - w.p_B0oOk_N);
          p_c += cw.m_sub * V + W.cross(cw.s_sub_N);
          h_c += cw.s_sub_N.cross(V) + cw.J_sub_N * W;
        }
        for (int s = 0; s <= l; ++s)
          M_(r, n.u0 + n.nuj + s) += cw.Wp_N.col(s).dot(h_c) + cw.Vp_N.col(s).dot(p_c);
      }
      mass_matrix_ancestors(n, r, p, h);
    }
  }
}

}  // namespace crossdyn::kane
