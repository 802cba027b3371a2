// The streaming comparison (harness/compare.hpp "Memory") gives the same numbers as comparing
// whole columns in memory, on every committed scene, whether the rows are in memory or spilled to
// temporary files; and per-run limits (--max-steps, --timeout) fail only the run that hits them.
#include <catch2/catch.hpp>

#include "core/errors.hpp"
#include "core/rotation.hpp"
#include "core/rows.hpp"
#include "core/scene/scene.hpp"
#include "harness/compare.hpp"
#include "tests/support/paths.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <unistd.h>

using namespace crossdyn;
using namespace crossdyn::harness;
namespace fs = std::filesystem;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The per-quantity algorithm compare used before it streamed (commit 1aca500, pair_check,
// drift_check and time_check), kept here as the reference: every column in memory, the error at
// every row in a vector, then the maximum, its time and the first row over the bound.
struct Reference {
  double error = 0, time = 0, scale = 0, bound = 0, normalised = 0;
  std::optional<double> first_exceeded;
  CheckStatus status = CheckStatus::Pass;
};

int col(const RunResult& r, const std::string& name) { return r.column(name); }

void finish(Reference& c, const Tolerance& tol) {
  c.bound = tol.atol + tol.rtol * c.scale;
  if (c.error == 0) c.normalised = 0;
  else if (c.bound > 0) c.normalised = c.error / c.bound;
  else c.normalised = std::numeric_limits<double>::infinity();
  if (!(c.error <= c.bound)) c.status = CheckStatus::Fail;
  if (std::isnan(c.error)) c.normalised = kNaN;
}

Reference reference_pair(const Check& k, const RunResult& A, const RunResult& B) {
  Reference c;
  const bool attitude = k.group == "attitude";
  std::vector<std::string> columns{k.quantity};
  if (attitude) {
    const std::string body = k.quantity.substr(0, k.quantity.size() - std::string(".attitude").size());
    columns = {body + ".qw", body + ".qx", body + ".qy", body + ".qz"};
  }
  std::vector<int> ca, cb;
  for (const std::string& name : columns) {
    ca.push_back(col(A, name));
    cb.push_back(col(B, name));
  }
  // Issue 26's vectors (positions, the CM, H and M, a joint's force and moment) are scaled by the
  // vector's largest norm, not the component's largest value.
  std::vector<int> vector_columns;
  const std::string& q = k.quantity;
  const bool vector = (k.group == "position" && (q.ends_with(".x") || q.ends_with(".y") || q.ends_with(".z") ||
                                                  q.rfind("CM", 0) == 0)) ||
                      k.group == "load" || q == "Hx" || q == "Hy" || q == "Hz" || q == "Mx" || q == "My" ||
                      q == "Mz";
  if (vector)
    for (const char* a : {"x", "y", "z"}) vector_columns.push_back(col(B, q.substr(0, q.size() - 1) + a));
  const std::size_t n = std::min(A.rows(), B.rows());
  const int ta = col(A, "t");
  c.scale = attitude ? 1.0 : 0.0;
  std::vector<double> err(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (attitude) {
      const Eigen::Quaterniond qa(A.at(i, ca[0]), A.at(i, ca[1]), A.at(i, ca[2]), A.at(i, ca[3]));
      const Eigen::Quaterniond qb(B.at(i, cb[0]), B.at(i, cb[1]), B.at(i, cb[2]), B.at(i, cb[3]));
      err[i] = rot::angle_between(qa.normalized(), qb.normalized());
    } else {
      const double a = A.at(i, ca[0]), b = B.at(i, cb[0]);
      err[i] = std::abs(a - b);
      double v = std::abs(b);
      if (!vector_columns.empty()) {
        double n2 = 0;
        for (int vc : vector_columns) n2 += B.at(i, vc) * B.at(i, vc);
        v = std::sqrt(n2);
      }
      c.scale = std::max(c.scale, v);
      if (!std::isfinite(a) || !std::isfinite(b)) err[i] = kNaN;
    }
  }
  for (std::size_t i = 0; i < n; ++i)
    if (std::isnan(err[i]) || err[i] > c.error) {
      c.error = err[i];
      c.time = ta >= 0 ? A.at(i, ta) : kNaN;
      if (std::isnan(err[i])) break;
    }
  finish(c, k.tolerance);
  for (std::size_t i = 0; i < n; ++i)
    if (!(err[i] <= c.bound)) {
      c.first_exceeded = ta >= 0 ? A.at(i, ta) : kNaN;
      break;
    }
  return c;
}

Reference reference_drift(const Check& k, const RunResult& R) {
  Reference c;
  const int ix = col(R, k.quantity.substr(0, 1)), it = col(R, "t");
  const double x0 = R.at(0, ix);
  c.scale = std::abs(x0);
  std::vector<double> err(R.rows());
  for (std::size_t i = 0; i < err.size(); ++i) {
    err[i] = std::abs(R.at(i, ix) - x0);
    if (std::isnan(err[i]) || err[i] > c.error) {
      c.error = err[i];
      c.time = it >= 0 ? R.at(i, it) : kNaN;
      if (std::isnan(err[i])) break;
    }
  }
  finish(c, k.tolerance);
  for (std::size_t i = 0; i < err.size(); ++i)
    if (!(err[i] <= c.bound)) {
      c.first_exceeded = it >= 0 ? R.at(i, it) : kNaN;
      break;
    }
  return c;
}

bool same(double a, double b) { return (std::isnan(a) && std::isnan(b)) || a == b; }
bool same(const std::optional<double>& a, const std::optional<double>& b) {
  return a.has_value() == b.has_value() && (!a || same(*a, *b));
}

const RunResult& run_of(const SceneComparison& c, const std::string& label) {
  for (const EngineRun& r : c.runs)
    if (r.label == label) return r.result;
  FAIL("no run " << label);
  throw std::logic_error("unreachable");
}

struct Budget {
  explicit Budget(std::size_t bytes) : saved(row_memory_budget()) { set_row_memory_budget(bytes); }
  ~Budget() { set_row_memory_budget(saved); }
  std::size_t saved;
};

}  // namespace

