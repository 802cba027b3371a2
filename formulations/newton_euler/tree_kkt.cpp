#include "formulations/newton_euler/tree_kkt.hpp"

#include <cmath>
#include <type_traits>
#include <utility>

namespace crossdyn::newton_euler {

namespace {

std::size_t at(int i) { return static_cast<std::size_t>(i); }

// A = L L^T on the leading n x n block (Golub & Van Loan 2013, Alg. 4.2.1, column form). Writes
// L's lower triangle and 1 / L(j, j). False when A is not (numerically) positive definite: a
// pivot that lost more than 12 of its 16 digits to cancellation means dependent rows (or a
// condition number beyond 1e12, where the multipliers would be meaningless anyway).
constexpr double kPivotRelTol = 1e-12;
template <class N>
bool cholesky(const Matrix6d& A, N n, Matrix6d& L, Vector6d& inv_diag) {
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

// b <- L^{-1} b on the leading n entries (forward substitution). The body blocks call it with
// the compile-time size 6 (Six below) so that the loops unroll.
template <class Vec, class N>
void forward(const Matrix6d& L, const Vector6d& inv_diag, N n, Vec&& b) {
  for (int i = 0; i < n; ++i) {
    double s = b(i);
    for (int k = 0; k < i; ++k) s -= L(i, k) * b(k);
    b(i) = s * inv_diag(i);
  }
}

// b <- L^{-T} b on the leading n entries (backward substitution).
template <class Vec, class N>
void backward(const Matrix6d& L, const Vector6d& inv_diag, N n, Vec&& b) {
  for (int i = n - 1; i >= 0; --i) {
    double s = b(i);
    for (int k = i + 1; k < n; ++k) s -= L(k, i) * b(k);
    b(i) = s * inv_diag(i);
  }
}

using Six = std::integral_constant<int, 6>;
constexpr Six six{};

}  // namespace

TreeKkt::TreeKkt(int n_bodies, std::vector<KktLink> links) : links_(std::move(links)) {
  const std::size_t nb = at(n_bodies), nl = links_.size();
  // The base is the one body that is nobody's child.
  std::vector<bool> is_child(nb, false);
  leaf_.assign(nb, true);
  for (const KktLink& l : links_) {
    is_child[at(l.child)] = true;
    leaf_[at(l.parent)] = false;
  }
  for (std::size_t b = 0; b < nb; ++b)
    if (!is_child[b]) base_ = static_cast<int>(b);
  M_.assign(nb, Matrix6d::Identity());
  L_body_.assign(nb, Matrix6d::Identity());
  inv_diag_body_.assign(nb, Vector6d::Ones());
  JP_.assign(nl, Matrix6d::Zero());
  JC_.assign(nl, Matrix6d::Zero());
  D_body_.assign(nb, Matrix6d::Zero());
  L_link_.assign(nl, Matrix6d::Zero());
  V_.assign(nl, Matrix6d::Zero());
  W_.assign(nl, Matrix6d::Zero());
  inv_diag_link_.assign(nl, Vector6d::Zero());
  r_body_.assign(nb, Vector6d::Zero());
  y_body_.assign(nb, Vector6d::Zero());
  r_link_.assign(nl, Vector6d::Zero());
  y_link_.assign(nl, Vector6d::Zero());
}

bool TreeKkt::set_mass(int b, const Matrix6d& M) {
  M_[at(b)] = M;
  Matrix6d L = Matrix6d::Zero();
  Vector6d inv_diag = Vector6d::Zero();
  if (!cholesky(M, six, L, inv_diag)) return false;
  if (leaf_[at(b)]) {
    L_body_[at(b)] = L;
    inv_diag_body_[at(b)] = inv_diag;
  }
  return true;
}

// Baraff (1996) Fig. 3 "factor": for each node i, children first,
//   D_i = H_ii - sum_{children c} H_ic D_c^{-1} H_ci.
// Node order: for links k = last..first, the child body C_k and then link k; the base last.
// With D_C = L_C L_C^T:   -D_k = J_C D_C^{-1} J_C^T = V_k^T V_k,      V_k = L_C^{-1} J_C^T;
// with -D_k = L_k L_k^T:  D_P -= J_P^T D_k^{-1} J_P, i.e. D_P += W_k^T W_k, W_k = L_k^{-1} J_P.
bool TreeKkt::factor() {
  for (std::size_t b = 0; b < M_.size(); ++b)
    if (!leaf_[b]) D_body_[b] = M_[b];
  for (int k = links() - 1; k >= 0; --k) {
    const KktLink& l = links_[at(k)];
    const std::size_t c = at(l.child), p = at(l.parent), kk = at(k);
    const int m = l.rows;
    // Body C_k: all its child links (indices > k) have been folded into D_body_[c].
    if (!leaf_[c] && !cholesky(D_body_[c], six, L_body_[c], inv_diag_body_[c])) return false;
    Matrix6d& V = V_[kk];
    V = JC_[kk].transpose();  // padded columns stay zero
    for (int col = 0; col < m; ++col) forward(L_body_[c], inv_diag_body_[c], six, V.col(col));
    const Matrix6d minus_D = V.transpose() * V;
    if (!cholesky(minus_D, m, L_link_[kk], inv_diag_link_[kk])) return false;
    Matrix6d& W = W_[kk];
    W = JP_[kk];  // padded rows stay zero
    for (int col = 0; col < 6; ++col) forward(L_link_[kk], inv_diag_link_[kk], m, W.col(col));
    D_body_[p].noalias() += W.transpose() * W;
  }
  return leaf_[at(base_)] ||
         cholesky(D_body_[at(base_)], six, L_body_[at(base_)], inv_diag_body_[at(base_)]);
}

// Baraff (1996) Fig. 3 "solve": forward (children first) r_i = b_i - sum_c H_ic y_c,
// y_i = D_i^{-1} r_i; backward (parents first) x_i = y_i - J_i x_{parent(i)}, where
// J_link x_P = -L_k^{-T} (W_k x_P) and J_body x_k = L_C^{-T} (V_k x_k).
void TreeKkt::solve(const std::vector<Vector6d>& f, const std::vector<Vector6d>& gamma,
                    std::vector<Vector6d>& nu_dot, std::vector<Vector6d>& y) {
  for (std::size_t b = 0; b < r_body_.size(); ++b) r_body_[b] = f[b];
  for (std::size_t k = 0; k < r_link_.size(); ++k) r_link_[k] = gamma[k];
  for (int k = links() - 1; k >= 0; --k) {
    const KktLink& l = links_[at(k)];
    const std::size_t c = at(l.child), p = at(l.parent), kk = at(k);
    Vector6d& yc = y_body_[c];
    yc = r_body_[c];
    forward(L_body_[c], inv_diag_body_[c], six, yc);
    backward(L_body_[c], inv_diag_body_[c], six, yc);
    r_link_[kk].noalias() -= JC_[kk] * yc;
    Vector6d& yk = y_link_[kk];
    yk = -r_link_[kk];  // D_k^{-1} r = -(L_k L_k^T)^{-1} r
    forward(L_link_[kk], inv_diag_link_[kk], l.rows, yk);
    backward(L_link_[kk], inv_diag_link_[kk], l.rows, yk);
    for (int i = l.rows; i < 6; ++i) yk(i) = 0.0;
    r_body_[p].noalias() -= JP_[kk].transpose() * yk;
  }
  const std::size_t base = at(base_);
  nu_dot[base] = r_body_[base];
  forward(L_body_[base], inv_diag_body_[base], six, nu_dot[base]);
  backward(L_body_[base], inv_diag_body_[base], six, nu_dot[base]);
  Vector6d t;
  for (int k = 0; k < links(); ++k) {
    const KktLink& l = links_[at(k)];
    const std::size_t c = at(l.child), p = at(l.parent), kk = at(k);
    t.noalias() = W_[kk] * nu_dot[p];
    backward(L_link_[kk], inv_diag_link_[kk], l.rows, t);
    for (int i = l.rows; i < 6; ++i) t(i) = 0.0;
    y[kk] = y_link_[kk] + t;
    t.noalias() = V_[kk] * y[kk];
    backward(L_body_[c], inv_diag_body_[c], six, t);
    nu_dot[c] = y_body_[c] - t;
  }
}

}  // namespace crossdyn::newton_euler
