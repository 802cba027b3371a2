// The beam generator (core/flex/beam.hpp) against closed forms, published roots and its model's
// own physics: the layout (stations where the slices were, Gauss-Legendre mass points), the node
// sums equal to the continuum's integrals to rounding, the slopes' signs, the frequencies of the
// discrete body equal to the closed form's.
#include <catch2/catch.hpp>

#include <Eigen/Geometry>
#include <boost/math/quadrature/gauss.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <string>

#include "core/errors.hpp"
#include "core/flex/beam.hpp"
#include "tests/support/close.hpp"
#include "tests/support/linalg.hpp"

using namespace crossdyn;
using namespace crossdyn::flex;
using crossdyn::test::close;
using crossdyn::test::generalized_symmetric_eigenvalues;
using crossdyn::test::symmetric_eigenvalues;

namespace {

// Scene 2's beam (docs/scenarios.md): 10 m along z, 50 kg/m, 2 x 2 m section, EI = 100 N m^2
// in both planes, two free-free modes per plane, unit displacement at the top end.
BeamSpec scene2_beam(int slices = 100, int modes = 2) {
  BeamSpec s;
  s.length = 10;
  s.axis = 2;
  s.mass_per_length = 50;
  s.section = {2, 2, 0};
  s.bending = {BeamPlane{modes, 100}, BeamPlane{modes, 100}, BeamPlane{}};
  s.slices = slices;
  return s;
}

// The same beam along another axis: the section and the bending planes move with it.
BeamSpec along(int axis, BeamBoundary boundary, int slices, int modes) {
  BeamSpec s = scene2_beam(slices, modes);
  s.axis = axis;
  s.section = {2, 2, 2};
  s.section[static_cast<std::size_t>(axis)] = 0;
  s.bending = {BeamPlane{modes, 100}, BeamPlane{modes, 100}, BeamPlane{modes, 100}};
  s.bending[static_cast<std::size_t>(axis)] = BeamPlane{};
  s.boundary = boundary;
  return s;
}

double omega(const BeamSpec& s, double lambda, int d) {
  return lambda * lambda *
         std::sqrt(s.bending[static_cast<std::size_t>(d)].EI /
                   (s.mass_per_length * std::pow(s.length, 4)));
}

// The textbook form (beam.hpp), fine for low modes only.
double naive_phi(bool clamped, double lambda, double xi) {
  const double x = lambda * xi, e = clamped ? -1 : 1;
  const double sigma = (std::cosh(lambda) - e * std::cos(lambda)) /
                       (std::sinh(lambda) - e * std::sin(lambda));
  return std::cosh(x) + e * std::cos(x) - sigma * (std::sinh(x) + e * std::sin(x));
}

Eigen::Vector3d sum_m_Phi(const FlexBody& f, int k) {
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  for (const FlexNode& n : f.nodes) s += n.mass * n.Phi_B.col(k);
  return s;
}
Eigen::Vector3d sum_m_p_cross_Phi(const FlexBody& f, int k) {
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  for (const FlexNode& n : f.nodes) s += n.mass * n.p_BoNi_B.cross(n.Phi_B.col(k));
  return s;
}
double modal_mass(const FlexBody& f, int k, int l) {
  double s = 0;
  for (const FlexNode& n : f.nodes) s += n.mass * n.Phi_B.col(k).dot(n.Phi_B.col(l));
  return s;
}

// The small-motion frequencies of the free body: K x = w^2 M x with M the rest mass matrix of
// rigid motion and modes (flex_model.hpp) and K padded with zeros for the six rigid speeds.
Eigen::VectorXd free_body_frequencies(const FlexBody& f, const Eigen::MatrixXd& K) {
  const int n = f.modes();
  const Eigen::MatrixXd M = rest_mass_matrix(f);
  Eigen::MatrixXd Kfull = Eigen::MatrixXd::Zero(6 + n, 6 + n);
  Kfull.bottomRightCorner(n, n) = K;
  // The six zeros first.
  return generalized_symmetric_eigenvalues(Kfull, M).tail(n).cwiseMax(0).cwiseSqrt();
}

}  // namespace

TEST_CASE("the frequency-equation roots equal the published values to 1e-14") {
  // Blevins (1979) Table 8-1 to 16 digits; k = 20 from the equation solved in 40-digit arithmetic.
  const double free_free[] = {4.730040744862704, 7.853204624095838, 10.99560783800167,
                              14.13716549125746, 17.27875965739948};
  const double clamped[] = {1.875104068711961, 4.694091132974175, 7.854757438237613,
                            10.99554073487547, 14.13716839104647};
  for (int k = 1; k <= 5; ++k) {
    INFO("k = " << k);
    CHECK(close(free_free_root(k), free_free[k - 1], 0, 1e-14));
    CHECK(close(clamped_root(k), clamped[k - 1], 0, 1e-14));
  }
  CHECK(close(free_free_root(20), 64.402649398590761388, 0, 1e-14));
  CHECK(close(clamped_root(20), 61.26105674500096815, 0, 1e-14));
}

