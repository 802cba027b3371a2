// The Newton-Euler engine's exact tangent, accelerations_tangent() (issue 27; core/engine.hpp):
// the complex step through its own pack() and equations of motion (Martins, Sturdza & Alonso 2003,
// ACM TOMS 29(3); Griewank & Walther 2008, "Evaluating Derivatives", 2nd ed., Ch. 3).
// Covered: rigid bodies with a free base and revolute, prismatic, universal, fixed and spherical
// joints, springs, dampers, motors, prescribed joints, body torques, uniform
// gravity and an orbit's gravity gradient. Checked on random states and tangents against
//   - a central difference of accelerations(pack(s +- h ds)) (h = 1e-5: agreement to the
//     difference's own accuracy, ~1e-8 of max |da|),
//   - a Richardson-extrapolated difference (h = 1e-2, two extrapolations, error O(h^6)): ~1e-11,
//     which only an exact derivative reaches,
// and: a is accelerations(pack(s)); da is linear in ds; for a torque-free rigid body d(wdot)/dw
// is the Jacobian of Euler's equations, I^-1 ([I w x] - [w x] I); what is not covered returns
// false and writes nothing.
// Then output_row_tangent() and rhs_tangent() (the output matrix C and the engine's own Jacobian):
// per column group against Richardson differences of output_row(pack(s +- h ds)), row bit-equal,
// linear; rhs_tangent() against Richardson differences of rhs(x +- h dx) on and off the
// manifold, xdot bit-equal, linear, its speed rows equal to accelerations_tangent()'s.
#include "core/orbit.hpp"
#include "core/rotation.hpp"
#include "core/scene/scene.hpp"
#include "formulations/newton_euler/newton_euler.hpp"
#include "formulations/newton_euler/so3.hpp"
#include "tests/newton_euler/ne_prescribed_scenes.hpp"
#include "tests/newton_euler/ne_systems.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <functional>
#include <random>
#include <string>
#include <vector>

namespace {

using namespace crossdyn;
using namespace crossdyn::test::ne;
using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;
namespace so3 = crossdyn::newton_euler::so3;

// Every field of a TreeAccel in one vector (a fixed order: bodies, then joints, then modes).
std::vector<double> flatten(const TreeAccel& a) {
  std::vector<double> v;
  for (const Vector3d& x : a.wdot_NB_B) v.insert(v.end(), x.data(), x.data() + 3);
  for (const Vector3d& x : a.a_NBo_N) v.insert(v.end(), x.data(), x.data() + 3);
  v.insert(v.end(), a.angle_ddot.begin(), a.angle_ddot.end());
  v.insert(v.end(), a.angle2_ddot.begin(), a.angle2_ddot.end());
  for (const Vector3d& x : a.wdot_PC_C) v.insert(v.end(), x.data(), x.data() + 3);
  for (const Eigen::VectorXd& x : a.eta_ddot) v.insert(v.end(), x.data(), x.data() + x.size());
  return v;
}

double max_abs(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::abs(x));
  return m;
}

double max_abs_diff(const std::vector<double>& a, const std::vector<double>& b) {
  REQUIRE(a.size() == b.size());
  double m = 0;
  for (std::size_t i = 0; i < a.size(); ++i) m = std::max(m, std::abs(a[i] - b[i]));
  return m;
}


std::vector<double> accel_at(Engine& e, double t, const TreeState& s) {
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(s, x.data());
  TreeAccel a;
  e.accelerations(t, x.data(), a);
  return flatten(a);
}

std::vector<double> central(Engine& e, double t, const TreeState& s, const TreeTangent& ds, double h) {
  const std::vector<double> p = accel_at(e, t, moved_along(s, ds, h)), m = accel_at(e, t, moved_along(s, ds, -h));
  std::vector<double> d(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) d[i] = (p[i] - m[i]) / (2 * h);
  return d;
}

// Two Richardson extrapolations of the central difference (error O(h^6)).
std::vector<double> richardson(Engine& e, double t, const TreeState& s, const TreeTangent& ds, double h) {
  const std::vector<double> d1 = central(e, t, s, ds, h), d2 = central(e, t, s, ds, h / 2),
                            d4 = central(e, t, s, ds, h / 4);
  std::vector<double> r(d1.size());
  for (std::size_t i = 0; i < r.size(); ++i) {
    const double r1 = (4 * d2[i] - d1[i]) / 3, r2 = (4 * d4[i] - d2[i]) / 3;
    r[i] = (16 * r2 - r1) / 15;
  }
  return r;
}

// random_state (ne_systems.hpp) with the universal joints' second angle and rate as well, and
// random modal coordinates and rates of every flexible body (|eta| <= 0.1, |eta'| <= 0.5).
TreeState random_state2(const System& system, std::mt19937& rng) {
  TreeState s = random_state(system, rng);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (std::size_t j = 1; j < system.joints.size(); ++j) {
    s.joints[j].angle2 = 3.0 * u(rng);
    s.joints[j].rate2 = 2.0 * u(rng);
  }
  deform(system, s, rng, 0.1, 0.5);
  return s;
}

// A random tangent of every covered field (unit scale).
TreeTangent random_tangent(const System& system, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&] { return Vector3d(u(rng), u(rng), u(rng)); };
  TreeTangent ds = TreeTangent::zero(system);
  ds.dp_NoBo_N = vec();
  ds.dtheta_B = vec();
  ds.dv_NBo_N = vec();
  ds.dw_NB_B = vec();
  for (std::size_t j = 1; j < ds.joints.size(); ++j) {
    if (system.joints[j].prescribed) continue;  // no tangent: the profile at t (TreeTangent)
    ds.joints[j].angle = u(rng);
    ds.joints[j].rate = u(rng);
    ds.joints[j].angle2 = u(rng);
    ds.joints[j].rate2 = u(rng);
    ds.joints[j].dtheta_J = vec();
    ds.joints[j].w_PC_C = vec();
  }
  for (auto& v : ds.eta)  // from rng (Eigen's Random() reads std::rand, shared by every test)
    for (Eigen::Index k = 0; k < v.size(); ++k) v(k) = u(rng);
  for (auto& v : ds.eta_rate)
    for (Eigen::Index k = 0; k < v.size(); ++k) v(k) = u(rng);
  return ds;
}

Environment uniform_gravity() {
  Environment e;
  e.kind = Environment::Kind::Uniform;
  e.g_N = Vector3d(0.3, -9.81, 1.2);
  return e;
}

// A low Earth orbit, inclined (as in test_ne_gravity.cpp).
Environment orbit() {
  Environment e;
  e.kind = Environment::Kind::Orbit;
  e.mu = 3.986004418e14;
  e.body_radius = 6.378e6;
  e.radius = 7.0e6;
  e.inclination = 0.9;
  e.raan = 0.4;
  e.latitude0 = 0.3;
  return e;
}

