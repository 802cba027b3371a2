// Reading and validating scene files (YAML). See README "Writing a scene" for the format.
#pragma once

#include "core/system.hpp"

#include <string>

namespace crossdyn {

// Reads, validates and converts (units to SI) one scene file. Throws InputError whose message
// starts "<file>:<line>:<column>: " and names the key and what is wrong. Never returns an invalid
// System: every check in README "What the reader checks" has passed.
System read_scene(const std::string& path);

// Why `path` cannot be opened as a scene file ("no such file", "it is a directory, not a scene
// file", "permission denied ...", "too many levels of symbolic links ...", "it is a socket ..."),
// or "" when it can. read_scene's message is "<path>:1:1: cannot open the scene file: <why>".
std::string scene_open_problem(const std::string& path);

// The same, from text already in memory; `file_label` is used in messages (fuzzing, tests).
System read_scene_text(const std::string& text, const std::string& file_label);

// Writes a System back as a scene file (SI units) that read_scene_text reads to an equal System.
std::string write_scene_text(const System& system);

}  // namespace crossdyn
