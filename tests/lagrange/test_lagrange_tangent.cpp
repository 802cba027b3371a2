// The Lagrange engine's exact linearisation (issue 27; tangent.cpp, core/engine.hpp
// accelerations_tangent): on random states and tangents of rigid and flexible trees (revolute,
// spherical, universal, prismatic and fixed joints, springs, dampers, motors, body torques in both
// frames, with and without the zero-linear-momentum rule), the variation da against central differences of
// accelerations(pack(s +- h ds)) (the same right perturbations), to the difference's accuracy, and
// against a Richardson extrapolation of them (Richardson 1911; three levels, error O(h^6)), to
// ~1e-11 relative, which only an exact derivative meets; a against accelerations(); linearity in
// ds; Euler's equations' Jacobian for a free rigid body in closed form; an InputError, with nothing
// written, for a malformed tangent. Every system is covered: rigid and flexible bodies (with
// geometric stiffening), uniform gravity, the orbit's gravity gradient, a prescribed joint and a
// prescribed base are among the tested systems.
//
// output_row_tangent (output_tangent.cpp) and rhs_tangent (tangent.cpp) on the same systems: drow
// against Richardson differences of output_row(pack(s +- h ds)), per column kind (ColumnKind),
// row against output_row() exactly, linearity in ds; dxdot against Richardson differences of
// rhs(x +- h dx) for x = pack(s) and for x moved off it at random (any x is the engine's: Euler
// angles and rates, no constraint), xdot against rhs() exactly, and the rate rows of dxdot
// against accelerations_tangent() for the exact variation of pack().
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "tests/support/tree_accel.hpp"
#include "core/errors.hpp"
#include "core/output_layout.hpp"
#include "core/rotation.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "tests/lagrange/flex_scenes.hpp"
#include "tests/lagrange/scenes.hpp"

using namespace crossdyn;
using crossdyn::lagrange::LagrangeEngine;

namespace {

Joint one_axis_joint(JointType type, const std::string& name, int parent, int child,
                     const Eigen::Vector3d& p_PoJ_P, const Eigen::Vector3d& p_CoJ_C,
                     const Eigen::Vector3d& axis_P) {
  Joint j;
  j.name = name;
  j.type = type;
  j.parent = parent;
  j.child = child;
  j.p_PoJ_P = p_PoJ_P;
  j.p_CoJ_C = p_CoJ_C;
  j.axis_P = axis_P.normalized();
  return j;
}

// A hub with a slider (prismatic, spring, damper, motor) and a gimbaled payload (universal,
// springs on both axes, an orientation offset), and a revolute arm on the payload.
System slider_gimbal(bool zero_linear_momentum) {
  System s;
  s.name = "slider_gimbal";
  Body hub = test::make_body("hub", 100, {40, 50, 60});
  hub.I_BBo_B(0, 1) = hub.I_BBo_B(1, 0) = 2.0;
  s.bodies = {hub, test::make_body("slider", 5, {0.5, 0.6, 0.7}),
              test::make_body("payload", 4, {0.3, 0.5, 0.6}), test::make_body("arm", 1, {0.1, 0.2, 0.2})};
  s.joints = {test::free_joint(0, {0.05, -0.03, 0.6})};
  Joint p = one_axis_joint(JointType::Prismatic, "slide", 0, 1, {0.8, 0.1, 0.2}, {-0.3, 0.0, 0.05},
                           {1.0, 0.2, 0.1});
  p.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(0, 1, 1).normalized()));
  p.stiffness = 30.0;
  p.neutral_angle = 0.05;
  p.damping = 2.0;
  p.motor_revolute.times = {0.0};
  p.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(0.7)};
  Joint u = one_axis_joint(JointType::Universal, "gimbal", 0, 2, {0.5, 0.3, 1.0}, {0.1, 0.0, -0.6},
                           {1, 0, 0.1});
  u.axis2_P = Eigen::Vector3d(0.3, 1, 0.2).normalized();
  u.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, -1, 2).normalized()));
  u.stiffness = 1.5;
  u.neutral_angle = 0.2;
  u.stiffness2 = 0.8;
  u.neutral_angle2 = -0.1;
  Joint r = one_axis_joint(JointType::Revolute, "elbow", 2, 3, {0.2, 0.1, 0.0}, {-0.4, 0.0, 0.0},
                           {0.1, 0.3, 1.0});
  r.stiffness = 0.6;
  r.damping = 0.05;
  s.joints.push_back(p);
  s.joints.push_back(u);
  s.joints.push_back(r);
  s.zero_linear_momentum = zero_linear_momentum;
  return s;
}

