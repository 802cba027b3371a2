// Scene reader: YAML text => validated System in SI units, and System => YAML text.
//
//   read_scene_text(text, label)  (text) => (System)   passes: precheck_text, parse_yaml,
//                                 read_top, read_bodies, read_joints, order_joints (topology),
//                                 read_run, read_compare, check_analytic.
//   write_scene_text(system)      (System) => (text)   SI numbers in their shortest round-trip
//                                 form (std::to_chars), so read(write(s)) == s field by field.
//
// Every error is an InputError "<file>:<line>:<column>: <key path>: <what is wrong>", the line and
// column 1-based from yaml-cpp's Mark of the offending node (the key itself for unknown keys, the
// enclosing mapping for missing ones).
//
// Guards against hostile input (found or anticipated by fuzz/scene_fuzzer.cpp, see fuzz/README.md):
//   - a scene larger than kMaxSceneBytes is rejected before parsing;
//   - the text must be valid UTF-8 without C0 control characters other than tab, LF and CR;
//   - nesting depth: yaml-cpp 0.7's parser is recursive but guards its own depth (DepthGuard in
//     SingleDocParser, ErrorMsg::BAD_FILE "bad file" past a few hundred levels); that exception
//     becomes an InputError here. The size limit bounds the work in any case;
//   - anchors and aliases may make the node graph cyclic (`&a [*a]`): the reader only follows the
//     scene schema, which has a fixed depth, and never walks the node graph generically.
#include "core/scene_reader.hpp"

#include "core/errors.hpp"
#include "core/run_limits.hpp"
#include "core/units.hpp"

#include <yaml-cpp/anchor.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>
#include <Eigen/Eigenvalues>

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <optional>
#include <queue>
#include <sstream>
#include <string_view>
#include <unordered_map>
#include <unordered_set>
#include <vector>

namespace crossdyn {
namespace {

using units::Dimension;

// ---------------------------------------------------------------------------------------------
// Limits (README "What the reader checks"). Each is far outside any physical spacecraft scene.
constexpr std::size_t kMaxSceneBytes = 1u << 20;   // 1 MiB of YAML
constexpr double kAbsurd = 1e12;                   // any SI value beyond this is a typo
constexpr double kMaxMass = 1e9;                   // kg
constexpr double kMinAxisLength = 1e-9;            // a shorter axis counts as zero
constexpr double kUnitQuaternionTolerance = 1e-3;  // |norm(q) - 1| accepted (then normalised)
constexpr double kSymmetryTolerance = 1e-9;        // |I_ij - I_ji| <= this * max |I_kl|
constexpr double kTriangleTolerance = 1e-9;        // I1 + I2 >= I3 - this * (I1 + I2 + I3)
// Vectors and quaternions whose norm is within this of 1 are kept as written, so that a written
// scene reads back bit for bit (normalising an already normalised vector may change its last bit).
constexpr double kUnitNormKeep = 8 * std::numeric_limits<double>::epsilon();

const std::vector<std::string> kIntegrators{"rk4", "dopri5", "rkf78", "bulirsch-stoer"};

// ---------------------------------------------------------------------------------------------
// Small text helpers.

std::string shortest(double x) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);
  return std::string(buf, r.ptr);
}

std::string quoted_excerpt(const std::string& s) {
  constexpr std::size_t kMax = 40;
  std::string out;
  for (char c : s.substr(0, kMax)) {
    const auto u = static_cast<unsigned char>(c);
    out += (u < 0x20 || u == 0x7F) ? '?' : c;
  }
  return "'" + out + (s.size() > kMax ? "...'" : "'");
}

std::string join(const std::vector<std::string>& v, std::size_t max_items = 12) {
  std::string s;
  for (std::size_t i = 0; i < v.size() && i < max_items; ++i) s += (i ? ", " : "") + v[i];
  if (v.size() > max_items) s += ", ...";
  return s;
}

// Optimal-string-alignment distance (Levenshtein plus adjacent transpositions), ignoring case.
std::size_t edit_distance(const std::string& a, const std::string& b) {
  auto same = [](char x, char y) {
    return std::tolower(static_cast<unsigned char>(x)) ==
           std::tolower(static_cast<unsigned char>(y));
  };
  std::vector<std::size_t> row(b.size() + 1), prev(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    const std::vector<std::size_t> before = row;  // row i - 1
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (same(a[i - 1], b[j - 1]) ? 0 : 1)});
      // An adjacent transposition ("amr" for "arm") costs one edit.
      if (i > 1 && j > 1 && same(a[i - 1], b[j - 2]) && same(a[i - 2], b[j - 1]))
        row[j] = std::min(row[j], prev[j - 2] + 1);
      diag = up;
    }
    prev = before;
  }
  return row[b.size()];
}

// " (did you mean 'x'?)" when one candidate is close to `word`, else "".
std::string suggestion(const std::string& word, const std::vector<std::string>& candidates) {
  if (word.size() > 64) return "";
  std::size_t best = std::numeric_limits<std::size_t>::max();
  std::string best_word;
  for (const std::string& c : candidates) {
    const std::size_t d = edit_distance(word, c);
    if (d < best) best = d, best_word = c;
  }
  const std::size_t limit =
      std::max<std::size_t>(1, std::min<std::size_t>(3, best_word.size() / 3));
  return best <= limit ? " (did you mean '" + best_word + "'?)" : "";
}

// Position of the first byte that is not valid UTF-8 (strict: no overlong forms, no surrogates,
// nothing above U+10FFFF), or npos.
std::size_t invalid_utf8_at(std::string_view s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    std::size_t n = 0;
    std::uint32_t cp = 0;
    if (c < 0x80) {
      ++i;
      continue;
    }
    if (c >= 0xC2 && c <= 0xDF)
      n = 1, cp = c & 0x1F;
    else if (c >= 0xE0 && c <= 0xEF)
      n = 2, cp = c & 0x0F;
    else if (c >= 0xF0 && c <= 0xF4)
      n = 3, cp = c & 0x07;
    else
      return i;
    if (i + n >= s.size()) return i;  // truncated sequence
    for (std::size_t k = 1; k <= n; ++k) {
      const auto d = static_cast<unsigned char>(s[i + k]);
      if ((d & 0xC0) != 0x80) return i;
      cp = (cp << 6) | (d & 0x3F);
    }
    if ((n == 2 && cp < 0x800) || (n == 3 && cp < 0x10000) || cp > 0x10FFFF ||
        (cp >= 0xD800 && cp <= 0xDFFF))
      return i;
    i += n + 1;
  }
  return std::string_view::npos;
}

// ---------------------------------------------------------------------------------------------
// A node together with its key path ("bodies[1].inertia") and a usable position.
struct Val {
  YAML::Node node;
  std::string path;
  YAML::Mark mark;
};

std::string describe(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Undefined:
    case YAML::NodeType::Null:
      return "no value";
    case YAML::NodeType::Scalar:
      return quoted_excerpt(n.Scalar());
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Map:
      return "a mapping";
  }
  return "?";
}

class Reader;

// The keys of one YAML mapping, checked against the keys the schema knows there.
class MapView {
 public:
  struct Entry {
    std::string key;
    YAML::Mark key_mark;
    Val value;
  };
  // known empty and any_key true: every key is accepted (the compare tolerances).
  MapView(const Reader& r, const Val& v, const std::vector<std::string>& known,
          const std::string& what, bool any_key = false);

