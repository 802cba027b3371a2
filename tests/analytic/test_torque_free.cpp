// The analytic torque-free rigid body (analytic/torque_free.hpp) checked against the physics it
// claims to solve, never against itself:
//   - Euler's equations I w' = -w x I w (Euler 1758; Landau & Lifshitz Sec. 36, Eq. 36.5), with w'
//     from a 5-point central finite difference (error O(dt^4), Abramowitz & Stegun 25.3.6);
//   - conservation of H_N = R_NB I w (vector, so the attitude is tested too) and of E;
//   - quaternion kinematics q' = 1/2 q (x) (0, w_B) (Kane, Likins & Levinson 1983, Sec. 1.13);
//   - the axisymmetric top's textbook solution (Kane, Likins & Levinson 1983, Sec. 3.1):
//     w_perp rotates about the symmetry axis at Omega = (Is - It) w3 / It, and
//     R_NB(t) = Rot(H_N / h, h t / It) R_NB(0) Rot(e3, -Omega t).
#include <catch2/catch.hpp>

#include "analytic/torque_free.hpp"
#include "core/rotation.hpp"
#include "core/system.hpp"
#include "tests/support/close.hpp"
#include "tests/support/linalg.hpp"

#include <cmath>
#include <string>
#include <vector>

using crossdyn::analytic::TorqueFreeBody;
using crossdyn::analytic::TorqueFreeState;
using crossdyn::test::ldlt_solve;
using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;
using Eigen::Vector4d;

namespace {

struct Case {
  std::string name;
  Matrix3d I;
  Vector3d w0;
  Quaterniond q0;
};

Matrix3d diag(double a, double b, double c) { return Vector3d(a, b, c).asDiagonal(); }

Quaterniond some_attitude() {
  return Quaterniond(Eigen::AngleAxisd(0.7, Vector3d(1, -2, 0.5).normalized()));
}

// A rotated, non-diagonal inertia: R diag(.) R^T with R not aligned with any axis.
Matrix3d rotated(const Matrix3d& D) {
  const Matrix3d R = Eigen::AngleAxisd(1.1, Vector3d(0.3, 0.9, -0.4).normalized()).toRotationMatrix();
  return R * D * R.transpose();
}

// Every regime of the solution: polhode about the largest axis (D > I2), about the smallest
// (D < I2), near the separatrix, on it, axisymmetric (oblate, prolate, rotated), and steady spin.
std::vector<Case> cases() {
  const Quaterniond q = some_attitude();
  return {
      {"asymmetric, polhode about the major axis", diag(2, 3, 5), Vector3d(0.4, -0.3, 1.2), q},
      {"asymmetric, polhode about the minor axis", diag(2, 3, 5), Vector3d(1.5, 0.6, -0.2), q},
      {"asymmetric, rotated inertia", rotated(diag(10, 14, 21)), Vector3d(-0.5, 0.8, 0.3), q},
      {"asymmetric, near the separatrix", diag(1, 2, 3), Vector3d(std::sqrt(3.0) * 1.0001, 0.01, 1.0), q},
      // h^2 = 2 E I2 exactly: sum I_i (I_i - I2) w_i^2 = -x^2 + 3 z^2 = 0 for x = sqrt(3) z.
      {"asymmetric, on the separatrix", diag(1, 2, 3), Vector3d(std::sqrt(3.0), 0.2, 1.0), q},
      {"axisymmetric oblate (SPEAR-1 main body)", diag(400, 400, 100), Vector3d(0.1, 0.05, 1.5), q},
      {"axisymmetric prolate", diag(100, 400, 400), Vector3d(1.57, 0.2, -0.1), q},
      {"axisymmetric, rotated inertia", rotated(diag(7, 7, 3)), Vector3d(0.2, -0.4, 0.9), q},
      {"steady spin about the intermediate axis", diag(2, 3, 5), Vector3d(0, 0.8, 0), q},
      {"sphere", diag(4, 4, 4), Vector3d(0.3, -0.2, 0.7), q},
  };
}

// I^-1 (-w x I w): Euler's equations for a torque-free body.
Vector3d euler_wdot(const Matrix3d& I, const Vector3d& w) { return ldlt_solve(I, -w.cross(I * w)); }

// Same-sign copy of q relative to ref (q and -q are the same attitude; finite differences need
// one continuous branch).
Quaterniond aligned(const Quaterniond& q, const Quaterniond& ref) {
  return q.coeffs().dot(ref.coeffs()) < 0 ? Quaterniond(-q.w(), -q.x(), -q.y(), -q.z()) : q;
}

// Sample times over several nutation periods (the largest rate here is ~2 rad/s), and a few late
// ones (hundreds of periods) to show that the argument reduction keeps the solution.
std::vector<double> sample_times() {
  std::vector<double> t;
  for (int i = 0; i <= 40; ++i) t.push_back(0.37 * i + 0.013 * i * i);
  for (double late : {250.3, 612.9, 999.7}) t.push_back(late);
  return t;
}

constexpr double kFdStep = 1e-3;  // s; 5-point stencil error ~ dt^4 |w^(5)| / 30 ~ 1e-13

}  // namespace

TEST_CASE("analytic torque-free body starts at its initial state") {
  for (const Case& c : cases()) {
    INFO(c.name);
    const TorqueFreeBody body(c.I, c.w0, c.q0);
    const TorqueFreeState s = body.at(0.0);
    CHECK(crossdyn::test::all_close(s.w_NB_B, c.w0, 1e-13, 1e-13));
    CHECK(crossdyn::rot::angle_between(s.q_NB, c.q0) < 1e-13);
  }
}

