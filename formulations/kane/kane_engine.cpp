// Kane's method for a tree of rigid bodies: the passes declared in kane_engine.hpp.
#include "formulations/kane/kane_engine.hpp"

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/scene/topology.hpp"
#include "core/rotation.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <string>

namespace crossdyn::kane {

namespace {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

std::string where(const System& s) { return s.file.empty() ? "scene '" + s.name + "'" : s.file; }

// Rotation matrix of a rotation about the unit vector k by the angle whose half has sine sh and
// cosine ch (Rodrigues' formula, the "simple rotation" of [KLL] Ch. 1):
// R = I + sin(a) [k x] + (1 - cos(a)) [k x]^2, with sin(a) = 2 sh ch and 1 - cos(a) = 2 sh^2
// (the half angle is what the attitude quaternion (ch, sh k) of output_row needs; 2 sh^2 also
// keeps 1 - cos(a) accurate at small angles).
Matrix3d axis_angle_matrix(const Vector3d& k, double sh, double ch) {
  const double s = 2.0 * sh * ch, v = 2.0 * sh * sh, c = 1.0 - v;
  Matrix3d R;
  R << c + v * k.x() * k.x(), v * k.x() * k.y() - s * k.z(), v * k.x() * k.z() + s * k.y(),
      v * k.y() * k.x() + s * k.z(), c + v * k.y() * k.y(), v * k.y() * k.z() - s * k.x(),
      v * k.z() * k.x() - s * k.y(), v * k.z() * k.y() + s * k.x(), c + v * k.z() * k.z();
  return R;
}

// q (x) (c, s e_i): the Hamilton product of q with the quaternion of a rotation about the
// coordinate axis e_i (i = 0, 1, 2; c, s the cosine and sine of half its angle), as
// c q + s q (x) (0, e_i) with q (x) (0, e_x) = (-x, w, z, -y), q (x) (0, e_y) = (-y, -z, w, x),
// q (x) (0, e_z) = (-z, y, -x, w) (scalar first): 8 products instead of the general 16.
Quaterniond times_axis_rotation(const Quaterniond& q, int i, double c, double s) {
  const double w = q.w(), x = q.x(), y = q.y(), z = q.z();
  switch (i) {
    case 0:
      return Quaterniond(c * w - s * x, c * x + s * w, c * y + s * z, c * z - s * y);
    case 1:
      return Quaterniond(c * w - s * y, c * x - s * z, c * y + s * w, c * z + s * x);
    default:
      return Quaterniond(c * w - s * z, c * x + s * y, c * y - s * x, c * z + s * w);
  }
}

// The symmetric inertia matrices below are formed entry by entry on the lower triangle and
// mirrored (J_ji = J_ij): half the products of the full matrix expressions, no temporaries.

// acc = v (the sum's first term: 0 + v = v exactly, so no accumulator needs zeroing) or acc += v.
template <class T, class V>
void put(bool first, T& acc, const V& v) {
  if (first)
    acc = v;
  else
    acc += v;
}

// Inertia about a point O of a mass m whose centre is at d from O, plus its central inertia:
// J = I + m (|d|^2 1 - d d^T)  (the parallel-axis or transfer theorem for inertia dyadics).
// Adds J to acc (first: acc = J).
void add_shifted_inertia(Matrix3d& acc, const Matrix3d& I, double m, const Vector3d& d,
                         bool first) {
  const double md2 = m * d.squaredNorm();
  for (int j = 0; j < 3; ++j)
    for (int i = j; i < 3; ++i) {
      const double v = I(i, j) - m * d(i) * d(j) + (i == j ? md2 : 0.0);
      put(first, acc(i, j), v);
      if (i != j) acc(j, i) = acc(i, j);
    }
}

// The first moment s about O of a mass m moved to the point O' = O - e:  s' = s + m e, and its
// inertia J_O' = J_O + (2 s.e + m |e|^2) 1 - s e^T - e s^T - m e e^T (the transfer theorem for
// a mass distribution whose centre is not at O; [KLL] Sec. 3.4).  Adds J_O' to acc (first:
// acc = J_O').
void add_moved_inertia(Matrix3d& acc, const Matrix3d& J, double m, const Vector3d& s,
                       const Vector3d& e, bool first) {
  const double c = 2.0 * s.dot(e) + m * e.squaredNorm();
  for (int j = 0; j < 3; ++j)
    for (int i = j; i < 3; ++i) {
      const double v =
          J(i, j) - s(i) * e(j) - e(i) * s(j) - m * e(i) * e(j) + (i == j ? c : 0.0);
      put(first, acc(i, j), v);
      if (i != j) acc(j, i) = acc(i, j);
    }
}

// I_N = R I_B R^T for a symmetric I_B (the inertia matrix for N axes, [KLL] Ch. 3, as
// position_pass formed it before), formed on the lower triangle and mirrored: with A = R I_B
// (for an I_B diagonal in B, column j of R times I_jj), I_N,ij = sum_l A_il R_jl.  27
// (diagonal: 9) + 18 products instead of the 54 of the two full matrix products.
void rotate_inertia(Matrix3d& I_N, const Matrix3d& R, const Matrix3d& I_B, bool diagonal) {
  Matrix3d A;
  if (diagonal)
    for (int j = 0; j < 3; ++j) A.col(j) = R.col(j) * I_B(j, j);
  else
    A.noalias() = R * I_B;
  for (int j = 0; j < 3; ++j)
    for (int i = j; i < 3; ++i) {
      const double v = A(i, 0) * R(j, 0) + A(i, 1) * R(j, 1) + A(i, 2) * R(j, 2);
      I_N(i, j) = v;
      if (i != j) I_N(j, i) = v;
    }
}

// sum_l A.col(l) c[l] for a 3 x n matrix and n coefficients (explicit loop: no temporaries).
Vector3d combine(const Eigen::Matrix3Xd& A, const double* c) {
  Vector3d v = Vector3d::Zero();
  for (Eigen::Index l = 0; l < A.cols(); ++l) v += A.col(l) * c[l];
  return v;
}

// 1 / k! for k = 0..27 (power series of NodeRotation).
struct InverseFactorials {
  double v[28];
  InverseFactorials() {
    v[0] = 1;
    for (int k = 1; k < 28; ++k) v[k] = v[k - 1] / k;
  }
};
const InverseFactorials kInvFact;

// g = G eta and 1/2 eta^T G eta (explicit loops: no temporaries).  Geometric stiffening's
// second-order displacement e (1/2 eta^T G eta) (docs/flexible-bodies.md; [KRB] Eq. (8)).
double stiff_g(const Eigen::MatrixXd& G, const double* eta, Eigen::VectorXd& g) {
  double q = 0;
  for (Eigen::Index k = 0; k < G.rows(); ++k) {
    double v = 0;
    for (Eigen::Index l = 0; l < G.cols(); ++l) v += G(k, l) * eta[l];
    g(k) = v;
    q += eta[k] * v;
  }
  return 0.5 * q;
}

// eta'^T G eta' (the second-order displacement's acceleration at eta'' = 0:
// d2/dt2 (1/2 eta^T G eta) = eta^T G eta'' + eta'^T G eta').
double stiff_quad(const Eigen::MatrixXd& G, const double* v) {
  double q = 0;
  for (Eigen::Index k = 0; k < G.rows(); ++k)
    for (Eigen::Index l = 0; l < G.cols(); ++l) q += v[k] * G(k, l) * v[l];
  return q;
}

bool all_zero(const Eigen::Matrix3Xd& A) { return A.size() == 0 || A.cwiseAbs().maxCoeff() == 0; }

}  // namespace

// ------------------------------------------------------------------------------------------------
// exp([psi x]) and the left Jacobian (kane_engine.hpp, NodeRotation; [Barfoot] Sec. 7.1.5).
//   a(t) = (1 - cos t)/t^2 = sum_k (-1)^k t^2k / (2k+2)!,  b(t) = (t - sin t)/t^3 = sum_k (-1)^k
//   t^2k / (2k+3)!,  a1 = a'(t)/t = (t sin t - 2 (1 - cos t))/t^4,  b1 = b'(t)/t =
//   (t (1 - cos t) - 3 (t - sin t))/t^5;  the series (t < 1, twelve terms: the next is below
//   1e-24) avoid the cancellation of the closed forms at small t.

void NodeRotation::set(const Vector3d& rotation_vector) {
  psi = rotation_vector;
  const double x = psi.squaredNorm();
  if (x < 1.0) {
    a = b = a1 = b1 = 0;
    double p = 1.0;  // (-x)^k
    for (int k = 0; k < 12; ++k) {
      a += p * kInvFact.v[2 * k + 2];
      b += p * kInvFact.v[2 * k + 3];
      // a1, b1: sum_{k>=1} -2k (-x)^(k-1) / (2k+2)!, / (2k+3)!
      a1 -= 2.0 * (k + 1) * p * kInvFact.v[2 * k + 4];
      b1 -= 2.0 * (k + 1) * p * kInvFact.v[2 * k + 5];
      p *= -x;
    }
  } else {
    const double t = std::sqrt(x), c = std::cos(t), sn = std::sin(t);
    a = (1.0 - c) / x;
    b = (t - sn) / (x * t);
    a1 = (t * sn - 2.0 * (1.0 - c)) / (x * x);
    b1 = (t * (1.0 - c) - 3.0 * (t - sn)) / (x * x * t);
  }
}

Matrix3d NodeRotation::R() const {
  const Matrix3d S = rot::skew(psi);
  Matrix3d R = (1.0 - psi.squaredNorm() * b) * S + a * S * S;  // sin t / t = 1 - t^2 b
  R.diagonal().array() += 1.0;
  return R;
}

Matrix3d NodeRotation::Jl() const {
  const Matrix3d S = rot::skew(psi);
  Matrix3d J = a * S + b * S * S;
  J.diagonal().array() += 1.0;
  return J;
}

// d/dt [a [psi x] + b [psi x]^2] psi' with a' = a1 (psi . psi'), b' = b1 (psi . psi') and
// psi' x psi' = 0:  a1 s (psi x psi') + b1 s psi x (psi x psi') + b psi' x (psi x psi').
Vector3d NodeRotation::Jl_dot_times(const Vector3d& psi_rate) const {
  const double s = psi.dot(psi_rate);
  const Vector3d c = psi.cross(psi_rate);
  return (a1 * s) * c + (b1 * s) * psi.cross(c) + b * psi_rate.cross(c);
}

namespace {

// Validates one flexible body and builds its modal integrals (kane_engine.hpp, FlexModel).
FlexModel build_flex_model(const Body& B, const std::string& file, double inertia_scale) {
  const FlexBody& fb = *B.flex;
  const std::string where_b = file + ": body '" + B.name + "'";
  const int n = fb.modes();
  const Eigen::Index ni = n;
  if (fb.nodes.empty()) throw InputError(where_b + ": a flexible body needs at least one node");
  auto check_matrix = [&](const Eigen::MatrixXd& M, const char* key, bool may_be_empty) {
    if (may_be_empty && M.size() == 0) return;
    if (M.rows() != ni || M.cols() != ni)
      throw InputError(where_b + ": " + key + " is " + std::to_string(M.rows()) + " x " +
                       std::to_string(M.cols()) + ", the body has " + std::to_string(n) + " modes");
    if (!M.allFinite()) throw InputError(where_b + ": " + key + " has a non-finite entry");
    if ((M - M.transpose()).cwiseAbs().maxCoeff() > 1e-12 * M.cwiseAbs().maxCoeff())
      throw InputError(where_b + ": " + key + " is not symmetric");
  };
  check_matrix(fb.K, "K (modal stiffness)", n == 0);
  check_matrix(fb.D, "D (modal damping)", true);

  FlexModel F;
  F.n = n;
  F.c0.setZero();
  F.I0.setZero();
  F.S = Eigen::Matrix3Xd::Zero(3, ni);
  F.Hs = Eigen::Matrix3Xd::Zero(3, ni);
  F.G.assign(static_cast<std::size_t>(n), Matrix3d::Zero());
  F.Q.assign(static_cast<std::size_t>(n * n), Matrix3d::Zero());
  F.C.assign(static_cast<std::size_t>(n * n), Vector3d::Zero());
  F.Mm = Eigen::MatrixXd::Zero(ni, ni);
  F.K = fb.K.size() ? Eigen::MatrixXd(0.5 * (fb.K + fb.K.transpose()))
                    : Eigen::MatrixXd::Zero(ni, ni);
  F.D = fb.D.size() ? Eigen::MatrixXd(0.5 * (fb.D + fb.D.transpose()))
                    : Eigen::MatrixXd::Zero(ni, ni);
  // The body's mass matrix at eta = 0 in body-frame speeds (v_Bo, w, eta'): every node moves
  // with v - [r_i x] w + Phi_i eta' (the singularity check below).
  Eigen::MatrixXd Mb = Eigen::MatrixXd::Zero(6 + ni, 6 + ni);
  Matrix3d Jsum = Matrix3d::Zero();
  for (const FlexNode& nd : fb.nodes) {
    const std::string where_n = where_b + ", node '" + nd.name + "'";
    if (!std::isfinite(nd.mass) || nd.mass < 0)
      throw InputError(where_n + ": mass must be finite and not negative");
    if (!nd.p_BoNi_B.allFinite() || !nd.J_Ni_B.allFinite())
      throw InputError(where_n + ": position and inertia must be finite");
    if ((nd.J_Ni_B - nd.J_Ni_B.transpose()).cwiseAbs().maxCoeff() >
        1e-12 * (1.0 + nd.J_Ni_B.cwiseAbs().maxCoeff()))
      throw InputError(where_n + ": its rotational inertia is not symmetric");
    for (const Eigen::Matrix3Xd* M : {&nd.Phi_B, &nd.Psi_B}) {
      const char* what = M == &nd.Phi_B ? "mode shapes" : "mode slopes";
      if (M->cols() != ni && !(M->cols() == 0))
        throw InputError(where_n + ": " + what + " have " + std::to_string(M->cols()) +
                         " columns, the body has " + std::to_string(n) + " modes");
      if (!M->allFinite()) throw InputError(where_n + ": " + what + " must be finite");
    }
    const double m = nd.mass;
    const Vector3d& p = nd.p_BoNi_B;
    const Eigen::Matrix3Xd Phi = nd.Phi_B.cols() ? nd.Phi_B : Eigen::Matrix3Xd::Zero(3, ni);
    F.mass += m;
    F.c0 += m * p;
    Jsum += 0.5 * (nd.J_Ni_B + nd.J_Ni_B.transpose());
    F.I0 += m * (p.squaredNorm() * Matrix3d::Identity() - p * p.transpose());
    F.S += m * Phi;
    for (int k = 0; k < n; ++k) {
      F.Hs.col(k) += m * p.cross(Phi.col(k));
      F.G[static_cast<std::size_t>(k)] += m * p * Phi.col(k).transpose();
      for (int l = 0; l < n; ++l) {
        F.Q[static_cast<std::size_t>(k * n + l)] += m * Phi.col(k) * Phi.col(l).transpose();
        F.C[static_cast<std::size_t>(k * n + l)] += m * Phi.col(k).cross(Phi.col(l));
        F.Mm(k, l) += m * Phi.col(k).dot(Phi.col(l));
      }
    }
    if (fb.geometric_stiffening) {
      FlexModel::StiffNode sn;
      sn.m = m;
      sn.p = p;
      sn.Phi = Phi;
      sn.e = nd.e_B;
      sn.G = nd.G.size() ? nd.G : Eigen::MatrixXd::Zero(ni, ni);
      if (sn.G.rows() != ni || sn.G.cols() != ni || !sn.G.allFinite() || !sn.e.allFinite())
        throw InputError(where_n + ": geometric stiffening needs a finite e and an n x n G (" +
                         std::to_string(n) + " modes)");
      const double g_max = sn.G.cwiseAbs().maxCoeff();
      if ((sn.G - sn.G.transpose()).cwiseAbs().maxCoeff() > 1e-12 * (1.0 + g_max))
        throw InputError(where_n + ": G is not symmetric");
      sn.G = 0.5 * (sn.G + sn.G.transpose());
      F.sn.push_back(std::move(sn));
    }
    Eigen::Matrix<double, 3, Eigen::Dynamic> V(3, 6 + ni);
    V.leftCols<3>().setIdentity();
    V.middleCols<3>(3) = -rot::skew(p);
    V.rightCols(ni) = Phi;
    Mb.noalias() += m * V.transpose() * V;
  }
  Mb.block<3, 3>(3, 3) += Jsum;
  if (!(F.mass > 0)) throw InputError(where_b + ": the node masses sum to zero");
  F.stiff = fb.geometric_stiffening;
  // The model's rigid mass and inertia are the node sums (docs/flexible-bodies.md); the System's
  // Body::mass and I_BBo_B must say the same.
  const Matrix3d I_nodes = Jsum + F.I0;
  if (std::abs(B.mass - F.mass) > 1e-9 * F.mass)
    throw InputError(where_b + ": mass " + std::to_string(B.mass) +
                     " kg differs from the sum of its node masses " + std::to_string(F.mass) +
                     " kg");
  if ((B.I_BBo_B - I_nodes).cwiseAbs().maxCoeff() > 1e-9 * I_nodes.cwiseAbs().maxCoeff())
    throw InputError(
        where_b + ": inertia differs from the node sum sum_i (J_i + m_i (|p_i|^2 1 - p_i p_i^T))");
  F.I0 = inertia_scale * I_nodes;
  for (int k = 0; k < n; ++k)
    if (!(F.Mm(k, k) > 0))
      throw InputError(where_b + ": mode '" + fb.mode_names[static_cast<std::size_t>(k)] +
                       "' moves no mass (sum_i m_i |Phi_ik|^2 = 0): its modal mass is zero");
  // Positive definite with the diagonal scaled to one: otherwise some mode is a rigid-body motion
  // or a combination of other modes, or the rigid inertia is singular, and Kane's mass matrix is
  // singular.
  const Eigen::VectorXd d = Mb.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd Ms = d.asDiagonal() * Mb * d.asDiagonal();
  const double lmin = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Ms).eigenvalues().minCoeff();
  if (!(lmin > 1e-12))
    throw InputError(
        where_b +
        ": the node masses cannot tell the modes and the rigid motions apart (the "
        "body's mass matrix at eta = 0 is singular: a mode is a rigid-body motion or a "
        "combination of other modes, or the rigid inertia is singular)");
  return F;
}

}  // namespace

