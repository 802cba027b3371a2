// Integrator plumbing (Boost.Odeint): runs one engine on one scene from t = 0 to the scene's
// duration and samples the engine's output row at every output time.
//
// Methods, chosen explicitly (README "Integrators"):
//   rk4              classical Runge-Kutta, fixed step dt (clipped to land on output times)
//   dopri5           Dormand-Prince 5(4), adaptive, dense output at the output times
//   rkf78            Runge-Kutta-Fehlberg 7(8), adaptive, steps clipped to land on output times
//   bulirsch-stoer   Bulirsch-Stoer extrapolation, adaptive, steps clipped likewise
// Adaptive steps are also clipped at the scene's load breakpoints (System::breakpoints()).
// After every accepted step the engine's after_step() runs; when it changes the state the stepper
// is restarted. Every right-hand-side call is counted and its result checked for non-finite values.
#pragma once

#include "core/engine.hpp"
#include "core/errors.hpp"

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace crossdyn {

struct IntegratorSettings {
  std::string method = "rkf78";
  double rtol = 1e-10;
  double atol = 1e-10;
  double dt = 1e-3;              // rk4 step; first trial step of adaptive methods
  double duration = 0;           // s
  double output_step = 0;        // s
  long max_steps = 20'000'000;   // accepted + rejected steps before the run is declared failed
  double min_step = 1e-13;       // s; an adaptive step below this is a step-size underflow
  bool keep_rows = true;         // false: rows go only to the RowCallback (long streamed runs)
  // From a scene's run block (duration, output step, method, tolerances, dt).
  static IntegratorSettings from(const RunSpec& run);
};

std::vector<std::string> integrator_names();  // rk4, dopri5, rkf78, bulirsch-stoer

struct RunStats {
  long rhs_calls = 0;
  long steps = 0;           // accepted
  long rejected = 0;        // rejected trial steps (adaptive methods)
  long restarts = 0;        // after_step() changed the state
  double wall_seconds = 0;
};

struct RunResult {
  std::string engine;
  std::vector<std::string> columns;
  std::vector<double> data;   // row-major, rows() x columns.size()
  RunStats stats;
  std::optional<RunFailure> failure;  // set when the run ended early; rows before it are valid

  std::size_t rows() const { return columns.empty() ? 0 : data.size() / columns.size(); }
  double at(std::size_t row, std::size_t col) const { return data[row * columns.size() + col]; }
  int column(const std::string& name) const;  // index, or -1
};

// Called with each finished row (columns.size() values) as soon as it is computed.
using RowCallback = std::function<void(const double* row)>;

// Runs `engine` from `initial`. Throws InputError for bad settings (unknown method, non-positive
// step or tolerance). A failing run (RunFailure from the engine or the plumbing: non-finite
// derivative or state, step-size underflow, step limit, interrupt) is returned in
// RunResult::failure, not thrown.
RunResult simulate(Engine& engine, const System& system, const TreeState& initial,
                   const IntegratorSettings& settings, const RowCallback& on_row = {});

// Async-signal-safe: asks every running simulate() to stop at its next step (Ctrl-C).
void request_interrupt();
// Whether an interrupt was requested (long waits outside simulate() poll it), and clearing it
// (an in-process caller that runs several commands: the fuzz target, tests).
bool interrupt_requested();
void clear_interrupt();

}  // namespace crossdyn
