// The Kane engine's Engine::linear_system (core/engine.hpp): Kane's equations M(q) u' = f(t, q, u)
// written out dense.  On every committed scene (rigid and flexible, prescribed joints, chain5 on
// the order-N solver, spear1_case1 on the composite one) at random states near the initial one:
// A square and symmetric, sizes consistent, and its solution equal to the u' that rhs() returns.
#include <catch2/catch.hpp>

#include "core/scene/scene.hpp"
#include "formulations/kane/kane_engine.hpp"
#include "tests/kane/kane_systems.hpp"
#include "tests/support/linalg.hpp"
#include "tests/support/paths.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>

using namespace crossdyn;
using namespace crossdyn::test::kane;
using kane::KaneEngine;
using kane::KaneSolver;

namespace {

// The scene's initial state with every free coordinate moved a little: attitudes turned by up to
// ~0.1 rad, angles and rates by ~0.1 (rad, rad/s, m/s), modal coordinates by ~0.01 and their rates
// by ~0.1.  Prescribed joints and a prescribed base keep their values (the engine takes them from
// the profile at t).
TreeState near_initial_state(const System& system, std::mt19937& g) {
  std::normal_distribution<double> n;
  auto vec = [&](double size) { return Eigen::Vector3d(size * n(g), size * n(g), size * n(g)); };
  auto turned = [&](const Eigen::Quaterniond& q) {
    const Eigen::Vector3d r = vec(0.1);
    return (q * Eigen::Quaterniond(Eigen::AngleAxisd(r.norm(), r.normalized()))).normalized();
  };
  TreeState s = TreeState::initial(system);
  if (system.base_is_free()) {
    s.p_NoBo_N += vec(0.1);
    s.q_NB = turned(s.q_NB);
    s.v_NBo_N += vec(0.1);
    s.w_NB_B += vec(0.1);
  }
  for (std::size_t j = 1; j < system.joints.size(); ++j) {
    const Joint& J = system.joints[j];
    if (J.type == JointType::Revolute && !J.prescribed) {
      s.joints[j].angle += 0.1 * n(g);
      s.joints[j].rate += 0.1 * n(g);
    } else if (J.type == JointType::Spherical) {
      s.joints[j].q_J = turned(s.joints[j].q_J);
      s.joints[j].w_PC_C += vec(0.1);
    }
  }
  for (std::size_t b = 0; b < system.bodies.size(); ++b)
    for (Eigen::Index k = 0; k < s.eta[b].size(); ++k) {
      s.eta[b](k) += 0.01 * n(g);
      s.eta_rate[b](k) += 0.1 * n(g);
    }
  return s;
}

double max_abs(const std::vector<double>& v) {
  double m = 0;
  for (double e : v) m = std::max(m, std::abs(e));
  return m;
}

// max_i |z(i) - xdot[speed_index[i]]| for z solving A z = b (Eigen's pivoted LDLT).
double solution_error(const Engine::LinearSystem& ls, const std::vector<double>& xdot) {
  Eigen::ComputationInfo ldlt_info{};
  const Eigen::VectorXd z = test::ldlt_solve(ls.A, ls.b, &ldlt_info);
  REQUIRE(ldlt_info == Eigen::Success);
  double err = 0;
  for (std::size_t i = 0; i < ls.speed_index.size(); ++i)
    err = std::max(err, std::abs(z(static_cast<Eigen::Index>(i)) -
                                 xdot[static_cast<std::size_t>(ls.speed_index[i])]));
  return err;
}

}  // namespace

