// The adaptive methods' first trial step (core/integrate.cpp, Runner::first_step): the user's when
// given, else Hairer's starting-step estimate (Hairer, Norsett and Wanner I, Sec. II.4).
//
// On the oscillator x'' = -omega^2 x, x(0) = 1, v(0) = 0 (tests/core/oscillator.hpp) the estimate
// is known in closed form. With rtol = atol = tol: sk = (2 tol, tol), f0 = (0, -omega^2), so
// d0 = 1 / (2 tol), d1 = omega^2 / tol, h0 = 0.01 d0 / d1 = 0.01 / (2 omega^2); the Euler step gives
// f1 - f0 = (-omega^2 h0, 0), d2 = omega^2 / (2 tol) < d1; so h1 = (0.01 tol / omega^2)^(1/p)
// and h = min(100 h0, h1) = h1 for tol small enough (1e-8 ... 1e-12 here).
#include <catch2/catch.hpp>

#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "tests/core/oscillator.hpp"

#include <cmath>
#include <string>

using namespace crossdyn;

namespace {

IntegratorSettings settings(const std::string& method, double tol) {
  IntegratorSettings s;
  s.method = method;
  s.rtol = s.atol = tol;
  s.duration = 2.0;
  s.output_step = 1.0;  // longer than any first step here: rkf78 is not clipped
  return s;
}

struct FirstStep {
  double t = 0;        // the end of the first accepted step
  long rejected = -1;  // trial steps rejected before it
};

FirstStep first_step(const std::string& method, double tol, double given = 0) {
  const System system = test::toy(false);
  test::Oscillator e(system);
  IntegratorSettings s = settings(method, tol);
  s.first_step = given;
  FirstStep f;
  const RunResult r = simulate(e, system, TreeState{}, s, {}, [&](double t, const RunStats& st) {
    if (t > 0 && f.rejected < 0) {
      f.t = t;
      f.rejected = st.rejected;
    }
  });
  REQUIRE_FALSE(r.failure);
  return f;
}

}  // namespace

TEST_CASE("the estimated first step is Hairer's h1 = (0.01 / max(d1, d2))^(1/order)") {
  const double w2 = test::kOmega * test::kOmega;
  for (const auto& [method, order] : {std::pair<std::string, int>{"dopri5", 5}, {"dop853", 8},
                                      {"rkf78", 8}}) {
    for (const double tol : {1e-8, 1e-10, 1e-12}) {
      INFO(method << " tol " << tol);
      const FirstStep f = first_step(method, tol);
      const double h1 = std::pow(0.01 * tol / w2, 1.0 / order);
      REQUIRE(h1 < 100 * 0.01 / (2 * w2));  // h1 is the smaller bound
      CHECK(f.rejected == 0);               // the estimate is a step the tolerance accepts
      CHECK(std::abs(f.t - h1) <= 1e-12 * h1);
    }
  }
}

TEST_CASE("a given first step is the first trial step, and the estimate scales as tol^(1/order)") {
  for (const std::string method : {"dopri5", "dop853", "rkf78"}) {
    INFO(method);
    const FirstStep given = first_step(method, 1e-10, 1e-4);
    CHECK(given.rejected == 0);
    CHECK(given.t == Approx(1e-4).epsilon(1e-12));
  }
  // A 10,000-fold tighter tolerance shortens the estimated step 10^(4/p)-fold.
  CHECK(first_step("dop853", 1e-8).t / first_step("dop853", 1e-12).t ==
        Approx(std::pow(1e4, 1.0 / 8)).epsilon(1e-9));
  CHECK(first_step("dopri5", 1e-8).t / first_step("dopri5", 1e-12).t ==
        Approx(std::pow(1e4, 1.0 / 5)).epsilon(1e-9));
}

TEST_CASE("every adaptive method solves the oscillator from its estimated first step") {
  const System system = test::toy(true);
  for (const std::string& m : test::adaptive_methods()) {
    INFO(m);
    test::Oscillator e(system);
    IntegratorSettings s = settings(m, 1e-10);
    s.duration = 5.0;
    s.output_step = 0.1;
    const RunResult r = simulate(e, system, TreeState{}, s);
    REQUIRE_FALSE(r.failure);
    CHECK(test::max_error(system, r) < 1e-7);
  }
}

// An engine that refuses a step (after_step() throws: a singularity crossed inside it, say) ends the
// run before the step's rows are written: no row lies past the last step it accepted, whatever the
// method (the dense ones interpolate rows inside a step; they used to write them first).
namespace {
class Refuses : public test::Oscillator {
 public:
  using test::Oscillator::Oscillator;
  bool after_step(double t, double*) override {
    if (t > 1.0) throw RunFailure(name(), t, "x", "refused by the engine");
    last_accepted = t;
    return false;
  }
  double last_accepted = 0;
};
}  // namespace

TEST_CASE("a step the engine refuses writes no rows: none past the last accepted step") {
  const System system = test::toy(false);
  for (const std::string& m : integrator_names()) {
    INFO(m);
    Refuses e(system);
    IntegratorSettings s = settings(m, 1e-8);
    s.duration = 5.0;
    s.output_step = 0.01;  // many rows inside each dense step
    const RunResult r = simulate(e, system, TreeState{}, s);
    REQUIRE(r.failure);
    CHECK(r.failure->time() > 1.0);
    REQUIRE(r.rows() > 0);
    CHECK(r.at(r.rows() - 1, 0) <= e.last_accepted);
  }
}
