// The constraint rows of each joint type against finite differences, at random (off-manifold)
// states: J is the derivative of g, g' = J nu, and gamma = -Jdot nu is the rest of g''.
#include "formulations/newton_euler/joint_constraints.hpp"

#include "core/rotation.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <random>

using namespace crossdyn;
using namespace crossdyn::newton_euler;
using Eigen::Quaterniond;
using Eigen::Vector3d;

namespace {

struct Motion {  // a body's state and its accelerations
  BodyKinematics k;
  Vector3d a_N, alpha_B;
};

Vector3d rvec(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return Vector3d(u(rng), u(rng), u(rng));
}

Motion random_motion(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Motion m;
  m.k.q_NB = Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
  m.k.R_NB = m.k.q_NB.toRotationMatrix();
  m.k.p_NoBo_N = rvec(rng);
  m.k.v_NBo_N = rvec(rng);
  m.k.w_NB_B = rvec(rng);
  m.a_N = rvec(rng);
  m.alpha_B = rvec(rng);
  return m;
}

// The body moved along its motion by time h (second order: enough for central differences).
BodyKinematics advance(const Motion& m, double h) {
  BodyKinematics k = m.k;
  k.p_NoBo_N += h * m.k.v_NBo_N + 0.5 * h * h * m.a_N;
  k.v_NBo_N += h * m.a_N;
  k.q_NB = m.k.q_NB * rot::from_rotation_vector(h * m.k.w_NB_B + 0.5 * h * h * m.alpha_B);
  k.R_NB = k.q_NB.toRotationMatrix();
  k.w_NB_B += h * m.alpha_B;
  return k;
}

// The body displaced by delta = [dp_N; dtheta_B] (the same coordinates as nu dt).
BodyKinematics displace(const BodyKinematics& b, const Vector6d& delta) {
  BodyKinematics k = b;
  k.p_NoBo_N += delta.head<3>();
  k.q_NB = b.q_NB * rot::from_rotation_vector(delta.tail<3>());
  k.R_NB = k.q_NB.toRotationMatrix();
  return k;
}

ConstraintRows rows_at(const JointModel& m, const BodyKinematics& P, const BodyKinematics& C) {
  JointKinematics jk;
  joint_kinematics(m, P, C, jk);
  ConstraintRows r;
  constraint_rows(m, P, C, jk, r);
  return r;
}

JointModel model(JointType type) {
  Joint j;
  j.type = type;
  j.parent = 0;
  j.child = 1;
  j.p_PoJ_P = Vector3d(1.0, 0.5, -0.2);
  j.p_CoJ_C = Vector3d(-0.8, 0.1, 0.3);
  j.axis_P = Vector3d(0.3, -0.5, 0.8).normalized();
  j.q_PJ0 = Quaterniond(Eigen::AngleAxisd(0.7, Vector3d(0, 1, 1).normalized()));
  return JointModel::from(j);
}

}  // namespace

TEST_CASE("constraint Jacobian, velocity and acceleration terms match finite differences",
          "[newton_euler][constraints]") {
  std::mt19937 rng(11);
  for (JointType type : {JointType::Revolute, JointType::Spherical, JointType::Fixed}) {
    const JointModel m = model(type);
    for (int trial = 0; trial < 10; ++trial) {
      const Motion P = random_motion(rng), C = random_motion(rng);
      const ConstraintRows r = rows_at(m, P.k, C.k);
      Vector6d nu_P, nu_C, nudot_P, nudot_C;
      nu_P << P.k.v_NBo_N, P.k.w_NB_B;
      nu_C << C.k.v_NBo_N, C.k.w_NB_B;
      nudot_P << P.a_N, P.alpha_B;
      nudot_C << C.a_N, C.alpha_B;
      INFO("joint type " << static_cast<int>(type) << ", trial " << trial);

      // g' = J nu: the same expression evaluated two ways, round-off only.
      const Vector6d J_nu = r.J_P * nu_P + r.J_C * nu_C;
      CHECK((r.gdot - J_nu).cwiseAbs().maxCoeff() <= 1e-14 * (1 + J_nu.cwiseAbs().maxCoeff()));

      // J = dg/dx along a random displacement: central difference, step 1e-6, so truncation
      // error ~1e-12 and round-off ~1e-10 (16 digits / 1e-6).
      Vector6d d_P, d_C;
      d_P << rvec(rng), rvec(rng);
      d_C << rvec(rng), rvec(rng);
      const double e = 1e-6;
      const Vector6d fd_g = (rows_at(m, displace(P.k, e * d_P), displace(C.k, e * d_C)).g -
                             rows_at(m, displace(P.k, -e * d_P), displace(C.k, -e * d_C)).g) /
                            (2 * e);
      const Vector6d J_d = r.J_P * d_P + r.J_C * d_C;
      CHECK((fd_g - J_d).cwiseAbs().maxCoeff() <= 1e-8 * (1 + J_d.cwiseAbs().maxCoeff()));

      // d/dt (J nu) = J nu' - gamma along the motion (central difference, step 1e-5).
      const double h = 1e-5;
      const Vector6d fd_gdot =
          (rows_at(m, advance(P, h), advance(C, h)).gdot - rows_at(m, advance(P, -h), advance(C, -h)).gdot) /
          (2 * h);
      const Vector6d expected = r.J_P * nudot_P + r.J_C * nudot_C - r.gamma;
      CHECK((fd_gdot - expected).cwiseAbs().maxCoeff() <= 1e-8 * (1 + expected.cwiseAbs().maxCoeff()));

      // Rows past the joint's count are zero.
      for (int i = m.rows; i < 6; ++i) {
        CHECK(r.J_P.row(i).isZero(0.0));
        CHECK(r.J_C.row(i).isZero(0.0));
        CHECK(r.g(i) == 0.0);
        CHECK(r.gamma(i) == 0.0);
      }
    }
  }
}

TEST_CASE("revolute angle is recovered from the two attitudes and unwrapped across +-pi",
          "[newton_euler][constraints]") {
  const JointModel m = model(JointType::Revolute);
  for (double angle : {-3.0, -1.0, 0.0, 0.5, 3.1}) {
    const Eigen::Matrix3d R_PC = m.R_PJ0 * Eigen::AngleAxisd(angle, m.a_C).toRotationMatrix();
    CHECK(std::abs(revolute_angle_wrapped(m, R_PC) - angle) <= 1e-14);
  }
  const double two_pi = 2 * std::numbers::pi;
  CHECK(std::abs(unwrap_angle(-3.1, 3.1) - (two_pi - 3.1)) <= 1e-15);
  CHECK(std::abs(unwrap_angle(3.1, -3.1) - (3.1 - two_pi)) <= 1e-15);
  CHECK(std::abs(unwrap_angle(0.2, 2 * two_pi) - (0.2 + 2 * two_pi)) <= 1e-14);
  CHECK(std::abs(unwrap_angle(0.2, 0.1) - 0.2) <= 1e-16);
}