  std::optional<Val> get(const std::string& key) const {
    for (const Entry& e : entries_)
      if (e.key == key) return e.value;
    return std::nullopt;
  }
  Val require(const std::string& key) const;
  const Entry* entry(const std::string& key) const {
    for (const Entry& e : entries_)
      if (e.key == key) return &e;
    return nullptr;
  }
  const std::vector<Entry>& entries() const { return entries_; }
  const Val& self() const { return self_; }

 private:
  const Reader& r_;
  Val self_;
  std::string what_;
  std::vector<Entry> entries_;
};

std::string key_path(const std::string& parent, const std::string& key) {
  return parent.empty() ? key : parent + "." + key;
}

class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const YAML::Mark& m, const std::string& path,
                         const std::string& what) const {
    const int line = m.is_null() || m.line < 0 ? 1 : m.line + 1;
    const int column = m.is_null() || m.column < 0 ? 1 : m.column + 1;
    throw InputError(file_ + ":" + std::to_string(line) + ":" + std::to_string(column) + ": " +
                     (path.empty() ? "" : path + ": ") + what);
  }
  [[noreturn]] void fail(const Val& v, const std::string& what) const {
    fail(v.mark, v.path, what);
  }

  Val sub(const Val& parent, const YAML::Node& n, std::string path) const {
    YAML::Mark m = n.Mark();
    if (m.is_null()) m = parent.mark;
    return Val{n, std::move(path), m};
  }

  // ----- passes --------------------------------------------------------------------------------
  void precheck_text(const std::string& text) const;
  Val parse_yaml(const std::string& text) const;
  System read(const std::string& text) const;

  // ----- typed values --------------------------------------------------------------------------
  std::vector<Val> list(const Val& v, const std::string& what, bool non_empty) const {
    if (!v.node.IsSequence()) fail(v, "expected " + what + ", found " + describe(v.node));
    std::vector<Val> items;
    std::size_t i = 0;
    for (const YAML::Node& n : v.node)
      items.push_back(sub(v, n, v.path + "[" + std::to_string(i++) + "]"));
    if (non_empty && items.empty()) fail(v, "expected " + what + ", found an empty list");
    return items;
  }

  const std::string& scalar(const Val& v, const std::string& what) const {
    if (!v.node.IsScalar()) fail(v, "expected " + what + ", found " + describe(v.node));
    return v.node.Scalar();
  }

  // A body, joint or scene name: it becomes part of output column names ("<body>.wx").
  std::string identifier(const Val& v, const std::string& what, bool allow_dot = false) const {
    const std::string& s = scalar(v, what);
    bool ok = !s.empty() && s.size() <= 64 && std::isalpha(static_cast<unsigned char>(s[0]));
    for (char c : s)
      ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' ||
                  (allow_dot && c == '.'));
    if (!ok)
      fail(v, "invalid " + what + " " + quoted_excerpt(s) +
                  ": use 1 to 64 letters, digits, '_' or '-'" + (allow_dot ? " or '.'" : "") +
                  ", starting with a letter");
    return s;
  }

  // Free text (description, source, reasons): printable UTF-8, tabs and newlines allowed.
  std::string free_text(const Val& v, const std::string& what) const {
    const std::string& s = scalar(v, what);
    if (invalid_utf8_at(s) != std::string_view::npos) fail(v, what + " is not valid UTF-8");
    for (char c : s) {
      const auto u = static_cast<unsigned char>(c);
      if ((u < 0x20 && c != '\n' && c != '\t') || u == 0x7F)
        fail(v, what + " contains the control character " + std::to_string(u) +
                    " (only tabs and newlines are allowed)");
    }
    return s;
  }

  // One of a fixed set of words.
  std::string choice(const Val& v, const std::string& what,
                     const std::vector<std::string>& words) const {
    const std::string& s = scalar(v, what);
    if (std::find(words.begin(), words.end(), s) == words.end())
      fail(v, "unknown " + what + " " + quoted_excerpt(s) + suggestion(s, words) +
                  "; expected one of: " + join(words));
    return s;
  }

  bool boolean(const Val& v) const {
    const std::string& s = scalar(v, "true or false");
    if (s == "true" || s == "True" || s == "TRUE") return true;
    if (s == "false" || s == "False" || s == "FALSE") return false;
    fail(v, "expected true or false, found " + quoted_excerpt(s));
  }

  // Splits "<number> <unit>" (the unit may be empty) and parses the number.
  std::pair<double, std::string> number_and_unit(const Val& v, Dimension d) const {
    const std::string expected =
        d == Dimension::None
            ? std::string("a number")
            : units::dimension_name(d) + " (a number in SI units, or \"<number> <unit>\")";
    if (!v.node.IsScalar()) fail(v, "expected " + expected + ", found " + describe(v.node));
    const std::string& s = v.node.Scalar();
    std::size_t b = 0, e = s.size();
    while (b < e && (s[b] == ' ' || s[b] == '\t')) ++b;
    while (e > b && (s[e - 1] == ' ' || s[e - 1] == '\t')) --e;
    std::string_view body(s.data() + b, e - b);
    // YAML's spellings of infinity and NaN, and the C ones from_chars accepts.
    std::string_view bare = body;
    if (!bare.empty() && (bare[0] == '+' || bare[0] == '-')) bare.remove_prefix(1);
    for (std::string_view w : {".inf", ".Inf", ".INF", ".nan", ".NaN", ".NAN"})
      if (bare.substr(0, w.size()) == w) fail(v, "non-finite number " + quoted_excerpt(s));
    if (!body.empty() && body[0] == '+' && body.size() > 1 && body[1] != '-' && body[1] != '+')
      body.remove_prefix(1);
    double x = 0;
    const auto r = std::from_chars(body.data(), body.data() + body.size(), x);
    if (r.ec == std::errc::invalid_argument)
      fail(v, "expected " + expected + ", found " + quoted_excerpt(s));
    if (r.ec == std::errc::result_out_of_range)
      fail(v, "number " + quoted_excerpt(s) + " is out of range");
    if (!std::isfinite(x)) fail(v, "non-finite number " + quoted_excerpt(s));
    std::string_view rest(r.ptr, static_cast<std::size_t>(body.data() + body.size() - r.ptr));
    while (!rest.empty() && (rest[0] == ' ' || rest[0] == '\t')) rest.remove_prefix(1);
    return {x, std::string(rest)};
  }

  double unit_factor(const Val& v, const std::string& unit, Dimension d) const {
    if (d == Dimension::None)
      fail(v, "this value is a pure number and takes no unit (found " + quoted_excerpt(unit) + ")");
    const auto u = units::find_unit(unit);
    if (!u) {
      fail(v, "unknown unit " + quoted_excerpt(unit) +
                  suggestion(units::normalise_unit(unit), units::unit_names(d)) + "; expected " +
                  units::dimension_name(d) + " in " + units::units_of(d));
    }
    if (u->dimension != d)
      fail(v, "unit " + quoted_excerpt(unit) + " is " + units::dimension_name(u->dimension) +
                  ", but this key expects " + units::dimension_name(d) + " (" + units::units_of(d) +
                  ")");
    return u->to_si;
  }

  double sane(const Val& v, double si) const {
    if (!std::isfinite(si)) fail(v, "value is not finite after unit conversion");
    if (std::abs(si) > kAbsurd)
      fail(v, "absurd value " + shortest(si) + " (magnitude above 1e12 in SI units)");
    return si;
  }

  // A scalar quantity in SI. `factor` set: the unit was given once for an enclosing list, and the
  // element itself must be a bare number.
  double quantity(const Val& v, Dimension d, std::optional<double> factor = std::nullopt) const {
    const auto [x, unit] = number_and_unit(v, d);
    if (factor) {
      if (!unit.empty())
        fail(v, "the unit is given once for this list; its elements must be bare numbers");
      return sane(v, x * *factor);
    }
    return sane(v, unit.empty() ? x : x * unit_factor(v, unit, d));
  }

  // A list of numbers: [a, b, c] (each a quantity) or {value: [a, b, c], unit: u}.
  std::vector<double> numbers(const Val& v, Dimension d, std::size_t n,
                              const std::string& what) const {
    Val items = v;
    std::optional<double> factor;
    if (v.node.IsMap()) {
      MapView m(*this, v, {"value", "unit"}, "a list with a unit");
      items = m.require("value");
      if (auto u = m.get("unit")) factor = unit_factor(*u, scalar(*u, "a unit"), d);
    }
    if (!items.node.IsSequence())
      fail(items, "expected " + what + " (a list of " + std::to_string(n) + " numbers), found " +
                      describe(items.node));
    const std::vector<Val> e = list(items, what, false);
    if (e.size() != n)
      fail(items, "expected " + what + " (a list of " + std::to_string(n) + " numbers), found " +
                      std::to_string(e.size()) + " elements");
    std::vector<double> out;
    for (const Val& x : e) out.push_back(quantity(x, d, factor));
    return out;
  }

  Eigen::Vector3d vec3(const Val& v, Dimension d, const std::string& what) const {
    const auto x = numbers(v, d, 3, what);
    return {x[0], x[1], x[2]};
  }

  // A direction: non-zero, normalised (kept as written when already unit to 8 eps).
  Eigen::Vector3d direction(const Val& v, const std::string& what) const {
    Eigen::Vector3d a = vec3(v, Dimension::None, what);
    const double n = a.norm();
    if (!(n >= kMinAxisLength))
      fail(v, "zero axis (length " + shortest(n) + "): give a non-zero direction");
    if (std::abs(n - 1) > kUnitNormKeep) a /= n;
    return a;
  }

  // An attitude: [w, x, y, z] (unit to 1e-3, then normalised) or {axis: [...], angle: ...}.
  Eigen::Quaterniond attitude(const Val& v) const {
    Eigen::Quaterniond q;
    if (v.node.IsMap()) {
      MapView m(*this, v, {"axis", "angle"}, "an axis-angle rotation");
      const Eigen::Vector3d axis = direction(m.require("axis"), "an axis");
      const double angle = quantity(m.require("angle"), Dimension::Angle);
      q = Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis));
    } else if (v.node.IsSequence()) {
      const auto c = numbers(v, Dimension::None, 4, "a quaternion [w, x, y, z]");
      q = Eigen::Quaterniond(c[0], c[1], c[2], c[3]);
      const double n = q.norm();
      if (!(std::abs(n - 1) <= kUnitQuaternionTolerance))
        fail(v, "quaternion [w, x, y, z] has norm " + shortest(n) +
                    "; expected a unit quaternion (norm within 1e-3 of 1)");
    } else {
      fail(
          v,
          "expected an attitude: a quaternion [w, x, y, z] or {axis: [x, y, z], angle: a}, found " +
              describe(v.node));
    }
    if (std::abs(q.norm() - 1) > kUnitNormKeep) q.normalize();
    return q;
  }

  Eigen::Matrix3d inertia(const Val& v) const;
  template <int D>
  PiecewiseConstant<D> profile(const Val& v, Dimension d) const;

  const std::string& file() const { return file_; }

 private:
  std::string file_;
};

