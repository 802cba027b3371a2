// Where crossdyn finds things: scenes named without a path, the report script, its version.
//
//   scene names   `crossdyn run gimbal_lock`: a SCENE argument that names no existing file and has
//                 no '/' is looked up as scenarios/SCENE, scenarios/SCENE.yaml, scenarios/SCENE.yml
//                 in the current folder, then in the source tree the program was built from.
//   report script verify --report runs <source tree>/reports/make_report.py, the script of the
//                 tree the program was built from, never one found beside the scenes (a scene
//                 bundle must not be able to run code); --report-script names another explicitly.
//   version       CMake's project version, plus `git describe` at configure time when available.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace crossdyn {
struct System;
struct NamedPath;
}  // namespace crossdyn

namespace crossdyn::harness {

// The inputs of a command that read `system` (for check_outputs_are_not_inputs): its scene file
// and every data file it read (nodal CSV files, System::input_files).
std::vector<NamedPath> scene_inputs(const System& system);
// The same for a scene file not read yet (verify reads its scenes later, one by one): the file,
// and when it is a regular file that reads as a scene, the data files it names. A scene that
// cannot be read gives the file alone (its error comes later, where the command reads it); a
// FIFO is never opened here (it could be read only once).
std::vector<NamedPath> scene_file_inputs(const std::string& path);

std::string source_tree();            // absolute, compiled in (CROSSDYN_SOURCE_DIR)
std::string version();                // "0.1.0 (git 1aca500-dirty)"
// The folder of the installed report scripts (make_report.py, draw_scene.py, their modules and
// templates): the source tree's reports/, never one found next to the scenes.
std::string installed_reports_dir();
std::string installed_report_script();  // installed_reports_dir()/make_report.py

// The folders searched for scene names, in order: ./scenarios (when it exists), then the source
// tree's scenarios/ (when it is another folder).
std::vector<std::string> scene_folders();

// The file a SCENE argument names (see above). Returns SCENE itself when it names an existing
// path or contains '/', so that read_scene reports why it cannot be read; throws InputError listing
// every path tried when a bare name is found nowhere.
std::string resolve_scene(const std::string& scene);

// A scenes folder (--scenarios DIR, list and verify; verify --shard plans its shards from the same
// list). A scene is every entry whose name ends in .yaml or .yml in any letter case (Scene.YAML)
// and does not start with '.', whatever it is: a link to a scene is read, and a dangling link, a
// directory, a FIFO, a device or an unreadable file named x.yaml is a scene that cannot be read
// (verify fails it, list names it). Hidden x.yaml files (emacs's `.#x.yaml` lock links) and names
// that hold .yaml/.yml but end otherwise (x.yaml~, x.yaml.bak, #x.yaml#) are skipped, named with
// the reason. Subfolders (scenarios/data) are not searched. Sorted. InputError when the folder
// cannot be listed, naming it and the reason.
struct SceneFolder {
  std::vector<std::string> scenes;
  std::vector<std::pair<std::string, std::string>> skipped;  // path, why it is not a scene
};
SceneFolder scan_scene_folder(const std::string& folder);
std::vector<std::string> scene_files_in(const std::string& folder);  // scan_scene_folder().scenes

// A sharded run (--shard) reads each scene again to plan and hash it and in every shard: a pipe,
// FIFO, socket or device cannot be read twice and could block, so it is refused (InputError).
// Missing files and directories pass: the run reports them like an unsharded one.
void require_shardable_scene(const std::string& path);

}  // namespace crossdyn::harness
