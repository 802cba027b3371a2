// exp([psi x]) and its left Jacobian Jl(psi) for the rotation vector psi of a node of a flexible
// body ([Barfoot] Sec. 7.1.5; README.md "Flexible bodies", kane_engine.hpp NodeRotation).
#include "formulations/kane/kane_internal.hpp"

#include "core/rotation.hpp"

#include <cmath>

namespace crossdyn::kane {

namespace {

// 1 / k! for k = 0..27 (power series of NodeRotation).
struct InverseFactorials {
  double v[28];
  InverseFactorials() {
    v[0] = 1;
    for (int k = 1; k < 28; ++k) v[k] = v[k - 1] / k;
  }
};
const InverseFactorials kInvFact;

}  // namespace

// ------------------------------------------------------------------------------------------------
// exp([psi x]) and the left Jacobian (kane_engine.hpp, NodeRotation; [Barfoot] Sec. 7.1.5).
//   a(t) = (1 - cos t)/t^2 = sum_k (-1)^k t^2k / (2k+2)!,  b(t) = (t - sin t)/t^3 = sum_k (-1)^k
//   t^2k / (2k+3)!,  a1 = a'(t)/t = (t sin t - 2 (1 - cos t))/t^4,  b1 = b'(t)/t =
//   (t (1 - cos t) - 3 (t - sin t))/t^5;  the series (t < 1, twelve terms: the next is below
//   1e-24) avoid the cancellation of the closed forms at small t.

void NodeRotation::set(const Vector3d& rotation_vector) {
  psi = rotation_vector;
  const double x = psi.squaredNorm();
  if (x < 1.0) {
    a = b = a1 = b1 = 0;
    double p = 1.0;  // (-x)^k
    for (int k = 0; k < 12; ++k) {
      a += p * kInvFact.v[2 * k + 2];
      b += p * kInvFact.v[2 * k + 3];
      // a1, b1: sum_{k>=1} -2k (-x)^(k-1) / (2k+2)!, / (2k+3)!
      a1 -= 2.0 * (k + 1) * p * kInvFact.v[2 * k + 4];
      b1 -= 2.0 * (k + 1) * p * kInvFact.v[2 * k + 5];
      p *= -x;
    }
  } else {
    const double t = std::sqrt(x), c = std::cos(t), sn = std::sin(t);
    a = (1.0 - c) / x;
    b = (t - sn) / (x * t);
    a1 = (t * sn - 2.0 * (1.0 - c)) / (x * x);
    b1 = (t * (1.0 - c) - 3.0 * (t - sn)) / (x * x * t);
  }
}

Matrix3d NodeRotation::R() const {
  const Matrix3d S = rot::skew(psi);
  Matrix3d R = (1.0 - psi.squaredNorm() * b) * S + a * S * S;  // sin t / t = 1 - t^2 b
  R.diagonal().array() += 1.0;
  return R;
}

Matrix3d NodeRotation::Jl() const {
  const Matrix3d S = rot::skew(psi);
  Matrix3d J = a * S + b * S * S;
  J.diagonal().array() += 1.0;
  return J;
}

// d/dt [a [psi x] + b [psi x]^2] psi' with a' = a1 (psi . psi'), b' = b1 (psi . psi') and
// psi' x psi' = 0:  a1 s (psi x psi') + b1 s psi x (psi x psi') + b psi' x (psi x psi').
Vector3d NodeRotation::Jl_dot_times(const Vector3d& psi_rate) const {
  const double s = psi.dot(psi_rate);
  const Vector3d c = psi.cross(psi_rate);
  return (a1 * s) * c + (b1 * s) * psi.cross(c) + b * psi_rate.cross(c);
}

}  // namespace crossdyn::kane
