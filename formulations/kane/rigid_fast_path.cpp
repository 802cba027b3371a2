// The fused rigid path of the Kane engine (README.md "Rigid trees"): rhs() and output_row() of a
// tree of rigid bodies with a free base on the composite solver (rigid_fast_), which is every
// committed rigid scene but chain5.
//
// rigid_rhs fuses Passes 1-3 (kinematics.cpp, accelerations.cpp) and the kinematical equations
// into one forward loop, Passes 4-6 (subtree_sums.cpp, mass_matrix.cpp, generalized_forces.cpp)
// into one backward loop, and writes Pass 7's solve (ltdl_solve.cpp) straight into xdot;
// rigid_output_row fuses Passes 1-2 with sum_momenta() (diagnostics.cpp) and the row.  Why: what
// goes is the work that cannot arise in such a tree (the flexible, attachment and prescribed
// branches), the passes' separate walks over the tree and the copies between them; the speed-up
// moved the order-N crossover up from chain3 (12 speeds) to 16 speeds (kane_order_n.cpp).
// Each quantity is formed by the same expressions as in the pass files, in the same order (the
// comments below say which pass each step is), so a change to a pass must be made here too.
#include "formulations/kane/kane_internal.hpp"

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/rotation.hpp"

#include <cmath>

namespace crossdyn::kane {

// ------------------------------------------------------------------------------------------------
// Rigid trees.  rhs() of a tree of rigid bodies with a free base on the composite solver (every
// committed rigid scene but chain5, spear1_case1 among them): Passes 1-3 and the kinematical
// equations fused into one forward loop (base first), Passes 4-6 into one backward loop (leaves
// first), and the L^T D L solve of Pass 7 writing u' straight into xdot.  Each node's quantities
// are formed by the expressions of the pass files, in the same order, so xdot is the same to
// the last bit as dynamics() gives; what goes is the work that cannot arise in such a tree (the
// flexible, attachment and prescribed branches), the passes' separate walks over the tree and
// the copies of u' and of w_NJp_N (here w_P).  The backward loop can form node k's rows of M
// (Pass 5) and its f_r (Pass 6) as soon as S(k)'s sums are complete: every descendant of k has a
// larger index, so it has been visited; the rows need, besides these sums, only the positions of
// k's ancestors (forward loop).

void KaneEngine::rigid_rhs(double t, const double* x, double* xdot) {
  const double* u = x + n_q_;
  const std::size_t nn = nodes_.size();
  // Forward, base first: q => R_NB, W_N, positions (Pass 1); u => w_NB_N, v_NBo_N (Pass 2);
  // alpha_t_N, a_t_N (Pass 3); the kinematical equations (as rhs(), kane_engine.cpp).
  {
    const Node& n = nodes_[0];
    NodeWork& w = work_[0];
    w.R_NB = read_quat(x, n.q0 + 3).toRotationMatrix();  // (the base's I_BBo_N is not formed)
    const Eigen::Map<const Vector3d> w_NB_B(u + n.u0);
    w.w_NB_N.noalias() = w.R_NB * w_NB_B;
    w.v_NBo_N = Eigen::Map<const Vector3d>(u + n.u0 + 3);
    // p_NoBo_N' = v_NBo_N;  q_NB' = 1/2 q_NB (x) (0, w_NB_B)  (KLL Sec. 1.13).
    for (int i = 0; i < 3; ++i) xdot[n.q0 + i] = u[n.u0 + 3 + i];
    const Quaterniond q(x[n.q0 + 3], x[n.q0 + 4], x[n.q0 + 5], x[n.q0 + 6]);
    const Eigen::Vector4d qd = rot::quat_rate_body(q, w_NB_B);
    for (int i = 0; i < 4; ++i) xdot[n.q0 + 3 + i] = qd(i);
  }
  for (std::size_t k = 1; k < nn; ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    const NodeWork& P = work_[static_cast<std::size_t>(n.parent)];
    const Matrix3d* R_NJ0 = &P.R_NB;
    Matrix3d R_NJ0_offset;
    if (n.has_offset) {
      R_NJ0_offset.noalias() = P.R_NB * n.R_PJ0;
      R_NJ0 = &R_NJ0_offset;
    }
    switch (n.shape) {
      case JointShape::Axis1: {
        const double half = 0.5 * x[n.q0];
        const double sh = std::sin(half), ch = std::cos(half);  // one libm sincos call
        w.sin_half = sh;
        w.cos_half = ch;
        if (n.axis_index >= 0) {  // R_NJ0 R_J turns two columns of R_NJ0 (Pass 1)
          const int i = n.axis_index, j = i == 2 ? 0 : i + 1, l = i == 0 ? 2 : i - 1;
          const double sa = n.axis_sign * 2.0 * sh * ch, ca = 1.0 - 2.0 * sh * sh;
          const Matrix3d& R0 = *R_NJ0;
          w.R_NB.col(i) = R0.col(i);
          w.R_NB.col(j) = ca * R0.col(j) + sa * R0.col(l);
          w.R_NB.col(l) = ca * R0.col(l) - sa * R0.col(j);
          w.W_N.col(0) = n.axis_sign * R0.col(i);
        } else {
          w.R_NB.noalias() = *R_NJ0 * axis_angle_matrix(n.axis_J, sh, ch);
          w.W_N.col(0).noalias() = P.R_NB * n.axis_P;
        }
        w.w_PC_N = w.W_N.col(0) * u[n.u0];
        xdot[n.q0] = u[n.u0];
        break;
      }
      case JointShape::Rotation3: {
        w.R_NB.noalias() = *R_NJ0 * read_quat(x, n.q0).toRotationMatrix();
        w.W_N = w.R_NB;  // W_r = j_r for u_r = w_PC,r in Jc components
        const Eigen::Map<const Vector3d> w_PC_C(u + n.u0);
        w.w_PC_N.noalias() = w.W_N * w_PC_C;
        // q_J' = 1/2 q_J (x) (0, w_PC_C): R_PC = R_PJ0 R(q_J) with R_PJ0 constant.
        const Quaterniond q(x[n.q0], x[n.q0 + 1], x[n.q0 + 2], x[n.q0 + 3]);
        const Eigen::Vector4d qd = rot::quat_rate_body(q, w_PC_C);
        for (int i = 0; i < 4; ++i) xdot[n.q0 + i] = qd(i);
        break;
      }
      default:
        w.R_NB = *R_NJ0;
        w.w_PC_N.setZero();
        break;
    }
    w.p_PoOk_N.noalias() = P.R_NB * n.p_PoJ_P;
    w.p_B0oOk_N = P.p_B0oBo_N + w.p_PoOk_N;
    w.p_OkBo_N.noalias() = -(w.R_NB * n.p_CoJ_C);
    w.p_B0oBo_N = w.p_B0oOk_N + w.p_OkBo_N;
    if (n.inertia != Node::Inertia::Isotropic)
      rotate_inertia(w.I_BBo_N, w.R_NB, n.I_BBo_B, n.inertia == Node::Inertia::Diagonal);
    // Velocities (Pass 2; w_Jp = w_P).
    const Vector3d& p_PoOk_N = w.p_PoOk_N;
    const Vector3d& p_OkCo_N = w.p_OkBo_N;
    const Vector3d v_Ok = P.v_NBo_N + P.w_NB_N.cross(p_PoOk_N);
    w.w_NB_N = P.w_NB_N + w.w_PC_N;
    w.v_NBo_N = v_Ok + w.w_NB_N.cross(p_OkCo_N);
    // Remainder accelerations (Pass 3; a free base's are zero).
    Vector3d a_Ok, alpha_C;
    if (n.parent_free_base) {
      a_Ok.noalias() = P.w_NB_N.cross(P.w_NB_N.cross(p_PoOk_N));
      alpha_C.setZero();
    } else {
      a_Ok = P.a_t_N + P.alpha_t_N.cross(p_PoOk_N) + P.w_NB_N.cross(P.w_NB_N.cross(p_PoOk_N));
      alpha_C = P.alpha_t_N;
    }
    alpha_C += P.w_NB_N.cross(w.w_PC_N);
    w.a_t_N = a_Ok + alpha_C.cross(p_OkCo_N) + w.w_NB_N.cross(w.w_NB_N.cross(p_OkCo_N));
    w.alpha_t_N = alpha_C;
  }
  // The environment's loads (gravity.cpp), from the positions just formed.
  if (gravity_) gravity_pass(t, Eigen::Map<const Vector3d>(x + nodes_[0].q0));

  // Backward, leaves first: S(k)'s sums (Pass 4), then k's rows of M (Pass 5) and its f_r
  // (Pass 6), then the sums moved to the parent's point.
  for (std::size_t kk = nn; kk-- > 1;) {
    cancel::poll();
    const Node& n = nodes_[kk];
    NodeWork& w = work_[kk];
    const bool start = n.sums_start;
    const Vector3d& d = w.p_OkBo_N;
    put(start, w.m_sub, n.mass);
    put(start, w.s_sub_N, n.mass * d);
    if (!n.leaf_rigid) add_shifted_inertia(w.J_sub_N, w.I_BBo_N, n.mass, d, start);
    Vector3d R_B = -n.mass * w.a_t_N;
    Vector3d T_B = rigid_residual_torque(n, w, w.alpha_t_N);
    if (n.body_torque) add_body_torque(n, w, t, T_B);
    if (gravity_) {  // as Pass 4 (subtree_sums.cpp)
      R_B += F_grav_N_[kk];
      T_B += tau_grav_N_[kk];
    }
    put(start, w.F_sub_N, R_B);
    put(start, w.M_sub_N, T_B + d.cross(R_B));

    for (int i = 0; i < n.nuj; ++i) {
      const int r = n.u0 + i;
      const Vector3d W_r = w.W_N.col(i);
      const Vector3d p_r = W_r.cross(w.s_sub_N);
      const Vector3d h_r = subtree_inertia_times(n, w, W_r);  // (Pass 5)
      for (int j = 0; j <= i; ++j) M_(r, n.u0 + j) = w.W_N.col(j).dot(h_r);
      // mass_matrix_ancestors for rigid ancestors.
      for (const Node::Ancestor& an : n.speed_ancestors)
        mass_matrix_ancestor_joint(w, an, r, p_r, h_r);
    }
    switch (n.shape) {
      case JointShape::Axis1:
        f_(n.u0) = w.W_N.col(0).dot(w.M_sub_N) + hinge_torque_revolute(n, t, x);
        break;
      case JointShape::Rotation3:
        f_.segment<3>(n.u0).noalias() =
            w.W_N.transpose() * w.M_sub_N + hinge_torque_spherical(n, t, x);
        break;
      default:
        break;
    }

    NodeWork& P = work_[static_cast<std::size_t>(n.parent)];
    const bool first = n.parent_start;
    const Vector3d e = w.p_B0oOk_N - P.p_B0oOk_N;
    put(first, P.m_sub, w.m_sub);
    put(first, P.s_sub_N, w.s_sub_N + w.m_sub * e);
    if (n.leaf_rigid)
      add_shifted_inertia(P.J_sub_N, w.I_BBo_N, n.mass, d + e, first);
    else
      add_moved_inertia(P.J_sub_N, w.J_sub_N, w.m_sub, w.s_sub_N, e, first);
    put(first, P.F_sub_N, w.F_sub_N);
    put(first, P.M_sub_N, w.M_sub_N + e.cross(w.F_sub_N));
  }
  {
    // The free base (Bo = Ok, zero remainder accelerations): the base block of M and f(w), f(v)
    // (Passes 4-6), with the base body's own terms in its body components, where its inertia is
    // I_BBo_B itself (W_r = b_r, u_r = w_NB_B,r):  M(w, w) = I_BBo_B + R_NB^T J_c R_NB and
    // f(w) = -w_NB_B x I_BBo_B w_NB_B + T_B + R_NB^T M_c, J_c and M_c the children's subtree
    // sums moved to B0o (none: M(w, w) = I_BBo_B, f(w) Euler's equations).  Same sums as
    // Passes 4-6 (which rotate I_BBo_B to N and back), one rotation fewer.
    const Node& n = nodes_[0];
    NodeWork& w = work_[0];
    const bool start = n.sums_start;  // no child
    put(start, w.m_sub, n.mass);
    if (start) {
      w.s_sub_N.setZero();
      w.F_sub_N.setZero();
    }
    const int r0 = n.u0;
    const Matrix3d& R = w.R_NB;
    const Eigen::Map<const Vector3d> w_B(u + r0);
    Vector3d f_w = Vector3d::Zero();
    if (!start && n.inertia != Node::Inertia::Isotropic) {
      Vector3d Iw;
      if (n.inertia == Node::Inertia::Diagonal)
        Iw = n.I_BBo_B.diagonal().cwiseProduct(w_B);
      else
        Iw.noalias() = n.I_BBo_B * w_B;
      f_w = -gyro_sign_ * w_B.cross(Iw);
    }
    if (!start && n.body_torque) {
      const Body& body = system_.bodies[static_cast<std::size_t>(n.body)];
      const Vector3d T = body.torque.value(t);
      if (body.torque_frame == Body::Frame::Body)
        f_w += T;
      else
        f_w.noalias() += R.transpose() * T;
    }
    if (start) {
      // A lone free body: Passes 4-6 as they are, in N components (the torque-free scenes'
      // results are checked against the analytic solution over 100 s, where rounding grows).
      if (n.inertia != Node::Inertia::Isotropic)
        rotate_inertia(w.I_BBo_N, R, n.I_BBo_B, n.inertia == Node::Inertia::Diagonal);
      Vector3d T_B = Vector3d::Zero();
      if (n.inertia != Node::Inertia::Isotropic)
        T_B.noalias() -= gyro_sign_ * w.w_NB_N.cross(w.I_BBo_N * w.w_NB_N);
      if (n.body_torque) add_body_torque(n, w, t, T_B);
      if (gravity_) T_B += tau_grav_N_[0];
      Matrix3d JR;
      JR.noalias() = w.I_BBo_N * R;
      for (int j = 0; j < 3; ++j)
        for (int i = j; i < 3; ++i) M_(r0 + i, r0 + j) = R.col(i).dot(JR.col(j));
      f_w.noalias() = R.transpose() * T_B;
    } else {
      Matrix3d JR;
      JR.noalias() = w.J_sub_N * R;
      for (int j = 0; j < 3; ++j)
        for (int i = j; i < 3; ++i) M_(r0 + i, r0 + j) = R.col(i).dot(JR.col(j)) + n.I_BBo_B(i, j);
      f_w.noalias() += R.transpose() * w.M_sub_N;
      if (gravity_) f_w.noalias() += R.transpose() * tau_grav_N_[0];
    }
    for (int j = 0; j < 3; ++j) M_.block<3, 1>(r0 + 3, r0 + j) = R.col(j).cross(w.s_sub_N);
    M_.block<3, 3>(r0 + 3, r0 + 3) = Matrix3d::Identity() * w.m_sub;
    f_.segment<3>(r0) = f_w;
    f_.segment<3>(r0 + 3) = w.F_sub_N;
    if (gravity_) f_.segment<3>(r0 + 3) += F_grav_N_[0];
  }
  if (!ltdl_solve_base6(M_.data(), M_.outerStride(), lambda_.data(), n_u_, f_.data(),
                        xdot + n_q_))
    throw RunFailure("kane", t, "mass matrix", "not positive definite (a pivot of L^T D L <= 0)");
}

// The same row for a rigid tree with a free base (rigid_fast_; no prescribed joint, so no joint
// torque column): the positions and velocities of Passes 1-2 (R_NB of each body, its origin
// from the base CM, w_NB_N, v_NBo_N), the attitude quaternions (q_NC = q_NP q_PJ0 q_J, as
// output_row() in diagnostics.cpp)
// and the sums of sum_momenta() (same formulas) in one loop over the nodes, each body's columns
// written as it is reached.  A rigid body's rotational inertia is used in body components
// (h_Bo = R_NB I_BBo_B w_NB_B), so no I_BBo_N is formed; the base's w_NB_B is its speeds u_1..3
// themselves.
void KaneEngine::rigid_output_row(double t, const double* x, double* row) {
  // Issue 26's joint loads need the accelerations: the general passes (dynamics(), whose u' is
  // rigid_rhs's to the last bit) and the loads from the subtree sums (loads.cpp), first, so that
  // the loop below overwrites the positions and velocities with the same values.
  dynamics(t, x);
  load_pass(t);
  const double* u = x + n_q_;
  RowWriter out(layout_, row);
  out.time(t);
  double quat_err = 0, T2 = 0;
  Vector3d P = Vector3d::Zero(), H = Vector3d::Zero(), first_moment = Vector3d::Zero();
  std::vector<Quaterniond>& q_N = q_N_;
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    if (n.shape == JointShape::Base6) {
      const Quaterniond q(x[n.q0 + 3], x[n.q0 + 4], x[n.q0 + 5], x[n.q0 + 6]);
      const double norm = q.norm();
      quat_err = std::abs(norm - 1.0);
      q_N[k] = Quaterniond(q.coeffs() / norm);
      w.R_NB = q_N[k].toRotationMatrix();
      w.w_NB_B = Eigen::Map<const Vector3d>(u + n.u0);
      w.w_NB_N.noalias() = w.R_NB * w.w_NB_B;
      w.v_NBo_N = Eigen::Map<const Vector3d>(u + n.u0 + 3);
    } else {
      const NodeWork& Pw = work_[static_cast<std::size_t>(n.parent)];
      const Matrix3d* R_NJ0 = &Pw.R_NB;
      Matrix3d R_NJ0_offset;
      if (n.has_offset) {
        R_NJ0_offset.noalias() = Pw.R_NB * n.R_PJ0;
        R_NJ0 = &R_NJ0_offset;
      }
      Quaterniond q_J = Quaterniond::Identity();
      bool q_done = false;
      Vector3d w_PC_N = Vector3d::Zero();
      switch (n.shape) {
        case JointShape::Axis1: {
          const double half = 0.5 * x[n.q0];
          const double sh = std::sin(half), ch = std::cos(half);
          if (n.axis_index >= 0) {  // as in Pass 1
            const int i = n.axis_index, j = i == 2 ? 0 : i + 1, l = i == 0 ? 2 : i - 1;
            const double sa = n.axis_sign * 2.0 * sh * ch, ca = 1.0 - 2.0 * sh * sh;
            const Matrix3d& R0 = *R_NJ0;
            w.R_NB.col(i) = R0.col(i);
            w.R_NB.col(j) = ca * R0.col(j) + sa * R0.col(l);
            w.R_NB.col(l) = ca * R0.col(l) - sa * R0.col(j);
            w_PC_N = (n.axis_sign * u[n.u0]) * R0.col(i);
          } else {
            w.R_NB.noalias() = *R_NJ0 * axis_angle_matrix(n.axis_J, sh, ch);
            w_PC_N.noalias() = Pw.R_NB * n.axis_P;
            w_PC_N *= u[n.u0];
          }
          // (cos a/2, sin a/2 k)
          if (n.axis_index >= 0 && !n.has_offset)  // q_NC = q_NP (ch, sign sh e_i)
          {
            q_N[k] = times_axis_rotation(q_N[static_cast<std::size_t>(n.parent)], n.axis_index,
                                         ch, n.axis_sign * sh);
            q_done = true;
          } else {
            q_J = Quaterniond(ch, sh * n.axis_J.x(), sh * n.axis_J.y(), sh * n.axis_J.z());
          }
          out.revolute(n.joint, x[n.q0], u[n.u0]);
          break;
        }
        case JointShape::Rotation3: {
          const Quaterniond q(x[n.q0], x[n.q0 + 1], x[n.q0 + 2], x[n.q0 + 3]);
          quat_err = std::max(quat_err, std::abs(q.norm() - 1.0));
          q_J = q.normalized();
          w.R_NB.noalias() = *R_NJ0 * q_J.toRotationMatrix();
          const Eigen::Map<const Vector3d> w_PC_C(u + n.u0);
          w_PC_N.noalias() = w.R_NB * w_PC_C;
          out.spherical(n.joint, w_PC_C);
          break;
        }
        default:
          w.R_NB = *R_NJ0;
          break;
      }
      // A product of unit quaternions: unit to rounding, not renormalised.
      const Quaterniond& q_NP = q_N[static_cast<std::size_t>(n.parent)];
      if (!q_done) q_N[k] = n.has_offset ? q_NP * n.q_PJ0 * q_J : q_NP * q_J;
      Vector3d p_PoOk_N, p_OkBo_N;
      p_PoOk_N.noalias() = Pw.R_NB * n.p_PoJ_P;
      p_OkBo_N.noalias() = -(w.R_NB * n.p_CoJ_C);
      w.p_B0oBo_N = Pw.p_B0oBo_N + p_PoOk_N + p_OkBo_N;
      w.w_NB_N = Pw.w_NB_N + w_PC_N;
      w.v_NBo_N = Pw.v_NBo_N + Pw.w_NB_N.cross(p_PoOk_N) + w.w_NB_N.cross(p_OkBo_N);
      w.w_NB_B.noalias() = w.R_NB.transpose() * w.w_NB_N;
    }
    out.body(n.body, w.w_NB_B, q_N[k]);
    // sum_momenta, rigid bodies (T2 = 2 T; the base's origin is B0o itself, p = 0).
    const Vector3d P_B = n.mass * w.v_NBo_N;
    Vector3d h_Bo;
    T2 += P_B.dot(w.v_NBo_N);
    if (n.inertia == Node::Inertia::Isotropic) {
      h_Bo = n.I_BBo_B(0, 0) * w.w_NB_N;
      T2 += h_Bo.dot(w.w_NB_N);
    } else {
      Vector3d h_B;
      if (n.inertia == Node::Inertia::Diagonal)
        h_B = n.I_BBo_B.diagonal().cwiseProduct(w.w_NB_B);
      else
        h_B.noalias() = n.I_BBo_B * w.w_NB_B;
      T2 += w.w_NB_B.dot(h_B);
      h_Bo.noalias() = w.R_NB * h_B;
    }
    P += P_B;
    if (k == 0) {
      H += h_Bo;
    } else {
      first_moment += n.mass * w.p_B0oBo_N;
      H += h_Bo + w.p_B0oBo_N.cross(P_B);
    }
  }
  const double T = 0.5 * T2;
  const Vector3d cm = first_moment / total_mass_;  // from the base's origin B0o
  H -= cm.cross(P);
  const Vector3d p_NoB0o_N(Eigen::Map<const Vector3d>(x + nodes_[0].q0));
  double V = has_potential_ ? potential_energy(x) : 0.0;
  if (gravity_) V += gravity_potential(t, p_NoB0o_N);  // gravity.cpp
  out.momentum(H);  // H = |H_N| and Hx, Hy, Hz
  out.energy(T + V);
  // Issue 26: positions, the system CM, joint loads, P, the external moment (loads.cpp).
  write_issue26_columns(t, x, p_NoB0o_N, p_NoB0o_N + cm, out);
  if (orbit_) out.jacobi(jacobi(t, T + V, H, P, p_NoB0o_N + cm));  // issue 28 (gravity.cpp)
  int c = extra0_;
  out.extra(c++, T);
  out.extra(c++, V);
  for (int i = 0; i < 3; ++i) out.extra(c++, H(i));
  for (int i = 0; i < 3; ++i) out.extra(c++, P(i));
  out.extra(c++, quat_err);
}

}  // namespace crossdyn::kane
