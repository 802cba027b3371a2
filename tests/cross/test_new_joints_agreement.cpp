// Prismatic and universal joints (issue 25; core/system.hpp, docs/conventions.md): the three
// engines, each with its own unit for each joint type, agree at random states (accelerations,
// joint accelerations, every pinned output column, a prescribed slider's force) and over whole
// runs; a free telescoping boom conserves H and E, and a gimbal sweeping its inner angle through
// 90 deg (where three Euler angles would lock) runs to its end in every engine.
#include <catch2/catch.hpp>

#include "core/output_layout.hpp"
#include "harness/compare.hpp"
#include "core/rotation.hpp"
#include "core/scene/scene.hpp"
#include "tests/cross/common.hpp"
#include "tests/support/paths.hpp"

#include <cmath>
#include <numbers>

using namespace crossdyn;
using namespace crossdyn::test;

namespace {

const std::vector<std::string> kOthers{"lagrange", "newton-euler"};

// A tree that holds every new joint the way a user would combine them: a free hub; a slider on an
// oblique axis with an offset, a spring, a damper and a motor; a gimbal on the slider with oblique,
// non-perpendicular axes, springs, dampers and motors; a revolute hinge after the gimbal; a second
// slider deployed by a prescribed profile on the hub; and a gimbal directly on the hub.
const char* kMixed = R"(name: mixed_new_joints
bodies:
  - {name: hub, mass: 120 kg, inertia: [40, 55, 60, 1.5, -0.8, 0.6]}
  - {name: carriage, mass: 6 kg, inertia: [0.3, 0.5, 0.4, 0.01, 0, 0.02]}
  - {name: head, mass: 3 kg, inertia: [0.08, 0.12, 0.1, 0, 0.01, 0]}
  - {name: flap, mass: 1 kg, inertia: [0.02, 0.01, 0.02]}
  - {name: ram, mass: 4 kg, inertia: [0.05, 0.3, 0.3]}
  - {name: eye, mass: 2 kg, inertia: [0.03, 0.05, 0.04]}
joints:
  - name: base
    type: free
    child: hub
    initial: {angular_velocity: [0.3, -0.2, 0.5]}
  - name: slide
    type: prismatic
    parent: hub
    child: carriage
    parent_point: [0.8, 0.2, -0.1]
    child_point: [-0.2, 0.05, 0.1]
    axis: [1, 0.3, -0.2]
    offset: {axis: [0.2, 1, 0.3], angle: 25 deg}
    spring: {stiffness: 80 N/m, neutral_position: 0.1 m}
    damper: {damping: 0.7 N s/m}
    motor: {profile: [{t: 0, value: 2 N}, {t: 0.5, value: -1 N}]}
    initial: {position: 0.15 m, rate: 0.2 m/s}
  - name: pan_tilt
    type: universal
    parent: carriage
    child: head
    parent_point: [0.2, 0, 0.15]
    child_point: [0, -0.05, -0.1]
    axis: [0.1, 0, 1]
    axis2: [0.2, 1, 0.1]
    offset: {axis: [1, 0, 0], angle: 10 deg}
    spring: {stiffness: [3, 2], neutral_angle: [5 deg, -10 deg]}
    damper: {damping: [0.05, 0.08]}
    motor: {profile: [{t: 0, value: [0.2, -0.1]}, {t: 0.7, value: [0, 0.05]}]}
    initial: {angle: [20 deg, -30 deg], rate: [0.4, -0.6]}
  - name: hinge
    type: revolute
    parent: head
    child: flap
    parent_point: [0.1, 0, 0]
    child_point: [-0.1, 0, 0]
    axis: [0, 0, 1]
    spring: {stiffness: 0.5}
    initial: {angle: 0.3, rate: 0.2}
  - name: drive
    type: prismatic
    parent: hub
    child: ram
    parent_point: [-0.5, 0.4, 0]
    child_point: [0.3, 0, 0]
    axis: [-1, 0, 0.2]
    prescribed: {profile: deploy, travel: 0.8 m, ramp_time: 2 s}
  - name: gimbal
    type: universal
    parent: hub
    child: eye
    parent_point: [0, -0.6, 0.3]
    child_point: [0, 0.1, 0]
    axis: [0, 1, 0]
    axis2: [0, 0, 1]
    initial: {angle: [0.5, 1.2], rate: [1.5, 2.5]}
run: {duration: 2 s, output_step: 0.05 s, integrator: rkf78, rtol: 1e-12, atol: 1e-12}
)";

