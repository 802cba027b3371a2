// The environment's loads in the Kane engine (issue 28; core/system.hpp, struct Environment;
// README.md "Gravity"): uniform gravity, or a central body's field to second order about the
// orbit's reference point O (the gravity gradient), evaluated from this engine's own state.
//
// Kane's generalised active forces ([KL85] Ch. 4: the generalised active force of a force F
// applied at a point Q is V_r^Q . F, of a couple of torque T on a body B W_r^B . T, summed over
// every force; a set of forces on a rigid body contributes V_r^P . R + W_r^B . M_P for its
// resultant R placed at any point P of the body and its moment M_P about P).  Here each body's gravity forces are replaced by their resultant
// F_grav_N at the body frame's origin Bo and their moment tau_grav_N about Bo (gravity_pass);
// Pass 4 adds them to the body's residual loads (R_B, T_B of subtree_sums.cpp), so that every
// speed's twist part W_r . M_k + V_r . F_k (Pass 6, generalized_forces.cpp; the order-N
// elimination, kane_order_n.cpp; the fused rigid path) carries them, and the joint loads'
// momentum balance (loads.cpp) includes them.  A flexible body's modal speed has besides its
// elastic partial velocities R Phi~_il at node i (README.md "Flexible bodies"), through which
// the node forces F_i give Q_grav_l = sum_i R Phi~_il . F_i, added to f in Pass 6 (node
// inertias J_i do not turn with the deformation: their torques have no elastic part).
//
// Uniform field g (every mass m_i at p_i: F_i = m_i g):
//   rigid body:     F = m g at Bo (the CM), tau = 0;
//   flexible body:  F = m g, tau = sum R r_i x m_i g = c_N x g (c_N = R sum m_i r_i, about Bo),
//                   Q_grav_l = sum m_i R Phi~_il . g = S_N,l . g;
//   V = -sum m_i g . p_i = -g . (m p_Bo + c_N)  per body.
// Orbit (Hughes 2004, "Spacecraft Attitude Dynamics", Sec. 8.1; Schaub and Junkins 2018,
// Sec. 4.3): the tidal acceleration a(r) = T r, T = n^2 (3 z z^T - 1), r from O, z the zenith
// (orbit_frame, core/orbit.hpp).  For a body with Bo at r_c from O and its masses at
// r_c + rho_i (rho_i = R r_i):
//   F   = sum m_i T (r_c + rho_i) = m T r_c + T c_N;
//   tau = sum rho_i x m_i T (r_c + rho_i) + sum 3 n^2 z x (J_i z)
//       = c_N x T r_c + 3 n^2 z x (I_N z),
//   since rho x T rho = 3 n^2 (rho x z)(z . rho) and sum m_i (rho_i x z)(z . rho_i) = -z x (Sigma z)
//   = z x (I_m z) (Sigma = sum m_i rho_i rho_i^T, I_m = tr(Sigma) 1 - Sigma; the x x (-1 x) term
//   is zero), I_N = I_m + sum J_i the body's inertia about Bo in N (a rigid body: c_N = 0, I_N =
//   R I_BBo_B R^T; a flexible one: deformed, FlexWork::I_B);
//   Q_grav_l = sum m_i Phi~_il^T R^T T (r_c + R r_i) = S_N,l . T r_c + <T_B, N_l>
//   (T_B = R^T T R, N_l = sum m_i Phi~_il r_i^T, <A, B> = sum_ab A_ab B_ab);
//   V = sum_i [-1/2 m_i (r_c + rho_i)^T T (r_c + rho_i)] + sum_i [3/2 n^2 z^T J_i z - 1/2 n^2 tr J_i]
//     = -1/2 m r_c^T T r_c - r_c^T T c_N + 3/2 n^2 z^T I_N z - 1/2 n^2 tr(I)
//   (-1/2 sum m rho^T T rho = -1/2 n^2 (3 z^T Sigma z - tr Sigma) = 3/2 n^2 z^T I_m z - 1/2 n^2
//   tr I_m, with z^T I_m z = tr Sigma - z^T Sigma z and tr I_m = 2 tr Sigma), the potential of
//   docs/environment.md per rigid body and per node, whose gradient gives the forces above.
// EngineOptions::test_gravity_gradient_sign is the Lagrange engine's hook: this engine ignores it.
#include "formulations/kane/kane_internal.hpp"

