// Linear-time factorisation of the Newton-Euler KKT system of a tree of rigid bodies.
//
//   [ M   J^T ] [ nu_dot ]   [ f     ]        M = blockdiag(M_b), each 6x6 symmetric positive
//   [ J   0   ] [ y      ] = [ gamma ]        definite; J = the joint constraint rows.
//
// The matrix is sparse with the pattern of a tree whose nodes are the bodies and the joints
// (body - joint - body ...): joint k's rows touch only the columns of its parent body P_k and its
// child body C_k. Eliminating the nodes leaves first (children before parents) creates no fill-in,
// so the block LDL^T factorisation costs O(number of bodies) (Baraff, D. (1996), "Linear-time
// dynamics using Lagrange multipliers", SIGGRAPH 96, Sec. 4-5, Figs. 3-4). The matrix is factorised
// once per state and then solved; nothing is inverted explicitly.
//
// Every joint block is stored padded to 6 rows (rows >= rows_k of J are zero), so all blocks are
// fixed-size 6x6 (no heap allocation); the pivot factorisations and solves of a joint use only its
// rows_k rows, and padded multipliers come out exactly zero.
//
// Pivot blocks: a body's is M_b plus positive semi-definite terms (positive definite); a joint's is
// -J_C D_C^{-1} J_C^T (negative definite when joint k's rows have full rank), factorised as the
// Cholesky factor of its negative. The Cholesky factorisation and triangular solves are a few
// lines written for these tiny blocks (Golub & Van Loan 2013, Alg. 4.2.1): Eigen's general
// routines cost several times more at this size.
#pragma once

#include <Eigen/Core>

#include <vector>

namespace crossdyn::newton_euler {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// One joint's constraint block: its parent and child bodies and its number of rows (<= 6).
struct KktLink {
  int parent = -1;
  int child = -1;
  int rows = 0;
};

class TreeKkt {
 public:
  TreeKkt() = default;
  // links in topological order: each link's parent is the base body or the child of an earlier
  // link; every body except the base is the child of exactly one link.
  TreeKkt(int n_bodies, std::vector<KktLink> links);

  int bodies() const { return static_cast<int>(M_.size()); }
  int links() const { return static_cast<int>(links_.size()); }
  const KktLink& link(int k) const { return links_[static_cast<std::size_t>(k)]; }

  // Inputs: M_b (false when not positive definite), and J_P, J_C of each link (rows >= rows_k
  // must be zero). A leaf body's pivot block is its mass matrix: factorised here, once.
  bool set_mass(int b, const Matrix6d& M);
  const Matrix6d& M(int b) const { return M_[static_cast<std::size_t>(b)]; }
  Matrix6d& J_parent(int k) { return JP_[static_cast<std::size_t>(k)]; }
  Matrix6d& J_child(int k) { return JC_[static_cast<std::size_t>(k)]; }
  const Matrix6d& J_parent(int k) const { return JP_[static_cast<std::size_t>(k)]; }
  const Matrix6d& J_child(int k) const { return JC_[static_cast<std::size_t>(k)]; }

  // (M, J) => block LDL^T factors. False when a pivot block is not definite (a body with a
  // non-positive-definite mass matrix or a joint with dependent constraint rows).
  bool factor();

  // (factors, f per body, gamma per link) => (nu_dot per body, y per link). The vectors must have
  // bodies() and links() elements; gamma's padded rows must be zero. No allocation.
  void solve(const std::vector<Vector6d>& f, const std::vector<Vector6d>& gamma,
             std::vector<Vector6d>& nu_dot, std::vector<Vector6d>& y);

 private:
  std::vector<KktLink> links_;
  int base_ = 0;
  std::vector<Matrix6d> M_, JP_, JC_;
  // Factors in square-root form: D_body = L_b L_b^T, -D_link = L_k L_k^T (lower triangles and
  // reciprocal diagonals), V_k = L_{C_k}^{-1} J_C^T and W_k = L_k^{-1} J_P, so that Baraff's
  // J_i = D_i^{-1} H_{i,parent(i)} is L_C^{-T} V_k (child body) and -L_k^{-T} W_k (link).
  std::vector<Matrix6d> D_body_, L_body_, L_link_, V_, W_;
  std::vector<Vector6d> inv_diag_body_, inv_diag_link_;
  std::vector<bool> leaf_;  // body with no child link: D_body = M, factor cached by set_mass()
  // Solve scratch.
  std::vector<Vector6d> r_body_, r_link_, y_body_, y_link_;
};

}  // namespace crossdyn::newton_euler