// random_state, plus a universal joint's second angle and rate (random_state draws the first).
TreeState random_new_joint_state(const System& system, std::mt19937& g) {
  TreeState s = random_state(system, g);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (std::size_t j = 0; j < system.joints.size(); ++j) {
    if (system.joints[j].type == JointType::Prismatic) s.joints[j].angle *= 0.3;  // within a metre
    s.joints[j].angle2 = 3.0 * u(g);
    s.joints[j].rate2 = 2.0 * u(g);
  }
  return s;
}

double rel(double a, double b) { return std::abs(a - b) / std::max(1.0, std::abs(b)); }

std::vector<System> systems() {
  std::vector<System> s;
  s.push_back(read_scene_text(kMixed, "mixed_new_joints.yaml"));
  for (const char* name : {"telescoping_boom", "gimbal_payload"}) s.push_back(read_scene(scene_path(name)));
  for (System& x : s) x.zero_linear_momentum = false;  // the base velocity as drawn (see above)
  return s;
}

}  // namespace

TEST_CASE("prismatic and universal joints: at random states every engine's accelerations, joint "
          "accelerations and pinned outputs agree with Kane's to 1e-10") {
  for (const System& system : systems()) {
    const OutputLayout layout(system);
    auto kane = make_engine("kane", system);
    std::mt19937 g(25);
    double worst = 0;
    std::string where;
    for (int k = 0; k < 40; ++k) {
      TreeState s = random_new_joint_state(system, g);
      const double t = 0.13 * k;
      follow_profile(system, s, t);
      const EngineAt at_kane = evaluate(*kane, s, t);
      const TreeAccel& ak = at_kane.accel;
      const std::vector<double>& rk = at_kane.row;
      for (const std::string& other : kOthers) {
        auto e = make_engine(other, system);
        const EngineAt at_other = evaluate(*e, s, t);
        const TreeAccel& ao = at_other.accel;
        const std::vector<double>& ro = at_other.row;
        auto note = [&](double d, const std::string& what) {
          if (d > worst) {
            worst = d;
            where = other + " " + what + " at t = " + std::to_string(t);
          }
        };
        for (std::size_t b = 0; b < system.bodies.size(); ++b)
          for (int i = 0; i < 3; ++i) {
            note(rel(ao.wdot_NB_B[b](i), ak.wdot_NB_B[b](i)), system.bodies[b].name + ".wdot");
            note(rel(ao.a_NBo_N[b](i), ak.a_NBo_N[b](i)), system.bodies[b].name + ".a_CM");
          }
        REQUIRE(ao.angle2_ddot.size() == system.joints.size());
        REQUIRE(ak.angle2_ddot.size() == system.joints.size());
        for (std::size_t j = 0; j < system.joints.size(); ++j) {
          note(rel(ao.angle_ddot[j], ak.angle_ddot[j]), system.joints[j].name + ".angle_ddot");
          note(rel(ao.angle2_ddot[j], ak.angle2_ddot[j]), system.joints[j].name + ".angle2_ddot");
        }
        // Every pinned column at the same state: attitudes, joint coordinates and rates, a
        // prescribed slider's force, H and E.
        for (std::size_t c = 0; c < layout.pinned_size(); ++c) note(rel(ro[c], rk[c]), layout.names()[c]);
      }
    }
    INFO(system.name << ": worst relative difference from kane " << worst << " (" << where << ")");
    CHECK(worst <= 1e-10);
  }
}

