// The scene reader's value layer (reader.hpp): mappings checked against the schema, and every
// typed value a key may hold.
#include <Eigen/Eigenvalues>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <unordered_map>

#include "core/errors.hpp"
#include "core/scene/reader.hpp"
#include "core/units.hpp"

namespace crossdyn::scene {
namespace {

using units::Dimension;

// Vectors and quaternions whose norm is within this of 1 are kept as written, so that a written
// scene reads back bit for bit (normalising an already normalised vector may change its last bit).
constexpr double kUnitNormKeep = 8 * std::numeric_limits<double>::epsilon();

std::string key_path(const std::string& parent, const std::string& key) {
  return parent.empty() ? key : parent + "." + key;
}

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

// `s` with every run of white space (a list written over several lines) made one space.
std::string one_line(const std::string& s) {
  std::string out;
  for (char c : s) {
    const bool space = c == ' ' || c == '\t' || c == '\n' || c == '\r';
    if (space && (out.empty() || out.back() == ' ')) continue;
    out += space ? ' ' : c;
  }
  if (!out.empty() && out.back() == ' ') out.pop_back();
  return out;
}

// "[30 kg m^2, 20 kg m^2, 12 kg m^2]" for the list "[30, 20, 12]" and the unit "kg m^2", or ""
// when the list holds more than plain numbers (nested lists, mappings, quoted text).
std::string with_each_element(const std::string& list, const std::string& unit) {
  if (list.size() < 2 || list.front() != '[' || list.back() != ']') return "";
  const std::string inner = list.substr(1, list.size() - 2);
  if (inner.find_first_of("[]{}\"'#") != std::string::npos) return "";
  std::string out = "[";
  std::size_t from = 0;
  for (;;) {
    const std::size_t comma = inner.find(',', from);
    const std::string element = one_line(inner.substr(from, comma - from));
    if (element.empty()) return "";
    out += (from == 0 ? "" : ", ") + element + " " + unit;
    if (comma == std::string::npos) break;
    from = comma + 1;
  }
  return out + "]";
}

// What to write instead of a unit after a list, for the key of schema row `row` (nullptr when
// not known).
std::string unit_after_list_message(const UnitAfterList& u, const Key* row) {
  const std::string head = "a unit after a list is not read (YAML ends the value at ']'): ";
  const std::string list = one_line(u.list);
  const std::string inner = list.substr(1, list.size() - 2);
  if (row != nullptr && row->path == "(list with unit).value")
    return head + "write the unit in `unit`: {value: " + list + ", unit: " + u.unit + "}";
  if (row != nullptr) switch (row->type) {
      case Type::List:
        return head + "write the unit with each value inside the list" +
               (row->path.ends_with("profile") ? " ({t: 2 s, value: 0.1 " + u.unit + "})" : "");
      case Type::Direction:
      case Type::Attitude:
        return head + "this key takes bare numbers, without a unit: write " + list;
      case Type::Quantity:
        return "a list is not read here: this key takes one number and its unit" +
               (inner.find_first_of("[]{},") == std::string::npos
                    ? ", " + inner + " " + u.unit
                    : std::string());
      case Type::Number:
        return "a list is not read here: this key takes one bare number";
      case Type::Text:
      case Type::Name:
      case Type::Word:
      case Type::Bool:
      case Type::Map:
        return "'[' begins a list in YAML, which ends at ']': put the whole value in quotes, "
               "\"" + list + " " + u.unit + "\"";
      case Type::Vector:
      case Type::Pair:
      case Type::Inertia:
        break;
    }
  std::string out = head + "write {value: " + list + ", unit: " + u.unit + "} (one unit for all)";
  const std::string each = with_each_element(list, u.unit);
  if (!each.empty()) out += " or " + each + " (each element with its unit)";
  if (row == nullptr) return out;
  out += "; a bare " + list + " is in " + units::unit_names(row->dimension).front() + " (SI)";
  const auto written = units::find_unit(u.unit);
  if (!written)
    out += "; and '" + u.unit + "' is not a known unit: " + units::dimension_name(row->dimension) +
           " is in " + units::units_of(row->dimension);
  else if (written->dimension != row->dimension)
    out += "; and '" + u.unit + "' is " + units::dimension_name(written->dimension) +
           ", but this key expects " + units::dimension_name(row->dimension) + " (" +
           units::units_of(row->dimension) + ")";
  return out;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Several errors

void Reader::keep(const InputError& e) const {
  // Two passes may read one value (a prescribed joint's initial block): say it once.
  for (const Recorded& x : errors_)
    if (x.message == e.what()) return;
  const auto* located = dynamic_cast<const SceneError*>(&e);
  if (located != nullptr && std::find(quiet_paths_.begin(), quiet_paths_.end(),
                                      located->path()) != quiet_paths_.end())
    return;
  if (errors_.size() >= kMaxRecordedErrors) {
    ++more_errors_;
    return;
  }
  errors_.push_back(Recorded{located ? located->line() : std::numeric_limits<int>::max(),
                             located ? located->column() : 0, e.what()});
}

void Reader::record(const YAML::Mark& m, const std::string& path, const std::string& what) const {
  attempt([&] { fail(m, path, what); });
}

void Reader::unit_after_list(const Val& v, const Key* row) const {
  const YAML::Mark m = v.node.Mark();
  if (units_after_lists_.empty() || m.is_null() || !v.node.IsSequence()) return;
  for (UnitAfterList& u : units_after_lists_)
    if (!u.reported && u.list_pos == static_cast<std::size_t>(m.pos)) {
      u.reported = true;
      record(u.mark, v.path, unit_after_list_message(u, row));
      quiet_paths_.push_back(v.path);
    }
}

void Reader::finish() const {
  for (UnitAfterList& u : units_after_lists_) {
    if (u.reported) continue;
    u.reported = true;
    // The key as written; its schema row when every row of that name has the same form.
    const Key* row = nullptr;
    bool one_form = !u.key.empty();
    for (const Key& k : keys()) {
      const std::string_view p = k.path;
      const std::size_t dot = p.rfind('.');
      if ((dot == std::string_view::npos ? p : p.substr(dot + 1)) != u.key) continue;
      if (row != nullptr && ((row->type == Type::List) != (k.type == Type::List) ||
                             row->dimension != k.dimension))
        one_form = false;
      row = &k;
    }
    record(u.mark, u.key, unit_after_list_message(u, one_form ? row : nullptr));
  }
  if (errors_.empty()) {
    if (skipped_) throw std::logic_error("scene reader: a part was skipped without an error");
    return;
  }
  std::stable_sort(errors_.begin(), errors_.end(), [](const Recorded& a, const Recorded& b) {
    return a.line != b.line ? a.line < b.line : a.column < b.column;
  });
  std::string message;
  const std::size_t shown = std::min(errors_.size(), kMaxReportedErrors);
  for (std::size_t i = 0; i < shown; ++i) message += (i == 0 ? "" : "\n") + errors_[i].message;
  if (const std::size_t more = errors_.size() + more_errors_ - shown; more > 0)
    message += "\n... and " + std::to_string(more) + " more error" + (more == 1 ? "" : "s");
  if (stopped_line_ > 0)
    message += "\n... and perhaps more after line " + std::to_string(stopped_line_) +
               ", where the reader stopped";
  throw InputError(message);
}

// ---------------------------------------------------------------------------------------------
// MapView

MapView::MapView(const Reader& r, const Val& v, std::string schema_path, unsigned joints,
                 std::string_view type_name)
    : r_(r), self_(v), schema_path_(std::move(schema_path)), joints_(joints) {
  const Key* self_row = find(schema_path_, joints);
  if (self_row == nullptr || self_row->type != Type::Map)
    throw std::logic_error("scene schema: no mapping row '" + schema_path_ + "'");
  noun_ = noun(*self_row, type_name);
  if (!v.node.IsMap())
    r.fail(v, "expected " + noun_ + " (a mapping of keys), found " + describe(v.node));
  const std::vector<std::string> known = child_names(schema_path_, joints);
  std::vector<std::string> named;  // the known keys without the wildcard
  bool any_key = false;
  for (const std::string& k : known) {
    if (k.starts_with('<'))
      any_key = true;  // a wildcard: any key is accepted (compare.tolerances)
    else
      named.push_back(k);
  }
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
    // Unknown and duplicate keys are recorded and left out; the other keys are read on.
    if (const auto [first, fresh] = seen.emplace(key, km.line); !fresh) {
      r.record(
          km, path,
          "duplicate key '" + key + "' (first at line " + std::to_string(first->second + 1) + ")");
      continue;
    }
    if (!any_key && std::find(named.begin(), named.end(), key) == named.end()) {
      r.record(km, path,
               "unknown key " + quoted_excerpt(key) + " in " + noun_ + suggestion(key, named) +
                   "; known keys: " + join(named));
      unknown_.push_back(key);
      continue;
    }
    // A key without a value ("mass:") has a null node whose mark is the next token's: use the
    // key's.
    entries_.push_back(
        Entry{key, km, value.IsNull() ? Val{value, path, km} : r.sub(v, value, path)});
    if (r.units_after_lists() > 0)
      r.unit_after_list(entries_.back().value, find(key_path(schema_path_, key), joints));
  }
  check_required();
}

// Every key required for all of joints_ must be there, with a value.
void MapView::check_required() const {
  for (const Key& k : keys()) {
    if (!k.required || (k.joints & joints_) != joints_) continue;
    const std::string_view p = k.path;
    const std::size_t dot = p.rfind('.');
    if (dot == std::string_view::npos ? !schema_path_.empty() : p.substr(0, dot) != schema_path_)
      continue;
    const std::string name(dot == std::string_view::npos ? p : p.substr(dot + 1));
    bool found = false;
    for (const Entry& e : entries_)
      if (e.key == name) {
        if (e.value.node.IsNull()) r_.fail(e.value, "key '" + name + "' has no value");
        found = true;
      }
    if (!found) missing(name, "missing required key '" + name + "' in " + noun_);
  }
}

bool MapView::mistyped(const std::string& key) const {
  for (const std::string& u : unknown_)
    if (!suggestion(u, {key}).empty()) return true;
  return false;
}

void MapView::missing(const std::string& key, const std::string& message) const {
  // A mistyped key ("mas" for "mass") is reported as unknown, with the suggestion: not twice.
  if (mistyped(key)) r_.skip();
  r_.fail(self_, message);
}

const Key& MapView::row(std::string_view key) const {
  const Key* k = find(key_path(schema_path_, std::string(key)), joints_);
  if (k == nullptr)
    throw std::logic_error("scene schema: the reader asked for '" +
                           key_path(schema_path_, std::string(key)) +
                           "', which the schema does not have");
  return *k;
}

std::optional<Field> MapView::get(std::string_view key) const {
  // A key of another joint type cannot be here (the constructor or narrow() rejected it).
  if (find(key_path(schema_path_, std::string(key)), joints_) == nullptr &&
      find(key_path(schema_path_, std::string(key))) != nullptr)
    return std::nullopt;
  const Key& k = row(key);
  for (const Entry& e : entries_)
    if (e.key == key) return Field{e.value, &k};
  return std::nullopt;
}

Field MapView::at(std::string_view key) const {
  const Key& k = row(key);
  if (!k.required)
    throw std::logic_error("scene schema: '" + std::string(k.path) + "' is optional; use get()");
  for (const Entry& e : entries_)
    if (e.key == key) return Field{e.value, &k};
  missing(std::string(key), "missing required key '" + std::string(key) + "' in " + noun_);
}

// ---------------------------------------------------------------------------------------------
// Reader: positions, structure

void Reader::fail(const YAML::Mark& m, const std::string& path, const std::string& what) const {
  const int line = m.is_null() || m.line < 0 ? 1 : m.line + 1;
  const int column = m.is_null() || m.column < 0 ? 1 : m.column + 1;
  throw SceneError(file_ + ":" + std::to_string(line) + ":" + std::to_string(column) + ": " +
                       (path.empty() ? "" : path + ": ") + what,
                   line, column, path);
}

void Reader::warn(const Val& v, const std::string& code, const std::string& what) const {
  const YAML::Mark& m = v.mark;
  warnings_.push_back(SceneWarning{file_, m.is_null() || m.line < 0 ? 1 : m.line + 1,
                                   m.is_null() || m.column < 0 ? 1 : m.column + 1, v.path, what,
                                   code, v.path});
}

std::vector<Val> Reader::list(const Val& v, const std::string& what, bool non_empty) const {
  if (!v.node.IsSequence()) fail(v, "expected " + what + ", found " + describe(v.node));
  std::vector<Val> items;
  std::size_t i = 0;
  for (const YAML::Node& n : v.node)
    items.push_back(sub(v, n, v.path + "[" + std::to_string(i++) + "]"));
  if (non_empty && items.empty()) fail(v, "expected " + what + ", found an empty list");
  return items;
}

std::vector<Val> Reader::list(const Field& f) const {
  return list(f.val, std::string(f.key->noun), f.key->required);
}

const std::string& Reader::scalar(const Val& v, const std::string& what) const {
  if (!v.node.IsScalar()) fail(v, "expected " + what + ", found " + describe(v.node));
  return v.node.Scalar();
}

// ---------------------------------------------------------------------------------------------
// Words and texts

// A body, joint or scene name: it becomes part of output column names ("<body>.wx").
std::string Reader::name(const Val& v, const std::string& what, bool allow_dot) const {
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

std::string Reader::name(const Field& f) const {
  // Scene and quantity names may hold dots ("main.wx", "spear1.case1"); body and joint names not.
  const bool allow_dot = f.key->path == "name" || f.key->path.starts_with("compare.");
  return name(f.val, std::string(f.key->noun), allow_dot);
}

// Free text (description, source, reasons): printable UTF-8, tabs and newlines allowed.
std::string Reader::text(const Field& f) const {
  const std::string what(f.key->noun);
  const std::string& s = scalar(f.val, what);
  if (invalid_utf8_at(s) != std::string_view::npos) fail(f.val, what + " is not valid UTF-8");
  for (char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if ((u < 0x20 && c != '\n' && c != '\t') || u == 0x7F)
      fail(f.val, what + " contains the control character " + std::to_string(u) +
                      " (only tabs and newlines are allowed)");
  }
  return s;
}

std::string Reader::word(const Field& f) const {
  const std::string what(f.key->noun);
  const std::vector<std::string> w = words(*f.key);
  const std::string& s = scalar(f.val, what);
  if (std::find(w.begin(), w.end(), s) == w.end())
    fail(f.val, "unknown " + without_article(what) + " " + quoted_excerpt(s) + suggestion(s, w) +
                    "; expected one of: " + join(w));
  return s;
}

bool Reader::boolean(const Field& f) const {
  const std::string& s = scalar(f.val, "true or false");
  if (s == "true" || s == "True" || s == "TRUE") return true;
  if (s == "false" || s == "False" || s == "FALSE") return false;
  fail(f.val, "expected true or false, found " + quoted_excerpt(s));
}

// ---------------------------------------------------------------------------------------------
// Numbers and units

// Splits "<number> <unit>" (the unit may be empty) and parses the number.
std::pair<double, std::string> Reader::number_and_unit(const Val& v, Dimension d) const {
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

double Reader::unit_factor(const Val& v, const std::string& unit, Dimension d) const {
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

double Reader::sane(const Val& v, double si, Dimension d) const {
  if (!std::isfinite(si)) fail(v, "value is not finite after unit conversion");
  // A gravitational parameter is large in SI (Earth 3.986e14, the Sun 1.327e20 m^3/s^2): its own
  // cap, 1e22 (above every star a spacecraft orbits; mu / R^3 stays a normal double).
  const double absurd = d == Dimension::GravitationalParameter ? 1e22 : kAbsurd;
  if (std::abs(si) > absurd)
    fail(v, "absurd value " + shortest(si) +
                (d == Dimension::GravitationalParameter
                     ? std::string(" (a gravitational parameter above 1e22 m^3/s^2)")
                     : std::string(" (magnitude above 1e12 in SI units)")));
  // A tiny nonzero value (1e-320, subnormal; 1e-200) would be read and then make the run
  // non-finite (ramp_time: 1e-320 gave NaN at t = 0): refused here, at its key. Between
  // kTiny and kAbsurd, a product or quotient of three values stays a normal double.
  if (si != 0 && std::abs(si) < kTiny)
    fail(v, "value " + shortest(si) + " is too small to compute with (a magnitude above 0 and "
            "below 1e-100 in SI units; the allowed magnitudes are 0 where the key allows it, "
            "and 1e-100 to 1e12)");
  // Angles whose size no run survives (measured: a hinge angle of 1e8 rad ends every engine's run
  // at its first steps, exit 3): refused here. Angular rates are not capped here: whether a fast
  // spin can be integrated depends on the duration and the step (a free body at 1e5 rad/s for
  // 10 ms runs with every adaptive method: tests/cli/test_cancel_cli.cpp); a prescribed rate has
  // its own limit (kMaxAngularRate, reader.cpp).
  if (d == Dimension::Angle && std::abs(si) > kMaxAngle)
    fail(v, "angle " + shortest(si) + " rad is too large: at most 1e6 rad in size (the allowed range "
            "is -1e6 to 1e6 rad)");
  return si;
}

double Reader::quantity(const Val& v, Dimension d, std::optional<double> factor) const {
  const auto [x, unit] = number_and_unit(v, d);
  if (factor) {
    if (!unit.empty())
      fail(v, "the unit is given once for this list; its elements must be bare numbers");
    return sane(v, x * *factor, d);
  }
  if (unit.empty() && d == Dimension::Angle && std::abs(x) > 2 * std::numbers::pi) {
    // Bare angles are radians; one above a full turn was probably meant in degrees.
    const std::string written = v.node.Scalar();
    char degrees[32];
    std::snprintf(degrees, sizeof degrees, "%.1f", x * 180 / std::numbers::pi);
    warn(v, "angle-unitless-large", written + " has no unit and is read as " + shortest(x) + " rad = " + degrees +
                " deg; write '" + written + " deg' or '" + written + " rad'");
  }
  return sane(v, unit.empty() ? x : x * unit_factor(v, unit, d), d);
}

double Reader::number(const Field& f) const { return quantity(f.val, f.key->dimension); }

// A list of numbers: [a, b, c] (each a quantity) or {value: [a, b, c], unit: u}.
std::vector<double> Reader::numbers(const Val& v, Dimension d, std::size_t n,
                                    const std::string& what) const {
  Val items = v;
  std::optional<double> factor;
  if (v.node.IsMap()) {
    const MapView m(*this, v, "(list with unit)");
    items = m.at("value").val;
    if (auto u = m.get("unit")) factor = unit_factor(u->val, scalar(u->val, "a unit"), d);
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

Eigen::Vector3d Reader::vector(const Field& f) const {
  const Dimension d = f.key->dimension;
  const std::string what =
      f.key->noun.empty() ? units::dimension_name(d) + " vector" : std::string(f.key->noun);
  const auto x = numbers(f.val, d, 3, what);
  return {x[0], x[1], x[2]};
}

Eigen::Vector2d Reader::pair(const Field& f) const {
  const Dimension d = f.key->dimension;
  const std::string what =
      f.key->noun.empty() ? "a pair of " + units::dimension_name(d) + " values (axis 1, axis 2)"
                          : std::string(f.key->noun);
  const auto x = numbers(f.val, d, 2, what);
  return {x[0], x[1]};
}

// A direction: non-zero, normalised (kept as written when already unit to 8 eps).
Eigen::Vector3d Reader::direction(const Field& f) const {
  const auto x = numbers(f.val, Dimension::None, 3, std::string(f.key->noun));
  Eigen::Vector3d a(x[0], x[1], x[2]);
  const double n = a.norm();
  if (!(n >= kMinAxisLength))
    fail(f.val, "zero axis (length " + shortest(n) + "): give a non-zero direction");
  if (std::abs(n - 1) > kUnitNormKeep) a /= n;
  return a;
}

// ---------------------------------------------------------------------------------------------
// Attitudes

// [w, x, y, z] (unit to 1e-3, then normalised), {axis: [...], angle: ...}, or a 3x3 rotation
// matrix given by rows (orthonormal to 1e-6, determinant +1).
Eigen::Quaterniond Reader::attitude(const Field& f) const {
  const Val& v = f.val;
  Eigen::Quaterniond q;
  if (v.node.IsMap()) {
    const MapView m(*this, v, "(axis-angle)");
    const Eigen::Vector3d axis = direction(m.at("axis"));
    const double angle = number(m.at("angle"));
    q = Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis));
  } else if (v.node.IsSequence() && v.node.size() > 0 && v.node[0].IsSequence()) {
    q = rotation_matrix(v);
  } else if (v.node.IsSequence()) {
    const auto c = numbers(v, Dimension::None, 4, "a quaternion [w, x, y, z]");
    q = Eigen::Quaterniond(c[0], c[1], c[2], c[3]);
    const double n = q.norm();
    if (!(std::abs(n - 1) <= kUnitQuaternionTolerance))
      fail(v, "quaternion [w, x, y, z] has norm " + shortest(n) +
                  "; expected a unit quaternion (norm within 1e-3 of 1)");
  } else {
    fail(v,
         "expected an attitude: a quaternion [w, x, y, z], {axis: [x, y, z], angle: a} or a 3x3 "
         "rotation matrix [[...], [...], [...]], found " +
             describe(v.node));
  }
  if (std::abs(q.norm() - 1) > kUnitNormKeep) q.normalize();
  return q;
}

// Rows of R (v_P = R v_C: its columns are the rotated frame's axes), checked orthonormal with
// determinant +1, turned into a quaternion (exact for matrices of 0 and +-1).
Eigen::Quaterniond Reader::rotation_matrix(const Val& v) const {
  const std::string form = "a rotation matrix (3 rows of 3 numbers)";
  const std::vector<Val> rows = list(v, form, false);
  if (rows.size() != 3)
    fail(v, "expected " + form + ", found " + std::to_string(rows.size()) + " rows");
  Eigen::Matrix3d R;
  for (int i = 0; i < 3; ++i) {
    const auto row = numbers(rows[static_cast<std::size_t>(i)], Dimension::None, 3, "a row");
    for (int j = 0; j < 3; ++j) R(i, j) = row[static_cast<std::size_t>(j)];
  }
  const double error = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!(error <= kRotationMatrixTolerance))
    fail(v, "rotation matrix is not orthonormal: max |R^T R - I| = " + shortest(error) +
                " (tolerance 1e-6); give 7 or more significant digits, or write the attitude as "
                "{axis: [x, y, z], angle: a}");
  if (R.determinant() < 0)
    fail(v, "rotation matrix has determinant " + shortest(R.determinant()) +
                ": it is a reflection, not a rotation (a right-handed frame needs determinant +1)");
  return Eigen::Quaterniond(R);
}

// ---------------------------------------------------------------------------------------------
// Inertia

// Inertia about the CM in body axes: [Ixx, Iyy, Izz], [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] (tensor
// components, so Ixy = -integral x y dm), or a 3x3 nested list; optionally {value: ..., unit: ...}.
// Checked: symmetric, positive definite, principal moments obeying the triangle inequality
// I1 + I2 >= I3 (Kane, Likins & Levinson 1983, Sec. 3.7: a real mass distribution has
// I1 + I2 - I3 = 2 integral z^2 dm >= 0 in principal axes).
Eigen::Matrix3d Reader::inertia(const Field& f) const {
  const Val& v = f.val;
  const Dimension d = f.key->dimension;
  Val items = v;
  std::optional<double> factor;
  if (v.node.IsMap()) {
    const MapView m(*this, v, "(list with unit)");
    items = m.at("value").val;
    if (auto u = m.get("unit")) factor = unit_factor(u->val, scalar(u->val, "a unit"), d);
  }
  const std::string forms =
      "an inertia: 3 numbers (principal moments), 6 numbers (xx, yy, zz, xy, xz, yz) or a 3x3 "
      "nested list";
  if (!items.node.IsSequence())
    fail(items, "expected " + forms + ", found " + describe(items.node));
  const std::vector<Val> e = list(items, forms, false);
  auto q = [&](const Val& x) { return quantity(x, d, factor); };
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

// ---------------------------------------------------------------------------------------------
// Profiles

// A piecewise-constant profile: [{t: t0, value: v0}, {t: t1, value: v1}, ...], t0 >= 0,
// strictly increasing times. D = 1: scalar values (a Quantity row); D = 3: 3-vectors (Vector).
template <int D>
PiecewiseConstant<D> Reader::profile(const Field& f, unsigned joints) const {
  PiecewiseConstant<D> p;
  const int which = profiles_++;
  const std::string item_path = std::string(f.key->path) + "[]";
  for (const Val& item : list(f)) {
    const MapView m(*this, item, item_path, joints);
    const Field tf = m.at("t");
    const double t = number(tf);
    if (t < 0) fail(tf.val, "profile time " + shortest(t) + " s is negative");
    if (!p.times.empty() && !(t > p.times.back()))
      fail(tf.val, "profile times must increase strictly: t = " + shortest(t) +
                       " s after t = " + shortest(p.times.back()) + " s");
    Eigen::Matrix<double, D, 1> value;
    if constexpr (D == 1)
      value[0] = number(m.at("value"));
    else if constexpr (D == 2)
      value = pair(m.at("value"));
    else
      value = vector(m.at("value"));
    p.times.push_back(t);
    p.values.push_back(value);
    profile_times_.push_back({tf.val, t, which});
  }
  return p;
}

template PiecewiseConstant<1> Reader::profile<1>(const Field&, unsigned) const;
template PiecewiseConstant<2> Reader::profile<2>(const Field&, unsigned) const;
template PiecewiseConstant<3> Reader::profile<3>(const Field&, unsigned) const;

}  // namespace crossdyn::scene