TEST_CASE(
    "kane linear_system: A = M is square and symmetric, sizes match b and speed_index, and "
    "A z = b gives the u' of rhs() on every committed scene") {
  std::mt19937 g(20260311);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  int flexible = 0, prescribed = 0, order_n = 0, composite = 0;
  bool chain5_order_n = false, spear1_composite = false;
  for (const std::string& path : crossdyn::test::committed_scenes()) {
    const System s = read_scene(path);
    KaneEngine engine(s, {});  // the solver every run takes (KaneSolver::Automatic)
    Engine& e = engine;        // through the interface, as the harness calls it
    const std::string name = std::filesystem::path(path).stem().string();
    bool has_flex = false, has_prescribed = false;
    for (const Body& b : s.bodies) has_flex = has_flex || b.flex.has_value();
    for (const Joint& j : s.joints) has_prescribed = has_prescribed || j.prescribed.has_value();
    flexible += has_flex;
    prescribed += has_prescribed;
    (engine.solver() == KaneSolver::OrderN ? order_n : composite) += 1;
    if (name == "chain5") chain5_order_n = engine.solver() == KaneSolver::OrderN;
    if (name == "spear1_case1") spear1_composite = engine.solver() == KaneSolver::Composite;
    for (int trial = 0; trial < 4; ++trial) {
      const std::vector<double> x = packed(e, near_initial_state(s, g));
      const double t = trial == 0 ? 0.0 : s.run.duration * U(g);
      std::vector<double> xdot(x.size());
      e.rhs(t, x.data(), xdot.data());
      const Engine::LinearSystem ls = e.linear_system(t, x.data());
      INFO(name << " (" << kane::kane_solver_name(engine.solver()) << "), trial " << trial
                << ", t = " << t << ": " << ls.what);

      // (1) Shape and symmetry.
      const Eigen::Index n = ls.A.rows();
      REQUIRE(n > 0);
      REQUIRE(ls.A.cols() == n);
      REQUIRE(ls.b.size() == n);
      REQUIRE(ls.speed_index.size() == static_cast<std::size_t>(n));  // no multipliers in Kane
      REQUIRE(n == engine.speed_size());
      for (int i : ls.speed_index) {
        REQUIRE(i >= 0);
        REQUIRE(i < e.state_size());
      }
      const double asym = (ls.A - ls.A.transpose()).cwiseAbs().maxCoeff();
      INFO("max |A - A^T| = " << asym << ", max |A| = " << ls.A.cwiseAbs().maxCoeff());
      CHECK(asym <= 1e-12 * ls.A.cwiseAbs().maxCoeff());

      // (2) Its solution is rhs()'s u'.
      const double scale = max_abs(xdot), err = solution_error(ls, xdot);
      INFO("max |z - xdot[speed_index]| = " << err << ", max |xdot| = " << scale);
      CHECK(scale > 0);
      CHECK(err <= 1e-10 * scale);

      // (3) A name.
      CHECK_FALSE(ls.what.empty());
      // rhs() after the diagnostic gives the same xdot, bit for bit (shared workspace).
      std::vector<double> again(x.size());
      e.rhs(t, x.data(), again.data());
      CHECK(again == xdot);
    }
  }
  // The scenes cover what the brief asks for: flexible bodies, prescribed joints, both solvers.
  CHECK(flexible > 0);
  CHECK(prescribed > 0);
  CHECK(order_n > 0);
  CHECK(composite > 0);
  CHECK(chain5_order_n);
  CHECK(spear1_composite);
}

TEST_CASE("kane linear_system: a wrong mass matrix is caught (the comparison can fail)") {
  // test_inertia_scale = 1.01 changes every inertia of one engine: its A z = b must then differ
  // from the unscaled engine's rhs() far beyond the tolerance above, on both solvers' scenes.
  EngineOptions scaled;
  scaled.test_inertia_scale = 1.01;
  std::mt19937 g(11);
  for (const char* scene : {"chain5", "spear1_case1", "pointing_flex"}) {
    const System s = read_scene(crossdyn::test::scene_path(scene));
    KaneEngine good(s, {}), wrong(s, scaled);
    const std::vector<double> x = packed(good, near_initial_state(s, g));
    std::vector<double> xdot(x.size());
    good.rhs(0.0, x.data(), xdot.data());
    const double err = solution_error(wrong.linear_system(0.0, x.data()), xdot);
    const double err_good = solution_error(good.linear_system(0.0, x.data()), xdot);
    INFO(scene << ": max |z - xdot| with inertias scaled by 1.01: " << err << "; unscaled "
               << err_good << "; max |xdot| = " << max_abs(xdot));
    CHECK(err > 1e-6 * max_abs(xdot));
    CHECK(err_good <= 1e-10 * max_abs(xdot));
  }
}
