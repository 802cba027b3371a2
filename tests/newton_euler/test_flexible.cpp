// Flexible (modal) bodies in the Newton-Euler engine, integrated with crossdyn::simulate and at
// single states: the rigid limit, a free vibration in closed form, conservation of H and E with
// joints at nodes, damping and motor power balances, projection with modal coordinates.
#include "formulations/newton_euler/newton_euler.hpp"

#include "core/integrate.hpp"
#include "core/rotation.hpp"
#include "tests/newton_euler/ne_run.hpp"
#include "tests/newton_euler/ne_systems.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

using namespace crossdyn;
using namespace crossdyn::test::ne;
using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;
using Eigen::VectorXd;

namespace {

RunResult run(const System& s, const TreeState& ts, double duration, double tol,
              const EngineOptions& o = {}, double output_step = 0) {
  return run_ne(s, ts, "rkf78", tol, duration, output_step > 0 ? output_step : duration / 100, o);
}

// The flexible tree from a deformed, spinning state: eta up to 0.1 m and rates up to 0.3 m/s.
TreeState deformed_tree_state(const System& s, unsigned seed) {
  std::mt19937 rng(seed);
  TreeState ts = TreeState::initial(s);
  deform(s, ts, rng, 0.1, 0.3);
  return ts;
}

}  // namespace

// H with no external torque, E with no dampers or motors (springs and modal stiffness are
// conservative, E includes their potential): rkf78 at 1e-12 over 10 s with large deformation
// (eta up to 0.1 m on a 4 m beam, slopes up to 0.15 rad), base rotation, and every joint type at
// nodes of flexible parents and children. Measured: see the INFO line.
TEST_CASE("newton-euler flex: H and E are conserved with joints at nodes of flexible bodies",
          "[newton_euler][flexible][simulation]") {
  const System s = flexible_tree();
  const TreeState ts = deformed_tree_state(s, 1);
  for (const char* stab : {"projection", "baumgarte", "none"}) {
    EngineOptions o;
    o.stabilization = stab;
    const RunResult r = run(s, ts, 10, 1e-12, o);
    const auto H = series(r, "H"), E = series(r, "E");
    const auto q = series(r, "beam.qx1"), angle = series(r, "hinge.angle");
    INFO(stab << ": H drift " << max_abs_change(H) / H.front() << ", E drift "
              << max_abs_change(E) / E.front() << ", constraint.pos " << max_of(series(r, "constraint.pos")));
    CHECK(max_abs_change(q) > 0.02);      // the beam does deform
    CHECK(max_abs_change(angle) > 0.5);   // and the payload does turn
    CHECK(max_abs_change(H) <= 1e-10 * H.front());
    CHECK(max_abs_change(E) <= 1e-10 * E.front());
  }
}