MapView::MapView(const Reader& r, const Val& v, const std::vector<std::string>& known,
                 const std::string& what, bool any_key)
    : r_(r), self_(v), what_(what) {
  if (!v.node.IsMap())
    r.fail(v, "expected " + what + " (a mapping of keys), found " + describe(v.node));
  std::unordered_map<std::string, int> seen;  // key => line, for duplicates (maps may be large)
  for (YAML::const_iterator it = v.node.begin(); it != v.node.end(); ++it) {
    // Copies, not references into the iterator's proxy (GCC 12 -Wdangling-pointer).
    const YAML::detail::iterator_value kv = *it;
    const YAML::Node k = kv.first;
    const YAML::Node value = kv.second;
    YAML::Mark km = k.Mark();
    if (km.is_null()) km = v.mark;
    if (!k.IsScalar()) r.fail(km, v.path, "a key must be a plain name, found " + describe(k));
    const std::string key = k.Scalar();
    const std::string path = key_path(v.path, key);
    if (const auto [first, fresh] = seen.emplace(key, km.line); !fresh)
      r.fail(
          km, path,
          "duplicate key '" + key + "' (first at line " + std::to_string(first->second + 1) + ")");
    if (!any_key && std::find(known.begin(), known.end(), key) == known.end())
      r.fail(km, path,
             "unknown key " + quoted_excerpt(key) + " in " + what + suggestion(key, known) +
                 "; known keys: " + join(known));
    // A key without a value ("mass:") has a null node whose mark is the next token's: use the
    // key's.
    entries_.push_back(
        Entry{key, km, value.IsNull() ? Val{value, path, km} : r.sub(v, value, path)});
  }
}

Val MapView::require(const std::string& key) const {
  if (auto v = get(key)) {
    if (v->node.IsNull()) r_.fail(*v, "key '" + key + "' has no value");
    return *v;
  }
  r_.fail(self_, "missing required key '" + key + "' in " + what_);
}

