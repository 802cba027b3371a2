// The scene reader moved to core/scene/ (scene.hpp: read_scene, read_scene_text,
// write_scene_text, SceneWarning, check_topology). This header forwards to it so that existing
// callers keep compiling; new code includes "core/scene/scene.hpp".
#pragma once

#include "core/scene/scene.hpp"
