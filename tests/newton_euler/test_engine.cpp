// The Newton-Euler engine at single states: pack, accelerations, constraint forces, outputs and
// input errors. Acceleration-level checks are written here from scratch (N-frame derivatives),
// not with the engine's own constraint rows.
#include "formulations/newton_euler/newton_euler.hpp"

#include "core/errors.hpp"
#include "core/rotation.hpp"
#include "tests/newton_euler/ne_systems.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <random>

using namespace crossdyn;
using namespace crossdyn::test::ne;
using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

namespace {

struct Packed {
  std::unique_ptr<Engine> engine;
  std::vector<double> x, row;
};

Packed packed(const System& s, const TreeState& ts, const EngineOptions& o = {}) {
  Packed p;
  p.engine = make_newton_euler_engine(s, o);
  p.x.resize(static_cast<std::size_t>(p.engine->state_size()));
  p.row.resize(p.engine->columns().size());
  p.engine->pack(ts, p.x.data());
  p.engine->output_row(0.0, p.x.data(), p.row.data());
  return p;
}

double col(const Packed& p, const std::string& name) {
  return p.row[static_cast<std::size_t>(column(*p.engine, name))];
}

}  // namespace

TEST_CASE("newton-euler: pack puts every joint on its constraint manifold and keeps the joint "
          "coordinates", "[newton_euler][engine]") {
  std::mt19937 rng(5);
  for (const System& s : {mixed_tree(), chain(5), spear1()}) {
    for (int trial = 0; trial < 5; ++trial) {
      const TreeState ts = random_state(s, rng);
      const Packed p = packed(s, ts);
      INFO(s.name << " trial " << trial);
      // Positions are O(1-10) m: round-off in the tree kinematics is ~1e-15 m.
      CHECK(col(p, "constraint.pos") <= 1e-14);
      CHECK(col(p, "constraint.vel") <= 1e-14);
      CHECK(col(p, "constraint.ang") <= 1e-14);
      CHECK(col(p, "constraint.angvel") <= 1e-14);
      for (std::size_t j = 1; j < s.joints.size(); ++j) {
        const Joint& J = s.joints[j];
        if (J.type == JointType::Revolute) {
          // Angles up to 6 rad: the continuous angle, not the wrapped one.
          CHECK(std::abs(col(p, J.name + ".angle") - ts.joints[j].angle) <= 1e-13);
          CHECK(std::abs(col(p, J.name + ".rate") - ts.joints[j].rate) <= 1e-14);
        } else if (J.type == JointType::Spherical) {
          CHECK(std::abs(col(p, J.name + ".wx") - ts.joints[j].w_PC_C.x()) <= 1e-14);
          CHECK(std::abs(col(p, J.name + ".wy") - ts.joints[j].w_PC_C.y()) <= 1e-14);
          CHECK(std::abs(col(p, J.name + ".wz") - ts.joints[j].w_PC_C.z()) <= 1e-14);
        }
      }
      // The base attitude and rate are the TreeState's; quaternions are output with qw >= 0.
      const std::string base = s.bodies[static_cast<std::size_t>(s.base_body())].name;
      const Quaterniond q = rot::canonical(ts.q_NB);
      CHECK(std::abs(col(p, base + ".qw") - q.w()) <= 1e-15);
      CHECK(std::abs(col(p, base + ".qx") - q.x()) <= 1e-15);
      CHECK(std::abs(col(p, base + ".wz") - ts.w_NB_B.z()) <= 1e-15);
      for (const Body& b : s.bodies) CHECK(col(p, b.name + ".qw") >= 0);
    }
  }
}

TEST_CASE("newton-euler: pack makes the total linear momentum zero when the scene asks",
          "[newton_euler][engine]") {
  std::mt19937 rng(9);
  System s = mixed_tree();
  s.zero_linear_momentum = true;
  const Packed p = packed(s, random_state(s, rng));
  Vector3d momentum = Vector3d::Zero();
  double speed = 0;
  for (const Body& b : s.bodies) {
    const BodyState bs = body_state(*p.engine, p.x.data(), b.name);
    momentum += b.mass * bs.v_N;
    speed = std::max(speed, b.mass * bs.v_N.norm());
  }
  CHECK(speed > 1.0);  // the bodies do move
  CHECK(momentum.norm() <= 1e-13 * speed);
}

