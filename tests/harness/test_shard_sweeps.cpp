// Sharded study, stability and converge (harness/shard.hpp sweep parts): merged runs equal the
// unsharded ones, directly and through GNU parallel (scripts/sweep_parallel.sh); their items read
// back bit for bit; and the refusals of parts that do not belong together (mixed commands, mixed
// options, a missing shard), each exit status 2 with its message.
//
// What is compared. Everything the commands write except what depends on the CPU time measured
// in each process: in study's CSV the fields cpu_ms_median, cpu_ms_min, cpu_ms_max (the timings)
// and front_end, front_history (the Pareto front of CPU time against error); in its text the
// table rows (their numbers are the CSV's) and, of each recommendation ("for 1e-08 end-state error
// on ... use ..."), only whether the target is reached (which configuration is cheapest is a
// timing). Stability's text (the maps, |lambda|max, the findings) has no timings and must be
// identical; of its CSV every field but cpu_ms.
#include "harness/shard.hpp"
#include "tests/harness/run_program.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

namespace fs = std::filesystem;
using crossdyn::test::run_crossdyn;
namespace h = crossdyn::harness;

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name)
      : path(fs::temp_directory_path() / ("crossdyn_sweeps_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string operator/(const std::string& f) const { return (path / f).string(); }
};

std::vector<std::string> split(const std::string& text, char sep) {
  std::vector<std::string> out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, sep)) out.push_back(item);
  return out;
}

// A CSV without the named columns (the fields carry no quoted commas in these scenes).
std::string csv_without(const std::string& text, const std::vector<std::string>& drop) {
  const std::vector<std::string> lines = split(text, '\n');
  REQUIRE(!lines.empty());
  const std::vector<std::string> header = split(lines.front(), ',');
  std::vector<bool> keep(header.size(), true);
  for (const std::string& d : drop) {
    const auto it = std::find(header.begin(), header.end(), d);
    REQUIRE(it != header.end());
    keep[static_cast<std::size_t>(it - header.begin())] = false;
  }
  std::string out;
  for (const std::string& line : lines) {
    const std::vector<std::string> f = split(line + ",", ',');  // keeps a trailing empty field
    for (std::size_t k = 0; k < f.size() && k < keep.size(); ++k)
      if (keep[k]) out += f[k] + ",";
    out += "\n";
  }
  return out;
}

// study's text without what depends on timings (see the file comment).
std::string study_text_without_timings(const std::string& text) {
  std::string out;
  bool recommendation = false;  // inside a "for ... use ...: N ms" recommendation and its wrap
  for (const std::string& line : split(text, '\n')) {
    if (recommendation && line.rfind("  ", 0) == 0) continue;
    recommendation = false;
    if (line.rfind("kane ", 0) == 0 || line.rfind("lagrange ", 0) == 0 || line.rfind("newton-euler ", 0) == 0)
      continue;  // a table row: its numbers are compared in the CSV
    if (line.rfind("for ", 0) == 0) {  // reached: which configuration is cheapest is a timing
      out += line.substr(0, line.find(" use ")) + " (reached)\n";
      recommendation = true;
      continue;
    }
    if (line.rfind("merge:", 0) == 0 || line.rfind("part ", 0) == 0) continue;
    out += line + "\n";
  }
  return out;
}

const std::string kStudyScenes = " scenarios/spear1_case1.yaml scenarios/chain5.yaml";
const std::string kStudyOptions =
    " --engines kane,lagrange --integrators dopri5,rk4 --tolerances 1e-6,1e-8 --dts 0.05 --repeat 1 -q";
const std::vector<std::string> kStudyTimed{"cpu_ms_median", "cpu_ms_min", "cpu_ms_max", "front_end",
                                           "front_history"};
const std::string kStability =
    " hub_two_panels --vary hinge1.stiffness --values 500,5e4,5e6 --engines kane "
    "--integrators rk4,dopri5 --tolerances 1e-6 --dts 0.05 --duration 2 -q";

}  // namespace

