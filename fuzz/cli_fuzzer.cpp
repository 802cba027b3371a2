// libFuzzer target for the command line and the scene reader together (fuzz/README.md): every
// input is an argument vector and a scene text (fuzz/cli_input.hpp), run in-process through
// crossdyn_main (harness/cli.cpp), the program's own entry point, in a scratch folder.
//
// Properties checked on every input:
//   1. crossdyn_main returns one of the documented exit statuses (0, 1, 2, 3, 130); an exception
//      escaping it, a crash, a sanitizer report, a leak or a hang is a finding;
//   2. the inputs are intact: scene.yaml and scenarios/scene.yaml hold the text written, and the
//      nodal data files beside them (panel_nodes.csv, panel_modes.csv: scenarios/data/'s example,
//      copied into both folders so that a scene can name them and an output can try to) hold
//      theirs whenever the scene's text names them.
// `draw` runs `--python=/bin/true` (appended): the geometry and the kane run are fuzzed, the
// drawing script is not run (no picture, so exit 2 with nothing written).
// Bounded work: at most 64 output rows per run (run_limits::set_max_output_rows), and a watchdog
// that interrupts (as Ctrl-C does) a command still running after 2 s; stdout goes to /dev/null.
#include "core/integrate.hpp"
#include "core/run_limits.hpp"
#include "fuzz/cli_input.hpp"
#include "harness/cli.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <thread>
#include <utility>
#include <vector>

namespace {

namespace fs = std::filesystem;

fs::path g_dir;   // the scratch folder, the command's current folder
fs::path g_home;  // libFuzzer's current folder (corpus and artifacts), restored after each input
// The nodal data files written beside each scene (name, text).
std::vector<std::pair<std::string, std::string>> g_nodal;

std::string read_all(const fs::path& p) {
  std::stringstream s;
  s << std::ifstream(p, std::ios::binary).rdbuf();
  return s.str();
}

// Interrupts the command after `limit` unless stopped first.
class Watchdog {
 public:
  explicit Watchdog(std::chrono::milliseconds limit)
      : thread_([this, limit] {
          std::unique_lock<std::mutex> lock(m_);
          if (!cv_.wait_for(lock, limit, [this] { return done_; })) crossdyn::request_interrupt();
        }) {}
  ~Watchdog() {
    {
      std::lock_guard<std::mutex> lock(m_);
      done_ = true;
    }
    cv_.notify_one();
    thread_.join();
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  bool done_ = false;
  std::thread thread_;
};

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  char tmpl[] = "/tmp/crossdyn-cli-fuzz-XXXXXX";
  if (!::mkdtemp(tmpl)) std::abort();
  g_dir = tmpl;
  g_home = fs::current_path();
  const int null = ::open("/dev/null", O_WRONLY);
  if (null < 0 || ::dup2(null, STDOUT_FILENO) < 0) std::abort();
  ::close(null);
  crossdyn::run_limits::set_max_output_rows(64);
  for (const char* name : {"panel_nodes.csv", "panel_modes.csv"}) {
    const fs::path from = fs::path(CROSSDYN_FUZZ_SOURCE_DIR) / "scenarios" / "data" / name;
    g_nodal.emplace_back(name, read_all(from));
    if (g_nodal.back().second.empty()) std::abort();
  }
  std::atexit([] {
    std::error_code ec;
    fs::remove_all(g_dir, ec);
  });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto input = crossdyn::fuzz::parse_cli_input(
      std::string_view(reinterpret_cast<const char*>(data), size));
  if (!input) return -1;  // outside the fuzzed space: not added to the corpus
  // A clean scratch folder holding only the scene.
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(g_dir, ec)) fs::remove_all(e.path(), ec);
  fs::create_directories(g_dir / "scenarios", ec);
  for (const char* name : {"scene.yaml", "scenarios/scene.yaml"})
    std::ofstream(g_dir / name, std::ios::binary) << input->scene;
  for (const auto& [name, text] : g_nodal)
    for (const fs::path& dir : {g_dir, g_dir / "scenarios"})
      std::ofstream(dir / name, std::ios::binary) << text;

  std::vector<std::string> args{"crossdyn"};
  args.insert(args.end(), input->args.begin(), input->args.end());
  if (!input->args.empty() && input->args.front() == "draw") args.push_back("--python=/bin/true");
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  crossdyn::clear_interrupt();
  int status = -1;
  if (::chdir(g_dir.c_str()) != 0) std::abort();
  {
    Watchdog watchdog(std::chrono::milliseconds(2000));
    status = crossdyn::crossdyn_main(static_cast<int>(args.size()), argv.data());
  }
  if (::chdir(g_home.c_str()) != 0) std::abort();
  crossdyn::clear_interrupt();
  if (status != 0 && status != 1 && status != 2 && status != 3 && status != 130) {
    std::fprintf(stderr, "unexpected exit status %d\n", status);
    std::abort();
  }
  for (const char* name : {"scene.yaml", "scenarios/scene.yaml"})
    if (read_all(g_dir / name) != input->scene) {
      std::fprintf(stderr, "the input %s was modified (exit status %d)\n", name, status);
      std::abort();
    }
  // A data file is an input when the scene names it (a scene that does not is free to be given
  // it as an output: `--part panel_modes.csv` of a scene without nodal data is the user's choice).
  for (const auto& [name, text] : g_nodal)
    for (const fs::path& dir : {g_dir, g_dir / "scenarios"})
      if (input->scene.find(name) != std::string::npos && read_all(dir / name) != text) {
        std::fprintf(stderr, "the input %s was modified (exit status %d)\n",
                     (dir / name).string().c_str(), status);
        std::abort();
      }
  return 0;
}
