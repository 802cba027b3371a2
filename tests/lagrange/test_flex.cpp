// The Lagrange engine with flexible (modal) bodies (docs/flexible-bodies.md): the node-frame
// rotation and its Jacobian, the modal inertia invariants against node sums, Newton's law at every
// node of a free flexible body, the equivalence of a zero-mode body with a rigid one, the vibration
// period of a momentum-free mode, the balance laws at random states of a tree with joints at nodes,
// and the validation of what the engine cannot run.
#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>
#include <random>

#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "core/rotation.hpp"
#include "formulations/lagrange/flex_body.hpp"
#include "formulations/lagrange/lagrange.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "tests/lagrange/flex_scenes.hpp"
#include "tests/support/close.hpp"

using namespace crossdyn;
using crossdyn::lagrange::Dual;
using crossdyn::lagrange::LagrangeEngine;
using crossdyn::test::all_close;
using crossdyn::test::close;

namespace {

std::vector<double> packed(LagrangeEngine& e, const TreeState& s) {
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(s, x.data());
  return x;
}

std::vector<double> advanced(const std::vector<double>& x, const std::vector<double>& xdot,
                             double h) {
  std::vector<double> y(x);
  for (std::size_t i = 0; i < x.size(); ++i) y[i] += h * xdot[i];
  return y;
}

Eigen::Vector3d vec3(std::mt19937& g, double scale) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return scale * Eigen::Vector3d(u(g), u(g), u(g));
}

// The attitude q_NB of body b from an output row.
Eigen::Quaterniond row_attitude(const LagrangeEngine& e, const std::vector<double>& row, int b) {
  const auto c = static_cast<std::size_t>(e.layout().body_q(b));
  return Eigen::Quaterniond(row[c], row[c + 1], row[c + 2], row[c + 3]);
}

RunResult run(const System& s, const TreeState& initial, double tol) {
  LagrangeEngine e(s, {});
  IntegratorSettings settings = IntegratorSettings::from(s.run);
  settings.method = "rkf78";
  settings.rtol = settings.atol = tol;
  return simulate(e, s, initial, settings);
}

double column_drift(const RunResult& r, const std::string& name) {
  const auto c = static_cast<std::size_t>(r.column(name));
  double d = 0;
  for (std::size_t k = 0; k < r.rows(); ++k)
    d = std::max(d, std::abs(r.at(k, c) - r.at(0, c)) / std::abs(r.at(0, c)));
  return d;
}

// A free flexible body (the base), with a body-frame torque tau.
System free_flex(std::mt19937& g, double damping, const Eigen::Vector3d& tau) {
  System s;
  s.name = "free_flex";
  s.bodies = {test::random_flex_body("body", 8, 3, 1.5, g, 20.0, damping)};
  s.joints = {test::free_joint(0, Eigen::Vector3d::Zero())};
  s.bodies[0].torque.times = {0.0};
  s.bodies[0].torque.values = {tau};
  s.run.duration = 5;
  s.run.output_step = 0.01;
  return s;
}

}  // namespace

TEST_CASE("lagrange flex: exp([psi x]) is the rotation and Jl(psi) psi' its angular velocity",
          "[lagrange][flex]") {
  // Barfoot 2017, Sec. 7.1.3-7.1.5: exp([psi x]) turns by |psi| about psi / |psi|, and
  // d/dt exp([psi x]) exp([psi x])^T = [(Jl(psi) psi') x]. The rate is taken here by Dual<1>
  // through exp alone, independently of the engine's closed-form Jl.
  using lagrange::Mat3;
  using lagrange::Vec3;
  std::mt19937 g(41);
  for (double t : {0.0, 1e-12, 1e-6, 1e-3, 0.1, 0.5, 1 - 1e-9, 1.0, 1 + 1e-9, 2.5, 3.1}) {
    for (int trial = 0; trial < 20; ++trial) {
      const Eigen::Vector3d axis = vec3(g, 1.0).normalized();
      const Eigen::Vector3d psi = t * axis, psi_dot = vec3(g, 2.0);
      Eigen::Matrix3d E, Jl;
      lagrange::rotvec_exp<double>(psi, E, &Jl);
      const Eigen::Matrix3d ref = Eigen::AngleAxisd(t, axis).toRotationMatrix();
      INFO("|psi| = " << t);
      CHECK(all_close(E, ref, 2e-15, 0));
      CHECK(all_close(E * E.transpose(), Eigen::Matrix3d::Identity(), 2e-15, 0));
      Vec3<Dual<1>> pd;
      for (int a = 0; a < 3; ++a) {
        pd(a) = Dual<1>(psi(a));
        pd(a).d[0] = psi_dot(a);
      }
      Mat3<Dual<1>> Ed;
      lagrange::rotvec_exp(pd, Ed, static_cast<Mat3<Dual<1>>*>(nullptr));
      Eigen::Matrix3d Edot;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) Edot(r, c) = Ed(r, c).d[0];
      const Eigen::Matrix3d W = Edot * E.transpose();
      CHECK(all_close(W, Eigen::Matrix3d(-W.transpose()), 1e-14, 0));
      const Eigen::Vector3d w(W(2, 1), W(0, 2), W(1, 0));
      CHECK(all_close(w, Jl * psi_dot, 1e-14, 1e-14));
    }
  }
  // The coefficients a1 = sin t / t, a2 = (1 - cos t) / t^2, a3 = (t - sin t) / t^3 and their
  // derivatives in t^2, on both sides of the switch from the series (t < 1) to the closed form,
  // against the closed forms in long double (where their cancellation costs < 1e-16 for t >= 0.1).
  for (double t : {0.1, 0.5, 1 - 1e-9, 1.0, 1 + 1e-9, 1.7, 3.0}) {
    Dual<1> t2(t * t), c, a1, a2, a3;
    t2.d[0] = 1.0;
    lagrange::rotvec_coefficients(t2, c, a1, a2, a3);
    const long double T = t, s = std::sin(T), co = std::cos(T);
    const long double r1 = s / T, r2 = (1 - co) / (T * T), r3 = (T - s) / (T * T * T);
    // d/d(t^2) = (d/dt) / (2 t)
    const long double d1 = (co / T - s / (T * T)) / (2 * T);
    const long double d2 = (s / (T * T) - 2 * (1 - co) / (T * T * T)) / (2 * T);
    const long double d3 = ((1 - co) / (T * T * T) - 3 * (T - s) / (T * T * T * T)) / (2 * T);
    INFO("t = " << t);
    CHECK(close(a1.v, static_cast<double>(r1), 0, 5e-16));  // a few ulp
    CHECK(close(a2.v, static_cast<double>(r2), 0, 5e-16));
    CHECK(close(a3.v, static_cast<double>(r3), 0, 1e-15));
    CHECK(close(c.v, std::cos(t), 5e-16, 0));
    CHECK(close(a1.d[0], static_cast<double>(d1), 0, 1e-14));
    CHECK(close(a2.d[0], static_cast<double>(d2), 0, 1e-14));
    CHECK(close(a3.d[0], static_cast<double>(d3), 0, 1e-13));
  }
}