// One free rigid body with a full (non-diagonal) inertia tensor.
System one_body(const std::string& name) {
  System s;
  s.name = name;
  Matrix3d I;
  I << 4.0, 0.3, -0.2, 0.3, 6.0, 0.5, -0.2, 0.5, 9.0;
  s.bodies.push_back(make_body("box", 20.0, I));
  Joint base = free_joint(0);
  base.w_NB_B0 = Vector3d(0.3, -0.2, 0.5);
  s.joints.push_back(base);
  return s;
}

// A rigid tree with every covered joint type and load (base box; a revolute arm with a spring,
// damper and motor; a spherical ball with a damper and motor; a universal gimbal with springs and
// dampers on both axes; a prismatic slider with a spring, damper and motor; a fixed plate),
// non-diagonal inertias and oblique axes.
System rigid_tree(const std::string& name) {
  System s;
  s.name = name;
  auto inertia = [](double a, double b, double c, double x) {
    Matrix3d I;
    I << a, x, -0.5 * x, x, b, 0.3 * x, -0.5 * x, 0.3 * x, c;
    return I;
  };
  s.bodies.push_back(make_body("box", 50.0, inertia(8, 10, 12, 0.4)));
  s.bodies.push_back(make_body("arm", 5.0, inertia(0.3, 2.0, 2.1, 0.05)));
  s.bodies.push_back(make_body("ball", 3.0, inertia(0.4, 0.5, 0.6, 0.02)));
  s.bodies.push_back(make_body("gimbal", 2.0, inertia(0.2, 0.3, 0.25, 0.01)));
  s.bodies.push_back(make_body("slider", 4.0, inertia(0.5, 0.4, 0.7, 0.03)));
  s.bodies.push_back(make_body("plate", 1.5, inertia(0.1, 0.2, 0.28, 0.01)));
  Joint base = free_joint(0);
  base.w_NB_B0 = Vector3d(0.3, -0.2, 0.5);
  s.joints.push_back(base);
  auto joint = [&](const char* n, JointType type, int parent, int child, Vector3d pp, Vector3d cp) {
    Joint j;
    j.name = n;
    j.type = type;
    j.parent = parent;
    j.child = child;
    j.p_PoJ_P = pp;
    j.p_CoJ_C = cp;
    j.q_PJ0 = Quaterniond(Eigen::AngleAxisd(0.4, Vector3d(1, 2, 3).normalized()));
    return j;
  };
  Joint arm = joint("arm_hinge", JointType::Revolute, 0, 1, Vector3d(1, 0.2, 0), Vector3d(-0.8, 0, 0.1));
  arm.axis_P = Vector3d(0.2, 0.1, 1).normalized();
  arm.stiffness = 30;
  arm.neutral_angle = 0.3;
  arm.damping = 2;
  arm.motor_revolute.times = {0.0};
  arm.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(0.7)};
  s.joints.push_back(arm);
  Joint ball = joint("ball", JointType::Spherical, 1, 2, Vector3d(0.8, 0, 0), Vector3d(-0.4, 0.1, 0));
  ball.damping = 0.5;
  ball.motor_spherical.times = {0.0};
  ball.motor_spherical.values = {Vector3d(0.1, -0.2, 0.05)};
  s.joints.push_back(ball);
  Joint gimbal = joint("gimbal", JointType::Universal, 0, 3, Vector3d(0, 1, 0.3), Vector3d(0, -0.3, 0));
  gimbal.axis_P = Vector3d(1, 0, 0.2).normalized();
  gimbal.axis2_P = Vector3d(0.1, 1, 0).normalized();
  gimbal.stiffness = 4;
  gimbal.damping = 0.3;
  gimbal.stiffness2 = 6;
  gimbal.damping2 = 0.2;
  gimbal.neutral_angle2 = -0.2;
  s.joints.push_back(gimbal);
  Joint slider = joint("slider", JointType::Prismatic, 0, 4, Vector3d(0, -1, 0), Vector3d(0.1, 0.2, 0));
  slider.axis_P = Vector3d(0.3, -1, 0.2).normalized();
  slider.stiffness = 20;
  slider.damping = 1.5;
  slider.motor_revolute.times = {0.0};
  slider.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(-2.0)};
  s.joints.push_back(slider);
  s.joints.push_back(joint("plate_mount", JointType::Fixed, 4, 5, Vector3d(0.2, 0, 0.5), Vector3d(0, 0, -0.2)));
  return s;
}

// A prescribed base: a rigid hub spun up about an oblique axis from N, carrying an arm on a
// revolute joint with a spring and damper and a ball on a spherical joint.
const char* kPrescribedHub = R"(name: prescribed_hub
bodies:
  - name: hub
    mass: 100 kg
    inertia: [10, 12, 14]
  - name: arm
    mass: 5 kg
    inertia: [0.3, 2.0, 2.1]
  - name: ball
    mass: 2 kg
    inertia: [0.2, 0.25, 0.3]
joints:
  - name: spin
    type: revolute
    child: hub
    parent_point: [0.1, 0, 0.2]
    child_point: [0, 0.05, 0]
    axis: [0.1, 0.2, 1]
    prescribed: {profile: spin-up, rate: 2 rad/s, ramp_time: 5 s}
  - name: hinge
    type: revolute
    parent: hub
    parent_point: [1, 0.2, 0]
    child: arm
    child_point: [-0.8, 0, 0.1]
    axis: [0.2, 1, 0.1]
    spring: {stiffness: 30}
    damper: {damping: 2}
  - name: ball_joint
    type: spherical
    parent: arm
    parent_point: [0.8, 0, 0]
    child: ball
    child_point: [-0.3, 0.1, 0]
run:
  duration: 1 s
  output_step: 0.1 s
)";

struct Case {
  std::string name;
  System system;
  double t = 0;
  EngineOptions options{};
  // The Richardson difference's step and the agreement asked of it. Its truncation error is
  // O(h^6) with the system's own scale of variation: flexible bodies (stiff modes, a state that
  // varies faster) need a smaller step than rigid ones, h = 3e-3 (at 1e-2 the difference is off by
  // ~1e-9, falling as h^6 to its rounding floor: hidden test case [.tangent_steps]); their
  // rounding floor is near 1e-11 (3e-11 asked: larger sums, node by node for stiffened beams).
  // The spin-up beam (50 nodes, a hub driven at 10 rad/s whose prescribed accelerations have no
  // tangent) has |a| >> |da|: the difference's rounding, ~eps |a| / (h |da|), grows as 1/h from
  // 2e-11 at h = 2e-2 (its truncation is below that already), so h = 2e-2 and 5e-11 there.
  double rich_h = 1e-2;
  double rich_tol = 1e-11;
};

