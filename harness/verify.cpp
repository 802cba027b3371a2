// crossdyn verify (see verify.hpp).
#include "harness/verify.hpp"

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/output.hpp"
#include "core/scene/scene.hpp"
#include "harness/converge.hpp"
#include "harness/locations.hpp"
#include "harness/scene_warnings.hpp"

#include <algorithm>
#include <chrono>
#include <optional>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <map>
#include <new>

namespace crossdyn::harness {

int VerifyResult::exit_code(bool strict) const {
  bool failed = false, error = false;
  for (const SceneOutcome& s : scenes) {
    if (!s.comparison && !s.internal_error) return kExitBadInput;
    error = error || s.internal_error;
    failed = failed || (s.comparison && !s.comparison->passed());
  }
  return strict_status(error ? kExitRunFailed : failed ? kExitCheckFailed : kExitOk, strict, warnings());
}

std::size_t VerifyResult::warnings() const {
  std::size_t n = 0;
  for (const SceneOutcome& s : scenes) n += s.warnings.size();
  return n;
}

std::vector<std::string> scene_files(const VerifyOptions& o) {
  if (!o.scenes.empty()) {
    std::vector<std::string> files;
    for (const std::string& s : o.scenes) files.push_back(resolve_scene(s));
    return files;
  }
  std::string dir = o.scenarios_dir;
  if (dir.empty()) {
    const std::vector<std::string> folders = scene_folders();
    if (folders.empty())
      throw InputError("no scenes named, and no scenes folder: neither ./scenarios nor " +
                       source_tree() + "/scenarios exists (name scenes or give --scenarios DIR)");
    dir = folders.front();
  }
  const SceneFolder folder = scan_scene_folder(dir);
  if (folder.scenes.empty()) throw InputError("no *.yaml or *.yml scenes in '" + dir + "'");
  if (!o.quiet)
    for (const auto& [path, why] : folder.skipped)
      std::cerr << "verify: skipped '" << path << "': " << why << '\n';
  return folder.scenes;
}

RunOverrides run_overrides(const CompareOptions& c) {
  RunOverrides o;
  if (c.integrator) o.integrator = c.integrator->str();
  o.rtol = c.rtol;
  o.atol = c.atol;
  o.dt = c.dt;
  return o;
}

std::string nothing_compared(const SceneComparison& c) {
  int ok = 0, pairs = 0, excluded = 0;
  for (const EngineRun& r : c.runs) ok += r.state == EngineRun::State::Ok ? 1 : 0;
  for (const Check& k : c.checks) {
    if (k.b.empty()) continue;  // runs and drifts concern one engine
    ++pairs;
    if (k.status == CheckStatus::Pass || k.status == CheckStatus::Fail) return "";
    if (k.status == CheckStatus::Excluded) ++excluded;
  }
  if (ok < 2) {
    std::string names;
    for (const EngineRun& r : c.runs)
      if (r.state == EngineRun::State::Ok) names += (names.empty() ? "" : ", ") + r.label;
    return ok == 0 ? "no run finished"
                   : "only " + names + " finished, and there is no second engine or analytic "
                     "solution to compare it with";
  }
  if (pairs > 0 && excluded == pairs) return "the scene excludes every compared quantity";
  return "no pairwise check was made";
}

void require_comparison(SceneComparison& c, bool allow) {
  const std::string why = nothing_compared(c);
  if (why.empty()) return;
  if (allow) {
    c.notes.push_back("nothing was compared (" + why + "); accepted by --allow-no-comparison");
    return;
  }
  Check k;
  k.quantity = "comparison";
  k.group = "run";
  k.a = "all runs";
  k.tolerance_key = "-";
  k.status = CheckStatus::Fail;
  k.error = k.normalised = std::numeric_limits<double>::infinity();
  k.note = "nothing was compared: " + why +
           " (run more engines, or pass --allow-no-comparison to accept this)";
  c.checks.push_back(k);
}

// A flexible scene's `converge` result for the report (converge.hpp), with kane and the
// comparison's run settings; what keeps it from running is a note, never a failure of the scene.
void add_converge(SceneOutcome& s, const VerifyOptions& o) {
  const std::vector<ModeGroup> groups = mode_groups(*s.system);
  if (groups.empty()) return;
  long models = 1;
  for (const ModeGroup& g : groups) models *= static_cast<long>(g.modes.size()) + 1;
  if (models > kVerifyConvergeModels) {
    s.converge_note = "converge not run by verify: " + std::to_string(models) +
                      " models (the limit here is " + std::to_string(kVerifyConvergeModels) +
                      "); run `crossdyn converge " + s.path + "`";
    return;
  }
  CompareOptions one = o.compare;
  one.engines = {{"kane", "kane", {}}};
  one.progress = false;
  try {
    s.converge_json = converge_json(converge_scene(*s.system, one));
  } catch (const cancel::Cancelled& c) {
    if (c.reason() == cancel::Reason::Interrupt) throw;
    s.converge_note = std::string("converge not completed: ") + c.what();
  } catch (const InputError& e) {
    s.converge_note = std::string("converge not run: ") + e.what();
  } catch (const RunFailure& f) {
    if (f.reason() == "interrupted" || cancel::interrupted()) throw;
    s.converge_note = std::string("converge not completed: ") + f.what();
  }
}

VerifyResult run_verify(const VerifyOptions& o, const std::vector<std::string>& files) {
  VerifyResult result;
  const RunOverrides overrides = run_overrides(o.compare);
  for (const std::string& path : files) {
    SceneOutcome s;
    s.path = path;
    const auto start = std::chrono::steady_clock::now();
    try {
      // A folder's scenes must be regular files (a FIFO there is refused, never waited on).
      CheckedScene checked = read_checked_scene(path, o.scenes.empty() ? Pipes::Refuse : Pipes::Allow);
      s.system = std::move(checked.system);
      s.warnings = std::move(checked.warnings);
      print_warnings(s.warnings, std::cerr);  // once per scene, --quiet or not
      settings_for(*s.system, overrides);  // the run limits on the scene with the overrides
      s.comparison = o.compare_fn ? o.compare_fn(*s.system, o.compare)
                                  : compare_scene(*s.system, o.compare);
      require_comparison(*s.comparison, o.allow_no_comparison);
      if (o.converge) add_converge(s, o);
    } catch (const cancel::Cancelled& c) {
      if (c.reason() == cancel::Reason::Interrupt) throw;  // Ctrl-C ends verify (exit 130)
      s.comparison.reset();
      s.internal_error = true;
      s.input_error = std::string("error: ") + c.what();
    } catch (const InputError& e) {
      if (cancel::interrupted()) throw;  // an interrupted read is not bad input
      s.comparison.reset();
      s.input_error = e.what();
    } catch (const RunFailure& f) {
      if (f.reason() == "interrupted" || cancel::interrupted()) throw;
      s.comparison.reset();
      s.internal_error = true;
      s.input_error = std::string("error: ") + f.what();
    } catch (const std::bad_alloc&) {
      s.comparison.reset();
      s.internal_error = true;
      s.input_error = "error: out of memory";
    } catch (const std::exception& e) {
      if (cancel::interrupted()) throw;
      s.comparison.reset();
      s.internal_error = true;
      s.input_error = std::string("internal error: ") + e.what();
    } catch (...) {
      s.comparison.reset();
      s.internal_error = true;
      s.input_error = "internal error: unknown exception";
    }
    if (!o.quiet) {
      const double secs =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      char line[512];
      std::snprintf(line, sizeof line, "verify: %-44s %s (%.1f s)\n", path.c_str(),
                    s.internal_error ? "ERROR"
                    : !s.comparison  ? "BAD INPUT"
                    : s.comparison->passed() ? "PASS" : "FAIL",
                    secs);
      std::cerr << line;
      if (!s.comparison) std::cerr << "  " << s.input_error << '\n';
    }
    result.scenes.push_back(std::move(s));
  }
  return result;
}

namespace {

// The table's columns: short headers, each over one or more check groups (group_order()), so that
// a scene with every kind of quantity fits 130 columns. A conserved quantity's drift and a
// balanced one's balance share one (a scene has one or the other); a prescribed joint's drive
// torque is a joint load.
struct TableColumn {
  const char* header;
  std::vector<std::string> groups;
};
const std::vector<TableColumn>& table_columns() {
  static const std::vector<TableColumn> columns{
      {"runs", {"run"}},   {"t", {"t"}},           {"w", {"w"}},
      {"att", {"attitude"}}, {"rate", {"rate"}},   {"angle", {"angle"}},
      {"pos", {"position"}}, {"modal", {"modal"}}, {"load", {"torque", "load"}},
      {"H", {"H"}},        {"E", {"E"}},           {"dH", {"H.drift", "H.balance"}},
      {"dE", {"E.drift", "E.balance", "J.drift"}},           {"extra", {"extra"}}};
  return columns;
}

// The groups of one column merged: Fail if any fails, Pass if any passes, else the rest.
std::optional<GroupSummary> merged(const std::vector<GroupSummary>& scene, const TableColumn& col) {
  std::optional<GroupSummary> m;
  for (const GroupSummary& g : scene) {
    if (std::find(col.groups.begin(), col.groups.end(), g.group) == col.groups.end()) continue;
    if (!m) {
      m = g;
      continue;
    }
    m->checks += g.checks;
    m->failed += g.failed;
    m->excluded += g.excluded;
    m->skipped += g.skipped;
    if (g.worst > m->worst) {
      m->worst = g.worst;
      m->worst_check = g.worst_check;
    }
    if (g.status == CheckStatus::Fail || (g.status == CheckStatus::Pass && m->status != CheckStatus::Fail))
      m->status = g.status;
  }
  return m;
}

}  // namespace

std::string format_verify_table(const VerifyResult& r, bool strict) {
  // Columns: those any scene has, in the fixed order.
  std::vector<std::vector<GroupSummary>> per_scene;
  for (const SceneOutcome& s : r.scenes)
    per_scene.push_back(s.comparison ? summarise_groups(*s.comparison) : std::vector<GroupSummary>{});
  std::vector<const TableColumn*> columns;
  for (const TableColumn& col : table_columns())
    if (std::any_of(per_scene.begin(), per_scene.end(), [&](const auto& gs) { return merged(gs, col).has_value(); }))
      columns.push_back(&col);
  std::vector<std::vector<std::string>> rows;
  rows.push_back({"scene"});
  for (const TableColumn* col : columns) rows[0].push_back(col->header);
  rows[0].push_back("result");
  int n_checks = 0, n_failed = 0, n_excluded = 0, n_skipped = 0;
  for (std::size_t i = 0; i < r.scenes.size(); ++i) {
    const SceneOutcome& s = r.scenes[i];
    std::vector<std::string> row{s.comparison ? s.comparison->scene : s.path};
    if (!s.comparison) {
      for (std::size_t k = 0; k < columns.size(); ++k) row.push_back("-");
      row.push_back(s.internal_error ? "ERROR" : "BAD INPUT");
      rows.push_back(row);
      continue;
    }
    for (const TableColumn* col : columns) {
      const std::optional<GroupSummary> m = merged(per_scene[i], *col);
      if (!m) {
        row.push_back("-");
        continue;
      }
      const GroupSummary& x = *m;
      if (x.group == "run") {
        const int ran = x.checks - x.failed - x.skipped;
        std::string cell = x.failed ? "FAIL " + std::to_string(x.failed) + " failed"
                                    : std::to_string(ran) + " ok";
        if (x.skipped) cell += ", " + std::to_string(x.skipped) + " skipped";
        row.push_back(cell);
      } else if (x.status == CheckStatus::Pass) {
        row.push_back(sci(x.worst, 1));  // a passing cell is its number: the table fits 130 columns
      } else if (x.status == CheckStatus::Fail) {
        row.push_back("FAIL " + sci(x.worst, 1));
      } else {
        row.push_back(x.status == CheckStatus::Excluded ? "excl." : "skip");
      }
    }
  const SceneComparison& c = *s.comparison;
    row.push_back(c.passed() ? "PASS" : "FAIL");
    rows.push_back(row);
    n_checks += static_cast<int>(c.checks.size());
    n_failed += c.count(CheckStatus::Fail);
    n_excluded += c.count(CheckStatus::Excluded);
    n_skipped += c.count(CheckStatus::Skipped);
  }
  std::string out = text_table(rows);
  out += "cells: worst normalised error of the group, error / (atol + rtol * scale); <= 1 passes\n"
         "       FAIL: above 1; excl.: excluded by the scene; -: the scene has no such quantity\n"
         "       att: attitudes; pos: positions; load: joint loads and drive torques; dH, dE: drift of H\n"
         "       and E where the scene conserves them, else their balance against the integral of M, P\n";
  // Failures: per scene and quantity the worst pair (or engine), at most kMaxLines lines.
  constexpr int kMaxLines = 30;
  std::string failures;
  int lines = 0, left_out = 0;
  for (const SceneOutcome& s : r.scenes) {
    if (!s.comparison) {
      failures += "  " + s.path + (s.internal_error ? ": " : ": bad input: ") + s.input_error + "\n";
      ++lines;
      continue;
    }
    std::vector<std::pair<std::string, std::vector<const Check*>>> by_quantity;
    for (const Check& c : s.comparison->checks) {
      if (c.status != CheckStatus::Fail) continue;
      const std::string key = c.group == "run" ? "run " + c.a : c.quantity;
      auto it = std::find_if(by_quantity.begin(), by_quantity.end(),
                             [&key](const auto& x) { return x.first == key; });
      if (it == by_quantity.end()) it = by_quantity.insert(by_quantity.end(), {key, {}});
      it->second.push_back(&c);
    }
    for (const auto& [key, checks] : by_quantity) {
      if (lines >= kMaxLines) {
        left_out += static_cast<int>(checks.size());
        continue;
      }
      const Check* worst = checks.front();
      for (const Check* c : checks)
        if (std::isnan(c->normalised) || c->normalised > worst->normalised) worst = c;
      failures += "  " + s.comparison->scene + ": " + describe_failure(*worst);
      if (checks.size() > 1) failures += " [and " + std::to_string(checks.size() - 1) + " more]";
      failures += "\n";
      ++lines;
    }
    // What compare found out about the failures (integration error or not, measured), or its
    // advice on loads.
    if (!by_quantity.empty())
      for (const std::string& note : s.comparison->notes)
        if (note.starts_with("tolerances 100 times tighter") || note.starts_with("joint loads differ")) {
          failures += "    " + note + "\n";
          ++lines;
        }
  }
  if (left_out > 0)
    failures += "  ... " + std::to_string(left_out) +
                " more failed checks: see `crossdyn compare SCENE` or the JSON summary\n";
  if (!failures.empty()) out += "\nfailed (per scene and quantity, the worst pair):\n" + failures;
  // The scenes' warnings: every one, each under its scene (they are not failures).
  std::string warned;
  for (const SceneOutcome& s : r.scenes)
    for (const SceneWarning& w : s.warnings)
      warned += "  " + (s.comparison ? s.comparison->scene : s.system ? s.system->name : s.path) +
                ": " + w.detail() + " [" + w.code + "]\n";
  if (!warned.empty())
    out += "\nscene warnings (not failures" +
           std::string(strict ? "; with --strict they make the exit status 1" : "") + "):\n" + warned;
  char totals[256];
  std::snprintf(totals, sizeof totals,
                "\n%zu scenes, %d checks: %d passed, %d failed, %d excluded, %d skipped; %zu scene "
                "warning%s\n",
                r.scenes.size(), n_checks, n_checks - n_failed - n_excluded - n_skipped, n_failed,
                n_excluded, n_skipped, r.warnings(), r.warnings() == 1 ? "" : "s");
  out += totals;
  return out;
}

}  // namespace crossdyn::harness