// ------------------------------------------------------------------------------------------------
// Construction: validate the tree, build the node tables, size the workspace.

KaneEngine::KaneEngine(const System& system, const EngineOptions& options, KaneSolver solver)
    : system_(system), layout_(system_) {
  const std::string file = where(system_);
  const std::size_t nj = system_.joints.size(), nb = system_.bodies.size();
  // The tree (one free joint first, every parent the child of an earlier joint, one joint per
  // body, indices in range): the one public check, core/scene/topology.hpp.
  check_topology(system_);
  if (!(options.test_inertia_scale > 0) || !std::isfinite(options.test_inertia_scale))
    throw InputError("engine option test_inertia_scale must be positive and finite");

  // Flexible bodies: validated, modal integrals built once.
  std::vector<int> flex_of_body(nb, -1);
  for (std::size_t b = 0; b < nb; ++b) {
    const Body& B = system_.bodies[b];
    if (!B.flex) continue;
    flex_of_body[b] = static_cast<int>(flex_.size());
    flex_.push_back(build_flex_model(B, file, options.test_inertia_scale));
  }

  nodes_.resize(nj);
  std::vector<int> node_of_body(nb, -1);
  int nq = 0, nu = 0;
  for (std::size_t k = 0; k < nj; ++k) {
    cancel::poll();
    const Joint& J = system_.joints[k];
    Node& n = nodes_[k];
    const std::string jname = file + ": joint '" + J.name + "'";
    n.type = J.type;
    n.joint = static_cast<int>(k);
    n.body = J.child;
    if (k > 0) n.parent = node_of_body[static_cast<std::size_t>(J.parent)];
    node_of_body[static_cast<std::size_t>(J.child)] = static_cast<int>(k);
    const Body& B = system_.bodies[static_cast<std::size_t>(J.child)];
    if (!(B.mass > 0) || !std::isfinite(B.mass))
      throw InputError(file + ": body '" + B.name + "': mass must be positive");
    n.flex = flex_of_body[static_cast<std::size_t>(J.child)];
    n.mass = n.flex >= 0 ? flex_[static_cast<std::size_t>(n.flex)].mass : B.mass;
    n.I_BBo_B = options.test_inertia_scale * 0.5 * (B.I_BBo_B + B.I_BBo_B.transpose());
    n.q_PJ0 = J.q_PJ0.normalized();
    n.R_PJ0 = n.q_PJ0.toRotationMatrix();
    n.has_offset = !n.R_PJ0.isIdentity(0.0);
    n.p_PoJ_P = J.p_PoJ_P;
    n.p_CoJ_C = J.p_CoJ_C;
    n.body_torque = !B.torque.empty();
    n.hinge_load = J.stiffness != 0 || J.damping != 0 || !J.motor_revolute.empty() ||
                   !J.motor_spherical.empty();
    if (n.flex < 0) {
      const Matrix3d& I = n.I_BBo_B;
      if (I(1, 0) == 0 && I(2, 0) == 0 && I(2, 1) == 0)
        n.inertia = I(0, 0) == I(1, 1) && I(1, 1) == I(2, 2) ? Node::Inertia::Isotropic
                                                              : Node::Inertia::Diagonal;
    }
    if (J.type == JointType::Revolute) {
      if (!(J.axis_P.norm() > 0)) throw InputError(jname + ": revolute axis must be non-zero");
      n.axis_P = J.axis_P.normalized();
      n.axis_J = n.R_PJ0.transpose() * n.axis_P;
      for (int i = 0; i < 3; ++i) {
        const int j = (i + 1) % 3, l = (i + 2) % 3;
        if (std::abs(n.axis_J(i)) == 1.0 && n.axis_J(j) == 0 && n.axis_J(l) == 0) {
          n.axis_index = i;
          n.axis_sign = n.axis_J(i);
        }
      }
      if (J.prescribed) {  // docs/prescribed-motion.md: not a degree of freedom
        n.prescribed = true;
        n.motion = *J.prescribed;
        n.angle0 = J.angle0;
        has_prescribed_ = true;
      }
    }

    // Attachment at nodes of flexible bodies (docs/flexible-bodies.md "Joints at nodes").
    auto attach = [&](int body, int node, const Eigen::Vector3d& point, const char* side,
                      Eigen::Matrix3Xd& Phi, Eigen::Matrix3Xd& Psi, bool& stiff,
                      Eigen::Vector3d& e, Eigen::MatrixXd& G) -> bool {
      const Body& A = system_.bodies[static_cast<std::size_t>(body)];
      if (node < 0) {
        if (A.flex) {  // attached to the body frame itself: no shape, no slope
          Phi = Eigen::Matrix3Xd::Zero(3, A.flex->modes());
          Psi = Phi;
        }
        return false;
      }
      if (!A.flex)
        throw InputError(jname + ": " + side + "_node is set but body '" + A.name + "' is rigid");
      if (node >= static_cast<int>(A.flex->nodes.size()))
        throw InputError(jname + ": " + side + "_node " + std::to_string(node) + " of body '" +
                         A.name + "' does not exist (it has " +
                         std::to_string(A.flex->nodes.size()) + " nodes)");
      const FlexNode& fn = A.flex->nodes[static_cast<std::size_t>(node)];
      if ((point - fn.p_BoNi_B).norm() > 1e-9 * (1.0 + fn.p_BoNi_B.norm()))
        throw InputError(jname + ": " + side + "_point differs from the position of node '" +
                         fn.name + "' of body '" + A.name + "'");
      const Eigen::Index m = A.flex->modes();
      Phi = fn.Phi_B.cols() ? fn.Phi_B : Eigen::Matrix3Xd::Zero(3, m);
      Psi = fn.Psi_B.cols() ? fn.Psi_B : Eigen::Matrix3Xd::Zero(3, m);
      // Geometric stiffening: the node also moves by e (1/2 eta^T G eta) (docs "Joints at nodes").
      stiff = A.flex->geometric_stiffening && fn.G.size() > 0 && fn.G.cwiseAbs().maxCoeff() > 0 &&
              fn.e_B.squaredNorm() > 0;
      if (stiff) {
        e = fn.e_B;
        G = 0.5 * (fn.G + fn.G.transpose());
      }
      // a node that never moves: rigid attachment
      return stiff || !(all_zero(Phi) && all_zero(Psi));
    };
    if (k > 0) {
      n.parent_attach = attach(J.parent, J.parent_node, J.p_PoJ_P, "parent", n.Phi_Pj, n.Psi_Pj,
                               n.stiff_P, n.e_Pj, n.G_Pj);
      n.pm = static_cast<int>(n.Phi_Pj.cols());
    } else if (J.parent_node >= 0) {
      throw InputError(jname + ": the free joint has no parent body, so no parent_node");
    }
    n.child_attach = attach(J.child, J.child_node, J.p_CoJ_C, "child", n.Phi_Cj, n.Psi_Cj,
                            n.stiff_C, n.e_Cj, n.G_Cj);
    if (k == 0 && J.type == JointType::Free && J.child_node >= 0)
      throw InputError(jname +
                       ": the free joint moves the base's body frame; child_node must "
                       "not be set");
    if (n.parent_attach)
      nodes_[static_cast<std::size_t>(n.parent)].attached_children.push_back(static_cast<int>(k));

    switch (J.type) {
      case JointType::Free:
        n.nqj = 7;
        n.nuj = 6;
        break;
      case JointType::Revolute:
        n.nqj = n.prescribed ? 0 : 1;
        n.nuj = n.prescribed ? 0 : 1;
        break;
      case JointType::Spherical:
        n.nqj = 4;
        n.nuj = 3;
        break;
      case JointType::Fixed:
        n.nqj = 0;
        n.nuj = 0;
        break;
    }
    n.nm = n.flex >= 0 ? flex_[static_cast<std::size_t>(n.flex)].n : 0;
    n.q0 = nq;
    n.u0 = nu;
    n.nq = n.nqj + n.nm;
    n.nu = n.nuj + n.nm;
    nq += n.nq;
    nu += n.nu;
    for (int a = n.parent, via = static_cast<int>(k); a >= 0;
         via = a, a = nodes_[static_cast<std::size_t>(a)].parent)
      if (nodes_[static_cast<std::size_t>(a)].nu > 0) n.speed_ancestors.push_back({a, via});
    total_mass_ += n.mass;
  }
  n_q_ = nq;
  n_u_ = nu;
  // subtree_pass's first terms: visiting nodes last first, the first child to reach a parent is
  // its highest-index one; a node no child reaches starts with its own body.
  for (std::size_t k = nj; k-- > 1;) {
    Node& p = nodes_[static_cast<std::size_t>(nodes_[k].parent)];
    nodes_[k].parent_start = p.sums_start;
    p.sums_start = false;
  }
  for (Node& n : nodes_) {
    n.leaf_rigid = n.sums_start && n.flex < 0 && n.parent >= 0 && !n.parent_attach;
    n.parent_free_base = n.parent >= 0 && nodes_[static_cast<std::size_t>(n.parent)].type == JointType::Free;
  }

  // State labels.
  labels_.assign(static_cast<std::size_t>(n_q_ + n_u_), "");
  for (const Node& n : nodes_) {
    const Body& body = system_.bodies[static_cast<std::size_t>(n.body)];
    const std::string& b = body.name;
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
        if (n.prescribed) break;
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
    for (int l = 0; l < n.nm; ++l) {
      const std::string mode = b + "." + body.flex->mode_names[static_cast<std::size_t>(l)];
      put(n.q0 + n.nqj + l, mode);
      put(n_q_ + n.u0 + n.nuj + l, mode + "_rate");
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
  prescribed_torque_.assign(nj, 0.0);
  for (NodeWork* w : {&ground_}) {
    w->R_NB.setIdentity();
    w->I_BBo_N.setZero();
    w->W_N.setZero();
    for (Vector3d* v : {&w->p_B0oBo_N, &w->p_B0oOk_N, &w->p_PoOk_N, &w->p_OkBo_N, &w->w_NB_N, &w->v_NBo_N, &w->w_NB_B,
                        &w->w_PC_N, &w->w_NJp_N, &w->alpha_t_N, &w->a_t_N, &w->alpha_N, &w->a_N})
      v->setZero();
  }
  for (std::size_t k = 0; k < nj; ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    w.R_NB.setIdentity();
    // An isotropic rigid body's inertia has the same components in every frame (position_pass
    // does not touch it).
    if (n.flex < 0 && n.inertia == Node::Inertia::Isotropic)
      w.I_BBo_N = n.I_BBo_B;
    else
      w.I_BBo_N.setZero();
    w.W_N.setZero();
    w.p_B0oBo_N.setZero();
    w.p_B0oOk_N.setZero();
    w.p_PoOk_N.setZero();
    w.p_OkBo_N.setZero();
    w.w_NB_N.setZero();
    w.w_NB_B.setZero();
    w.v_NBo_N.setZero();
    w.w_PC_N.setZero();
    w.w_NJp_N.setZero();
    w.alpha_t_N.setZero();
    w.a_t_N.setZero();
    w.alpha_N.setZero();
    w.a_N.setZero();
    w.m_sub = 0;
    w.s_sub_N.setZero();
    w.J_sub_N.setZero();
    w.F_sub_N.setZero();
    w.M_sub_N.setZero();
    const Eigen::Index pm = n.parent_attach ? n.pm : 0, nm = n.child_attach ? n.nm : 0;
    w.Wp_N = Eigen::Matrix3Xd::Zero(3, pm);
    w.Vp_N = Eigen::Matrix3Xd::Zero(3, pm);
    w.pp_N = Eigen::Matrix3Xd::Zero(3, pm);
    w.hp_N = Eigen::Matrix3Xd::Zero(3, pm);
    w.Wm_N = Eigen::Matrix3Xd::Zero(3, nm);
    w.Vm_N = Eigen::Matrix3Xd::Zero(3, nm);
    for (Vector3d* v : {&w.w_att_N, &w.v_att_N, &w.jdot_att_N, &w.w_m_N, &w.v_m_N, &w.jdot_m_N})
      v->setZero();
    w.gP = Eigen::VectorXd::Zero(n.stiff_P ? n.pm : 0);
    w.gC = Eigen::VectorXd::Zero(n.stiff_C ? n.nm : 0);
  }
  flex_work_.resize(flex_.size());
  for (std::size_t f = 0; f < flex_.size(); ++f) {
    const Eigen::Index m = flex_[f].n;
    FlexWork& fw = flex_work_[f];
    fw.c_B.setZero();
    fw.c_N.setZero();
    fw.I_B.setZero();
    for (Eigen::Matrix3Xd* M : {&fw.A_B, &fw.S_N, &fw.A_N, &fw.Ce_B, &fw.pm_N, &fw.hm_N})
      *M = Eigen::Matrix3Xd::Zero(3, m);
    fw.N_B.assign(static_cast<std::size_t>(m), Matrix3d::Zero());
    fw.cdot_N.setZero();
    fw.hdef_N.setZero();
    fw.L_B.setZero();
    const FlexModel& F = flex_[f];
    fw.S_B = F.S;
    fw.Mm = F.Mm;
    fw.bgen = Eigen::VectorXd::Zero(m);
    if (F.stiff) {
      fw.Phit.assign(F.sn.size(), Eigen::Matrix3Xd::Zero(3, m));
      fw.r.assign(F.sn.size(), Vector3d::Zero());
      fw.g.assign(F.sn.size(), Eigen::VectorXd::Zero(m));
    }
  }
  M_ = Eigen::MatrixXd::Zero(n_u_, n_u_);
  f_ = Eigen::VectorXd::Zero(n_u_);
  udot_ = Eigen::VectorXd::Zero(n_u_);
  lambda_.assign(static_cast<std::size_t>(n_u_), -1);
  for (const Node& n : nodes_) {
    if (n.nu == 0) continue;
    int parent_speed = -1;
    if (!n.speed_ancestors.empty()) {
      const Node& a = nodes_[static_cast<std::size_t>(n.speed_ancestors.front().node)];
      parent_speed = a.u0 + a.nu - 1;
    }
    for (int i = 0; i < n.nu; ++i)
      lambda_[static_cast<std::size_t>(n.u0 + i)] = i == 0 ? parent_speed : n.u0 + i - 1;
  }
  q_N_.assign(nj, Quaterniond::Identity());

  // Solver (kane_engine.hpp, "Two solvers"): the speeds on the deepest root-to-leaf path decide.
  std::vector<int> depth(nj, 0);
  for (std::size_t k = 0; k < nj; ++k) {
    const Node& n = nodes_[k];
    depth[k] = n.nu + (n.parent >= 0 ? depth[static_cast<std::size_t>(n.parent)] : 0);
    max_speed_depth_ = std::max(max_speed_depth_, depth[k]);
  }
  const bool rigid = flex_.empty();
  // The order-N solver declines prescribed joints (issue 13): its elimination assumes a free
  // base and a speed for every revolute joint, so a scene with a prescribed joint (inside the
  // tree or as the base) always uses the composite solver, which handles both.
  const bool order_n_ok = rigid && !has_prescribed_ && system_.base_is_free();
  if (solver == KaneSolver::OrderN && rigid && !order_n_ok)
    throw InputError(file + ": the kane engine's order-N solver handles no prescribed joint; use "
                     "the composite solver");
  if (solver == KaneSolver::OrderN && !rigid) {
    std::string flexible;
    for (const Body& b : system_.bodies)
      if (b.flex && flexible.empty()) flexible = b.name;
    throw InputError(file + ": the kane engine's order-N solver handles rigid bodies only (body '" +
                     flexible + "' is flexible); use the composite solver");
  }
  if (solver == KaneSolver::Automatic)
    solver = order_n_ok && max_speed_depth_ >= kOrderNMinDepth ? KaneSolver::OrderN
                                                          : KaneSolver::Composite;
  solver_ = solver;
  rigid_fast_ = solver_ == KaneSolver::Composite && rigid && !has_prescribed_ &&
                system_.base_is_free();
  for (const Joint& J : system_.joints) has_potential_ = has_potential_ || J.stiffness != 0;
  has_potential_ = has_potential_ || !flex_.empty();
  if (solver_ == KaneSolver::OrderN) {
    art_.resize(nj);
    for (ArticulatedWork& a : art_) {
      for (Matrix3d* M : {&a.Iww_N, &a.Iwv_N, &a.Ivv_N, &a.U_M_N, &a.U_F_N, &a.D_inv}) M->setZero();
      for (Vector3d* v : {&a.Z_M_N, &a.Z_F_N, &a.g, &a.dalpha_N, &a.da_Ok_N}) v->setZero();
    }
  }
}

const char* kane_solver_name(KaneSolver s) {
  switch (s) {
    case KaneSolver::Automatic:
      return "automatic";
    case KaneSolver::Composite:
      return "composite";
    case KaneSolver::OrderN:
      return "order-n";
  }
  return "?";
}

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

// ------------------------------------------------------------------------------------------------
// Pass 1. q => R_NB, I_BBo_N, W_N (partial angular velocities), p_B0oBo_N, p_B0oOk_N, and
// at nodes of flexible bodies the twists of the modal speeds.
// Joint kinematics of core/system.hpp and docs/flexible-bodies.md "Joints at nodes":
//   R_NJp = R_NP E_Pj,  R_NJc = R_NJp R_PJ0 R_J,  R_NC = R_NJc E_Cj^T  (E = exp([psi x]));
//   the joint point is common to P and C: p_Ok = p_Po + R_NP r_Pj = p_Co + R_NC r_Cj, r = p + u.
//   Parent side (w_Jp = w_P + Wp eta_P', v_Ok = v_Po + w_P x (p_Ok - p_Po) + Vp eta_P'):
//     Wp = R_NP Jl(psi_Pj) Psi_Pj,  Vp = R_NP Phi_Pj.
//   Child side (w_C = w_Jc + Wm eta_C', v_Co = v_Ok + w_C x (p_Co - p_Ok) + Vm eta_C'):
//     Wm = -R_NC Jl(psi_Cj) Psi_Cj,  Vm = -R_NC Phi_Cj   (kane_engine.hpp, partial velocities).

void KaneEngine::position_pass(const double* x, bool rigid_inertia) {
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    if (n.type == JointType::Free) {
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
      switch (n.type) {
        case JointType::Revolute:
        {
          const double half = 0.5 * (n.prescribed ? w.pres_angle : x[n.q0]);
          const double sh = std::sin(half), ch = std::cos(half);  // one sincos
          w.sin_half = sh;
          w.cos_half = ch;
          if (n.axis_index >= 0) {
            // axis_J = sign e_i: R_J e_i = e_i, and with (i, j, l) cyclic R_J e_j = c e_j + s e_l,
            // R_J e_l = c e_l - s e_j (Rodrigues' formula above with [e_i x] e_j = e_l, s =
            // sign sin(a), c = cos(a) = 1 - 2 sh^2), so R_NJ0 R_J turns two columns of R_NJ0.
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
        case JointType::Spherical:
          R_NJc.noalias() = *R_NJ0 * read_quat(x, n.q0).toRotationMatrix();
          w.W_N = R_NJc;  // W_r = j_r for u_r = w_PC,r in Jc components
          break;
        default:
          R_NJc = *R_NJ0;
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

// Flexible body at eta => FlexWork (body frame, then N), I_BBo_N (kane_engine.hpp):
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
//   v_Ok = v_Po + w_P x p_PoOk + Vp eta_P';  v_Co = v_Ok + w_C x p_OkCo + Vm eta_C'
//   (a point fixed on, or moving in, a rigid frame, [KLL] Secs. 1.17-1.18).
//   Node-frame rates: psi' = Psi eta', and (d/dt Jl) psi' for the remainder pass.

void KaneEngine::velocity_pass(const double* u) {
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    if (n.type == JointType::Free) {
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
      switch (n.type) {
        case JointType::Revolute:  // a prescribed joint: its rate theta'(t)
          w.w_PC_N = w.W_N.col(0) * (n.prescribed ? w.pres_rate : u[n.u0]);
          break;
        case JointType::Spherical:
          w.w_PC_N.noalias() = w.W_N * Eigen::Map<const Vector3d>(u + n.u0);
          break;
        default:
          w.w_PC_N.setZero();
          break;
      }
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
    if (n.type == JointType::Free) {
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
    if (n.flex < 0 && n.type == JointType::Free) {
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
          T_B.noalias() -= w.w_NB_N.cross(w.I_BBo_N * w.w_NB_N);
      }
      if (n.body_torque) add_body_torque(n, w, t, T_B);
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
      T_B = -c.cross(a_t) - w.I_BBo_N * alpha_t - wN.cross(w.I_BBo_N * wN) -
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
  return -(w.I_BBo_N * alpha) - w.w_NB_N.cross(w.I_BBo_N * w.w_NB_N);
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
//   Base block: M(w, w) = R^T J_0 R;  M(v_i, w_j) = n_i . (b_j x s_0);  M(v, v) = m 1.

// One ancestor's joint-speed entries of row r (above: a joint's W . h_a; a free base's R^T h_a
// and p), returning h_a = h + (p_k - p_a) x p, the momentum moment about the ancestor's point.
inline Vector3d KaneEngine::mass_matrix_ancestor_joint(const NodeWork& w,
                                                       const Node::Ancestor& an, int r,
                                                       const Vector3d& p, const Vector3d& h) {
  const Node& A = nodes_[static_cast<std::size_t>(an.node)];
  const NodeWork& wa = work_[static_cast<std::size_t>(an.node)];
  const Vector3d h_a = h + (w.p_B0oOk_N - wa.p_B0oOk_N).cross(p);
  if (A.type == JointType::Free) {
    M_.block<1, 3>(r, A.u0).noalias() = (wa.R_NB.transpose() * h_a).transpose();
    M_.block<1, 3>(r, A.u0 + 3) = p.transpose();
  } else {
    for (int j = 0; j < A.nuj; ++j) M_(r, A.u0 + j) = wa.W_N.col(j).dot(h_a);
  }
  return h_a;
}

// J_k W: the subtree's inertia about Ok times W; for a rigid leaf (S(k) is the body alone, J_k
// never formed) J_k W = I W + m (|d|^2 W - d (d . W)) = I W + m d x (W x d), d = p_OkBo_N.
inline Vector3d KaneEngine::subtree_inertia_times(const Node& n, const NodeWork& w,
                                                  const Vector3d& W) const {
  if (!n.leaf_rigid) return w.J_sub_N * W;
  const Vector3d& d = w.p_OkBo_N;
  Vector3d h = n.mass * d.cross(W.cross(d));
  if (n.inertia == Node::Inertia::Isotropic)
    h += n.I_BBo_B(0, 0) * W;
  else
    h.noalias() += w.I_BBo_N * W;
  return h;
}

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
  if (nodes_[0].type == JointType::Free) {
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
        const Vector3d p_r = W_r.cross(w.s_sub_N);
        const Vector3d h_r = subtree_inertia_times(n, w, W_r);
        for (int j = 0; j <= i; ++j) M_(r, n.u0 + j) = w.W_N.col(j).dot(h_r);
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
      if (n.type == JointType::Free) {
        M_.block<1, 3>(r, n.u0).noalias() = (w.R_NB.transpose() * h).transpose();
        M_.block<1, 3>(r, n.u0 + 3) = p.transpose();
      } else {
        for (int j = 0; j < n.nuj; ++j) M_(r, n.u0 + j) = w.W_N.col(j).dot(h);
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

// ------------------------------------------------------------------------------------------------
// Pass 6. subtree sums, hinge loads, modal stiffness and damping => f = F_r + F_r*|_{u'=0}.
//   Twist part of speed r: W_r . M_k + V_r . F_k.  Base: f(w) = R_NB^T M_0 (W_r = b_r),
//   f(v) = F_0 (V_r = n_r).  Joint speeds: f_r = W_r . M_k plus the hinge's own spring, damper
//   and motor (the only speeds its action-reaction pair works on, kane_engine.hpp).
//   Modal speed l of C, elastic part (paper Eq. (40), [KRB]):
//     g_l = sum_i R Phi_il . (-m_i a_t,i) = -(S_l . a_B + alpha_B . A_l + w_B^T N_l w_B
//           - |w_B|^2 tr N_l + 2 w_B . Ce_l)   (body components of a_t, alpha_t, w)
//     plus Wp_c,l . M_c + Vp_c,l . F_c for every attached child c, and -(K eta + D eta')_l
//     (the generalised active forces of the strain energy and the modal damping, [KLL] Ch. 4).

double KaneEngine::hinge_torque_revolute(const Node& n, double t, const double* x) const {
  if (!n.hinge_load) return 0;
  const Joint& J = system_.joints[static_cast<std::size_t>(n.joint)];
  double tau = 0;
  if (J.stiffness != 0) tau -= J.stiffness * (x[n.q0] - J.neutral_angle);
  if (J.damping != 0) tau -= J.damping * x[n_q_ + n.u0];
  if (!J.motor_revolute.empty()) tau += J.motor_revolute.value(t)(0);
  return tau;
}

Vector3d KaneEngine::hinge_torque_spherical(const Node& n, double t, const double* x) const {
  if (!n.hinge_load) return Vector3d::Zero();
  const Joint& J = system_.joints[static_cast<std::size_t>(n.joint)];
  Vector3d tau = Vector3d::Zero();
  if (J.stiffness != 0) tau -= J.stiffness * rot::rotation_vector(read_quat(x, n.q0));
  if (J.damping != 0) tau -= J.damping * Eigen::Map<const Vector3d>(x + n_q_ + n.u0);
  if (!J.motor_spherical.empty()) tau += J.motor_spherical.value(t);
  return tau;
}

void KaneEngine::generalized_force_pass(double t, const double* x) {
  const NodeWork& base = work_[0];
  if (nodes_[0].type == JointType::Free) {
    f_.segment<3>(nodes_[0].u0).noalias() = base.R_NB.transpose() * base.M_sub_N;
    f_.segment<3>(nodes_[0].u0 + 3) = base.F_sub_N;
  }
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    const NodeWork& w = work_[k];
    switch (n.type) {
      case JointType::Revolute:
        if (!n.prescribed) f_(n.u0) = w.W_N.col(0).dot(w.M_sub_N) + hinge_torque_revolute(n, t, x);
        break;
      case JointType::Spherical:
        f_.segment<3>(n.u0).noalias() =
            w.W_N.transpose() * w.M_sub_N + hinge_torque_spherical(n, t, x);
        break;
      default:
        break;
    }
    if (n.nm == 0) continue;
    const FlexModel& F = flex_[static_cast<std::size_t>(n.flex)];
    const FlexWork& fw = flex_work_[static_cast<std::size_t>(n.flex)];
    const double* eta = x + n.q0 + n.nqj;
    const double* eta_rate = x + n_q_ + n.u0 + n.nuj;
    const Vector3d a_B = w.R_NB.transpose() * w.a_t_N;
    const Vector3d alpha_B = w.R_NB.transpose() * w.alpha_t_N;
    const Vector3d w_B = w.R_NB.transpose() * w.w_NB_N;
    const double w2 = w_B.squaredNorm();
    for (int l = 0; l < n.nm; ++l) {
      const Matrix3d& N = fw.N_B[static_cast<std::size_t>(l)];
      const Eigen::Matrix3Xd& S = F.stiff ? fw.S_B : F.S;  // S~ with stiffening
      double g = -(S.col(l).dot(a_B) + alpha_B.dot(fw.A_B.col(l)) + w_B.dot(N * w_B) -
                   w2 * N.trace() + 2.0 * w_B.dot(fw.Ce_B.col(l)));
      if (F.stiff) g -= fw.bgen(l);  // -sum m_i Phi~_il . b_i
      if (n.child_attach) g += w.Wm_N.col(l).dot(w.M_sub_N) + w.Vm_N.col(l).dot(w.F_sub_N);
      for (int c : n.attached_children) {
        const NodeWork& cw = work_[static_cast<std::size_t>(c)];
        g += cw.Wp_N.col(l).dot(cw.M_sub_N) + cw.Vp_N.col(l).dot(cw.F_sub_N);
      }
      for (int m = 0; m < n.nm; ++m) g -= F.K(l, m) * eta[m] + F.D(l, m) * eta_rate[m];
      f_(n.u0 + n.nuj + l) = g;
    }
  }
}

// ------------------------------------------------------------------------------------------------
// Pass 7. (M, f) => u'.  Factorisation M = L^T D L (L unit lower triangular, D diagonal) taken
// in reverse order, which keeps the tree's branch-induced sparsity with no fill-in: M_ik != 0
// (k > i) only when i is on the chain i = lambda(k), lambda(lambda(k)), ... of parent speeds
// ([Feath] Sec. 6.5, Table 6.3 "LTDL"; the square-root-free form of the Cholesky factorisation).
// Then u' = L^-1 D^-1 L^-T f (Table 6.4).  M is positive definite exactly when every pivot D_kk
// is positive.  In place: M_ holds L below its diagonal and D on it afterwards (but for a rigid
// base's block on the fixed path, factorised in a local copy).
//
// The base's speeds 0 ... nb-1 (nb = the base node's speed count) are ancestors of every other
// speed and form a dense block; the chain of any other speed ends with nb-1, nb-2, ..., 0.  So
// each chain is walked through lambda down to nb and then over the base block as plain loops:
// the same operations as walking lambda throughout.  For a rigid base (nb = 6, ltdl_solve_base6)
// the base block is held in a local 6 x 6 array with constant loop bounds: it cannot alias H's
// other rows, f or x, so it stays in registers and the loops unroll; a flexible base takes nb at
// run time (ltdl_solve).  Both do the same operations in the same order, so they give the same
// u' (tests/kane).
namespace {

// Eliminates row k against the base block's columns 0..n-1 (all of them ancestors of k):
// a_i = H_ki / H_kk, H_ij -= a_i H_kj (j <= i < n), H_ki = a_i.
void eliminate_base(double* H, Eigen::Index ld, int k, double inv_d, int n) {
  double* Hk = H + k * ld;
  for (int i = n - 1; i >= 0; --i) {
    const double a = Hk[i] * inv_d;
    double* Hi = H + i * ld;
    for (int j = i; j >= 0; --j) Hi[j] -= a * Hk[j];
    Hk[i] = a;
  }
}

bool ltdl_solve(double* H, Eigen::Index ld, const int* lambda, int n, int nb, const double* f,
                double* x) {
  // Speeds above the base block, last first.
  for (int k = n - 1; k >= nb; --k) {
    cancel::poll();
    double* Hk = H + k * ld;
    const double d = Hk[k];
    if (!(d > 0)) return false;
    const double inv_d = 1.0 / d;
    for (int i = lambda[k]; i >= nb; i = lambda[i]) {
      const double a = Hk[i] * inv_d;
      double* Hi = H + i * ld;
      for (int j = i; j >= nb; j = lambda[j]) Hi[j] -= a * Hk[j];
      for (int j = nb - 1; j >= 0; --j) Hi[j] -= a * Hk[j];
      Hk[i] = a;
    }
    eliminate_base(H, ld, k, inv_d, nb);
  }
  // The base block's own factorisation, rows nb-1 ... 0.
  for (int k = nb - 1; k >= 0; --k) {
    const double d = H[k * ld + k];
    if (!(d > 0)) return false;
    eliminate_base(H, ld, k, 1.0 / d, k);
  }
  for (int i = 0; i < n; ++i) x[i] = f[i];
  for (int i = n - 1; i >= nb; --i) {  // L^T z = f
    const double* Hi = H + i * ld;
    const double xi = x[i];
    for (int j = lambda[i]; j >= nb; j = lambda[j]) x[j] -= Hi[j] * xi;
    for (int j = nb - 1; j >= 0; --j) x[j] -= Hi[j] * xi;
  }
  for (int i = nb - 1; i >= 0; --i)
    for (int j = i - 1; j >= 0; --j) x[j] -= H[i * ld + j] * x[i];
  for (int i = 0; i < n; ++i) x[i] /= H[i * ld + i];  // y = D^-1 z
  for (int i = 0; i < nb; ++i)                         // L u' = y
    for (int j = i - 1; j >= 0; --j) x[i] -= H[i * ld + j] * x[j];
  for (int i = nb; i < n; ++i) {
    const double* Hi = H + i * ld;
    double xi = x[i];
    for (int j = lambda[i]; j >= nb; j = lambda[j]) xi -= Hi[j] * x[j];
    for (int j = nb - 1; j >= 0; --j) xi -= Hi[j] * x[j];
    x[i] = xi;
  }
  return true;
}

// The same with nb = 6 and the base block (lower triangle) in the local array b, every loop
// over it of constant length and unrolled (#pragma GCC unroll: GCC and Clang).
using Base6 = double[6][6];

// b_ij -= a_i c_j for 0 <= j <= i < M (a rank-1 update of the lower triangle).
template <int M>
inline void rank1_lower(Base6& b, const double* a, const double* c) {
#pragma GCC unroll 6
  for (int i = 0; i < M; ++i)
#pragma GCC unroll 6
    for (int j = 0; j <= i; ++j) b[i][j] -= a[i] * c[j];
}

// The base block's own factorisation, rows K-1 ... 0.
template <int K>
inline bool factor_base6(Base6& b) {
  if constexpr (K == 0) {
    return true;
  } else {
    const double d = b[K - 1][K - 1];
    if (!(d > 0)) return false;
    const double inv_d = 1.0 / d;
    double c[6], a[6];
#pragma GCC unroll 6
    for (int j = 0; j < K - 1; ++j) {
      c[j] = b[K - 1][j];
      a[j] = c[j] * inv_d;
    }
    rank1_lower<K - 1>(b, a, c);
#pragma GCC unroll 6
    for (int j = 0; j < K - 1; ++j) b[K - 1][j] = a[j];
    return factor_base6<K - 1>(b);
  }
}

bool ltdl_solve_base6(double* H, Eigen::Index ld, const int* lambda, int n, const double* f,
                      double* x) {
  constexpr int nb = 6;
  Base6 b;
#pragma GCC unroll 6
  for (int i = 0; i < nb; ++i)
#pragma GCC unroll 6
    for (int j = 0; j <= i; ++j) b[i][j] = H[i * ld + j];
  for (int k = n - 1; k >= nb; --k) {
    cancel::poll();
    double* Hk = H + k * ld;
    const double d = Hk[k];
    if (!(d > 0)) return false;
    const double inv_d = 1.0 / d;
    for (int i = lambda[k]; i >= nb; i = lambda[i]) {
      const double a = Hk[i] * inv_d;
      double* Hi = H + i * ld;
      for (int j = i; j >= nb; j = lambda[j]) Hi[j] -= a * Hk[j];
      for (int j = nb - 1; j >= 0; --j) Hi[j] -= a * Hk[j];
      Hk[i] = a;
    }
    double c[nb], a[nb];
#pragma GCC unroll 6
    for (int j = 0; j < nb; ++j) {
      c[j] = Hk[j];
      a[j] = c[j] * inv_d;
    }
    rank1_lower<nb>(b, a, c);
#pragma GCC unroll 6
    for (int j = 0; j < nb; ++j) Hk[j] = a[j];
  }
  if (!factor_base6<nb>(b)) return false;
  double xb[nb];
#pragma GCC unroll 6
  for (int i = 0; i < nb; ++i) xb[i] = f[i];
  for (int i = nb; i < n; ++i) x[i] = f[i];
  for (int i = n - 1; i >= nb; --i) {  // L^T z = f
    const double* Hi = H + i * ld;
    const double xi = x[i];
    for (int j = lambda[i]; j >= nb; j = lambda[j]) x[j] -= Hi[j] * xi;
#pragma GCC unroll 6
    for (int j = nb - 1; j >= 0; --j) xb[j] -= Hi[j] * xi;
  }
#pragma GCC unroll 6
  for (int i = nb - 1; i >= 0; --i)
#pragma GCC unroll 6
    for (int j = i - 1; j >= 0; --j) xb[j] -= b[i][j] * xb[i];
#pragma GCC unroll 6
  for (int i = 0; i < nb; ++i) xb[i] /= b[i][i];  // y = D^-1 z
  for (int i = nb; i < n; ++i) x[i] /= H[i * ld + i];
#pragma GCC unroll 6
  for (int i = 0; i < nb; ++i)  // L u' = y
#pragma GCC unroll 6
    for (int j = i - 1; j >= 0; --j) xb[i] -= b[i][j] * xb[j];
#pragma GCC unroll 6
  for (int i = 0; i < nb; ++i) x[i] = xb[i];
  for (int i = nb; i < n; ++i) {
    const double* Hi = H + i * ld;
    double xi = x[i];
    for (int j = lambda[i]; j >= nb; j = lambda[j]) xi -= Hi[j] * x[j];
#pragma GCC unroll 6
    for (int j = nb - 1; j >= 0; --j) xi -= Hi[j] * xb[j];
    x[i] = xi;
  }
  return true;
}

}  // namespace

bool KaneEngine::solve(bool fixed_base_block) {
  const int nb = nodes_[0].nu;
  if (fixed_base_block && nb == 6)
    return ltdl_solve_base6(M_.data(), M_.outerStride(), lambda_.data(), n_u_, f_.data(),
                            udot_.data());
  return ltdl_solve(M_.data(), M_.outerStride(), lambda_.data(), n_u_, nb, f_.data(),
                    udot_.data());
}

Eigen::VectorXd KaneEngine::composite_udot(double t, const double* x, bool fixed_base_block) {
  set_time(t);
  position_pass(x);
  velocity_pass(x + n_q_);
  remainder_pass();
  subtree_pass(t);
  mass_matrix_pass();
  generalized_force_pass(t, x);
  if (!solve(fixed_base_block))
    throw RunFailure("kane", t, "mass matrix", "not positive definite (a pivot of L^T D L <= 0)");
  return udot_;
}

void KaneEngine::dynamics(double t, const double* x) {
  set_time(t);
  position_pass(x);
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
// Rigid trees.  rhs() of a tree of rigid bodies with a free base on the composite solver (every
// committed rigid scene but chain5, spear1_case1 among them): Passes 1-3 and the kinematical
// equations fused into one forward loop (base first), Passes 4-6 into one backward loop (leaves
// first), and the L^T D L solve of Pass 7 writing u' straight into xdot.  Each node's quantities
// are formed by the expressions of the passes above, in the same order, so xdot is the same to
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
  // alpha_t_N, a_t_N (Pass 3); the kinematical equations (rhs below).
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
    switch (n.type) {
      case JointType::Revolute: {
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
      case JointType::Spherical: {
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
    const Vector3d R_B = -n.mass * w.a_t_N;
    Vector3d T_B = rigid_residual_torque(n, w, w.alpha_t_N);
    if (n.body_torque) add_body_torque(n, w, t, T_B);
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
      f_w = -w_B.cross(Iw);
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
        T_B.noalias() -= w.w_NB_N.cross(w.I_BBo_N * w.w_NB_N);
      if (n.body_torque) add_body_torque(n, w, t, T_B);
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
    }
    for (int j = 0; j < 3; ++j) M_.block<3, 1>(r0 + 3, r0 + j) = R.col(j).cross(w.s_sub_N);
    M_.block<3, 3>(r0 + 3, r0 + 3) = Matrix3d::Identity() * w.m_sub;
    f_.segment<3>(r0) = f_w;
    f_.segment<3>(r0 + 3) = w.F_sub_N;
  }
  if (!ltdl_solve_base6(M_.data(), M_.outerStride(), lambda_.data(), n_u_, f_.data(),
                        xdot + n_q_))
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
        if (!n.prescribed) xdot[n.q0] = u[n.u0];
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
      case JointType::Revolute:  // a prescribed joint: nothing (its profile gives it at any t)
        if (n.prescribed) break;
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

// ------------------------------------------------------------------------------------------------
// u' => alpha_N, a_N (full accelerations, for accelerations()): the remainder-pass recursion
// with the sums W_r u_r' and V_r u_r' added (propagate_accelerations).

// (full is explicit: with no speed at all, a prescribed base's rigid tree, udot is null.)
void KaneEngine::acceleration_pass(const double* udot) { propagate_accelerations(udot, true); }

// The torque a prescribed joint applies to its child about its axis (docs/prescribed-motion.md):
// Kane's equation of its speed, kept as a known function of time (Kane and Levinson 1985,
// Sec. 6.1), F_r + F_r* + tau = 0, where the speed's partial velocities move the subtree S(k)
// rigidly about Ok with W_r = the axis, so F_r + F_r* = W_r . M_k, the moment about Ok of every
// external and inertia force on S(k) with the full accelerations (hinge torques below k and the
// elastic forces are internal to S(k) and cancel):  tau = -W_r . M_k.
void KaneEngine::prescribed_torque_pass(double t) {
  acceleration_pass(udot_.data());
  subtree_pass(t, /*full=*/true);
  for (const Node& n : nodes_)
    if (n.prescribed) {
      const NodeWork& w = work_[static_cast<std::size_t>(n.joint)];
      prescribed_torque_[static_cast<std::size_t>(n.joint)] = -w.W_N.col(0).dot(w.M_sub_N);
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
  a.eta_ddot.assign(nb, Eigen::VectorXd());
  for (const Node& n : nodes_) {
    if (n.nm > 0) a.eta_ddot[static_cast<std::size_t>(n.body)] = udot_.segment(n.u0 + n.nuj, n.nm);
    const NodeWork& w = work_[static_cast<std::size_t>(n.joint)];
    // d/dt of the body-frame components of w_NB: R_NB^T alpha (the w x w term vanishes).
    // For a flexible body: its frame; a_NBo_N is the acceleration of the frame origin Bo.
    a.wdot_NB_B[static_cast<std::size_t>(n.body)] = w.R_NB.transpose() * w.alpha_N;
    a.a_NBo_N[static_cast<std::size_t>(n.body)] = w.a_N;
    if (n.type == JointType::Revolute)
      a.angle_ddot[static_cast<std::size_t>(n.joint)] = n.prescribed ? w.pres_accel : udot_(n.u0);
    if (n.type == JointType::Spherical)
      a.wdot_PC_C[static_cast<std::size_t>(n.joint)] = udot_.segment<3>(n.u0);
  }
}

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
  m.H -= (first_moment / total_mass_).cross(m.P);
  return m;
}

double KaneEngine::potential_energy(const double* x) const {
  double V = 0;
  for (const Node& n : nodes_) {
    if (!n.hinge_load) continue;
    const Joint& J = system_.joints[static_cast<std::size_t>(n.joint)];
    if (J.stiffness == 0) continue;
    if (n.type == JointType::Revolute) {
      const double d = x[n.q0] - J.neutral_angle;
      V += 0.5 * J.stiffness * d * d;
    } else if (n.type == JointType::Spherical) {
      V += 0.5 * J.stiffness * rot::rotation_vector(read_quat(x, n.q0)).squaredNorm();
    }
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
  const Vector3d p_NoB0o_N = nodes_[0].type == JointType::Free
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
      f.p_NoJ_N_parent = J.type == JointType::Free ? f.p_NoJ_N_child : J.p_PoJ_P;
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
  if (has_prescribed_) {  // the prescribed joints' torques need the accelerations
    dynamics(t, x);
    prescribed_torque_pass(t);
  }
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
    if (n.type == JointType::Free) {
      const Quaterniond q(x[n.q0 + 3], x[n.q0 + 4], x[n.q0 + 5], x[n.q0 + 6]);
      quat_err = std::max(quat_err, std::abs(q.norm() - 1.0));
      q_N[k] = q.normalized();
      continue;
    }
    Quaterniond q_J = Quaterniond::Identity();
    if (n.type == JointType::Revolute) {  // (cos a/2, sin a/2 k), half angle from position_pass
      const NodeWork& w = work_[k];
      q_J = Quaterniond(w.cos_half, w.sin_half * n.axis_J.x(), w.sin_half * n.axis_J.y(),
                        w.sin_half * n.axis_J.z());
    }
    if (n.type == JointType::Spherical) {
      const Quaterniond q(x[n.q0], x[n.q0 + 1], x[n.q0 + 2], x[n.q0 + 3]);
      quat_err = std::max(quat_err, std::abs(q.norm() - 1.0));
      q_J = q.normalized();
    }
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
  const double T = m.T, V = potential_energy(x);
  RowWriter out(layout_, row);
  out.time(t);
  for (std::size_t b = 0; b < system_.bodies.size(); ++b) {
    const std::size_t k = static_cast<std::size_t>(system_.joint_of_body(static_cast<int>(b)));
    out.body(static_cast<int>(b), work_[k].w_NB_B, q_N[k]);
  }
  for (const Node& n : nodes_) {
    if (n.type == JointType::Revolute && n.prescribed) {
      const NodeWork& w = work_[static_cast<std::size_t>(n.joint)];
      out.revolute(n.joint, w.pres_angle, w.pres_rate);
      out.joint_torque(n.joint, prescribed_torque_[static_cast<std::size_t>(n.joint)]);
    } else if (n.type == JointType::Revolute) {
      out.revolute(n.joint, x[n.q0], u[n.u0]);
    }
    if (n.type == JointType::Spherical)
      out.spherical(n.joint, Vector3d(u[n.u0], u[n.u0 + 1], u[n.u0 + 2]));
    if (n.nm > 0)
      out.modal(n.body, Eigen::Map<const Eigen::VectorXd>(x + n.q0 + n.nqj, n.nm),
                Eigen::Map<const Eigen::VectorXd>(u + n.u0 + n.nuj, n.nm));
  }
  out.momentum(H.norm());
  out.energy(T + V);
  int c = extra0_;
  out.extra(c++, T);
  out.extra(c++, V);
  for (int i = 0; i < 3; ++i) out.extra(c++, H(i));
  for (int i = 0; i < 3; ++i) out.extra(c++, P(i));
  out.extra(c++, quat_err);
}

// The same row for a rigid tree with a free base (rigid_fast_; no prescribed joint, so no joint
// torque column): the positions and velocities of Passes 1-2 (R_NB of each body, its origin
// from the base CM, w_NB_N, v_NBo_N), the attitude quaternions (q_NC = q_NP q_PJ0 q_J, as above)
// and the sums of sum_momenta() (same formulas) in one loop over the nodes, each body's columns
// written as it is reached.  A rigid body's rotational inertia is used in body components
// (h_Bo = R_NB I_BBo_B w_NB_B), so no I_BBo_N is formed; the base's w_NB_B is its speeds u_1..3
// themselves.
void KaneEngine::rigid_output_row(double t, const double* x, double* row) {
  const double* u = x + n_q_;
  RowWriter out(layout_, row);
  out.time(t);
  double quat_err = 0, T2 = 0;
  Vector3d P = Vector3d::Zero(), H = Vector3d::Zero(), first_moment = Vector3d::Zero();
  std::vector<Quaterniond>& q_N = q_N_;
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    const Node& n = nodes_[k];
    NodeWork& w = work_[k];
    if (n.type == JointType::Free) {
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
      switch (n.type) {
        case JointType::Revolute: {
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
        case JointType::Spherical: {
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
  H -= (first_moment / total_mass_).cross(P);
  const double V = has_potential_ ? potential_energy(x) : 0.0;
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