TEST_CASE("lagrange flex: the modal inertia invariants give the node sums' energy and momenta",
          "[lagrange][flex]") {
  // T = 1/2 sum m_i |v + w x r_i + Phi_i eta'|^2 + 1/2 w . J w and its gradients in (w, v, eta'),
  // summed here node by node, against the engine's O(n^2) evaluation from invariants.
  std::mt19937 g(42);
  for (int trial = 0; trial < 50; ++trial) {
    const int modes = 1 + trial % 4;
    const Body body = test::random_flex_body("b", 9, modes, 1.5, g);
    const FlexBody& fb = *body.flex;
    const lagrange::FlexInvariants f(fb, 1.0);
    CHECK(all_close(f.rigid_inertia(), body.I_BBo_B, 1e-13, 1e-13));
    CHECK(close(f.m, body.mass, 0, 1e-15));
    const double scale = trial < 25 ? 0.1 : 1.0;  // realistic, then very large deformations
    Eigen::VectorXd eta(modes), ed(modes);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int k = 0; k < modes; ++k) {
      eta(k) = scale * u(g);
      ed(k) = u(g);
    }
    const Eigen::Vector3d w = vec3(g, 2.0), v = vec3(g, 1.0);
    lagrange::FlexInertia<double> fi;
    fi.resize(modes);
    lagrange::flex_inertia(f, eta.data(), fi);
    Eigen::Vector3d hw, hv;
    Eigen::VectorXd he(modes);
    lagrange::flex_momentum<double>(f, fi, w, v, ed.data(), hw, hv, he.data());
    const double T = lagrange::flex_kinetic_energy<double>(f, fi, w, v, ed.data(), he.data());
    double T_ref = 0;
    Eigen::Vector3d hw_ref = Eigen::Vector3d::Zero(), hv_ref = Eigen::Vector3d::Zero();
    Eigen::VectorXd he_ref = Eigen::VectorXd::Zero(modes);
    for (const FlexNode& n : fb.nodes) {
      const Eigen::Vector3d r = n.p_BoNi_B + n.Phi_B * eta;
      const Eigen::Vector3d vi = v + w.cross(r) + n.Phi_B * ed;
      T_ref += 0.5 * n.mass * vi.squaredNorm() + 0.5 * w.dot(n.J_Ni_B * w);
      hv_ref += n.mass * vi;
      hw_ref += n.mass * r.cross(vi) + n.J_Ni_B * w;
      he_ref += n.mass * n.Phi_B.transpose() * vi;
    }
    INFO("trial " << trial << ", modes " << modes << ", eta scale " << scale);
    CHECK(close(T, T_ref, 0, 1e-13));
    CHECK(all_close(hw, hw_ref, 1e-13 * hw_ref.norm(), 0));
    CHECK(all_close(hv, hv_ref, 1e-13 * hv_ref.norm(), 0));
    CHECK(all_close(he, he_ref, 1e-13 * he_ref.norm(), 0));
  }
}