TEST_CASE("a 2-shard study merged equals the unsharded study, timings aside", "[shard][study]") {
  TempDir dir("study");
  const auto whole = run_crossdyn("study" + kStudyScenes + kStudyOptions + " --csv '" + dir / "whole.csv" + "'");
  REQUIRE(whole.status == 0);
  for (int k = 0; k < 2; ++k) {
    const auto shard = run_crossdyn("study" + kStudyScenes + kStudyOptions + " --shard " +
                                    std::to_string(k) + "/2 --part '" + dir / ("part-" + std::to_string(k) + ".json") + "'");
    INFO(shard.output);
    REQUIRE(shard.status == 0);
  }
  // Each shard studied one whole scene (two scenes, two shards).
  const h::Part p0 = h::read_part(dir / "part-0.json");
  const h::Part p1 = h::read_part(dir / "part-1.json");
  CHECK(p0.command == "study");
  CHECK(p0.items.size() == 1);
  CHECK(p1.items.size() == 1);
  const auto merged = run_crossdyn("merge '" + dir / "part-1.json" + "' '" + dir / "part-0.json" +
                                   "' -q --csv '" + dir / "merged.csv" + "' --report '" + dir / "report" + "'");
  INFO(merged.output);
  REQUIRE(merged.status == 0);
  CHECK(csv_without(slurp(dir / "merged.csv"), kStudyTimed) == csv_without(slurp(dir / "whole.csv"), kStudyTimed));
  CHECK(study_text_without_timings(merged.output) == study_text_without_timings(whole.output));
  CHECK(fs::exists(dir / "report/study.json"));
  // Same rows in the same order, rhs counts and steps to the last digit: the CSV above; and the
  // merge carries each shard's own numbers bit for bit (the item read back writes the same text).
  for (const h::Part* p : {&p0, &p1})
    for (const std::string& item : p->items) CHECK(h::study_item_json(h::study_item_from(item)) == item);
}

TEST_CASE("study and stability items read back bit for bit", "[shard]") {
  h::SceneStudy s;
  s.scene = "x";
  s.reference.kind = "engines";
  h::StudyRow r;
  r.engine = "kane";
  r.integrator = "dopri5";
  r.tolerance = 1e-8;
  r.cpu_median = 0.1 + 0.2;  // not a short decimal
  r.error.end = std::nextafter(1e-9, 1.0);
  r.drift_H = std::numeric_limits<double>::infinity();
  s.rows.push_back(r);
  const std::string text = h::study_item_json({s, "", 0});
  const h::StudyItem back = h::study_item_from(text);
  REQUIRE(back.study);
  CHECK(back.study->rows.at(0).cpu_median == 0.1 + 0.2);
  CHECK(back.study->rows.at(0).error.end == std::nextafter(1e-9, 1.0));
  CHECK(std::isnan(back.study->rows.at(0).drift_E));
  CHECK(std::isinf(back.study->rows.at(0).drift_H));
  CHECK(h::study_item_json(back) == text);
  const h::StudyItem refused = h::study_item_from(h::study_item_json({std::nullopt, "engines disagree", 1}));
  CHECK(!refused.study);
  CHECK(refused.exit_status == 1);

  h::StabilityValue v;
  v.column.value = 5e4;
  v.column.lambda_max = {18.69, std::numeric_limits<double>::quiet_NaN()};
  h::StabilityCell c;
  c.engine = "kane";
  c.integrator = "rk4";
  c.result.cls = h::StabilityClass::Diverged;
  c.result.why = "non-finite";
  v.cells.push_back(c);
  v.refused_note = "at k = 1: no";
  const std::string vt = h::stability_value_json(v);
  CHECK(h::stability_value_json(h::stability_value_from(vt)) == vt);
  CHECK(h::stability_value_from(vt).cells.at(0).result.cls == h::StabilityClass::Diverged);
}

