// Sharded verify: the slicing, part files and their merge (see shard.hpp).
#include "harness/shard.hpp"
#include "harness/scene_warnings.hpp"

#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "harness/converge.hpp"
#include "harness/locations.hpp"
#include "harness/sha256.hpp"
#include "harness/verify.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <new>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <sstream>

namespace crossdyn::harness {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

namespace {

const char* type_phrase(const json& j) {
  switch (j.type()) {
    case json::value_t::null: return "null";
    case json::value_t::object: return "an object";
    case json::value_t::array: return "an array";
    case json::value_t::string: return "a string";
    case json::value_t::boolean: return "true or false";
    case json::value_t::binary: return "binary data";
    case json::value_t::discarded: return "nothing";
    default: return "a number";
  }
}

}  // namespace

// The numbers of the runs' "data" lists of the part being read: parse_bounded stores them here
// (8 bytes a value) instead of in the DOM (16 bytes a value and a list's spare room), and the
// DOM's "data" list holds one index into this store.
thread_local std::vector<std::vector<double>>* t_data_store = nullptr;

// A JSON value of a part with where it is ("/outcomes/0/comparison/checks/3"): every accessor
// throws an InputError naming the field and what is wrong, never the library's text.
class PartField {
 public:
  PartField(const json& j, std::string where) : j_(&j), where_(std::move(where)) {}
  const json& value() const { return *j_; }
  const std::string& where() const { return where_; }
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError("field '" + (where_.empty() ? std::string("/") : where_) + "' " + what);
  }
  PartField at(const std::string& key) const {
    if (!j_->is_object()) fail("must be an object, not " + std::string(type_phrase(*j_)));
    const auto it = j_->find(key);
    if (it == j_->end()) throw InputError("field '" + where_ + "/" + key + "' is missing");
    return PartField(*it, where_ + "/" + key);
  }
  bool has(const std::string& key) const { return j_->is_object() && j_->contains(key); }
  std::size_t size() const {
    if (!j_->is_array()) fail("must be a list, not " + std::string(type_phrase(*j_)));
    return j_->size();
  }
  PartField operator[](std::size_t i) const { return PartField((*j_)[i], where_ + "/" + std::to_string(i)); }
  bool is_null() const { return j_->is_null(); }
  std::string str() const {
    if (!j_->is_string()) fail("must be a string, not " + std::string(type_phrase(*j_)));
    return j_->get<std::string>();
  }
  bool boolean() const {
    if (!j_->is_boolean()) fail("must be true or false, not " + std::string(type_phrase(*j_)));
    return j_->get<bool>();
  }
  long long integer(long long lo, long long hi) const {
    if (j_->is_number_float()) {
      const double v = j_->get<double>();
      if (!(v == std::floor(v))) fail("must be a whole number, not " + shortest_text(v));
      // (hi as a double may round up past hi: 2^63 for LLONG_MAX; no whole part has such values)
      if (!(v >= static_cast<double>(lo) && v <= static_cast<double>(hi)) || std::fabs(v) >= 9.2e18)
        fail("is out of range (" + shortest_text(v) + ", from " + std::to_string(lo) + " to " +
             std::to_string(hi) + ")");
      return static_cast<long long>(v);
    }
    if (j_->is_number_unsigned()) {
      const auto v = j_->get<std::uint64_t>();
      if (v > static_cast<std::uint64_t>(hi))
        fail("is out of range (" + std::to_string(v) + ", from " + std::to_string(lo) + " to " +
             std::to_string(hi) + ")");
      if (static_cast<long long>(v) < lo)
        fail("is out of range (" + std::to_string(v) + ", from " + std::to_string(lo) + " to " +
             std::to_string(hi) + ")");
      return static_cast<long long>(v);
    }
    if (!j_->is_number_integer()) fail("must be a whole number, not " + std::string(type_phrase(*j_)));
    const auto v = j_->get<long long>();
    if (v < lo || v > hi)
      fail("is out of range (" + std::to_string(v) + ", from " + std::to_string(lo) + " to " +
           std::to_string(hi) + ")");
    return v;
  }
  int i32() const { return static_cast<int>(integer(std::numeric_limits<int>::min(), std::numeric_limits<int>::max())); }
  long i64() const { return static_cast<long>(integer(std::numeric_limits<long>::min(), std::numeric_limits<long>::max())); }
  double number() const {
    if (j_->is_string()) {
      const std::string s = j_->get<std::string>();
      if (s == "nan") return std::numeric_limits<double>::quiet_NaN();
      if (s == "inf") return std::numeric_limits<double>::infinity();
      if (s == "-inf") return -std::numeric_limits<double>::infinity();
      fail("must be a number (or \"nan\", \"inf\", \"-inf\"), not the string '" + s.substr(0, 40) + "'");
    }
    if (!j_->is_number()) fail("must be a number, not " + std::string(type_phrase(*j_)));
    return j_->get<double>();
  }
  std::vector<std::string> strings() const {
    std::vector<std::string> v;
    for (std::size_t i = 0, n = size(); i < n; ++i) v.push_back((*this)[i].str());
    return v;
  }
  std::vector<int> ints() const {
    std::vector<int> v;
    for (std::size_t i = 0, n = size(); i < n; ++i) v.push_back((*this)[i].i32());
    return v;
  }
  std::vector<double> numbers() const {
    std::vector<double> v;
    for (std::size_t i = 0, n = size(); i < n; ++i) v.push_back((*this)[i].number());
    return v;
  }

 private:
  const json* j_;
  std::string where_;
};

namespace {
// The elements of a list field, each with its place.
std::vector<PartField> each(const PartField& f) {
  std::vector<PartField> out;
  const std::size_t n = f.size();
  out.reserve(n);
  for (std::size_t i = 0; i < n; ++i) out.push_back(f[i]);
  return out;
}
}  // namespace

ShardSpec parse_shard(const std::string& text) {
  const auto bad = [&text](const std::string& why) {
    return InputError("--shard: '" + text + "' " + why +
                      " (write K/N: slice K of N, K from 0 to N-1, e.g. 0/4 ... 3/4)");
  };
  const std::size_t slash = text.find('/');
  if (slash == std::string::npos) throw bad("has no '/'");
  const auto whole = [&](const std::string& s, const char* what) {
    if (s.empty() || s.size() > 6 || !std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; }))
      throw bad(std::string("has no whole number ") + what);
    return std::stoi(s);
  };
  ShardSpec s;
  s.index = whole(text.substr(0, slash), "K before the '/'");
  s.count = whole(text.substr(slash + 1), "N after the '/'");
  if (s.count < 1 || s.count > 10000) throw bad("needs N from 1 to 10000");
  if (s.index >= s.count) throw bad("needs K below N (K counts from 0)");
  return s;
}

namespace {

// The file's bytes; false when it cannot be read.
bool read_bytes(const std::string& path, std::string& out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) return false;
  out = s.str();
  return true;
}

}  // namespace

std::string file_sha256(const std::string& path) {
  std::string bytes;
  return read_bytes(path, bytes) ? sha256_hex(bytes) : "";
}

double system_run_cost(const System& s) {
  double steps = s.run.duration / s.run.output_step;
  if (s.run.integrator == Integrator::Rk4) steps = std::max(steps, s.run.duration / s.run.dt);
  double modes = 0;
  for (const Body& b : s.bodies) modes += b.flex ? b.flex->modes() : 0;
  const double cost = (steps + 1) * static_cast<double>(s.bodies.size()) * (1 + modes);
  return std::isfinite(cost) && cost > 0 ? cost : 1;
}

double scene_cost(const std::string& path) {
  try {
    std::vector<SceneWarning> warnings;  // verify prints them; the estimate stays quiet
    const System s = read_scene(path, &warnings);
    const double one_run = system_run_cost(s);
    double runs = 3;  // the engines compare runs
    long models = 1;
    for (const ModeGroup& g : mode_groups(s)) models *= static_cast<long>(g.modes.size()) + 1;
    if (models > 1 && models <= kVerifyConvergeModels) runs += static_cast<double>(models);
    const double cost = one_run * runs;
    return std::isfinite(cost) && cost > 0 ? cost : 1;
  } catch (const std::bad_alloc&) {
    throw;  // out of memory is not an unreadable scene
  } catch (const std::exception&) {
    return 1;  // unreadable: verify reports it without running anything
  }
}

std::vector<ShardScene> plan_shards(const std::vector<std::string>& files, int count) {
  std::vector<ShardScene> units;
  for (const std::string& f : files) {
    ShardScene s;
    s.path = f;
    s.cost = scene_cost(f);
    units.push_back(s);
  }
  return plan_units(std::move(units), count);
}

