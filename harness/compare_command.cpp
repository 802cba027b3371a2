// crossdyn compare SCENE [--engines ...]: every engine (and the analytic solution where the scene
// has one) on one scene, every pinned quantity compared pairwise (see harness/compare.hpp).
#include <CLI/CLI.hpp>

#include "core/errors.hpp"
#include "core/output.hpp"
#include "core/scene/scene.hpp"
#include "harness/cli.hpp"
#include "harness/commands.hpp"
#include "harness/compare.hpp"
#include "harness/engines.hpp"
#include "harness/locations.hpp"
#include "harness/report.hpp"
#include "harness/scene_warnings.hpp"
#include "harness/settings.hpp"
#include "harness/verify.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>

namespace crossdyn {

namespace harness {

void add_compare_cli_options(CLI::App& sub, CompareCliOptions& o) {
  list_option(sub.add_option("--engines", o.engines,
                 "Comma-separated engines to run, in reference order (default: "
                 "kane,lagrange,newton-euler; engines not built yet are skipped)"));
  sub.add_option("--integrator", o.integrator,
                 known_names<Integrator>() + " (default: the scene's)");
  sub.add_option("--rtol", o.rtol, "Relative tolerance of adaptive integrators (default: the scene's)");
  sub.add_option("--atol", o.atol, "Absolute tolerance of adaptive integrators (default: the scene's)");
  sub.add_option("--dt", o.dt, "rk4 step, and the first trial step of adaptive integrators, s (default: the scene's run.dt; adaptive integrators estimate their first step when neither gives it)");
  sub.add_flag("--no-analytic", o.no_analytic,
               "Leave out the analytic solution even where the scene has one");
  sub.add_flag("--no-diagnosis", o.no_diagnosis,
               "When checks fail (every run complete), do not run the scene again at tolerances 100 "
               "times tighter to tell integration error (the differences fall) from physics (they stay)");
  sub.add_option("--max-steps", o.max_steps,
                 "Per engine run: fail the run after N steps (accepted and rejected); the other "
                 "engines and scenes go on (default 20000000)");
  sub.add_option("--timeout", o.timeout,
                 "Per engine run: fail the run after SECONDS of wall-clock time, set-up included; "
                 "the other engines and scenes go on (default: none)");
  // Test hook (hidden): a deliberately wrong copy of an engine, to show the checks catch it.
  sub.add_option("--test-inertia-scale", o.test_inertia_scale,
                 "Add a copy of ENGINE whose inertias are scaled by FACTOR (ENGINE=FACTOR), "
                 "labelled ENGINE*FACTOR; for tests")
      ->group("");
}

CompareOptions to_compare_options(const CompareCliOptions& o) {
  // The run limits on each override alone (core/run_limits.hpp); with a scene, settings_for.
  RunOverrides overrides;
  overrides.integrator = o.integrator;
  overrides.rtol = o.rtol;
  overrides.atol = o.atol;
  overrides.dt = o.dt;
  check_overrides(overrides);
  CompareOptions c;
  if (o.integrator) c.integrator = *o.integrator;  // checked above
  c.rtol = o.rtol;
  c.atol = o.atol;
  c.dt = o.dt;
  c.analytic = !o.no_analytic;
  c.diagnose = !o.no_diagnosis;
  if (o.max_steps && *o.max_steps <= 0)
    throw InputError("--max-steps: must be a positive number of steps, got " +
                     std::to_string(*o.max_steps));
  if (o.timeout && !(*o.timeout > 0 && std::isfinite(*o.timeout))) {
    char b[64];
    std::snprintf(b, sizeof b, "%g", *o.timeout);
    throw InputError(std::string("--timeout: must be a positive, finite number of seconds, got ") + b);
  }
  if (o.timeout && (*o.timeout < 1e-3 || *o.timeout > 1e9)) {  // 1e-320 s: no run could start
    char b[64];
    std::snprintf(b, sizeof b, "%g", *o.timeout);
    throw InputError(std::string("--timeout: ") + b + " s is outside the allowed range, 0.001 to 1e9 s");
  }
  c.max_steps = o.max_steps;
  c.timeout = o.timeout;
  c.progress = !o.quiet;
  const std::vector<std::string> known = engine_names();
  auto check_name = [&known](const std::string& name, const std::string& option) {
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      std::string list;
      for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
      throw InputError(option + ": unknown engine '" + name + "' (known: " + list + ")");
    }
  };
  if (!o.engines.empty()) {
    std::stringstream in(o.engines);
    std::string name;
    while (std::getline(in, name, ',')) {
      if (name.empty()) throw InputError("--engines: empty engine name in '" + o.engines + "'");
      check_name(name, "--engines");
      for (const EngineSpec& e : c.engines)
        if (e.label == name) throw InputError("--engines: '" + name + "' is listed twice");
      c.engines.push_back({name, name, {}});
    }
  } else {
    for (const std::string& name : known) c.engines.push_back({name, name, {}});
  }
  for (const std::string& spec : o.test_inertia_scale) {
    const auto eq = spec.find('=');
    if (eq == std::string::npos)
      throw InputError("--test-inertia-scale: expected ENGINE=FACTOR, found '" + spec + "'");
    const std::string name = spec.substr(0, eq), factor_text = spec.substr(eq + 1);
    check_name(name, "--test-inertia-scale");
    double factor = 0;
    try {
      std::size_t used = 0;
      factor = std::stod(factor_text, &used);
      if (used != factor_text.size()) throw std::invalid_argument("trailing characters");
    } catch (const std::exception&) {
      throw InputError("--test-inertia-scale: '" + factor_text + "' is not a number");
    }
    if (!(factor > 0)) throw InputError("--test-inertia-scale: the factor must be positive");
    EngineSpec e{name + "*" + factor_text, name, {}};
    e.options.test_inertia_scale = factor;
    c.engines.push_back(e);
  }
  return c;
}

}  // namespace harness

