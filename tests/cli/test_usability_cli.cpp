// What a new user meets (issue 9, "Rough edges"): scene names without a path, why a scene cannot
// be opened, `crossdyn list`, `--version`, "did you mean" for mistyped options and commands, and
// compare's table: failures first, 100 columns.
#include <catch2/catch.hpp>

#include "core/scene/scene.hpp"
#include "tests/cli/cli_helpers.hpp"

#include <sys/socket.h>
#include <sys/un.h>

#include <regex>

using namespace crossdyn::test;

namespace {

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> v;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) v.push_back(l);
  return v;
}

}  // namespace

TEST_CASE("scene names: looked up in ./scenarios, then in the source tree's scenarios/") {
  Scratch s("names");
  // No scenarios/ here: the source tree's gimbal_lock.
  Run r = run_in(s.dir(), "run gimbal_lock --duration 0.1");
  INFO(r.err);
  CHECK(r.status == 0);
  CHECK(r.out.rfind("t,body.wx", 0) == 0);
  CHECK(run_in(s.dir(), "run gimbal_lock.yaml --duration 0.1").status == 0);
  CHECK(run_in(s.dir(), "compare torque_free_asymmetric --engines kane,lagrange").status == 0);
  // A local scenarios/ comes first, *.yml too.
  s.write("scenarios/gimbal_lock.yml", kSmallScene);
  r = run_in(s.dir(), "run gimbal_lock");
  CHECK(r.status == 0);
  CHECK(r.out.rfind("t,hub.wx", 0) == 0);
  // Not found anywhere: every path tried.
  r = run_in(s.dir(), "run no_such_scene");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "cannot find the scene 'no_such_scene': no such file; tried"));
  CHECK(contains(r.err, "scenarios/no_such_scene.yaml"));
  CHECK(contains(r.err, source_dir() + "/scenarios/no_such_scene.yml"));
  CHECK(contains(r.err, "crossdyn list"));
}

TEST_CASE("a scene that cannot be opened says why, with the path tried") {
  Scratch s("reasons");
  s.write("scene.yaml", kSmallScene);
  fs::create_directories(s.dir() / "folder.yaml");
  fs::create_symlink("loop2.yaml", s.dir() / "loop1.yaml");
  fs::create_symlink("loop1.yaml", s.dir() / "loop2.yaml");
  fs::create_symlink("gone.yaml", s.dir() / "dangling.yaml");
  const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::string sock = s.path("sock.yaml");
  const bool have_socket = sock.size() < sizeof addr.sun_path;
  if (have_socket) {
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", sock.c_str());
    REQUIRE(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0);
  }
  std::vector<std::pair<std::string, std::string>> cases{
      {"./missing.yaml", "no such file"},
      {"folder.yaml", "it is a directory, not a scene file"},
      {"loop1.yaml", "too many levels of symbolic links (a symbolic link loop)"},
      {"dangling.yaml", "it is a symbolic link to a file that does not exist"},
      {"scene.yaml/x.yaml", "a part of the path is not a folder"}};
  if (have_socket) cases.push_back({"sock.yaml", "it is a socket, not a regular file"});
  if (!is_root()) {  // root reads any file
    const std::string locked = s.write("locked.yaml", kSmallScene);
    ::chmod(locked.c_str(), 0);
    cases.push_back({"locked.yaml", "permission denied"});
  }
  for (const char* command : {"run", "compare"})
    for (const auto& [path, why] : cases) {
      const Run r = run_in(s.dir(), std::string(command) + " " + path);
      INFO(command << " " << path << ": " << r.err);
      CHECK(r.status == 2);
      CHECK(contains(r.err, path + ":1:1: cannot open the scene file: " + why));
    }
  ::close(fd);
  // A FIFO is read like a file (`crossdyn run <(...)`). A FIFO without a writer is an empty scene
  // at once (nothing blocks): when the machine is loaded, crossdyn may open the FIFO before the
  // background writer does, see an empty scene (exit 2), and leave the writer blocked in its
  // open. That attempt frees the writer (a reader of its own) and tries again; the writer always
  // ends, so the test never waits on it (it hung 600 s under load before).
  REQUIRE(::mkfifo(s.path("fifo.yaml").c_str(), 0644) == 0);
  const int raw = std::system(("cd " + quote(s.dir().string()) +
                               " && for i in $(seq 50); do { cat scene.yaml > fifo.yaml & } ; w=$!; " +
                               "sleep 0.05; " + quote(crossdyn_binary()) +
                               " run fifo.yaml > fifo.csv; st=$?; " +
                               "if [ $st -ne 0 ]; then timeout 10 cat fifo.yaml > /dev/null; fi; " +
                               "wait $w; echo $st > status; [ $st -eq 0 ] && break; done; true")
                                  .c_str());
  CHECK(WEXITSTATUS(raw) == 0);
  CHECK(read_file(s.path("status")) == "0\n");
  CHECK(read_file(s.path("fifo.csv")).rfind("t,hub.wx", 0) == 0);
}

