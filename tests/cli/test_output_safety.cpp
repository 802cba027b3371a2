// Nothing lost (issue 9, "Data loss"): an output never overwrites an input, whatever its spelling;
// special files are written in place; symbolic links are followed; read-only files are refused;
// temporaries are exclusive, recognisable and cleaned up; every write is checked.
#include <catch2/catch.hpp>

#include "core/output.hpp"
#include "tests/cli/cli_helpers.hpp"

#include <sys/socket.h>
#include <sys/un.h>

#include <set>

using namespace crossdyn::test;

namespace {

std::set<std::string> listing(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

// A pid that is certainly not running: a child that has exited and been reaped.
long dead_pid() {
  const pid_t pid = ::fork();
  if (pid == 0) ::_exit(0);
  int st = 0;
  ::waitpid(pid, &st, 0);
  return pid;
}

int sh(const std::string& script) {
  const int raw = std::system(("bash -c " + quote(script)).c_str());
  return WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
}

}  // namespace

TEST_CASE("an output is never an input: every output option of every command, by file identity") {
  Scratch s("same");
  const std::string scene = s.write("scene.yaml", kSmallScene);
  fs::create_symlink("scene.yaml", s.dir() / "link.yaml");
  fs::create_hard_link(scene, s.dir() / "hard.yaml");
  fs::create_directories(s.dir() / "sub");
  const std::set<std::string> before = listing(s.dir());
  // The same file, spelled five ways: as given, through '.', '..', a symbolic link, a hard link.
  const std::vector<std::string> spellings{"scene.yaml", "./scene.yaml", "sub/../scene.yaml",
                                           "link.yaml", "hard.yaml", scene};
  const std::vector<std::pair<std::string, std::string>> commands{
      {"run scene.yaml -o ", "--output"},
      {"compare scene.yaml --json ", "--json"},
      {"verify scene.yaml --json ", "--json"},
      {"verify scene.yaml --junit ", "--junit"},
      {"verify scene.yaml --json x.json --junit ", "--junit"}};
  for (const auto& [command, option] : commands)
    for (const std::string& out : spellings) {
      const Run r = run_in(s.dir(), command + quote(out));
      INFO(command << out << "\n" << r.err);
      CHECK(r.status == 2);
      CHECK(contains(r.err, option + " '" + out + "' is the same file as the scene file"));
      CHECK(read_file(scene) == kSmallScene);
      CHECK(listing(s.dir()) == before);  // no temporary, no JSON, nothing else written
    }
  // Standard output appended to the scene (`>> scene.yaml`), for each command.
  for (const char* command : {"run scene.yaml", "compare scene.yaml", "verify scene.yaml --json x.json", "list --scenarios ."}) {
    const Run r = run_in(s.dir(), command, ">> link.yaml");
    INFO(command << "\n" << r.err);
    if (std::string(command).rfind("list", 0) == 0) continue;  // list reads scenes, writes no file
    CHECK(r.status == 2);
    CHECK(contains(r.err, "standard output is the same file as the scene file"));
    CHECK(read_file(scene) == kSmallScene);
  }
  // Two outputs naming one file.
  const Run r = run_in(s.dir(), "verify scene.yaml --json out.xml --junit ./out.xml");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "are the same file"));
  CHECK_FALSE(fs::exists(s.dir() / "out.xml"));
}

TEST_CASE("the report folder must not hold an input: a scene or the report script") {
  Scratch s("reportdir");
  const std::string in_data = s.write("rep/data/small.yaml", kSmallScene);
  const std::string named_like_output = s.write("rep2/summary.json", kSmallScene);
  for (const auto& [scene, dir] : {std::pair{in_data, std::string("rep")},
                                   std::pair{named_like_output, std::string("rep2")},
                                   std::pair{in_data, std::string(".")}}) {
    const Run r = run_in(s.dir(), "verify " + quote(scene) + " --report=" + dir);
    INFO(r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, "--report '" + dir + "' holds the scene file"));
    CHECK(read_file(scene) == kSmallScene);
  }
  // The report script is an input too: no output may replace it.
  const std::string script = s.write("tools/make_report.py", "print('report')\n");
  s.write("scene.yaml", kSmallScene);
  Run r = run_in(s.dir(), "verify scene.yaml --report=out --report-script tools/make_report.py --json tools/make_report.py");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "is the same file as the report script"));
  r = run_in(s.dir(), "verify scene.yaml --report=tools --report-script tools/make_report.py");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "holds the report script"));
  CHECK(read_file(script) == "print('report')\n");
}

