// The scene's flexible bodies (internal to core/scene/): a body's `flexible:` block read into a
// FlexModel (core/flex/), and the canonical text the writer writes back.
//
//   flexible: {beam: {...}}                      the beam generator, core/flex/beam.hpp
//   flexible: {nodes: file.csv, modes: m.csv}    nodal data files, core/flex/nodal_csv.hpp
//
// Every error is the reader's "<file>:<line>:<column>: <key path>: <what>"; an error inside a
// nodal data file adds that file's own "<csv>:<line>:<column>: column '<name>': <what>".
#pragma once

#include <string>

#include "core/flex/flex_model.hpp"
#include "core/scene/reader.hpp"

namespace crossdyn::scene {

// Limits of a scene's flexible bodies against hostile input (docs/scene-format.md), tighter than
// core/flex's own: the reader's work is about slices (or nodes) x (6 + modes)^2.
inline constexpr int kMaxSceneSlices = 10000;
inline constexpr int kMaxSceneBeamModes = 50;   // per bending plane
inline constexpr int kMaxSceneFlexModes = 200;  // per flexible body, any source

// Reads the `flexible` block `f` of a body. The FlexBody's scene_form is set to the block in the
// writer's canonical form (flow YAML, SI numbers in shortest round-trip form, every key), so
// that reading it back gives the same bits.
flex::FlexModel read_flexible(const Reader& r, const Field& f);

}  // namespace crossdyn::scene
