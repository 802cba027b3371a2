// crossdyn verify [SCENE ...]: compare on every scene (all of scenarios/ by default), one summary
// table, a JSON summary, JUnit XML and an HTML report (see harness/verify.hpp for the order and
// why the report never changes the verdict).
#include <CLI/CLI.hpp>

#include "core/errors.hpp"
#include "core/input_file.hpp"
#include "core/integrate.hpp"
#include "core/output.hpp"
#include "harness/commands.hpp"
#include "harness/locations.hpp"
#include "harness/report.hpp"
#include "harness/scene_warnings.hpp"
#include "harness/shard.hpp"
#include "harness/verify.hpp"

#include <cstdint>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <set>

namespace crossdyn {

namespace {

namespace fs = std::filesystem;

struct VerifyCommandOptions {
  harness::VerifyOptions verify;
  harness::CompareCliOptions common;
  std::string json = "reports/latest/summary.json";
  std::string junit;
  std::optional<std::string> report;
  std::string python = "/usr/bin/python3";
  std::string report_script;
  CLI::Option* json_option = nullptr;
  CLI::Option* python_option = nullptr;  // merge: --python is for verify's parts only
  std::string shard;  // --shard K/N
  std::string part;   // --part FILE
  std::vector<std::string> parts;  // merge: the part files
  std::string csv;                 // merge of study or stability parts: --csv FILE
};

// Opens an AtomicFile for an output in `f`, its folder created first (nothing for "").
void open_output(std::optional<AtomicFile>& f, const std::string& path, const std::string& label) {
  if (path.empty()) return;
  if (path != "-") harness::make_directories(fs::path(path).parent_path().string());
  f.emplace(path, label);
}

// The outputs verify (and merge) open before the work: JSON summary and JUnit XML files, opened
// now so that a bad path is refused (exit 2) before anything runs; checks that no output is an
// input (`inputs`: the scene files, plus the report script here).
struct Outputs {
  std::string json;
  std::string script;
  std::optional<AtomicFile> json_file, junit_file;
};
void open_outputs(VerifyCommandOptions& o, std::vector<NamedPath> inputs, Outputs& out) {
  out.json = o.json;
  // The report folder has its own summary.json; write another only when asked.
  if (o.report && o.json_option->count() == 0) out.json.clear();
  out.script = o.report_script.empty() ? harness::installed_report_script() : o.report_script;
  std::vector<NamedPath> outputs{{"standard output", "-"}}, folders;
  if (o.report) {
    inputs.push_back({"the report script", out.script});
    folders.push_back({"--report", *o.report});
  }
  if (!out.json.empty()) outputs.push_back({"--json", out.json});
  if (!o.junit.empty()) outputs.push_back({"--junit", o.junit});
  check_outputs_are_not_inputs(outputs, inputs, folders);
  open_output(out.json_file, out.json, "--json");
  open_output(out.junit_file, o.junit, "--junit");
  if (o.report) {
    // An unusable report folder (a file, not a report, no room for a folder beside it) or a
    // missing script is refused now (exit 2), before the work.
    harness::ReportOptions r;
    r.dir = *o.report;
    r.python = o.python;
    r.script = out.script;
    std::vector<std::string> scene_files;
    for (const NamedPath& in : inputs)
      if (in.role == "the scene file") scene_files.push_back(in.path);
    harness::check_report(scene_files, r);
  }
}

// What verify writes after the comparisons: the table; then the report is built in its staging
// folder; then the JSON summary, the JUnit XML and the report replace the old ones together
// (core/output.hpp commit_together). A report that cannot be made (its script fails) is
// reported and never changes the verdict: the JSON and JUnit files are still written and the
// old report folder is left as it was. Returns the exit status.
int write_outputs(VerifyCommandOptions& o, Outputs& out, const harness::VerifyResult& result) {
  std::cout << harness::format_verify_table(result, o.verify.strict);
  check_written(std::cout);
  if (out.json_file) out.json_file->stream() << harness::json_summary(result.scenes);
  if (out.junit_file) out.junit_file->stream() << harness::junit_xml(result.scenes);

  // The report: its failure is reported, never the verdict; Ctrl-C during it is 130.
  std::unique_ptr<harness::StagedFolder> report;
  bool report_failed = false;
  if (o.report) {
    harness::ReportOptions r;
    r.dir = *o.report;
    r.python = o.python;
    r.script = out.script;
    try {
      report = harness::build_report(result.scenes, r);
    } catch (const RunFailure& f) {
      if (f.reason() == "interrupted") throw;
      report_failed = true;
      std::cerr << "crossdyn: report not written: " << f.what() << '\n';
    } catch (const std::exception& e) {
      report_failed = true;
      std::cerr << "crossdyn: report not written: " << e.what()
                << " (the verdict above stands; exit status " << result.exit_code(o.verify.strict)
                << ")\n";
    }
    if (interrupt_requested()) throw RunFailure("report", 0.0, "", "interrupted");
  }
  commit_together({out.json_file ? &*out.json_file : nullptr, out.junit_file ? &*out.junit_file : nullptr},
                  {report.get()});
  if (out.json_file) std::cout << "JSON summary: " << out.json << '\n';
  if (out.junit_file) std::cout << "JUnit XML: " << o.junit << '\n';
  if (report) std::cout << "report: " << *o.report << "/index.html\n";
  if (report_failed) std::cout << "report: NOT WRITTEN (see the message on stderr)\n";
  check_written(std::cout);
  return result.exit_code(o.verify.strict);
}

// verify --shard K/N --part FILE: slice K's scenes only, its table, and the part file for merge.
// The exit status is slice K's verdict (merge gives the whole run's).
int verify_shard(VerifyCommandOptions& o, const std::vector<std::string>& files) {
  const harness::ShardSpec shard = harness::parse_shard(o.shard.empty() ? "0/1" : o.shard);
  if (o.part.empty())
    throw InputError("--shard: give --part FILE, the part file `crossdyn merge` combines");
  if (o.json_option->count() > 0 || !o.junit.empty() || o.report)
    throw InputError("--shard/--part: --json, --junit and --report are written by `crossdyn merge "
                     "PARTS...` from all the parts, not by one shard");
  std::vector<NamedPath> inputs;
  for (const std::string& f : files)
    for (NamedPath& p : harness::scene_file_inputs(f)) inputs.push_back(std::move(p));
  check_outputs_are_not_inputs({{"standard output", "-"}, {"--part", o.part}}, inputs, {});
  std::optional<AtomicFile> part_file;
  open_output(part_file, o.part, "--part");
  for (const std::string& f : files) harness::require_shardable_scene(f);
  const std::vector<harness::ShardScene> plan = harness::plan_shards(files, shard.count);
  std::vector<std::string> own;
  for (const harness::ShardScene& s : plan)
    if (s.shard == shard.index) own.push_back(s.path);
  if (!o.verify.quiet)
    std::cerr << "verify: shard " << shard.index << "/" << shard.count << ": " << own.size()
              << " of " << files.size() << " scenes\n";
  // A part holds what merge can check from its numbers (harness/shard.hpp): no second run at
  // tighter tolerances (compare's diagnosis), whose figures the part does not carry.
  o.verify.compare.diagnose = false;
  const harness::VerifyResult result = harness::run_verify(o.verify, own);
  std::cout << harness::format_verify_table(result, o.verify.strict);
  // What the outcomes depend on besides the scenes: merge refuses parts that differ in any.
  const harness::CompareCliOptions& c = o.common;
  const auto opt_num = [](const std::optional<double>& v) {
    return v ? harness::shortest_text(*v) : std::string("(scene's)");
  };
  std::string inertia;
  for (const std::string& x : c.test_inertia_scale) inertia += (inertia.empty() ? "" : " ") + x;
  const harness::PartOptions part_options{
      {"--engines", c.engines.empty() ? "(all)" : c.engines},
      {"--integrator", c.integrator ? *c.integrator : "(scene's)"},
      {"--rtol", opt_num(c.rtol)},
      {"--atol", opt_num(c.atol)},
      {"--dt", opt_num(c.dt)},
      {"--no-analytic", c.no_analytic ? "yes" : "no"},
      {"--max-steps", c.max_steps ? std::to_string(*c.max_steps) : "(scene's)"},
      {"--timeout", opt_num(c.timeout)},
      {"--allow-no-comparison", o.verify.allow_no_comparison ? "yes" : "no"},
      {"--no-converge", o.verify.converge ? "no" : "yes"},
      {"--test-inertia-scale", inertia.empty() ? "(none)" : inertia}};
  part_file->stream() << harness::part_json(shard, plan, result.scenes, part_options);
  commit_together({&*part_file});
  std::cout << "part " << shard.index << "/" << shard.count << ": " << o.part << '\n';
  check_written(std::cout);
  return result.exit_code(o.verify.strict);
}

int verify(VerifyCommandOptions& o) {
  o.common.quiet = o.verify.quiet;  // --quiet also silences the progress line
  // 1. Everything that can be refused before the work: options, scenes, outputs (exit 2).
  o.verify.compare = harness::to_compare_options(o.common);
  if (!o.shard.empty()) harness::parse_shard(o.shard);  // a bad --shard before anything else
  const std::vector<std::string> files = harness::scene_files(o.verify);
  if (!o.shard.empty() || !o.part.empty()) return verify_shard(o, files);
  // The scenes and every data file they read (nodal CSV files).
  std::vector<NamedPath> inputs;
  for (const std::string& f : files)
    for (NamedPath& p : harness::scene_file_inputs(f)) inputs.push_back(std::move(p));
  Outputs out;
  open_outputs(o, inputs, out);

  // 2. The verdict: every scene compared, the table, the JSON summary, the JUnit XML, the report.
  const harness::VerifyResult result = harness::run_verify(o.verify, files);
  return write_outputs(o, out, result);
}

// crossdyn merge PARTS...: the parts checked (harness/shard.hpp merge_parts), then exactly what
// verify writes for the whole run.
int merge_parts_command(VerifyCommandOptions& o);

// A part's text reaches the messages (paths, versions, names): a control character in it (a
// newline) would break the one-line error, so it is shown as '?'.
int merge(VerifyCommandOptions& o) {
  try {
    return merge_parts_command(o);
  } catch (const InputError& e) {
    std::string m = e.what();
    for (char& c : m)
      if (static_cast<unsigned char>(c) < 32 || c == 127) c = '?';
    throw InputError(m);
  }
}

int merge_parts_command(VerifyCommandOptions& o) {
  std::vector<harness::Part> parts;
  std::vector<NamedPath> inputs;
  for (const std::string& f : o.parts) inputs.push_back({"the part file", f});
  // A part must be a regular file: a FIFO with no writer would block the read forever, /dev/zero
  // never end (opened without blocking and checked on the descriptor: core/input_file.hpp).
  for (const std::string& f : o.parts)
    if (const std::string why = input_file_problem(f, Pipes::Refuse); !why.empty())
      throw InputError("cannot read the part file '" + f + "': " + why);
  std::size_t budget = harness::kPartMemoryBudget;  // all the parts together
  for (const std::string& f : o.parts) parts.push_back(harness::read_part(f, budget));
  // The scenes the parts name (and the data files they read) are inputs too: every output is
  // checked against them now, before the merge's work, not when the report is written.
  std::set<std::string> named;
  for (const harness::Part& p : parts)
    for (const harness::ShardScene& sc : p.scenes)
      if (named.insert(sc.path).second)
        for (NamedPath& in : harness::scene_file_inputs(sc.path)) inputs.push_back(std::move(in));
  const std::string command = parts.front().command;
  if (command != "verify") {
    // study and stability parts: their outputs (the commands' own --csv and --report).
    // study and stability: the table, --csv, --report; converge: the table, --json.
    const bool converge = command == "converge";
    if (o.python_option->count() > 0)
      throw InputError("merge: --python is for the report of verify's parts; parts of `crossdyn " +
                       command + "` are merged as the command writes them (its reports run "
                       "/usr/bin/python3)");
    if (o.verify.strict)
      throw InputError("merge: --strict is for verify's parts (their scene warnings); parts of "
                       "`crossdyn " + command + "` are merged as the command writes them");
    if ((!converge && o.json_option->count() > 0) || !o.junit.empty() || !o.report_script.empty() ||
        (converge && (!o.csv.empty() || o.report)))
      throw InputError("merge: parts of `crossdyn " + command + "` give " +
                       (converge ? "the table and --json" : "the table, --csv and --report") +
                       ", as the command does");
    std::vector<NamedPath> outputs{{"standard output", "-"}}, folders;
    if (!o.csv.empty()) outputs.push_back({"--csv", o.csv});
    if (converge && o.json_option->count() > 0) outputs.push_back({"--json", o.json});
    if (o.report) folders.push_back({"--report", *o.report});
    check_outputs_are_not_inputs(outputs, inputs, folders);
    const SweepMergeOutputs sweep{o.csv, o.report, converge && o.json_option->count() > 0 ? o.json : "",
                                  o.verify.quiet};
    if (command == "study") return merge_study_parts(parts, sweep);
    if (command == "stability") return merge_stability_parts(parts, sweep);
    if (converge) return merge_converge_parts(parts, sweep);
    throw InputError("part '" + parts.front().file + "' was written by `crossdyn " + command +
                     "`, which this crossdyn cannot merge");
  }
  if (!o.csv.empty())
    throw InputError("merge: --csv is for parts of `crossdyn study` and `crossdyn stability`; "
                     "verify's parts give --json, --junit and --report");
  Outputs out;
  open_outputs(o, inputs, out);
  int checked = 0;
  harness::VerifyResult result;
  result.scenes = harness::merge_parts(parts, harness::version(), &checked);
  if (!o.verify.quiet)
    std::cerr << "merge: " << parts.size() << " parts, " << result.scenes.size() << " scenes ("
              << checked << " scene files on disk checked against their SHA-256)\n";
  // The scenes' warnings, as verify printed them in the shards: once per scene, --quiet or not.
  for (const harness::SceneOutcome& s : result.scenes) harness::print_warnings(s.warnings, std::cerr);
  return write_outputs(o, out, result);
}

}  // namespace

void add_verify_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<VerifyCommandOptions>();
  CLI::App* sub = app.add_subcommand(
      "verify",
      "Run `compare` on every scene (all of scenarios/*.yaml and *.yml when none is named), print\n"
      "one scene x check table (worst normalised error, PASS/FAIL), write a JSON summary and, when\n"
      "asked, JUnit XML and an HTML report. A scene that cannot be read or whose comparison fails\n"
      "is reported and the others still run. The report comes last and never changes the exit\n"
      "status: 0 all pass, 1 a check failed or a scene compared nothing (or, with --strict, a\n"
      "scene has a warning), 2 bad input, 3 a scene ended with an error or an output could not\n"
      "be written, 130 interrupted. Scene warnings are printed on stderr, once per scene, and\n"
      "are in the table, the JSON summary, the JUnit XML and the report; they are not failures.");
  sub->add_option("scenes", o->verify.scenes,
                  "Scene files or names (default: every scene of the scenes folder)");
  sub->add_option("--scenarios", o->verify.scenarios_dir,
                  "Folder of scenes used when none is named (default: ./scenarios, else the "
                  "source tree's)");
  harness::add_compare_cli_options(*sub, o->common);
  sub->add_flag("--allow-no-comparison", o->verify.allow_no_comparison,
                "Accept a scene where nothing is compared (one engine, every quantity excluded); "
                "by default that fails");
  o->json_option = sub->add_option("--json", o->json,
                                   "Write the JSON summary to FILE (default: "
                                   "reports/latest/summary.json, or only DIR/summary.json with "
                                   "--report DIR)");
  sub->add_option("--junit", o->junit, "Write JUnit XML to FILE (for CI)");
  sub->add_option("--report", o->report,
                  "Write the HTML report (index.html, a page per scene, PNG charts) to DIR "
                  "(default when given without DIR: reports/latest; name the scenes before "
                  "--report or write --report=DIR). DIR must not hold any input.")
      ->expected(0, 1)
      ->default_str("reports/latest");
  sub->add_option("--python", o->python,
                  "Python with matplotlib for the report (default: /usr/bin/python3, Debian's)");
  sub->add_option("--report-script", o->report_script,
                  "The report script to run (default: reports/make_report.py of the source tree "
                  "crossdyn was built from; a script beside the scenes is never run)");
  sub->add_flag("--quiet,-q", o->verify.quiet,
                "No progress line per scene on stderr (scene warnings are still printed)");
  sub->add_flag("--strict", o->verify.strict,
                "Exit with status 1 when a scene has a warning and nothing worse happened (every "
                "output written as usual; with --shard, the slice's status)");
  sub->add_flag("--no-converge", [o](std::int64_t) { o->verify.converge = false; },
                "Do not run `converge` on flexible scenes (the report's model-size section)");
  sub->add_option("--shard", o->shard,
                  "Run only slice K of N (K counts from 0: 0/4, 1/4, 2/4, 3/4, as Slurm's "
                  "SLURM_ARRAY_TASK_ID) and write --part FILE for `crossdyn merge`. Scenes are "
                  "assigned by content (SHA-256 of name and bytes) and balanced by a static cost "
                  "estimate, so the slices do not depend on the order the scenes are named in")
      ->type_name("K/N");
  sub->add_option("--part", o->part,
                  "With --shard: write this shard's part file (JSON: version, all scenes with "
                  "their SHA-256, this slice's full results); without --shard: the whole run as "
                  "part 0/1");
  sub->callback([o, &exit_code] { exit_code = verify(*o); });
}

