// crossdyn verify: compare on every scene, one summary table, a JSON summary, JUnit XML and the
// HTML report (README "Verifying"). A scene that cannot be read is reported (exit 2 at the end)
// and the others still run; a failing engine run is a failed check of that scene.
#pragma once

#include "harness/compare.hpp"
#include "harness/report.hpp"

#include <optional>
#include <string>
#include <vector>

namespace crossdyn::harness {

struct VerifyOptions {
  std::vector<std::string> scenes;          // empty: every *.yaml in scenarios_dir, sorted
  std::string scenarios_dir = "scenarios";
  CompareOptions compare;
  std::string json = "reports/latest/summary.json";  // "" : none
  std::string junit;                        // "" : none
  std::optional<ReportOptions> report;      // empty: no HTML report
  bool quiet = false;                       // no per-scene progress lines on stderr
};

struct VerifyResult {
  std::vector<SceneOutcome> scenes;
  // 0 every check passed, 1 a check failed, 2 a scene could not be read.
  int exit_code() const;
};

// The scene files verify runs: the given ones, or every scenarios_dir/*.yaml (InputError when
// there are none).
std::vector<std::string> scene_files(const VerifyOptions& options);

// Compares every scene and writes the JSON summary, JUnit XML and report that were asked for.
VerifyResult run_verify(const VerifyOptions& options);

// The scene x check-group table: per cell the worst normalised error and PASS/FAIL; failed checks
// listed under it with their numbers.
std::string format_verify_table(const VerifyResult& result);

}  // namespace crossdyn::harness
