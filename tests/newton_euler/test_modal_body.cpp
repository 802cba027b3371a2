// The flexible body's equations from precomputed invariants (modal_body.hpp) against the paper's
// Eqs. (3)-(6) evaluated node by node: every node's acceleration is written out from the body's
// motion, and its modal projection, its resultant and its moment about Bo are summed over the nodes.
// Nodes, shapes, deformation and rates are random and large, so every second-order term shows.
#include "formulations/newton_euler/modal_body.hpp"

#include "core/rotation.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Geometry>

#include <random>

using namespace crossdyn;
using namespace crossdyn::newton_euler;
using Eigen::Matrix3d;
using Eigen::Vector3d;
using Eigen::VectorXd;

namespace {

struct Random {
  std::mt19937 rng;
  std::uniform_real_distribution<double> u{-1.0, 1.0};
  double operator()() { return u(rng); }
  Vector3d vec() { return Vector3d(u(rng), u(rng), u(rng)); }
  VectorXd vec(int n, double scale) {
    VectorXd v(n);
    for (int i = 0; i < n; ++i) v(i) = scale * u(rng);
    return v;
  }
};

// Random nodes (origin not at their CM, so S0 != 0 is exercised too), rigid node inertias,
// shapes of size 1, symmetric positive definite K and D.
FlexBody random_body(Random& r, int nodes, int n) {
  FlexBody f;
  for (int k = 0; k < n; ++k) f.mode_names.push_back("q" + std::to_string(k + 1));
  for (int i = 0; i < nodes; ++i) {
    FlexNode nd;
    nd.name = "n" + std::to_string(i);
    nd.mass = 1.0 + r();
    nd.p_BoNi_B = 2.0 * r.vec();
    const Matrix3d A = 0.3 * Matrix3d::Random();
    nd.J_Ni_B = A * A.transpose();
    nd.Phi_B = Eigen::Matrix3Xd::Random(3, n);
    nd.Psi_B = Eigen::Matrix3Xd::Random(3, n);
    f.nodes.push_back(nd);
  }
  const Eigen::MatrixXd A = Eigen::MatrixXd::Random(n, n), B = Eigen::MatrixXd::Random(n, n);
  f.K = A * A.transpose() + Eigen::MatrixXd::Identity(n, n);
  f.D = B * B.transpose();
  return f;
}

}  // namespace