TEST_CASE("a 2-shard stability over 3 values merged equals the unsharded map", "[shard][stability]") {
  TempDir dir("stability");
  const auto whole = run_crossdyn("stability" + kStability + " --csv '" + dir / "whole.csv" + "'");
  INFO(whole.output);
  REQUIRE(whole.status == 0);
  for (int k = 0; k < 2; ++k)
    REQUIRE(run_crossdyn("stability" + kStability + " --shard " + std::to_string(k) + "/2 --part '" +
                         dir / ("part-" + std::to_string(k) + ".json") + "'")
                .status == 0);
  const h::Part p0 = h::read_part(dir / "part-0.json");
  const h::Part p1 = h::read_part(dir / "part-1.json");
  CHECK(p0.items.size() + p1.items.size() == 3);
  CHECK(p0.items.size() >= 1);
  CHECK(p1.items.size() >= 1);
  const auto merged = run_crossdyn("merge -q '" + dir / "part-0.json" + "' '" + dir / "part-1.json" +
                                   "' --csv '" + dir / "merged.csv" + "'");
  REQUIRE(merged.status == 0);
  // The whole text: the maps (classes), |lambda|max, the legend and the findings.
  CHECK(merged.output == whole.output);
  CHECK(whole.output.find("kane + rk4:") != std::string::npos);  // the findings are there
  // Every CSV field but cpu_ms: classes, why, history errors, rhs calls, steps, h |lambda|max.
  CHECK(csv_without(slurp(dir / "merged.csv"), {"cpu_ms"}) == csv_without(slurp(dir / "whole.csv"), {"cpu_ms"}));
}

TEST_CASE("merge refuses sweep parts that do not belong together, exit status 2", "[shard]") {
  TempDir dir("sweepbad");
  const std::string cheap = " scenarios/spear1_case1.yaml scenarios/chain5.yaml --engines kane "
                            "--integrators dopri5 --dts 0.05 --repeat 1 -q";
  const auto part = [&](const std::string& cmd, const std::string& name) {
    const auto r = run_crossdyn(cmd + " --part '" + dir / name + "'");
    INFO(r.output);
    REQUIRE(r.status == 0);
    return "'" + dir / name + "'";
  };
  const std::string s0 = part("study" + cheap + " --tolerances 1e-6 --shard 0/2", "s0.json");
  const std::string s1 = part("study" + cheap + " --tolerances 1e-6 --shard 1/2", "s1.json");
  const std::string s1b = part("study" + cheap + " --tolerances 1e-6,1e-8 --shard 1/2", "s1b.json");
  const std::string stab = " hub_two_panels --vary hinge1.stiffness --engines kane --integrators dopri5 "
                           "--tolerances 1e-6 --duration 0.5 -q";
  const std::string t0 = part("stability" + stab + " --values 500,5e4 --shard 0/2", "t0.json");
  const std::string t1 = part("stability" + stab + " --values 500,5e4 --shard 1/2", "t1.json");
  const std::string t1b = part("stability" + stab + " --values 500,5e5 --shard 1/2", "t1b.json");

  SECTION("the good ones merge") {
    CHECK(run_crossdyn("merge -q " + s0 + " " + s1).status == 0);
    CHECK(run_crossdyn("merge -q " + t0 + " " + t1).status == 0);
  }
  SECTION("mixed commands") {
    const auto r = run_crossdyn("merge -q " + s0 + " " + t1);
    CHECK(r.status == 2);
    CHECK(r.output.find("parts of different commands: '" + dir / "s0.json" +
                        "' was written by `crossdyn study`, '" + dir / "t1.json" +
                        "' by `crossdyn stability`") != std::string::npos);
  }
  SECTION("study parts made with different tolerances") {
    const auto r = run_crossdyn("merge -q " + s0 + " " + s1b);
    CHECK(r.status == 2);
    CHECK(r.output.find("parts made with different options: --tolerances is '1e-06' in '" + dir / "s0.json" +
                        "' but '1e-06,1e-08' in '" + dir / "s1b.json" + "'") != std::string::npos);
  }
  SECTION("stability parts made with different values") {
    const auto r = run_crossdyn("merge -q " + t0 + " " + t1b);
    CHECK(r.status == 2);
    CHECK(r.output.find("parts made with different options: --values is '5e+02,5e+04' in '") != std::string::npos);
  }
  SECTION("a missing shard") {
    const auto r = run_crossdyn("merge -q " + s1);
    CHECK(r.status == 2);
    CHECK(r.output.find("missing shard 0/2 (give all 2 parts of the run)") != std::string::npos);
    const auto t = run_crossdyn("merge -q " + t0);
    CHECK(t.status == 2);
    CHECK(t.output.find("missing shard 1/2") != std::string::npos);
  }
  SECTION("a shard given twice") {
    const auto r = run_crossdyn("merge -q " + s0 + " " + s0);
    CHECK(r.status == 2);
    CHECK(r.output.find("shard 0/2 is given 2 times") != std::string::npos);
  }
  SECTION("options that belong to the merge, not a shard") {
    const auto r = run_crossdyn("study" + cheap + " --shard 0/2 --part '" + dir / "x.json" + "' --scaling");
    CHECK(r.status == 2);
    CHECK(r.output.find("--scaling is not sharded") != std::string::npos);
    const auto c = run_crossdyn("stability" + stab + " --values 500 --shard 0/2 --part '" + dir / "y.json" +
                                "' --csv '" + dir / "y.csv" + "'");
    CHECK(c.status == 2);
    CHECK(c.output.find("--csv and --report are written by `crossdyn merge") != std::string::npos);
    const auto j = run_crossdyn("merge -q " + s0 + " " + s1 + " --junit '" + dir / "j.xml" + "'");
    CHECK(j.status == 2);
  }
}

