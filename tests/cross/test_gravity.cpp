// Issue 28: gravity, the gravity gradient and the orbit (docs/environment.md). Each engine evaluates
// the loads itself; here they must agree with each other at random states on scenes given each
// environment, match closed forms derived here (not the engines' formulas), conserve what the
// environment conserves, and a gravity-gradient torque of the wrong sign in one engine must be
// caught by `compare`.
#include <catch2/catch.hpp>

#include "core/orbit.hpp"
#include "core/output_layout.hpp"
#include "core/scene/scene.hpp"
#include "harness/compare.hpp"
#include "harness/scene_geometry.hpp"
#include "tests/cross/common.hpp"
#include "tests/support/paths.hpp"

#include <cmath>
#include <map>
#include <numbers>

using namespace crossdyn;
using namespace crossdyn::test;

namespace {

const std::vector<std::string> kEngines{"kane", "lagrange", "newton-euler"};
constexpr double kMuEarth = 3.986004418e14;

Environment uniform(const Eigen::Vector3d& g) {
  Environment e;
  e.kind = Environment::Kind::Uniform;
  e.g_N = g;
  return e;
}

Environment orbit(double radius, double inclination = 0.7, double raan = 0.4, double u0 = 1.1) {
  Environment e;
  e.kind = Environment::Kind::Orbit;
  e.mu = kMuEarth;
  e.radius = radius;
  e.inclination = inclination;
  e.raan = raan;
  e.latitude0 = u0;
  return e;
}

// The largest difference of two engines' accelerations, relative to the largest of them (per
// kind: angular, linear, joint, modal).
double accel_difference(const TreeAccel& a, const TreeAccel& b) {
  double scale = 0, diff = 0;
  auto feed = [&](double x, double y) {
    scale = std::max({scale, std::abs(x), std::abs(y)});
    diff = std::max(diff, std::isfinite(x) && std::isfinite(y) ? std::abs(x - y) : INFINITY);
  };
  for (std::size_t i = 0; i < a.wdot_NB_B.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      feed(a.wdot_NB_B[i](k), b.wdot_NB_B[i](k));
      feed(a.a_NBo_N[i](k), b.a_NBo_N[i](k));
    }
  for (std::size_t j = 0; j < a.angle_ddot.size(); ++j) {
    feed(a.angle_ddot[j], b.angle_ddot[j]);
    feed(a.angle2_ddot[j], b.angle2_ddot[j]);
    for (int k = 0; k < 3; ++k) feed(a.wdot_PC_C[j](k), b.wdot_PC_C[j](k));
  }
  for (std::size_t i = 0; i < a.eta_ddot.size(); ++i)
    for (int k = 0; k < a.eta_ddot[i].size(); ++k) feed(a.eta_ddot[i](k), b.eta_ddot[i](k));
  return diff / std::max(scale, 1e-300);
}

// A run's column by name.
std::vector<double> column(const RunResult& r, const std::string& name) {
  const int c = r.column(name);
  REQUIRE(c >= 0);
  std::vector<double> v;
  for (std::size_t i = 0; i < r.rows(); ++i) v.push_back(r.at(i, static_cast<std::size_t>(c)));
  return v;
}

// The times where x crosses zero, each from the cubic through the four samples around it
// (Lagrange interpolation, then Newton's method on the cubic).
std::vector<double> zero_crossings(const std::vector<double>& t, const std::vector<double>& x) {
  std::vector<double> z;
  for (std::size_t i = 1; i + 2 < x.size(); ++i) {
    if (!(x[i] == 0 || (x[i] < 0) != (x[i + 1] < 0))) continue;
    const double* T = &t[i - 1];
    const double* X = &x[i - 1];
    auto p = [&](double s) {
      double v = 0;
      for (int a = 0; a < 4; ++a) {
        double l = 1;
        for (int b = 0; b < 4; ++b)
          if (b != a) l *= (s - T[b]) / (T[a] - T[b]);
        v += X[a] * l;
      }
      return v;
    };
    double s = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i]);
    for (int k = 0; k < 30; ++k) {
      const double h = 1e-6 * (t[i + 1] - t[i]);
      const double d = (p(s + h) - p(s - h)) / (2 * h);
      const double step = p(s) / d;
      s -= step;
      if (std::abs(step) < 1e-14 * std::abs(s)) break;
    }
    z.push_back(s);
  }
  return z;
}