TEST_CASE("the roots solve cos(x) cosh(x) = +-1 to rounding and approach (2k +- 1) pi / 2") {
  for (int k = 1; k <= 60; ++k) {
    const double f = free_free_root(k), c = clamped_root(k);
    INFO("k = " << k);
    // cos x = +-sech x, with cos evaluated to an absolute error of a few ulp of x.
    CHECK(std::abs(std::cos(f) - 1 / std::cosh(f)) <= 4e-16 * f);
    CHECK(std::abs(std::cos(c) + 1 / std::cosh(c)) <= 4e-16 * c);
    // The asymptotes: |x - (2k+1) pi/2| ~ 2 e^-x.
    CHECK(std::abs(f - (2 * k + 1) * std::numbers::pi / 2) <= 2.5 * std::exp(-f) + 1e-14 * f);
    CHECK(std::abs(c - (2 * k - 1) * std::numbers::pi / 2) <= 2.5 * std::exp(-c) + 1e-14 * c);
  }
}

TEST_CASE("the stable shapes equal the textbook form for low modes and stay exact for high ones") {
  for (bool clamped : {false, true}) {
    for (int k = 1; k <= 3; ++k)
      for (double xi : {0.0, 0.13, 0.5, 0.77, 1.0}) {
        const double lambda = clamped ? clamped_root(k) : free_free_root(k);
        CHECK(close(beam_shape(clamped, k, xi).phi, naive_phi(clamped, lambda, xi), 1e-12, 0));
      }
    for (int k = 1; k <= 30; ++k) {
      INFO((clamped ? "clamped" : "free-free") << ", k = " << k);
      // End values: free-free |phi| = 2 at both ends; clamped: phi = phi' = 0 at 0, |phi(1)| = 2.
      const ShapeValue s0 = beam_shape(clamped, k, 0), s1 = beam_shape(clamped, k, 1);
      CHECK(close(std::abs(s1.phi), 2, 1e-12, 0));
      if (clamped) {
        CHECK(std::abs(s0.phi) <= 1e-12);
        CHECK(std::abs(s0.dphi) <= 1e-12 * k);
      } else {
        CHECK(close(s0.phi, 2, 1e-12, 0));
      }
      // Unit mean square: the integral of phi^2 over [0, 1] is 1 (Gauss-Legendre, 200 panels).
      double integral = 0;
      for (int p = 0; p < 200; ++p)
        integral += boost::math::quadrature::gauss<double, 15>::integrate(
            [&](double xi) { return std::pow(beam_shape(clamped, k, xi).phi, 2); }, p / 200.0,
            (p + 1) / 200.0);
      CHECK(close(integral, 1, 1e-11, 0));
      // dphi is the derivative of phi (central difference, h = 1e-6).
      for (double xi : {0.1, 0.4, 0.9}) {
        const double h = 1e-6;
        const double fd = (beam_shape(clamped, k, xi + h).phi - beam_shape(clamped, k, xi - h).phi) / (2 * h);
        CHECK(close(beam_shape(clamped, k, xi).dphi, fd, 1e-6 * k * k, 0));
      }
    }
  }
}


TEST_CASE("nodes: bottom then stations slice1..N at the slice centres then mass points gauss1..N then top with massless ends and stations") {
  // N = 4 along x, L = 10: one block of the 4-point Gauss-Legendre rule (Abramowitz & Stegun
  // 25.4.29: +-0.339981043584856, weight 0.652145154862546; +-0.861136311594053, 0.347854845137454).
  const FlexModel b = make_beam(along(0, BeamBoundary::FreeFree, 4, 1), "beam");
  const auto& n = b.flex.nodes;
  REQUIRE(n.size() == 10);
  const std::vector<std::string> names = {"bottom", "slice1", "slice2", "slice3", "slice4",
                                          "gauss1", "gauss2", "gauss3", "gauss4", "top"};
  for (std::size_t i = 0; i < n.size(); ++i) CHECK(n[i].name == names[i]);
  const double stations[] = {-5, -3.75, -1.25, 1.25, 3.75, 5};
  for (int i = 0; i < 6; ++i) {
    const FlexNode& s = n[static_cast<std::size_t>(i == 5 ? 9 : i)];
    CHECK(s.mass == 0.0);
    CHECK(s.J_Ni_B.isZero(0));
    CHECK(test::all_close(s.p_BoNi_B, Eigen::Vector3d(stations[i], 0, 0), 0, 0));
  }
  const double t[] = {-0.861136311594053, -0.339981043584856, 0.339981043584856, 0.861136311594053};
  const double w[] = {0.347854845137454, 0.652145154862546, 0.652145154862546, 0.347854845137454};
  for (int i = 0; i < 4; ++i) {
    const FlexNode& g = n[static_cast<std::size_t>(5 + i)];
    INFO(g.name);
    CHECK(close(g.p_BoNi_B.x(), 5 * t[i], 1e-14, 0));
    CHECK(g.p_BoNi_B.y() == 0.0);
    CHECK(g.p_BoNi_B.z() == 0.0);
    CHECK(close(g.mass, 250 * w[i], 0, 1e-14));
    // Its own inertia is its section's only: (m/12) diag(4 + 4, 4, 4) for the 2 x 2 m section.
    CHECK(test::all_close(g.J_Ni_B, Eigen::Matrix3d(Eigen::Vector3d(8, 4, 4).asDiagonal() * (g.mass / 12)), 0, 1e-15));
  }
  CHECK(b.flex.mode_names == std::vector<std::string>{"qy1", "qz1"});
}

