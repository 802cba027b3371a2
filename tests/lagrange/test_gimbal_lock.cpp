// Euler-angle singularities: the gimbal_lock scene passes through the gimbal lock of the default
// 3-2-1 sequence. With re-charting (default) the run carries on with continuous outputs and
// conserved H and E; with EngineOptions::rechart = false it stops with a RunFailure that names
// the time, the body and the angle.
#include <catch2/catch.hpp>
#include <random>

#include "analytic/torque_free.hpp"
#include "core/integrate.hpp"
#include "core/rotation.hpp"
#include "core/scene/scene.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "tests/lagrange/scenes.hpp"
#include "tests/support/close.hpp"
#include "tests/support/paths.hpp"

using namespace crossdyn;
using crossdyn::lagrange::LagrangeEngine;

namespace {

const System& gimbal_lock() {
  static const System s = read_scene(test::scene_path("gimbal_lock"));
  return s;
}

RunResult run_gimbal_lock(bool rechart, long* recharts = nullptr) {
  const System& s = gimbal_lock();
  EngineOptions options;
  options.rechart = rechart;
  LagrangeEngine e(s, options);
  RunResult r = simulate(e, s, TreeState::initial(s), IntegratorSettings::from(s.run));
  if (recharts) *recharts = e.recharts();
  return r;
}

Eigen::Quaterniond attitude(const RunResult& r, std::size_t k) {
  return Eigen::Quaterniond(r.at(k, 4), r.at(k, 5), r.at(k, 6), r.at(k, 7));
}

}  // namespace

TEST_CASE("gimbal lock: re-charting carries the run through the 3-2-1 singularity",
          "[lagrange][gimbal]") {
  long recharts = 0;
  const RunResult r = run_gimbal_lock(true, &recharts);
  INFO((r.failure ? r.failure->what() : "ok")
       << "; " << r.stats.steps << " steps, " << r.stats.restarts << " restarts");
  REQUIRE_FALSE(r.failure);
  const System& s = gimbal_lock();
  REQUIRE(r.rows() ==
          static_cast<std::size_t>(std::lround(s.run.duration / s.run.output_step)) + 1);

  // The attitude passes through the singular orientation of 3-2-1 (body x along +-z_N, where
  // |R(z, x)| = |sin(pitch)| = 1). Rows are |w| dt = 1.4 deg apart, so the closest row is within
  // 0.7 deg of the closest approach, itself within the 0.1 deg nutation of this scene.
  double closest = 1.0;
  for (std::size_t k = 0; k < r.rows(); ++k) {
    const Eigen::Matrix3d R = attitude(r, k).toRotationMatrix();
    closest = std::min(closest, 1.0 - lagrange::chart_singularity(lagrange::kSequences[0], R));
  }
  INFO("closest row to gimbal lock: " << std::acos(1.0 - closest) / test::kDegree << " deg");
  CHECK(std::acos(1.0 - closest) < 0.8 * test::kDegree);

  // Re-charts happened, are counted in the extra column, and restarted the integrator.
  const int rc = r.column("lagrange.recharts");
  REQUIRE(rc >= 0);
  CHECK(recharts >= 1);
  CHECK(r.at(r.rows() - 1, static_cast<std::size_t>(rc)) == static_cast<double>(recharts));
  CHECK(r.stats.restarts >= recharts);

  // Conservation across the re-charts.
  for (const char* c : {"H", "E"}) {
    const auto col = static_cast<std::size_t>(r.column(c));
    double drift = 0;
    for (std::size_t k = 0; k < r.rows(); ++k)
      drift = std::max(drift, std::abs(r.at(k, col) / r.at(0, col) - 1.0));
    INFO(c << " relative drift " << drift);
    CHECK(drift < 1e-10);
  }

  // Outputs are continuous: between rows the attitude turns by at most |w| dt, and the angular
  // velocity changes by at most |w'| dt (w' = I^-1 (w x I w) is bounded by this body's data), so
  // no re-chart shows as a jump.
  const double dt = s.run.output_step;
  const Eigen::Matrix3d I = s.bodies[0].I_BBo_B;
  for (std::size_t k = 1; k < r.rows(); ++k) {
    const Eigen::Vector3d w0(r.at(k - 1, 1), r.at(k - 1, 2), r.at(k - 1, 3));
    const Eigen::Vector3d w1(r.at(k, 1), r.at(k, 2), r.at(k, 3));
    const double turn = rot::angle_between(attitude(r, k - 1), attitude(r, k));
    CHECK(turn <= 1.001 * std::max(w0.norm(), w1.norm()) * dt);
    const double wdot_max = (I.inverse() * w0.cross(I * w0)).norm() * 1.5 + 1e-12;
    CHECK((w1 - w0).norm() <= wdot_max * dt);
  }

  // And the motion is right: the closed-form torque-free solution, at every row.
  const analytic::TorqueFreeBody ref(I, s.joints[0].w_NB_B0, s.joints[0].q_NB0);
  double dq = 0, dw = 0;
  for (std::size_t k = 0; k < r.rows(); ++k) {
    const analytic::TorqueFreeState a = ref.at(r.at(k, 0));
    dq = std::max(dq, rot::angle_between(attitude(r, k), a.q_NB));
    dw = std::max(dw, (Eigen::Vector3d(r.at(k, 1), r.at(k, 2), r.at(k, 3)) - a.w_NB_B).norm());
  }
  INFO("max attitude error " << dq << " rad, max |w - w_ref| " << dw << " rad/s");
  CHECK(dq < 1e-9);
  CHECK(dw < 1e-9);
}

