// Sharded verify: the slicing, part files and their merge (see shard.hpp).
#include "harness/shard.hpp"

#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "harness/converge.hpp"
#include "harness/locations.hpp"
#include "harness/sha256.hpp"
#include "harness/verify.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
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

double get_num(const json& j) {
  if (j.is_string()) {
    const std::string s = j.get<std::string>();
    if (s == "nan") return std::numeric_limits<double>::quiet_NaN();
    if (s == "inf") return std::numeric_limits<double>::infinity();
    if (s == "-inf") return -std::numeric_limits<double>::infinity();
    throw InputError("'" + s + "' is not a number");
  }
  return j.get<double>();
}

const char* status_name(CheckStatus s) { return to_string(s); }

CheckStatus status_from(const std::string& s) {
  for (CheckStatus c : {CheckStatus::Pass, CheckStatus::Fail, CheckStatus::Excluded, CheckStatus::Skipped})
    if (s == to_string(c)) return c;
  throw InputError("unknown check status '" + s + "'");
}

const char* state_name(EngineRun::State s) {
  switch (s) {
    case EngineRun::State::Ok: return "ok";
    case EngineRun::State::Failed: return "failed";
    case EngineRun::State::NotBuilt: return "not_built";
  }
  return "?";
}

EngineRun::State state_from(const std::string& s) {
  if (s == "ok") return EngineRun::State::Ok;
  if (s == "failed") return EngineRun::State::Failed;
  if (s == "not_built") return EngineRun::State::NotBuilt;
  throw InputError("unknown run state '" + s + "'");
}

json check_to(const Check& c) {
  return {{"quantity", c.quantity}, {"group", c.group}, {"a", c.a}, {"b", c.b},
          {"tolerance_key", c.tolerance_key}, {"atol", num(c.tolerance.atol)},
          {"rtol", num(c.tolerance.rtol)}, {"scale", num(c.scale)}, {"bound", num(c.bound)},
          {"error", num(c.error)}, {"time", num(c.time)},
          {"first_exceeded", c.first_exceeded ? num(*c.first_exceeded) : json(nullptr)},
          {"normalised", num(c.normalised)}, {"status", status_name(c.status)}, {"note", c.note}};
}

