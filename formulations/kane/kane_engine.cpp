// Kane's method for a tree of rigid bodies: the passes declared in kane_engine.hpp.
#include "formulations/kane/kane_engine.hpp"

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/rotation.hpp"

#include <cmath>
#include <string>

namespace crossdyn::kane {

namespace {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

std::string where(const System& s) { return s.file.empty() ? "scene '" + s.name + "'" : s.file; }

// Rotation matrix of a rotation by `angle` about the unit vector k (Rodrigues' formula, the
// "simple rotation" of [KLL] Ch. 1): R = I + sin(a) [k x] + (1 - cos(a)) [k x]^2.
Matrix3d axis_angle_matrix(const Vector3d& k, double angle) {
  const double s = std::sin(angle), c = std::cos(angle), v = 1.0 - c;
  Matrix3d R;
  R << c + v * k.x() * k.x(), v * k.x() * k.y() - s * k.z(), v * k.x() * k.z() + s * k.y(),
      v * k.y() * k.x() + s * k.z(), c + v * k.y() * k.y(), v * k.y() * k.z() - s * k.x(),
      v * k.z() * k.x() - s * k.y(), v * k.z() * k.y() + s * k.x(), c + v * k.z() * k.z();
  return R;
}

// Inertia about a point O of a mass m whose centre is at d from O, plus its central inertia:
// J = I + m (|d|^2 1 - d d^T)  (the parallel-axis or transfer theorem for inertia dyadics).
Matrix3d shifted_inertia(const Matrix3d& I, double m, const Vector3d& d) {
  Matrix3d J = I - m * d * d.transpose();
  J.diagonal().array() += m * d.squaredNorm();
  return J;
}

}  // namespace

// ------------------------------------------------------------------------------------------------
// Construction: validate the tree, build the node tables, size the workspace.

KaneEngine::KaneEngine(const System& system, const EngineOptions& options)
    : system_(system), layout_(system_) {
  const std::string file = where(system_);
  const std::size_t nj = system_.joints.size();
  if (nj == 0) throw InputError(file + ": no joints: the kane engine needs a free base joint");
  if (nj != system_.bodies.size())
    throw InputError(file + ": " + std::to_string(system_.bodies.size()) + " bodies but " +
                     std::to_string(nj) + " joints (exactly one joint per body is required)");
  if (!(options.test_inertia_scale > 0) || !std::isfinite(options.test_inertia_scale))
    throw InputError("engine option test_inertia_scale must be positive and finite");

  for (const Body& b : system_.bodies)
    if (b.flex)
      throw InputError(file + ": body '" + b.name +
                       "': flexible bodies are not supported by the kane engine yet");

  nodes_.resize(nj);
  std::vector<int> node_of_body(system_.bodies.size(), -1);
  int nq = 0, nu = 0;
  for (std::size_t k = 0; k < nj; ++k) {
    cancel::poll();
    const Joint& J = system_.joints[k];
    Node& n = nodes_[k];
    const std::string jname = file + ": joint '" + J.name + "'";
    n.type = J.type;
    n.joint = static_cast<int>(k);
    n.body = J.child;
    if (J.child < 0 || J.child >= static_cast<int>(system_.bodies.size()))
      throw InputError(jname + ": child body index out of range");
    if (k == 0) {
      if (J.type != JointType::Free || J.parent != -1)
        throw InputError(jname + ": the first joint must be the free joint of the base body");
    } else {
      if (J.type == JointType::Free)
        throw InputError(jname + ": only the first joint may be free (one free base)");
      if (J.parent < 0 || J.parent >= static_cast<int>(system_.bodies.size()) ||
          node_of_body[static_cast<std::size_t>(J.parent)] < 0)
        throw InputError(jname + ": parent body must be the child of an earlier joint");
      n.parent = node_of_body[static_cast<std::size_t>(J.parent)];
    }
    if (node_of_body[static_cast<std::size_t>(J.child)] >= 0)
      throw InputError(jname + ": body '" + system_.bodies[static_cast<std::size_t>(J.child)].name +
                       "' is the child of two joints");
    node_of_body[static_cast<std::size_t>(J.child)] = static_cast<int>(k);
    const Body& B = system_.bodies[static_cast<std::size_t>(J.child)];
    if (!(B.mass > 0) || !std::isfinite(B.mass))
      throw InputError(file + ": body '" + B.name + "': mass must be positive");
    n.mass = B.mass;
    n.I_BBo_B = options.test_inertia_scale * 0.5 * (B.I_BBo_B + B.I_BBo_B.transpose());
    n.q_PJ0 = J.q_PJ0.normalized();
    n.R_PJ0 = n.q_PJ0.toRotationMatrix();
    n.has_offset = !n.R_PJ0.isIdentity(0.0);
    n.p_PoJ_P = J.p_PoJ_P;
    n.p_CoJ_C = J.p_CoJ_C;
    if (J.type == JointType::Revolute) {
      if (!(J.axis_P.norm() > 0)) throw InputError(jname + ": revolute axis must be non-zero");
      n.axis_P = J.axis_P.normalized();
      n.axis_J = n.R_PJ0.transpose() * n.axis_P;
    }
    n.q0 = nq;
    n.u0 = nu;
    switch (J.type) {
      case JointType::Free:
        n.nq = 7;
        n.nu = 6;
        break;
      case JointType::Revolute:
        n.nq = 1;
        n.nu = 1;
        break;
      case JointType::Spherical:
        n.nq = 4;
        n.nu = 3;
        break;
      case JointType::Fixed:
        n.nq = 0;
        n.nu = 0;
        break;
    }
    nq += n.nq;
    nu += n.nu;
    for (int a = n.parent; a >= 0; a = nodes_[static_cast<std::size_t>(a)].parent)
      if (nodes_[static_cast<std::size_t>(a)].nu > 0) n.speed_ancestors.push_back(a);
    total_mass_ += n.mass;
  }
  n_q_ = nq;
  n_u_ = nu;

  // State labels.
  labels_.assign(static_cast<std::size_t>(n_q_ + n_u_), "");
  for (const Node& n : nodes_) {
    const std::string& b = system_.bodies[static_cast<std::size_t>(n.body)].name;
    const std::string& j = system_.joints[static_cast<std::size_t>(n.joint)].name;
    auto put = [this](int i, const std::string& s) { labels_[static_cast<std::size_t>(i)] = s; };
    switch (n.type) {
      case JointType::Free:
        for (int i = 0; i < 3; ++i) put(n.q0 + i, b + "." + "xyz"[i]);
        for (int i = 0; i < 4; ++i) put(n.q0 + 3 + i, b + ".q" + "wxyz"[i]);
        for (int i = 0; i < 3; ++i) put(n_q_ + n.u0 + i, b + ".w" + "xyz"[i]);
        for (int i = 0; i < 3; ++i) put(n_q_ + n.u0 + 3 + i, b + ".v" + "xyz"[i]);
        break;
      case JointType::Revolute:
        put(n.q0, j + ".angle");
        put(n_q_ + n.u0, j + ".rate");
        break;
      case JointType::Spherical:
        for (int i = 0; i < 4; ++i) put(n.q0 + i, j + ".q" + "wxyz"[i]);
        for (int i = 0; i < 3; ++i) put(n_q_ + n.u0 + i, j + ".w" + "xyz"[i]);
        break;
      case JointType::Fixed:
        break;
    }
  }

  // Output columns: the pinned ones, then this engine's extras.
  extra0_ = layout_.add_extra("kane.T", "J");
  layout_.add_extra("kane.V", "J");
  for (const char* c : {"kane.H_N.x", "kane.H_N.y", "kane.H_N.z"}) layout_.add_extra(c, "kg m^2/s");
  for (const char* c : {"kane.P_N.x", "kane.P_N.y", "kane.P_N.z"}) layout_.add_extra(c, "kg m/s");
  layout_.add_extra("kane.quat_norm_error", "");

  // Workspace.
  work_.resize(nj);
  for (NodeWork& w : work_) {
    w.R_NB.setIdentity();
    w.I_BBo_N.setZero();
    w.W_N.setZero();
    w.p_B0oBo_N.setZero();
    w.p_B0oOk_N.setZero();
    w.w_NB_N.setZero();
    w.v_NBo_N.setZero();
    w.w_PC_N.setZero();
    w.alpha_t_N.setZero();
    w.a_t_N.setZero();
    w.alpha_N.setZero();
    w.a_N.setZero();
    w.m_sub = 0;
    w.s_sub_N.setZero();
    w.J_sub_N.setZero();
    w.F_sub_N.setZero();
    w.M_sub_N.setZero();
  }
  M_ = Eigen::MatrixXd::Zero(n_u_, n_u_);
  f_ = Eigen::VectorXd::Zero(n_u_);
  udot_ = Eigen::VectorXd::Zero(n_u_);
  lambda_.assign(static_cast<std::size_t>(n_u_), -1);
  for (const Node& n : nodes_) {
    if (n.nu == 0) continue;
    int parent_speed = -1;
    if (!n.speed_ancestors.empty()) {
      const Node& a = nodes_[static_cast<std::size_t>(n.speed_ancestors.front())];
      parent_speed = a.u0 + a.nu - 1;
    }
    for (int i = 0; i < n.nu; ++i)
      lambda_[static_cast<std::size_t>(n.u0 + i)] = i == 0 ? parent_speed : n.u0 + i - 1;
  }
  q_N_.assign(nj, Quaterniond::Identity());
}

std::string KaneEngine::state_label(int i) const {
  if (i < 0 || i >= n_q_ + n_u_) return "x[" + std::to_string(i) + "]";
  return labels_[static_cast<std::size_t>(i)];
}

Quaterniond KaneEngine::read_quat(const double* x, int i) const {
  return Quaterniond(x[i], x[i + 1], x[i + 2], x[i + 3]).normalized();
}

// ------------------------------------------------------------------------------------------------
// Pass 1. q => R_NB, I_BBo_N, W_N (partial angular velocities), p_B0oBo_N, p_B0oOk_N.
// Joint kinematics of core/system.hpp: R_NC = R_NP R_PJ0 R_J; the joint point is common to P and
// C: p_J = p_Po + R_NP p_PoJ_P = p_Co + R_NC p_CoJ_C.

void KaneEngine::position_pass(const double* x) {
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    if (n.type == JointType::Free) {
      w.R_NB = read_quat(x, n.q0 + 3).toRotationMatrix();
      w.p_B0oBo_N.setZero();
      w.p_B0oOk_N.setZero();
      w.W_N = w.R_NB;  // W_r = b_r for u_r = w_NB_B,r (r = 1..3)
    } else {
      const NodeWork& P = work_[static_cast<std::size_t>(n.parent)];
      Matrix3d R_NJ0 = n.has_offset ? Matrix3d(P.R_NB * n.R_PJ0) : P.R_NB;
      switch (n.type) {
        case JointType::Revolute:
          w.R_NB.noalias() = R_NJ0 * axis_angle_matrix(n.axis_J, x[n.q0]);
          w.W_N.col(0).noalias() = P.R_NB * n.axis_P;  // W_r = axis (fixed in P and in C)
          break;
        case JointType::Spherical:
          w.R_NB.noalias() = R_NJ0 * read_quat(x, n.q0).toRotationMatrix();
          w.W_N = w.R_NB;  // W_r = c_r for u_r = w_PC_C,r
          break;
        default:
          w.R_NB = R_NJ0;
          break;
      }
      w.p_B0oOk_N.noalias() = P.p_B0oBo_N + P.R_NB * n.p_PoJ_P;
      w.p_B0oBo_N.noalias() = w.p_B0oOk_N - w.R_NB * n.p_CoJ_C;
    }
    w.I_BBo_N.noalias() = w.R_NB * n.I_BBo_B * w.R_NB.transpose();
  }
}

