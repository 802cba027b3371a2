// Issue 23, classes 1 and 2, across every command and output kind (docs/outputs.md "Outputs:
// special files, symbolic links, read-only files"):
//   class 1: no output of any command replaces an input: the scene, the nodal data files it
//            reads, the part files of a merge (exit 2, the input's bytes unchanged);
//   class 2: an unusable output is refused (exit 2) before the work, with no other output
//            written; an interrupted command (exit 130) leaves every old output, and an
//            interrupt during the final renames leaves every new one (the test hook
//            CROSSDYN_TEST_INTERRUPT_AT=report / before-commit / during-commit, core/cancel.hpp).
#include <catch2/catch.hpp>

#include "tests/cli/cli_helpers.hpp"

#include <atomic>
#include <chrono>
#include <optional>
#include <vector>

namespace {

using namespace crossdyn::test;

// A hub and a flexible panel whose data come from two nodal files beside the scene (relative
// paths: the reader resolves them against the scene's folder).
std::string flex_scene(const std::string& nodes, const std::string& modes) {
  return "name: flexpanel\ndescription: A hub and a panel from nodal data files.\n"
         "source: crossdyn tests (tests/cli/test_output_classes.cpp).\nbodies:\n"
         "  - {name: hub, mass: 100, inertia: [10, 20, 25]}\n"
         "  - name: panel\n    flexible: {nodes: " + nodes + ", modes: " + modes + "}\n"
         "joints:\n"
         "  - {name: base, type: free, child: hub, initial: {angular_velocity: [0.01, 0, 0.02]}}\n"
         "  - {name: hinge, type: revolute, parent: hub, child: panel, parent_point: [1, 0, 0],\n"
         "     child_node: root, axis: [1, 0, 0], spring: {stiffness: 50}, initial: {angle: 0.01}}\n"
         "run: {duration: 0.2, output_step: 0.05}\n";
}

// Copies the example nodal files into the scratch folder under the given names; writes s.yaml.
void flex_files(const Scratch& s, const std::string& nodes = "nodes.csv",
                const std::string& modes = "modes.csv") {
  const std::string data = source_dir() + "/scenarios/data/";
  s.write(nodes, read_file(data + "panel_nodes.csv"));
  s.write(modes, read_file(data + "panel_modes.csv"));
  s.write("s.yaml", flex_scene(nodes, modes));
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Nothing of crossdyn's left in the folder: no temporaries, no staging folders.
bool no_leftovers(const Scratch& s) {
  for (const auto& e : fs::recursive_directory_iterator(s.dir())) {
    const std::string n = e.path().filename().string();
    if (contains(n, ".crossdyn-") || contains(n, ".partial-")) return false;
  }
  return true;
}

// `cd DIR && PREFIX crossdyn ARGS`, as run_in (the redirections are the calling shell's).
Run run_with(const std::string& prefix, const std::string& dir, const std::string& args) {
  static std::atomic<int> counter{0};
  const fs::path tmp = fs::temp_directory_path() /
                       ("crossdyn_runas_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  fs::create_directories(tmp);
  const std::string out = (tmp / "out").string(), err = (tmp / "err").string();
  const std::string cmd = "cd " + quote(dir) + " && " + prefix + " " + quote(crossdyn_binary()) + " " +
                          args + " > " + quote(out) + " 2> " + quote(err);
  const int raw = std::system(cmd.c_str());
  Run r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = read_file(out);
  r.err = read_file(err);
  fs::remove_all(tmp);
  return r;
}

// How to run crossdyn as an unprivileged user (uid and gid 65534, "nobody"): "" when the tests
// already run as one; setpriv (util-linux) when root; nullopt (with the reason) when impossible.
std::optional<std::string> unprivileged_prefix(std::string& why) {
  if (!is_root()) return std::string();
  const std::string prefix = "setpriv --reuid=65534 --regid=65534 --clear-groups";
  if (std::system((prefix + " " + quote(crossdyn_binary()) + " --version > /dev/null 2>&1").c_str()) != 0) {
    why = "cannot run '" + crossdyn_binary() + "' as uid 65534 through setpriv (not installed, or "
          "the build folder is not readable by other users)";
    return std::nullopt;
  }
  return prefix;
}

}  // namespace

TEST_CASE("class 1, an input is never overwritten, whatever names it: every command's outputs "
          "against the scene, its nodal data files and merge's part files") {
  Scratch s("class1");
  flex_files(s);
  const std::string nodes = read_file(s.path("nodes.csv")), modes = read_file(s.path("modes.csv"));
  const std::string scene = read_file(s.path("s.yaml"));
  REQUIRE(run_in(s.dir(), "run s.yaml -q --output /dev/null").status == 0);  // the scene reads

  const std::vector<std::string> cases = {
      "run s.yaml -q --output nodes.csv",
      "run s.yaml -q -o modes.csv",
      "compare s.yaml -q --json nodes.csv",
      "verify s.yaml -q --json modes.csv",
      "verify s.yaml -q --json ok.json --junit nodes.csv",
      "verify s.yaml -q --shard 0/1 --part nodes.csv",
      "converge s.yaml -q --json nodes.csv",
      "converge s.yaml -q --shard 0/2 --part modes.csv",
      "study s.yaml -q --csv nodes.csv",
      "study s.yaml -q --shard 0/1 --part modes.csv",
      "study s.yaml -q --report .",  // the report folder holds the inputs
      "stability s.yaml -q --vary hinge.stiffness --values 10,20 --csv nodes.csv",
      "stability s.yaml -q --vary hinge.stiffness --values 10,20 --shard 0/1 --part modes.csv",
      "stability s.yaml -q --vary hinge.stiffness --values 10,20 --report .",
      "verify s.yaml -q --report .",
      "linearize s.yaml --jacobian-only --json nodes.csv",
      "linearize s.yaml --jacobian-only --report .",
      "linearize s.yaml --jacobian-only --vary hinge.stiffness --values 10,20 --json modes.csv",
  };
  for (const std::string& args : cases) {
    INFO(args);
    const auto t0 = std::chrono::steady_clock::now();
    const Run r = run_in(s.dir(), args);
    INFO(r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, "crossdyn: error: "));
    CHECK((contains(r.err, "input") || contains(r.err, "holds")));
    CHECK(seconds_since(t0) < 10);  // refused before the work
    CHECK(read_file(s.path("nodes.csv")) == nodes);
    CHECK(read_file(s.path("modes.csv")) == modes);
    CHECK(read_file(s.path("s.yaml")) == scene);
    CHECK(!fs::exists(s.path("ok.json")));
  }

  // Standard output appended to, or opened read-write on, an input (a `>` redirection empties
  // the file in the shell before crossdyn starts: nothing crossdyn can prevent).
  const std::vector<std::pair<std::string, std::string>> redirected = {
      {"run s.yaml -q", ">> nodes.csv"},
      {"run s.yaml -q", "1<> modes.csv"},
      {"run s.yaml -q", ">> s.yaml"},
      {"compare s.yaml -q", ">> nodes.csv"},
      {"verify s.yaml -q --json ok.json", "1<> modes.csv"},
      {"converge s.yaml -q", ">> nodes.csv"},
      {"study s.yaml -q --engines kane --integrators rk4 --dts 0.05", ">> modes.csv"},
      {"stability s.yaml -q --vary hinge.stiffness --values 10,20", ">> nodes.csv"},
      {"draw s.yaml --no-motion -o ok.png", ">> s.yaml"},
      {"linearize s.yaml --jacobian-only --json ok.json", ">> nodes.csv"},
  };
  for (const auto& [args, redirect] : redirected) {
    INFO(args << " " << redirect);
    const Run r = run_in(s.dir(), args, redirect);
    INFO(r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, "standard output is the same file as the"));
    CHECK(read_file(s.path("nodes.csv")) == nodes);
    CHECK(read_file(s.path("modes.csv")) == modes);
    CHECK(read_file(s.path("s.yaml")) == scene);
    CHECK(!fs::exists(s.path("ok.json")));
    CHECK(!fs::exists(s.path("ok.png")));
  }

