// Forward-mode automatic differentiation for the Lagrange engine (internal header: included only by
// formulations/lagrange/*.cpp and tests/lagrange; keep it out of widely included headers).
//
//   Dual<K>   a value a and K directional derivatives d[c] = da/de_c, stored inline (no heap).
// Evaluating f with the inputs seeded x + sum_c d_c e_c gives f and its derivatives along the K
// seed directions d_c (Griewank & Walther 2008, "Evaluating Derivatives", 2nd ed., Ch. 3, the
// tangent mode). Each operation below applies the chain rule once.
//
// Used for the time derivative along the motion (K = 1, seed q*' = B(q*) pi'), the gradient of the
// Lagrangian with respect to the quasi-coordinates (K <= 8 per chunk, seeds B(q*) e_r) and the
// derivatives of the Euler-angle kinematic matrix A (K = 2).
//
// Why not Eigen's AutoDiffScalar (unsupported/Eigen/AutoDiff)? It was this engine's first scalar;
// its expression templates made the right-hand side about twice as slow, and its atan2 returns a
// dynamic-size derivative (a heap allocation in rhs()). This type is small and tested on its own
// (tests/lagrange/test_autodiff.cpp).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>

namespace crossdyn::lagrange {

// Layout: the derivatives first, then the value, so that the derivative pairs the compiler moves
// with 16-byte loads start where whole-object copies put their 16-byte stores (with the value first,
// every d[0..1] load straddled two stores of a fresh copy: a store-forwarding stall per operation,
// most of the right-hand side's time in the Dual<5> gradient pass).
template <int K>
struct Dual {
  std::array<double, K> d{};
  double v = 0.0;

  constexpr Dual() = default;
  constexpr Dual(double value) : v(value) {}  // NOLINT: a constant converts implicitly
  // The variable x = value seeded along direction c (d = e_c).
  static Dual variable(double value, int c) {
    Dual r(value);
    r.d[static_cast<std::size_t>(c)] = 1.0;
    return r;
  }
  double value() const { return v; }

