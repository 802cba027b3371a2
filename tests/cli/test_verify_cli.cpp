// crossdyn verify as a user and a CI job see it (issue 9): the verdict never depends on the
// report; Ctrl-C during the report is 130; *.yml scenes count; a run that compares nothing fails;
// only the installed report script runs; one scene's failure never stops the others.
#include <catch2/catch.hpp>

#include "tests/cli/cli_helpers.hpp"

#include <nlohmann/json.hpp>

#include <regex>
#include <sstream>
#include <string>

using namespace crossdyn::test;

namespace {

int sh(const std::string& script) {
  const int raw = std::system(("bash -c " + quote(script)).c_str());
  return WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
}

std::string executable(const Scratch& s, const std::string& name, const std::string& text) {
  const std::string p = s.write(name, text);
  ::chmod(p.c_str(), 0755);
  return p;
}

}  // namespace

TEST_CASE("verify: the verdict, table, JSON and JUnit come first and never depend on the report") {
  Scratch s("report_fails");
  s.write("scene.yaml", kSmallScene);
  s.write("a_file", "not a folder\n");
  executable(s, "nomatplotlib.sh",
             "#!/bin/sh\necho \"ModuleNotFoundError: No module named 'matplotlib'\" >&2\nexit 1\n");
  executable(s, "failing.py", "#!/bin/sh\nexit 7\n");
  struct Case {
    std::string options, why;
  };
  // (--report naming a file, or a --python that is missing, a folder or not executable, is
  // refused before the work, exit 2: tests/cli/test_output_classes.cpp.)
  const std::vector<Case> cases{
      {"--report=out --python ./nomatplotlib.sh", "failed (exit status 1)"},   // no matplotlib
      {"--report=out --python /bin/sh --report-script failing.py", "failed (exit status 7)"}};
  for (const bool fail : {false, true})
    for (const Case& c : cases) {
      fs::remove_all(s.dir() / "j.json");
      fs::remove_all(s.dir() / "u.xml");
      const std::string wrong = fail ? " --test-inertia-scale kane=1.01" : "";
      const Run r = run_in(s.dir(), "verify scene.yaml -q --json j.json --junit u.xml " + c.options + wrong);
      INFO(c.options << wrong << "\n" << r.out << r.err);
      CHECK(r.status == (fail ? 1 : 0));  // the comparison's verdict, whatever the report did
      CHECK(contains(r.out, fail ? "FAIL" : "PASS"));
      CHECK(contains(r.out, "checks:"));
      CHECK(contains(r.out, "report: NOT WRITTEN"));
      CHECK(contains(r.err, "crossdyn: report not written: "));
      CHECK(contains(r.err, c.why));
      CHECK(nlohmann::json::parse(read_file(s.path("j.json")))["passed"] == !fail);
      CHECK(contains(read_file(s.path("u.xml")), "<testsuites"));
    }
}

TEST_CASE("verify: the summary table's cells are numbers, FAIL marks a failing group, lines fit 130 columns") {
  Scratch s("table_cells");
  s.write("scene.yaml", kSmallScene);
  for (const bool fail : {false, true}) {
    const Run r = run_in(s.dir(), std::string("verify scene.yaml -q") +
                                      (fail ? " --test-inertia-scale kane=1.01" : ""));
    INFO(r.out << r.err);
    CHECK(r.status == (fail ? 1 : 0));
    std::istringstream lines(r.out);
    std::string line, row;
    bool table = true;  // the table and its legend; the failure lines after it are prose
    while (std::getline(lines, line)) {
      if (line.rfind("cells:", 0) == 0) table = false;
      if (table) CHECK(line.size() <= 130);
      if (line.rfind("small ", 0) == 0) row = line;
    }
    REQUIRE_FALSE(row.empty());  // the scene's row
    CHECK(std::regex_search(row, std::regex(" [0-9]e[-+][0-9][0-9] ")));  // a group's worst error
    CHECK(contains(row, "FAIL ") == fail);                                      // a failing group's cell
    CHECK(row.substr(row.size() - 4) == (fail ? "FAIL" : "PASS"));             // the scene's result
  }
}