std::vector<ShardScene> plan_units(std::vector<ShardScene> scenes, int count) {
  std::vector<std::string> identity;  // SHA-256 of file name + bytes (+ item): order-independent
  std::map<std::string, std::pair<bool, std::string>> file_of;  // read once (stability: many units)
  for (ShardScene& s : scenes) {
    auto it = file_of.find(s.path);
    if (it == file_of.end()) {
      std::string bytes;
      const bool readable = read_bytes(s.path, bytes);
      it = file_of.emplace(s.path, std::make_pair(readable, readable ? bytes : std::string())).first;
    }
    const auto& [readable, bytes] = it->second;
    s.sha256 = readable ? sha256_hex(bytes) : "";
    std::string id = fs::path(s.path).filename().string() + '\n' + bytes;
    if (!s.item.empty()) id += '\n' + s.item;
    identity.push_back(sha256_hex(id));
  }
  // Longest processing time first over (cost, identity, path, item): a total order on the units.
  std::vector<std::size_t> order(scenes.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (scenes[a].cost != scenes[b].cost) return scenes[a].cost > scenes[b].cost;
    if (identity[a] != identity[b]) return identity[a] < identity[b];
    if (scenes[a].path != scenes[b].path) return scenes[a].path < scenes[b].path;
    return scenes[a].item < scenes[b].item;
  });
  std::vector<double> load(static_cast<std::size_t>(count), 0.0);
  for (std::size_t i : order) {
    const auto least = std::min_element(load.begin(), load.end());  // the first: lowest K
    scenes[i].shard = static_cast<int>(least - load.begin());
    *least += scenes[i].cost;
  }
  return scenes;
}

namespace {

// ---- JSON of the outcomes: exact, NaN and infinities as strings -------------------------------

json num(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return v;
}

const char* status_name(CheckStatus s) { return to_string(s); }

CheckStatus status_from(const PartField& f) {
  const std::string s = f.str();
  for (CheckStatus c : {CheckStatus::Pass, CheckStatus::Fail, CheckStatus::Excluded, CheckStatus::Skipped})
    if (s == to_string(c)) return c;
  f.fail("is '" + s.substr(0, 40) + "', not a check status (PASS, FAIL, EXCLUDED, SKIPPED)");
}

const char* state_name(EngineRun::State s) {
  switch (s) {
    case EngineRun::State::Ok: return "ok";
    case EngineRun::State::Failed: return "failed";
    case EngineRun::State::NotBuilt: return "not_built";
  }
  return "?";
}

EngineRun::State state_from(const PartField& f) {
  const std::string s = f.str();
  if (s == "ok") return EngineRun::State::Ok;
  if (s == "failed") return EngineRun::State::Failed;
  if (s == "not_built") return EngineRun::State::NotBuilt;
  f.fail("is '" + s.substr(0, 40) + "', not a run state (ok, failed, not_built)");
}

json check_to(const Check& c) {
  return {{"quantity", c.quantity}, {"group", c.group}, {"a", c.a}, {"b", c.b},
          {"tolerance_key", c.tolerance_key}, {"atol", num(c.tolerance.atol)},
          {"rtol", num(c.tolerance.rtol)}, {"scale", num(c.scale)}, {"bound", num(c.bound)},
          {"allowance", num(c.allowance)}, {"error", num(c.error)}, {"time", num(c.time)},
          {"first_exceeded", c.first_exceeded ? num(*c.first_exceeded) : json(nullptr)},
          {"normalised", num(c.normalised)}, {"status", status_name(c.status)}, {"note", c.note}};
}

Check check_from(const PartField& j) {
  Check c;
  c.quantity = j.at("quantity").str();
  c.group = j.at("group").str();
  c.a = j.at("a").str();
  c.b = j.at("b").str();
  c.tolerance_key = j.at("tolerance_key").str();
  c.tolerance.atol = j.at("atol").number();
  c.tolerance.rtol = j.at("rtol").number();
  c.scale = j.at("scale").number();
  c.bound = j.at("bound").number();
  if (j.has("allowance")) c.allowance = j.at("allowance").number();  // a balance's quadrature
  c.error = j.at("error").number();
  c.time = j.at("time").number();
  if (!j.at("first_exceeded").is_null()) c.first_exceeded = j.at("first_exceeded").number();
  c.normalised = j.at("normalised").number();
  c.status = status_from(j.at("status"));
  c.note = j.at("note").str();
  return c;
}

json run_to(const EngineRun& r) {
  json rows = json::array();
  r.result.for_each_row([&](const double* row) {
    for (std::size_t k = 0; k < r.result.columns.size(); ++k) rows.push_back(num(row[k]));
  });
  const RunStats& st = r.result.stats;
  json j = {{"label", r.label}, {"engine", r.engine}, {"state", state_name(r.state)},
            {"note", r.note}, {"result_engine", r.result.engine},
            {"columns", r.result.columns}, {"data", rows},
            {"stats", {{"rhs_calls", st.rhs_calls}, {"steps", st.steps}, {"rejected", st.rejected},
                       {"restarts", st.restarts}, {"wall_seconds", num(st.wall_seconds)}}}};
  if (r.result.failure) {
    const RunFailure& f = *r.result.failure;
    j["failure"] = {{"engine", f.engine()}, {"time", num(f.time())}, {"quantity", f.quantity()},
                    {"reason", f.reason()}};
  }
  return j;
}

EngineRun run_from(const PartField& j) {
  EngineRun r;
  r.label = j.at("label").str();
  r.engine = j.at("engine").str();
  r.state = state_from(j.at("state"));
  r.note = j.at("note").str();
  r.result.engine = j.at("result_engine").str();
  r.result.columns = j.at("columns").strings();
  const PartField data = j.at("data");
  if (t_data_store && data.value().is_array() && data.value().size() == 1 &&
      data.value()[0].is_number_unsigned() && data.value()[0].get<std::size_t>() < t_data_store->size()) {
    std::vector<double>& stored = (*t_data_store)[data.value()[0].get<std::size_t>()];
    stored.shrink_to_fit();
    r.result.data = std::move(stored);
  } else {
    for (const PartField& v : each(data)) r.result.data.push_back(v.number());
  }
  if (!r.result.columns.empty() && r.result.data.size() % r.result.columns.size() != 0)
    j.at("data").fail("is not whole rows of the " + std::to_string(r.result.columns.size()) + " columns");
  const PartField st = j.at("stats");
  r.result.stats.rhs_calls = st.at("rhs_calls").i64();
  r.result.stats.steps = st.at("steps").i64();
  r.result.stats.rejected = st.at("rejected").i64();
  r.result.stats.restarts = st.at("restarts").i64();
  r.result.stats.wall_seconds = st.at("wall_seconds").number();
  if (j.has("failure")) {
    const PartField f = j.at("failure");
    r.result.failure.emplace(f.at("engine").str(), f.at("time").number(),
                             f.at("quantity").str(), f.at("reason").str());
  }
  return r;
}

json settings_to(const IntegratorSettings& s) {
  return {{"method", s.method.str()}, {"rtol", num(s.rtol)}, {"atol", num(s.atol)},
          {"dt", num(s.dt)}, {"first_step", num(s.first_step)}, {"duration", num(s.duration)}, {"output_step", num(s.output_step)},
          {"max_steps", s.max_steps}, {"min_step", num(s.min_step)}, {"keep_rows", s.keep_rows}};
}

IntegratorSettings settings_from(const PartField& j) {
  IntegratorSettings s;
  try {
    s.method = Choice<Integrator>(j.at("method").str());
  } catch (const InputError& e) {
    j.at("method").fail(std::string("is not an integrator: ") + e.what());
  }
  s.rtol = j.at("rtol").number();
  s.atol = j.at("atol").number();
  s.dt = j.at("dt").number();
  s.first_step = j.at("first_step").number();
  s.duration = j.at("duration").number();
  s.output_step = j.at("output_step").number();
  s.max_steps = j.at("max_steps").i64();
  s.min_step = j.at("min_step").number();
  s.keep_rows = j.at("keep_rows").boolean();
  return s;
}

// The System is carried as scene text (write_scene_text reads back bit for bit) plus the fields
// that come from the file rather than its text.
json system_to(const System& s) {
  return {{"name", s.name}, {"file", s.file}, {"description", s.description},
          {"source", s.source}, {"text", write_scene_text(s)}};
}

System system_from(const PartField& j) {
  std::vector<SceneWarning> warnings;  // the shard printed them already
  System s;
  try {
    s = read_scene_text(j.at("text").str(), j.at("file").str(), &warnings);
  } catch (const InputError& e) {
    j.at("text").fail(std::string("is not a scene crossdyn reads: ") + e.what());
  }
  s.name = j.at("name").str();
  s.file = j.at("file").str();
  s.description = j.at("description").str();
  s.source = j.at("source").str();
  return s;
}

// A scene warning whole (the reader's line and key too), so that merge gives back exactly what
// the shard printed.
json part_warning_to(const SceneWarning& w) {
  return {{"code", w.code}, {"subject", w.subject}, {"file", w.file}, {"line", w.line},
          {"column", w.column}, {"key", w.key}, {"message", w.message}};
}

SceneWarning part_warning_from(const PartField& j) {
  SceneWarning w;
  w.code = j.at("code").str();
  w.subject = j.at("subject").str();
  w.file = j.at("file").str();
  w.line = j.at("line").i32();
  w.column = j.at("column").i32();
  w.key = j.at("key").str();
  w.message = j.at("message").str();
  return w;
}

json outcome_to(const SceneOutcome& o) {
  json j = {{"path", o.path}, {"input_error", o.input_error}, {"internal_error", o.internal_error},
            {"converge_json", o.converge_json}, {"converge_note", o.converge_note}};
  json warnings = json::array();
  for (const SceneWarning& w : o.warnings) warnings.push_back(part_warning_to(w));
  j["warnings"] = warnings;
  j["system"] = o.system ? system_to(*o.system) : json(nullptr);
  if (o.comparison) {
    const SceneComparison& c = *o.comparison;
    json runs = json::array(), checks = json::array();
    for (const EngineRun& r : c.runs) runs.push_back(run_to(r));
    for (const Check& k : c.checks) checks.push_back(check_to(k));
    j["comparison"] = {{"scene", c.scene}, {"file", c.file}, {"settings", settings_to(c.settings)},
                       {"runs", runs}, {"checks", checks}, {"notes", c.notes}};
  } else {
    j["comparison"] = nullptr;
  }
  return j;
}

SceneOutcome outcome_from(const PartField& j) {
  SceneOutcome o;
  o.path = j.at("path").str();
  o.input_error = j.at("input_error").str();
  o.internal_error = j.at("internal_error").boolean();
  o.converge_json = j.at("converge_json").str();
  o.converge_note = j.at("converge_note").str();
  // Parts written before scene warnings were carried have none: refused by name, since merging
  // them would lose the warnings the shard printed.
  if (!j.has("warnings"))
    throw InputError("field '" + j.where() + "/warnings' is missing: the part was written by an "
                     "older crossdyn, which did not carry the scenes' warnings; run that shard "
                     "again with this crossdyn");
  for (const PartField& w : each(j.at("warnings"))) o.warnings.push_back(part_warning_from(w));
  if (!j.at("system").is_null()) o.system = system_from(j.at("system"));
  if (!j.at("comparison").is_null()) {
    const PartField jc = j.at("comparison");
    SceneComparison c;
    c.scene = jc.at("scene").str();
    c.file = jc.at("file").str();
    c.settings = settings_from(jc.at("settings"));
    for (const PartField& r : each(jc.at("runs"))) c.runs.push_back(run_from(r));
    for (const PartField& k : each(jc.at("checks"))) c.checks.push_back(check_from(k));
    c.notes = jc.at("notes").strings();
    o.comparison = std::move(c);
  }
  return o;
}

std::string shard_text(const ShardSpec& s) {
  return std::to_string(s.index) + "/" + std::to_string(s.count);
}

}  // namespace

