// Scene warnings: what a scene says that is valid but probably not what its author meant, in one
// place (docs/scene-format.md "Warnings"). A warning is never an error: run, compare, verify, draw
// and merge print each on stderr and go on; `--strict` makes such a command whose work succeeded
// exit with status 1 when its scenes have any. (study, stability and converge print the reader's
// warnings only, in the same form: the merges of their parts could not repeat the others.)
//
// The warnings (SceneWarning, core/scene/scene.hpp), each with a stable code:
//   angle-unitless-large  (reader) an angle without a unit whose magnitude is above 2 pi
//   profile-after-end     (reader) a torque or motor profile step at or after the run's end
//   cm-inboard            a child's CM inboard of its joint, inside its parent's box: usually a
//                         wrong sign of child_point or of the offset
//   mirror-axes           two revolute joints on one parent carry identical bodies at mirror-image
//                         points (or at one point), yet a positive angle does not move them as
//                         mirror images: often a flipped axis sign, sometimes the design
//   joint-gap             a joint's two points (from the parent and from the child) apart
//   axis-mismatch         a revolute axis fixed in the child off the one fixed in the parent
// The reader's come with their line; the others are checks of the configuration at t = 0 that
// the scene places (harness/scene_geometry.hpp), the same the drawing shows: `crossdyn draw`'s
// picture and the report's scene pages print the warnings crossdyn made here (the geometry
// document's "warnings"), never their own. joint-gap and axis-mismatch cannot happen for a scene
// placed from its joints (the placement makes the points and axes agree); they guard the
// placement itself, as the drawing's red marks do.
#pragma once

#include "core/input_file.hpp"
#include "core/scene/scene.hpp"
#include "core/system.hpp"

#include <nlohmann/json_fwd.hpp>

#include <cstddef>
#include <iosfwd>
#include <string>
#include <vector>

namespace crossdyn::harness {

namespace geometry {
struct Configuration;
}

// The checks of one configuration of the scene (joint-gap, axis-mismatch, cm-inboard per joint in
// joint order, then mirror-axes per pair); file = system.file, no line.
std::vector<SceneWarning> configuration_warnings(const System& system, const geometry::Configuration& c);
// configuration_warnings at t = 0, the configuration the scene places (initial_configuration).
std::vector<SceneWarning> geometry_warnings(const System& system);

// Every warning of a scene: the reader's (as read_scene gave them), then geometry_warnings.
std::vector<SceneWarning> scene_warnings(const System& system,
                                         const std::vector<SceneWarning>& reader_warnings = {});

// A scene as read, with all its warnings.
struct CheckedScene {
  System system;
  std::vector<SceneWarning> warnings;
};
// read_scene and scene_warnings: what every command reads a scene with.
CheckedScene read_checked_scene(const std::string& path, Pipes pipes = Pipes::Allow);

// "crossdyn: warning: <file>: <detail>", the line printed on stderr.
std::string warning_line(const SceneWarning& w);
// Prints every warning's line on `err`, once each (--quiet silences progress, not warnings).
void print_warnings(const std::vector<SceneWarning>& warnings, std::ostream& err);

// --strict: a command whose status is 0 exits with 1 when there are warnings; any other status
// stands (a failed check, bad input or a failed run says more than a warning).
int strict_status(int status, bool strict, std::size_t warnings);

// The warnings as JSON (the geometry document, the JSON summary, the report):
// [{"code", "subject", "line" (null: none), "column", "message": detail()}].
nlohmann::ordered_json warnings_json(const std::vector<SceneWarning>& warnings);

}  // namespace crossdyn::harness