// One free rigid body with a full inertia, torque-free.
System one_body() {
  System s;
  s.name = "one_body";
  Body b = test::make_body("body", 7, {3, 4, 6});
  b.I_BBo_B(0, 1) = b.I_BBo_B(1, 0) = 0.3;
  b.I_BBo_B(0, 2) = b.I_BBo_B(2, 0) = -0.2;
  b.I_BBo_B(1, 2) = b.I_BBo_B(2, 1) = 0.4;
  s.bodies = {b};
  s.joints = {test::free_joint(0, {0.3, -0.5, 0.8})};
  return s;
}

Environment uniform_gravity() {
  Environment env;
  env.kind = Environment::Kind::Uniform;
  env.g_N = Eigen::Vector3d(0.3, -1.2, -9.81);
  return env;
}

// A circular orbit, mean motion n = 0.05 rad/s (fast, so the gravity gradient is not small next to
// the other loads), radius 7000 km, inclined.
Environment orbit() {
  Environment env;
  env.kind = Environment::Kind::Orbit;
  const double n = 0.05;
  env.radius = 7.0e6;
  env.mu = n * n * env.radius * env.radius * env.radius;
  env.inclination = 0.6;
  env.raan = 0.3;
  env.latitude0 = 0.2;
  return env;
}

System with_environment(System s, const Environment& env, const std::string& name) {
  s.environment = env;
  s.name = name;
  return s;
}

// spear1 with its first hinge spun up by a prescribed profile (docs/prescribed-motion.md).
System spear1_prescribed_hinge() {
  System s = test::spear1();
  s.name = "spear1_prescribed_hinge";
  PrescribedMotion p;
  p.rate = 1.0;
  p.ramp_time = 2.0;
  s.joints[1].prescribed = p;
  s.joints[1].rate0 = 0.0;
  return s;
}

// A prescribed base: a rotor turned about z through a point off its CM by a spin-up profile,
// carrying an arm on a spherical joint with a spring and a slider (prismatic).
System prescribed_base() {
  System s;
  s.name = "prescribed_base";
  s.bodies = {test::make_body("rotor", 20, {2, 3, 4}), test::make_body("arm", 2, {0.1, 0.4, 0.45}),
              test::make_body("slider", 1, {0.05, 0.06, 0.07})};
  Joint base = one_axis_joint(JointType::Revolute, "spin", -1, 0, {0.1, -0.2, 0.3}, {0.2, 0.1, 0.0},
                              {0.1, 0.2, 1.0});
  PrescribedMotion p;
  p.rate = 2.0;
  p.ramp_time = 1.5;
  base.prescribed = p;
  Joint arm;
  arm.name = "shoulder";
  arm.type = JointType::Spherical;
  arm.parent = 0;
  arm.child = 1;
  arm.p_PoJ_P = {0.6, 0.0, 0.1};
  arm.p_CoJ_C = {-0.5, 0.0, 0.0};
  arm.stiffness = 2.0;
  arm.damping = 0.1;
  Joint slide = one_axis_joint(JointType::Prismatic, "slide", 1, 2, {0.3, 0.0, 0.0},
                               {-0.1, 0.0, 0.0}, {1.0, 0.1, 0.0});
  slide.stiffness = 5.0;
  s.joints = {base, arm, slide};
  return s;
}

struct Case {
  std::string name;
  System system;
};

