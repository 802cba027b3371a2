// The limits on a run's settings, written once and applied both to a scene's run block (the scene
// reader) and to the command-line overrides (--duration, --output-step, --dt, --rtol, --atol,
// --integrator, --max-steps), so that the command line cannot reach what the file may not.
//
//   duration      positive, finite, at most 1e12 s
//   output_step   positive, finite, at most the duration; duration / output_step at most 1e7
//                 output rows (max_output_rows())
//   dt            positive, finite, at most 1e12 s; with rk4 (fixed step) duration / dt at most the
//                 step limit, since such a run could only end by hitting it
//   rtol, atol    positive and finite
//   integrator    a name of core/names.hpp's table (rk4, dopri5, dop853, rkf78, bulirsch-stoer, cvode-adams,
//                 cvode-bdf)
//   max_steps     at least 1
// Every check returns "" when the value is acceptable, else what is wrong, without the key or the
// option (the caller adds "run.dt" or "--dt").
#pragma once

#include "core/integrate.hpp"

#include <optional>
#include <string>

namespace crossdyn::run_limits {

inline constexpr double kMaxOutputRows = 1e7;
inline constexpr double kMaxSeconds = 1e12;  // the reader's bound on any SI value
inline constexpr double kMinSeconds = 1e-100;  // the reader's floor on any nonzero SI value

// The output-row limit in force: kMaxOutputRows, lowered only by the fuzz target (bounded work).
double max_output_rows();
void set_max_output_rows(double rows);

std::string duration_problem(double duration);
std::string output_step_problem(double output_step, double duration);
std::string dt_problem(double dt);
std::string tolerance_problem(const std::string& key, double value);  // key: "rtol" or "atol"
std::string integrator_problem(const std::string& name);  // unknown_name_message<Integrator>
std::string max_steps_problem(long max_steps);
// An adaptive method's first trial step (run.dt, --dt) below its minimum step (IntegratorSettings::
// min_step, 1e-13 s): the run would end at t = 0 with a step-size underflow.
std::string first_step_problem(double dt, double min_step);
std::string fixed_step_count_problem(double duration, double dt, long max_steps);

// The first problem of a complete set of settings: which setting ("duration", "output_step",
// "dt", "rtol", "atol", "max_steps") and what is wrong (the method, a Choice, is always valid).
struct Problem {
  std::string setting;
  std::string message;
};
std::optional<Problem> check(const IntegratorSettings& s);

}  // namespace crossdyn::run_limits
