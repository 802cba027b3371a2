// The O(n) tree factorisation of the KKT matrix against a dense LU solve of the same matrix.
#include "formulations/newton_euler/tree_kkt.hpp"

#include <catch2/catch.hpp>

#include <Eigen/LU>

#include <random>
#include <vector>

using crossdyn::newton_euler::KktLink;
using crossdyn::newton_euler::Matrix6d;
using crossdyn::newton_euler::TreeKkt;
using crossdyn::newton_euler::Vector6d;

namespace {

struct Problem {
  int nb = 0;
  std::vector<KktLink> links;
  std::vector<Matrix6d> M, JP, JC;
  std::vector<Vector6d> f, gamma;
};

// A branching tree: 0 -> 1, 0 -> 2, 1 -> 3, 2 -> 4, 1 -> 5, 5 -> 6, with every row count in use.
Problem random_problem(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Problem p;
  p.nb = 7;
  p.links = {{0, 1, 5}, {0, 2, 3}, {1, 3, 6}, {2, 4, 3}, {1, 5, 5}, {5, 6, 1}};
  for (int b = 0; b < p.nb; ++b) {
    Matrix6d A;
    for (int i = 0; i < 36; ++i) A(i) = u(rng);
    p.M.push_back(A * A.transpose() + 0.5 * Matrix6d::Identity());
    Vector6d f;
    for (int i = 0; i < 6; ++i) f(i) = u(rng);
    p.f.push_back(f);
  }
  for (const KktLink& l : p.links) {
    Matrix6d jp = Matrix6d::Zero(), jc = Matrix6d::Zero();
    Vector6d g = Vector6d::Zero();
    for (int i = 0; i < l.rows; ++i) {
      for (int c = 0; c < 6; ++c) {
        jp(i, c) = u(rng);
        jc(i, c) = u(rng);
      }
      g(i) = u(rng);
    }
    p.JP.push_back(jp);
    p.JC.push_back(jc);
    p.gamma.push_back(g);
  }
  return p;
}

}  // namespace

TEST_CASE("tree KKT factorisation solves the KKT system like a dense LU", "[newton_euler][kkt]") {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const Problem p = random_problem(rng);
    TreeKkt kkt(p.nb, p.links);
    for (int b = 0; b < p.nb; ++b) REQUIRE(kkt.set_mass(b, p.M[static_cast<std::size_t>(b)]));
    for (std::size_t k = 0; k < p.links.size(); ++k) {
      kkt.J_parent(static_cast<int>(k)) = p.JP[k];
      kkt.J_child(static_cast<int>(k)) = p.JC[k];
    }
    REQUIRE(kkt.factor());
    std::vector<Vector6d> nu(static_cast<std::size_t>(p.nb)), y(p.links.size());
    kkt.solve(p.f, p.gamma, nu, y);

    // Dense [M J^T; J 0] with each link's rows_k rows.
    int m = 0;
    std::vector<int> row0;
    for (const KktLink& l : p.links) {
      row0.push_back(6 * p.nb + m);
      m += l.rows;
    }
    const int n = 6 * p.nb + m;
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd rhs(n);
    for (int b = 0; b < p.nb; ++b) {
      H.block<6, 6>(6 * b, 6 * b) = p.M[static_cast<std::size_t>(b)];
      rhs.segment<6>(6 * b) = p.f[static_cast<std::size_t>(b)];
    }
    for (std::size_t k = 0; k < p.links.size(); ++k) {
      const KktLink& l = p.links[k];
      const int r = row0[k];
      H.block(r, 6 * l.parent, l.rows, 6) = p.JP[k].topRows(l.rows);
      H.block(r, 6 * l.child, l.rows, 6) = p.JC[k].topRows(l.rows);
      H.block(6 * l.parent, r, 6, l.rows) = p.JP[k].topRows(l.rows).transpose();
      H.block(6 * l.child, r, 6, l.rows) = p.JC[k].topRows(l.rows).transpose();
      rhs.segment(r, l.rows) = p.gamma[k].head(l.rows);
    }
    const Eigen::VectorXd z = H.fullPivLu().solve(rhs);
    const double scale = z.cwiseAbs().maxCoeff();
    double err = 0;
    for (int b = 0; b < p.nb; ++b)
      err = std::max(err, (nu[static_cast<std::size_t>(b)] - z.segment<6>(6 * b)).cwiseAbs().maxCoeff());
    for (std::size_t k = 0; k < p.links.size(); ++k) {
      const KktLink& l = p.links[k];
      err = std::max(err, (y[k].head(l.rows) - z.segment(row0[k], l.rows)).cwiseAbs().maxCoeff());
      // Padded multipliers are exactly zero.
      for (int i = l.rows; i < 6; ++i) REQUIRE(y[k](i) == 0.0);
    }
    // Random blocks give condition numbers up to ~1e4: 1e-10 leaves room above round-off.
    INFO("trial " << trial << " max error " << err << " scale " << scale);
    CHECK(err <= 1e-10 * scale);
  }
}

TEST_CASE("tree KKT factorisation reports dependent constraint rows", "[newton_euler][kkt]") {
  std::mt19937 rng(3);
  Problem p = random_problem(rng);
  // Link 1's second row repeats its first: -D_1 is singular.
  p.JP[1].row(1) = p.JP[1].row(0);
  p.JC[1].row(1) = p.JC[1].row(0);
  TreeKkt kkt(p.nb, p.links);
  for (int b = 0; b < p.nb; ++b) REQUIRE(kkt.set_mass(b, p.M[static_cast<std::size_t>(b)]));
  for (std::size_t k = 0; k < p.links.size(); ++k) {
    kkt.J_parent(static_cast<int>(k)) = p.JP[k];
    kkt.J_child(static_cast<int>(k)) = p.JC[k];
  }
  CHECK_FALSE(kkt.factor());
  CHECK_FALSE(kkt.set_mass(0, -Matrix6d::Identity()));
}