namespace {

// The value of `key` in a nodal flexible block's canonical form, `{nodes: "a.csv", modes: "b.csv"}`
// (core/scene/flex_block.cpp nodes_form: double-quoted YAML strings); "" when absent.
std::string quoted_value(const std::string& form, const std::string& key) {
  const std::string start = key + ": \"";
  std::size_t i = form.find(start);
  if (i == std::string::npos || (i > 0 && form[i - 1] != '{' && form[i - 1] != ' ')) return "";
  i += start.size();
  std::string out;
  const auto hex = [&](std::size_t n) {
    unsigned long v = std::strtoul(form.substr(i, n).c_str(), nullptr, 16);
    i += n;
    return v;
  };
  while (i < form.size() && form[i] != '"') {
    char c = form[i++];
    if (c != '\\' || i >= form.size()) {
      out += c;
      continue;
    }
    c = form[i++];
    unsigned long cp = 0;
    switch (c) {
      case 'n': out += '\n'; continue;
      case 't': out += '\t'; continue;
      case 'r': out += '\r'; continue;
      case '0': out += '\0'; continue;
      case 'x': cp = hex(2); break;
      case 'u': cp = hex(4); break;
      case 'U': cp = hex(8); break;
      default: out += c; continue;
    }
    if (cp < 0x80) out += static_cast<char>(cp);  // UTF-8
    else if (cp < 0x800) out += {static_cast<char>(0xC0 | (cp >> 6)), static_cast<char>(0x80 | (cp & 0x3F))};
    else if (cp < 0x10000)
      out += {static_cast<char>(0xE0 | (cp >> 12)), static_cast<char>(0x80 | ((cp >> 6) & 0x3F)),
              static_cast<char>(0x80 | (cp & 0x3F))};
    else
      out += {static_cast<char>(0xF0 | (cp >> 18)), static_cast<char>(0x80 | ((cp >> 12) & 0x3F)),
              static_cast<char>(0x80 | ((cp >> 6) & 0x3F)), static_cast<char>(0x80 | (cp & 0x3F))};
  }
  return out;
}

}  // namespace

std::vector<PartInput> unit_inputs(const std::vector<ShardScene>& units) {
  std::vector<PartInput> out;
  std::set<std::string> files, seen;
  for (const ShardScene& u : units) {
    if (!files.insert(u.path).second) continue;
    std::vector<SceneWarning> warnings;
    System s;
    try {
      s = read_scene(u.path, &warnings);
    } catch (const std::bad_alloc&) {
      throw;  // out of memory is not an unreadable scene
    } catch (const std::exception&) {
      continue;  // the unit records why it cannot be read
    }
    const fs::path dir = fs::path(u.path).parent_path();
    for (const Body& b : s.bodies) {
      if (!b.flex || b.flex->scene_form.empty()) continue;
      for (const char* key : {"nodes", "modes"}) {
        std::string p = quoted_value(b.flex->scene_form, key);
        if (p.empty()) continue;
        if (!fs::path(p).is_absolute() && !dir.empty()) p = (dir / p).string();
        if (seen.insert(p).second) out.push_back({p, file_sha256(p)});
      }
    }
  }
  return out;
}

namespace {
json inputs_json(const std::vector<ShardScene>& units) {
  json a = json::array();
  for (const PartInput& i : unit_inputs(units)) a.push_back({{"path", i.path}, {"sha256", i.sha256}});
  return a;
}
json options_json(const PartOptions& options) {
  json opts = json::array();
  for (const auto& [k, v] : options) opts.push_back({k, v});
  return opts;
}
}  // namespace

std::string part_json(const ShardSpec& shard, const std::vector<ShardScene>& scenes,
                      const std::vector<SceneOutcome>& own, const PartOptions& options) {
  json list = json::array(), outcomes = json::array();
  for (const ShardScene& s : scenes)
    list.push_back({{"path", s.path}, {"sha256", s.sha256}, {"cost", s.cost}, {"shard", s.shard}});
  for (const SceneOutcome& o : own) outcomes.push_back(outcome_to(o));
  const json j = {{"tool", "crossdyn-part"},
                  {"format", 1},
                  {"version", version()},
                  {"command", "verify"},
                  {"options", options_json(options)},
                  {"inputs", inputs_json(scenes)},
                  {"shard", {{"index", shard.index}, {"count", shard.count}}},
                  {"scenes", list},
                  {"outcomes", outcomes}};
  return j.dump() + "\n";
}

std::string shortest_text(double value) {
  char buf[40];
  for (int digits = 1; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, value);
    if (std::strtod(buf, nullptr) == value || std::isnan(value)) break;
  }
  return buf;
}

std::string shortest_list(const std::vector<double>& values) {
  if (values.empty()) return "(default)";
  std::string out;
  for (double v : values) out += (out.empty() ? "" : ",") + shortest_text(v);
  return out;
}

std::string sweep_part_json(const std::string& command, const PartOptions& options,
                            const ShardSpec& shard, const std::vector<ShardScene>& units,
                            const std::string& frame, const std::vector<std::string>& items) {
  json list = json::array(), opts = json::array(), own = json::array();
  for (const ShardScene& s : units)
    list.push_back({{"path", s.path}, {"sha256", s.sha256}, {"cost", s.cost}, {"shard", s.shard},
                    {"item", s.item}});
  for (const auto& [k, v] : options) opts.push_back({k, v});
  for (const std::string& i : items) own.push_back(json::parse(i));
  const json j = {{"tool", "crossdyn-part"},
                  {"format", 1},
                  {"version", version()},
                  {"command", command},
                  {"options", opts},
                  {"inputs", inputs_json(units)},
                  {"shard", {{"index", shard.index}, {"count", shard.count}}},
                  {"scenes", list},
                  {"frame", json::parse(frame)},
                  {"items", own}};
  return j.dump() + "\n";
}

namespace {

// ---- Reading a part: bounded memory, errors as sentences ------------------------------------------

// A SAX handler that builds the DOM (nlohmann's own DOM builder) while charging every value its
// memory: a part whose DOM would pass the budget is refused at the value that passes it, before
// the memory is taken (docs/commands/merge.md, "Limits").
struct BudgetedDom {
  nlohmann::detail::json_sax_dom_parser<json> dom;
  std::size_t budget;
  std::size_t used = 0;
  bool over = false;
  std::size_t error_at = 0;
  std::string error_token;
  bool failed = false;