// ------------------------------------------------------------------------------------------------
// Pass 2. (q, u) => w_NB_N, v_NBo_N, w_PC_N (velocities as sums of partial velocities times u).
//   w_C = w_P + w_PC (addition theorem for angular velocities);  v_J = v_Po + w_P x p_PoJ;
//   v_Co = v_J + w_C x p_JCo (two points fixed on a rigid body, applied to P and to C; [KLL] Ch.
//   1).

void KaneEngine::velocity_pass(const double* u) {
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    if (n.type == JointType::Free) {
      const Eigen::Map<const Vector3d> w_NB_B(u + n.u0), v_NBo_N(u + n.u0 + 3);
      w.w_NB_N.noalias() = w.R_NB * w_NB_B;
      w.v_NBo_N = v_NBo_N;
      w.w_PC_N = w.w_NB_N;
      continue;
    }
    const NodeWork& P = work_[static_cast<std::size_t>(n.parent)];
    switch (n.type) {
      case JointType::Revolute:
        w.w_PC_N = w.W_N.col(0) * u[n.u0];
        break;
      case JointType::Spherical:
        w.w_PC_N.noalias() = w.W_N * Eigen::Map<const Vector3d>(u + n.u0);
        break;
      default:
        w.w_PC_N.setZero();
        break;
    }
    w.w_NB_N = P.w_NB_N + w.w_PC_N;
    const Vector3d p_PoJ_N = w.p_B0oOk_N - P.p_B0oBo_N;
    const Vector3d p_JCo_N = w.p_B0oBo_N - w.p_B0oOk_N;
    w.v_NBo_N = P.v_NBo_N + P.w_NB_N.cross(p_PoJ_N) + w.w_NB_N.cross(p_JCo_N);
  }
}