// The covered systems: one free rigid body torque-free; with a body torque in N and uniform
// gravity; on an orbit (tidal force and gravity-gradient torque: the position and the attitude
// matter), with and without zero_linear_momentum; a body torque in the body frame on the orbit.
std::vector<Case> covered_cases() {
  std::vector<Case> cases;
  cases.push_back({"torque-free body", one_body("torque_free"), 0.0});
  {
    System s = one_body("gravity_torque_N");
    s.environment = uniform_gravity();
    s.bodies[0].torque.times = {0.0, 2.0};
    s.bodies[0].torque.values = {Vector3d(0.4, -0.7, 0.2), Vector3d(1, 1, 1)};
    s.bodies[0].torque_frame = Body::Frame::Inertial;
    s.zero_linear_momentum = false;
    cases.push_back({"uniform gravity, torque in N", s, 1.0});
  }
  {
    System s = one_body("orbit");
    s.environment = orbit();
    cases.push_back({"orbit, zero linear momentum", s, 700.0});
  }
  {
    System s = one_body("orbit_free_v");
    s.environment = orbit();
    s.zero_linear_momentum = false;
    s.bodies[0].torque.times = {0.0};
    s.bodies[0].torque.values = {Vector3d(-0.3, 0.1, 0.6)};
    s.bodies[0].torque_frame = Body::Frame::Body;
    cases.push_back({"orbit, body torque, free v", s, 1234.5});
  }
  cases.push_back({"spherical chain (chain3)", chain(3), 0.0});
  cases.push_back({"rigid tree, all joint types", rigid_tree("tree"), 0.5});
  {
    System s = rigid_tree("tree_gravity");
    s.environment = uniform_gravity();
    s.zero_linear_momentum = false;
    cases.push_back({"rigid tree, uniform gravity", s, 0.5});
  }
  {
    System s = rigid_tree("tree_orbit");
    s.environment = orbit();
    cases.push_back({"rigid tree, orbit", s, 800.0});
  }
  {
    Case c{"rigid tree, Baumgarte", rigid_tree("tree_baumgarte"), 0.5};
    c.options.stabilization = ConstraintStabilization::Baumgarte;
    cases.push_back(c);
  }
  cases.push_back({"mixed tree (spherical spring)", mixed_tree(), 0.3});
  cases.push_back(
      {"prescribed joint (scan platform)", read_scene_text(scan_platform_text(), "scan_platform_test"), 2.0});
  cases.push_back({"prescribed base (rigid hub)", read_scene_text(kPrescribedHub, "prescribed_hub"), 2.0});
  // Flexible (modal) bodies: every joint type at nodes, modal stiffness, damping, gravity, orbit.
  cases.push_back({"flexible chain3 (nodes)", flexible_chain(3), 0.0, {}, 3e-3, 3e-11});
  {
    System s = flexible_tree();
    for (Body& b : s.bodies)
      if (b.flex) b.flex->D = 0.05 * b.flex->K;  // modal damping
    s.bodies[0].torque.times = {0.0};
    s.bodies[0].torque.values = {Vector3d(0.2, -0.1, 0.3)};
    cases.push_back({"flexible tree, modal damping", s, 0.4, {}, 3e-3, 3e-11});
  }
  {
    System s = flexible_tree();
    s.environment = uniform_gravity();
    s.zero_linear_momentum = false;
    cases.push_back({"flexible tree, uniform gravity", s, 0.4, {}, 3e-3, 3e-11});
  }
  {
    System s = flexible_tree();
    s.environment = orbit();
    cases.push_back({"flexible tree, orbit", s, 900.0, {}, 3e-3, 3e-11});
  }
  {
    Case c{"flexible tree, Baumgarte", flexible_tree(), 0.4, {}, 3e-3, 3e-11};
    c.options.stabilization = ConstraintStabilization::Baumgarte;
    cases.push_back(c);
  }
  // Geometric stiffening: the spin-up beam (a prescribed base carrying a stiffened beam), a free
  // spinning stiffened beam with a tip on a hinge at its node, and on an orbit.
  cases.push_back({"stiffened spin-up beam (prescribed base)", read_scene_text(spinup_beam_text(true), "spinup"), 3.0,
                   {}, 2e-2, 5e-11});
  cases.push_back({"stiffened beam + tip, hinge at node", read_scene_text(beam_with_tip_text(false), "beam_tip"), 0.5,
                   {}, 5e-3, 3e-11});
  {
    System s = read_scene_text(beam_with_tip_text(false), "beam_tip_orbit");
    s.environment = orbit();
    cases.push_back({"stiffened beam + tip, orbit", s, 500.0, {}, 5e-3, 3e-11});
  }
  {
    System s = read_scene_text(kPrescribedHub, "prescribed_hub_gravity");
    s.environment = uniform_gravity();
    Case c{"prescribed base, gravity, Baumgarte", s, 3.0};
    c.options.stabilization = ConstraintStabilization::Baumgarte;
    cases.push_back(c);
  }
  return cases;
}

// Largest relative differences over the random states of one case (printed by the hidden test
// case "newton-euler tangent: report").
struct Figures {
  std::string name;
  double vs_central = 0, vs_richardson = 0;
};

void check_case(const Case& c, int states, Figures& fig) {
  std::unique_ptr<Engine> e = make_newton_euler_engine(c.system, c.options);
  std::mt19937 rng(2718);
  fig.name = c.name;
  for (int k = 0; k < states; ++k) {
    const TreeState s = random_state2(c.system, rng);
    const TreeTangent ds = random_tangent(c.system, rng);
    TreeAccel a, da;
    REQUIRE(e->accelerations_tangent(c.t, s, ds, a, da));
    const std::vector<double> fa = flatten(a), fda = flatten(da);
    // a is the run's accelerations at pack(s).
    const std::vector<double> a_ref = accel_at(*e, c.t, s);
    REQUIRE(fa.size() == a_ref.size());
    CHECK(max_abs_diff(fa, a_ref) <= 1e-14 * std::max(1.0, max_abs(a_ref)));
    // Sizes as accelerations() gives them.
    TreeAccel a_sized;
    std::vector<double> x(static_cast<std::size_t>(e->state_size()));
    e->pack(s, x.data());
    e->accelerations(c.t, x.data(), a_sized);
    CHECK(da.wdot_NB_B.size() == a_sized.wdot_NB_B.size());
    CHECK(da.a_NBo_N.size() == a_sized.a_NBo_N.size());
    CHECK(da.angle_ddot.size() == a_sized.angle_ddot.size());
    CHECK(da.angle2_ddot.size() == a_sized.angle2_ddot.size());
    CHECK(da.wdot_PC_C.size() == a_sized.wdot_PC_C.size());
    REQUIRE(da.eta_ddot.size() == a_sized.eta_ddot.size());
    for (std::size_t b = 0; b < da.eta_ddot.size(); ++b)
      CHECK(da.eta_ddot[b].size() == a_sized.eta_ddot[b].size());

    const double scale = max_abs(fda);
    REQUIRE(scale > 0);
    const double rel_c = max_abs_diff(fda, central(*e, c.t, s, ds, 1e-5)) / scale;
    const double rel_r = max_abs_diff(fda, richardson(*e, c.t, s, ds, c.rich_h)) / scale;
    INFO(c.name << ", state " << k << ": vs central " << rel_c << ", vs Richardson " << rel_r);
    CHECK(rel_c < 1e-8);
    CHECK(rel_r < c.rich_tol);
    fig.vs_central = std::max(fig.vs_central, rel_c);
    fig.vs_richardson = std::max(fig.vs_richardson, rel_r);
  }
}

}  // namespace

