// The prescribed-motion profile (core/system.hpp PrescribedMotion; docs/prescribed-motion.md):
// the spin-up law of Kane, Ryan and Banerjee 1987, Eq. (61), its derivatives and its smoothness,
// the breakpoint, and a prescribed base's initial pose in TreeState::initial.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "core/engine.hpp"
#include "core/output_layout.hpp"
#include "core/system.hpp"

using namespace crossdyn;

TEST_CASE("spin-up profile: velocity and acceleration are the angle's derivatives, C^2 across T") {
  PrescribedMotion p;
  p.rate = 10;
  p.ramp_time = 15;
  const double h = 1e-4;
  for (double t : {0.3, 2.0, 7.5, 11.0, 14.9, 15.1, 18.0, 40.0}) {
    INFO("t = " << t);
    // Central differences: error O(h^2) times the third derivative, below 1e-6 here.
    CHECK(std::abs((p.angle(t + h) - p.angle(t - h)) / (2 * h) - p.velocity(t)) <= 1e-6);
    CHECK(std::abs((p.velocity(t + h) - p.velocity(t - h)) / (2 * h) - p.accel(t)) <= 1e-6);
  }
  CHECK(p.angle(0) == 0);
  CHECK(p.velocity(0) == 0);
  CHECK(p.accel(0) == 0);
  // At T: angle Omega T / 2, rate Omega, acceleration 0, from both formulas.
  const double T = p.ramp_time, e = 1e-9;
  CHECK(std::abs(p.angle(T) - 75.0) <= 1e-12);
  CHECK(std::abs(p.angle(T + e) - p.angle(T)) <= 1e-7);
  CHECK(std::abs(p.velocity(T) - 10.0) <= 1e-12);
  CHECK(std::abs(p.velocity(T + e) - p.velocity(T)) <= 1e-7);
  CHECK(std::abs(p.accel(T)) <= 1e-12);
  // The mean acceleration over the ramp is Omega / T (the rate rises from 0 to Omega).
  CHECK(std::abs(p.accel(T / 2) - 2 * 10.0 / 15.0) <= 1e-12);
  CHECK(p.breakpoints() == std::vector<double>{15.0});
}

TEST_CASE("deploy profile: rest to rest through the travel, derivatives consistent, C^2 across T") {
  PrescribedMotion p;
  p.profile = PrescribedMotion::Profile::Deploy;
  p.travel = 1.5;
  p.ramp_time = 20;
  p.rate = 99;  // not used by deploy
  const double h = 1e-4;
  for (double t : {0.3, 2.0, 7.5, 10.0, 13.0, 19.9, 20.1, 35.0}) {
    INFO("t = " << t);
    CHECK(std::abs((p.angle(t + h) - p.angle(t - h)) / (2 * h) - p.velocity(t)) <= 1e-8);
    CHECK(std::abs((p.velocity(t + h) - p.velocity(t - h)) / (2 * h) - p.accel(t)) <= 1e-8);
  }
  // From rest at 0 to rest at travel at T, on both sides of T; the largest rate 2 travel / T at
  // T/2, and the motion's mean rate travel / T.
  const double T = p.ramp_time, e = 1e-9;
  CHECK(p.angle(0) == 0);
  CHECK(p.velocity(0) == 0);
  CHECK(p.accel(0) == 0);
  CHECK(std::abs(p.angle(T) - 1.5) <= 1e-15);
  CHECK(std::abs(p.angle(T - e) - 1.5) <= 1e-12);
  CHECK(std::abs(p.velocity(T - e)) <= 1e-10);
  CHECK(std::abs(p.accel(T - e)) <= 1e-9);
  CHECK(p.velocity(T + 1) == 0);
  CHECK(std::abs(p.velocity(T / 2) - 2 * 1.5 / 20) <= 1e-15);
  CHECK(std::abs(p.angle(T / 2) - 0.75) <= 1e-15);
  CHECK(p.breakpoints() == std::vector<double>{20.0});
}

TEST_CASE("a prescribed joint has no degree of freedom, its time T is a breakpoint, its torque a column") {
  System s;
  s.bodies.resize(2);
  s.bodies[0].name = "hub";
  s.bodies[1].name = "arm";
  Joint base;
  base.name = "base";
  base.type = JointType::Free;
  base.child = 0;
  Joint hinge;
  hinge.name = "hinge";
  hinge.type = JointType::Revolute;
  hinge.parent = 0;
  hinge.child = 1;
  hinge.prescribed = PrescribedMotion{PrescribedMotion::Profile::SpinUp, 2.0, 5.0};
  s.joints = {base, hinge};
  CHECK(s.joints[1].dof() == 0);
  CHECK(s.breakpoints() == std::vector<double>{5.0});
  const OutputLayout layout(s);
  const auto& names = layout.names();
  const auto at = std::find(names.begin(), names.end(), "hinge.torque");
  REQUIRE(at != names.end());
  CHECK(*(at - 1) == "hinge.rate");
  CHECK(layout.columns()[static_cast<std::size_t>(at - names.begin())].kind == ColumnKind::JointTorque);
}

TEST_CASE("a prescribed base: TreeState::initial places it by its joint at t = 0") {
  System s;
  s.bodies.resize(1);
  s.bodies[0].name = "hub";
  Joint spin;
  spin.name = "spin";
  spin.type = JointType::Revolute;
  spin.parent = -1;
  spin.child = 0;
  spin.axis_P = Eigen::Vector3d::UnitZ();
  spin.p_PoJ_P = Eigen::Vector3d(1, 2, 3);   // the joint point in N
  spin.p_CoJ_C = Eigen::Vector3d(0.5, 0, 0);  // the same point from the hub's CM
  spin.angle0 = std::numbers::pi / 2;
  spin.prescribed = PrescribedMotion{PrescribedMotion::Profile::SpinUp, 3.0, 1.0};
  s.joints = {spin};
  CHECK_FALSE(s.base_is_free());
  const TreeState x = TreeState::initial(s);
  // Turned a quarter turn about z: the hub's +x points along N +y, so its CM sits 0.5 m along -y
  // of the joint point.
  CHECK((x.q_NB * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm() <= 1e-15);
  CHECK((x.p_NoBo_N - Eigen::Vector3d(1, 1.5, 3)).norm() <= 1e-15);
  CHECK(x.w_NB_B.norm() == 0);  // the spin-up starts from rest
  CHECK(x.v_NBo_N.norm() == 0);
}
