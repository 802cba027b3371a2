// Comparing doubles with an absolute and a relative bound (docs/style.md item 9):
// close(a, b, atol, rtol) is |a - b| <= atol + rtol * |b|. Use an absolute bound where the expected
// value is zero; never compare doubles for equality.
#pragma once

#include <Eigen/Core>

#include <cmath>

namespace crossdyn::test {

inline bool close(double a, double b, double atol, double rtol) {
  return std::abs(a - b) <= atol + rtol * std::abs(b);
}

template <typename A, typename B>
bool all_close(const Eigen::MatrixBase<A>& a, const Eigen::MatrixBase<B>& b, double atol,
               double rtol) {
  return (a - b).cwiseAbs().maxCoeff() <= atol + rtol * b.cwiseAbs().maxCoeff();
}

}  // namespace crossdyn::test