// ------------------------------------------------------------------------------------------------
// Pass 3. (q, u) => alpha_t_N, a_t_N: the accelerations with every u' = 0 (the remainder terms of
// alpha_B = sum W_r u_r' + alpha_t, a_Bo = sum V_r u_r' + a_t).
//   Base: w_NB_N = R_NB w_NB_B, so alpha = R_NB w_NB_B' (w x w = 0) and a = v_NBo_N':  both zero.
//   Child: the joint's partial angular velocities are fixed in P (revolute axis) or in C (c_i);
//   either way d/dt(W_r) u_r sums to w_P x w_PC, so alpha_t,C = alpha_t,P + w_P x w_PC.
//   a_J = a_Po + alpha_P x p_PoJ + w_P x (w_P x p_PoJ), a_Co = a_J + alpha_C x p_JCo +
//   w_C x (w_C x p_JCo)  (two points fixed on a rigid body, [KLL] Ch. 1), with remainder values.

void KaneEngine::remainder_pass() {
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    if (n.type == JointType::Free) {
      w.alpha_t_N.setZero();
      w.a_t_N.setZero();
      continue;
    }
    const NodeWork& P = work_[static_cast<std::size_t>(n.parent)];
    w.alpha_t_N = P.alpha_t_N + P.w_NB_N.cross(w.w_PC_N);
    const Vector3d p_PoJ_N = w.p_B0oOk_N - P.p_B0oBo_N;
    const Vector3d p_JCo_N = w.p_B0oBo_N - w.p_B0oOk_N;
    w.a_t_N = P.a_t_N + P.alpha_t_N.cross(p_PoJ_N) + P.w_NB_N.cross(P.w_NB_N.cross(p_PoJ_N)) +
              w.alpha_t_N.cross(p_JCo_N) + w.w_NB_N.cross(w.w_NB_N.cross(p_JCo_N));
  }
}

