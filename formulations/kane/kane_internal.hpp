// The Kane engine's internal header: included by formulations/kane/*.cpp only (never by users of
// the engine; kane_engine.hpp is the engine's interface).  It holds the small kinematics and
// inertia helpers that several passes share, and the few functions one pass file calls in another.
//
// The helpers are internal to each translation unit (anonymous namespace), as they were when every
// pass lived in one file, so that the compiler makes the same inlining choices in each pass file:
// same operations, same order, same instruction counts.  [[maybe_unused]]: not every pass file
// uses every helper.
#pragma once

#include "formulations/kane/kane_engine.hpp"
#include "formulations/kane/joints/joint_unit.hpp"

#include <string>

namespace crossdyn::kane {

namespace {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

[[maybe_unused]]
std::string where(const System& s) { return s.file.empty() ? "scene '" + s.name + "'" : s.file; }

// Rotation matrix of a rotation about the unit vector k by the angle whose half has sine sh and
// cosine ch (Rodrigues' formula, the "simple rotation" of [KLL] Ch. 1):
// R = I + sin(a) [k x] + (1 - cos(a)) [k x]^2, with sin(a) = 2 sh ch and 1 - cos(a) = 2 sh^2
// (the half angle is what the attitude quaternion (ch, sh k) of output_row needs; 2 sh^2 also
// keeps 1 - cos(a) accurate at small angles).
[[maybe_unused]]
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
[[maybe_unused]]
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
[[maybe_unused]]
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
[[maybe_unused]]
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
[[maybe_unused]]
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
[[maybe_unused]]
Vector3d combine(const Eigen::Matrix3Xd& A, const double* c) {
  Vector3d v = Vector3d::Zero();
  for (Eigen::Index l = 0; l < A.cols(); ++l) v += A.col(l) * c[l];
  return v;
}

// g = G eta and 1/2 eta^T G eta (explicit loops: no temporaries).  Geometric stiffening's
// second-order displacement e (1/2 eta^T G eta) (docs/flexible-bodies.md; [KRB] Eq. (8)).
[[maybe_unused]]
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
[[maybe_unused]]
double stiff_quad(const Eigen::MatrixXd& G, const double* v) {
  double q = 0;
  for (Eigen::Index k = 0; k < G.rows(); ++k)
    for (Eigen::Index l = 0; l < G.cols(); ++l) q += v[k] * G(k, l) * v[l];
  return q;
}

[[maybe_unused]]
bool all_zero(const Eigen::Matrix3Xd& A) { return A.size() == 0 || A.cwiseAbs().maxCoeff() == 0; }

}  // namespace

// Validates one flexible body and builds its modal integrals (flex_model.cpp).
FlexModel build_flex_model(const Body& B, const std::string& file, double inertia_scale);

// Pass 7's L^T D L solve of M u' = f with a rigid base's 6 x 6 block held in a local array
// (ltdl_solve.cpp); rigid_rhs (rigid_fast_path.cpp) and solve() call it.
bool ltdl_solve_base6(double* H, Eigen::Index ld, const int* lambda, int n, const double* f,
                      double* x);

// Pass 5's helpers (mass_matrix.cpp), also called by the fused rigid path (rigid_fast_path.cpp).

// One ancestor's joint-speed entries of row r (mass_matrix.cpp, Pass 5: a joint's W . h_a, plus
// V . p for a sliding joint; a free base's R^T h_a and p), returning h_a = h + (p_k - p_a) x p, the momentum moment about the
// ancestor's point.
inline Vector3d KaneEngine::mass_matrix_ancestor_joint(const NodeWork& w,
                                                       const Node::Ancestor& an, int r,
                                                       const Vector3d& p, const Vector3d& h) {
  const Node& A = nodes_[static_cast<std::size_t>(an.node)];
  const NodeWork& wa = work_[static_cast<std::size_t>(an.node)];
  const Vector3d h_a = h + (w.p_B0oOk_N - wa.p_B0oOk_N).cross(p);
  if (A.shape == JointShape::Base6) {
    M_.block<1, 3>(r, A.u0).noalias() = (wa.R_NB.transpose() * h_a).transpose();
    M_.block<1, 3>(r, A.u0 + 3) = p.transpose();
  } else if (!A.slides) {
    for (int j = 0; j < A.nuj; ++j) M_(r, A.u0 + j) = wa.W_N.col(j).dot(h_a);
  } else {  // the ancestor's speeds translate S(a) too: + V_j . p
    for (int j = 0; j < A.nuj; ++j)
      M_(r, A.u0 + j) = wa.W_N.col(j).dot(h_a) + wa.V_N.col(j).dot(p);
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

}  // namespace crossdyn::kane
