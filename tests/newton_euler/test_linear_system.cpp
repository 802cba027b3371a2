// Engine::linear_system of the Newton-Euler engine: the KKT system [M J^T; J 0] z = [f; gamma_s]
// written out dense (core/engine.hpp). At states near each committed scene's initial one (and
// off the constraint manifold, so that Baumgarte's terms are not zero), solved here with Eigen's
// own pivoting LU, it must give the accelerations rhs() returns: a check of the dense system
// against the engine's linear-time factorisation (tree_kkt.hpp), which never forms it.
#include "formulations/newton_euler/newton_euler.hpp"

#include "core/scene/scene.hpp"
#include "tests/newton_euler/ne_systems.hpp"
#include "tests/support/linalg.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <string>
#include <vector>

using namespace crossdyn;
using namespace crossdyn::test::ne;

namespace {

// Constraint rows per joint, from the joint types alone: a joint between bodies removes the six
// relative motions less its own degrees of freedom (joint_constraints.hpp: spherical 3, revolute
// 5, prescribed revolute 6, fixed 6); the free base none.
int expected_constraint_rows(const System& s) {
  int rows = 0;
  for (const Joint& j : s.joints)
    if (j.type != JointType::Free) rows += 6 - j.dof();
  return rows;
}

// A state label is a velocity-level one (newton_euler.hpp: ".vx" ... ".wz", "<mode>_rate").
bool is_speed_label(const std::string& l) {
  for (const char* s : {".vx", ".vy", ".vz", ".wx", ".wy", ".wz", "_rate"}) {
    const std::string suffix(s);
    if (l.size() > suffix.size() && l.compare(l.size() - suffix.size(), suffix.size(), suffix) == 0)
      return true;
  }
  return false;
}

}  // namespace

TEST_CASE("newton-euler: linear_system is a symmetric KKT matrix whose solution is rhs()'s "
          "accelerations, on every committed scene, with projection and baumgarte",
          "[newton_euler][engine][linear_system]") {
  std::vector<System> systems;
  for (const std::string& path : test::committed_scenes()) systems.push_back(read_scene(path));
  systems.push_back(flexible_tree());  // every joint type at nodes of flexible bodies
  // The scenes the brief names must be among them (a renamed file would silently drop one).
  std::set<std::string> names;
  bool flexible = false, prescribed_joint = false, prescribed_base = false;
  for (const System& s : systems) {
    names.insert(s.name);
    for (const Body& b : s.bodies) flexible = flexible || (b.flex && b.flex->modes() > 0);
    for (std::size_t j = 1; j < s.joints.size(); ++j)
      prescribed_joint = prescribed_joint || s.joints[j].prescribed.has_value();
    prescribed_base = prescribed_base || !s.base_is_free();
  }
  for (const char* n : {"chain5", "spear1_case1", "scan_platform", "spinup_beam", "pointing_flex"})
    CHECK(names.count(n) == 1);
  CHECK(flexible);
  CHECK(prescribed_joint);
  CHECK(prescribed_base);

  std::mt19937 rng(41);
  std::uniform_real_distribution<double> time(0.0, 3.0);
  // Off the manifold by ~1e-4 in every state entry: g and g' are then ~1e-4 and Baumgarte's
  // alpha g' + beta g (alpha 10 /s, beta 25 /s^2) is far above round-off in gamma_s.
  std::normal_distribution<double> noise(0.0, 1e-4);
  for (const System& s : systems) {
    for (auto stab : {ConstraintStabilization::Projection, ConstraintStabilization::Baumgarte}) {
      EngineOptions o;
      o.stabilization = stab;
      auto e = make_newton_euler_engine(s, o);
      const int nx = e->state_size();
      // The velocity-level state entries, by label (the engine's layout, newton_euler.hpp).
      std::vector<int> speeds;
      for (int i = 0; i < nx; ++i)
        if (is_speed_label(e->state_label(i))) speeds.push_back(i);
      for (int trial = 0; trial < 3; ++trial) {
        TreeState ts = TreeState::initial(s);
        deform(s, ts, rng, 0.01, 0.03);  // modal coordinates (m per unit) and rates near 0
        std::vector<double> x(static_cast<std::size_t>(nx)), xdot(x.size()), xdot2(x.size());
        e->pack(ts, x.data());
        for (double& v : x) v += noise(rng);
        const double t = time(rng);
        INFO(s.name << ", " << o.stabilization << ", trial " << trial << ", t = " << t);

        e->rhs(t, x.data(), xdot.data());
        const Engine::LinearSystem ls = e->linear_system(t, x.data());
        // (3) named.
        CHECK(!ls.what.empty());
        // (1) square, sizes consistent: every velocity-level state entry once, then one
        // multiplier per constraint row.
        const auto n = ls.A.rows();
        REQUIRE(n > 0);
        REQUIRE(ls.A.cols() == n);
        REQUIRE(ls.b.size() == n);
        std::vector<int> index = ls.speed_index;
        std::sort(index.begin(), index.end());
        CHECK(index == speeds);
        CHECK(n - static_cast<Eigen::Index>(ls.speed_index.size()) == expected_constraint_rows(s));
        REQUIRE(ls.A.allFinite());
        REQUIRE(ls.b.allFinite());
        // Symmetric to 1e-12 of its largest entry.
        const double a_max = ls.A.cwiseAbs().maxCoeff();
        CHECK((ls.A - ls.A.transpose()).cwiseAbs().maxCoeff() <= 1e-12 * a_max);
        // (2) A z = b, solved by a pivoting LU (A is indefinite: M > 0, its Schur complement
        // -J M^-1 J^T < 0), gives rhs()'s accelerations. Both solves are backward stable and
        // these matrices' condition numbers are at most ~4e5 (2-norm; entries in kg, kg m^2 and
        // dimensionless rows): the differences seen are below 1e-13 of max |xdot|, and a wrong
        // gamma_s (Baumgarte's terms left out) gives 1e-5 or more.
        const Eigen::VectorXd z = test::full_piv_lu_solve(ls.A, ls.b);
        REQUIRE(z.allFinite());
        double x_max = 0;
        for (double v : xdot) x_max = std::max(x_max, std::abs(v));
        double err = 0;
        for (std::size_t i = 0; i < ls.speed_index.size(); ++i)
          err = std::max(err, std::abs(z(static_cast<Eigen::Index>(i)) -
                                       xdot[static_cast<std::size_t>(ls.speed_index[i])]));
        INFO("max |z - xdot| = " << err << ", max |xdot| = " << x_max);
        CHECK(err <= 1e-10 * x_max);
        // The residual of the LU solution is round-off: A and b are one consistent system.
        CHECK((ls.A * z - ls.b).cwiseAbs().maxCoeff() <=
              1e-12 * (a_max * z.cwiseAbs().maxCoeff() + ls.b.cwiseAbs().maxCoeff()));
        // linear_system leaves the engine as it was: rhs() after it is bit-identical.
        e->rhs(t, x.data(), xdot2.data());
        CHECK(xdot2 == xdot);
      }
    }
  }
}
