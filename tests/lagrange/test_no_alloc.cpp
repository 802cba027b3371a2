// rhs() allocates nothing. This program defines malloc, calloc, realloc and aligned_alloc, which
// take precedence over the C library's for every caller (operator new in libstdc++, Eigen's
// aligned_malloc), forwards them to glibc's own entry points and counts the calls made while
// counting is on. Not built under AddressSanitizer, which intercepts these functions itself.
#include <atomic>
#include <catch2/catch.hpp>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "formulations/lagrange/lagrange_engine.hpp"
#include "core/scene/scene.hpp"
#include "tests/lagrange/flex_scenes.hpp"
#include "tests/lagrange/scenes.hpp"

#if defined(__SANITIZE_ADDRESS__)
#define CROSSDYN_COUNT_MALLOC 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define CROSSDYN_COUNT_MALLOC 0
#endif
#endif
#ifndef CROSSDYN_COUNT_MALLOC
#define CROSSDYN_COUNT_MALLOC 1
#endif

#if CROSSDYN_COUNT_MALLOC
namespace {
std::atomic<long> g_allocations{0};
std::atomic<bool> g_counting{false};
void count() {
  if (g_counting.load(std::memory_order_relaxed))
    g_allocations.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void* malloc(std::size_t size) {
  count();
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) {
  count();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) {
  count();
  return __libc_realloc(p, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  count();
  return __libc_memalign(alignment, size);
}
}

TEST_CASE("lagrange: rhs() does not allocate", "[lagrange][alloc]") {
  using crossdyn::lagrange::LagrangeEngine;
  // The counter works: a vector allocates.
  g_allocations = 0;
  g_counting = true;
  {
    std::vector<double> v(10);
    v[3] = 1.0;
  }
  g_counting = false;
  REQUIRE(g_allocations.load() >= 1);

  std::mt19937 g(31);
  for (const crossdyn::System& s :
       {crossdyn::test::spear1(), crossdyn::test::chain(12), crossdyn::test::mixed_tree(true),
        crossdyn::test::flex_tree(true)}) {
    LagrangeEngine e(s, {});
    std::vector<double> x(static_cast<std::size_t>(e.state_size())), xdot(x.size());
    e.pack(crossdyn::test::random_flex_state(s, g), x.data());
    e.rhs(0.0, x.data(), xdot.data());  // warm-up
    g_allocations = 0;
    g_counting = true;
    for (int k = 0; k < 10; ++k) e.rhs(0.1 * k, x.data(), xdot.data());
    g_counting = false;
    INFO("scene " << s.name);
    CHECK(g_allocations.load() == 0);
  }
}
TEST_CASE("lagrange: rhs() does not allocate with prescribed joints and geometric stiffening",
          "[lagrange][alloc][prescribed]") {
  using crossdyn::lagrange::LagrangeEngine;
  // A prescribed base carrying a stiffened clamped beam at a node, and a free bus with an
  // internal prescribed hinge.
  const std::string beam = R"(name: alloc_beam
bodies:
  - name: hub
    mass: 100 kg
    inertia: [10, 10, 10]
  - name: beam
    flexible:
      beam:
        length: 10 m
        axis: x
        mass_per_length: 1.2
        section: [0, 0.02 m, 0.02 m]
        bending:
          y: {modes: 3, EI: 14000}
        boundary: clamped-bottom
        slices: 10
        geometric_stiffening: true
joints:
  - name: spin
    type: revolute
    child: hub
    parent_point: [0, 0, 0]
    child_point: [0, 0, 0]
    axis: [0, 0, 1]
    prescribed: {profile: spin-up, rate: 10 rad/s, ramp_time: 15 s}
  - name: root
    type: fixed
    parent: hub
    parent_point: [0, 0, 0]
    child: beam
    child_node: bottom
run:
  duration: 1 s
  output_step: 0.1 s
)";
  const std::string scan = R"(name: alloc_scan
bodies:
  - name: bus
    mass: 800 kg
    inertia: [600, 500, 400]
  - name: platform
    mass: 60 kg
    inertia: [2.6, 5.8, 6.8]
joints:
  - name: base
    type: free
    child: bus
  - name: scan
    type: revolute
    parent: bus
    parent_point: [0.5, 0, 0]
    child: platform
    child_point: [-0.3, 0, 0]
    axis: [1, 0, 0]
    prescribed: {profile: spin-up, rate: 2 rad/s, ramp_time: 5 s}
run:
  duration: 1 s
  output_step: 0.1 s
)";
  for (const std::string& text : {beam, scan}) {
    const crossdyn::System s = crossdyn::read_scene_text(text, "alloc");
    LagrangeEngine e(s, {});
    std::vector<double> x(static_cast<std::size_t>(e.state_size())), xdot(x.size());
    crossdyn::TreeState st = crossdyn::TreeState::initial(s);
    for (auto& v : st.eta) v.setConstant(0.01);
    e.pack(st, x.data());
    e.rhs(0.0, x.data(), xdot.data());  // warm-up
    g_allocations = 0;
    g_counting = true;
    for (int k = 0; k < 10; ++k) e.rhs(0.7 * k, x.data(), xdot.data());
    g_counting = false;
    INFO("scene " << s.name);
    CHECK(g_allocations.load() == 0);
  }
}
// output_row() (issue 26: an evaluation of the accelerations and the joint loads per row) does not
// allocate either: a run writes thousands of rows.
TEST_CASE("lagrange: output_row() does not allocate", "[lagrange][alloc][loads]") {
  using crossdyn::lagrange::LagrangeEngine;
  std::mt19937 g(32);
  for (const crossdyn::System& s :
       {crossdyn::test::spear1(), crossdyn::test::chain(12), crossdyn::test::mixed_tree(true),
        crossdyn::test::flex_tree(true)}) {
    LagrangeEngine e(s, {});
    std::vector<double> x(static_cast<std::size_t>(e.state_size()));
    std::vector<double> row(e.layout().size());
    e.pack(crossdyn::test::random_flex_state(s, g), x.data());
    e.output_row(0.0, x.data(), row.data());  // warm-up
    g_allocations = 0;
    g_counting = true;
    for (int k = 0; k < 10; ++k) e.output_row(0.1 * k, x.data(), row.data());
    g_counting = false;
    INFO("scene " << s.name);
    CHECK(g_allocations.load() == 0);
  }
}
// With an environment (issue 28; gravity.cpp): rhs() and output_row() still allocate nothing,
// uniform gravity and an orbit, rigid, flexible and stiffened flexible bodies.
TEST_CASE("lagrange: rhs() and output_row() do not allocate under gravity",
          "[lagrange][alloc][gravity]") {
  using crossdyn::lagrange::LagrangeEngine;
  std::mt19937 g(33);
  crossdyn::Environment uniform, orbit;
  uniform.kind = crossdyn::Environment::Kind::Uniform;
  uniform.g_N = {0.1, -9.8, 0.3};
  orbit.kind = crossdyn::Environment::Kind::Orbit;
  orbit.radius = 7.0e6;
  orbit.mu = 3.986e14;
  orbit.inclination = 0.5;
  for (const crossdyn::Environment& env : {uniform, orbit})
    for (crossdyn::System s :
         {crossdyn::test::spear1(), crossdyn::test::flex_tree(true),
          crossdyn::test::with_stiffening(crossdyn::test::flex_tree(true))}) {
      s.environment = env;
      LagrangeEngine e(s, {});
      std::vector<double> x(static_cast<std::size_t>(e.state_size())), xdot(x.size());
      std::vector<double> row(e.layout().size());
      e.pack(crossdyn::test::random_flex_state(s, g), x.data());
      e.rhs(0.0, x.data(), xdot.data());  // warm-up
      e.output_row(0.0, x.data(), row.data());
      g_allocations = 0;
      g_counting = true;
      for (int k = 0; k < 10; ++k) {
        e.rhs(0.1 * k, x.data(), xdot.data());
        e.output_row(0.1 * k, x.data(), row.data());
      }
      g_counting = false;
      INFO("scene " << s.name << (env.orbit() ? " on an orbit" : " under uniform gravity"));
      CHECK(g_allocations.load() == 0);
    }
}
#endif