TEST_CASE("lagrange flex: a free flexible body obeys Newton's law at every node", "[lagrange][flex]") {
  // The accelerations of the node particles a_i = a_Bo + R (w' x r_i + w x (w x r_i)
  // + 2 w x Phi_i eta' + Phi_i eta''), formed here from the engine's accelerations, must satisfy
  // Newton's and Euler's laws for the free body (no force, body-frame torque tau) and, projected on
  // each mode's virtual displacement R Phi_ik (reference paper Eqs. (3)-(5): the modal projection
  // of every mass element's acceleration), sum_i m_i (R Phi_ik) . a_i = -(K eta + D eta')_k.
  // Also H and E of the output row, and the zero total linear momentum of pack(), by node sums.
  std::mt19937 g(43);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d tau = vec3(g, 0.5);
    const System s = free_flex(g, 0.3, tau);
    const FlexBody& fb = *s.bodies[0].flex;
    LagrangeEngine e(s, {});
    const TreeState st = test::random_flex_state(s, g, 0.2, 1.0);
    const std::vector<double> x = packed(e, st);
    TreeAccel a;
    e.accelerations(0.5, x.data(), a);
    std::vector<double> row(e.columns().size());
    e.output_row(0.5, x.data(), row.data());
    const int n = e.dof(), e0 = e.modal_index(0), nm = fb.modes();
    REQUIRE(e0 == 6);
    const Eigen::Matrix3d R = row_attitude(e, row, 0).toRotationMatrix();
    const Eigen::Vector3d p_Bo = Eigen::Map<const Eigen::Vector3d>(x.data());
    const Eigen::Vector3d v_Bo = Eigen::Map<const Eigen::Vector3d>(x.data() + n);
    const Eigen::Vector3d w = Eigen::Map<const Eigen::Vector3d>(x.data() + n + 3);
    const Eigen::VectorXd eta = Eigen::Map<const Eigen::VectorXd>(x.data() + e0, nm);
    const Eigen::VectorXd ed = Eigen::Map<const Eigen::VectorXd>(x.data() + n + e0, nm);
    const Eigen::Vector3d wd = a.wdot_NB_B[0];
    const Eigen::VectorXd& edd = a.eta_ddot[0];
    REQUIRE(edd.size() == nm);
    Eigen::Vector3d F = Eigen::Vector3d::Zero(), M = Eigen::Vector3d::Zero();
    Eigen::VectorXd Q = Eigen::VectorXd::Zero(nm);
    Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
    double scale = 0, mass = 0, T = 0;
    Eigen::Vector3d x_c = Eigen::Vector3d::Zero(), P = Eigen::Vector3d::Zero();
    for (const FlexNode& nd : fb.nodes) {
      const Eigen::Vector3d r = nd.p_BoNi_B + nd.Phi_B * eta, rd = nd.Phi_B * ed;
      const Eigen::Vector3d ai =
          a.a_NBo_N[0] +
          R * (wd.cross(r) + w.cross(w.cross(r)) + 2 * w.cross(rd) + nd.Phi_B * edd);
      F += nd.mass * ai;
      M += nd.mass * (R * r).cross(ai);
      Q += nd.mass * (R * nd.Phi_B).transpose() * ai;
      J += nd.J_Ni_B;
      scale = std::max(scale, nd.mass * ai.norm());
      const Eigen::Vector3d vi = v_Bo + R * (w.cross(r) + rd);
      mass += nd.mass;
      x_c += nd.mass * (p_Bo + R * r);
      P += nd.mass * vi;
      T += 0.5 * nd.mass * vi.squaredNorm();
    }
    M += R * (J * wd + w.cross(J * w));
    T += 0.5 * w.dot(J * w);
    x_c /= mass;
    INFO("trial " << trial);
    CHECK(F.norm() < 1e-12 * scale);
    CHECK(all_close(M, Eigen::Vector3d(R * tau), 1e-12 * scale, 0));
    CHECK(all_close(Q, Eigen::VectorXd(-fb.K * eta - fb.D * ed), 1e-12 * scale, 0));
    // pack(): zero total linear momentum, modal rates included.
    CHECK(P.norm() < 1e-13 * mass * (1 + v_Bo.norm()));
    // H about the system CM and E, by node sums.
    Eigen::Vector3d H = R * (J * w);
    for (const FlexNode& nd : fb.nodes) {
      const Eigen::Vector3d r = nd.p_BoNi_B + nd.Phi_B * eta;
      const Eigen::Vector3d vi = v_Bo + R * (w.cross(r) + nd.Phi_B * ed);
      H += nd.mass * (p_Bo + R * r - x_c).cross(vi - P / mass);
    }
    const double V = 0.5 * eta.dot(fb.K * eta);
    CHECK(close(row[static_cast<std::size_t>(e.layout().H())], H.norm(), 0, 1e-13));
    CHECK(close(row[static_cast<std::size_t>(e.layout().E())], T + V, 0, 1e-13));
    CHECK(close(e.kinetic_energy(x.data()), T, 0, 1e-13));
  }
}

TEST_CASE("lagrange flex: a flexible body with zero modes moves exactly as the rigid body",
          "[lagrange][flex]") {
  // mixed_tree with its base `core` and the child `hand` replaced by zero-mode flexible bodies
  // with the same mass and inertia (one node at the CM carrying them, massless nodes at the joint
  // points), the joints attached at those nodes.
  const System rigid = test::mixed_tree(true);
  System flex = rigid;
  auto as_flex = [](const Body& b, const std::vector<Eigen::Vector3d>& points) {
    std::vector<FlexNode> nodes{test::node(b.name + "_cm", b.mass, Eigen::Vector3d::Zero(), 0)};
    nodes[0].J_Ni_B = b.I_BBo_B;
    for (std::size_t i = 0; i < points.size(); ++i)
      nodes.push_back(test::node(b.name + "_j" + std::to_string(i), 0.0, points[i], 0));
    Body f = test::flex_body(b.name, nodes, Eigen::MatrixXd(0, 0), Eigen::MatrixXd(0, 0));
    f.torque = b.torque;
    f.torque_frame = b.torque_frame;
    return f;
  };
  // Joints of mixed_tree: 1 shoulder core->arm, 2 wrist arm->hand, 3 mount core->panel,
  // 4 knuckle hand->tip.
  flex.bodies[0] = as_flex(rigid.bodies[0], {rigid.joints[1].p_PoJ_P, rigid.joints[3].p_PoJ_P});
  flex.bodies[2] = as_flex(rigid.bodies[2], {rigid.joints[2].p_CoJ_C, rigid.joints[4].p_PoJ_P});
  flex.joints[1].parent_node = 1;
  flex.joints[3].parent_node = 2;
  flex.joints[2].child_node = 1;
  flex.joints[4].parent_node = 2;
  LagrangeEngine er(rigid, {}), ef(flex, {});
  REQUIRE(er.state_size() == ef.state_size());
  REQUIRE(er.columns() == ef.columns());
  std::mt19937 g(44);
  for (int trial = 0; trial < 20; ++trial) {
    const TreeState st = test::random_state(rigid, g);
    TreeState sf = st;
    sf.eta = TreeState::initial(flex).eta;
    sf.eta_rate = sf.eta;
    const std::vector<double> xr = packed(er, st), xf = packed(ef, sf);
    CHECK(all_close(Eigen::Map<const Eigen::VectorXd>(xf.data(), static_cast<Eigen::Index>(xf.size())),
                    Eigen::Map<const Eigen::VectorXd>(xr.data(), static_cast<Eigen::Index>(xr.size())),
                    1e-14, 1e-14));
    const Eigen::VectorXd ur = er.terms(0.2, xr.data()).udot, uf = ef.terms(0.2, xf.data()).udot;
    CHECK(all_close(uf, ur, 1e-12 * (1 + ur.norm()), 0));
  }
  const RunResult rr = run(rigid, TreeState::initial(rigid), 1e-12);
  const RunResult rf = run(flex, TreeState::initial(flex), 1e-12);
  REQUIRE_FALSE(rr.failure);
  REQUIRE_FALSE(rf.failure);
  REQUIRE(rr.rows() == rf.rows());
  for (std::size_t c = 0; c < rr.columns.size(); ++c) {
    double diff = 0, size = 0;
    for (std::size_t k = 0; k < rr.rows(); ++k) {
      diff = std::max(diff, std::abs(rr.at(k, c) - rf.at(k, c)));
      size = std::max(size, std::abs(rr.at(k, c)));
    }
    INFO("column " << rr.columns[c] << ": max difference " << diff);
    CHECK(diff <= 1e-11 * (1 + size));
  }
}