TEST_CASE("verify: Ctrl-C during the report ends the script and the command with status 130") {
  Scratch s("report_sigint");
  s.write("scene.yaml", kSmallScene);
  // A report "script" that says it started, then takes 60 s.
  s.write("slow.sh", "touch started\nexec sleep 60\n");
  const int rc = sh("cd " + quote(s.dir().string()) + " || exit 1; " + quote(crossdyn_binary()) +
                    " verify scene.yaml -q --json j.json --report=out --python /bin/sh"
                    " --report-script slow.sh > out.txt 2> err.txt & pid=$!;"
                    " for i in $(seq 600); do [ -e started ] && break; sleep 0.05; done;"
                    " kill -INT $pid; wait $pid; echo $? > status");
  CHECK(rc == 0);
  INFO(read_file(s.path("err.txt")));
  CHECK(read_file(s.path("status")) == "130\n");
  CHECK(contains(read_file(s.path("out.txt")), "PASS"));  // the verdict was already printed
  CHECK(contains(read_file(s.path("err.txt")), "interrupted"));
  // Issue 23 class 2: the outputs are committed together at the end, so an interrupt during the
  // report leaves the old ones (here: none) and no temporaries or staging folders.
  CHECK_FALSE(fs::exists(s.dir() / "j.json"));
  CHECK_FALSE(fs::exists(s.dir() / "out"));
  for (const auto& e : fs::directory_iterator(s.dir())) {
    INFO(e.path());
    CHECK_FALSE(contains(e.path().filename().string(), ".crossdyn-"));
    CHECK_FALSE(contains(e.path().filename().string(), ".partial-"));
  }
}

TEST_CASE("verify: *.yml scenes are verified like *.yaml: hidden files and others are not") {
  Scratch s("yml");
  s.write("scenes/a.yaml", kSmallScene);
  std::string b = kSmallScene;
  b.replace(b.find("name: small"), 11, "name: small_yml");
  s.write("scenes/b.yml", b);
  s.write("scenes/.#lock.yaml", "not a scene");
  s.write("scenes/notes.txt", "not a scene");
  const Run r = run_in(s.dir(), "verify --scenarios scenes -q --json j.json");
  INFO(r.out << r.err);
  CHECK(r.status == 0);
  CHECK(contains(r.out, "small_yml"));
  CHECK(contains(r.out, "2 scenes"));
}

TEST_CASE("verify and compare fail when nothing is compared, unless --allow-no-comparison") {
  Scratch s("nothing");
  s.write("scene.yaml", kSmallScene);
  std::string excluded = kSmallScene;
  excluded += "compare:\n  exclude:\n";
  for (const char* q : {"w", "attitude", "angle", "rate", "position", "load", "H", "E"})
    excluded += std::string("    - {quantity: ") + q + ", reason: test}\n";
  s.write("excluded.yaml", excluded);
  struct Case {
    std::string args, why;
  };
  for (const Case& c : {Case{"scene.yaml --engines kane", "only kane finished"},
                        Case{"excluded.yaml", "the scene excludes every compared quantity"}}) {
    Run r = run_in(s.dir(), "compare " + c.args + " --json c.json");
    INFO(c.args << "\n" << r.out << r.err);
    CHECK(r.status == 1);
    CHECK(contains(r.out, "nothing was compared: " + c.why));
    CHECK(nlohmann::json::parse(read_file(s.path("c.json")))["passed"] == false);
    r = run_in(s.dir(), "verify -q " + c.args + " --json v.json --junit v.xml");
    CHECK(r.status == 1);
    CHECK(contains(r.out, "nothing was compared: " + c.why));
    CHECK(contains(read_file(s.path("v.xml")), "nothing was compared"));
    // Asked for explicitly: accepted, with a note.
    r = run_in(s.dir(), "compare " + c.args + " --allow-no-comparison");
    CHECK(r.status == 0);
    CHECK(contains(r.out, "nothing was compared (" + c.why));
    CHECK(contains(r.out, "accepted by"));
    CHECK(run_in(s.dir(), "verify -q " + c.args + " --json v.json --allow-no-comparison").status == 0);
  }
}

