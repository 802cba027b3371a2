// The automatic-differentiation type of the Lagrange engine (formulations/lagrange/autodiff.hpp)
// against functions whose derivatives are known in closed form.
#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>

#include "formulations/lagrange/autodiff.hpp"
#include "tests/support/close.hpp"

using crossdyn::lagrange::Dual;
using crossdyn::test::close;

namespace {

constexpr double kTol = 1e-14;  // derivatives of elementary functions: a few ulp

}  // namespace

TEST_CASE("Dual<K> derivatives of elementary functions equal their closed forms", "[autodiff]") {
  for (double x0 : {-2.3, -0.4, 0.3, 1.1, 2.9}) {
    for (double y0 : {-1.7, 0.2, 0.9}) {
      // Two independent variables, seeded e_1 and e_2.
      const Dual<2> x = Dual<2>::variable(x0, 0), y = Dual<2>::variable(y0, 1);
      const Dual<2> f = sin(x) * cos(y) + x * x * y - y / (1.0 + x * x);
      const double fx = cos(x0) * cos(y0) + 2 * x0 * y0 + 2 * x0 * y0 / std::pow(1 + x0 * x0, 2);
      const double fy = -sin(x0) * sin(y0) + x0 * x0 - 1 / (1 + x0 * x0);
      CHECK(close(f.d[0], fx, kTol, kTol));
      CHECK(close(f.d[1], fy, kTol, kTol));
      const Dual<2> g = atan2(y, x);  // d/dx = -y / r^2, d/dy = x / r^2
      const double r2 = x0 * x0 + y0 * y0;
      CHECK(close(g.value(), std::atan2(y0, x0), 0, kTol));
      CHECK(close(g.d[0], -y0 / r2, kTol, kTol));
      CHECK(close(g.d[1], x0 / r2, kTol, kTol));
      const Dual<2> h = sqrt(x * x + y * y);  // d/dx = x / r
      CHECK(close(h.d[0], x0 / std::sqrt(r2), kTol, kTol));
      CHECK(close(h.d[1], y0 / std::sqrt(r2), kTol, kTol));
    }
  }
}

TEST_CASE("Dual<K>: arithmetic with constants and compound assignment", "[autodiff]") {
  const Dual<3> a = Dual<3>::variable(1.5, 0), b = Dual<3>::variable(-0.5, 2);
  // f = (2 - a) / (3 a) + b / 4 - 1 / b + a * 0.5; df/da = -2 / (3 a^2) + 0.5, df/db = 1/4 + 1/b^2.
  Dual<3> f = (2.0 - a) / (3.0 * a) + b / 4.0 - 1.0 / b + a * 0.5;
  CHECK(close(f.d[0], -2.0 / (3 * 1.5 * 1.5) + 0.5, kTol, kTol));
  CHECK(f.d[1] == 0.0);
  CHECK(close(f.d[2], 0.25 + 1 / (0.25), kTol, kTol));
  f -= a;  // -1
  f *= b;  // product rule
  f += 2.0;
  const double f0 = ((2 - 1.5) / (4.5) - 0.5 / 4 + 2 + 0.75 - 1.5) * -0.5 + 2;
  CHECK(close(f.v, f0, kTol, kTol));
  CHECK(close(f.d[0], (-2.0 / (3 * 1.5 * 1.5) + 0.5 - 1) * -0.5, kTol, kTol));
  CHECK(
      close(f.d[2], (0.25 + 4) * -0.5 + ((2 - 1.5) / 4.5 - 0.5 / 4 + 2 + 0.75 - 1.5), kTol, kTol));
  // Eigen matrices of Dual<K>: a product of two matrices that depend on one variable.
  const Dual<1> t = Dual<1>::variable(0.3, 0);
  Eigen::Matrix<Dual<1>, 2, 2> P, Q;
  P << t, 2.0 * t, Dual<1>(1.0), t * t;
  Q << Dual<1>(3.0), t, -t, Dual<1>(0.5);
  const Eigen::Matrix<Dual<1>, 2, 2> PQ = P * Q;  // (PQ)' = P' Q + P Q'
  Eigen::Matrix2d Pv, Pd, Qv, Qd;
  Pv << 0.3, 0.6, 1, 0.09;
  Pd << 1, 2, 0, 0.6;
  Qv << 3, 0.3, -0.3, 0.5;
  Qd << 0, 1, -1, 0;
  const Eigen::Matrix2d expected = Pd * Qv + Pv * Qd;
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) CHECK(close(PQ(r, c).d[0], expected(r, c), kTol, kTol));
}

TEST_CASE("Dual<K> carries a seed direction through a composition (chain rule)", "[autodiff]") {
  // f(x(s), y(s)) with x = cos s, y = s^2 seeded along d/ds: f' = f_x x' + f_y y'.
  const double s0 = 0.7;
  const Dual<1> s = Dual<1>::variable(s0, 0);
  const Dual<1> x = cos(s), y = s * s;
  const Dual<1> f = exp(x * y);
  const double expected =
      std::exp(std::cos(s0) * s0 * s0) * (-std::sin(s0) * s0 * s0 + std::cos(s0) * 2 * s0);
  CHECK(close(f.d[0], expected, kTol, kTol));
}