TEST_CASE("prismatic and universal joints: integrated at 1e-12, every engine's history agrees with "
          "Kane's to 1e-9, and H is conserved where nothing external acts") {
  for (System system : systems()) {
    system.zero_linear_momentum = true;
    system.run.duration = std::min(system.run.duration, 6.0);
    const RunResult ref = run_engine("kane", system, "rkf78", 1e-12);
    REQUIRE_FALSE(ref.failure);
    const auto pinned = pinned_columns(system);
    const int H = ref.column("H");
    double H0 = ref.at(0, static_cast<std::size_t>(H)), H_drift = 0;
    for (std::size_t i = 0; i < ref.rows(); ++i)
      H_drift = std::max(H_drift, std::abs(ref.at(i, static_cast<std::size_t>(H)) - H0) / H0);
    INFO(system.name << ": kane's relative H drift " << H_drift);
    CHECK(H_drift <= 1e-9);  // every load is internal: joint springs, dampers, motors, drives
    for (const std::string& other : kOthers) {
      const RunResult r = run_engine(other, system, "rkf78", 1e-12);
      REQUIRE_FALSE(r.failure);
      REQUIRE(r.rows() == ref.rows());
      double worst = 0;
      std::string where;
      for (std::size_t c = 0; c < pinned.size(); ++c) {
        const std::string& col = pinned[c];
        if (col.find(".q") != std::string::npos) continue;  // attitudes below
        const int rc = r.column(col);
        REQUIRE(rc >= 0);
        double diff = 0, scale = 1.0;
        for (std::size_t i = 0; i < ref.rows(); ++i) {
          diff = std::max(diff, std::abs(r.at(i, static_cast<std::size_t>(rc)) - ref.at(i, c)));
          scale = std::max(scale, std::abs(ref.at(i, c)));
        }
        if (diff / scale > worst) {
          worst = diff / scale;
          where = col;
        }
      }
      for (const Body& b : system.bodies) {
        const int k0 = ref.column(b.name + ".qw"), o0 = r.column(b.name + ".qw");
        for (std::size_t i = 0; i < ref.rows(); ++i) {
          auto q = [](const RunResult& x, std::size_t row, int c0) {
            const auto c = static_cast<std::size_t>(c0);
            return Eigen::Quaterniond(x.at(row, c), x.at(row, c + 1), x.at(row, c + 2), x.at(row, c + 3));
          };
          const double d = rot::angle_between(q(ref, i, k0), q(r, i, o0));
          if (d > worst) {
            worst = d;
            where = b.name + " attitude";
          }
        }
      }
      INFO(system.name << ": " << other << " vs kane, worst " << worst << " (" << where << ")");
      CHECK(worst <= 1e-9);
    }
  }
}

TEST_CASE("a free telescoping boom conserves H and E in every engine, and a gimbal's inner angle "
          "passes 90 deg without a singularity") {
  // telescoping_boom without its drive and damper: a free slider on a spinning hub is thrown out
  // and pulled back by its spring, exchanging energy with the spin; nothing is lost.
  System boom = read_scene(scene_path("telescoping_boom"));
  for (Joint& J : boom.joints) {
    if (J.name == "extend1") {
      J.prescribed.reset();
      J.rate0 = 0.05;
    }
    J.damping = 0;
  }
  boom.run.duration = 20;
  // mixed_new_joints' gimbal on the hub turns its inner angle from 1.2 rad at 2.5 rad/s: through
  // pi/2 within the first second.
  System mixed = read_scene_text(kMixed, "mixed_new_joints.yaml");
  for (const System* system : {&boom, &mixed}) {
    for (const std::string& engine : {std::string("kane"), std::string("lagrange"), std::string("newton-euler")}) {
      const RunResult r = run_engine(engine, *system, "rkf78", 1e-12);
      INFO(system->name << " " << engine << (r.failure ? std::string(": ") + r.failure->what() : std::string()));
      REQUIRE_FALSE(r.failure);
      const auto H = static_cast<std::size_t>(r.column("H")), E = static_cast<std::size_t>(r.column("E"));
      double dH = 0, dE = 0;
      for (std::size_t i = 0; i < r.rows(); ++i) {
        dH = std::max(dH, std::abs(r.at(i, H) - r.at(0, H)) / r.at(0, H));
        dE = std::max(dE, std::abs(r.at(i, E) - r.at(0, E)) / r.at(0, E));
      }
      INFO("relative drift: H " << dH << ", E " << dE);
      CHECK(dH <= 1e-9);
      if (system == &boom) CHECK(dE <= 1e-9);
      if (system == &mixed) {
        double top = 0;
        const auto a2 = static_cast<std::size_t>(r.column("gimbal.angle2"));
        for (std::size_t i = 0; i < r.rows(); ++i) top = std::max(top, r.at(i, a2));
        CHECK(top > std::numbers::pi / 2 + 0.5);
      }
    }
  }
}