// The angular frequency of x(t) from its zero crossings (the mean half period over them).
double frequency_from_crossings(const std::vector<double>& t, const std::vector<double>& x) {
  const std::vector<double> z = zero_crossings(t, x);
  REQUIRE(z.size() >= 3);
  const double half_period = (z.back() - z.front()) / static_cast<double>(z.size() - 1);
  return std::numbers::pi / half_period;
}

// The composite inertia about the system CM at the initial state, from the bodies' CM positions
// (the scene picture's placement, harness/scene_geometry.hpp) and their inertias, in N.
Eigen::Matrix3d composite_inertia_N(const System& s) {
  const harness::geometry::Configuration x = harness::geometry::initial_configuration(s);
  double m = 0;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t b = 0; b < s.bodies.size(); ++b) {
    m += s.bodies[b].mass;
    c += s.bodies[b].mass * x.bodies[b].p_NoBo_N;
  }
  c /= m;
  Eigen::Matrix3d I = Eigen::Matrix3d::Zero();
  for (std::size_t b = 0; b < s.bodies.size(); ++b) {
    const Eigen::Matrix3d& R = x.bodies[b].R_NB;
    const Eigen::Vector3d d = x.bodies[b].p_NoBo_N - c;
    I += R * s.bodies[b].I_BBo_B * R.transpose() +
         s.bodies[b].mass * (d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose());
  }
  return I;
}

}  // namespace

TEST_CASE("gravity: at random states every engine's accelerations and outputs (E, J, M, joint loads) "
          "agree with Kane's on committed scenes put under uniform gravity and on an orbit") {
  double worst_overall = 0;
  for (const char* name : {"hub_two_panels", "chain5", "spear1_case1_spherical", "scan_platform",
                                  "gimbal_payload", "telescoping_boom", "pointing_flex", "hub_nodal_panel",
                                  "spinup_beam", "iftomm_pendulum", "gg_libration", "boom_on_orbit"}) {
    for (int env = 0; env < 2; ++env) {
      System system = read_scene(scene_path(name));
      system.zero_linear_momentum = false;
      // Gravity that matters against the scenes' own loads: 9.81 m/s^2, and an orbit whose mean
      // motion is 0.3 rad/s (mu = n^2 R^3: a fictitious central body, so that the gravity-gradient
      // loads are of the size of the scenes' inertial loads rather than 1e-6 of them).
      system.environment = env == 0 ? uniform({0.3, -9.81, 1.2}) : orbit(7000e3);
      if (env == 1) system.environment.mu = 0.09 * std::pow(7000e3, 3);
      const OutputLayout layout(system);
      std::map<std::string, std::unique_ptr<Engine>> engines;
      for (const std::string& e : kEngines) engines[e] = make_engine(e, system);
      std::mt19937 g(28);
      double worst = 0;
      std::string where;
      for (int trial = 0; trial < 5; ++trial) {
        const double t = 0.37 * trial + (env == 1 ? 1000.0 * trial : 0.0);
        const TreeState s = random_tree_state(system, g, t);
        std::map<std::string, EngineAt> at;
        for (const std::string& e : kEngines) at[e] = evaluate(*engines[e], s, t);
        for (const char* e : {"lagrange", "newton-euler"}) {
          const double d = accel_difference(at[e].accel, at["kane"].accel);
          if (d > worst) {
            worst = d;
            where = std::string(e) + " accelerations, trial " + std::to_string(trial);
          }
          // E, J and the other new columns against their own scales.
          for (std::size_t c = 0; c < layout.pinned_size(); ++c) {
            const Column& col = layout.columns()[c];
            const bool energy = col.kind == ColumnKind::EnergyE || col.kind == ColumnKind::Jacobi;
            const std::string grp = new_column_scale_group(col);
            if (!energy && grp.empty()) continue;
            double sc = energy ? 1e-300 : 0.0;
            for (std::size_t k = 0; k < layout.pinned_size(); ++k) {
              const Column& other = layout.columns()[k];
              const bool same = energy ? other.kind == ColumnKind::EnergyE || other.kind == ColumnKind::Jacobi
                                       : new_column_scale_group(other) == grp;
              if (same)
                for (const std::string& x : kEngines) sc = std::max(sc, std::abs(at[x].row[k]));
            }
            if (grp == "position") sc = std::max(sc, 1.0);
            if (sc == 0) continue;
            const double v = at[e].row[c], ref = at["kane"].row[c];
            const double d2 = std::isfinite(v) && std::isfinite(ref) ? std::abs(v - ref) / sc : INFINITY;
            if (d2 > worst) {
              worst = d2;
              where = std::string(e) + " " + col.name + ", trial " + std::to_string(trial);
            }
          }
        }
      }
      INFO(name << (env == 0 ? " under uniform gravity" : " on an orbit") << ": worst " << worst << " ("
                << where << ")");
      WARN(name << (env == 0 ? " under uniform gravity" : " on an orbit") << ": worst relative difference "
                << worst << " (" << where << ")");
      CHECK(worst <= 1e-9);
      worst_overall = std::max(worst_overall, worst);
    }
  }
  CHECK(worst_overall > 0);  // independent engines differ in rounding somewhere
}