// Inertia about the CM in body axes: [Ixx, Iyy, Izz], [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] (tensor
// components, so Ixy = -integral x y dm), or a 3x3 nested list; optionally {value: ..., unit: ...}.
// Checked: symmetric, positive definite, principal moments obeying the triangle inequality
// I1 + I2 >= I3 (Kane, Likins & Levinson 1983, Sec. 3.7: a real mass distribution has
// I1 + I2 - I3 = 2 integral z^2 dm >= 0 in principal axes).
Eigen::Matrix3d Reader::inertia(const Val& v) const {
  Val items = v;
  std::optional<double> factor;
  if (v.node.IsMap()) {
    MapView m(*this, v, {"value", "unit"}, "an inertia with a unit");
    items = m.require("value");
    if (auto u = m.get("unit")) factor = unit_factor(*u, scalar(*u, "a unit"), Dimension::Inertia);
  }
  const std::string forms =
      "an inertia: 3 numbers (principal moments), 6 numbers (xx, yy, zz, xy, xz, yz) or a 3x3 "
      "nested list";
  if (!items.node.IsSequence())
    fail(items, "expected " + forms + ", found " + describe(items.node));
  const std::vector<Val> e = list(items, forms, false);
  auto q = [&](const Val& x) { return quantity(x, Dimension::Inertia, factor); };
  Eigen::Matrix3d I = Eigen::Matrix3d::Zero();
  const bool all_scalars =
      std::all_of(e.begin(), e.end(), [](const Val& x) { return x.node.IsScalar(); });
  if (e.size() == 3 && all_scalars) {
    for (int i = 0; i < 3; ++i) I(i, i) = q(e[static_cast<std::size_t>(i)]);
  } else if (e.size() == 6 && all_scalars) {
    for (int i = 0; i < 3; ++i) I(i, i) = q(e[static_cast<std::size_t>(i)]);
    I(0, 1) = I(1, 0) = q(e[3]);
    I(0, 2) = I(2, 0) = q(e[4]);
    I(1, 2) = I(2, 1) = q(e[5]);
  } else if (e.size() == 3 &&
             std::all_of(e.begin(), e.end(), [](const Val& x) { return x.node.IsSequence(); })) {
    for (int i = 0; i < 3; ++i) {
      const std::vector<Val> row =
          list(e[static_cast<std::size_t>(i)], "a row of 3 numbers", false);
      if (row.size() != 3)
        fail(e[static_cast<std::size_t>(i)],
             "expected a row of 3 numbers, found " + std::to_string(row.size()));
      for (int j = 0; j < 3; ++j) I(i, j) = q(row[static_cast<std::size_t>(j)]);
    }
    const double scale = I.cwiseAbs().maxCoeff();
    for (int i = 0; i < 3; ++i)
      for (int j = i + 1; j < 3; ++j) {
        if (std::abs(I(i, j) - I(j, i)) > kSymmetryTolerance * scale)
          fail(v, "inertia matrix is not symmetric: I(" + std::to_string(i + 1) + "," +
                      std::to_string(j + 1) + ") = " + shortest(I(i, j)) + " but I(" +
                      std::to_string(j + 1) + "," + std::to_string(i + 1) +
                      ") = " + shortest(I(j, i)));
        I(i, j) = I(j, i) = 0.5 * (I(i, j) + I(j, i));
      }
  } else {
    fail(items,
         "expected " + forms + ", found a list of " + std::to_string(e.size()) + " elements");
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(I, Eigen::EigenvaluesOnly);
  const Eigen::Vector3d p = eig.eigenvalues();  // ascending
  const std::string moments =
      "principal moments " + shortest(p[0]) + ", " + shortest(p[1]) + ", " + shortest(p[2]);
  if (eig.info() != Eigen::Success || !(p[0] > 0))
    fail(v, "inertia is not positive definite (" + moments + " kg m^2)");
  if (p[0] + p[1] < p[2] - kTriangleTolerance * (p[0] + p[1] + p[2]))
    fail(v, "inertia violates the triangle inequality I1 + I2 >= I3 (" + moments +
                " kg m^2): no real mass distribution has it");
  return I;
}

// A piecewise-constant profile: [{t: t0, value: v0}, {t: t1, value: v1}, ...], t0 >= 0,
// strictly increasing times. D = 1: scalar values; D = 3: 3-vectors.
template <int D>
PiecewiseConstant<D> Reader::profile(const Val& v, Dimension d) const {
  PiecewiseConstant<D> p;
  const std::vector<Val> items = list(v, "a profile: a list of {t: time, value: ...}", true);
  for (const Val& item : items) {
    MapView m(*this, item, {"t", "value"}, "a profile entry");
    const Val tv = m.require("t");
    const double t = quantity(tv, Dimension::Time);
    if (t < 0) fail(tv, "profile time " + shortest(t) + " s is negative");
    if (!p.times.empty() && !(t > p.times.back()))
      fail(tv, "profile times must increase strictly: t = " + shortest(t) +
                   " s after t = " + shortest(p.times.back()) + " s");
    Eigen::Matrix<double, D, 1> value;
    if constexpr (D == 1) {
      value[0] = quantity(m.require("value"), d);
    } else {
      value = vec3(m.require("value"), d, units::dimension_name(d) + " vector");
    }
    p.times.push_back(t);
    p.values.push_back(value);
  }
  return p;
}

void Reader::precheck_text(const std::string& text) const {
  if (text.size() > kMaxSceneBytes)
    fail(YAML::Mark(), "",
         "the scene is larger than the limit of " + std::to_string(kMaxSceneBytes) +
             " bytes (a guard against hostile input; see fuzz/README.md)");
  auto position = [&text](std::size_t at) {
    YAML::Mark m;
    for (std::size_t i = 0; i < at; ++i) {
      if (text[i] == '\n')
        ++m.line, m.column = 0;
      else
        ++m.column;
    }
    return m;
  };
  const std::size_t bad = invalid_utf8_at(text);
  if (bad != std::string_view::npos) fail(position(bad), "", "the scene is not valid UTF-8 text");
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto u = static_cast<unsigned char>(text[i]);
    if ((u < 0x20 && u != '\t' && u != '\n' && u != '\r') || u == 0x7F)
      fail(position(i), "",
           "control character " + std::to_string(u) + " is not allowed in a scene file");
  }
}

// Records where each document starts; ignores everything else (used to count documents).
struct DocumentStarts : YAML::EventHandler {
  std::vector<YAML::Mark> starts;
  void OnDocumentStart(const YAML::Mark& mark) override { starts.push_back(mark); }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t,
                const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}
};

Val Reader::parse_yaml(const std::string& text) const {
  YAML::Node doc;
  try {
    doc = YAML::Load(text);
    // One document only. Not YAML::LoadAll: yaml-cpp 0.7's document loop never ends when junk
    // follows a document's top-level scalar ("\"a\", b" yields empty documents forever; found by
    // the fuzzer, tests/scene/fuzz_regressions/loadall-hang-*.yaml). Two calls are bounded.
    std::istringstream in(text);
    YAML::Parser parser(in);
    DocumentStarts starts;
    parser.HandleNextDocument(starts);
    if (parser.HandleNextDocument(starts))
      fail(starts.starts.size() > 1 ? starts.starts[1] : YAML::Mark(), "",
           "a second YAML document or text after the end of the first; a scene file holds one "
           "document");
  } catch (const YAML::Exception& e) {
    // yaml-cpp's depth guard reports ErrorMsg::BAD_FILE ("bad file"); say what it means.
    fail(e.mark, "",
         "malformed YAML: " +
             (e.msg == "bad file" ? std::string("nesting too deep (yaml-cpp: bad file)") : e.msg));
  }
  if (doc.IsNull())
    fail(YAML::Mark(), "",
         "the scene is empty; expected a mapping with the keys name, bodies, joints, run");
  return Val{doc, "", doc.Mark().is_null() ? YAML::Mark() : doc.Mark()};
}

// ---------------------------------------------------------------------------------------------
// The scene.

const std::vector<std::string> kTopKeys{"name",    "description", "source",
                                        "bodies",  "joints",      "run",
                                        "compare", "analytic",    "zero_linear_momentum"};
const std::vector<std::string> kBodyKeys{"name", "mass", "inertia", "torque"};
const std::vector<std::string> kJointKeys{"name",         "type",        "parent", "child",
                                          "parent_point", "child_point", "axis",   "offset",
                                          "spring",       "damper",      "motor",  "initial"};