TEST_CASE("crossdyn list shows every scene with its one-line description, in 100 columns") {
  const Run r = run_in(source_dir(), "list");
  INFO(r.err);
  CHECK(r.status == 0);
  for (const std::string& path : committed_scenes()) {
    const std::string name = fs::path(path).stem().string();
    const crossdyn::System s = crossdyn::read_scene(path);
    const std::string words = s.description.substr(0, 20);
    bool found = false;
    for (const std::string& line : lines_of(r.out))
      if (line.rfind("  " + name + " ", 0) == 0) {
        found = true;
        std::string flat = words;
        for (char& c : flat) c = c == '\n' ? ' ' : c;
        CHECK(contains(line, flat));
      }
    INFO(name);
    CHECK(found);
  }
  for (const std::string& line : lines_of(r.out)) CHECK(line.size() <= 100);
  // A scene that cannot be read is listed with the reason; the status says so.
  Scratch s("list");
  s.write("scenes/good.yaml", kSmallScene);
  s.write("scenes/bad.yml", "name: [\n");
  const Run b = run_in(s.dir(), "list --scenarios scenes");
  CHECK(b.status == 2);
  CHECK(contains(b.out, "  good  A hub and a panel on a hinge, for command-line tests."));
  CHECK(contains(b.out, "  bad   cannot be read: scenes/bad.yml:"));
}

TEST_CASE("crossdyn --version prints the project version of CMakeLists.txt") {
  const std::string cmake = read_file(source_dir() + "/CMakeLists.txt");
  std::smatch m;
  REQUIRE(std::regex_search(cmake, m, std::regex(R"(project\(crossdyn VERSION ([0-9.]+))")));
  const Run r = run_in(source_dir(), "--version");
  CHECK(r.status == 0);
  CHECK(r.out.rfind("crossdyn " + m[1].str(), 0) == 0);
}

TEST_CASE("mistyped options and commands get a \"did you mean\": exit status 2") {
  const std::string scene = quote(source_dir() + "/scenarios/spear1_case1.yaml");
  struct Case {
    std::string args, message;
  };
  const std::vector<Case> cases{
      {"compare " + scene + " --engine kane", "compare: unknown option '--engine' (did you mean '--engines'?)"},
      {"compare --engine kane " + scene, "compare: unknown option '--engine' (did you mean '--engines'?)"},
      {"run " + scene + " --enigne kane", "run: unknown option '--enigne' (did you mean '--engine'?)"},
      {"run " + scene + " --engines kane", "run: unknown option '--engines' (did you mean '--engine'?)"},
      {"run " + scene + " --outptu x.csv", "run: unknown option '--outptu' (did you mean '--output'?)"},
      {"run " + scene + " --output_step=0.1", "run: unknown option '--output_step' (did you mean '--output-step'?)"},
      {"verify --junt x.xml", "verify: unknown option '--junt' (did you mean '--junit'?)"},
      {"verify --alow-no-comparison", "verify: unknown option '--alow-no-comparison' (did you mean '--allow-no-comparison'?)"},
      {"lsit", "unknown command 'lsit' (did you mean 'list'?)"},
      {"comapre " + scene, "unknown command 'comapre' (did you mean 'compare'?)"},
      {"run " + scene + " --frobnicate", "run: unknown option '--frobnicate'\n"}};
  for (const Case& c : cases) {
    const Run r = run_in(source_dir(), c.args);
    INFO(c.args << "\n" << r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, "crossdyn: error: " + c.message));
    CHECK(r.out.empty());
  }
}

TEST_CASE("compare's table: failures first, worst first, and every line within 100 columns") {
  // A copy of kane with 1 % more inertia: many failures among many passes, and long labels.
  const Run r = run_in(source_dir(), "compare spear1_case1 --test-inertia-scale kane=1.01");
  CHECK(r.status == 1);
  const auto lines = lines_of(r.out);
  for (const std::string& line : lines) {
    INFO(line);
    CHECK(line.size() <= 100);
  }
  // The check rows: from the header "quantity ..." to the first empty line.
  std::size_t k = 0;
  while (k < lines.size() && lines[k].rfind("quantity ", 0) != 0) ++k;
  REQUIRE(k < lines.size());
  std::vector<std::string> rows;
  for (k += 2; k < lines.size() && !lines[k].empty(); ++k) rows.push_back(lines[k]);
  REQUIRE(rows.size() > 20);
  auto result = [](const std::string& row) { return row.substr(row.find_last_not_of(' ') - 3, 4); };
  auto ratio = [](const std::string& row) {
    std::istringstream in(row);
    std::vector<std::string> f;
    for (std::string w; in >> w;) f.push_back(w);
    return std::stod(f[f.size() - 2]);
  };
  std::size_t fails = 0;
  while (fails < rows.size() && result(rows[fails]) == "FAIL") ++fails;
  CHECK(fails > 0);
  for (std::size_t i = fails; i < rows.size(); ++i) CHECK(result(rows[i]) != "FAIL");
  for (std::size_t i = 1; i < fails; ++i) CHECK(ratio(rows[i - 1]) >= ratio(rows[i]));
  // --failures lists the failures only.
  const Run f = run_in(source_dir(), "compare spear1_case1 --failures --test-inertia-scale kane=1.01");
  CHECK(f.status == 1);
  CHECK_FALSE(contains(f.out, "PASS\n"));
}
