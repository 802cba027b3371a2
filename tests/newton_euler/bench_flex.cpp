// Right-hand-side cost of the Newton-Euler engine on flexible scenes built in code (speed is
// measured here and reported, never asserted in a test):
//   build/tests/newton_euler/newton_euler_flex_bench
// beam_nodes/N: a free flexible beam (4 modes: 2 per bending plane) carried by N nodes, with a
// rigid payload hinged at its top node and another at its bottom node (the shape of the paper's
// Example 2). The modal integrals are node sums done once at construction, so the cost should not
// depend on N. flexible_tree: every joint type at nodes (tests/newton_euler/ne_systems.hpp).
#include "formulations/newton_euler/newton_euler.hpp"

#include "tests/newton_euler/ne_systems.hpp"

#include <benchmark/benchmark.h>

#include <random>

namespace {

using namespace crossdyn;

System beam_with_payloads(int slices) {
  System s;
  s.name = "beam_nodes";
  s.bodies = {test::ne::flexible_beam("beam", 500, 10, slices, 2, 2, {1, 2, 3, 4}),
              test::ne::make_body("payload1", 100, Eigen::Vector3d(12.5, 39.6, 39.6).asDiagonal()),
              test::ne::make_body("payload2", 100, Eigen::Vector3d(12.5, 39.6, 39.6).asDiagonal())};
  s.joints.push_back(test::ne::free_joint(0));
  for (int k = 1; k <= 2; ++k) {
    Joint j;
    j.name = "joint" + std::to_string(k);
    j.type = JointType::Revolute;
    j.parent = 0;
    j.child = k;
    j.parent_node = test::ne::node_of(s, 0, k == 1 ? "top" : "bottom");
    j.p_PoJ_P = Eigen::Vector3d(0, 0, k == 1 ? 5 : -5);
    j.p_CoJ_C = Eigen::Vector3d(-1, 0, 0);
    j.axis_P = Eigen::Vector3d::UnitY();
    j.motor_revolute = {{0.0}, {Eigen::Matrix<double, 1, 1>(1.0)}};
    s.joints.push_back(j);
  }
  return s;
}

void bench_rhs(benchmark::State& state, const System& s) {
  auto e = make_newton_euler_engine(s, {});
  std::vector<double> x(static_cast<std::size_t>(e->state_size())), xdot(x.size());
  TreeState ts = TreeState::initial(s);
  std::mt19937 rng(1);
  test::ne::deform(s, ts, rng, 0.05, 0.1);
  e->pack(ts, x.data());
  for (auto _ : state) {
    e->rhs(0.0, x.data(), xdot.data());
    benchmark::DoNotOptimize(xdot.data());
    benchmark::ClobberMemory();
  }
  state.counters["states"] = static_cast<double>(x.size());
}

}  // namespace

int main(int argc, char** argv) {
  static const System n10 = beam_with_payloads(10), n1000 = beam_with_payloads(1000),
                      tree = test::ne::flexible_tree();
  benchmark::RegisterBenchmark("newton-euler/beam_nodes/10", [](benchmark::State& s) { bench_rhs(s, n10); });
  benchmark::RegisterBenchmark("newton-euler/beam_nodes/1000", [](benchmark::State& s) { bench_rhs(s, n1000); });
  benchmark::RegisterBenchmark("newton-euler/flexible_tree", [](benchmark::State& s) { bench_rhs(s, tree); });
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