Check check_from(const json& j) {
  Check c;
  c.quantity = j.at("quantity").get<std::string>();
  c.group = j.at("group").get<std::string>();
  c.a = j.at("a").get<std::string>();
  c.b = j.at("b").get<std::string>();
  c.tolerance_key = j.at("tolerance_key").get<std::string>();
  c.tolerance.atol = get_num(j.at("atol"));
  c.tolerance.rtol = get_num(j.at("rtol"));
  c.scale = get_num(j.at("scale"));
  c.bound = get_num(j.at("bound"));
  c.error = get_num(j.at("error"));
  c.time = get_num(j.at("time"));
  if (!j.at("first_exceeded").is_null()) c.first_exceeded = get_num(j.at("first_exceeded"));
  c.normalised = get_num(j.at("normalised"));
  c.status = status_from(j.at("status").get<std::string>());
  c.note = j.at("note").get<std::string>();
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

EngineRun run_from(const json& j) {
  EngineRun r;
  r.label = j.at("label").get<std::string>();
  r.engine = j.at("engine").get<std::string>();
  r.state = state_from(j.at("state").get<std::string>());
  r.note = j.at("note").get<std::string>();
  r.result.engine = j.at("result_engine").get<std::string>();
  r.result.columns = j.at("columns").get<std::vector<std::string>>();
  for (const json& v : j.at("data")) r.result.data.push_back(get_num(v));
  if (!r.result.columns.empty() && r.result.data.size() % r.result.columns.size() != 0)
    throw InputError("run '" + r.label + "': the data is not whole rows");
  const json& st = j.at("stats");
  r.result.stats.rhs_calls = st.at("rhs_calls").get<long>();
  r.result.stats.steps = st.at("steps").get<long>();
  r.result.stats.rejected = st.at("rejected").get<long>();
  r.result.stats.restarts = st.at("restarts").get<long>();
  r.result.stats.wall_seconds = get_num(st.at("wall_seconds"));
  if (j.contains("failure")) {
    const json& f = j.at("failure");
    r.result.failure.emplace(f.at("engine").get<std::string>(), get_num(f.at("time")),
                             f.at("quantity").get<std::string>(), f.at("reason").get<std::string>());
  }
  return r;
}

json settings_to(const IntegratorSettings& s) {
  return {{"method", s.method.str()}, {"rtol", num(s.rtol)}, {"atol", num(s.atol)},
          {"dt", num(s.dt)}, {"first_step", num(s.first_step)}, {"duration", num(s.duration)}, {"output_step", num(s.output_step)},
          {"max_steps", s.max_steps}, {"min_step", num(s.min_step)}, {"keep_rows", s.keep_rows}};
}

IntegratorSettings settings_from(const json& j) {
  IntegratorSettings s;
  s.method = Choice<Integrator>(j.at("method").get<std::string>());
  s.rtol = get_num(j.at("rtol"));
  s.atol = get_num(j.at("atol"));
  s.dt = get_num(j.at("dt"));
  s.first_step = get_num(j.at("first_step"));
  s.duration = get_num(j.at("duration"));
  s.output_step = get_num(j.at("output_step"));
  s.max_steps = j.at("max_steps").get<long>();
  s.min_step = get_num(j.at("min_step"));
  s.keep_rows = j.at("keep_rows").get<bool>();
  return s;
}

// The System is carried as scene text (write_scene_text reads back bit for bit) plus the fields
// that come from the file rather than its text.
json system_to(const System& s) {
  return {{"name", s.name}, {"file", s.file}, {"description", s.description},
          {"source", s.source}, {"text", write_scene_text(s)}};
}

System system_from(const json& j) {
  std::vector<SceneWarning> warnings;  // the shard printed them already
  System s = read_scene_text(j.at("text").get<std::string>(), j.at("file").get<std::string>(), &warnings);
  s.name = j.at("name").get<std::string>();
  s.file = j.at("file").get<std::string>();
  s.description = j.at("description").get<std::string>();
  s.source = j.at("source").get<std::string>();
  return s;
}

json outcome_to(const SceneOutcome& o) {
  json j = {{"path", o.path}, {"input_error", o.input_error}, {"internal_error", o.internal_error},
            {"converge_json", o.converge_json}, {"converge_note", o.converge_note}};
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

SceneOutcome outcome_from(const json& j) {
  SceneOutcome o;
  o.path = j.at("path").get<std::string>();
  o.input_error = j.at("input_error").get<std::string>();
  o.internal_error = j.at("internal_error").get<bool>();
  o.converge_json = j.at("converge_json").get<std::string>();
  o.converge_note = j.at("converge_note").get<std::string>();
  if (!j.at("system").is_null()) o.system = system_from(j.at("system"));
  if (!j.at("comparison").is_null()) {
    const json& jc = j.at("comparison");
    SceneComparison c;
    c.scene = jc.at("scene").get<std::string>();
    c.file = jc.at("file").get<std::string>();
    c.settings = settings_from(jc.at("settings"));
    for (const json& r : jc.at("runs")) c.runs.push_back(run_from(r));
    for (const json& k : jc.at("checks")) c.checks.push_back(check_from(k));
    c.notes = jc.at("notes").get<std::vector<std::string>>();
    o.comparison = std::move(c);
  }
  return o;
}

std::string shard_text(const ShardSpec& s) {
  return std::to_string(s.index) + "/" + std::to_string(s.count);
}

}  // namespace

std::string part_json(const ShardSpec& shard, const std::vector<ShardScene>& scenes,
                      const std::vector<SceneOutcome>& own) {
  json list = json::array(), outcomes = json::array();
  for (const ShardScene& s : scenes)
    list.push_back({{"path", s.path}, {"sha256", s.sha256}, {"cost", s.cost}, {"shard", s.shard}});
  for (const SceneOutcome& o : own) outcomes.push_back(outcome_to(o));
  const json j = {{"tool", "crossdyn-part"},
                  {"format", 1},
                  {"version", version()},
                  {"command", "verify"},
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
                  {"shard", {{"index", shard.index}, {"count", shard.count}}},
                  {"scenes", list},
                  {"frame", json::parse(frame)},
                  {"items", own}};
  return j.dump() + "\n";
}

Part read_part(const std::string& file) {
  std::string text;
  if (!read_bytes(file, text)) throw InputError("cannot read the part file '" + file + "'");
  Part p;
  p.file = file;
  try {
    const json j = json::parse(text);
    if (!j.is_object() || j.value("tool", "") != "crossdyn-part")
      throw InputError("it is not a crossdyn part file (written by `crossdyn verify|study|"
                       "stability --shard K/N --part FILE`)");
    if (j.at("format").get<int>() != 1)
      throw InputError("part format " + j.at("format").dump() + " is not the one this crossdyn reads (1)");
    p.version = j.at("version").get<std::string>();
    p.command = j.value("command", "verify");
    if (j.contains("options"))
      for (const json& kv : j.at("options"))
        p.options.emplace_back(kv.at(0).get<std::string>(), kv.at(1).get<std::string>());
    p.shard.index = j.at("shard").at("index").get<int>();
    p.shard.count = j.at("shard").at("count").get<int>();
    if (p.shard.count < 1 || p.shard.index < 0 || p.shard.index >= p.shard.count)
      throw InputError("shard " + shard_text(p.shard) + " is not K/N with 0 <= K < N");
    for (const json& s : j.at("scenes")) {
      ShardScene x;
      x.path = s.at("path").get<std::string>();
      x.sha256 = s.at("sha256").get<std::string>();
      x.cost = s.at("cost").get<double>();
      x.shard = s.at("shard").get<int>();
      x.item = s.value("item", "");
      p.scenes.push_back(x);
    }
    if (p.command == "verify") {
      for (const json& o : j.at("outcomes")) p.outcomes.push_back(outcome_from(o));
    } else {
      p.frame = j.at("frame").dump();
      for (const json& i : j.at("items")) p.items.push_back(i.dump());
    }
  } catch (const InputError& e) {
    throw InputError("part file '" + file + "': " + e.what());
  } catch (const json::exception& e) {
    throw InputError("part file '" + file + "' is not a valid part: " + e.what());
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
  if (checked) *checked = n_checked;
}

std::vector<SceneOutcome> merge_parts(const std::vector<Part>& parts, const std::string& ver,
                                      int* checked) {
  check_parts(parts, ver, checked);
  const Part& first = parts.front();
  if (first.command != "verify")
    throw InputError("part '" + first.file + "' was written by `crossdyn " + first.command +
                     "`, not `crossdyn verify`");
  // 5. Each scene's outcome from its shard's part, in the run's order.
  std::vector<SceneOutcome> out;
  std::vector<std::size_t> next(parts.size(), 0);
  std::map<int, std::size_t> part_of;
  for (std::size_t p = 0; p < parts.size(); ++p) part_of[parts[p].shard.index] = p;
  for (const ShardScene& s : first.scenes) {
    const std::size_t p = part_of.at(s.shard);
    if (next[p] >= parts[p].outcomes.size() || parts[p].outcomes[next[p]].path != s.path)
      throw InputError("part '" + parts[p].file + "' lacks the outcome of its scene '" + s.path + "'");
    out.push_back(parts[p].outcomes[next[p]++]);
  }
  for (std::size_t p = 0; p < parts.size(); ++p)
    if (next[p] != parts[p].outcomes.size())
      throw InputError("part '" + parts[p].file + "' holds outcomes of scenes that are not its shard's");
  return out;
}

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

std::vector<double> get_nums(const json& j) {
  std::vector<double> v;
  for (const json& x : j) v.push_back(get_num(x));
  return v;
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

StudyRow row_from(const json& j) {
  StudyRow r;
  r.engine = j.at("engine").get<std::string>();
  r.integrator = j.at("integrator").get<std::string>();
  r.fixed_step = j.at("fixed_step").get<bool>();
  r.tolerance = get_num(j.at("tolerance"));
  r.dt = get_num(j.at("dt"));
  r.ok = j.at("ok").get<bool>();
  r.failure = j.at("failure").get<std::string>();
  r.cpu_median = get_num(j.at("cpu_median"));
  r.cpu_min = get_num(j.at("cpu_min"));
  r.cpu_max = get_num(j.at("cpu_max"));
  r.repeats = j.at("repeats").get<int>();
  r.rhs_calls = j.at("rhs_calls").get<long>();
  r.steps = j.at("steps").get<long>();
  r.rejected = j.at("rejected").get<long>();
  r.error.end = get_num(j.at("end"));
  r.error.history = get_num(j.at("history"));
  r.error.end_quantity = j.at("end_quantity").get<std::string>();
  r.error.history_quantity = j.at("history_quantity").get<std::string>();
  r.drift_H = get_num(j.at("drift_H"));
  r.drift_E = get_num(j.at("drift_E"));
  r.front_end = j.at("front_end").get<bool>();
  r.front_history = j.at("front_history").get<bool>();
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
                  {"output_step", num(s.output_step)},
                  {"reference", {{"kind", ref.kind}, {"description", ref.description},
                                 {"runs", ref.runs}, {"agreement", num(ref.agreement)},
                                 {"worst_pair", ref.worst_pair}, {"cpu_seconds", num(ref.cpu_seconds)}}},
                  {"rows", rows}, {"notes", s.notes}};
  }
  return j.dump();
}

StudyItem study_item_from(const std::string& text) {
  try {
    const json j = json::parse(text);
    StudyItem item;
    item.refused = j.at("refused").get<std::string>();
    item.exit_status = j.at("exit_status").get<int>();
    if (!j.at("study").is_null()) {
      const json& js = j.at("study");
      SceneStudy s;
      s.scene = js.at("scene").get<std::string>();
      s.file = js.at("file").get<std::string>();
      s.duration = get_num(js.at("duration"));
      s.output_step = get_num(js.at("output_step"));
      const json& jr = js.at("reference");
      s.reference.kind = jr.at("kind").get<std::string>();
      s.reference.description = jr.at("description").get<std::string>();
      s.reference.runs = jr.at("runs").get<std::vector<std::string>>();
      s.reference.agreement = get_num(jr.at("agreement"));
      s.reference.worst_pair = jr.at("worst_pair").get<std::string>();
      s.reference.cpu_seconds = get_num(jr.at("cpu_seconds"));
      for (const json& r : js.at("rows")) s.rows.push_back(row_from(r));
      s.notes = js.at("notes").get<std::vector<std::string>>();
      item.study = std::move(s);
    }
    return item;
  } catch (const json::exception& e) {
    throw InputError(std::string("a study result in the part is not valid: ") + e.what());
  }
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

StabilityMap stability_frame_from(const std::string& text) {
  try {
    const json j = json::parse(text);
    StabilityMap m;
    m.scene = j.at("scene").get<std::string>();
    m.file = j.at("file").get<std::string>();
    const json& k = j.at("knob");
    const int kind = k.at("kind").get<int>();
    if (kind < 0 || kind > static_cast<int>(Knob::Kind::Links)) throw InputError("unknown knob kind");
    m.knob.kind = static_cast<Knob::Kind>(kind);
    m.knob.spec = k.at("spec").get<std::string>();
    m.knob.index = k.at("index").get<int>();
    m.knob.unit = k.at("unit").get<std::string>();
    m.knob.description = k.at("description").get<std::string>();
    m.limits.tolerance = get_num(j.at("limits").at("tolerance"));
    m.limits.drift_limit = get_num(j.at("limits").at("drift_limit"));
    m.limits.diverged_error = get_num(j.at("limits").at("diverged_error"));
    m.engines = j.at("engines").get<std::vector<std::string>>();
    m.integrators = j.at("integrators").get<std::vector<std::string>>();
    return m;
  } catch (const json::exception& e) {
    throw InputError(std::string("the stability map in the part is not valid: ") + e.what());
  }
}

std::string stability_value_json(const StabilityValue& v) {
  json cells = json::array();
  for (const StabilityCell& c : v.cells)
    cells.push_back({{"engine", c.engine}, {"integrator", c.integrator}, {"fixed_step", c.fixed_step},
                     {"setting", num(c.setting)}, {"class", static_cast<int>(c.result.cls)},
                     {"why", c.result.why}, {"history_error", num(c.history_error)},
                     {"cpu", num(c.cpu)}, {"rhs_calls", c.rhs_calls}, {"steps", c.steps},
                     {"h_lambda", num(c.h_lambda)}});
  const StabilityColumn& col = v.column;
  const json j = {{"value", num(col.value)}, {"reference", col.reference},
                  {"reference_note", col.reference_note}, {"lambda_max", nums(col.lambda_max)},
                  {"cells", cells}, {"study_notes", v.study_notes}, {"refused_note", v.refused_note}};
  return j.dump();
}

StabilityValue stability_value_from(const std::string& text) {
  try {
    const json j = json::parse(text);
    StabilityValue v;
    v.column.value = get_num(j.at("value"));
    v.column.reference = j.at("reference").get<bool>();
    v.column.reference_note = j.at("reference_note").get<std::string>();
    v.column.lambda_max = get_nums(j.at("lambda_max"));
    for (const json& jc : j.at("cells")) {
      StabilityCell c;
      c.engine = jc.at("engine").get<std::string>();
      c.integrator = jc.at("integrator").get<std::string>();
      c.fixed_step = jc.at("fixed_step").get<bool>();
      c.setting = get_num(jc.at("setting"));
      const int cls = jc.at("class").get<int>();
      if (cls < 0 || cls > static_cast<int>(StabilityClass::NoReference))
        throw InputError("unknown stability class");
      c.result.cls = static_cast<StabilityClass>(cls);
      c.result.why = jc.at("why").get<std::string>();
      c.history_error = get_num(jc.at("history_error"));
      c.cpu = get_num(jc.at("cpu"));
      c.rhs_calls = jc.at("rhs_calls").get<long>();
      c.steps = jc.at("steps").get<long>();
      c.h_lambda = get_num(jc.at("h_lambda"));
      v.cells.push_back(c);
    }
    v.study_notes = j.at("study_notes").get<std::vector<std::string>>();
    v.refused_note = j.at("refused_note").get<std::string>();
    return v;
  } catch (const json::exception& e) {
    throw InputError(std::string("a stability value in the part is not valid: ") + e.what());
  }
}

// ---- converge items --------------------------------------------------------------------------------

namespace {

json model_to(const ConvergeModel& m) {
  json checks = json::array();
  for (const Check& k : m.checks) checks.push_back(check_to(k));
  return {{"counts", m.counts}, {"modes", m.modes}, {"label", m.label}, {"full", m.full},
          {"slices", m.slices}, {"slice_body", m.slice_body}, {"checks", checks},
          {"worst_normalised", num(m.worst_normalised)}, {"worst_quantity", m.worst_quantity},
          {"passed", m.passed}};
}

ConvergeModel model_from(const json& j) {
  ConvergeModel m;
  m.counts = j.at("counts").get<std::vector<int>>();
  m.modes = j.at("modes").get<int>();
  m.label = j.at("label").get<std::string>();
  m.full = j.at("full").get<bool>();
  m.slices = j.at("slices").get<int>();
  m.slice_body = j.at("slice_body").get<int>();
  for (const json& k : j.at("checks")) m.checks.push_back(check_from(k));
  m.worst_normalised = get_num(j.at("worst_normalised"));
  m.worst_quantity = j.at("worst_quantity").get<std::string>();
  m.passed = j.at("passed").get<bool>();
  return m;
}

}  // namespace

std::string converge_frame_json(const ConvergeResult& r) {
  json groups = json::array();
  for (const ModeGroup& g : r.groups) groups.push_back({{"body", g.body}, {"name", g.name}, {"modes", g.modes}});
  const json j = {{"scene", r.scene}, {"engine", r.engine}, {"groups", groups},
                  {"full", r.models.empty() ? json(nullptr) : model_to(r.models.front())}};
  return j.dump();
}

ConvergeResult converge_frame_from(const std::string& text) {
  try {
    const json j = json::parse(text);
    ConvergeResult r;
    r.scene = j.at("scene").get<std::string>();
    r.engine = j.at("engine").get<std::string>();
    for (const json& g : j.at("groups"))
      r.groups.push_back({g.at("body").get<int>(), g.at("name").get<std::string>(),
                          g.at("modes").get<std::vector<int>>()});
    if (j.at("full").is_null()) throw InputError("the part has no full model");
    r.models.push_back(model_from(j.at("full")));
    return r;
  } catch (const json::exception& e) {
    throw InputError(std::string("the converge result in the part is not valid: ") + e.what());
  }
}

std::string converge_item_json(const std::optional<ConvergeModel>& model, const std::string& note) {
  const json j = {{"model", model ? model_to(*model) : json(nullptr)}, {"note", note}};
  return j.dump();
}

std::pair<std::optional<ConvergeModel>, std::string> converge_item_from(const std::string& text) {
  try {
    const json j = json::parse(text);
    std::optional<ConvergeModel> m;
    if (!j.at("model").is_null()) m = model_from(j.at("model"));
    return {std::move(m), j.at("note").get<std::string>()};
  } catch (const json::exception& e) {
    throw InputError(std::string("a converge model in the part is not valid: ") + e.what());
  }
}

}  // namespace crossdyn::harness
