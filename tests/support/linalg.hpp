// Eigen's decompositions for the tests, compiled once (tests/support/linalg.cpp) instead of in every
// test file that uses one (issue 29: instantiating EigenSolver, LDLT, FullPivLU... was a third of
// such a file's compile time). Each function is exactly the Eigen call the tests made before (same
// decomposition, same scalar type and size, same options), so results are bit for bit the same.
// This header includes only <Eigen/Core>: include it, not <Eigen/Eigenvalues> and the like.
#pragma once

#include <Eigen/Core>

namespace crossdyn::test {

// Eigenvalues of a general real matrix, in Eigen's order: Eigen::EigenSolver<MatrixXd>(A,
// compute_eigenvectors) (the vectors are not returned; the flag is Eigen's, kept as each test had it).
Eigen::VectorXcd eigenvalues(const Eigen::MatrixXd& A, bool compute_eigenvectors = true);

// Eigenvalues of a symmetric matrix, ascending: Eigen::SelfAdjointEigenSolver<MatrixXd>(A) (its
// default options: eigenvectors computed too).
Eigen::VectorXd symmetric_eigenvalues(const Eigen::MatrixXd& A);
// The same for a fixed 3x3 matrix: Eigen::SelfAdjointEigenSolver<Matrix3d>(A) (Eigen's 3x3
// tridiagonalisation).
Eigen::Vector3d symmetric_eigenvalues(const Eigen::Matrix3d& A);

// lambda of A x = lambda B x (A symmetric, B symmetric positive definite), ascending:
// Eigen::GeneralizedSelfAdjointEigenSolver<MatrixXd>(A, B) (default options: Ax_lBx, vectors too).
Eigen::VectorXd generalized_symmetric_eigenvalues(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B);

// x solving A x = b, A symmetric: Eigen::LDLT<Matrix3d> (A.ldlt().solve(b) on a fixed 3x3 matrix).
Eigen::Vector3d ldlt_solve(const Eigen::Matrix3d& A, const Eigen::Vector3d& b);
// x solving A x = b, A symmetric: Eigen::LDLT<MatrixXd>; *info (when given) is its info().
Eigen::VectorXd ldlt_solve(const Eigen::MatrixXd& A, const Eigen::VectorXd& b,
                           Eigen::ComputationInfo* info = nullptr);
// X solving A X = B, A symmetric: Eigen::LDLT<MatrixXd>, solved for all of B's columns at once.
Eigen::MatrixXd ldlt_solve(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B);

// x solving A x = b, A symmetric positive definite: Eigen::LLT<MatrixXd>; *info (when given) is
// its info() (NumericalIssue: A is not positive definite).
Eigen::VectorXd llt_solve(const Eigen::MatrixXd& A, const Eigen::VectorXd& b,
                          Eigen::ComputationInfo* info = nullptr);

// x solving A x = b, A square (indefinite, possibly singular): Eigen::FullPivLU<MatrixXd>.
Eigen::VectorXd full_piv_lu_solve(const Eigen::MatrixXd& A, const Eigen::VectorXd& b);

}  // namespace crossdyn::test
