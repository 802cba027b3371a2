// The constraint rows of each joint type against finite differences, at random (off-manifold)
// states: J is the derivative of g, g' = J nu, and gamma = -Jdot nu is the rest of g''. With
// rigid bodies, and with joints at nodes of flexible bodies (the modal columns, the node frames
// exp([psi x]) and their exact angular velocities).
#include "formulations/newton_euler/joint_constraints.hpp"

#include "core/rotation.hpp"
#include "tests/newton_euler/ne_systems.hpp"

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
  Eigen::VectorXd eta_ddot;
};

Vector3d rvec(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return Vector3d(u(rng), u(rng), u(rng));
}

Motion random_motion(std::mt19937& rng, int modes = 0, double eta_scale = 0) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Motion m;
  m.k.eta = Eigen::VectorXd(modes);
  m.k.eta_dot = Eigen::VectorXd(modes);
  m.eta_ddot = Eigen::VectorXd(modes);
  for (int i = 0; i < modes; ++i) {
    m.k.eta(i) = eta_scale * u(rng);
    m.k.eta_dot(i) = u(rng);
    m.eta_ddot(i) = u(rng);
  }
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
  k.eta += h * m.k.eta_dot + 0.5 * h * h * m.eta_ddot;
  k.eta_dot += h * m.eta_ddot;
  return k;
}

// The body displaced by delta = [dp_N; dtheta_B; d eta] (the same coordinates as nu dt).
BodyKinematics displace(const BodyKinematics& b, const Eigen::VectorXd& delta) {
  BodyKinematics k = b;
  k.p_NoBo_N += delta.head<3>();
  k.q_NB = b.q_NB * rot::from_rotation_vector(delta.segment<3>(3));
  k.R_NB = k.q_NB.toRotationMatrix();
  k.eta += delta.tail(delta.size() - 6);
  return k;
}

ConstraintRows rows_at(const JointModel& m, const BodyKinematics& P, const BodyKinematics& C) {
  JointKinematics jk(m);
  joint_kinematics(m, P, C, jk);
  ConstraintRows r(m);
  constraint_rows(m, P, C, jk, r);
  return r;
}

// [J_P Je_P] and [J_C Je_C]: the rows against all of a body's unknowns.
Eigen::MatrixXd full(const Matrix6d& J, const Eigen::Matrix<double, 6, Eigen::Dynamic>& Je) {
  Eigen::MatrixXd F(6, 6 + Je.cols());
  F << J, Je;
  return F;
}

Eigen::VectorXd random_vector(std::mt19937& rng, int n) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::VectorXd v(n);
  for (int i = 0; i < n; ++i) v(i) = u(rng);
  return v;
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

