// CSV formatting and atomic files (nothing half-written: issue 6).
#include <catch2/catch.hpp>

#include "core/errors.hpp"
#include "core/output.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

using namespace crossdyn;
namespace fs = std::filesystem;

namespace {

// The bits of a double (so -0 and 0, and NaN payloads, are told apart).
std::uint64_t bits_of(double v) {
  std::uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

double double_of(std::uint64_t b) {
  double v;
  std::memcpy(&v, &b, sizeof v);
  return v;
}

// Significant digits of a formatted finite value ("-1.25e-07" -> 3, "0.05" -> 1, "100" -> 1).
int significant_digits(const std::string& text) {
  std::string mantissa = text.substr(0, text.find_first_of("eE"));
  std::string digits;
  for (char c : mantissa)
    if (c >= '0' && c <= '9') digits += c;
  const auto first = digits.find_first_not_of('0');
  if (first == std::string::npos) return 1;
  digits = digits.substr(first);
  // Trailing zeros of an integer written in fixed notation ("100") are not significant.
  while (digits.size() > 1 && digits.back() == '0') digits.pop_back();
  return static_cast<int>(digits.size());
}

// Finite doubles from random bit patterns (every exponent, subnormals included), plus the edges.
std::vector<double> test_values() {
  std::vector<double> values = {0.0, -0.0, 0.1, 0.05, -1.0 / 3.0, M_PI, 6.02214076e23, 1e-300, 1e300,
                                5e-324, -5e-324,
                                std::numeric_limits<double>::min(),
                                std::numeric_limits<double>::max(),
                                std::numeric_limits<double>::lowest(),
                                std::numeric_limits<double>::denorm_min(),
                                std::nextafter(std::numeric_limits<double>::min(), 0.0),
                                std::nextafter(1.0, 2.0), std::nextafter(1.0, 0.0), 9007199254740993.0,
                                123456789012345680000.0, 1e21, 1e22, 1e23, 2.2250738585072014e-308};
  std::mt19937_64 random(20261123);
  for (int i = 0; i < 100000; ++i) {
    const double v = double_of(random());
    if (std::isfinite(v)) values.push_back(v);
  }
  // Subnormals and values of simulation-like magnitude.
  std::uniform_int_distribution<std::uint64_t> subnormal(1, (std::uint64_t{1} << 52) - 1);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int i = 0; i < 20000; ++i) {
    values.push_back(double_of(subnormal(random)));
    values.push_back(-double_of(subnormal(random)));
    values.push_back(normal(random) * std::pow(10.0, static_cast<int>(random() % 13) - 6));
  }
  return values;
}

// The fewest significant digits D (1 to 17) with which "%.{D-1}e" reads back as v: that text.
std::string shortest_scientific(double v) {
  char b[512];  // %e of a double with 16 decimals fits in 32; the compiler cannot tell
  for (int digits = 1; digits <= 17; ++digits) {
    std::snprintf(b, sizeof b, "%.*e", digits - 1, v);
    if (std::strtod(b, nullptr) == v) break;
  }
  return b;
}

}  // namespace

TEST_CASE("every value is written in the shortest text that reads back as the same double") {
  std::size_t checked = 0, failures = 0;
  for (const double v : test_values()) {
    const std::string text = format_value(v);
    const double back = std::strtod(text.c_str(), nullptr);
    // Exact round trip, bit for bit (the sign of zero included).
    if (bits_of(back) != bits_of(v)) {
      if (++failures <= 5) FAIL_CHECK("'" << text << "' reads back as a different double");
      continue;
    }
    // Shortest: no longer than the scientific form with the fewest digits that reads back, and
    // in scientific notation no more digits than it. (Fixed notation wins when it is no longer,
    // and may then show more digits: 1.2345678901234568e+20 is written 123456789012345683968,
    // the exact integer, as C++17 to_chars specifies.)
    const std::string sci = shortest_scientific(v);
    const int n = significant_digits(text);
    if (text.size() > sci.size() ||
        (text.find('e') != std::string::npos && n > significant_digits(sci))) {
      if (++failures <= 5) FAIL_CHECK("'" << text << "' is not the shortest: '" << sci << "' reads back too");
      continue;
    }
    if (text.find('e') != std::string::npos) CHECK(n <= 17);
    ++checked;
  }
  CHECK(failures == 0);
  CHECK(checked > 100000);
}

