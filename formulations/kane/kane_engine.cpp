// The Kane engine's Engine interface (kane_engine.hpp): the passes in order (dynamics), rhs,
// after_step, pack, accelerations and the prescribed joints' time.  The passes themselves live
// one file each (README.md gives the equations and the file of each).
#include "formulations/kane/kane_internal.hpp"

#include "core/errors.hpp"
#include "core/rotation.hpp"

#include <cmath>
#include <string>

namespace crossdyn::kane {

std::string KaneEngine::state_label(int i) const {
  if (i < 0 || i >= n_q_ + n_u_) return "x[" + std::to_string(i) + "]";
  return labels_[static_cast<std::size_t>(i)];
}

// Prescribed joints at time t (docs/prescribed-motion.md "The motion"; the spin-up profile of
// Kane, Ryan and Banerjee 1987, Eq. (61), evaluated by PrescribedMotion):
//   angle = angle0 + theta(t),  rate = theta'(t),  angle'' = theta''(t).
void KaneEngine::set_time(double t) {
  if (!has_prescribed_) return;
  for (const Node& n : nodes_) {
    if (!n.prescribed) continue;
    NodeWork& w = work_[static_cast<std::size_t>(n.joint)];
    w.pres_angle = n.angle0 + n.motion.angle(t);
    w.pres_rate = n.motion.velocity(t);
    w.pres_accel = n.motion.accel(t);
  }
}

Quaterniond KaneEngine::read_quat(const double* x, int i) const {
  return Quaterniond(x[i], x[i + 1], x[i + 2], x[i + 3]).normalized();
}

void KaneEngine::dynamics(double t, const double* x) {
  set_time(t);
  position_pass(x);
  if (gravity_) gravity_pass(t, base_origin(x));  // the environment's loads (gravity.cpp)
  velocity_pass(x + n_q_);
  remainder_pass();
  if (solver_ == KaneSolver::OrderN) {
    articulated_pass(t, x);
    articulated_solve(t);
    return;
  }
  subtree_pass(t);
  mass_matrix_pass();
  generalized_force_pass(t, x);
  if (!solve())
    throw RunFailure("kane", t, "mass matrix", "not positive definite (a pivot of L^T D L <= 0)");
}

// ------------------------------------------------------------------------------------------------
// (t, x) => xdot: kinematical equations for the positions, Kane's equations for the speeds.

void KaneEngine::rhs(double t, const double* x, double* xdot) {
  if (rigid_fast_) {
    rigid_rhs(t, x, xdot);
    return;
  }
  dynamics(t, x);
  const double* u = x + n_q_;
  for (const Node& n : nodes_) {
    n.unit->q_rates(n, x, u, xdot);
    // eta' is the modal speed itself.
    for (int l = 0; l < n.nm; ++l) xdot[n.q0 + n.nqj + l] = u[n.u0 + n.nuj + l];
  }
  for (int r = 0; r < n_u_; ++r) xdot[n_q_ + r] = udot_(r);
}

bool KaneEngine::after_step(double /*t*/, double* x) {
  // The dynamics normalise every quaternion where they read it and the kinematical equations
  // conserve |q|, so only integration error moves |q|; renormalise once it is visible.
  constexpr double kDrift = 1e-9;
  bool changed = false;
  for (const Node& n : nodes_) {
    if (n.unit->quat_offset < 0) continue;
    const int i = n.q0 + n.unit->quat_offset;
    Eigen::Map<Eigen::Vector4d> q(x + i);
    const double norm = q.norm();
    if (std::abs(norm - 1.0) > kDrift && norm > 0) {
      q /= norm;
      changed = true;
    }
  }
  return changed;
}

// ------------------------------------------------------------------------------------------------
// TreeState => x. The base velocity for zero linear momentum: every particle's velocity is
// v_B0o + (terms in the other speeds, modal rates included) (partial velocity n_i of the base
// translations for every particle), so with P0 the momentum at v_B0o = 0, v_B0o = -P0 / m_total.

void KaneEngine::pack(const TreeState& s, double* x) {
  if (s.joints.size() != nodes_.size())
    throw InputError(where(system_) + ": tree state has " + std::to_string(s.joints.size()) +
                     " joints, the scene " + std::to_string(nodes_.size()));
  double* u = x + n_q_;
  for (const Node& n : nodes_) {
    const TreeState::JointState& js = s.joints[static_cast<std::size_t>(n.joint)];
    n.unit->pack(n, s, js, x, u);
    if (n.nm > 0) {
      const std::size_t b = static_cast<std::size_t>(n.body);
      if (s.eta.size() <= b || s.eta_rate.size() <= b || s.eta[b].size() != n.nm ||
          s.eta_rate[b].size() != n.nm)
        throw InputError(where(system_) + ": tree state: body '" + system_.bodies[b].name +
                         "' needs " + std::to_string(n.nm) +
                         " modal coordinates and as many rates");
      if (!s.eta[b].allFinite() || !s.eta_rate[b].allFinite())
        throw InputError(where(system_) + ": tree state: body '" + system_.bodies[b].name +
                         "': modal coordinates must be finite");
      for (int l = 0; l < n.nm; ++l) {
        x[n.q0 + n.nqj + l] = s.eta[b](l);
        u[n.u0 + n.nuj + l] = s.eta_rate[b](l);
      }
    }
  }
  set_time(0.0);
  // Zero linear momentum applies to a free base only (docs/prescribed-motion.md).
  if (system_.zero_linear_momentum && system_.base_is_free()) {
    for (int i = 0; i < 3; ++i) u[nodes_[0].u0 + 3 + i] = 0.0;
    position_pass(x);
    velocity_pass(u);
    const Vector3d v = -sum_momenta(u).P / total_mass_;
    for (int i = 0; i < 3; ++i) u[nodes_[0].u0 + 3 + i] = v(i);
  }
}

void KaneEngine::accelerations(double t, const double* x, TreeAccel& a) {
  dynamics(t, x);
  acceleration_pass(udot_.data());
  const std::size_t nb = system_.bodies.size(), nj = system_.joints.size();
  a.wdot_NB_B.assign(nb, Vector3d::Zero());
  a.a_NBo_N.assign(nb, Vector3d::Zero());
  a.angle_ddot.assign(nj, 0.0);
  a.angle2_ddot.assign(nj, 0.0);
  a.wdot_PC_C.assign(nj, Vector3d::Zero());
  a.eta_ddot.assign(nb, Eigen::VectorXd());
  for (const Node& n : nodes_) {
    if (n.nm > 0) a.eta_ddot[static_cast<std::size_t>(n.body)] = udot_.segment(n.u0 + n.nuj, n.nm);
    const NodeWork& w = work_[static_cast<std::size_t>(n.joint)];
    // d/dt of the body-frame components of w_NB: R_NB^T alpha (the w x w term vanishes).
    // For a flexible body: its frame; a_NBo_N is the acceleration of the frame origin Bo.
    a.wdot_NB_B[static_cast<std::size_t>(n.body)] = w.R_NB.transpose() * w.alpha_N;
    a.a_NBo_N[static_cast<std::size_t>(n.body)] = w.a_N;
    n.unit->accel(n, w, udot_, a);
  }
}

}  // namespace crossdyn::kane
