// `crossdyn converge`: fewer modes, the same rigid body, and the smallest model named
// (harness/converge.hpp).
#include <catch2/catch.hpp>

#include "core/engine.hpp"
#include "core/errors.hpp"
#include "harness/converge.hpp"
#include "harness/engines.hpp"
#include "tests/cross/flex_systems.hpp"
#include "tests/harness/run_program.hpp"

using namespace crossdyn;
using namespace crossdyn::harness;

TEST_CASE("converge: the beam generator's modes form one group per bending plane") {
  const System s = test::pointing_flex_system(3);
  const std::vector<ModeGroup> g = mode_groups(s);
  REQUIRE(g.size() == 2);
  CHECK(g[0].name == "qx");
  CHECK(g[1].name == "qy");
  CHECK(g[0].modes == std::vector<int>{0, 1, 2});
  CHECK(g[1].modes == std::vector<int>{3, 4, 5});
  CHECK(model_label(s, g, {2, 0}) == "beam qx2 qy0");
  CHECK(mode_groups(test::pointing_flex_system(0)).empty());
}

TEST_CASE("converge: modes that the motion does not excite can be left out exactly, in every "
          "engine") {
  // Scene 2 moves in the beam's x-z plane only (hinges about y, motors about y, no y-plane
  // deflection): the y-plane modes are not excited. At such a state the full model's qy
  // accelerations vanish, and the model without them (truncate_modes: qx2 qy0) has the same
  // accelerations of every other coordinate, in every engine: the truncation is the full model
  // with the dropped coordinates held at zero.
  const System full = test::pointing_flex_system(2);
  const std::vector<ModeGroup> g = mode_groups(full);
  const System cut = truncate_modes(full, g, {2, 0});
  REQUIRE(cut.bodies[0].flex->modes() == 2);
  CHECK(cut.bodies[0].flex->mode_names == std::vector<std::string>{"qx1", "qx2"});
  CHECK(cut.bodies[0].mass == full.bodies[0].mass);
  CHECK(cut.bodies[0].I_BBo_B == full.bodies[0].I_BBo_B);
  CHECK(cut.bodies[0].flex->K == full.bodies[0].flex->K.topLeftCorner(2, 2));
  for (const std::string& engine : engine_names()) {
    auto ef = make_engine(engine, full);
    auto ec = make_engine(engine, cut);
    TreeState sf = TreeState::initial(full), sc = TreeState::initial(cut);
    sf.w_NB_B = sc.w_NB_B = Eigen::Vector3d(0.0, 0.03, 0.0);
    sf.joints[1].angle = sc.joints[1].angle = 0.4;
    sf.joints[1].rate = sc.joints[1].rate = 0.2;
    sf.joints[2].angle = sc.joints[2].angle = -0.3;
    sf.joints[2].rate = sc.joints[2].rate = -0.1;
    sf.eta[0](0) = sc.eta[0](0) = 0.01;
    sf.eta[0](1) = sc.eta[0](1) = -0.004;
    sf.eta_rate[0](0) = sc.eta_rate[0](0) = -0.02;
    sf.eta_rate[0](1) = sc.eta_rate[0](1) = 0.003;
    std::vector<double> xf(static_cast<std::size_t>(ef->state_size()));
    std::vector<double> xc(static_cast<std::size_t>(ec->state_size()));
    ef->pack(sf, xf.data());
    ec->pack(sc, xc.data());
    TreeAccel af, ac;
    ef->accelerations(1.0, xf.data(), af);  // motors at +1 N m
    ec->accelerations(1.0, xc.data(), ac);
    INFO(engine << ": full model qy accelerations " << af.eta_ddot[0].tail(2).transpose()
                << ", qx " << af.eta_ddot[0].head(2).transpose() << " (truncated "
                << ac.eta_ddot[0].transpose() << ")");
    REQUIRE(ac.eta_ddot[0].size() == 2);
    REQUIRE(af.eta_ddot[0].size() == 4);
    const double scale = af.eta_ddot[0].cwiseAbs().maxCoeff();
    REQUIRE(scale > 1e-4);  // the motion does excite the x-plane modes
    CHECK(af.eta_ddot[0].tail(2).cwiseAbs().maxCoeff() <= 1e-12 * scale);
    CHECK((ac.eta_ddot[0] - af.eta_ddot[0].head(2)).cwiseAbs().maxCoeff() <= 1e-12 * scale);
    for (std::size_t b = 0; b < full.bodies.size(); ++b) {
      CHECK((ac.wdot_NB_B[b] - af.wdot_NB_B[b]).norm() <= 1e-12 * (1 + af.wdot_NB_B[b].norm()));
      CHECK((ac.a_NBo_N[b] - af.a_NBo_N[b]).norm() <= 1e-12 * (1 + af.a_NBo_N[b].norm()));
    }
    for (std::size_t j = 0; j < full.joints.size(); ++j)
      CHECK(std::abs(ac.angle_ddot[j] - af.angle_ddot[j]) <= 1e-12 * (1 + std::abs(af.angle_ddot[j])));
  }
}

