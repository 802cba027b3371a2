// Scene files (YAML) => validated System in SI units, and System => scene text.
// The format: docs/scene-format.md (its key tables are generated from core/scene/schema.hpp).
//
//   read_scene / read_scene_text   (text) => (System, warnings)   core/scene/reader.cpp
//   write_scene_text               (System) => (text)             core/scene/writer.cpp
//   check_topology                 (System) => () or InputError   core/scene/topology.hpp
#pragma once

#include <string>
#include <vector>

#include "core/input_file.hpp"
#include "core/scene/topology.hpp"
#include "core/system.hpp"

namespace crossdyn {

// Something in a scene that is valid but probably not what its author meant. The reader makes
// some (an angle without a unit whose magnitude is above 2 pi, a profile step at or after the
// run's end), with the line and column; the harness adds the checks of the scene's geometry
// (harness/scene_warnings.hpp), which have no line. Every command that reads a scene prints each
// on stderr, "crossdyn: warning: <file>: <detail()>"; a warning is not an error.
struct SceneWarning {
  std::string file;
  int line = 0, column = 0;  // 1-based; 0 when the warning is about the scene as a whole
  std::string key;           // key path, "joints[1].initial.angle"; "" for a geometry check
  std::string message;       // "7 has no unit and is read as 7 rad = 401.1 deg; ..."
  std::string code;          // stable short name: "angle-unitless-large", "cm-inboard", ...
  std::string subject;       // what it concerns: the key path, or the joint(s) or body
  // "<file>:<line>:<column>: warning: <key>: <message>" (the reader's form, for messages in tests)
  std::string text() const;
  // "line 9: joints[1].initial.angle: 7 has no unit ..." or the geometry check's sentence: what
  // follows "<file>: " on stderr, and what the drawing and the reports show.
  std::string detail() const;
};

// Reads, validates and converts (units to SI, center_of_mass to the CM frame, joints to tree
// order) one scene file. Throws InputError whose message starts "<file>:<line>:<column>: " and
// names the key and what is wrong. Never returns an invalid System: every check of
// docs/scene-format.md "What the reader checks" has passed, check_topology() included. Warnings
// are appended to *warnings when given.
// Never blocks on a special file (core/input_file.hpp): a FIFO or pipe is read unless `pipes` is
// Pipes::Refuse (the scenes of a --scenarios folder must be regular files).
System read_scene(const std::string& path, std::vector<SceneWarning>* warnings = nullptr,
                  Pipes pipes = Pipes::Allow);

// Why `path` cannot be opened as a scene file ("no such file", "it is a directory, not a scene
// file", "permission denied ...", "too many levels of symbolic links ...", "it is a socket ..."),
// or "" when it can. read_scene's message is "<path>:1:1: cannot open the scene file: <why>".
std::string scene_open_problem(const std::string& path, Pipes pipes = Pipes::Allow);

// The same, from text already in memory; `file_label` is used in messages (fuzzing, tests).
System read_scene_text(const std::string& text, const std::string& file_label,
                       std::vector<SceneWarning>* warnings = nullptr);

// Writes a System back as a scene file (SI units) that read_scene_text reads to an equal System,
// field by field and bit for bit.
std::string write_scene_text(const System& system);

}  // namespace crossdyn
