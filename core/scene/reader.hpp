// The scene reader's value layer (internal to core/scene/): YAML nodes with their key path and
// position, mappings checked against the schema, and typed values read as the schema row says.
//
// Every error is an InputError "<file>:<line>:<column>: <key path>: <what is wrong>", the line and
// column 1-based from yaml-cpp's Mark of the offending node (the key itself for unknown keys, the
// enclosing mapping for missing ones).
//
// Several errors of one file are reported together: Reader::fail throws a SceneError, and the
// reader catches it with Reader::attempt where it loops over items whose values do not depend on
// each other (each body, each joint, each key of the scene, a body, a joint, the run block, each
// tolerance and exclusion), records it and goes on; a mapping records each unknown, duplicate or
// misplaced key and reads the others (a missing key that one of them mistypes is not reported
// again). Reader::finish then throws one InputError holding every recorded error in file order,
// one per line (at most kMaxReportedErrors, then "... and N more errors"). Passes that need
// everything before them (topology, the analytic check) run only when nothing was recorded, and a
// YAML syntax error stops at once. A value read after an error is never used: no System is made.
#pragma once

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "core/scene/schema.hpp"
#include "core/scene/text.hpp"

namespace crossdyn::scene {

// Limits (docs/scene-format.md "What the reader checks"). Each is far outside any physical
// spacecraft scene.
inline constexpr std::size_t kMaxSceneBytes = 1u << 20;  // 1 MiB of YAML
inline constexpr double kAbsurd = 1e12;                  // any SI value beyond this is a typo
inline constexpr double kTiny = 1e-100;                 // a nonzero SI value below this is refused
inline constexpr double kMaxAngularRate = 1e4;          // rad/s, a prescribed rate
inline constexpr double kMaxAngle = 1e6;                // rad, any angle
inline constexpr double kMaxMass = 1e9;                  // kg
inline constexpr double kMinAxisLength = 1e-9;           // a shorter axis counts as zero
inline constexpr double kUnitQuaternionTolerance =
    1e-3;  // |norm(q) - 1| accepted (then normalised)
inline constexpr double kRotationMatrixTolerance = 1e-6;  // max |R^T R - I| accepted
inline constexpr double kSymmetryTolerance = 1e-9;        // |I_ij - I_ji| <= this * max |I_kl|
inline constexpr double kTriangleTolerance = 1e-9;        // I1 + I2 >= I3 - this * (I1 + I2 + I3)
inline constexpr std::size_t kMaxReportedErrors = 20;     // errors listed in one message
inline constexpr std::size_t kMaxRecordedErrors = 1000;   // errors kept (later ones only counted)

// One error of the reader, with its 1-based position in the scene file (for ordering) and its
// key path.
class SceneError : public InputError {
 public:
  SceneError(const std::string& message, int line, int column, std::string path)
      : InputError(message), line_(line), column_(column), path_(std::move(path)) {}
  int line() const { return line_; }
  int column() const { return column_; }
  const std::string& path() const { return path_; }

 private:
  int line_;
  int column_;
  std::string path_;
};

// A unit written after a flow list, "inertia: [30, 20, 12] kg m^2", which YAML cannot read (the
// value ends at ']'; yaml-cpp says "end of map not found"). The parser blanks the unit and reads
// on; the reader reports it at the key that holds the list (Reader::unit_after_list).
struct UnitAfterList {
  std::size_t list_pos = 0;  // where the list's '[' is in the text (its node's Mark().pos)
  YAML::Mark mark;           // where the unit is
  std::string unit;          // as written
  std::string list;          // the list as written, "[30, 20, 12]"
  std::string key;           // the key before the list, or before the list holding it ("")
  bool reported = false;
};

// A node together with its key path ("bodies[1].inertia") and a usable position.
struct Val {
  YAML::Node node;
  std::string path;
  YAML::Mark mark;
};

// A value with the schema row that describes it.
struct Field {
  Val val;
  const Key* key;
};

class Reader;

// The keys of one YAML mapping, checked against the schema rows under `schema_path` that apply
// to the joint types `joints`: unknown keys (with a "did you mean"), duplicate keys, required
// keys that are missing or have no value. Accessors name keys of the schema only (asking for
// another is a programming error: std::logic_error).
class MapView {
 public:
  struct Entry {
    std::string key;
    YAML::Mark key_mark;
    Val value;
  };
  // `type_name` fills "{type}" in the schema's noun ("the initial conditions of a {type} joint").
  MapView(const Reader& r, const Val& v, std::string schema_path, unsigned joints = kAnyJoint,
          std::string_view type_name = "");