TEST_CASE("newton-euler tangent: agrees with central and Richardson differences on covered systems",
          "[newton_euler][tangent]") {
  for (const Case& c : covered_cases()) {
    Figures fig;
    check_case(c, 8, fig);
  }
}

TEST_CASE("newton-euler tangent: the differences of an orbit's position tangent alone",
          "[newton_euler][tangent]") {
  // On the orbit the position enters only through the tidal force n^2 (3 z z^T - 1) d (1e-6 of
  // the other terms): a tangent of p alone isolates it, d a = m^-1 m T dp = T dp exactly.
  const Case c{"orbit", [] {
                 System s = one_body("orbit_dp");
                 s.environment = orbit();
                 s.zero_linear_momentum = false;
                 return s;
               }(),
               321.0};
  std::unique_ptr<Engine> e = make_newton_euler_engine(c.system, EngineOptions{});
  std::mt19937 rng(11);
  const TreeState s = random_state2(c.system, rng);
  TreeTangent ds = TreeTangent::zero(c.system);
  ds.dp_NoBo_N = Vector3d(0.7, -0.4, 0.2);
  TreeAccel a, da;
  REQUIRE(e->accelerations_tangent(c.t, s, ds, a, da));
  const OrbitFrame of = orbit_frame(c.system.environment, c.t);
  const Vector3d z = of.zenith_N;
  const Vector3d expected = of.n * of.n * (3.0 * z.dot(ds.dp_NoBo_N) * z - ds.dp_NoBo_N);
  CHECK((da.a_NBo_N[0] - expected).norm() <= 1e-14 * expected.norm());
  CHECK(da.wdot_NB_B[0].norm() == 0.0);  // no moment of the tidal force about the CM
}

TEST_CASE("newton-euler tangent: a spherical spring at zero deflection", "[newton_euler][tangent]") {
  // The rotation vector's series branch (|v| < 1e-8, rot::rotation_vector) at q_J = 1, where a
  // linearisation about an equilibrium evaluates it: the complex step stays analytic there.
  const System sys = mixed_tree();
  std::unique_ptr<Engine> e = make_newton_euler_engine(sys, EngineOptions{});
  std::mt19937 rng(17);
  for (int k = 0; k < 4; ++k) {
    TreeState s = random_state2(sys, rng);
    for (std::size_t j = 1; j < sys.joints.size(); ++j)
      if (sys.joints[j].type == JointType::Spherical) s.joints[j].q_J = Quaterniond::Identity();
    const TreeTangent ds = random_tangent(sys, rng);
    TreeAccel a, da;
    REQUIRE(e->accelerations_tangent(0.0, s, ds, a, da));
    const std::vector<double> fda = flatten(da);
    const double rel = max_abs_diff(fda, richardson(*e, 0.0, s, ds, 1e-2)) / max_abs(fda);
    INFO("state " << k << ": vs Richardson " << rel);
    CHECK(rel < 1e-11);
  }
}

TEST_CASE("newton-euler tangent: a prescribed base follows its profile (zero tangent)",
          "[newton_euler][tangent]") {
  // The base's motion is the profile at t (six root rows to N): its accelerations have no
  // tangent, whatever the tangent of the bodies it carries; the base pose's own tangent is not
  // read (pack() places the base from N).
  const System sys = read_scene_text(kPrescribedHub, "prescribed_hub");
  std::unique_ptr<Engine> e = make_newton_euler_engine(sys, EngineOptions{});
  std::mt19937 rng(23);
  for (int k = 0; k < 4; ++k) {
    const TreeState s = random_state2(sys, rng);
    const TreeTangent ds = random_tangent(sys, rng);
    TreeAccel a, da;
    REQUIRE(e->accelerations_tangent(2.0, s, ds, a, da));
    const double scale = max_abs(flatten(da));
    REQUIRE(scale > 0);
    CHECK(da.wdot_NB_B[0].cwiseAbs().maxCoeff() <= 1e-14 * scale);
    CHECK(da.a_NBo_N[0].cwiseAbs().maxCoeff() <= 1e-14 * scale);
    CHECK(da.angle_ddot[0] == 0.0);
    TreeTangent base_only = TreeTangent::zero(sys);
    base_only.dp_NoBo_N = ds.dp_NoBo_N;
    base_only.dtheta_B = ds.dtheta_B;
    base_only.dv_NBo_N = ds.dv_NBo_N;
    base_only.dw_NB_B = ds.dw_NB_B;
    REQUIRE(e->accelerations_tangent(2.0, s, base_only, a, da));
    CHECK(max_abs(flatten(da)) == 0.0);
  }
}

TEST_CASE("newton-euler tangent: linear in the tangent", "[newton_euler][tangent]") {
  for (const Case& c : covered_cases()) {
    std::unique_ptr<Engine> e = make_newton_euler_engine(c.system, c.options);
    std::mt19937 rng(31);
    for (int k = 0; k < 4; ++k) {
      const TreeState s = random_state2(c.system, rng);
      const TreeTangent d1 = random_tangent(c.system, rng), d2 = random_tangent(c.system, rng);
      TreeTangent d12 = d1;
      d12.dp_NoBo_N += 2 * d2.dp_NoBo_N;
      d12.dtheta_B += 2 * d2.dtheta_B;
      d12.dv_NBo_N += 2 * d2.dv_NBo_N;
      d12.dw_NB_B += 2 * d2.dw_NB_B;
      for (std::size_t j = 0; j < d12.joints.size(); ++j) {
        TreeTangent::JointTangent& t12 = d12.joints[j];
        const TreeTangent::JointTangent& t2 = d2.joints[j];
        t12.angle += 2 * t2.angle;
        t12.rate += 2 * t2.rate;
        t12.angle2 += 2 * t2.angle2;
        t12.rate2 += 2 * t2.rate2;
        t12.dtheta_J += 2 * t2.dtheta_J;
        t12.w_PC_C += 2 * t2.w_PC_C;
      }
      for (std::size_t b = 0; b < d12.eta.size(); ++b) {
        d12.eta[b] += 2 * d2.eta[b];
        d12.eta_rate[b] += 2 * d2.eta_rate[b];
      }
      TreeAccel a, da1, da2, da12;
      REQUIRE(e->accelerations_tangent(c.t, s, d1, a, da1));
      REQUIRE(e->accelerations_tangent(c.t, s, d2, a, da2));
      REQUIRE(e->accelerations_tangent(c.t, s, d12, a, da12));
      const std::vector<double> f1 = flatten(da1), f2 = flatten(da2), f12 = flatten(da12);
      std::vector<double> sum(f1.size());
      for (std::size_t i = 0; i < sum.size(); ++i) sum[i] = f1[i] + 2 * f2[i];
      INFO(c.name);
      // To rounding: 1e-12 of the largest entry (a stiffened beam's node sums of 20-50 nodes
      // cancel to ~1e-13; every rigid and linear flexible case agrees to ~1e-15).
      CHECK(max_abs_diff(f12, sum) <= 1e-12 * std::max(max_abs(f1), max_abs(f2)));
    }
  }
}

