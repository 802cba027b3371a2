// crossdyn study SCENE...: speed against accuracy, and the scaling of the right-hand side with
// chain length (harness/study.hpp).
#include <CLI/CLI.hpp>

#include "core/errors.hpp"
#include "core/output.hpp"
#include "core/progress.hpp"
#include "core/scene/scene.hpp"
#include "harness/cli.hpp"
#include "harness/commands.hpp"
#include "harness/engines.hpp"
#include "harness/locations.hpp"
#include "harness/report.hpp"
#include "harness/settings.hpp"
#include "harness/shard.hpp"
#include "harness/study.hpp"
#include "harness/scene_warnings.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>

namespace crossdyn {

namespace {

struct StudyCliOptions {
  std::vector<std::string> scenes;
  std::string engines, integrators;
  std::optional<std::string> tolerances, dts, accuracy;
  int repeat = 3;
  std::optional<long> max_steps;
  double timeout = 60;
  std::optional<double> duration, output_step;  // overrides of the scenes' run block, as `run`'s
  std::string report, csv;
  bool scaling = false;
  int max_links = 128;
  double budget = 0.2;
  bool quiet = false;
  std::string shard, part;  // --shard K/N --part FILE
};

// What study writes: --csv and --report, opened (and so refused when unusable, exit 2) before
// the work and committed together at the end.
struct StudyOutputs {
  std::optional<AtomicFile> csv;
  std::unique_ptr<harness::StagedFolder> report;
};

void open_study_outputs(StudyOutputs& out, const std::string& csv, const std::string& report) {
  if (!csv.empty()) {
    if (csv != "-") harness::make_directories(std::filesystem::path(csv).parent_path().string());
    out.csv.emplace(csv, "--csv");
  }
  if (!report.empty()) out.report = harness::stage_study_report(report);
}

// Writes and commits them; an exit status of 3 (a reference run failed) replaces nothing.
void write_study_outputs(const std::vector<harness::SceneStudy>& results,
                         const std::optional<harness::ScalingStudy>& scaling, StudyOutputs& out,
                         int status) {
  if (status == kExitRunFailed) {
    if (out.csv || out.report)
      std::cerr << "crossdyn: --csv and --report not replaced: the study failed (exit status 3)\n";
    return;
  }
  if (out.csv) {
    out.csv->stream() << harness::study_csv_header();
    for (const harness::SceneStudy& s : results) out.csv->stream() << harness::study_csv_rows(s);
  }
  if (out.report) harness::write_study_report(*out.report, results, scaling);
  commit_together({out.csv ? &*out.csv : nullptr}, {out.report.get()});
}

int study(const StudyCliOptions& o) {
  // Everything that can be refused is refused before any run (exit 2).
  if (o.scenes.empty() && !o.scaling)
    throw InputError("study: give at least one scene, or --scaling");
  harness::StudyOptions options;
  options.engines = harness::parse_names(o.engines, "--engines", engine_names(), "engine");
  options.integrators = harness::parse_names(o.integrators, "--integrators", integrator_names(), "integrator");
  if (o.tolerances) options.tolerances = harness::parse_values(*o.tolerances, "--tolerances", true);
  if (o.accuracy) {
    options.targets = harness::parse_values(*o.accuracy, "--accuracy", true);
    for (double t : options.targets)
      if (!(t < 1))
        throw InputError("--accuracy: " + harness::shortest_text(t) + " is not an accuracy: give the "
                         "end-state errors to recommend for, relative to each quantity's scale, below 1 "
                         "(e.g. 1e-4,1e-6 or 1e-3..1e-8)");
  }
  if (o.dts) options.dts = harness::parse_values(*o.dts, "--dts", false);
  if (o.repeat < 1 || o.repeat > 1000)
    throw InputError("--repeat: must be from 1 to 1000, got " + std::to_string(o.repeat));
  options.repeat = o.repeat;
  if (o.max_steps && *o.max_steps <= 0)
    throw InputError("--max-steps: must be a positive number of steps, got " + std::to_string(*o.max_steps));
  options.max_steps = o.max_steps;
  if (!(o.timeout >= 0) || !std::isfinite(o.timeout))
    throw InputError("--timeout: must be a finite number of seconds >= 0 (0: no limit)");
  if (o.timeout != 0 && (o.timeout < 1e-3 || o.timeout > 1e9))  // 1e-320 s: no run could start
    throw InputError("--timeout: " + harness::shortest_text(o.timeout) +
                     " s is outside the allowed range, 0 (none) or 0.001 to 1e9 s");
  options.timeout = o.timeout;
  if (!(o.budget >= 1e-3) || !(o.budget <= 60))  // 1e-320 s: no measurement fits in it
    throw InputError("--budget: must be from 0.001 to 60 s, got " + harness::shortest_text(o.budget));
  const bool sharded = !o.shard.empty() || !o.part.empty();
  const harness::ShardSpec shard = harness::parse_shard(o.shard.empty() ? "0/1" : o.shard);
  if (sharded) {
    if (o.part.empty()) throw InputError("--shard: give --part FILE, the part file `crossdyn merge` combines");
    if (!o.csv.empty() || !o.report.empty())
      throw InputError("--shard/--part: --csv and --report are written by `crossdyn merge PARTS...` "
                       "from all the parts, not by one shard");
    if (o.scaling)
      throw InputError("--shard/--part: --scaling is not sharded (it measures the right-hand-side "
                       "cost in one process); run `crossdyn study --scaling` on its own");
  }
  std::vector<std::string> paths;
  for (const std::string& s : o.scenes) paths.push_back(harness::resolve_scene(s));
  std::vector<System> systems;
  harness::RunOverrides overrides;
  overrides.duration = o.duration;
  overrides.output_step = o.output_step;
  harness::check_overrides(overrides);
  for (const std::string& p : paths) {
    std::vector<SceneWarning> warnings;
    systems.push_back(read_scene(p, &warnings));
    // The reader's warnings (as `crossdyn: warning: ...`); the scene checks of run, compare, verify
    // and draw (harness/scene_warnings.hpp) are theirs: a merge of this command's parts could not
    // repeat them.
    harness::print_warnings(warnings, std::cerr);
    // --duration, --output-step: checked with the scene's other settings (InputError naming the
    // option), then the scene's own, so that every run of the study (reference too) uses them.
    const IntegratorSettings checked = harness::settings_for(systems.back(), overrides);
    systems.back().run.duration = checked.duration;
    systems.back().run.output_step = checked.output_step;
  }
  // Every output against every input the scenes were read from (nodal data files too).
  std::vector<NamedPath> outputs{{"standard output", "-"}}, folders;
  if (!o.csv.empty()) outputs.push_back({"--csv", o.csv});
  if (sharded) outputs.push_back({"--part", o.part});
  if (!o.report.empty()) folders.push_back({"--report", o.report});
  std::vector<NamedPath> inputs;
  for (const System& s : systems)
    for (NamedPath& p : harness::scene_inputs(s)) inputs.push_back(std::move(p));
  if (!o.report.empty()) inputs.push_back({"the report script", harness::installed_report_script()});
  check_outputs_are_not_inputs(outputs, inputs, folders);
  StudyOutputs study_outputs;
  open_study_outputs(study_outputs, o.csv, o.report);

  std::optional<AtomicFile> part_file;
  std::vector<harness::ShardScene> plan;
  if (sharded) {
    if (o.part != "-") harness::make_directories(std::filesystem::path(o.part).parent_path().string());
    part_file.emplace(o.part, "--part");
    // A scene's cost: one engine run's estimate x the configurations it is studied in.
    for (std::size_t k = 0; k < paths.size(); ++k) {
      const System& s = systems[k];
      const std::size_t engines = options.engines.empty() ? engine_names().size() : options.engines.size();
      double configs = 0;
      for (const std::string& i : options.integrators.empty() ? integrator_names() : options.integrators)
        configs += Choice<Integrator>(i) == Integrator::Rk4
                       ? static_cast<double>(options.dts.empty() ? 8 : options.dts.size())
                       : static_cast<double>(options.tolerances.empty() ? 10 : options.tolerances.size());
      harness::ShardScene u;
      u.path = paths[k];
      u.cost = harness::system_run_cost(s) * static_cast<double>(engines) * std::max(configs, 1.0) *
               options.repeat;
      plan.push_back(u);
    }
    for (const harness::ShardScene& u : plan) harness::require_shardable_scene(u.path);
    plan = harness::plan_units(std::move(plan), shard.count);
  }

  ProgressLine progress(!o.quiet);
  options.progress = &progress;
  std::vector<harness::SceneStudy> results;
  std::vector<std::string> items;  // --part: one per scene of this shard
  int status = kExitOk;
  for (std::size_t k = 0; k < systems.size(); ++k) {
    const System& system = systems[k];
    if (sharded && plan[k].shard != shard.index) continue;
    try {
      results.push_back(harness::study_scene(system, options));
    } catch (const harness::StudyRefused& r) {
      progress.clear();
      std::cerr << "crossdyn: study refused: " << r.what() << '\n';
      status = std::max(status, r.exit_status());
      if (sharded) items.push_back(harness::study_item_json({std::nullopt, r.what(), r.exit_status()}));
      continue;
    }
    if (sharded) items.push_back(harness::study_item_json({results.back(), "", 0}));
    std::cout << harness::format_study(results.back()) << '\n';
    check_written(std::cout);
  }
  if (sharded) {
    const harness::PartOptions part_options{
        {"--engines", o.engines.empty() ? "(all)" : o.engines},
        {"--integrators", o.integrators.empty() ? "(all)" : o.integrators},
        {"--tolerances", harness::shortest_list(options.tolerances)},
        {"--accuracy", harness::shortest_list(options.targets)},
        {"--dts", harness::shortest_list(options.dts)},
        {"--repeat", std::to_string(options.repeat)},
        {"--max-steps", o.max_steps ? std::to_string(*o.max_steps) : "(none)"},
        {"--timeout", harness::shortest_list({options.timeout})},
        {"--duration", o.duration ? harness::shortest_list({*o.duration}) : "(the scene's)"},
        {"--output-step", o.output_step ? harness::shortest_list({*o.output_step}) : "(the scene's)"}};
    part_file->stream() << harness::sweep_part_json("study", part_options, shard, plan, "null", items);
    commit_together({&*part_file});
    std::cout << "part " << shard.index << "/" << shard.count << ": " << o.part << '\n';
    check_written(std::cout);
    return status;
  }
  std::optional<harness::ScalingStudy> scaling;
  if (o.scaling) {
    harness::ScalingOptions so;
    so.engines = options.engines;
    so.max_links = o.max_links;
    so.budget = o.budget;
    so.progress = &progress;
    scaling = harness::scaling_study(so);
    std::cout << harness::format_scaling(*scaling) << '\n';
    check_written(std::cout);
  }
  write_study_outputs(results, scaling, study_outputs, status);
  return status;
}

}  // namespace

int merge_study_parts(const std::vector<harness::Part>& parts, const SweepMergeOutputs& out) {
  StudyOutputs outputs;
  open_study_outputs(outputs, out.csv, out.report ? *out.report : "");
  int checked = 0;
  const std::vector<std::string> items = harness::merge_items(parts, harness::version(), &checked);
  if (!out.quiet)
    std::cerr << "merge: " << parts.size() << " study parts, " << items.size() << " scenes ("
              << checked << " scene files on disk checked against their SHA-256)\n";
  std::vector<harness::SceneStudy> results;
  int status = kExitOk;
  for (const std::string& text : items) {
    harness::StudyItem item = harness::study_item_from(text);
    if (!item.study) {
      std::cerr << "crossdyn: study refused: " << item.refused << '\n';
      status = std::max(status, item.exit_status);
      continue;
    }
    results.push_back(std::move(*item.study));
    std::cout << harness::format_study(results.back()) << '\n';
    check_written(std::cout);
  }
  write_study_outputs(results, std::nullopt, outputs, status);
  return status;
}

void add_study_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<StudyCliOptions>();
  CLI::App* sub = app.add_subcommand(
      "study",
      "Speed against accuracy: for each scene x engine x integrator x tolerance (or rk4 step),\n"
      "the CPU time of the integration, right-hand-side calls, steps, and the error of the end\n"
      "state and of the whole history against a reference; the Pareto front and the cheapest\n"
      "configuration for 1e-4 ... 1e-10 end-state error.\n\n"
      "Timed: " + harness::study_timing_text() + "\n\n"
      "Error: " + harness::study_error_text() + "\n\n"
      "Reference: the analytic solution where the scene has one; otherwise the mean of every\n"
      "engine run with rkf78 and dop853 at rtol 1e-13 (atol 1e-17), used only when every pair of them\n"
      "agrees to 1e-11 (else the scene is refused, with the pair and the difference).\n\n"
      "--scaling: the right-hand-side cost (median CPU per call) on chainN, N = 2 ... --max-links,\n"
      "one line per engine, with the exponent fitted over the upper half of N.\n\n"
      "Exit status 0 done, 1 a scene was refused (its reference engines disagree), 2 bad input,\n"
      "3 a reference run or a write failed, 130 interrupted.");
  sub->add_option("scene", o->scenes, "Scene files (YAML) or scene names (see `crossdyn list`)");
  list_option(sub->add_option("--engines", o->engines, "Comma-separated engines (default: all: " +
                                               [] {
                                                 std::string l;
                                                 for (const std::string& e : engine_names())
                                                   l += (l.empty() ? "" : ", ") + e;
                                                 return l;
                                               }() + ")"));
  list_option(sub->add_option("--integrators", o->integrators,
                  "Comma-separated integrators (default: all: " + known_names<Integrator>() + ")"));
  list_option(sub->add_option("--accuracy", o->accuracy,
                              "The accuracies to recommend a configuration for: end-state errors "
                              "relative to each quantity's scale (the study's error metric), a list "
                              "(1e-4,1e-6) or a range one per decade (1e-3..1e-8) (default "
                              "1e-4,1e-6,1e-8,1e-10). Not the scene's compare tolerances")
                  ->type_name("LIST"));
  list_option(sub->add_option("--tolerances", o->tolerances,
                  "Adaptive methods' rtol = atol: a range one per decade (1e-4..1e-13, the default) "
                  "or a list (1e-4,1e-8)"));
  list_option(sub->add_option("--dts", o->dts, "rk4 steps, s, a list (default: the output step / 1, 2, 4, ... 128)"));
  sub->add_option("--repeat", o->repeat, "Timed runs per configuration; the median is reported (default 3)");
  sub->add_option("--max-steps", o->max_steps, "Per run: fail the run after N steps");
  sub->add_option("--timeout", o->timeout, "Per run: fail the run after SECONDS (default 60; 0: none)");
  sub->add_option("--duration", o->duration, "Override the scenes' run length, s (every run, the reference too)");
  sub->add_option("--output-step", o->output_step,
                  "Override the scenes' output step, s (the times the errors are measured at)");
  sub->add_option("--report", o->report,
                  "Write the pages (index.html, <scene>-study.html, scaling.html), PNG charts and "
                  "CSV files into DIR");
  sub->add_option("--csv", o->csv, "Write one CSV line per configuration to FILE (header: " +
                                       harness::study_csv_header().substr(0, harness::study_csv_header().size() - 1) +
                                       "; times in ms, errors as above, empty when failed)");
  sub->add_flag("--scaling", o->scaling, "Also measure the right-hand-side cost against chain length");
  sub->add_option("--max-links", o->max_links, "--scaling: the longest chain (default 128)");
  sub->add_option("--budget", o->budget, "--scaling: CPU seconds per point (default 0.2)");
  sub->add_flag("--quiet,-q", o->quiet, "No progress line on stderr");
  sub->add_option("--shard", o->shard,
                  "Study only slice K of N of the scenes (K counts from 0, as Slurm's "
                  "SLURM_ARRAY_TASK_ID) and write --part FILE for `crossdyn merge`; whole scenes "
                  "are sliced (each is measured against its own reference), by content and "
                  "estimated cost. Not with --scaling, --csv or --report (merge writes those)")
      ->type_name("K/N");
  sub->add_option("--part", o->part,
                  "With --shard: write this shard's part file (version, options, all scenes with "
                  "their SHA-256, this slice's studies)");
  sub->callback([o, &exit_code] { exit_code = study(*o); });
}

}  // namespace crossdyn