  // A data file named like the outputs of draw (-o *.png, --geometry *.json).
  Scratch d("class1draw");
  flex_files(d, "panel.json", "panel_modes.png");
  const std::string pj = read_file(d.path("panel.json")), pp = read_file(d.path("panel_modes.png"));
  for (const std::string args : {"draw s.yaml --no-motion -o panel_modes.png",
                                  "draw s.yaml --no-motion -o x.png --geometry panel.json"}) {
    INFO(args);
    const Run r = run_in(d.dir(), args);
    INFO(r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, "input"));
    CHECK(read_file(d.path("panel.json")) == pj);
    CHECK(read_file(d.path("panel_modes.png")) == pp);
    CHECK(!fs::exists(d.path("x.png")));
  }

  // linearize --csv DIR writes files of known names into DIR: a data file named like one of them.
  Scratch l("class1linearize");
  flex_files(l, "kane.A.csv", "states.csv");
  const std::string ka = read_file(l.path("kane.A.csv")), st = read_file(l.path("states.csv"));
  for (const std::string args : {"linearize s.yaml --jacobian-only --csv .",
                                  "linearize s.yaml --jacobian-only --engines kane --csv . --json ok.json"}) {
    INFO(args);
    const Run r = run_in(l.dir(), args);
    INFO(r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, "input"));
    CHECK(read_file(l.path("kane.A.csv")) == ka);
    CHECK(read_file(l.path("states.csv")) == st);
    CHECK(!fs::exists(l.path("ok.json")));
    CHECK(!fs::exists(l.path("inputs.csv")));
  }
  CHECK(no_leftovers(l));

  // merge: its outputs against its part files.
  Scratch m("class1merge");
  m.write("a.yaml", kSmallScene);
  REQUIRE(run_in(m.dir(), "verify a.yaml -q --shard 0/1 --part p.json").status == 0);
  REQUIRE(run_in(m.dir(), "study a.yaml -q --engines kane --integrators rk4 --dts 0.05 --repeat 1 "
                          "--shard 0/1 --part q.json").status == 0);
  const std::string p = read_file(m.path("p.json")), q = read_file(m.path("q.json"));
  for (const std::string args : {"merge p.json --json p.json", "merge p.json --junit p.json",
                                  "merge p.json --report=.", "merge q.json --csv q.json",
                                  "merge q.json --report=."}) {
    INFO(args);
    const Run r = run_in(m.dir(), args);
    INFO(r.err);
    CHECK(r.status == 2);
    CHECK(read_file(m.path("p.json")) == p);
    CHECK(read_file(m.path("q.json")) == q);
  }
  CHECK(no_leftovers(s));
  CHECK(no_leftovers(m));
}