TEST_CASE("newton-euler tangent: a torque-free rigid body's d(wdot)/dw is the Jacobian of Euler's "
          "equations",
          "[newton_euler][tangent]") {
  // I wdot = -w x I w, so d wdot = I^-1 ([I w x] - [w x] I) dw (Kane, Likins & Levinson 1983,
  // Sec. 1.13; the linearisation of Euler's equations).
  const System sys = one_body("euler");
  const Matrix3d I = sys.bodies[0].I_BBo_B;
  std::unique_ptr<Engine> e = make_newton_euler_engine(sys, EngineOptions{});
  auto cross = [](const Vector3d& v) {
    Matrix3d m;
    m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
    return m;
  };
  std::mt19937 rng(5);
  for (int k = 0; k < 6; ++k) {
    const TreeState s = random_state(sys, rng);
    const Vector3d w = s.w_NB_B;
    const Matrix3d jac = I.inverse() * (cross(I * w) - cross(w) * I);
    for (int axis = 0; axis < 3; ++axis) {
      TreeTangent ds = TreeTangent::zero(sys);
      ds.dw_NB_B = Vector3d::Unit(axis);
      TreeAccel a, da;
      REQUIRE(e->accelerations_tangent(0.0, s, ds, a, da));
      const Vector3d expected = jac.col(axis);
      INFO("state " << k << ", axis " << axis);
      CHECK((da.wdot_NB_B[0] - expected).cwiseAbs().maxCoeff() <= 1e-14 * expected.cwiseAbs().maxCoeff());
      CHECK(da.a_NBo_N[0].norm() == 0.0);
    }
    // An attitude or position tangent changes nothing without loads.
    TreeTangent ds = TreeTangent::zero(sys);
    ds.dtheta_B = Vector3d(0.3, -0.5, 0.1);
    ds.dp_NoBo_N = Vector3d(1, 2, 3);
    TreeAccel a, da;
    REQUIRE(e->accelerations_tangent(0.0, s, ds, a, da));
    CHECK(da.wdot_NB_B[0].norm() == 0.0);
    CHECK(da.a_NBo_N[0].norm() == 0.0);
  }
}

TEST_CASE("newton-euler tangent: every committed scene is covered and agrees with Richardson",
          "[newton_euler][tangent]") {
  // Nothing this engine models returns false any more (rigid and flexible bodies, stiffening,
  // every joint type, a free or prescribed base, every load and environment). Each committed
  // scene at its initial state, deformed (random modal coordinates and rates) and a random
  // tangent: a is accelerations(pack(s)), da finite and equal to a Richardson difference (h = 2e-3:
  // flexible scenes vary faster, see Case::rich_h) to 1e-10 of max |da|.
  for (const std::string& file : test::committed_scenes()) {
    const System sys = read_scene(file);
    INFO(file);
    std::unique_ptr<Engine> e = make_newton_euler_engine(sys, EngineOptions{});
    std::mt19937 rng(41);
    TreeState s = TreeState::initial(sys);
    deform(sys, s, rng, 0.02, 0.1);
    const TreeTangent ds = random_tangent(sys, rng);
    TreeAccel a, da;
    REQUIRE(e->accelerations_tangent(0.0, s, ds, a, da));
    const std::vector<double> fa = flatten(a), fda = flatten(da), a_ref = accel_at(*e, 0.0, s);
    CHECK(max_abs_diff(fa, a_ref) <= 1e-14 * std::max(1.0, max_abs(a_ref)));
    for (double v : fda) REQUIRE(std::isfinite(v));
    const double scale = std::max(max_abs(fda), 1e-300);
    const double rel = max_abs_diff(fda, richardson(*e, 0.0, s, ds, 2e-3)) / scale;
    INFO("vs Richardson " << rel);
    CHECK(rel < 1e-10);
  }
}

// The first test case again, printing its figures (hidden: run it by its tag).
TEST_CASE("newton-euler tangent: report", "[.tangent_report]") {
  for (const Case& c : covered_cases()) {
    Figures fig;
    check_case(c, 8, fig);
    std::printf("%-40s max rel. diff vs central(1e-5) %.2e, vs Richardson(h = %.0e, O(h^6)) %.2e\n",
                fig.name.c_str(), fig.vs_central, c.rich_h, fig.vs_richardson);
  }
}

// The Richardson difference against the tangent over its step h (hidden; run by its tag): the
// gap falls as h^6 to a rounding floor, the signature of an exact tangent (a wrong one would
// leave a gap independent of h).
TEST_CASE("newton-euler tangent: Richardson steps", "[.tangent_steps]") {
  for (const Case& c : covered_cases()) {
    std::unique_ptr<Engine> e = make_newton_euler_engine(c.system, c.options);
    std::mt19937 rng(2718);
    double worst[6] = {0, 0, 0, 0, 0, 0};
    const double hs[6] = {2e-2, 1e-2, 5e-3, 2e-3, 1e-3, 5e-4};
    for (int k = 0; k < 4; ++k) {
      const TreeState s = random_state2(c.system, rng);
      const TreeTangent ds = random_tangent(c.system, rng);
      TreeAccel a, da;
      REQUIRE(e->accelerations_tangent(c.t, s, ds, a, da));
      const std::vector<double> fda = flatten(da);
      for (int i = 0; i < 6; ++i)
        worst[i] = std::max(worst[i], max_abs_diff(fda, richardson(*e, c.t, s, ds, hs[i])) / max_abs(fda));
    }
    std::printf("%-40s", c.name.c_str());
    for (double w : worst) std::printf(" %.1e", w);
    std::printf("\n");
  }
}

