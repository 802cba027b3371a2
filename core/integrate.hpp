// Integrator plumbing (Boost.Odeint, SUNDIALS CVODE): runs one engine on one scene from t = 0 to
// the scene's duration and samples the engine's output row at every output time.
//
// Methods, chosen explicitly (docs/integrators.md):
//   rk4              classical Runge-Kutta, fixed step dt (clipped to land on output times)
//   dopri5           Dormand-Prince 5(4), adaptive, dense output at the output times
//   dop853           Dormand-Prince 8(5,3), adaptive, dense output of order 7 (core/dop853.hpp)
//   rkf78            Runge-Kutta-Fehlberg 7(8), adaptive, steps clipped to land on output times
//                    (no continuous extension of its order in Odeint)
//   bulirsch-stoer   Bulirsch-Stoer extrapolation, adaptive, dense output (interpolation error
//                    controlled)
//   cvode-adams      CVODE Adams-Moulton, orders 1-12, fixed-point iteration, dense output
//   cvode-bdf        CVODE BDF, orders 1-5, Newton with dense linear solver and difference-
//                    quotient Jacobian, dense output
// Adaptive steps also end exactly at the scene's load breakpoints (System::breakpoints()) and at
// the duration: no step straddles a change of load (a CVODE history restarts there).
// After every accepted step the engine's after_step() runs, before the step's output rows are
// written (they are computed first, in the coordinates the step was taken in; a step it refuses by
// throwing leaves no row past its start); when it changes the state the stepper
// is restarted (CVODE: only when the change exceeds the error it accepts in one step, weighted RMS
// norm > 1; a smaller change is dropped, since a restart costs it its order). Every right-hand-side call is counted and its result checked for non-finite values.
// The dense methods' steps and right-hand-side calls do not depend on the number of output rows.
//
// What ends a run (RunResult::failure), and what does not:
//   * A trial step of an adaptive method (all but rk4) in which any stage's
//     derivative is non-finite or diverged (|value| > 1e100) is a rejected step, like one whose
//     error estimate is too large: the step is retried 4 times shorter. Only these end the run:
//     a non-finite or diverged derivative at an accepted state, a non-finite or diverged accepted
//     state or output, a step-size underflow (below min_step), the step limit (max_steps), an
//     engine's own RunFailure, and cancellation (core/cancel.hpp: "interrupted", or
//     "timed out after N s" when a cancel::Deadline of the calling thread passed).
//   * rk4 (fixed step) has no trial steps: a non-finite or diverged derivative ends the run.
#pragma once

