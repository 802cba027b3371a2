// Helpers for tests that run the crossdyn program as a user does: a scratch folder per test, a
// small scene, and running `crossdyn ARGS` through the shell with stdout and stderr kept apart.
#pragma once

#include "tests/support/paths.hpp"

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace crossdyn::test {

namespace fs = std::filesystem;

struct Run {
  int status = -1;  // exit status; 128 + N when killed by signal N
  std::string out, err;
};

// A scratch folder, removed (after making everything writable again) when the test ends.
class Scratch {
 public:
  explicit Scratch(const std::string& tag) {
    static std::atomic<int> counter{0};
    dir_ = fs::temp_directory_path() /
           ("crossdyn_" + tag + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  ~Scratch() {
    std::error_code ec;
    for (auto it = fs::recursive_directory_iterator(dir_, ec); it != fs::recursive_directory_iterator();
         it.increment(ec))
      if (!it->is_symlink(ec)) ::chmod(it->path().c_str(), 0755);
    ::chmod(dir_.c_str(), 0755);
    fs::remove_all(dir_, ec);
  }
  Scratch(const Scratch&) = delete;
  Scratch& operator=(const Scratch&) = delete;
  const fs::path& dir() const { return dir_; }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string write(const std::string& name, const std::string& text) const {
    const fs::path p = dir_ / name;
    fs::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
  }

 private:
  fs::path dir_;
};

inline std::string read_file(const std::string& path) {
  std::stringstream s;
  s << std::ifstream(path, std::ios::binary).rdbuf();
  return s.str();
}

inline std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

inline std::string crossdyn_binary() { return binary_dir() + "/crossdyn"; }

// Runs `cd DIR && crossdyn ARGS > out 2> err` (ARGS quoted by the caller; `redirect` may replace
// the stdout redirection, e.g. "> /dev/full").
inline Run run_in(const std::string& dir, const std::string& args, const std::string& redirect = "") {
  static std::atomic<int> counter{0};
  const fs::path tmp = fs::temp_directory_path() /
                       ("crossdyn_run_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  fs::create_directories(tmp);
  const std::string out = (tmp / "out").string(), err = (tmp / "err").string();
  const std::string cmd = "cd " + quote(dir) + " && " + quote(crossdyn_binary()) + " " + args + " " +
                          (redirect.empty() ? "> " + quote(out) : redirect) + " 2> " + quote(err);
  const int raw = std::system(cmd.c_str());
  Run r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = read_file(out);
  r.err = read_file(err);
  fs::remove_all(tmp);
  return r;
}

inline bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

inline bool is_root() { return ::geteuid() == 0; }

// Two bodies and a hinge, 0.5 s: every engine runs it in milliseconds and they agree.
inline const char* kSmallScene = R"(name: small
description: A hub and a panel on a hinge, for command-line tests.
source: crossdyn tests (tests/cli).
bodies:
  - {name: hub, mass: 100, inertia: [10, 20, 25]}
  - {name: panel, mass: 5, inertia: [1, 1, 1]}
joints:
  - {name: base, type: free, child: hub, initial: {angular_velocity: [0.1, 0, 0.2]}}
  - name: hinge
    type: revolute
    parent: hub
    child: panel
    parent_point: [1, 0, 0]
    child_point: [-1, 0, 0]
    axis: [0, 0, 1]
    initial: {angle: 0.1, rate: 0.2}
run: {duration: 0.5, output_step: 0.05}
)";

}  // namespace crossdyn::test
