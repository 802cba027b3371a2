#include "formulations/newton_euler/so3.hpp"

#include "core/rotation.hpp"

#include <cmath>

namespace crossdyn::newton_euler::so3 {

using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {
// The power series of the coefficients in x = t^2 (see so3.hpp), for t < 1: term k of each uses
// the factorials (2k+1)!, (2k+2)!, (2k+3)!, accumulated as f1, f2, f3. One body for the run's
// double and the complex step's std::complex<double> (the same operations in the same order).
template <class S, class Out>
void series(const S& x, Out& c) {
  S xk = 1.0, xk_minus_1 = 0.0;  // x^k, x^(k-1) (for a1 and b1)
  double f1 = 1.0, f2 = 2.0, f3 = 6.0, sign = 1.0;
  c.s = c.a = c.b = c.a1 = c.b1 = 0.0;
  for (int k = 0; k < 14; ++k) {
    c.s += sign * xk / f1;
    c.a += sign * xk / f2;
    c.b += sign * xk / f3;
    if (k >= 1) {
      c.a1 += sign * 2.0 * k * xk_minus_1 / f2;
      c.b1 += sign * 2.0 * k * xk_minus_1 / f3;
    }
    xk_minus_1 = xk;
    xk *= x;
    sign = -sign;
    const double n = 2.0 * k;  // next factorials: (2k+3)! = (2k+1)! (2k+2)(2k+3), ...
    f1 *= (n + 2) * (n + 3);
    f2 *= (n + 3) * (n + 4);
    f3 *= (n + 4) * (n + 5);
  }
}
}  // namespace

Coefficients coefficients(double t) {
  Coefficients c;
  if (t < 1.0) {
    series(t * t, c);
    return c;
  }
  const double st = std::sin(t), ct = std::cos(t);
  const double t2 = t * t, t3 = t2 * t;
  c.s = st / t;
  c.a = (1.0 - ct) / t2;
  c.b = (t - st) / t3;
  c.a1 = (t * st - 2.0 * (1.0 - ct)) / (t2 * t2);
  c.b1 = (3.0 * st - 2.0 * t - t * ct) / (t3 * t2);
  return c;
}

CoefficientsCx coefficients_sq(const std::complex<double>& x) {
  using C = std::complex<double>;
  CoefficientsCx c;
  if (x.real() < 1.0) {  // the series of coefficients(), in x = t^2
    series(x, c);
    return c;
  }
  const C t = std::sqrt(x);
  const C st = std::sin(t), ct = std::cos(t);
  const C t2 = x, t3 = t2 * t;
  c.s = st / t;
  c.a = (1.0 - ct) / t2;
  c.b = (t - st) / t3;
  c.a1 = (t * st - 2.0 * (1.0 - ct)) / (t2 * t2);
  c.b1 = (3.0 * st - 2.0 * t - t * ct) / (t3 * t2);
  return c;
}

Eigen::Quaternion<std::complex<double>> quaternion(const Eigen::Matrix<std::complex<double>, 3, 1>& psi) {
  using C = std::complex<double>;
  const C x = psi(0) * psi(0) + psi(1) * psi(1) + psi(2) * psi(2);
  C cw, sh;  // cos(t/2), sin(t/2)/t
  if (x.real() < 1.0) {  // cos(t/2) = sum (-1)^k (x/4)^k / (2k)!, sin(t/2)/t = 1/2 sum (-1)^k (x/4)^k / (2k+1)!
    const C y = x / 4.0;
    C yk = 1.0;
    double f0 = 1.0, f1 = 1.0, sign = 1.0;
    cw = sh = 0.0;
    for (int k = 0; k < 14; ++k) {
      cw += sign * yk / f0;
      sh += sign * yk / f1;
      yk *= y;
      sign = -sign;
      f0 *= (2.0 * k + 1) * (2.0 * k + 2);
      f1 *= (2.0 * k + 2) * (2.0 * k + 3);
    }
    sh *= 0.5;
  } else {
    const C t = std::sqrt(x);
    cw = std::cos(0.5 * t);
    sh = std::sin(0.5 * t) / t;
  }
  return Eigen::Quaternion<C>(cw, sh * psi(0), sh * psi(1), sh * psi(2));
}

Matrix3d exp(const Vector3d& psi) {
  const Coefficients c = coefficients(psi.norm());
  const Matrix3d S = rot::skew(psi);
  return Matrix3d::Identity() + c.s * S + c.a * (S * S);
}

Matrix3d left_jacobian(const Vector3d& psi) {
  const Coefficients c = coefficients(psi.norm());
  const Matrix3d S = rot::skew(psi);
  return Matrix3d::Identity() + c.a * S + c.b * (S * S);
}

Matrix3d left_jacobian_rate(const Vector3d& psi, const Vector3d& psi_dot) {
  const Coefficients c = coefficients(psi.norm());
  const Matrix3d S = rot::skew(psi), Sd = rot::skew(psi_dot);
  const double pp = psi.dot(psi_dot);
  return c.a1 * pp * S + c.a * Sd + c.b1 * pp * (S * S) + c.b * (Sd * S + S * Sd);
}

}  // namespace crossdyn::newton_euler::so3
