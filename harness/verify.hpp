// crossdyn verify: compare on every scene, one summary table, a JSON summary, JUnit XML and the
// HTML report (docs/commands/verify.md).
//
// Order, so that the verdict never depends on the report: every scene is compared (a scene that
// cannot be read, or whose comparison throws anything, is recorded for that scene and the others
// still run), then the table is printed, then the JSON summary and the JUnit XML are written,
// then the report. A report that cannot be made (no matplotlib, --report naming a file, the script
// failing) is a message on stderr and a line under the table; the exit status stays the verdict.
#pragma once

#include "harness/compare.hpp"
#include "harness/report.hpp"
#include "harness/settings.hpp"

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace crossdyn::harness {

// The most models verify's converge runs for one scene (converge.hpp); beyond, a note.
inline constexpr long kVerifyConvergeModels = 32;

struct VerifyOptions {
  std::vector<std::string> scenes;          // empty: every scene of scenarios_dir
  std::string scenarios_dir;                // "": the first of scene_folders() (locations.hpp)
  CompareOptions compare;
  bool allow_no_comparison = false;         // a scene that compares nothing passes (with a note)
  bool quiet = false;                       // no per-scene progress lines on stderr (warnings stay)
  bool strict = false;                      // a scene warning makes an exit status 0 a 1
  // Flexible scenes: also run `converge` (kane, at most kVerifyConvergeModels models) for the
  // report's model-size table and chart; informational, never part of the verdict.
  bool converge = true;
  // The comparison of one scene; compare_scene unless a test replaces it.
  std::function<SceneComparison(const System&, const CompareOptions&)> compare_fn;
};

struct VerifyResult {
  std::vector<SceneOutcome> scenes;
  // 2 a scene could not be read, else 3 a scene's comparison ended with an error, else 1 a check
  // failed (or a scene compared nothing), else (with `strict`) 1 a scene has a warning, else 0.
  int exit_code(bool strict = false) const;
  std::size_t warnings() const;  // the scenes' warnings, all together
};

// The scene files verify runs: the given ones (names resolved as `crossdyn run` does), or every
// *.yaml and *.yml of the scenes folder. InputError when there are none or the folder cannot be
// listed.
std::vector<std::string> scene_files(const VerifyOptions& options);

// Compares every scene of `files`; writes nothing. Rethrows only an interrupt (Ctrl-C).
VerifyResult run_verify(const VerifyOptions& options, const std::vector<std::string>& files);

// The overrides compare and verify apply to every scene, for the run limits (settings.hpp).
RunOverrides run_overrides(const CompareOptions& options);

// "" when `c` compared at least one pair of runs (a pairwise check that passed or failed), else
// why nothing was compared.
std::string nothing_compared(const SceneComparison& c);
// When nothing was compared: a failed check "comparison" (so every output shows it), or with
// `allow` only a note.
void require_comparison(SceneComparison& c, bool allow);

// The scene x check-group table: per cell the worst normalised error and PASS/FAIL; failed checks
// listed under it with their numbers; then the scenes' warnings, one line each, and the totals
// (with the number of warnings, and what --strict, when `strict`, makes of them).
std::string format_verify_table(const VerifyResult& result, bool strict = false);

}  // namespace crossdyn::harness
