// crossdyn converge SCENE: re-run a flexible scene with fewer modes and name the smallest model
// within the accuracy asked (--accuracy; harness/converge.hpp).
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
#include "harness/shard.hpp"
#include "harness/verify.hpp"
#include "harness/scene_warnings.hpp"

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
  double accuracy = harness::kConvergeAccuracy;
  std::string json;
  std::string shard, part;  // --shard K/N --part FILE
};

// What converge writes: the text and --json.
void write_converge_outputs(const harness::ConvergeResult& r, std::optional<AtomicFile>& json) {
  std::cout << harness::format_converge(r);
  check_written(std::cout);
  if (json) {
    json->stream() << harness::converge_json(r);
    commit_together({&*json});
  }
}

// converge --shard K/N --part FILE: the full model (every model is compared with it) and the jobs
// of slice K; the jobs are the unit of work (models and slicing rows), balanced by one run's
// estimate of each.
int converge_shard(const ConvergeOptions& o, const std::string& scene, const System& system,
                   const harness::CompareOptions& options, AtomicFile& part_file) {
  const harness::ShardSpec shard = harness::parse_shard(o.shard.empty() ? "0/1" : o.shard);
  std::vector<harness::ConvergeJob> jobs;
  harness::ConvergeResult frame = harness::converge_frame(system, options, &jobs, o.accuracy);
  std::vector<harness::ShardScene> plan;
  for (std::size_t k = 0; k < jobs.size(); ++k) {
    harness::ShardScene u;
    u.path = scene;
    u.item = "model " + std::to_string(k + 1) + ": " + harness::model_label(system, frame.groups, jobs[k].counts) +
             (jobs[k].slices > 0 ? ", " + std::to_string(jobs[k].slices) + " slices" : "");
    u.cost = harness::system_run_cost(harness::truncate_modes(system, frame.groups, jobs[k].counts));
    plan.push_back(u);
  }
  for (const harness::ShardScene& u : plan) harness::require_shardable_scene(u.path);
  plan = harness::plan_units(std::move(plan), shard.count);
  frame.models.push_back(harness::converge_full_model(system, frame, options));
  const harness::EngineRun full_run = frame.models.front().run;
  std::vector<std::string> items;
  for (std::size_t k = 0; k < jobs.size(); ++k) {
    if (plan[k].shard != shard.index) continue;
    std::string note;
    const std::optional<harness::ConvergeModel> m =
        harness::converge_job(system, frame, jobs[k], full_run, options, &note);
    items.push_back(harness::converge_item_json(m, note));
  }
  const auto opt = [](const auto& v) { return v ? harness::shortest_text(static_cast<double>(*v)) : std::string("(scene's)"); };
  const harness::PartOptions part_options{
      {"--engine", o.engine},
      {"--accuracy", harness::shortest_text(o.accuracy)},
      {"--integrator", o.common.integrator ? *o.common.integrator : "(scene's)"},
      {"--rtol", opt(o.common.rtol)},
      {"--atol", opt(o.common.atol)},
      {"--dt", opt(o.common.dt)},
      {"--max-steps", opt(o.common.max_steps)},
      {"--timeout", opt(o.common.timeout)}};
  part_file.stream() << harness::sweep_part_json("converge", part_options, shard, plan,
                                                 harness::converge_frame_json(frame), items);
  commit_together({&part_file});
  std::cout << "converge: shard " << shard.index << "/" << shard.count << ": " << items.size()
            << " of " << jobs.size() << " models besides the full one\n"
            << "part " << shard.index << "/" << shard.count << ": " << o.part << '\n';
  check_written(std::cout);
  return kExitOk;
}

