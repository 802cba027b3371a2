// Gimbal lock between accepted steps: whether a run notices the lock of its 3-2-1 Euler angles must
// not depend on where the integrator's steps land. The gimbal_lock scene with a pure spin about y
// (w_NB_B = (0, 0.5, 0) rad/s) has pitch = 0.5 t exactly: it reaches the lock (90 deg; Kane, Likins
// & Levinson 1983, Sec. 1.16; Wertz 1978, App. E) at t = pi s and again every 2 pi s. The motion in
// the 3-2-1 chart is so simple that dense-output and multistep integrators take steps of seconds,
// from one side of the lock to the other, and before after_step() compared the lock sheets of
// consecutive accepted states they carried on for 20 s past it with re-charting off (dopri5,
// dop853, bulirsch-stoer, cvode-adams, cvode-bdf), and with re-charting on never re-charted
// (dopri5, bulirsch-stoer, cvode-adams, cvode-bdf).
#include <catch2/catch.hpp>
#include <numbers>

#include "analytic/torque_free.hpp"
#include "core/integrate.hpp"
#include "core/rotation.hpp"
#include "core/scene/scene.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "tests/lagrange/scenes.hpp"
#include "tests/support/paths.hpp"

using namespace crossdyn;
using crossdyn::lagrange::LagrangeEngine;

namespace {

// The gimbal_lock scene (20 s, 0.05 s outputs, tolerances 1e-12) with initial w_NB_B = w.
System spin_scene(const Eigen::Vector3d& w) {
  System s = read_scene(test::scene_path("gimbal_lock"));
  s.joints[0].w_NB_B0 = w;
  return s;
}

struct Outcome {
  RunResult result;
  long recharts = 0, lock_crossings = 0;
};

Outcome run(const System& s, const std::string& integrator, bool rechart) {
  EngineOptions options;
  options.rechart = rechart;
  LagrangeEngine e(s, options);
  IntegratorSettings settings = IntegratorSettings::from(s.run);
  settings.method = integrator;
  Outcome o{simulate(e, s, TreeState::initial(s), settings), 0, 0};
  o.recharts = e.recharts();
  o.lock_crossings = e.lock_crossings();
  return o;
}

// With re-charting off the run stops as singular (the words harness/stability.cpp's classifier
// looks for), naming the body's middle angle, no later than t_latest.
void check_stops_at_lock(const Outcome& o, double t_latest) {
  REQUIRE(o.result.failure);
  const RunFailure& f = *o.result.failure;
  const std::string what = f.what();
  INFO(what);
  CHECK(f.engine() == "lagrange");
  CHECK(f.quantity() == "body.euler2 (3-2-1)");
  CHECK(what.find("attitude of body 'body' reached gimbal lock of its 3-2-1 Euler angles") !=
        std::string::npos);
  CHECK(what.find("re-charting is off") != std::string::npos);
  CHECK(f.time() > 3.0);
  CHECK(f.time() <= t_latest);
  CHECK(o.recharts == 0);
}

}  // namespace

TEST_CASE("lock crossing: a pure spin through the 3-2-1 lock stops every integrator at t = pi s",
          "[lagrange][gimbal]") {
  const System s = spin_scene({0, 0.5, 0});
  const double t_lock = std::numbers::pi / 2 / 0.5;
  for (const std::string& integrator : integrator_names())
    DYNAMIC_SECTION("integrator " << integrator) {
      const Outcome o = run(s, integrator, false);
      check_stops_at_lock(o, t_lock + s.run.output_step);
      // pitch = 0.5 t is linear in t, so the interpolated crossing is the lock's time itself (the
      // integrators that land on the 89 deg limit first report that step's time, before pi s).
      CHECK(o.result.failure->time() <= t_lock + 1e-9);
    }
}

TEST_CASE("lock crossing: the gimbal_lock scene's wobble stops every integrator by 3.2 s",
          "[lagrange][gimbal]") {
  const System s = spin_scene({0.002, 0.5, 0.001});
  for (const std::string& integrator : integrator_names())
    DYNAMIC_SECTION("integrator " << integrator) {
      check_stops_at_lock(run(s, integrator, false), 3.2);
    }
}