TEST_CASE("rotation_angle_squared: value and derivative of theta^2 on both branches",
          "[autodiff]") {
  // q = (cos(theta/2), sin(theta/2) n): angle^2 = theta^2, d/dtheta = 2 theta, including at the
  // identity (series branch) where sqrt(|v|^2) alone would give an infinite derivative.
  using crossdyn::lagrange::rotation_angle_squared;
  const Eigen::Vector3d n = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
  for (double theta0 : {0.0, 1e-9, -3e-7, 1e-5, 0.01, 0.5, -1.3, 2.0, 3.1}) {
    const Dual<1> th = Dual<1>::variable(theta0, 0);
    const Dual<1> w = cos(0.5 * th), s = sin(0.5 * th);
    const Dual<1> a2 = rotation_angle_squared<Dual<1>>(w, s * n.x(), s * n.y(), s * n.z());
    CHECK(close(a2.value(), theta0 * theta0, 1e-30, 1e-14));
    CHECK(std::isfinite(a2.d[0]));
    CHECK(close(a2.d[0], 2 * theta0, 1e-15, 1e-12));
  }
  // -q is the same rotation: the angle is still |theta| <= pi.
  const double theta0 = 2.5;
  const Dual<1> th = Dual<1>::variable(theta0, 0);
  const Dual<1> w = -cos(0.5 * th), s = -sin(0.5 * th);
  const Dual<1> a2 = rotation_angle_squared<Dual<1>>(w, s * n.x(), s * n.y(), s * n.z());
  CHECK(close(a2.value(), theta0 * theta0, 0, 1e-14));
  CHECK(close(a2.d[0], 2 * theta0, 0, 1e-12));
}

TEST_CASE("Dual<K, Dual<1>>: nested forward mode gives exact second derivatives",
          "[autodiff][tangent]") {
  // Griewank & Walther 2008, Ch. 13: the inner Dual<2> holds the gradient, the outer Dual<1> (its
  // base scalar) the variation of everything along x, so d[c].d[0] is a column of the Hessian.
  using D1 = Dual<1>;
  using N2 = Dual<2, D1>;
  for (double x0 : {-1.3, 0.4, 2.1}) {
    for (double y0 : {-0.8, 0.6}) {
      const N2 x = N2::variable(D1::variable(x0, 0), 0), y = N2::variable(D1(y0), 1);
      const N2 g = sin(x) * cos(y) + exp(x * y);
      const double e = std::exp(x0 * y0);
      CHECK(close(g.v.v, std::sin(x0) * std::cos(y0) + e, kTol, kTol));
      CHECK(close(g.v.d[0], std::cos(x0) * std::cos(y0) + y0 * e, kTol, kTol));  // g_x
      CHECK(close(g.d[0].v, std::cos(x0) * std::cos(y0) + y0 * e, kTol, kTol));  // g_x
      CHECK(close(g.d[1].v, -std::sin(x0) * std::sin(y0) + x0 * e, kTol, kTol));  // g_y
      CHECK(close(g.d[0].d[0], -std::sin(x0) * std::cos(y0) + y0 * y0 * e, kTol, kTol));  // g_xx
      CHECK(close(g.d[1].d[0], -std::cos(x0) * std::sin(y0) + e + x0 * y0 * e, kTol, kTol));  // g_xy
      // atan2, sqrt, division and the base-scalar operands: h = atan2(y, x) + sqrt(x^2 + y^2) / X
      // with X the inner variable x as a constant of the inner level (only the outer part varies).
      const D1 X = D1::variable(x0, 0);
      const N2 h = atan2(y, x) + sqrt(x * x + y * y) / X - X * y + (2.0 - X) / x;
      const double r2 = x0 * x0 + y0 * y0, r = std::sqrt(r2);
      // h_x (inner) = -y/r^2 + x/(r X) - (2 - X)/x^2; its outer variation d/dx of that with X = x:
      const double hx = -y0 / r2 + x0 / (r * x0) - (2.0 - x0) / (x0 * x0);
      const double hxx = 2 * x0 * y0 / (r2 * r2) + (1 / r - x0 * x0 / (r2 * r)) / x0 -
                         x0 / (r * x0 * x0) + 1 / (x0 * x0) + 2 * (2.0 - x0) / (x0 * x0 * x0);
      const double hy = x0 / r2 + y0 / (r * x0) - x0;
      const double hyx = (y0 * y0 - x0 * x0) / (r2 * r2) - y0 * x0 / (r2 * r * x0) -
                         y0 / (r * x0 * x0) - 1.0;
      CHECK(close(h.d[0].v, hx, kTol, kTol));
      CHECK(close(h.d[1].v, hy, kTol, kTol));
      CHECK(close(h.d[0].d[0], hxx, 1e-13, 1e-13));
      CHECK(close(h.d[1].d[0], hyx, 1e-13, 1e-13));
    }
  }
}
