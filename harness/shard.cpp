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
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <numeric>
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

double scene_cost(const std::string& path) {
  try {
    std::vector<SceneWarning> warnings;  // verify prints them; the estimate stays quiet
    const System s = read_scene(path, &warnings);
    double steps = s.run.duration / s.run.output_step;
    if (s.run.integrator == Integrator::Rk4) steps = std::max(steps, s.run.duration / s.run.dt);
    double modes = 0;
    for (const Body& b : s.bodies) modes += b.flex ? b.flex->modes() : 0;
    const double one_run = (steps + 1) * static_cast<double>(s.bodies.size()) * (1 + modes);
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
  std::vector<ShardScene> scenes;
  std::vector<std::string> identity;  // SHA-256 of file name + bytes: independent of the order
  for (const std::string& f : files) {
    ShardScene s;
    s.path = f;
    std::string bytes;
    const bool readable = read_bytes(f, bytes);
    s.sha256 = readable ? sha256_hex(bytes) : "";
    s.cost = scene_cost(f);
    identity.push_back(sha256_hex(fs::path(f).filename().string() + '\n' + bytes));
    scenes.push_back(s);
  }
  // Longest processing time first over (cost, identity, path): a total order on the scenes.
  std::vector<std::size_t> order(scenes.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (scenes[a].cost != scenes[b].cost) return scenes[a].cost > scenes[b].cost;
    if (identity[a] != identity[b]) return identity[a] < identity[b];
    return scenes[a].path < scenes[b].path;
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
          {"dt", num(s.dt)}, {"duration", num(s.duration)}, {"output_step", num(s.output_step)},
          {"max_steps", s.max_steps}, {"min_step", num(s.min_step)}, {"keep_rows", s.keep_rows}};
}

IntegratorSettings settings_from(const json& j) {
  IntegratorSettings s;
  s.method = Choice<Integrator>(j.at("method").get<std::string>());
  s.rtol = get_num(j.at("rtol"));
  s.atol = get_num(j.at("atol"));
  s.dt = get_num(j.at("dt"));
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
                  {"shard", {{"index", shard.index}, {"count", shard.count}}},
                  {"scenes", list},
                  {"outcomes", outcomes}};
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
      throw InputError("it is not a crossdyn part file (written by `crossdyn verify --shard K/N "
                       "--part FILE`)");
    if (j.at("format").get<int>() != 1)
      throw InputError("part format " + j.at("format").dump() + " is not the one this crossdyn reads (1)");
    p.version = j.at("version").get<std::string>();
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
      p.scenes.push_back(x);
    }
    for (const json& o : j.at("outcomes")) p.outcomes.push_back(outcome_from(o));
  } catch (const InputError& e) {
    throw InputError("part file '" + file + "': " + e.what());
  } catch (const json::exception& e) {
    throw InputError("part file '" + file + "' is not a valid part: " + e.what());
  }
  return p;
}

std::vector<SceneOutcome> merge_parts(const std::vector<Part>& parts, const std::string& ver,
                                      int* checked) {
  if (parts.empty()) throw InputError("merge: no part files given");
  const Part& first = parts.front();
  // 1. The same crossdyn, and the same N.
  for (const Part& p : parts)
    if (p.version != ver)
      throw InputError("part '" + p.file + "' was written by crossdyn " + p.version +
                       ", this is crossdyn " + ver + ": merge parts of one version with that version");
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
      if (a.path != b.path)
        throw InputError("parts of different runs: scene " + std::to_string(i + 1) + " is '" +
                         a.path + "' in '" + first.file + "' but '" + b.path + "' in '" + p.file + "'");
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
  for (const ShardScene& s : first.scenes) {
    std::error_code ec;
    if (s.sha256.empty() || !fs::is_regular_file(s.path, ec)) continue;
    const std::string now = file_sha256(s.path);
    if (now != s.sha256)
      throw InputError("scene file '" + s.path + "' changed since the parts were written (SHA-256 " +
                       s.sha256 + " then, " + (now.empty() ? std::string("unreadable") : now) +
                       " now): run the shards again");
    ++n_checked;
  }
  if (checked) *checked = n_checked;
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

}  // namespace crossdyn::harness
