// The integrator plumbing on a forced harmonic oscillator with a known solution: convergence order,
// accuracy of the adaptive methods across a load discontinuity, output times, failure reporting.
#include <catch2/catch.hpp>

#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "tests/core/oscillator.hpp"

#include <cmath>

using namespace crossdyn;

using test::Oscillator;
using test::exact;
using test::max_error;
using test::toy;

namespace {

IntegratorSettings settings(const std::string& method, double tol, double dt) {
  IntegratorSettings s;
  s.method = method;
  s.rtol = s.atol = tol;
  s.dt = dt;
  s.duration = 2.0;
  s.output_step = 0.1;
  return s;
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
  for (const std::string& m : test::adaptive_methods()) {
    Oscillator e(s);
    const RunResult r = simulate(e, s, TreeState{}, settings(m, 1e-12, 1e-3));
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
  for (const std::string& m : integrator_names()) {
    Oscillator e(s);
    e.nan_after = 0.55;
    const RunResult r = simulate(e, s, TreeState{}, settings(m, 1e-10, 1e-3));
    REQUIRE(r.failure);
    INFO(m << ": " << r.failure->what());
    CHECK(r.failure->engine() == "oscillator");
    CHECK(r.failure->quantity() == "d/dt v");
    if (m == "rk4") {
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

TEST_CASE("the step limit ends the run as a failure, for every method") {
  const System s = toy(false);
  for (const std::string& m : integrator_names()) {
    Oscillator e(s);
    IntegratorSettings st = settings(m, 1e-12, 1e-3);
    st.duration = 200;  // ~64 periods: more than 50 steps for every method
    st.max_steps = 50;
    const RunResult r = simulate(e, s, TreeState{}, st);
    INFO(m);
    REQUIRE(r.failure);
    CHECK(std::string(r.failure->what()).find("step limit reached (50 steps)") != std::string::npos);
    CHECK(r.stats.steps + r.stats.rejected >= 50);  // the limit counts accepted and rejected steps
    CHECK(r.stats.steps <= 50);
  }
}

TEST_CASE("a state change reported by after_step restarts the stepper without losing accuracy") {
  // The engine reports a change at every step (the values stay the same): the Odeint methods
  // restart; the CVODE methods restart only for a change beyond their one-step error
  // (integrate_cvode.cpp), so they keep their order and their accuracy.
  const System s = toy(true);
  for (const std::string& m : test::adaptive_methods()) {
    Oscillator e(s);
    e.report_change = true;
    const RunResult r = simulate(e, s, TreeState{}, settings(m, 1e-12, 1e-3));
    REQUIRE_FALSE(r.failure);
    INFO(m << " steps " << r.stats.steps << " error " << max_error(s, r));
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
