// Integrators that do not waste steps (issue 12): the dense-output methods (dopri5,
// bulirsch-stoer, cvode-adams, cvode-bdf) take the steps their tolerance allows and interpolate the
// output times; load breakpoints still end a step exactly; the CVODE methods converge, fail and
// stop like the Odeint ones; cvode-bdf handles a stiff problem cheaply. Counts, never timings.
#include <catch2/catch.hpp>

#include "core/cancel.hpp"
#include "core/dop853.hpp"
#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "tests/core/oscillator.hpp"

#include <cmath>
#include <string>
#include <vector>

using namespace crossdyn;
using test::exact;
using test::max_error;
using test::Oscillator;
using test::toy;

namespace {

// Every method of core/names.hpp's table but rk4 (fixed step), and of those every one but rkf78
// (it lands on the output times): a method added to the table is tested here without a change.
const std::vector<std::string> kAdaptive = test::adaptive_methods();
const std::vector<std::string> kDense = test::dense_methods();

IntegratorSettings settings(const std::string& method, double tol, double duration,
                            double output_step) {
  IntegratorSettings s;
  s.method = method;
  s.rtol = s.atol = tol;
  s.dt = 1e-3;
  s.duration = duration;
  s.output_step = output_step;
  return s;
}

// x1' = -lambda (x1 - cos t) - sin t, x2' = x1; x(0) = (1, 0): exact x1 = cos t, x2 = sin t.
// Stiff for lambda = 1e4 /s: an explicit method's step is bounded by its stability (about
// 3.3 / lambda for dopri5) long after the fast transient (there is none here) has gone.
class StiffLinear : public Engine {
 public:
  static constexpr double kLambda = 1e4;  // 1/s
  StiffLinear() {
    for (const char* c : {"t", "x1", "x2"}) layout_.add_extra(c, "");
  }
  const char* name() const override { return "stiff"; }
  int state_size() const override { return 2; }
  std::string state_label(int i) const override { return i == 0 ? "x1" : "x2"; }
  void pack(const TreeState&, double* x) override { x[0] = 1.0; x[1] = 0.0; }
  void rhs(double t, const double* x, double* xdot) override {
    xdot[0] = -kLambda * (x[0] - std::cos(t)) - std::sin(t);
    xdot[1] = x[0];
  }
  void accelerations(double, const double*, TreeAccel&) override {}
  const OutputLayout& layout() const override { return layout_; }
  void output_row(double t, const double* x, double* row) override {
    row[0] = t;
    row[1] = x[0];
    row[2] = x[1];
  }

 private:
  OutputLayout layout_;
};

}  // namespace

TEST_CASE("dense output at an output time matches a run whose duration ends there, to the "
          "stepper's tolerance") {
  const System s = toy(true);  // a torque step at 1.3 s
  constexpr double kTol = 1e-9;
  for (const std::string& m : kDense) {
    Oscillator e(s);
    const RunResult whole = simulate(e, s, TreeState{}, settings(m, kTol, 2.0, 0.1));
    REQUIRE_FALSE(whole.failure);
    REQUIRE(whole.rows() == 21);
    for (int k : {3, 7, 12, 17}) {  // t = 0.3, 0.7, 1.2, 1.7 s: inside steps, before and after the jump
      const double t = 0.1 * k;
      Oscillator e2(s);
      const RunResult stop = simulate(e2, s, TreeState{}, settings(m, kTol, t, t));
      REQUIRE_FALSE(stop.failure);
      REQUIRE(stop.rows() == 2);
      const Eigen::Vector2d dense(whole.at(k, 1), whole.at(k, 2));
      const Eigen::Vector2d ended(stop.at(1, 1), stop.at(1, 2));
      INFO(m << " t " << t << " dense - ended " << (dense - ended).norm() << " dense - exact "
             << (dense - exact(s, t)).norm() << " ended - exact " << (ended - exact(s, t)).norm());
      CHECK(whole.at(k, 0) == Approx(t).margin(1e-15));
      // Within a few tolerances of each other (the local tolerance: both have the same global
      // error up to the last step); linear interpolation between steps would be off by ~1e-3.
      CHECK((dense - ended).norm() < 50 * kTol);
      CHECK((dense - exact(s, t)).norm() < 200 * kTol);
    }
  }
}

