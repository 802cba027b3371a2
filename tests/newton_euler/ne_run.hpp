// Runs of the Newton-Euler engine for the simulation tests, and the output series they check
// (shared by test_simulation.cpp, test_flexible.cpp, test_ne_new_joints.cpp).
#pragma once

#include "core/integrate.hpp"
#include "formulations/newton_euler/newton_euler.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace crossdyn::test::ne {

// `system` from `initial` with integrator `method` at rtol = atol = tol; a failed run fails the
// test.
inline RunResult run_ne(const System& system, const TreeState& initial, const char* method,
                        double tol, double duration, double output_step,
                        const EngineOptions& options = {}) {
  auto e = make_newton_euler_engine(system, options);
  IntegratorSettings st;
  st.method = method;
  st.rtol = st.atol = tol;
  st.duration = duration;
  st.output_step = output_step;
  st.dt = 1e-3;
  RunResult r = simulate(*e, system, initial, st);
  if (r.failure) FAIL(r.failure->what());
  REQUIRE(r.rows() > 1);
  return r;
}

// One output column over the run.
inline std::vector<double> series(const RunResult& r, const std::string& column) {
  const int i = r.column(column);
  REQUIRE(i >= 0);
  std::vector<double> v;
  for (std::size_t k = 0; k < r.rows(); ++k) v.push_back(r.at(k, static_cast<std::size_t>(i)));
  return v;
}

inline double max_abs_change(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::abs(x - v.front()));
  return m;
}

inline double max_of(const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); }
inline double min_of(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }

}  // namespace crossdyn::test::ne
