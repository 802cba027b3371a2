// The study's JSON and report folder (see study.hpp; the pages are made by reports/make_report.py,
// "kind": "study").
#include "harness/study.hpp"

#include "core/errors.hpp"
#include "core/output.hpp"
#include "harness/locations.hpp"
#include "harness/report.hpp"
#include "harness/numbers.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>

namespace crossdyn::harness {

namespace {

namespace fs = std::filesystem;
using page_json = nlohmann::json;  // the pages' JSON keeps sorted keys (harness::json keeps order)

// Unique ids, one per scene (page <id>-study.html, <id>-study.csv).
std::vector<std::string> study_ids(const std::vector<SceneStudy>& scenes) {
  std::vector<std::string> bases;
  for (const SceneStudy& s : scenes) bases.push_back(file_safe(s.scene, false));
  return unique_ids(bases, {"index", "scaling"}, '_');
}

page_json scene_json(const SceneStudy& s, const std::string& id) {
  page_json j;
  j["scene"] = s.scene;
  j["file"] = s.file;
  j["id"] = id;
  j["page"] = id + "-study.html";
  j["csv"] = id + "-study.csv";
  j["duration"] = s.duration;
  j["output_step"] = s.output_step;
  j["reference"] = {{"kind", s.reference.kind},
                    {"description", s.reference.description},
                    {"runs", s.reference.runs},
                    {"agreement", json_number<page_json>(s.reference.agreement)},
                    {"agreement_end", json_number<page_json>(s.reference.spread(false))},
                    {"worst_pair", s.reference.worst_pair},
                    {"smallest_target", json_number<page_json>(smallest_supported_target(s))},
                    {"smallest_history_target", json_number<page_json>(smallest_supported_target(s, true))},
                    {"cpu_seconds", json_number<page_json>(s.reference.cpu_seconds)}};
  j["notes"] = s.notes;
  page_json recs = page_json::array();
  j["targets"] = s.targets;
  for (double t : s.targets) {
    const bool measured = t >= smallest_supported_target(s);
    const auto best = measured ? cheapest_within(s, t) : std::nullopt;
    recs.push_back({{"target", t},
                    {"measured", measured},
                    {"text", recommendation(s, t)},
                    {"row", best ? page_json(*best) : page_json(nullptr)}});
  }
  j["recommendations"] = recs;
  page_json rows = page_json::array();
  for (const StudyRow& r : s.rows)
    rows.push_back({{"engine", r.engine},
                    {"step_set_by_output_times", step_set_by_output_times(s, r)},
                    {"integrator", r.integrator},
                    {"fixed_step", r.fixed_step},
                    {"tolerance", r.fixed_step ? page_json(nullptr) : json_number<page_json>(r.tolerance)},
                    {"dt", r.fixed_step ? json_number<page_json>(r.dt) : page_json(nullptr)},
                    {"setting", r.setting()},
                    {"ok", r.ok},
                    {"failure", r.failure},
                    {"cpu_median", json_number<page_json>(r.cpu_median)},
                    {"cpu_min", json_number<page_json>(r.cpu_min)},
                    {"cpu_max", json_number<page_json>(r.cpu_max)},
                    {"repeats", r.repeats},
                    {"rhs_calls", r.rhs_calls},
                    {"steps", r.steps},
                    {"rejected", r.rejected},
                    {"end_error", r.ok ? json_number<page_json>(r.error.end) : page_json(nullptr)},
                    {"history_error", r.ok ? json_number<page_json>(r.error.history) : page_json(nullptr)},
                    {"end_quantity", r.error.end_quantity},
                    {"history_quantity", r.error.history_quantity},
                    {"front_end", r.front_end},
                    {"front_history", r.front_history}});
  j["rows"] = rows;
  return j;
}

page_json scaling_json(const ScalingStudy& s) {
  page_json j;
  j["links"] = s.links;
  j["budget"] = s.budget;
  j["csv"] = "scaling.csv";
  j["page"] = "scaling.html";
  page_json lines = page_json::array();
  for (const ScalingLine& l : s.lines) {
    page_json points = page_json::array();
    for (const ScalingPoint& p : l.points)
      points.push_back({{"links", p.links},
                        {"seconds_per_call", p.ok ? json_number<page_json>(p.seconds_per_call) : page_json(nullptr)},
                        {"calls", p.calls},
                        {"ok", p.ok},
                        {"note", p.note},
                        {"condition", json_number<page_json>(p.condition)},
                        {"system_size", p.system_size},
                        {"accel_deviation", json_number<page_json>(p.accel_deviation)}});
    lines.push_back({{"engine", l.engine}, {"exponent", json_number<page_json>(l.exponent)},
                     {"condition_exponent", json_number<page_json>(l.condition_exponent)}, {"system", l.system},
                     {"points", points}});
  }
  j["lines"] = lines;
  return j;
}

// What a study report owns at the top of its folder (replaced by the next report); anything
// else there is carried over.
bool study_owned(const fs::path& name) {
  const std::string n = name.string();
  const std::string ext = name.extension().string();
  return n == "study.json" || n == "scaling.csv" || ext == ".html" || ext == ".png" ||
         (n.size() > 10 && n.compare(n.size() - 10, 10, "-study.csv") == 0) ||
         n.find(".crossdyn-") != std::string::npos;
}

}  // namespace

std::string study_json(const std::vector<SceneStudy>& scenes, const std::optional<ScalingStudy>& scaling,
                       const std::string& what_is_timed) {
  page_json j;
  j["tool"] = "crossdyn";
  j["kind"] = "study";
  j["version"] = version();
  j["timing"] = what_is_timed;
  j["error_metric"] = study_error_text();
  j["csv_header"] = study_csv_header();
  const std::vector<std::string> ids = study_ids(scenes);
  page_json list = page_json::array();
  for (std::size_t i = 0; i < scenes.size(); ++i) list.push_back(scene_json(scenes[i], ids[i]));
  j["scenes"] = list;
  j["scaling"] = scaling ? scaling_json(*scaling) : page_json(nullptr);
  return j.dump(1) + "\n";
}

std::unique_ptr<StagedFolder> stage_study_report(const std::string& dir) {
  return stage_report_folder(dir, "study.json", "study", study_owned);
}

void write_study_report(StagedFolder& staged, const std::vector<SceneStudy>& scenes,
                        const std::optional<ScalingStudy>& scaling, const std::string& python) {
  const fs::path& dir = staged.path();
  const std::vector<std::string> ids = study_ids(scenes);
  for (std::size_t i = 0; i < scenes.size(); ++i)
    write_file_atomic((dir / (ids[i] + "-study.csv")).string(),
                      study_csv_header() + study_csv_rows(scenes[i]));
  if (scaling) write_file_atomic((dir / "scaling.csv").string(), scaling_csv(*scaling));
  const std::string summary = (dir / "study.json").string();
  write_file_atomic(summary, study_json(scenes, scaling, study_timing_text()));
  run_python(python, {installed_report_script(), summary, dir.string()});
}

}  // namespace crossdyn::harness