std::vector<Case> covered_systems() {
  System spear_spherical = test::spear1(-10, true);
  spear_spherical.zero_linear_momentum = false;
  return {{"spear1 (revolute)", test::spear1()},
          {"spear1 spherical, no momentum rule", spear_spherical},
          {"chain5 (spherical)", test::chain(5)},
          {"mixed_tree (loads, fixed joint, torques)", test::mixed_tree(true)},
          {"slider_gimbal (prismatic, universal)", slider_gimbal(true)},
          {"slider_gimbal, no momentum rule", slider_gimbal(false)},
          {"one free body", one_body()},
          {"mixed_tree, uniform gravity",
           with_environment(test::mixed_tree(true), uniform_gravity(), "mixed_tree_uniform")},
          {"slider_gimbal, orbit", with_environment(slider_gimbal(false), orbit(), "slider_gimbal_orbit")},
          {"chain5, orbit", with_environment(test::chain(5), orbit(), "chain5_orbit")},
          {"spear1, prescribed hinge", spear1_prescribed_hinge()},
          {"flex_tree (flexible, joints at nodes, loads)", test::flex_tree(true)},
          {"flex_tree, geometric stiffening", test::with_stiffening(test::flex_tree(true))},
          {"flex_tree, uniform gravity",
           with_environment(test::flex_tree(true), uniform_gravity(), "flex_tree_uniform")},
          {"flex_tree stiffened, orbit",
           with_environment(test::with_stiffening(test::flex_tree(true)), orbit(), "flex_tree_orbit")},
          {"prescribed base, uniform gravity",
           with_environment(prescribed_base(), uniform_gravity(), "prescribed_base_g")}};
}

Eigen::Vector3d random_vec(std::mt19937& g, double scale) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return Eigen::Vector3d(u(g), u(g), u(g)) * scale;
}

TreeTangent random_tangent(const System& system, std::mt19937& g) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  TreeTangent ds = TreeTangent::zero(system);
  ds.dp_NoBo_N = random_vec(g, 1.0);
  ds.dtheta_B = random_vec(g, 1.0);
  ds.dv_NBo_N = random_vec(g, 1.0);
  ds.dw_NB_B = random_vec(g, 1.0);
  for (std::size_t b = 0; b < ds.eta.size(); ++b)
    for (Eigen::Index k = 0; k < ds.eta[b].size(); ++k) {
      ds.eta[b](k) = 0.1 * u(g);
      ds.eta_rate[b](k) = u(g);
    }
  for (TreeTangent::JointTangent& j : ds.joints) {
    j.angle = u(g);
    j.rate = u(g);
    j.angle2 = u(g);
    j.rate2 = u(g);
    j.dtheta_J = random_vec(g, 1.0);
    j.w_PC_C = random_vec(g, 1.0);
  }
  return ds;
}

TreeTangent combine(const TreeTangent& a, double c, const TreeTangent& b) {  // a + c b
  TreeTangent r = a;
  r.dp_NoBo_N += c * b.dp_NoBo_N;
  r.dtheta_B += c * b.dtheta_B;
  r.dv_NBo_N += c * b.dv_NBo_N;
  r.dw_NB_B += c * b.dw_NB_B;
  for (std::size_t k = 0; k < r.eta.size(); ++k) {
    r.eta[k] += c * b.eta[k];
    r.eta_rate[k] += c * b.eta_rate[k];
  }
  for (std::size_t j = 0; j < r.joints.size(); ++j) {
    r.joints[j].angle += c * b.joints[j].angle;
    r.joints[j].rate += c * b.joints[j].rate;
    r.joints[j].angle2 += c * b.joints[j].angle2;
    r.joints[j].rate2 += c * b.joints[j].rate2;
    r.joints[j].dtheta_J += c * b.joints[j].dtheta_J;
    r.joints[j].w_PC_C += c * b.joints[j].w_PC_C;
  }
  return r;
}


using crossdyn::test::flat;

Eigen::VectorXd accel_at(LagrangeEngine& e, double t, const TreeState& s) {
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(s, x.data());
  TreeAccel a;
  e.accelerations(t, x.data(), a);
  return flat(a);
}

