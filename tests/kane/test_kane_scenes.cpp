// The Kane engine on the committed scenes, read with crossdyn::read_scene and integrated with
// crossdyn::simulate (core/integrate.hpp).
#include <catch2/catch.hpp>

#include "analytic/torque_free.hpp"
#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "core/rotation.hpp"
#include "core/scene/scene.hpp"
#include "formulations/kane/kane.hpp"
#include "tests/kane/kane_systems.hpp"
#include "tests/support/paths.hpp"

#include <algorithm>
#include <filesystem>

using namespace crossdyn;

namespace {

// No load that does work (motor, damper, modal damping, body torque): E is conserved. No
// external torque: H is.
bool energy_conserved(const System& s) {
  // On an orbit E changes as the potential turns with the orbit frame: J is conserved instead
  // (test_kane_gravity.cpp checks it).
  if (s.environment.orbit()) return false;
  for (const Joint& j : s.joints)
    if (j.damping != 0 || !j.motor_revolute.empty() || !j.motor_spherical.empty() ||
        j.prescribed)  // a prescribed joint does work (test_kane_prescribed.cpp checks it)
      return false;
  for (const Body& b : s.bodies)
    if (!b.torque.empty() || (b.flex && b.flex->D.size() && b.flex->D.cwiseAbs().maxCoeff() > 0))
      return false;
  return true;
}
bool momentum_conserved(const System& s) {
  if (!s.base_is_free()) return false;  // a prescribed base: N applies the torque
  if (s.environment.orbit()) return false;  // the gravity-gradient torques
  for (const Body& b : s.bodies)
    if (!b.torque.empty()) return false;
  return true;
}

double relative_drift(const RunResult& r, const std::string& column) {
  const int c = r.column(column);
  REQUIRE(c >= 0);
  const double ref = r.at(0, static_cast<std::size_t>(c));
  double d = 0;
  for (std::size_t i = 0; i < r.rows(); ++i)
    d = std::max(d, std::abs(r.at(i, static_cast<std::size_t>(c)) - ref));
  // Absolute where the quantity starts at zero (H of pointing_flex: all loads internal), as
  // compare's drift rule atol + rtol |X(0)| does.
  return std::abs(ref) > 1e-12 ? d / std::abs(ref) : d;
}

}  // namespace

TEST_CASE(
    "kane: every committed scene runs to its end: H and E are conserved where they must be") {
  std::vector<std::string> scenes;
  for (const auto& f :
       std::filesystem::directory_iterator(crossdyn::test::source_dir() + "/scenarios"))
    if (f.path().extension() == ".yaml") scenes.push_back(f.path().string());
  std::sort(scenes.begin(), scenes.end());
  REQUIRE(!scenes.empty());
  for (const std::string& path : scenes) {
    const System s = read_scene(path);
    auto engine = make_kane_engine(s, {});
    const RunResult r =
        simulate(*engine, s, TreeState::initial(s), IntegratorSettings::from(s.run));
    INFO(path << (r.failure ? std::string(": ") + r.failure->what() : std::string()));
    REQUIRE_FALSE(r.failure.has_value());
    CHECK(r.at(r.rows() - 1, 0) == Approx(s.run.duration).margin(1e-12));
    if (momentum_conserved(s)) {
      const double dH = relative_drift(r, "H");
      INFO("max |H - H0| / H0 = " << dH);
      CHECK(dH <= 1e-9);
    }
    if (energy_conserved(s)) {
      const double dE = relative_drift(r, "E");
      INFO("max |E - E0| / E0 = " << dE);
      CHECK(dE <= 1e-9);
    }
    if (s.analytic == "torque-free") {
      // A single free rigid body: the analytic solution (analytic/torque_free.hpp).
      const Body& b = s.bodies[0];
      const analytic::TorqueFreeBody ref(b.I_BBo_B, s.joints[0].w_NB_B0,
                                         s.joints[0].q_NB0.normalized());
      double dw = 0, dq = 0;
      auto col = [&](const std::string& c) {
        return static_cast<std::size_t>(r.column(b.name + c));
      };
      for (std::size_t i = 0; i < r.rows(); ++i) {
        const analytic::TorqueFreeState x = ref.at(r.at(i, 0));
        const Eigen::Vector3d w(r.at(i, col(".wx")), r.at(i, col(".wy")), r.at(i, col(".wz")));
        const Eigen::Quaterniond q(r.at(i, col(".qw")), r.at(i, col(".qx")), r.at(i, col(".qy")),
                                   r.at(i, col(".qz")));
        dw = std::max(dw, (w - x.w_NB_B).norm() / x.w_NB_B.norm());
        dq = std::max(dq, rot::angle_between(q, x.q_NB));
      }
      INFO("against the analytic solution: max |w - w_ref| / |w_ref| = "
           << dw << ", max attitude error = " << dq << " rad");
      CHECK(dw <= 1e-8);
      CHECK(dq <= 1e-8);
    }
  }
}

TEST_CASE("kane: spear1_case1.yaml gives the same rows as the scene built in code") {
  const System file = read_scene(crossdyn::test::scene_path("spear1_case1"));
  const System code = crossdyn::test::kane::spear1_case1();
  auto ef = make_kane_engine(file, {});
  auto ec = make_kane_engine(code, {});
  IntegratorSettings settings = IntegratorSettings::from(file.run);
  const RunResult rf = simulate(*ef, file, TreeState::initial(file), settings);
  const RunResult rc = simulate(*ec, code, TreeState::initial(code), settings);
  REQUIRE_FALSE(rf.failure.has_value());
  REQUIRE(rf.rows() == rc.rows());
  REQUIRE(rf.columns == rc.columns);
  double diff = 0;
  for (std::size_t i = 0; i < rf.data.size(); ++i)
    diff = std::max(diff, std::abs(rf.data[i] - rc.data[i]));
  INFO("largest difference between the two runs = " << diff);
  CHECK(diff <= 1e-12);
}
