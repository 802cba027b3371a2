// Small rotation helpers shared by the engines (the only maths they may share; each has a test in
// tests/core/test_rotation.cpp). Quaternions are Eigen's, scalar first in outputs, unit norm.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace crossdyn::rot {

// [v x], the cross-product matrix: skew(a) b = a x b.
inline Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

// Quaternion kinematics with the angular velocity in the rotated (body) frame:
// q' = 1/2 q (x) (0, w_B)   (Kane, Likins & Levinson 1983, Sec. 1.13; Shuster 1993 Eq. 305 with
// Hamilton's product). Returns (qw', qx', qy', qz').
inline Eigen::Vector4d quat_rate_body(const Eigen::Quaterniond& q, const Eigen::Vector3d& w_B) {
  const double w = q.w(), x = q.x(), y = q.y(), z = q.z();
  return 0.5 * Eigen::Vector4d(-x * w_B.x() - y * w_B.y() - z * w_B.z(),
                               w * w_B.x() + y * w_B.z() - z * w_B.y(),
                               w * w_B.y() + z * w_B.x() - x * w_B.z(),
                               w * w_B.z() + x * w_B.y() - y * w_B.x());
}

// The same quaternion with a non-negative scalar part (q and -q are the same attitude; outputs use
// this sign so that engines' columns can be compared directly).
inline Eigen::Quaterniond canonical(const Eigen::Quaterniond& q) {
  return q.w() < 0 ? Eigen::Quaterniond(-q.w(), -q.x(), -q.y(), -q.z()) : q;
}

// Rotation angle (rad, in [0, pi]) of the relative rotation between two attitudes; 0 for q and -q.
double angle_between(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b);

// Rotation vector phi (axis times angle, |phi| <= pi) of a unit quaternion: the log map.
Eigen::Vector3d rotation_vector(const Eigen::Quaterniond& q);

// Unit quaternion of a rotation vector: the exponential map.
Eigen::Quaterniond from_rotation_vector(const Eigen::Vector3d& phi);

}  // namespace crossdyn::rot
