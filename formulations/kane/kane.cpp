// The factory of the Kane engine (the class: kane_engine.hpp; its passes, one file each:
// README.md).
#include "formulations/kane/kane.hpp"

#include "formulations/kane/kane_engine.hpp"

namespace crossdyn {

std::unique_ptr<Engine> make_kane_engine(const System& system, const EngineOptions& options) {
  return std::make_unique<kane::KaneEngine>(system, options);
}

}  // namespace crossdyn