#include "core/engine.hpp"
#include "core/errors.hpp"
#include "core/names.hpp"
#include "core/rows.hpp"

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace crossdyn {

struct IntegratorSettings {
  Choice<Integrator> method = Integrator::Rkf78;  // core/names.hpp
  double rtol = 1e-10;
  double atol = 1e-10;
  double dt = 1e-3;              // rk4 step, s
  double first_step = 0;         // adaptive methods' first trial step, s; 0: estimated from the
                                 // derivatives at the start (integrate.cpp, Runner::first_step)
  double duration = 0;           // s
  double output_step = 0;        // s
  long max_steps = 20'000'000;   // accepted + rejected steps before the run is declared failed
  double min_step = 1e-13;       // s; an adaptive step below this is a step-size underflow
  bool keep_rows = true;         // false: rows go only to the RowCallback (long streamed runs);
                                 // true: kept in RunResult, in memory or a temporary file (rows.hpp)
  // Ending a run as soon as its pace shows it cannot finish within its step limit (`crossdyn
  // stability`: a too costly cell decided early). 0: never, the run goes to its limits. When > 0,
  // at every tenth of max_steps from the second on, the pace over the last tenth (steps per
  // simulated second) is extrapolated to the duration; a run that would need more than
  // give_up_factor x the steps left ends at once with a RunFailure "step limit: stopped early
  // after ...: at its pace ..." (deterministic: the same run stops at the same step). A
  // prediction: wrong only if the pace, measured over a tenth of the limit, improves more than
  // that factor for the rest of the run. Not for the time limit: measured by the wall clock, a
  // pace misjudged an implicit run whose steps lengthened later (newton-euler + cvode-bdf on
  // chain8 at 1e-9: predicted more than 5 x the time left after 10 s, finished in 15 s).
  double give_up_factor = 0;
  // Dense-output methods (dopri5, dop853, bulirsch-stoer) end a step at every output time instead
  // of interpolating it (the study's reference runs: a dense output's error is not controlled by
  // the tolerance; on a 60 s flexible-panel scene dop853's interpolated values of the fastest
  // modal rate were off by 3.4e-9 of its scale at rtol 1e-13, the step ends by 5e-11). Each
  // output time then costs a restart (one right-hand side, and the step regrows from there).
  bool land_on_outputs = false;
  // The rates of the engine's own E and H along its own equations of motion at every output row
  // (issue 26; `compare` sets it): columns after the engine's (rate_column_names()), each the
  // directional derivative of the engine's E (Hx, Hy, Hz) at (t, x) along (1, xdot), by the
  // sixth-order central difference over t +- h, +- 2h, +- 3h (h = kRateStep x the output step;
  // within 4h of a load or profile breakpoint the fourth-order one-sided difference on the side
  // away from it), then each one's estimated error: its difference from the next lower order plus
  // kRateUlps ulps of the largest value times the weights over h (rounding). Compared with the engine's P
  // (and M) they check, row by row, that the power the engine reports is the one its equations of
  // motion dissipate or supply. A state beside which the engine cannot be evaluated (it throws)
  // gives NaN there, and the run goes on.
  bool rate_columns = false;
  // From a scene's run block (duration, output step, method, tolerances, dt; a `run.dt` the scene
  // gives is also the first trial step).
  static IntegratorSettings from(const RunSpec& run);
};

std::vector<std::string> integrator_names();  // all_names<Integrator>(): rk4, dopri5, ..., cvode-bdf
// The names, each with what it does ("rk4 (fixed step --dt), dopri5 (adaptive, dense output), ..."):
// command-line help.
std::string integrator_help();

struct RunStats {
  long rhs_calls = 0;
  long steps = 0;           // accepted
  long rejected = 0;        // rejected trial steps (adaptive methods)
  long restarts = 0;        // after_step() changed the state
  double wall_seconds = 0;
};

// A run's output rows and how it went. The rows are in `data` (row-major, in memory) or, when
// they did not fit the program's row memory budget (core/rows.hpp), in the temporary file
// `spill` (data then empty). Read them in order with reader() or for_each_row(), which work for
// both; at() reads one value from either (from the file: one read per call).
struct RunResult {
  std::string engine;
  std::vector<std::string> columns;
  std::vector<double> data;             // row-major, rows() x columns.size(), when in memory
  std::shared_ptr<const RowFile> spill;  // the rows, when moved to a temporary file
  std::shared_ptr<const void> reservation;  // data's share of the row memory budget
  RunStats stats;
  std::optional<RunFailure> failure;  // set when the run ended early; rows before it are valid

  std::size_t rows() const;
  double at(std::size_t row, std::size_t col) const;
  int column(const std::string& name) const;  // index, or -1
  RowReader reader() const { return RowReader(&data, spill, columns.size()); }
  void for_each_row(const std::function<void(const double* row)>& f) const;
  // Takes the rows of a finished writer (replacing any rows held).
  void store(RowStore::Rows rows);
};

// Called with each finished row (columns.size() values) as soon as it is computed.
using RowCallback = std::function<void(const double* row)>;

// Called after every accepted step with the time reached and the counts so far (progress).
using StepCallback = std::function<void(double t, const RunStats& stats)>;

// Runs `engine` from `initial`. Throws InputError for bad settings (non-positive step or
// tolerance). A failing run (RunFailure from the engine or the plumbing: non-finite
// derivative or state, step-size underflow, step limit, interrupt, timeout, rows that cannot be
// stored) is returned in RunResult::failure, not thrown. cancel::poll() is called before every
// step attempt (engines poll inside long right-hand sides).
// The names of the columns IntegratorSettings::rate_columns adds, and the difference step.
inline const std::vector<std::string>& rate_column_names() {
  static const std::vector<std::string> names{"dE_dt",     "dHx_dt",     "dHy_dt",     "dHz_dt",
                                              "dE_dt.err", "dHx_dt.err", "dHy_dt.err", "dHz_dt.err"};
  return names;
}
inline constexpr double kRateStep = 2e-3;
inline constexpr double kRateUlps = 32;

RunResult simulate(Engine& engine, const System& system, const TreeState& initial,
                   const IntegratorSettings& settings, const RowCallback& on_row = {},
                   const StepCallback& on_step = {});

// Async-signal-safe: asks every running simulate() to stop (cancel::request_interrupt()).
void request_interrupt();
// Whether an interrupt was requested (long waits outside simulate() poll it), and clearing it
// (an in-process caller that runs several commands: the fuzz target, tests).
bool interrupt_requested();
void clear_interrupt();

}  // namespace crossdyn