// ------------------------------------------------------------------------------------------------
// Pass 4 (backward, leaves first). => per node k the sums over its subtree S(k), about Ok:
//   m_sub, s_sub = sum m (p_Bo - p_Ok), J_sub = sum I_B + m (|d|^2 1 - d d^T)  (mass properties
//   for M), and the residual loads of Eq. (36) at u' = 0 plus the external torques of Eq. (35):
//   R_B = -m a_t at Bo,  T_B = T_ext - I alpha_t - w x I w;  F_sub = sum R_B,
//   M_sub = sum T_B + (p_Bo - p_Ok) x R_B.
// A child's sums move to its parent's point Op with e = p_Ok - p_Op:
//   s' = s + m e;  J' = J + (2 s.e + m |e|^2) 1 - s e^T - e s^T - m e e^T;  M' = M + e x F.

void KaneEngine::subtree_pass(double t) {
  for (NodeWork& w : work_) {
    w.m_sub = 0;
    w.s_sub_N.setZero();
    w.J_sub_N.setZero();
    w.F_sub_N.setZero();
    w.M_sub_N.setZero();
  }
  for (std::size_t kk = nodes_.size(); kk-- > 0;) {
    const Node& n = nodes_[kk];
    NodeWork& w = work_[kk];
    const Body& body = system_.bodies[static_cast<std::size_t>(n.body)];

    // This node's own body.
    const Vector3d d = w.p_B0oBo_N - w.p_B0oOk_N;
    w.m_sub += n.mass;
    w.s_sub_N += n.mass * d;
    w.J_sub_N += shifted_inertia(w.I_BBo_N, n.mass, d);
    const Vector3d R_B = -n.mass * w.a_t_N;
    Vector3d T_B = -(w.I_BBo_N * w.alpha_t_N) - w.w_NB_N.cross(w.I_BBo_N * w.w_NB_N);
    if (!body.torque.empty()) {
      const Vector3d T = body.torque.value(t);
      if (body.torque_frame == Body::Frame::Body)
        T_B.noalias() += w.R_NB * T;
      else
        T_B += T;
    }
    w.F_sub_N += R_B;
    w.M_sub_N += T_B + d.cross(R_B);

    // Move the finished subtree sums to the parent's reference point.
    if (n.parent < 0) continue;
    NodeWork& P = work_[static_cast<std::size_t>(n.parent)];
    const Vector3d e = w.p_B0oOk_N - P.p_B0oOk_N;
    P.m_sub += w.m_sub;
    P.s_sub_N += w.s_sub_N + w.m_sub * e;
    Matrix3d J = w.J_sub_N - w.s_sub_N * e.transpose() - e * w.s_sub_N.transpose() -
                 w.m_sub * e * e.transpose();
    J.diagonal().array() += 2.0 * w.s_sub_N.dot(e) + w.m_sub * e.squaredNorm();
    P.J_sub_N += J;
    P.F_sub_N += w.F_sub_N;
    P.M_sub_N += w.M_sub_N + e.cross(w.F_sub_N);
  }
}

// ------------------------------------------------------------------------------------------------
// Pass 5. subtree sums => M (lower triangle).
//   Speed r of node k (rotational, W_r): p_r = W_r x s_k, h_r = J_k W_r (momenta of S(k) in the
//   partial motion r);  M_rs = W_s . h_r within node k;  M_rs = W_s . (h_r + (p_Ok - p_Oa) x p_r)
//   for a rotational speed s of an ancestor a;  M_rs = n_i . p_r for the base translations.
//   Base block: M(w, w) = R_NB^T J_0 R_NB;  M(v_i, w_j) = n_i . (b_j x s_0);  M(v, v) = m 1.

