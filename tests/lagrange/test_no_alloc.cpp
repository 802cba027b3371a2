// rhs() allocates nothing. This program defines malloc, calloc, realloc and aligned_alloc, which
// take precedence over the C library's for every caller (operator new in libstdc++, Eigen's
// aligned_malloc), forwards them to glibc's own entry points and counts the calls made while
// counting is on. Not built under AddressSanitizer, which intercepts these functions itself.
#include <atomic>
#include <catch2/catch.hpp>
#include <cstdlib>
#include <random>
#include <vector>

#include "formulations/lagrange/lagrange_engine.hpp"
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
#endif