TEST_CASE("lagrange flex: a momentum-free mode vibrates at sqrt(K / M_modal), the rigid motion "
          "stays zero",
          "[lagrange][flex]") {
  // Four nodes; the mode moves the pair on the x axis apart along x (sum m_i Phi_i = 0,
  // sum m_i p_i x Phi_i = 0), so it exchanges no momentum with the rigid motion: with w = 0 it is a
  // linear oscillator of modal mass M_modal = sum m_i |Phi_i|^2 = 2 m_x and stiffness K.
  const double m_x = 1.5, m_y = 2.5, a = 0.8, b = 1.3, K = 40.0;
  std::vector<FlexNode> nodes{test::node("px", m_x, {a, 0, 0}, 1), test::node("mx", m_x, {-a, 0, 0}, 1),
                              test::node("py", m_y, {0, b, 0}, 1), test::node("my", m_y, {0, -b, 0}, 1)};
  nodes[0].Phi_B.col(0) = Eigen::Vector3d::UnitX();
  nodes[1].Phi_B.col(0) = -Eigen::Vector3d::UnitX();
  nodes[0].Psi_B.col(0) = Eigen::Vector3d(0, 0.5, 0);  // slopes do not enter T
  for (FlexNode& n : nodes) n.J_Ni_B = Eigen::Vector3d(0.01, 0.02, 0.03).asDiagonal();
  System s;
  s.name = "breathing";
  s.bodies = {test::flex_body("body", nodes, Eigen::MatrixXd::Constant(1, 1, K),
                              Eigen::MatrixXd::Zero(1, 1))};
  s.joints = {test::free_joint(0, Eigen::Vector3d::Zero())};
  const double omega = std::sqrt(K / (2 * m_x)), period = 2 * std::numbers::pi / omega;
  s.run.duration = 3 * period;
  s.run.output_step = period / 20;
  TreeState st = TreeState::initial(s);
  st.eta[0](0) = 1e-3;
  const RunResult r = run(s, st, 1e-12);
  REQUIRE_FALSE(r.failure);
  const std::size_t last = r.rows() - 1;
  const double t_end = r.at(last, 0);
  const double eta = r.at(last, static_cast<std::size_t>(r.column("body.q1")));
  const double rate = r.at(last, static_cast<std::size_t>(r.column("body.q1_rate")));
  // The maximum nearest t_end (one Newton step on eta' = 0 with the engine's own eta''):
  LagrangeEngine e(s, {});
  TreeState end = TreeState::initial(s);
  end.eta[0](0) = eta;
  end.eta_rate[0](0) = rate;
  const std::vector<double> x = packed(e, end);
  TreeAccel acc;
  e.accelerations(t_end, x.data(), acc);
  const double measured = (t_end - rate / acc.eta_ddot[0](0)) / 3;
  INFO("period " << measured << " s, closed form " << period << " s, relative difference "
                  << (measured - period) / period);
  CHECK(close(measured, period, 0, 1e-8));
  CHECK(close(eta, 1e-3, 1e-12, 0));
  // The rigid motion stays zero.
  double w_max = 0;
  for (std::size_t k = 0; k < r.rows(); ++k)
    for (const char* c : {"body.wx", "body.wy", "body.wz"})
      w_max = std::max(w_max, std::abs(r.at(k, static_cast<std::size_t>(r.column(c)))));
  CHECK(w_max < 1e-15);
  CHECK(acc.a_NBo_N[0].norm() < 1e-15);
  CHECK(acc.wdot_NB_B[0].norm() < 1e-15);
  // E = K eta^2 / 2 ~ 2e-5 J is held by the integrator's absolute tolerance 1e-12 on eta ~ 1e-3.
  CHECK(column_drift(r, "E") < 1e-8);
}

