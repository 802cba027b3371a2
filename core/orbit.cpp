// The orbit frame (core/orbit.hpp for the equations and their sources).
#include "core/orbit.hpp"

#include <cmath>

namespace crossdyn {

double Environment::mean_motion() const {
  if (kind != Kind::Orbit || radius <= 0) return 0.0;
  return std::sqrt(mu / (radius * radius * radius));
}

OrbitFrame orbit_frame(const Environment& env, double t) {
  OrbitFrame f;
  f.n = env.mean_motion();
  f.u = env.latitude0 + f.n * t;
  const double ci = std::cos(env.inclination), si = std::sin(env.inclination);
  const double cO = std::cos(env.raan), sO = std::sin(env.raan);
  const Eigen::Vector3d P(cO, sO, 0.0);
  const Eigen::Vector3d Q(-ci * sO, ci * cO, si);
  const Eigen::Vector3d h = P.cross(Q);  // (si sO, -si cO, ci)
  const double cu = std::cos(f.u), su = std::sin(f.u);
  f.zenith_N = cu * P + su * Q;
  const Eigen::Vector3d along_N = -su * P + cu * Q;
  f.p_EO_N = env.radius * f.zenith_N;
  f.R_NO.col(0) = along_N;
  f.R_NO.col(1) = -h;
  f.R_NO.col(2) = -f.zenith_N;
  f.w_NO_N = f.n * h;
  return f;
}

Eigen::Vector3d roll_pitch_yaw(const Eigen::Matrix3d& R) {
  // R = Rz(y) Ry(p) Rx(r): R(2,0) = -sin p, R(2,1) = cos p sin r, R(2,2) = cos p cos r,
  // R(1,0) = sin y cos p, R(0,0) = cos y cos p.
  const double sp = std::max(-1.0, std::min(1.0, -R(2, 0)));
  const double pitch = std::asin(sp);
  if (std::abs(sp) > 1.0 - 1e-12) {
    // Gimbal lock: only yaw -+ roll is defined; roll = 0 and R(0,1) = -sin y, R(1,1) = cos y.
    return {0.0, pitch, std::atan2(-R(0, 1), R(1, 1))};
  }
  return {std::atan2(R(2, 1), R(2, 2)), pitch, std::atan2(R(1, 0), R(0, 0))};
}

Eigen::Matrix3d from_roll_pitch_yaw(const Eigen::Vector3d& a) {
  const Eigen::Matrix3d Rx = Eigen::AngleAxisd(a(0), Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Matrix3d Ry = Eigen::AngleAxisd(a(1), Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Matrix3d Rz = Eigen::AngleAxisd(a(2), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return Rz * Ry * Rx;
}

}  // namespace crossdyn
