// Right-hand-side cost of the Kane engine on flexible bodies against their number of nodes (a
// benchmark, never a test: speed is reported, not asserted). The modal integrals are built at
// construction, so the rhs cost should not grow with the nodes:
//   build/tests/kane/kane_flex_bench                       every case
//   build/tests/kane/kane_flex_bench --benchmark_filter=nodes:1000
// Cases: a free flexible body with 4 modes, alone ("free") and carrying a rigid body on a
// revolute joint at one of its nodes and a flexible body with 2 modes at another ("tree").
#include <benchmark/benchmark.h>

#include "formulations/kane/kane_engine.hpp"
#include "tests/kane/kane_flex_systems.hpp"

#include <random>
#include <string>
#include <vector>

namespace {

using namespace crossdyn;
using namespace crossdyn::test::kane;

System flexible_system(int nodes, bool tree) {
  std::mt19937 g(7);
  System s;
  s.name = (tree ? "tree" : "free") + std::string("/nodes:") + std::to_string(nodes);
  s.bodies.push_back(random_flex_body("beam", nodes, 4, g, 2.0, 0.3, 0.3, 50.0, 0.01));
  s.joints.push_back(free_joint("base", 0, Eigen::Vector3d(0.1, 0.2, 0.3)));
  if (tree) {
    s.bodies.push_back(rigid_body("payload", 20, diag(1, 2, 3)));
    Joint j = joint("hinge", JointType::Revolute, 0, 1, node_position(s, 0, 0),
                    Eigen::Vector3d(0.5, 0, 0));
    j.parent_node = 0;
    j.rate0 = 0.2;
    s.joints.push_back(j);
    s.bodies.push_back(random_flex_body("panel", nodes, 2, g, 1.0, 0.3, 0.3, 20.0, 0.01));
    Joint k =
        joint("mount", JointType::Spherical, 0, 2, node_position(s, 0, 1), node_position(s, 2, 0));
    k.parent_node = 1;
    k.child_node = 0;
    s.joints.push_back(k);
  }
  return s;
}

void bench_rhs(benchmark::State& state, const System& system) {
  kane::KaneEngine engine(system, {});
  std::vector<double> x = packed(engine, flex_state(system, 0.05, 0.2)), xdot(x.size());
  for (auto _ : state) {
    engine.rhs(0.0, x.data(), xdot.data());
    benchmark::DoNotOptimize(xdot.data());
    benchmark::ClobberMemory();
  }
  state.counters["states"] = static_cast<double>(x.size());
}

}  // namespace

int main(int argc, char** argv) {
  static std::vector<System> systems;
  for (bool tree : {false, true})
    for (int nodes : {10, 100, 1000}) systems.push_back(flexible_system(nodes, tree));
  for (const System& s : systems)
    benchmark::RegisterBenchmark(("kane/" + s.name).c_str(),
                                 [&s](benchmark::State& st) { bench_rhs(st, s); });
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