  std::vector<std::vector<double>>* store = nullptr;  // runs' "data" lists go here when set
  std::string last_key;
  std::vector<bool> in_data;  // per open list: is it a "data" list stored aside
  bool bad_data = false;

  BudgetedDom(json& root, std::size_t b) : dom(root, false), budget(b) {}
  bool data_now() const { return !in_data.empty() && in_data.back(); }
  bool put(double v) { return charge(sizeof(double)) && (store->back().push_back(v), true); }
  bool charge(std::size_t n) {
    used += n;
    if (used > budget) over = true;
    return !over;
  }
  static constexpr std::size_t kValue = sizeof(json);
  bool not_data() {
    bad_data = true;  // a "data" list holds numbers only
    return false;
  }
  bool null() { return data_now() ? not_data() : charge(kValue) && dom.null(); }
  bool boolean(bool v) { return data_now() ? not_data() : charge(kValue) && dom.boolean(v); }
  bool number_integer(json::number_integer_t v) {
    if (data_now()) return put(static_cast<double>(v));
    return charge(kValue) && dom.number_integer(v);
  }
  bool number_unsigned(json::number_unsigned_t v) {
    if (data_now()) return put(static_cast<double>(v));
    return charge(kValue) && dom.number_unsigned(v);
  }
  bool number_float(json::number_float_t v, const json::string_t& s) {
    if (data_now()) return put(v);
    return charge(kValue) && dom.number_float(v, s);
  }
  bool string(json::string_t& v) {
    if (data_now()) {
      if (v == "nan") return put(std::numeric_limits<double>::quiet_NaN());
      if (v == "inf") return put(std::numeric_limits<double>::infinity());
      if (v == "-inf") return put(-std::numeric_limits<double>::infinity());
      return not_data();
    }
    return charge(kValue + sizeof(json::string_t) + v.size()) && dom.string(v);
  }
  bool binary(json::binary_t& v) { return data_now() ? not_data() : charge(kValue + v.size()) && dom.binary(v); }
  bool start_object(std::size_t n) {
    if (data_now()) return not_data();
    in_data.push_back(false);
    return charge(kValue + sizeof(json::object_t)) && dom.start_object(n);
  }
  bool key(json::string_t& k) {
    last_key = k;
    return charge(sizeof(json::string_t) + k.size() + kValue) && dom.key(k);
  }
  bool end_object() {
    in_data.pop_back();
    last_key.clear();
    return dom.end_object();
  }
  bool start_array(std::size_t n) {
    if (data_now()) return not_data();
    const bool data = store && last_key == "data";
    last_key.clear();
    in_data.push_back(data);
    if (!charge(kValue + sizeof(json::array_t)) || !dom.start_array(n)) return false;
    if (!data) return true;
    store->emplace_back();  // the DOM's list: [index into the store]
    return dom.number_unsigned(store->size() - 1);
  }
  bool end_array() {
    in_data.pop_back();
    last_key.clear();
    return dom.end_array();
  }
  bool parse_error(std::size_t position, const std::string& token, const nlohmann::detail::exception&) {
    failed = true;
    error_at = position;
    error_token = token;
    return false;
  }
};

std::string mib(std::uintmax_t bytes) { return std::to_string((bytes + (1u << 20) - 1) >> 20) + " MiB"; }


}  // namespace


namespace {

// Parses `in` (a part file's text, or an item's) into `out` within `budget` bytes of DOM
// (decreased by what it used); InputError, as a sentence, when it is not JSON or too big.
void parse_bounded(std::istream& in, json& out, std::size_t& budget,
                   std::vector<std::vector<double>>* data_store = nullptr) {
  BudgetedDom sax(out, budget);
  sax.store = data_store;
  json::sax_parse(in, &sax, nlohmann::detail::input_format_t::json, false);
  if (sax.bad_data)
    throw InputError("holds a \"data\" list with something other than numbers (or \"nan\", "
                     "\"inf\", \"-inf\")");
  if (sax.over)
    throw InputError("holds more values than merge reads (its parsed form would pass " +
                     mib(budget) + ", the memory left of merge's " + mib(kPartMemoryBudget) +
                     " for all the parts): merge fewer or smaller parts");
  if (sax.failed) {
    std::string tok = sax.error_token.substr(0, 40);
    for (char& c : tok)
      if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) c = '?';
    throw InputError("is not valid JSON at byte " + std::to_string(sax.error_at) +
                     (tok.empty() ? std::string(" (it ends early)") : " (near '" + tok + "')"));
  }
  budget -= std::min(budget, sax.used);
}

}  // namespace

// The items' readers on a part's JSON (defined with the items below).
StudyItem study_item_from_field(const PartField& j);
StabilityMap stability_frame_from_field(const PartField& j);
StabilityValue stability_value_from_field(const PartField& j);
ConvergeResult converge_frame_from_field(const PartField& j);
std::pair<std::optional<ConvergeModel>, std::string> converge_item_from_field(const PartField& j);

namespace {

// A part's JSON into `p`: every field checked (InputError naming it), the items of sweep parts
// read once here so that a wrong item is named with its place.
void read_part_json(const json& root, Part& p) {
  const PartField j(root, "");
  if (!root.is_object() || !root.contains("tool") || !root["tool"].is_string() ||
      root["tool"].get<std::string>() != "crossdyn-part")
    throw InputError("it is not a crossdyn part file (written by `crossdyn verify|study|stability|"
                     "converge --shard K/N --part FILE`)");
  const long long format = j.at("format").integer(0, 1000000);
  if (format != 1)
    j.at("format").fail("is " + std::to_string(format) + ", not the part format this crossdyn reads (1)");
  p.version = j.at("version").str();
  p.command = j.has("command") ? j.at("command").str() : "verify";
  if (p.command != "verify" && p.command != "study" && p.command != "stability" && p.command != "converge")
    j.at("command").fail("is '" + p.command.substr(0, 40) +
                         "', not a command that writes parts (verify, study, stability, converge)");
  if (j.has("options"))
    for (const PartField& kv : each(j.at("options"))) {
      if (kv.size() != 2) kv.fail("must be a pair [option, value]");
      p.options.emplace_back(kv[0].str(), kv[1].str());
    }
  if (j.has("inputs"))
    for (const PartField& f : each(j.at("inputs")))
      p.inputs.push_back({f.at("path").str(), f.at("sha256").str()});
  const PartField shard = j.at("shard");
  p.shard.count = static_cast<int>(shard.at("count").integer(1, 10000));
  p.shard.index = static_cast<int>(shard.at("index").integer(0, p.shard.count - 1));
  for (const PartField& f : each(j.at("scenes"))) {
    ShardScene x;
    x.path = f.at("path").str();
    x.sha256 = f.at("sha256").str();
    x.cost = f.at("cost").number();
    x.shard = static_cast<int>(f.at("shard").integer(0, p.shard.count - 1));
    x.item = f.has("item") ? f.at("item").str() : "";
    p.scenes.push_back(x);
  }
  if (p.command == "verify") {
    for (const PartField& o : each(j.at("outcomes"))) p.outcomes.push_back(outcome_from(o));
    return;
  }
  const PartField frame = j.at("frame");
  if (p.command == "stability") stability_frame_from_field(frame);
  if (p.command == "converge") converge_frame_from_field(frame);
  p.frame = frame.value().dump();
  for (const PartField& i : each(j.at("items"))) {
    if (p.command == "study") study_item_from_field(i);
    if (p.command == "stability") stability_value_from_field(i);
    if (p.command == "converge") converge_item_from_field(i);
    p.items.push_back(i.value().dump());
  }
}

}  // namespace

Part read_part(const std::string& file) {
  std::size_t budget = kPartMemoryBudget;
  return read_part(file, budget);
}

Part read_part(const std::string& file, std::size_t& budget) {
  Part p;
  p.file = file;
  try {
    std::error_code ec;
    const auto st = fs::status(file, ec);
    if (ec || !fs::exists(st)) throw InputError("cannot be read (no such file)");
    if (fs::is_directory(st)) throw InputError("is a directory, not a part file");
    if (fs::is_regular_file(st)) {
      const std::uintmax_t size = fs::file_size(file, ec);
      if (!ec && size > kMaxPartFileBytes)
        throw InputError("is " + mib(size) + "; merge reads part files up to " + mib(kMaxPartFileBytes) +
                         " (docs/commands/merge.md, \"Limits\"): shard the run into more parts");
    }
    std::ifstream in(file, std::ios::binary);
    if (!in) throw InputError("cannot be read");
    json root;
    std::vector<std::vector<double>> data;
    parse_bounded(in, root, budget, &data);
    if (in.bad()) throw InputError("cannot be read (an I/O error)");
    t_data_store = &data;
    struct Reset {
      ~Reset() { t_data_store = nullptr; }
    } reset;
    read_part_json(root, p);
  } catch (const InputError& e) {
    throw InputError("part file '" + file + "': " + e.what());
  } catch (const json::exception&) {
    // Every field is read through PartField; this is a safety net that names the file.
    throw InputError("part file '" + file + "' is not a valid part (a field has the wrong form)");
  }
  return p;
}

