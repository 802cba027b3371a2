// Numbers in the Lagrange engine's error messages (internal header).
#pragma once

#include <Eigen/Core>
#include <cstdio>
#include <string>

namespace crossdyn::lagrange {

inline std::string format_number(double v, const char* fmt = "%.6g") {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

inline std::string format_vector(const Eigen::Vector3d& v) {
  return "(" + format_number(v.x(), "%.9g") + ", " + format_number(v.y(), "%.9g") + ", " +
         format_number(v.z(), "%.9g") + ")";
}

}  // namespace crossdyn::lagrange
