// Micro-benchmarks: one right-hand-side call per engine per scene, at the scene's initial state.
// Speed is measured here and reported, never asserted in a test.
//   build/crossdyn_bench                       all engines, every committed scene (scenarios/)
//   build/crossdyn_bench --benchmark_filter=kane/spear1_case1
#include <benchmark/benchmark.h>

#include "core/engine.hpp"
#include "harness/engines.hpp"
#include "core/errors.hpp"
#include "core/scene/scene.hpp"

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <memory>
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

}  // namespace

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
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