TEST_CASE("class: the layout is exactly antisymmetric about the CM for every slicing (blocks of <= 20 points)") {
  // Odd and even N, one block, several blocks, an even block count made odd (21, 41), N = 1.
  for (int N : {1, 2, 4, 7, 12, 20, 21, 40, 41, 48, 50, 60, 99, 100, 101, 1000}) {
    INFO("N = " << N);
    const FlexBody f = make_beam(along(2, BeamBoundary::FreeFree, N, 0), "beam").flex;
    REQUIRE(f.nodes.size() == static_cast<std::size_t>(2 * N + 2));
    double total = 0, previous = -6;
    for (int i = 0; i < N; ++i) {
      const FlexNode& g = f.nodes[static_cast<std::size_t>(N + 1 + i)];
      const FlexNode& mirror = f.nodes[static_cast<std::size_t>(2 * N - i)];
      CHECK(g.name == "gauss" + std::to_string(i + 1));
      CHECK(g.p_BoNi_B.z() == -mirror.p_BoNi_B.z());  // to the bit
      CHECK(g.mass == mirror.mass);
      CHECK(g.p_BoNi_B.z() > previous);               // ascending, inside the beam
      CHECK(g.mass > 0);
      previous = g.p_BoNi_B.z();
      total += g.mass;
      const FlexNode& s = f.nodes[static_cast<std::size_t>(1 + i)];
      CHECK(s.p_BoNi_B.z() == -f.nodes[static_cast<std::size_t>(N - i)].p_BoNi_B.z());
    }
    CHECK(previous < 5);
    CHECK(close(total, 500, 0, 1e-14));
  }
}

TEST_CASE("class: bottom, top and every slice<i> keep their places and shapes (slice centres), every axis and boundary") {
  // The joints of every scene attach where they did before the mass moved to the Gauss-Legendre
  // points: slice<i> at -L/2 + (i - 1/2) L/N, the ends at -+L/2, and at each the closed-form shape
  // and slope there (the normalisation constant c from the end value, as before).
  for (int axis = 0; axis < 3; ++axis)
    for (BeamBoundary bc : {BeamBoundary::FreeFree, BeamBoundary::ClampedBottom, BeamBoundary::ClampedTop})
      for (int N : {6, 8, 21, 60, 100}) {
        const FlexBody f = make_beam(along(axis, bc, N, 2), "beam").flex;
        const bool clamped = bc != BeamBoundary::FreeFree, from_top = bc == BeamBoundary::ClampedTop;
        INFO("axis " << axis << ", boundary " << static_cast<int>(bc) << ", N = " << N);
        CHECK(f.nodes[static_cast<std::size_t>(f.node_index("bottom"))].p_BoNi_B(axis) == -5.0);
        CHECK(f.nodes[static_cast<std::size_t>(f.node_index("top"))].p_BoNi_B(axis) == 5.0);
        const FlexNode& ref = from_top ? f.nodes.front() : f.nodes.back();
        for (int i = 1; i <= N; ++i) {
          const int j = f.node_index("slice" + std::to_string(i));
          REQUIRE(j == i);
          const FlexNode& s = f.nodes[static_cast<std::size_t>(j)];
          CHECK(close(s.p_BoNi_B(axis), -5 + (i - 0.5) * 10.0 / N, 1e-15 * 5, 0));
          CHECK(s.p_BoNi_B.norm() == std::abs(s.p_BoNi_B(axis)));
          CHECK(s.mass == 0.0);
          const double xi = from_top ? (N - i + 0.5) / N : (i - 0.5) / N;
          for (int k = 0; k < f.modes(); ++k) {
            const int order = k % 2 + 1;
            const double c = 1 / beam_shape(clamped, order, 1).phi;
            const Eigen::Vector3d phi = s.Phi_B.col(k), end = ref.Phi_B.col(k);
            CHECK(close(phi.dot(end), c * beam_shape(clamped, order, xi).phi, 1e-14, 0));
            CHECK(close(phi.norm(), std::abs(c * beam_shape(clamped, order, xi).phi), 1e-14, 0));
          }
        }
      }
  // The brief's example: slice4 of 8 on a 2 m beam sits at -1 + 3.5 * 0.25 = -0.125 m.
  BeamSpec s = along(2, BeamBoundary::FreeFree, 8, 1);
  s.length = 2;
  const FlexBody f = make_beam(s, "beam").flex;
  CHECK(f.nodes[static_cast<std::size_t>(f.node_index("slice4"))].p_BoNi_B.z() == -0.125);
}

TEST_CASE("K is diagonal positive definite with the closed-form frequencies and node-sum modal masses") {
  const BeamSpec s = scene2_beam(100, 3);
  const FlexModel b = make_beam(s, "beam");
  const FlexBody& f = b.flex;
  REQUIRE(f.modes() == 6);
  CHECK(f.mode_names == std::vector<std::string>{"qx1", "qx2", "qx3", "qy1", "qy2", "qy3"});
  CHECK(test::all_close(f.K, Eigen::MatrixXd(f.K.transpose()), 0, 0));
  CHECK(f.K.isDiagonal(0));
  CHECK(f.D.isZero(0));
  CHECK(symmetric_eigenvalues(f.K).minCoeff() > 0);
  for (int k = 0; k < 6; ++k) {
    const double w = omega(s, free_free_root(k % 3 + 1), k < 3 ? 0 : 1);
    CHECK(close(std::sqrt(f.K(k, k) / modal_mass(f, k, k)), w, 0, 1e-14));
  }
  // Scene 2: omega_1 = 4.730040744862704^2 sqrt(100 / (50 10^4)) = 0.316406037... rad/s.
  CHECK(close(std::sqrt(f.K(0, 0) / modal_mass(f, 0, 0)), 0.31640603715492926, 0, 1e-14));
}