namespace {

// A body's state read through the engine's labels, with its modal coordinates.
struct FlexState {
  BodyState b;
  VectorXd eta, rate;
};

FlexState flex_state(const Engine& e, const double* x, const System& s, int body) {
  FlexState f;
  f.b = body_state(e, x, s.bodies[static_cast<std::size_t>(body)].name);
  std::tie(f.eta, f.rate) = modal_state(e, x, s, body);
  return f;
}

// Node i of a flexible body: position from Bo (body frame), deformed, and its body-frame rate.
Vector3d node_r(const FlexNode& nd, const VectorXd& eta) {
  return eta.size() ? Vector3d(nd.p_BoNi_B + nd.Phi_B * eta) : nd.p_BoNi_B;
}
Vector3d node_rdot(const FlexNode& nd, const VectorXd& rate) {
  return rate.size() ? Vector3d(nd.Phi_B * rate) : Vector3d::Zero();
}

// Total linear momentum, angular momentum about the system CM and kinetic energy, summed over
// every node of every flexible body and every rigid body (docs/flexible-bodies.md "Energy").
struct Totals {
  Vector3d L = Vector3d::Zero(), H = Vector3d::Zero(), cm = Vector3d::Zero();
  double T = 0, V_modal = 0;
};

Totals node_totals(const Engine& e, const double* x, const System& s) {
  struct Element {
    double m;
    Vector3d x, v, h_spin;  // h_spin: the element's own rotational momentum (N)
  };
  std::vector<Element> el;
  Totals t;
  for (std::size_t b = 0; b < s.bodies.size(); ++b) {
    const Body& body = s.bodies[b];
    const FlexState f = flex_state(e, x, s, static_cast<int>(b));
    const Vector3d w_N = f.b.R_NB * f.b.w_B;
    if (!body.flex) {
      el.push_back({body.mass, f.b.p_N, f.b.v_N, f.b.R_NB * body.I_BBo_B * f.b.w_B});
      t.T += 0.5 * f.b.w_B.dot(body.I_BBo_B * f.b.w_B);
      continue;
    }
    for (const FlexNode& nd : body.flex->nodes) {
      const Vector3d r = node_r(nd, f.eta);
      el.push_back({nd.mass, f.b.p_N + f.b.R_NB * r,
                    f.b.v_N + w_N.cross(f.b.R_NB * r) + f.b.R_NB * node_rdot(nd, f.rate),
                    f.b.R_NB * nd.J_Ni_B * f.b.w_B});
      t.T += 0.5 * f.b.w_B.dot(nd.J_Ni_B * f.b.w_B);
    }
    if (f.eta.size()) t.V_modal += 0.5 * f.eta.dot(body.flex->K * f.eta);
  }
  double m = 0;
  Vector3d xc = Vector3d::Zero();
  for (const Element& a : el) {
    m += a.m;
    xc += a.m * a.x;
    t.L += a.m * a.v;
  }
  xc /= m;
  t.cm = xc;
  for (const Element& a : el) {
    t.H += a.m * (a.x - xc).cross(a.v) + a.h_spin;
    t.T += 0.5 * a.m * a.v.squaredNorm();
  }
  return t;
}

struct Packed {
  std::unique_ptr<Engine> engine;
  std::vector<double> x, row;
  double col(const std::string& name) const {
    return row[static_cast<std::size_t>(column(*engine, name))];
  }
  void output(double t = 0) { engine->output_row(t, x.data(), row.data()); }
};

Packed packed(const System& s, const TreeState& ts, const EngineOptions& o = {}) {
  Packed p;
  p.engine = make_newton_euler_engine(s, o);
  p.x.resize(static_cast<std::size_t>(p.engine->state_size()));
  p.row.resize(p.engine->columns().size());
  p.engine->pack(ts, p.x.data());
  p.output();
  return p;
}

// A random state of the flexible tree: random joint coordinates and base motion, eta up to 0.1 m.
TreeState random_tree_state(const System& s, std::mt19937& rng) {
  TreeState ts = random_state(s, rng);
  deform(s, ts, rng, 0.1, 0.5);
  return ts;
}

// dE/dt along the flow at the packed state, by a central difference of the E column along
// x +- h xdot (h = 1e-5 s: truncation ~1e-10 |E'''|, round-off ~1e-11 |E|).
double energy_rate(Packed& p, double t) {
  Engine& e = *p.engine;
  const std::size_t n = p.x.size();
  std::vector<double> xdot(n), xp(n), xm(n), rp(p.row.size()), rm(p.row.size());
  e.rhs(t, p.x.data(), xdot.data());
  const double h = 1e-5;
  for (std::size_t i = 0; i < n; ++i) {
    xp[i] = p.x[i] + h * xdot[i];
    xm[i] = p.x[i] - h * xdot[i];
  }
  e.output_row(t, xp.data(), rp.data());
  e.output_row(t, xm.data(), rm.data());
  const auto iE = static_cast<std::size_t>(column(e, "E"));
  return (rp[iE] - rm[iE]) / (2 * h);
}

}  // namespace

