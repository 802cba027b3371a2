// A trial step that blows up is a rejected step, not a failed run (core/integrate.hpp), for every
// adaptive method; rk4 has no trial steps and fails.
//
// The system x' = -lambda x^3, x(0) = 1, lambda = 1e6 /s, has the solution
// x(t) = 1 / sqrt(1 + 2 lambda t): smooth and easy after the first microseconds. But a first trial
// step of 1 ms puts a stage at x ~ 1 - 0.2 lambda h = -199, whose derivative (~1e13) puts the next
// stage further out, and within a few stages the derivative passes 1e100 (diverged) or overflows.
#include <catch2/catch.hpp>

#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "core/output_layout.hpp"
#include "tests/core/oscillator.hpp"

#include <cmath>

using namespace crossdyn;

namespace {

constexpr double kLambda = 1e6;  // 1/s

class Cubic : public Engine {
 public:
  const char* name() const override { return "cubic"; }
  int state_size() const override { return 1; }
  std::string state_label(int) const override { return "x"; }
  void pack(const TreeState&, double* x) override { x[0] = 1.0; }
  void rhs(double, const double* x, double* xdot) override {
    xdot[0] = nan_everywhere || (nan_below_zero && x[0] < 0) ? std::nan("")
                                                              : -kLambda * x[0] * x[0] * x[0];
    if (!std::isfinite(xdot[0]) || std::abs(xdot[0]) > 1e100) ++blow_ups;
  }
  void accelerations(double, const double*, TreeAccel&) override {}
  const OutputLayout& layout() const override { return layout_; }
  void output_row(double t, const double* x, double* row) override {
    row[0] = t;
    row[1] = x[0];
  }
  long blow_ups = 0;  // right-hand-side values the plumbing must have rejected
  bool nan_everywhere = false;
  bool nan_below_zero = false;  // x < 0 is off the solution (always positive): NaN there

 private:
  OutputLayout layout_ = [] {  // not a scene's layout: two plain columns
    OutputLayout l;
    l.add_extra("t", "s");
    l.add_extra("x", "");
    return l;
  }();
};

IntegratorSettings settings(const std::string& method) {
  IntegratorSettings s;
  s.method = method;
  s.rtol = s.atol = 1e-10;
  s.dt = s.first_step = 1e-3;  // the over-large first trial step (not estimated)
  s.duration = 1.0;
  s.output_step = 0.1;
  return s;
}

}  // namespace

// The CVODE methods' implicit corrector iterations see the divergence coming and reject the
// step (a convergence failure) before any derivative passes 1e100; the variant that is NaN for
// x < 0 (where the first trial step's predictor lands) makes them meet a non-finite derivative.
TEST_CASE("every adaptive method rejects trial steps that blow up and still solves the system") {
  System system;
  for (const std::string& m : test::adaptive_methods()) {
    for (const bool nan_below_zero : {false, true}) {
      Cubic e;
      e.nan_below_zero = nan_below_zero;
      const RunResult r = simulate(e, system, TreeState{}, settings(m));
      INFO(m << (nan_below_zero ? " (NaN below zero)" : "")
             << (r.failure ? std::string(": ") + r.failure->what() : std::string()));
      REQUIRE_FALSE(r.failure);
      if (nan_below_zero || std::string(m).rfind("cvode", 0) != 0)
        CHECK(e.blow_ups > 0);        // the trial steps did blow up ...
      CHECK(r.stats.rejected >= 1);   // ... and were rejected
      REQUIRE(r.rows() == 11);
      for (std::size_t k = 0; k < r.rows(); ++k) {
        const double t = r.at(k, 0), exact = 1 / std::sqrt(1 + 2 * kLambda * t);
        CHECK(std::abs(r.at(k, 1) - exact) <= 1e-8 * std::max(1.0, exact) + 1e-9);
      }
    }
  }
}

TEST_CASE("rk4 has no trial steps: the same blow-up ends its run, naming the derivative") {
  System system;
  Cubic e;
  const RunResult r = simulate(e, system, TreeState{}, settings("rk4"));
  REQUIRE(r.failure);
  CHECK(r.failure->quantity() == "d/dt x");
  CHECK(r.failure->time() <= 1e-3);
  const std::string what = r.failure->what();
  CHECK((what.find("diverged") != std::string::npos || what.find("non-finite") != std::string::npos));
}

TEST_CASE("a non-finite derivative at the accepted state itself ends the run at once") {
  System system;
  for (const std::string& m : integrator_names()) {
    Cubic e;
    e.nan_everywhere = true;
    const RunResult r = simulate(e, system, TreeState{}, settings(m));
    INFO(m);
    REQUIRE(r.failure);
    CHECK(r.failure->time() == 0);
    CHECK(r.failure->quantity() == "d/dt x");
    CHECK(r.failure->reason() == "non-finite derivative");
    CHECK(r.stats.rejected == 0);  // no shorter step was tried: none could help
  }
}
