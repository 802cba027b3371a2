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
#include <tuple>

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
      {"fifo.yaml", ":1:1: the scene is empty: nothing was written to the pipe"},
      {"/dev/zero", ":1:1: cannot open the scene file: it is a character device"},
      {"/dev/urandom", ":1:1: cannot open the scene file: it is a character device"},
      {"/dev/null", ":1:1: cannot open the scene file: it is a character device"},
      {"/dev/tty", ":1:1: cannot open the scene file: it is a "},  // a terminal, or none: refused
      {"folder.yaml", ":1:1: cannot open the scene file: it is a directory, not a scene file"}};
  if (have_socket) cases.push_back({"sock.yaml", ":1:1: cannot open the scene file: it is a socket, not a regular file"});
  for (const char* command : {"run", "compare", "verify", "draw", "converge", "study --tolerances 1e-6",
                              "stability --vary hub.mass --values 1,2", "linearize",
                              "linearize --vary hub.mass --values 1,2"})
    for (const auto& [path, why] : cases) {
      const Run r = timed(s.dir().string(), std::string(command) + " " + path);
      INFO(command << " " << path << ": " << r.err);
      CHECK(r.status != kTimedOut);
      CHECK(r.status == 2);
      CHECK(contains(r.err, path + why));
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
           {"fifo.csv", "fifo.csv: it is a named pipe"},
           {"/dev/zero", "/dev/zero: it is a char"},
           {"/dev/urandom", "/dev/urandom: it is a"},
           {"zero.csv", "zero.csv: it is a char"},
           {"dir.csv", "dir.csv: it is a directory"}}) {
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
  CHECK(contains(list.out, "scenes/x.yaml:1:1: cannot open the scene file: it is a named"));
  CHECK(contains(list.out, "scenes/zero.yaml:1:1: cannot open the scene file: it is a char"));
  CHECK(contains(list.out, "scenes/dir.yml:1:1: cannot open the scene file: it is a direc"));
  const Run verify = timed(f.dir().string(), "verify --scenarios scenes --json v.json");
  INFO(verify.out << verify.err);
  CHECK(verify.status == 2);
  CHECK(contains(verify.out, "x.yaml"));
  CHECK(contains(verify.out, "zero.yaml"));
  CHECK(contains(verify.out, "dir.yml"));
  const Run shard = timed(f.dir().string(), "verify --scenarios scenes --shard 0/2 --part p.json");
  CHECK(shard.status == 2);
  CHECK(shard.status != kTimedOut);
  // The report script as a FIFO, a character device, a directory: refused before the work, never
  // waited on (exit 2, nothing written: issue 23 class 2).
  s.write("scene.yaml", kSmallScene);
  REQUIRE(::mkfifo(s.path("script.py").c_str(), 0644) == 0);
  for (const std::string script : {"script.py", "/dev/zero", "dir.csv"}) {
    const Run r = timed(s.dir().string(), "verify scene.yaml --report rep --report-script " + script);
    INFO(script << ": " << r.err);
    CHECK(r.status != kTimedOut);
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
  CHECK(contains(list.out, "dangling  cannot be read: scenes/dangling.yaml:1:1: cannot open the scene file: it is a sym"));
  CHECK(contains(list.out, "folder    cannot be read: scenes/folder.yaml:1:1: cannot open the scene file: it is a dir"));
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
  for (const std::string& name : scenes) {  // stderr names every file, the table the bad ones
    CHECK(contains(v.err, "verify: scenes/" + name));
    CHECK(contains(junit, name));
  }
  for (const char* bad : {"scenes/broken.yml", "scenes/dangling.yaml", "scenes/folder.yaml"})
    CHECK(contains(v.out, bad));
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
  CHECK(contains(ok.err, "verify: scenes/B.YAML"));
  for (int k = 0; k < 2; ++k)
    CHECK(timed(g.dir().string(), "verify --scenarios scenes --shard " + std::to_string(k) + "/2 --part p" +
                                      std::to_string(k) + ".json").status == 0);
  const Run merged = timed(g.dir().string(), "merge p0.json p1.json --json m.json");
  INFO(merged.out << merged.err);
  CHECK(merged.status == 0);
  CHECK(contains(merged.out, "2 scenes"));
}

TEST_CASE("class 8, a value is refused where it is given: empty and repeated lists on every list option") {
  Scratch s("lists");
  s.write("scene.yaml", kSmallScene);
  struct Case {
    std::string args, message;
  };
  std::vector<Case> cases;
  const std::vector<std::pair<std::string, std::string>> commands{
      {"compare scene.yaml", ""}, {"verify scene.yaml", ""},
      {"study scene.yaml", ""}, {"stability scene.yaml --vary hub.mass", " --values 1,2"},
      {"linearize scene.yaml", ""}, {"linearize scene.yaml --vary hub.mass", " --values 1,2"}};
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
  cases.push_back({"linearize scene.yaml --vary hub.mass --values ''", "--values: the list is empty"});
  cases.push_back({"linearize scene.yaml --vary hub.mass --values 1,1", "--values: '1' is listed twice"});
  cases.push_back({"linearize scene.yaml --set panel.mass=2 --set panel.mass=3", "--set: 'panel.mass' is set twice"});
  cases.push_back({"linearize scene.yaml --inputs hinge.motor,hinge.motor", "--inputs: 'hinge.motor' is listed twice"});
  cases.push_back({"linearize scene.yaml --outputs hub.wx,", "--outputs: an empty item"});
  cases.push_back({"linearize scene.yaml --outputs ''", "--outputs: "});
  cases.push_back({"stability scene.yaml --vary hub.mass --values 1,1", "--values: '1' is listed twice"});
  cases.push_back({"stability scene.yaml --vary hinge.stiffness --values 10,1e1", "--values: the value 1e+01 is listed twice"});
  cases.push_back({"stability scene.yaml --vary hub.mass --values 1,2 --set ''", "--set: an empty value"});
  cases.push_back({"stability scene.yaml --vary hub.mass --values 1,2 --set panel.mass=2 --set panel.mass=3",
                   "--set: 'panel.mass' is set twice"});
  // Knob values and numeric lists hold the scene's bounds (1e-320 is too small, not "not a number").
  const std::string st = "stability scene.yaml --integrators dop853 --tolerances 1e-6 ";
  cases.push_back({st + "--vary hinge.stiffness --values 1e-320", "--values: 1e-320 for hinge.stiffness: too small to compute with"});
  cases.push_back({st + "--vary hinge.stiffness --values 1,1e300", "--values: 1e+300 for hinge.stiffness: absurd"});
  cases.push_back({st + "--vary hinge.rate --values 1e6", "--values: 1e+06 for hinge.rate: at most 1e4 rad/s"});
  cases.push_back({st + "--vary hinge.stiffness --values 1 --set base.wx=1e-320", "for base.wx: too small to compute with"});
  cases.push_back({st + "--vary hinge.stiffness --values 1e400", "--values: '1e400' is not a finite number"});
  cases.push_back({"study scene.yaml --tolerances 1e-320", "--tolerances: 1e-320 is outside the allowed range, 1e-100 to 1e12"});
  cases.push_back({"study scene.yaml --dts 1e300", "--dts: 1e300 is outside the allowed range"});
  // Any option given an empty value: an error, not its default (`--scenarios ''` is not scenarios/).
  for (const std::string args : {"list --scenarios ''", "verify --scenarios ''", "run scene.yaml --output ''",
                                 "verify scene.yaml --json ''", "verify scene.yaml --report-script ''",
                                 "run scene.yaml --integrator ''", "compare scene.yaml --dt ''",
                                 "study scene.yaml --csv ''", "draw scene.yaml --geometry ''"})
    cases.push_back({args, "an empty value (leave the option out for its default)"});
  for (const Case& c : cases) {
    const Run r = timed(s.dir().string(), c.args);
    INFO(c.args << "\n" << r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, c.message));
    check_one_sentence(r);
  }
}