TEST_CASE("CSV numbers: shortest text, fixed or scientific, signs and non-finite values") {
  CHECK(format_value(0.05) == "0.05");  // "%.17g" wrote 0.050000000000000003
  CHECK(format_value(0.1) == "0.1");
  CHECK(format_value(0.0) == "0");
  CHECK(format_value(-0.0) == "-0");
  CHECK(format_value(5.0) == "5");
  CHECK(format_value(-2.25) == "-2.25");
  CHECK(format_value(1e-300) == "1e-300");
  CHECK(format_value(5e-324) == "5e-324");
  CHECK(format_value(1e22) == "1e+22");
  CHECK(format_value(std::numeric_limits<double>::max()) == "1.7976931348623157e+308");
  CHECK(format_value(-2.2250738585072014e-308).size() == 24);  // the longest, < kMaxValueChars
  CHECK(format_value(std::numeric_limits<double>::infinity()) == "inf");
  CHECK(format_value(-std::numeric_limits<double>::infinity()) == "-inf");
  CHECK(format_value(std::numeric_limits<double>::quiet_NaN()) == "nan");
  for (const double v : test_values()) {
    char b[kMaxValueChars + 1];
    b[kMaxValueChars] = '#';
    char* const end = format_value_to(b, v);
    REQUIRE(end - b <= 24);
    CHECK(std::string(b, end) == format_value(v));
    CHECK(b[kMaxValueChars] == '#');
  }
}

namespace {

// std::to_chars's own spelling of v (the formatter before issue 12's fast path: the reference).
std::string to_chars_text(double v) {
  char b[64];
  return std::string(b, std::to_chars(b, b + sizeof b, v).ptr);
}

// Doubles of every kind for the comparison with std::to_chars: random bit patterns (every
// exponent, mostly 16-17 significant digits), short decimals of 1 to 17 digits at every exponent
// (the fixed/scientific choice: 1e-05 against 0.0001, 1e+21 against 100000000000000000000),
// integers below and above 2^53, powers of two and of ten with their neighbours, subnormals.
std::vector<double> spelling_values() {
  std::vector<double> values = test_values();
  std::mt19937_64 random(1212);
  for (int i = 0; i < 1000000; ++i) values.push_back(double_of(random()));
  // Short decimals: d digits, decimal exponent e, over the whole range.
  std::uniform_int_distribution<int> digits(1, 17), exponent(-340, 310), small_exponent(-30, 30);
  for (int i = 0; i < 600000; ++i) {
    const int d = digits(random);
    std::uint64_t m = random() % 9 + 1;
    for (int k = 1; k < d; ++k) m = m * 10 + random() % 10;
    const std::string text =
        std::to_string(m) + "e" + std::to_string(i % 2 ? exponent(random) : small_exponent(random));
    values.push_back(std::strtod(text.c_str(), nullptr));
  }
  for (int k = -325; k <= 309; ++k) {
    const double p = std::pow(10.0, k);
    for (double v : {p, std::nextafter(p, 0.0), std::nextafter(p, HUGE_VAL), 1.5 * p, 9.99 * p})
      values.push_back(v);
  }
  for (int k = -1074; k <= 1023; ++k) {
    const double p = std::ldexp(1.0, k);
    for (double v : {p, std::nextafter(p, 0.0), std::nextafter(p, HUGE_VAL)}) values.push_back(v);
  }
  for (std::uint64_t i = 0; i <= 100000; ++i) values.push_back(static_cast<double>(i));
  for (int i = 0; i < 200000; ++i) {
    values.push_back(static_cast<double>(random() >> (random() % 64)));  // integers to 2^64
    values.push_back(std::ldexp(static_cast<double>(random() >> 11), static_cast<int>(random() % 30)));
  }
  std::uniform_int_distribution<std::uint64_t> subnormal(1, (std::uint64_t{1} << 52) - 1);
  for (int i = 0; i < 100000; ++i) values.push_back(double_of(subnormal(random)));
  const std::size_t count = values.size();
  for (std::size_t i = 0; i < count; ++i) values.push_back(-values[i]);
  for (double v : {HUGE_VAL, -HUGE_VAL, std::nan(""), -std::nan(""), 0.0, -0.0}) values.push_back(v);
  return values;
}

}  // namespace

