#include "formulations/newton_euler/tree_kkt.hpp"

#include <algorithm>
#include <cmath>
#include <type_traits>
#include <utility>

namespace crossdyn::newton_euler {

namespace {

std::size_t at(int i) { return static_cast<std::size_t>(i); }

using Six = std::integral_constant<int, 6>;
constexpr Six six{};

// The size argument of the kernels below: the compile-time 6 for rigid bodies (the loops unroll),
// the run-time d otherwise.
template <int D>
auto size_arg(int d) {
  if constexpr (D == 6) return six;
  else return d;
}

// Views of a body's d x d matrices, d x 6 and 6 x d link matrices and d-vectors, with the
// compile-time size D (6 or Eigen::Dynamic). Whole matrices start at an Eigen heap block, aligned
// to 16 bytes; vector segments at body offsets need not be.
template <int D> using Mat = Eigen::Map<Eigen::Matrix<double, D, D>, Eigen::Aligned16>;
template <int D> using Vec = Eigen::Map<Eigen::Matrix<double, D, 1>>;
template <int D> using ConstVec = Eigen::Map<const Eigen::Matrix<double, D, 1>>;
template <int D> using ColsD = Eigen::Map<Eigen::Matrix<double, D, 6>, Eigen::Aligned16>;  // d x 6
template <int D> using RowsD = Eigen::Map<Eigen::Matrix<double, 6, D>, Eigen::Aligned16>;  // 6 x d

// A = L L^T on the leading n x n block (Golub & Van Loan 2013, Alg. 4.2.1, column form). Writes
// L's lower triangle and 1 / L(j, j). False when A is not (numerically) positive definite: a
// pivot that lost more than 12 of its 16 digits to cancellation means dependent rows (or a
// condition number beyond 1e12, where the multipliers would be meaningless anyway).
constexpr double kPivotRelTol = 1e-12;
template <class AM, class N, class LM, class VM>
bool cholesky(const AM& A, N n, LM&& L, VM&& inv_diag) {
  for (int j = 0; j < n; ++j) {
    double d = A(j, j);
    for (int k = 0; k < j; ++k) d -= L(j, k) * L(j, k);
    if (!(d > kPivotRelTol * A(j, j))) return false;
    const double l = std::sqrt(d);
    L(j, j) = l;
    inv_diag(j) = 1.0 / l;
    for (int i = j + 1; i < n; ++i) {
      double s = A(i, j);
      for (int k = 0; k < j; ++k) s -= L(i, k) * L(j, k);
      L(i, j) = s * inv_diag(j);
    }
  }
  return true;
}

// b <- L^{-1} b on the leading n entries (forward substitution).
template <class LM, class VM, class N, class Vec_>
void forward(const LM& L, const VM& inv_diag, N n, Vec_&& b) {
  for (int i = 0; i < n; ++i) {
    double s = b(i);
    for (int k = 0; k < i; ++k) s -= L(i, k) * b(k);
    b(i) = s * inv_diag(i);
  }
}

// b <- L^{-T} b on the leading n entries (backward substitution).
template <class LM, class VM, class N, class Vec_>
void backward(const LM& L, const VM& inv_diag, N n, Vec_&& b) {
  for (int i = n - 1; i >= 0; --i) {
    double s = b(i);
    for (int k = i + 1; k < n; ++k) s -= L(k, i) * b(k);
    b(i) = s * inv_diag(i);
  }
}

}  // namespace

TreeKkt::TreeKkt(int n_bodies, std::vector<KktLink> links)
    : TreeKkt(std::vector<int>(at(n_bodies), 6), std::move(links)) {}

TreeKkt::TreeKkt(std::vector<int> dofs, std::vector<KktLink> links, int root_rows)
    : TreeKkt(std::move(dofs), std::move(links)) {
  root_rows_ = std::clamp(root_rows, 0, 6);
}

TreeKkt::TreeKkt(std::vector<int> dofs, std::vector<KktLink> links)
    : links_(std::move(links)), dofs_(std::move(dofs)) {
  const std::size_t nb = dofs_.size(), nl = links_.size();
  // The base is the one body that is nobody's child.
  std::vector<bool> is_child(nb, false);
  leaf_.assign(nb, 1);
  for (const KktLink& l : links_) {
    is_child[at(l.child)] = true;
    leaf_[at(l.parent)] = 0;
  }
  for (std::size_t b = 0; b < nb; ++b)
    if (!is_child[b]) base_ = static_cast<int>(b);
  int max_dofs = 6;
  for (std::size_t b = 0; b < nb; ++b) {
    const int d = dofs_[b];
    offset_.push_back(size_);
    size_ += d;
    max_dofs = std::max(max_dofs, d);
    rigid_.push_back(d == 6 ? 1 : 0);
    M_.push_back(Eigen::MatrixXd::Identity(d, d));
    D_body_.push_back(Eigen::MatrixXd::Zero(d, d));
    L_body_.push_back(Eigen::MatrixXd::Identity(d, d));
    inv_diag_body_.push_back(Eigen::VectorXd::Ones(d));
  }
  for (const KktLink& l : links_) {
    const int dp = dofs_[at(l.parent)], dc = dofs_[at(l.child)];
    JP_.push_back(Eigen::MatrixXd::Zero(6, dp));
    JC_.push_back(Eigen::MatrixXd::Zero(6, dc));
    W_.push_back(Eigen::MatrixXd::Zero(6, dp));
    V_.push_back(Eigen::MatrixXd::Zero(dc, 6));
  }
  L_link_.assign(nl, Matrix6d::Zero());
  inv_diag_link_.assign(nl, Vector6d::Zero());
  r_body_ = Eigen::VectorXd::Zero(size_);
  y_body_ = Eigen::VectorXd::Zero(size_);
  t_body_ = Eigen::VectorXd::Zero(max_dofs);
  r_link_.assign(nl, Vector6d::Zero());
  y_link_.assign(nl, Vector6d::Zero());
  JR_ = Eigen::MatrixXd::Zero(6, dofs_.empty() ? 6 : dofs_[at(base_)]);
  VR_ = Eigen::MatrixXd::Zero(JR_.cols(), 6);
}

// The root rows' Schur complement S = J_R D_base^{-1} J_R^T = V_R^T V_R (header).
bool TreeKkt::factor_root() {
  if (root_rows_ == 0) return true;
  const std::size_t b = at(base_);
  const int d = dofs_[b];
  VR_ = JR_.transpose();  // same size: no allocation
  for (int col = 0; col < root_rows_; ++col)
    forward(L_body_[b], inv_diag_body_[b], d, VR_.col(col));
  Matrix6d S;
  S.noalias() = VR_.transpose() * VR_;
  return cholesky(S, root_rows_, L_root_, inv_diag_root_);
}

// Given x = D_base^{-1} r in y_body_ (the unconstrained base solve): y_R = S^{-1} (J_R x -
// gamma_R), then x -= D^{-1} J_R^T y_R (header).
void TreeKkt::solve_root() {
  y_root_.setZero();
  if (root_rows_ == 0) return;
  const std::size_t b = at(base_);
  const int d = dofs_[b], o = offset_[b];
  Vector6d y = Vector6d::Zero();
  y.head(root_rows_).noalias() = JR_.topRows(root_rows_) * y_body_.segment(o, d);
  y -= gamma_root_;
  forward(L_root_, inv_diag_root_, root_rows_, y);
  backward(L_root_, inv_diag_root_, root_rows_, y);
  for (int i = root_rows_; i < 6; ++i) y(i) = 0.0;
  y_root_ = y;
  auto t = t_body_.head(d);
  t.noalias() = JR_.transpose() * y;
  forward(L_body_[b], inv_diag_body_[b], d, t);
  backward(L_body_[b], inv_diag_body_[b], d, t);
  y_body_.segment(o, d) -= t;
}

bool TreeKkt::set_mass(int b, const Eigen::Ref<const Eigen::MatrixXd>& M) {
  const std::size_t bb = at(b);
  const int d = dofs_[bb];
  if (M.rows() != d || M.cols() != d) return false;
  M_[bb] = M;  // same size: no allocation
  if (!leaf_[bb]) {
    // Checked here so that a bad mass matrix is reported where it is given; factor() repeats it
    // on M plus the children's (positive semi-definite) terms.
    D_body_[bb] = M;
    return cholesky(D_body_[bb], d, L_body_[bb], inv_diag_body_[bb]);
  }
  return cholesky(M_[bb], d, L_body_[bb], inv_diag_body_[bb]);
}

// Baraff (1996) Fig. 3 "factor": for each node i, children first,
//   D_i = H_ii - sum_{children c} H_ic D_c^{-1} H_ci.
// Node order: for links k = last..first, the child body C_k and then link k; the base last.
// With D_C = L_C L_C^T:   -D_k = J_C D_C^{-1} J_C^T = V_k^T V_k,      V_k = L_C^{-1} J_C^T;
// with -D_k = L_k L_k^T:  D_P -= J_P^T D_k^{-1} J_P, i.e. D_P += W_k^T W_k, W_k = L_k^{-1} J_P.
template <int D>
EIGEN_ALWAYS_INLINE void TreeKkt::link_child_factor(std::size_t k) {
  const KktLink& l = links_[k];
  const std::size_t c = at(l.child);
  const int d = dofs_[c];
  const Mat<D> L(L_body_[c].data(), d, d);
  const Vec<D> inv(inv_diag_body_[c].data(), d);
  ColsD<D> V(V_[k].data(), d, 6);
  V = RowsD<D>(JC_[k].data(), 6, d).transpose();  // padded columns stay zero
  for (int col = 0; col < l.rows; ++col) forward(L, inv, size_arg<D>(d), V.col(col));
}

template <int D>
EIGEN_ALWAYS_INLINE void TreeKkt::link_parent_update(std::size_t k) {
  const KktLink& l = links_[k];
  const std::size_t p = at(l.parent);
  const int d = dofs_[p];
  RowsD<D> W(W_[k].data(), 6, d);
  W = RowsD<D>(JP_[k].data(), 6, d);  // padded rows stay zero
  for (int col = 0; col < d; ++col) forward(L_link_[k], inv_diag_link_[k], l.rows, W.col(col));
  Mat<D>(D_body_[p].data(), d, d).noalias() += W.transpose() * W;
}

bool TreeKkt::factor() {
  for (std::size_t b = 0; b < M_.size(); ++b) {
    if (leaf_[b]) continue;
    if (rigid_[b]) Mat<6>(D_body_[b].data()) = Mat<6>(M_[b].data());
    else D_body_[b] = M_[b];
  }
  for (int k = links() - 1; k >= 0; --k) {
    const KktLink& l = links_[at(k)];
    const std::size_t c = at(l.child), kk = at(k);
    // Body C_k: all its child links (indices > k) have been folded into D_body_[c].
    if (!leaf_[c]) {
      const bool ok = rigid_[c] ? cholesky(Mat<6>(D_body_[c].data()), six, Mat<6>(L_body_[c].data()),
                                           Vec<6>(inv_diag_body_[c].data()))
                                : cholesky(D_body_[c], dofs_[c], L_body_[c], inv_diag_body_[c]);
      if (!ok) return false;
    }
    if (rigid_[c]) link_child_factor<6>(kk);
    else link_child_factor<Eigen::Dynamic>(kk);
    const Matrix6d minus_D = rigid_[c] ? Matrix6d(ColsD<6>(V_[kk].data()).transpose() *
                                                  ColsD<6>(V_[kk].data()))
                                       : Matrix6d(V_[kk].transpose() * V_[kk]);
    if (!cholesky(minus_D, l.rows, L_link_[kk], inv_diag_link_[kk])) return false;
    if (rigid_[at(l.parent)]) link_parent_update<6>(kk);
    else link_parent_update<Eigen::Dynamic>(kk);
  }
  const std::size_t b = at(base_);
  if (leaf_[b]) return factor_root();
  const bool ok = rigid_[b] ? cholesky(Mat<6>(D_body_[b].data()), six, Mat<6>(L_body_[b].data()),
                                       Vec<6>(inv_diag_body_[b].data()))
                            : cholesky(D_body_[b], dofs_[b], L_body_[b], inv_diag_body_[b]);
  return ok && factor_root();
}

// Baraff (1996) Fig. 3 "solve": forward (children first) r_i = b_i - sum_c H_ic y_c,
// y_i = D_i^{-1} r_i; backward (parents first) x_i = y_i - J_i x_{parent(i)}, where
// J_link x_P = -L_k^{-T} (W_k x_P) and J_body x_k = L_C^{-T} (V_k x_k).
template <int D>
EIGEN_ALWAYS_INLINE void TreeKkt::solve_child_down(std::size_t k) {
  const KktLink& l = links_[k];
  const std::size_t c = at(l.child);
  const int d = dofs_[c], o = offset_[c];
  const Mat<D> L(L_body_[c].data(), d, d);
  const Vec<D> inv(inv_diag_body_[c].data(), d);
  Vec<D> yc(y_body_.data() + o, d);
  yc = Vec<D>(r_body_.data() + o, d);
  forward(L, inv, size_arg<D>(d), yc);
  backward(L, inv, size_arg<D>(d), yc);
  r_link_[k].noalias() -= RowsD<D>(JC_[k].data(), 6, d) * yc;
  Vector6d& yk = y_link_[k];
  yk = -r_link_[k];  // D_k^{-1} r = -(L_k L_k^T)^{-1} r
  forward(L_link_[k], inv_diag_link_[k], l.rows, yk);
  backward(L_link_[k], inv_diag_link_[k], l.rows, yk);
  for (int i = l.rows; i < 6; ++i) yk(i) = 0.0;
}

template <int D>
EIGEN_ALWAYS_INLINE void TreeKkt::solve_parent_down(std::size_t k) {
  const std::size_t p = at(links_[k].parent);
  const int d = dofs_[p];
  Vec<D>(r_body_.data() + offset_[p], d).noalias() -=
      RowsD<D>(JP_[k].data(), 6, d).transpose() * y_link_[k];
}

template <int D>
EIGEN_ALWAYS_INLINE void TreeKkt::solve_base() {
  const std::size_t b = at(base_);
  const int d = dofs_[b], o = offset_[b];
  Vec<D> x(y_body_.data() + o, d);
  x = Vec<D>(r_body_.data() + o, d);
  forward(Mat<D>(L_body_[b].data(), d, d), Vec<D>(inv_diag_body_[b].data(), d), size_arg<D>(d), x);
  backward(Mat<D>(L_body_[b].data(), d, d), Vec<D>(inv_diag_body_[b].data(), d), size_arg<D>(d), x);
}

// Link k's multipliers from its parent's accelerations: y_k = y_link_k + L_k^{-T} (W_k nu_P)
// (stored back into y_link_).
template <int D>
EIGEN_ALWAYS_INLINE void TreeKkt::solve_parent_up(std::size_t k, const Eigen::Ref<const Eigen::VectorXd>& nu_dot) {
  const KktLink& l = links_[k];
  const std::size_t p = at(l.parent);
  const int d = dofs_[p];
  Vector6d t;
  t.noalias() = RowsD<D>(W_[k].data(), 6, d) * ConstVec<D>(nu_dot.data() + offset_[p], d);
  backward(L_link_[k], inv_diag_link_[k], l.rows, t);
  for (int i = l.rows; i < 6; ++i) t(i) = 0.0;
  y_link_[k] += t;
}

// The child's accelerations from its link's multipliers: nu_C = y_C - L_C^{-T} (V_k y_k).
template <int D>
EIGEN_ALWAYS_INLINE void TreeKkt::solve_child_up(std::size_t k, Eigen::Ref<Eigen::VectorXd> nu_dot) {
  const std::size_t c = at(links_[k].child);
  const int d = dofs_[c], o = offset_[c];
  Vec<D> t(t_body_.data(), d);
  t.noalias() = ColsD<D>(V_[k].data(), d, 6) * y_link_[k];
  backward(Mat<D>(L_body_[c].data(), d, d), Vec<D>(inv_diag_body_[c].data(), d), size_arg<D>(d), t);
  Vec<D>(nu_dot.data() + o, d) = Vec<D>(y_body_.data() + o, d) - t;
}

void TreeKkt::solve(const Eigen::Ref<const Eigen::VectorXd>& f, const std::vector<Vector6d>& gamma,
                    Eigen::Ref<Eigen::VectorXd> nu_dot, std::vector<Vector6d>& y) {
  r_body_ = f;
  for (std::size_t k = 0; k < r_link_.size(); ++k) r_link_[k] = gamma[k];
  for (int k = links() - 1; k >= 0; --k) {
    const KktLink& l = links_[at(k)];
    if (rigid_[at(l.child)]) solve_child_down<6>(at(k));
    else solve_child_down<Eigen::Dynamic>(at(k));
    if (rigid_[at(l.parent)]) solve_parent_down<6>(at(k));
    else solve_parent_down<Eigen::Dynamic>(at(k));
  }
  if (rigid_[at(base_)]) solve_base<6>();
  else solve_base<Eigen::Dynamic>();
  solve_root();
  const int ob = offset_[at(base_)], db = dofs_[at(base_)];
  nu_dot.segment(ob, db) = y_body_.segment(ob, db);
  for (int k = 0; k < links(); ++k) {
    const KktLink& l = links_[at(k)];
    if (rigid_[at(l.parent)]) solve_parent_up<6>(at(k), nu_dot);
    else solve_parent_up<Eigen::Dynamic>(at(k), nu_dot);
    y[at(k)] = y_link_[at(k)];
    if (rigid_[at(l.child)]) solve_child_up<6>(at(k), nu_dot);
    else solve_child_up<Eigen::Dynamic>(at(k), nu_dot);
  }
}

}  // namespace crossdyn::newton_euler
