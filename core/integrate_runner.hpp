// Internal to the integrator plumbing (core/integrate.cpp, core/integrate_cvode.cpp); include it
// nowhere else. The Runner drives one run: output times, load breakpoints, the checked and counted
// right-hand side, cancellation, the step limit and the after_step() hook, shared by every method.
// The Odeint methods are in integrate.cpp, the SUNDIALS CVODE ones in integrate_cvode.cpp, so
// that neither library's headers reach this file or core/integrate.hpp.
#pragma once

#include "core/integrate.hpp"

#include <cmath>
#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace crossdyn::integrate_detail {

using State = std::vector<double>;

// Largest magnitude we accept in a state or derivative before calling the run diverged.
inline constexpr double kDiverged = 1e100;

// A trial step that blew up is retried this much shorter (the Odeint methods; CVODE shrinks by its
// own factor after a recoverable right-hand-side failure, also 1/4).
inline constexpr double kBlowUpShrink = 0.25;

std::string fmt(double v);  // "%.6g"

// A stage of an adaptive trial step produced a non-finite or diverged derivative: the trial is
// rejected (integrate.hpp), not the run.
struct TrialRejected {
  std::string quantity, reason;  // "d/dt main.wx", "non-finite derivative"
};

// The right-hand side: (x, t) => dxdt through the engine, counted and checked.
// Loads are right-continuous (value(t) switches at t = breakpoint), but a step that ends on a
// breakpoint must see the load of the interval it integrates: stage times at or past the end of the
// current load interval are evaluated just before it.
// A bad derivative ends the run (RunFailure) when the method has no trial steps (rk4) or when it is
// the derivative at the accepted state itself (no shorter step can avoid it); otherwise it rejects
// the trial step (throws TrialRejected).
struct OdeSystem {
  Engine* engine;
  RunStats* stats;
  bool trial_steps = false;      // adaptive method
  double start_t = 0;            // the accepted state the current step starts from
  const State* start_x = nullptr;
  double interval_end = std::numeric_limits<double>::infinity();

  void eval(const double* x, double* dxdt, std::size_t n, double t_stage) const;
  // The form Odeint calls.
  void operator()(const State& x, State& dxdt, double t_stage) const {
    eval(x.data(), dxdt.data(), x.size(), t_stage);
  }
};

class Runner {
 public:
  Runner(Engine& engine, const System& system, const IntegratorSettings& s, RunResult& result,
         const RowCallback& on_row, const StepCallback& on_step, RowStore* rows);

  void run(State& x);
  double last_time() const { return last_t_; }

 private:
  // The methods (integrate.cpp: Odeint; integrate_cvode.cpp: CVODE).
  void fixed_rk4(State& x);
  template <class Stepper>
  void controlled(Stepper& stepper, State& x);
  template <class Stepper>
  void dense(Stepper& stepper, State& x, int stages_per_rejection, int order);
  void cvode(State& x);
  double weighted_rms_change(const double* y, const State& x) const;
  // The first trial step from (0, x) for a method of order `order`, at most h_max: the user's
  // (IntegratorSettings::first_step) or estimated; f0 is set to f(0, x) when it was computed.
  double first_step(const State& x, double h_max, int order, State& f0);

  // Computes, checks and stores (or hands on) the output row at t.
  void emit(double t, const double* x);
  // The rows of a step, computed as the step left them (the engine's coordinates as they were
  // during the step) and held back until after_step() has accepted it: hold() computes and checks
  // one, release() stores or hands on those held. A step the engine refuses leaves none.
  void hold(double t, const double* x);
  void release();
  // Called before every step attempt from the accepted state (t, x): cancellation, step limit.
  void guard(double t, const State& x);
  // Cancellation and the step limit (guard(), and each trial step retried inside a stepper).
  void limits(double t);
  // IntegratorSettings::give_up_factor: at each tenth of the step limit, the pace's prediction.
  void predict_cost(double t);
  // An adaptive step below min_step ends the run (underflow() only then; underflow_failure()
  // always). When the last rejection was a blow-up, the failure names its quantity and reason:
  // no step, however short, got past it.
  void underflow(double t, double dt) const;
  // `relation`: "below" the minimum step, or "at" it (CVODE, which never goes below it).
  [[noreturn]] void underflow_failure(double t, double dt, const char* relation) const;
  // The first load breakpoint after t (infinity if none). Within 1e-12 relative of t counts as
  // reached, so that rounding never asks for a vanishing step.
  double next_break(double t) const;
  // The next time a step must land on: the target output time or an earlier load breakpoint.
  double next_stop(double t, double target) const;
  // After an accepted step: state check, then the engine's projection or re-charting. True when
  // after_step() changed the state (the stepper must restart from it).
  bool accepted(double t, State& x);

  double last_t_ = 0;
  State start_x_;
  std::optional<TrialRejected> blow_up_;  // the last rejection, when it was a blow-up

  Engine& engine_;
  const IntegratorSettings& s_;
  RunResult& result_;
  const RowCallback& on_row_;
  const StepCallback& on_step_;
  RowStore* rows_;
  OdeSystem sys_;
  std::vector<double> outputs_;
  std::vector<double> breaks_;
  std::vector<double> row_;
  std::vector<double> held_;  // rows computed by hold(), row-major
  // rate_columns: the engine's own row width, and scratch for the differences.
  std::size_t engine_width_ = 0;
  std::vector<double> xdot_, xs_, side_;
  void rates(double t, const double* x);
  // predict_cost(): the start of the current tenth of the step limit (steps used, the simulated
  // time then), and where the next tenth begins.
  struct Pace {
    bool started = false;
    double used = 0, t = 0;
    double next = 0;
  };
  Pace pace_;
};

}  // namespace crossdyn::integrate_detail
