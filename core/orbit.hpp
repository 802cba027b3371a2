// The orbit frame of a scene whose environment is a central body (core/system.hpp, Environment:
// Kind::Orbit; docs/environment.md). Scene data, like a prescribed joint's profile: every engine
// reads O's direction and the orbit frame from here, and evaluates the gravity loads itself.
//
// The reference point O moves on a circular orbit of radius R at the mean motion n = sqrt(mu/R^3)
// (Vallado 2013, "Fundamentals of Astrodynamics and Applications", 4th ed., Sec. 2.3). In the
// central body's inertial axes (N's axes), with the orbit plane's node line P and in-plane normal
// to it Q (Vallado Sec. 2.6, the perifocal-to-inertial rotation R3(-raan) R1(-i) with the argument
// of latitude u in place of the true anomaly):
//   P = (cos raan, sin raan, 0),  Q = (-cos i sin raan, cos i cos raan, sin i),  h = P x Q,
//   u(t) = u0 + n t,  zenith(t) = cos u P + sin u Q  (unit, from the central body's centre to O),
//   along(t) = -sin u P + cos u Q  (the velocity's direction), w_NO_N = n h.
// The local orbit frame O (LVLH, the convention of Hughes 2004, "Spacecraft Attitude Dynamics",
// Sec. 8.1, and of Wie 2008, Sec. 6.4, for gravity-gradient stabilisation):
//   o1 = along   (roll axis, x: along-track, the velocity's direction for a circular orbit)
//   o2 = -h      (pitch axis, y: opposite the orbit normal)
//   o3 = -zenith (yaw axis, z: nadir)
// R_NO has the columns o1, o2, o3 (v_N = R_NO v_O). A body B's attitude relative to O is
// R_OB = R_NO^T R_NB = Rz(yaw) Ry(pitch) Rx(roll) (a 3-2-1 sequence: yaw about o3, then pitch
// about the new y, then roll about the body's x; Diebel 2006, "Representing Attitude", Eq. (287)).
// With this convention a body whose principal axes x, y, z lie along o1, o2, o3 librates in pitch
// at n sqrt(3 (Ix - Iz) / Iy) (Hughes Sec. 9.3, Eq. (9.27)).
#pragma once

#include "core/system.hpp"

#include <Eigen/Core>

namespace crossdyn {

struct OrbitFrame {
  double n = 0;                                         // mean motion, rad/s
  double u = 0;                                         // argument of latitude at t, rad
  Eigen::Vector3d p_EO_N = Eigen::Vector3d::Zero();     // O from the central body's centre E, m
  Eigen::Vector3d zenith_N = Eigen::Vector3d::UnitX();  // unit, E to O
  Eigen::Matrix3d R_NO = Eigen::Matrix3d::Identity();   // columns o1 (along), o2 (-h), o3 (nadir)
  Eigen::Vector3d w_NO_N = Eigen::Vector3d::Zero();     // n h, rad/s
};

// The orbit frame at time t (env.orbit() must hold).
OrbitFrame orbit_frame(const Environment& env, double t);

// (roll, pitch, yaw) of R_OB = Rz(yaw) Ry(pitch) Rx(roll): pitch in [-pi/2, pi/2], roll and yaw in
// (-pi, pi]. At pitch = +-pi/2 (gimbal lock) roll is set to 0 and yaw takes the whole turn.
Eigen::Vector3d roll_pitch_yaw(const Eigen::Matrix3d& R_OB);
// R_OB = Rz(yaw) Ry(pitch) Rx(roll).
Eigen::Matrix3d from_roll_pitch_yaw(const Eigen::Vector3d& roll_pitch_yaw);

}  // namespace crossdyn