TEST_CASE("telescoping_boom: each engine's energy changes by the drive's work less the damper's "
          "dissipation") {
  // dE/dt = F s1' - c s2'^2: the prescribed stage's force times its rate (the `.force` column is
  // the force the joint applies to its child), and the damper's power on the free stage. Both
  // integrated by Simpson's rule on a 5 ms output grid (error ~1e-10 of the work here).
  System boom = read_scene(scene_path("telescoping_boom"));
  boom.run.output_step = 0.005;
  double c = 0;
  for (const Joint& J : boom.joints)
    if (J.name == "extend2") c = J.damping;
  REQUIRE(c > 0);
  for (const std::string& engine : {std::string("kane"), std::string("lagrange"), std::string("newton-euler")}) {
    const RunResult r = run_engine(engine, boom, "rkf78", 1e-12);
    REQUIRE_FALSE(r.failure);
    const auto F = static_cast<std::size_t>(r.column("extend1.force"));
    const auto s1 = static_cast<std::size_t>(r.column("extend1.rate"));
    const auto s2 = static_cast<std::size_t>(r.column("extend2.rate"));
    const auto E = static_cast<std::size_t>(r.column("E"));
    auto power = [&](std::size_t i) { return r.at(i, F) * r.at(i, s1) - c * r.at(i, s2) * r.at(i, s2); };
    const double h = boom.run.output_step;
    double worst = 0, work = 0, E_max = 0, W_max = 0;
    for (std::size_t i = 2; i < r.rows(); i += 2) {
      work += h / 3 * (power(i - 2) + 4 * power(i - 1) + power(i));
      worst = std::max(worst, std::abs(r.at(i, E) - r.at(0, E) - work));
      W_max = std::max(W_max, std::abs(work));
      E_max = std::max(E_max, std::abs(r.at(i, E)));
    }
    INFO(engine << ": largest |E - E0 - W| " << worst << " J, largest |W| " << W_max << " J, E up to "
                << E_max << " J");
    CHECK(W_max > 1.0);  // the drive and the damper do work that matters here
    CHECK(worst <= 1e-8 * E_max);
  }
}

TEST_CASE("compare notes a universal joint's keyhole (its boresight on its outer axis) as a finding, "
          "not a failure") {
  // mixed_new_joints' hub gimbal (perpendicular axes) turns its inner angle through 90 deg; the
  // pan-tilt head's axes are oblique and its inner angle stays small; gimbal_payload's reaches
  // about 50 deg.
  const System mixed = read_scene_text(kMixed, "mixed_new_joints.yaml");
  const harness::SceneComparison c = harness::compare_scene(mixed, harness::CompareOptions{});
  std::vector<std::string> keyhole;
  for (const std::string& n : c.notes)
    if (n.find("keyhole") != std::string::npos) keyhole.push_back(n);
  INFO(keyhole.size() << " keyhole notes");
  REQUIRE(keyhole.size() == 1);
  CHECK(keyhole[0].rfind("gimbal: the gimbal's boresight", 0) == 0);
  CHECK(keyhole[0].find("the dynamics have no singularity") != std::string::npos);
  bool failed = false;
  for (const harness::Check& k : c.checks) failed = failed || k.status == harness::CheckStatus::Fail;
  CHECK_FALSE(failed);
  const harness::SceneComparison g =
      harness::compare_scene(read_scene(scene_path("gimbal_payload")), harness::CompareOptions{});
  for (const std::string& n : g.notes) CHECK(n.find("keyhole") == std::string::npos);
}
