// The scene reader's value layer (internal to core/scene/): YAML nodes with their key path and
// position, mappings checked against the schema, and typed values read as the schema row says.
//
// Every error is an InputError "<file>:<line>:<column>: <key path>: <what is wrong>", the line and
// column 1-based from yaml-cpp's Mark of the offending node (the key itself for unknown keys, the
// enclosing mapping for missing ones).
#pragma once

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

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
};

class Reader {
 public:
  explicit Reader(std::string file) : file_(std::move(file)) {}
  const std::string& file() const { return file_; }
  std::vector<SceneWarning>& warnings() const { return warnings_; }

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

  std::string file_;
  mutable std::vector<SceneWarning> warnings_;
  mutable std::vector<ProfileTime> profile_times_;
  mutable int profiles_ = 0;
};

template <typename WhyNot>
void MapView::narrow(unsigned joints, std::string_view type_name, WhyNot why_not) {
  const std::vector<std::string> allowed = child_names(schema_path_, joints);
  for (const Entry& e : entries_)
    if (std::find(allowed.begin(), allowed.end(), e.key) == allowed.end()) {
      std::string why = "'" + e.key + "' does not apply to a " + std::string(type_name) + " joint";
      const std::string reason = why_not(e.key);
      if (!reason.empty()) why += " (" + reason + ")";
      r_.fail(e.key_mark, e.value.path, why + "; its keys: " + join(allowed));
    }
  joints_ = joints;
  check_required();
}

}  // namespace crossdyn::scene
