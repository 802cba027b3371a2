// Run settings from the command line: the overrides of a scene's run block, checked against the
// same limits as the scene file (core/run_limits.hpp), each message naming the option.
#pragma once

#include "core/integrate.hpp"
#include "core/system.hpp"

#include <optional>
#include <string>

namespace crossdyn::harness {

struct RunOverrides {
  std::optional<std::string> integrator;
  std::optional<double> rtol, atol, dt, duration, output_step;
  std::optional<long> max_steps;
};

// Each override alone (no scene needed): InputError "--rtol nan: rtol must be a finite number...".
void check_overrides(const RunOverrides& o);

// The scene's run settings with the overrides applied, checked as a whole. InputError naming the
// option when an override is (part of) the problem, else the scene's key ("<file>: run.dt: ...").
IntegratorSettings settings_for(const System& system, const RunOverrides& o);

}  // namespace crossdyn::harness