TEST_CASE("unit displacement at the named end: the top by default, the free end of a cantilever") {
  for (int axis = 0; axis < 3; ++axis) {
    const FlexModel ff = make_beam(along(axis, BeamBoundary::FreeFree, 40, 3), "beam");
    const FlexModel ct = make_beam(along(axis, BeamBoundary::ClampedTop, 40, 3), "beam");
    for (int k = 0; k < 6; ++k) {
      const int d = ff.flex.mode_names[static_cast<std::size_t>(k)][1] - 'x';
      CHECK(test::all_close(ff.flex.nodes.back().Phi_B.col(k), Eigen::Vector3d::Unit(d), 1e-15, 0));
      CHECK(test::all_close(ct.flex.nodes.front().Phi_B.col(k), Eigen::Vector3d::Unit(d), 1e-15, 0));
    }
  }
  BeamSpec s = scene2_beam(60, 2);
  s.normalisation = BeamNormalisation::Bottom;
  const FlexModel bottom = make_beam(s, "beam");
  CHECK(test::all_close(bottom.flex.nodes.front().Phi_B.col(1), Eigen::Vector3d::UnitX(), 1e-15, 0));
  s.normalisation = BeamNormalisation::Mass;
  const FlexModel unit = make_beam(s, "beam");
  for (int k = 0; k < 4; ++k) {
    CHECK(close(modal_mass(unit.flex, k, k), 1, 0, 1e-14));
    CHECK(unit.flex.nodes.back().Phi_B.col(k).sum() > 0);  // sign: the top end moves along +d
  }
}

TEST_CASE("cantilever shapes and slopes vanish at the clamped end, for both ends and every axis") {
  for (int axis = 0; axis < 3; ++axis)
    for (BeamBoundary b : {BeamBoundary::ClampedBottom, BeamBoundary::ClampedTop}) {
      const FlexModel m = make_beam(along(axis, b, 50, 4), "beam");
      const FlexNode& root = b == BeamBoundary::ClampedBottom ? m.flex.nodes.front() : m.flex.nodes.back();
      const FlexNode& tip = b == BeamBoundary::ClampedBottom ? m.flex.nodes.back() : m.flex.nodes.front();
      INFO("axis " << axis << (b == BeamBoundary::ClampedBottom ? " clamped bottom" : " clamped top"));
      for (int k = 0; k < m.flex.modes(); ++k) {
        CHECK(root.Phi_B.col(k).norm() <= 1e-13);
        CHECK(root.Psi_B.col(k).norm() <= 1e-13);
        CHECK(close(tip.Phi_B.col(k).norm(), 1, 1e-15, 0));
      }
    }
}

TEST_CASE("slopes: the section turns the long axis to the centre line's tangent (right-hand rule)") {
  // Psi x e_a must equal d Phi / d x_a (a rotation psi takes e_a to e_a + psi x e_a), checked
  // against a central difference of the slice nodes' shapes (error O(h^2)), for every long axis,
  // both planes, free-free and both cantilevers.
  const int N = 400;
  for (int axis = 0; axis < 3; ++axis)
    for (BeamBoundary bc : {BeamBoundary::FreeFree, BeamBoundary::ClampedBottom, BeamBoundary::ClampedTop}) {
      const FlexModel m = make_beam(along(axis, bc, N, 2), "beam");
      const auto& nodes = m.flex.nodes;
      const double h = 10.0 / N;
      const Eigen::Vector3d e_a = Eigen::Vector3d::Unit(axis);
      for (int k = 0; k < m.flex.modes(); ++k) {
        double worst = 0, scale = 0;
        for (int j = 2; j < N; ++j) {
          const Eigen::Vector3d fd = (nodes[static_cast<std::size_t>(j + 1)].Phi_B.col(k) -
                                      nodes[static_cast<std::size_t>(j - 1)].Phi_B.col(k)) / (2 * h);
          const Eigen::Vector3d psi = nodes[static_cast<std::size_t>(j)].Psi_B.col(k);
          worst = std::max(worst, (psi.cross(e_a) - fd).norm());
          scale = std::max(scale, fd.norm());
          // The slope is a rotation about e_a x e_d only (no twist, no component along e_a).
          CHECK(std::abs(psi.dot(e_a)) == 0.0);
        }
        INFO("axis " << axis << ", mode " << m.flex.mode_names[static_cast<std::size_t>(k)]);
        CHECK(worst <= 1e-4 * scale);
      }
    }
  // The examples of the brief: a beam along z, bending in x with positive slope d phi/dz turns
  // about +y; bending in y with positive slope turns about -x. And exp([psi x]) e_z is the unit
  // tangent of the deformed centre line for a small deflection eta.
  const FlexModel m = make_beam(scene2_beam(400, 1), "beam");
  const FlexNode& n = m.flex.nodes[300];  // slice 300: z = 2.4875 m
  const FlexNode& up = m.flex.nodes[301];
  const FlexNode& down = m.flex.nodes[299];
  const double slope_x = (up.Phi_B(0, 0) - down.Phi_B(0, 0)) / (2 * 10.0 / 400);
  const double slope_y = (up.Phi_B(1, 1) - down.Phi_B(1, 1)) / (2 * 10.0 / 400);
  CHECK(n.Psi_B(1, 0) * slope_x > 0);
  CHECK(close(n.Psi_B(1, 0), slope_x, 1e-5, 0));
  CHECK(n.Psi_B(0, 1) * slope_y < 0);
  CHECK(close(n.Psi_B(0, 1), -slope_y, 1e-5, 0));
  const double eta = 1e-4;
  const Eigen::Vector3d psi = n.Psi_B.col(0) * eta;
  const Eigen::Vector3d turned = Eigen::AngleAxisd(psi.norm(), psi.normalized()) * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d tangent = (Eigen::Vector3d::UnitZ() + Eigen::Vector3d(slope_x * eta, 0, 0)).normalized();
  CHECK((turned - tangent).norm() <= 1e-8);
}