TEST_CASE(
    "gimbal lock: with rechart = false the run stops with a RunFailure naming time, body "
    "and angle",
    "[lagrange][gimbal]") {
  long recharts = -1;
  const RunResult r = run_gimbal_lock(false, &recharts);
  REQUIRE(r.failure);
  const RunFailure& f = *r.failure;
  INFO(f.what());
  CHECK(recharts == 0);
  CHECK(f.engine() == "lagrange");
  CHECK(f.quantity() == "body.euler2 (3-2-1)");
  const std::string what = f.what();
  CHECK(what.find("attitude of body 'body'") != std::string::npos);
  CHECK(what.find("3-2-1") != std::string::npos);
  CHECK(what.find("gimbal lock") != std::string::npos);
  CHECK(what.find(" s") != std::string::npos);
  // The body's x axis reaches 89 deg pitch shortly before -z_N at t = pi / (2 * 0.5 rad/s).
  const double t_lock = std::numbers::pi / (2 * gimbal_lock().joints[0].w_NB_B0.y());
  CHECK(f.time() > t_lock - 0.1);
  CHECK(f.time() < t_lock);
  // The rows before the failure are valid and stop before it.
  CHECK(r.rows() >= 2);
  CHECK(r.at(r.rows() - 1, 0) <= f.time());
}

TEST_CASE(
    "gimbal lock: after_step() re-charts every Euler set past the limit without changing "
    "any output or acceleration",
    "[lagrange][gimbal]") {
  std::mt19937 g(41);
  const System s = test::mixed_tree(true);
  for (int trial = 0; trial < 20; ++trial) {
    LagrangeEngine e(s, {});
    const int n = e.dof();
    std::vector<double> x(static_cast<std::size_t>(e.state_size()));
    e.pack(test::random_state(s, g), x.data());
    // Drive every Euler set's middle angle to 80 deg in its current chart (a valid state in that
    // chart), then compare everything before and after the re-chart.
    std::vector<int> middle;
    for (int k = 0; k < e.euler_sets(); ++k)
      for (int i = 0; i < n; ++i)
        if (e.state_label(i).rfind(e.euler_set_owner(k) + ".euler2", 0) == 0) middle.push_back(i);
    REQUIRE(middle.size() == 3);  // the base and the spherical joints shoulder and knuckle
    for (int i : middle)
      x[static_cast<std::size_t>(i)] = (trial % 2 ? -80.0 : 80.0) * test::kDegree;
    std::vector<double> row0(e.columns().size()), row1(row0.size()), xd0(x.size()), xd1(x.size());
    e.output_row(1.0, x.data(), row0.data());
    e.rhs(1.0, x.data(), xd0.data());
    std::vector<std::string> charts0;
    for (int k = 0; k < e.euler_sets(); ++k) charts0.push_back(e.chart_name(k));
    const std::vector<double> x_before = x;
    REQUIRE(e.after_step(1.0, x.data()));
    CHECK(e.recharts() == e.euler_sets());
    for (int k = 0; k < e.euler_sets(); ++k) {
      CHECK(e.chart_name(k) != charts0[static_cast<std::size_t>(k)]);
      CHECK(std::abs(x[static_cast<std::size_t>(middle[static_cast<std::size_t>(k)])]) <=
            45.0 * test::kDegree + 1e-12);
    }
    for (int i = n; i < 2 * n; ++i)
      CHECK(x[static_cast<std::size_t>(i)] == x_before[static_cast<std::size_t>(i)]);
    e.output_row(1.0, x.data(), row1.data());
    e.rhs(1.0, x.data(), xd1.data());
    for (std::size_t c = 0; c + 1 < row0.size(); ++c) {  // all but lagrange.recharts
      INFO("column " << e.columns()[c]);
      CHECK(test::close(row1[c], row0[c], 1e-14, 1e-13));
    }
    CHECK(row1.back() == row0.back() + e.euler_sets());
    for (int i = n; i < 2 * n; ++i) {  // pi'' does not depend on the chart
      INFO("state " << e.state_label(i));
      CHECK(test::close(xd1[static_cast<std::size_t>(i)], xd0[static_cast<std::size_t>(i)], 1e-12,
                        1e-11));
    }
    // A second call finds nothing to do.
    CHECK_FALSE(e.after_step(1.0, x.data()));
  }
}

TEST_CASE(
    "gimbal lock: with rechart = false a spherical joint's lock names the joint and the "
    "angle",
    "[lagrange][gimbal]") {
  const System s = test::mixed_tree(false);
  EngineOptions options;
  options.rechart = false;
  LagrangeEngine e(s, options);
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(TreeState::initial(s), x.data());
  int shoulder = -1;
  for (int i = 0; i < e.dof(); ++i)
    if (e.state_label(i).rfind("shoulder.euler2", 0) == 0) shoulder = i;
  REQUIRE(shoulder >= 0);
  // Past the re-chart limit but before the failure limit: carry on in the same chart.
  x[static_cast<std::size_t>(shoulder)] = 85.0 * test::kDegree;
  CHECK_FALSE(e.after_step(2.0, x.data()));
  CHECK(e.recharts() == 0);
  x[static_cast<std::size_t>(shoulder)] = -89.5 * test::kDegree;
  try {
    e.after_step(2.5, x.data());
    FAIL("no RunFailure at 89.5 deg");
  } catch (const RunFailure& f) {
    CHECK(f.time() == 2.5);
    CHECK(f.quantity() == "shoulder.euler2 (3-2-1)");
    const std::string what = f.what();
    INFO(what);
    CHECK(what.find("spherical joint 'shoulder' (body 'arm')") != std::string::npos);
    CHECK(what.find("-89.500 deg") != std::string::npos);
  }
}
