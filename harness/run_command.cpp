// crossdyn run SCENE --engine NAME ...: one engine, one scene, one CSV.
#include <CLI/CLI.hpp>

#include "core/errors.hpp"
#include "harness/engines.hpp"
#include "core/integrate.hpp"
#include "core/output.hpp"
#include "core/progress.hpp"
#include "core/scene/scene.hpp"
#include "harness/commands.hpp"
#include "harness/locations.hpp"
#include "harness/scene_warnings.hpp"
#include "harness/settings.hpp"

#include <iostream>
#include <memory>
#include <optional>

namespace crossdyn {

namespace {

struct RunOptions {
  std::string scene;
  std::string engine = "kane";
  harness::RunOverrides overrides;
  std::string output;
  bool stats = false;
  bool quiet = false;
  bool strict = false;
  EngineOptions engine_options;
  std::optional<std::string> stabilization;  // --stabilization, a name of ConstraintStabilization
  bool no_rechart = false;
};

int run(const RunOptions& o) {
  // Everything that can be refused is refused before anything is written (exit 2).
  harness::check_overrides(o.overrides);
  const std::string scene = harness::resolve_scene(o.scene);
  const bool to_stdout = o.output.empty() || o.output == "-";
  const harness::CheckedScene checked = harness::read_checked_scene(scene);
  const System& system = checked.system;
  harness::print_warnings(checked.warnings, std::cerr);  // --quiet too: it silences progress only
  // The output (standard output when the rows go there, e.g. `>> nodes.csv`) against every
  // input the scene was read from (nodal data files too).
  check_outputs_are_not_inputs({to_stdout ? NamedPath{"standard output", "-"}
                                          : NamedPath{"--output", o.output}},
                               harness::scene_inputs(system));
  IntegratorSettings s = harness::settings_for(system, o.overrides);
  s.keep_rows = false;  // rows stream to the CSV as they are computed; memory stays flat
  EngineOptions eo = o.engine_options;
  if (o.stabilization) eo.stabilization = *o.stabilization;  // the option's check parsed it
  eo.rechart = !o.no_rechart;
  // On a terminal only (and not when the rows themselves go to it); erased before any message.
  ProgressLine progress(!o.quiet && (!o.output.empty() || !ProgressLine::stdout_is_terminal()));
  progress.start(system.name + " " + o.engine, s.duration);
  progress.phase("setting up the engine");
  std::unique_ptr<Engine> engine = make_engine(o.engine, system, eo);
  const std::size_t n = engine->columns().size();

  // stdout: rows stream out as they are computed (a failed run leaves its complete earlier rows
  // and the message on stderr). A file: written whole or not at all. Every write is checked: a
  // failed one (disk full, closed pipe) stops the run at once (OutputError, exit 3).
  std::optional<AtomicFile> file;
  if (!to_stdout) file.emplace(o.output, "--output");
  std::ostream& out = file ? file->stream() : std::cout;
  write_csv_header(out, engine->columns());
  std::size_t rows = 0;
  const RunResult r = simulate(*engine, system, TreeState::initial(system), s,
                               [&out, &rows, n](const double* row) {
                                 write_csv_row(out, row, n);
                                 if (!out) check_written(out);
                                 ++rows;
                               },
                               [&progress](double t, const RunStats& st) { progress.update(t, st.steps); });
  progress.clear();
  if (o.stats)
    std::cerr << "engine " << r.engine << ", integrator " << s.method << ": " << rows
              << " rows, " << r.stats.steps << " steps, " << r.stats.rejected << " rejected, "
              << r.stats.restarts << " restarts, " << r.stats.rhs_calls << " rhs calls, "
              << r.stats.wall_seconds << " s\n";
  if (r.failure) {
    if (!file) check_written(out);
    if (file)
      std::cerr << "crossdyn: no output written to '" << o.output << "' (" << rows
                << " rows were complete before the failure)\n";
    throw *r.failure;
  }
  if (file) commit_together({&*file});
  else check_written(out);
  return harness::strict_status(kExitOk, o.strict, checked.warnings.size());
}

}  // namespace

void add_run_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<RunOptions>();
  CLI::App* sub = app.add_subcommand(
      "run", "Run one engine on one scene and write its time history as CSV (stdout by default).");
  sub->add_option("scene", o->scene,
                  "Scene file (YAML), e.g. scenarios/spear1_case1.yaml, or a scene name such as "
                  "gimbal_lock (looked up in scenarios/; `crossdyn list` shows them)")
      ->required();
  sub->add_option("--engine", o->engine, "Engine: kane, lagrange or newton-euler (default kane)");
  sub->add_option("--integrator", o->overrides.integrator,
                  integrator_help() + "; default: the scene's (docs/integrators.md)");
  sub->add_option("--rtol", o->overrides.rtol, "Relative tolerance of adaptive integrators (> 0)");
  sub->add_option("--atol", o->overrides.atol, "Absolute tolerance of adaptive integrators (> 0)");
  sub->add_option("--dt", o->overrides.dt, "rk4 step, and the first trial step of adaptive integrators, s (default: the scene's run.dt; adaptive integrators estimate their first step when neither gives it)");
  sub->add_option("--duration", o->overrides.duration, "Override the scene's run length, s");
  sub->add_option("--output-step", o->overrides.output_step,
                  "Override the scene's output step, s (at most 1e7 output rows)");
  sub->add_option("--max-steps", o->overrides.max_steps,
                  "Fail the run after this many steps (at least 1; default 20000000)");
  sub->add_option("--output,-o", o->output,
                  "Write the CSV to FILE (atomically: complete file or none; '-' is stdout; see "
                  "docs/outputs.md for devices, FIFOs, symbolic links and read-only files)");
  sub->add_flag("--stats", o->stats, "Print step and right-hand-side counts to stderr");
  sub->add_flag("--quiet,-q", o->quiet, "No progress line on stderr (scene warnings are still printed)");
  sub->add_flag("--strict", o->strict,
                "Exit with status 1 when the scene has a warning (after the run, the output "
                "written as usual)");
  sub->add_option("--stabilization", o->stabilization,
                  "newton-euler: " + known_names<ConstraintStabilization>() + " (default " +
                      EngineOptions{}.stabilization.str() + ")")
      ->check(CLI::Validator(
          [](std::string& name) {
            return parse_name<ConstraintStabilization>(name)
                       ? std::string()
                       : unknown_name_message<ConstraintStabilization>(name);
          },
          "{" + known_names<ConstraintStabilization>(",") + "}"));
  sub->add_option("--baumgarte-alpha", o->engine_options.baumgarte_alpha,
                  "newton-euler: Baumgarte velocity gain, 1/s (default 10)");
  sub->add_option("--baumgarte-beta", o->engine_options.baumgarte_beta,
                  "newton-euler: Baumgarte position gain, 1/s^2 (default 25)");
  sub->add_flag("--no-rechart", o->no_rechart,
                "lagrange: stop at an Euler-angle singularity instead of switching sequence");
  sub->callback([o, &exit_code] { exit_code = run(*o); });
}

}  // namespace crossdyn