void KaneEngine::mass_matrix_pass() {
  const NodeWork& base = work_[0];
  const Node& base_node = nodes_[0];
  {
    const int r0 = base_node.u0;
    M_.block<3, 3>(r0, r0).noalias() = base.R_NB.transpose() * base.J_sub_N * base.R_NB;
    M_.block<3, 3>(r0 + 3, r0).noalias() = -rot::skew(base.s_sub_N) * base.R_NB;
    M_.block<3, 3>(r0 + 3, r0 + 3) = Matrix3d::Identity() * base.m_sub;
  }
  for (std::size_t k = 1; k < nodes_.size(); ++k) {
    cancel::poll();
    const Node& n = nodes_[k];
    const NodeWork& w = work_[k];
    for (int i = 0; i < n.nu; ++i) {
      const int r = n.u0 + i;
      const Vector3d W_r = w.W_N.col(i);
      const Vector3d p_r = W_r.cross(w.s_sub_N);
      const Vector3d h_r = w.J_sub_N * W_r;
      for (int j = 0; j <= i; ++j) M_(r, n.u0 + j) = w.W_N.col(j).dot(h_r);
      for (int a : n.speed_ancestors) {
        const Node& A = nodes_[static_cast<std::size_t>(a)];
        const NodeWork& wa = work_[static_cast<std::size_t>(a)];
        const Vector3d h_ra = h_r + (w.p_B0oOk_N - wa.p_B0oOk_N).cross(p_r);
        if (A.type == JointType::Free) {
          M_.block<1, 3>(r, A.u0).noalias() = (wa.R_NB.transpose() * h_ra).transpose();
          M_.block<1, 3>(r, A.u0 + 3) = p_r.transpose();
        } else {
          for (int j = 0; j < A.nu; ++j) M_(r, A.u0 + j) = wa.W_N.col(j).dot(h_ra);
        }
      }
    }
  }
}

// ------------------------------------------------------------------------------------------------
// Pass 6. subtree sums, hinge loads => f = F_r + F_r*|_{u'=0}.
//   Base: f(w) = R_NB^T M_0 (W_r = b_r),  f(v) = F_0 (V_r = n_r).  Node k: f_r = W_r . M_k plus
//   the hinge's own spring, damper and motor (the only speeds its action-reaction pair works on).

double KaneEngine::hinge_torque_revolute(const Node& n, double t, const double* x) const {
  const Joint& J = system_.joints[static_cast<std::size_t>(n.joint)];
  double tau = 0;
  if (J.stiffness != 0) tau -= J.stiffness * (x[n.q0] - J.neutral_angle);
  if (J.damping != 0) tau -= J.damping * x[n_q_ + n.u0];
  if (!J.motor_revolute.empty()) tau += J.motor_revolute.value(t)(0);
  return tau;
}

Vector3d KaneEngine::hinge_torque_spherical(const Node& n, double t, const double* x) const {
  const Joint& J = system_.joints[static_cast<std::size_t>(n.joint)];
  Vector3d tau = Vector3d::Zero();
  if (J.stiffness != 0) tau -= J.stiffness * rot::rotation_vector(read_quat(x, n.q0));
  if (J.damping != 0) tau -= J.damping * Eigen::Map<const Vector3d>(x + n_q_ + n.u0);
  if (!J.motor_spherical.empty()) tau += J.motor_spherical.value(t);
  return tau;
}

void KaneEngine::generalized_force_pass(double t, const double* x) {
  const NodeWork& base = work_[0];
  f_.segment<3>(nodes_[0].u0).noalias() = base.R_NB.transpose() * base.M_sub_N;
  f_.segment<3>(nodes_[0].u0 + 3) = base.F_sub_N;
  for (std::size_t k = 1; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    const NodeWork& w = work_[k];
    switch (n.type) {
      case JointType::Revolute:
        f_(n.u0) = w.W_N.col(0).dot(w.M_sub_N) + hinge_torque_revolute(n, t, x);
        break;
      case JointType::Spherical:
        f_.segment<3>(n.u0).noalias() =
            w.W_N.transpose() * w.M_sub_N + hinge_torque_spherical(n, t, x);
        break;
      default:
        break;
    }
  }
}

// ------------------------------------------------------------------------------------------------
// Pass 7. (M, f) => u'.  Factorisation M = L^T D L (L unit lower triangular, D diagonal) taken
// in reverse order, which keeps the tree's branch-induced sparsity with no fill-in: M_ik != 0
// (k > i) only when i is on the chain i = lambda(k), lambda(lambda(k)), ... of parent speeds
// ([Feath] Sec. 6.5, Table 6.3 "LTDL"; the square-root-free form of the Cholesky factorisation).
// Then u' = L^-1 D^-1 L^-T f (Table 6.4).  M is positive definite exactly when every pivot D_kk
// is positive.  In place: M_ holds L below its diagonal and D on it afterwards.

