// Row storage (core/rows.hpp): rows stay in memory within the budget and go to an unlinked
// temporary file beyond it; either way they read back exactly, in order, any number of times,
// and nothing is left on disk.
#include <catch2/catch.hpp>

#include "core/integrate.hpp"
#include "core/rows.hpp"

#include <cstdlib>
#include <filesystem>
#include <unistd.h>

using namespace crossdyn;
namespace fs = std::filesystem;

namespace {

// Row k, column c: a value no two cells share, with all 64 bits in play.
double cell(std::size_t k, std::size_t c) { return static_cast<double>(k) * 1.0000001 + static_cast<double>(c) / 3.0; }

// Sets the row budget for a test and restores it.
struct Budget {
  explicit Budget(std::size_t bytes) : saved(row_memory_budget()) { set_row_memory_budget(bytes); }
  ~Budget() { set_row_memory_budget(saved); }
  std::size_t saved;
};

// TMPDIR pointed at a fresh folder for a test.
struct TempDir {
  TempDir() : path(fs::temp_directory_path() / ("crossdyn_rows_" + std::to_string(::getpid()))) {
    fs::create_directories(path);
    const char* old = std::getenv("TMPDIR");
    if (old) saved = old;
    ::setenv("TMPDIR", path.c_str(), 1);
  }
  ~TempDir() {
    if (saved.empty()) ::unsetenv("TMPDIR");
    else ::setenv("TMPDIR", saved.c_str(), 1);
    fs::remove_all(path);
  }
  std::size_t entries() const {
    return static_cast<std::size_t>(std::distance(fs::directory_iterator(path), fs::directory_iterator()));
  }
  fs::path path;
  std::string saved;
};

RunResult write_rows(std::size_t rows, std::size_t columns) {
  RunResult r;
  r.columns.resize(columns, "c");
  RowStore store(columns);
  std::vector<double> row(columns);
  for (std::size_t k = 0; k < rows; ++k) {
    for (std::size_t c = 0; c < columns; ++c) row[c] = cell(k, c);
    store.append(row.data());
  }
  CHECK(store.rows() == rows);
  r.store(store.finish());
  return r;
}

void check_rows(const RunResult& r, std::size_t rows, std::size_t columns) {
  REQUIRE(r.rows() == rows);
  for (int pass = 0; pass < 2; ++pass) {  // a reader starts from the first row every time
    RowReader reader = r.reader();
    std::size_t k = 0, bad = 0;
    while (const double* row = reader.next()) {
      for (std::size_t c = 0; c < columns; ++c) bad += row[c] != cell(k, c);
      ++k;
    }
    CHECK(k == rows);
    CHECK(bad == 0);
  }
  CHECK(r.at(rows / 2, columns - 1) == cell(rows / 2, columns - 1));
  std::size_t k = 0;
  r.for_each_row([&k](const double* row) { k += row[0] == cell(k, 0); });
  CHECK(k == rows);
}

}  // namespace

TEST_CASE("rows within the budget stay in memory, and their share of the budget is returned") {
  const std::size_t before = row_memory_in_use();
  {
    const RunResult r = write_rows(1000, 7);
    CHECK_FALSE(r.spill);
    CHECK(r.data.size() == 7000);
    CHECK(row_memory_in_use() >= before + 7000 * sizeof(double));
    check_rows(r, 1000, 7);
  }
  CHECK(row_memory_in_use() == before);
}

TEST_CASE("rows beyond the budget go to an unlinked temporary file and read back exactly") {
  TempDir tmp;
  for (std::size_t budget : {std::size_t{0}, std::size_t{100'000}}) {  // none, or part of the rows
    Budget b(budget);
    const std::size_t before = row_memory_in_use();
    // 20000 rows of 33 columns (5 MiB): several blocks of the file, an odd row size.
    const RunResult r = write_rows(20'000, 33);
    REQUIRE(r.spill);
    CHECK(r.data.empty());
    CHECK(row_memory_in_use() == before);  // spilled rows hold none of the budget
    CHECK(tmp.entries() == 0);             // no name on disk, even while the rows are in use
    check_rows(r, 20'000, 33);
  }
  CHECK(tmp.entries() == 0);
}

TEST_CASE("a row wider than a file block (1 MiB) is stored and read back") {
  TempDir tmp;
  Budget b(0);
  const RunResult r = write_rows(3, 200'000);
  REQUIRE(r.spill);
  check_rows(r, 3, 200'000);
}

TEST_CASE("a temporary folder that cannot be written is a RowStorageError naming it") {
  Budget b(0);
  const char* old = std::getenv("TMPDIR");
  const std::string saved = old ? old : "";
  ::setenv("TMPDIR", "/nonexistent/crossdyn", 1);
  RowStore store(2);
  const double row[2] = {1, 2};
  try {
    store.append(row);
    FAIL("no error");
  } catch (const RowStorageError& e) {
    CHECK(std::string(e.what()).find("'/nonexistent/crossdyn'") != std::string::npos);
  }
  if (saved.empty()) ::unsetenv("TMPDIR");
  else ::setenv("TMPDIR", saved.c_str(), 1);
}
