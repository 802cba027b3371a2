// rhs() and after_step() run once per stage and once per step: they must not touch the heap.
// This program replaces the global operator new to count allocations (Eigen's own heap goes
// through malloc, but the engine uses only fixed-size Eigen types, so containers are what could
// allocate).
#include "formulations/newton_euler/newton_euler.hpp"

#include "core/scene/scene.hpp"
#include "tests/newton_euler/ne_prescribed_scenes.hpp"
#include "tests/newton_euler/ne_systems.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>

#include <atomic>
#include <cstdlib>
#include <new>
#include <random>

// GCC 12 inlines the test systems' std::vector code (ne_systems.hpp) next to the replaced
// operators below and then reports their malloc/free pairing as "mismatched" (a false positive:
// every form here allocates with malloc and releases with free).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif

namespace {
std::atomic<long> g_allocations{0};
}  // namespace

// Every replaceable (non-aligned) form, so that allocation and release always pair malloc/free
// (AddressSanitizer checks the pairing).
void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  return std::malloc(n == 0 ? 1 : n);
}
void* operator new[](std::size_t n, const std::nothrow_t& t) noexcept { return operator new(n, t); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }

TEST_CASE("newton-euler: rhs and after_step do not allocate", "[newton_euler][allocation]") {
  using namespace crossdyn;
  for (const char* scene : {"spear1_case1", "chain5", "hub_two_panels", "chain_motor"}) {
    const System s = read_scene(test::scene_path(scene));
    auto e = make_newton_euler_engine(s, {});
    std::vector<double> x(static_cast<std::size_t>(e->state_size())), xdot(x.size());
    e->pack(TreeState::initial(s), x.data());
    std::mt19937 rng(1);
    std::normal_distribution<double> noise(0.0, 1e-6);
    const long before = g_allocations.load();
    for (int k = 0; k < 100; ++k) {
      e->rhs(0.01 * k, x.data(), xdot.data());
      for (double& v : x) v += noise(rng);  // off the manifold: after_step must project
      e->after_step(0.01 * k, x.data());
    }
    const long allocations = g_allocations.load() - before;  // before INFO, which allocates
    INFO(scene);
    CHECK(allocations == 0);
  }
  // Flexible bodies with joints at nodes (built in code): variable-size KKT blocks, modal terms.
  for (const System& s : {test::ne::flexible_tree(), test::ne::flexible_chain(4)}) {
    auto e = make_newton_euler_engine(s, {});
    std::vector<double> x(static_cast<std::size_t>(e->state_size())), xdot(x.size());
    TreeState ts = TreeState::initial(s);
    std::mt19937 rng(2);
    test::ne::deform(s, ts, rng, 0.1, 0.3);
    e->pack(ts, x.data());
    std::normal_distribution<double> noise(0.0, 1e-6);
    const long before = g_allocations.load();
    for (int k = 0; k < 100; ++k) {
      e->rhs(0.01 * k, x.data(), xdot.data());
      for (double& v : x) v += noise(rng);
      e->after_step(0.01 * k, x.data());
    }
    const long allocations = g_allocations.load() - before;
    INFO(s.name);
    CHECK(allocations == 0);
  }
  // Prescribed joints (inside the tree, and the base) and geometric stiffening (issue 13).
  for (const std::string& text :
       {test::ne::scan_platform_text(), test::ne::spinup_beam_text(true),
        test::ne::spinup_beam_text(false), test::ne::free_spinning_beam_text()}) {
    const System s = read_scene_text(text, "allocation");
    auto e = make_newton_euler_engine(s, {});
    std::vector<double> x(static_cast<std::size_t>(e->state_size())), xdot(x.size());
    TreeState ts = TreeState::initial(s);
    std::mt19937 rng(3);
    test::ne::deform(s, ts, rng, 0.1, 0.3);
    e->pack(ts, x.data());
    std::normal_distribution<double> noise(0.0, 1e-6);
    const long before = g_allocations.load();
    for (int k = 0; k < 100; ++k) {
      e->rhs(0.01 * k, x.data(), xdot.data());
      for (double& v : x) v += noise(rng);
      e->after_step(0.01 * k, x.data());
    }
    const long allocations = g_allocations.load() - before;
    INFO(s.name);
    CHECK(allocations == 0);
  }
  // Gravity (issue 28): uniform and orbit, on the flexible tree and a geometrically stiffened
  // body (its orbit loads are node sums per state).
  for (const Environment::Kind kind : {Environment::Kind::Uniform, Environment::Kind::Orbit}) {
    for (System s : {test::ne::flexible_tree(),
                     read_scene_text(test::ne::free_spinning_beam_text(), "allocation")}) {
      s.environment.kind = kind;
      s.environment.g_N = Eigen::Vector3d(0.3, -9.81, 1.0);
      s.environment.mu = 3.986004418e14;
      s.environment.radius = 7.0e6;
      s.environment.inclination = 0.5;
      auto e = make_newton_euler_engine(s, {});
      std::vector<double> x(static_cast<std::size_t>(e->state_size())), xdot(x.size());
      TreeState ts = TreeState::initial(s);
      std::mt19937 rng(4);
      test::ne::deform(s, ts, rng, 0.1, 0.3);
      e->pack(ts, x.data());
      std::normal_distribution<double> noise(0.0, 1e-6);
      const long before = g_allocations.load();
      for (int k = 0; k < 100; ++k) {
        e->rhs(0.01 * k, x.data(), xdot.data());
        for (double& v : x) v += noise(rng);
        e->after_step(0.01 * k, x.data());
      }
      const long allocations = g_allocations.load() - before;
      INFO(s.name << (kind == Environment::Kind::Orbit ? " on an orbit" : " under uniform gravity"));
      CHECK(allocations == 0);
    }
  }
  // Control: the counter does see allocations.
  const long before = g_allocations.load();
  std::vector<double> v(10);
  CHECK(g_allocations.load() - before == 1);
}
