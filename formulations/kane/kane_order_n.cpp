// The Kane engine's order-N solver (README.md, "Two solvers"): Kane's equations of a rigid
// tree eliminated along the tree, leaves first, without forming the mass matrix.
//
// Derivation (followed here; the structure is Featherstone's articulated-body algorithm, [Feath]
// Ch. 7 (articulated-body inertia and the articulated-body algorithm), written with Kane's
// partial velocities instead of spatial joint motion subspaces, as the order-n Kane formulations
// do: [Ban93]; Stoneking's 42 simulator, ORDER_N option).  The passes before it are the composite
// path's (passes 1-3: kinematics.cpp, accelerations.cpp): positions, velocities and the
// remainder accelerations alpha_t, a_t (all u' = 0).
//
//   Increments.  alpha_B = alpha_t + sum_r W_r u_r',  a_Bo = a_t + sum_r V_r u_r' (the
//   accelerations are linear in u', [KLL] pp. 87-90).  Every speed r of node j moves S(j) with a
//   rigid twist about Oj (joint speeds: W_r, V_r = 0 at Oj; base: W = R_NB columns, V = n_i), so
//   the u' part of the motion of node k's body is one rigid field: its angular acceleration
//   increment dalpha_k and the increment da_k of the acceleration of its point at Ok.  Along a
//   joint (Ok fixed in P and in C):
//     dalpha_k = dalpha_p + sum_{r of k} W_r u_r',   da_k = da_p + dalpha_p x (p_Ok - p_Op).
//   Inertia forces of the increments on a body (Eq. (36) with a = a_t + da + dalpha x d, d =
//   p_Bo - p_Ok): about Ok,  -(J_Ok dalpha + s x da),  resultant -(m da - s x dalpha),  s = m d,
//   J_Ok = I_Bo + m (|d|^2 1 - d d^T): the rigid inertia about Ok, (Iww, Iwv, Ivv) = (J_Ok, [s x],
//   m 1).
//
//   Kane's equation of speed r of node k (Eqs. (34)-(36)): V_r^Bo = W_r x (p_Bo - p_Ok) on S(k),
//   so F_r + F_r* = W_r . M_Ok(every load on S(k)) + tau_r = 0, where the hinge torque tau_r of
//   joint k is the only joint load that works through r (README.md) and the moment sums the
//   residual loads (passes 3-4: -m a_t, T - I alpha_t - w x I w) and the increments' inertia
//   forces.
//
//   Elimination (leaves first).  Claim: once the equations of every joint below k hold, the loads
//   on S(k) are Z_k - I^A_k dA_k (dA = (dalpha, da) at Ok), I^A_k symmetric (articulated inertia).
//   True for a leaf (its rigid inertia, Z = its residual loads).  For a child c of k,
//   dA_c = X_c dA_k + S_c u_c' (X_c: the rigid shift above, S_c = (W_c, 0)), and c's equations
//     S_c^T (Z_c - I^A_c dA_c) + tau_c = 0  =>  u_c' = D_c^-1 (g_c - U_c^T X_c dA_k),
//     U_c = I^A_c S_c,  D_c = S_c^T U_c,  g_c = tau_c + S_c^T Z_c
//   so the loads on S(c) are  Za_c - Ia_c X_c dA_k  with
//     Ia_c = I^A_c - U_c D_c^-1 U_c^T,  Za_c = Z_c - U_c D_c^-1 g_c
//   and moved to Ok (moment + e x force, e = p_Oc - p_Ok; inertia X^T Ia X) they add to k's own:
//     Iww += Iww' - Iwv' E + E Iwv'^T - E Ivv' E,  Iwv += Iwv' + E Ivv',  Ivv += Ivv',  E = [e x]
//   (the transfer of [KLL] Sec. 3.4 for an articulated inertia).  A joint speed with a partial
//   velocity at Ok (prismatic: S_c = (0, V_c)) enters S_c the same way, and the increment
//   dA_c = X_c dA_k + S_c u_c' then has da_c += V_c u_c'.  A fixed joint passes I^A and Z
//   unchanged.  Base (free joint, S_0 invertible, no hinge): S_0^T (Z_0 - I^A_0 dA_0) = 0 gives
//   I^A_0 dA_0 = Z_0, a 6 x 6 solve; then w_NB_B' = R_NB^T dalpha_0, v_NBo_N' = da_0 (the base's
//   remainder accelerations are zero).  Forward, base first: the u_c' above, then dA_c.
//   The u' solve the same equations F_r + F_r* = 0 as M u' = f: tests/kane compares the paths.
//
// Cost: O(1) 3 x 3 work per node, so O(n_bodies) for any tree.  Crossover against the composite
// path (KaneEngine::kOrderNMinDepth below), measured with
//   build/crossdyn_bench --benchmark_filter='^kane_(composite|order_n)/'
//     --benchmark_min_time=0.3 --benchmark_repetitions=5   (one command line)
// (Release, CPU ns per rhs, medians, 2026-11-26, an idle 2-core machine), composite / order-N,
// with the speeds on the deepest path; the composite path here is the rigid free-base one
// (rigid_fast_path.cpp), which moved the crossover up from chain3 (12 speeds):
//   spear1_case1 (7) 230 / 485;  hub_two_panels (7) 271 / 533;  dual_spin 199 / 401;
//   basilisk_hinged_panels 258 / 519;  chain_motor 266 / 534;  chain2 (9) 258 / 441;
//   chain3 (12) 539 / 660;  chain4 (15) 855 / 879;  chain5 (18) 1249 / 1080;  chain6 (21)
//   1775 / 1276;  chain8 (27) 3137 / 1617;  chain20 (63) 47383 / 3885;  chain80 (243)
//   3872490 / 14995;  chain128 (387) 16.6e6 / 23468;
// chain3 ... chain5 again with --benchmark_min_time=0.5 --benchmark_repetitions=9
// --benchmark_enable_random_interleaving=true: chain3 457 / 602, chain4 716 / 794, chain5
// 1070 / 999.  So composite up to 15 speeds (chain4; every committed rigid scene but chain5),
// order-N from 16 (chain5 has 18).

