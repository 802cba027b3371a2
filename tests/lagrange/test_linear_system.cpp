// The Lagrange engine's linear system (Engine::linear_system, core/engine.hpp): on every committed
// scene, at states near the initial one, the Boltzmann-Hamel system M pi'' = f it writes out is
// square and symmetric, and solving it independently (Eigen's pivoting LU, not the engine's
// Cholesky) gives the speed derivatives rhs() returns at the same (t, x).
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "core/engine.hpp"
#include "core/scene/scene.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "tests/support/linalg.hpp"
#include "tests/support/paths.hpp"

using namespace crossdyn;
using crossdyn::lagrange::LagrangeEngine;

namespace {

// R exp([phi x]) for phi uniform in the ball of radius `angle` per component.
Eigen::Quaterniond turned(const Eigen::Quaterniond& q, double angle, std::mt19937& g) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d phi(angle * u(g), angle * u(g), angle * u(g));
  const double a = phi.norm();
  if (a == 0.0) return q;
  return (q * Eigen::Quaterniond(Eigen::AngleAxisd(a, phi / a))).normalized();
}

// A state near the scene's initial one: attitudes turned by up to 0.3 rad per axis, rates changed
// by up to 0.3 (rad/s, m/s), joint angles by up to 0.3 rad, modal coordinates and rates set to
// up to 0.01 (prescribed joints take theirs from the profile: pack() ignores the values here).
TreeState near_initial(const System& s, std::mt19937& g) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&](double scale) -> Eigen::Vector3d {
    return Eigen::Vector3d(u(g), u(g), u(g)) * scale;
  };
  TreeState st = TreeState::initial(s);
  st.p_NoBo_N += vec(1.0);
  st.q_NB = turned(st.q_NB, 0.3, g);
  st.v_NBo_N += vec(0.3);
  st.w_NB_B += vec(0.3);
  for (TreeState::JointState& j : st.joints) {
    j.angle += 0.3 * u(g);
    j.rate += 0.3 * u(g);
    j.q_J = turned(j.q_J, 0.3, g);
    j.w_PC_C += vec(0.3);
  }
  for (std::size_t b = 0; b < st.eta.size(); ++b)
    for (Eigen::Index k = 0; k < st.eta[b].size(); ++k) {
      st.eta[b](k) = 0.01 * u(g);
      st.eta_rate[b](k) = 0.01 * u(g);
    }
  return st;
}

std::string stem(const std::string& path) { return std::filesystem::path(path).stem().string(); }

}  // namespace

