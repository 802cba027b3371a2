// The Lagrange engine's solve: M pi'' = f by Cholesky (fixed-size kernels up to n = 12), with
// prescribed joints the free block and the joints' torques (README.md, "Solve"), and
// linear_system(), that system written out.
#include <cmath>
#include <cstddef>
#include <string>
#include <utility>

#include "core/errors.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/passes.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

namespace {

// solve: M x = b for symmetric positive definite M (upper triangle read), by Cholesky M = U^T U
// (Golub & Van Loan 2013, "Matrix Computations", 4th ed., Alg. 4.2.1, in its column (gaxpy) form:
// every inner product runs down two contiguous columns of U), then U^T y = b and U x = y.
// b => x in place; U is scratch of M's size and inv_diag of its diagonal's (the reciprocals of
// U's diagonal: one division per column, the rest multiplications). Returns false when M is not
// positive definite (a pivot <= 0, or NaN). A plain loop: at this engine's sizes (n up to a few
// dozen) it is faster than a blocked, dynamically dispatched factorisation. The kernel is written
// once, for a size known at compile time (N > 0, n <= kFixedCholesky: the loops unroll completely,
// about half the instructions at n = 8) and for one known at run time (N = 0); both do the same
// operations in the same order (unrolling reorders nothing), so their results are identical.
constexpr int kFixedCholesky = 12;

#define CROSSDYN_UNROLL _Pragma("GCC unroll 12")
template <int N>
bool cholesky_kernel(Eigen::Index n_runtime, const double* M, double* U, double* r, double* v) {
  const Eigen::Index n = N > 0 ? N : n_runtime;
  CROSSDYN_UNROLL for (Eigen::Index j = 0; j < n; ++j) {
    double* uj = U + j * n;
    const double* mj = M + j * n;
    double d = mj[j];
    CROSSDYN_UNROLL for (Eigen::Index i = 0; i < j; ++i) {
      const double* ui = U + i * n;
      double s = mj[i];
      CROSSDYN_UNROLL for (Eigen::Index k = 0; k < i; ++k) s -= ui[k] * uj[k];
      uj[i] = s * r[i];
      d -= uj[i] * uj[i];
    }
    if (!(d > 0.0)) return false;
    uj[j] = std::sqrt(d);
    r[j] = 1.0 / uj[j];
  }
  CROSSDYN_UNROLL for (Eigen::Index j = 0; j < n; ++j) {  // U^T y = b: row j of U^T is column j
    const double* uj = U + j * n;
    double s = v[j];
    CROSSDYN_UNROLL for (Eigen::Index k = 0; k < j; ++k) s -= uj[k] * v[k];
    v[j] = s * r[j];
  }
  CROSSDYN_UNROLL for (Eigen::Index j = n - 1; j >= 0; --j) {  // U x = y, column by column
    const double* uj = U + j * n;
    const double vj = v[j] * r[j];
    v[j] = vj;
    CROSSDYN_UNROLL for (Eigen::Index k = 0; k < j; ++k) v[k] -= uj[k] * vj;
  }
  return true;
}
#undef CROSSDYN_UNROLL

template <int... N>
bool cholesky_dispatch(std::integer_sequence<int, N...>, Eigen::Index n, const double* M, double* U,
                       double* r, double* v) {
  bool ok = false;
  const bool fixed =
      ((n == N + 1 ? (ok = cholesky_kernel<N + 1>(n, M, U, r, v), true) : false) || ...);
  return fixed ? ok : cholesky_kernel<0>(n, M, U, r, v);
}

bool cholesky_solve(const Eigen::MatrixXd& M, Eigen::MatrixXd& U, Eigen::VectorXd& inv_diag,
                    Eigen::VectorXd& x) {
  return cholesky_dispatch(std::make_integer_sequence<int, kFixedCholesky>(), M.rows(), M.data(),
                           U.data(), inv_diag.data(), x.data());
}

// With prescribed joints: the free block's right-hand side f_f - M_fc theta'' at free coordinate a
// (the solve's; theta'' held in udot at the prescribed coordinates).
// M holds its upper triangle only: M_ij = M(min(i, j), max(i, j)).
double reduced_rhs(const Model& m, const Workspace& w, int a) {
  const int i = m.free_index[static_cast<std::size_t>(a)];
  double b = w.f(i);
  for (int j : m.prescribed_joints) {
    const int c = m.joints[static_cast<std::size_t>(j)].i0;
    b -= (i <= c ? w.M(i, c) : w.M(c, i)) * w.udot(c);
  }
  return b;
}

}  // namespace