TEST_CASE("lagrange flex: the balance laws hold at random states of a tree with joints at nodes",
          "[lagrange][flex]") {
  // Along the motion through x (x + h xdot): total linear momentum constant, dH/dt = external
  // torques, dE/dt = power of hinge dampers and motors, body torques and modal damping, and the
  // generalised momentum obeys Boltzmann-Hamel: dp/dt = N + B^T dL/dq* - B^T W^T p. The engine-
  // neutral accelerations are the time derivatives of the outputs (body rates, modal rates, base
  // velocity).
  std::mt19937 g(45);
  for (const bool loads : {false, true}) {
    const System s = test::flex_tree(loads);
    LagrangeEngine e(s, {});
    const int n = e.dof(), nx = e.state_size();
    for (int trial = 0; trial < 8; ++trial) {
      INFO("scene " << s.name << ", trial " << trial);
      const double t0 = 0.3, h = 1e-5;
      const std::vector<double> x = packed(e, test::random_flex_state(s, g));
      std::vector<double> xdot(static_cast<std::size_t>(nx));
      e.rhs(t0, x.data(), xdot.data());
      const LagrangeEngine::Terms terms = e.terms(t0, x.data());
      const std::vector<double> xp = advanced(x, xdot, h), xm = advanced(x, xdot, -h);
      auto fd = [h](const auto& plus, const auto& minus) { return (plus - minus) / (2 * h); };
      // Linear momentum: no external force.
      const Eigen::Vector3d dP = fd(e.linear_momentum_N(xp.data()), e.linear_momentum_N(xm.data()));
      CHECK(dP.norm() < 1e-7 * (1 + e.linear_momentum_N(x.data()).norm() + e.kinetic_energy(x.data())));
      // Outputs at x, x + h xdot, x - h xdot.
      std::vector<double> row(e.columns().size()), rp(row.size()), rm(row.size());
      e.output_row(t0, x.data(), row.data());
      e.output_row(t0, xp.data(), rp.data());
      e.output_row(t0, xm.data(), rm.data());
      // dH/dt = sum of external torques (joint loads are internal pairs).
      Eigen::Vector3d tau_N = Eigen::Vector3d::Zero();
      double power = 0;
      for (std::size_t b = 0; b < s.bodies.size(); ++b) {
        const Eigen::Quaterniond q = row_attitude(e, row, static_cast<int>(b));
        const auto c = static_cast<std::size_t>(e.layout().body_w(static_cast<int>(b)));
        const Eigen::Vector3d w(row[c], row[c + 1], row[c + 2]);
        const Eigen::Vector3d tau = s.bodies[b].torque.value(t0);
        const bool inertial = s.bodies[b].torque_frame == Body::Frame::Inertial;
        tau_N += inertial ? tau : q * tau;
        power += w.dot(inertial ? q.conjugate() * tau : tau);
        if (s.bodies[b].flex) {
          const auto mc = static_cast<std::size_t>(e.layout().modal_first(static_cast<int>(b)));
          const auto nm = static_cast<Eigen::Index>(s.bodies[b].flex->modes());
          const Eigen::VectorXd ed = Eigen::Map<const Eigen::VectorXd>(&row[mc + static_cast<std::size_t>(nm)], nm);
          power -= ed.dot(s.bodies[b].flex->D * ed);
        }
      }
      for (std::size_t j = 0; j < s.joints.size(); ++j) {
        const Joint& J = s.joints[j];
        const int c0 = e.layout().joint_first(static_cast<int>(j));
        if (c0 < 0) continue;
        const auto c = static_cast<std::size_t>(c0);
        if (J.type == JointType::Revolute) {
          const double rate = row[c + 1];
          power += rate * (-J.damping * rate + J.motor_revolute.value(t0)(0));
        } else if (J.type == JointType::Spherical) {
          const Eigen::Vector3d w(row[c], row[c + 1], row[c + 2]);
          power += w.dot(-J.damping * w + J.motor_spherical.value(t0));
        }
      }
      const Eigen::Vector3d H = e.angular_momentum_N(x.data());
      const Eigen::Vector3d dH = fd(e.angular_momentum_N(xp.data()), e.angular_momentum_N(xm.data()));
      CHECK(all_close(dH, tau_N, 1e-7 * (1 + tau_N.norm() + H.norm()), 0));
      auto energy = [&](const std::vector<double>& y) {
        return e.kinetic_energy(y.data()) + e.potential_energy(y.data());
      };
      CHECK(close(fd(energy(xp), energy(xm)), power, 1e-7 * (1 + energy(x)), 0));
      // Boltzmann-Hamel: the generalised momentum's rate along the motion.
      const Eigen::VectorXd dp = fd(e.terms(t0, xp.data()).p, e.terms(t0, xm.data()).p);
      const Eigen::VectorXd rhs = terms.N + terms.dL - terms.hamel;
      CHECK(all_close(dp, rhs, 1e-7 * (1 + rhs.norm() + terms.p.norm()), 0));
      // Accelerations against the outputs' rates.
      TreeAccel a;
      e.accelerations(t0, x.data(), a);
      for (std::size_t b = 0; b < s.bodies.size(); ++b) {
        const auto c = static_cast<std::size_t>(e.layout().body_w(static_cast<int>(b)));
        const Eigen::Vector3d wd((rp[c] - rm[c]) / (2 * h), (rp[c + 1] - rm[c + 1]) / (2 * h),
                                 (rp[c + 2] - rm[c + 2]) / (2 * h));
        CHECK(all_close(a.wdot_NB_B[b], wd, 1e-7 * (1 + wd.norm()), 0));
        if (!s.bodies[b].flex) continue;
        const auto mc = static_cast<std::size_t>(e.layout().modal_first(static_cast<int>(b)));
        const auto nm = static_cast<std::size_t>(s.bodies[b].flex->modes());
        for (std::size_t k = 0; k < nm; ++k)
          CHECK(close(a.eta_ddot[b](static_cast<Eigen::Index>(k)),
                      (rp[mc + nm + k] - rm[mc + nm + k]) / (2 * h), 1e-7, 1e-7));
      }
      // The base's a_NBo_N is the rate of its velocity state v_NBo_N.
      CHECK(all_close(a.a_NBo_N[0], Eigen::Vector3d(xdot[static_cast<std::size_t>(n)],
                                                    xdot[static_cast<std::size_t>(n + 1)],
                                                    xdot[static_cast<std::size_t>(n + 2)]),
                      1e-14, 1e-13));
    }
  }
}