TEST_CASE("newton-euler tangent: the node frames' so3 maps on the complex step",
          "[newton_euler][tangent]") {
  // so3::coefficients_sq(x) is coefficients(sqrt(x)) on both branches (series below x = 1), and
  // its complex step gives d/dx of each coefficient: checked against a central difference in x;
  // so3::quaternion(psi) is the rotation exp([psi x]) and its complex step in psi is the right
  // one (against a central difference of rot::from_rotation_vector).
  using C = std::complex<double>;
  for (double x : {0.0, 1e-6, 0.3, 0.999, 1.001, 2.5, 9.0}) {
    const so3::Coefficients r = so3::coefficients(std::sqrt(x));
    const so3::CoefficientsCx c = so3::coefficients_sq(C(x, 0.0));
    INFO("x = " << x);
    CHECK(std::abs(c.s.real() - r.s) <= 1e-15);
    CHECK(std::abs(c.a.real() - r.a) <= 1e-15);
    CHECK(std::abs(c.b.real() - r.b) <= 1e-15);
    CHECK(std::abs(c.a1.real() - r.a1) <= 1e-13);
    CHECK(std::abs(c.b1.real() - r.b1) <= 1e-13);
    if (x < 0.01) continue;  // the differences below reach sqrt of a negative argument
    const double h = 1e-30, d = 1e-5;
    const so3::CoefficientsCx cs = so3::coefficients_sq(C(x, h));
    const so3::Coefficients p = so3::coefficients(std::sqrt(x + d)), m = so3::coefficients(std::sqrt(x - d));
    CHECK(std::abs(cs.s.imag() / h - (p.s - m.s) / (2 * d)) <= 1e-9);
    CHECK(std::abs(cs.a.imag() / h - (p.a - m.a) / (2 * d)) <= 1e-9);
    CHECK(std::abs(cs.b.imag() / h - (p.b - m.b) / (2 * d)) <= 1e-9);
  }
  for (double scale : {1e-3, 0.5, 1.5, 3.0}) {
    const Vector3d psi = scale * Vector3d(0.3, -0.8, 0.5).normalized(), dpsi(0.2, 0.1, -0.4);
    const Quaterniond q0 = rot::from_rotation_vector(psi);
    const Eigen::Quaternion<C> q = so3::quaternion(Eigen::Matrix<C, 3, 1>(psi.cast<C>() + C(0, 1e-30) * dpsi.cast<C>()));
    const Quaterniond qp = rot::from_rotation_vector(psi + 1e-6 * dpsi), qm = rot::from_rotation_vector(psi - 1e-6 * dpsi);
    INFO("|psi| = " << scale);
    for (int i = 0; i < 4; ++i) {
      CHECK(std::abs(q.coeffs()(i).real() - q0.coeffs()(i)) <= 1e-15);
      CHECK(std::abs(q.coeffs()(i).imag() / 1e-30 - (qp.coeffs()(i) - qm.coeffs()(i)) / 2e-6) <= 1e-9);
    }
  }
}

// ---- output_row_tangent() and rhs_tangent() (issue 27: the output matrix C and the engine's own
// Jacobian, exact) ---------------------------------------------------------------------------------

