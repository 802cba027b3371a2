// The Lagrange engine: Lagrange's equations in quasi-coordinates (Boltzmann-Hamel form, reference
// paper Eq. 23), Euler-angle coordinates with automatic re-charting. Details in
// lagrange_engine.hpp.
#pragma once

#include <memory>

#include "core/engine.hpp"

namespace crossdyn {

// Throws InputError for systems the engine cannot handle (no free base joint, a second free joint,
// joints at nodes of rigid bodies, flexible bodies whose mass matrix is singular).
std::unique_ptr<Engine> make_lagrange_engine(const System& system, const EngineOptions& options);

}  // namespace crossdyn