TEST_CASE("converge on Scene 2 finds that the y-plane modes can be left out and the x-plane modes "
          "cannot") {
  System s = test::pointing_flex_system(2);
  s.run.duration = 20.0;
  s.run.output_step = 0.5;
  s.compare.default_tolerance = {1e-8, 1e-8};
  CompareOptions o;
  o.engines = {{"kane", "kane", {}}};
  const ConvergeResult r = converge_scene(s, o);
  INFO(format_converge(r));
  REQUIRE(r.models.size() == 9);
  CHECK(r.models.front().full);
  const ConvergeModel& best = r.models[static_cast<std::size_t>(r.smallest)];
  CHECK(best.counts == std::vector<int>{2, 0});
  for (const ConvergeModel& m : r.models) {
    if (m.full) continue;
    // Leaving out an x-plane mode changes the answer beyond the tolerance; y-plane modes do not.
    CHECK(m.passed == (m.counts[0] == 2));
  }
}

TEST_CASE("converge refuses a scene without modes and a scene with too many models") {
  CompareOptions o;
  o.engines = {{"kane", "kane", {}}};
  System rigid = test::pointing_flex_system(0);
  rigid.file = "rigid.yaml";
  CHECK_THROWS_WITH(converge_scene(rigid, o),
                    Catch::Contains("rigid.yaml") && Catch::Contains("needs a flexible body"));
  System many = test::pointing_flex_system(16);  // 17 x 17 = 289 models
  many.file = "many.yaml";
  CHECK_THROWS_WITH(converge_scene(many, o),
                    Catch::Contains("289 models") && Catch::Contains("the limit is 256"));
}

TEST_CASE("crossdyn converge on a rigid scene, with an unknown engine or an output that is the "
          "scene: exit status 2 and the reason") {
  auto r = test::run_crossdyn("converge scenarios/spear1_case1.yaml -q");
  CHECK(r.status == 2);
  CHECK_THAT(r.output, Catch::Contains("spear1_case1.yaml") &&
                           Catch::Contains("needs a flexible body with at least one mode"));
  r = test::run_crossdyn("converge scenarios/spear1_case1.yaml --engine knae -q");
  CHECK(r.status == 2);
  CHECK_THAT(r.output, Catch::Contains("unknown engine 'knae'"));
  r = test::run_crossdyn("converge scenarios/spear1_case1.yaml --json scenarios/spear1_case1.yaml");
  CHECK(r.status == 2);
  CHECK_THAT(r.output, Catch::Contains("--json") && Catch::Contains("scene file"));
  r = test::run_crossdyn("convrge scenarios/spear1_case1.yaml");
  CHECK(r.status == 2);
  CHECK_THAT(r.output, Catch::Contains("did you mean 'converge'"));
}
