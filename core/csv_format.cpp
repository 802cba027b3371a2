// CSV numbers and rows (output.hpp): the shortest text that reads back as the same double, spelled
// exactly as std::to_chars(first, last, double) spells it, about three times faster (issue 12).
//
// The shortest decimal digits come from fmt's Dragonbox (fmt::detail::dragonbox::to_decimal,
// header-only fmt, compiled into this file alone); the layout below reproduces the plain
// std::to_chars overload ([charconv.to.chars]/2, as libstdc++ implements it):
//   - digits: the shortest that round trip, the closest to the value among those (ties to even):
//     what Ryu (libstdc++) and Dragonbox both compute;
//   - notation: fixed ("%f"-style) when it is no longer than scientific, scientific otherwise;
//   - scientific: "d.ddde[+-]XX", the exponent with a sign and at least two digits;
//   - zero: "0" or "-0"; infinities and NaN: std::to_chars itself ("inf", "-inf", "nan", "-nan").
// One case is left to std::to_chars: fixed notation of an integer at or above 2^53, which
// to_chars writes as the exact integer (123456789012345683968, not the shortest digits padded
// with zeros). tests/core/test_output.cpp compares this formatter with std::to_chars over
// millions of doubles of every kind and checks that each text reads back bit for bit.
#include "core/output.hpp"

// The full table of powers of ten (about 10 kB): faster than the compressed one.
#define FMT_USE_FULL_CACHE_DRAGONBOX 1
#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <ostream>

