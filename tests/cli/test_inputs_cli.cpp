// Issue 23, the inputs' classes: nothing blocks on a special file (class 3), a scenes folder is
// verified whole (class 4), a value is refused where it is given (class 8), every error is a
// sentence about the user's input (class 10). Every run has a time limit, so that a regression
// fails (status 124) instead of hanging the suite.
#include <catch2/catch.hpp>

#include "tests/cli/cli_helpers.hpp"

#include <sys/socket.h>
#include <sys/un.h>

#include <nlohmann/json.hpp>

#include <regex>

using namespace crossdyn::test;

namespace {

constexpr int kTimedOut = 124;  // timeout(1)'s status

// `crossdyn ARGS` in DIR, killed after 60 s (status 124): a hang is a failure, not a stuck suite.
Run timed(const std::string& dir, const std::string& args, const std::string& redirect = "") {
  static std::atomic<int> counter{0};
  const fs::path tmp = fs::temp_directory_path() /
                       ("crossdyn_timed_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  fs::create_directories(tmp);
  const std::string out = (tmp / "out").string(), err = (tmp / "err").string();
  const std::string cmd = "cd " + quote(dir) + " && timeout -k 5 60 " + quote(crossdyn_binary()) + " " +
                          args + " " + (redirect.empty() ? "< /dev/null > " + quote(out) : redirect) +
                          " 2> " + quote(err);
  const int raw = std::system(cmd.c_str());
  Run r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = read_file(out);
  r.err = read_file(err);
  fs::remove_all(tmp);
  return r;
}

// One line "crossdyn: error: ..." (and nothing of a library's own wording).
void check_one_sentence(const Run& r) {
  INFO(r.err);
  CHECK(r.err.rfind("crossdyn: error: ", 0) == 0);
  for (const char* library : {"json.exception", "stoi", "stod", "stol", "basic_string", "filesystem error",
                              "yaml-cpp", "bad_alloc", "std::", "what()", "terminate", "Could not convert"})
    CHECK_FALSE(contains(r.err, library));
}

bool make_socket(const std::string& path, int& fd) {
  fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (fd < 0 || path.size() >= sizeof addr.sun_path) return false;
  std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
  return ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
}

// A hub and a panel of nodal data (scenarios/data), the nodes file named by `nodes`.
std::string nodal_scene(const std::string& nodes) {
  return "name: nodal\ndescription: nodal data for the input tests.\nbodies:\n"
         "  - {name: hub, mass: 100, inertia: [10, 20, 25]}\n"
         "  - name: panel\n    flexible: {nodes: " + nodes + ", modes: panel_modes.csv}\n"
         "joints:\n  - {name: base, type: free, child: hub}\n"
         "  - {name: root, type: fixed, parent: hub, child: panel, parent_point: [1, 0, 0], "
         "child_point: [0, 0, 0]}\nrun: {duration: 0.02, output_step: 0.01}\n";
}

}  // namespace

TEST_CASE("class 3, nothing blocks on a special file: scenes named on the command line") {
  Scratch s("special");
  REQUIRE(::mkfifo(s.path("fifo.yaml").c_str(), 0644) == 0);  // no writer, ever
  fs::create_directories(s.dir() / "folder.yaml");
  int fd = -1;
  const bool have_socket = make_socket(s.path("sock.yaml"), fd);
  std::vector<std::pair<std::string, std::string>> cases{
      {"fifo.yaml", "the scene is empty: nothing was written to the pipe"},
      {"/dev/zero", "it is a character device"},
      {"/dev/urandom", "it is a character device"},
      {"/dev/null", "it is a character device"},
      {"/dev/tty", ""},  // a character device, or no terminal at all: refused either way
      {"folder.yaml", "it is a directory, not a scene file"}};
  if (have_socket) cases.push_back({"sock.yaml", "it is a socket, not a regular file"});
  for (const char* command : {"run", "compare", "verify", "draw", "converge", "study --tolerances 1e-6",
                              "stability --vary hub.mass --values 1,2"})
    for (const auto& [path, why] : cases) {
      const Run r = timed(s.dir().string(), std::string(command) + " " + path);
      INFO(command << " " << path << ": " << r.err);
      CHECK(r.status != kTimedOut);
      CHECK(r.status == 2);
      CHECK(contains(r.err, path + ":1:1: cannot open the scene file: " + why));
    }
  if (fd >= 0) ::close(fd);
  // A sharded run reads each scene again: a pipe is refused before any work, never waited on.
  const Run sh = timed(s.dir().string(), "verify fifo.yaml --shard 0/2 --part p.json");
  CHECK(sh.status == 2);
  CHECK(contains(sh.err, "fifo.yaml"));
  CHECK_FALSE(fs::exists(s.path("p.json")));
  // A pipe with a writer is still read: `crossdyn run <(...)`.
  s.write("scene.yaml", kSmallScene);
  const Run piped = timed(s.dir().string(), "run /dev/stdin", "< scene.yaml > out.csv");
  CHECK(piped.status == 0);
  CHECK(read_file(s.path("out.csv")).rfind("t,hub.wx", 0) == 0);
}

TEST_CASE("class 3, nothing blocks on a special file: nodal CSV files, scenes folders, the report script") {
  Scratch s("special_in");
  fs::copy_file(source_dir() + "/scenarios/data/panel_modes.csv", s.path("panel_modes.csv"));
  fs::copy_file(source_dir() + "/scenarios/data/panel_nodes.csv", s.path("panel_nodes.csv"));
  s.write("good.yaml", nodal_scene("panel_nodes.csv"));
  REQUIRE(timed(s.dir().string(), "run good.yaml --output good.csv").status == 0);
  // The nodal file as a FIFO with no writer, /dev/zero, /dev/urandom, a directory.
  REQUIRE(::mkfifo(s.path("fifo.csv").c_str(), 0644) == 0);
  fs::create_directories(s.dir() / "dir.csv");
  fs::create_symlink("/dev/zero", s.dir() / "zero.csv");
  for (const auto& [nodes, why] : std::vector<std::pair<std::string, std::string>>{
           {"fifo.csv", "it is a named pipe (FIFO), not a regular file"},
           {"/dev/zero", "it is a character device"},
           {"/dev/urandom", "it is a character device"},
           {"zero.csv", "it is a character device"},
           {"dir.csv", "it is a directory"}}) {
    s.write("bad.yaml", nodal_scene(nodes));
    for (const char* command : {"run", "compare", "list --scenarios ."}) {
      const Run r = timed(s.dir().string(), std::string(command) + (contains(command, "list") ? "" : " bad.yaml"));
      INFO(command << " with nodes " << nodes << ": " << r.out << r.err);
      CHECK(r.status == 2);
      CHECK(contains(r.out + r.err, why));
    }
  }
  // A scenes folder holding a FIFO, a link to /dev/zero and a directory named like scenes: each
  // is named as unreadable, none is waited on.
  Scratch f("special_folder");
  f.write("scenes/good.yaml", kSmallScene);
  REQUIRE(::mkfifo(f.path("scenes/x.yaml").c_str(), 0644) == 0);
  fs::create_symlink("/dev/zero", f.dir() / "scenes" / "zero.yaml");
  fs::create_directories(f.dir() / "scenes" / "dir.yml");
  const Run list = timed(f.dir().string(), "list --scenarios scenes");
  CHECK(list.status == 2);
  CHECK(contains(list.out, "it is a named pipe (FIFO), not a regular file"));
  CHECK(contains(list.out, "it is a character device"));
  CHECK(contains(list.out, "it is a directory"));
  const Run verify = timed(f.dir().string(), "verify --scenarios scenes --json v.json");
  INFO(verify.out << verify.err);
  CHECK(verify.status == 2);
  CHECK(contains(verify.out, "x.yaml"));
  CHECK(contains(verify.out, "zero.yaml"));
  CHECK(contains(verify.out, "dir.yml"));
  const Run shard = timed(f.dir().string(), "verify --scenarios scenes --shard 0/2 --part p.json");
  CHECK(shard.status == 2);
  CHECK(shard.status != kTimedOut);
  // The report script as a FIFO, a character device, a directory: refused before any run.
  s.write("scene.yaml", kSmallScene);
  REQUIRE(::mkfifo(s.path("script.py").c_str(), 0644) == 0);
  for (const std::string script : {"script.py", "/dev/zero", "dir.csv"}) {
    const Run r = timed(s.dir().string(), "verify scene.yaml --report rep --report-script " + script);
    INFO(script << ": " << r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, "--report-script: '" + script + "' cannot be used: it is a"));
    CHECK_FALSE(fs::exists(s.path("rep")));
  }
}