void check_parts(const std::vector<Part>& parts, const std::string& ver, int* checked) {
  if (parts.empty()) throw InputError("merge: no part files given");
  const Part& first = parts.front();
  // 1. The same crossdyn, the same command with the same options, and the same N.
  for (const Part& p : parts)
    if (p.version != ver)
      throw InputError("part '" + p.file + "' was written by crossdyn " + p.version +
                       ", this is crossdyn " + ver + ": merge parts of one version with that version");
  for (const Part& p : parts)
    if (p.command != first.command)
      throw InputError("parts of different commands: '" + first.file + "' was written by `crossdyn " +
                       first.command + "`, '" + p.file + "' by `crossdyn " + p.command +
                       "` (merge the parts of one run)");
  for (const Part& p : parts) {
    const auto value = [](const PartOptions& o, const std::string& key) -> std::string {
      for (const auto& [k, v] : o)
        if (k == key) return v;
      return "(not given)";
    };
    PartOptions keys = first.options;
    for (const auto& kv : p.options)
      if (std::none_of(keys.begin(), keys.end(), [&](const auto& x) { return x.first == kv.first; }))
        keys.push_back(kv);
    for (const auto& kv : keys) {
      const std::string a = value(first.options, kv.first), b = value(p.options, kv.first);
      if (a != b)
        throw InputError("parts made with different options: " + kv.first + " is '" + a + "' in '" +
                         first.file + "' but '" + b + "' in '" + p.file +
                         "' (every shard of a run needs the same options)");
    }
  }
  for (const Part& p : parts)
    if (p.shard.count != first.shard.count)
      throw InputError("parts of different shard counts: '" + first.file + "' is shard " +
                       shard_text(first.shard) + ", '" + p.file + "' is shard " + shard_text(p.shard));
  // 2. Every K once.
  const int n = first.shard.count;
  std::map<int, std::vector<std::string>> by_k;
  for (const Part& p : parts) by_k[p.shard.index].push_back(p.file);
  for (const auto& [k, files] : by_k)
    if (files.size() > 1) {
      std::string list;
      for (const std::string& f : files) list += (list.empty() ? "'" : ", '") + f + "'";
      throw InputError("shard " + std::to_string(k) + "/" + std::to_string(n) + " is given " +
                       std::to_string(files.size()) + " times: " + list);
    }
  std::string missing;
  for (int k = 0; k < n; ++k)
    if (!by_k.count(k)) missing += (missing.empty() ? "" : ", ") + std::to_string(k) + "/" + std::to_string(n);
  if (!missing.empty())
    throw InputError("missing shard" + std::string(missing.find(',') != std::string::npos ? "s " : " ") +
                     missing + " (give all " + std::to_string(n) + " parts of the run)");
  // 3. The same scenes with the same contents.
  for (const Part& p : parts) {
    if (p.scenes.size() != first.scenes.size())
      throw InputError("parts of different runs: '" + first.file + "' lists " +
                       std::to_string(first.scenes.size()) + " scenes, '" + p.file + "' " +
                       std::to_string(p.scenes.size()));
    for (std::size_t i = 0; i < p.scenes.size(); ++i) {
      const ShardScene& a = first.scenes[i];
      const ShardScene& b = p.scenes[i];
      if (a.path != b.path || a.item != b.item)
        throw InputError("parts of different runs: unit " + std::to_string(i + 1) + " is '" +
                         a.path + (a.item.empty() ? "" : " " + a.item) + "' in '" + first.file +
                         "' but '" + b.path + (b.item.empty() ? "" : " " + b.item) + "' in '" +
                         p.file + "'");
      if (a.sha256 != b.sha256)
        throw InputError("scene '" + a.path + "' changed between the shards: SHA-256 " + a.sha256 +
                         " in '" + first.file + "', " + b.sha256 + " in '" + p.file + "'");
      if (a.shard != b.shard)
        throw InputError("the parts disagree on the shard of scene '" + a.path + "' (" +
                         std::to_string(a.shard) + " in '" + first.file + "', " +
                         std::to_string(b.shard) + " in '" + p.file + "')");
    }
  }
  // 4. The files on disk, where they can be found, still hold what was compared.
  int n_checked = 0;
  std::set<std::string> seen;  // a file once (stability: a unit per value)
  for (const ShardScene& s : first.scenes) {
    std::error_code ec;
    if (!seen.insert(s.path).second) continue;
    if (s.sha256.empty() || !fs::is_regular_file(s.path, ec)) continue;
    const std::string now = file_sha256(s.path);
    if (now != s.sha256)
      throw InputError("scene file '" + s.path + "' changed since the parts were written (SHA-256 " +
                       s.sha256 + " then, " + (now.empty() ? std::string("unreadable") : now) +
                       " now): run the shards again");
    ++n_checked;
  }
  // The frame (what every part's units are put together with) is the same in every part.
  for (const Part& p : parts)
    if (p.frame != first.frame)
      throw InputError("parts of different runs: the field 'frame' differs between '" + first.file +
                       "' and '" + p.file + "' (the scene, its limits or options)");
  // 5. The other files the units read (nodal data): the same in every part, and unchanged on disk.
  for (const Part& p : parts) {
    const auto differ = [&](const std::string& what) {
      throw InputError("parts of different inputs: " + what + " (in '" + first.file + "' and '" +
                       p.file + "'): run the shards again from the same files");
    };
    if (p.inputs.size() != first.inputs.size())
      differ(std::to_string(first.inputs.size()) + " and " + std::to_string(p.inputs.size()) +
             " data files");
    for (std::size_t i = 0; i < p.inputs.size(); ++i)
      if (p.inputs[i].path != first.inputs[i].path || p.inputs[i].sha256 != first.inputs[i].sha256)
        differ("data file '" + first.inputs[i].path + "' (SHA-256 " + first.inputs[i].sha256 +
               ") and '" + p.inputs[i].path + "' (SHA-256 " + p.inputs[i].sha256 + ")");
  }
  for (const PartInput& in : first.inputs) {
    std::error_code ec;
    if (in.sha256.empty() || !fs::is_regular_file(in.path, ec)) continue;
    const std::string now = file_sha256(in.path);
    if (now != in.sha256)
      throw InputError("data file '" + in.path + "' (read by a scene of the run) changed since the "
                       "parts were written (SHA-256 " + in.sha256 + " then, " +
                       (now.empty() ? std::string("unreadable") : now) + " now): run the shards again");
    ++n_checked;
  }
  if (checked) *checked = n_checked;
}

