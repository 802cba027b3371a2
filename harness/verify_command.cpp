// crossdyn verify [SCENE ...]: compare on every scene (all of scenarios/*.yaml by default), one
// summary table, a JSON summary, JUnit XML and an HTML report (see harness/verify.hpp).
#include <CLI/CLI.hpp>

#include "core/errors.hpp"
#include "harness/commands.hpp"
#include "harness/verify.hpp"

#include <iostream>
#include <memory>

namespace crossdyn {

namespace {

struct VerifyCommandOptions {
  harness::VerifyOptions verify;
  harness::CompareCliOptions common;
  std::optional<std::string> report;
  std::string python = "/usr/bin/python3";
  std::string report_script;
  CLI::Option* json_option = nullptr;
};

int verify(VerifyCommandOptions& o) {
  o.common.quiet = o.verify.quiet;  // --quiet also silences the progress line
  o.verify.compare = harness::to_compare_options(o.common);
  if (o.report) {
    harness::ReportOptions r;
    r.dir = *o.report;
    r.python = o.python;
    r.script = o.report_script;
    o.verify.report = r;
    // The report folder has its own summary.json; write another only when asked.
    if (o.json_option->count() == 0) o.verify.json.clear();
  }
  const harness::VerifyResult result = harness::run_verify(o.verify);
  std::cout << harness::format_verify_table(result);
  if (!o.verify.json.empty()) std::cout << "JSON summary: " << o.verify.json << '\n';
  if (!o.verify.junit.empty()) std::cout << "JUnit XML: " << o.verify.junit << '\n';
  if (o.verify.report) std::cout << "report: " << o.verify.report->dir << "/index.html\n";
  return result.exit_code();
}

}  // namespace

void add_verify_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<VerifyCommandOptions>();
  CLI::App* sub = app.add_subcommand(
      "verify",
      "Run `compare` on every scene (all of scenarios/*.yaml when none is named), print one\n"
      "scene x check table (worst normalised error, PASS/FAIL), write a JSON summary and, when\n"
      "asked, JUnit XML and an HTML report. A scene that cannot be read or an engine run that\n"
      "fails is reported and the others still run. Exit status 0 all pass, 1 a check failed,\n"
      "2 bad input.");
  sub->add_option("scenes", o->verify.scenes, "Scene files (default: every SCENARIOS/*.yaml)");
  sub->add_option("--scenarios", o->verify.scenarios_dir,
                  "Folder of scenes used when none is named (default: scenarios)");
  harness::add_compare_cli_options(*sub, o->common);
  o->json_option = sub->add_option("--json", o->verify.json,
                  "Write the JSON summary to FILE (default: reports/latest/summary.json, or "
                                   "only DIR/summary.json with --report DIR)");
  sub->add_option("--junit", o->verify.junit, "Write JUnit XML to FILE (for CI)");
  sub->add_option("--report", o->report,
                  "Write the HTML report (index.html, a page per scene, PNG charts) to DIR "
                  "(default when given without DIR: reports/latest; name the scenes before "
                  "--report or write --report=DIR)")
      ->expected(0, 1)
      ->default_str("reports/latest");
  sub->add_option("--python", o->python,
                  "Python with matplotlib for the report (default: /usr/bin/python3, Debian's)");
  sub->add_option("--report-script", o->report_script,
                  "The report script (default: reports/make_report.py next to the scenes' folder)");
  sub->add_flag("--quiet,-q", o->verify.quiet, "No progress line per scene on stderr");
  sub->callback([o, &exit_code] { exit_code = verify(*o); });
}

}  // namespace crossdyn
