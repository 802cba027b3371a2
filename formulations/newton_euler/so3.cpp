#include "formulations/newton_euler/so3.hpp"

#include "core/rotation.hpp"

#include <cmath>

namespace crossdyn::newton_euler::so3 {

using Eigen::Matrix3d;
using Eigen::Vector3d;

Coefficients coefficients(double t) {
  Coefficients c;
  if (t < 1.0) {
    // Power series in x = t^2 (see so3.hpp); term k of each uses the factorials (2k+1)!, (2k+2)!,
    // (2k+3)!, accumulated as f1, f2, f3.
    const double x = t * t;
    double xk = 1.0, f1 = 1.0, f2 = 2.0, f3 = 6.0, sign = 1.0;
    c.s = c.a = c.b = c.a1 = c.b1 = 0.0;
    double xk_minus_1 = 0.0;  // x^(k-1), for a1 and b1
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