namespace {

// A scene with a value of every kind (masses, inertias, lengths, rates, angles, a spring, a
// damper, a motor profile, a prescribed spin-up, the run block); @KEY@ is replaced.
const char* kEveryKind = R"(name: kinds
description: every kind of value, for class 8.
bodies:
  - {name: hub, mass: @mass@ kg, inertia: [@inertia@, 10, 10]}
  - {name: arm, mass: 2 kg, inertia: [1, 1, 1], center_of_mass: [@com@ m, 0, 0]}
  - {name: wheel, mass: 1 kg, inertia: [1, 1, 1]}
joints:
  - name: base
    type: free
    child: hub
    initial: {angular_velocity: [@w@ rad/s, 0, 0.1 rad/s]}
  - name: hinge
    type: revolute
    parent: hub
    child: arm
    parent_point: [1 m, 0, 0]
    child_point: [-1 m, 0, 0]
    axis: [0, 0, 1]
    spring: {stiffness: @k@}
    damper: {damping: @c@}
    motor: {profile: [{t: @t0@ s, value: @torque@}, {t: 0.05 s, value: 0}]}
    initial: {angle: @angle@ rad, rate: @rate@ rad/s}
  - name: spin
    type: revolute
    parent: hub
    child: wheel
    parent_point: [0, 1 m, 0]
    child_point: [0, 0, 0]
    axis: [0, 0, 1]
    prescribed: {profile: spin-up, rate: @prate@ rad/s, ramp_time: @ramp@ s}
run: {duration: @duration@ s, output_step: @ostep@ s, integrator: dop853, rtol: @rtol@, atol: @atol@, dt: @dt@ s}
)";