TEST_CASE("class 2, a bad output is refused before the work: every command and output option, "
          "nothing written, nothing run") {
  Scratch s("class2bad");
  s.write("a.yaml", kSmallScene);
  // verify has no --duration: a scene that runs long (2e6 output rows) instead.
  std::string long_scene = kSmallScene;
  long_scene.replace(long_scene.find("duration: 0.5"), 13, "duration: 1e5");
  s.write("long.yaml", long_scene);
  flex_files(s);
  fs::create_directories(s.path("dir"));
  fs::create_directories(s.path("dir.png"));
  fs::create_directories(s.path("dir.json"));
  s.write("ro.csv", "old\n");
  s.write("ro.json", "old\n");
  ::chmod(s.path("ro.csv").c_str(), 0444);
  ::chmod(s.path("ro.json").c_str(), 0444);
  s.write("file", "a file, not a folder\n");
  fs::create_symlink("ok.png", s.path("glink.json"));
  REQUIRE(run_in(s.dir(), "verify a.yaml -q --shard 0/1 --part p.json").status == 0);
  REQUIRE(run_in(s.dir(), "study a.yaml -q --engines kane --integrators rk4 --dts 0.05 --repeat 1 "
                          "--shard 0/1 --part q.json").status == 0);
  REQUIRE(run_in(s.dir(), "stability a.yaml -q --engines kane --integrators rk4 --dts 0.05 --vary "
                          "hinge.rate --values 0.1 --shard 0/1 --part r.json").status == 0);
  REQUIRE(run_in(s.dir(), "converge s.yaml -q --shard 0/1 --part c.json").status == 0);
  // A long sweep: refused at once, or the test's time bound fails.
  const std::string study = "study a.yaml -q --repeat 5 ";
  const std::string stab = "stability a.yaml -q --vary hinge.rate --values 0.1,0.2,0.3,0.4 ";
  const std::vector<std::string> cases = {
      "run a.yaml -q --duration 1e5 --output dir",
      "run a.yaml -q --duration 1e5 --output ro.csv",
      "compare a.yaml -q --duration 1e5 --json dir",
      "compare a.yaml -q --duration 1e5 --json ro.json",
      "verify long.yaml -q --json ok.json --junit dir",
      "verify long.yaml -q --json ok.json --junit ro.json",
      "verify long.yaml -q --json ok.json --report=file",
      "verify long.yaml -q --shard 0/1 --part dir",
      "converge s.yaml -q --json dir",
      "converge s.yaml -q --json ro.json",
      "converge s.yaml -q --shard 0/2 --part dir",
      study + "--csv dir --report ok",
      study + "--csv ok.csv --report file",
      study + "--csv ro.csv --report ok",
      study + "--shard 0/1 --part dir",
      stab + "--csv dir",
      stab + "--csv ok.csv --report file",
      stab + "--csv ro.csv --report ok",
      stab + "--shard 0/1 --part ro.json",
      "merge p.json --json dir --junit ok.xml",
      "merge p.json --json ok.json --junit ro.json",
      "merge p.json --json ok.json --report=file",
      "merge q.json --csv dir --report=ok",
      "merge q.json --csv ok.csv --report=file",
      "merge r.json --csv ro.csv --report=ok",
      "merge r.json --csv ok.csv --report=file",
      "merge c.json --json dir",
      "merge c.json --json ro.json",
      "draw a.yaml -o dir.png",
      "draw a.yaml -o ok.png --geometry dir.json",
      "draw a.yaml -o ok.png --geometry ro.json",
      "draw a.yaml -o ok.png --geometry glink.json",  // a dangling link to ok.png: one file
      // An output file that is, or is inside, the report folder the command replaces.
      "verify long.yaml -q --json ok/summary.json --report=ok",
      "verify long.yaml -q --json ok.json --junit ok/x.xml --report=ok",
      study + "--csv ok.csv --report ok.csv", study + "--csv ok/x.csv --report ok",
      stab + "--csv ok.csv --report ok.csv", stab + "--csv ok/a/x.csv --report ok",
      "merge q.json --csv ok/x.csv --report=ok", "merge r.json --csv ok.csv --report=ok.csv",
      "merge p.json --json ok/summary.json --report=ok",
      "linearize long.yaml --jacobian-only --json dir",
      "linearize long.yaml --jacobian-only --json ro.json",
      "linearize long.yaml --jacobian-only --csv file",
      "linearize long.yaml --jacobian-only --csv ok --json ro.json",
      "linearize long.yaml --jacobian-only --csv ok --report file",
      "linearize long.yaml --jacobian-only --json ok.json --report file",
      "linearize long.yaml --jacobian-only --json ok/x.json --report ok",
      "linearize long.yaml --jacobian-only --vary hinge.rate --values 0.1,0.2 --csv file",
      "linearize long.yaml --jacobian-only --vary hinge.rate --values 0.1,0.2 --json ro.json",
  };
  for (const std::string& args : cases) {
    INFO(args);
    const auto t0 = std::chrono::steady_clock::now();
    const Run r = run_in(s.dir(), args);
    INFO(r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, "crossdyn: error: "));
    CHECK(seconds_since(t0) < 10);
    for (const char* ok : {"ok.csv", "ok.json", "ok.xml", "ok.png", "ok"}) CHECK(!fs::exists(s.path(ok)));
    CHECK(read_file(s.path("ro.csv")) == "old\n");
    CHECK(read_file(s.path("ro.json")) == "old\n");
    CHECK(fs::is_empty(s.path("dir")));
  }
  // A --python that cannot run (missing, a folder, not executable) is refused before the work,
  // by every command that runs Python: verify and merge (their reports) and draw; merge of
  // study/stability parts (whose reports use Debian's python3) refuses --python.
  {
    const std::vector<std::string> python_cases = {
        "verify long.yaml -q --json ok.json --report=ok --python /nonexistent/python3",
        "verify long.yaml -q --json ok.json --report=ok --python dir",
        "verify long.yaml -q --json ok.json --report=ok --python ro.csv",
        "verify long.yaml -q --json ok.json --report=ok --python ''",
        "merge p.json --json ok.json --report=ok --python /nonexistent/python3",
        "merge p.json --json ok.json --report=ok --python dir",
        "merge p.json --json ok.json --report=ok --python ro.csv",
        "merge q.json --csv ok.csv --report=ok --python /usr/bin/python3",
        "merge r.json --csv ok.csv --python /nonexistent/python3",
        "draw long.yaml -o ok.png --python /nonexistent/python3",
        "draw long.yaml -o ok.png --python dir",
        "draw long.yaml -o ok.png --python ro.csv"};
    for (const std::string& args : python_cases) {
      INFO(args);
      const auto t0 = std::chrono::steady_clock::now();
      const Run r = run_in(s.dir(), args);
      INFO(r.err);
      CHECK(r.status == 2);
      CHECK(contains(r.err, "crossdyn: error: "));
      CHECK(contains(r.err, "--python"));
      CHECK(seconds_since(t0) < 10);
      for (const char* ok : {"ok.csv", "ok.json", "ok.png", "ok"}) CHECK(!fs::exists(s.path(ok)));
    }
  }
  // merge: every output against the scenes the parts name (and their nodal files), before the
  // merge's work: a --report DIR holding such a scene, --json naming its nodal data file.
  {
    s.write("rep/b.yaml", kSmallScene);
    s.write("repq/b.yaml", kSmallScene);
    s.write("repq/study.json", "{\"tool\": \"crossdyn\", \"kind\": \"study\"}\n");
    REQUIRE(run_in(s.dir(), "verify rep/b.yaml -q --shard 0/1 --part pr.json").status == 0);
    REQUIRE(run_in(s.dir(), "study repq/b.yaml -q --engines kane --integrators rk4 --dts 0.05 "
                            "--repeat 1 --shard 0/1 --part qr.json").status == 0);
    REQUIRE(run_in(s.dir(), "verify s.yaml -q --shard 0/1 --part ps.json").status == 0);
    const std::string nodes = read_file(s.path("nodes.csv"));
    const std::string rep = read_file(s.path("rep/b.yaml")), repq = read_file(s.path("repq/b.yaml"));
    for (const char* args :
         {"merge pr.json --json ok.json --report=rep", "merge pr.json --json ok.json --report=rep/",
          "merge qr.json --csv ok.csv --report=repq", "merge ps.json --json nodes.csv",
          "merge ps.json --json ok.json --junit nodes.csv", "merge c.json --json nodes.csv"}) {
      INFO(args);
      const Run r = run_in(s.dir(), args);
      INFO(r.err);
      CHECK(r.status == 2);
      CHECK(contains(r.err, "crossdyn: error: "));
      CHECK((contains(r.err, "holds") || contains(r.err, "same file")));
      for (const char* ok : {"ok.csv", "ok.json"}) CHECK(!fs::exists(s.path(ok)));
      CHECK(read_file(s.path("nodes.csv")) == nodes);
      CHECK(read_file(s.path("rep/b.yaml")) == rep);
      CHECK(read_file(s.path("repq/b.yaml")) == repq);
      CHECK(fs::directory_iterator(s.path("rep"))->path().filename() == "b.yaml");
    }
  }
  // Standard output is the --part file, or appended to a part being merged: refused.
  {
    const std::string q = read_file(s.path("q.json"));
    const std::vector<std::pair<std::string, std::string>> stdout_cases = {
        {"verify a.yaml -q --shard 0/1 --part out.json", "> out.json"},
        {"study a.yaml -q --engines kane --integrators rk4 --dts 0.05 --repeat 1 --shard 0/1 "
         "--part out.json", ">> out.json"},
        {"merge q.json --csv ok.csv", ">> q.json"},
        {"merge q.json --csv ok.csv", ">> ./link.json"}};  // a symbolic link to the part
    fs::create_symlink("q.json", s.path("link.json"));
    for (const auto& [args, redirect] : stdout_cases) {
      INFO(args << " " << redirect);
      const Run r = run_in(s.dir(), args, redirect);
      INFO(r.err);
      CHECK(r.status == 2);
      CHECK(contains(r.err, "same file"));
      CHECK(read_file(s.path("q.json")) == q);
      CHECK(!fs::exists(s.path("ok.csv")));
    }
    fs::remove(s.path("out.json"));
    fs::remove(s.path("link.json"));
  }
  // A folder where nothing can be created: one without write bits is refused by its mode bits
  // for every user, root included (as read-only files are); a folder the user may not write
  // (owned by root, mode 0755) is refused for an unprivileged user. Both before the work.
  const std::vector<std::string> locked_cases = {
      "run a.yaml -q --duration 1e5 --output L/x.csv",
      "compare a.yaml -q --duration 1e5 --json L/x.json",
      "verify long.yaml -q --json ok.json --junit L/x.xml",
      "verify long.yaml -q --json L/x.json",
      "verify long.yaml -q --json ok.json --report=L/r",     // the report's parent
      "verify long.yaml -q --json ok.json --report=L/a/b/r", // folders made in L
      "verify long.yaml -q --shard 0/1 --part L/p.json",
      "converge s.yaml -q --json L/c.json",
      "converge s.yaml -q --shard 0/2 --part L/c.json",
      study + "--csv ok.csv --report L/r", study + "--csv L/x.csv --report ok",
      study + "--shard 0/1 --part L/q.json",
      stab + "--report L/r", stab + "--csv L/x.csv",
      "merge q.json --csv L/x.csv --report=ok", "merge q.json --csv ok.csv --report=L/r",
      "merge p.json --json ok.json --report=L/r", "merge p.json --json L/x.json",
      "merge c.json --json L/c.json",
      "draw a.yaml -o ok.png --geometry L/g.json", "draw a.yaml -o L/x.png"};
  auto check_locked = [&](const std::string& prefix, const std::string& locked) {
    for (std::string args : locked_cases) {
      for (std::size_t at; (at = args.find("L/")) != std::string::npos;) args.replace(at, 1, locked);
      INFO(prefix << " crossdyn " << args);
      const auto t0 = std::chrono::steady_clock::now();
      const Run r = run_with(prefix, s.dir(), args);
      INFO(r.err);
      CHECK(r.status == 2);
      CHECK(contains(r.err, "crossdyn: error: "));
      CHECK(seconds_since(t0) < 10);
      for (const char* ok : {"ok.csv", "ok.json", "ok.xml", "ok.png", "ok"}) CHECK(!fs::exists(s.path(ok)));
      CHECK(fs::is_empty(s.path(locked)));
    }
  };
  fs::create_directories(s.path("locked"));
  ::chmod(s.path("locked").c_str(), 0555);
  check_locked("", "locked");  // whoever runs the tests, root included
  CHECK(no_leftovers(s));
  std::string why;
  if (const std::optional<std::string> prefix = unprivileged_prefix(why)) {
    // The scratch folder becomes the unprivileged user's (its inputs readable, ok.* creatable);
    // "rootonly" stays root's, mode 0755: writable by its mode bits, but not by that user.
    fs::create_directories(s.path("rootonly"));
    if (is_root()) {
      for (const auto& e : fs::recursive_directory_iterator(s.dir()))
        if (e.path().filename() != "rootonly") REQUIRE(::lchown(e.path().c_str(), 65534, 65534) == 0);
      REQUIRE(::chown(s.dir().c_str(), 65534, 65534) == 0);
      REQUIRE(::chmod(s.dir().c_str(), 0755) == 0);
      REQUIRE(::chmod(s.path("rootonly").c_str(), 0755) == 0);
      REQUIRE(run_with(*prefix, s.dir(), "run a.yaml -q --output /dev/null").status == 0);  // it can read
    } else {
      ::chmod(s.path("rootonly").c_str(), 0555);  // the best an unprivileged test can do
    }
    check_locked(*prefix, "locked");
    check_locked(*prefix, "rootonly");
  } else {
    WARN("class 2, a folder where nothing can be created, as an unprivileged user: not run: " << why);
  }
  CHECK(no_leftovers(s));
}