namespace {

bool same_number(double a, double b) {
  return (std::isnan(a) && std::isnan(b)) || (a == b && std::signbit(a) == std::signbit(b));
}

// Refuses a verify outcome whose derived fields are not what its numbers give: the comparison is
// made again from the part's scene and runs with compare_runs and require_comparison, the code
// the unsharded verify uses, and every check, note and run state must be the same.
void recheck_outcome(const Part& part, SceneOutcome& o, bool allow_no_comparison) {
  const auto refuse = [&](const std::string& what) {
    throw InputError("part '" + part.file + "', scene '" + o.path + "': " + what +
                     ": the part does not hold what its numbers give (edited, or written by "
                     "another program); run that shard again");
  };
  // The scene's geometry warnings are made again from its scene; the reader's (with a line) are
  // the part's own, since the scene text the part carries is written with units.
  if (!o.system && !o.warnings.empty()) refuse("it has scene warnings but no scene");
  if (o.system) {
    std::vector<SceneWarning> given;
    for (const SceneWarning& w : o.warnings)
      if (w.line == 0) given.push_back(w);
    const std::vector<SceneWarning> made = geometry_warnings(*o.system);
    const auto same = [](const SceneWarning& a, const SceneWarning& b) {
      return a.code == b.code && a.subject == b.subject && a.message == b.message && a.file == b.file &&
             a.key == b.key && a.column == b.column;
    };
    if (given.size() != made.size() || !std::equal(given.begin(), given.end(), made.begin(), same))
      refuse("field 'warnings' is not what its scene gives (" + std::to_string(given.size()) +
             " geometry warnings in the part, " + std::to_string(made.size()) + " from its scene)");
  }
  if (!o.comparison) return;
  SceneComparison& c = *o.comparison;
  if (!o.system) refuse("field 'system' is missing beside a comparison");
  for (const EngineRun& r : c.runs) {
    const bool failed = r.result.failure.has_value();
    if (failed != (r.state == EngineRun::State::Failed))
      refuse("run '" + r.label + "' has state '" + std::string(r.state == EngineRun::State::Failed ? "failed" : r.state == EngineRun::State::Ok ? "ok" : "not_built") +
             "' but " + (failed ? "a failure" : "no failure"));
  }
  // The analytic solution's rows are numbers the merge can make too: made again at the part's
  // output times, they must be the part's to the last bit.
  for (const EngineRun& r : c.runs) {
    if (r.engine != "analytic" || r.result.columns.empty() || r.result.columns.front() != "t") continue;
    std::vector<double> times;
    const std::size_t width = r.result.columns.size();
    for (std::size_t k = 0; k < r.result.data.size(); k += width) times.push_back(r.result.data[k]);
    const RunResult made = analytic_run(*o.system, times);
    if (made.columns != r.result.columns || made.data.size() != r.result.data.size())
      refuse("run 'analytic': its columns or rows are not the analytic solution's");
    for (std::size_t k = 0; k < made.data.size(); ++k)
      if (!same_number(made.data[k], r.result.data[k]))
        refuse("run 'analytic', row " + std::to_string(k / width + 1) + ", column '" +
               made.columns[k % width] + "': " + shortest_text(r.result.data[k]) + " in the part, " +
               shortest_text(made.data[k]) + " from the analytic solution");
  }
  SceneComparison again = compare_runs(*o.system, std::move(c.runs));  // the runs lent, not copied
  c.runs = std::move(again.runs);
  again.settings = c.settings;
  require_comparison(again, allow_no_comparison);
  if (again.checks.size() != c.checks.size())
    refuse("it has " + std::to_string(c.checks.size()) + " checks where its runs give " +
           std::to_string(again.checks.size()));
  for (std::size_t i = 0; i < c.checks.size(); ++i) {
    const Check& a = c.checks[i];  // the part's
    const Check& b = again.checks[i];
    const std::string name = "check " + std::to_string(i + 1) + " '" + b.quantity + "'" +
                             (b.a.empty() ? "" : " (" + b.a + (b.b.empty() ? "" : " vs " + b.b) + ")");
    const auto text_field = [&](const char* field, const std::string& x, const std::string& y) {
      if (x != y) refuse(name + ", field '" + field + "': '" + x.substr(0, 60) + "' in the part, '" +
                         y.substr(0, 60) + "' from its numbers");
    };
    const auto num_field = [&](const char* field, double x, double y) {
      if (!same_number(x, y))
        refuse(name + ", field '" + field + "': " + shortest_text(x) + " in the part, " +
               shortest_text(y) + " from its numbers");
    };
    text_field("quantity", a.quantity, b.quantity);
    text_field("group", a.group, b.group);
    text_field("a", a.a, b.a);
    text_field("b", a.b, b.b);
    text_field("tolerance_key", a.tolerance_key, b.tolerance_key);
    num_field("atol", a.tolerance.atol, b.tolerance.atol);
    num_field("rtol", a.tolerance.rtol, b.tolerance.rtol);
    num_field("scale", a.scale, b.scale);
    num_field("bound", a.bound, b.bound);
    num_field("error", a.error, b.error);
    num_field("time", a.time, b.time);
    if (a.first_exceeded.has_value() != b.first_exceeded.has_value())
      refuse(name + ", field 'first_exceeded': " + (a.first_exceeded ? "given" : "null") +
             " in the part, " + (b.first_exceeded ? "a time" : "null") + " from its numbers");
    if (a.first_exceeded) num_field("first_exceeded", *a.first_exceeded, *b.first_exceeded);
    num_field("normalised", a.normalised, b.normalised);
    text_field("status", to_string(a.status), to_string(b.status));
    text_field("note", a.note, b.note);
  }
  if (again.notes != c.notes) refuse("field 'notes' is not what its runs give");
  if (again.scene != c.scene) refuse("field 'scene' is '" + c.scene + "', its scene is '" + again.scene + "'");
}

}  // namespace

std::vector<SceneOutcome> merge_parts(std::vector<Part>& parts, const std::string& ver,
                                      int* checked) {
  check_parts(parts, ver, checked);
  const Part& first = parts.front();
  if (first.command != "verify")
    throw InputError("part '" + first.file + "' was written by `crossdyn " + first.command +
                     "`, not `crossdyn verify`");
  // 6. Each scene's outcome from its shard's part, in the run's order, its checks made again.
  bool allow_no_comparison = false;
  for (const auto& [k, v] : first.options)
    if (k == "--allow-no-comparison") allow_no_comparison = v == "yes";
  std::vector<SceneOutcome> out;
  std::vector<std::size_t> next(parts.size(), 0);
  std::map<int, std::size_t> part_of;
  for (std::size_t p = 0; p < parts.size(); ++p) part_of[parts[p].shard.index] = p;
  for (const ShardScene& s : first.scenes) {
    const std::size_t p = part_of.at(s.shard);
    if (next[p] >= parts[p].outcomes.size() || parts[p].outcomes[next[p]].path != s.path)
      throw InputError("part '" + parts[p].file + "' lacks the outcome of its scene '" + s.path + "'");
    recheck_outcome(parts[p], parts[p].outcomes[next[p]], allow_no_comparison);
    out.push_back(std::move(parts[p].outcomes[next[p]++]));  // the parts' run data is not copied
  }
  for (std::size_t p = 0; p < parts.size(); ++p)
    if (next[p] != parts[p].outcomes.size())
      throw InputError("part '" + parts[p].file + "' holds outcomes of scenes that are not its shard's");
  return out;
}

namespace {

// The derived fields of one sweep item against what its numbers give (the code the command
// uses: judge_check, classify, mark_fronts, the converge pass rule); InputError naming the part,
// the unit and the field otherwise.
void recheck_item(const Part& part, const ShardScene& unit, const std::string& text) {
  const auto refuse = [&](const std::string& what) {
    throw InputError("part '" + part.file + "', unit '" + unit.path +
                     (unit.item.empty() ? "" : " " + unit.item) + "': " + what +
                     ": the part does not hold what its numbers give (edited, or written by "
                     "another program); run that shard again");
  };
  const auto num_text = [](double v) { return shortest_text(v); };
  if (part.command == "stability") {
    const StabilityMap frame = stability_frame_from(part.frame);
    const StabilityValue v = stability_value_from(text);
    for (std::size_t i = 0; i < v.cells.size(); ++i) {
      const StabilityCell& c = v.cells[i];
      const std::string name = "cell " + std::to_string(i + 1) + " (" + c.engine + " " + c.integrator +
                               " " + c.setting_text() + ")";
      const Classified again = classify(c.facts, frame.limits);
      if (again.cls != c.result.cls)
        refuse(name + ", field 'class': " + class_name(c.result.cls) + " in the part, " +
               class_name(again.cls) + " from its facts (" + again.why + ")");
      if (again.why != c.result.why)
        refuse(name + ", field 'why': '" + c.result.why + "' in the part, '" + again.why + "' from its facts");
      if (!same_number(c.history_error, c.facts.history_error))
        refuse(name + ", field 'history_error': " + num_text(c.history_error) + " beside " +
               num_text(c.facts.history_error) + " in its facts");
      if (c.fixed_step) {
        const auto e = std::find(frame.engines.begin(), frame.engines.end(), c.engine);
        const std::size_t ei = static_cast<std::size_t>(e - frame.engines.begin());
        const double h = e != frame.engines.end() && ei < v.column.lambda_max.size()
                             ? c.setting * v.column.lambda_max[ei]
                             : std::numeric_limits<double>::quiet_NaN();
        if (!same_number(h, c.h_lambda))
          refuse(name + ", field 'h_lambda': " + num_text(c.h_lambda) + " in the part, " + num_text(h) +
                 " from dt x the column's |lambda|max of " + c.engine);
      }
      if (c.facts.reference != v.column.reference)
        refuse(name + ", field 'facts/reference' differs from the column's 'reference'");
    }
  } else if (part.command == "converge") {
    const auto [model, note] = converge_item_from(text);
    if (!model) return;
    const ConvergeModel& m = *model;
    for (std::size_t i = 0; i < m.checks.size(); ++i) {
      const Check& k = m.checks[i];
      if (k.status == CheckStatus::Excluded || k.status == CheckStatus::Skipped) continue;
      Check again = k;
      judge_check(again);
      const std::string name = "check " + std::to_string(i + 1) + " '" + k.quantity + "'";
      if (!same_number(again.bound, k.bound))
        refuse(name + ", field 'bound': " + num_text(k.bound) + " in the part, " +
               num_text(again.bound) + " from atol + rtol * scale");
      if (!same_number(again.normalised, k.normalised))
        refuse(name + ", field 'normalised': " + num_text(k.normalised) + " in the part, " +
               num_text(again.normalised) + " from error / bound");
      if (again.status != k.status)
        refuse(name + ", field 'status': " + to_string(k.status) + " in the part, " +
               to_string(again.status) + " from error " + num_text(k.error) + " and bound " +
               num_text(k.bound));
    }
    if (m.worst_quantity.rfind("run: ", 0) == 0) {  // the model's run failed
      if (m.passed) refuse("field 'passed': true for a model whose run failed (" + m.worst_quantity + ")");
      if (!m.checks.empty()) refuse("field 'checks': checks for a model whose run failed");
      return;
    }
    // The verdict again from the checks' errors and scales, at the frame's accuracy.
    ConvergeModel again = m;
    judge_converge_model(again, converge_frame_from(part.frame).accuracy);
    if (again.passed != m.passed)
      refuse("field 'passed': " + std::string(m.passed ? "true" : "false") + " in the part, but its " +
             "largest relative change " + num_text(again.worst_relative) + " is " +
             (again.passed ? "within" : "beyond") + " the accuracy");
    if (!same_number(again.worst_relative, m.worst_relative))
      refuse("field 'worst_relative': " + num_text(m.worst_relative) + " in the part, " +
             num_text(again.worst_relative) + " from its checks");
    if (!same_number(again.worst_normalised, m.worst_normalised))
      refuse("field 'worst_normalised': " + num_text(m.worst_normalised) + " in the part, " +
             num_text(again.worst_normalised) + " from its checks");
    if (again.worst_quantity != m.worst_quantity)
      refuse("field 'worst_quantity': '" + m.worst_quantity + "' in the part, '" + again.worst_quantity +
             "' from its checks");
  } else if (part.command == "study") {
    const StudyItem item = study_item_from(text);
    if (!item.study) {
      if (item.refused.empty()) refuse("field 'refused' is empty for a scene without a study");
      if (item.exit_status < 1 || item.exit_status > 3)
        refuse("field 'exit_status' is " + std::to_string(item.exit_status) +
               " for a refused scene (1, 2 or 3)");
      return;
    }
    if (!item.refused.empty() || item.exit_status != 0)
      refuse("field 'refused' or 'exit_status' is set beside a study (a study's is empty and 0)");
    const SceneStudy& st = *item.study;
    const double required = StudyOptions{}.reference_agreement;
    if (st.reference.kind != "analytic" && st.reference.kind != "engines")
      refuse("field 'reference/kind' is '" + st.reference.kind + "', not analytic or engines");
    if (st.reference.kind == "engines" && !(st.reference.agreement <= required))
      refuse("field 'reference/agreement': " + num_text(st.reference.agreement) + " is above the " +
             num_text(required) + " a study needs of its reference (the scene is refused, not studied)");
    if (st.reference.agreement_end > st.reference.agreement)
      refuse("field 'reference/agreement_end': " + num_text(st.reference.agreement_end) +
             " is above 'reference/agreement' (" + num_text(st.reference.agreement) +
             "): the runs cannot differ more at the end than over the run");
    SceneStudy again = st;
    mark_fronts(again);
    const auto yes = [](bool b) { return std::string(b ? "true" : "false"); };
    for (std::size_t i = 0; i < st.rows.size(); ++i) {
      const StudyRow& r = st.rows[i];
      const std::string name = "row " + std::to_string(i + 1) + " (" + r.engine + " " + r.integrator + ")";
      if (r.ok != r.failure.empty())
        refuse(name + ", field 'ok': " + yes(r.ok) + " beside " + (r.failure.empty() ? "no failure" : "a failure"));
      if (again.rows[i].front_end != r.front_end)
        refuse(name + ", field 'front_end': " + yes(r.front_end) + " in the part, " +
               yes(again.rows[i].front_end) + " from the rows' CPU times and errors");
      if (again.rows[i].front_history != r.front_history)
        refuse(name + ", field 'front_history': " + yes(r.front_history) + " in the part, " +
               yes(again.rows[i].front_history) + " from the rows' CPU times and errors");
    }
  }
}

}  // namespace