TEST_CASE("streaming compare: every check's numbers equal the whole-column reference, and are "
          "identical with the rows spilled to temporary files, on every committed scene") {
  const std::vector<std::string> scenes = test::committed_scenes();
  REQUIRE(scenes.size() >= 10);
  for (const std::string& path : scenes) {
    INFO(path);
    const System system = read_scene(path);
    const SceneComparison memory = compare_scene(system, {});
    int referenced = 0;
    for (const Check& k : memory.checks) {
      if (k.status != CheckStatus::Pass && k.status != CheckStatus::Fail) continue;
      if (k.group == "run" || k.group == "t" || !k.note.empty()) continue;
      INFO(k.quantity << " " << k.a << " vs " << k.b);
      const Reference r = k.b.empty() ? reference_drift(k, run_of(memory, k.a))
                                      : reference_pair(k, run_of(memory, k.a), run_of(memory, k.b));
      CHECK(same(k.error, r.error));
      CHECK(same(k.time, r.time));
      CHECK(same(k.scale, r.scale));
      CHECK(same(k.bound, r.bound));
      CHECK(same(k.normalised, r.normalised));
      CHECK(same(k.first_exceeded, r.first_exceeded));
      CHECK(k.status == r.status);
      ++referenced;
    }
    CHECK(referenced > 10);

    Budget none(0);  // every run's rows go to a temporary file
    const SceneComparison spilled = compare_scene(system, {});
    for (const EngineRun& r : spilled.runs) CHECK(r.result.spill != nullptr);
    REQUIRE(spilled.checks.size() == memory.checks.size());
    for (std::size_t i = 0; i < memory.checks.size(); ++i) {
      const Check &a = memory.checks[i], &b = spilled.checks[i];
      INFO(a.quantity << " " << a.a << " vs " << a.b);
      CHECK(a.quantity == b.quantity);
      CHECK(a.a == b.a);
      CHECK(a.b == b.b);
      CHECK(same(a.error, b.error));
      CHECK(same(a.time, b.time));
      CHECK(same(a.scale, b.scale));
      CHECK(same(a.bound, b.bound));
      CHECK(same(a.normalised, b.normalised));
      CHECK(same(a.first_exceeded, b.first_exceeded));
      CHECK(a.status == b.status);
      CHECK(a.note == b.note);
    }
    CHECK(memory.notes == spilled.notes);
  }
}