namespace {

std::vector<double> row_at(Engine& e, double t, const TreeState& s) {
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(s, x.data());
  std::vector<double> row(e.layout().size());
  e.output_row(t, x.data(), row.data());
  return row;
}

// output_row at moved_along(s, ds, h), each body's quaternion columns given the sign of those at
// h = 0: the canonical sign (qw >= 0) jumps where qw crosses 0, and a difference across the jump
// means nothing; the tangent is that of the sign the value takes (core/engine.hpp), i.e. of the
// aligned row.
std::vector<double> row_along(Engine& e, double t, const TreeState& s, const TreeTangent& ds, double h,
                              const std::vector<double>& row0) {
  std::vector<double> row = row_at(e, t, moved_along(s, ds, h));
  const OutputLayout& layout = e.layout();
  for (std::size_t i = 0; i < layout.columns().size(); ++i) {
    const Column& c = layout.columns()[i];
    if (c.kind != ColumnKind::BodyQ || c.component != 0) continue;
    double dot = 0;
    for (std::size_t k = 0; k < 4; ++k) dot += row[i + k] * row0[i + k];
    if (dot < 0)
      for (std::size_t k = 0; k < 4; ++k) row[i + k] = -row[i + k];
  }
  return row;
}

// Two Richardson extrapolations (error O(h^6)) of the central difference of f(e) at e = 0.
std::vector<double> richardson_of(const std::function<std::vector<double>(double)>& f, double h) {
  auto central_of = [&](double step) {
    const std::vector<double> p = f(step), m = f(-step);
    std::vector<double> d(p.size());
    for (std::size_t i = 0; i < p.size(); ++i) d[i] = (p[i] - m[i]) / (2 * step);
    return d;
  };
  const std::vector<double> d1 = central_of(h), d2 = central_of(h / 2), d4 = central_of(h / 4);
  std::vector<double> r(d1.size());
  for (std::size_t i = 0; i < r.size(); ++i) {
    const double r1 = (4 * d2[i] - d1[i]) / 3, r2 = (4 * d4[i] - d2[i]) / 3;
    r[i] = (16 * r2 - r1) / 15;
  }
  return r;
}

// The worst column group: per ColumnKind, max |drow - richardson| over the group's max |drow|.
// A group whose tangent is below 1e-6 of the row's largest (zero in exact arithmetic: the time
// column, the extras, M under uniform gravity, whose moments about the CM cancel) is measured
// against the row's largest tangent instead: its difference is rounding of cancelling terms.
struct GroupGap {
  double rel = 0;
  std::string column;
};

GroupGap worst_group(const OutputLayout& layout, const std::vector<double>& drow,
                     const std::vector<double>& ref) {
  const std::vector<Column>& cols = layout.columns();
  double overall = 0;
  for (double v : drow) overall = std::max(overall, std::abs(v));
  GroupGap worst;
  for (std::size_t i = 0; i < cols.size(); ++i) {
    double scale = 0;
    for (std::size_t k = 0; k < cols.size(); ++k)
      if (cols[k].kind == cols[i].kind) scale = std::max(scale, std::abs(drow[k]));
    if (scale < 1e-6 * overall || scale == 0) scale = std::max(overall, 1e-300);
    const double rel = std::abs(drow[i] - ref[i]) / scale;
    if (rel > worst.rel) worst = {rel, cols[i].name};
  }
  return worst;
}

TreeTangent combined(const TreeTangent& d1, const TreeTangent& d2, double c) {  // d1 + c d2
  TreeTangent d = d1;
  d.dp_NoBo_N += c * d2.dp_NoBo_N;
  d.dtheta_B += c * d2.dtheta_B;
  d.dv_NBo_N += c * d2.dv_NBo_N;
  d.dw_NB_B += c * d2.dw_NB_B;
  for (std::size_t j = 0; j < d.joints.size(); ++j) {
    d.joints[j].angle += c * d2.joints[j].angle;
    d.joints[j].rate += c * d2.joints[j].rate;
    d.joints[j].angle2 += c * d2.joints[j].angle2;
    d.joints[j].rate2 += c * d2.joints[j].rate2;
    d.joints[j].dtheta_J += c * d2.joints[j].dtheta_J;
    d.joints[j].w_PC_C += c * d2.joints[j].w_PC_C;
  }
  for (std::size_t b = 0; b < d.eta.size(); ++b) {
    d.eta[b] += c * d2.eta[b];
    d.eta_rate[b] += c * d2.eta_rate[b];
  }
  return d;
}

// output_row_tangent() on one case: row is output_row(pack(s)) bit for bit; drow finite, its
// extras and time column zero, and per column group equal to the Richardson difference of
// output_row(pack(moved_along(s, ds, +-h))) to tol (h at most 5e-3: chain3's |H| at h = 1e-2 is
// off by 1.2e-10, falling as h^6 to 1.9e-12 at 5e-3); linear in ds. Returns the worst gap.
GroupGap check_output_case(const Case& c, int states, double tol) {
  std::unique_ptr<Engine> e = make_newton_euler_engine(c.system, c.options);
  const OutputLayout& layout = e->layout();
  std::mt19937 rng(4242);
  GroupGap worst;
  for (int k = 0; k < states; ++k) {
    const TreeState s = random_state2(c.system, rng);
    const TreeTangent ds = random_tangent(c.system, rng), ds2 = random_tangent(c.system, rng);
    std::vector<double> row(layout.size()), drow(layout.size());
    REQUIRE(e->output_row_tangent(c.t, s, ds, row.data(), drow.data()));
    const std::vector<double> row_ref = row_at(*e, c.t, s);
    for (std::size_t i = 0; i < row.size(); ++i) {
      INFO(c.name << ", state " << k << ", column " << layout.columns()[i].name);
      REQUIRE(std::isfinite(drow[i]));
      CHECK(row[i] == row_ref[i]);
    }
    CHECK(drow[0] == 0.0);
    for (std::size_t i = layout.pinned_size(); i < layout.size(); ++i) CHECK(drow[i] == 0.0);
    const std::vector<double> ref =
        richardson_of([&](double h) { return row_along(*e, c.t, s, ds, h, row_ref); }, std::min(c.rich_h, 5e-3));
    const GroupGap g = worst_group(layout, drow, ref);
    INFO(c.name << ", state " << k << ": worst column " << g.column << ", " << g.rel);
    CHECK(g.rel < tol);
    if (g.rel > worst.rel) worst = g;
    // Linear in ds: drow(ds + 2 ds2) = drow(ds) + 2 drow(ds2) to rounding.
    std::vector<double> drow2(layout.size()), drow12(layout.size());
    REQUIRE(e->output_row_tangent(c.t, s, ds2, row.data(), drow2.data()));
    REQUIRE(e->output_row_tangent(c.t, s, combined(ds, ds2, 2.0), row.data(), drow12.data()));
    double scale = 0, gap = 0;
    for (std::size_t i = 0; i < drow.size(); ++i) {
      scale = std::max({scale, std::abs(drow[i]), std::abs(drow2[i])});
      gap = std::max(gap, std::abs(drow12[i] - drow[i] - 2 * drow2[i]));
    }
    CHECK(gap <= 1e-12 * scale);
  }
  return worst;
}

// A random state x of the engine's own coordinates off its constraint manifold and off the unit
// quaternions: pack(s) plus a random 1e-3 perturbation, each body's quaternion scaled by 1.2.
std::vector<double> off_manifold_state(Engine& e, const System& system, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(random_state2(system, rng), x.data());
  for (double& v : x) v += 1e-3 * u(rng);
  for (int i = 0; i < e.state_size(); ++i)
    if (e.state_label(i).size() > 3 && e.state_label(i).substr(e.state_label(i).size() - 3, 2) == ".q")
      x[static_cast<std::size_t>(i)] *= 1.2;
  return x;
}

struct RhsGap {
  double rel = 0;
  std::string label;
};

// rhs_tangent() on one case at random states on the manifold (pack) and off it: xdot is rhs(x)
// bit for bit; dxdot equals the Richardson difference of rhs(x +- h dx) to tol of max |dxdot|
// (h at most 2e-3: dx moves every coordinate, and at 1e-2 one state of the mixed tree's spherical
// spring crosses the rotation vector's branch at pi, where rhs() jumps);
// linear in dx; on the manifold, with dx the differenced d pack(s + e ds)/de, the speed rows
// equal accelerations_tangent()'s accelerations (to the difference's accuracy).
RhsGap check_rhs_case(const Case& c, int states, double tol) {
  std::unique_ptr<Engine> e = make_newton_euler_engine(c.system, c.options);
  const auto n = static_cast<std::size_t>(e->state_size());
  std::mt19937 rng(5150);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  RhsGap worst;
  auto rhs_at = [&](const std::vector<double>& x) {
    std::vector<double> xd(n);
    e->rhs(c.t, x.data(), xd.data());
    return xd;
  };
  for (int k = 0; k < states; ++k) {
    for (int off = 0; off < 2; ++off) {
      std::vector<double> x(n);
      if (off) x = off_manifold_state(*e, c.system, rng);
      else e->pack(random_state2(c.system, rng), x.data());
      std::vector<double> dx(n);
      for (double& v : dx) v = u(rng);
      std::vector<double> xdot(n), dxdot(n);
      REQUIRE(e->rhs_tangent(c.t, x.data(), dx.data(), xdot.data(), dxdot.data()));
      const std::vector<double> xdot_ref = rhs_at(x);
      for (std::size_t i = 0; i < n; ++i) {
        INFO(c.name << ", " << e->state_label(static_cast<int>(i)));
        REQUIRE(std::isfinite(dxdot[i]));
        CHECK(xdot[i] == xdot_ref[i]);
      }
      const std::vector<double> ref = richardson_of(
          [&](double h) {
            std::vector<double> xh = x;
            for (std::size_t i = 0; i < n; ++i) xh[i] += h * dx[i];
            return rhs_at(xh);
          },
          std::min(c.rich_h, 2e-3));
      const double scale = max_abs(dxdot);
      REQUIRE(scale > 0);
      RhsGap g;
      for (std::size_t i = 0; i < n; ++i) {
        const double rel = std::abs(dxdot[i] - ref[i]) / scale;
        if (rel > g.rel) g = {rel, e->state_label(static_cast<int>(i))};
      }
      INFO(c.name << (off ? ", off the manifold" : ", packed") << ", state " << k << ": worst row " << g.label
                  << ", " << g.rel);
      CHECK(g.rel < tol);
      if (g.rel > worst.rel) worst = g;
      // Linear in dx.
      std::vector<double> dx2(n), dx12(n), d2(n), d12(n), unused(n);
      for (std::size_t i = 0; i < n; ++i) {
        dx2[i] = u(rng);
        dx12[i] = dx[i] + 2 * dx2[i];
      }
      REQUIRE(e->rhs_tangent(c.t, x.data(), dx2.data(), unused.data(), d2.data()));
      REQUIRE(e->rhs_tangent(c.t, x.data(), dx12.data(), unused.data(), d12.data()));
      double lin = 0;
      for (std::size_t i = 0; i < n; ++i) lin = std::max(lin, std::abs(d12[i] - dxdot[i] - 2 * d2[i]));
      CHECK(lin <= 1e-12 * std::max(scale, max_abs(d2)));
    }
  }
  return worst;
}

}  // namespace