TEST_CASE("special files are written in place: /dev/null stays a device, a FIFO gets the CSV") {
  Scratch s("special");
  s.write("scene.yaml", kSmallScene);
  Run r = run_in(s.dir(), "run scene.yaml -o /dev/null");
  CHECK(r.status == 0);
  struct stat st {};
  REQUIRE(::stat("/dev/null", &st) == 0);
  CHECK(S_ISCHR(st.st_mode));  // as root the old code renamed a regular file over it
  const std::string expected = run_in(s.dir(), "run scene.yaml").out;
  REQUIRE(contains(expected, "t,hub.wx"));
  // '-', /dev/stdout and /dev/fd/1 are standard output, written through its descriptor (so an
  // appending redirection keeps what was there).
  CHECK(run_in(s.dir(), "run scene.yaml -o -").out == expected);
  CHECK(run_in(s.dir(), "run scene.yaml -o /dev/stdout").out == expected);
  s.write("appended.csv", "before\n");
  CHECK(run_in(s.dir(), "run scene.yaml -o /dev/fd/1", ">> appended.csv").status == 0);
  CHECK(read_file(s.path("appended.csv")) == "before\n" + expected);
  // A FIFO: crossdyn waits for the reader, then writes the whole CSV into it.
  REQUIRE(::mkfifo(s.path("fifo").c_str(), 0644) == 0);
  const int rc = sh("cd " + quote(s.dir().string()) + " && { cat fifo > got & } && " +
                    quote(crossdyn_binary()) + " run scene.yaml -o fifo && wait");
  CHECK(rc == 0);
  CHECK(read_file(s.path("got")) == expected);
  REQUIRE(::lstat(s.path("fifo").c_str(), &st) == 0);
  CHECK(S_ISFIFO(st.st_mode));
  // A FIFO whose reader goes away after 100 bytes: a write error (exit 3), not a silent success.
  const int rc2 = sh("cd " + quote(s.dir().string()) + " && { head -c 100 fifo > /dev/null & } && " +
                     quote(crossdyn_binary()) + " run scene.yaml --duration 50 -o fifo 2> err; echo $? > status; wait");
  CHECK(rc2 == 0);
  CHECK(read_file(s.path("status")) == "3\n");
  CHECK(contains(read_file(s.path("err")), "cannot write 'fifo': Broken pipe"));
}

TEST_CASE("symbolic links are followed: the target is replaced atomically and the link stays") {
  Scratch s("links");
  s.write("scene.yaml", kSmallScene);
  const std::string expected = run_in(s.dir(), "run scene.yaml").out;
  s.write("data/out.csv", "old\n");
  fs::create_symlink("data/out.csv", s.dir() / "link.csv");
  fs::create_symlink("link.csv", s.dir() / "link2.csv");    // a chain of two links
  fs::create_symlink("data/new.csv", s.dir() / "dangling.csv");
  for (const char* link : {"link.csv", "link2.csv"}) {
    s.write("data/out.csv", "old\n");
    const Run r = run_in(s.dir(), std::string("run scene.yaml -o ") + link);
    CHECK(r.status == 0);
    CHECK(fs::is_symlink(s.dir() / link));
    CHECK(read_file(s.path("data/out.csv")) == expected);
    CHECK(listing(s.dir() / "data") == std::set<std::string>{"out.csv"});
  }
  Run r = run_in(s.dir(), "run scene.yaml -o dangling.csv");  // creates the file it points to
  CHECK(r.status == 0);
  CHECK(fs::is_symlink(s.dir() / "dangling.csv"));
  CHECK(read_file(s.path("data/new.csv")) == expected);
  // A loop is refused before anything runs.
  fs::create_symlink("loop_b", s.dir() / "loop_a");
  fs::create_symlink("loop_a", s.dir() / "loop_b");
  r = run_in(s.dir(), "run scene.yaml -o loop_a");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "symbolic link loop"));
  CHECK(r.out.empty());
}