bool KaneEngine::solve() {
  double* H = M_.data();
  const Eigen::Index ld = M_.outerStride();
  auto h = [H, ld](int i, int j) -> double& { return H[i * ld + j]; };  // row major (row i, col j)
  const int* lambda = lambda_.data();
  for (int k = n_u_ - 1; k >= 0; --k) {
    cancel::poll();
    const double d = h(k, k);
    if (!(d > 0)) return false;
    const double inv_d = 1.0 / d;
    for (int i = lambda[k]; i >= 0; i = lambda[i]) {
      const double a = h(k, i) * inv_d;
      for (int j = i; j >= 0; j = lambda[j]) h(i, j) -= a * h(k, j);
      h(k, i) = a;
    }
  }
  double* x = udot_.data();
  for (int i = 0; i < n_u_; ++i) x[i] = f_(i);
  for (int i = n_u_ - 1; i >= 0; --i)  // L^T z = f
    for (int j = lambda[i]; j >= 0; j = lambda[j]) x[j] -= h(i, j) * x[i];
  for (int i = 0; i < n_u_; ++i) x[i] /= h(i, i);  // y = D^-1 z
  for (int i = 0; i < n_u_; ++i)                   // L u' = y
    for (int j = lambda[i]; j >= 0; j = lambda[j]) x[i] -= h(i, j) * x[j];
  return true;
}

void KaneEngine::dynamics(double t, const double* x) {
  position_pass(x);
  velocity_pass(x + n_q_);
  remainder_pass();
  subtree_pass(t);
  mass_matrix_pass();
  generalized_force_pass(t, x);
  if (!solve())
    throw RunFailure("kane", t, "mass matrix", "not positive definite (a pivot of L^T D L <= 0)");
}

// ------------------------------------------------------------------------------------------------
// (t, x) => xdot: kinematical equations for the positions, Kane's equations for the speeds.

void KaneEngine::rhs(double t, const double* x, double* xdot) {
  dynamics(t, x);
  const double* u = x + n_q_;
  for (const Node& n : nodes_) {
    switch (n.type) {
      case JointType::Free: {
        // p_NoBo_N' = v_NBo_N;  q_NB' = 1/2 q_NB (x) (0, w_NB_B)  (KLL Sec. 1.13).
        for (int i = 0; i < 3; ++i) xdot[n.q0 + i] = u[n.u0 + 3 + i];
        const Quaterniond q(x[n.q0 + 3], x[n.q0 + 4], x[n.q0 + 5], x[n.q0 + 6]);
        const Eigen::Vector4d qd = rot::quat_rate_body(q, Eigen::Map<const Vector3d>(u + n.u0));
        for (int i = 0; i < 4; ++i) xdot[n.q0 + 3 + i] = qd(i);
        break;
      }
      case JointType::Revolute:
        xdot[n.q0] = u[n.u0];
        break;
      case JointType::Spherical: {
        // q_J' = 1/2 q_J (x) (0, w_PC_C): R_PC = R_PJ0 R(q_J) with R_PJ0 constant.
        const Quaterniond q(x[n.q0], x[n.q0 + 1], x[n.q0 + 2], x[n.q0 + 3]);
        const Eigen::Vector4d qd = rot::quat_rate_body(q, Eigen::Map<const Vector3d>(u + n.u0));
        for (int i = 0; i < 4; ++i) xdot[n.q0 + i] = qd(i);
        break;
      }
      case JointType::Fixed:
        break;
    }
  }
  for (int r = 0; r < n_u_; ++r) xdot[n_q_ + r] = udot_(r);
}