// A flexible body with no modes is a rigid body: spear1 (asymmetric deployment) with `main` and
// `boom1` given as node sets with the same mass and inertia, one hinge at a node of each, gives
// the same time histories as the rigid scene (the equations are the same, up to round-off).
TEST_CASE("newton-euler flex: a flexible body with zero modes moves as the rigid body",
          "[newton_euler][flexible][simulation]") {
  System rigid = spear1();
  rigid.joints[2].rate0 = -5.0 * std::numbers::pi / 180;
  System flex = rigid;
  {
    FlexBody f;  // main: 300 kg, diag(100, 400, 400) from two 150 kg nodes at x = +-1 m
    for (double sx : {1.0, -1.0}) {
      FlexNode nd;
      nd.name = sx > 0 ? "front" : "back";
      nd.mass = 150;
      nd.p_BoNi_B = Vector3d(sx, 0, 0);
      nd.J_Ni_B = 50 * Matrix3d::Identity();
      f.nodes.push_back(nd);
    }
    FlexNode hinge;
    hinge.name = "hinge";
    hinge.p_BoNi_B = Vector3d(6, 0, 0);
    f.nodes.push_back(hinge);
    f.K = f.D = Eigen::MatrixXd(0, 0);
    flex.bodies[0].flex = f;
    set_node_sums(flex.bodies[0]);
  }
  {
    FlexBody f;  // boom1: the sphere as one node, and its rod's end as a massless node
    FlexNode ball;
    ball.name = "ball";
    ball.mass = 10;
    ball.J_Ni_B = 10 * Matrix3d::Identity();
    FlexNode end;
    end.name = "end";
    end.p_BoNi_B = Vector3d(-2, 0, 0);
    f.nodes = {ball, end};
    flex.bodies[1].flex = f;
    set_node_sums(flex.bodies[1]);
  }
  REQUIRE((flex.bodies[0].I_BBo_B - rigid.bodies[0].I_BBo_B).norm() == 0.0);
  flex.joints[1].parent_node = 2;
  flex.joints[1].child_node = 1;
  const RunResult a = run(rigid, TreeState::initial(rigid), 5, 1e-12);
  const RunResult b = run(flex, TreeState::initial(flex), 5, 1e-12);
  REQUIRE(a.rows() == b.rows());
  double worst = 0;
  for (const std::string& c : pinned_columns(rigid)) {
    const auto x = series(a, c), y = series(b, c);
    for (std::size_t k = 0; k < x.size(); ++k) worst = std::max(worst, std::abs(x[k] - y[k]));
  }
  INFO("largest difference " << worst);
  CHECK(worst <= 1e-12);
  CHECK(std::abs(series(a, "hinge2.angle").back()) > 0.1);  // the booms did deploy
}

// Four 2 kg nodes at (+-a, 0, 0), (0, +-a, 0) and one mode moving them in and out in opposite
// phase: sum m_i Phi_i = 0, sum m_i p_i x Phi_i = 0 and (all nodes on their lines of motion)
// sum m_i r_i x Phi_i = 0 for any eta. Without rotation the mode decouples exactly:
// M_modal eta'' + K eta = 0, M_modal = sum m_i |Phi_i|^2 = 8 kg, K = 50 N/m, omega = 2.5 rad/s.
TEST_CASE("newton-euler flex: a momentum-free mode of a free body vibrates at sqrt(K / M_modal)",
          "[newton_euler][flexible][simulation]") {
  const double a = 0.8, m = 2, K = 50, eta0 = 1e-3;
  System s;
  s.name = "breathing";
  Body body;
  body.name = "cross";
  FlexBody f;
  f.mode_names = {"q1"};
  const Vector3d pos[4] = {{a, 0, 0}, {-a, 0, 0}, {0, a, 0}, {0, -a, 0}};
  const Vector3d shape[4] = {{1, 0, 0}, {-1, 0, 0}, {0, -1, 0}, {0, 1, 0}};
  for (int i = 0; i < 4; ++i) {
    FlexNode nd;
    nd.name = "n" + std::to_string(i);
    nd.mass = m;
    nd.p_BoNi_B = pos[i];
    nd.J_Ni_B = 0.1 * Matrix3d::Identity();
    nd.Phi_B = shape[i];
    nd.Psi_B = Eigen::Matrix3Xd::Zero(3, 1);
    f.nodes.push_back(nd);
  }
  f.K = Eigen::MatrixXd::Constant(1, 1, K);
  f.D = Eigen::MatrixXd::Zero(1, 1);
  body.flex = f;
  set_node_sums(body);
  s.bodies = {body};
  s.joints = {free_joint(0)};
  TreeState ts = TreeState::initial(s);
  ts.eta[0](0) = eta0;
  const double omega = std::sqrt(K / (4 * m)), period = 2 * std::numbers::pi / omega;
  const int periods = 10;
  const RunResult r = run(s, ts, periods * period, 1e-13, {}, period / 20);
  const auto t = series(r, "t"), q = series(r, "cross.q1"), qd = series(r, "cross.q1_rate");
  double worst = 0;
  for (std::size_t k = 0; k < t.size(); ++k)
    worst = std::max(worst, std::abs(q[k] - eta0 * std::cos(omega * t[k])));
  // The phase at the end gives the simulated period: t_end = periods * T_sim * (1 + phase / 2 pi N).
  const double phase = std::atan2(-qd.back() / omega, q.back());
  const double simulated_period = t.back() / (periods + phase / (2 * std::numbers::pi));
  INFO("largest deviation from eta0 cos(omega t): " << worst / eta0 << " eta0; period error "
                                                     << simulated_period / period - 1);
  CHECK(worst <= 1e-9 * eta0);
  CHECK(std::abs(simulated_period / period - 1) <= 1e-8);
  for (const char* c : {"cross.wx", "cross.wy", "cross.wz", "cross.qx", "cross.qy", "cross.qz", "H"})
    CHECK(max_of(series(r, c)) <= 1e-15);
}