TEST_CASE("verify --report runs the installed report script, never one beside the scenes") {
  Scratch s("bundle");
  // A downloaded bundle: scenes, and a reports/make_report.py that must never run.
  s.write("bundle/scenarios/small.yaml", kSmallScene);
  s.write("bundle/reports/make_report.py", "open('pwned', 'w').write('ran')\n");
  // A stand-in for Python that records which script it was asked to run.
  const std::string py = executable(s, "python.sh", "#!/bin/sh\necho \"$1\" > " + s.path("ran_script") + "\n");
  for (const std::string& where : {s.path("bundle"), s.dir().string()}) {
    const std::string scenes = where == s.dir().string() ? " --scenarios bundle/scenarios" : "";
    const Run r = run_in(where, "verify -q" + scenes + " --report=out --python " + quote(py));
    INFO(r.out << r.err);
    CHECK(r.status == 0);
    CHECK(read_file(s.path("ran_script")) == source_dir() + "/reports/make_report.py\n");
    CHECK_FALSE(fs::exists(fs::path(where) / "pwned"));
    fs::remove(s.path("ran_script"));
  }
  // --report-script names another script explicitly.
  s.write("mine.py", "");
  const Run r = run_in(s.path("bundle"), "verify -q --report=out --python " + quote(py) +
                                             " --report-script " + quote(s.path("mine.py")));
  CHECK(r.status == 0);
  CHECK(read_file(s.path("ran_script")) == s.path("mine.py") + "\n");
}

TEST_CASE("verify: a scene that cannot be read is reported with its reason and the others run") {
  Scratch s("broken_scenes");
  s.write("scenes/good.yaml", kSmallScene);
  s.write("scenes/malformed.yaml", "name: [unclosed\n");
  fs::create_symlink("loop_b.yaml", s.dir() / "scenes/loop_a.yaml");
  fs::create_symlink("loop_a.yaml", s.dir() / "scenes/loop_b.yaml");
  fs::create_symlink("gone.yaml", s.dir() / "scenes/dangling.yaml");
  fs::create_directories(s.dir() / "scenes/folder.yaml");
  const Run r = run_in(s.dir(), "verify --scenarios scenes -q --json j.json --junit u.xml");
  INFO(r.out << r.err);
  CHECK(r.status == 2);  // not 134: nothing aborts
  CHECK(contains(r.out, "6 scenes"));
  CHECK(contains(r.out, "small "));
  CHECK(contains(r.out, "symbolic link loop"));
  CHECK(contains(r.out, "a symbolic link to a file that does not exist"));
  CHECK(contains(r.out, "it is a directory, not a scene file"));
  CHECK(contains(r.out, "malformed.yaml:"));
  const auto j = nlohmann::json::parse(read_file(s.path("j.json")));
  CHECK(j["counts"]["scenes_unreadable"] == 5);
  // The folder itself: missing, a file, a symbolic link loop, unreadable.
  fs::create_symlink("loopdir_b", s.dir() / "loopdir_a");
  fs::create_symlink("loopdir_a", s.dir() / "loopdir_b");
  for (const auto& [dir, why] : {std::pair<std::string, std::string>{"nowhere", "does not exist"},
                                 {"scenes/good.yaml", "is not a folder"},
                                 {"loopdir_a", "Too many levels of symbolic links"}}) {
    const Run f = run_in(s.dir(), "verify -q --json j.json --scenarios " + dir);
    INFO(dir << ": " << f.err);
    CHECK(f.status == 2);
    CHECK(contains(f.err, why));
  }
  if (!is_root()) {  // root reads any folder
    ::chmod(s.path("scenes").c_str(), 0);
    const Run f = run_in(s.dir(), "verify -q --json j.json --scenarios scenes");
    CHECK(f.status == 2);
    CHECK(contains(f.err, "Permission denied"));
  }
}
