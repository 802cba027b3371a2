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

// Something in a scene file that is read but probably not what its author meant (an angle
// without a unit whose magnitude is above 2 pi). The scene is valid; the commands print each
// warning on stderr (text()) before they run it.
struct SceneWarning {
  std::string file;
  int line = 1, column = 1;  // 1-based
  std::string key;           // key path, "joints[1].initial.angle"
  std::string message;       // "5 has no unit and is read as 5 rad = 286.5 deg; ..."
  // "<file>:<line>:<column>: warning: <key>: <message>"
  std::string text() const;
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
