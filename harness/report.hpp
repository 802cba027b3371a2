// What verify and compare write: the JSON summary, JUnit XML, and the HTML report folder (made by
// reports/make_report.py from the JSON summary and the runs' CSV files). Every file is written
// atomically (core/output.hpp AtomicFile): a reader sees the old file or the complete new one.
#pragma once

#include "core/output.hpp"
#include "core/scene/scene.hpp"
#include "harness/compare.hpp"

#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace crossdyn::harness {

// One scene of a verify run: read and compared, or rejected as bad input.
struct SceneOutcome {
  std::string path;                           // the scene file as given
  std::optional<System> system;               // empty when the file could not be read
  std::optional<SceneComparison> comparison;  // empty when the file could not be read
  std::string input_error;                    // InputError message when it could not
  bool internal_error = false;                // input_error is another error (verify: exit 3)
  // verify on a flexible scene: `crossdyn converge`'s result as JSON (harness/converge.hpp
  // converge_json), or why it was not run; informational, never part of the verdict.
  std::string converge_json{};
  std::string converge_note{};
  // The scene's warnings (harness/scene_warnings.hpp), when it could be read; never a failure.
  std::vector<SceneWarning> warnings{};
};

// The scene x check-group summary cell (verify's table, the report index, JSON "groups").
struct GroupSummary {
  std::string group;        // "run", "w", "attitude", "rate", "angle", "modal", "H", "E",
                            // "H.drift", "E.drift", "extra", "t"
  CheckStatus status = CheckStatus::Pass;  // Fail if any fails; Pass if any passes; else the rest
  double worst = 0;         // largest normalised error of the group's passed/failed checks
  std::string worst_check;  // "main.wx kane*1.001 vs kane"
  int checks = 0, failed = 0, excluded = 0, skipped = 0;
};
// Groups in table order; only groups that have checks.
std::vector<GroupSummary> summarise_groups(const SceneComparison& c);
// The fixed order of the groups in tables.
const std::vector<std::string>& group_order();

// One line with the numbers of a failed check: "main.wx, lagrange vs kane: max error 1.2e-05 at
// t = 3.4 s > bound 2.6e-08 (atol 1e-08 + rtol 1e-08 * 1.57), error/bound 4.6e+02, first over at
// t = 0.05 s"; for a run: "kane: run failed at t = 2.1 s: <reason>".
std::string describe_failure(const Check& c);

// JSON summary of every scene: settings, scene data and assumptions, runs, every check, the
// group summary and notes. `data_files`, when not empty, gives per scene (same order) and per run
// the CSV file written for the report (relative to the JSON file).
std::string json_summary(const std::vector<SceneOutcome>& scenes,
                         const std::vector<std::vector<std::string>>& data_files = {});
void write_json_summary(const std::string& path, const std::vector<SceneOutcome>& scenes);

// JUnit XML (the Jenkins/Ant schema CI systems read): one <testsuite> per scene, one <testcase>
// per scene and check (a quantity over all engine pairs, a drift over all engines, or one
// engine's run); <failure> carries the numbers, <skipped> the reason, and an unreadable scene is
// an <error>.
std::string junit_xml(const std::vector<SceneOutcome>& scenes);

struct ReportOptions {
  std::string dir = "reports/latest";
  std::string python = "/usr/bin/python3";  // Debian's, which has matplotlib
  std::string script;                        // "" : the installed reports/make_report.py
};

