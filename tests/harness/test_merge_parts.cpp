// Issue 23 for `crossdyn merge` and the part files (harness/shard.hpp):
//   class 5   a merged verdict is the verdict of the numbers: every derived field of every part
//             kind (verify, study, stability, converge) edited is refused, naming the part and the
//             field; options, scene files and nodal data files that differ or changed are refused;
//   class 6   memory stays bounded (a part over the size limit refused before it is read, a part
//             whose values would pass the memory budget refused before the memory is taken) and
//             running out of memory is exit status 3 with a message, never an abort (merge,
//             verify, study under `ulimit -v`);
//   class 10  every error about a part file is a sentence naming the file and the field.
#include "tests/harness/run_program.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;
using crossdyn::test::run_crossdyn;
using json = nlohmann::ordered_json;

namespace {

struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name)
      : path(fs::temp_directory_path() / ("crossdyn_mergeparts_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string operator/(const std::string& f) const { return (path / f).string(); }
};

json load(const std::string& file) {
  std::ifstream in(file);
  return json::parse(in);
}
void save(const json& j, const std::string& file) { std::ofstream(file) << j.dump(); }

// Sets (or with `erase`, removes) the value at a JSON pointer of a copy of `part`.
json edited(const json& part, const std::string& pointer, const json& value, bool erase = false) {
  json j = part;
  const json::json_pointer p(pointer);
  json& parent = j[p.parent_pointer()];
  if (erase && parent.is_array()) parent.erase(std::stoul(p.back()));
  else if (erase) parent.erase(p.back());
  else j[p] = value;
  return j;
}

// A merge of `parts` in `dir` must be refused (exit 2) with a message naming `file` and `field`,
// one line `crossdyn: error: ...`, and no library text.
void require_refused(const std::string& args, const std::string& dir, const std::string& file,
                     const std::string& field) {
  const auto r = run_crossdyn("merge -q " + args, dir);
  INFO("merge " << args << "\n" << r.output);
  CHECK(r.status == 2);
  CHECK(r.output.find("crossdyn: error: ") == 0);
  CHECK(r.output.find(file) != std::string::npos);
  CHECK(r.output.find(field) != std::string::npos);
  CHECK(r.output.find("json.exception") == std::string::npos);
  CHECK(r.output.find('\n') == r.output.size() - 1);  // one line
}

// A nodal-data version of hub_flex_array (the panel of scenarios/data) in `dir`, 1 s long.
void write_nodal_scene(const TempDir& dir) {
  std::ifstream in(crossdyn::test::source_dir() + "/scenarios/hub_flex_array.yaml");
  std::stringstream s;
  s << in.rdbuf();
  std::string t = s.str();
  const auto a = t.find("    flexible:\n      beam:");
  const auto b = t.find("\njoints:");
  REQUIRE(a != std::string::npos);
  REQUIRE(b != std::string::npos);
  t = t.substr(0, a) + "    flexible: {nodes: data/panel_nodes.csv, modes: data/panel_modes.csv}\n" + t.substr(b);
  t.replace(t.find("child_node: bottom"), 18, "child_node: root");
  t.replace(t.find("duration: 30 s"), 14, "duration: 1 s");
  std::ofstream(dir / "nodal.yaml") << t;
  fs::create_directories(dir.path / "data");
  for (const char* f : {"panel_nodes.csv", "panel_modes.csv"})
    fs::copy_file(crossdyn::test::source_dir() + "/scenarios/data/" + f, dir.path / "data" / f);
}

const std::string kStability =
    " hub_two_panels --vary hinge1.stiffness --values 500,5e6 --engines kane "
    "--integrators rk4,dopri5 --tolerances 1e-6 --dts 0.05 --duration 2 -q";
const std::string kStudy =
    " torque_free_asymmetric --engines kane,lagrange --integrators dopri5,rk4 --tolerances 1e-6,1e-8 "
    "--dts 0.05 --repeat 1 -q";

// Runs a shell command line in the source folder: exit status (-1: killed by a signal) and output.
crossdyn::test::ProgramResult run_shell(const std::string& line) {
  crossdyn::test::ProgramResult r;
  FILE* p = ::popen(("cd '" + crossdyn::test::source_dir() + "' && (" + line + ") 2>&1").c_str(), "r");
  if (!p) return r;
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.output.append(buf, n);
  const int st = ::pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

}  // namespace

TEST_CASE("class 5, a merged verdict is the verdict of the numbers: verify parts", "[shard][class5]") {
  TempDir dir("class5verify");
  for (const char* s : {"torque_free_asymmetric.yaml", "dual_spin.yaml"})
    fs::copy_file(crossdyn::test::source_dir() + "/scenarios/" + s, dir.path / s);
  const std::string scenes = " torque_free_asymmetric.yaml dual_spin.yaml";
  for (int k = 0; k < 2; ++k)
    REQUIRE(run_crossdyn("verify -q --no-converge" + scenes + " --shard " + std::to_string(k) +
                             "/2 --part p" + std::to_string(k) + ".json",
                         dir.path.string())
                .status == 0);
  REQUIRE(run_crossdyn("merge -q p0.json p1.json", dir.path.string()).status == 0);
  const json p0 = load(dir / "p0.json");
  const std::string c = "/outcomes/0/comparison";
  REQUIRE(p0.at(json::json_pointer(c + "/checks")).size() > 6);
  // Every derived field of a check, and the lists around them.
  struct Edit {
    std::string pointer;
    json value;
    bool erase;
    std::string field;
  };
  const std::vector<Edit> edits{
      {c + "/checks/5/status", "FAIL", false, "field 'status'"},
      {c + "/checks/5/error", 1e5, false, "field 'error'"},
      {c + "/checks/5/normalised", 0.5, false, "field 'normalised'"},
      {c + "/checks/5/bound", 1.0, false, "field 'bound'"},
      {c + "/checks/5/scale", 7.0, false, "field 'scale'"},
      {c + "/checks/5/time", 0.125, false, "field 'time'"},
      {c + "/checks/5/tolerance_key", "w", false, "field 'tolerance_key'"},
      {c + "/checks/5/note", "fine", false, "field 'note'"},
      {c + "/checks/3", nullptr, true, "checks"},
      {c + "/notes", json::array({"all good"}), false, "field 'notes'"},
      {c + "/runs/1/state", "failed", false, "run '"},
      {c + "/runs/1/data/40", 123.0, false, "does not hold what its numbers give"},
  };
  for (const Edit& e : edits) {
    save(edited(p0, e.pointer, e.value, e.erase), dir / "e0.json");
    require_refused("e0.json p1.json", dir.path.string(), "e0.json", e.field);
  }
  // The analytic solution's rows are made again (torque_free_asymmetric, in the other part).
  const json p1 = load(dir / "p1.json");
  REQUIRE(p1.at(json::json_pointer(c + "/runs/0/engine")) == "analytic");
  save(edited(p1, c + "/runs/0/data/30", 0.25), dir / "e1.json");
  require_refused("p0.json e1.json", dir.path.string(), "e1.json", "from the analytic solution");
  // The example: a failing part edited from FAIL to PASS.
  REQUIRE(run_crossdyn("verify -q --no-converge" + scenes +
                           " --test-inertia-scale kane=1.01 --shard 0/1 --part f.json",
                       dir.path.string())
              .status == 1);
  json f = load(dir / "f.json");
  int flipped = 0;
  for (json& o : f["outcomes"])
    for (json& k : o["comparison"]["checks"])
      if (k["status"] == "FAIL") {
        k["status"] = "PASS";
        ++flipped;
      }
  REQUIRE(flipped > 0);
  save(f, dir / "f-edited.json");
  require_refused("f-edited.json", dir.path.string(), "f-edited.json", "'FAIL' from its numbers");
  CHECK(run_crossdyn("merge -q f.json", dir.path.string()).status == 1);  // unedited: the verdict stands
  // Options differ between the parts.
  REQUIRE(run_crossdyn("verify -q --no-converge --rtol 1e-10" + scenes + " --shard 1/2 --part r1.json",
                       dir.path.string())
              .status == 0);
  require_refused("p0.json r1.json", dir.path.string(), "r1.json", "--rtol");
  // A scene file edited since the parts were written.
  std::ofstream(dir / "dual_spin.yaml", std::ios::app) << "# edited\n";
  require_refused("p0.json p1.json", dir.path.string(), "dual_spin.yaml", "changed since the parts were written");
}

TEST_CASE("class 5, a merged verdict is the verdict of the numbers: nodal data files are inputs",
          "[shard][class5]") {
  TempDir dir("class5nodal");
  write_nodal_scene(dir);
  const auto shard = run_crossdyn("verify -q --no-converge nodal.yaml --shard 0/1 --part p.json", dir.path.string());
  INFO(shard.output);
  REQUIRE(shard.status == 0);
  const json p = load(dir / "p.json");
  REQUIRE(p.at("inputs").size() == 2);
  CHECK(run_crossdyn("merge -q p.json", dir.path.string()).status == 0);
  // Parts that disagree on an input's hash, then the file edited on disk.
  save(edited(p, "/inputs/1/sha256", std::string(64, '0')), dir / "q.json");
  require_refused("q.json", dir.path.string(), "panel_modes.csv", "changed since the parts were written");
  std::ofstream(dir / "data/panel_nodes.csv", std::ios::app) << "# edited\n";
  require_refused("p.json", dir.path.string(), "panel_nodes.csv", "changed since the parts were written");
}

TEST_CASE("class 5, a merged verdict is the verdict of the numbers: study, stability, converge parts",
          "[shard][class5]") {
  TempDir dir("class5sweeps");
  const std::string d = dir.path.string();
  const std::string src = crossdyn::test::source_dir();
  REQUIRE(run_crossdyn("converge pointing_flex -q --shard 0/1 --part '" + dir / "c.json" + "'").status == 0);
  REQUIRE(run_crossdyn("stability" + kStability + " --shard 0/1 --part '" + dir / "s.json" + "'").status == 0);
  REQUIRE(run_crossdyn("study" + kStudy + " --shard 0/1 --part '" + dir / "t.json" + "'").status == 0);
  for (const char* f : {"c.json", "s.json", "t.json"})
    REQUIRE(run_crossdyn("merge -q '" + dir / f + "'").status == 0);
  // converge: a model's check, its verdict and its worst change.
  const json c = load(dir / "c.json");
  std::size_t failing = 0, passing = 0;
  for (std::size_t i = 0; i < c["items"].size(); ++i) {
    if (c["items"][i]["model"].is_null()) continue;
    (c["items"][i]["model"]["passed"].get<bool>() ? passing : failing) = i;
  }
  REQUIRE(failing > 0);
  const std::string m = "/items/" + std::to_string(failing) + "/model";
  const std::string mp = "/items/" + std::to_string(passing) + "/model";
  for (const auto& [pointer, value, field] : std::vector<std::tuple<std::string, json, std::string>>{
           {m + "/passed", true, "field 'passed'"},
           {m + "/worst_normalised", 0.5, "field 'worst_normalised'"},
           {m + "/worst_relative", 0.5, "field 'worst_relative'"},
           {"/frame/accuracy", 0.999, "field 'passed'"},
           {"/frame/accuracy", 0, "field '/frame/accuracy' must be above 0 and below 1"},
           {m + "/worst_quantity", "array.qx1", "field 'worst_quantity'"},
           {mp + "/checks/0/status", "FAIL", "field 'status'"},
           {mp + "/checks/0/error", 1e9, "field 'normalised'"},
           {mp + "/checks/0/normalised", 1e-30, "field 'normalised'"},
           {mp + "/checks/0/bound", 1e9, "field 'bound'"}}) {
    save(edited(c, pointer, value), dir / "ce.json");
    require_refused("'" + dir / "ce.json" + "'", src, "ce.json", field);
  }
  // stability: a cell's class and reason against its facts and the map's limits; the limits.
  const json s = load(dir / "s.json");
  for (const auto& [pointer, value, field] : std::vector<std::tuple<std::string, json, std::string>>{
           {"/items/0/cells/0/class", 0, "field 'class'"},
           {"/items/0/cells/1/class", 4, "field 'class'"},
           {"/items/0/cells/0/why", "fine", "field 'why'"},
           {"/items/0/cells/0/history_error", 1e-20, "field 'history_error'"},
           {"/items/0/cells/0/facts/history_error", 1e-20, "field 'class'"},
           {"/items/0/cells/0/h_lambda", 7.0, "field 'h_lambda'"}}) {
    json e = edited(s, pointer, value);
    // A class edit that happens to be the real class is no edit: make it differ.
    if (e == s) continue;
    save(e, dir / "se.json");
    require_refused("'" + dir / "se.json" + "'", src, "se.json", field);
  }
  // study: the Pareto fronts (recomputed from the rows), refused/exit status, ok beside a failure.
  const json t = load(dir / "t.json");
  const std::string r0 = "/items/0/study/rows/0";
  for (const auto& [pointer, value, field] : std::vector<std::tuple<std::string, json, std::string>>{
           {r0 + "/front_end", !t.at(json::json_pointer(r0 + "/front_end")).get<bool>(), "field 'front_end'"},
           {r0 + "/front_history", !t.at(json::json_pointer(r0 + "/front_history")).get<bool>(),
            "field 'front_history'"},
           {r0 + "/ok", false, "field 'ok'"},
           {"/items/0/exit_status", 1, "field 'refused' or 'exit_status'"},
           {"/items/0/refused", "nope", "field 'refused' or 'exit_status'"}}) {
    save(edited(t, pointer, value), dir / "te.json");
    require_refused("'" + dir / "te.json" + "'", src, "te.json", field);
  }
  save(edited(edited(t, "/items/0/study/reference/kind", "engines"), "/items/0/study/reference/agreement", 1e-3),
       dir / "te.json");
  require_refused("'" + dir / "te.json" + "'", src, "te.json", "field 'reference/agreement'");
  json refused = t;
  refused["items"][0]["study"] = nullptr;
  refused["items"][0]["exit_status"] = 0;
  save(refused, dir / "te.json");
  require_refused("'" + dir / "te.json" + "'", src, "te.json", "field 'refused' is empty");
}

TEST_CASE("class 10, every error about a part file names the file and the field, in every part kind",
          "[shard][class10]") {
  TempDir dir("class10");
  const std::string src = crossdyn::test::source_dir();
  REQUIRE(run_crossdyn("verify -q --no-converge torque_free_asymmetric --shard 0/1 --part '" + dir / "v.json" + "'")
              .status == 0);
  REQUIRE(run_crossdyn("converge pointing_flex -q --shard 0/1 --part '" + dir / "c.json" + "'").status == 0);
  REQUIRE(run_crossdyn("stability" + kStability + " --shard 0/1 --part '" + dir / "s.json" + "'").status == 0);
  REQUIRE(run_crossdyn("study" + kStudy + " --shard 0/1 --part '" + dir / "t.json" + "'").status == 0);
  struct Case {
    std::string part, pointer;
    json value;
    bool erase;
    std::string expect;
  };
  const std::vector<Case> cases{
      // the header, any kind
      {"v.json", "/command", "frame", false, "field '/command' is 'frame', not a command"},
      {"c.json", "/frame", nullptr, true, "field '/frame' is missing"},
      {"v.json", "/format", "1", false, "field '/format' must be a whole number, not a string"},
      {"s.json", "/shard/index", 3, false, "field '/shard/index' is out of range (3, from 0 to 0)"},
      {"t.json", "/shard/count", 1e300, false, "field '/shard/count' is out of range"},
      {"v.json", "/scenes/0/sha256", 5, false, "field '/scenes/0/sha256' must be a string, not a number"},
      {"t.json", "/options/0", "x", false, "field '/options/0' must be a list, not a string"},
      // verify
      {"v.json", "/outcomes/0/path", nullptr, true, "field '/outcomes/0/path' is missing"},
      {"v.json", "/outcomes/0/comparison/checks/2/atol", "big", false,
       "field '/outcomes/0/comparison/checks/2/atol' must be a number"},
      {"v.json", "/outcomes/0/comparison/checks/2/status", "MAYBE", false,
       "field '/outcomes/0/comparison/checks/2/status' is 'MAYBE', not a check status"},
      {"v.json", "/outcomes/0/comparison/runs/0/data", json::array({1, true}), false,
       "\"data\" list with something other than numbers"},
      {"v.json", "/outcomes/0/comparison/runs/0/stats/steps", -1.5, false,
       "field '/outcomes/0/comparison/runs/0/stats/steps' must be a whole number"},
      {"v.json", "/outcomes/0/comparison/settings/method", "euler", false,
       "field '/outcomes/0/comparison/settings/method' is not an integrator"},
      // converge
      {"c.json", "/frame/full/worst_normalised", true, false,
       "field '/frame/full/worst_normalised' must be a number"},
      {"c.json", "/items/0/model/passed", nullptr, true, "field '/items/0/model/passed' is missing"},
      {"c.json", "/frame/groups/0/modes", "all", false, "field '/frame/groups/0/modes' must be a list"},
      // stability
      {"s.json", "/frame/limits", nullptr, true, "field '/frame/limits' is missing"},
      {"s.json", "/items/0/cells/0/class", "x", false, "field '/items/0/cells/0/class' must be a whole number"},
      {"s.json", "/items/0/cells/0/class", 99, false, "field '/items/0/cells/0/class' is not a stability class"},
      {"s.json", "/items/0/cells/0/facts", nullptr, true, "field '/items/0/cells/0/facts' is missing"},
      // study
      {"t.json", "/items/0/study/rows/0/ok", "yes", false,
       "field '/items/0/study/rows/0/ok' must be true or false, not a string"},
      {"t.json", "/items/0/study/reference", nullptr, true, "field '/items/0/study/reference' is missing"},
      {"t.json", "/items/0/exit_status", 1e10, false, "field '/items/0/exit_status' is out of range"},
  };
  for (const Case& k : cases) {
    save(edited(load(dir / k.part), k.pointer, k.value, k.erase), dir / "bad.json");
    const auto r = run_crossdyn("merge -q '" + dir / "bad.json" + "'", src);
    INFO(k.part << " " << k.pointer << "\n" << r.output);
    CHECK(r.status == 2);
    CHECK(r.output.rfind("crossdyn: error: part file '" + dir / "bad.json" + "'", 0) == 0);
    CHECK(r.output.find(k.expect) != std::string::npos);
    CHECK(r.output.find("json.exception") == std::string::npos);
  }
  // A part's text with a newline (a version, a scene path) stays one line in the message.
  for (const auto& [pointer, value] : std::vector<std::pair<std::string, json>>{
           {"/version", "0.0\nfake"}, {"/scenes/0/path", "a\nb.yaml"}, {"/command", "verify\nx"}}) {
    save(edited(load(dir / "v.json"), pointer, value), dir / "bad.json");
    const auto r = run_crossdyn("merge -q '" + dir / "bad.json" + "'", src);
    INFO(pointer << "\n" << r.output);
    CHECK(r.status == 2);
    CHECK(r.output.rfind("crossdyn: error: part", 0) == 0);
    CHECK(r.output.find('\n') == r.output.size() - 1);
  }
  // Not JSON, empty, not a part.
  for (const auto& [text, expect] : std::vector<std::pair<std::string, std::string>>{
           {"{\"tool\": \"crossdyn-part\", \"format\": 1,", "is not valid JSON at byte"},
           {"", "is not valid JSON at byte"},
           {"[1, 2]", "it is not a crossdyn part file"}}) {
    std::ofstream(dir / "bad.json") << text;
    const auto r = run_crossdyn("merge -q '" + dir / "bad.json" + "'", src);
    INFO(r.output);
    CHECK(r.status == 2);
    CHECK(r.output.find(expect) != std::string::npos);
    CHECK(r.output.find("json.exception") == std::string::npos);
  }
}

TEST_CASE("class 6, memory stays bounded, and running out is exit 3, never an abort", "[shard][class6]") {
  TempDir dir("class6");
  const std::string src = crossdyn::test::source_dir();
  REQUIRE(run_crossdyn("verify -q --no-converge torque_free_asymmetric --shard 0/1 --part '" + dir / "v.json" + "'")
              .status == 0);
  // Over the size limit: refused before it is read (a sparse file: no time, no disk).
  {
    std::ofstream(dir / "huge.json") << "{";
    fs::resize_file(dir / "huge.json", (std::uintmax_t{256} << 20) + 1);
    const auto r = run_crossdyn("merge -q '" + dir / "huge.json" + "'", src);
    INFO(r.output);
    CHECK(r.status == 2);
    CHECK(r.output.find("merge reads part files up to 256 MiB") != std::string::npos);
    CHECK(r.output.find("docs/commands/merge.md") != std::string::npos);  // the limits explained
  }
  // Under the size limit but with more values than the budget: refused while parsing (a "data"
  // list of 40 MB of "1," is 20 million values, and a list of them in a field that is not
  // data costs a DOM value each).
  const std::string text = [&] {
    std::ifstream in(dir / "v.json");
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }();
  for (const std::string& key : {std::string("\"notes\":["), std::string("\"data\":[")}) {
    const std::size_t at = text.find(key);
    REQUIRE(at != std::string::npos);
    std::string many;
    const std::size_t n = key == "\"data\":[" ? 40'000'000 : 20'000'000;
    many.reserve(2 * n);
    for (std::size_t i = 0; i < n; ++i) many += "1,";
    std::ofstream(dir / "many.json") << text.substr(0, at + key.size()) << many << text.substr(at + key.size());
    const auto r = run_crossdyn("merge -q '" + dir / "many.json" + "'", src);
    INFO(key << "\n" << r.output);
    CHECK(r.status == 2);
    CHECK(r.output.find("holds more values than merge reads") != std::string::npos);
  }
  // Running out of memory: merge (a 100 MB part under 60 MB of address space), verify and study
  // (no room for a thread's stack): exit status 3 and the message, never a signal.
  {
    const std::size_t at = text.find("\"data\":[") + 8;
    std::string many;
    many.reserve(100'000'000);
    while (many.size() < 100'000'000) many += "1.2345678901234567e-05,";
    std::ofstream(dir / "big.json") << text.substr(0, at) << many << text.substr(at);
  }
  // verify of a flexible scene under 20 MB: the thread starts, an allocation of an engine's run
  // fails (std::bad_alloc; newton-euler's at t = 0 since the exact tangents): the scene is an ERROR
  // "out of memory", exit status 3, never an engine's "unexpected error" (exit 1, which it was).
  for (const auto& [args, limit] : std::vector<std::pair<std::string, std::string>>{
           {"merge -q '" + dir / "big.json" + "'", "60000"},
           {"verify -q --no-converge spinup_beam --json '" + dir / "x.json" + "'", "12000"},
           {"study -q --tolerances 1e-4 --repeat 1 torque_free_asymmetric", "12000"},
           {"verify hub_flex_array --json '" + dir / "y.json" + "'", "20000"}}) {
    const auto r = run_shell("ulimit -v " + limit + "; exec '" + crossdyn::test::binary_dir() + "/crossdyn' " + args);
    INFO(args << "\n" << r.output);
    CHECK(r.status == 3);
    CHECK(r.output.find("error: out of memory") != std::string::npos);
  }
  CHECK(!fs::exists(dir / "x.json"));
}
