// Diagnostics and outputs of the Kane engine: energies and momenta, the introspection for tests
// (body motions, mass points, joint frames, M and f), Kane's equations written out
// (linear_system) and the output rows of the general path (the rigid fast path's row:
// rigid_fast_path.cpp).
#include "formulations/kane/kane_internal.hpp"

#include "core/rotation.hpp"

#include <cmath>
#include <string>

namespace crossdyn::kane {

// ------------------------------------------------------------------------------------------------
// Energies and momenta (after position_pass and velocity_pass).

// One pass over the bodies (docs/flexible-bodies.md "Energy" for the flexible terms):
// T = sum over rigid bodies 1/2 m v.v + 1/2 w.I w, and over flexible bodies, from the nodes'
// velocities v_i = v_Bo + w x R r_i + R Phi_i eta' summed with the modal integrals:
//   1/2 m v.v + v.(w x c + cdot) + 1/2 w.I w + w.hdef + 1/2 eta'^T Mm eta';
// P = sum P_B, with P_B = m v_Bo for a rigid body and sum m_i v_i = m v_Bo + w x c + cdot for a
// flexible one;
// H about the system CM c_sys: sum over bodies of h_Bo + (p_Bo - c_sys) x P_B (sum m_i (x_i -
// c_sys) = 0 over the system) = sum (h_Bo + p_Bo x P_B) - c_sys x P, with h_Bo = I w for a rigid
// body and, for a flexible one, sum m_i (x_i - p_Bo) x v_i + sum J_i w = c x v_Bo + I w + hdef.
// A rigid body's I w is taken in body components, h_Bo = R_NB (I_BBo_B w_NB_B) (output_row's
// position pass skips I_BBo_N); w_NB_B is kept in NodeWork for output_row.
KaneEngine::Momenta KaneEngine::sum_momenta(const double* u) {
  Momenta m;
  m.T = 0;
  m.P.setZero();
  m.H.setZero();
  Vector3d first_moment = Vector3d::Zero();
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    w.w_NB_B.noalias() = w.R_NB.transpose() * w.w_NB_N;
    Vector3d P_B = n.mass * w.v_NBo_N;
    Vector3d h_Bo;
    double T = 0.5 * n.mass * w.v_NBo_N.squaredNorm();
    first_moment += n.mass * w.p_B0oBo_N;
    if (n.flex < 0 && n.inertia == Node::Inertia::Isotropic) {  // I w = c w in any frame
      const double c = n.I_BBo_B(0, 0);
      T += 0.5 * c * w.w_NB_N.squaredNorm();
      h_Bo = c * w.w_NB_N;
    } else if (n.flex < 0) {
      Vector3d h_B;
      if (n.inertia == Node::Inertia::Diagonal)
        h_B = n.I_BBo_B.diagonal().cwiseProduct(w.w_NB_B);
      else
        h_B.noalias() = n.I_BBo_B * w.w_NB_B;
      T += 0.5 * w.w_NB_B.dot(h_B);
      h_Bo.noalias() = w.R_NB * h_B;
    } else {
      const FlexModel& F = flex_[static_cast<std::size_t>(n.flex)];
      const FlexWork& fw = flex_work_[static_cast<std::size_t>(n.flex)];
      const Eigen::Map<const Eigen::VectorXd> eta_rate(u + n.u0 + n.nuj, n.nm);
      const Vector3d Iw = w.I_BBo_N * w.w_NB_N;
      T += 0.5 * w.w_NB_N.dot(Iw) + w.v_NBo_N.dot(w.w_NB_N.cross(fw.c_N) + fw.cdot_N) +
           w.w_NB_N.dot(fw.hdef_N) + 0.5 * eta_rate.dot((F.stiff ? fw.Mm : F.Mm) * eta_rate);
      h_Bo = fw.c_N.cross(w.v_NBo_N) + Iw + fw.hdef_N;
      P_B += w.w_NB_N.cross(fw.c_N) + fw.cdot_N;
      first_moment += fw.c_N;
    }
    m.T += T;
    m.P += P_B;
    m.H += h_Bo + w.p_B0oBo_N.cross(P_B);
  }
  m.cm = first_moment / total_mass_;
  m.H -= m.cm.cross(m.P);
  return m;
}

