// Factory of the Lagrange engine (Lagrange's equations in quasi-coordinates; lagrange_engine.hpp).
#include "formulations/lagrange/lagrange.hpp"

#include "formulations/lagrange/lagrange_engine.hpp"

namespace crossdyn {

std::unique_ptr<Engine> make_lagrange_engine(const System& system, const EngineOptions& options) {
  return std::make_unique<lagrange::LagrangeEngine>(system, options);
}

}  // namespace crossdyn
