// Exact rotation-vector maps for the node frames of flexible bodies (docs/flexible-bodies.md "Joints
// at nodes"): a joint frame at node i is the body frame turned by exp([psi x]), psi = Psi_i eta.
//
//   exp([psi x])   = 1 + s [psi x] + a [psi x]^2                       (Rodrigues)
//   Jl(psi)        = 1 + a [psi x] + b [psi x]^2                       (left Jacobian)
//   d/dt Jl(psi)   = a1 (psi . psi') [psi x] + a [psi' x]
//                    + b1 (psi . psi') [psi x]^2 + b ([psi' x][psi x] + [psi x][psi' x])
// with t = |psi| and
//   s = sin t / t,  a = (1 - cos t) / t^2,  b = (t - sin t) / t^3,
//   a1 = (1/t) da/dt = (t sin t - 2 (1 - cos t)) / t^4,  b1 = (1/t) db/dt = (3 sin t - 2 t - t cos t) / t^5.
// Jl is defined by  d/dt exp([psi x]) exp([psi x])^T = [(Jl(psi) psi') x]: the angular velocity of
// the turned frame relative to the unturned one, in the unturned frame's components (Barfoot 2017,
// "State Estimation for Robotics", Sec. 7.1.5, Eqs. (7.79)-(7.87); Murray, Li & Sastry 1994,
// Sec. 2.3). d/dt Jl is the time derivative of that expression along psi(t) (the product and chain
// rules applied to it; a and b depend on t only, and dt/dt = psi . psi' / t).
//
// All five coefficients are even power series in t (s = sum (-1)^k t^2k / (2k+1)!, a with
// (2k+2)!, b with (2k+3)!, a1 = sum_{k>=1} (-1)^k 2k t^(2k-2) / (2k+2)!, b1 likewise with
// (2k+3)!); below t = 1 the series are summed to 14 terms (truncation < 1e-25 relative), above it
// the closed forms lose at most ~1e-13 relative to cancellation. Every psi is exact: there is no
// small-angle simplification.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <complex>

namespace crossdyn::newton_euler::so3 {

struct Coefficients {
  double s = 1, a = 0.5, b = 1.0 / 6, a1 = -1.0 / 12, b1 = -1.0 / 60;
};

// The coefficients at t = |psi| (any t >= 0).
Coefficients coefficients(double t);

// The same coefficients on std::complex<double> (the exact tangent's complex step, scalar.hpp),
// as analytic functions of x = psi . psi (no |.|): the series in x when Re x < 1, else the closed
// forms with t = sqrt(x). On a real x they are coefficients(sqrt(x)).
struct CoefficientsCx {
  std::complex<double> s, a, b, a1, b1;
};
CoefficientsCx coefficients_sq(const std::complex<double>& x);
// The unit quaternion of exp([psi x]), (cos(t/2), sin(t/2)/t psi), on std::complex<double>, as an
// analytic function of x = psi . psi (series below Re x < 1).
Eigen::Quaternion<std::complex<double>> quaternion(const Eigen::Matrix<std::complex<double>, 3, 1>& psi);

Eigen::Matrix3d exp(const Eigen::Vector3d& psi);
Eigen::Matrix3d left_jacobian(const Eigen::Vector3d& psi);
// d/dt Jl(psi(t)) at psi with psi' = psi_dot.
Eigen::Matrix3d left_jacobian_rate(const Eigen::Vector3d& psi, const Eigen::Vector3d& psi_dot);

}  // namespace crossdyn::newton_euler::so3