// pack: joints closed, joint and modal coordinates kept, and with zero_linear_momentum the total
// linear momentum, deformation rates included, is zero (node sums over the whole system).
TEST_CASE("newton-euler flex: pack closes the joints at nodes and zeroes the linear momentum",
          "[newton_euler][flexible][engine]") {
  std::mt19937 rng(5);
  const System s = flexible_tree();
  for (int trial = 0; trial < 5; ++trial) {
    const TreeState ts = random_tree_state(s, rng);
    const Packed p = packed(s, ts);
    INFO("trial " << trial);
    CHECK(p.col("constraint.pos") <= 1e-14);
    CHECK(p.col("constraint.vel") <= 1e-14);
    CHECK(p.col("constraint.ang") <= 1e-14);
    CHECK(p.col("constraint.angvel") <= 1e-14);
    for (const char* j : {"hinge", "flap", "side"}) {
      const auto jj = static_cast<std::size_t>(std::find_if(s.joints.begin(), s.joints.end(),
                                                            [&](const Joint& J) { return J.name == j; }) -
                                               s.joints.begin());
      CHECK(std::abs(p.col(std::string(j) + ".angle") - ts.joints[jj].angle) <= 1e-13);
      CHECK(std::abs(p.col(std::string(j) + ".rate") - ts.joints[jj].rate) <= 1e-14);
    }
    CHECK((Vector3d(p.col("ball.wx"), p.col("ball.wy"), p.col("ball.wz")) - ts.joints[2].w_PC_C).norm() <= 1e-14);
    for (int b : {0, 2, 4}) {
      const auto [eta, rate] = modal_state(*p.engine, p.x.data(), s, b);
      CHECK((eta - ts.eta[static_cast<std::size_t>(b)]).norm() == 0.0);
      CHECK((rate - ts.eta_rate[static_cast<std::size_t>(b)]).norm() == 0.0);
    }
    const Totals tot = node_totals(*p.engine, p.x.data(), s);
    double speed = 0;
    for (const Body& b : s.bodies) speed = std::max(speed, b.mass * body_state(*p.engine, p.x.data(), b.name).v_N.norm());
    CHECK(speed > 1.0);
    CHECK(tot.L.norm() <= 1e-13 * speed);
  }
}

// The H and E columns against sums over every node (and every rigid body), at random deformed
// states: the deformation-dependent inertia, the modal momenta and the strain energy are all in.
TEST_CASE("newton-euler flex: H and E equal their node sums", "[newton_euler][flexible][engine]") {
  std::mt19937 rng(6);
  System s = flexible_tree();
  for (Joint& j : s.joints) j.stiffness = 0;  // E is then kinetic + modal strain energy alone
  for (int trial = 0; trial < 5; ++trial) {
    const Packed p = packed(s, random_tree_state(s, rng));
    const Totals tot = node_totals(*p.engine, p.x.data(), s);
    INFO("trial " << trial << ": H " << p.col("H") << " vs " << tot.H.norm() << ", E " << p.col("E")
                  << " vs " << tot.T + tot.V_modal);
    CHECK(tot.V_modal > 0);
    CHECK(std::abs(p.col("H") - tot.H.norm()) <= 1e-13 * tot.H.norm());
    CHECK(std::abs(p.col("E") - (tot.T + tot.V_modal)) <= 1e-13 * (tot.T + tot.V_modal));
  }
}