Eigen::VectorXd central(LagrangeEngine& e, double t, const TreeState& s, const TreeTangent& ds,
                        double h) {
  return (accel_at(e, t, moved_along(s, ds, h)) - accel_at(e, t, moved_along(s, ds, -h))) / (2 * h);
}

// Richardson's extrapolation of central differences at h, h/2, h/4: error O(h^6).
Eigen::VectorXd richardson(LagrangeEngine& e, double t, const TreeState& s, const TreeTangent& ds,
                           double h) {
  const Eigen::VectorXd d1 = central(e, t, s, ds, h), d2 = central(e, t, s, ds, h / 2),
                        d3 = central(e, t, s, ds, h / 4);
  const Eigen::VectorXd r1 = (4 * d2 - d1) / 3, r2 = (4 * d3 - d2) / 3;
  return (16 * r2 - r1) / 15;
}

double rel(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return (a - b).cwiseAbs().maxCoeff() / b.cwiseAbs().maxCoeff();
}

// ---- output_row_tangent and rhs_tangent ----

using VecFn = std::function<Eigen::VectorXd(double)>;  // e => f(x(e))

// Richardson's extrapolation of central differences of f at h, h/2, h/4 (error O(h^6)).
Eigen::VectorXd richardson_of(const VecFn& f, double h) {
  auto cd = [&](double k) { return Eigen::VectorXd((f(k) - f(-k)) / (2 * k)); };
  const Eigen::VectorXd d1 = cd(h), d2 = cd(h / 2), d3 = cd(h / 4);
  const Eigen::VectorXd r1 = (4 * d2 - d1) / 3, r2 = (4 * d3 - d2) / 3;
  return (16 * r2 - r1) / 15;
}

Eigen::VectorXd row_at(LagrangeEngine& e, double t, const TreeState& s) {
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(s, x.data());
  Eigen::VectorXd row(static_cast<Eigen::Index>(e.layout().size()));
  e.output_row(t, x.data(), row.data());
  return row;
}

const char* kind_name(ColumnKind k) {
  static const char* names[] = {"t", "w", "q", "joint coordinate", "joint rate", "joint torque",
                                "spherical w", "modal", "modal rate", "H", "E", "position", "CM",
                                "Hxyz", "joint force", "joint moment", "P", "Mxyz", "roll/pitch/yaw",
                                "wo", "J", "extra"};
  return names[static_cast<int>(k)];
}

// Per column kind (ColumnKind): max |d - ref| / max |d| over the kind's columns, and its worst
// column. A kind whose variation is below 1e-3 of the row's largest is measured against that
// instead (a joint that carries no moment: its moments and their variations are rounding, ~1e-13,
// relative to nothing).
struct KindError {
  double error = 0;
  std::string column;
};
std::map<int, KindError> errors_by_kind(const OutputLayout& L, const Eigen::VectorXd& d,
                                        const Eigen::VectorXd& ref) {
  std::map<int, double> scale;
  const double floor = 1e-3 * d.cwiseAbs().maxCoeff();
  for (std::size_t i = 0; i < L.size(); ++i) {
    double& sc = scale[static_cast<int>(L.columns()[i].kind)];
    sc = std::max({sc, floor, std::abs(d(static_cast<Eigen::Index>(i)))});
  }
  std::map<int, KindError> r;
  for (std::size_t i = 0; i < L.size(); ++i) {
    const int kind = static_cast<int>(L.columns()[i].kind);
    const double sc = scale[kind];
    const double e = std::abs(d(static_cast<Eigen::Index>(i)) - ref(static_cast<Eigen::Index>(i))) /
                     (sc > 0 ? sc : 1.0);
    KindError& k = r[kind];
    if (e >= k.error) k = {e, L.columns()[i].name + " (" + kind_name(L.columns()[i].kind) + ")"};
  }
  return r;
}

}  // namespace

