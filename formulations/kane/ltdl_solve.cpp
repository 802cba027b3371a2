// Pass 7 of the Kane engine (README.md "Solve"): M u' = f by the sparse L^T D L factorisation taken
// in reverse order ([Feath] Sec. 6.5), and the composite path's u' for tests.
#include "formulations/kane/kane_internal.hpp"

#include "core/cancel.hpp"
#include "core/errors.hpp"

namespace crossdyn::kane {

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

}  // namespace

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

}  // namespace crossdyn::kane