TEST_CASE("gravity: a free spacecraft in uniform gravity falls as a whole: its CM accelerates at g and "
          "nothing inside it changes") {
  for (const char* name : {"hub_two_panels", "pointing_flex", "chain5"}) {
    System plain = read_scene(scene_path(name));
    plain.zero_linear_momentum = false;
    System heavy = plain;
    const Eigen::Vector3d g(1.0, -9.81, 0.5);
    heavy.environment = uniform(g);
    std::mt19937 rng(5);
    for (const std::string& e : kEngines) {
      auto a = make_engine(e, plain);
      auto b = make_engine(e, heavy);
      for (int trial = 0; trial < 3; ++trial) {
        const TreeState s = random_tree_state(plain, rng, 0.2 * trial);
        const EngineAt x = evaluate(*a, s, 0.2 * trial), y = evaluate(*b, s, 0.2 * trial);
        INFO(name << " " << e);
        for (std::size_t i = 0; i < x.accel.a_NBo_N.size(); ++i) {
          CHECK((y.accel.a_NBo_N[i] - x.accel.a_NBo_N[i] - g).norm() < 1e-11 * (1 + x.accel.a_NBo_N[i].norm()));
          CHECK((y.accel.wdot_NB_B[i] - x.accel.wdot_NB_B[i]).norm() < 1e-11 * (1 + x.accel.wdot_NB_B[i].norm()));
        }
        for (std::size_t j = 0; j < x.accel.angle_ddot.size(); ++j)
          CHECK(std::abs(y.accel.angle_ddot[j] - x.accel.angle_ddot[j]) < 1e-11 * (1 + std::abs(x.accel.angle_ddot[j])));
        for (std::size_t k = 0; k < x.accel.eta_ddot.size(); ++k)
          CHECK((y.accel.eta_ddot[k] - x.accel.eta_ddot[k]).norm() < 1e-11 * (1 + x.accel.eta_ddot[k].norm()));
      }
    }
  }
}