TEST_CASE("class 4, a scenes folder is verified whole: every scene-looking file is verified or named") {
  Scratch s("folder_whole");
  s.write("scenes/good.yaml", kSmallScene);
  s.write("scenes/Scene.YAML", kSmallScene);  // any letter case
  s.write("scenes/other.Yml", kSmallScene);
  s.write("scenes/broken.yml", "name: [\n");
  s.write("scenes/.hidden.yaml", kSmallScene);      // hidden: skipped, named
  s.write("scenes/good.yaml~", kSmallScene);        // an editor backup: skipped, named
  s.write("scenes/good.yaml.bak", kSmallScene);
  s.write("scenes/notes.txt", "not a scene");        // not scene-like: ignored
  s.write("scenes/data/inner.yaml", kSmallScene);   // subfolders are not searched
  fs::create_symlink("gone.yaml", s.dir() / "scenes" / "dangling.yaml");
  fs::create_symlink("good.yaml", s.dir() / "scenes" / "linked.yaml");
  fs::create_directories(s.dir() / "scenes" / "folder.yaml");
  const std::vector<std::string> scenes{"Scene.YAML", "broken.yml", "dangling.yaml", "folder.yaml",
                                        "good.yaml", "linked.yaml", "other.Yml"};

  // list: every scene with its description or why it cannot be read; the skipped ones named.
  const Run list = timed(s.dir().string(), "list --scenarios scenes");
  INFO(list.out << list.err);
  CHECK(list.status == 2);
  CHECK(contains(list.out, "scenes in scenes/ (7):"));
  for (const char* name : {"  Scene ", "  other ", "  good ", "  linked "})
    CHECK(contains(list.out, std::string(name)));
  CHECK(contains(list.out, "dangling.yaml:1:1: cannot open the scene file: it is a symbolic link to a file that does not exist"));
  CHECK(contains(list.out, "folder.yaml:1:1: cannot open the scene file: it is a directory"));
  CHECK(contains(list.out, "skipped .hidden.yaml: a hidden file"));
  CHECK(contains(list.out, "skipped good.yaml~: the name does not end in .yaml or .yml"));
  CHECK(contains(list.out, "skipped good.yaml.bak: the name does not end in .yaml or .yml"));
  CHECK_FALSE(contains(list.out, "notes.txt"));
  CHECK_FALSE(contains(list.out, "inner"));

  // verify: every scene is a row of the table, the JSON and the JUnit XML; the unreadable ones
  // make it fail (exit 2); the skipped files are named on stderr.
  const Run v = timed(s.dir().string(), "verify --scenarios scenes --json v.json --junit j.xml");
  INFO(v.out << v.err);
  CHECK(v.status == 2);
  const nlohmann::json j = nlohmann::json::parse(read_file(s.path("v.json")));
  const std::string junit = read_file(s.path("j.xml"));
  std::vector<std::string> in_json;
  for (const auto& sc : j.at("scenes")) in_json.push_back(fs::path(sc.at("path").get<std::string>()).filename().string());
  std::sort(in_json.begin(), in_json.end());
  CHECK(in_json == scenes);
  for (const std::string& name : scenes) {
    CHECK(contains(v.out, name));
    CHECK(contains(junit, name));
  }
  CHECK(contains(v.err, "verify: skipped 'scenes/.hidden.yaml': a hidden file"));
  CHECK(contains(v.err, "verify: skipped 'scenes/good.yaml~'"));
  // A folder of only good scenes, one of them Scene.YAML, passes; with --shard the shards see the
  // same list (two parts cover all the scenes).
  Scratch g("folder_good");
  g.write("scenes/a.yaml", kSmallScene);
  g.write("scenes/B.YAML", kSmallScene);
  const Run ok = timed(g.dir().string(), "verify --scenarios scenes --json v.json");
  INFO(ok.out << ok.err);
  CHECK(ok.status == 0);
  CHECK(contains(ok.out, "B.YAML"));
  for (int k = 0; k < 2; ++k)
    CHECK(timed(g.dir().string(), "verify --scenarios scenes --shard " + std::to_string(k) + "/2 --part p" +
                                      std::to_string(k) + ".json").status == 0);
  const Run merged = timed(g.dir().string(), "merge p0.json p1.json --json m.json");
  INFO(merged.out << merged.err);
  CHECK(merged.status == 0);
  CHECK(contains(merged.out, "B.YAML"));
  CHECK(contains(merged.out, "a.yaml"));
}

