// The node-frame rotation maps (formulations/newton_euler/so3.hpp) against independent
// evaluations: exp against Eigen's angle-axis rotation, the left Jacobian against a central
// difference of exp, its time derivative against a central difference of the Jacobian, and the
// series and closed forms against each other where they meet (t = 1).
#include "formulations/newton_euler/so3.hpp"

#include "core/rotation.hpp"

#include <catch2/catch.hpp>

#include <Eigen/Geometry>

#include <cmath>
#include <random>

using namespace crossdyn::newton_euler;
using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

// Rotation angles from 0 through the series range (t < 1), across its edge, and beyond pi.
const double kAngles[] = {0.0, 1e-9, 1e-4, 0.05, 0.1, 0.3, 0.7, 0.999, 1.0, 1.001, 1.7, 3.0, 4.5};

Vector3d unit(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Vector3d(g(rng), g(rng), g(rng)).normalized();
}

Vector3d vex(const Matrix3d& S) { return Vector3d(S(2, 1), S(0, 2), S(1, 0)); }

}  // namespace

TEST_CASE("so3: exp is the rotation by |psi| about psi", "[newton_euler][so3]") {
  std::mt19937 rng(1);
  for (double t : kAngles) {
    const Vector3d axis = unit(rng);
    const Matrix3d R = so3::exp(t * axis);
    const Matrix3d expected = Eigen::AngleAxisd(t, axis).toRotationMatrix();
    INFO("t = " << t);
    CHECK((R - expected).cwiseAbs().maxCoeff() <= 4e-16);
    CHECK((R * R.transpose() - Matrix3d::Identity()).cwiseAbs().maxCoeff() <= 1e-15);
  }
}

// d/dh exp(psi + h d) exp(psi)^T at h = 0 is [(Jl(psi) d) x]. Central difference, step 1e-6:
// truncation ~1e-12, round-off ~1e-10.
TEST_CASE("so3: the left Jacobian maps psi' to the angular velocity of exp(psi)",
          "[newton_euler][so3]") {
  std::mt19937 rng(2);
  const double h = 1e-6;
  for (double t : kAngles) {
    const Vector3d psi = t * unit(rng), d = unit(rng);
    const Matrix3d dR = (so3::exp(psi + h * d) - so3::exp(psi - h * d)) / (2 * h);
    const Matrix3d W = dR * so3::exp(psi).transpose();  // skew: [w x]
    INFO("t = " << t);
    CHECK((W + W.transpose()).cwiseAbs().maxCoeff() <= 1e-9);
    CHECK((vex(W) - so3::left_jacobian(psi) * d).norm() <= 1e-9);
  }
}

TEST_CASE("so3: the Jacobian's rate is its time derivative along psi(t)", "[newton_euler][so3]") {
  std::mt19937 rng(3);
  const double h = 1e-5;
  for (double t : kAngles) {
    const Vector3d psi = t * unit(rng), v = 0.7 * unit(rng), acc = 0.4 * unit(rng);
    auto at = [&](double s) { return so3::left_jacobian(psi + s * v + 0.5 * s * s * acc); };
    const Matrix3d fd = (at(h) - at(-h)) / (2 * h);  // truncation ~1e-10, round-off ~1e-11
    INFO("t = " << t);
    CHECK((fd - so3::left_jacobian_rate(psi, v)).cwiseAbs().maxCoeff() <= 1e-9);
  }
}

// The series (t < 1) and the closed forms (t >= 1) of the five coefficients agree at t = 1.
TEST_CASE("so3: series and closed forms meet at t = 1", "[newton_euler][so3]") {
  const so3::Coefficients below = so3::coefficients(std::nextafter(1.0, 0.0));
  const so3::Coefficients above = so3::coefficients(1.0);
  CHECK(std::abs(below.s - above.s) <= 1e-15);
  CHECK(std::abs(below.a - above.a) <= 1e-15);
  CHECK(std::abs(below.b - above.b) <= 1e-15);
  CHECK(std::abs(below.a1 - above.a1) <= 1e-14);
  CHECK(std::abs(below.b1 - above.b1) <= 1e-13);
  // The limits at t = 0.
  const so3::Coefficients zero = so3::coefficients(0.0);
  CHECK(zero.s == 1.0);
  CHECK(std::abs(zero.a - 0.5) <= 1e-16);
  CHECK(std::abs(zero.b - 1.0 / 6) <= 1e-16);
  CHECK(std::abs(zero.a1 + 1.0 / 12) <= 1e-16);
  CHECK(std::abs(zero.b1 + 1.0 / 60) <= 1e-16);
}