// Independent acceleration-level constraints (N-frame derivatives of the joint conditions):
//   joint point: a_P + R_NP (alpha_P x r_P + w_P x (w_P x r_P)) = the same for C;
//   revolute: w_C^N - w_P^N = rate a_N with a_N = R_NP a_P, so
//             R_NC alpha_C - R_NP alpha_P = rate'' a_N + rate (w_P^N x a_N);
//   fixed: R_NC alpha_C - R_NP alpha_P = 0 (relative rate zero);
//   spherical: wdot_PC_C = R_CN (R_NC alpha_C - R_NP alpha_P) - w_C x w_PC_C.
TEST_CASE("newton-euler: accelerations satisfy the acceleration-level constraints",
          "[newton_euler][engine]") {
  std::mt19937 rng(21);
  for (const System& s : {mixed_tree(), chain(5), spear1()}) {
    for (int trial = 0; trial < 5; ++trial) {
      const TreeState ts = random_state(s, rng);
      Packed p = packed(s, ts);
      TreeAccel a;
      p.engine->accelerations(0.3, p.x.data(), a);
      double scale = 1;
      for (std::size_t b = 0; b < s.bodies.size(); ++b)
        scale = std::max({scale, a.a_NBo_N[b].norm(), a.wdot_NB_B[b].norm()});
      for (std::size_t j = 1; j < s.joints.size(); ++j) {
        const Joint& J = s.joints[j];
        const auto P = static_cast<std::size_t>(J.parent), C = static_cast<std::size_t>(J.child);
        const BodyState bp = body_state(*p.engine, p.x.data(), s.bodies[P].name);
        const BodyState bc = body_state(*p.engine, p.x.data(), s.bodies[C].name);
        INFO(s.name << " trial " << trial << " joint " << J.name);
        const Vector3d acc_J_P = a.a_NBo_N[P] + bp.R_NB * (a.wdot_NB_B[P].cross(J.p_PoJ_P) +
                                                           bp.w_B.cross(bp.w_B.cross(J.p_PoJ_P)));
        const Vector3d acc_J_C = a.a_NBo_N[C] + bc.R_NB * (a.wdot_NB_B[C].cross(J.p_CoJ_C) +
                                                           bc.w_B.cross(bc.w_B.cross(J.p_CoJ_C)));
        CHECK((acc_J_P - acc_J_C).norm() <= 1e-12 * scale);
        const Vector3d rel_alpha_N = bc.R_NB * a.wdot_NB_B[C] - bp.R_NB * a.wdot_NB_B[P];
        const Vector3d wP_N = bp.R_NB * bp.w_B;
        if (J.type == JointType::Revolute) {
          const Vector3d a_N = bp.R_NB * J.axis_P.normalized();
          const double rate = ts.joints[j].rate;
          const Vector3d rest = rel_alpha_N - rate * wP_N.cross(a_N);
          CHECK(rest.cross(a_N).norm() <= 1e-12 * scale);
          CHECK(std::abs(a.angle_ddot[j] - rest.dot(a_N)) <= 1e-12 * scale);
        } else if (J.type == JointType::Fixed) {
          CHECK(rel_alpha_N.norm() <= 1e-12 * scale);
        } else if (J.type == JointType::Spherical) {
          const Vector3d expected =
              bc.R_NB.transpose() * rel_alpha_N - bc.w_B.cross(ts.joints[j].w_PC_C);
          CHECK((a.wdot_PC_C[j] - expected).norm() <= 1e-12 * scale);
        }
      }
    }
  }
}