// Bibliography: README.md ([KLL], [Feath], [Ban93]).
#include "formulations/kane/kane_engine.hpp"
#include "formulations/kane/joints/joint_unit.hpp"

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/rotation.hpp"

#include <Eigen/Cholesky>

namespace crossdyn::kane {

const int KaneEngine::kOrderNMinDepth = 16;

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

// Inverse of the symmetric 3 x 3 matrix D (its upper triangle read) by cofactors; false unless D is
// positive definite (Sylvester's criterion: the leading minors D00, D00 D11 - D01^2 and det D > 0).
bool symmetric_inverse(const Matrix3d& D, Matrix3d& D_inv) {
  const double a = D(0, 0), b = D(0, 1), c = D(0, 2), d = D(1, 1), e = D(1, 2), f = D(2, 2);
  const double c00 = d * f - e * e, c01 = c * e - b * f, c02 = b * e - c * d;
  const double det = a * c00 + b * c01 + c * c02;
  if (!(a > 0) || !(a * d - b * b > 0) || !(det > 0)) return false;
  const double s = 1.0 / det;
  D_inv(0, 0) = c00 * s;
  D_inv(0, 1) = D_inv(1, 0) = c01 * s;
  D_inv(0, 2) = D_inv(2, 0) = c02 * s;
  D_inv(1, 1) = (a * f - c * c) * s;
  D_inv(1, 2) = D_inv(2, 1) = (b * c - a * e) * s;
  D_inv(2, 2) = (a * d - b * b) * s;
  return true;
}

// Joint k's elimination for a joint the pass does not inline (prismatic, universal: its unit's
// W_N, V_N; README.md "Joint units"): S = (W, V) with m = nuj columns, U = I^A S, D = S^T U,
// g = tau + S^T Z; the unused columns of U, D^-1 and g stay zero.  Then I^A - U D^-1 U^T and
// Z - U D^-1 g into Iww ... Z_F.  Out of line, so that articulated_pass's own branches compile
// as they did without it.
[[gnu::noinline]] void eliminate_unit_joint(const Node& n, const NodeWork& w, const Joint& J,
                                            double t, const double* x, const double* u,
                                            ArticulatedWork& a, Matrix3d& Iww, Matrix3d& Iwv,
                                            Matrix3d& Ivv, Vector3d& Z_M, Vector3d& Z_F) {
  const int m = n.nuj;
  const Matrix3d& W = w.W_N;
  const Matrix3d& V = w.V_N;
  for (int c = 0; c < m; ++c) {
    a.U_M_N.col(c).noalias() = a.Iww_N * W.col(c);
    a.U_F_N.col(c).noalias() = a.Iwv_N.transpose() * W.col(c);
    if (n.slides) {
      a.U_M_N.col(c).noalias() += a.Iwv_N * V.col(c);
      a.U_F_N.col(c).noalias() += a.Ivv_N * V.col(c);
    }
  }
  Matrix3d D = Matrix3d::Identity();
  for (int i = 0; i < m; ++i) {
    for (int c = 0; c < m; ++c)
      D(i, c) = W.col(i).dot(a.U_M_N.col(c)) + V.col(i).dot(a.U_F_N.col(c));
    a.g(i) = W.col(i).dot(a.Z_M_N) + V.col(i).dot(a.Z_F_N);
  }
  if (n.hinge_load) n.unit->hinge(n, J, t, x, u, a.g.data());
  // D padded with the identity beyond m: its inverse is D_m^-1 padded likewise (then zeroed).
  if (!symmetric_inverse(D, a.D_inv))
    throw RunFailure("kane", t, "articulated inertia",
                     "not positive definite at joint '" + J.name + "'");
  for (int i = m; i < 3; ++i) a.D_inv(i, i) = 0;
  // Rank-m updates, column by column (K = U D^-1).
  for (int c = 0; c < m; ++c) {
    Vector3d K_M = Vector3d::Zero(), K_F = Vector3d::Zero();
    for (int j = 0; j < m; ++j) {
      K_M += a.U_M_N.col(j) * a.D_inv(j, c);
      K_F += a.U_F_N.col(j) * a.D_inv(j, c);
    }
    const Vector3d U_M = a.U_M_N.col(c), U_F = a.U_F_N.col(c);
    Iww.noalias() -= K_M * U_M.transpose();
    Iwv.noalias() -= K_M * U_F.transpose();
    Ivv.noalias() -= K_F * U_F.transpose();
    Z_M -= K_M * a.g(c);
    Z_F -= K_F * a.g(c);
  }
}

}  // namespace