namespace crossdyn {

namespace {

// "00" "01" ... "99".
constexpr char kDigitPairs[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

// The 8 decimal digits of v < 10^8, zero-padded, as ASCII in one word, the first digit in the
// lowest byte (the order in memory on a little-endian machine): lanes of 4, 2, then 1 digits,
// divided by multiplication, all in registers.
[[gnu::always_inline]] inline std::uint64_t digits8(std::uint32_t v) {
  std::uint64_t x = (v / 10000) | (static_cast<std::uint64_t>(v % 10000) << 32);
  const std::uint64_t hundreds = ((x * 10486) >> 20) & 0x0000007F0000007Fu;  // each lane / 100
  x = hundreds | ((x - 100 * hundreds) << 16);
  const std::uint64_t tens = ((x * 103) >> 10) & 0x000F000F000F000Fu;  // each lane / 10
  x = tens | ((x - 10 * tens) << 8);
  return x + 0x3030303030303030u;
}

// The 24 digits of a significand (< 10^17), zero-padded, as three words in string order, and a
// fourth and fifth of zeros; put(dest, k) writes the 24 bytes from the k-th digit (k <= 23) at
// dest: shifts of whole words, no store and reload of the digits (which would stall).
class Digits {
 public:
  explicit Digits(std::uint64_t significand) {
    const std::uint64_t high = significand / 100000000;
    // The 17th digit from the end alone (0 to 9), in the last byte: "0000000d".
    w_[0] = 0x0030303030303030u | ((0x30u + high / 100000000) << 56);
    w_[1] = digits8(static_cast<std::uint32_t>(high % 100000000));
    w_[2] = digits8(static_cast<std::uint32_t>(significand % 100000000));
    w_[3] = w_[4] = 0;
  }
  void put(char* dest, int k) const {
    const int q = k >> 3, s = (k & 7) * 8;
    // (w << 1) << (63 - s): w << (64 - s) without the undefined shift by 64 when s == 0.
    const std::uint64_t a = (w_[q] >> s) | ((w_[q + 1] << 1) << (63 - s));
    const std::uint64_t b = (w_[q + 1] >> s) | ((w_[q + 2] << 1) << (63 - s));
    const std::uint64_t c = w_[q + 2] >> s;
    std::memcpy(dest, &a, 8);
    std::memcpy(dest + 8, &b, 8);
    std::memcpy(dest + 16, &c, 8);
  }
  char digit(int k) const { return static_cast<char>(w_[k >> 3] >> ((k & 7) * 8)); }

 private:
  std::uint64_t w_[5];
};

constexpr std::uint64_t kExponentMask = 0x7FF0000000000000u;
constexpr double kTwoTo53 = 9007199254740992.0;

using Decimal = fmt::detail::dragonbox::decimal_fp<double>;

// |v| = significand * 10^exponent, the shortest significand, without trailing zeros (Dragonbox);
// {0, 0} for zeros, infinities and NaN.
inline Decimal decimal_of(double v) {
  std::uint64_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  if ((bits & kExponentMask) == kExponentMask || (bits << 1) == 0) return {0, 0};
  return fmt::detail::dragonbox::to_decimal(v);
}

// Writes v, whose decimal_of is `dec`, at `first`. The text is written with fixed-size stores,
// each of which may write past the value's end (bytes overwritten or ignored later) but never
// past first + kMaxValueChars: no loop or library call whose length depends on the value.
[[gnu::always_inline]] inline char* write_value(char* first, double v, Decimal dec) {
  static_assert(kMaxValueChars >= 48, "the stores below reach first + 43");
  std::uint64_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  if ((bits & kExponentMask) == kExponentMask)  // inf, nan: to_chars's own spelling
    return std::to_chars(first, first + kMaxValueChars, v).ptr;
  // The sign without a branch (random signs would mispredict one).
  *first = '-';
  char* p = first + (bits >> 63);
  if ((bits << 1) == 0) {
    *p++ = '0';
    return p;
  }
  const std::uint64_t sig = dec.significand;  // < 10^17
  const int e = dec.exponent;
  const int n = fmt::detail::count_digits(sig);
  const Digits digits(sig);
  const int z = 24 - n;  // the first significant digit (7 <= z <= 23)
  const int x = n - 1 + e;  // the scientific exponent
  const int sci_length = n + (n > 1 ? 1 : 0) + 2 + (x <= -100 || x >= 100 ? 3 : 2);
  const int fixed_length = e >= 0 ? n + e : x >= 0 ? n + 1 : n + 1 - x;
  // The furthest byte each branch writes is noted (p <= first + 1). Fixed notation is no longer
  // than scientific only when e <= 5 (whole numbers) and x >= -4 (0.000ddd).
  if (fixed_length <= sci_length) {
    if (e >= 0) {
      // A whole number. Below 2^53 the shortest digits padded with zeros are the exact value;
      // above, to_chars writes the exact integer, which may differ from the padding.
      if (v >= kTwoTo53 || v <= -kTwoTo53)
        return std::to_chars(first, first + kMaxValueChars, v).ptr;
      digits.put(p, z);                   // first + 25
      std::memcpy(p + n, "00000000", 8);  // first + 26
      return p + n + e;
    }
    // ddd.ddd (x >= 0) and 0.000ddd (x < 0) alike, without a branch between them: the zero-padded
    // digits from a, a point after the first w of them (the integer part: "0" when x < 0).
    const int w = x >= 0 ? x + 1 : 1;  // 1 <= w <= 16
    const int a = z + x + 1 - w;       // z, or z + x (>= z - 4 >= 3) before the zeros
    digits.put(p, a);                  // first + 25
    p[w] = '.';
    digits.put(p + w + 1, a + w);  // first + 42
    return p + 25 - a;
  }
  // d.ddde+XX: the digits from p + 1, the first moved before the point.
  digits.put(p + 1, z);  // first + 26
  p[0] = digits.digit(z);
  p[1] = '.';
  p += n > 1 ? n + 1 : 1;
  *p++ = 'e';
  *p++ = x < 0 ? '-' : '+';
  int ax = x < 0 ? -x : x;
  if (ax >= 100) {
    *p++ = static_cast<char>('0' + ax / 100);
    ax %= 100;
  }
  std::memcpy(p, kDigitPairs + 2 * ax, 2);
  return p + 2;  // first + 24
}

}  // namespace

char* format_value_to(char* first, double v) { return write_value(first, v, decimal_of(v)); }

std::string format_value(double v) {
  char b[kMaxValueChars];
  return std::string(b, format_value_to(b, v));
}

void write_csv_header(std::ostream& out, const std::vector<std::string>& columns) {
  for (std::size_t i = 0; i < columns.size(); ++i) out << (i ? "," : "") << columns[i];
  out << '\n';
}

// On x86-64 with GCC the row writer is compiled twice, for the baseline instruction set and for
// x86-64-v3 (BMI2 shifts and multiplies, LZCNT, AVX2), and the loader picks the one the processor
// runs (GCC function multiversioning, an ifunc). The formatting is integer arithmetic only, so
// both write the same bytes; the v3 one is about 8 % faster (issue 12).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define CROSSDYN_CSV_CLONES gnu::target_clones("arch=x86-64-v3", "default"),
#else
#define CROSSDYN_CSV_CLONES
#endif
[[CROSSDYN_CSV_CLONES gnu::flatten]] void write_csv_row(std::ostream& out, const double* row,
                                                        std::size_t n) {
  // Formatted into a local block and handed to the stream in one write per block (one per row
  // up to ~80 columns); a failed write sets the stream's badbit as before. The decimal digits of
  // a batch of values are found first, then laid out: the searches are independent of each other
  // and overlap in the processor, where each layout has to wait for the previous one's end.
  constexpr std::size_t kBatch = 16;
  char block[4096];
  char* const end = block + sizeof block;
  char* p = block;
  Decimal decimals[kBatch];
  // Every value is followed by a comma, the last one's replaced by the newline; the room for a
  // batch (each value's stores stay within kMaxValueChars of its start) is checked once.
  for (std::size_t i = 0; i < n; i += kBatch) {
    const std::size_t m = std::min(kBatch, n - i);
    for (std::size_t j = 0; j < m; ++j) decimals[j] = decimal_of(row[i + j]);
    if (static_cast<std::size_t>(end - p) < kBatch * (kMaxValueChars + 1)) {
      out.write(block, p - block);
      p = block;
    }
    for (std::size_t j = 0; j < m; ++j) {
      p = write_value(p, row[i + j], decimals[j]);
      *p++ = ',';
    }
  }
  if (n == 0) ++p;
  p[-1] = '\n';
  out.write(block, p - block);
}

}  // namespace crossdyn