TEST_CASE("class: the modal integrals are the continuum's to rounding, every boundary, axis, normalisation and slicing") {
  // With the mass at composite Gauss-Legendre points the node sums of the closed-form shapes are
  // the continuum's integrals: integral phi_k phi_l = L delta_kl, and for free-free modes
  // integral phi = integral (s - L/2) phi = 0 (no momentum of the rigid motion). So with a unit end
  // value (|phi(end)| = 2) the modal mass is rho A L / 4, the cross modal masses and the coupling
  // sums vanish, and the small-motion frequencies of the discrete body are the closed form's
  // (the free body's from its rest mass matrix; a cantilever's from K x = w^2 M_ee x) at the
  // default slicing and at small N alike. (Before, each was off by O(N^-2).)
  const double M = 500, L = 10;
  for (BeamBoundary bc : {BeamBoundary::FreeFree, BeamBoundary::ClampedBottom, BeamBoundary::ClampedTop})
    for (int axis = 0; axis < 3; ++axis)
      for (BeamNormalisation norm : {BeamNormalisation::Auto, BeamNormalisation::Mass})
        for (int N : {12, 21, 40, 50, 61, 100}) {
          BeamSpec s = along(axis, bc, N, 2);
          s.normalisation = norm;
          const FlexBody f = make_beam(s, "beam").flex;
          const bool clamped = bc != BeamBoundary::FreeFree;
          INFO("boundary " << static_cast<int>(bc) << ", axis " << axis << ", normalisation "
                           << static_cast<int>(norm) << ", N = " << N);
          REQUIRE(f.modes() == 4);
          const FlexNode& end = bc == BeamBoundary::ClampedTop ? f.nodes.front() : f.nodes.back();
          double worst_mass = 0, worst_cross = 0, worst_lin = 0, worst_ang = 0;
          for (int k = 0; k < 4; ++k) {
            const double e = end.Phi_B.col(k).norm();  // 1, or 2 / sqrt(rho A L) for unit modal mass
            const double expected = norm == BeamNormalisation::Mass ? 1.0 : M / 4;
            if (norm == BeamNormalisation::Mass) CHECK(close(e, 2 / std::sqrt(M), N >= 21 ? 1e-13 : 1e-9, 0));
            worst_mass = std::max(worst_mass, std::abs(modal_mass(f, k, k) / expected - 1));
            for (int l = 0; l < 4; ++l)
              if (l != k) worst_cross = std::max(worst_cross, std::abs(modal_mass(f, k, l)) / expected);
            if (!clamped) {
              worst_lin = std::max(worst_lin, sum_m_Phi(f, k).norm() / (M * e));
              worst_ang = std::max(worst_ang, sum_m_p_cross_Phi(f, k).norm() / (M * L * e));
            }
          }
          // A block of n points integrates a polynomial of degree 2n - 1 exactly: phi_k phi_l
          // of mode 2 (lambda = 7.85) needs more than 12 points on the whole beam for rounding.
          const double tol = N >= 21 ? 1e-13 : 1e-9;
          CHECK(worst_mass <= tol);
          CHECK(worst_cross <= tol);
          CHECK(worst_lin <= 1e-13);
          CHECK(worst_ang <= 1e-13);
          // The frequencies: EI = 100 in both planes, so each pair is one frequency.
          const Eigen::VectorXd w =
              clamped ? Eigen::VectorXd(generalized_symmetric_eigenvalues(f.K, [&] {
                          Eigen::MatrixXd Mee(4, 4);
                          for (int k = 0; k < 4; ++k)
                            for (int l = 0; l < 4; ++l) Mee(k, l) = modal_mass(f, k, l);
                          return Mee;
                        }()).cwiseSqrt())
                      : free_body_frequencies(f, f.K);
          for (int k = 0; k < 4; ++k) {
            const double lambda = clamped ? clamped_root(k / 2 + 1) : free_free_root(k / 2 + 1);
            CHECK(close(w(k), omega(s, lambda, axis == 0 ? 1 : 0), 0, 1e-12));
          }
        }
}