// q, u, alpha_t, a_t, loads => per node I^A (about Ok), Z, and for joints U, D^-1, g.
void KaneEngine::articulated_pass(double t, const double* x) {
  for (ArticulatedWork& a : art_) {
    a.Iww_N.setZero();
    a.Iwv_N.setZero();
    a.Ivv_N.setZero();
    a.Z_M_N.setZero();
    a.Z_F_N.setZero();
  }
  for (std::size_t kk = nodes_.size(); kk-- > 0;) {
    const Node& n = nodes_[kk];
    const NodeWork& w = work_[kk];
    ArticulatedWork& a = art_[kk];

    // This node's own body: rigid inertia about Ok, residual loads (passes 3-4:
    // accelerations.cpp, subtree_sums.cpp).
    const Vector3d& d = w.p_OkBo_N;
    const Vector3d s = n.mass * d;
    a.Iww_N += w.I_BBo_N - s * d.transpose();
    a.Iww_N.diagonal().array() += s.dot(d);
    a.Iwv_N += rot::skew(s);
    a.Ivv_N.diagonal().array() += n.mass;
    Vector3d R_B = -n.mass * w.a_t_N;
    Vector3d T_B = rigid_residual_torque(n, w, w.alpha_t_N);
    if (n.body_torque) add_body_torque(n, w, t, T_B);
    if (gravity_) {  // the environment's loads (gravity.cpp)
      R_B += F_grav_N_[kk];
      T_B += tau_grav_N_[kk];
    }
    a.Z_M_N += T_B + d.cross(R_B);
    a.Z_F_N += R_B;
    if (n.parent < 0) continue;

    // Joint k's equations, solved for u_k' in terms of the parent's increments: Ia, Za.
    Matrix3d Iww = a.Iww_N, Iwv = a.Iwv_N, Ivv = a.Ivv_N;
    Vector3d Z_M = a.Z_M_N, Z_F = a.Z_F_N;
    if (n.shape == JointShape::Axis1) {
      const Vector3d h = w.W_N.col(0);
      const Vector3d U_M = a.Iww_N * h, U_F = a.Iwv_N.transpose() * h;
      const double D = h.dot(U_M);
      if (!(D > 0))
        throw RunFailure("kane", t, "articulated inertia",
                         "not positive definite at joint '" +
                             system_.joints[kk].name + "'");
      a.U_M_N.col(0) = U_M;
      a.U_F_N.col(0) = U_F;
      a.D_inv(0, 0) = 1.0 / D;
      a.g(0) = hinge_torque_revolute(n, t, x) + h.dot(a.Z_M_N);
      const Vector3d K_M = U_M / D, K_F = U_F / D;
      Iww.noalias() -= K_M * U_M.transpose();
      Iwv.noalias() -= K_M * U_F.transpose();
      Ivv.noalias() -= K_F * U_F.transpose();
      Z_M -= K_M * a.g(0);
      Z_F -= K_F * a.g(0);
    } else if (n.shape == JointShape::Rotation3) {
      const Matrix3d& W = w.W_N;
      a.U_M_N.noalias() = a.Iww_N * W;
      a.U_F_N.noalias() = a.Iwv_N.transpose() * W;
      Matrix3d D;
      D.noalias() = W.transpose() * a.U_M_N;
      if (!symmetric_inverse(D, a.D_inv))
        throw RunFailure("kane", t, "articulated inertia",
                         "not positive definite at joint '" +
                             system_.joints[kk].name + "'");
      a.g.noalias() = W.transpose() * a.Z_M_N;
      a.g += hinge_torque_spherical(n, t, x);
      Matrix3d K_M, K_F;
      K_M.noalias() = a.U_M_N * a.D_inv;
      K_F.noalias() = a.U_F_N * a.D_inv;
      Iww.noalias() -= K_M * a.U_M_N.transpose();
      Iwv.noalias() -= K_M * a.U_F_N.transpose();
      Ivv.noalias() -= K_F * a.U_F_N.transpose();
      Z_M.noalias() -= K_M * a.g;
      Z_F.noalias() -= K_F * a.g;
    } else if (n.nuj > 0) {  // every other joint, by its unit's W_N and V_N
      eliminate_unit_joint(n, w, system_.joints[kk], t, x, x + n_q_, a, Iww, Iwv, Ivv, Z_M, Z_F);
    }

    // Moved to the parent's reference point Op and added to its sums.
    ArticulatedWork& P = art_[static_cast<std::size_t>(n.parent)];
    const Vector3d e = w.p_B0oOk_N - work_[static_cast<std::size_t>(n.parent)].p_B0oOk_N;
    const Matrix3d E = rot::skew(e);
    Matrix3d IwvE, EIvv;
    IwvE.noalias() = Iwv * E;
    EIvv.noalias() = E * Ivv;
    P.Iww_N += Iww - IwvE - IwvE.transpose();  // E Iwv^T = -(Iwv E)^T (E^T = -E)
    P.Iww_N.noalias() -= EIvv * E;
    P.Iwv_N += Iwv + EIvv;
    P.Ivv_N += Ivv;
    P.Z_M_N += Z_M + e.cross(Z_F);
    P.Z_F_N += Z_F;
  }
}