TEST_CASE("lagrange flex: H and E are conserved over runs with large deformation and joints at "
          "nodes",
          "[lagrange][flex][run]") {
  // flex_tree: flexible base, flexible parent and child at nodes, springs. Large deformation
  // (eta up to 0.3: nodes move ~0.3 m and turn ~0.3 rad) and rotation. Without external torques
  // and dissipation H and E are constant; with hinge dampers and motors and modal damping (internal)
  // H still is.
  std::mt19937 g(46);
  for (const bool loads : {false, true}) {
    System s = test::flex_tree(loads);
    s.bodies[0].torque = {};
    s.bodies[2].torque = {};
    s.run.duration = 10;
    // The scene's joint state (a random spherical-joint attitude could reach the rotation angle
    // pi, where the spring k |phi|^2 / 2 of system.hpp has a kink), random modal state.
    TreeState st = TreeState::initial(s);
    const TreeState random = test::random_flex_state(s, g, 0.3, 1.0);
    st.eta = random.eta;
    st.eta_rate = random.eta_rate;
    st.w_NB_B = Eigen::Vector3d(0.5, -0.8, 0.6);
    const RunResult r = run(s, st, 1e-12);
    INFO("scene " << s.name << ": " << (r.failure ? r.failure->what() : "ok") << ", "
                  << r.stats.steps << " steps");
    REQUIRE_FALSE(r.failure);
    // The deformation stays large.
    double eta_max = 0;
    for (std::size_t k = 0; k < r.rows(); ++k)
      eta_max = std::max(eta_max, std::abs(r.at(k, static_cast<std::size_t>(r.column("beam.q1")))));
    CHECK(eta_max > 0.05);
    const double dH = column_drift(r, "H"), dE = column_drift(r, "E");
    INFO("H drift " << dH << ", E drift " << dE);
    CHECK(dH < 1e-10);
    if (!loads) CHECK(dE < 1e-10);
  }
}

TEST_CASE("lagrange flex: modal damping dissipates exactly eta'^T D eta'", "[lagrange][flex][run]") {
  // A free spinning flexible body with D > 0 and nothing else dissipating: E decreases
  // monotonically, and E(t) - E(0) = -integral of eta'^T D eta' (Simpson's rule on the outputs);
  // at random states dE/dt = -eta'^T D eta' to the finite-difference accuracy.
  std::mt19937 g(47);
  System s = free_flex(g, 0.0, Eigen::Vector3d::Zero());
  s.bodies[0].torque = {};
  Eigen::MatrixXd A = Eigen::MatrixXd::Random(3, 3);
  s.bodies[0].flex->D = 0.5 * A * A.transpose() + 0.2 * Eigen::MatrixXd::Identity(3, 3);
  const Eigen::MatrixXd& D = s.bodies[0].flex->D;
  LagrangeEngine e(s, {});
  for (int trial = 0; trial < 10; ++trial) {
    const std::vector<double> x = packed(e, test::random_flex_state(s, g, 0.2, 1.0));
    std::vector<double> xdot(x.size());
    e.rhs(0, x.data(), xdot.data());
    const int n = e.dof(), e0 = e.modal_index(0);
    const Eigen::VectorXd ed = Eigen::Map<const Eigen::VectorXd>(x.data() + n + e0, 3);
    auto energy = [&](const std::vector<double>& y) {
      return e.kinetic_energy(y.data()) + e.potential_energy(y.data());
    };
    const double h = 1e-5;
    const double dE = (energy(advanced(x, xdot, h)) - energy(advanced(x, xdot, -h))) / (2 * h);
    CHECK(close(dE, -ed.dot(D * ed), 1e-7 * (1 + energy(x)), 0));
  }
  TreeState st = test::random_flex_state(s, g, 0.2, 1.0);
  st.w_NB_B = Eigen::Vector3d(1.0, 0.3, -0.5);
  const RunResult r = run(s, st, 1e-12);
  REQUIRE_FALSE(r.failure);
  const auto E = static_cast<std::size_t>(r.column("E"));
  const auto m0 = static_cast<std::size_t>(r.column("body.q1_rate"));
  auto dissipation = [&](std::size_t k) {
    Eigen::Vector3d ed(r.at(k, m0), r.at(k, m0 + 1), r.at(k, m0 + 2));
    return ed.dot(D * ed);
  };
  double lost = 0;  // Simpson's rule over pairs of output steps
  const double dt = s.run.output_step;
  for (std::size_t k = 1; k < r.rows(); ++k) {
    CHECK(r.at(k, E) < r.at(k - 1, E));
    if (k % 2 == 0)
      lost += dt / 3 * (dissipation(k - 2) + 4 * dissipation(k - 1) + dissipation(k));
  }
  const std::size_t last = (r.rows() - 1) / 2 * 2;
  const double change = r.at(last, E) - r.at(0, E);
  INFO("E change " << change << " J, dissipated " << lost << " J");
  CHECK(change < -0.1 * r.at(0, E));
  CHECK(close(change, -lost, 1e-6 * r.at(0, E), 0));
  CHECK(column_drift(r, "H") < 1e-10);
}