TEST_CASE("lagrange tangent: da against central and Richardson differences on rigid and flexible trees",
          "[lagrange][tangent]") {
  std::mt19937 g(27);
  for (const Case& c : covered_systems()) {
    LagrangeEngine e(c.system, {});
    double worst_central = 0, worst_richardson = 0, worst_a = 0;
    for (int trial = 0; trial < 3; ++trial) {
      const TreeState s = test::random_flex_state(c.system, g);
      const TreeTangent ds = random_tangent(c.system, g);
      const double t = 0.3;
      TreeAccel a, da;
      REQUIRE(e.accelerations_tangent(t, s, ds, a, da));
      const Eigen::VectorXd fa = flat(a), fda = flat(da);
      REQUIRE(fa.size() == accel_at(e, t, s).size());
      REQUIRE(fda.size() == fa.size());
      worst_a = std::max(worst_a, rel(fa, accel_at(e, t, s)));
      worst_central = std::max(worst_central, rel(central(e, t, s, ds, 1e-5), fda));
      // The extrapolation at its best first step: truncation O(h^6) above, the rounding of
      // accelerations() (relative eps_a ~ 1e-15 to 1e-12, the chain's the largest) times 1/h below.
      double best = 1.0;
      for (double h : {3.2e-2, 1.6e-2, 8e-3}) best = std::min(best, rel(richardson(e, t, s, ds, h), fda));
      worst_richardson = std::max(worst_richardson, best);
    }
    INFO(c.name << ": max relative difference to accelerations() " << worst_a
                << ", to central differences " << worst_central << ", to Richardson "
                << worst_richardson);
    CHECK(worst_a <= 1e-14);
    // Central differences at h = 1e-5: truncation ~h^2 ~ 1e-10, rounding eps_a / h up to ~1e-7
    // (the chain's).
    CHECK(worst_central < 2e-7);
    // Richardson: ~1e-13 on every system but the chain (~5e-11, its accelerations' rounding).
    CHECK(worst_richardson < 1e-10);
  }
}

TEST_CASE("lagrange tangent: da is linear in ds", "[lagrange][tangent]") {
  std::mt19937 g(28);
  for (const Case& c : covered_systems()) {
    LagrangeEngine e(c.system, {});
    const TreeState s = test::random_flex_state(c.system, g);
    const TreeTangent d1 = random_tangent(c.system, g), d2 = random_tangent(c.system, g);
    TreeAccel a, da1, da2, da12;
    REQUIRE(e.accelerations_tangent(0.0, s, d1, a, da1));
    REQUIRE(e.accelerations_tangent(0.0, s, d2, a, da2));
    REQUIRE(e.accelerations_tangent(0.0, s, combine(d1, 2.0, d2), a, da12));
    INFO(c.name);
    CHECK(rel(flat(da12), flat(da1) + 2 * flat(da2)) < 1e-12);
  }
}

TEST_CASE("lagrange tangent: a free rigid body's d(wdot)/dw is Euler's Jacobian",
          "[lagrange][tangent]") {
  // I w' = -w x I w  =>  d(w')/dw = I^-1 ([I w x] - [w x] I) (torque-free, any attitude).
  const System sys = one_body();
  LagrangeEngine e(sys, {});
  std::mt19937 g(29);
  const Eigen::Matrix3d I = sys.bodies[0].I_BBo_B;
  for (int trial = 0; trial < 5; ++trial) {
    const TreeState s = test::random_state(sys, g);
    const Eigen::Vector3d w = s.w_NB_B;
    const Eigen::Matrix3d J = I.inverse() * (rot::skew(I * w) - rot::skew(w) * I);
    Eigen::Matrix3d D;
    for (int k = 0; k < 3; ++k) {
      TreeTangent ds = TreeTangent::zero(sys);
      ds.dw_NB_B(k) = 1.0;
      TreeAccel a, da;
      REQUIRE(e.accelerations_tangent(0.0, s, ds, a, da));
      D.col(k) = da.wdot_NB_B[0];
      CHECK(da.a_NBo_N[0].norm() == 0.0);  // no force: the CM does not accelerate
    }
    INFO("D\n" << D << "\nJ\n" << J);
    CHECK((D - J).cwiseAbs().maxCoeff() <= 1e-14 * J.cwiseAbs().maxCoeff());
  }
}