TEST_CASE("CSV numbers are spelled exactly as std::to_chars spells them and read back bit for bit") {
  std::size_t compared = 0, mismatches = 0, fixed = 0, scientific = 0, subnormals = 0;
  for (const double v : spelling_values()) {
    char b[kMaxValueChars];
    const std::string text(b, format_value_to(b, v));
    const std::string expected = to_chars_text(v);
    if (text != expected) {
      if (++mismatches <= 10)
        FAIL_CHECK("bits " << bits_of(v) << ": '" << text << "', std::to_chars '" << expected << "'");
      continue;
    }
    if (std::isfinite(v)) {
      const double back = std::strtod(text.c_str(), nullptr);
      if (bits_of(back) != bits_of(v)) {
        if (++mismatches <= 10) FAIL_CHECK("'" << text << "' reads back as a different double");
        continue;
      }
      (text.find('e') == std::string::npos ? fixed : scientific) += 1;
      if (v != 0 && std::fabs(v) < std::numeric_limits<double>::min()) ++subnormals;
    }
    ++compared;
  }
  CHECK(mismatches == 0);
  // Every family above was reached: both notations, subnormals.
  CHECK(compared > 4000000);
  CHECK(fixed > 500000);
  CHECK(scientific > 500000);
  CHECK(subnormals > 100000);
  // Spot checks of the boundaries between the notations.
  CHECK(format_value(1e-5) == "1e-05");
  CHECK(format_value(1e-4) == "1e-04");     // 5 characters against 6
  CHECK(format_value(0.001) == "0.001");     // a tie: fixed
  CHECK(format_value(1.5e-5) == "1.5e-05");
  CHECK(format_value(1.25e-4) == "0.000125");  // a tie with 1.25e-04: fixed
  CHECK(format_value(1e21) == "1e+21");
  CHECK(format_value(123456789012345680000.0) == "123456789012345683968");
  CHECK(format_value(1e15) == "1e+15");
  CHECK(format_value(100000.0) == "1e+05");
  CHECK(format_value(10000.0) == "10000");
  CHECK(format_value(-std::nan("")) == to_chars_text(-std::nan("")));
}

TEST_CASE("the pinned CSV layout: header, commas, one line per row, nothing else") {
  std::ostringstream s;
  const double row[3] = {0.0, 1.5, -2.25};
  write_csv_header(s, {"t", "a", "b"});
  write_csv_row(s, row, 3);
  CHECK(s.str() == "t,a,b\n0,1.5,-2.25\n");
  // A row wider than write_csv_row's block (4096 bytes) is written whole and in order.
  std::mt19937_64 random(7);
  std::vector<double> wide(700);
  for (double& v : wide) v = double_of(random() & ~(std::uint64_t{1} << 62));  // finite, varied
  std::ostringstream w;
  write_csv_row(w, wide.data(), wide.size());
  std::string expected;
  for (std::size_t i = 0; i < wide.size(); ++i) expected += (i ? "," : "") + format_value(wide[i]);
  expected += '\n';
  CHECK(w.str().size() > 8192);
  CHECK(w.str() == expected);
  // Rows mix zeros, non-finite values, integers and every notation (the row writer finds the
  // digits of a batch of values first, then lays them out): the same text as value by value.
  std::vector<double> mixed;
  std::vector<double> spelled = spelling_values();
  for (std::size_t i = 0; i < spelled.size(); i += 997) mixed.push_back(spelled[i]);
  for (double v : {0.0, -0.0, HUGE_VAL, -HUGE_VAL, std::nan(""), 1.0, -1e-5, 1e21, 0.1})
    mixed.insert(mixed.begin() + static_cast<long>(mixed.size() / 2), v);
  for (std::size_t columns : {1u, 15u, 16u, 17u, 37u, 100u}) {
    std::ostringstream rows;
    std::string expected_rows;
    for (std::size_t k = 0; k + columns <= mixed.size(); k += columns) {
      write_csv_row(rows, mixed.data() + k, columns);
      for (std::size_t c = 0; c < columns; ++c) expected_rows += (c ? "," : "") + to_chars_text(mixed[k + c]);
      expected_rows += '\n';
    }
    CHECK(rows.str() == expected_rows);
  }
  std::ostringstream empty;
  write_csv_row(empty, nullptr, 0);
  CHECK(empty.str() == "\n");
}

TEST_CASE("a CSV row written to a full device fails the stream (the run then exits 3)") {
  const int fd = ::open("/dev/full", O_WRONLY | O_CLOEXEC);
  if (fd < 0) return;  // no /dev/full here: nothing to check
  {
    FdStreamBuf buf(fd, "'/dev/full'");
    std::ostream out(&buf);
    const double row[2] = {1.0, 2.0};
    for (int i = 0; i < 100000 && out; ++i) write_csv_row(out, row, 2);
    CHECK_FALSE(out);
    CHECK(buf.error() == ENOSPC);
    CHECK_THROWS_AS(check_written(out), OutputError);
  }
  ::close(fd);
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