// I^A, Z, U, D^-1, g => u' (udot_) and the increments dalpha, da_Ok, base first.
void KaneEngine::articulated_solve(double t) {
  cancel::poll();
  {
    const Node& n = nodes_[0];
    ArticulatedWork& a = art_[0];
    Eigen::Matrix<double, 6, 6> I0;
    I0.topLeftCorner<3, 3>() = a.Iww_N;
    I0.topRightCorner<3, 3>() = a.Iwv_N;
    I0.bottomLeftCorner<3, 3>() = a.Iwv_N.transpose();
    I0.bottomRightCorner<3, 3>() = a.Ivv_N;
    Eigen::Matrix<double, 6, 1> Z0;
    Z0.head<3>() = a.Z_M_N;
    Z0.tail<3>() = a.Z_F_N;
    const Eigen::LLT<Eigen::Matrix<double, 6, 6>> llt(I0);
    if (llt.info() != Eigen::Success)
      throw RunFailure("kane", t, "articulated inertia", "not positive definite at the base");
    const Eigen::Matrix<double, 6, 1> dA0 = llt.solve(Z0);
    a.dalpha_N = dA0.head<3>();
    a.da_Ok_N = dA0.tail<3>();
    udot_.segment<3>(n.u0).noalias() = work_[0].R_NB.transpose() * a.dalpha_N;
    udot_.segment<3>(n.u0 + 3) = a.da_Ok_N;
  }
  for (std::size_t k = 1; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    const NodeWork& w = work_[k];
    ArticulatedWork& a = art_[k];
    const ArticulatedWork& P = art_[static_cast<std::size_t>(n.parent)];
    const Vector3d e = w.p_B0oOk_N - work_[static_cast<std::size_t>(n.parent)].p_B0oOk_N;
    a.dalpha_N = P.dalpha_N;
    a.da_Ok_N = P.da_Ok_N + P.dalpha_N.cross(e);
    if (n.shape == JointShape::Axis1) {
      const double ud = a.D_inv(0, 0) * (a.g(0) - a.U_M_N.col(0).dot(a.dalpha_N) -
                                         a.U_F_N.col(0).dot(a.da_Ok_N));
      udot_(n.u0) = ud;
      a.dalpha_N += w.W_N.col(0) * ud;
    } else if (n.shape == JointShape::Rotation3) {
      Vector3d r = a.g;
      r.noalias() -= a.U_M_N.transpose() * a.dalpha_N;
      r.noalias() -= a.U_F_N.transpose() * a.da_Ok_N;
      const Vector3d ud = a.D_inv * r;
      udot_.segment<3>(n.u0) = ud;
      a.dalpha_N.noalias() += w.W_N * ud;
    } else if (n.nuj > 0) {  // u' = D^-1 (g - U^T dA), then dA += S u'
      const int m = n.nuj;
      double r[3];
      for (int i = 0; i < m; ++i)
        r[i] = a.g(i) - a.U_M_N.col(i).dot(a.dalpha_N) - a.U_F_N.col(i).dot(a.da_Ok_N);
      for (int i = 0; i < m; ++i) {
        double ud = 0;
        for (int j = 0; j < m; ++j) ud += a.D_inv(i, j) * r[j];
        udot_(n.u0 + i) = ud;
      }
      for (int i = 0; i < m; ++i) {
        a.dalpha_N += w.W_N.col(i) * udot_(n.u0 + i);
        if (n.slides) a.da_Ok_N += w.V_N.col(i) * udot_(n.u0 + i);
      }
    }
  }
}

}  // namespace crossdyn::kane
