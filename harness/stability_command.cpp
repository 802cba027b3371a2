// crossdyn stability SCENE --vary KNOB --values LIST: where each method fails (harness/stability.hpp).
#include <cctype>
#include <cstdlib>
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
#include "harness/shard.hpp"
#include "harness/stability.hpp"
#include "harness/study.hpp"
#include "harness/scene_warnings.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <thread>

namespace crossdyn {

namespace {

struct StabilityCliOptions {
  std::string scene, vary, values;
  std::string engines, integrators;
  std::optional<std::string> tolerances, dts;
  std::optional<double> tolerance;
  double drift_limit = 1e-6;
  long max_steps = 200000;
  double timeout = 20;
  double reference_timeout = 600;
  std::optional<double> duration;
  std::vector<std::string> settings;
  std::string report, csv;
  bool quiet = false;
  std::string shard, part;  // --shard K/N --part FILE
  std::optional<int> jobs;  // --jobs N (default: the cores)
};

// What stability writes besides the text: --csv and --report, opened (refused when unusable,
// exit 2) before the work and committed together at the end.
struct StabilityOutputs {
  std::optional<AtomicFile> csv;
  std::unique_ptr<harness::StagedFolder> report;
};

void open_stability_outputs(StabilityOutputs& out, const std::string& csv, const std::string& report) {
  if (!csv.empty()) {
    if (csv != "-") harness::make_directories(std::filesystem::path(csv).parent_path().string());
    out.csv.emplace(csv, "--csv");
  }
  if (!report.empty()) out.report = harness::stage_stability_report(report);
}

void write_stability_outputs(const harness::StabilityMap& map, StabilityOutputs& out) {
  std::cout << harness::format_stability(map);
  check_written(std::cout);
  if (out.csv) out.csv->stream() << harness::stability_csv(map);
  if (out.report) harness::write_stability_report(*out.report, {map});
  commit_together({out.csv ? &*out.csv : nullptr}, {out.report.get()});
}

int stability(const StabilityCliOptions& o) {
  harness::StabilityOptions options;
  options.engine_specs = harness::parse_engine_variants(o.engines, "--engines");
  options.integrators = harness::parse_names(o.integrators, "--integrators", integrator_names(), "integrator");
  if (o.tolerances) options.tolerances = harness::parse_values(*o.tolerances, "--tolerances", true);
  if (o.dts) options.dts = harness::parse_values(*o.dts, "--dts", false);
  if (o.tolerance && !(*o.tolerance > 0 && *o.tolerance < 1))
    throw InputError("--accuracy: " + harness::shortest_text(*o.tolerance) + " is not an accuracy: give "
                     "the history error counted accurate, relative to each quantity's scale, above 0 "
                     "and below 1 (e.g. 1e-6)");
  options.tolerance = o.tolerance;
  if (!(o.drift_limit > 0)) throw InputError("--drift-limit: must be positive");
  options.drift_limit = o.drift_limit;
  if (o.max_steps <= 0) throw InputError("--max-steps: must be a positive number of steps");
  options.max_steps = o.max_steps;
  if (!(o.timeout >= 0) || !std::isfinite(o.timeout))
    throw InputError("--timeout: must be a finite number of seconds >= 0 (0: none)");
  if (o.timeout != 0 && (o.timeout < 1e-3 || o.timeout > 1e9))  // 1e-320 s: no run could start
    throw InputError("--timeout: " + harness::shortest_text(o.timeout) +
                     " s is outside the allowed range, 0 (none) or 0.001 to 1e9 s");
  options.timeout = o.timeout;
  if (!(o.reference_timeout >= 0) || !std::isfinite(o.reference_timeout))
    throw InputError("--reference-timeout: must be a finite number of seconds >= 0 (0: none)");
  options.reference_timeout = o.reference_timeout;
  if (o.jobs && (*o.jobs < 1 || *o.jobs > 256))
    throw InputError("--jobs: " + std::to_string(*o.jobs) + " is outside the allowed range, 1 to 256");
  options.jobs = o.jobs ? *o.jobs : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const bool sharded = !o.shard.empty() || !o.part.empty();
  const harness::ShardSpec shard = harness::parse_shard(o.shard.empty() ? "0/1" : o.shard);
  if (sharded) {
    if (o.part.empty()) throw InputError("--shard: give --part FILE, the part file `crossdyn merge` combines");
    if (!o.csv.empty() || !o.report.empty())
      throw InputError("--shard/--part: --csv and --report are written by `crossdyn merge PARTS...` "
                       "from all the parts, not by one shard");
  }
  const std::string path = harness::resolve_scene(o.scene);
  std::vector<SceneWarning> warnings;
  System system = read_scene(path, &warnings);
  // Every output against every input the scene was read from (nodal data files too).
  std::vector<NamedPath> outputs{{"standard output", "-"}}, folders;
  if (!o.csv.empty()) outputs.push_back({"--csv", o.csv});
  if (sharded) outputs.push_back({"--part", o.part});
  if (!o.report.empty()) folders.push_back({"--report", o.report});
  std::vector<NamedPath> inputs = harness::scene_inputs(system);
  if (!o.report.empty()) inputs.push_back({"the report script", harness::installed_report_script()});
  check_outputs_are_not_inputs(outputs, inputs, folders);
  if (o.duration) {
    if (!(*o.duration > 0) || *o.duration > 1e7)
      throw InputError("--duration: must be positive and at most 1e7 s");
    system.run.duration = *o.duration;
    system.run.output_step = std::min(system.run.output_step, *o.duration);
  }
  // The reader's warnings (as `crossdyn: warning: ...`); the scene checks of run, compare, verify
  // and draw (harness/scene_warnings.hpp) are theirs: a merge of this command's parts could not
  // repeat them.
  harness::print_warnings(warnings, std::cerr);
  system = harness::apply_settings(system, o.settings);
  if (o.vary.empty()) {
    std::string list;
    for (const std::string& k : harness::available_knobs(system)) list += (list.empty() ? "" : ", ") + k;
    throw InputError("--vary: give the scene parameter to sweep (this scene offers: " + list + ")");
  }
  const harness::Knob knob = harness::parse_knob(system, o.vary);
  const std::vector<double> values = harness::parse_parameter_values(o.values);
  for (double v : values) (void)harness::apply_knob(system, knob, v);  // refuse bad values first

  StabilityOutputs stability_outputs;
  open_stability_outputs(stability_outputs, o.csv, o.report);
  std::optional<AtomicFile> part;
  if (sharded) {
    if (o.part != "-") harness::make_directories(std::filesystem::path(o.part).parent_path().string());
    part.emplace(o.part, "--part");
  }

  ProgressLine progress(!o.quiet);
  options.progress = &progress;
  if (!sharded) {
    const harness::StabilityMap map = harness::stability_scene(system, knob, values, options);
    progress.clear();
    write_stability_outputs(map, stability_outputs);
    return kExitOk;
  }

  // --shard K/N: the values of slice K, each an independent study of the modified scene. A
  // value's cost: one run of the modified scene (duration and links change it) x the cells.
  AtomicFile& part_file = *part;
  const harness::StabilityMap frame = harness::stability_frame(system, knob, options);
  double cells = 0;
  for (const std::string& i : frame.integrators)
    cells += Choice<Integrator>(i) == Integrator::Rk4
                 ? static_cast<double>(options.dts.empty() ? 7 : options.dts.size())
                 : static_cast<double>(options.tolerances.empty() ? 4 : options.tolerances.size());
  cells *= static_cast<double>(frame.engines.size());
  std::vector<harness::ShardScene> plan;
  for (std::size_t k = 0; k < values.size(); ++k) {
    harness::ShardScene u;
    u.path = path;
    u.item = "value " + std::to_string(k + 1) + ": " + harness::shortest_text(values[k]);
    u.cost = harness::system_run_cost(harness::apply_knob(system, knob, values[k])) * std::max(cells, 1.0);
    plan.push_back(u);
  }
  for (const harness::ShardScene& u : plan) harness::require_shardable_scene(u.path);
  plan = harness::plan_units(std::move(plan), shard.count);
  harness::StabilityMap own = frame;  // this shard's values, for its own text
  std::vector<std::string> items;
  std::vector<double> mine;
  for (std::size_t k = 0; k < values.size(); ++k)
    if (plan[k].shard == shard.index) mine.push_back(values[k]);
  for (harness::StabilityValue& v : harness::stability_values(system, knob, mine, frame, options)) {
    items.push_back(harness::stability_value_json(v));
    harness::add_stability_value(own, std::move(v));
  }
  progress.clear();
  if (!own.columns.empty()) {
    own.findings = harness::stability_findings(own);
    std::cout << harness::format_stability(own);
  } else {
    std::cout << "stability: shard " << shard.index << "/" << shard.count << " has no values\n";
  }
  const harness::PartOptions part_options{
      {"--vary", o.vary},
      {"--values", harness::shortest_list(values)},
      {"--engines", o.engines.empty() ? "(all)" : o.engines},
      {"--integrators", o.integrators.empty() ? "(default)" : o.integrators},
      {"--tolerances", harness::shortest_list(options.tolerances)},
      {"--dts", harness::shortest_list(options.dts)},
      {"--accuracy", harness::shortest_text(o.tolerance ? *o.tolerance : harness::kStabilityAccuracy)},
      {"--drift-limit", harness::shortest_text(o.drift_limit)},
      {"--max-steps", std::to_string(o.max_steps)},
      {"--timeout", harness::shortest_text(o.timeout)},
      {"--reference-timeout", harness::shortest_text(o.reference_timeout)},
      {"--duration", o.duration ? harness::shortest_text(*o.duration) : "(scene's)"},
      {"--set", [&o] {
         std::string all;
         for (const std::string& x : o.settings) all += (all.empty() ? "" : " ") + x;
         return all.empty() ? std::string("(none)") : all;
       }()}};
  part_file.stream() << harness::sweep_part_json("stability", part_options, shard, plan,
                                                 harness::stability_frame_json(frame), items);
  commit_together({&part_file});
  std::cout << "part " << shard.index << "/" << shard.count << ": " << o.part << '\n';
  check_written(std::cout);
  return kExitOk;
}

}  // namespace

int merge_stability_parts(const std::vector<harness::Part>& parts, const SweepMergeOutputs& out) {
  StabilityOutputs outputs;
  open_stability_outputs(outputs, out.csv, out.report ? *out.report : "");
  int checked = 0;
  const std::vector<std::string> items = harness::merge_items(parts, harness::version(), &checked);
  if (!out.quiet)
    std::cerr << "merge: " << parts.size() << " stability parts, " << items.size() << " values ("
              << checked << " scene file on disk checked against its SHA-256)\n";
  harness::StabilityMap map = harness::stability_frame_from(parts.front().frame);
  for (const std::string& text : items) harness::add_stability_value(map, harness::stability_value_from(text));
  map.findings = harness::stability_findings(map);
  write_stability_outputs(map, outputs);
  return kExitOk;
}

void add_stability_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<StabilityCliOptions>();
  CLI::App* sub = app.add_subcommand(
      "stability",
      "Where each method fails: for each engine x integrator x step (rk4) or tolerance, against\n"
      "the values of one scene parameter (--vary), each run classified as accurate, inaccurate,\n"
      "drift (H or E drifts where the scene conserves it), diverged, singular (Euler-angle lock)\n"
      "or too costly (step or time limit), against the same reference as `crossdyn study`; with\n"
      "the largest |eigenvalue| of the right-hand side's Jacobian per value (rk4 diverges above\n"
      "h |lambda|max ~ 2.8), and the findings in words: where it fails, how, and the remedy.\n\n"
      "--vary: <joint>.stiffness, <joint>.rate (initial rate: a rotor speed),\n"
      "<joint>.prescribed_rate, <joint>.wx|wy|wz (a free base's initial w_NB_B),\n"
      "<body>.modal_stiffness (scale on K), <body>.modal_damping (ratio),\n"
      "duration, links (chainN). --set KNOB=VALUE fixes another of them first.\n\n"
      "Exit status 0 done (whatever the map shows), 2 bad input, 3 a write failed, 130 interrupted.");
  sub->add_option("scene", o->scene, "Scene file (YAML) or scene name")->required();
  sub->add_option("--vary", o->vary, "The scene parameter to sweep");
  list_option(sub->add_option("--values", o->values, "Its values: a list (1,10,100) or a range one per decade (1..1e4)")
      ->required());
  list_option(sub->add_option("--engines", o->engines,
                  "Comma-separated engines (default: all), each optionally with a variant: "
                  "newton-euler:none|baumgarte|projection (constraint stabilisation), lagrange:no-rechart"));
  list_option(sub->add_option("--integrators", o->integrators,
                  "Comma-separated integrators (default: rk4, dopri5, dop853, cvode-bdf)"));
  list_option(sub->add_option("--tolerances", o->tolerances, "Adaptive methods' rtol = atol (default 1e-3,1e-6,1e-9,1e-12)"));
  list_option(sub->add_option("--dts", o->dts, "rk4 steps, s (default: the output step / 1, 2, 4, ... 64)"));
  sub->add_option("--accuracy", o->tolerance,
                  "History error counted accurate, relative to each quantity's scale (the study's "
                  "error metric) (default 1e-6). Not the scene's compare tolerances, which check "
                  "that the engines agree");
  sub->add_option("--drift-limit", o->drift_limit, "Relative H or E drift counted as drift (default 1e-6)");
  sub->add_option("--max-steps", o->max_steps, "Per run: too costly after N steps (default 200000)");
  sub->add_option("--timeout", o->timeout, "Per run: too costly after SECONDS (default 20; 0: none)");
  sub->add_option("--reference-timeout", o->reference_timeout,
                  "Each reference run's own budget, SECONDS (default 600; 0: none), independent of "
                  "--timeout; a reference still not made is a finding with its reason");
  sub->add_option("--duration", o->duration, "Run every cell for T s instead of the scene's duration");
  sub->add_option("--set", o->settings,
                  "KNOB=VALUE: set another scene parameter before the sweep (repeatable), e.g. "
                  "--set array.modal_stiffness=1000 --vary array.modal_damping");
  sub->add_option("--report", o->report, "Write the pages (index.html, one page per map, PNG maps, CSV) into DIR");
  sub->add_option("--csv", o->csv, "Write one CSV line per cell to FILE");
  sub->add_option("--jobs,-j", o->jobs,
                  "Runs at once, on N threads (default: the number of cores). The map is the same "
                  "for any N but for the CPU times and what a wall-clock --timeout stops")
      ->type_name("N");
  sub->add_flag("--quiet,-q", o->quiet, "No progress line on stderr");
  sub->add_option("--shard", o->shard,
                  "Run only slice K of N of the values (K counts from 0, as Slurm's "
                  "SLURM_ARRAY_TASK_ID) and write --part FILE for `crossdyn merge`, which puts the "
                  "map's columns back in the order of --values. Not with --csv or --report")
      ->type_name("K/N");
  sub->add_option("--part", o->part,
                  "With --shard: write this shard's part file (version, options, the scene's "
                  "SHA-256, this slice's columns)");
  sub->callback([o, &exit_code] { exit_code = stability(*o); });
}

namespace harness {

// "1,10,100" or "1..1e4" (one per decade); negative and zero values allowed in lists (a rate).
std::vector<double> parse_parameter_values(const std::string& text) {
  if (text.find("..") != std::string::npos) return harness::parse_values(text, "--values", true);
  std::vector<double> out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;  // strtod: 1e-320 is a number, refused by apply_knob's bounds
    const double v = std::strtod(item.c_str(), &end);
    if (end == item.c_str() || end != item.c_str() + item.size() || std::isspace(static_cast<unsigned char>(item[0])))
      throw InputError("--values: '" + item + "' is not a number (give a list 1,10,100 or a range 1..1e4)");
    if (!std::isfinite(v))
      throw InputError("--values: '" + item + "' is not a finite number");
    out.push_back(v);
  }
  if (out.empty() || out.size() > 40) throw InputError("--values: give 1 to 40 values");
  for (std::size_t i = 0; i < out.size(); ++i)  // 10,1e1: one value twice (as for every list)
    for (std::size_t j = 0; j < i; ++j)
      if (out[i] == out[j])
        throw InputError("--values: the value " + harness::shortest_text(out[i]) + " is listed twice in '" + text + "'");
  return out;
}

}  // namespace harness

}  // namespace crossdyn