void solve(const Model& m, Workspace& w, double t) {
  const int n = m.n;
  // solve: M pi'' = N + B^T dL/dq* - (dM/dt) pi' - B^T W^T p.
  w.f = w.N + w.dL - w.Mdot_u - w.hamel;
  if (!m.has_prescribed) {
    w.udot = w.f;
    if (!cholesky_solve(w.M, w.U, w.inv_diag, w.udot))
      throw RunFailure("lagrange", t, "", "mass matrix is not positive definite");
    return;
  }
  // Prescribed joints (docs/prescribed-motion.md): the equations above hold for every coordinate
  // with, on a prescribed coordinate c, the joint torque tau_c as an extra generalised force (its
  // virtual power is tau_c times the rate, as for a motor). Partitioned into free (f) and
  // prescribed (c) coordinates with pi''_c = theta''(t) known (Greenwood, "Advanced Dynamics"
  // 2003, Sec. 2.4, rheonomic constraints; Lagrange's equations of the constrained coordinate
  // give its constraint force):
  //   M_ff pi''_f = f_f - M_fc theta'',        tau_c = M_cf pi''_f + M_cc theta'' - f_c.
  // M holds its upper triangle only: M_ij = M(min(i, j), max(i, j)).
  auto Msym = [&w](int i, int j) { return i <= j ? w.M(i, j) : w.M(j, i); };
  for (int j : m.prescribed_joints) {
    const Model::JointM& J = m.joints[static_cast<std::size_t>(j)];
    w.udot(J.i0) = J.motion.accel(t);
  }
  const int nf = m.nf;
  for (int a = 0; a < nf; ++a) {
    const int i = m.free_index[static_cast<std::size_t>(a)];
    w.bf(a) = reduced_rhs(m, w, a);
    for (int bb = a; bb < nf; ++bb) w.Mff(a, bb) = Msym(i, m.free_index[static_cast<std::size_t>(bb)]);
  }
  if (!cholesky_solve(w.Mff, w.Uff, w.inv_diag_f, w.bf))
    throw RunFailure("lagrange", t, "", "mass matrix is not positive definite");
  for (int a = 0; a < nf; ++a) w.udot(m.free_index[static_cast<std::size_t>(a)]) = w.bf(a);
  for (std::size_t k = 0; k < m.prescribed_joints.size(); ++k) {
    const int c = m.joints[static_cast<std::size_t>(m.prescribed_joints[k])].i0;
    double tau = -w.f(c);
    for (int i = 0; i < n; ++i) tau += Msym(c, i) * w.udot(i);
    w.torque(static_cast<Eigen::Index>(k)) = tau;
  }
}

// linear_system: (t, x) => the system of the solve pass written out (Engine::linear_system), for
// the conditioning study (README.md, "Solve"): M and f exactly as evaluate() leaves them for its
// Cholesky solve, or with prescribed joints the free block, whose right-hand side solve()
// overwrites with pi''_f and which is formed again here by the same reduced_rhs().
Engine::LinearSystem LagrangeEngine::linear_system(double t, const double* x) {
  const Model& m = *model_;
  evaluate(t, expand(t, x));
  const Workspace& w = *ws_;
  const int nf = m.nf;
  LinearSystem ls;
  ls.speed_index.resize(static_cast<std::size_t>(nf));
  for (int a = 0; a < nf; ++a) ls.speed_index[static_cast<std::size_t>(a)] = nf + a;
  const std::string count = std::to_string(nf) + " velocities (M factored by Cholesky)";
  if (!m.has_prescribed) {
    ls.A = w.M;  // evaluate() fills the upper triangle only (the one the Cholesky kernel reads)
    ls.b = w.f;
    ls.what = "Boltzmann-Hamel equations M(q*) pi'' = f, " + count;
  } else {
    ls.A = w.Mff;  // upper triangle, as above
    ls.b.resize(nf);
    for (int a = 0; a < nf; ++a) ls.b(a) = reduced_rhs(m, w, a);
    ls.what = "Boltzmann-Hamel equations M_ff(q*) pi_f'' = f_f - M_fc theta'', " + count + " (" +
              std::to_string(m.prescribed_joints.size()) + " prescribed joint" +
              (m.prescribed_joints.size() == 1 ? "" : "s") + " eliminated)";
  }
  ls.A.triangularView<Eigen::StrictlyLower>() = ls.A.transpose();
  return ls;
}

}  // namespace crossdyn::lagrange