TEST_CASE("class 8, a value is refused where it is given: empty and repeated lists on every list option") {
  Scratch s("lists");
  s.write("scene.yaml", kSmallScene);
  struct Case {
    std::string args, message;
  };
  std::vector<Case> cases;
  const std::vector<std::pair<std::string, std::string>> commands{
      {"compare scene.yaml", ""}, {"verify scene.yaml", ""}, {"converge scene.yaml", ""},
      {"study scene.yaml", ""}, {"stability scene.yaml --vary hub.mass", " --values 1,2"}};
  for (const auto& [command, needed] : commands) {
    cases.push_back({command + needed + " --engines ''", "--engines: the list is empty"});
    cases.push_back({command + needed + " --engines kane,kane", "--engines: 'kane' is listed twice"});
    cases.push_back({command + needed + " --engines kane,", "--engines: an empty item in 'kane,'"});
    cases.push_back({command + needed + " --engines ,kane", "--engines: an empty item"});
  }
  for (const std::string command : {"study scene.yaml", "stability scene.yaml --vary hub.mass --values 1,2"}) {
    for (const std::string option : {"--integrators", "--tolerances", "--dts"})
      cases.push_back({command + " " + option + " ''", option + ": the list is empty"});
    cases.push_back({command + " --integrators rk4,rk4", "--integrators: 'rk4' is listed twice"});
    cases.push_back({command + " --tolerances 1e-6,1e-6", "--tolerances: '1e-6' is listed twice"});
    cases.push_back({command + " --tolerances 1e-6,1e-06", "--tolerances: the value 1e-06 is listed twice"});
    cases.push_back({command + " --dts 0.01,0.010", "--dts: the value"});
    cases.push_back({command + " --tolerances 1e-6,,1e-8", "--tolerances: an empty item"});
  }
  cases.push_back({"stability scene.yaml --vary hub.mass --values ''", "--values: the list is empty"});
  cases.push_back({"stability scene.yaml --vary hub.mass --values 1,1", "--values: '1' is listed twice"});
  cases.push_back({"stability scene.yaml --vary hub.mass --values 10,1e1", "--values: the value 10 is listed twice"});
  cases.push_back({"stability scene.yaml --vary hub.mass --values 1,2 --set ''", "--set '': expected KNOB=VALUE"});
  cases.push_back({"stability scene.yaml --vary hub.mass --values 1,2 --set panel.mass=2 --set panel.mass=3",
                   "--set: 'panel.mass' is set twice"});
  for (const Case& c : cases) {
    const Run r = timed(s.dir().string(), c.args);
    INFO(c.args << "\n" << r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, c.message));
    check_one_sentence(r);
  }
}
