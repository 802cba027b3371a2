// crossdyn verify (see verify.hpp).
#include "harness/verify.hpp"

#include "core/errors.hpp"
#include "core/output.hpp"
#include "core/scene/scene.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>

namespace crossdyn::harness {

namespace fs = std::filesystem;

int VerifyResult::exit_code() const {
  bool failed = false;
  for (const SceneOutcome& s : scenes) {
    if (!s.comparison) return kExitBadInput;
    failed = failed || !s.comparison->passed();
  }
  return failed ? kExitCheckFailed : kExitOk;
}

std::vector<std::string> scene_files(const VerifyOptions& o) {
  if (!o.scenes.empty()) return o.scenes;
  std::error_code ec;
  if (!fs::is_directory(o.scenarios_dir, ec))
    throw InputError("no scenes named and the scenes folder '" + o.scenarios_dir +
                     "' does not exist (run from the project folder or give --scenarios DIR)");
  std::vector<std::string> files;
  for (const fs::directory_entry& e : fs::directory_iterator(o.scenarios_dir, ec))
    if (e.is_regular_file() && e.path().extension() == ".yaml") files.push_back(e.path().string());
  if (ec) throw InputError("cannot list '" + o.scenarios_dir + "': " + ec.message());
  std::sort(files.begin(), files.end());
  if (files.empty()) throw InputError("no *.yaml scenes in '" + o.scenarios_dir + "'");
  return files;
}

VerifyResult run_verify(const VerifyOptions& o) {
  VerifyResult result;
  for (const std::string& path : scene_files(o)) {
    SceneOutcome s;
    s.path = path;
    const auto start = std::chrono::steady_clock::now();
    try {
      std::vector<SceneWarning> warnings;
      s.system = read_scene(path, &warnings);
      for (const SceneWarning& w : warnings) std::cerr << w.text() << '\n';
      s.comparison = compare_scene(*s.system, o.compare);
    } catch (const InputError& e) {
      s.comparison.reset();
      s.input_error = e.what();
    }
    if (!o.quiet) {
      const double secs =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      char line[512];
      std::snprintf(line, sizeof line, "verify: %-44s %s (%.1f s)\n", path.c_str(),
                    !s.comparison ? "BAD INPUT" : s.comparison->passed() ? "PASS" : "FAIL", secs);
      std::cerr << line;
      if (!s.comparison) std::cerr << "  " << s.input_error << '\n';
    }
    result.scenes.push_back(std::move(s));
  }
  if (!o.json.empty()) write_json_summary(o.json, result.scenes);
  if (!o.junit.empty()) {
    make_directories(fs::path(o.junit).parent_path().string());
    write_file_atomic(o.junit, junit_xml(result.scenes));
  }
  if (o.report) write_report(result.scenes, *o.report);
  return result;
}

std::string format_verify_table(const VerifyResult& r) {
  // Columns: the groups any scene has, in the fixed order.
  std::vector<std::string> groups;
  std::vector<std::vector<GroupSummary>> per_scene;
  for (const SceneOutcome& s : r.scenes)
    per_scene.push_back(s.comparison ? summarise_groups(*s.comparison) : std::vector<GroupSummary>{});
  for (const std::string& g : group_order())
    for (const auto& gs : per_scene)
      if (std::any_of(gs.begin(), gs.end(), [&g](const GroupSummary& x) { return x.group == g; })) {
        groups.push_back(g);
        break;
      }
  std::vector<std::vector<std::string>> rows;
  rows.push_back({"scene"});
  for (const std::string& g : groups) rows[0].push_back(g == "run" ? "runs" : g);
  rows[0].push_back("result");
  int n_checks = 0, n_failed = 0, n_excluded = 0, n_skipped = 0;
  for (std::size_t i = 0; i < r.scenes.size(); ++i) {
    const SceneOutcome& s = r.scenes[i];
    std::vector<std::string> row{s.comparison ? s.comparison->scene : s.path};
    if (!s.comparison) {
      for (std::size_t k = 0; k < groups.size(); ++k) row.push_back("-");
      row.push_back("BAD INPUT");
      rows.push_back(row);
      continue;
    }
    std::map<std::string, const GroupSummary*> by_group;
    for (const GroupSummary& g : per_scene[i]) by_group[g.group] = &g;
    for (const std::string& g : groups) {
      const auto it = by_group.find(g);
      if (it == by_group.end()) {
        row.push_back("-");
        continue;
      }
      const GroupSummary& x = *it->second;
      if (g == "run") {
        const int ran = x.checks - x.failed - x.skipped;
        std::string cell = x.failed ? "FAIL " + std::to_string(x.failed) + " failed"
                                    : std::to_string(ran) + " ok";
        if (x.skipped) cell += ", " + std::to_string(x.skipped) + " skipped";
        row.push_back(cell);
      } else if (x.status == CheckStatus::Pass || x.status == CheckStatus::Fail) {
        row.push_back(std::string(to_string(x.status)) + " " + sci(x.worst, 2));
      } else {
        row.push_back(x.status == CheckStatus::Excluded ? "excluded" : "skipped");
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
  out += "cells: worst normalised error of the group, error / (atol + rtol * scale); <= 1 passes\n";
  // Failures: per scene and quantity the worst pair (or engine), at most kMaxLines lines.
  constexpr int kMaxLines = 30;
  std::string failures;
  int lines = 0, left_out = 0;
  for (const SceneOutcome& s : r.scenes) {
    if (!s.comparison) {
      failures += "  " + s.path + ": bad input: " + s.input_error + "\n";
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
  }
  if (left_out > 0)
    failures += "  ... " + std::to_string(left_out) +
                " more failed checks: see `crossdyn compare SCENE` or the JSON summary\n";
  if (!failures.empty()) out += "\nfailed (per scene and quantity, the worst pair):\n" + failures;
  char totals[256];
  std::snprintf(totals, sizeof totals,
                "\n%zu scenes, %d checks: %d passed, %d failed, %d excluded, %d skipped\n",
                r.scenes.size(), n_checks, n_checks - n_failed - n_excluded - n_skipped, n_failed,
                n_excluded, n_skipped);
  out += totals;
  return out;
}

}  // namespace crossdyn::harness
