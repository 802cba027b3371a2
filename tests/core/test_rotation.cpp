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
