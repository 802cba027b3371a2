// Small number helpers shared by the harness's sources (one definition, so that the harness can be
// compiled as a unity build: docs/development.md "Build time").
#pragma once

#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

namespace crossdyn::harness {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// v with `digits` significant digits, printf's %g.
inline std::string fmt_g(double v, int digits) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

// A double as a JSON value: finite numbers as numbers, NaN and infinities as null (JSON has no NaN).
// Json is nlohmann::json or nlohmann::ordered_json.
template <class Json>
Json json_number(double v) {
  return std::isfinite(v) ? Json(v) : Json(nullptr);
}

}  // namespace crossdyn::harness