TEST_CASE("GNU parallel runs a 2-shard study (scripts/sweep_parallel.sh), merged equal to unsharded",
          "[shard][study]") {
  REQUIRE(fs::exists("/usr/bin/parallel"));
  TempDir dir("sweepparallel");
  const auto whole = run_crossdyn("study" + kStudyScenes + kStudyOptions + " --csv '" + dir / "whole.csv" + "'");
  REQUIRE(whole.status == 0);
  const std::string cmd = "cd '" + crossdyn::test::source_dir() + "' && CROSSDYN='" +
                          crossdyn::test::binary_dir() + "/crossdyn' scripts/sweep_parallel.sh study 2 '" +
                          dir / "out" + "'" + kStudyScenes + kStudyOptions + " > '" + dir / "merged.txt" +
                          "' 2>&1";
  const int status = std::system(cmd.c_str());
  INFO(slurp(dir / "merged.txt"));
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);
  REQUIRE(fs::exists(dir / "out/part-0.json"));
  REQUIRE(fs::exists(dir / "out/part-1.json"));
  CHECK(csv_without(slurp(dir / "out/study.csv"), kStudyTimed) == csv_without(slurp(dir / "whole.csv"), kStudyTimed));
  CHECK(study_text_without_timings(slurp(dir / "merged.txt")) == study_text_without_timings(whole.output));
}

TEST_CASE("a 3-shard converge merged equals the unsharded converge, text and JSON", "[shard][converge]") {
  TempDir dir("converge");
  const auto whole = run_crossdyn("converge pointing_flex -q --json '" + dir / "whole.json" + "'");
  REQUIRE(whole.status == 0);
  for (int k = 0; k < 3; ++k)
    REQUIRE(run_crossdyn("converge pointing_flex -q --shard " + std::to_string(k) + "/3 --part '" +
                         dir / ("part-" + std::to_string(k) + ".json") + "'")
                .status == 0);
  std::size_t models = 0;
  for (int k = 0; k < 3; ++k) {
    const h::Part p = h::read_part(dir / ("part-" + std::to_string(k) + ".json"));
    CHECK(p.command == "converge");
    CHECK(!p.items.empty());  // 10 models besides the full one, over 3 shards
    models += p.items.size();
  }
  CHECK(models == 10);
  const auto merged = run_crossdyn("merge -q '" + dir / "part-2.json" + "' '" + dir / "part-0.json" + "' '" +
                                   dir / "part-1.json" + "' --json '" + dir / "merged.json" + "'");
  REQUIRE(merged.status == 0);
  CHECK(merged.output == whole.output);  // converge writes no timings: all of it
  CHECK(slurp(dir / "merged.json") == slurp(dir / "whole.json"));
  // Parts of converge and of another command, or of converge with another engine, do not mix.
  REQUIRE(run_crossdyn("converge pointing_flex -q --engine lagrange --shard 1/3 --part '" + dir / "other.json" + "'")
              .status == 0);
  const auto engines = run_crossdyn("merge -q '" + dir / "part-0.json" + "' '" + dir / "other.json" + "' '" +
                                    dir / "part-2.json" + "'");
  CHECK(engines.status == 2);
  CHECK(engines.output.find("parts made with different options: --engine is 'kane' in '") != std::string::npos);
  const auto junit = run_crossdyn("merge -q '" + dir / "part-0.json" + "' '" + dir / "part-1.json" + "' '" +
                                  dir / "part-2.json" + "' --csv '" + dir / "x.csv" + "'");
  CHECK(junit.status == 2);
}