// The engine's accelerations (TreeAccel: body-frame origins, w', eta'') satisfy the joints'
// acceleration-level conditions written from scratch with node kinematics: the joint point's
// inertial acceleration is the same from both sides,
//   a_Bo + R (w' x s + w x (w x s) + 2 w x Phi eta' + Phi eta''),  s = r + Phi eta.
TEST_CASE("newton-euler flex: accelerations keep the joint points at nodes together",
          "[newton_euler][flexible][engine]") {
  std::mt19937 rng(21);
  const System s = flexible_tree();
  for (int trial = 0; trial < 5; ++trial) {
    Packed p = packed(s, random_tree_state(s, rng));
    TreeAccel a;
    p.engine->accelerations(0.2, p.x.data(), a);
    double scale = 1;
    for (std::size_t b = 0; b < s.bodies.size(); ++b) {
      scale = std::max({scale, a.a_NBo_N[b].norm(), a.wdot_NB_B[b].norm()});
      if (s.bodies[b].flex) {
        REQUIRE(a.eta_ddot[b].size() == s.bodies[b].flex->modes());
        scale = std::max(scale, a.eta_ddot[b].cwiseAbs().maxCoeff());
      } else {
        CHECK(a.eta_ddot[b].size() == 0);
      }
    }
    auto point_acc = [&](int body, int node, const Vector3d& r) {
      const auto b = static_cast<std::size_t>(body);
      const FlexState f = flex_state(*p.engine, p.x.data(), s, body);
      Vector3d sp = r, sd = Vector3d::Zero(), sdd = Vector3d::Zero();
      if (node >= 0) {
        const FlexNode& nd = s.bodies[b].flex->nodes[static_cast<std::size_t>(node)];
        sp = node_r(nd, f.eta);
        sd = nd.Phi_B * f.rate;
        sdd = nd.Phi_B * a.eta_ddot[b];
      }
      const Vector3d& w = f.b.w_B;
      return Vector3d(a.a_NBo_N[b] + f.b.R_NB * (a.wdot_NB_B[b].cross(sp) + w.cross(w.cross(sp)) +
                                                 2.0 * w.cross(sd) + sdd));
    };
    for (std::size_t j = 1; j < s.joints.size(); ++j) {
      const Joint& J = s.joints[j];
      INFO("trial " << trial << " joint " << J.name);
      const Vector3d aP = point_acc(J.parent, J.parent_node, J.p_PoJ_P);
      const Vector3d aC = point_acc(J.child, J.child_node, J.p_CoJ_C);
      CHECK((aP - aC).norm() <= 1e-12 * scale);
    }
  }
}

// Joint and modal accelerations are the time derivatives of the output rates (a central
// difference along the flow, step 1e-6 s).
TEST_CASE("newton-euler flex: joint and modal accelerations are the derivatives of their rates",
          "[newton_euler][flexible][engine]") {
  std::mt19937 rng(33);
  const System s = flexible_tree();
  Packed p = packed(s, random_tree_state(s, rng));
  Engine& e = *p.engine;
  const std::size_t n = p.x.size();
  std::vector<double> xdot(n), xp(n), xm(n), rp(p.row.size()), rm(p.row.size());
  e.rhs(0.0, p.x.data(), xdot.data());
  TreeAccel a;
  e.accelerations(0.0, p.x.data(), a);
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
  auto near = [](double x, double y) { return std::abs(x - y) <= 1e-7 * (1 + std::abs(y)); };
  CHECK(near(fd("hinge.rate"), a.angle_ddot[1]));
  CHECK(near(fd("flap.rate"), a.angle_ddot[4]));
  CHECK(near(fd("side.rate"), a.angle_ddot[5]));
  for (int i = 0; i < 3; ++i) CHECK(near(fd(std::string("ball.w") + "xyz"[i]), a.wdot_PC_C[2](i)));
  CHECK(near(fd("beam.qx1_rate"), a.eta_ddot[0](0)));
  CHECK(near(fd("beam.qy1_rate"), a.eta_ddot[0](2)));
  CHECK(near(fd("arm.qy1_rate"), a.eta_ddot[2](1)));
  CHECK(near(fd("panel.qx1_rate"), a.eta_ddot[4](0)));
  for (int i = 0; i < 3; ++i) CHECK(near(fd(std::string("beam.w") + "xyz"[i]), a.wdot_NB_B[0](i)));
}