std::string every_kind(const std::string& key, const std::string& value) {
  const std::vector<std::pair<std::string, std::string>> defaults{
      {"mass", "100"}, {"inertia", "10"}, {"com", "0.1"}, {"w", "0.1"}, {"k", "5"}, {"c", "0.1"},
      {"t0", "0"}, {"torque", "0.1"}, {"angle", "0.1"}, {"rate", "0"}, {"prate", "1"}, {"ramp", "0.5"},
      {"duration", "0.1"}, {"ostep", "0.01"}, {"rtol", "1e-8"}, {"atol", "1e-8"}, {"dt", "0.001"}};
  std::string text = kEveryKind;
  for (const auto& [k, v] : defaults) {
    const std::string mark = "@" + k + "@";
    text.replace(text.find(mark), mark.size(), k == key ? value : v);
  }
  return text;
}

}  // namespace

TEST_CASE("class 8, a value is refused where it is given: tiny and huge scene values and options") {
  Scratch s("values");
  s.write("ok.yaml", every_kind("", ""));
  REQUIRE(timed(s.dir().string(), "run ok.yaml --output ok.csv").status == 0);
  const std::vector<std::pair<std::string, std::string>> keys{
      {"mass", "bodies[0].mass"}, {"inertia", "bodies[0].inertia[0]"}, {"com", "bodies[1].center_of_mass[0]"},
      {"w", "joints[0].initial.angular_velocity[0]"}, {"k", "joints[1].spring.stiffness"},
      {"c", "joints[1].damper.damping"}, {"t0", "joints[1].motor.profile[0].t"},
      {"torque", "joints[1].motor.profile[0].value"}, {"angle", "joints[1].initial.angle"},
      {"rate", "joints[1].initial.rate"}, {"prate", "joints[2].prescribed.rate"},
      {"ramp", "joints[2].prescribed.ramp_time"}, {"duration", "run.duration"},
      {"ostep", "run.output_step"}, {"rtol", "run.rtol"}, {"atol", "run.atol"}, {"dt", "run.dt"}};
  for (const auto& [key, path] : keys)
    for (const std::string value : {"1e-320", "-1e-320", "1e-300", "4.9e-324", "1e-101", "1e300", "1e308"}) {
      s.write("bad.yaml", every_kind(key, value));
      const Run r = timed(s.dir().string(), "run bad.yaml --output out.csv");
      INFO(key << " = " << value << ": " << r.err);
      CHECK(r.status == 2);  // never exit 3 at t = 0
      CHECK(std::regex_search(r.err, std::regex("^crossdyn: error: bad\\.yaml:[0-9]+:[0-9]+: ")));
      CHECK(contains(r.err, path + ":"));
      check_one_sentence(r);
      CHECK_FALSE(fs::exists(s.path("out.csv")));
    }
  // Angles no engine's run survives (measured: 1e8 rad) and prescribed rates above their limit.
  // (Initial rates are not capped: a 1e5 rad/s spin for 10 ms is a solvable scene.)
  for (const auto& [key, value, path] : std::vector<std::tuple<std::string, std::string, std::string>>{
           {"prate", "2e4", "joints[2].prescribed.rate"}, {"angle", "1e8", "joints[1].initial.angle"}}) {
    s.write("bad.yaml", every_kind(key, value));
    const Run r = timed(s.dir().string(), "run bad.yaml");
    INFO(key << " = " << value << ": " << r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, path + ": "));
    CHECK((contains(r.err, "is too large: at most") || contains(r.err, "at most 1e4 rad/s in size")));
  }
  // The issue's example, word for word.
  s.write("ramp.yaml", every_kind("ramp", "1e-320"));
  const Run ramp = timed(s.dir().string(), "run ramp.yaml");
  CHECK(ramp.status == 2);
  CHECK(contains(ramp.err, "joints[2].prescribed.ramp_time: value 1e-320 is too small to compute with"));
  CHECK(contains(ramp.err, "1e-100 to 1e12"));
  // An adaptive method's first trial step below its minimum step (1e-13 s) is refused at run.dt,
  // and as --dt; rk4 takes it (its step count is the limit).
  s.write("dt.yaml", every_kind("dt", "1e-20"));
  const Run dt = timed(s.dir().string(), "run dt.yaml");
  CHECK(dt.status == 2);
  CHECK(contains(dt.err, "run.dt: dt = 1e-20 s is the adaptive integrators' first trial step"));
  const Run dt_option = timed(s.dir().string(), "run ok.yaml --dt 1e-20");
  CHECK(dt_option.status == 2);
  CHECK(contains(dt_option.err, "--dt 1e-20: dt = 1e-20 s is the adaptive integrators' first trial step"));
  // Every numeric option of the run block, tiny and huge, on every command that takes it.
  for (const std::string command : {"run ok.yaml --output out.json", "compare ok.yaml --json out.json",
                                     "verify ok.yaml --json out.json"})
    for (const std::string option : {"--dt", "--rtol", "--atol"})
      for (const std::string value : {"1e-320", "1e-200", "1e300"}) {
        const Run r = timed(s.dir().string(), command + " " + option + " " + value);
        CHECK_FALSE(fs::exists(s.path("out.json")));
        INFO(command << " " << option << " " << value << ": " << r.err);
        CHECK(r.status == 2);
        CHECK(contains(r.err, "crossdyn: error: " + option + " "));
        check_one_sentence(r);
      }
  // A per-run timeout no run could start within (1e-320 s), or beyond the watchdog's range.
  for (const std::string command : {"compare ok.yaml", "verify ok.yaml", "study ok.yaml",
                                     "stability ok.yaml --vary hinge.stiffness --values 1,2"})
    for (const std::string value : {"1e-320", "1e-6", "1e300"}) {
      const Run r = timed(s.dir().string(), command + " --timeout " + value);
      INFO(command << " --timeout " << value << ": " << r.err);
      CHECK(r.status == 2);
      CHECK(contains(r.err, "crossdyn: error: --timeout: "));
      CHECK(contains(r.err, "0.001 to 1e9 s"));
    }
  for (const std::string option : {"--duration", "--output-step"})
    for (const std::string value : {"1e-320", "1e-200", "1e300"}) {
      const Run r = timed(s.dir().string(), "run ok.yaml " + option + " " + value);
      INFO(option << " " << value << ": " << r.err);
      CHECK(r.status == 2);
      CHECK(contains(r.err, "crossdyn: error: " + option + " "));
      check_one_sentence(r);
    }
}

