#include "core/rotation.hpp"

#include <algorithm>
#include <cmath>

namespace crossdyn::rot {

double angle_between(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  // |<a, b>| = |cos(theta / 2)|; use atan2 of the vector and scalar parts for accuracy near 0.
  const Eigen::Quaterniond d = a.conjugate() * b;
  return 2.0 * std::atan2(d.vec().norm(), std::abs(d.w()));
}

Eigen::Vector3d rotation_vector(const Eigen::Quaterniond& q_in) {
  const Eigen::Quaterniond q = canonical(q_in);
  const double s = q.vec().norm();
  if (s < 1e-8) return 2.0 * q.vec() / q.w();  // series: angle/sin(angle/2) -> 2 (error O(s^2))
  const double angle = 2.0 * std::atan2(s, q.w());
  return q.vec() * (angle / s);
}

Eigen::Quaterniond from_rotation_vector(const Eigen::Vector3d& phi) {
  const double angle = phi.norm();
  if (angle < 1e-8) {
    Eigen::Quaterniond q(1.0, 0.5 * phi.x(), 0.5 * phi.y(), 0.5 * phi.z());
    return q.normalized();
  }
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, phi / angle));
}

}  // namespace crossdyn::rot
