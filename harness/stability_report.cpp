// The stability maps' JSON and report folder (see stability.hpp; the pages are made by
// reports/make_report.py, "kind": "stability").
#include "harness/stability.hpp"

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

// Unique ids, one per map: <scene>-<knob> (page <id>.html, <id>.csv).
std::vector<std::string> map_ids(const std::vector<StabilityMap>& maps) {
  std::vector<std::string> bases;
  for (const StabilityMap& m : maps) bases.push_back(file_safe(m.scene + "-" + m.knob.spec, false));
  return unique_ids(bases, {"index"}, '_');
}

page_json map_json(const StabilityMap& m, const std::string& id) {
  page_json j;
  j["scene"] = m.scene;
  j["file"] = m.file;
  j["id"] = id;
  j["page"] = id + ".html";
  j["csv"] = id + ".csv";
  j["parameter"] = {{"spec", m.knob.spec}, {"unit", m.knob.unit}, {"description", m.knob.description}};
  j["limits"] = {{"tolerance", m.limits.tolerance},
                 {"drift_limit", m.limits.drift_limit},
                 {"diverged_error", m.limits.diverged_error}};
  page_json cols = page_json::array();
  for (const StabilityColumn& c : m.columns) {
    page_json lambda = page_json::array();  // per engine, in "engines" order
    for (double l : c.lambda_max) lambda.push_back(json_number<page_json>(l));
    cols.push_back({{"value", c.value},
                    {"reference", c.reference},
                    {"reference_note", c.reference_note},
                    {"lambda_max", lambda}});
  }
  j["columns"] = cols;
  j["engines"] = m.engines;
  j["integrators"] = m.integrators;
  page_json cells = page_json::array();
  for (const StabilityCell& c : m.cells)
    cells.push_back({{"engine", c.engine},
                     {"integrator", c.integrator},
                     {"fixed_step", c.fixed_step},
                     {"setting", c.setting},
                     {"setting_text", c.setting_text()},
                     {"column", c.column},
                     {"class", class_name(c.result.cls)},
                     {"why", c.result.why},
                     {"history_error", json_number<page_json>(c.history_error)},
                     {"cpu", c.result.cls == StabilityClass::NoReference ? page_json(nullptr) : json_number<page_json>(c.cpu)},
                     {"rhs_calls", c.rhs_calls},
                     {"steps", c.steps},
                     {"h_lambda", json_number<page_json>(c.h_lambda)}});
  j["cells"] = cells;
  j["findings"] = m.findings;
  j["notes"] = m.notes;
  return j;
}

// What a stability report owns at the top of its folder; anything else there is carried over.
bool stability_owned(const fs::path& name) {
  const std::string ext = name.extension().string();
  return name == "stability.json" || ext == ".csv" || ext == ".html" || ext == ".png" ||
         name.string().find(".crossdyn-") != std::string::npos;
}

}  // namespace

std::string stability_json(const std::vector<StabilityMap>& maps) {
  page_json j;
  j["tool"] = "crossdyn";
  j["kind"] = "stability";
  j["version"] = version();
  page_json classes = page_json::array();
  for (StabilityClass c : kStabilityClasses) classes.push_back(class_name(c));
  j["classes"] = classes;
  const std::vector<std::string> ids = map_ids(maps);
  page_json list = page_json::array();
  for (std::size_t i = 0; i < maps.size(); ++i) list.push_back(map_json(maps[i], ids[i]));
  j["maps"] = list;
  return j.dump(1) + "\n";
}

std::unique_ptr<StagedFolder> stage_stability_report(const std::string& dir) {
  return stage_report_folder(dir, "stability.json", "stability", stability_owned);
}

void write_stability_report(StagedFolder& staged, const std::vector<StabilityMap>& maps,
                            const std::string& python) {
  const fs::path& dir = staged.path();
  const std::vector<std::string> ids = map_ids(maps);
  for (std::size_t i = 0; i < maps.size(); ++i)
    write_file_atomic((dir / (ids[i] + ".csv")).string(), stability_csv(maps[i]));
  const std::string summary = (dir / "stability.json").string();
  write_file_atomic(summary, stability_json(maps));
  run_python(python, {installed_report_script(), summary, dir.string()});
}

}  // namespace crossdyn::harness