TEST_CASE("newton-euler: joint accelerations are the time derivatives of the joint rates",
          "[newton_euler][engine]") {
  std::mt19937 rng(33);
  const System s = mixed_tree();
  Packed p = packed(s, random_state(s, rng));
  Engine& e = *p.engine;
  const std::size_t n = p.x.size();
  std::vector<double> xdot(n), xp(n), xm(n), rp(p.row.size()), rm(p.row.size());
  e.rhs(0.0, p.x.data(), xdot.data());
  TreeAccel a;
  e.accelerations(0.0, p.x.data(), a);
  // Central difference along the flow, step 1e-6 s: truncation ~1e-12, round-off ~1e-10.
  const double h = 1e-6;
  for (std::size_t i = 0; i < n; ++i) {
    xp[i] = p.x[i] + h * xdot[i];
    xm[i] = p.x[i] - h * xdot[i];
  }
  e.output_row(0.0, xp.data(), rp.data());
  e.output_row(0.0, xm.data(), rm.data());
  auto fd = [&](const std::string& c) {
    const auto i = static_cast<std::size_t>(column(e, c));
    return (rp[i] - rm[i]) / (2 * h);
  };
  CHECK(std::abs(fd("shoulder.rate") - a.angle_ddot[1]) <= 1e-7 * (1 + std::abs(a.angle_ddot[1])));
  CHECK(std::abs(fd("finger.rate") - a.angle_ddot[4]) <= 1e-7 * (1 + std::abs(a.angle_ddot[4])));
  const Vector3d fd_w(fd("wrist.wx"), fd("wrist.wy"), fd("wrist.wz"));
  CHECK((fd_w - a.wdot_PC_C[2]).norm() <= 1e-7 * (1 + a.wdot_PC_C[2].norm()));
  const Vector3d fd_hub(fd("hub.wx"), fd("hub.wy"), fd("hub.wz"));
  CHECK((fd_hub - a.wdot_NB_B[0]).norm() <= 1e-7 * (1 + a.wdot_NB_B[0].norm()));
}

// SPEAR-1 at its initial state: no external force acts on a boom, so the hinge force IS the
// boom's m a; the boom's Euler equation about its CM balances the hinge force's moment and the
// hinge's moment about the joint point; the main body carries both reactions; with no spring,
// damper or motor the moment has no axis component. The loads are the pinned <joint>.Fx .. .Mz:
// the child's (boom's) frame, about the joint point.
TEST_CASE("newton-euler: hinge constraint forces on spear1 are each body's m a and I alpha",
          "[newton_euler][engine][forces]") {
  const System s = spear1();
  Packed p = packed(s, TreeState::initial(s));
  TreeAccel a;
  p.engine->accelerations(0.0, p.x.data(), a);
  const BodyState main = body_state(*p.engine, p.x.data(), "main");
  Vector3d reaction_N = Vector3d::Zero();
  for (int k = 1; k <= 2; ++k) {
    const std::string hinge = "hinge" + std::to_string(k);
    const Body& boom = s.bodies[static_cast<std::size_t>(k)];
    const Joint& J = s.joints[static_cast<std::size_t>(k)];
    const BodyState bs = body_state(*p.engine, p.x.data(), boom.name);
    const Vector3d F_C(col(p, hinge + ".Fx"), col(p, hinge + ".Fy"), col(p, hinge + ".Fz"));
    const Vector3d M_C(col(p, hinge + ".Mx"), col(p, hinge + ".My"), col(p, hinge + ".Mz"));
    const Vector3d F_N = bs.R_NB * F_C;
    const Vector3d m_a = boom.mass * a.a_NBo_N[static_cast<std::size_t>(k)];
    INFO(hinge << " F_N " << F_N.transpose() << " m a " << m_a.transpose());
    CHECK(m_a.norm() > 1.0);  // the spinning booms do pull on their hinges (~ 1e2 N)
    CHECK((F_N - m_a).norm() <= 1e-12 * m_a.norm());
    // Euler: I alpha + w x I w = (r_C x F) + M_J, in boom axes.
    const Vector3d& alpha = a.wdot_NB_B[static_cast<std::size_t>(k)];
    const Vector3d lhs = boom.I_BBo_B * alpha + bs.w_B.cross(boom.I_BBo_B * bs.w_B);
    const Vector3d rhs = J.p_CoJ_C.cross(F_C) + M_C;
    CHECK((lhs - rhs).norm() <= 1e-12 * (1 + lhs.norm()));
    const Vector3d axis_C = bs.R_NB.transpose() * (main.R_NB * J.axis_P);
    CHECK(std::abs(M_C.dot(axis_C)) <= 1e-12 * (1 + M_C.norm()));
    reaction_N -= F_N;
  }
  const Vector3d m_a_main = s.bodies[0].mass * a.a_NBo_N[0];
  CHECK((m_a_main - reaction_N).norm() <= 1e-12 * reaction_N.norm());
  // Symmetric deployment: the two hinge forces mirror each other across main's x-z plane (both
  // booms at angle 0: their frames are main's).
  CHECK(std::abs(col(p, "hinge1.Fx") - col(p, "hinge2.Fx")) <= 1e-12 * std::abs(col(p, "hinge1.Fx")));
  CHECK(std::abs(col(p, "hinge1.Fy") + col(p, "hinge2.Fy")) <= 1e-12 * std::abs(col(p, "hinge1.Fx")));
}

