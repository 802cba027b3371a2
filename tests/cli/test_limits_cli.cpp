// Command-line overrides meet the same limits as the scene file (core/run_limits.hpp): bad values
// are exit 2 with a message naming the option, before anything is written (issue 9, "Crashes").
#include <catch2/catch.hpp>

#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "tests/cli/cli_helpers.hpp"

using namespace crossdyn::test;

namespace {

struct Bad {
  std::string option, value, problem;
};

// Every override, with values that are out of range, not finite or absurd.
const std::vector<Bad> kRunOverrides{
    {"--duration", "0", "duration must be positive"},
    {"--duration", "-1", "duration must be positive"},
    {"--duration", "nan", "duration must be a finite number"},
    {"--duration", "inf", "duration must be a finite number"},
    {"--duration", "-inf", "duration must be a finite number"},
    {"--duration", "1e13", "is absurd"},
    {"--output-step", "0", "output_step must be positive"},
    {"--output-step", "-0.1", "output_step must be positive"},
    {"--output-step", "NaN", "output_step must be a finite number"},
    {"--output-step", "1e-90", "output rows; the limit is 1e+07"},
    {"--output-step", "1e-300", "too small to compute with (limit 1e-100 s)"},
    {"--dt", "1e-300", "too small to compute with (limit 1e-100 s)"},
    {"--output-step", "10", "is longer than the duration"},
    {"--dt", "0", "dt must be positive"},
    {"--dt", "-1e-3", "dt must be positive"},
    {"--dt", "inf", "dt must be a finite number"},
    {"--max-steps", "0", "the step limit must be at least 1"},
    {"--max-steps", "-5", "the step limit must be at least 1"}};
const std::vector<Bad> kSharedOverrides{  // run, compare and verify
    {"--rtol", "0", "rtol must be positive"},
    {"--rtol", "-1e-9", "negative tolerance"},
    {"--rtol", "nan", "rtol must be a finite number"},
    {"--atol", "inf", "atol must be a finite number"},
    {"--atol", "0", "atol must be positive"},
    {"--dt", "0", "dt must be positive"},
    {"--dt", "nan", "dt must be a finite number"},
    {"--integrator", "rk45", "unknown integrator 'rk45'"},
    {"--integrator", "Euler", "unknown integrator 'Euler'"}};

}  // namespace

TEST_CASE("limits: every bad override is exit 2 naming the option, before anything is written") {
  Scratch s("limits");
  s.write("scene.yaml", kSmallScene);
  std::vector<std::pair<std::string, Bad>> cases;
  for (const Bad& b : kRunOverrides) cases.push_back({"run scene.yaml -o out.csv", b});
  for (const Bad& b : kRunOverrides) cases.push_back({"run scene.yaml", b});
  for (const char* cmd : {"run scene.yaml", "compare scene.yaml --json out.json",
                          "verify scene.yaml --json out.json"})
    for (const Bad& b : kSharedOverrides) cases.push_back({cmd, b});
  for (const auto& [cmd, b] : cases) {
    const Run r = run_in(s.dir(), cmd + " " + b.option + "=" + quote(b.value));
    INFO(cmd << " " << b.option << "=" << b.value << "\n" << r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, "crossdyn: error: " + b.option + " "));
    CHECK(contains(r.err, b.problem));
    CHECK(r.out.empty());  // not even the CSV header
    CHECK_FALSE(fs::exists(s.dir() / "out.csv"));
    CHECK_FALSE(fs::exists(s.dir() / "out.json"));
  }
}

TEST_CASE("limits: combinations with the scene's values name the option that broke them") {
  Scratch s("combined");
  s.write("scene.yaml", kSmallScene);  // duration 0.5 s, output step 0.05 s
  // 1e7 s at the scene's 0.05 s step: 2e8 rows (ran out of memory before).
  Run r = run_in(s.dir(), "run scene.yaml --duration 1e7");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "--duration 1e+07: duration / output_step = 2e+08 output rows"));
  r = run_in(s.dir(), "run scene.yaml --duration 1e7 --output-step 1e-3");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "--output-step 0.001: duration / output_step = 1e+10 output rows"));
  r = run_in(s.dir(), "run scene.yaml --duration 0.01");  // shorter than the scene's output step
  CHECK(r.status == 2);
  CHECK(contains(r.err, "--duration 0.01: output_step 0.05 s is longer than the duration 0.01 s"));
  // rk4 takes duration / dt steps: more than the step limit could only end by hitting it.
  r = run_in(s.dir(), "run scene.yaml --integrator rk4 --dt 1e-9");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "--dt 1e-09: rk4 with dt = 1e-09 s needs duration / dt = 5e+08 steps"));
  r = run_in(s.dir(), "run scene.yaml --integrator rk4 --dt 0.01 --max-steps 10");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "more than the step limit of 10"));
  r = run_in(s.dir(), "compare scene.yaml --integrator rk4 --dt 1e-9");
  CHECK(r.status == 2);
  CHECK(contains(r.err, "rk4 with dt = 1e-09 s needs"));
  // In verify the scene with the bad combination is bad input; the verdict is exit 2.
  r = run_in(s.dir(), "verify scene.yaml --json out.json --integrator rk4 --dt 1e-9");
  CHECK(r.status == 2);
  CHECK(contains(r.out, "BAD INPUT"));
  // The limits' edges are accepted: an output step equal to the duration, 1e7 rows' worth.
  CHECK(run_in(s.dir(), "run scene.yaml --output-step 0.5 -o a.csv").status == 0);
  CHECK(run_in(s.dir(), "run scene.yaml --integrator rk4 --dt 0.05 --max-steps 10 -o b.csv").status == 0);
}

TEST_CASE("limits: the scene file and the command line say the same thing about the same value") {
  Scratch s("same_words");
  const std::string base = kSmallScene;
  const std::string run_line = "run: {duration: 0.5, output_step: 0.05}";
  struct Pair {
    std::string file_run, option, file_key;
  };
  const std::vector<Pair> pairs{
      {"run: {duration: 0.5, output_step: 1e-90}", "--output-step=1e-90", "run.output_step"},
      {"run: {duration: 0.5, output_step: 0.05, rtol: 0}", "--rtol=0", "run.rtol"},
      {"run: {duration: 0.5, output_step: 0.05, dt: -1}", "--dt=-1", "run.dt"},
      {"run: {duration: 1e9, output_step: 0.05}", "--duration=1e9", "run.output_step"}};
  for (const Pair& p : pairs) {
    std::string text = base;
    text.replace(text.find(run_line), run_line.size(), p.file_run);
    const std::string file = s.write("edited.yaml", text);
    std::string from_file;
    try {
      crossdyn::read_scene(file);
    } catch (const crossdyn::InputError& e) {
      from_file = e.what();
    }
    INFO(from_file);
    REQUIRE(contains(from_file, p.file_key + ": "));
    const std::string file_problem = from_file.substr(from_file.find(p.file_key + ": ") + p.file_key.size() + 2);
    s.write("scene.yaml", kSmallScene);
    const Run r = run_in(s.dir(), "run scene.yaml " + p.option);
    INFO(r.err);
    CHECK(r.status == 2);
    CHECK(contains(r.err, file_problem));
  }
}