const std::vector<std::string> kJointTypes{"free", "revolute", "spherical", "fixed"};

// Keys each joint type takes, and its initial conditions.
const std::vector<std::string>& joint_keys(JointType t) {
  static const std::vector<std::string> free{"name", "type", "child", "initial"};
  static const std::vector<std::string> revolute{
      "name", "type",   "parent", "child",  "parent_point", "child_point",
      "axis", "offset", "spring", "damper", "motor",        "initial"};
  static const std::vector<std::string> spherical{"name",         "type",        "parent", "child",
                                                  "parent_point", "child_point", "offset", "spring",
                                                  "damper",       "motor",       "initial"};
  static const std::vector<std::string> fixed{"name",         "type",        "parent", "child",
                                              "parent_point", "child_point", "offset"};
  switch (t) {
    case JointType::Free:
      return free;
    case JointType::Revolute:
      return revolute;
    case JointType::Spherical:
      return spherical;
    case JointType::Fixed:
      return fixed;
  }
  return fixed;
}

const std::vector<std::string>& initial_keys(JointType t) {
  static const std::vector<std::string> free{"position", "attitude", "angular_velocity",
                                             "velocity"};
  static const std::vector<std::string> revolute{"angle", "rate"};
  static const std::vector<std::string> spherical{"attitude", "angular_velocity"};
  static const std::vector<std::string> none;
  switch (t) {
    case JointType::Free:
      return free;
    case JointType::Revolute:
      return revolute;
    case JointType::Spherical:
      return spherical;
    case JointType::Fixed:
      return none;
  }
  return none;
}

std::string type_name(JointType t) {
  switch (t) {
    case JointType::Free:
      return "free";
    case JointType::Revolute:
      return "revolute";
    case JointType::Spherical:
      return "spherical";
    case JointType::Fixed:
      return "fixed";
  }
  return "?";
}

// A joint as read, before the topology pass orders the joints.
struct RawJoint {
  Joint joint;
  Val node;
  Val type_val;
  Val child_val;
  std::optional<Val> parent_val;
  std::optional<Val> velocity_val;  // free joint's initial velocity, if given
};