TEST_CASE("the dense-output methods' steps and right-hand sides do not grow with the number of "
          "output rows, and rkf78's do (it lands on every output time)") {
  const System s = toy(false);
  for (const std::string& m : kAdaptive) {
    Oscillator e10(s), e2000(s);
    const RunResult few = simulate(e10, s, TreeState{}, settings(m, 1e-10, 20.0, 2.0));
    const RunResult many = simulate(e2000, s, TreeState{}, settings(m, 1e-10, 20.0, 0.01));
    REQUIRE_FALSE(few.failure);
    REQUIRE_FALSE(many.failure);
    REQUIRE(few.rows() == 11);
    REQUIRE(many.rows() == 2001);
    INFO(m << ": rhs " << few.stats.rhs_calls << " vs " << many.stats.rhs_calls << ", steps "
           << few.stats.steps << " vs " << many.stats.steps);
    if (m == "rkf78") {
      CHECK(many.stats.steps >= 2000);  // at least one step per output interval
      CHECK(many.stats.rhs_calls > 2 * few.stats.rhs_calls);
    } else {
      // dop853 evaluates its continuous extension's 3 stages in each step that holds an output
      // time (core/dop853.hpp): at most 3 more per step, whatever the number of rows.
      const long extension = m == "dop853" ? 3 * many.stats.steps : 0;
      CHECK(many.stats.rhs_calls - few.stats.rhs_calls <= extension + 0.03 * few.stats.rhs_calls);
      CHECK(few.stats.rhs_calls - many.stats.rhs_calls <= 0.03 * few.stats.rhs_calls);
      CHECK(std::abs(many.stats.steps - few.stats.steps) <= 0.03 * few.stats.steps + 1);
      CHECK(many.stats.steps < 2000);  // fewer steps than output rows
    }
    // Same answer at the shared rows (t = 0, 2, ..., 20 s), to the tolerance.
    for (std::size_t k = 0; k < few.rows(); ++k)
      CHECK(std::abs(few.at(k, 1) - many.at(200 * k, 1)) < 1e-7);
  }
}

TEST_CASE("a load breakpoint ends a step exactly with every adaptive method: the state there is "
          "the exact solution's") {
  // The torque steps at 1.25 s, which is not an output time of the 0.1 s grid.
  const System s = toy(true, 1.25);
  for (const std::string& m : kAdaptive) {
    Oscillator e(s);
    std::vector<double> step_ends;
    const RunResult r = simulate(e, s, TreeState{}, settings(m, 1e-11, 2.0, 0.1), {},
                                 [&](double t, const RunStats&) { step_ends.push_back(t); });
    REQUIRE_FALSE(r.failure);
    INFO(m << ": max error " << max_error(s, r) << ", rhs " << r.stats.rhs_calls);
    bool landed = false;
    for (double t : step_ends) landed = landed || t == 1.25;
    CHECK(landed);  // a step ends on the breakpoint itself, not near it
    CHECK(max_error(s, r) < 1e-8);
    // On an output grid that holds the breakpoint, the row there is exact to the tolerance.
    Oscillator e2(s);
    const RunResult fine = simulate(e2, s, TreeState{}, settings(m, 1e-11, 2.0, 0.05));
    REQUIRE_FALSE(fine.failure);
    REQUIRE(fine.at(25, 0) == 1.25);
    CHECK((Eigen::Vector2d(fine.at(25, 1), fine.at(25, 2)) - exact(s, 1.25)).norm() < 1e-8);
  }
}

TEST_CASE("the new integrators converge on the oscillator: the error falls as the tolerance "
          "tightens") {
  const System s = toy(true);
  for (const std::string m : {"bulirsch-stoer", "cvode-adams", "cvode-bdf"}) {
    std::vector<double> errors;
    for (double tol : {1e-5, 1e-7, 1e-9, 1e-11}) {
      Oscillator e(s);
      const RunResult r = simulate(e, s, TreeState{}, settings(m, tol, 2.0, 0.1));
      REQUIRE_FALSE(r.failure);
      errors.push_back(max_error(s, r));
    }
    INFO(m << ": errors " << errors[0] << " " << errors[1] << " " << errors[2] << " " << errors[3]);
    for (std::size_t i = 1; i < errors.size(); ++i) CHECK(errors[i] < errors[i - 1] / 5);
    CHECK(errors.back() < 1e-8);
  }
}

TEST_CASE("cvode-bdf solves a stiff linear problem with far fewer right-hand sides than dopri5") {
  System s;
  IntegratorSettings st = settings("cvode-bdf", 1e-8, 10.0, 0.5);
  StiffLinear bdf_engine, dopri_engine;
  const RunResult bdf = simulate(bdf_engine, s, TreeState{}, st);
  st.method = "dopri5";
  const RunResult dopri = simulate(dopri_engine, s, TreeState{}, st);
  REQUIRE_FALSE(bdf.failure);
  REQUIRE_FALSE(dopri.failure);
  INFO("rhs calls: cvode-bdf " << bdf.stats.rhs_calls << ", dopri5 " << dopri.stats.rhs_calls);
  CHECK(bdf.stats.rhs_calls * 20 < dopri.stats.rhs_calls);
  for (const RunResult* r : {&bdf, &dopri})
    for (std::size_t k = 0; k < r->rows(); ++k) {
      const double t = r->at(k, 0);
      CHECK(std::abs(r->at(k, 1) - std::cos(t)) < 1e-6);
      CHECK(std::abs(r->at(k, 2) - std::sin(t)) < 1e-6);
    }
}

