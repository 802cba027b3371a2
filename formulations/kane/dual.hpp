// A dual number v + d eps (eps^2 = 0) for the Kane engine's exact tangent (issue 27,
// KaneEngine::accelerations_tangent, tangent.cpp): forward-mode automatic differentiation, one
// direction per evaluation (Griewank and Walther 2008, "Evaluating Derivatives", 2nd ed., Ch. 3,
// the tangent mode: every elementary operation carries the derivative of its result along with
// its value, so the derivative is exact to rounding).
//
// Internal to the Kane engine: included by formulations/kane/tangent.cpp (and by tests/kane)
// only, never by kane_engine.hpp.  Branches on values compare the value part.
#pragma once

#include <Eigen/Core>

#include <cmath>
#include <limits>

namespace crossdyn::kane {

struct Dual {
  double v = 0;  // value
  double d = 0;  // derivative along the direction
  constexpr Dual() = default;
  constexpr Dual(double value) : v(value) {}  // NOLINT: a constant (zero derivative)
  constexpr Dual(double value, double deriv) : v(value), d(deriv) {}
  Dual& operator+=(const Dual& b) {
    v += b.v;
    d += b.d;
    return *this;
  }
  Dual& operator-=(const Dual& b) {
    v -= b.v;
    d -= b.d;
    return *this;
  }
  Dual& operator*=(const Dual& b) {
    d = d * b.v + v * b.d;
    v *= b.v;
    return *this;
  }
  Dual& operator/=(const Dual& b) {
    const double q = v / b.v;
    d = (d - q * b.d) / b.v;
    v = q;
    return *this;
  }
};

inline Dual operator+(const Dual& a) { return a; }
inline Dual operator-(const Dual& a) { return {-a.v, -a.d}; }
inline Dual operator+(const Dual& a, const Dual& b) { return {a.v + b.v, a.d + b.d}; }
inline Dual operator-(const Dual& a, const Dual& b) { return {a.v - b.v, a.d - b.d}; }
inline Dual operator*(const Dual& a, const Dual& b) { return {a.v * b.v, a.d * b.v + a.v * b.d}; }
inline Dual operator/(const Dual& a, const Dual& b) {
  const double q = a.v / b.v;
  return {q, (a.d - q * b.d) / b.v};
}
inline Dual operator+(const Dual& a, double b) { return {a.v + b, a.d}; }
inline Dual operator+(double a, const Dual& b) { return {a + b.v, b.d}; }
inline Dual operator-(const Dual& a, double b) { return {a.v - b, a.d}; }
inline Dual operator-(double a, const Dual& b) { return {a - b.v, -b.d}; }
inline Dual operator*(const Dual& a, double b) { return {a.v * b, a.d * b}; }
inline Dual operator*(double a, const Dual& b) { return {a * b.v, a * b.d}; }
inline Dual operator/(const Dual& a, double b) { return {a.v / b, a.d / b}; }
inline Dual operator/(double a, const Dual& b) {
  const double q = a / b.v;
  return {q, -q * b.d / b.v};
}
inline bool operator<(const Dual& a, const Dual& b) { return a.v < b.v; }
inline bool operator>(const Dual& a, const Dual& b) { return a.v > b.v; }
inline bool operator<=(const Dual& a, const Dual& b) { return a.v <= b.v; }
inline bool operator>=(const Dual& a, const Dual& b) { return a.v >= b.v; }
inline bool operator==(const Dual& a, const Dual& b) { return a.v == b.v && a.d == b.d; }
inline bool operator!=(const Dual& a, const Dual& b) { return !(a == b); }

inline Dual sin(const Dual& a) { return {std::sin(a.v), std::cos(a.v) * a.d}; }
inline Dual cos(const Dual& a) { return {std::cos(a.v), -std::sin(a.v) * a.d}; }
// sqrt at 0 has no derivative: callers never take it there (the value part is tested first).
inline Dual sqrt(const Dual& a) {
  const double s = std::sqrt(a.v);
  return {s, a.d / (2.0 * s)};
}
// d atan2(y, x) = (x dy - y dx) / (x^2 + y^2).
inline Dual atan2(const Dual& y, const Dual& x) {
  return {std::atan2(y.v, x.v), (x.v * y.d - y.v * x.d) / (x.v * x.v + y.v * y.v)};
}
inline Dual abs(const Dual& a) { return a.v < 0 ? -a : a; }
inline bool isfinite(const Dual& a) { return std::isfinite(a.v) && std::isfinite(a.d); }

// The value and derivative parts of a double (the double instantiation of the templates).
inline double value(double a) { return a; }
inline double value(const Dual& a) { return a.v; }

}  // namespace crossdyn::kane

namespace Eigen {

// Eigen's "Using custom scalar types": a real, signed, non-integer scalar T carried on doubles,
// with its costs (Dual here; tangent.cpp's Jet too).
template <class T, int Read, int Add, int Mul>
struct KaneRealNumTraits : GenericNumTraits<double> {
  using Real = T;
  using NonInteger = T;
  using Nested = T;
  using Literal = double;
  enum {
    IsComplex = 0,
    IsInteger = 0,
    IsSigned = 1,
    RequireInitialization = 1,
    ReadCost = Read,
    AddCost = Add,
    MulCost = Mul
  };
  static inline Real epsilon() { return Real(std::numeric_limits<double>::epsilon()); }
  static inline Real dummy_precision() { return Real(1e-12); }
  static inline Real highest() { return Real(std::numeric_limits<double>::max()); }
  static inline Real lowest() { return Real(std::numeric_limits<double>::lowest()); }
  static inline int digits10() { return std::numeric_limits<double>::digits10; }
};

template <>
struct NumTraits<crossdyn::kane::Dual> : KaneRealNumTraits<crossdyn::kane::Dual, 2, 2, 3> {};

// Mixed double and Dual operands (a model constant times a state quantity) give a Dual.
template <typename BinaryOp>
struct ScalarBinaryOpTraits<crossdyn::kane::Dual, double, BinaryOp> {
  using ReturnType = crossdyn::kane::Dual;
};
template <typename BinaryOp>
struct ScalarBinaryOpTraits<double, crossdyn::kane::Dual, BinaryOp> {
  using ReturnType = crossdyn::kane::Dual;
};

}  // namespace Eigen
