// The integrator plumbing on a forced harmonic oscillator with a known solution: convergence order,
// accuracy of the adaptive methods across a load discontinuity, output times, failure reporting.
#include <catch2/catch.hpp>

#include "core/errors.hpp"
#include "core/integrate.hpp"

#include <cmath>

using namespace crossdyn;

namespace {

constexpr double kOmega = 2.0;  // rad/s

// x'' = -omega^2 x + F(t), F the piecewise-constant body torque x-component of the toy System.
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

System toy(bool forced) {
  System s;
  s.bodies.resize(1);
  if (forced) {
    s.bodies[0].torque.times = {0.0, 1.3};
    s.bodies[0].torque.values = {Eigen::Vector3d(0.8, 0, 0), Eigen::Vector3d(-0.5, 0, 0)};
  }
  return s;
}

// Exact solution from x(0) = 1, v(0) = 0, piece by piece.
Eigen::Vector2d exact(const System& s, double t) {
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

IntegratorSettings settings(const std::string& method, double tol, double dt) {
  IntegratorSettings s;
  s.method = method;
  s.rtol = s.atol = tol;
  s.dt = dt;
  s.duration = 2.0;
  s.output_step = 0.1;
  return s;
}

double max_error(const System& s, const RunResult& r) {
  double e = 0;
  for (std::size_t i = 0; i < r.rows(); ++i)
    e = std::max(e, (Eigen::Vector2d(r.at(i, 1), r.at(i, 2)) - exact(s, r.at(i, 0))).norm());
  return e;
}

}  // namespace

TEST_CASE("rk4 converges at order 4: halving the step divides the error by 16 +- 20%") {
  const System s = toy(false);
  double previous = 0;
  for (double dt : {0.02, 0.01, 0.005}) {
    Oscillator e(s);
    const RunResult r = simulate(e, s, TreeState{}, settings("rk4", 0, dt));
    REQUIRE_FALSE(r.failure);
    const double err = max_error(s, r);
    if (previous > 0) {
      INFO("dt " << dt << " error " << err << " ratio " << previous / err);
      CHECK(previous / err > 16 * 0.8);
      CHECK(previous / err < 16 * 1.2);
    }
    previous = err;
  }
}

TEST_CASE("adaptive methods land on output times and on load breakpoints") {
  const System s = toy(true);
  for (const char* m : {"dopri5", "rkf78", "bulirsch-stoer"}) {
    Oscillator e(s);
    const RunResult r = simulate(e, s, TreeState{}, settings(std::string(m), 1e-12, 1e-3));
    REQUIRE_FALSE(r.failure);
    REQUIRE(r.rows() == 21);
    for (std::size_t i = 0; i < r.rows(); ++i) CHECK(r.at(i, 0) == Approx(0.1 * i).margin(1e-15));
    INFO(m << " max error " << max_error(s, r) << " rhs calls " << r.stats.rhs_calls);
    // The jump at t = 1.3 s is resolved because no step straddles it.
    CHECK(max_error(s, r) < 1e-9);
    CHECK(r.stats.rhs_calls > 0);
  }
}

// Past t = 0.55 every derivative is NaN whatever the state: rk4 fails at its first step past it;
// an adaptive method rejects the trial steps that reach past it, shrinks them until the step-size
// underflow at t = 0.55 (to within steps of 1e-13 s), and names the derivative that stopped it.
TEST_CASE("a non-finite derivative ends the run with engine, time and quantity, keeping earlier rows") {
  const System s = toy(false);
  for (const char* m : {"rk4", "dopri5", "rkf78", "bulirsch-stoer"}) {
    Oscillator e(s);
    e.nan_after = 0.55;
    const RunResult r = simulate(e, s, TreeState{}, settings(std::string(m), 1e-10, 1e-3));
    REQUIRE(r.failure);
    INFO(m << ": " << r.failure->what());
    CHECK(r.failure->engine() == "oscillator");
    CHECK(r.failure->quantity() == "d/dt v");
    if (std::string(m) == "rk4") {
      CHECK(r.failure->time() > 0.55);
    } else {
      CHECK(r.failure->time() > 0.55 - 1e-9);
      CHECK(std::string(r.failure->what()).find("step-size underflow") != std::string::npos);
    }
    CHECK(r.failure->time() < 0.65);
    CHECK(r.rows() == 6);  // t = 0 ... 0.5
    CHECK(std::string(r.failure->what()).find("non-finite derivative") != std::string::npos);
  }
}

TEST_CASE("the step limit ends the run as a failure") {
  const System s = toy(false);
  Oscillator e(s);
  IntegratorSettings st = settings("rk4", 0, 1e-3);
  st.max_steps = 50;
  const RunResult r = simulate(e, s, TreeState{}, st);
  REQUIRE(r.failure);
  CHECK(std::string(r.failure->what()).find("step limit") != std::string::npos);
}

TEST_CASE("a state change reported by after_step restarts the stepper without losing accuracy") {
  const System s = toy(true);
  for (const char* m : {"dopri5", "rkf78", "bulirsch-stoer"}) {
    Oscillator e(s);
    e.report_change = true;
    const RunResult r = simulate(e, s, TreeState{}, settings(std::string(m), 1e-12, 1e-3));
    REQUIRE_FALSE(r.failure);
    CHECK(r.stats.restarts == r.stats.steps);
    CHECK(max_error(s, r) < 1e-9);
  }
}

TEST_CASE("bad integrator settings are input errors") {
  const System s = toy(false);
  Oscillator e(s);
  CHECK_THROWS_AS(simulate(e, s, TreeState{}, settings("euler", 1e-8, 1e-3)), InputError);
  CHECK_THROWS_AS(simulate(e, s, TreeState{}, settings("rkf78", -1e-8, 1e-3)), InputError);
  IntegratorSettings st = settings("rk4", 0, 1e-3);
  st.output_step = 0;
  CHECK_THROWS_AS(simulate(e, s, TreeState{}, st), InputError);
}