// Joints at nodes: a flexible parent (3 modes) and a flexible child (2 modes), each attached at a
// node or rigidly, against rigid partners; every joint type; deformations up to psi ~ 1.5 rad so
// that the node rotation's series and closed forms are both used.
TEST_CASE("constraint rows at nodes of flexible bodies match finite differences",
          "[newton_euler][constraints][flexible]") {
  using crossdyn::test::ne::flexible_beam;
  using crossdyn::test::ne::make_body;
  System s;
  s.bodies = {flexible_beam("P", 10, 3, 6, 2, 1, {1, 2, 3}), flexible_beam("C", 5, 2, 4, 1, 1, {1, 2}),
              make_body("rigidP", 1, Eigen::Matrix3d::Identity()),
              make_body("rigidC", 1, Eigen::Matrix3d::Identity())};
  struct Case {
    int parent, child;
    const char* parent_node;
    const char* child_node;
  };
  const Case cases[] = {{0, 3, "top", nullptr}, {2, 1, nullptr, "bottom"}, {0, 1, "bottom", "top"},
                        {0, 1, nullptr, "mid"}, {0, 1, "s1", nullptr}};
  std::mt19937 rng(17);
  double worst_J = 0, worst_gamma = 0;
  for (const Case& c : cases) {
    for (JointType type : {JointType::Revolute, JointType::Spherical, JointType::Fixed}) {
      for (double eta_scale : {0.1, 0.6}) {
        Joint j;
        j.type = type;
        j.parent = c.parent;
        j.child = c.child;
        j.p_PoJ_P = Vector3d(0.4, -0.2, 0.7);
        j.p_CoJ_C = Vector3d(-0.3, 0.1, -0.5);
        if (c.parent_node) j.parent_node = s.bodies[static_cast<std::size_t>(c.parent)].flex->node_index(c.parent_node);
        if (c.child_node) j.child_node = s.bodies[static_cast<std::size_t>(c.child)].flex->node_index(c.child_node);
        j.axis_P = Vector3d(0.3, -0.5, 0.8).normalized();
        j.q_PJ0 = Quaterniond(Eigen::AngleAxisd(0.7, Vector3d(0, 1, 1).normalized()));
        s.joints = {j};
        const JointModel m = JointModel::from(s, 0);
        const int nP = m.P.modes, nC = m.C.modes;
        for (int trial = 0; trial < 5; ++trial) {
          const Motion P = random_motion(rng, nP, eta_scale), C = random_motion(rng, nC, eta_scale);
          const ConstraintRows r = rows_at(m, P.k, C.k);
          const Eigen::MatrixXd JP = full(r.J_P, r.Je_P), JC = full(r.J_C, r.Je_C);
          Eigen::VectorXd nu_P(6 + nP), nu_C(6 + nC), nudot_P(6 + nP), nudot_C(6 + nC);
          nu_P << P.k.v_NBo_N, P.k.w_NB_B, P.k.eta_dot;
          nu_C << C.k.v_NBo_N, C.k.w_NB_B, C.k.eta_dot;
          nudot_P << P.a_N, P.alpha_B, P.eta_ddot;
          nudot_C << C.a_N, C.alpha_B, C.eta_ddot;
          INFO("parent " << c.parent << " node " << (c.parent_node ? c.parent_node : "-") << ", child "
                         << c.child << " node " << (c.child_node ? c.child_node : "-") << ", type "
                         << static_cast<int>(type) << ", eta scale " << eta_scale << ", trial " << trial);

          const Vector6d J_nu = JP * nu_P + JC * nu_C;
          CHECK((r.gdot - J_nu).cwiseAbs().maxCoeff() <= 1e-14 * (1 + J_nu.cwiseAbs().maxCoeff()));

          const Eigen::VectorXd d_P = random_vector(rng, 6 + nP), d_C = random_vector(rng, 6 + nC);
          const double e = 1e-6;
          const Vector6d fd_g = (rows_at(m, displace(P.k, e * d_P), displace(C.k, e * d_C)).g -
                                 rows_at(m, displace(P.k, -e * d_P), displace(C.k, -e * d_C)).g) /
                                (2 * e);
          const Vector6d J_d = JP * d_P + JC * d_C;
          const double errJ = (fd_g - J_d).cwiseAbs().maxCoeff() / (1 + J_d.cwiseAbs().maxCoeff());
          worst_J = std::max(worst_J, errJ);
          CHECK(errJ <= 1e-8);

          const double h = 3e-6;  // truncation ~1e-11 |g''''|, round-off ~3e-11 |g'|
          const Vector6d fd_gdot = (rows_at(m, advance(P, h), advance(C, h)).gdot -
                                    rows_at(m, advance(P, -h), advance(C, -h)).gdot) /
                                   (2 * h);
          const Vector6d expected = JP * nudot_P + JC * nudot_C - r.gamma;
          const double errG = (fd_gdot - expected).cwiseAbs().maxCoeff() / (1 + expected.cwiseAbs().maxCoeff());
          worst_gamma = std::max(worst_gamma, errG);
          CHECK(errG <= 1e-8);
          for (int i = m.rows; i < 6; ++i) {
            CHECK(JP.row(i).isZero(0.0));
            CHECK(JC.row(i).isZero(0.0));
          }
        }
      }
    }
  }
  // Measured: worst J error 2.6e-10, worst gamma error 2.3e-10 (relative).
  CHECK(worst_J <= 1e-8);
  CHECK(worst_gamma <= 1e-8);
}
