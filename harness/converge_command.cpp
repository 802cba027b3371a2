// crossdyn converge SCENE: re-run a flexible scene with fewer modes and name the smallest model
// within the scene's tolerances (harness/converge.hpp).
#include <CLI/CLI.hpp>

#include "core/errors.hpp"
#include "core/output.hpp"
#include "core/scene/scene.hpp"
#include "harness/commands.hpp"
#include "harness/compare.hpp"
#include "harness/converge.hpp"
#include "harness/locations.hpp"
#include "harness/report.hpp"
#include "harness/settings.hpp"
#include "harness/verify.hpp"

#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>

namespace crossdyn {

namespace {

struct ConvergeOptions {
  std::string scene;
  harness::CompareCliOptions common;
  std::string engine = "kane";
  std::string json;
};

int converge(const ConvergeOptions& o) {
  // Everything that can be refused is refused before the engines run (exit 2).
  harness::CompareCliOptions cli = o.common;
  cli.engines = o.engine;
  const harness::CompareOptions options = harness::to_compare_options(cli);
  const std::string scene = harness::resolve_scene(o.scene);
  std::vector<NamedPath> outputs{{"standard output", "-"}};
  if (!o.json.empty()) outputs.push_back({"--json", o.json});
  check_outputs_are_not_inputs(outputs, {{"the scene file", scene}});
  std::vector<SceneWarning> warnings;
  const System system = read_scene(scene, &warnings);
  for (const SceneWarning& w : warnings) std::cerr << w.text() << '\n';
  harness::settings_for(system, harness::run_overrides(options));
  if (harness::mode_groups(system).empty())
    throw InputError(scene + ": converge needs a flexible body with at least one mode; this "
                             "scene has none");
  std::optional<AtomicFile> json;
  if (!o.json.empty()) {
    if (o.json != "-") harness::make_directories(std::filesystem::path(o.json).parent_path().string());
    json.emplace(o.json, "--json");
  }
  const harness::ConvergeResult r = harness::converge_scene(system, options);
  std::cout << harness::format_converge(r);
  check_written(std::cout);
  if (json) {
    json->stream() << harness::converge_json(r);
    json->commit();
  }
  return kExitOk;
}

}  // namespace

void add_converge_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<ConvergeOptions>();
  CLI::App* sub = app.add_subcommand(
      "converge",
      "Model no more than the scene needs: re-run a flexible scene with 0, 1, ... n modes of\n"
      "every mode group (the beam generator's bending planes qx, qy), compare each run with the\n"
      "full model's on every quantity with the scene's tolerances, and name the smallest model\n"
      "that stays within them. Exit status 0 done, 2 bad input (or no flexible body), 3 the\n"
      "full model's run failed or a write failed, 130 interrupted.");
  sub->add_option("scene", o->scene,
                  "Scene file (YAML) with a flexible body, or a scene name (see `crossdyn list`)")
      ->required();
  sub->add_option("--engine", o->engine, "The engine that runs every model (default: kane)");
  sub->add_option("--integrator", o->common.integrator,
                  known_names<Integrator>() + " (default: the scene's)");
  sub->add_option("--rtol", o->common.rtol, "Relative tolerance (default: the scene's)");
  sub->add_option("--atol", o->common.atol, "Absolute tolerance (default: the scene's)");
  sub->add_option("--dt", o->common.dt, "rk4 step, or first trial step, s");
  sub->add_option("--max-steps", o->common.max_steps, "Per run: fail the run after N steps");
  sub->add_option("--timeout", o->common.timeout, "Per run: fail the run after SECONDS");
  sub->add_option("--json", o->json, "Also write the result as JSON to FILE (atomically)");
  sub->add_flag("--quiet,-q", o->common.quiet, "No progress line on stderr");
  sub->callback([o, &exit_code] { exit_code = converge(*o); });
}

}  // namespace crossdyn