  Dual& operator+=(const Dual& b) {
    v += b.v;
    for (int c = 0; c < K; ++c) d[c] += b.d[c];
    return *this;
  }
  Dual& operator-=(const Dual& b) {
    v -= b.v;
    for (int c = 0; c < K; ++c) d[c] -= b.d[c];
    return *this;
  }
  Dual& operator*=(const Dual& b) {
    for (int c = 0; c < K; ++c) d[c] = d[c] * b.v + v * b.d[c];
    v *= b.v;
    return *this;
  }
  Dual& operator+=(double b) {
    v += b;
    return *this;
  }
  Dual& operator*=(double b) {
    v *= b;
    for (int c = 0; c < K; ++c) d[c] *= b;
    return *this;
  }
};

// f(a) with f' = df/da: value f, derivatives f' d.
template <int K>
Dual<K> chain(const Dual<K>& a, double f, double fprime) {
  Dual<K> r(f);
  for (int c = 0; c < K; ++c) r.d[c] = fprime * a.d[c];
  return r;
}

template <int K>
Dual<K> operator-(const Dual<K>& a) {
  return chain(a, -a.v, -1.0);
}
template <int K>
Dual<K> operator+(Dual<K> a, const Dual<K>& b) {
  return a += b;
}
template <int K>
Dual<K> operator-(Dual<K> a, const Dual<K>& b) {
  return a -= b;
}
template <int K>
Dual<K> operator*(const Dual<K>& a, const Dual<K>& b) {
  Dual<K> r(a.v * b.v);
  for (int c = 0; c < K; ++c) r.d[c] = a.d[c] * b.v + a.v * b.d[c];
  return r;
}
template <int K>
Dual<K> operator/(const Dual<K>& a, const Dual<K>& b) {
  const double q = a.v / b.v;
  Dual<K> r(q);
  for (int c = 0; c < K; ++c) r.d[c] = (a.d[c] - q * b.d[c]) / b.v;
  return r;
}
template <int K>
Dual<K> operator+(Dual<K> a, double b) {
  return a += b;
}
template <int K>
Dual<K> operator+(double a, Dual<K> b) {
  return b += a;
}
template <int K>
Dual<K> operator-(Dual<K> a, double b) {
  return a += -b;
}
template <int K>
Dual<K> operator-(double a, const Dual<K>& b) {
  return chain(b, a - b.v, -1.0);
}
template <int K>
Dual<K> operator*(Dual<K> a, double b) {
  return a *= b;
}
template <int K>
Dual<K> operator*(double a, Dual<K> b) {
  return b *= a;
}
template <int K>
Dual<K> operator/(Dual<K> a, double b) {
  return a *= 1.0 / b;
}
template <int K>
Dual<K> operator/(double a, const Dual<K>& b) {
  return chain(b, a / b.v, -a / (b.v * b.v));
}
template <int K>
bool operator==(const Dual<K>& a, const Dual<K>& b) {
  return a.v == b.v && a.d == b.d;
}
template <int K>
bool operator!=(const Dual<K>& a, const Dual<K>& b) {
  return !(a == b);
}

template <int K>
Dual<K> sin(const Dual<K>& a) {
  return chain(a, std::sin(a.v), std::cos(a.v));
}
template <int K>
Dual<K> cos(const Dual<K>& a) {
  return chain(a, std::cos(a.v), -std::sin(a.v));
}
template <int K>
Dual<K> exp(const Dual<K>& a) {
  const double e = std::exp(a.v);
  return chain(a, e, e);
}
template <int K>
Dual<K> sqrt(const Dual<K>& a) {
  const double s = std::sqrt(a.v);
  return chain(a, s, 0.5 / s);
}
// d atan2(y, x) = (x dy - y dx) / (x^2 + y^2).
template <int K>
Dual<K> atan2(const Dual<K>& y, const Dual<K>& x) {
  const double r2 = x.v * x.v + y.v * y.v;
  Dual<K> r(std::atan2(y.v, x.v));
  for (int c = 0; c < K; ++c) r.d[c] = (x.v * y.d[c] - y.v * x.d[c]) / r2;
  return r;
}

template <class S>
using Vec3 = Eigen::Matrix<S, 3, 1>;
template <class S>
using Mat3 = Eigen::Matrix<S, 3, 3>;

// The value part of a scalar (identity for double).
inline double value_of(double a) {
  return a;
}
template <int K>
double value_of(const Dual<K>& a) {
  return a.v;
}

// Square of the rotation angle of the unit quaternion (w, x, y, z): angle = 2 atan2(|v|, |w|), so
// |phi|^2 for the rotation vector phi of system.hpp. Differentiable everywhere on unit
// quaternions, including the identity, where sqrt(|v|^2) would give an infinite derivative: there
// atan(t)^2 = t^2 - 2 t^4 / 3 + 23 t^6 / 45 - ..., t = |v| / |w| (Abramowitz & Stegun 4.4.42),
// used while t^2 < 1e-12 (the next term is below 1e-48).
template <class S>
S rotation_angle_squared(S w, S x, S y, S z) {
  using std::atan2;
  using std::sqrt;
  if (value_of(w) < 0) {  // q and -q are the same rotation; pick the one with angle <= pi
    w = -w;
    x = -x;
    y = -y;
    z = -z;
  }
  const S s2 = x * x + y * y + z * z;
  if (value_of(s2) < 1e-12 * value_of(w * w)) {
    const S t2 = s2 / (w * w);
    return 4.0 * t2 * (1.0 + t2 * (-2.0 / 3.0 + t2 * (23.0 / 45.0)));
  }
  const S half = atan2(sqrt(s2), w);
  return 4.0 * half * half;
}

}  // namespace crossdyn::lagrange

// Dual<K> as an Eigen scalar (Eigen docs, "Using custom scalar types").
namespace Eigen {
template <int K>
struct NumTraits<crossdyn::lagrange::Dual<K>> : NumTraits<double> {
  using Real = crossdyn::lagrange::Dual<K>;
  using NonInteger = crossdyn::lagrange::Dual<K>;
  using Nested = crossdyn::lagrange::Dual<K>;
  using Literal = crossdyn::lagrange::Dual<K>;
  enum {
    IsComplex = 0,
    IsInteger = 0,
    IsSigned = 1,
    RequireInitialization = 1,
    ReadCost = K + 1,
    AddCost = K + 1,
    MulCost = 2 * K + 1
  };
};
template <int K, typename BinaryOp>
struct ScalarBinaryOpTraits<crossdyn::lagrange::Dual<K>, double, BinaryOp> {
  using ReturnType = crossdyn::lagrange::Dual<K>;
};
template <int K, typename BinaryOp>
struct ScalarBinaryOpTraits<double, crossdyn::lagrange::Dual<K>, BinaryOp> {
  using ReturnType = crossdyn::lagrange::Dual<K>;
};
}  // namespace Eigen