TEST_CASE("modal body: M nu' - f_bias equals the node sums of Eqs. (3)-(6)",
          "[newton_euler][flexible][modal]") {
  Random r{std::mt19937(4)};
  for (int trial = 0; trial < 10; ++trial) {
    const int n = 1 + trial % 4, nodes = 3 + 7 * trial;
    const FlexBody flex = random_body(r, nodes, n);
    const ModalInvariants inv = ModalInvariants::from(flex, Matrix3d::Zero());
    const Matrix3d R = Eigen::Quaterniond(r(), r(), r(), r()).normalized().toRotationMatrix();
    const Vector3d v = r.vec(), w = r.vec(), a = r.vec(), alpha = r.vec();
    const VectorXd eta = r.vec(n, 0.3), eta_dot = r.vec(n, 1.0), eta_ddot = r.vec(n, 1.0);
    ModalTerms mt(n);
    modal_terms(inv, R, w, eta, eta_dot, mt);

    // Node by node: r_i, u_i', the inertial acceleration a_i (paper Eq. (3)), then the resultant
    // (Eq. (1)), the moment about Bo with the node inertias (Eq. (6)), the modal projections
    // (Eq. (4)), the kinetic energy and the momenta.
    Vector3d F = Vector3d::Zero(), M = Vector3d::Zero(), S = Vector3d::Zero();
    Vector3d L = Vector3d::Zero(), h_Bo = Vector3d::Zero();
    VectorXd Q = inv.K * eta + inv.Dmp * eta_dot;
    double T = 0;
    Matrix3d I = Matrix3d::Zero();
    for (const FlexNode& nd : flex.nodes) {
      const Vector3d ri = nd.p_BoNi_B + nd.Phi_B * eta;
      const Vector3d ui_dot = nd.Phi_B * eta_dot;
      const Vector3d acc_B = R.transpose() * a + alpha.cross(ri) + w.cross(w.cross(ri)) +
                             2.0 * w.cross(ui_dot) + nd.Phi_B * eta_ddot;
      const Vector3d vel_N = v + R * (w.cross(ri) + ui_dot);
      F += nd.mass * R * acc_B;
      M += nd.mass * ri.cross(acc_B) + nd.J_Ni_B * alpha + w.cross(nd.J_Ni_B * w);
      Q += nd.mass * nd.Phi_B.transpose() * acc_B;
      T += 0.5 * nd.mass * vel_N.squaredNorm() + 0.5 * w.dot(nd.J_Ni_B * w);
      S += nd.mass * ri;
      L += nd.mass * vel_N;
      h_Bo += nd.mass * (R * ri).cross(vel_N) + R * nd.J_Ni_B * w;
      I += nd.J_Ni_B + nd.mass * (ri.squaredNorm() * Matrix3d::Identity() - ri * ri.transpose());
    }
    VectorXd nu(6 + n), nu_dot(6 + n), node_sums(6 + n);
    nu << v, w, eta_dot;
    nu_dot << a, alpha, eta_ddot;
    node_sums << F, M, Q;
    const VectorXd invariants = mt.M * nu_dot - mt.f;
    INFO("trial " << trial << ": " << nodes << " nodes, " << n << " modes");
    // Magnitudes are O(10-100); round-off in sums of ~50 nodes is ~1e-13 of that.
    CHECK((invariants - node_sums).cwiseAbs().maxCoeff() <= 1e-12 * node_sums.cwiseAbs().maxCoeff());
    CHECK((mt.M - mt.M.transpose()).cwiseAbs().maxCoeff() <= 1e-14 * mt.M.cwiseAbs().maxCoeff());
    CHECK(std::abs(0.5 * nu.dot(mt.M * nu) - T) <= 1e-13 * T);
    CHECK((mt.S - S).norm() <= 1e-13 * S.norm());
    CHECK((mt.I - I).cwiseAbs().maxCoeff() <= 1e-13 * I.cwiseAbs().maxCoeff());
    CHECK((inv.m * v + R * (w.cross(mt.S) + mt.p_rel) - L).norm() <= 1e-13 * L.norm());
    const Vector3d h = (R * mt.S).cross(v) + R * (mt.I * w + mt.h_rel);
    CHECK((h - h_Bo).norm() <= 1e-13 * h_Bo.norm());
  }
}

// With no modes the body is rigid: M = [m 1, -R [S0 x]; [S0 x] R^T, I] and f_bias = [-R w x (w x
// S0); -w x I w]; with the origin at the nodes' CM, diag(m 1, I) and the Euler term alone.
TEST_CASE("modal body: no modes and the origin at the CM give the rigid body's equations",
          "[newton_euler][flexible][modal]") {
  FlexBody f;
  const double m = 3.0;
  for (int s : {-1, 1}) {
    FlexNode nd;
    nd.name = s < 0 ? "a" : "b";
    nd.mass = m / 2;
    nd.p_BoNi_B = Vector3d(s * 0.5, s * 0.2, -s * 0.1);
    nd.J_Ni_B = Vector3d(0.1, 0.2, 0.3).asDiagonal();
    f.nodes.push_back(nd);
  }
  const ModalInvariants inv = ModalInvariants::from(f, Matrix3d::Zero());
  const Matrix3d I = inv.rigid_inertia();
  ModalTerms mt(0);
  const Matrix3d R = Eigen::AngleAxisd(0.7, Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Vector3d w(0.3, -0.8, 0.5);
  modal_terms(inv, R, w, VectorXd(0), VectorXd(0), mt);
  Eigen::Matrix<double, 6, 6> expected = Eigen::Matrix<double, 6, 6>::Zero();
  expected.topLeftCorner<3, 3>() = m * Matrix3d::Identity();
  expected.bottomRightCorner<3, 3>() = I;
  CHECK((mt.M - expected).cwiseAbs().maxCoeff() <= 1e-16);
  CHECK(mt.f.head<3>().norm() <= 1e-16);
  CHECK((mt.f.tail<3>() + w.cross(I * w)).norm() <= 1e-15);
}
