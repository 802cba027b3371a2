// Every field of a TreeAccel (core/engine.hpp) in one vector, in a fixed order, for comparing an
// engine's accelerations or their tangents (Engine::accelerations_tangent) entry by entry.
#pragma once

#include "core/engine.hpp"

#include <Eigen/Core>

#include <vector>

namespace crossdyn::test {

inline Eigen::VectorXd flat(const TreeAccel& a) {
  std::vector<double> v;
  for (const Eigen::Vector3d& x : a.wdot_NB_B) v.insert(v.end(), x.data(), x.data() + 3);
  for (const Eigen::Vector3d& x : a.a_NBo_N) v.insert(v.end(), x.data(), x.data() + 3);
  v.insert(v.end(), a.angle_ddot.begin(), a.angle_ddot.end());
  v.insert(v.end(), a.angle2_ddot.begin(), a.angle2_ddot.end());
  for (const Eigen::Vector3d& x : a.wdot_PC_C) v.insert(v.end(), x.data(), x.data() + 3);
  for (const Eigen::VectorXd& x : a.eta_ddot) v.insert(v.end(), x.data(), x.data() + x.size());
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

}  // namespace crossdyn::test
