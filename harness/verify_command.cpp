// crossdyn verify [SCENE ...]: compare on every scene (all of scenarios/ by default), one summary
// table, a JSON summary, JUnit XML and an HTML report (see harness/verify.hpp for the order and
// why the report never changes the verdict).
#include <CLI/CLI.hpp>

#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "core/output.hpp"
#include "harness/commands.hpp"
#include "harness/locations.hpp"
#include "harness/verify.hpp"

#include <cstdint>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>

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
};

// Opens an AtomicFile for an output in `f`, its folder created first (nothing for "").
void open_output(std::optional<AtomicFile>& f, const std::string& path, const std::string& label) {
  if (path.empty()) return;
  if (path != "-") harness::make_directories(fs::path(path).parent_path().string());
  f.emplace(path, label);
}

int verify(VerifyCommandOptions& o) {
  o.common.quiet = o.verify.quiet;  // --quiet also silences the progress line
  // 1. Everything that can be refused before the work: options, scenes, outputs (exit 2).
  o.verify.compare = harness::to_compare_options(o.common);
  const std::vector<std::string> files = harness::scene_files(o.verify);
  std::string json = o.json;
  // The report folder has its own summary.json; write another only when asked.
  if (o.report && o.json_option->count() == 0) json.clear();
  const std::string script = o.report_script.empty() ? harness::installed_report_script()
                                                     : o.report_script;
  std::vector<NamedPath> inputs, outputs{{"standard output", "-"}}, folders;
  for (const std::string& f : files) inputs.push_back({"the scene file", f});
  if (o.report) {
    inputs.push_back({"the report script", script});
    folders.push_back({"--report", *o.report});
  }
  if (!json.empty()) outputs.push_back({"--json", json});
  if (!o.junit.empty()) outputs.push_back({"--junit", o.junit});
  check_outputs_are_not_inputs(outputs, inputs, folders);
  std::optional<AtomicFile> json_file, junit_file;
  open_output(json_file, json, "--json");
  open_output(junit_file, o.junit, "--junit");

  // 2. The verdict: every scene compared, the table, the JSON summary, the JUnit XML.
  const harness::VerifyResult result = harness::run_verify(o.verify, files);
  std::cout << harness::format_verify_table(result);
  check_written(std::cout);
  if (json_file) {
    json_file->stream() << harness::json_summary(result.scenes);
    json_file->commit();
    std::cout << "JSON summary: " << json << '\n';
  }
  if (junit_file) {
    junit_file->stream() << harness::junit_xml(result.scenes);
    junit_file->commit();
    std::cout << "JUnit XML: " << o.junit << '\n';
  }
  check_written(std::cout);

  // 3. The report: its failure is reported, never the verdict; Ctrl-C during it is 130.
  if (o.report) {
    harness::ReportOptions r;
    r.dir = *o.report;
    r.python = o.python;
    r.script = script;
    try {
      harness::write_report(result.scenes, r);
      std::cout << "report: " << r.dir << "/index.html\n";
    } catch (const RunFailure& f) {
      if (f.reason() == "interrupted") throw;
      std::cout << "report: NOT WRITTEN (see the message on stderr)\n";
      std::cerr << "crossdyn: report not written: " << f.what() << '\n';
    } catch (const std::exception& e) {
      std::cout << "report: NOT WRITTEN (see the message on stderr)\n";
      std::cerr << "crossdyn: report not written: " << e.what()
                << " (the verdict above stands; exit status " << result.exit_code() << ")\n";
    }
    if (interrupt_requested()) throw RunFailure("report", 0.0, "", "interrupted");
    check_written(std::cout);
  }
  return result.exit_code();
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
      "status: 0 all pass, 1 a check failed or a scene compared nothing, 2 bad input, 3 a scene\n"
      "ended with an error or an output could not be written, 130 interrupted.");
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
  sub->add_flag("--quiet,-q", o->verify.quiet, "No progress line per scene on stderr");
  sub->add_flag("--no-converge", [o](std::int64_t) { o->verify.converge = false; },
                "Do not run `converge` on flexible scenes (the report's model-size section)");
  sub->callback([o, &exit_code] { exit_code = verify(*o); });
}

}  // namespace crossdyn
