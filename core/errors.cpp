#include "core/errors.hpp"

#include <cstdio>

namespace crossdyn {

std::string RunFailure::format(const std::string& engine, double t, const std::string& quantity,
                               const std::string& reason) {
  char time[64];
  std::snprintf(time, sizeof time, "%.9g", t);
  return "engine " + engine + " failed at t = " + time + " s" +
         (quantity.empty() ? std::string() : " (" + quantity + ")") + ": " + reason;
}

}  // namespace crossdyn