TEST_CASE("class: the rigid mass and inertia are the uniform box's and the layout changes nothing else (N = 1 included)") {
  // Node sums against the box, and the rest mass matrix's rigid blocks against the box: a single
  // mass point keeps the whole box's inertia along the axis, two or more integrate x^2 exactly.
  for (int axis = 0; axis < 3; ++axis)
    for (int slices : {1, 2, 3, 20, 21, 41, 100, 1001}) {
      const FlexModel b = make_beam(along(axis, BeamBoundary::FreeFree, slices, 0), "beam");
      Eigen::Vector3d expected = Eigen::Vector3d::Constant(500.0 / 12 * (4 + 100));
      expected(axis) = 500.0 / 12 * (4 + 4);
      INFO("axis " << axis << ", " << slices << " slices");
      CHECK(close(b.mass, 500, 0, 1e-14));
      CHECK(test::all_close(b.I_BBo_B, Eigen::Matrix3d(expected.asDiagonal()), 0, 1e-14));
      Eigen::Vector3d first_moment = Eigen::Vector3d::Zero();
      for (const FlexNode& n : b.flex.nodes) first_moment += n.mass * n.p_BoNi_B;
      CHECK(first_moment.norm() <= 1e-13 * 500 * 5);
    }
  // Scene 2's numbers as written in docs/scenarios.md.
  const FlexModel b = make_beam(scene2_beam(), "beam");
  CHECK(close(b.I_BBo_B(0, 0), 4333.33, 0.01, 0));
  CHECK(close(b.I_BBo_B(2, 2), 333.33, 0.01, 0));
}



TEST_CASE("high modes (k = 20) are finite, normalised and have the continuum's modal mass") {
  for (BeamBoundary bc : {BeamBoundary::FreeFree, BeamBoundary::ClampedBottom}) {
    BeamSpec s = along(2, bc, 2000, 20);
    const FlexModel m = make_beam(s, "beam");  // validate_flex passes inside
    const FlexBody& f = m.flex;
    REQUIRE(f.modes() == 40);
    const int k = 19;  // qx20
    CHECK(f.mode_names[19] == "qx20");
    CHECK(close(f.nodes.back().Phi_B(0, k), 1, 1e-14, 0));
    for (const FlexNode& n : f.nodes) {
      CHECK(n.Phi_B.allFinite());
      CHECK(n.Psi_B.allFinite());
      CHECK(n.Phi_B.col(k).norm() <= 1.0 + 1e-9);  // |phi| <= |phi(L)| = 2: the tip is the largest
    }
    // Continuum modal mass of a shape with unit end value: rho A L / 4 (integral of phi^2 = L,
    // phi(L) = +-2), to rounding: 20-point blocks of L / 100 integrate even mode 20 exactly.
    for (int l = 0; l < 20; ++l) CHECK(close(modal_mass(f, l, l), 50 * 10 / 4.0, 0, 1e-12));
    CHECK(std::abs(modal_mass(f, 0, k)) <= 1e-12 * 50 * 10 / 4.0);
    const double w = omega(s, bc == BeamBoundary::FreeFree ? free_free_root(20) : clamped_root(20), 0);
    CHECK(close(std::sqrt(f.K(k, k) / modal_mass(f, k, k)), w, 0, 1e-14));
  }
}

TEST_CASE("damping: ratios give D_k = 2 zeta_k omega_k M_k, Rayleigh gives alpha M_k + beta K_k") {
  BeamSpec s = scene2_beam(60, 2);
  s.damping.kind = BeamDamping::Kind::Ratio;
  s.damping.ratios = {0.01, 0.02, 0.03, 0.04};
  const FlexBody f = make_beam(s, "beam").flex;
  CHECK(f.D.isDiagonal(0));
  for (int k = 0; k < 4; ++k) {
    const double M = modal_mass(f, k, k), w = std::sqrt(f.K(k, k) / M);
    CHECK(close(f.D(k, k), 2 * 0.01 * (k + 1) * w * M, 0, 1e-14));
  }
  s.damping.ratios = {0.05};
  const FlexBody one = make_beam(s, "beam").flex;
  CHECK(close(one.D(3, 3), 2 * 0.05 * std::sqrt(one.K(3, 3) / modal_mass(one, 3, 3)) * modal_mass(one, 3, 3), 0, 1e-14));
  s.damping = {BeamDamping::Kind::Rayleigh, {}, 0.1, 0.2};
  const FlexBody r = make_beam(s, "beam").flex;
  for (int k = 0; k < 4; ++k) CHECK(close(r.D(k, k), 0.1 * modal_mass(r, k, k) + 0.2 * r.K(k, k), 0, 1e-14));
}

