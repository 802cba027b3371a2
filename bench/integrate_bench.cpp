// Whole integrations as `crossdyn study` times them (issue 12's target: spear1_case1 to 1e-10
// end-state error in <= 0.25 ms of integration CPU with the best engine and integrator). One
// iteration is one simulate() call from the initial state to the end: every step and right-hand
// side, the engine's after-step work and, at each output time, the engine's output row with its
// pinned values copied to memory reserved beforehand; no row store, no CSV, the engine made once
// outside the loop (the study's timing, harness/study.cpp timed_run). The counter rhs is the
// right-hand sides per run. rtol = atol = 1e-10, at which kane + dop853 reaches 3.7e-11 end-state
// error on spear1_case1 (reports/example/study/spear1_case1-study.csv).
//   build/crossdyn_bench --benchmark_filter=integrate/
#include <benchmark/benchmark.h>

#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "core/output_layout.hpp"
#include "core/scene/scene.hpp"
#include "harness/engines.hpp"

#include <deque>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

namespace {

void bench_integrate(benchmark::State& state, const crossdyn::System& system,
                     const std::string& engine_name, const std::string& method, double tol) {
  std::unique_ptr<crossdyn::Engine> engine = crossdyn::make_engine(engine_name, system);
  crossdyn::IntegratorSettings s = crossdyn::IntegratorSettings::from(system.run);
  s.method = method;
  s.rtol = s.atol = tol;
  s.keep_rows = false;
  const std::size_t pinned = crossdyn::pinned_columns(system).size();
  std::vector<double> history;
  history.reserve(pinned * 1024);
  const crossdyn::RowCallback on_row = [&history, pinned](const double* row) {
    if (history.size() + pinned <= history.capacity()) history.insert(history.end(), row, row + pinned);
  };
  const crossdyn::TreeState initial = crossdyn::TreeState::initial(system);
  long rhs = 0;
  for (auto _ : state) {
    history.clear();
    const crossdyn::RunResult r = crossdyn::simulate(*engine, system, initial, s, on_row);
    if (r.failure) {
      state.SkipWithError(r.failure->what());
      break;
    }
    rhs = r.stats.rhs_calls;
    benchmark::DoNotOptimize(history.data());
  }
  state.counters["rhs"] = static_cast<double>(rhs);
}

}  // namespace

void register_integrate_benchmarks() {
  static std::deque<crossdyn::System> systems;  // outlives the registered benchmarks
  try {
    systems.push_back(crossdyn::read_scene(std::string(CROSSDYN_SOURCE_DIR) + "/scenarios/spear1_case1.yaml"));
  } catch (const crossdyn::InputError& e) {
    std::cerr << "skipping integrate/: " << e.what() << '\n';
    return;
  }
  const crossdyn::System& system = systems.back();
  for (const std::string& engine : crossdyn::engine_names())
    for (const char* method : {"dop853", "dopri5", "rkf78", "cvode-adams"}) {
      const std::string name = "integrate/" + system.name + "/" + engine + "/" + method + "/1e-10";
      benchmark::RegisterBenchmark(name.c_str(), [&system, engine, method](benchmark::State& st) {
        bench_integrate(st, system, engine, method, 1e-10);
      })->Unit(benchmark::kMicrosecond);
    }
}
