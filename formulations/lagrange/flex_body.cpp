// Modal inertia invariants of a flexible body, summed once over its nodes (flex_body.hpp).
#include "formulations/lagrange/flex_body.hpp"

#include "core/rotation.hpp"

namespace crossdyn::lagrange {

namespace {

// Upper triangle (xx xy xz yy yz zz) of a 3 x 3 matrix.
std::array<double, 6> upper(const Eigen::Matrix3d& A) {
  return {A(0, 0), A(0, 1), A(0, 2), A(1, 1), A(1, 2), A(2, 2)};
}

}  // namespace

FlexInvariants::FlexInvariants(const FlexBody& f, double inertia_scale) {
  n = f.modes();
  const auto nn = static_cast<Eigen::Index>(n);
  s0.setZero();
  S1 = Eigen::Matrix3Xd::Zero(3, nn);
  Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
  std::vector<Eigen::Matrix3d> Ck(static_cast<std::size_t>(n), Eigen::Matrix3d::Zero());
  std::vector<Eigen::Matrix3d> Dkl(static_cast<std::size_t>(n * n), Eigen::Matrix3d::Zero());
  J.setZero();
  Hp = Eigen::Matrix3Xd::Zero(3, nn);
  Hk = Eigen::Matrix3Xd::Zero(3, nn * nn);
  Mee = Eigen::MatrixXd::Zero(nn, nn);
  for (const FlexNode& node : f.nodes) {
    const double mi = node.mass;
    const Eigen::Vector3d& p = node.p_BoNi_B;
    m += mi;
    s0 += mi * p;
    P += mi * p * p.transpose();
    J += node.J_Ni_B;
    for (int k = 0; k < n; ++k) {
      const Eigen::Vector3d phk = node.Phi_B.col(k);
      S1.col(k) += mi * phk;
      Ck[static_cast<std::size_t>(k)] += mi * p * phk.transpose();
      Hp.col(k) += mi * p.cross(phk);
      for (int l = 0; l < n; ++l) {
        const Eigen::Vector3d phl = node.Phi_B.col(l);
        Dkl[static_cast<std::size_t>(k * n + l)] += mi * phk * phl.transpose();
        Hk.col(k * n + l) += mi * phk.cross(phl);
        Mee(k, l) += mi * phk.dot(phl);
      }
    }
  }
  // Test hook: scale the undeformed rigid inertia (tr(P2) 1 - P2 + J) by inertia_scale.
  const Eigen::Matrix3d I0 = P.trace() * Eigen::Matrix3d::Identity() - P + J;
  J += (inertia_scale - 1.0) * I0;
  P2 = upper(P);
  for (int k = 0; k < n; ++k) {
    const Eigen::Matrix3d& c = Ck[static_cast<std::size_t>(k)];
    C.push_back(upper(c + c.transpose()));
  }
  D.assign(static_cast<std::size_t>(n * n), std::array<double, 6>{});
  for (int k = 0; k < n; ++k)
    for (int l = k; l < n; ++l) {
      const Eigen::Matrix3d& a = Dkl[static_cast<std::size_t>(k * n + l)];
      // Q gets eta_k eta_l (D_kl + D_lk) once for k < l; D_lk = D_kl^T.
      D[static_cast<std::size_t>(k * n + l)] = upper(k == l ? a : Eigen::Matrix3d(a + a.transpose()));
    }
  K = 0.5 * (f.K + f.K.transpose());
  Dmp = f.D;
  stiff = f.geometric_stiffening;
  if (stiff)
    for (const FlexNode& node : f.nodes) {
      StiffNode sn;
      sn.m = node.mass;
      sn.p = node.p_BoNi_B;
      sn.e = node.e_B;
      sn.Phi = node.Phi_B;
      sn.G = node.G.size() == 0 ? Eigen::MatrixXd::Zero(nn, nn)
                                : Eigen::MatrixXd(0.5 * (node.G + node.G.transpose()));
      nodes.push_back(std::move(sn));
    }
}

Eigen::Matrix3d FlexInvariants::rigid_inertia() const {
  Eigen::Matrix3d P;
  P << P2[0], P2[1], P2[2], P2[1], P2[3], P2[4], P2[2], P2[4], P2[5];
  return P.trace() * Eigen::Matrix3d::Identity() - P + J;
}

Eigen::MatrixXd FlexInvariants::mass_matrix_at_rest() const {
  const auto nn = static_cast<Eigen::Index>(n);
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(6 + nn, 6 + nn);
  M.topLeftCorner<3, 3>() = rigid_inertia();
  M.block<3, 3>(0, 3) = rot::skew(s0);
  M.block<3, 3>(3, 0) = -rot::skew(s0);
  M.block<3, 3>(3, 3) = m * Eigen::Matrix3d::Identity();
  M.block(0, 6, 3, nn) = Hp;
  M.block(6, 0, nn, 3) = Hp.transpose();
  M.block(3, 6, 3, nn) = S1;
  M.block(6, 3, nn, 3) = S1.transpose();
  M.bottomRightCorner(nn, nn) = Mee;
  return M;
}

}  // namespace crossdyn::lagrange
