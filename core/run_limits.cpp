// The limits on a run's settings (see run_limits.hpp).
#include "core/run_limits.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>

namespace crossdyn::run_limits {

namespace {

double g_max_output_rows = kMaxOutputRows;

std::string shortest(double x) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);
  return std::string(buf, r.ptr);
}

// "1e+07", "2.5e+08": counts too large to print in full.
std::string approx(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", x);
  return buf;
}

// "" for a positive finite time up to kMaxSeconds.
std::string positive_time(const char* what, double x) {
  if (std::isnan(x) || std::isinf(x))
    return std::string(what) + " must be a finite number of seconds, found " + shortest(x);
  if (!(x > 0)) return std::string(what) + " must be positive, found " + shortest(x) + " s";
  if (x < kMinSeconds)  // 1e-320 s: read, then a non-finite run at t = 0
    return std::string(what) + " of " + shortest(x) + " s is too small to compute with (limit 1e-100 s)";
  if (x > kMaxSeconds)
    return std::string(what) + " of " + shortest(x) + " s is absurd (limit 1e12 s)";
  return "";
}

}  // namespace

}  // namespace crossdyn::run_limits

namespace crossdyn {
// Declared in core/integrate.hpp; the names come from the one table, core/names.hpp.
std::vector<std::string> integrator_names() { return all_names<Integrator>(); }

std::string integrator_help() {
  std::string out;
  for (const auto& n : Names<Integrator>::table) {
    const char* what = "";
    switch (n.value) {
      case Integrator::Rk4: what = "fixed step --dt"; break;
      case Integrator::Dopri5: what = "adaptive, dense output"; break;
      case Integrator::Dop853: what = "adaptive, order 8, dense output of order 7"; break;
      case Integrator::Rkf78: what = "adaptive, steps land on every output time"; break;
      case Integrator::BulirschStoer: what = "adaptive, dense output"; break;
      case Integrator::CvodeAdams: what = "adaptive multistep, nonstiff, dense output"; break;
      case Integrator::CvodeBdf: what = "adaptive multistep, stiff, dense output"; break;
    }
    out += (out.empty() ? "" : ", ") + std::string(n.name) + " (" + what + ")";
  }
  return out;
}
}  // namespace crossdyn

namespace crossdyn::run_limits {

double max_output_rows() { return g_max_output_rows; }
void set_max_output_rows(double rows) { g_max_output_rows = rows; }

std::string duration_problem(double duration) { return positive_time("duration", duration); }

std::string output_step_problem(double output_step, double duration) {
  if (std::string p = positive_time("output_step", output_step); !p.empty()) return p;
  if (output_step > duration)
    return "output_step " + shortest(output_step) + " s is longer than the duration " +
           shortest(duration) + " s";
  const double rows = duration / output_step;
  if (!(rows <= g_max_output_rows))
    return "duration / output_step = " + approx(rows) + " output rows; the limit is " +
           approx(g_max_output_rows);
  return "";
}

std::string dt_problem(double dt) { return positive_time("dt", dt); }

std::string first_step_problem(double dt, double min_step) {
  if (!(dt < min_step)) return "";
  return "dt = " + shortest(dt) + " s is the adaptive integrators' first trial step, and it is below "
         "their minimum step of " + shortest(min_step) + " s (a step-size underflow at t = 0); "
         "give a larger dt, or leave it out";
}

std::string tolerance_problem(const std::string& key, double value) {
  if (std::isnan(value) || std::isinf(value))
    return key + " must be a finite number, found " + shortest(value);
  if (value < 0) return "negative tolerance " + shortest(value);
  if (value == 0) return key + " must be positive (the step-size control needs it)";
  if (value < kMinSeconds)
    return key + " " + shortest(value) + " is too small to compute with (the allowed range is 1e-100 to 1e12)";
  if (value > kMaxSeconds)
    return key + " " + shortest(value) + " is absurd (the allowed range is 1e-100 to 1e12)";
  return "";
}

std::string integrator_problem(const std::string& name) {
  return parse_name<Integrator>(name) ? "" : unknown_name_message<Integrator>(name);
}

std::string max_steps_problem(long max_steps) {
  if (max_steps < 1) return "the step limit must be at least 1, found " + std::to_string(max_steps);
  return "";
}

std::string fixed_step_count_problem(double duration, double dt, long max_steps) {
  const double steps = std::ceil(duration / dt);
  if (!(steps <= static_cast<double>(max_steps)))
    return "rk4 with dt = " + shortest(dt) + " s needs duration / dt = " + approx(steps) +
           " steps, more than the step limit of " + std::to_string(max_steps) +
           " (a larger dt, a shorter duration or a larger --max-steps)";
  return "";
}

std::optional<Problem> check(const IntegratorSettings& s) {
  auto first = [](const char* setting, std::string message) -> std::optional<Problem> {
    if (message.empty()) return std::nullopt;
    return Problem{setting, std::move(message)};
  };
  if (auto p = first("duration", duration_problem(s.duration))) return p;
  if (auto p = first("output_step", output_step_problem(s.output_step, s.duration))) return p;
  if (auto p = first("dt", dt_problem(s.dt))) return p;
  if (s.method != Integrator::Rk4) {
    if (s.first_step > 0)
      if (auto p = first("dt", first_step_problem(s.first_step, s.min_step))) return p;
    if (auto p = first("rtol", tolerance_problem("rtol", s.rtol))) return p;
    if (auto p = first("atol", tolerance_problem("atol", s.atol))) return p;
  }
  if (auto p = first("max_steps", max_steps_problem(s.max_steps))) return p;
  if (s.method == Integrator::Rk4)
    if (auto p = first("dt", fixed_step_count_problem(s.duration, s.dt, s.max_steps))) return p;
  return std::nullopt;
}

}  // namespace crossdyn::run_limits