System Reader::read(const std::string& text) const {
  precheck_text(text);
  const Val root = parse_yaml(text);
  const MapView top(*this, root, kTopKeys, "the scene");

  System s;
  s.file = file_;

  // ----- read_top: name, texts, flags -----
  s.name = identifier(top.require("name"), "scene name", true);
  if (auto v = top.get("description")) s.description = free_text(*v, "description");
  if (auto v = top.get("source")) s.source = free_text(*v, "source");
  if (auto v = top.get("analytic")) s.analytic = choice(*v, "analytic reference", {"torque-free"});
  if (auto v = top.get("zero_linear_momentum")) s.zero_linear_momentum = boolean(*v);

  // ----- read_bodies -----
  const Val bodies_val = top.require("bodies");
  const std::vector<Val> body_items = list(bodies_val, "a list of bodies", true);
  std::unordered_map<std::string, int> body_index;
  std::vector<Val> body_vals;
  for (const Val& item : body_items) {
    const MapView m(*this, item, kBodyKeys, "a body");
    Body b;
    const Val name_val = m.require("name");
    b.name = identifier(name_val, "body name");
    if (auto it = body_index.find(b.name); it != body_index.end())
      fail(name_val,
           "duplicate body name '" + b.name + "' (first at line " +
               std::to_string(body_vals[static_cast<std::size_t>(it->second)].mark.line + 1) + ")");
    const Val mass_val = m.require("mass");
    b.mass = quantity(mass_val, Dimension::Mass);
    if (!(b.mass > 0)) fail(mass_val, "mass must be positive, found " + shortest(b.mass) + " kg");
    if (b.mass > kMaxMass) fail(mass_val, "absurd mass " + shortest(b.mass) + " kg (limit 1e9 kg)");
    b.I_BBo_B = inertia(m.require("inertia"));
    if (auto tv = m.get("torque")) {
      const MapView t(*this, *tv, {"frame", "profile"}, "a body torque");
      if (auto f = t.get("frame"))
        b.torque_frame = choice(*f, "torque frame", {"body", "inertial"}) == "inertial"
                             ? Body::Frame::Inertial
                             : Body::Frame::Body;
      b.torque = profile<3>(t.require("profile"), Dimension::Torque);
    }
    body_index.emplace(b.name, static_cast<int>(s.bodies.size()));
    body_vals.push_back(item);
    s.bodies.push_back(std::move(b));
  }
  std::vector<std::string> body_names;
  for (const Body& b : s.bodies) body_names.push_back(b.name);

  auto find_body = [&](const Val& v, const std::string& role) {
    const std::string n = identifier(v, role + " body name");
    const auto it = body_index.find(n);
    if (it == body_index.end())
      fail(v, "unknown body '" + n + "'" + suggestion(n, body_names) +
                  "; bodies: " + join(body_names));
    return it->second;
  };

  // ----- read_joints -----
  const Val joints_val = top.require("joints");
  const std::vector<Val> joint_items = list(joints_val, "a list of joints", true);
  std::vector<RawJoint> raw;
  std::unordered_map<std::string, std::size_t> joint_index;
  for (const Val& item : joint_items) {
    const MapView m(*this, item, kJointKeys, "a joint");
    Joint j;
    const Val name_val = m.require("name");
    j.name = identifier(name_val, "joint name");
    if (auto it = joint_index.find(j.name); it != joint_index.end())
      fail(name_val, "duplicate joint name '" + j.name + "' (first at line " +
                         std::to_string(raw[it->second].node.mark.line + 1) + ")");
    if (body_index.count(j.name))
      fail(name_val, "joint name '" + j.name + "' is also a body name; output columns \"" + j.name +
                         ".*\" would clash");
    const Val type_val = m.require("type");
    const std::string type = choice(type_val, "joint type", kJointTypes);
    j.type = type == "free"        ? JointType::Free
             : type == "revolute"  ? JointType::Revolute
             : type == "spherical" ? JointType::Spherical
                                   : JointType::Fixed;
    const std::vector<std::string>& allowed = joint_keys(j.type);
    for (const MapView::Entry& e : m.entries())
      if (std::find(allowed.begin(), allowed.end(), e.key) == allowed.end()) {
        std::string why = "'" + e.key + "' does not apply to a " + type + " joint";
        if (e.key == "parent" && j.type == JointType::Free)
          why += " (its parent is the inertial frame N)";
        else if (e.key == "initial" && j.type == JointType::Fixed)
          why += " (a fixed joint has no degrees of freedom, so no initial conditions)";
        fail(e.key_mark, e.value.path, why + "; its keys: " + join(allowed));
      }

    RawJoint r{j, item, type_val, m.require("child"), std::nullopt, std::nullopt};
    Joint& J = r.joint;
    J.child = find_body(r.child_val, "child");
    if (J.type != JointType::Free) {
      r.parent_val = m.require("parent");
      J.parent = find_body(*r.parent_val, "parent");
      if (J.parent == J.child)
        fail(*r.parent_val, "joint connects body '" + J.name + "' to itself");
      J.p_PoJ_P = vec3(m.require("parent_point"), Dimension::Length, "a point");
      J.p_CoJ_C = vec3(m.require("child_point"), Dimension::Length, "a point");
      if (auto v = m.get("offset")) J.q_PJ0 = attitude(*v);
    }
    if (J.type == JointType::Revolute) J.axis_P = direction(m.require("axis"), "an axis");
    if (auto v = m.get("spring")) {
      const std::vector<std::string> keys =
          J.type == JointType::Revolute ? std::vector<std::string>{"stiffness", "neutral_angle"}
                                        : std::vector<std::string>{"stiffness"};
      const MapView sp(*this, *v, keys, "a " + type + " joint's spring");
      const Val k = sp.require("stiffness");
      J.stiffness = quantity(k, Dimension::Stiffness);
      if (J.stiffness < 0) fail(k, "negative stiffness " + shortest(J.stiffness) + " N m/rad");
      if (auto a = sp.get("neutral_angle")) J.neutral_angle = quantity(*a, Dimension::Angle);
    }
    if (auto v = m.get("damper")) {
      const MapView dm(*this, *v, {"damping"}, "a damper");
      const Val c = dm.require("damping");
      J.damping = quantity(c, Dimension::Damping);
      if (J.damping < 0) fail(c, "negative damping " + shortest(J.damping) + " N m s/rad");
    }
    if (auto v = m.get("motor")) {
      const MapView mo(*this, *v, {"profile"}, "a motor");
      if (J.type == JointType::Revolute)
        J.motor_revolute = profile<1>(mo.require("profile"), Dimension::Torque);
      else
        J.motor_spherical = profile<3>(mo.require("profile"), Dimension::Torque);
    }
    if (auto v = m.get("initial")) {
      const MapView ic(*this, *v, initial_keys(J.type),
                       "the initial conditions of a " + type + " joint");
      switch (J.type) {
        case JointType::Free:
          if (auto x = ic.get("position")) J.p_NoBo_N0 = vec3(*x, Dimension::Length, "a position");
          if (auto x = ic.get("attitude")) J.q_NB0 = attitude(*x);
          if (auto x = ic.get("angular_velocity"))
            J.w_NB_B0 = vec3(*x, Dimension::AngularRate, "an angular velocity");
          if (auto x = ic.get("velocity")) {
            J.v_NBo_N0 = vec3(*x, Dimension::Velocity, "a velocity");
            r.velocity_val = *x;
          }
          break;
        case JointType::Revolute:
          if (auto x = ic.get("angle")) J.angle0 = quantity(*x, Dimension::Angle);
          if (auto x = ic.get("rate")) J.rate0 = quantity(*x, Dimension::AngularRate);
          break;
        case JointType::Spherical:
          if (auto x = ic.get("attitude")) J.q_J0 = attitude(*x);
          if (auto x = ic.get("angular_velocity"))
            J.w_PC_C0 = vec3(*x, Dimension::AngularRate, "an angular velocity");
          break;
        case JointType::Fixed:
          break;
      }
    }
    joint_index.emplace(J.name, raw.size());
    raw.push_back(std::move(r));
  }

  // ----- order_joints: one parent per body, one free joint, no cycles, topological order -----
  const std::size_t nb = s.bodies.size();
  std::vector<int> joint_of(nb, -1);
  int free_joint = -1;
  for (std::size_t k = 0; k < raw.size(); ++k) {
    const Joint& J = raw[k].joint;
    if (J.type == JointType::Free) {
      if (free_joint >= 0)
        fail(raw[k].type_val, "a second free joint (the first is '" +
                                  raw[static_cast<std::size_t>(free_joint)].joint.name +
                                  "'); exactly one joint, the base body's, is free");
      free_joint = static_cast<int>(k);
    }
    int& owner = joint_of[static_cast<std::size_t>(J.child)];
    if (owner >= 0)
      fail(raw[k].child_val,
           "body '" + s.bodies[static_cast<std::size_t>(J.child)].name +
               "' already has a parent joint '" + raw[static_cast<std::size_t>(owner)].joint.name +
               "' (line " +
               std::to_string(raw[static_cast<std::size_t>(owner)].node.mark.line + 1) +
               "); a body has exactly one parent");
    owner = static_cast<int>(k);
  }
  if (free_joint < 0)
    fail(joints_val,
         "no free joint: exactly one joint must be of type free (it holds the base body)");
  for (std::size_t b = 0; b < nb; ++b)
    if (joint_of[b] < 0)
      fail(body_vals[b].mark, body_vals[b].path,
           "body '" + s.bodies[b].name +
               "' has no joint: every body is the child of exactly one joint");
  // Every body has one parent, so a body not connected to the base lies on or below a cycle.
  std::vector<int> state(nb, 0);  // 0 unseen, 1 on the current walk, 2 connected to the base
  const int base = raw[static_cast<std::size_t>(free_joint)].joint.child;
  state[static_cast<std::size_t>(base)] = 2;
  for (std::size_t b0 = 0; b0 < nb; ++b0) {
    std::vector<int> walk;
    int b = static_cast<int>(b0);
    while (state[static_cast<std::size_t>(b)] == 0) {
      state[static_cast<std::size_t>(b)] = 1;
      walk.push_back(b);
      b = raw[static_cast<std::size_t>(joint_of[static_cast<std::size_t>(b)])].joint.parent;
    }
    if (state[static_cast<std::size_t>(b)] == 1) {
      std::string cycle = s.bodies[static_cast<std::size_t>(b)].name;
      const auto start = std::find(walk.begin(), walk.end(), b);
      for (auto it = std::next(start); it != walk.end(); ++it)
        cycle += " -> " + s.bodies[static_cast<std::size_t>(*it)].name;
      cycle += " -> " + s.bodies[static_cast<std::size_t>(b)].name;
      const RawJoint& rj = raw[static_cast<std::size_t>(joint_of[static_cast<std::size_t>(b)])];
      fail(*rj.parent_val, "body '" + s.bodies[static_cast<std::size_t>(b)].name +
                               "' is not connected to the base body '" +
                               s.bodies[static_cast<std::size_t>(base)].name +
                               "': the joints form a cycle of parents (" + cycle + ")");
    }
    for (int w : walk) state[static_cast<std::size_t>(w)] = 2;
  }
  // Kahn's algorithm, always taking the ready joint listed first in the file, so a file already
  // in topological order keeps its order.
  std::vector<std::vector<std::size_t>> children(nb);
  for (std::size_t k = 0; k < raw.size(); ++k)
    if (raw[k].joint.parent >= 0)
      children[static_cast<std::size_t>(raw[k].joint.parent)].push_back(k);
  std::priority_queue<std::size_t, std::vector<std::size_t>, std::greater<>> ready;
  ready.push(static_cast<std::size_t>(free_joint));
  while (!ready.empty()) {
    const std::size_t k = ready.top();
    ready.pop();
    s.joints.push_back(raw[k].joint);
    for (std::size_t c : children[static_cast<std::size_t>(raw[k].joint.child)]) ready.push(c);
  }

  // ----- zero linear momentum vs a given base velocity -----
  const RawJoint& free_raw = raw[static_cast<std::size_t>(free_joint)];
  if (s.zero_linear_momentum && free_raw.velocity_val)
    fail(*free_raw.velocity_val,
         "the base velocity is computed when zero_linear_momentum is true (the default); remove it "
         "or "
         "set zero_linear_momentum: false");

  // ----- read_run ----- (the limits are core/run_limits.hpp's, shared with the command line)
  {
    const MapView m(*this, top.require("run"),
                    {"duration", "output_step", "integrator", "rtol", "atol", "dt"},
                    "the run block");
    auto limit = [this](const Val& v, const std::string& problem) {
      if (!problem.empty()) fail(v, problem);
    };
    const Val dv = m.require("duration");
    s.run.duration = quantity(dv, Dimension::Time);
    limit(dv, run_limits::duration_problem(s.run.duration));
    const Val ov = m.require("output_step");
    s.run.output_step = quantity(ov, Dimension::Time);
    limit(ov, run_limits::output_step_problem(s.run.output_step, s.run.duration));
    if (auto v = m.get("integrator")) s.run.integrator = choice(*v, "integrator", kIntegrators);
    for (const char* key : {"rtol", "atol"})
      if (auto v = m.get(key)) {
        const double x = quantity(*v, Dimension::None);
        limit(*v, run_limits::tolerance_problem(key, x));
        (std::string(key) == "rtol" ? s.run.rtol : s.run.atol) = x;
      }
    if (auto v = m.get("dt")) {
      s.run.dt = quantity(*v, Dimension::Time);
      limit(*v, run_limits::dt_problem(s.run.dt));
    }
  }

  // ----- read_compare -----
  if (auto cv = top.get("compare")) {
    const MapView m(*this, *cv, {"tolerances", "exclude"}, "the compare block");
    auto tolerance = [&](const Val& v, Tolerance base) {
      const MapView t(*this, v, {"atol", "rtol"}, "a tolerance");
      for (const char* key : {"atol", "rtol"})
        if (auto x = t.get(key)) {
          const double value = quantity(*x, Dimension::None);
          if (value < 0) fail(*x, "negative tolerance " + shortest(value));
          (std::string(key) == "atol" ? base.atol : base.rtol) = value;
        }
      return base;
    };
    if (auto tv = m.get("tolerances")) {
      const MapView t(*this, *tv, {}, "the tolerances", true);
      if (auto d = t.get("default"))
        s.compare.default_tolerance = tolerance(*d, s.compare.default_tolerance);
      for (const MapView::Entry& e : t.entries()) {
        if (e.key == "default") continue;
        identifier(Val{YAML::Node(e.key), e.value.path, e.key_mark}, "quantity name", true);
        s.compare.tolerances.emplace_back(e.key, tolerance(e.value, s.compare.default_tolerance));
      }
    }
    if (auto ev = m.get("exclude")) {
      std::unordered_set<std::string> excluded;
      for (const Val& item : list(*ev, "a list of {quantity, reason}", false)) {
        const MapView x(*this, item, {"quantity", "reason"}, "an exclusion");
        const Val qv = x.require("quantity");
        const std::string q = identifier(qv, "quantity name", true);
        if (!excluded.insert(q).second) fail(qv, "quantity '" + q + "' is excluded twice");
        const Val rv = x.require("reason");
        const std::string reason = free_text(rv, "reason");
        if (reason.empty()) fail(rv, "give a reason for excluding '" + q + "'");
        s.compare.excluded.emplace_back(q, reason);
      }
    }
  }

  // ----- check_analytic -----
  if (s.analytic == "torque-free") {
    const Val av = *top.get("analytic");
    if (s.bodies.size() != 1)
      fail(av, "the torque-free reference needs a single free rigid body; this scene has " +
                   std::to_string(s.bodies.size()) + " bodies");
    if (!s.bodies[0].torque.empty())
      fail(av, "the torque-free reference needs a body without external torque");
  }
  return s;
}