TEST_CASE("lagrange tangent: a malformed tangent throws, with nothing written",
          "[lagrange][tangent]") {
  // Every system is covered (the constructor's Model::tangent); what remains is the input check.
  const System sys = test::flex_tree(true);
  LagrangeEngine e(sys, {});
  TreeTangent no_modes = TreeTangent::zero(sys);
  for (Eigen::VectorXd& v : no_modes.eta) v.resize(0);
  TreeTangent no_joints = TreeTangent::zero(sys);
  no_joints.joints.pop_back();
  for (const TreeTangent& ds : {no_modes, no_joints}) {
    TreeAccel a, da;
    a.angle_ddot = {42.0};
    da.angle_ddot = {43.0};
    CHECK_THROWS_AS(e.accelerations_tangent(0.0, TreeState::initial(sys), ds, a, da), InputError);
    CHECK(a.angle_ddot == std::vector<double>{42.0});
    CHECK(da.angle_ddot == std::vector<double>{43.0});
    CHECK(a.wdot_NB_B.empty());
    CHECK(da.wdot_NB_B.empty());
  }
}

TEST_CASE("lagrange tangent: the engine's run state is left as it was", "[lagrange][tangent]") {
  // accelerations_tangent() packs s (choosing charts): a run's state x keeps its meaning after.
  const System sys = test::chain(5);
  LagrangeEngine e(sys, {});
  std::mt19937 g(31);
  std::vector<double> x(static_cast<std::size_t>(e.state_size())), f0(x.size()), f1(x.size());
  e.pack(test::random_state(sys, g), x.data());
  std::vector<int> charts;
  for (int k = 0; k < e.euler_sets(); ++k) charts.push_back(e.chart(k));
  e.rhs(0.0, x.data(), f0.data());
  for (int trial = 0; trial < 5; ++trial) {
    const TreeState s = test::random_state(sys, g);
    TreeAccel a, da;
    REQUIRE(e.accelerations_tangent(0.0, s, random_tangent(sys, g), a, da));
  }
  for (int k = 0; k < e.euler_sets(); ++k) CHECK(e.chart(k) == charts[static_cast<std::size_t>(k)]);
  e.rhs(0.0, x.data(), f1.data());
  CHECK(f0 == f1);
}

TEST_CASE("lagrange output tangent: drow against Richardson differences per column kind",
          "[lagrange][tangent][output]") {
  std::mt19937 g(39);
  for (const Case& c : covered_systems()) {
    LagrangeEngine e(c.system, {});
    const OutputLayout& L = e.layout();
    const auto nc = static_cast<Eigen::Index>(L.size());
    double worst = 0, worst_row = 0;
    std::string worst_col;
    for (int trial = 0; trial < 3; ++trial) {
      const TreeState s = test::random_flex_state(c.system, g);
      const TreeTangent ds = random_tangent(c.system, g);
      const double t = 0.3;
      Eigen::VectorXd row(nc), drow(nc);
      REQUIRE(e.output_row_tangent(t, s, ds, row.data(), drow.data()));
      const Eigen::VectorXd r0 = row_at(e, t, s);
      worst_row = std::max(worst_row, (row - r0).cwiseAbs().maxCoeff());
      CHECK(drow(0) == 0.0);  // the time column
      const VecFn f = [&](double h) { return row_at(e, t, moved_along(s, ds, h)); };
      // Per column kind, the extrapolation at its best first step (as for da above; the kinds'
      // truncation and rounding differ).
      std::map<int, KindError> best;
      for (double h : {6.4e-2, 3.2e-2, 1.6e-2, 8e-3})
        for (const auto& [kind, ke] : errors_by_kind(L, drow, richardson_of(f, h)))
          if (!best.count(kind) || ke.error < best[kind].error) best[kind] = ke;
      for (const auto& [kind, ke] : best)
        if (ke.error >= worst) {
          worst = ke.error;
          worst_col = ke.column;
        }
    }
    INFO(c.name << ": row against output_row() " << worst_row
                << ", drow against Richardson (per column kind) " << worst << ", worst column "
                << worst_col);
    CHECK(worst_row == 0.0);
    // ~1e-12 on most systems; the five-link chain ~1e-10 (its joints carry no moment: the moments'
    // rounding over h).
    CHECK(worst < 5e-10);
    WARN(c.name << ": output drow vs Richardson " << worst << " (" << worst_col << ")");
  }
}

