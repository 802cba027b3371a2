// The stability maps' JSON and report folder (see stability.hpp; the pages are made by
// reports/make_report.py, "kind": "stability").
#include "harness/stability.hpp"

#include "core/errors.hpp"
#include "core/output.hpp"
#include "harness/locations.hpp"
#include "harness/report.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>

namespace crossdyn::harness {

namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

json number(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

// Unique ids, one per map: <scene>-<knob> (page <id>.html, <id>.csv).
std::vector<std::string> map_ids(const std::vector<StabilityMap>& maps) {
  std::vector<std::string> bases;
  for (const StabilityMap& m : maps) bases.push_back(file_safe(m.scene + "-" + m.knob.spec, false));
  return unique_ids(bases, {"index"}, '_');
}

json map_json(const StabilityMap& m, const std::string& id) {
  json j;
  j["scene"] = m.scene;
  j["file"] = m.file;
  j["id"] = id;
  j["page"] = id + ".html";
  j["csv"] = id + ".csv";
  j["parameter"] = {{"spec", m.knob.spec}, {"unit", m.knob.unit}, {"description", m.knob.description}};
  j["limits"] = {{"tolerance", m.limits.tolerance},
                 {"drift_limit", m.limits.drift_limit},
                 {"diverged_error", m.limits.diverged_error}};
  json cols = json::array();
  for (const StabilityColumn& c : m.columns) {
    json lambda = json::array();  // per engine, in "engines" order
    for (double l : c.lambda_max) lambda.push_back(number(l));
    cols.push_back({{"value", c.value},
                    {"reference", c.reference},
                    {"reference_note", c.reference_note},
                    {"lambda_max", lambda}});
  }
  j["columns"] = cols;
  j["engines"] = m.engines;
  j["integrators"] = m.integrators;
  json cells = json::array();
  for (const StabilityCell& c : m.cells)
    cells.push_back({{"engine", c.engine},
                     {"integrator", c.integrator},
                     {"fixed_step", c.fixed_step},
                     {"setting", c.setting},
                     {"setting_text", c.setting_text()},
                     {"column", c.column},
                     {"class", class_name(c.result.cls)},
                     {"why", c.result.why},
                     {"history_error", number(c.history_error)},
                     {"cpu", c.result.cls == StabilityClass::NoReference ? json(nullptr) : number(c.cpu)},
                     {"rhs_calls", c.rhs_calls},
                     {"steps", c.steps},
                     {"h_lambda", number(c.h_lambda)}});
  j["cells"] = cells;
  j["findings"] = m.findings;
  j["notes"] = m.notes;
  return j;
}

bool is_stability_folder(const fs::path& dir) {
  std::ifstream in(dir / "stability.json");
  if (!in) return false;
  try {
    const json j = json::parse(in);
    return j.is_object() && j.value("tool", "") == "crossdyn" && j.value("kind", "") == "stability";
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace

std::string stability_json(const std::vector<StabilityMap>& maps) {
  json j;
  j["tool"] = "crossdyn";
  j["kind"] = "stability";
  j["version"] = version();
  json classes = json::array();
  for (StabilityClass c : kStabilityClasses) classes.push_back(class_name(c));
  j["classes"] = classes;
  const std::vector<std::string> ids = map_ids(maps);
  json list = json::array();
  for (std::size_t i = 0; i < maps.size(); ++i) list.push_back(map_json(maps[i], ids[i]));
  j["maps"] = list;
  return j.dump(1) + "\n";
}

void write_stability_report(const std::string& given, const std::vector<StabilityMap>& maps,
                            const std::string& python) {
  if (given.empty()) throw InputError("--report: the folder name is empty");
  const fs::path dir = fs::absolute(given).lexically_normal();
  std::error_code ec;
  if (fs::exists(dir, ec)) {
    if (!fs::is_directory(dir, ec)) throw InputError("--report: '" + given + "' is a file, not a folder");
    if (!fs::is_empty(dir, ec) && !is_stability_folder(dir))
      throw InputError("--report: '" + given + "' is neither empty nor a crossdyn stability report "
                       "(no stability.json written by crossdyn stability); give a new folder, an "
                       "empty one or an earlier stability report");
  }
  make_directories(dir.string());
  const std::vector<std::string> ids = map_ids(maps);
  for (std::size_t i = 0; i < maps.size(); ++i)
    write_file_atomic((dir / (ids[i] + ".csv")).string(), stability_csv(maps[i]));
  const std::string summary = (dir / "stability.json").string();
  write_file_atomic(summary, stability_json(maps));
  run_python(python, {installed_report_script(), summary, dir.string()});
}

}  // namespace crossdyn::harness