TEST_CASE("outputs that cannot be written are refused before the run: read-only, folders, sockets") {
  Scratch s("refused");
  s.write("scene.yaml", kSmallScene);
  // Read-only by its mode bits: refused for every user, root included (root could write it, but
  // the user protected it). This is the check made: no write bit at all in the file's mode.
  const std::string ro = s.write("ro.csv", "keep\n");
  ::chmod(ro.c_str(), 0444);
  Run r = run_in(s.dir(), "run scene.yaml -o ro.csv");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "cannot write --output 'ro.csv': the file is read-only (mode 0444)"));
  CHECK(read_file(ro) == "keep\n");
  r = run_in(s.dir(), "compare scene.yaml --json ro.csv");
  CHECK(r.status == 2);
  CHECK(r.out.empty());  // refused before the engines ran
  CHECK(read_file(ro) == "keep\n");
  // A read-only folder: refused by its mode bits for every user, root included, as files are.
  fs::create_directories(s.dir() / "locked");
  ::chmod(s.path("locked").c_str(), 0555);
  r = run_in(s.dir(), "run scene.yaml -o locked/out.csv");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "folder 'locked' is read-only (mode 0555)"));
  CHECK(fs::is_empty(s.path("locked")));
  ::chmod(s.path("locked").c_str(), 0755);
  // A folder, a missing folder, a socket, a block device: before the CSV header is written.
  fs::create_directories(s.dir() / "folder");
  r = run_in(s.dir(), "run scene.yaml -o folder");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "cannot write --output 'folder': it is a directory"));
  CHECK(r.out.empty());
  r = run_in(s.dir(), "run scene.yaml -o missing/out.csv");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "folder 'missing'"));
  const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::string sock = s.path("sock");
  if (sock.size() < sizeof addr.sun_path) {
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", sock.c_str());
    REQUIRE(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0);
    r = run_in(s.dir(), "run scene.yaml -o sock");
    CHECK(r.status == 2);
    CHECK(contains(r.err, "it is a socket"));
  }
  ::close(fd);
  // A replaced file keeps its mode.
  const std::string kept = s.write("mode.csv", "x\n");
  ::chmod(kept.c_str(), 0640);
  CHECK(run_in(s.dir(), "run scene.yaml -o mode.csv").status == 0);
  struct stat st {};
  REQUIRE(::stat(kept.c_str(), &st) == 0);
  CHECK((st.st_mode & 07777) == 0640);
}