TEST_CASE("class 2, an interrupted command leaves the old outputs or the new, never a mix: "
          "every command, Ctrl-C before and during the final commit") {
  Scratch s("class2int");
  s.write("a.yaml", kSmallScene);
  flex_files(s);
  const std::string study = "study a.yaml -q --engines kane --integrators rk4 --dts 0.05 --repeat 1 ";
  const std::string stab = "stability a.yaml -q --engines kane --integrators rk4 --dts 0.05 "
                           "--vary hinge.rate --values 0.1,0.2 ";
  REQUIRE(run_in(s.dir(), "verify a.yaml -q --shard 0/1 --part p.json").status == 0);
  REQUIRE(run_in(s.dir(), study + "--shard 0/1 --part q.json").status == 0);
  REQUIRE(run_in(s.dir(), "converge s.yaml -q --shard 0/1 --part c.json").status == 0);
  struct Case {
    std::string args;
    std::vector<std::string> files;    // output files (old content "OLD <name>" planted)
    std::vector<std::string> reports;  // report folders: their marker file gets an "old" key
    std::string kind;                  // the report's kind ("study", "stability", "" verify)
  };
  const std::vector<Case> cases = {
      {"run a.yaml -q --output o.csv", {"o.csv"}, {}, ""},
      {"compare a.yaml -q --json o.json", {"o.json"}, {}, ""},
      {"verify a.yaml -q --json o.json --junit o.xml", {"o.json", "o.xml"}, {}, ""},
      {"verify a.yaml -q --json o.json --junit o.xml --report=R", {"o.json", "o.xml"}, {"R"}, ""},
      {"verify a.yaml -q --shard 0/1 --part o.part", {"o.part"}, {}, ""},
      {"converge s.yaml -q --json o.json", {"o.json"}, {}, ""},
      {study + "--csv o.csv --report R", {"o.csv"}, {"R"}, "study"},
      {stab + "--csv o.csv --report R", {"o.csv"}, {"R"}, "stability"},
      {"merge p.json -q --json o.json --junit o.xml --report=R", {"o.json", "o.xml"}, {"R"}, ""},
      {"merge q.json -q --csv o.csv --report=R", {"o.csv"}, {"R"}, "study"},
      {"merge c.json -q --json o.json", {"o.json"}, {}, ""},
      {"converge s.yaml -q --shard 0/1 --part o.part", {"o.part"}, {}, ""},
      {stab + "--shard 0/1 --part o.part", {"o.part"}, {}, ""},
      {study + "--shard 0/1 --part o.part", {"o.part"}, {}, ""},
      {"draw a.yaml --no-motion -o o.png --geometry o.geometry.json", {"o.png", "o.geometry.json"}, {}, ""},
      {"linearize a.yaml --jacobian-only --json o.json --csv O --report R",
       {"o.json", "O/states.csv", "O/kane.A.csv", "O/newton-euler.own_A.csv"}, {"R"}, "linearize"},
      {"linearize a.yaml --jacobian-only --vary hinge.rate --values 0.1,0.2 --json o.json --csv O --report R",
       {"o.json", "O/root_locus.csv"}, {"R"}, "linearize"},
  };
  for (const Case& c : cases) {
    INFO(c.args);
    // A first, complete run makes the outputs (and report folders crossdyn accepts again).
    for (const std::string& f : c.files) fs::remove(s.path(f));
    for (const std::string& d : c.reports) fs::remove_all(s.path(d));
    const Run first = run_in(s.dir(), c.args);
    INFO(first.err);
    REQUIRE(first.status == 0);
    // "report": Ctrl-C while the report (or drawing) script runs, the issue's example.
    const bool script = !c.reports.empty() || contains(c.args, "draw ");
    for (const char* phase : {"report", "before-commit", "during-commit"}) {
      if (!script && std::string(phase) == "report") continue;
      INFO(phase);
      // Plant recognisable old outputs.
      for (const std::string& f : c.files) s.write(f, "OLD " + f);
      for (const std::string& d : c.reports) {
        const std::string marker = c.kind.empty() ? "summary.json" : c.kind + ".json";
        fs::remove_all(s.path(d));
        s.write(d + "/" + marker, "{\"tool\": \"crossdyn\", \"kind\": \"" +
                                      (c.kind.empty() ? std::string("verify") : c.kind) + "\", \"old\": true}\n");
        s.write(d + "/old.html", "old page");
        s.write(d + "/notes.txt", "the user's notes");
      }
      const std::string env = "CROSSDYN_TEST_INTERRUPT_AT=" + std::string(phase) + " ";
      const std::string cmd = "cd " + quote(s.dir().string()) + " && " + env +
                              quote(crossdyn_binary()) + " " + c.args + " > /dev/null 2> err.txt";
      const int raw = std::system(cmd.c_str());
      const int status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
      INFO(read_file(s.path("err.txt")));
      CHECK(status == 130);
      const bool old = std::string(phase) != "during-commit";
      for (const std::string& f : c.files) {
        INFO(f);
        CHECK((read_file(s.path(f)) == "OLD " + f) == old);
      }
      for (const std::string& d : c.reports) {
        const std::string marker = c.kind.empty() ? "summary.json" : c.kind + ".json";
        INFO(d);
        CHECK(contains(read_file(s.path(d + "/" + marker)), "\"old\": true") == old);
        CHECK(fs::exists(s.path(d + "/old.html")) == old);
        CHECK(read_file(s.path(d + "/notes.txt")) == "the user's notes");  // carried over
        CHECK(fs::exists(s.path(d + "/index.html")) != old);
      }
      CHECK(no_leftovers(s));
    }
  }
}