std::vector<std::string> merge_items(const std::vector<Part>& parts, const std::string& ver,
                                     int* checked) {
  check_parts(parts, ver, checked);
  std::map<int, std::size_t> part_of;
  for (std::size_t p = 0; p < parts.size(); ++p) part_of[parts[p].shard.index] = p;
  std::vector<std::size_t> next(parts.size(), 0);
  std::vector<std::string> out;
  for (const ShardScene& s : parts.front().scenes) {
    const std::size_t p = part_of.at(s.shard);
    if (next[p] >= parts[p].items.size())
      throw InputError("part '" + parts[p].file + "' lacks the result of its unit '" + s.path +
                       (s.item.empty() ? "" : " " + s.item) + "'");
    recheck_item(parts[p], s, parts[p].items[next[p]]);
    out.push_back(parts[p].items[next[p]++]);
  }
  for (std::size_t p = 0; p < parts.size(); ++p)
    if (next[p] != parts[p].items.size())
      throw InputError("part '" + parts[p].file + "' holds results of units that are not its shard's");
  return out;
}

// ---- study and stability items ------------------------------------------------------------------

namespace {

json nums(const std::vector<double>& v) {
  json a = json::array();
  for (double x : v) a.push_back(num(x));
  return a;
}

json row_to(const StudyRow& r) {
  return {{"engine", r.engine}, {"integrator", r.integrator}, {"fixed_step", r.fixed_step},
          {"tolerance", num(r.tolerance)}, {"dt", num(r.dt)}, {"ok", r.ok}, {"failure", r.failure},
          {"cpu_median", num(r.cpu_median)}, {"cpu_min", num(r.cpu_min)}, {"cpu_max", num(r.cpu_max)},
          {"repeats", r.repeats}, {"rhs_calls", r.rhs_calls}, {"steps", r.steps},
          {"rejected", r.rejected}, {"end", num(r.error.end)}, {"history", num(r.error.history)},
          {"end_quantity", r.error.end_quantity}, {"history_quantity", r.error.history_quantity},
          {"drift_H", num(r.drift_H)}, {"drift_E", num(r.drift_E)}, {"front_end", r.front_end},
          {"front_history", r.front_history}};
}

StudyRow row_from(const PartField& j) {
  StudyRow r;
  r.engine = j.at("engine").str();
  r.integrator = j.at("integrator").str();
  r.fixed_step = j.at("fixed_step").boolean();
  r.tolerance = j.at("tolerance").number();
  r.dt = j.at("dt").number();
  r.ok = j.at("ok").boolean();
  r.failure = j.at("failure").str();
  r.cpu_median = j.at("cpu_median").number();
  r.cpu_min = j.at("cpu_min").number();
  r.cpu_max = j.at("cpu_max").number();
  r.repeats = j.at("repeats").i32();
  r.rhs_calls = j.at("rhs_calls").i64();
  r.steps = j.at("steps").i64();
  r.rejected = j.at("rejected").i64();
  r.error.end = j.at("end").number();
  r.error.history = j.at("history").number();
  r.error.end_quantity = j.at("end_quantity").str();
  r.error.history_quantity = j.at("history_quantity").str();
  r.drift_H = j.at("drift_H").number();
  r.drift_E = j.at("drift_E").number();
  r.front_end = j.at("front_end").boolean();
  r.front_history = j.at("front_history").boolean();
  return r;
}

}  // namespace

std::string study_item_json(const StudyItem& item) {
  json j = {{"refused", item.refused}, {"exit_status", item.exit_status}, {"study", nullptr}};
  if (item.study) {
    const SceneStudy& s = *item.study;
    const StudyReference& ref = s.reference;
    json rows = json::array();
    for (const StudyRow& r : s.rows) rows.push_back(row_to(r));
    j["study"] = {{"scene", s.scene}, {"file", s.file}, {"duration", num(s.duration)},
                  {"output_step", num(s.output_step)}, {"targets", s.targets},
                  {"reference", {{"kind", ref.kind}, {"description", ref.description},
                                 {"runs", ref.runs}, {"agreement", num(ref.agreement)},
                                 {"agreement_end", num(ref.agreement_end)},
                                 {"worst_pair", ref.worst_pair}, {"cpu_seconds", num(ref.cpu_seconds)}}},
                  {"rows", rows}, {"notes", s.notes}};
  }
  return j.dump();
}

StudyItem study_item_from_field(const PartField& j) {
  StudyItem item;
  item.refused = j.at("refused").str();
  item.exit_status = j.at("exit_status").i32();
  if (!j.at("study").is_null()) {
    const PartField js = j.at("study");
    SceneStudy s;
    s.scene = js.at("scene").str();
    s.file = js.at("file").str();
    s.duration = js.at("duration").number();
    s.output_step = js.at("output_step").number();
    s.targets = js.at("targets").numbers();
    for (double t : s.targets)
      if (!(t > 0 && t < 1)) js.at("targets").fail("holds " + shortest_text(t) + ", not an accuracy above 0 and below 1");
    const PartField jr = js.at("reference");
    s.reference.kind = jr.at("kind").str();
    s.reference.description = jr.at("description").str();
    s.reference.runs = jr.at("runs").strings();
    s.reference.agreement = jr.at("agreement").number();
    if (jr.has("agreement_end") && !jr.at("agreement_end").is_null())
      s.reference.agreement_end = jr.at("agreement_end").number();
    s.reference.worst_pair = jr.at("worst_pair").str();
    s.reference.cpu_seconds = jr.at("cpu_seconds").number();
    for (const PartField& r : each(js.at("rows"))) s.rows.push_back(row_from(r));
    s.notes = js.at("notes").strings();
    item.study = std::move(s);
  }
  return item;
}

StudyItem study_item_from(const std::string& text) {
  json root;
  std::istringstream in(text);
  std::size_t budget = kPartMemoryBudget;
  parse_bounded(in, root, budget);
  return study_item_from_field(PartField(root, ""));
}