int converge(const ConvergeOptions& o) {
  // Everything that can be refused is refused before the engines run (exit 2).
  harness::CompareCliOptions cli = o.common;
  cli.engines = o.engine;
  const harness::CompareOptions options = harness::to_compare_options(cli);
  if (!(o.accuracy > 0 && o.accuracy < 1))
    throw InputError("--accuracy: " + harness::shortest_text(o.accuracy) +
                     " is not an accuracy: give the largest relative change a model may make, above "
                     "0 and below 1 (e.g. 1e-3: 0.1 % of each quantity's scale)");
  const bool sharded = !o.shard.empty() || !o.part.empty();
  if (sharded) {
    harness::parse_shard(o.shard.empty() ? "0/1" : o.shard);
    if (o.part.empty()) throw InputError("--shard: give --part FILE, the part file `crossdyn merge` combines");
    if (!o.json.empty())
      throw InputError("--shard/--part: --json is written by `crossdyn merge PARTS...` from all the "
                       "parts, not by one shard");
  }
  const std::string scene = harness::resolve_scene(o.scene);
  std::vector<SceneWarning> warnings;
  const System system = read_scene(scene, &warnings);
  // The reader's warnings (as `crossdyn: warning: ...`); the scene checks of run, compare, verify
  // and draw (harness/scene_warnings.hpp) are theirs: a merge of this command's parts could not
  // repeat them.
  harness::print_warnings(warnings, std::cerr);
  // Every output against every input the scene was read from (nodal data files too).
  std::vector<NamedPath> outputs{{"standard output", "-"}};
  if (!o.json.empty()) outputs.push_back({"--json", o.json});
  if (sharded) outputs.push_back({"--part", o.part});
  check_outputs_are_not_inputs(outputs, harness::scene_inputs(system));
  harness::settings_for(system, harness::run_overrides(options));
  if (harness::mode_groups(system).empty())
    throw InputError(scene + ": converge needs a flexible body with at least one mode; this "
                             "scene has none");
  if (sharded) {
    if (o.part != "-") harness::make_directories(std::filesystem::path(o.part).parent_path().string());
    AtomicFile part_file(o.part, "--part");  // refused now (exit 2) when unusable, before the runs
    return converge_shard(o, scene, system, options, part_file);
  }
  std::optional<AtomicFile> json;
  if (!o.json.empty()) {
    if (o.json != "-") harness::make_directories(std::filesystem::path(o.json).parent_path().string());
    json.emplace(o.json, "--json");
  }
  const harness::ConvergeResult r = harness::converge_scene(system, options, o.accuracy);
  write_converge_outputs(r, json);
  return kExitOk;
}

}  // namespace

int merge_converge_parts(const std::vector<harness::Part>& parts, const SweepMergeOutputs& out) {
  std::optional<AtomicFile> json;  // opened (refused when unusable) before the merge's work
  if (!out.json.empty()) {
    if (out.json != "-") harness::make_directories(std::filesystem::path(out.json).parent_path().string());
    json.emplace(out.json, "--json");
  }
  int checked = 0;
  const std::vector<std::string> items = harness::merge_items(parts, harness::version(), &checked);
  if (!out.quiet)
    std::cerr << "merge: " << parts.size() << " converge parts, " << items.size() + 1 << " models ("
              << checked << " scene file on disk checked against its SHA-256)\n";
  harness::ConvergeResult r = harness::converge_frame_from(parts.front().frame);
  for (const std::string& text : items) {
    auto [model, note] = harness::converge_item_from(text);
    if (model) r.models.push_back(std::move(*model));
    if (!note.empty()) r.notes.push_back(note);
  }
  harness::converge_finish(r);
  write_converge_outputs(r, json);
  return kExitOk;
}

void add_converge_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<ConvergeOptions>();
  CLI::App* sub = app.add_subcommand(
      "converge",
      "Model no more than the scene needs: re-run a flexible scene with 0, 1, ... n modes of\n"
      "every mode group (the beam generator's bending planes qx, qy), compare each run with the\n"
      "full model's on every quantity, and name the smallest model within --accuracy of it (each\n"
      "quantity's change relative to its scale, as `crossdyn study` measures errors; the scene's\n"
      "compare tolerances are for checking that the engines agree, not used here). Exit status 0 done, 2 bad input (or no flexible body), 3 the\n"
      "full model's run failed or a write failed, 130 interrupted.");
  sub->add_option("scene", o->scene,
                  "Scene file (YAML) with a flexible body, or a scene name (see `crossdyn list`)")
      ->required();
  sub->add_option("--engine", o->engine, "The engine that runs every model (default: kane)");
  sub->add_option("--accuracy", o->accuracy,
                  "The largest change a model may make against the full model, relative to each "
                  "quantity's scale (its kind of motion's size in the full model; attitudes in rad) "
                  "(default 1e-3)");
  sub->add_option("--integrator", o->common.integrator,
                  known_names<Integrator>() + " (default: the scene's)");
  sub->add_option("--rtol", o->common.rtol, "The integrator's relative tolerance (default: the scene's run block)");
  sub->add_option("--atol", o->common.atol, "The integrator's absolute tolerance (default: the scene's run block)");
  sub->add_option("--dt", o->common.dt, "rk4 step, and the first trial step of adaptive integrators, s (default: the scene's run.dt; adaptive integrators estimate their first step when neither gives it)");
  sub->add_option("--max-steps", o->common.max_steps, "Per run: fail the run after N steps");
  sub->add_option("--timeout", o->common.timeout, "Per run: fail the run after SECONDS");
  sub->add_option("--json", o->json, "Also write the result as JSON to FILE (atomically)");
  sub->add_flag("--quiet,-q", o->common.quiet, "No progress line on stderr");
  sub->add_option("--shard", o->shard,
                  "Run only slice K of N of the models (K counts from 0) and write --part FILE for "
                  "`crossdyn merge`; every shard also runs the full model, which every model is "
                  "compared with. Not with --json (merge writes it)")
      ->type_name("K/N");
  sub->add_option("--part", o->part, "With --shard: write this shard's part file");
  sub->callback([o, &exit_code] { exit_code = converge(*o); });
}

}  // namespace crossdyn