TEST_CASE("newton-euler output tangent: agrees with Richardson differences per column group",
          "[newton_euler][tangent][output_tangent]") {
  // Every covered case: rigid trees of every joint type with springs, dampers and motors (P),
  // a prescribed joint (its .torque column) and a prescribed base, uniform gravity, orbits
  // (roll, pitch, yaw, wox..woz, J), flexible and stiffened bodies, Baumgarte.
  for (const Case& c : covered_cases()) check_output_case(c, 3, 1e-10);
}

TEST_CASE("newton-euler rhs tangent: agrees with Richardson differences on and off the manifold",
          "[newton_euler][tangent][rhs_tangent]") {
  for (const Case& c : covered_cases()) check_rhs_case(c, 2, 1e-10);
}

TEST_CASE("newton-euler rhs tangent: its speed rows are accelerations_tangent's along d pack",
          "[newton_euler][tangent][rhs_tangent]") {
  // x(e) = pack(s + e ds): dx = x'(0) by a Richardson difference (~1e-11); the velocity block of
  // rhs_tangent(x(0), dx) is d nu'/de, which accelerations_tangent() gives as a_NBo_N, wdot_NB_B,
  // eta_ddot (the state's velocities are the KKT unknowns, newton_euler.hpp).
  for (const Case& c : covered_cases()) {
    std::unique_ptr<Engine> e = make_newton_euler_engine(c.system, c.options);
    const auto n = static_cast<std::size_t>(e->state_size());
    std::mt19937 rng(77);
    const TreeState s = random_state2(c.system, rng);
    const TreeTangent ds = random_tangent(c.system, rng);
    const std::vector<double> dx = richardson_of(
        [&](double h) {
          std::vector<double> x(n);
          e->pack(moved_along(s, ds, h), x.data());
          return x;
        },
        c.rich_h);
    std::vector<double> x(n), xdot(n), dxdot(n);
    e->pack(s, x.data());
    REQUIRE(e->rhs_tangent(c.t, x.data(), dx.data(), xdot.data(), dxdot.data()));
    TreeAccel a, da;
    REQUIRE(e->accelerations_tangent(c.t, s, ds, a, da));
    std::vector<double> speeds;  // the velocity block in body order: [a; wdot; eta'']
    for (std::size_t b = 0; b < da.a_NBo_N.size(); ++b) {
      speeds.insert(speeds.end(), da.a_NBo_N[b].data(), da.a_NBo_N[b].data() + 3);
      speeds.insert(speeds.end(), da.wdot_NB_B[b].data(), da.wdot_NB_B[b].data() + 3);
      speeds.insert(speeds.end(), da.eta_ddot[b].data(), da.eta_ddot[b].data() + da.eta_ddot[b].size());
    }
    const std::vector<double> tail(dxdot.end() - static_cast<std::ptrdiff_t>(speeds.size()), dxdot.end());
    INFO(c.name);
    CHECK(max_abs_diff(tail, speeds) <= 1e-8 * max_abs(speeds));
  }
}

TEST_CASE("newton-euler output and rhs tangents: every committed scene", "[newton_euler][tangent]") {
  // Nothing this engine models returns false (its constructor decides: every joint type has Cx
  // verbs). Each committed scene deformed, a random tangent: Richardson agreement as above.
  for (const std::string& file : test::committed_scenes()) {
    const System sys = read_scene(file);
    INFO(file);
    std::mt19937 rng(43);
    Case c{file, sys, 0.0, {}, 2e-3, 1e-10};
    std::unique_ptr<Engine> e = make_newton_euler_engine(sys, EngineOptions{});
    TreeState s = TreeState::initial(sys);
    deform(sys, s, rng, 0.02, 0.1);
    const TreeTangent ds = random_tangent(sys, rng);
    std::vector<double> row(e->layout().size()), drow(e->layout().size());
    REQUIRE(e->output_row_tangent(0.0, s, ds, row.data(), drow.data()));
    const std::vector<double> ref =
        richardson_of([&](double h) { return row_along(*e, 0.0, s, ds, h, row); }, c.rich_h);
    // |H| (column H) near or at H = 0 (scenes at rest): its second derivative |dH|^2 / |H| spoils
    // the difference, so H is checked as the chain rule of Hx, Hy, Hz (themselves checked with
    // the other columns): H . dH / |H|, and 0 at H = 0 (cx_row_writer.cpp).
    const OutputLayout& layout = e->layout();
    const auto iH = static_cast<std::size_t>(layout.H()), iHv = static_cast<std::size_t>(layout.H_vector());
    const Vector3d H(row[iHv], row[iHv + 1], row[iHv + 2]), dH(drow[iHv], drow[iHv + 1], drow[iHv + 2]);
    if (H.norm() == 0) CHECK(drow[iH] == 0.0);
    else CHECK(std::abs(drow[iH] - H.dot(dH) / H.norm()) <= 1e-13 * dH.norm());
    std::vector<double> drow_noH = drow, ref_noH = ref;
    drow_noH[iH] = ref_noH[iH] = 0.0;
    const GroupGap g = worst_group(layout, drow_noH, ref_noH);
    INFO("output: worst column " << g.column << ", " << g.rel);
    CHECK(g.rel < 1e-10);
    const auto n = static_cast<std::size_t>(e->state_size());
    std::vector<double> x(n), dx(n), xdot(n), dxdot(n);
    e->pack(s, x.data());
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (double& v : dx) v = u(rng);
    REQUIRE(e->rhs_tangent(0.0, x.data(), dx.data(), xdot.data(), dxdot.data()));
    const std::vector<double> rref = richardson_of(
        [&](double h) {
          std::vector<double> xh = x, xd(n);
          for (std::size_t i = 0; i < n; ++i) xh[i] += h * dx[i];
          e->rhs(0.0, xh.data(), xd.data());
          return xd;
        },
        c.rich_h);
    const double rel = max_abs_diff(dxdot, rref) / max_abs(dxdot);
    INFO("rhs: " << rel);
    // iftomm_pendulum's bob (1e-6 kg m^2 against 1 kg, its scene file: the constraint solve's
    // conditioning) leaves 5e-10 in bob.wy's row whatever the step (2e-2 .. 5e-4): the rounding
    // of both solves, tangent's and difference's, not truncation. 1e-10 elsewhere.
    CHECK(rel < (file.find("iftomm_pendulum") != std::string::npos ? 2e-9 : 1e-10));
  }
}

// The figures of the two tests above (hidden: run by its tag).
TEST_CASE("newton-euler output and rhs tangents: report", "[.output_tangent_report]") {
  for (const Case& c : covered_cases()) {
    const GroupGap g = check_output_case(c, 3, 1e-10);
    const RhsGap r = check_rhs_case(c, 2, 1e-10);
    std::printf("%-42s output %.1e (%s)   rhs %.1e (%s)\n", c.name.c_str(), g.rel, g.column.c_str(), r.rel,
                r.label.c_str());
  }
}