TEST_CASE("lagrange output tangent: drow is linear in ds, and the engine is left as it was",
          "[lagrange][tangent][output]") {
  std::mt19937 g(40);
  for (const Case& c : covered_systems()) {
    LagrangeEngine e(c.system, {});
    const auto nc = static_cast<Eigen::Index>(e.layout().size());
    std::vector<double> x(static_cast<std::size_t>(e.state_size())), f0(x.size()), f1(x.size());
    e.pack(test::random_flex_state(c.system, g), x.data());
    e.rhs(0.1, x.data(), f0.data());
    const TreeState s = test::random_flex_state(c.system, g);
    const TreeTangent d1 = random_tangent(c.system, g), d2 = random_tangent(c.system, g);
    Eigen::VectorXd row(nc), dr1(nc), dr2(nc), dr12(nc);
    REQUIRE(e.output_row_tangent(0.2, s, d1, row.data(), dr1.data()));
    REQUIRE(e.output_row_tangent(0.2, s, d2, row.data(), dr2.data()));
    REQUIRE(e.output_row_tangent(0.2, s, combine(d1, 2.0, d2), row.data(), dr12.data()));
    INFO(c.name);
    CHECK(rel(dr12, dr1 + 2 * dr2) < 1e-12);
    e.rhs(0.1, x.data(), f1.data());
    CHECK(f0 == f1);
  }
}

TEST_CASE("lagrange output tangent: a malformed tangent throws, with nothing written",
          "[lagrange][tangent][output]") {
  const System sys = test::flex_tree(true);
  LagrangeEngine e(sys, {});
  TreeTangent no_modes = TreeTangent::zero(sys);
  for (Eigen::VectorXd& v : no_modes.eta) v.resize(0);
  TreeTangent no_joints = TreeTangent::zero(sys);
  no_joints.joints.pop_back();
  for (const TreeTangent& ds : {no_modes, no_joints}) {
    std::vector<double> row(e.layout().size(), 42.0), drow(e.layout().size(), 43.0);
    CHECK_THROWS_AS(e.output_row_tangent(0.0, TreeState::initial(sys), ds, row.data(), drow.data()),
                    InputError);
    CHECK(std::all_of(row.begin(), row.end(), [](double v) { return v == 42.0; }));
    CHECK(std::all_of(drow.begin(), drow.end(), [](double v) { return v == 43.0; }));
  }
}

