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
#include <cstddef>
#include <type_traits>

namespace crossdyn::lagrange {

// Nested forward mode (Griewank & Walther 2008, Ch. 13, higher derivatives by repeated tangent
// propagation): Dual<K, T> carries its value and derivatives in a base scalar T, double by default
// (Dual<K> is Dual<K, double>, the run's path, unchanged: the same members, layout and arithmetic).
// With T = Dual<1>, every value and derivative also carries its first-order variation along an
// outer direction, so that a computation written on Dual<K> derivatives (the engine's mass,
// gradient and time-derivative passes) can be differentiated once more, exactly (issue 27:
// Engine::accelerations_tangent). The operations below are written once for every T; those with a
// double operand exist for every T, those with a T operand only when T is not double.
//
// Layout: the derivatives first, then the value, so that the derivative pairs the compiler moves
// with 16-byte loads start where whole-object copies put their 16-byte stores (with the value first,
// every d[0..1] load straddled two stores of a fresh copy: a store-forwarding stall per operation,
// most of the right-hand side's time in the Dual<5> gradient pass).
template <int K, class T = double>
struct Dual {
  std::array<T, K> d{};
  T v = T(0.0);

  constexpr Dual() = default;
  constexpr Dual(double value) : v(value) {}  // NOLINT: a constant converts implicitly
  constexpr Dual(const T& value)              // NOLINT: the base scalar converts implicitly
    requires(!std::is_same_v<T, double>)
      : v(value) {}
  // The variable x = value seeded along direction c (d = e_c).
  static Dual variable(const T& value, int c) {
    Dual r(value);
    r.d[static_cast<std::size_t>(c)] = T(1.0);
    return r;
  }
  T value() const { return v; }

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
  Dual& operator+=(const T& b)
    requires(!std::is_same_v<T, double>)
  {
    v += b;
    return *this;
  }
  Dual& operator*=(const T& b)
    requires(!std::is_same_v<T, double>)
  {
    v *= b;
    for (int c = 0; c < K; ++c) d[c] *= b;
    return *this;
  }
};

// f(a) with f' = df/da: value f, derivatives f' d.
template <int K, class T>
Dual<K, T> chain(const Dual<K, T>& a, const T& f, const T& fprime) {
  Dual<K, T> r(f);
  for (int c = 0; c < K; ++c) r.d[c] = fprime * a.d[c];
  return r;
}

template <int K, class T>
Dual<K, T> operator-(const Dual<K, T>& a) {
  return chain(a, T(-a.v), T(-1.0));
}
template <int K, class T>
Dual<K, T> operator+(Dual<K, T> a, const Dual<K, T>& b) {
  return a += b;
}
template <int K, class T>
Dual<K, T> operator-(Dual<K, T> a, const Dual<K, T>& b) {
  return a -= b;
}
template <int K, class T>
Dual<K, T> operator*(const Dual<K, T>& a, const Dual<K, T>& b) {
  Dual<K, T> r(a.v * b.v);
  for (int c = 0; c < K; ++c) r.d[c] = a.d[c] * b.v + a.v * b.d[c];
  return r;
}
template <int K, class T>
Dual<K, T> operator/(const Dual<K, T>& a, const Dual<K, T>& b) {
  const T q = a.v / b.v;
  Dual<K, T> r(q);
  for (int c = 0; c < K; ++c) r.d[c] = (a.d[c] - q * b.d[c]) / b.v;
  return r;
}
template <int K, class T>
Dual<K, T> operator+(Dual<K, T> a, double b) {
  return a += b;
}
template <int K, class T>
Dual<K, T> operator+(double a, Dual<K, T> b) {
  return b += a;
}
template <int K, class T>
Dual<K, T> operator-(Dual<K, T> a, double b) {
  return a += -b;
}
template <int K, class T>
Dual<K, T> operator-(double a, const Dual<K, T>& b) {
  return chain(b, T(a - b.v), T(-1.0));
}
template <int K, class T>
Dual<K, T> operator*(Dual<K, T> a, double b) {
  return a *= b;
}
template <int K, class T>
Dual<K, T> operator*(double a, Dual<K, T> b) {
  return b *= a;
}
template <int K, class T>
Dual<K, T> operator/(Dual<K, T> a, double b) {
  return a *= 1.0 / b;
}
template <int K, class T>
Dual<K, T> operator/(double a, const Dual<K, T>& b) {
  return chain(b, T(a / b.v), T(-a / (b.v * b.v)));
}
// With the base scalar T (nested duals only; for T = double these are the overloads above).
template <int K, class T>
  requires(!std::is_same_v<T, double>)
Dual<K, T> operator+(Dual<K, T> a, const T& b) {
  return a += b;
}
template <int K, class T>
  requires(!std::is_same_v<T, double>)
Dual<K, T> operator+(const T& a, Dual<K, T> b) {
  return b += a;
}
template <int K, class T>
  requires(!std::is_same_v<T, double>)
Dual<K, T> operator-(Dual<K, T> a, const T& b) {
  return a += T(-b);
}
template <int K, class T>
  requires(!std::is_same_v<T, double>)
Dual<K, T> operator-(const T& a, const Dual<K, T>& b) {
  return chain(b, T(a - b.v), T(-1.0));
}
template <int K, class T>
  requires(!std::is_same_v<T, double>)
Dual<K, T> operator*(Dual<K, T> a, const T& b) {
  return a *= b;
}
template <int K, class T>
  requires(!std::is_same_v<T, double>)
Dual<K, T> operator*(const T& a, Dual<K, T> b) {
  return b *= a;
}
template <int K, class T>
  requires(!std::is_same_v<T, double>)
Dual<K, T> operator/(const Dual<K, T>& a, const T& b) {
  return a / Dual<K, T>(b);
}
template <int K, class T>
  requires(!std::is_same_v<T, double>)
Dual<K, T> operator/(const T& a, const Dual<K, T>& b) {
  return chain(b, T(a / b.v), T(-a / (b.v * b.v)));
}
template <int K, class T>
bool operator==(const Dual<K, T>& a, const Dual<K, T>& b) {
  return a.v == b.v && a.d == b.d;
}
template <int K, class T>
bool operator!=(const Dual<K, T>& a, const Dual<K, T>& b) {
  return !(a == b);
}

// The elementary functions: on the value std:: (T = double) or these overloads again (nested, by
// argument-dependent lookup).
template <int K, class T>
Dual<K, T> sin(const Dual<K, T>& a) {
  using std::cos;
  using std::sin;
  return chain(a, T(sin(a.v)), T(cos(a.v)));
}
template <int K, class T>
Dual<K, T> cos(const Dual<K, T>& a) {
  using std::cos;
  using std::sin;
  return chain(a, T(cos(a.v)), T(-sin(a.v)));
}
template <int K, class T>
Dual<K, T> exp(const Dual<K, T>& a) {
  using std::exp;
  const T e = exp(a.v);
  return chain(a, e, e);
}
template <int K, class T>
Dual<K, T> sqrt(const Dual<K, T>& a) {
  using std::sqrt;
  const T s = sqrt(a.v);
  return chain(a, s, T(0.5 / s));
}
// d atan2(y, x) = (x dy - y dx) / (x^2 + y^2).
template <int K, class T>
Dual<K, T> atan2(const Dual<K, T>& y, const Dual<K, T>& x) {
  using std::atan2;
  const T r2 = x.v * x.v + y.v * y.v;
  Dual<K, T> r(T(atan2(y.v, x.v)));
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
template <int K, class T>
double value_of(const Dual<K, T>& a) {
  return value_of(a.v);
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

// Dual<K, T> as an Eigen scalar (Eigen docs, "Using custom scalar types"). The costs are the
// base scalar's times the number of its operations (for T = double: K + 1, K + 1, 2 K + 1).
namespace Eigen {
template <int K, class T>
struct NumTraits<crossdyn::lagrange::Dual<K, T>> : NumTraits<double> {
  using Real = crossdyn::lagrange::Dual<K, T>;
  using NonInteger = crossdyn::lagrange::Dual<K, T>;
  using Nested = crossdyn::lagrange::Dual<K, T>;
  using Literal = crossdyn::lagrange::Dual<K, T>;
  enum {
    IsComplex = 0,
    IsInteger = 0,
    IsSigned = 1,
    RequireInitialization = 1,
    ReadCost = (K + 1) * int(NumTraits<T>::ReadCost),
    AddCost = (K + 1) * int(NumTraits<T>::AddCost),
    MulCost = (2 * K + 1) * int(NumTraits<T>::MulCost)
  };
};
template <int K, class T, typename BinaryOp>
struct ScalarBinaryOpTraits<crossdyn::lagrange::Dual<K, T>, double, BinaryOp> {
  using ReturnType = crossdyn::lagrange::Dual<K, T>;
};
template <int K, class T, typename BinaryOp>
struct ScalarBinaryOpTraits<double, crossdyn::lagrange::Dual<K, T>, BinaryOp> {
  using ReturnType = crossdyn::lagrange::Dual<K, T>;
};
}  // namespace Eigen
