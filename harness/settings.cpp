// Run settings from the command line (see settings.hpp).
#include "harness/settings.hpp"

#include "core/errors.hpp"
#include "core/run_limits.hpp"

#include <charconv>

namespace crossdyn::harness {

namespace {

std::string shortest(double x) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);
  return std::string(buf, r.ptr);
}

void require(const std::string& option, const std::string& value, const std::string& problem) {
  if (!problem.empty()) throw InputError(option + " " + value + ": " + problem);
}

}  // namespace

void check_overrides(const RunOverrides& o) {
  namespace L = run_limits;
  if (o.integrator) require("--integrator", *o.integrator, L::integrator_problem(*o.integrator));
  if (o.duration) require("--duration", shortest(*o.duration), L::duration_problem(*o.duration));
  if (o.output_step)  // against itself as the duration: the rows limit needs the scene
    require("--output-step", shortest(*o.output_step),
            L::output_step_problem(*o.output_step, o.duration.value_or(*o.output_step)));
  if (o.dt) require("--dt", shortest(*o.dt), L::dt_problem(*o.dt));
  if (o.rtol) require("--rtol", shortest(*o.rtol), L::tolerance_problem("rtol", *o.rtol));
  if (o.atol) require("--atol", shortest(*o.atol), L::tolerance_problem("atol", *o.atol));
  if (o.max_steps)
    require("--max-steps", std::to_string(*o.max_steps), L::max_steps_problem(*o.max_steps));
}

IntegratorSettings settings_for(const System& system, const RunOverrides& o) {
  check_overrides(o);
  IntegratorSettings s = IntegratorSettings::from(system.run);
  if (o.integrator) s.method = *o.integrator;
  if (o.rtol) s.rtol = *o.rtol;
  if (o.atol) s.atol = *o.atol;
  if (o.dt) s.dt = s.first_step = *o.dt;  // rk4's step and the adaptive methods' first trial step
  if (o.duration) s.duration = *o.duration;
  if (o.output_step) s.output_step = *o.output_step;
  if (o.max_steps) s.max_steps = *o.max_steps;
  const auto p = run_limits::check(s);
  if (!p) return s;
  // Blame the option that set the failing value; for a limit involving the duration (output rows,
  // rk4 step count), --duration when the value itself came from the scene.
  struct Source {
    const char* setting;
    const char* option;
    bool given;
    std::string value;
  };
  const Source sources[] = {
      {"duration", "--duration", o.duration.has_value(), shortest(s.duration)},
      {"output_step", "--output-step", o.output_step.has_value(), shortest(s.output_step)},
      {"dt", "--dt", o.dt.has_value(), shortest(s.dt)},
      {"rtol", "--rtol", o.rtol.has_value(), shortest(s.rtol)},
      {"atol", "--atol", o.atol.has_value(), shortest(s.atol)},
      {"max_steps", "--max-steps", o.max_steps.has_value(), std::to_string(s.max_steps)},
  };
  for (const Source& src : sources)
    if (p->setting == src.setting && src.given)
      throw InputError(std::string(src.option) + " " + src.value + ": " + p->message);
  // A limit that involves the duration or the step limit: the option that set one of those.
  if (p->setting == "output_step" || p->setting == "dt") {
    const std::string from_scene = " (run." + p->setting + " from the scene file)";
    if (o.duration)
      throw InputError("--duration " + shortest(s.duration) + ": " + p->message + from_scene);
    if (p->setting == "dt" && o.max_steps)
      throw InputError("--max-steps " + std::to_string(s.max_steps) + ": " + p->message + from_scene);
    if (p->setting == "dt" && o.integrator)
      throw InputError("--integrator " + s.method.str() + ": " + p->message + from_scene);
  }
  throw InputError(system.file + ": run." + p->setting + ": " + p->message);
}

}  // namespace crossdyn::harness
