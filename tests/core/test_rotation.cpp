// The shared rotation helpers (core/rotation.hpp) against definitions and finite differences.
#include <catch2/catch.hpp>

#include "core/rotation.hpp"

#include <cmath>
#include <random>

using namespace crossdyn;

namespace {
Eigen::Quaterniond random_quat(std::mt19937& g) {
  std::normal_distribution<double> n;
  return Eigen::Quaterniond(n(g), n(g), n(g), n(g)).normalized();
}
}  // namespace

TEST_CASE("skew(a) b equals a x b") {
  const Eigen::Vector3d a(0.3, -1.2, 2.5), b(-0.7, 0.4, 1.1);
  CHECK((rot::skew(a) * b - a.cross(b)).norm() < 1e-15);
  CHECK((rot::skew(a) + rot::skew(a).transpose()).norm() == 0.0);
}

TEST_CASE("quat_rate_body matches the finite-difference derivative of q(t) = q0 exp(w t)") {
  std::mt19937 g(7);
  for (int i = 0; i < 20; ++i) {
    const Eigen::Quaterniond q0 = random_quat(g);
    const Eigen::Vector3d w_B(0.3 * i - 2.0, 1.1, -0.4 * i);
    const double h = 1e-6;
    // With w constant in B, q(t) = q0 (x) exp(w_B t / 2) exactly.
    const Eigen::Quaterniond qp = q0 * rot::from_rotation_vector(w_B * h);
    const Eigen::Quaterniond qm = q0 * rot::from_rotation_vector(-w_B * h);
    const Eigen::Vector4d fd = (Eigen::Vector4d(qp.w(), qp.x(), qp.y(), qp.z()) -
                                Eigen::Vector4d(qm.w(), qm.x(), qm.y(), qm.z())) / (2 * h);
    CHECK((rot::quat_rate_body(q0, w_B) - fd).norm() < 1e-8 * (1 + w_B.norm()));
  }
}

TEST_CASE("rotation vector and exponential map are inverse, also near zero and near pi") {
  std::mt19937 g(11);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Quaterniond q = random_quat(g);
    const Eigen::Quaterniond back = rot::from_rotation_vector(rot::rotation_vector(q));
    CHECK(rot::angle_between(q, back) < 1e-14);
  }
  for (double angle : {1e-12, 1e-9, 1e-7, 0.5, 3.0, M_PI - 1e-9}) {
    const Eigen::Vector3d phi = angle * Eigen::Vector3d(1, 2, -2) / 3.0;
    CHECK((rot::rotation_vector(rot::from_rotation_vector(phi)) - phi).norm() <= 1e-15 + 1e-13 * angle);
  }
}

TEST_CASE("angle_between is the relative rotation angle and ignores the sign of q") {
  const Eigen::Quaterniond a(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()));
  const Eigen::Quaterniond b = a * Eigen::Quaterniond(Eigen::AngleAxisd(0.25, Eigen::Vector3d(0, 0.6, 0.8)));
  CHECK(std::abs(rot::angle_between(a, b) - 0.25) < 1e-15);
  const Eigen::Quaterniond minus_b(-b.w(), -b.x(), -b.y(), -b.z());
  CHECK(std::abs(rot::angle_between(a, minus_b) - 0.25) < 1e-15);
  CHECK(rot::angle_between(a, a) == 0.0);
}

TEST_CASE("canonical gives a non-negative scalar part and the same rotation") {
  const Eigen::Quaterniond q(-0.5, 0.5, -0.5, 0.5);
  const Eigen::Quaterniond c = rot::canonical(q);
  CHECK(c.w() >= 0);
  CHECK((c.toRotationMatrix() - q.toRotationMatrix()).norm() < 1e-15);
}

// The helpers two engines share (kane and newton-euler both call quat_rate_body and
// rotation_vector) are checked here against closed forms that do not use any other helper of
// core/rotation.hpp, only Eigen's own AngleAxis (Rodrigues' formula) and quaternion product, so a
// sign or convention error in a helper cannot be hidden by the same error in its inverse.

TEST_CASE("quat_rate_body integrates to R(t) = R0 Rot(w_B/|w_B|, |w_B| t) for constant w_B") {
  // Kane, Likins & Levinson 1983 Sec. 1.13: with w_B constant in the body frame the body turns
  // about the body-fixed axis w_B at the rate |w_B|, so R_NB(t) = R_NB(0) Rot(w_hat, |w| t).
  std::mt19937 g(17);
  for (int i = 0; i < 10; ++i) {
    const Eigen::Quaterniond q0 = random_quat(g);
    const Eigen::Vector3d w_B(0.7 - 0.3 * i, 1.3, 0.2 * i - 0.5);  // rad/s
    const double T = 2.0, h = 1e-3;
    // RK4 on q' = quat_rate_body(q, w_B), quaternion as a plain 4-vector (w, x, y, z).
    auto f = [&w_B](const Eigen::Vector4d& v) {
      return rot::quat_rate_body(Eigen::Quaterniond(v(0), v(1), v(2), v(3)), w_B);
    };
    Eigen::Vector4d v(q0.w(), q0.x(), q0.y(), q0.z());
    for (int k = 0; k < static_cast<int>(T / h + 0.5); ++k) {
      const Eigen::Vector4d k1 = f(v), k2 = f(v + 0.5 * h * k1), k3 = f(v + 0.5 * h * k2),
                            k4 = f(v + h * k3);
      v += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    }
    const Eigen::Matrix3d R = Eigen::Quaterniond(v(0), v(1), v(2), v(3)).normalized().toRotationMatrix();
    const Eigen::Matrix3d expected =
        q0.toRotationMatrix() * Eigen::AngleAxisd(w_B.norm() * T, w_B.normalized()).toRotationMatrix();
    // RK4 with |w| h <= 3e-3: global error ~ (|w| h)^4 |w| T / 120 < 1e-11.
    CHECK((R - expected).norm() < 1e-10);
    // The opposite convention (w in N, q' = 1/2 (0, w) q) would give Rot(...) R0 instead:
    const Eigen::Matrix3d wrong =
        Eigen::AngleAxisd(w_B.norm() * T, w_B.normalized()).toRotationMatrix() * q0.toRotationMatrix();
    CHECK((R - wrong).norm() > 1e-3);
  }
}

TEST_CASE("rotation_vector of Eigen's AngleAxis(theta, n) is theta n, for q and for -q") {
  std::mt19937 g(23);
  std::normal_distribution<double> n;
  for (double theta : {0.0, 1e-12, 1e-8, 1e-4, 0.3, 1.0, 2.0, 3.0, M_PI - 1e-6}) {
    for (int i = 0; i < 5; ++i) {
      const Eigen::Vector3d axis = Eigen::Vector3d(n(g), n(g), n(g)).normalized();
      const Eigen::Quaterniond q(Eigen::AngleAxisd(theta, axis));
      const Eigen::Quaterniond minus_q(-q.w(), -q.x(), -q.y(), -q.z());
      const Eigen::Vector3d expected = theta * axis;
      CHECK((rot::rotation_vector(q) - expected).norm() <= 1e-15 + 1e-14 * theta);
      CHECK((rot::rotation_vector(minus_q) - expected).norm() <= 1e-15 + 1e-14 * theta);
      // And the exponential map is Eigen's Rodrigues rotation of the same vector.
      CHECK((rot::from_rotation_vector(expected).toRotationMatrix() -
             Eigen::AngleAxisd(theta, axis).toRotationMatrix()).norm() <= 1e-15 + 1e-14 * theta);
    }
  }
}
