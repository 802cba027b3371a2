// The command-line fuzz target's seeds and regression inputs (fuzz/cli_seeds/, fuzz/cli_regressions/),
// replayed through the real program without clang: each ends with a documented exit status and
// leaves its input scene intact (the properties fuzz/cli_fuzzer.cpp checks).
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
    std::string args;
    for (const std::string& a : input->args) args += " " + quote(a);
    const Run r = run_in(s.dir().string(), args, "> /dev/null");
    INFO(args << "\n" << r.err);
    CHECK((r.status == 0 || r.status == 1 || r.status == 2 || r.status == 3));
    CHECK(read_file(s.path("scene.yaml")) == input->scene);
    CHECK(read_file(s.path("scenarios/scene.yaml")) == input->scene);
  }
}