TEST_CASE("a bad beam description names the key and what is wrong") {
  struct Case {
    void (*change)(BeamSpec&);
    std::string message;
  };
  const Case cases[] = {
      {[](BeamSpec& s) { s.length = 0; }, "length: the beam's length must be positive, found 0 m"},
      {[](BeamSpec& s) { s.length = NAN; }, "length: the beam's length must be positive, found nan m"},
      {[](BeamSpec& s) { s.axis = 3; }, "axis: the long axis must be x, y or z"},
      {[](BeamSpec& s) { s.mass_per_length = -1; }, "mass_per_length: the mass per length must be positive, found -1 kg/m"},
      {[](BeamSpec& s) { s.section[2] = 10; }, "section.z: the beam lies along z: give the section's sides across it only (its length is `length`)"},
      {[](BeamSpec& s) { s.section[1] = 0; }, "section.y: the section's side along y must be positive, found 0 m"},
      {[](BeamSpec& s) { s.bending[2].modes = 1; }, "bending.z: the beam lies along z: it bends along the two other axes only"},
      {[](BeamSpec& s) { s.bending[0].modes = -1; }, "bending.x.modes: the number of modes must be 0 to 100, found -1"},
      {[](BeamSpec& s) { s.bending[1].modes = 101; }, "bending.y.modes: the number of modes must be 0 to 100, found 101"},
      {[](BeamSpec& s) { s.bending[1].EI = 0; }, "bending.y.EI: the bending stiffness must be positive, found 0 N m^2"},
      {[](BeamSpec& s) { s.slices = 0; }, "slices: the number of slices must be 1 to 50000, found 0"},
      {[](BeamSpec& s) { s.slices = 5; }, "slices: 5 slices cannot resolve mode 2 (about 3 half-waves): use at least 6"},
      {[](BeamSpec& s) { s.boundary = BeamBoundary::ClampedTop; s.normalisation = BeamNormalisation::Top; },
       "normalisation: the beam is clamped at the top, where every shape is zero: normalise at the bottom or to unit modal mass"},
      {[](BeamSpec& s) { s.boundary = BeamBoundary::ClampedBottom; s.normalisation = BeamNormalisation::Bottom; },
       "normalisation: the beam is clamped at the bottom, where every shape is zero: normalise at the top or to unit modal mass"},
      {[](BeamSpec& s) { s.damping = {BeamDamping::Kind::Ratio, {0.1, 0.2}, 0, 0}; },
       "damping.ratios: give one damping ratio for every mode or one per mode (4), found 2"},
      {[](BeamSpec& s) { s.damping = {BeamDamping::Kind::Ratio, {-0.1}, 0, 0}; },
       "damping.ratios: a damping ratio must be >= 0, found -0.1"},
      {[](BeamSpec& s) { s.damping = {BeamDamping::Kind::Rayleigh, {}, -1, 0}; },
       "damping.alpha: Rayleigh alpha must be >= 0, found -1 1/s"},
      {[](BeamSpec& s) { s.damping = {BeamDamping::Kind::Rayleigh, {}, 0, INFINITY}; },
       "damping.beta: Rayleigh beta must be >= 0, found inf s"},
  };
  for (const Case& c : cases) {
    BeamSpec s = scene2_beam(100, 2);
    c.change(s);
    const auto problems = beam_spec_problems(s);
    REQUIRE(!problems.empty());
    CHECK(problems.front().key + ": " + problems.front().what == c.message);
    CHECK_THROWS_WITH(make_beam(s, "scene.yaml:7:5: bodies[0].flexible.beam"),
                      "scene.yaml:7:5: bodies[0].flexible.beam: " + c.message);
  }
  CHECK(beam_spec_problems(scene2_beam()).empty());
}

// Geometric stiffening (beam.hpp BeamSpec::geometric_stiffening; docs/flexible-bodies.md): node i
// carries e_i (1/2 eta^T G_i eta) with G_i,kl = -integral_0^{s_i} phi_k' phi_l' ds. Checked here
// against an independent quadrature (composite Simpson on 20000 panels of the closed-form
// derivative beam_shape(...).dphi) and against the properties the foreshortening must have.
TEST_CASE("geometric stiffening: G_i = -integral from the clamp of phi_k' phi_l', e from the clamp to the tip") {
  for (BeamBoundary b : {BeamBoundary::ClampedBottom, BeamBoundary::ClampedTop}) {
    BeamSpec s = along(0, b, 40, 3);
    s.bending[1] = BeamPlane{3, 14000};
    s.bending[2] = BeamPlane{2, 500};
    s.geometric_stiffening = true;
    const FlexModel m = make_beam(s, "beam");
    const FlexBody& f = m.flex;
    REQUIRE(f.geometric_stiffening);
    const int n = f.modes();
    REQUIRE(n == 5);
    const bool from_top = b == BeamBoundary::ClampedTop;
    const FlexNode& tip = from_top ? f.nodes.front() : f.nodes.back();
    const FlexNode& root = from_top ? f.nodes.back() : f.nodes.front();
    INFO((from_top ? "clamped top" : "clamped bottom"));
    // e: the long axis (x) pointing from the clamp to the free end.
    CHECK(tip.e_B == Eigen::Vector3d(from_top ? -1.0 : 1.0, 0, 0));
    // At the clamp nothing has been integrated yet.
    CHECK(root.G.cwiseAbs().maxCoeff() == 0.0);
    // Independent quadrature at the tip: the modes' normalisation c_k = 1 / phi_k(tip) (unit tip
    // displacement), phi_k' = (c_k / L) dshape/dxi; Simpson's rule on 20000 panels.
    const std::array<int, 5> plane = {1, 1, 1, 2, 2}, order = {1, 2, 3, 1, 2};
    const int panels = 20000;
    for (int k = 0; k < n; ++k)
      for (int l = 0; l < n; ++l) {
        double expected = 0;
        if (plane[k] == plane[l]) {
          const double ck = 1 / beam_shape(true, order[k], 1).phi;
          const double cl = 1 / beam_shape(true, order[l], 1).phi;
          double sum = 0;
          for (int i = 0; i <= panels; ++i) {
            const double xi = static_cast<double>(i) / panels;
            const double w = i == 0 || i == panels ? 1 : i % 2 ? 4 : 2;
            sum += w * beam_shape(true, order[k], xi).dphi * beam_shape(true, order[l], xi).dphi;
          }
          expected = -(ck * cl / s.length) * sum / (3.0 * panels);
        }
        INFO("modes " << k << ", " << l);
        CHECK(std::abs(tip.G(k, l) - expected) <= 1e-9 * std::abs(tip.G(0, 0)));
        CHECK(tip.G(k, l) == tip.G(l, k));
      }
    // Foreshortening only shortens: each G_i is negative semi-definite, and grows along the beam
    // (a node farther from the clamp moves more).
    double previous = 0;
    std::vector<const FlexNode*> along_beam;
    for (const FlexNode& node : f.nodes) along_beam.push_back(&node);
    std::stable_sort(along_beam.begin(), along_beam.end(), [&](const FlexNode* a, const FlexNode* b) {
      return from_top ? a->p_BoNi_B.x() > b->p_BoNi_B.x() : a->p_BoNi_B.x() < b->p_BoNi_B.x();
    });
    for (const FlexNode* node : along_beam) {
      const Eigen::VectorXd ev = symmetric_eigenvalues(node->G);
      CHECK(ev.maxCoeff() <= 1e-12 * std::abs(tip.G(0, 0)));
      CHECK(node->G(0, 0) <= previous);
      previous = node->G(0, 0);
    }
  }
}