// The rigid leaves hang on joints at nodes: the joint force on each is its m a, the joint moment
// about the joint point and the force's moment about its CM give I w' + w x I w (the pinned
// <joint>.Fx .. .Mz, in the leaf's frame). The revolute joint's moment along its axis (the node
// frame's, F = R_NP exp([psi x]), psi = Psi_node eta, here by Eigen's angle-axis) is its torque.
TEST_CASE("newton-euler flex: joint loads at nodes are the leaves' m a and I alpha",
          "[newton_euler][flexible][engine][forces]") {
  std::mt19937 rng(8);
  const System s = flexible_tree();
  for (int trial = 0; trial < 3; ++trial) {
    Packed p = packed(s, random_tree_state(s, rng));
    TreeAccel a;
    p.engine->accelerations(0.0, p.x.data(), a);
    for (const char* leaf : {"weld", "side"}) {
      const auto j = static_cast<std::size_t>(std::find_if(s.joints.begin(), s.joints.end(),
                                                           [&](const Joint& J) { return J.name == leaf; }) -
                                              s.joints.begin());
      const Joint& J = s.joints[j];
      const auto C = static_cast<std::size_t>(J.child);
      const Body& body = s.bodies[C];
      const FlexState P = flex_state(*p.engine, p.x.data(), s, J.parent);
      const BodyState c = body_state(*p.engine, p.x.data(), body.name);
      const FlexNode& nd = s.bodies[static_cast<std::size_t>(J.parent)].flex->nodes[static_cast<std::size_t>(J.parent_node)];
      const Vector3d psi = nd.Psi_B * P.eta;
      const Matrix3d E = Eigen::AngleAxisd(psi.norm(), psi.normalized()).toRotationMatrix();
      const Matrix3d R_NF = P.b.R_NB * E;
      const std::string n(leaf);
      const Vector3d F_C(p.col(n + ".Fx"), p.col(n + ".Fy"), p.col(n + ".Fz"));
      const Vector3d M_C(p.col(n + ".Mx"), p.col(n + ".My"), p.col(n + ".Mz"));
      const Vector3d m_a = body.mass * a.a_NBo_N[C];
      INFO("trial " << trial << " joint " << leaf);
      CHECK(m_a.norm() > 0.1);
      CHECK((c.R_NB * F_C - m_a).norm() <= 1e-12 * m_a.norm());
      const Vector3d& alpha = a.wdot_NB_B[C];
      const Vector3d lhs = body.I_BBo_B * alpha + c.w_B.cross(body.I_BBo_B * c.w_B);
      const Vector3d rhs = J.p_CoJ_C.cross(F_C) + M_C;
      CHECK((lhs - rhs).norm() <= 1e-12 * (1 + lhs.norm()));
      if (J.type == JointType::Revolute) {
        const double tau = -J.stiffness * (p.col(n + ".angle") - J.neutral_angle) - J.damping * p.col(n + ".rate");
        const Vector3d axis_C = c.R_NB.transpose() * (R_NF * J.axis_P.normalized());
        CHECK(std::abs(M_C.dot(axis_C) - tau) <= 1e-12 * (1 + M_C.norm()));
      }
    }
  }
}

// Modal damping: at random states dE/dt = -sum eta'^T D eta' (nothing else dissipates), and over a
// run E never rises.
TEST_CASE("newton-euler flex: modal damping dissipates eta'^T D eta'",
          "[newton_euler][flexible][simulation]") {
  System s = flexible_tree();
  s.bodies[0].flex->D = Eigen::Vector3d(2.0, 5.0, 1.0).asDiagonal();
  s.bodies[2].flex->D = (Eigen::Matrix2d() << 0.5, 0.1, 0.1, 0.3).finished();
  s.bodies[4].flex->D = Eigen::MatrixXd::Constant(1, 1, 0.2);
  std::mt19937 rng(12);
  for (int trial = 0; trial < 5; ++trial) {
    Packed p = packed(s, random_tree_state(s, rng));
    double dissipation = 0;
    for (int b : {0, 2, 4}) {
      const VectorXd rate = modal_state(*p.engine, p.x.data(), s, b).second;
      dissipation += rate.dot(s.bodies[static_cast<std::size_t>(b)].flex->D * rate);
    }
    const double dEdt = energy_rate(p, 0.0);
    INFO("trial " << trial << ": dE/dt " << dEdt << ", -eta'^T D eta' " << -dissipation);
    CHECK(dissipation > 0.01);
    CHECK(std::abs(dEdt + dissipation) <= 1e-7 * (1 + dissipation));
  }
  const RunResult r = run(s, deformed_tree_state(s, 3), 5, 1e-11, {}, 0.05);
  const auto E = series(r, "E");
  for (std::size_t k = 1; k < E.size(); ++k) CHECK(E[k] <= E[k - 1] + 1e-11 * E.front());
  CHECK(E.back() < 0.99 * E.front());
  CHECK(max_abs_change(series(r, "H")) <= 1e-9 * series(r, "H").front());
}

