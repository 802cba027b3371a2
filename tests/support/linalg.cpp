// The tests' Eigen decompositions, instantiated here once (tests/support/linalg.hpp).
#include "tests/support/linalg.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

namespace crossdyn::test {

Eigen::VectorXcd eigenvalues(const Eigen::MatrixXd& A, bool compute_eigenvectors) {
  return Eigen::EigenSolver<Eigen::MatrixXd>(A, compute_eigenvectors).eigenvalues();
}

Eigen::VectorXd symmetric_eigenvalues(const Eigen::MatrixXd& A) {
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(A).eigenvalues();
}

Eigen::Vector3d symmetric_eigenvalues(const Eigen::Matrix3d& A) {
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(A).eigenvalues();
}

Eigen::VectorXd generalized_symmetric_eigenvalues(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) {
  return Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd>(A, B).eigenvalues();
}

Eigen::Vector3d ldlt_solve(const Eigen::Matrix3d& A, const Eigen::Vector3d& b) {
  return A.ldlt().solve(b);
}

Eigen::VectorXd ldlt_solve(const Eigen::MatrixXd& A, const Eigen::VectorXd& b,
                           Eigen::ComputationInfo* info) {
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(A);
  if (info) *info = ldlt.info();
  return ldlt.solve(b);
}

Eigen::MatrixXd ldlt_solve(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) {
  return A.ldlt().solve(B);
}

Eigen::VectorXd llt_solve(const Eigen::MatrixXd& A, const Eigen::VectorXd& b,
                          Eigen::ComputationInfo* info) {
  const Eigen::LLT<Eigen::MatrixXd> llt(A);
  if (info) *info = llt.info();
  return llt.solve(b);
}

Eigen::VectorXd full_piv_lu_solve(const Eigen::MatrixXd& A, const Eigen::VectorXd& b) {
  return Eigen::FullPivLU<Eigen::MatrixXd>(A).solve(b);
}

}  // namespace crossdyn::test