// ---------------------------------------------------------------------------------------------
// Writing.

YAML::Emitter& number(YAML::Emitter& out, double x) { return out << shortest(x); }

template <typename V>
void vector_flow(YAML::Emitter& out, const V& v) {
  out << YAML::Flow << YAML::BeginSeq;
  for (Eigen::Index i = 0; i < v.size(); ++i) number(out, v[i]);
  out << YAML::EndSeq;
}

void quaternion_flow(YAML::Emitter& out, const Eigen::Quaterniond& q) {
  vector_flow(out, Eigen::Vector4d(q.w(), q.x(), q.y(), q.z()));
}

template <int D>
void profile_out(YAML::Emitter& out, const PiecewiseConstant<D>& p) {
  out << YAML::BeginSeq;
  for (std::size_t k = 0; k < p.times.size(); ++k) {
    out << YAML::Flow << YAML::BeginMap << YAML::Key << "t" << YAML::Value;
    number(out, p.times[k]);
    out << YAML::Key << "value" << YAML::Value;
    if constexpr (D == 1)
      number(out, p.values[k][0]);
    else
      vector_flow(out, p.values[k]);
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;
}

bool is_identity(const Eigen::Quaterniond& q) {
  return q.w() == 1 && q.x() == 0 && q.y() == 0 && q.z() == 0;
}

}  // namespace

System read_scene_text(const std::string& text, const std::string& file_label) {
  const Reader reader(file_label);
  try {
    return reader.read(text);
  } catch (const YAML::Exception& e) {  // anything yaml-cpp throws past parsing
    reader.fail(e.mark, "", "malformed YAML: " + e.msg);
  }
}

// Why `path` cannot be read as a scene, or "" when it can be opened: missing, a directory, no
// permission, a symbolic link loop, not a regular file (FIFOs are read: `<(...)`).
std::string scene_open_problem(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int e = errno;
    if (e == ENOENT) {
      struct stat lst {};
      return ::lstat(path.c_str(), &lst) == 0 ? "it is a symbolic link to a file that does not exist"
                                             : "no such file";
    }
    if (e == ELOOP) return "too many levels of symbolic links (a symbolic link loop)";
    if (e == EACCES) return "permission denied (a folder on the path cannot be searched)";
    if (e == ENOTDIR) return "a part of the path is not a folder";
    return std::strerror(e);
  }
  if (S_ISDIR(st.st_mode)) return "it is a directory, not a scene file";
  if (S_ISSOCK(st.st_mode)) return "it is a socket, not a regular file";
  if (S_ISBLK(st.st_mode)) return "it is a block device, not a regular file";
  if (::access(path.c_str(), R_OK) != 0)
    return errno == EACCES ? "permission denied (the file is not readable)" : std::strerror(errno);
  return "";
}

System read_scene(const std::string& path) {
  if (const std::string why = scene_open_problem(path); !why.empty())
    throw InputError(path + ":1:1: cannot open the scene file: " + why);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ":1:1: cannot open the scene file: " + std::strerror(errno));
  std::string text;
  char buf[65536];
  while (in.read(buf, sizeof buf) || in.gcount() > 0) {
    text.append(buf, static_cast<std::size_t>(in.gcount()));
    if (text.size() > kMaxSceneBytes) break;  // precheck_text reports it
  }
  if (in.bad()) throw InputError(path + ":1:1: cannot read the scene file");
  return read_scene_text(text, path);
}