TEST_CASE(
    "lagrange linear_system: A is square and symmetric, and A z = b solved by LU gives rhs()'s "
    "speed derivatives, on every committed scene",
    "[lagrange][linear_system]") {
  std::mt19937 g(71);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::set<std::string> seen, prescribed_seen, flexible_seen;
  int non_default_charts = 0;
  for (const std::string& path : test::committed_scenes()) {
    const System s = read_scene(path);
    const std::string name = stem(path);
    LagrangeEngine e(s, {});
    const int nf = e.dof();
    int speeds = 0;
    for (const Joint& j : s.joints) speeds += j.dof();
    for (const Body& b : s.bodies)
      if (b.flex) speeds += b.flex->modes();
    REQUIRE(e.state_size() == 2 * speeds);
    for (int trial = 0; trial < 6; ++trial) {
      TreeState st = near_initial(s, g);
      // The last trial with a free base: its attitude pitched by 80 deg, past kPackDeg, so pack()
      // puts the base's angles in another chart than the default (the system is the one of the
      // chart x is in).
      const bool pitched = trial == 5 && s.base_is_free();
      if (pitched)
        st.q_NB = st.q_NB * Eigen::Quaterniond(Eigen::AngleAxisd(80.0 * std::numbers::pi / 180.0,
                                                                 Eigen::Vector3d::UnitY()));
      std::vector<double> x(static_cast<std::size_t>(e.state_size()));
      std::vector<double> xdot(x.size());
      e.pack(st, x.data());
      for (int k = 0; k < e.euler_sets(); ++k)
        if (e.chart(k) != lagrange::kDefaultChart) ++non_default_charts;
      const double t = u(g) * s.run.duration;
      e.rhs(t, x.data(), xdot.data());
      const Engine::LinearSystem ls = e.linear_system(t, x.data());
      INFO("scene " << name << ", trial " << trial << ", t = " << t << " s: " << ls.what);
      // (3) The system is named.
      CHECK_FALSE(ls.what.empty());
      // (1) Square, sizes agree with b and speed_index, symmetric.
      REQUIRE(ls.A.rows() > 0);
      REQUIRE(ls.A.rows() == ls.A.cols());
      REQUIRE(ls.b.size() == ls.A.rows());
      // No multipliers here: one unknown per free speed, counted from the System (Joint::dof():
      // free 6, revolute 1, spherical 3, fixed and prescribed 0; plus every mode of a flexible
      // body), each the derivative of a distinct index in x's second half.
      REQUIRE(ls.speed_index.size() == static_cast<std::size_t>(ls.A.rows()));
      REQUIRE(ls.speed_index.size() == static_cast<std::size_t>(speeds));
      std::vector<int> sorted = ls.speed_index;
      std::sort(sorted.begin(), sorted.end());
      CHECK(std::adjacent_find(sorted.begin(), sorted.end()) == sorted.end());
      for (int i : ls.speed_index) {
        INFO("speed_index entry " << i);
        REQUIRE(i >= nf);
        REQUIRE(i < 2 * nf);
      }
      const double a_max = ls.A.cwiseAbs().maxCoeff();
      const double asym = (ls.A - ls.A.transpose()).cwiseAbs().maxCoeff();
      INFO("max |A - A^T| = " << asym << ", max |A| = " << a_max);
      CHECK(asym <= 1e-12 * a_max);
      // (2) A z = b, solved independently of the engine, reproduces rhs()'s speed derivatives.
      const Eigen::VectorXd z = test::full_piv_lu_solve(ls.A, ls.b);
      double xdot_max = 0.0;
      for (double v : xdot) xdot_max = std::max(xdot_max, std::abs(v));
      double err = 0.0;
      std::size_t worst = 0;
      for (std::size_t i = 0; i < ls.speed_index.size(); ++i) {
        const double d = std::abs(z(static_cast<Eigen::Index>(i)) -
                                  xdot[static_cast<std::size_t>(ls.speed_index[i])]);
        if (d > err) {
          err = d;
          worst = i;
        }
      }
      INFO("max |z - xdot[speed_index]| = "
           << err << " at " << e.state_label(ls.speed_index[worst]) << ", max |xdot| = "
           << xdot_max);
      CHECK(err <= 1e-10 * xdot_max);
      seen.insert(name);
      if (std::any_of(s.joints.begin(), s.joints.end(),
                      [](const Joint& j) { return j.prescribed.has_value(); }))
        prescribed_seen.insert(name);
      if (std::any_of(s.bodies.begin(), s.bodies.end(),
                      [](const Body& b) { return b.flex.has_value(); }))
        flexible_seen.insert(name);
    }
  }
  // The scenes the check must cover: flexible, prescribed (inside the tree and as the base), a
  // chain of spherical joints, SPEAR-1; and a state in a non-default chart.
  for (const char* name :
       {"spear1_case1", "chain5", "pointing_flex", "scan_platform", "spinup_beam"}) {
    INFO("scene " << name);
    CHECK(seen.count(name) == 1);
  }
  CHECK(prescribed_seen.count("scan_platform") == 1);
  CHECK(prescribed_seen.count("spinup_beam") == 1);
  CHECK(flexible_seen.count("pointing_flex") == 1);
  CHECK(non_default_charts > 0);
}