bool KaneEngine::after_step(double /*t*/, double* x) {
  // The dynamics normalise every quaternion where they read it and the kinematical equations
  // conserve |q|, so only integration error moves |q|; renormalise once it is visible.
  constexpr double kDrift = 1e-9;
  bool changed = false;
  for (const Node& n : nodes_) {
    int i = -1;
    if (n.type == JointType::Free) i = n.q0 + 3;
    if (n.type == JointType::Spherical) i = n.q0;
    if (i < 0) continue;
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
// TreeState => x. The base CM velocity for zero linear momentum: every body's CM velocity is
// v_B0o + (terms in the other speeds) (partial velocity n_i of the base translations for every
// body), so with P0 the momentum at v_B0o = 0, v_B0o = -P0 / m_total.

void KaneEngine::pack(const TreeState& s, double* x) {
  if (s.joints.size() != nodes_.size())
    throw InputError(where(system_) + ": tree state has " + std::to_string(s.joints.size()) +
                     " joints, the scene " + std::to_string(nodes_.size()));
  double* u = x + n_q_;
  for (const Node& n : nodes_) {
    const TreeState::JointState& js = s.joints[static_cast<std::size_t>(n.joint)];
    switch (n.type) {
      case JointType::Free: {
        const Quaterniond q = s.q_NB.normalized();
        for (int i = 0; i < 3; ++i) x[n.q0 + i] = s.p_NoBo_N(i);
        x[n.q0 + 3] = q.w();
        x[n.q0 + 4] = q.x();
        x[n.q0 + 5] = q.y();
        x[n.q0 + 6] = q.z();
        for (int i = 0; i < 3; ++i) u[n.u0 + i] = s.w_NB_B(i);
        for (int i = 0; i < 3; ++i) u[n.u0 + 3 + i] = s.v_NBo_N(i);
        break;
      }
      case JointType::Revolute:
        x[n.q0] = js.angle;
        u[n.u0] = js.rate;
        break;
      case JointType::Spherical: {
        const Quaterniond q = js.q_J.normalized();
        x[n.q0] = q.w();
        x[n.q0 + 1] = q.x();
        x[n.q0 + 2] = q.y();
        x[n.q0 + 3] = q.z();
        for (int i = 0; i < 3; ++i) u[n.u0 + i] = js.w_PC_C(i);
        break;
      }
      case JointType::Fixed:
        break;
    }
  }
  if (system_.zero_linear_momentum) {
    for (int i = 0; i < 3; ++i) u[nodes_[0].u0 + 3 + i] = 0.0;
    position_pass(x);
    velocity_pass(u);
    const Vector3d v = -sum_linear_momentum() / total_mass_;
    for (int i = 0; i < 3; ++i) u[nodes_[0].u0 + 3 + i] = v(i);
  }
}

// ------------------------------------------------------------------------------------------------
// u' => alpha_N, a_N (full accelerations, for accelerations()): the remainder-pass recursion
// with the joint's sum W_r u_r' added to alpha and a_B0o = v_NBo_N'.

void KaneEngine::acceleration_pass(const double* udot) {
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    if (n.type == JointType::Free) {
      w.alpha_N.noalias() = w.R_NB * Eigen::Map<const Vector3d>(udot + n.u0);
      w.a_N = Eigen::Map<const Vector3d>(udot + n.u0 + 3);
      continue;
    }
    const NodeWork& P = work_[static_cast<std::size_t>(n.parent)];
    w.alpha_N = P.alpha_N + P.w_NB_N.cross(w.w_PC_N);
    for (int i = 0; i < n.nu; ++i) w.alpha_N += w.W_N.col(i) * udot[n.u0 + i];
    const Vector3d p_PoJ_N = w.p_B0oOk_N - P.p_B0oBo_N;
    const Vector3d p_JCo_N = w.p_B0oBo_N - w.p_B0oOk_N;
    w.a_N = P.a_N + P.alpha_N.cross(p_PoJ_N) + P.w_NB_N.cross(P.w_NB_N.cross(p_PoJ_N)) +
            w.alpha_N.cross(p_JCo_N) + w.w_NB_N.cross(w.w_NB_N.cross(p_JCo_N));
  }
}

void KaneEngine::accelerations(double t, const double* x, TreeAccel& a) {
  dynamics(t, x);
  acceleration_pass(udot_.data());
  const std::size_t nb = system_.bodies.size(), nj = system_.joints.size();
  a.wdot_NB_B.assign(nb, Vector3d::Zero());
  a.a_NBo_N.assign(nb, Vector3d::Zero());
  a.angle_ddot.assign(nj, 0.0);
  a.wdot_PC_C.assign(nj, Vector3d::Zero());
  for (const Node& n : nodes_) {
    const NodeWork& w = work_[static_cast<std::size_t>(n.joint)];
    // d/dt of the body-frame components of w_NB: R_NB^T alpha (the w x w term vanishes).
    a.wdot_NB_B[static_cast<std::size_t>(n.body)] = w.R_NB.transpose() * w.alpha_N;
    a.a_NBo_N[static_cast<std::size_t>(n.body)] = w.a_N;
    if (n.type == JointType::Revolute)
      a.angle_ddot[static_cast<std::size_t>(n.joint)] = udot_(n.u0);
    if (n.type == JointType::Spherical)
      a.wdot_PC_C[static_cast<std::size_t>(n.joint)] = udot_.segment<3>(n.u0);
  }
}

// ------------------------------------------------------------------------------------------------
// Energies and momenta (after position_pass and velocity_pass).

double KaneEngine::sum_kinetic_energy() const {
  double T = 0;
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const NodeWork& w = work_[k];
    T += 0.5 * nodes_[k].mass * w.v_NBo_N.squaredNorm() + 0.5 * w.w_NB_N.dot(w.I_BBo_N * w.w_NB_N);
  }
  return T;
}

Vector3d KaneEngine::sum_linear_momentum() const {
  Vector3d P = Vector3d::Zero();
  for (std::size_t k = 0; k < nodes_.size(); ++k) P += nodes_[k].mass * work_[k].v_NBo_N;
  return P;
}

// H about the system CM c: sum I_B w_B + (p_Bo - c) x m_B v_Bo (central angular momentum of a
// set of rigid bodies).
Vector3d KaneEngine::sum_angular_momentum() const {
  Vector3d c = Vector3d::Zero();
  for (std::size_t k = 0; k < nodes_.size(); ++k) c += nodes_[k].mass * work_[k].p_B0oBo_N;
  c /= total_mass_;
  Vector3d H = Vector3d::Zero();
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const NodeWork& w = work_[k];
    H += w.I_BBo_N * w.w_NB_N + (w.p_B0oBo_N - c).cross(nodes_[k].mass * w.v_NBo_N);
  }
  return H;
}