  // Narrows a joint's mapping, read with every joint type's keys, to its type: keys that do not
  // apply are errors (`why_not` adds a reason, "" for none), and the type's required keys must be
  // there.
  template <typename WhyNot>
  void narrow(unsigned joints, std::string_view type_name, WhyNot why_not);

  // An optional key, if given (nothing for a key of another joint type).
  std::optional<Field> get(std::string_view key) const;
  Field at(std::string_view key) const;  // a required key (checked present)
  const std::vector<Entry>& entries() const { return entries_; }
  const Val& self() const { return self_; }
  // A required key `key` is missing: `message`, at the mapping; nothing more (a skip) when an
  // unknown key of this mapping is a typo of it (that key's message says so).
  [[noreturn]] void missing(const std::string& key, const std::string& message) const;
  // Whether an unknown key of this mapping is a typo of `key` ("mas" of "mass").
  bool mistyped(const std::string& key) const;
  const std::string& schema_path() const { return schema_path_; }
  unsigned joints() const { return joints_; }

 private:
  const Key& row(std::string_view key) const;
  void check_required() const;
  const Reader& r_;
  Val self_;
  std::string schema_path_;
  unsigned joints_;
  std::string noun_;
  std::vector<Entry> entries_;
  std::vector<std::string> unknown_;  // unknown keys (recorded, left out)
};

class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}
  const std::string& file() const { return file_; }
  std::vector<SceneWarning>& warnings() const { return warnings_; }

  // Throws the SceneError "<file>:<line>:<column>: <path>: <what>".
  [[noreturn]] void fail(const YAML::Mark& m, const std::string& path,
                         const std::string& what) const;
  [[noreturn]] void fail(const Val& v, const std::string& what) const {
    fail(v.mark, v.path, what);
  }
  // A warning at v's line and key; `code` is its stable name (SceneWarning::code).
  void warn(const Val& v, const std::string& code, const std::string& what) const;
  // The times of every profile read (its `t` values, with where they are), for the check
  // against the run's duration once the run block is read (check_profile_times).
  struct ProfileTime {
    Val val;
    double t;
    int profile;  // which profile, counted from 0 in reading order
  };
  const std::vector<ProfileTime>& profile_times() const { return profile_times_; }

  // ----- several errors (see the top of this file) ---------------------------------------------
  // Thrown to stop reading a part whose problem is an error already recorded elsewhere (a joint
  // at a body that had errors): attempt() gives false without a message of its own.
  struct Skip {};
  [[noreturn]] void skip() const {
    skipped_ = true;
    throw Skip{};
  }
  // Stops the reading at `m` (more errors than a message shows): the message says so.
  [[noreturn]] void stop(const YAML::Mark& m) const {
    stopped_line_ = m.is_null() || m.line < 0 ? 1 : m.line + 1;
    skip();
  }
  // Runs f; an error it throws is recorded, and the result is false (also after a Skip).
  template <typename F>
  bool attempt(F&& f) const {
    try {
      f();
      return true;
    } catch (const InputError& e) {
      keep(e);
    } catch (const Skip&) {
    }
    return false;
  }
  // Records an error (a SceneError keeps its position; another InputError goes last). Past
  // kMaxRecordedErrors only counted.
  void keep(const InputError& e) const;
  void record(const YAML::Mark& m, const std::string& path, const std::string& what) const;
  bool failed() const { return !errors_.empty(); }
  // Throws one InputError holding every recorded error, if any (the units after lists that no
  // key reported first).
  void finish() const;

  // Units after lists found by the parser; a mapping reports one at its key (`row`: the key's
  // schema row, nullptr when unknown) when `v` is that list.
  void note_unit_after_list(UnitAfterList u) const { units_after_lists_.push_back(std::move(u)); }
  std::size_t units_after_lists() const { return units_after_lists_.size(); }
  void unit_after_list(const Val& v, const Key* row) const;

  Val sub(const Val& parent, const YAML::Node& n, std::string path) const {
    YAML::Mark m = n.Mark();
    if (m.is_null()) m = parent.mark;
    return Val{n, std::move(path), m};
  }

  // ----- structure ---------------------------------------------------------------------------
  std::vector<Val> list(const Val& v, const std::string& what, bool non_empty) const;
  std::vector<Val> list(const Field& f) const;  // a List row: its items (non-empty if required)
  const std::string& scalar(const Val& v, const std::string& what) const;

  // ----- typed values, as the schema row says (reader_values.cpp) ------------------------------
  std::string text(const Field& f) const;  // Text
  std::string name(const Field& f) const;  // Name
  std::string name(const Val& v, const std::string& what, bool allow_dot) const;
  std::string word(const Field& f) const;             // Word
  bool boolean(const Field& f) const;                 // Bool
  double number(const Field& f) const;                // Number, Quantity
  Eigen::Vector3d vector(const Field& f) const;       // Vector
  Eigen::Vector2d pair(const Field& f) const;         // Pair
  Eigen::Vector3d direction(const Field& f) const;    // Direction
  Eigen::Quaterniond attitude(const Field& f) const;  // Attitude
  Eigen::Matrix3d inertia(const Field& f) const;      // Inertia
  template <int D>
  PiecewiseConstant<D> profile(const Field& f, unsigned joints) const;  // List of {t, value}

  // Lower level: a number of dimension d in SI; `factor` set when the unit was given once for
  // the enclosing list. Bare angles above 2 pi draw a warning.
  double quantity(const Val& v, units::Dimension d,
                  std::optional<double> factor = std::nullopt) const;
  double unit_factor(const Val& v, const std::string& unit, units::Dimension d) const;

 private:
  std::pair<double, std::string> number_and_unit(const Val& v, units::Dimension d) const;
  double sane(const Val& v, double si, units::Dimension d) const;
  std::vector<double> numbers(const Val& v, units::Dimension d, std::size_t n,
                              const std::string& what) const;
  Eigen::Quaterniond rotation_matrix(const Val& v) const;

  struct Recorded {
    int line;
    int column;
    std::string message;
  };
  std::string file_;
  mutable std::vector<SceneWarning> warnings_;
  mutable std::vector<Recorded> errors_;
  mutable std::size_t more_errors_ = 0;  // past kMaxRecordedErrors
  mutable bool skipped_ = false;
  mutable int stopped_line_ = 0;  // where stop() ended the reading (0: it did not)
  mutable std::vector<UnitAfterList> units_after_lists_;
  // Keys whose value was a list with a unit after it: what their read says next (a list where a
  // quantity was expected) is that error again, left out.
  mutable std::vector<std::string> quiet_paths_;
  mutable std::vector<ProfileTime> profile_times_;
  mutable int profiles_ = 0;
};

template <typename WhyNot>
void MapView::narrow(unsigned joints, std::string_view type_name, WhyNot why_not) {
  const std::vector<std::string> allowed = child_names(schema_path_, joints);
  // Each key that does not apply is recorded and left out (get() gives nothing for it).
  for (const Entry& e : entries_)
    if (std::find(allowed.begin(), allowed.end(), e.key) == allowed.end()) {
      std::string why = "'" + e.key + "' does not apply to a " + std::string(type_name) + " joint";
      const std::string reason = why_not(e.key);
      if (!reason.empty()) why += " (" + reason + ")";
      r_.record(e.key_mark, e.value.path, why + "; its keys: " + join(allowed));
    }
  joints_ = joints;
  check_required();
}

}  // namespace crossdyn::scene