TEST_CASE("gravity: one rigid body on an orbit turns as Euler's equations with the gravity-gradient "
          "torque 3 n^2 zhat x (I zhat) say, at random attitudes, rates and times") {
  System s = read_scene(scene_path("gg_libration"));
  s.environment = orbit(6900e3, 1.2, 0.3, 2.0);
  s.bodies[0].I_BBo_B << 1200, 30, -20, 30, 1500, 10, -20, 10, 400;
  std::mt19937 g(9);
  for (const std::string& e : kEngines) {
    auto engine = make_engine(e, s);
    for (int trial = 0; trial < 10; ++trial) {
      TreeState x = random_tree_state(s, g, 0);
      const double t = 700.0 * trial;
      const EngineAt at = evaluate(*engine, x, t);
      // The test's own closed form: Hughes (2004) Sec. 8.1, Eq. (8.15), in body components.
      const OrbitFrame f = orbit_frame(s.environment, t);
      const Eigen::Matrix3d R = x.q_NB.toRotationMatrix();
      const Eigen::Vector3d c_B = R.transpose() * f.zenith_N;
      const Eigen::Matrix3d& I = s.bodies[0].I_BBo_B;
      const Eigen::Vector3d tau_B = 3 * f.n * f.n * c_B.cross(I * c_B);
      const Eigen::Vector3d w = x.w_NB_B;
      const Eigen::Vector3d wdot = I.ldlt().solve(tau_B - w.cross(I * w));
      INFO(e << " trial " << trial);
      CHECK((at.accel.wdot_NB_B[0] - wdot).norm() <= 1e-12 * wdot.norm());
      // The CM at the reference point O: no tidal force (the system CM at t = 0 is O).
    }
  }
}

TEST_CASE("gravity: gg_libration librates in pitch at n sqrt(3 (Ix - Iz) / Iy) in every engine, to 1e-8, "
          "and its Jacobi integral is constant") {
  const System s = read_scene(scene_path("gg_libration"));
  const double n = s.environment.mean_motion();
  const Eigen::Matrix3d& I = s.bodies[0].I_BBo_B;
  const double closed = n * std::sqrt(3 * (I(0, 0) - I(2, 2)) / I(1, 1));
  for (const std::string& e : kEngines) {
    const RunResult r = run_engine(e, s, "rkf78", 1e-12);
    REQUIRE_FALSE(r.failure);
    const double w = frequency_from_crossings(column(r, "t"), column(r, "sat.pitch"));
    const std::vector<double> J = column(r, "J");
    double drift = 0;
    for (double j : J) drift = std::max(drift, std::abs(j - J.front()));
    INFO(e << ": pitch frequency " << w << " against " << closed << " (relative " << (w - closed) / closed
           << "); J drift " << drift / std::abs(J.front()) << " relative");
    WARN(e << ": pitch frequency relative error " << (w - closed) / closed << ", J drift "
           << drift / std::abs(J.front()));
    CHECK(std::abs(w - closed) <= 1e-8 * closed);
    CHECK(drift <= 1e-10 * std::abs(J.front()));
    // Roll and yaw stay at rest (the pitch motion does not excite them at first order).
    for (const char* c : {"sat.roll", "sat.yaw"})
      for (double v : column(r, c)) CHECK(std::abs(v) < 1e-12);
  }
}

TEST_CASE("gravity: a hub with a long boom librates at the composite body's frequency, which the tidal "
          "forces on the bodies' CM offsets make 2.6 times what the torques alone would give") {
  System s = read_scene(scene_path("boom_on_orbit"));
  // Held rigid: the hinge made a fixed joint, so the whole is one rigid body of composite inertia.
  s.joints[1].type = JointType::Fixed;
  s.joints[1].stiffness = 0;
  const double n = s.environment.mean_motion();
  const Eigen::Matrix3d Ic = composite_inertia_N(s);
  // In the hub's axes (those of the orbit frame at zero pitch; not the orbit frame's own axes at
  // t = 0, in which the 1 mrad tilt moves the moments by 7e-7).
  const Eigen::Matrix3d R_NB = harness::geometry::initial_configuration(s).bodies[0].R_NB;
  const Eigen::Matrix3d I_O = R_NB.transpose() * Ic * R_NB;
  const double closed = n * std::sqrt(3 * (I_O(0, 0) - I_O(2, 2)) / I_O(1, 1));
  // The torques about each body's own CM alone: the bodies' own inertias summed, no m d^2.
  Eigen::Matrix3d I_own = Eigen::Matrix3d::Zero();
  for (const Body& b : s.bodies) I_own += b.I_BBo_B;
  const double torques_only = n * std::sqrt(3 * (I_own(0, 0) - I_own(2, 2)) / I_O(1, 1));
  CHECK(closed / torques_only > 2.5);
  s.run.duration = 9000;
  for (const std::string& e : kEngines) {
    const RunResult r = run_engine(e, s, "rkf78", 1e-12);
    REQUIRE_FALSE(r.failure);
    const double w = frequency_from_crossings(column(r, "t"), column(r, "hub.pitch"));
    INFO(e << ": " << w / n << " n against the composite body's " << closed / n << " n (torques alone "
           << torques_only / n << " n)");
    WARN(e << ": boom_on_orbit held rigid: pitch frequency relative error " << (w - closed) / closed);
    // The pitch equation Iy p'' = -3 n^2 (Ix - Iz) sin p cos p is a pendulum in 2p: a 1 mrad
    // amplitude lowers the frequency by (2 p0)^2 / 16 = 2.5e-7.
    CHECK(std::abs(w - closed * (1 - 2.5e-7)) <= 1e-8 * closed);
  }
}