TEST_CASE("analytic torque-free body satisfies Euler's equations") {
  for (const Case& c : cases()) {
    INFO(c.name);
    const TorqueFreeBody body(c.I, c.w0, c.q0);
    double worst = 0;
    for (double t : sample_times()) {
      const double h = kFdStep;
      const Vector3d fd = (body.at(t - 2 * h).w_NB_B - 8 * body.at(t - h).w_NB_B +
                           8 * body.at(t + h).w_NB_B - body.at(t + 2 * h).w_NB_B) /
                          (12 * h);
      const Vector3d exact = euler_wdot(c.I, body.at(t).w_NB_B);
      const double scale = std::max(exact.norm(), c.w0.squaredNorm());
      worst = std::max(worst, (fd - exact).norm() / scale);
    }
    INFO("worst relative error of w' " << worst);
    CHECK(worst < 1e-8);
  }
}

TEST_CASE("analytic torque-free body conserves H (as a vector in N) and E") {
  for (const Case& c : cases()) {
    INFO(c.name);
    const TorqueFreeBody body(c.I, c.w0, c.q0);
    const Vector3d H0_N = c.q0 * (c.I * c.w0);
    const double E0 = 0.5 * c.w0.dot(c.I * c.w0);
    double worst_H = 0, worst_E = 0;
    for (double t : sample_times()) {
      const TorqueFreeState s = body.at(t);
      worst_H = std::max(worst_H, (s.q_NB * (c.I * s.w_NB_B) - H0_N).norm() / H0_N.norm());
      worst_E = std::max(worst_E, std::abs(0.5 * s.w_NB_B.dot(c.I * s.w_NB_B) - E0) / E0);
    }
    INFO("relative drift of H_N " << worst_H << ", of E " << worst_E);
    CHECK(worst_H < 1e-12);
    CHECK(worst_E < 1e-13);
  }
}

TEST_CASE("analytic torque-free attitude is consistent with its angular velocity") {
  for (const Case& c : cases()) {
    INFO(c.name);
    const TorqueFreeBody body(c.I, c.w0, c.q0);
    double worst = 0;
    for (double t : sample_times()) {
      const double h = kFdStep;
      const Quaterniond q = body.at(t).q_NB;
      auto qc = [&](double dt) { return aligned(body.at(t + dt).q_NB, q).coeffs(); };
      // coeffs() order is (x, y, z, w); quat_rate_body returns (w, x, y, z).
      const Vector4d fd_xyzw = (qc(-2 * h) - 8 * qc(-h) + 8 * qc(h) - qc(2 * h)) / (12 * h);
      const Vector4d fd(fd_xyzw(3), fd_xyzw(0), fd_xyzw(1), fd_xyzw(2));
      const Vector4d exact = crossdyn::rot::quat_rate_body(q, body.at(t).w_NB_B);
      worst = std::max(worst, (fd - exact).norm() / c.w0.norm());
    }
    INFO("worst relative error of q' " << worst);
    CHECK(worst < 1e-8);
  }
}

TEST_CASE("analytic axisymmetric body matches the textbook closed form") {
  // Symmetry axis e3 of B; It transverse, Is axial; oblate and prolate; long run (many turns).
  for (const auto& [It, Is] : {std::pair{400.0, 100.0}, std::pair{100.0, 400.0}}) {
    const Matrix3d I = diag(It, It, Is);
    const Vector3d w0(0.3, -0.1, 1.57);
    const Quaterniond q0 = some_attitude();
    const TorqueFreeBody body(I, w0, q0);
    const Vector3d H0_N = q0 * (I * w0);
    const double h = H0_N.norm();
    const double Omega = (Is - It) * w0.z() / It;
    double worst_w = 0, worst_q = 0;
    for (double t = 0; t <= 200; t += 1.7) {
      const Eigen::AngleAxisd spin_perp(Omega * t, Vector3d::UnitZ());
      const Vector3d w_book(0, 0, w0.z());
      const Vector3d w_expected = w_book + spin_perp * Vector3d(w0.x(), w0.y(), 0);
      const Quaterniond q_expected =
          Quaterniond(Eigen::AngleAxisd(h * t / It, H0_N / h)) * q0 *
          Quaterniond(Eigen::AngleAxisd(-Omega * t, Vector3d::UnitZ()));
      const TorqueFreeState s = body.at(t);
      worst_w = std::max(worst_w, (s.w_NB_B - w_expected).norm() / w0.norm());
      worst_q = std::max(worst_q, crossdyn::rot::angle_between(s.q_NB, q_expected));
    }
    INFO("It " << It << ", Is " << Is << ": worst w error " << worst_w << ", attitude " << worst_q
               << " rad");
    CHECK(worst_w < 1e-12);
    CHECK(worst_q < 1e-11);
  }
}

TEST_CASE("is_torque_free accepts one free body without loads only") {
  crossdyn::Body body;
  body.mass = 1;
  body.I_BBo_B = diag(1, 2, 3);
  crossdyn::Joint base;
  base.type = crossdyn::JointType::Free;
  base.child = 0;
  crossdyn::System s;
  s.bodies.push_back(body);
  s.joints.push_back(base);
  CHECK(crossdyn::analytic::is_torque_free(s));
  crossdyn::System torqued = s;
  torqued.bodies[0].torque.times = {0.0};
  torqued.bodies[0].torque.values = {Vector3d(0, 0, 1)};
  CHECK_FALSE(crossdyn::analytic::is_torque_free(torqued));
  crossdyn::System two = s;
  two.bodies.push_back(s.bodies[0]);
  two.joints.push_back(s.joints[0]);
  two.joints[1].type = crossdyn::JointType::Revolute;
  two.joints[1].parent = 0;
  two.joints[1].child = 1;
  CHECK_FALSE(crossdyn::analytic::is_torque_free(two));
}