// Motors at node frames do work through the node's rotation: dE/dt = sum tau . (relative angular
// velocity of the joint frames) for a revolute motor at a flexible parent's node (hinge), a
// revolute motor at a flexible child's node (flap) and a spherical motor between nodes of two
// flexible bodies (ball); over a run with the hinge motor alone, E - E0 = tau (angle - angle0)
// and H stays (the torques are internal).
TEST_CASE("newton-euler flex: motors at node frames do work tau . relative angular velocity",
          "[newton_euler][flexible][simulation][loads]") {
  System s = flexible_tree();
  const double tau_hinge = 2.0, tau_flap = -1.5;
  const Vector3d tau_ball(0.3, -0.2, 0.5);
  s.joints[1].motor_revolute = {{0.0}, {Eigen::Matrix<double, 1, 1>(tau_hinge)}};
  s.joints[4].motor_revolute = {{0.0}, {Eigen::Matrix<double, 1, 1>(tau_flap)}};
  s.joints[2].motor_spherical = {{0.0}, {tau_ball}};
  std::mt19937 rng(13);
  for (int trial = 0; trial < 5; ++trial) {
    Packed p = packed(s, random_tree_state(s, rng));
    const double power = tau_hinge * p.col("hinge.rate") + tau_flap * p.col("flap.rate") +
                         tau_ball.dot(Vector3d(p.col("ball.wx"), p.col("ball.wy"), p.col("ball.wz")));
    const double dEdt = energy_rate(p, 0.5);
    INFO("trial " << trial << ": dE/dt " << dEdt << ", motor power " << power);
    CHECK(std::abs(power) > 0.1);
    CHECK(std::abs(dEdt - power) <= 1e-7 * (1 + std::abs(power)));
  }
  System one = flexible_tree();
  one.joints[1].motor_revolute = {{0.0}, {Eigen::Matrix<double, 1, 1>(tau_hinge)}};
  const RunResult r = run(one, deformed_tree_state(one, 4), 5, 1e-12, {}, 0.05);
  const auto E = series(r, "E"), angle = series(r, "hinge.angle"), H = series(r, "H");
  double worst = 0, work = 0;
  for (std::size_t k = 0; k < E.size(); ++k) {
    work = std::max(work, std::abs(tau_hinge * (angle[k] - angle[0])));
    worst = std::max(worst, std::abs(E[k] - E[0] - tau_hinge * (angle[k] - angle[0])));
  }
  INFO("largest |E - E0 - tau (angle - angle0)| " << worst << " J, work up to " << work << " J");
  CHECK(work > 1.0);
  CHECK(worst <= 1e-9 * E[0]);
  CHECK(max_abs_change(H) <= 1e-10 * H.front());
}

// Projection in after_step() with modal coordinates: a state of a flexible chain pushed off the
// manifold (every coordinate, eta and eta' included) comes back to round-off (positions by Newton
// iterations over [p, q, eta], velocities over [v, w, eta'] in one step, both in the mass metric),
// the system's CM and total linear momentum (node sums) do not change, eta is among what moves, and
// a state on the manifold is left alone.
TEST_CASE("newton-euler flex: projection restores the joints at nodes, moving eta too",
          "[newton_euler][flexible][stabilization]") {
  std::mt19937 rng(8);
  std::normal_distribution<double> noise(0.0, 1e-4);
  const System s = flexible_chain(4);
  TreeState ts = TreeState::initial(s);
  deform(s, ts, rng, 0.1, 0.3);
  Packed p = packed(s, ts);
  Engine& e = *p.engine;
  CHECK_FALSE(e.after_step(0.0, p.x.data()));
  for (double& v : p.x) v += noise(rng);
  const Totals before = node_totals(e, p.x.data(), s);
  const VectorXd eta_before = modal_state(e, p.x.data(), s, 1).first;
  p.output();
  CHECK(p.col("constraint.pos") > 1e-5);
  CHECK(e.after_step(0.0, p.x.data()));
  p.output();
  // Newton stops at 1e-14 per metre of model size (~8 m here); velocities are exact to round-off.
  CHECK(p.col("constraint.pos") <= 1e-13);
  CHECK(p.col("constraint.ang") <= 1e-13);
  CHECK(p.col("constraint.vel") <= 1e-13);
  CHECK(p.col("constraint.angvel") <= 1e-13);
  const Totals after = node_totals(e, p.x.data(), s);
  INFO("momentum before " << before.L.transpose() << ", change " << (after.L - before.L).norm());
  CHECK((after.L - before.L).norm() <= 1e-13);
  CHECK((after.cm - before.cm).norm() <= 1e-14);
  CHECK((modal_state(e, p.x.data(), s, 1).first - eta_before).norm() > 1e-7);
  CHECK_FALSE(e.after_step(0.0, p.x.data()));
}