TEST_CASE("streaming compare: a failing check's first time over the bound is found in the spilled "
          "rows too") {
  // A deliberately wrong engine (inertias 0.1% off) fails many checks: pass 2 runs.
  const System system = read_scene(test::scene_path("spear1_case1"));
  CompareOptions o;
  o.engines = {{"kane", "kane", {}}, {"kane*1.001", "kane", {}}};
  o.engines[1].options.test_inertia_scale = 1.001;
  const SceneComparison memory = compare_scene(system, o);
  Budget none(0);
  const SceneComparison spilled = compare_scene(system, o);
  int failed = 0;
  REQUIRE(memory.checks.size() == spilled.checks.size());
  for (std::size_t i = 0; i < memory.checks.size(); ++i) {
    if (memory.checks[i].status != CheckStatus::Fail) continue;
    ++failed;
    REQUIRE(memory.checks[i].first_exceeded);
    CHECK(same(memory.checks[i].first_exceeded, spilled.checks[i].first_exceeded));
    CHECK(same(memory.checks[i].error, spilled.checks[i].error));
  }
  CHECK(failed > 5);
}

TEST_CASE("per-run limits: a run that hits --max-steps or --timeout is a failed run check and the "
          "other engines still run") {
  // A scene that would run for a very long time: a 1e6 s run of spear1_case1's data.
  const fs::path dir = fs::temp_directory_path() / ("crossdyn_limits_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ifstream in(test::scene_path("spear1_case1"));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto run_at = text.find("\nrun:");
  REQUIRE(run_at != std::string::npos);
  const auto run_end = text.find("\ncompare:", run_at);
  text = text.substr(0, run_at) +
         "\nrun: {duration: 1e6 s, output_step: 1000 s, integrator: rkf78, rtol: 1e-10, atol: 1e-10}\n" +
         (run_end == std::string::npos ? "" : text.substr(run_end + 1));
  const fs::path scene = dir / "long.yaml";
  std::ofstream(scene) << text;
  const System system = read_scene(scene.string());

  SECTION("--max-steps") {
    CompareOptions o;
    o.max_steps = 25;
    const SceneComparison c = compare_scene(system, o);
    int failed_runs = 0;
    for (const Check& k : c.checks)
      if (k.group == "run") {
        CHECK(k.status == CheckStatus::Fail);
        CHECK(k.note.find("step limit reached (25 steps)") != std::string::npos);
        ++failed_runs;
      }
    CHECK(failed_runs == 3);  // every engine ran, each to its own limit
    CHECK_FALSE(c.passed());
  }
  SECTION("--timeout") {
    CompareOptions o;
    o.timeout = 0.3;
    const SceneComparison c = compare_scene(system, o);
    int failed_runs = 0;
    for (const Check& k : c.checks)
      if (k.group == "run") {
        INFO(k.note);
        CHECK(k.status == CheckStatus::Fail);
        CHECK(k.note.find("timed out after 0.3 s") != std::string::npos);
        CHECK(k.note.find("engine " + k.a + " failed at t = ") == 0);
        ++failed_runs;
      }
    CHECK(failed_runs == 3);
  }
  fs::remove_all(dir);
}