#include "core/errors.hpp"
#include "core/orbit.hpp"

#include <cmath>

namespace crossdyn::kane {

Vector3d KaneEngine::base_origin(const double* x) const {
  if (nodes_[0].shape == JointShape::Base6) return Eigen::Map<const Vector3d>(x + nodes_[0].q0);
  return Vector3d::Zero();
}

void KaneEngine::init_environment() {
  const Environment& env = system_.environment;
  gravity_ = !env.none();
  orbit_ = env.orbit();
  if (!gravity_) return;
  const std::string file = where(system_);
  if (env.uniform()) {
    if (!env.g_N.allFinite()) throw InputError(file + ": environment: gravity must be finite");
    g_N_ = env.g_N;
  }
  if (orbit_) {
    const double n = env.mean_motion();
    if (!(n > 0) || !std::isfinite(n))
      throw InputError(file + ": environment: the orbit needs mu > 0 and radius > 0");
  }
  const std::size_t nj = nodes_.size();
  F_grav_N_.assign(nj, Vector3d::Zero());
  tau_grav_N_.assign(nj, Vector3d::Zero());
  for (std::size_t f = 0; f < flex_.size(); ++f) flex_work_[f].Q_grav = Eigen::VectorXd::Zero(flex_[f].n);
  if (!orbit_) return;
  // O = the system's CM at t = 0, from the scene's initial state packed as a run packs it (the
  // base velocity for zero linear momentum included; the CM does not depend on it).
  std::vector<double> x(static_cast<std::size_t>(n_q_ + n_u_), 0.0);
  pack(TreeState::initial(system_), x.data());
  position_pass(x.data());
  velocity_pass(x.data() + n_q_);
  p_NoO_N_ = base_origin(x.data()) + sum_momenta(x.data() + n_q_).cm;
}

void KaneEngine::gravity_pass(double t, const Vector3d& p_NoB0o_N) {
  Matrix3d T_N = Matrix3d::Zero();
  Vector3d z_N = Vector3d::Zero();
  double n2 = 0;
  if (orbit_) {
    const OrbitFrame o = orbit_frame(system_.environment, t);
    z_N = o.zenith_N;
    n2 = o.n * o.n;
    T_N.noalias() = (3.0 * n2) * z_N * z_N.transpose();
    T_N.diagonal().array() -= n2;
  }
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    const NodeWork& w = work_[k];
    Vector3d& F = F_grav_N_[k];
    Vector3d& tau = tau_grav_N_[k];
    FlexWork* fw = n.flex >= 0 ? &flex_work_[static_cast<std::size_t>(n.flex)] : nullptr;
    if (!orbit_) {  // uniform
      F = n.mass * g_N_;
      if (fw == nullptr) {
        tau.setZero();
        continue;
      }
      tau = fw->c_N.cross(g_N_);
      for (int l = 0; l < n.nm; ++l) fw->Q_grav(l) = fw->S_N.col(l).dot(g_N_);
      continue;
    }
    const Vector3d r_c = p_NoB0o_N + w.p_B0oBo_N - p_NoO_N_;  // Bo from O
    const Vector3d Tr = T_N * r_c;
    F = n.mass * Tr;
    if (fw == nullptr && n.inertia == Node::Inertia::Isotropic) {
      tau.setZero();  // I z parallel to z
      continue;
    }
    const Vector3d z_B = w.R_NB.transpose() * z_N;
    const Matrix3d& I_B = fw != nullptr ? fw->I_B : n.I_BBo_B;
    const Vector3d Iz_N = w.R_NB * (I_B * z_B);
    tau = (3.0 * n2) * z_N.cross(Iz_N);
    if (fw == nullptr) continue;
    F.noalias() += T_N * fw->c_N;
    tau += fw->c_N.cross(Tr);
    Matrix3d T_B;
    T_B.noalias() = w.R_NB.transpose() * T_N * w.R_NB;
    for (int l = 0; l < n.nm; ++l)
      fw->Q_grav(l) = fw->S_N.col(l).dot(Tr) +
                      T_B.cwiseProduct(fw->N_B[static_cast<std::size_t>(l)]).sum();
  }
}

