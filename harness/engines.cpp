// The engine registry: the only place that knows all engines (they never know each other).
#include "harness/engines.hpp"

#include "core/errors.hpp"
#include "formulations/kane/kane.hpp"
#include "formulations/lagrange/lagrange.hpp"
#include "formulations/newton_euler/newton_euler.hpp"

namespace crossdyn {

std::vector<std::string> engine_names() { return {"kane", "lagrange", "newton-euler"}; }

std::unique_ptr<Engine> make_engine(const std::string& name, const System& system,
                                    const EngineOptions& options) {
  if (name == "kane") return make_kane_engine(system, options);
  if (name == "lagrange") return make_lagrange_engine(system, options);
  if (name == "newton-euler") return make_newton_euler_engine(system, options);
  throw InputError("unknown engine '" + name + "' (known: kane, lagrange, newton-euler)");
}

}  // namespace crossdyn