void add_merge_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<VerifyCommandOptions>();
  CLI::App* sub = app.add_subcommand(
      "merge",
      "Combine the part files of `crossdyn verify|study|stability|converge --shard K/N --part\n"
      "FILE` (K = 0..N-1) into exactly what the unsharded command writes: verify's table, JSON\n"
      "summary, JUnit XML and report (run times are each part's own); study's tables, --csv and\n"
      "--report; stability's map, --csv and --report (CPU times are each part's own); converge's\n"
      "table and --json. Refused, exit status 2, naming what is wrong: parts of another crossdyn\n"
      "version or of different commands, made with different options, of different N, a missing\n"
      "or repeated shard, different scene lists or scene hashes, or a scene file on disk that\n"
      "changed since (run merge where the shards ran). Otherwise the exit status is the whole\n"
      "run's, as the command's.");
  sub->add_option("parts", o->parts, "The part files, one per shard, in any order")->required();
  o->json_option = sub->add_option("--json", o->json,
                                   "Write the JSON summary to FILE (default: "
                                   "reports/latest/summary.json, or only DIR/summary.json with "
                                   "--report DIR; converge parts: the converge JSON, "
                                   "only when given)");
  sub->add_option("--junit", o->junit, "Write JUnit XML to FILE (for CI; verify parts)");
  sub->add_option("--csv", o->csv, "Write the CSV to FILE (study and stability parts, as their --csv)");
  sub->add_option("--report", o->report,
                  "Write the HTML report to DIR (default when given without DIR: reports/latest; "
                  "write --report=DIR after the parts)")
      ->expected(0, 1)
      ->default_str("reports/latest");
  o->python_option = sub->add_option("--python", o->python,
                                     "Python with matplotlib for the report of verify's parts "
                                     "(default: /usr/bin/python3, Debian's)");
  sub->add_option("--report-script", o->report_script,
                  "The report script to run (default: reports/make_report.py of the source tree "
                  "crossdyn was built from)");
  sub->add_flag("--quiet,-q", o->verify.quiet,
                "No summary line on stderr (the scenes' warnings are still printed)");
  sub->add_flag("--strict", o->verify.strict,
                "verify parts: exit with status 1 when a scene has a warning and nothing worse "
                "happened, as `verify --strict` (every output written as usual)");
  sub->callback([o, &exit_code] { exit_code = merge(*o); });
}

}  // namespace crossdyn