double KaneEngine::gravity_potential(double t, const Vector3d& p_NoB0o_N) const {
  if (!gravity_) return 0.0;
  double V = 0;
  if (!orbit_) {
    for (std::size_t k = 0; k < nodes_.size(); ++k) {
      const Node& n = nodes_[k];
      Vector3d first_moment = n.mass * (p_NoB0o_N + work_[k].p_B0oBo_N);
      if (n.flex >= 0) first_moment += flex_work_[static_cast<std::size_t>(n.flex)].c_N;
      V -= g_N_.dot(first_moment);
    }
    return V;
  }
  const OrbitFrame o = orbit_frame(system_.environment, t);
  const double n2 = o.n * o.n;
  const Vector3d& z_N = o.zenith_N;
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    const NodeWork& w = work_[k];
    const Vector3d r_c = p_NoB0o_N + w.p_B0oBo_N - p_NoO_N_;
    // r^T T r = n^2 (3 (z . r)^2 - |r|^2)
    const double zr = z_N.dot(r_c);
    V -= 0.5 * n.mass * n2 * (3.0 * zr * zr - r_c.squaredNorm());
    const Vector3d z_B = w.R_NB.transpose() * z_N;
    const Matrix3d* I_B = &n.I_BBo_B;
    if (n.flex >= 0) {
      const FlexWork& fw = flex_work_[static_cast<std::size_t>(n.flex)];
      V -= n2 * (3.0 * zr * z_N.dot(fw.c_N) - r_c.dot(fw.c_N));  // r_c^T T c_N
      I_B = &fw.I_B;
    }
    V += 1.5 * n2 * z_B.dot(*I_B * z_B) - 0.5 * n2 * I_B->trace();
  }
  return V;
}

double KaneEngine::jacobi(double t, double E, const Vector3d& H_Scm_N, const Vector3d& P_N,
                          const Vector3d& p_NoScm_N) const {
  const OrbitFrame o = orbit_frame(system_.environment, t);
  // H about O: H_Scm + M (p_cm - p_O) x v_cm, M v_cm = P (the system's linear momentum).
  const Vector3d H_O_N = H_Scm_N + (p_NoScm_N - p_NoO_N_).cross(P_N);
  return E - o.w_NO_N.dot(H_O_N);
}

Vector3d KaneEngine::gravity_moment(const Vector3d& p_NoB0o_N, const Vector3d& p_NoScm_N) const {
  Vector3d M = Vector3d::Zero();
  for (std::size_t k = 0; k < nodes_.size(); ++k)
    M += (p_NoB0o_N + work_[k].p_B0oBo_N - p_NoScm_N).cross(F_grav_N_[k]) + tau_grav_N_[k];
  return M;
}

double KaneEngine::gravity_potential_energy(double t, const double* x) {
  set_time(t);
  position_pass(x);
  return gravity_potential(t, base_origin(x));
}

double KaneEngine::jacobi_integral(double t, const double* x) {
  set_time(t);
  position_pass(x);
  velocity_pass(x + n_q_);
  const Momenta m = sum_momenta(x + n_q_);
  const Vector3d p0 = base_origin(x);
  const double E = m.T + potential_energy(x) + gravity_potential(t, p0);
  return orbit_ ? jacobi(t, E, m.H, m.P, p0 + m.cm) : E;
}

}  // namespace crossdyn::kane