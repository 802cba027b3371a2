// The scene format's schema: ONE table of every key a scene file may hold (after MuJoCo's MJCF
// table, src/xml/xml_native_reader.cc). The reader checks input against it (unknown, missing and
// misplaced keys, each value's type and unit dimension), the writer writes only keys it holds,
// docs/scene-format.md's key tables are generated from it (tests/scene/test_scene_docs.cpp fails
// when they differ), and fuzz/scene.dict is tested against it. Nothing else lists the keys.
//
// A key's path names where it sits: "bodies[].mass" is the key mass of every item of the list
// bodies; "compare.tolerances.<quantity>" stands for any key of that mapping (a quantity name).
// Paths in parentheses are value forms rather than scene keys: "(axis-angle).angle" is the angle
// of an attitude written {axis: [x, y, z], angle: a}, wherever an attitude is accepted.
//
// Keys under "joints[]" apply to some joint types only (`joints`, a set of JointSet bits): a
// `parent` on a free joint is an error, `axis` exists for revolute joints only. A key marked
// required is required for every joint type that takes it. One path may have several rows when
// its meaning depends on the joint type (joints[].initial.attitude is q_NB on the free joint and
// the joint quaternion q_J on a spherical one); their joint sets do not overlap.
#pragma once

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/system.hpp"
#include "core/units.hpp"

namespace crossdyn::scene {

// What a key's value is (docs/scene-format.md "Values" describes each form).
enum class Type {
  Text,       // free text: printable UTF-8, tabs and newlines allowed
  Name,       // identifier: 1 to 64 letters, digits, '_', '-', starting with a letter
  Bool,       // true | false
  Word,       // one of Key::words
  Number,     // a pure number (no unit)
  Quantity,   // a number of Key::dimension: SI, or "<number> <unit>"
  Vector,     // 3 numbers of Key::dimension, or {value: [x, y, z], unit: u}
  Pair,       // 2 numbers of Key::dimension (a universal joint's two axes), or {value: [a, b], unit: u}
  Direction,  // a non-zero 3-vector, normalised by the reader
  Attitude,   // quaternion [w, x, y, z] | {axis: [x, y, z], angle: a} | 3x3 rotation matrix (rows)
  Inertia,    // [Ixx, Iyy, Izz] | [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] | 3x3; optionally {value, unit}
  Map,        // a mapping of the keys listed under this path
  List,       // a list of items, each described by the rows under "<path>[]"
};

// Sets of joint types, for keys under "joints[]".
enum JointSet : unsigned {
  kFree = 1u << 0,
  kRevolute = 1u << 1,
  kSpherical = 1u << 2,
  kFixed = 1u << 3,
  kPrismatic = 1u << 4,
  kUniversal = 1u << 5,
  kJointed = kRevolute | kSpherical | kFixed | kPrismatic | kUniversal,  // every type with a parent
  kMoving = kRevolute | kSpherical | kPrismatic | kUniversal,  // every type with a joint coordinate
  kAxial = kRevolute | kPrismatic,                              // one coordinate along or about an axis
  kAnyJoint = kFree | kJointed,
};

struct Key {
  std::string_view path;
  Type type;
  units::Dimension dimension = units::Dimension::None;
  bool required = false;
  std::string_view default_value = "";  // as documented ("" when required or when absent = none)
  unsigned joints = kAnyJoint;          // the joint types that take it (keys under joints[] only)
  std::string_view words = "";          // Word: the accepted words, separated by '|'
  std::string_view noun = "";           // Map/List items: how messages name it ("a body");
                                        // "{type}" stands for the joint type
  bool written = true;                  // false: a reader convenience the writer never writes
                                        // (it writes the System, already converted)
  std::string_view doc = "";
};

// The table, in the order the documentation and the writer follow.
std::span<const Key> keys();

// One joint type: its name in files, the System's enum and the generalised speeds it adds.
// Its keys and initial keys are the rows of keys() whose joint set holds it.
struct JointTypeInfo {
  std::string_view name;
  JointType type;
  unsigned bit;  // its JointSet bit
  int dof;       // generalised speeds (Joint::dof(), tested equal)
  std::string_view doc;
};
std::span<const JointTypeInfo> joint_types();
const JointTypeInfo& joint_type(JointType t);

// The row for `path` that applies to joint types `joints` (kAnyJoint outside joints[]), or
// nullptr. A path with a "<...>" component matches any name there.
const Key* find(std::string_view path, unsigned joints = kAnyJoint);

// The names of the keys directly under `parent` ("bodies[]", "joints[].initial", "" for the top)
// that apply to any of `joints`, in table order. A wildcard child appears as "<quantity>".
std::vector<std::string> child_names(std::string_view parent, unsigned joints = kAnyJoint);

// The keys of joint type t (the rows under "joints[]" and "joints[].initial" that take it).
std::vector<std::string> joint_keys(JointType t);
std::vector<std::string> initial_keys(JointType t);

// Word rows: the accepted words.
std::vector<std::string> words(const Key& key);

// "a body" etc. for a Map or List item row, with "{type}" replaced by `type_name`.
std::string noun(const Key& key, std::string_view type_name = "");

// The Markdown key reference of docs/scene-format.md (between its "generated" markers): one table
// per block of the format, the joint-type table, the value forms and the units.
std::string markdown_reference();

// fuzz/scene.dict: every key ("mass:"), word and unit of the schema, then YAML syntax, so that
// libFuzzer's mutations reach past the first unknown-key check (tests/scene/test_schema.cpp
// compares the committed file with this).
std::string fuzz_dictionary();

}  // namespace crossdyn::scene
