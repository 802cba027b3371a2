// Right-hand-side cost of the Lagrange engine on flexible Systems built in code (a benchmark, not a
// test: speed is reported, never asserted). The modal inertia invariants are summed over the nodes
// once, at construction, so a body of 1000 nodes costs what a body of 10 nodes with the same modes
// costs.
//   build/tests/lagrange/lagrange_flex_bench
//   build/tests/lagrange/lagrange_flex_bench --benchmark_filter=nodes
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "formulations/lagrange/lagrange_engine.hpp"
#include "tests/lagrange/flex_scenes.hpp"

namespace {

using crossdyn::System;

// A free flexible body of `nodes` nodes and `modes` modes, spinning and vibrating.
System free_body(int nodes, int modes) {
  std::mt19937 g(5);
  System s;
  s.name = "free_flex";
  s.bodies = {crossdyn::test::random_flex_body("body", nodes, modes, 2.0, g)};
  s.joints = {crossdyn::test::free_joint(0, {0.3, -0.2, 0.4})};
  return s;
}

// A flexible base with two rigid payloads hinged at its end nodes (the shape of the paper's
// Example 2): `nodes` nodes, `modes` modes.
System beam_with_payloads(int nodes, int modes) {
  std::mt19937 g(6);
  System s;
  s.name = "beam_payloads";
  s.bodies = {crossdyn::test::random_flex_body("beam", nodes, modes, 5.0, g),
              crossdyn::test::make_body("payload1", 100, {12.5, 39.6, 39.6}),
              crossdyn::test::make_body("payload2", 100, {12.5, 39.6, 39.6})};
  s.joints = {crossdyn::test::free_joint(0, {0.0, 0.01, 0.0})};
  for (int k = 0; k < 2; ++k) {
    crossdyn::Joint j = crossdyn::test::joint_at(s, "joint" + std::to_string(k + 1),
                                                 crossdyn::JointType::Revolute, 0, k + 1,
                                                 k == 0 ? 0 : nodes - 1, -1, {}, {-1, 0, 0});
    j.axis_P = Eigen::Vector3d::UnitY();
    s.joints.push_back(j);
  }
  return s;
}

void bench_rhs(benchmark::State& state, const System& system) {
  crossdyn::lagrange::LagrangeEngine engine(system, {});
  std::mt19937 g(8);
  std::vector<double> x(static_cast<std::size_t>(engine.state_size())), xdot(x.size());
  engine.pack(crossdyn::test::random_flex_state(system, g), x.data());
  for (auto _ : state) {
    engine.rhs(0.0, x.data(), xdot.data());
    benchmark::DoNotOptimize(xdot.data());
    benchmark::ClobberMemory();
  }
  state.counters["states"] = static_cast<double>(x.size());
}

}  // namespace

int main(int argc, char** argv) {
  static std::vector<std::pair<std::string, System>> systems;
  for (int nodes : {10, 1000}) {
    systems.emplace_back("lagrange/free_flex/nodes:" + std::to_string(nodes) + "/modes:4",
                         free_body(nodes, 4));
    systems.emplace_back("lagrange/beam_payloads/nodes:" + std::to_string(nodes) + "/modes:4",
                         beam_with_payloads(nodes, 4));
  }
  systems.emplace_back("lagrange/flex_tree", crossdyn::test::flex_tree(true));
  for (const auto& [name, system] : systems)
    benchmark::RegisterBenchmark(name.c_str(),
                                 [&s = system](benchmark::State& st) { bench_rhs(st, s); });
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