double KaneEngine::potential_energy(const double* x) const {
  double V = 0;
  for (const Node& n : nodes_) {
    if (!n.hinge_load) continue;
    const Joint& J = system_.joints[static_cast<std::size_t>(n.joint)];
    if (J.stiffness == 0 && J.stiffness2 == 0) continue;
    V += n.unit->spring_energy(n, J, x);
  }
  // Strain energy 1/2 eta^T K eta (docs/flexible-bodies.md "Energy").
  for (const Node& n : nodes_) {
    if (n.nm == 0) continue;
    const Eigen::Map<const Eigen::VectorXd> eta(x + n.q0 + n.nqj, n.nm);
    V += 0.5 * eta.dot(flex_[static_cast<std::size_t>(n.flex)].K * eta);
  }
  return V;
}

double KaneEngine::kinetic_energy(const double* x) {
  position_pass(x);
  velocity_pass(x + n_q_);
  return sum_momenta(x + n_q_).T;
}

Vector3d KaneEngine::linear_momentum_N(const double* x) {
  position_pass(x);
  velocity_pass(x + n_q_);
  return sum_momenta(x + n_q_).P;
}

Vector3d KaneEngine::angular_momentum_N(const double* x) {
  position_pass(x);
  velocity_pass(x + n_q_);
  return sum_momenta(x + n_q_).H;
}

std::vector<BodyMotion> KaneEngine::body_motion(const double* x) {
  position_pass(x);
  velocity_pass(x + n_q_);
  std::vector<BodyMotion> m(nodes_.size());
  // A free base's position is in x; a prescribed base's tree is measured from No already.
  const Vector3d p_NoB0o_N = nodes_[0].shape == JointShape::Base6
                                 ? Vector3d(Eigen::Map<const Vector3d>(x + nodes_[0].q0))
                                 : Vector3d::Zero();
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const NodeWork& w = work_[k];
    BodyMotion& b = m[static_cast<std::size_t>(nodes_[k].body)];
    b.R_NB = w.R_NB;
    b.p_NoBo_N = p_NoB0o_N + w.p_B0oBo_N;
    b.w_NB_B = w.R_NB.transpose() * w.w_NB_N;
    b.v_NBo_N = w.v_NBo_N;
  }
  return m;
}

// Node by node from the body frames and the System's own node data (no modal integrals, no
// attachment tables): x_i = p_Bo + R r_i, v_i = v_Bo + w x R r_i + R Phi_i eta'.
std::vector<MassPoint> KaneEngine::mass_points(const double* x) {
  const std::vector<BodyMotion> bm = body_motion(x);
  std::vector<MassPoint> pts;
  for (const Node& n : nodes_) {
    const BodyMotion& m = bm[static_cast<std::size_t>(n.body)];
    const Body& B = system_.bodies[static_cast<std::size_t>(n.body)];
    const Vector3d w_N = m.R_NB * m.w_NB_B;
    if (!B.flex) {
      MassPoint p;
      p.body = n.body;
      p.mass = B.mass;
      p.J_N = m.R_NB * B.I_BBo_B * m.R_NB.transpose();
      p.p_NoP_N = m.p_NoBo_N;
      p.v_NP_N = m.v_NBo_N;
      pts.push_back(p);
      continue;
    }
    const Eigen::Map<const Eigen::VectorXd> eta(x + n.q0 + n.nqj, n.nm),
        eta_rate(x + n_q_ + n.u0 + n.nuj, n.nm);
    for (std::size_t i = 0; i < B.flex->nodes.size(); ++i) {
      const FlexNode& nd = B.flex->nodes[i];
      const Eigen::Matrix3Xd Phi = nd.Phi_B.cols() ? nd.Phi_B : Eigen::Matrix3Xd::Zero(3, n.nm);
      MassPoint p;
      p.body = n.body;
      p.node = static_cast<int>(i);
      p.mass = nd.mass;
      p.J_N = m.R_NB * nd.J_Ni_B * m.R_NB.transpose();
      Vector3d u = Phi * eta, u_rate = Phi * eta_rate;
      if (B.flex->geometric_stiffening && nd.G.size()) {  // + e (1/2 eta^T G eta), its rate
        u += nd.e_B * (0.5 * eta.dot(nd.G * eta));
        u_rate += nd.e_B * eta.dot(nd.G * eta_rate);
      }
      const Vector3d r_N = m.R_NB * (nd.p_BoNi_B + u);
      p.p_NoP_N = m.p_NoBo_N + r_N;
      p.v_NP_N = m.v_NBo_N + w_N.cross(r_N) + m.R_NB * u_rate;
      pts.push_back(p);
    }
  }
  return pts;
}