namespace {

struct CompareCommandOptions {
  std::string scene;
  harness::CompareCliOptions common;
  std::string json;
  bool failures_only = false;
  bool allow_no_comparison = false;
  bool strict = false;
};

int compare(const CompareCommandOptions& o) {
  // Everything that can be refused is refused before the engines run (exit 2).
  const harness::CompareOptions options = harness::to_compare_options(o.common);
  const std::string scene = harness::resolve_scene(o.scene);
  const harness::CheckedScene checked = harness::read_checked_scene(scene);
  const System& system = checked.system;
  harness::print_warnings(checked.warnings, std::cerr);  // --quiet too: it silences progress only
  // Every output against every input the scene was read from (nodal data files too).
  std::vector<NamedPath> outputs{{"standard output", "-"}};
  if (!o.json.empty()) outputs.push_back({"--json", o.json});
  check_outputs_are_not_inputs(outputs, harness::scene_inputs(system));
  harness::settings_for(system, harness::run_overrides(options));
  std::optional<AtomicFile> json;
  if (!o.json.empty()) {
    if (o.json != "-") harness::make_directories(std::filesystem::path(o.json).parent_path().string());
    json.emplace(o.json, "--json");
  }

  harness::SceneComparison c = harness::compare_scene(system, options);
  harness::require_comparison(c, o.allow_no_comparison);
  std::cout << harness::format_comparison(c, o.failures_only);
  check_written(std::cout);
  if (json) {
    harness::SceneOutcome outcome{scene, system, c, ""};
    outcome.warnings = checked.warnings;
    json->stream() << harness::json_summary({outcome});
    commit_together({&*json});
  }
  return harness::strict_status(c.passed() ? kExitOk : kExitCheckFailed, o.strict,
                                checked.warnings.size());
}

}  // namespace

void add_compare_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<CompareCommandOptions>();
  CLI::App* sub = app.add_subcommand(
      "compare",
      "Run every engine on one scene (and the analytic solution where it has one) and compare\n"
      "them at the output times: per quantity and engine pair the largest difference, when it\n"
      "happened and the tolerance (pass when max|a - b| <= atol + rtol * max|b|), and each\n"
      "engine's drift of H and E. Failures come first. Exit status 0 all pass, 1 a check failed\n"
      "or nothing was compared (or, with --strict, the scene has a warning), 2 bad input, 3 a\n"
      "write failed, 130 interrupted. Scene warnings are printed on stderr.");
  sub->add_option("scene", o->scene,
                  "Scene file (YAML), e.g. scenarios/spear1_case1.yaml, or a scene name (see "
                  "`crossdyn list`)")
      ->required();
  harness::add_compare_cli_options(*sub, o->common);
  sub->add_flag("--allow-no-comparison", o->allow_no_comparison,
                "Accept a run where nothing is compared (one engine, every quantity excluded); "
                "by default that fails with exit status 1");
  sub->add_option("--json", o->json, "Also write the comparison as JSON to FILE (atomically)");
  sub->add_flag("--failures", o->failures_only, "List only the failed checks");
  sub->add_flag("--quiet,-q", o->common.quiet, "No progress line on stderr (scene warnings are still printed)");
  sub->add_flag("--strict", o->strict,
                "Exit with status 1 when the scene has a warning and every check passed (the "
                "outputs written as usual)");
  sub->callback([o, &exit_code] { exit_code = compare(*o); });
}

}  // namespace crossdyn