TEST_CASE("an interrupt stops a CVODE run like an Odeint one: failure \"interrupted\" at its time") {
  const System s = toy(false);
  for (const std::string& m : kAdaptive) {
    Oscillator e(s);
    const RunResult r = simulate(e, s, TreeState{}, settings(m, 1e-10, 2.0, 0.1), {},
                                 [](double t, const RunStats&) {
                                   if (t > 0.5) cancel::request_interrupt();
                                 });
    cancel::detail::reset_interrupt_for_tests();
    INFO(m);
    REQUIRE(r.failure);
    CHECK(r.failure->reason() == "interrupted");
    CHECK(r.failure->time() > 0.5);
    CHECK(r.failure->time() < 1.0);  // at the next step attempt, not at the end
    CHECK(r.rows() >= 6);            // the rows up to 0.5 s are kept
    CHECK(r.rows() < 21);
  }
}

namespace {

// y1' = y2, y2' = -sin y1 + 0.3 cos(1.7 t) (1 + y1^2), y3' = y1 y2 - y3: nonlinear and
// non-autonomous, so that every order condition of the method (not only those of linear
// problems) enters its local error.
struct Pendulum {
  void operator()(const std::vector<double>& y, std::vector<double>& dy, double t) const {
    dy[0] = y[1];
    dy[1] = -std::sin(y[0]) + 0.3 * std::cos(1.7 * t) * (1 + y[0] * y[0]);
    dy[2] = y[0] * y[1] - y[2];
  }
};

// One step of DOP853 of exactly h from (y0, t0) (tolerances so loose that it is accepted).
std::vector<double> dop853_step(const std::vector<double>& y0, double t0, double h,
                                std::vector<double>* dense_at = nullptr, double s = 0) {
  integrate_detail::Dop853 stepper(1e30, 1e30);
  stepper.initialize(y0, t0, h);
  const Pendulum f;
  const auto step = stepper.do_step(f);
  REQUIRE(step.second - step.first == Approx(h).margin(1e-15));
  if (dense_at) stepper.calc_state(t0 + s * h, *dense_at);
  return stepper.current_state();
}

// The solution at t0 + h to ~1e-16: 64 steps of h / 64 (each with local error ~64^-9 of one).
std::vector<double> reference(std::vector<double> y, double t0, double h) {
  for (int i = 0; i < 64; ++i) y = dop853_step(y, t0 + i * h / 64, h / 64);
  return y;
}

double distance(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}

}  // namespace

TEST_CASE("dop853 has order 8 and its dense output order 7: local errors fall as h^9 and h^8") {
  // A transcription error in any coefficient (c, a, b, d) lowers one of these orders.
  const std::vector<double> y0{0.9, -0.4, 0.2};
  const double t0 = 0.3;
  std::vector<double> step_errors, dense_errors;
  for (double h : {0.4, 0.2, 0.1}) {
    std::vector<double> dense;
    const double s = 0.37;
    const std::vector<double> y1 = dop853_step(y0, t0, h, &dense, s);
    step_errors.push_back(distance(y1, reference(y0, t0, h)));
    dense_errors.push_back(distance(dense, reference(y0, t0, s * h)));
  }
  for (std::size_t i = 1; i < step_errors.size(); ++i) {
    const double step_order = std::log2(step_errors[i - 1] / step_errors[i]);
    const double dense_order = std::log2(dense_errors[i - 1] / dense_errors[i]);
    INFO("h " << 0.4 / (1 << (i - 1)) << " -> " << 0.4 / (1 << i) << ": step errors "
              << step_errors[i - 1] << " -> " << step_errors[i] << " (slope " << step_order
              << "), dense errors " << dense_errors[i - 1] << " -> " << dense_errors[i]
              << " (slope " << dense_order << ")");
    CHECK(step_order == Approx(9.0).margin(0.6));   // local error of an order-8 method: h^9
    CHECK(dense_order == Approx(8.0).margin(0.6));  // of an order-7 extension: h^8
  }
}

TEST_CASE("dop853: a step the error test refuses is retried shorter, the hook told of each, and the "
          "accepted one keeps the tolerance") {
  integrate_detail::Dop853 stepper(1e-10, 1e-10);
  std::vector<double> tried;
  stepper.set_reject_hook([&](double t, double next_dt) {
    CHECK(t == 0.3);
    tried.push_back(next_dt);
  });
  const std::vector<double> y0{0.9, -0.4, 0.2};
  stepper.initialize(y0, 0.3, 2.0);  // far too long for 1e-10
  const auto step = stepper.do_step(Pendulum{});
  REQUIRE_FALSE(tried.empty());
  for (std::size_t i = 1; i < tried.size(); ++i) CHECK(tried[i] < tried[i - 1]);
  CHECK(step.second - step.first == Approx(tried.back()).margin(1e-15));
  CHECK(distance(stepper.current_state(), reference(y0, 0.3, tried.back())) < 1e-9);
}
