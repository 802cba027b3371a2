// Linear-time factorisation of the Newton-Euler KKT system of a tree of rigid and flexible bodies.
//
//   [ M   J^T ] [ nu_dot ]   [ f     ]        M = blockdiag(M_b), each d_b x d_b symmetric positive
//   [ J   0   ] [ y      ] = [ gamma ]        definite; J = the joint constraint rows.
//
// A body's block has d_b = 6 unknowns (rigid: [a_NBo_N; alpha_NB_B]) or 6 + n_b (a flexible body
// with n_b modes: the frame's 6 and eta''; its block is full, newton_euler.hpp "Flexible bodies").
// The matrix is sparse with the pattern of a tree whose nodes are the bodies and the joints
// (body - joint - body ...): joint k's rows touch only the columns of its parent body P_k and its
// child body C_k. Eliminating the nodes leaves first (children before parents) creates no fill-in,
// so the block LDL^T factorisation costs O(number of bodies) (Baraff, D. (1996), "Linear-time
// dynamics using Lagrange multipliers", SIGGRAPH 96, Sec. 4-5, Figs. 3-4; the algorithm is written
// for nodes of any dimension). The matrix is factorised once per state and then solved; nothing is
// inverted explicitly.
//
// Every joint block is stored padded to 6 rows (rows >= rows_k of J are zero); the pivot
// factorisations and solves of a joint use only its rows_k rows, and padded multipliers come out
// exactly zero. Body vectors (f, nu_dot) are stacked in body order, body b at offset(b).
//
// Pivot blocks: a body's is M_b plus positive semi-definite terms (positive definite); a joint's is
// -J_C D_C^{-1} J_C^T (negative definite when joint k's rows have full rank), factorised as the
// Cholesky factor of its negative. The Cholesky factorisation and triangular solves are a few
// lines written for these small blocks (Golub & Van Loan 2013, Alg. 4.2.1): Eigen's general
// routines cost several times more at this size. The same templated kernels run with the
// compile-time size 6 for rigid bodies (unrolled; the rigid scenes' speed) and with the run-time
// size 6 + n_b for flexible ones. All storage is allocated by the constructor.
//
// Root rows (a prescribed base, docs/prescribed-motion.md): optionally, up to 6 constraint rows
// J_R nu_base = gamma_R on the base body alone (its link to N). The base is eliminated last, so
// they only change the last step: with D_base = L L^T, the base's small KKT system
//   [D_base J_R^T; J_R 0] [x; y_R] = [r; gamma_R]
// is solved by the range-space method (Nocedal & Wright 2006, "Numerical Optimization", 2nd ed.,
// Sec. 16.2, Eq. (16.16)): S = J_R D^{-1} J_R^T = V_R^T V_R, V_R = L^{-1} J_R^T;
// y_R = S^{-1} (J_R D^{-1} r - gamma_R), x = D^{-1} (r - J_R^T y_R).
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
  // dofs[b] >= 6: body b's number of unknowns. links in topological order: each link's parent is
  // the base body or the child of an earlier link; every body except the base is the child of
  // exactly one link.
  TreeKkt(std::vector<int> dofs, std::vector<KktLink> links);
  // With root rows (0: none) on the base body (see the header).
  TreeKkt(std::vector<int> dofs, std::vector<KktLink> links, int root_rows);
  // All bodies rigid (6 unknowns each).
  TreeKkt(int n_bodies, std::vector<KktLink> links);

  int bodies() const { return static_cast<int>(dofs_.size()); }
  int links() const { return static_cast<int>(links_.size()); }
  int dofs(int b) const { return dofs_[static_cast<std::size_t>(b)]; }
  int offset(int b) const { return offset_[static_cast<std::size_t>(b)]; }
  int size() const { return size_; }  // sum of dofs
  const KktLink& link(int k) const { return links_[static_cast<std::size_t>(k)]; }

  // Inputs: M_b (dofs(b) square; false when not positive definite), and J_P (6 x dofs(parent)),
  // J_C (6 x dofs(child)) of each link, written in place (rows >= rows_k must be zero; never
  // resize them). A leaf body's pivot block is its mass matrix: factorised here, once per call.
  bool set_mass(int b, const Eigen::Ref<const Eigen::MatrixXd>& M);
  const Eigen::MatrixXd& M(int b) const { return M_[static_cast<std::size_t>(b)]; }
  Eigen::MatrixXd& J_parent(int k) { return JP_[static_cast<std::size_t>(k)]; }
  Eigen::MatrixXd& J_child(int k) { return JC_[static_cast<std::size_t>(k)]; }
  const Eigen::MatrixXd& J_parent(int k) const { return JP_[static_cast<std::size_t>(k)]; }
  const Eigen::MatrixXd& J_child(int k) const { return JC_[static_cast<std::size_t>(k)]; }

  int root_rows() const { return root_rows_; }
  int base() const { return base_; }
  // Root rows J_R (6 x dofs(base); rows >= root_rows() zero), written in place.
  Eigen::MatrixXd& J_root() { return JR_; }
  // Their right-hand side gamma_R (set before solve()) and multipliers y_R (after solve()).
  Vector6d& gamma_root() { return gamma_root_; }
  const Vector6d& y_root() const { return y_root_; }

  // (M, J) => block LDL^T factors. False when a pivot block is not definite (a body with a
  // non-positive-definite mass matrix or a joint with dependent constraint rows).
  bool factor();

  // (factors, f stacked by body, gamma per link) => (nu_dot stacked, y per link). f and nu_dot
  // have size() entries, gamma and y links() elements; gamma's padded rows must be zero. No
  // allocation.
  void solve(const Eigen::Ref<const Eigen::VectorXd>& f, const std::vector<Vector6d>& gamma,
             Eigen::Ref<Eigen::VectorXd> nu_dot, std::vector<Vector6d>& y);

 private:
  template <int D> void link_child_factor(std::size_t k);
  template <int D> void link_parent_update(std::size_t k);
  template <int D> void solve_child_down(std::size_t k);
  template <int D> void solve_parent_down(std::size_t k);
  template <int D> void solve_base();
  template <int D> void solve_child_up(std::size_t k, Eigen::Ref<Eigen::VectorXd> nu_dot);
  template <int D> void solve_parent_up(std::size_t k, const Eigen::Ref<const Eigen::VectorXd>& nu_dot);

  bool factor_root();
  void solve_root();

  std::vector<KktLink> links_;
  int root_rows_ = 0;
  Eigen::MatrixXd JR_, VR_;           // 6 x d_base, d_base x 6
  Matrix6d L_root_ = Matrix6d::Zero();
  Vector6d inv_diag_root_ = Vector6d::Zero(), gamma_root_ = Vector6d::Zero(),
           y_root_ = Vector6d::Zero();
  std::vector<int> dofs_, offset_;
  int size_ = 0;
  int base_ = 0;
  std::vector<char> rigid_;  // dofs == 6: the compile-time-size kernels
  std::vector<Eigen::MatrixXd> M_, JP_, JC_;
  // Factors in square-root form: D_body = L_b L_b^T, -D_link = L_k L_k^T (lower triangles and
  // reciprocal diagonals), V_k = L_{C_k}^{-1} J_C^T (d_C x 6) and W_k = L_k^{-1} J_P (6 x d_P),
  // so that Baraff's J_i = D_i^{-1} H_{i,parent(i)} is L_C^{-T} V_k (child body) and -L_k^{-T} W_k
  // (link).
  std::vector<Eigen::MatrixXd> D_body_, L_body_, V_, W_;
  std::vector<Eigen::VectorXd> inv_diag_body_;
  std::vector<Matrix6d> L_link_;
  std::vector<Vector6d> inv_diag_link_;
  std::vector<char> leaf_;  // body with no child link: D_body = M, factor cached by set_mass()
  // Solve scratch: stacked body vectors, one body's vector, per-link vectors.
  Eigen::VectorXd r_body_, y_body_, t_body_;
  std::vector<Vector6d> r_link_, y_link_;
};

}  // namespace crossdyn::newton_euler