// Joint frames from both sides, from the body frames and the System's node data:
// R_NJp = R_NP exp([psi_P x]) (then R_PJ0 R_J to Jc), R_NJc = R_NC exp([psi_C x]).
std::vector<JointFrames> KaneEngine::joint_frames(const double* x) {
  const std::vector<BodyMotion> bm = body_motion(x);
  std::vector<JointFrames> jf(nodes_.size());
  auto node_of = [&](int body, int node, const Eigen::Vector3d& point, Vector3d& r, Matrix3d& E) {
    r = point;
    E.setIdentity();
    if (node < 0) return;
    const Body& B = system_.bodies[static_cast<std::size_t>(body)];
    const FlexNode& nd = B.flex->nodes[static_cast<std::size_t>(node)];
    const Node& bn = nodes_[static_cast<std::size_t>(system_.joint_of_body(body))];
    const Eigen::Map<const Eigen::VectorXd> eta(x + bn.q0 + bn.nqj, bn.nm);
    if (nd.Phi_B.cols()) r += nd.Phi_B * eta;
    if (B.flex->geometric_stiffening && nd.G.size()) r += nd.e_B * (0.5 * eta.dot(nd.G * eta));
    if (nd.Psi_B.cols()) E = rot::from_rotation_vector(nd.Psi_B * eta).toRotationMatrix();
  };
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Joint& J = system_.joints[k];
    const BodyMotion& c = bm[static_cast<std::size_t>(J.child)];
    JointFrames& f = jf[k];
    Vector3d r;
    Matrix3d E;
    node_of(J.child, J.child_node, J.p_CoJ_C, r, E);
    f.R_NJc = c.R_NB * E;
    f.p_NoJ_N_child = c.p_NoBo_N + c.R_NB * r;
    if (J.parent < 0) {  // N: the free joint's "point" is the child's; a prescribed base's is fixed
      f.R_NJp.setIdentity();
      f.p_NoJ_N_parent = nodes_[k].shape == JointShape::Base6 ? f.p_NoJ_N_child : J.p_PoJ_P;
      continue;
    }
    const BodyMotion& p = bm[static_cast<std::size_t>(J.parent)];
    node_of(J.parent, J.parent_node, J.p_PoJ_P, r, E);
    f.R_NJp = p.R_NB * E;
    f.p_NoJ_N_parent = p.p_NoBo_N + p.R_NB * r;
  }
  return jf;
}

Eigen::MatrixXd KaneEngine::mass_matrix(const double* x) {
  position_pass(x);
  velocity_pass(x + n_q_);
  subtree_pass(0.0);
  mass_matrix_pass();
  return M_.selfadjointView<Eigen::Lower>();
}

Eigen::VectorXd KaneEngine::generalized_forces(double t, const double* x) {
  set_time(t);
  position_pass(x);
  if (gravity_) gravity_pass(t, base_origin(x));
  velocity_pass(x + n_q_);
  remainder_pass();
  subtree_pass(t);
  generalized_force_pass(t, x);
  return f_;
}

// Kane's equations F_r + F_r* = 0 ([Paper] Eq. (34); [KLL] pp. 87-90 and Ch. 4), linear in u':
// M(q) u' = f(t, q, u), M of Pass 5 and f = F_r + F_r*|_{u'=0} of Pass 6 at (t, x), the system
// Pass 7 solves (the order-N solver eliminates the same equations without forming M).  The
// unknowns are the generalised speeds' rates u' = xdot[n_q + r]: every joint and modal speed; a
// prescribed joint has no speed (its u_r is known, [KL85] Sec. 6.1), so no row (a tree with no
// speed at all gives A 0 x 0).  M_ is zeroed first so that A holds this pass's entries alone:
// the pass writes only the lower triangle's structural entries (M_rs with one of r, s an
// ancestor speed of the other), and M_ keeps elsewhere whatever an earlier call left there.
// Allocates (the returned matrices); rhs() never calls it.
Engine::LinearSystem KaneEngine::linear_system(double t, const double* x) {
  LinearSystem ls;
  ls.b = generalized_forces(t, x);  // Passes 1-4 and 6 at (t, x); Pass 5 reads what 1-4 left
  M_.setZero();
  mass_matrix_pass();
  ls.A = M_.selfadjointView<Eigen::Lower>();
  ls.speed_index.resize(static_cast<std::size_t>(n_u_));
  for (int r = 0; r < n_u_; ++r) ls.speed_index[static_cast<std::size_t>(r)] = n_q_ + r;
  ls.what = "Kane's equations M u' = f, " + std::to_string(n_u_) + " generalised speeds" +
            (solver_ == KaneSolver::OrderN ? " (solved by the order-N recursion, M not formed)"
                                           : " (M factored by L^T D L)");
  return ls;
}

// ------------------------------------------------------------------------------------------------
// (t, x) => one output row (columns() order).