TEST_CASE(
    "lock crossing: with re-charting on, the pure spin runs 20 s with every integrator, "
    "re-charts and matches the torque-free solution",
    "[lagrange][gimbal]") {
  const System s = spin_scene({0, 0.5, 0});
  const analytic::TorqueFreeBody ref(s.bodies[0].I_BBo_B, s.joints[0].w_NB_B0, s.joints[0].q_NB0);
  for (const std::string& integrator : integrator_names())
    DYNAMIC_SECTION("integrator " << integrator) {
      const Outcome o = run(s, integrator, true);
      const RunResult& r = o.result;
      INFO((r.failure ? r.failure->what() : "ok") << "; " << o.recharts << " re-charts, "
                                                  << o.lock_crossings << " after a crossing");
      REQUIRE_FALSE(r.failure);
      REQUIRE(r.rows() ==
              static_cast<std::size_t>(std::lround(s.run.duration / s.run.output_step)) + 1);
      // The lock at pi s is noticed by every integrator: re-charted on the way in (75 deg) or
      // right after a step that jumped across it; once re-charted, a pure y spin is far from the
      // new chart's lock.
      CHECK(o.recharts >= 1);
      CHECK(o.lock_crossings <= o.recharts);
      double dq = 0, dw = 0;
      for (std::size_t k = 0; k < r.rows(); ++k) {
        const analytic::TorqueFreeState a = ref.at(r.at(k, 0));
        const Eigen::Quaterniond q(r.at(k, 4), r.at(k, 5), r.at(k, 6), r.at(k, 7));
        dq = std::max(dq, rot::angle_between(q, a.q_NB));
        dw = std::max(dw, (Eigen::Vector3d(r.at(k, 1), r.at(k, 2), r.at(k, 3)) - a.w_NB_B).norm());
      }
      INFO("max attitude error " << dq << " rad, max |w - w_ref| " << dw << " rad/s");
      CHECK(dq < 1e-8);
      CHECK(dw < 1e-8);
    }
}

TEST_CASE(
    "lock crossing: after_step() sees a middle angle that crossed a lock since the last "
    "accepted state, for the base and for a spherical joint",
    "[lagrange][gimbal]") {
  const System s = test::mixed_tree(false);
  for (const std::string owner : {"core", "shoulder"}) {  // the free base body, a spherical joint
    INFO("Euler set of " << owner);
    for (const bool rechart : {false, true}) {
      INFO("rechart " << rechart);
      EngineOptions options;
      options.rechart = rechart;
      LagrangeEngine e(s, options);
      std::vector<double> x(static_cast<std::size_t>(e.state_size()));
      e.pack(TreeState::initial(s), x.data());
      int middle = -1;
      for (int i = 0; i < e.dof(); ++i)
        if (e.state_label(i).rfind(owner + ".euler2", 0) == 0) middle = i;
      REQUIRE(middle >= 0);
      double& a2 = x[static_cast<std::size_t>(middle)];
      // 60 deg: far from the lock, no re-chart (75 deg), no failure.
      a2 = 60.0 * test::kDegree;
      CHECK_FALSE(e.after_step(1.0, x.data()));
      // 130 deg: 40 deg from the lock at 90, which the step from 60 deg crossed.
      a2 = 130.0 * test::kDegree;
      if (!rechart) {
        try {
          e.after_step(2.0, x.data());
          FAIL("no RunFailure for the crossing from 60 to 130 deg");
        } catch (const RunFailure& f) {
          const std::string what = f.what();
          INFO(what);
          CHECK(f.quantity() == owner + ".euler2 (3-2-1)");
          CHECK(what.find("reached gimbal lock of its 3-2-1 Euler angles") != std::string::npos);
          CHECK(what.find("crossed 90 deg") != std::string::npos);
          CHECK(what.find("linear interpolation") != std::string::npos);
          // 90 deg is 3/7 of the way from 60 to 130 deg.
          CHECK(std::abs(f.time() - (1.0 + 3.0 / 7.0)) < 1e-12);
        }
        // Going back down across -90 deg names that lock.
        a2 = 0.0;
        CHECK_FALSE(e.after_step(3.0, x.data()));
        a2 = -100.0 * test::kDegree;
        try {
          e.after_step(4.0, x.data());
          FAIL("no RunFailure for the crossing from 0 to -100 deg");
        } catch (const RunFailure& f) {
          INFO(f.what());
          CHECK(std::string(f.what()).find("crossed -90 deg") != std::string::npos);
          CHECK(std::abs(f.time() - 3.9) < 1e-12);
        }
      } else {
        CHECK(e.after_step(2.0, x.data()));
        CHECK(e.recharts() == 1);
        CHECK(e.lock_crossings() == 1);
        CHECK(std::abs(x[static_cast<std::size_t>(middle)]) <= 45.0 * test::kDegree + 1e-12);
        CHECK_FALSE(e.after_step(3.0, x.data()));  // nothing more to do
      }
    }
  }
}
