// Micro-benchmarks of CSV output (issue 12: <= 30 ns per value, exact round trip). Each formats
// rows of doubles like a run's (an output time, then full-precision state values of mixed
// magnitude) through write_csv_row into a checked FdStreamBuf on /dev/null, so the figure includes
// the stream and the buffered, checked writes but no disk. The counter per_value is CPU time per
// value written. csv_row_printf17g is the previous formatting ("%.17g" through the stream),
// kept as a reference for the same machine and load.
//   build/crossdyn_bench --benchmark_filter=csv_row
#include <benchmark/benchmark.h>

#include "core/output.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <ostream>
#include <random>
#include <stdexcept>
#include <vector>

namespace {

constexpr std::size_t kRows = 256;

// kRows rows of `columns` values: t = 0.05 k, then values ~ N(0, 1) * 10^U{-3..3}.
std::vector<double> sample_rows(std::size_t columns) {
  std::mt19937_64 random(12);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_int_distribution<int> decade(-3, 3);
  std::vector<double> rows(kRows * columns);
  for (std::size_t k = 0; k < kRows; ++k) {
    rows[k * columns] = 0.05 * static_cast<double>(k);
    for (std::size_t c = 1; c < columns; ++c)
      rows[k * columns + c] = normal(random) * std::pow(10.0, decade(random));
  }
  return rows;
}

// A checked stream on /dev/null, as `crossdyn run -o /dev/null` writes.
struct NullOutput {
  NullOutput() : fd(::open("/dev/null", O_WRONLY | O_CLOEXEC)), buf(fd, "'/dev/null'"), out(&buf) {
    if (fd < 0) throw std::runtime_error("cannot open /dev/null");
  }
  ~NullOutput() {
    out.flush();
    ::close(fd);
  }
  int fd;
  crossdyn::FdStreamBuf buf;
  std::ostream out;
};

void set_counters(benchmark::State& state, std::size_t columns) {
  const auto values = static_cast<double>(state.iterations() * kRows * columns);
  // CPU seconds per value, printed with its SI prefix ("38.2ns").
  state.counters["per_value"] = benchmark::Counter(
      values, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.SetItemsProcessed(static_cast<std::int64_t>(values));
}

void csv_row(benchmark::State& state) {
  const auto columns = static_cast<std::size_t>(state.range(0));
  const std::vector<double> rows = sample_rows(columns);
  NullOutput null;
  for (auto _ : state)
    for (std::size_t k = 0; k < kRows; ++k) crossdyn::write_csv_row(null.out, &rows[k * columns], columns);
  crossdyn::check_written(null.out);
  set_counters(state, columns);
}

void csv_row_printf17g(benchmark::State& state) {
  const auto columns = static_cast<std::size_t>(state.range(0));
  const std::vector<double> rows = sample_rows(columns);
  NullOutput null;
  char b[40];
  for (auto _ : state)
    for (std::size_t k = 0; k < kRows; ++k) {
      for (std::size_t c = 0; c < columns; ++c) {
        std::snprintf(b, sizeof b, "%.17g", rows[k * columns + c]);
        null.out << (c ? "," : "") << b;
      }
      null.out << '\n';
    }
  crossdyn::check_written(null.out);
  set_counters(state, columns);
}

// 37 columns: a spear1_case1 row (3 bodies, 2 joints, H, E and the engine's own columns); 100: a
// large chain. Every value here has a full 17-digit mantissa, the slow case: real rows also hold
// exact zeros and ones, which format faster.
BENCHMARK(csv_row)->Arg(37)->Arg(100);
BENCHMARK(csv_row_printf17g)->Arg(37)->Arg(100);

}  // namespace