// Over a 20 s run at rkf78 1e-8 the projection keeps the flexible chain's joints closed to
// round-off, while without stabilisation the gap grows with the integration error.
TEST_CASE("newton-euler flex: constraint drift on a flexible chain per stabilisation",
          "[newton_euler][flexible][stabilization]") {
  const System s = flexible_chain(4);
  const TreeState ts = deformed_tree_state(s, 9);
  auto drift = [&](const char* stab) {
    EngineOptions o;
    o.stabilization = stab;
    return max_of(series(run(s, ts, 20, 1e-8, o, 0.5), "constraint.pos"));
  };
  const double none = drift("none"), projection = drift("projection");
  INFO("largest joint gap: none " << none << " m, projection " << projection << " m");
  CHECK(none > 1e-10);
  CHECK(projection <= 1e-10);  // the trigger is 1e-12 per metre of model size (~8 m)
}

TEST_CASE("newton-euler flex: modal state labels and input errors", "[newton_euler][flexible][engine]") {
  const System s = flexible_tree();
  auto e = make_newton_euler_engine(s, {});
  // 6 bodies: 7 + 6 per body, plus 2 x (3 + 2 + 1) modal coordinates and rates.
  CHECK(e->state_size() == 6 * 13 + 2 * 6);
  CHECK(e->state_label(label_index(*e, "beam.qx1")) == "beam.qx1");
  CHECK_NOTHROW(label_index(*e, "beam.qy1_rate"));
  CHECK_NOTHROW(label_index(*e, "panel.qx1_rate"));
  CHECK(label_index(*e, "beam.qx2") == label_index(*e, "beam.qx1") + 1);
  for (const char* c : {"beam.qx1", "beam.qx2", "beam.qy1", "beam.qx1_rate", "arm.qy1_rate", "ball.Fx", "weld.Mz"})
    CHECK_NOTHROW(column(*e, c));

  auto error = [](const System& bad) {
    try {
      make_newton_euler_engine(bad, {});
    } catch (const InputError& err) {
      return std::string(err.what());
    }
    return std::string("no error");
  };
  System bad = s;
  bad.joints[1].child_node = 0;  // payload is rigid
  CHECK_THAT(error(bad), Catch::Contains("'hinge'") && Catch::Contains("child_node") &&
                             Catch::Contains("'payload'") && Catch::Contains("not flexible"));
  bad = s;
  bad.joints[2].parent_node = 99;
  CHECK_THAT(error(bad), Catch::Contains("'ball'") && Catch::Contains("not a node of 'beam'"));
  bad = s;
  bad.bodies[0].mass += 1;
  CHECK_THAT(error(bad), Catch::Contains("'beam'") && Catch::Contains("differs from the sum of its node masses"));
  bad = s;
  bad.bodies[2].flex->nodes[0].Phi_B = Eigen::Matrix3Xd::Zero(3, 3);
  CHECK_THAT(error(bad), Catch::Contains("'arm'") && Catch::Contains("node 's0'") && Catch::Contains("3 x 2"));
  bad = s;
  bad.bodies[2].flex->K(0, 1) = 1;
  CHECK_THAT(error(bad), Catch::Contains("'arm'") && Catch::Contains("symmetric"));
  bad = s;
  bad.bodies[4].flex->K(0, 0) = -1;
  CHECK_THAT(error(bad), Catch::Contains("'panel'") && Catch::Contains("positive semi-definite"));
  bad = s;  // a mode that moves only massless nodes: no modal mass, a singular mass matrix
  for (FlexNode& nd : bad.bodies[4].flex->nodes)
    if (nd.mass > 0) nd.Phi_B.setZero();
  CHECK_THAT(error(bad), Catch::Contains("'panel'") && Catch::Contains("not positive definite"));
  bad = s;  // a mode that is a rigid translation: the frame and the mode cannot be told apart
  for (FlexNode& nd : bad.bodies[4].flex->nodes) nd.Phi_B = Vector3d(1, 0, 0);
  CHECK_THAT(error(bad), Catch::Contains("'panel'") && Catch::Contains("not positive definite"));
  TreeState ts = TreeState::initial(s);
  ts.eta[0].resize(1);
  std::vector<double> x(static_cast<std::size_t>(e->state_size()));
  CHECK_THROWS_WITH(e->pack(ts, x.data()), Catch::Contains("'beam'") && Catch::Contains("3 finite modal"));
}