TEST_CASE("class 2, a command that fails (exit 3) replaces none of its outputs") {
  Scratch s("class2fail");
  s.write("a.yaml", kSmallScene);
  struct Case {
    std::string args;
    std::vector<std::string> files;
    std::string report;  // "" or a study report folder
  };
  // --max-steps 1: the runs (and study's reference runs, a.yaml has no analytic solution) fail.
  const std::vector<Case> cases = {
      {"run a.yaml -q --max-steps 1 --output o.csv", {"o.csv"}, ""},
      {"study a.yaml -q --engines kane --integrators rk4 --dts 0.05 --repeat 1 --max-steps 1 "
       "--csv o.csv --report R", {"o.csv"}, "R"},
  };
  for (const Case& c : cases) {
    INFO(c.args);
    for (const std::string& f : c.files) s.write(f, "OLD " + f);
    if (!c.report.empty())
      s.write(c.report + "/study.json", "{\"tool\": \"crossdyn\", \"kind\": \"study\", \"old\": true}\n");
    const Run r = run_in(s.dir(), c.args);
    INFO(r.err);
    CHECK(r.status == 3);
    for (const std::string& f : c.files) CHECK(read_file(s.path(f)) == "OLD " + f);
    if (!c.report.empty()) {
      CHECK(contains(read_file(s.path(c.report + "/study.json")), "\"old\": true"));
      CHECK(!fs::exists(s.path(c.report + "/index.html")));
    }
    CHECK(no_leftovers(s));
  }
}