std::string stability_frame_json(const StabilityMap& m) {
  const Knob& k = m.knob;
  const json j = {{"scene", m.scene}, {"file", m.file},
                  {"knob", {{"kind", static_cast<int>(k.kind)}, {"spec", k.spec}, {"index", k.index},
                            {"unit", k.unit}, {"description", k.description}}},
                  {"limits", {{"tolerance", num(m.limits.tolerance)},
                              {"drift_limit", num(m.limits.drift_limit)},
                              {"diverged_error", num(m.limits.diverged_error)}}},
                  {"engines", m.engines}, {"integrators", m.integrators}};
  return j.dump();
}

StabilityMap stability_frame_from_field(const PartField& j) {
  StabilityMap m;
  m.scene = j.at("scene").str();
  m.file = j.at("file").str();
  const PartField k = j.at("knob");
  const int kind = k.at("kind").i32();
  if (kind < 0 || kind > static_cast<int>(Knob::Kind::PrescribedTravel)) k.at("kind").fail("is not a knob kind");
  m.knob.kind = static_cast<Knob::Kind>(kind);
  m.knob.spec = k.at("spec").str();
  m.knob.index = k.at("index").i32();
  m.knob.unit = k.at("unit").str();
  m.knob.description = k.at("description").str();
  m.limits.tolerance = j.at("limits").at("tolerance").number();
  m.limits.drift_limit = j.at("limits").at("drift_limit").number();
  m.limits.diverged_error = j.at("limits").at("diverged_error").number();
  m.engines = j.at("engines").strings();
  m.integrators = j.at("integrators").strings();
  return m;
}

StabilityMap stability_frame_from(const std::string& text) {
  json root;
  std::istringstream in(text);
  std::size_t budget = kPartMemoryBudget;
  parse_bounded(in, root, budget);
  return stability_frame_from_field(PartField(root, ""));
}

std::string stability_value_json(const StabilityValue& v) {
  json cells = json::array();
  for (const StabilityCell& c : v.cells)
    cells.push_back({{"engine", c.engine}, {"integrator", c.integrator}, {"fixed_step", c.fixed_step},
                     {"setting", num(c.setting)}, {"class", static_cast<int>(c.result.cls)},
                     {"why", c.result.why}, {"history_error", num(c.history_error)},
                     {"cpu", num(c.cpu)}, {"rhs_calls", c.rhs_calls}, {"steps", c.steps},
                     {"h_lambda", num(c.h_lambda)},
                     {"facts", {{"reference", c.facts.reference}, {"ok", c.facts.ok},
                                {"failure", c.facts.failure},
                                {"history_error", num(c.facts.history_error)},
                                {"drift_H", num(c.facts.drift_H)}, {"drift_E", num(c.facts.drift_E)},
                                {"H_conserved", c.facts.H_conserved},
                                {"E_conserved", c.facts.E_conserved}}}});
  const StabilityColumn& col = v.column;
  const json j = {{"value", num(col.value)}, {"reference", col.reference},
                  {"reference_note", col.reference_note}, {"lambda_max", nums(col.lambda_max)},
                  {"cells", cells}, {"study_notes", v.study_notes}, {"refused_note", v.refused_note}};
  return j.dump();
}

StabilityValue stability_value_from_field(const PartField& j) {
  StabilityValue v;
  v.column.value = j.at("value").number();
  v.column.reference = j.at("reference").boolean();
  v.column.reference_note = j.at("reference_note").str();
  v.column.lambda_max = j.at("lambda_max").numbers();
  for (const PartField& jc : each(j.at("cells"))) {
    StabilityCell c;
    c.engine = jc.at("engine").str();
    c.integrator = jc.at("integrator").str();
    c.fixed_step = jc.at("fixed_step").boolean();
    c.setting = jc.at("setting").number();
    const int cls = jc.at("class").i32();
    if (cls < 0 || cls > static_cast<int>(StabilityClass::NoReference))
      jc.at("class").fail("is not a stability class");
    c.result.cls = static_cast<StabilityClass>(cls);
    c.result.why = jc.at("why").str();
    c.history_error = jc.at("history_error").number();
    c.cpu = jc.at("cpu").number();
    c.rhs_calls = jc.at("rhs_calls").i64();
    c.steps = jc.at("steps").i64();
    c.h_lambda = jc.at("h_lambda").number();
    const PartField f = jc.at("facts");
    c.facts.reference = f.at("reference").boolean();
    c.facts.ok = f.at("ok").boolean();
    c.facts.failure = f.at("failure").str();
    c.facts.history_error = f.at("history_error").number();
    c.facts.drift_H = f.at("drift_H").number();
    c.facts.drift_E = f.at("drift_E").number();
    c.facts.H_conserved = f.at("H_conserved").boolean();
    c.facts.E_conserved = f.at("E_conserved").boolean();
    v.cells.push_back(c);
  }
  v.study_notes = j.at("study_notes").strings();
  v.refused_note = j.at("refused_note").str();
  return v;
}

StabilityValue stability_value_from(const std::string& text) {
  json root;
  std::istringstream in(text);
  std::size_t budget = kPartMemoryBudget;
  parse_bounded(in, root, budget);
  return stability_value_from_field(PartField(root, ""));
}

// ---- converge items --------------------------------------------------------------------------------

namespace {

json model_to(const ConvergeModel& m) {
  json checks = json::array();
  for (const Check& k : m.checks) checks.push_back(check_to(k));
  json scales = json::array();
  for (double x : m.scales) scales.push_back(num(x));
  return {{"counts", m.counts}, {"modes", m.modes}, {"label", m.label}, {"full", m.full},
          {"slices", m.slices}, {"slice_body", m.slice_body}, {"checks", checks}, {"scales", scales},
          {"worst_relative", num(m.worst_relative)}, {"worst_normalised", num(m.worst_normalised)},
          {"worst_quantity", m.worst_quantity}, {"passed", m.passed}};
}

ConvergeModel model_from(const PartField& j) {
  ConvergeModel m;
  m.counts = j.at("counts").ints();
  m.modes = j.at("modes").i32();
  m.label = j.at("label").str();
  m.full = j.at("full").boolean();
  m.slices = j.at("slices").i32();
  m.slice_body = j.at("slice_body").i32();
  for (const PartField& k : each(j.at("checks"))) m.checks.push_back(check_from(k));
  m.scales = j.at("scales").numbers();
  if (m.scales.size() != m.checks.size())
    j.at("scales").fail("has " + std::to_string(m.scales.size()) + " values for " +
                        std::to_string(m.checks.size()) + " checks (one scale per check)");
  m.worst_relative = j.at("worst_relative").number();
  m.worst_normalised = j.at("worst_normalised").number();
  m.worst_quantity = j.at("worst_quantity").str();
  m.passed = j.at("passed").boolean();
  return m;
}

}  // namespace

std::string converge_frame_json(const ConvergeResult& r) {
  json groups = json::array();
  for (const ModeGroup& g : r.groups) groups.push_back({{"body", g.body}, {"name", g.name}, {"modes", g.modes}});
  const json j = {{"scene", r.scene}, {"engine", r.engine}, {"accuracy", r.accuracy}, {"groups", groups},
                  {"full", r.models.empty() ? json(nullptr) : model_to(r.models.front())}};
  return j.dump();
}

ConvergeResult converge_frame_from_field(const PartField& j) {
  ConvergeResult r;
  r.scene = j.at("scene").str();
  r.engine = j.at("engine").str();
  r.accuracy = j.at("accuracy").number();
  if (!(r.accuracy > 0 && r.accuracy < 1)) j.at("accuracy").fail("must be above 0 and below 1");
  for (const PartField& g : each(j.at("groups")))
    r.groups.push_back({g.at("body").i32(), g.at("name").str(),
                        g.at("modes").ints()});
  if (j.at("full").is_null()) j.at("full").fail("is null: the part has no full model");
  r.models.push_back(model_from(j.at("full")));
  return r;
}

ConvergeResult converge_frame_from(const std::string& text) {
  json root;
  std::istringstream in(text);
  std::size_t budget = kPartMemoryBudget;
  parse_bounded(in, root, budget);
  return converge_frame_from_field(PartField(root, ""));
}

std::string converge_item_json(const std::optional<ConvergeModel>& model, const std::string& note) {
  const json j = {{"model", model ? model_to(*model) : json(nullptr)}, {"note", note}};
  return j.dump();
}

std::pair<std::optional<ConvergeModel>, std::string> converge_item_from_field(const PartField& j) {
  std::optional<ConvergeModel> m;
  if (!j.at("model").is_null()) m = model_from(j.at("model"));
  return {std::move(m), j.at("note").str()};
}

std::pair<std::optional<ConvergeModel>, std::string> converge_item_from(const std::string& text) {
  json root;
  std::istringstream in(text);
  std::size_t budget = kPartMemoryBudget;
  parse_bounded(in, root, budget);
  return converge_item_from_field(PartField(root, ""));
}

}  // namespace crossdyn::harness