std::string write_scene_text(const System& s) {
  YAML::Emitter out;
  out.SetIndent(2);
  out << YAML::BeginMap;
  out << YAML::Key << "name" << YAML::Value << s.name;
  out << YAML::Key << "description" << YAML::Value << YAML::DoubleQuoted << s.description;
  out << YAML::Key << "source" << YAML::Value << YAML::DoubleQuoted << s.source;
  if (!s.analytic.empty()) out << YAML::Key << "analytic" << YAML::Value << s.analytic;
  out << YAML::Key << "zero_linear_momentum" << YAML::Value
      << (s.zero_linear_momentum ? "true" : "false");

  out << YAML::Key << "bodies" << YAML::Value << YAML::BeginSeq;
  for (const Body& b : s.bodies) {
    out << YAML::BeginMap;
    out << YAML::Key << "name" << YAML::Value << b.name;
    out << YAML::Key << "mass" << YAML::Value;
    number(out, b.mass);
    out << YAML::Key << "inertia" << YAML::Value;
    const Eigen::Matrix3d& I = b.I_BBo_B;
    if (I(0, 1) == 0 && I(0, 2) == 0 && I(1, 2) == 0)
      vector_flow(out, Eigen::Vector3d(I(0, 0), I(1, 1), I(2, 2)));
    else
      vector_flow(out, (Eigen::Matrix<double, 6, 1>() << I(0, 0), I(1, 1), I(2, 2), I(0, 1),
                        I(0, 2), I(1, 2))
                           .finished());
    if (!b.torque.empty()) {
      out << YAML::Key << "torque" << YAML::Value << YAML::BeginMap;
      out << YAML::Key << "frame" << YAML::Value
          << (b.torque_frame == Body::Frame::Inertial ? "inertial" : "body");
      out << YAML::Key << "profile" << YAML::Value;
      profile_out(out, b.torque);
      out << YAML::EndMap;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;

  auto body_name = [&s](int b) { return s.bodies.at(static_cast<std::size_t>(b)).name; };
  out << YAML::Key << "joints" << YAML::Value << YAML::BeginSeq;
  for (const Joint& j : s.joints) {
    out << YAML::BeginMap;
    out << YAML::Key << "name" << YAML::Value << j.name;
    out << YAML::Key << "type" << YAML::Value << type_name(j.type);
    if (j.type != JointType::Free)
      out << YAML::Key << "parent" << YAML::Value << body_name(j.parent);
    out << YAML::Key << "child" << YAML::Value << body_name(j.child);
    if (j.type != JointType::Free) {
      out << YAML::Key << "parent_point" << YAML::Value;
      vector_flow(out, j.p_PoJ_P);
      out << YAML::Key << "child_point" << YAML::Value;
      vector_flow(out, j.p_CoJ_C);
      if (!is_identity(j.q_PJ0)) {
        out << YAML::Key << "offset" << YAML::Value;
        quaternion_flow(out, j.q_PJ0);
      }
    }
    if (j.type == JointType::Revolute) {
      out << YAML::Key << "axis" << YAML::Value;
      vector_flow(out, j.axis_P);
    }
    if (j.type == JointType::Revolute || j.type == JointType::Spherical) {
      if (j.stiffness != 0 || (j.type == JointType::Revolute && j.neutral_angle != 0)) {
        out << YAML::Key << "spring" << YAML::Value << YAML::Flow << YAML::BeginMap;
        out << YAML::Key << "stiffness" << YAML::Value;
        number(out, j.stiffness);
        if (j.type == JointType::Revolute) {
          out << YAML::Key << "neutral_angle" << YAML::Value;
          number(out, j.neutral_angle);
        }
        out << YAML::EndMap;
      }
      if (j.damping != 0) {
        out << YAML::Key << "damper" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key
            << "damping" << YAML::Value;
        number(out, j.damping);
        out << YAML::EndMap;
      }
      const bool motor =
          j.type == JointType::Revolute ? !j.motor_revolute.empty() : !j.motor_spherical.empty();
      if (motor) {
        out << YAML::Key << "motor" << YAML::Value << YAML::BeginMap << YAML::Key << "profile"
            << YAML::Value;
        if (j.type == JointType::Revolute)
          profile_out(out, j.motor_revolute);
        else
          profile_out(out, j.motor_spherical);
        out << YAML::EndMap;
      }
    }
    switch (j.type) {
      case JointType::Free:
        out << YAML::Key << "initial" << YAML::Value << YAML::BeginMap;
        out << YAML::Key << "position" << YAML::Value;
        vector_flow(out, j.p_NoBo_N0);
        out << YAML::Key << "attitude" << YAML::Value;
        quaternion_flow(out, j.q_NB0);
        out << YAML::Key << "angular_velocity" << YAML::Value;
        vector_flow(out, j.w_NB_B0);
        if (!s.zero_linear_momentum) {
          out << YAML::Key << "velocity" << YAML::Value;
          vector_flow(out, j.v_NBo_N0);
        }
        out << YAML::EndMap;
        break;
      case JointType::Revolute:
        out << YAML::Key << "initial" << YAML::Value << YAML::Flow << YAML::BeginMap;
        out << YAML::Key << "angle" << YAML::Value;
        number(out, j.angle0);
        out << YAML::Key << "rate" << YAML::Value;
        number(out, j.rate0);
        out << YAML::EndMap;
        break;
      case JointType::Spherical:
        out << YAML::Key << "initial" << YAML::Value << YAML::BeginMap;
        out << YAML::Key << "attitude" << YAML::Value;
        quaternion_flow(out, j.q_J0);
        out << YAML::Key << "angular_velocity" << YAML::Value;
        vector_flow(out, j.w_PC_C0);
        out << YAML::EndMap;
        break;
      case JointType::Fixed:
        break;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;

  out << YAML::Key << "run" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "duration" << YAML::Value;
  number(out, s.run.duration);
  out << YAML::Key << "output_step" << YAML::Value;
  number(out, s.run.output_step);
  out << YAML::Key << "integrator" << YAML::Value << s.run.integrator;
  out << YAML::Key << "rtol" << YAML::Value;
  number(out, s.run.rtol);
  out << YAML::Key << "atol" << YAML::Value;
  number(out, s.run.atol);
  out << YAML::Key << "dt" << YAML::Value;
  number(out, s.run.dt);
  out << YAML::EndMap;

  auto tolerance_out = [&out](const Tolerance& t) {
    out << YAML::Flow << YAML::BeginMap << YAML::Key << "atol" << YAML::Value;
    number(out, t.atol);
    out << YAML::Key << "rtol" << YAML::Value;
    number(out, t.rtol);
    out << YAML::EndMap;
  };
  out << YAML::Key << "compare" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "tolerances" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "default" << YAML::Value;
  tolerance_out(s.compare.default_tolerance);
  for (const auto& [quantity, t] : s.compare.tolerances) {
    out << YAML::Key << quantity << YAML::Value;
    tolerance_out(t);
  }
  out << YAML::EndMap;
  if (!s.compare.excluded.empty()) {
    out << YAML::Key << "exclude" << YAML::Value << YAML::BeginSeq;
    for (const auto& [quantity, reason] : s.compare.excluded) {
      out << YAML::BeginMap << YAML::Key << "quantity" << YAML::Value << quantity;
      out << YAML::Key << "reason" << YAML::Value << YAML::DoubleQuoted << reason << YAML::EndMap;
    }
    out << YAML::EndSeq;
  }
  out << YAML::EndMap;

  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace crossdyn
