// A toy engine for the integrator tests: the forced harmonic oscillator x'' = -omega^2 x + F(t),
// F the piecewise-constant body-torque x-component of a one-body System, with its exact solution.
#pragma once

#include "core/integrate.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace crossdyn::test {

// The adaptive methods: every integrator name but rk4 (fixed step).
inline std::vector<std::string> adaptive_methods() {
  std::vector<std::string> out;
  for (const std::string& m : integrator_names())
    if (m != "rk4") out.push_back(m);
  return out;
}
// The adaptive methods with dense output: all but rkf78, which lands on every output time.
inline std::vector<std::string> dense_methods() {
  std::vector<std::string> out;
  for (const std::string& m : adaptive_methods())
    if (m != "rkf78") out.push_back(m);
  return out;
}

constexpr double kOmega = 2.0;  // rad/s

// x'' = -omega^2 x + F(t), x(0) = 1, v(0) = 0.
class Oscillator : public Engine {
 public:
  explicit Oscillator(const System& s) : s_(s) {
    for (const char* c : {"t", "x", "v"}) layout_.add_extra(c, "");
  }
  const char* name() const override { return "oscillator"; }
  int state_size() const override { return 2; }
  std::string state_label(int i) const override { return i == 0 ? "x" : "v"; }
  void pack(const TreeState&, double* x) override { x[0] = 1.0; x[1] = 0.0; }
  void rhs(double t, const double* x, double* xdot) override {
    xdot[0] = x[1];
    xdot[1] = -kOmega * kOmega * x[0] + s_.bodies[0].torque.value(t).x();
    if (nan_after >= 0 && t > nan_after) xdot[1] = std::nan("");
  }
  bool after_step(double, double*) override { return report_change; }
  void accelerations(double, const double*, TreeAccel&) override {}
  const OutputLayout& layout() const override { return layout_; }
  void output_row(double t, const double* x, double* row) override {
    row[0] = t;
    row[1] = x[0];
    row[2] = x[1];
  }
  double nan_after = -1;
  bool report_change = false;

 private:
  const System& s_;
  OutputLayout layout_;  // not a scene's layout: three plain columns
};

// One body; forced: a torque step from 0.8 to -0.5 at `jump` s.
inline System toy(bool forced, double jump = 1.3) {
  System s;
  s.bodies.resize(1);
  if (forced) {
    s.bodies[0].torque.times = {0.0, jump};
    s.bodies[0].torque.values = {Eigen::Vector3d(0.8, 0, 0), Eigen::Vector3d(-0.5, 0, 0)};
  }
  return s;
}

// Exact solution from x(0) = 1, v(0) = 0, piece by piece (constant force F on each piece:
// x = F/omega^2 + (x0 - F/omega^2) cos(omega tau) + v0/omega sin(omega tau)).
inline Eigen::Vector2d exact(const System& s, double t) {
  double x = 1, v = 0, ta = 0;
  std::vector<double> edges{0.0};
  for (double b : s.bodies[0].torque.times)
    if (b > 0) edges.push_back(b);
  edges.push_back(1e300);
  for (std::size_t k = 0; k + 1 < edges.size() && ta < t; ++k) {
    const double tb = std::min(edges[k + 1], t);
    const double F = s.bodies[0].torque.value(ta).x(), xs = F / (kOmega * kOmega), tau = tb - ta;
    const double xn = xs + (x - xs) * std::cos(kOmega * tau) + v / kOmega * std::sin(kOmega * tau);
    v = -(x - xs) * kOmega * std::sin(kOmega * tau) + v * std::cos(kOmega * tau);
    x = xn;
    ta = tb;
  }
  return {x, v};
}

// The largest error of the rows (t, x, v) against the exact solution.
inline double max_error(const System& s, const RunResult& r) {
  double e = 0;
  for (std::size_t i = 0; i < r.rows(); ++i)
    e = std::max(e, (Eigen::Vector2d(r.at(i, 1), r.at(i, 2)) - exact(s, r.at(i, 0))).norm());
  return e;
}

}  // namespace crossdyn::test