// Two equal bodies (mass m, CMs 2d apart, joint midway) turning rigidly at rate W about z, a
// principal axis through the system CM: a steady rotation. Each CM circles the system CM at radius
// d, so the joint pulls the child toward the parent with m W^2 d. With the revolute variant the
// bodies' inertia tensors carry opposite products I_xz = +-c, and the steady turn needs the couple
// w x I w = (0, c W^2, 0) on the child, which only the hinge's constraint moment can supply.
// (The pinned loads are in the child's frame, here the parent's: the joint is at zero.)
TEST_CASE("newton-euler: joint constraint force and moment of a steadily turning pair match the "
          "closed form", "[newton_euler][engine][forces]") {
  const double m = 5, d = 1.5, W = 0.8, c = 0.3;
  for (JointType type : {JointType::Spherical, JointType::Revolute}) {
    System s;
    s.name = "pair";
    Matrix3d I_P = Vector3d(2, 3, 4).asDiagonal(), I_C = I_P;
    if (type == JointType::Revolute) {
      I_P(0, 2) = I_P(2, 0) = -c;
      I_C(0, 2) = I_C(2, 0) = c;
    }
    s.bodies = {make_body("a", m, I_P), make_body("b", m, I_C)};
    Joint base = free_joint(0);
    base.w_NB_B0 = Vector3d(0, 0, W);
    Joint j;
    j.name = "j";
    j.type = type;
    j.parent = 0;
    j.child = 1;
    j.p_PoJ_P = Vector3d(d, 0, 0);
    j.p_CoJ_C = Vector3d(-d, 0, 0);
    j.axis_P = Vector3d::UnitZ();
    s.joints = {base, j};
    Packed p = packed(s, TreeState::initial(s));
    TreeAccel a;
    p.engine->accelerations(0.0, p.x.data(), a);
    INFO("joint type " << static_cast<int>(type));
    const double f = m * W * W * d;
    CHECK(std::abs(col(p, "j.Fx") + f) <= 1e-13 * f);
    CHECK(std::abs(col(p, "j.Fy")) <= 1e-13 * f);
    CHECK(std::abs(col(p, "j.Fz")) <= 1e-13 * f);
    CHECK(std::abs(col(p, "j.Mx")) <= 1e-13);
    CHECK(std::abs(col(p, "j.My") - (type == JointType::Revolute ? c * W * W : 0.0)) <= 1e-13);
    CHECK(std::abs(col(p, "j.Mz")) <= 1e-13);
    for (int b = 0; b < 2; ++b) {
      CHECK(a.wdot_NB_B[static_cast<std::size_t>(b)].norm() <= 1e-13);
      CHECK(std::abs(a.a_NBo_N[static_cast<std::size_t>(b)].x() - (b == 0 ? 1 : -1) * W * W * d) <= 1e-13);
    }
  }
}