TEST_CASE("temporaries are recognisable, removed on failure, and stale ones of dead runs cleaned") {
  Scratch s("temps");
  const std::string out = s.path("out.csv");
  {
    crossdyn::AtomicFile f(out);
    f.stream() << "partial";
    // The temporary: in the target's folder, named .<name>.crossdyn-<pid>-XXXXXX.tmp.
    const std::string prefix = crossdyn::temporary_prefix("out.csv", ::getpid());
    const std::string tmp = fs::path(f.temporary()).filename().string();
    CHECK(tmp.rfind(prefix, 0) == 0);
    CHECK(tmp.size() == prefix.size() + 6 + 4);
    CHECK(fs::path(f.temporary()).parent_path() == s.dir());
    CHECK(listing(s.dir()) == std::set<std::string>{tmp});
  }
  CHECK(fs::is_empty(s.dir()));  // abandoned: the temporary is gone
  // Stale temporaries: a dead process's is removed, a live one's (ours) and another name's kept.
  const long dead = dead_pid();
  const std::string stale = crossdyn::temporary_prefix("out.csv", dead) + "abcdef.tmp";
  const std::string live = crossdyn::temporary_prefix("out.csv", ::getpid()) + "abcdef.tmp";
  const std::string other = crossdyn::temporary_prefix("other.csv", dead) + "abcdef.tmp";
  for (const std::string& n : {stale, live, other}) s.write(n, "left behind\n");
  s.write("scene.yaml", kSmallScene);
  CHECK(run_in(s.dir(), "run scene.yaml -o out.csv").status == 0);
  const auto names = listing(s.dir());
  CHECK_FALSE(names.count(stale));
  CHECK(names.count(live));
  CHECK(names.count(other));
  if (is_root()) {  // another user's stale temporary is not ours to remove
    const std::string theirs = s.write(stale, "someone else's\n");
    REQUIRE(::chown(theirs.c_str(), 65534, 65534) == 0);
    CHECK(run_in(s.dir(), "run scene.yaml -o out.csv").status == 0);
    CHECK(fs::exists(theirs));
    fs::remove(theirs);
  }
  // A failed run leaves no temporary (and the old file as it was).
  s.write("out.csv", "previous\n");
  const Run r = run_in(s.dir(), "run scene.yaml -o out.csv --max-steps 2");
  CHECK(r.status == 3);
  CHECK(contains(r.err, "step limit reached"));
  CHECK(read_file(out) == "previous\n");
  CHECK(listing(s.dir()) == std::set<std::string>{"out.csv", "scene.yaml", live, other});
}

TEST_CASE("every write is checked: a full disk is exit 3 with the reason, for every output") {
  if (!fs::exists("/dev/full")) {
    WARN("no /dev/full on this machine: skipped");
    return;
  }
  Scratch s("full");
  s.write("scene.yaml", kSmallScene);
  struct Case {
    std::string args, redirect, message;
  };
  const std::string enospc = ": No space left on device";
  const std::vector<Case> cases{
      {"run scene.yaml", "> /dev/full", "cannot write standard output" + enospc},
      {"run scene.yaml -o /dev/full", "", "cannot write '/dev/full'" + enospc},
      {"compare scene.yaml", "> /dev/full", "cannot write standard output" + enospc},
      {"compare scene.yaml --json /dev/full", "", "cannot write '/dev/full'" + enospc},
      {"verify scene.yaml --json x.json", "> /dev/full", "cannot write standard output" + enospc},
      {"verify scene.yaml --json /dev/full", "", "cannot write '/dev/full'" + enospc},
      {"verify scene.yaml --json x.json --junit /dev/full", "", "cannot write '/dev/full'" + enospc},
      {"list --scenarios .", "> /dev/full", "cannot write standard output" + enospc},
      {"--help", "> /dev/full", "cannot write standard output" + enospc},
      {"run --help", "> /dev/full", "cannot write standard output" + enospc},
      {"--version", "> /dev/full", "cannot write standard output" + enospc}};
  for (const Case& c : cases) {
    const Run r = run_in(s.dir(), c.args, c.redirect);
    INFO(c.args << " " << c.redirect << "\n" << r.err);
    CHECK(r.status == 3);
    CHECK(contains(r.err, "crossdyn: error: " + c.message));
  }
}

TEST_CASE("a closed pipe on stdout ends the command quietly with status 141") {
  Scratch s("pipe");
  s.write("scene.yaml", kSmallScene);
  // A run of 1e6 rows whose reader stops after the first line.
  const int rc = sh("cd " + quote(s.dir().string()) + " && " + quote(crossdyn_binary()) +
                    " run scene.yaml --duration 1e4 --output-step 0.01 2> err | head -1 > first;"
                    " echo ${PIPESTATUS[0]} > status");
  CHECK(rc == 0);
  CHECK(read_file(s.path("status")) == "141\n");
  CHECK(read_file(s.path("err")).empty());
  CHECK(read_file(s.path("first")).rfind("t,hub.wx", 0) == 0);
}
