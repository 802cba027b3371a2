// The engine registry (harness/engines.cpp): the only place that knows every engine. Engines never
// know each other (core/engine.hpp is their one interface; tests/independence enforces it).
#pragma once

#include "core/engine.hpp"

#include <memory>
#include <string>
#include <vector>

namespace crossdyn {

// Names of the engines this build knows, in reference order: kane, lagrange, newton-euler.
std::vector<std::string> engine_names();

// A new engine `name` on `system`. Throws InputError for an unknown name (listing the known ones)
// or for a scene the engine cannot run.
std::unique_ptr<Engine> make_engine(const std::string& name, const System& system,
                                    const EngineOptions& options = {});

}  // namespace crossdyn
