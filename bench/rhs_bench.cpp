// Micro-benchmarks: one right-hand-side call per engine per scene, at the scene's initial state.
// Speed is measured here and reported, never asserted in a test.
//   build/crossdyn_bench                       all engines, every committed scene (scenarios/)
//   build/crossdyn_bench --benchmark_filter=kane/spear1_case1
#include <benchmark/benchmark.h>

#include "core/engine.hpp"
#include "harness/engines.hpp"
#include "harness/study.hpp"
#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "formulations/kane/kane_engine.hpp"

#include <algorithm>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace {

void bench_rhs(benchmark::State& state, const crossdyn::System& system, const std::string& name) {
  std::unique_ptr<crossdyn::Engine> engine = crossdyn::make_engine(name, system);
  std::vector<double> x(static_cast<std::size_t>(engine->state_size()));
  std::vector<double> xdot(x.size());
  engine->pack(crossdyn::TreeState::initial(system), x.data());
  double t = 0.0;
  for (auto _ : state) {
    engine->rhs(t, x.data(), xdot.data());
    benchmark::DoNotOptimize(xdot.data());
    benchmark::ClobberMemory();
  }
  state.counters["states"] = static_cast<double>(x.size());
}

// The Kane engine with each of its solvers forced (formulations/kane/README.md, "Two
// solvers"): kane_composite/SCENE and kane_order_n/SCENE, on every committed rigid scene and on
// chainN as scripts/make_chain.py N writes it (N = 2 ... 128; the crossover of the automatic
// choice, KaneEngine::kOrderNMinDepth, is read from these):
//   build/crossdyn_bench --benchmark_filter='kane_(composite|order_n)/chain'
void bench_kane_solver(benchmark::State& state, const crossdyn::System& system,
                       crossdyn::kane::KaneSolver solver) {
  std::optional<crossdyn::kane::KaneEngine> made;
  try {
    made.emplace(system, crossdyn::EngineOptions{}, solver);
  } catch (const crossdyn::InputError& e) {  // e.g. the order-N solver and a prescribed joint
    state.SkipWithError(e.what());
    return;
  }
  crossdyn::kane::KaneEngine& engine = *made;
  std::vector<double> x(static_cast<std::size_t>(engine.state_size()));
  std::vector<double> xdot(x.size());
  engine.pack(crossdyn::TreeState::initial(system), x.data());
  for (auto _ : state) {
    engine.rhs(0.0, x.data(), xdot.data());
    benchmark::DoNotOptimize(xdot.data());
    benchmark::ClobberMemory();
  }
  state.counters["states"] = static_cast<double>(x.size());
}

// chainN, generated in-process by the harness (harness/study.hpp chain_scene_text: the same text as
// scripts/make_chain.py N).
crossdyn::System make_chain(int n) {
  return crossdyn::read_scene_text(crossdyn::harness::chain_scene_text(n), "chain" + std::to_string(n) + " (generated)");
}

void register_kane_solvers(const std::vector<crossdyn::System>& committed) {
  static std::deque<crossdyn::System> systems;  // outlives the registered benchmarks
  for (const crossdyn::System& s : committed) systems.push_back(s);
  for (int n : {2, 3, 4, 5, 6, 8, 20, 40, 80, 128}) {
    try {
      systems.push_back(make_chain(n));
    } catch (const crossdyn::InputError& e) {
      std::cerr << "skipping chain" << n << ": " << e.what() << '\n';
    }
  }
  std::vector<std::string> seen;
  for (const crossdyn::System& system : systems) {
    if (std::find(seen.begin(), seen.end(), system.name) != seen.end())
      continue;  // chain5 is committed and generated
    seen.push_back(system.name);
    if (std::any_of(system.bodies.begin(), system.bodies.end(),
                    [](const crossdyn::Body& b) { return b.flex; }))
      continue;  // the order-N solver is for rigid bodies only
    for (const auto solver : {crossdyn::kane::KaneSolver::Composite,
                              crossdyn::kane::KaneSolver::OrderN}) {
      const std::string name = solver == crossdyn::kane::KaneSolver::OrderN ? "kane_order_n/"
                                                                             : "kane_composite/";
      benchmark::RegisterBenchmark((name + system.name).c_str(),
                                   [&system, solver](benchmark::State& s) {
                                     bench_kane_solver(s, system, solver);
                                   });
    }
  }
}

}  // namespace

void register_integrate_benchmarks();  // integrate_bench.cpp

int main(int argc, char** argv) {
  static std::vector<crossdyn::System> systems;  // outlives the registered benchmarks
  std::vector<std::filesystem::path> scenes;
  for (const auto& f :
       std::filesystem::directory_iterator(std::string(CROSSDYN_SOURCE_DIR) + "/scenarios"))
    if (f.path().extension() == ".yaml") scenes.push_back(f.path());
  std::sort(scenes.begin(), scenes.end());
  systems.reserve(scenes.size());
  for (const auto& scene : scenes) {
    try {
      systems.push_back(crossdyn::read_scene(scene.string()));
    } catch (const crossdyn::InputError& e) {
      std::cerr << "skipping " << scene << ": " << e.what() << '\n';
    }
  }
  for (const crossdyn::System& system : systems)
    for (const std::string& name : crossdyn::engine_names()) {
      try {
        crossdyn::make_engine(name, system);
      } catch (const crossdyn::InputError& e) {
        std::cerr << "skipping " << name << " on " << system.name << ": " << e.what() << '\n';
        continue;
      }
      benchmark::RegisterBenchmark((name + "/" + system.name).c_str(),
                                   [&system, name](benchmark::State& s) { bench_rhs(s, system, name); });
    }
  register_kane_solvers(systems);
  register_integrate_benchmarks();
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
