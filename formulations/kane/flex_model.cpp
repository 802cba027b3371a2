// The modal integrals of a flexible body (FlexModel), validated and built once from its nodes
// (README.md "Flexible bodies": S, Hs, G_k, Q_kl, C_kl, Mm; paper Eqs. (3)-(6)).
#include "formulations/kane/kane_internal.hpp"

#include "core/errors.hpp"
#include "core/rotation.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <string>

namespace crossdyn::kane {

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

}  // namespace crossdyn::kane
