// CSV formatting and atomic files (nothing half-written: issue 6).
#include <catch2/catch.hpp>

#include "core/errors.hpp"
#include "core/output.hpp"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

using namespace crossdyn;
namespace fs = std::filesystem;

TEST_CASE("values are written with 17 significant digits and read back exactly") {
  for (double v : {M_PI, -1.0 / 3.0, 6.02214076e23, 5e-324, 0.1}) {
    CHECK(std::strtod(format_value(v).c_str(), nullptr) == v);
  }
  std::ostringstream s;
  const double row[3] = {0.0, 1.5, -2.25};
  write_csv_header(s, {"t", "a", "b"});
  write_csv_row(s, row, 3);
  CHECK(s.str() == "t,a,b\n0,1.5,-2.25\n");
}

TEST_CASE("an AtomicFile appears only on commit and an abandoned one leaves the old file") {
  const fs::path dir = fs::temp_directory_path() / "crossdyn_test_output";
  fs::create_directories(dir);
  const fs::path p = dir / "out.csv";
  fs::remove(p);
  {
    AtomicFile f(p.string());
    f.stream() << "partial";
    CHECK_FALSE(fs::exists(p));
  }  // abandoned: no file, no temporary left behind
  CHECK_FALSE(fs::exists(p));
  CHECK(fs::is_empty(dir));
  write_file_atomic(p.string(), "first\n");
  {
    AtomicFile f(p.string());
    f.stream() << "second, never committed";
  }
  std::ifstream in(p);
  std::string line;
  std::getline(in, line);
  CHECK(line == "first");
  fs::remove_all(dir);
}

TEST_CASE("an AtomicFile in a folder that does not exist is an InputError naming the path") {
  try {
    AtomicFile f("/nonexistent-crossdyn-dir/x.csv");
    FAIL("no error");
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).find("/nonexistent-crossdyn-dir/x.csv") != std::string::npos);
  }
}