void KaneEngine::output_row(double t, const double* x, double* row) {
  if (rigid_fast_) {
    rigid_output_row(t, x, row);
    return;
  }
  // The joint loads and the prescribed joints' torques need the accelerations (loads.cpp).
  dynamics(t, x);
  load_pass(t);
  set_time(t);
  position_pass(x, /*rigid_inertia=*/false);  // the sums below use I_BBo_B for rigid bodies
  velocity_pass(x + n_q_);
  const double* u = x + n_q_;

  // Attitudes composed as quaternions (unit norm to rounding):
  // q_NC = q_NP q(psi_P) q_PJ0 q_J q(psi_C)^-1 (q(psi): the node rotations, identity if rigid).
  std::vector<Quaterniond>& q_N = q_N_;
  double quat_err = 0;
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    if (n.shape == JointShape::Base6) {
      const Quaterniond q(x[n.q0 + 3], x[n.q0 + 4], x[n.q0 + 5], x[n.q0 + 6]);
      quat_err = std::max(quat_err, std::abs(q.norm() - 1.0));
      q_N[k] = q.normalized();
      continue;
    }
    Quaterniond q_J = Quaterniond::Identity();
    if (n.shape == JointShape::Axis1) {  // (cos a/2, sin a/2 k), half angle from position_pass
      const NodeWork& w = work_[k];
      q_J = Quaterniond(w.cos_half, w.sin_half * n.axis_J.x(), w.sin_half * n.axis_J.y(),
                        w.sin_half * n.axis_J.z());
    }
    if (n.shape == JointShape::Rotation3) {
      const Quaterniond q(x[n.q0], x[n.q0 + 1], x[n.q0 + 2], x[n.q0 + 3]);
      quat_err = std::max(quat_err, std::abs(q.norm() - 1.0));
      q_J = q.normalized();
    }
    if (n.unit->joint_quat) q_J = n.unit->joint_quat(n, x);  // the other joints' units
    // A prescribed base's parent is N (parent -1): its joint frame starts from the identity.
    Quaterniond q_NJp = n.parent >= 0 ? q_N[static_cast<std::size_t>(n.parent)] : Quaterniond::Identity();
    if (n.parent_attach) q_NJp = q_NJp * rot::from_rotation_vector(work_[k].rot_P.psi);
    Quaterniond q = n.has_offset ? q_NJp * n.q_PJ0 * q_J : q_NJp * q_J;
    if (n.child_attach) q = q * rot::from_rotation_vector(work_[k].rot_C.psi).conjugate();
    q_N[k] = q.normalized();
  }

  const Momenta m = sum_momenta(u);  // also w_NB_B of every body
  const Vector3d& H = m.H;
  const Vector3d& P = m.P;
  const Vector3d p_NoB0o_N = base_origin(x);
  // Hinge springs, strain energy and the environment's potential (gravity.cpp).
  const double T = m.T, V = potential_energy(x) + gravity_potential(t, p_NoB0o_N);
  RowWriter out(layout_, row);
  out.time(t);
  for (std::size_t b = 0; b < system_.bodies.size(); ++b) {
    const std::size_t k = static_cast<std::size_t>(system_.joint_of_body(static_cast<int>(b)));
    out.body(static_cast<int>(b), work_[k].w_NB_B, q_N[k]);
  }
  for (const Node& n : nodes_) {
    n.unit->output(n, work_[static_cast<std::size_t>(n.joint)],
                   prescribed_torque_[static_cast<std::size_t>(n.joint)], x, u, out);
    if (n.nm > 0)
      out.modal(n.body, Eigen::Map<const Eigen::VectorXd>(x + n.q0 + n.nqj, n.nm),
                Eigen::Map<const Eigen::VectorXd>(u + n.u0 + n.nuj, n.nm));
  }
  out.momentum(H);  // H = |H_N| and Hx, Hy, Hz
  out.energy(T + V);
  // Issue 26: positions (a free base's origin is in x; a prescribed base's tree is measured
  // from No), the system CM, joint loads, P and the external moment (loads.cpp).
  write_issue26_columns(t, x, p_NoB0o_N, p_NoB0o_N + m.cm, out);
  if (orbit_) out.jacobi(jacobi(t, T + V, H, P, p_NoB0o_N + m.cm));  // issue 28 (gravity.cpp)
  // Extras: kane.H_N.x/y/z repeat Hx, Hy, Hz (kept; superseded by the pinned columns).
  int c = extra0_;
  out.extra(c++, T);
  out.extra(c++, V);
  for (int i = 0; i < 3; ++i) out.extra(c++, H(i));
  for (int i = 0; i < 3; ++i) out.extra(c++, P(i));
  out.extra(c++, quat_err);
}

}  // namespace crossdyn::kane
