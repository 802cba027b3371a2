// The O(n) tree factorisation of the KKT matrix against a dense LU solve of the same matrix, with
// rigid (6 unknowns) and flexible (6 + n unknowns) body blocks mixed in one tree.
#include "formulations/newton_euler/tree_kkt.hpp"
#include "tests/support/linalg.hpp"

#include <catch2/catch.hpp>

#include <random>
#include <vector>

using crossdyn::newton_euler::KktLink;
using crossdyn::newton_euler::Matrix6d;
using crossdyn::newton_euler::TreeKkt;
using crossdyn::newton_euler::Vector6d;

namespace {

struct Problem {
  int nb = 0;
  std::vector<int> dofs;
  std::vector<KktLink> links;
  std::vector<Eigen::MatrixXd> M, JP, JC;
  Eigen::VectorXd f;
  std::vector<Vector6d> gamma;
};

// A branching tree: 0 -> 1, 0 -> 2, 1 -> 3, 2 -> 4, 1 -> 5, 5 -> 6, with every row count in use.
// flexible: bodies 0 (the base), 1 (a parent), 4 (a leaf) and 5 get 1 to 4 modes.
Problem random_problem(std::mt19937& rng, bool flexible) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Problem p;
  p.nb = 7;
  p.dofs = flexible ? std::vector<int>{9, 10, 6, 6, 7, 8, 6} : std::vector<int>(7, 6);
  p.links = {{0, 1, 5}, {0, 2, 3}, {1, 3, 6}, {2, 4, 3}, {1, 5, 5}, {5, 6, 1}};
  int n = 0;
  for (int d : p.dofs) n += d;
  p.f = Eigen::VectorXd::Zero(n);
  for (int i = 0; i < n; ++i) p.f(i) = u(rng);
  for (int b = 0; b < p.nb; ++b) {
    const int d = p.dofs[static_cast<std::size_t>(b)];
    Eigen::MatrixXd A(d, d);
    for (int i = 0; i < d * d; ++i) A(i) = u(rng);
    p.M.push_back(A * A.transpose() + 0.5 * Eigen::MatrixXd::Identity(d, d));
  }
  for (const KktLink& l : p.links) {
    const int dp = p.dofs[static_cast<std::size_t>(l.parent)];
    const int dc = p.dofs[static_cast<std::size_t>(l.child)];
    Eigen::MatrixXd jp = Eigen::MatrixXd::Zero(6, dp), jc = Eigen::MatrixXd::Zero(6, dc);
    Vector6d g = Vector6d::Zero();
    for (int i = 0; i < l.rows; ++i) {
      for (int c = 0; c < dp; ++c) jp(i, c) = u(rng);
      for (int c = 0; c < dc; ++c) jc(i, c) = u(rng);
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
  for (int trial = 0; trial < 40; ++trial) {
    const bool flexible = trial % 2 == 1;
    const Problem p = random_problem(rng, flexible);
    TreeKkt kkt(p.dofs, p.links);
    for (int b = 0; b < p.nb; ++b) REQUIRE(kkt.set_mass(b, p.M[static_cast<std::size_t>(b)]));
    for (std::size_t k = 0; k < p.links.size(); ++k) {
      kkt.J_parent(static_cast<int>(k)) = p.JP[k];
      kkt.J_child(static_cast<int>(k)) = p.JC[k];
    }
    REQUIRE(kkt.factor());
    Eigen::VectorXd nu = Eigen::VectorXd::Zero(kkt.size());
    std::vector<Vector6d> y(p.links.size());
    kkt.solve(p.f, p.gamma, nu, y);

    // Dense [M J^T; J 0] with each link's rows_k rows.
    const int nv = kkt.size();
    int m = 0;
    std::vector<int> row0;
    for (const KktLink& l : p.links) {
      row0.push_back(nv + m);
      m += l.rows;
    }
    const int n = nv + m;
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd rhs(n);
    rhs.head(nv) = p.f;
    for (int b = 0; b < p.nb; ++b)
      H.block(kkt.offset(b), kkt.offset(b), kkt.dofs(b), kkt.dofs(b)) = p.M[static_cast<std::size_t>(b)];
    for (std::size_t k = 0; k < p.links.size(); ++k) {
      const KktLink& l = p.links[k];
      const int r = row0[k], op = kkt.offset(l.parent), oc = kkt.offset(l.child);
      const int dp = kkt.dofs(l.parent), dc = kkt.dofs(l.child);
      H.block(r, op, l.rows, dp) = p.JP[k].topRows(l.rows);
      H.block(r, oc, l.rows, dc) = p.JC[k].topRows(l.rows);
      H.block(op, r, dp, l.rows) = p.JP[k].topRows(l.rows).transpose();
      H.block(oc, r, dc, l.rows) = p.JC[k].topRows(l.rows).transpose();
      rhs.segment(r, l.rows) = p.gamma[k].head(l.rows);
    }
    const Eigen::VectorXd z = crossdyn::test::full_piv_lu_solve(H, rhs);
    const double scale = z.cwiseAbs().maxCoeff();
    double err = (nu - z.head(nv)).cwiseAbs().maxCoeff();
    for (std::size_t k = 0; k < p.links.size(); ++k) {
      const KktLink& l = p.links[k];
      err = std::max(err, (y[k].head(l.rows) - z.segment(row0[k], l.rows)).cwiseAbs().maxCoeff());
      // Padded multipliers are exactly zero.
      for (int i = l.rows; i < 6; ++i) REQUIRE(y[k](i) == 0.0);
    }
    // Random blocks give condition numbers up to ~1e4: 1e-10 leaves room above round-off.
    INFO("trial " << trial << (flexible ? " (flexible)" : "") << " max error " << err << " scale " << scale);
    CHECK(err <= 1e-10 * scale);
  }
}

TEST_CASE("tree KKT factorisation reports dependent constraint rows", "[newton_euler][kkt]") {
  std::mt19937 rng(3);
  Problem p = random_problem(rng, true);
  // Link 1's second row repeats its first: -D_1 is singular.
  p.JP[1].row(1) = p.JP[1].row(0);
  p.JC[1].row(1) = p.JC[1].row(0);
  TreeKkt kkt(p.dofs, p.links);
  for (int b = 0; b < p.nb; ++b) REQUIRE(kkt.set_mass(b, p.M[static_cast<std::size_t>(b)]));
  for (std::size_t k = 0; k < p.links.size(); ++k) {
    kkt.J_parent(static_cast<int>(k)) = p.JP[k];
    kkt.J_child(static_cast<int>(k)) = p.JC[k];
  }
  CHECK_FALSE(kkt.factor());
  CHECK_FALSE(kkt.set_mass(2, -Matrix6d::Identity()));                 // rigid, not definite
  CHECK_FALSE(kkt.set_mass(0, -Eigen::MatrixXd::Identity(9, 9)));      // flexible, not definite
  CHECK_FALSE(kkt.set_mass(0, Eigen::MatrixXd::Identity(6, 6)));       // wrong size
}