double KaneEngine::potential_energy(const double* x) const {
  double V = 0;
  for (const Node& n : nodes_) {
    const Joint& J = system_.joints[static_cast<std::size_t>(n.joint)];
    if (J.stiffness == 0) continue;
    if (n.type == JointType::Revolute) {
      const double d = x[n.q0] - J.neutral_angle;
      V += 0.5 * J.stiffness * d * d;
    } else if (n.type == JointType::Spherical) {
      V += 0.5 * J.stiffness * rot::rotation_vector(read_quat(x, n.q0)).squaredNorm();
    }
  }
  return V;
}

double KaneEngine::kinetic_energy(const double* x) {
  position_pass(x);
  velocity_pass(x + n_q_);
  return sum_kinetic_energy();
}

Vector3d KaneEngine::linear_momentum_N(const double* x) {
  position_pass(x);
  velocity_pass(x + n_q_);
  return sum_linear_momentum();
}

Vector3d KaneEngine::angular_momentum_N(const double* x) {
  position_pass(x);
  velocity_pass(x + n_q_);
  return sum_angular_momentum();
}

std::vector<BodyMotion> KaneEngine::body_motion(const double* x) {
  position_pass(x);
  velocity_pass(x + n_q_);
  std::vector<BodyMotion> m(nodes_.size());
  const Eigen::Map<const Vector3d> p_NoB0o_N(x + nodes_[0].q0);
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

Eigen::MatrixXd KaneEngine::mass_matrix(const double* x) {
  position_pass(x);
  velocity_pass(x + n_q_);
  subtree_pass(0.0);
  mass_matrix_pass();
  return M_.selfadjointView<Eigen::Lower>();
}

Eigen::VectorXd KaneEngine::generalized_forces(double t, const double* x) {
  position_pass(x);
  velocity_pass(x + n_q_);
  remainder_pass();
  subtree_pass(t);
  generalized_force_pass(t, x);
  return f_;
}

// ------------------------------------------------------------------------------------------------
// (t, x) => one output row (columns() order).

void KaneEngine::output_row(double t, const double* x, double* row) {
  position_pass(x);
  velocity_pass(x + n_q_);
  const double* u = x + n_q_;

  // Attitudes composed as quaternions (unit norm to rounding): q_NC = q_NP q_PJ0 q_J.
  std::vector<Quaterniond>& q_N = q_N_;
  double quat_err = 0;
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    if (n.type == JointType::Free) {
      const Quaterniond q(x[n.q0 + 3], x[n.q0 + 4], x[n.q0 + 5], x[n.q0 + 6]);
      quat_err = std::max(quat_err, std::abs(q.norm() - 1.0));
      q_N[k] = q.normalized();
      continue;
    }
    Quaterniond q_J = Quaterniond::Identity();
    if (n.type == JointType::Revolute) q_J = Quaterniond(Eigen::AngleAxisd(x[n.q0], n.axis_J));
    if (n.type == JointType::Spherical) {
      const Quaterniond q(x[n.q0], x[n.q0 + 1], x[n.q0 + 2], x[n.q0 + 3]);
      quat_err = std::max(quat_err, std::abs(q.norm() - 1.0));
      q_J = q.normalized();
    }
    q_N[k] = (q_N[static_cast<std::size_t>(n.parent)] * n.q_PJ0 * q_J).normalized();
  }

  RowWriter out(layout_, row);
  out.time(t);
  for (std::size_t b = 0; b < system_.bodies.size(); ++b) {
    const std::size_t k = static_cast<std::size_t>(system_.joint_of_body(static_cast<int>(b)));
    out.body(static_cast<int>(b), work_[k].R_NB.transpose() * work_[k].w_NB_N, q_N[k]);
  }
  for (const Node& n : nodes_) {
    if (n.type == JointType::Revolute) out.revolute(n.joint, x[n.q0], u[n.u0]);
    if (n.type == JointType::Spherical)
      out.spherical(n.joint, Vector3d(u[n.u0], u[n.u0 + 1], u[n.u0 + 2]));
  }
  const Vector3d H = sum_angular_momentum();
  const double T = sum_kinetic_energy(), V = potential_energy(x);
  const Vector3d P = sum_linear_momentum();
  out.momentum(H.norm());
  out.energy(T + V);
  int c = extra0_;
  out.extra(c++, T);
  out.extra(c++, V);
  for (int i = 0; i < 3; ++i) out.extra(c++, H(i));
  for (int i = 0; i < 3; ++i) out.extra(c++, P(i));
  out.extra(c++, quat_err);
}

}  // namespace crossdyn::kane