// Writes the report into a new sibling folder of DIR (DIR.partial-<pid>-<random>): the runs' CSV
// files DIR/data/<scene>/<run>.csv, each scene's drawing geometry DIR/data/<scene>/geometry.json
// (harness/scene_geometry.hpp; the later pictures from the kane run), DIR/summary.json; then runs
// the report script, which writes index.html, <scene>.html and the PNG charts there. Then, holding
// an exclusive lock on DIR's parent folder, swaps the new folder in for DIR in one rename and
// removes the old one: a reader, and a second verify writing the same DIR, always see one whole
// report, never a mixture. Refuses (InputError, before any work) a DIR that is a file, a folder
// that is neither empty nor a crossdyn report (no summary.json with "tool": "crossdyn"), or one
// that holds a scene file or the current folder. Throws InputError when the folder cannot be
// written or the script fails; the partial folder is removed (and so are partial folders left
// by killed runs whose process is gone).
void write_report(const std::vector<SceneOutcome>& scenes, const ReportOptions& options);

class PartialFolder;
// A report folder replaced whole (the machinery of write_report, for every command's --report):
// constructed, it creates DIR.partial-<pid>-<random> beside DIR (InputError when it cannot: a
// folder where nothing can be created is refused before the work); the report is written into
// path(); commit_together (core/output.hpp) then prepares it (locks DIR's parent folder and
// copies in what DIR holds that `owned` says the report does not own: a user's notes) and
// publishes it (one rename exchanges the folders). Destroyed before, it removes the new folder
// and DIR is untouched.
class StagedFolder : public StagedOutput {
 public:
  StagedFolder(std::filesystem::path dir, bool (*owned)(const std::filesystem::path& name));
  ~StagedFolder() override;
  StagedFolder(const StagedFolder&) = delete;
  StagedFolder& operator=(const StagedFolder&) = delete;
  const std::filesystem::path& path() const;
  const std::filesystem::path& target() const { return dir_; }
  void prepare() override;
  void publish() override;

 private:
  std::filesystem::path dir_;
  bool (*owned_)(const std::filesystem::path&);
  std::unique_ptr<PartialFolder> partial_;
  int lock_fd_ = -1;
};

// write_report in two steps: check_report refuses, before any work, what write_report would
// refuse (a missing script, a DIR that is a file or not a report folder, one holding a scene, a
// folder where nothing can be created); build_report writes the report into a StagedFolder for
// commit_together, so that it is swapped in together with the command's other outputs.
void check_report(const std::vector<std::string>& scene_files, const ReportOptions& options);
std::unique_ptr<StagedFolder> build_report(const std::vector<SceneOutcome>& scenes,
                                           const ReportOptions& options);

// The --report DIR of study and stability (and of merge of their parts), checked before the work:
// refuses (InputError) a DIR that is a file, the root, one holding the current folder, or a
// non-empty folder without a `marker` JSON file whose "tool" is crossdyn and "kind" is `kind`;
// creates DIR's parents and its staging folder (StagedFolder), or refuses when it cannot.
std::unique_ptr<StagedFolder> stage_report_folder(const std::string& given, const std::string& marker,
                                                  const std::string& kind,
                                                  bool (*owned)(const std::filesystem::path& name));

// Refuses (InputError, exit 2), before the work, a `--python` that cannot be run: missing, a
// folder or another non-regular file, or one without an execute bit (for root too) or that the
// user may not execute. The path is used as given (no PATH search), as run_python does.
void check_python(const std::string& python);

// Runs `python ARGS...` (with PYTHONDONTWRITEBYTECODE=1) and waits; Ctrl-C ends it (RunFailure
// "interrupted"); InputError naming args[0] when it cannot start or fails.
void run_python(const std::string& python, const std::vector<std::string>& args);

// A name safe in a file name: letters, digits, '-', '_' (and '.' when keep_dots); anything else
// becomes '_'; an empty name becomes `empty`.
std::string file_safe(std::string s, bool keep_dots = true, const std::string& empty = "_");

// One id per base, in order, unique among themselves and `taken` (reserved page names): a base
// already taken gets `<base><separator>2`, `<base><separator>3`, ...
std::vector<std::string> unique_ids(const std::vector<std::string>& bases, std::set<std::string> taken,
                                    char separator);

// Creates a folder and its parents; InputError naming it when that fails.
void make_directories(const std::string& dir);

}  // namespace crossdyn::harness