TEST_CASE("gravity: the Jacobi integral of boom_on_orbit is constant to 1e-10 in every engine, and E "
          "is constant under uniform gravity (iftomm_pendulum)") {
  const System s = read_scene(scene_path("boom_on_orbit"));
  for (const std::string& e : kEngines) {
    const RunResult r = run_engine(e, s, "rkf78", 1e-12);
    REQUIRE_FALSE(r.failure);
    const std::vector<double> J = column(r, "J");
    double drift = 0;
    for (double j : J) drift = std::max(drift, std::abs(j - J.front()));
    INFO(e << ": J drift " << drift / std::abs(J.front()));
    CHECK(drift <= 1e-10 * std::abs(J.front()));
  }
  const System p = read_scene(scene_path("iftomm_pendulum"));
  for (const std::string& e : kEngines) {
    const RunResult r = run_engine(e, p, "rkf78", 1e-12);
    REQUIRE_FALSE(r.failure);
    const std::vector<double> E = column(r, "E");
    double drift = 0, scale = 0;
    for (double x : E) {
      drift = std::max(drift, std::abs(x - E.front()));
      scale = std::max(scale, std::abs(x));
    }
    INFO(e << ": E drift " << drift << " J of " << scale);
    CHECK(drift <= 1e-10 * std::max(scale, 9.81));
    // The bob's height by energy conservation: m g y + (m L^2 + I) w^2 / 2 = 0 (L = 1 m).
    const double m = p.bodies[1].mass, I_pivot = m + p.bodies[1].I_BBo_B(2, 2);
    const std::vector<double> y = column(r, "bob.y"), rate = column(r, "hinge.rate");
    double worst = 0;
    for (std::size_t i = 0; i < y.size(); ++i)
      worst = std::max(worst, std::abs(y[i] + I_pivot * rate[i] * rate[i] / (2 * m * 9.81)));
    CHECK(worst < 1e-11);
  }
}

TEST_CASE("gravity: a gravity-gradient torque of the wrong sign in one engine is caught by compare") {
  const System s = read_scene(scene_path("gg_libration"));
  harness::CompareOptions o;
  o.engines.push_back({"kane", "kane", {}});
  o.engines.push_back({"lagrange", "lagrange", {}});
  EngineOptions wrong;
  wrong.test_gravity_gradient_sign = -1;
  o.engines.push_back({"lagrange*gg", "lagrange", wrong});
  const harness::SceneComparison c = harness::compare_scene(s, o);
  int failed_wrong = 0, failed_right = 0;
  for (const harness::Check& k : c.checks) {
    const bool involves_wrong = k.a == "lagrange*gg" || k.b == "lagrange*gg";
    if (k.status == harness::CheckStatus::Fail) (involves_wrong ? failed_wrong : failed_right)++;
  }
  INFO(harness::format_comparison(c, true));
  CHECK(failed_right == 0);
  CHECK(failed_wrong > 0);
  // Its own Jacobi integral catches it too (the flipped torque is not the potential's gradient).
  bool j_failed = false;
  for (const harness::Check& k : c.checks)
    if (k.quantity == "J.drift" && k.a == "lagrange*gg") j_failed = k.status == harness::CheckStatus::Fail;
  CHECK(j_failed);
}