TEST_CASE("geometric stiffening: first mode's tip foreshortening against the continuum value") {
  // The first cantilever mode, normalised to unit tip deflection, shortens the beam by
  // 1/2 d^2 (1/L) integral_0^1 (dphi/dxi)^2 dxi for a tip deflection d. That integral is
  // 1.16194457967 for lambda = 1.8751 (trapezoid rule on 200000 panels of the textbook form
  // cosh - cos - sigma (sinh - sin), numpy, not crossdyn's stable form), just under the 6/5 of the
  // static tip-load shape 3/2 (s/L)^2 - 1/2 (s/L)^3.
  BeamSpec s = along(0, BeamBoundary::ClampedBottom, 100, 1);
  s.bending[2] = BeamPlane{};
  s.geometric_stiffening = true;
  const FlexModel m = make_beam(s, "beam");
  const double g = -m.flex.nodes.back().G(0, 0) * s.length;  // integral_0^1 (dphi/dxi)^2
  CHECK(std::abs(g - 1.16194457967) <= 1e-10);
}

TEST_CASE("class: geometric stiffening's G at every node (ends, stations, mass points) is the integral from the clamp, symmetric to the bit") {
  // G_i,kl = -(c_k c_l / L) integral_0^{xi_i} dshape_k dshape_l dxi, checked at every node against
  // one 30-point Gauss-Legendre rule on [0, xi_i] (exact for these two low modes) of the
  // closed-form derivatives, with xi_i the node's distance from the clamp over L; both clamped ends.
  for (BeamBoundary b : {BeamBoundary::ClampedBottom, BeamBoundary::ClampedTop})
    for (int N : {6, 25}) {
      BeamSpec s = along(2, b, N, 2);
      s.geometric_stiffening = true;
      const FlexBody f = make_beam(s, "beam").flex;
      const bool from_top = b == BeamBoundary::ClampedTop;
      const double c[2] = {1 / beam_shape(true, 1, 1).phi, 1 / beam_shape(true, 2, 1).phi};
      struct Shape {
        int k;
        ShapeValue at(double xi) const { return beam_shape(true, k, xi); }
      };
      const Shape shape[2] = {{1}, {2}};
      double worst = 0;
      for (const FlexNode& node : f.nodes) {
        INFO(node.name);
        REQUIRE(node.G.rows() == 4);
        CHECK(node.G == Eigen::MatrixXd(node.G.transpose()));
        const double xi = from_top ? 0.5 - node.p_BoNi_B.z() / 10 : 0.5 + node.p_BoNi_B.z() / 10;
        for (int k = 0; k < 2; ++k)
          for (int l = 0; l < 2; ++l) {
            const double integral = xi <= 0 ? 0.0
                : boost::math::quadrature::gauss<double, 30>::integrate(
                      [&](double t) { return shape[k].at(t).dphi * shape[l].at(t).dphi; }, 0.0, xi);
            worst = std::max(worst, std::abs(node.G(k, l) + c[k] * c[l] / 10 * integral));
            CHECK(node.G(k, l + 2) == 0.0);  // across planes
          }
      }
      INFO("boundary " << static_cast<int>(b) << ", N = " << N);
      CHECK(worst <= 1e-13 * std::abs(f.nodes[from_top ? 0 : f.nodes.size() - 1].G(0, 0)));
    }
}

TEST_CASE("geometric stiffening needs a clamped beam with modes") {
  BeamSpec s = along(2, BeamBoundary::FreeFree, 20, 2);
  s.geometric_stiffening = true;
  CHECK_THROWS_WITH(make_beam(s, "beam"), Catch::Contains("geometric_stiffening") &&
                                              Catch::Contains("clamped"));
  s.boundary = BeamBoundary::ClampedBottom;
  s.bending = {};
  CHECK_THROWS_WITH(make_beam(s, "beam"), Catch::Contains("needs bending modes"));
}