TEST_CASE("lagrange flex: a hinge torque at a node frame does work through the relative rotation",
          "[lagrange][flex][run]") {
  // A motor between a flexible body and a rigid body attached at one of its nodes, in both
  // directions (flexible parent; flexible child at its node), revolute and spherical: the only
  // power is tau . (relative angular velocity of the joint frames), so dE/dt = tau rate or
  // tau . w_PC_C; and E(t) - E(0) is the motor's work over a run.
  std::mt19937 g(48);
  for (const JointType type : {JointType::Revolute, JointType::Spherical}) {
    for (const bool flexible_parent : {true, false}) {
      System s;
      s.name = "motor_at_node";
      s.bodies = {test::random_flex_body("plate", 5, 3, 1.2, g, 15.0),
                  test::make_body("box", 3, {0.3, 0.4, 0.5})};
      if (!flexible_parent) std::swap(s.bodies[0], s.bodies[1]);
      s.joints = {test::free_joint(0, {0.4, 0.1, -0.3})};
      Joint j = flexible_parent
                    ? test::joint_at(s, "motor", type, 0, 1, 2, -1, {}, {-0.5, 0.1, 0.0})
                    : test::joint_at(s, "motor", type, 0, 1, -1, 3, {0.6, 0.0, 0.2});
      j.axis_P = Eigen::Vector3d(0.2, 0.3, 1.0).normalized();
      j.q_PJ0 = Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 1, 0).normalized()));
      j.rate0 = 0.4;
      j.w_PC_C0 = {0.1, 0.3, -0.2};
      j.motor_revolute.times = {0.0, 1.0};
      j.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(0.8), Eigen::Matrix<double, 1, 1>(-0.5)};
      j.motor_spherical.times = {0.0, 1.0};
      j.motor_spherical.values = {Eigen::Vector3d(0.5, -0.3, 0.4), Eigen::Vector3d(-0.2, 0.6, 0.1)};
      s.joints.push_back(j);
      s.run.duration = 2;
      s.run.output_step = 0.005;
      INFO((type == JointType::Revolute ? "revolute" : "spherical")
           << (flexible_parent ? ", flexible parent" : ", flexible child"));
      LagrangeEngine e(s, {});
      const int n = e.dof();
      const std::size_t rate = static_cast<std::size_t>(n + (flexible_parent ? 9 : 6));
      for (int trial = 0; trial < 5; ++trial) {
        const std::vector<double> x = packed(e, test::random_flex_state(s, g, 0.1, 1.0));
        std::vector<double> xdot(x.size());
        const double t0 = 0.5, h = 1e-5;
        e.rhs(t0, x.data(), xdot.data());
        const double power =
            type == JointType::Revolute
                ? x[rate] * j.motor_revolute.value(t0)(0)
                : Eigen::Map<const Eigen::Vector3d>(x.data() + rate).dot(j.motor_spherical.value(t0));
        auto energy = [&](const std::vector<double>& y) {
          return e.kinetic_energy(y.data()) + e.potential_energy(y.data());
        };
        const double dE = (energy(advanced(x, xdot, h)) - energy(advanced(x, xdot, -h))) / (2 * h);
        CHECK(close(dE, power, 1e-7 * (1 + energy(x)), 0));
      }
      // Over a run: E(t) - E(0) = integral of the motor's power (Simpson's rule per load interval).
      const RunResult r = run(s, test::random_flex_state(s, g, 0.1, 1.0), 1e-12);
      REQUIRE_FALSE(r.failure);
      const auto E = static_cast<std::size_t>(r.column("E"));
      const auto c = static_cast<std::size_t>(e.layout().joint_first(1));
      auto power_at = [&](std::size_t k, double t) {
        if (type == JointType::Revolute) return r.at(k, c + 1) * j.motor_revolute.value(t)(0);
        return Eigen::Vector3d(r.at(k, c), r.at(k, c + 1), r.at(k, c + 2))
            .dot(j.motor_spherical.value(t));
      };
      double work = 0;
      const double dt = s.run.output_step;
      const std::size_t k_switch = 200;  // t = 1 s, where the motor switches
      REQUIRE(close(r.at(k_switch, 0), 1.0, 1e-12, 0));
      for (std::size_t k = 2; k < r.rows(); k += 2) {
        // No pair of steps straddles the switch (k_switch is even): the load of a pair is the
        // one at its middle.
        const double t_mid = r.at(k - 1, 0);
        work += dt / 3 * (power_at(k - 2, t_mid) + 4 * power_at(k - 1, t_mid) + power_at(k, t_mid));
      }
      const double change = r.at(r.rows() - 1, E) - r.at(0, E);
      INFO("E change " << change << " J, motor work " << work << " J");
      CHECK(close(change, work, 1e-7 * r.at(0, E), 0));
    }
  }
}

