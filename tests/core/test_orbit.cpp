// The orbit frame (core/orbit.hpp): its kinematics against closed forms and derivatives taken
// here, roll/pitch/yaw both ways, and the reader's `frame: lvlh` conversion (issue 28).
#include "core/orbit.hpp"
#include "core/output_layout.hpp"
#include "core/scene/scene.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <random>

using namespace crossdyn;
using Catch::Matchers::WithinAbs;

namespace {

Environment leo(double i, double raan, double u0) {
  Environment e;
  e.kind = Environment::Kind::Orbit;
  e.mu = 3.986004418e14;
  e.radius = 7000e3;
  e.inclination = i;
  e.raan = raan;
  e.latitude0 = u0;
  return e;
}

}  // namespace

TEST_CASE("orbit: O moves on a Kepler circle and the orbit frame turns at w_NO") {
  std::mt19937 g(28);
  std::uniform_real_distribution<double> a(0.0, 2 * std::numbers::pi), inc(0.0, std::numbers::pi);
  for (int k = 0; k < 20; ++k) {
    const Environment e = leo(inc(g), a(g), a(g));
    const double n = e.mean_motion();
    CHECK_THAT(n, WithinAbs(std::sqrt(3.986004418e14 / std::pow(7000e3, 3)), 1e-18));
    const double t = 1000.0 * a(g);
    const OrbitFrame f = orbit_frame(e, t);
    // An orthonormal right-handed frame: o1 along-track, o2 -normal, o3 nadir.
    CHECK((f.R_NO.transpose() * f.R_NO - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-15);
    CHECK_THAT(f.R_NO.determinant(), WithinAbs(1.0, 1e-15));
    CHECK((f.R_NO.col(2) + f.p_EO_N.normalized()).norm() < 1e-15);
    // Two-body motion, p'' = -mu p / |p|^3, and o1 along p' (central differences, h = 1 s:
    // truncation h^2 |p''''| / 12 ~ 1e-7 m/s^2 of the 8 m/s^2).
    const double h = 1.0;
    const Eigen::Vector3d pm = orbit_frame(e, t - h).p_EO_N, pp = orbit_frame(e, t + h).p_EO_N;
    const Eigen::Vector3d v = (pp - pm) / (2 * h);
    const Eigen::Vector3d acc = (pp - 2 * f.p_EO_N + pm) / (h * h);
    const Eigen::Vector3d kepler = -e.mu * f.p_EO_N / std::pow(f.p_EO_N.norm(), 3);
    CHECK((acc - kepler).norm() < 1e-6 * kepler.norm());
    CHECK((v.normalized() - f.R_NO.col(0)).norm() < 1e-9);
    CHECK_THAT(v.norm(), WithinAbs(n * e.radius, 1e-6 * n * e.radius));
    // R_NO' = [w_NO_N x] R_NO.
    const Eigen::Matrix3d Rdot = (orbit_frame(e, t + h).R_NO - orbit_frame(e, t - h).R_NO) / (2 * h);
    const Eigen::Matrix3d W = Rdot * f.R_NO.transpose();
    const Eigen::Vector3d w(W(2, 1), W(0, 2), W(1, 0));
    CHECK((w - f.w_NO_N).norm() < 1e-6 * n);  // truncation (n h)^2 / 6 ~ 2e-7
    CHECK((f.w_NO_N + n * f.R_NO.col(1)).norm() < 1e-15);  // w_NO = n h = -n o2
  }
  // The default orbit: O on N's x axis at t = 0, moving along +y, the normal along +z.
  const OrbitFrame f0 = orbit_frame(leo(0, 0, 0), 0.0);
  CHECK((f0.zenith_N - Eigen::Vector3d::UnitX()).norm() < 1e-15);
  CHECK((f0.R_NO.col(0) - Eigen::Vector3d::UnitY()).norm() < 1e-15);
  CHECK((f0.R_NO.col(1) + Eigen::Vector3d::UnitZ()).norm() < 1e-15);
}

TEST_CASE("orbit: roll, pitch and yaw of R_OB = Rz(yaw) Ry(pitch) Rx(roll), both ways") {
  std::mt19937 g(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector3d a(std::numbers::pi * u(g), 0.5 * std::numbers::pi * u(g), std::numbers::pi * u(g));
    const Eigen::Matrix3d R = from_roll_pitch_yaw(a);
    CHECK((roll_pitch_yaw(R) - a).norm() < 1e-12);
    // The sequence: yaw about z, then pitch about the new y, then roll about the body x.
    const Eigen::Matrix3d R2 = Eigen::AngleAxisd(a(2), Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                               Eigen::AngleAxisd(a(1), Eigen::Vector3d::UnitY()).toRotationMatrix() *
                               Eigen::AngleAxisd(a(0), Eigen::Vector3d::UnitX()).toRotationMatrix();
    CHECK((R - R2).cwiseAbs().maxCoeff() < 1e-15);
  }
  // A small pitch is a turn about o2 (the negative orbit normal) and nothing else.
  const Eigen::Vector3d p = roll_pitch_yaw(Eigen::AngleAxisd(1e-5, Eigen::Vector3d::UnitY()).toRotationMatrix());
  CHECK_THAT(p(1), WithinAbs(1e-5, 1e-20));
  CHECK_THAT(p(0), WithinAbs(0, 1e-20));
  CHECK_THAT(p(2), WithinAbs(0, 1e-20));
  // Gimbal lock: pitch 90 deg keeps yaw - roll, with roll set to 0.
  const Eigen::Matrix3d L = from_roll_pitch_yaw({0.3, std::numbers::pi / 2, 0.5});
  const Eigen::Vector3d l = roll_pitch_yaw(L);
  CHECK((from_roll_pitch_yaw(l) - L).cwiseAbs().maxCoeff() < 1e-12);
  CHECK(l(0) == 0.0);
}

TEST_CASE("orbit: a base given relative to the orbit frame (frame: lvlh) is read into N") {
  const System s = read_scene_text(R"(
name: lvlh
environment:
  central_body: {mu: 3.986004418e14}
  orbit: {radius: 7000 km, inclination: 50 deg, raan: 20 deg, argument_of_latitude: 10 deg}
bodies: [{name: b, mass: 1, inertia: [1, 2, 3]}]
joints:
  - name: base
    type: free
    child: b
    initial: {frame: lvlh, attitude: {axis: [0, 1, 0], angle: 2 deg}, angular_velocity: [0, 0.001, 0]}
run: {duration: 1, output_step: 0.1}
)",
                                   "lvlh.yaml");
  const Environment& e = s.environment;
  REQUIRE(e.orbit());
  const OrbitFrame f = orbit_frame(e, 0.0);
  const Joint& J = s.joints[0];
  const Eigen::Matrix3d R_OB = f.R_NO.transpose() * J.q_NB0.toRotationMatrix();
  const Eigen::Vector3d rpy = roll_pitch_yaw(R_OB);
  CHECK_THAT(rpy(1), WithinAbs(2 * std::numbers::pi / 180, 1e-14));
  CHECK_THAT(rpy(0), WithinAbs(0, 1e-14));
  // w_NB_B = w_OB_B + R_BN w_NO_N: about body y, -n + 0.001 (the body's y is o2 turned by the pitch).
  CHECK((J.w_NB_B0 - Eigen::Vector3d(0, 0.001 - e.mean_motion(), 0)).norm() < 1e-15);
}

TEST_CASE("orbit: the row writer gives each body's roll, pitch, yaw and rate relative to the orbit "
          "frame at the row's time") {
  System s = read_scene_text(R"(
name: rows
environment:
  central_body: {mu: 3.986004418e14}
  orbit: {radius: 7000 km, inclination: 30 deg}
bodies: [{name: b, mass: 1, inertia: [1, 2, 3]}]
joints: [{name: base, type: free, child: b}]
run: {duration: 1, output_step: 0.1}
)",
                             "rows.yaml");
  const OutputLayout layout(s);
  REQUIRE(layout.lvlh(0) >= 0);
  CHECK(layout.names()[static_cast<std::size_t>(layout.lvlh(0))] == "b.roll");
  CHECK(layout.names()[static_cast<std::size_t>(layout.lvlh(0) + 5)] == "b.woz");
  CHECK(layout.J() >= 0);
  const double t = 1234.5;
  const OrbitFrame f = orbit_frame(s.environment, t);
  const Eigen::Vector3d rpy(0.01, -0.2, 0.3), w_OB_B(0.001, 0.02, -0.003);
  const Eigen::Matrix3d R_NB = f.R_NO * from_roll_pitch_yaw(rpy);
  const Eigen::Vector3d w_NB_B = w_OB_B + R_NB.transpose() * f.w_NO_N;
  std::vector<double> row(layout.size());
  RowWriter w(layout, row.data());
  w.time(t);
  w.body(0, w_NB_B, Eigen::Quaterniond(R_NB));
  for (int i = 0; i < 3; ++i) {
    CHECK_THAT(row[static_cast<std::size_t>(layout.lvlh(0) + i)], WithinAbs(rpy(i), 1e-14));
    CHECK_THAT(row[static_cast<std::size_t>(layout.lvlh(0) + 3 + i)], WithinAbs(w_OB_B(i), 1e-17));
  }
}
