// Euler-angle charts (formulations/lagrange/euler_chart.hpp): round trips, the kinematic matrix A
// against the time derivative of the rotation (by AD), the singularity, the chart choice.
#include <catch2/catch.hpp>
#include <random>

#include "core/rotation.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "tests/lagrange/scenes.hpp"
#include "tests/support/close.hpp"

using namespace crossdyn::lagrange;
using crossdyn::test::all_close;
using crossdyn::test::close;

TEST_CASE("Euler charts: angles => rotation => angles round trip in all six sequences", "[chart]") {
  std::mt19937 g(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const EulerSequence& seq : kSequences) {
    INFO("sequence " << seq.name);
    for (int trial = 0; trial < 200; ++trial) {
      const double a1 = 3.1 * u(g), a2 = 1.5 * u(g), a3 = 3.1 * u(g);
      const Eigen::Matrix3d R = euler_rotation(seq, a1, a2, a3);
      CHECK(all_close(R.transpose() * R, Eigen::Matrix3d::Identity(), 1e-15, 0));
      CHECK(close(R.determinant(), 1.0, 1e-15, 0));
      const Eigen::Vector3d a = euler_angles(seq, R);
      CHECK(close(a(0), a1, 1e-12, 0));
      CHECK(close(a(1), a2, 1e-12, 0));
      CHECK(close(a(2), a3, 1e-12, 0));
      CHECK(close(chart_singularity(seq, R), std::abs(std::sin(a2)), 1e-15, 0));
      // The quaternion form is the same rotation.
      const Eigen::Vector4d q = euler_quaternion(seq, a1, a2, a3);
      CHECK(all_close(Eigen::Quaterniond(q(0), q(1), q(2), q(3)).toRotationMatrix(), R, 1e-15, 0));
    }
  }
  // 3-2-1 is yaw about z, pitch about y, roll about x: R = Rz Ry Rx.
  const Eigen::Matrix3d R = euler_rotation(kSequences[kDefaultChart], 0.3, -0.2, 0.9);
  const Eigen::Matrix3d expected = (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitY()) *
                                    Eigen::AngleAxisd(0.9, Eigen::Vector3d::UnitX()))
                                       .toRotationMatrix();
  CHECK(all_close(R, expected, 1e-15, 0));
}

TEST_CASE("Euler charts: w = A(a) a' equals (R^T R')^vee with R' by automatic differentiation",
          "[chart]") {
  std::mt19937 g(12);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const EulerSequence& seq : kSequences) {
    INFO("sequence " << seq.name);
    for (int trial = 0; trial < 50; ++trial) {
      const Eigen::Vector3d a(3 * u(g), 1.4 * u(g), 3 * u(g)), ad(u(g), u(g), u(g));
      Dual<1> a1(a(0)), a2(a(1)), a3(a(2));  // seeded along the motion a' = ad
      a1.d[0] = ad(0);
      a2.d[0] = ad(1);
      a3.d[0] = ad(2);
      const Mat3<Dual<1>> R = euler_rotation(seq, a1, a2, a3);
      Eigen::Matrix3d Rv, Rd;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          Rv(r, c) = R(r, c).value();
          Rd(r, c) = R(r, c).d[0];
        }
      const Eigen::Matrix3d W = Rv.transpose() * Rd;  // skew(w), w in the rotated frame
      CHECK(all_close(W + W.transpose(), Eigen::Matrix3d::Zero(), 1e-14, 0));
      const Eigen::Vector3d w(W(2, 1), W(0, 2), W(1, 0));
      const Eigen::Matrix3d A = euler_rate_matrix(seq, a(1), a(2));
      CHECK(all_close(A * ad, w, 1e-14, 1e-14));
      // det A = -+cos(a2): singular exactly at gimbal lock.
      CHECK(close(std::abs(A.determinant()), std::abs(std::cos(a(1))), 1e-14, 0));
    }
  }
}

TEST_CASE("Euler charts: the best chart keeps the middle angle within 45 deg", "[chart]") {
  std::mt19937 g(13);
  double worst = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Eigen::Matrix3d R = crossdyn::test::random_quaternion(g).toRotationMatrix();
    const int c = best_chart(R);
    const Eigen::Vector3d a = euler_angles(kSequences[static_cast<std::size_t>(c)], R);
    worst = std::max(worst, std::abs(a(1)));
    CHECK(all_close(euler_rotation(kSequences[static_cast<std::size_t>(c)], a(0), a(1), a(2)), R,
                    1e-14, 0));
  }
  CHECK(worst <= 45.0 * crossdyn::test::kDegree + 1e-12);
  // At the 3-2-1 gimbal lock (body x along -z_N) the best chart is far from its own singularity.
  const Eigen::Matrix3d lock =
      euler_rotation(kSequences[kDefaultChart], 0.4, std::numbers::pi / 2, 0.1);
  CHECK(close(chart_singularity(kSequences[kDefaultChart], lock), 1.0, 1e-15, 0));
  CHECK(chart_singularity(kSequences[static_cast<std::size_t>(best_chart(lock))], lock) < 1e-12);
}
