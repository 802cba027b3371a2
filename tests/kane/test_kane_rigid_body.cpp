// The Kane engine on a single free rigid body: Euler's equations, external torques in both
// frames, the analytic torque-free motion, the inertia-scale hook.
#include <catch2/catch.hpp>

#include "analytic/torque_free.hpp"
#include "core/rotation.hpp"
#include "formulations/kane/kane_engine.hpp"
#include "tests/kane/kane_systems.hpp"
#include "tests/support/close.hpp"

#include <random>

using namespace crossdyn;
using namespace crossdyn::test::kane;
using crossdyn::test::all_close;
using crossdyn::test::close;

namespace {

Eigen::Vector3d speed_rates(const std::vector<double>& xdot, const kane::KaneEngine& e, int at) {
  return Eigen::Vector3d(xdot[static_cast<std::size_t>(e.position_size() + at)],
                         xdot[static_cast<std::size_t>(e.position_size() + at + 1)],
                         xdot[static_cast<std::size_t>(e.position_size() + at + 2)]);
}

}  // namespace

TEST_CASE("kane: a single free body reproduces Euler's equations w' = I^-1 (T_B - w x I w)") {
  // Euler's dynamical equations for a rigid body about its CM, in body axes; the CM moves
  // uniformly (no force); p' = v, q' = 1/2 q (x) (0, w).
  std::mt19937 g(2024);
  std::normal_distribution<double> n;
  for (int sample = 0; sample < 20; ++sample) {
    const Eigen::Quaterniond q_axes(n(g), n(g), n(g), n(g));
    const Eigen::Matrix3d I = turned_inertia(1.0 + std::abs(n(g)), 2.0 + std::abs(n(g)),
                                             2.5 + std::abs(n(g)), q_axes.normalized());
    System s = single_body(I, Eigen::Vector3d::Zero());
    s.zero_linear_momentum = false;
    const Eigen::Vector3d T(n(g), n(g), n(g));  // N m
    const int frame = sample % 3;               // 0: no torque, 1: body frame, 2: inertial frame
    if (frame > 0) {
      s.bodies[0].torque.times = {0.0};
      s.bodies[0].torque.values = {T};
      s.bodies[0].torque_frame = frame == 1 ? Body::Frame::Body : Body::Frame::Inertial;
    }
    kane::KaneEngine e(s, {});
    TreeState st = random_state(s, g);
    std::vector<double> x(static_cast<std::size_t>(e.state_size())), xdot(x.size());
    e.pack(st, x.data());
    e.rhs(0.5, x.data(), xdot.data());

    const Eigen::Vector3d w = st.w_NB_B;
    const Eigen::Matrix3d R_NB = st.q_NB.toRotationMatrix();
    Eigen::Vector3d T_B = Eigen::Vector3d::Zero();
    if (frame == 1) T_B = T;
    if (frame == 2) T_B = R_NB.transpose() * T;
    const Eigen::Vector3d wdot_expected = I.inverse() * (T_B - w.cross(I * w));
    const Eigen::Vector3d wdot = speed_rates(xdot, e, 0);
    CHECK(all_close(wdot, wdot_expected, 1e-14, 1e-12));
    CHECK(speed_rates(xdot, e, 3).norm() <= 1e-15);  // v' = 0 (abs: zero expected)
    for (int i = 0; i < 3; ++i)                      // p' = v
      CHECK(close(xdot[static_cast<std::size_t>(i)], st.v_NBo_N(i), 1e-15, 1e-15));
    const Eigen::Vector4d qdot = rot::quat_rate_body(st.q_NB, w);
    for (int i = 0; i < 4; ++i)
      CHECK(close(xdot[static_cast<std::size_t>(3 + i)], qdot(i), 1e-15, 1e-14));
  }
}

TEST_CASE("kane: a torque-free body follows the analytic solution (RK4, dt = 1 ms, 20 s)") {
  // Asymmetric inertia with principal axes not along the body axes; the analytic solution
  // (analytic/torque_free.hpp) is independent of every engine.
  const Eigen::Matrix3d I = turned_inertia(3.0, 4.0, 6.0, quat_from_axis(0.7, {1, 2, -1}));
  const Eigen::Vector3d w0(0.5, 1.0, -0.3);
  const Eigen::Quaterniond q0 = quat_from_axis(1.1, {-2, 1, 0.5});
  System s = single_body(I, w0);
  s.joints[0].q_NB0 = q0;
  kane::KaneEngine e(s, {});
  const analytic::TorqueFreeBody ref(I, w0, q0);
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(TreeState::initial(s), x.data());
  double max_dw = 0, max_angle = 0;
  rk4(e, x, 0.0, 1e-3, 20000, [&](double t, const std::vector<double>& xx) {
    const analytic::TorqueFreeState r = ref.at(t);
    const std::size_t u = static_cast<std::size_t>(e.position_size());
    const Eigen::Vector3d w(xx[u], xx[u + 1], xx[u + 2]);
    const Eigen::Quaterniond q(xx[3], xx[4], xx[5], xx[6]);
    max_dw = std::max(max_dw, (w - r.w_NB_B).norm());
    max_angle = std::max(max_angle, rot::angle_between(q.normalized(), r.q_NB));
  });
  INFO("max |w - w_ref| = " << max_dw << " rad/s, max attitude error = " << max_angle << " rad");
  CHECK(max_dw <= 1e-9 * w0.norm());
  CHECK(max_angle <= 1e-9);
}

TEST_CASE("kane: test_inertia_scale scales every inertia, not the mass") {
  const Eigen::Matrix3d I = turned_inertia(3.0, 4.0, 6.0, quat_from_axis(0.3, {0, 1, 1}));
  const double mass = 7.0;
  const System s = single_body(I, Eigen::Vector3d(0.1, 0.2, 0.3), mass);
  EngineOptions o;
  o.test_inertia_scale = 1.5;
  kane::KaneEngine e(s, o);
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(TreeState::initial(s), x.data());
  const Eigen::MatrixXd M = e.mass_matrix(x.data());
  // One body: M = diag(I_BBo_B (base-frame speeds), m 1 (N-frame CM velocity)).
  CHECK(all_close(M.topLeftCorner<3, 3>(), (1.5 * I).eval(), 1e-14, 1e-14));
  CHECK(all_close(M.bottomRightCorner<3, 3>(), (mass * Eigen::Matrix3d::Identity()).eval(), 1e-14,
                  1e-14));
  CHECK(M.topRightCorner<3, 3>().norm() <= 1e-14);
}