TEST_CASE("lagrange flex: pack, labels, modal columns and attitudes of bodies at nodes",
          "[lagrange][flex]") {
  const System s = test::flex_tree(true);
  LagrangeEngine e(s, {});
  // Blocks: base (6 + 3 beam modes), hinge (1), ball (3 + 2 arm modes), weld (0), flap (1 + 2).
  CHECK(e.dof() == 9 + 1 + 5 + 0 + 3);
  CHECK(e.state_label(6) == "beam.q1");
  CHECK(e.state_label(8) == "beam.q3");
  CHECK(e.state_label(13) == "arm.q1");
  CHECK(e.state_label(17) == "flap.q2");
  CHECK(e.state_label(e.dof() + 6) == "beam.q1_rate");
  CHECK(e.state_label(e.dof() + 17) == "flap.q2_rate");
  std::vector<std::string> expected = pinned_columns(s);
  expected.push_back("lagrange.recharts");
  CHECK(e.columns() == expected);
  std::mt19937 g(49);
  for (int trial = 0; trial < 20; ++trial) {
    const TreeState st = test::random_flex_state(s, g);
    const std::vector<double> x = packed(e, st);
    std::vector<double> row(e.columns().size());
    e.output_row(0.0, x.data(), row.data());
    for (std::size_t b = 0; b < s.bodies.size(); ++b) {
      if (!s.bodies[b].flex) continue;
      const auto mc = static_cast<std::size_t>(e.layout().modal_first(static_cast<int>(b)));
      const auto nm = static_cast<Eigen::Index>(s.bodies[b].flex->modes());
      for (Eigen::Index k = 0; k < nm; ++k) {
        CHECK(row[mc + static_cast<std::size_t>(k)] == st.eta[b](k));
        CHECK(row[mc + static_cast<std::size_t>(nm + k)] == st.eta_rate[b](k));
      }
    }
    // q_NC = q_NP q(psi_P) q_PJ0 q_J q(psi_C)^*, formed here from the TreeState.
    std::vector<Eigen::Quaterniond> q(s.bodies.size());
    auto node_q = [&](int body, int node) {
      if (node < 0) return Eigen::Quaterniond::Identity();
      const FlexBody& f = *s.bodies[static_cast<std::size_t>(body)].flex;
      const Eigen::Vector3d psi =
          f.nodes[static_cast<std::size_t>(node)].Psi_B * st.eta[static_cast<std::size_t>(body)];
      return Eigen::Quaterniond(Eigen::AngleAxisd(psi.norm(), psi.normalized()));
    };
    for (std::size_t j = 0; j < s.joints.size(); ++j) {
      const Joint& J = s.joints[j];
      const auto c = static_cast<std::size_t>(J.child);
      if (J.type == JointType::Free) {
        q[c] = st.q_NB;
        continue;
      }
      Eigen::Quaterniond qJ = Eigen::Quaterniond::Identity();
      if (J.type == JointType::Revolute)
        qJ = Eigen::AngleAxisd(st.joints[j].angle, J.q_PJ0.conjugate() * J.axis_P);
      if (J.type == JointType::Spherical) qJ = st.joints[j].q_J;
      q[c] = q[static_cast<std::size_t>(J.parent)] * node_q(J.parent, J.parent_node) * J.q_PJ0 *
             qJ * node_q(J.child, J.child_node).conjugate();
    }
    for (std::size_t b = 0; b < s.bodies.size(); ++b)
      CHECK(rot::angle_between(row_attitude(e, row, static_cast<int>(b)), q[b]) < 1e-13);
    CHECK(e.linear_momentum_N(x.data()).norm() < 1e-12);
  }
}

TEST_CASE("lagrange flex: what the engine cannot run is an InputError naming file, body or joint",
          "[lagrange][flex]") {
  auto message = [](const System& s) -> std::string {
    try {
      make_lagrange_engine(s, {});
    } catch (const InputError& e) {
      return e.what();
    }
    return "no error";
  };
  auto has = [](const std::string& what, std::initializer_list<const char*> parts) {
    for (const char* p : parts)
      if (what.find(p) == std::string::npos) return false;
    return true;
  };
  System base = test::flex_tree(false);
  base.file = "scenes/tree.yaml";
  REQUIRE(message(base) == "no error");
  {  // a joint at a node of a rigid body
    System s = base;
    s.joints[4].parent_node = 0;  // flap_hinge: parent panel is rigid
    const std::string w = message(s);
    INFO(w);
    CHECK(has(w, {"scenes/tree.yaml", "joint 'flap_hinge'", "'panel'", "rigid"}));
  }
  {  // a node index out of range
    System s = base;
    s.joints[2].child_node = 4;  // arm has 4 nodes
    const std::string w = message(s);
    INFO(w);
    CHECK(has(w, {"scenes/tree.yaml", "joint 'ball'", "'arm'", "out of range", "4 nodes"}));
  }
  {  // a joint point that is not the node's position
    System s = base;
    s.joints[1].p_PoJ_P += Eigen::Vector3d(0.01, 0, 0);
    const std::string w = message(s);
    INFO(w);
    CHECK(has(w, {"scenes/tree.yaml", "joint 'hinge'", "parent_point", "node 'beam_n1'"}));
  }
  {  // the free joint at a node
    System s = base;
    s.joints[0].child_node = 0;
    const std::string w = message(s);
    INFO(w);
    CHECK(has(w, {"scenes/tree.yaml", "joint 'base'", "free joint cannot attach at a node"}));
  }
  {  // a mode without kinetic energy (it moves only a massless node)
    System s = base;
    FlexBody& f = *s.bodies[2].flex;
    f.nodes[3].mass = 0;
    for (std::size_t i = 0; i < f.nodes.size(); ++i) f.nodes[i].Phi_B.col(1).setZero();
    f.nodes[3].Phi_B.col(1) = Eigen::Vector3d(0, 0, 1);
    const std::string w = message(s);
    INFO(w);
    CHECK(has(w, {"scenes/tree.yaml", "body 'arm'", "singular", "no kinetic energy"}));
  }
  {  // a mode that is a rigid translation
    System s = base;
    for (FlexNode& nd : s.bodies[0].flex->nodes) nd.Phi_B.col(2) = Eigen::Vector3d(0.3, -0.2, 0.1);
    const std::string w = message(s);
    INFO(w);
    CHECK(has(w, {"scenes/tree.yaml", "body 'beam'", "singular", "rigid-body motion"}));
  }
  {  // K of the wrong size
    System s = base;
    s.bodies[4].flex->K = Eigen::MatrixXd::Identity(3, 3);
    const std::string w = message(s);
    INFO(w);
    CHECK(has(w, {"scenes/tree.yaml", "body 'flap'", "K and D must be 2 x 2"}));
  }
  {  // pack() without the modal state
    LagrangeEngine e(base, {});
    TreeState st = TreeState::initial(base);
    st.eta[2].resize(0);
    std::vector<double> x(static_cast<std::size_t>(e.state_size()));
    try {
      e.pack(st, x.data());
      FAIL("no InputError");
    } catch (const InputError& err) {
      CHECK(has(err.what(), {"flexible body 'arm'", "modal coordinates"}));
    }
  }
}
