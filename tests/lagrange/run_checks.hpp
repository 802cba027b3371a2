// Checks on the output rows of a run, shared by the Lagrange engine's tests: a column's value, and
// the energy balance E(t) - E(0) = W(t) of non-conservative loads (prescribed joints, motors,
// dampers).
#pragma once

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>
#include <utility>

#include "core/integrate.hpp"

namespace crossdyn::test {

inline double col(const RunResult& r, std::size_t row, const std::string& name) {
  const int c = r.column(name);
  REQUIRE(c >= 0);
  return r.at(row, static_cast<std::size_t>(c));
}

// E(t) - E(0) against the work W(row) done up to each row: {max |E - E0 - W|, max |W|}.
template <class Work>
std::pair<double, double> work_balance(const RunResult& r, const Work& work) {
  const double E0 = col(r, 0, "E");
  double err = 0, Wmax = 0;
  for (std::size_t k = 0; k < r.rows(); ++k) {
    const double W = work(k);
    err = std::max(err, std::abs(col(r, k, "E") - E0 - W));
    Wmax = std::max(Wmax, std::abs(W));
  }
  return {err, Wmax};
}

// Energy balance E(t) - E(0) = integral_0^t power dt, the integral by Simpson's rule on the output
// rows (even rows). Returns {max |E - E0 - W|, max |W|}.
template <class Power>
std::pair<double, double> energy_balance(const RunResult& r, const Power& power) {
  const std::size_t n = r.rows();
  REQUIRE(n >= 3);
  const double E0 = col(r, 0, "E");
  double W = 0, err = 0, Wmax = 0;
  for (std::size_t k = 2; k < n; k += 2) {
    const double h = 0.5 * (col(r, k, "t") - col(r, k - 2, "t"));
    W += h / 3.0 * (power(k - 2) + 4.0 * power(k - 1) + power(k));
    err = std::max(err, std::abs(col(r, k, "E") - E0 - W));
    Wmax = std::max(Wmax, std::abs(W));
  }
  return {err, Wmax};
}

}  // namespace crossdyn::test