TEST_CASE("class 10, every error is a sentence about the user's input: numbers on the command line") {
  Scratch s("sentences");
  s.write("scene.yaml", kSmallScene);
  const std::vector<std::pair<std::string, std::string>> cases{
      {"run scene.yaml --max-steps 1e30", "--max-steps: '1e30' is not a whole number"},
      {"run scene.yaml --max-steps 99999999999999999999", "--max-steps: '99999999999999999999' is too large"},
      {"run scene.yaml --max-steps 0x10", "--max-steps: '0x10' is not a whole number"},
      {"run scene.yaml --max-steps abc", "--max-steps: 'abc' is not a whole number"},
      {"compare scene.yaml --max-steps 3000000000", "--max-steps: '3000000000' is too large"},
      {"study scene.yaml --repeat 99999999999", "--repeat: '99999999999' is too large"},
      {"study scene.yaml --repeat 1.5", "--repeat: '1.5' is not a whole number"},
      {"draw scene.yaml --panels 1e3", "--panels: '1e3' is not a whole number"},
      {"run scene.yaml --duration abc", "--duration: 'abc' is not a number this option takes"},
      {"compare scene.yaml --timeout 1x", "--timeout: '1x' is not a number this option takes"},
      {"study scene.yaml --budget two", "--budget: 'two' is not a number this option takes"},
      {"linearize scene.yaml --time abc", "--time: 'abc' is not a number this option takes"},
      {"linearize scene.yaml --rtol 1x", "--rtol: '1x' is not a number this option takes"}};
  for (const auto& [args, message] : cases) {
    const Run r = timed(s.dir().string(), args);
    INFO(args << ": " << r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, message));
    check_one_sentence(r);
  }
  // "010" is ten steps, not CLI11's octal eight: the run stops at the step limit of ten.
  const Run octal = timed(s.dir().string(), "run scene.yaml --max-steps 010 --output o.csv");
  CHECK(octal.status == 3);
  CHECK(contains(octal.err, "10 steps"));
}

TEST_CASE("class 3, nothing blocks on a special file: part files given to merge") {
  Scratch s("special_parts");
  s.write("scene.yaml", kSmallScene);
  REQUIRE(timed(s.dir().string(), "verify scene.yaml --shard 0/1 --part good.json").status == 0);
  REQUIRE(::mkfifo(s.path("fifo.json").c_str(), 0644) == 0);
  fs::create_directories(s.dir() / "dir.json");
  fs::create_symlink("/dev/zero", s.dir() / "zero.json");
  for (const auto& [part, why] : std::vector<std::pair<std::string, std::string>>{
           {"fifo.json", "it is a named pipe (FIFO), not a regular file"},
           {"/dev/zero", "it is a character device"},
           {"/dev/urandom", "it is a character device"},
           {"zero.json", "it is a character device"},
           {"dir.json", "it is a directory"}}) {
    const Run r = timed(s.dir().string(), "merge good.json " + part + " --json m.json");
    INFO(part << ": " << r.err);
    CHECK(r.status != kTimedOut);
    CHECK(r.status == 2);
    CHECK(contains(r.err, "cannot read the part file '" + part + "': " + why));
    CHECK_FALSE(fs::exists(s.path("m.json")));
  }
}
