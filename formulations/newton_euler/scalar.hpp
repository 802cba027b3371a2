// The scalar types of the Newton-Euler engine's equations (issue 27): double (the run's path) and
// Cx = std::complex<double> (the complex step of accelerations_tangent(), newton_euler.cpp;
// Martins, Sturdza & Alonso 2003, "The complex-step derivative approximation", ACM TOMS 29(3)).
// The complex step is exact only if every operation on the state is analytic: nothing may take
// |.| or conjugate. Eigen's norm(), dot() and cross() do (for complex scalars), so the templated
// equations use the helpers below; branches read real_part(). On double each helper is the call
// the engine always made (the same arithmetic, bit for bit).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>
#include <complex>
#include <type_traits>

namespace crossdyn::newton_euler {

using Cx = std::complex<double>;
template <class S> using Vec3 = Eigen::Matrix<S, 3, 1>;
template <class S> using Mat3 = Eigen::Matrix<S, 3, 3>;
template <class S> using Vec6 = Eigen::Matrix<S, 6, 1>;
template <class S> using Mat6 = Eigen::Matrix<S, 6, 6>;
template <class S> using Quat = Eigen::Quaternion<S>;

template <class S> constexpr bool kIsReal = std::is_same_v<S, double>;

inline double real_part(double v) { return v; }
inline double real_part(const Cx& v) { return v.real(); }

// a . b without conjugation.
template <class S, class A, class B>
S tdot(const A& a, const B& b) {
  if constexpr (kIsReal<S>) {
    return a.dot(b);
  } else {
    S r = a(0) * b(0);
    for (Eigen::Index i = 1; i < a.size(); ++i) r += a(i) * b(i);
    return r;
  }
}

// |v|^2 without |.| (squaredNorm() on double).
template <class S, class A>
S tsquared_norm(const A& v) {
  if constexpr (kIsReal<S>) return v.squaredNorm();
  else return tdot<S>(v, v);
}

// a x b without conjugation (Eigen's cross() conjugates a complex result).
template <class S, class A, class B>
Vec3<S> tcross(const A& a, const B& b) {
  if constexpr (kIsReal<S>) {
    return a.cross(b);
  } else {
    return Vec3<S>(a(1) * b(2) - a(2) * b(1), a(2) * b(0) - a(0) * b(2), a(0) * b(1) - a(1) * b(0));
  }
}

// [v x] (rot::skew on double).
template <class S>
Mat3<S> tskew(const Vec3<S>& v) {
  Mat3<S> m;
  m << S(0), -v.z(), v.y(), v.z(), S(0), -v.x(), -v.y(), v.x(), S(0);
  return m;
}

// atan2(y, x): on Cx its value at the real parts and its first-order imaginary part
// (x Im y - y Im x) / (x^2 + y^2), the complex step's analytic extension.
inline double tatan2(double y, double x) { return std::atan2(y, x); }
inline Cx tatan2(const Cx& y, const Cx& x) {
  const double xr = x.real(), yr = y.real();
  return Cx(std::atan2(yr, xr), (xr * y.imag() - yr * x.imag()) / (xr * xr + yr * yr));
}

// q / |q| and |q| (|q| = sqrt(w^2 + x^2 + y^2 + z^2): analytic).
template <class S>
Quat<S> unit_quaternion(const Quat<S>& q, S& norm) {
  if constexpr (kIsReal<S>) {
    norm = q.norm();
  } else {
    using std::sqrt;
    norm = sqrt(q.w() * q.w() + q.x() * q.x() + q.y() * q.y() + q.z() * q.z());
  }
  return Quat<S>(q.coeffs() / norm);
}

}  // namespace crossdyn::newton_euler