TEST_CASE("newton-euler: test_inertia_scale scales the inertia tensors and not the masses",
          "[newton_euler][engine]") {
  std::mt19937 rng(4);
  const System s = mixed_tree();
  const TreeState ts = random_state(s, rng);
  EngineOptions scaled;
  scaled.test_inertia_scale = 2.0;
  const Packed p1 = packed(s, ts), p2 = packed(s, ts, scaled);
  // Velocities after pack do not depend on inertia; the rotational kinetic energy doubles.
  double rotational = 0;
  for (const Body& b : s.bodies) {
    const Vector3d w(col(p1, b.name + ".wx"), col(p1, b.name + ".wy"), col(p1, b.name + ".wz"));
    rotational += 0.5 * w.dot(b.I_BBo_B * w);
  }
  CHECK(rotational > 0.1);
  CHECK(std::abs((col(p2, "E") - col(p1, "E")) - rotational) <= 1e-12 * col(p1, "E"));
}

TEST_CASE("newton-euler: state labels, columns and input errors", "[newton_euler][engine]") {
  const System s = spear1();
  auto e = make_newton_euler_engine(s, {});
  CHECK(std::string(e->name()) == "newton-euler");
  CHECK(e->state_size() == 39);
  CHECK_NOTHROW(label_index(*e, "boom1.vx"));
  CHECK_NOTHROW(label_index(*e, "main.qw"));
  CHECK(e->state_label(label_index(*e, "main.wz")) == "main.wz");
  const std::vector<std::string> pinned = pinned_columns(s);
  REQUIRE(e->columns().size() > pinned.size());
  for (std::size_t i = 0; i < pinned.size(); ++i) CHECK(e->columns()[i] == pinned[i]);
  for (const char* c : {"hinge1.Fx", "hinge2.Mz", "constraint.pos", "constraint.vel"})
    CHECK_NOTHROW(column(*e, c));

  System flexible = s;
  flexible.bodies[1].flex = FlexBody{};
  CHECK_THROWS_WITH(make_newton_euler_engine(flexible, {}), Catch::Contains("at least one node") &&
                                                                Catch::Contains("boom1"));
  EngineOptions bad;
  // An unknown stabilisation name is refused where it is parsed (core/names.hpp).
  CHECK_THROWS_WITH(bad.stabilization = "magic",
                    "unknown stabilization 'magic'; known: projection, baumgarte, none");
  bad = {};
  bad.baumgarte_beta = -1;
  CHECK_THROWS_AS(make_newton_euler_engine(s, bad), InputError);
  bad = {};
  bad.test_inertia_scale = 0;
  CHECK_THROWS_AS(make_newton_euler_engine(s, bad), InputError);
}

// Projection in after_step(): a state pushed off the manifold comes back (positions by Newton
// iterations, velocities in one step), the CM and the linear momentum do not move, and a state
// already on the manifold is left alone (after_step returns false).
TEST_CASE("newton-euler: projection restores the constraints without moving the CM",
          "[newton_euler][engine][stabilization]") {
  std::mt19937 rng(8);
  std::normal_distribution<double> noise(0.0, 1e-4);
  const System s = mixed_tree();
  Packed p = packed(s, random_state(s, rng));
  Engine& e = *p.engine;
  CHECK_FALSE(e.after_step(0.0, p.x.data()));
  auto cm = [&](bool velocity) {
    Vector3d sum = Vector3d::Zero();
    for (const Body& b : s.bodies) {
      const BodyState bs = body_state(e, p.x.data(), b.name);
      sum += b.mass * (velocity ? bs.v_N : bs.p_N);
    }
    return sum;
  };
  for (double& v : p.x) v += noise(rng);
  const Vector3d cm0 = cm(false), mom0 = cm(true);
  e.output_row(0.0, p.x.data(), p.row.data());
  CHECK(col(p, "constraint.pos") > 1e-5);
  CHECK(e.after_step(0.0, p.x.data()));
  e.output_row(0.0, p.x.data(), p.row.data());
  // Newton stops at 1e-14 per metre of model size (~3 m here); velocities are exact to round-off.
  CHECK(col(p, "constraint.pos") <= 1e-13);
  CHECK(col(p, "constraint.ang") <= 1e-13);
  CHECK(col(p, "constraint.vel") <= 1e-13);
  CHECK(col(p, "constraint.angvel") <= 1e-13);
  CHECK((cm(false) - cm0).norm() <= 1e-12);
  CHECK((cm(true) - mom0).norm() <= 1e-12);
  CHECK_FALSE(e.after_step(0.0, p.x.data()));
}
