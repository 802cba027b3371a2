// The command-line fuzz target's seeds and regression inputs (fuzz/cli_seeds/, fuzz/cli_regressions/),
// replayed through the real program without clang: each ends with a documented exit status and
// leaves its inputs intact (the properties fuzz/cli_fuzzer.cpp checks).
#include <catch2/catch.hpp>

#include "fuzz/cli_input.hpp"
#include "tests/cli/cli_helpers.hpp"

using namespace crossdyn::test;

TEST_CASE("every command-line fuzz seed and regression input ends with a documented status") {
  std::vector<fs::path> files;
  for (const char* dir : {"/fuzz/cli_seeds", "/fuzz/cli_regressions"})
    if (fs::exists(source_dir() + dir))
      for (const auto& e : fs::directory_iterator(source_dir() + dir)) files.push_back(e.path());
  REQUIRE(files.size() >= 10);
  for (const fs::path& f : files) {
    const auto input = crossdyn::fuzz::parse_cli_input(read_file(f.string()));
    INFO(f);
    REQUIRE(input);
    Scratch s("fuzz_replay");
    s.write("scene.yaml", input->scene);
    s.write("scenarios/scene.yaml", input->scene);
    // As the target: the nodal data example beside both scenes, draw without its script.
    std::vector<std::pair<std::string, std::string>> nodal;
    for (const char* name : {"panel_nodes.csv", "panel_modes.csv"}) {
      nodal.emplace_back(name, read_file(source_dir() + "/scenarios/data/" + name));
      s.write(name, nodal.back().second);
      s.write(std::string("scenarios/") + name, nodal.back().second);
    }
    std::string args;
    for (const std::string& a : input->args) args += " " + quote(a);
    if (!input->args.empty() && input->args.front() == "draw") args += " --python=/bin/true";
    const Run r = run_in(s.dir().string(), args, "> /dev/null");
    INFO(args << "\n" << r.err);
    CHECK((r.status == 0 || r.status == 1 || r.status == 2 || r.status == 3));
    CHECK(read_file(s.path("scene.yaml")) == input->scene);
    CHECK(read_file(s.path("scenarios/scene.yaml")) == input->scene);
    for (const auto& [name, text] : nodal) {
      if (input->scene.find(name) == std::string::npos) continue;  // not an input of this scene
      CHECK(read_file(s.path(name)) == text);
      CHECK(read_file(s.path("scenarios/" + name)) == text);
    }
  }
}
