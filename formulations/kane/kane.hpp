// The Kane engine: Kane's method (generalised speeds, partial velocities and partial angular
// velocities, F_r + F_r* = 0) for a tree of rigid and flexible (modal) bodies. See
// kane_engine.hpp for the state layout, the passes and the bibliography.
#pragma once

#include "core/engine.hpp"

#include <memory>

namespace crossdyn {

// Engine name "kane". Throws InputError for a scene it cannot run (a malformed tree, modal data
// that would make its mass matrix singular or that contradict the body's mass and inertia).
std::unique_ptr<Engine> make_kane_engine(const System& system, const EngineOptions& options);

}  // namespace crossdyn
