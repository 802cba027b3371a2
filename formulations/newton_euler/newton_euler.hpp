#pragma once
#include "core/engine.hpp"
namespace crossdyn {
std::unique_ptr<Engine> make_newton_euler_engine(const System& system, const EngineOptions& options);
}