TEST_CASE("lagrange rhs tangent: dxdot against Richardson differences, on and off pack()'s states",
          "[lagrange][tangent][rhs]") {
  std::mt19937 g(41);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const Case& c : covered_systems()) {
    LagrangeEngine e(c.system, {});
    const auto nx = static_cast<Eigen::Index>(e.state_size());
    double worst = 0, worst_f = 0;
    std::string worst_label;
    for (int trial = 0; trial < 4; ++trial) {
      Eigen::VectorXd x(nx), dx(nx), f(nx), df(nx), f0(nx);
      e.pack(test::random_flex_state(c.system, g), x.data());
      if (trial % 2 == 1)  // an arbitrary x near it (the engine's coordinates have no constraint)
        for (Eigen::Index i = 0; i < nx; ++i) x(i) += 0.05 * u(g);
      for (Eigen::Index i = 0; i < nx; ++i) dx(i) = u(g);
      const double t = 0.4;
      REQUIRE(e.rhs_tangent(t, x.data(), dx.data(), f.data(), df.data()));
      e.rhs(t, x.data(), f0.data());
      worst_f = std::max(worst_f, (f - f0).cwiseAbs().maxCoeff());
      const VecFn fn = [&](double h) {
        Eigen::VectorXd xh = x + h * dx, r(nx);
        e.rhs(t, xh.data(), r.data());
        return r;
      };
      double best = 1e300;
      Eigen::Index at = 0;
      for (double h : {1.6e-2, 8e-3, 4e-3}) {
        const Eigen::VectorXd err = (richardson_of(fn, h) - df).cwiseAbs();
        // Per block: the coordinate rates q*' and the accelerations pi'', each relative to its
        // largest variation.
        const Eigen::Index n = nx / 2;
        Eigen::Index iq, iu;
        const double eq = err.head(n).maxCoeff(&iq) / std::max(df.head(n).cwiseAbs().maxCoeff(), 1e-300);
        const double eu = err.tail(n).maxCoeff(&iu) / std::max(df.tail(n).cwiseAbs().maxCoeff(), 1e-300);
        const double r = std::max(eq, eu);
        if (r < best) {
          best = r;
          at = eq >= eu ? iq : n + iu;
        }
      }
      if (best >= worst) {
        worst = best;
        worst_label = e.state_label(static_cast<int>(at));
      }
    }
    INFO(c.name << ": xdot against rhs() " << worst_f << ", dxdot against Richardson " << worst
                << " (worst " << worst_label << ")");
    CHECK(worst_f == 0.0);
    // ~1e-12; the five-link chain ~2e-10 (the rounding of its rhs(), as for da above).
    CHECK(worst < 5e-10);
    WARN(c.name << ": rhs dxdot vs Richardson " << worst << " (" << worst_label << ")");
  }
}

TEST_CASE("lagrange rhs tangent: linear in dx, its rates match accelerations_tangent()",
          "[lagrange][tangent][rhs]") {
  std::mt19937 g(42);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  // One free rigid body: pi' = (v_NBo_N, w_NB_B) are the TreeState's own, so the rate rows of
  // dxdot for the variation of pack() along ds are da's wdot_NB_B and a_NBo_N (no force).
  const System sys = one_body();
  LagrangeEngine e(sys, {});
  for (int trial = 0; trial < 3; ++trial) {
    const TreeState s = test::random_state(sys, g);
    TreeTangent ds = TreeTangent::zero(sys);
    ds.dw_NB_B = random_vec(g, 1.0);
    ds.dv_NBo_N = random_vec(g, 1.0);
    ds.dp_NoBo_N = random_vec(g, 1.0);
    std::vector<double> x(12), dx(12, 0.0), f(12), df(12), df2(12), df12(12), dx2(12), dx12(12);
    e.pack(s, x.data());
    for (int i = 0; i < 3; ++i) {
      dx[static_cast<std::size_t>(i)] = ds.dp_NoBo_N(i);
      dx[static_cast<std::size_t>(6 + i)] = ds.dv_NBo_N(i);
      dx[static_cast<std::size_t>(9 + i)] = ds.dw_NB_B(i);
    }
    REQUIRE(e.rhs_tangent(0.0, x.data(), dx.data(), f.data(), df.data()));
    TreeAccel a, da;
    REQUIRE(e.accelerations_tangent(0.0, s, ds, a, da));
    for (int i = 0; i < 3; ++i) {
      CHECK(df[static_cast<std::size_t>(9 + i)] == Approx(da.wdot_NB_B[0](i)).margin(1e-13));
      CHECK(df[static_cast<std::size_t>(6 + i)] == Approx(da.a_NBo_N[0](i)).margin(1e-13));
    }
    for (std::size_t i = 0; i < 12; ++i) {
      dx2[i] = u(g);
      dx12[i] = dx[i] + 2.0 * dx2[i];
    }
    REQUIRE(e.rhs_tangent(0.0, x.data(), dx2.data(), f.data(), df2.data()));
    REQUIRE(e.rhs_tangent(0.0, x.data(), dx12.data(), f.data(), df12.data()));
    for (std::size_t i = 0; i < 12; ++i)
      CHECK(df12[i] == Approx(df[i] + 2.0 * df2[i]).margin(1e-12));
  }
}

