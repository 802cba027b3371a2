// Every engine against the analytic torque-free rigid body (analytic/torque_free.hpp) over 100 s.
#include <catch2/catch.hpp>

#include "analytic/torque_free.hpp"
#include "core/rotation.hpp"
#include "tests/cross/common.hpp"

#include <cmath>

using namespace crossdyn;
using namespace crossdyn::test;

TEST_CASE("torque-free bodies follow the analytic solution to 1e-10 relative over 100 s") {
  for (const char* scene : {"torque_free_axisymmetric", "torque_free_asymmetric"}) {
    const System system = read_scene(scene_path(scene));
    REQUIRE(analytic::is_torque_free(system));
    REQUIRE(system.run.duration >= 100.0);
    const Body& body = system.bodies[0];
    const Joint& base = system.joints[0];
    const analytic::TorqueFreeBody exact(body.I_BBo_B, base.w_NB_B0, base.q_NB0);
    const double w_scale = base.w_NB_B0.norm();
    for (const std::string& engine : engine_names()) {
      const RunResult r = run_engine(engine, system, "rkf78", 1e-13);
      REQUIRE_FALSE(r.failure);
      const auto wx = static_cast<std::size_t>(r.column(body.name + ".wx"));
      const auto qw = static_cast<std::size_t>(r.column(body.name + ".qw"));
      double err_w = 0, err_q = 0;
      for (std::size_t i = 0; i < r.rows(); ++i) {
        const analytic::TorqueFreeState s = exact.at(r.at(i, 0));
        const Eigen::Vector3d w(r.at(i, wx), r.at(i, wx + 1), r.at(i, wx + 2));
        const Eigen::Quaterniond q(r.at(i, qw), r.at(i, qw + 1), r.at(i, qw + 2), r.at(i, qw + 3));
        err_w = std::max(err_w, (w - s.w_NB_B).norm() / w_scale);
        err_q = std::max(err_q, rot::angle_between(q, s.q_NB));
      }
      INFO(scene << " with " << engine << ": relative error of w " << err_w << ", attitude error "
                 << err_q << " rad over " << r.at(r.rows() - 1, 0) << " s");
      CHECK(err_w <= 1e-10);
      CHECK(err_q <= 1e-10);
    }
  }
}
