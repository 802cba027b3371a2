// The Kane engine with flexible (modal) bodies (docs/flexible-bodies.md): Kane's equations checked
// particle by particle against finite differences, the mass matrix against the node sums, the
// node-rotation helper, zero modes against the rigid body, the free vibration period,
// conservation, damping and the power of motors at node frames, state layout and input errors.
#include <catch2/catch.hpp>

#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "core/rotation.hpp"
#include "formulations/kane/kane.hpp"
#include "formulations/kane/kane_engine.hpp"
#include "tests/kane/kane_flex_systems.hpp"
#include "tests/support/close.hpp"
#include "tests/support/linalg.hpp"

#include <cmath>
#include <random>

using namespace crossdyn;
using namespace crossdyn::test::kane;
using crossdyn::test::all_close;
using crossdyn::test::close;
using crossdyn::test::llt_solve;
using crossdyn::test::symmetric_eigenvalues;
using Eigen::Matrix3d;
using Eigen::Vector3d;
using Eigen::VectorXd;

namespace {

Vector3d vee(const Matrix3d& S) {  // [w x] => w (of the skew part)
  return 0.5 * Vector3d(S(2, 1) - S(1, 2), S(0, 2) - S(2, 0), S(1, 0) - S(0, 1));
}

// Every mass point's velocity, stacked (3 per point, kane::MassPoint order).
VectorXd point_velocities(kane::KaneEngine& e, const std::vector<double>& x) {
  const auto P = e.mass_points(x.data());
  VectorXd v(3 * static_cast<Eigen::Index>(P.size()));
  for (std::size_t i = 0; i < P.size(); ++i)
    v.segment<3>(3 * static_cast<Eigen::Index>(i)) = P[i].v_NP_N;
  return v;
}
VectorXd point_positions(kane::KaneEngine& e, const std::vector<double>& x) {
  const auto P = e.mass_points(x.data());
  VectorXd v(3 * static_cast<Eigen::Index>(P.size()));
  for (std::size_t i = 0; i < P.size(); ++i)
    v.segment<3>(3 * static_cast<Eigen::Index>(i)) = P[i].p_NoP_N;
  return v;
}
// Every body frame's angular velocity in N, stacked (System::bodies order).
VectorXd frame_rates(kane::KaneEngine& e, const std::vector<double>& x) {
  const auto B = e.body_motion(x.data());
  VectorXd w(3 * static_cast<Eigen::Index>(B.size()));
  for (std::size_t b = 0; b < B.size(); ++b)
    w.segment<3>(3 * static_cast<Eigen::Index>(b)) = B[b].R_NB * B[b].w_NB_B;
  return w;
}

// The state x with every speed zero except speed r = 1.
std::vector<double> unit_speed(const kane::KaneEngine& e, const std::vector<double>& x, int r) {
  std::vector<double> y(x);
  for (int i = 0; i < e.speed_size(); ++i)
    y[static_cast<std::size_t>(e.position_size() + i)] = i == r ? 1.0 : 0.0;
  return y;
}

// Hinge torque of joint j in N (on the child-side frame; docs "Loads at joints"), from the state.
Vector3d hinge_torque_N(const System& s, const kane::KaneEngine& e, const std::vector<double>& x,
                        double t, int j, const kane::JointFrames& f) {
  const Joint& J = s.joints[static_cast<std::size_t>(j)];
  const kane::Node& n = e.nodes()[static_cast<std::size_t>(j)];
  const double* u = x.data() + e.position_size() + n.u0;
  if (J.type == JointType::Revolute) {
    const double tau = -J.stiffness * (x[static_cast<std::size_t>(n.q0)] - J.neutral_angle) -
                       J.damping * u[0] + J.motor_revolute.value(t)(0);
    return tau * (f.R_NJp * J.axis_P.normalized());
  }
  if (J.type == JointType::Spherical) {
    const Eigen::Quaterniond q(
        x[static_cast<std::size_t>(n.q0)], x[static_cast<std::size_t>(n.q0 + 1)],
        x[static_cast<std::size_t>(n.q0 + 2)], x[static_cast<std::size_t>(n.q0 + 3)]);
    const Vector3d tau_C = -J.stiffness * rot::rotation_vector(q.normalized()) -
                           J.damping * Vector3d(u[0], u[1], u[2]) + J.motor_spherical.value(t);
    return f.R_NJc * tau_C;
  }
  return Vector3d::Zero();
}

int column(const Engine& e, const std::string& name) {
  const auto& c = e.columns();
  for (std::size_t i = 0; i < c.size(); ++i)
    if (c[i] == name) return static_cast<int>(i);
  FAIL("no column " << name);
  return -1;
}

double max_drift(const RunResult& r, const std::string& name) {
  const std::size_t c = static_cast<std::size_t>(r.column(name));
  double d = 0;
  for (std::size_t i = 0; i < r.rows(); ++i) d = std::max(d, std::abs(r.at(i, c) - r.at(0, c)));
  return d / std::abs(r.at(0, c));
}

IntegratorSettings rkf78(double duration, double output_step, double tol) {
  IntegratorSettings s;
  s.method = "rkf78";
  s.rtol = s.atol = tol;
  s.duration = duration;
  s.output_step = output_step;
  s.dt = 1e-3;
  return s;
}

}  // namespace

TEST_CASE(
    "kane flex: the node rotation exp([psi x]) and its left Jacobian, series and closed forms") {
  // R is Eigen's angle-axis rotation; R' R^T = [(Jl psi') x] and (d/dt Jl) psi' by differences;
  // the series (t < 1) and the closed forms (t >= 1) meet at t = 1.
  std::mt19937 g(3);
  std::normal_distribution<double> N;
  for (double t : {0.0, 1e-7, 1e-3, 0.1, 0.7, 1.0 - 1e-12, 1.0, 1.5, 3.0}) {
    const Vector3d axis = Vector3d(N(g), N(g), N(g)).normalized();
    const Vector3d psi = t * axis, rate(N(g), N(g), N(g));
    kane::NodeRotation r;
    r.set(psi);
    const Matrix3d R_ref = Eigen::AngleAxisd(t, axis).toRotationMatrix();
    INFO("t = " << t);
    CHECK(all_close(r.R(), R_ref, 1e-15, 0));
    if (t == 0) continue;
    auto R_at = [&](double h) {
      kane::NodeRotation q;
      q.set(psi + h * rate);
      return q.R();
    };
    auto Jl_at = [&](double h) {
      kane::NodeRotation q;
      q.set(psi + h * rate);
      return Vector3d(q.Jl() * rate);
    };
    const double h = 1e-4;
    const Vector3d w = vee(derivative(R_at, h) * r.R().transpose());
    CHECK(all_close(w, Vector3d(r.Jl() * rate), 1e-10, 0));
    CHECK(all_close(r.Jl_dot_times(rate), derivative(Jl_at, h), 1e-10, 0));
  }
  // Continuity of a, b, a1, b1 across t = 1 (series below, closed forms above).
  kane::NodeRotation lo, hi;
  lo.set(Vector3d(1.0 - 1e-13, 0, 0));
  hi.set(Vector3d(1.0, 0, 0));
  CHECK(close(lo.a, hi.a, 1e-14, 0));
  CHECK(close(lo.b, hi.b, 1e-14, 0));
  CHECK(close(lo.a1, hi.a1, 1e-14, 0));
  CHECK(close(lo.b1, hi.b1, 1e-14, 0));
}

TEST_CASE("kane flex: positions, joints at nodes and particle velocities are consistent") {
  // The joint point is the same seen from both sides; R_NJc = R_NJp R_PJ0 R_J; every node's
  // velocity is the derivative of its position along the motion.
  // Also with geometric stiffening (u_i = Phi_i eta + e_i 1/2 eta^T G_i eta, joint nodes too).
  for (bool stiff : {false, true}) {
    const System s = stiff ? stiffened(flex_tree(true)) : flex_tree(true);
    kane::KaneEngine e(s, {});
    std::mt19937 g(12);
    INFO((stiff ? "with" : "without") << " geometric stiffening");
    for (int trial = 0; trial < 3; ++trial) {
      std::vector<double> x = packed(e, random_flex_state(s, g)), xdot(x.size());
      e.rhs(0.3, x.data(), xdot.data());
      const auto frames = e.joint_frames(x.data());
      double dp = 0, dR = 0;
      for (std::size_t j = 1; j < s.joints.size(); ++j) {
        const Joint& J = s.joints[j];
        const kane::Node& n = e.nodes()[j];
        dp = std::max(dp, (frames[j].p_NoJ_N_parent - frames[j].p_NoJ_N_child).norm());
        Matrix3d R_J = Matrix3d::Identity();
        if (J.type == JointType::Revolute)
          R_J = Eigen::AngleAxisd(
                    x[static_cast<std::size_t>(n.q0)],
                    J.q_PJ0.normalized().toRotationMatrix().transpose() * J.axis_P.normalized())
                    .toRotationMatrix();
        if (J.type == JointType::Spherical)
          R_J = Eigen::Quaterniond(
                    x[static_cast<std::size_t>(n.q0)], x[static_cast<std::size_t>(n.q0 + 1)],
                    x[static_cast<std::size_t>(n.q0 + 2)], x[static_cast<std::size_t>(n.q0 + 3)])
                    .normalized()
                    .toRotationMatrix();
        dR = std::max(
            dR, (frames[j].R_NJc - frames[j].R_NJp * J.q_PJ0.normalized().toRotationMatrix() * R_J)
                    .cwiseAbs()
                    .maxCoeff());
      }
      const VectorXd v_fd =
          derivative([&](double h) { return point_positions(e, along(x, xdot, h)); }, 1e-4);
      const VectorXd v = point_velocities(e, x);
      INFO("joint point gap " << dp << " m, joint frame error " << dR << ", max |v - dx/dt| "
                              << (v - v_fd).cwiseAbs().maxCoeff() << " m/s");
      CHECK(dp <= 1e-14);
      CHECK(dR <= 1e-14);
      CHECK(all_close(v, v_fd, 1e-9, 1e-10));
    }
  }
}

TEST_CASE("kane flex: Kane's equations F_r + F_r* = 0 hold particle by particle at random states") {
  // Independent of the engine's modal integrals, subtree sums and remainder terms: with the
  // engine's u' (rhs), every node's acceleration a_i is the difference quotient of its velocity
  // along the motion, every partial velocity V_r^i is its velocity at u = e_r (velocities are
  // linear in u), the partial angular velocities of body and joint frames likewise, and
  //   sum_i V_r^i . (-m_i a_i) + sum_B W_r^B . (T_B - J alpha - w x J w)
  //     + sum_hinges (W_r^Jc - W_r^Jp) . tau  -  (K eta + D eta')_r  =  0     ([KLL] Eq. (4.11.2)).
  const double t = 0.4, h = 1e-4;
  // Also with geometric stiffening on every flexible body (stiffened(): its exactness, joint
  // nodes included; the particles' positions and velocities of mass_points() carry it).
  for (int variant = 0; variant < 4; ++variant) {
    const bool loaded = variant % 2 == 1, stiff = variant >= 2;
    const System s = stiff ? stiffened(flex_tree(loaded)) : flex_tree(loaded);
    kane::KaneEngine e(s, {});
    const int nq = e.position_size(), nu = e.speed_size();
    std::mt19937 g(loaded ? 31 : 32);
    INFO((stiff ? "with" : "without") << " geometric stiffening");
    for (int trial = 0; trial < 3; ++trial) {
      std::vector<double> x = packed(e, random_flex_state(s, g)), xdot(x.size());
      e.rhs(t, x.data(), xdot.data());
      const auto pts = e.mass_points(x.data());
      const auto bodies = e.body_motion(x.data());
      const auto frames = e.joint_frames(x.data());
      const VectorXd a =
          derivative([&](double k) { return point_velocities(e, along(x, xdot, k)); }, h);
      const VectorXd alpha =
          derivative([&](double k) { return frame_rates(e, along(x, xdot, k)); }, h);
      double worst = 0, scale = 0;
      for (int r = 0; r < nu; ++r) {
        const std::vector<double> y = unit_speed(e, x, r);
        std::vector<double> ydot(y.size());
        e.rhs(t, y.data(), ydot.data());
        const VectorXd V = point_velocities(e, y), W = frame_rates(e, y);
        double F = 0, size = 0;
        auto add = [&](double term) {
          F += term;
          size += std::abs(term);
        };
        for (std::size_t i = 0; i < pts.size(); ++i) {
          const kane::MassPoint& p = pts[i];
          const Eigen::Index b3 = 3 * p.body, i3 = 3 * static_cast<Eigen::Index>(i);
          const Vector3d w = bodies[static_cast<std::size_t>(p.body)].R_NB *
                             bodies[static_cast<std::size_t>(p.body)].w_NB_B;
          add(V.segment<3>(i3).dot(-p.mass * a.segment<3>(i3)));
          add(W.segment<3>(b3).dot(-(p.J_N * alpha.segment<3>(b3)) - w.cross(p.J_N * w)));
        }
        for (std::size_t b = 0; b < s.bodies.size(); ++b) {
          const Body& B = s.bodies[b];
          if (B.torque.empty()) continue;
          const Vector3d T = B.torque_frame == Body::Frame::Body
                                 ? Vector3d(bodies[b].R_NB * B.torque.value(t))
                                 : Vector3d(B.torque.value(t));
          add(W.segment<3>(3 * static_cast<Eigen::Index>(b)).dot(T));
        }
        for (std::size_t j = 1; j < s.joints.size(); ++j) {
          const Vector3d tau = hinge_torque_N(s, e, x, t, static_cast<int>(j), frames[j]);
          if (tau.norm() == 0) continue;
          auto Rc = [&](double k) {
            return Matrix3d(e.joint_frames(along(y, ydot, k).data())[j].R_NJc);
          };
          auto Rp = [&](double k) {
            return Matrix3d(e.joint_frames(along(y, ydot, k).data())[j].R_NJp);
          };
          const Vector3d Wc = vee(derivative(Rc, h) * frames[j].R_NJc.transpose());
          const Vector3d Wp = vee(derivative(Rp, h) * frames[j].R_NJp.transpose());
          add((Wc - Wp).dot(tau));
        }
        for (const kane::Node& n : e.nodes())
          if (r >= n.u0 + n.nuj && r < n.u0 + n.nu) {
            const int l = r - n.u0 - n.nuj;
            const FlexBody& fb = *s.bodies[static_cast<std::size_t>(n.body)].flex;
            const Eigen::Map<const VectorXd> eta(x.data() + n.q0 + n.nqj, n.nm),
                eta_rate(x.data() + nq + n.u0 + n.nuj, n.nm);
            add(-fb.K.row(l).dot(eta) - (fb.D.size() ? fb.D.row(l).dot(eta_rate) : 0.0));
          }
        worst = std::max(worst, std::abs(F));
        scale = std::max(scale, size);
      }
      INFO(s.name << ": max_r |F_r + F_r*| = " << worst << " against terms of size " << scale);
      CHECK(worst <= 1e-8 * scale);
    }
  }
}

TEST_CASE(
    "kane flex: the mass matrix is sum m_i V_r.V_s + W_r.J W_s over the nodes, symmetric "
    "and positive definite, energy and momenta equal the node sums") {
  const System s = flex_tree(true);
  kane::KaneEngine e(s, {});
  const int nq = e.position_size(), nu = e.speed_size();
  std::mt19937 g(13);
  for (int trial = 0; trial < 4; ++trial) {
    const std::vector<double> x = packed(e, random_flex_state(s, g));
    const Eigen::MatrixXd M = e.mass_matrix(x.data());
    const auto pts = e.mass_points(x.data());
    std::vector<VectorXd> V, W;
    for (int r = 0; r < nu; ++r) {
      V.push_back(point_velocities(e, unit_speed(e, x, r)));
      W.push_back(frame_rates(e, unit_speed(e, x, r)));
    }
    Eigen::MatrixXd Mb = Eigen::MatrixXd::Zero(nu, nu);
    for (int r = 0; r < nu; ++r)
      for (int c = 0; c < nu; ++c)
        for (std::size_t i = 0; i < pts.size(); ++i) {
          const Eigen::Index i3 = 3 * static_cast<Eigen::Index>(i), b3 = 3 * pts[i].body;
          Mb(r, c) += pts[i].mass * V[static_cast<std::size_t>(r)].segment<3>(i3).dot(
                                        V[static_cast<std::size_t>(c)].segment<3>(i3)) +
                      W[static_cast<std::size_t>(r)].segment<3>(b3).dot(
                          pts[i].J_N * W[static_cast<std::size_t>(c)].segment<3>(b3));
        }
    INFO("max |M - M_nodes| = " << (M - Mb).cwiseAbs().maxCoeff()
                                << ", max |M| = " << M.cwiseAbs().maxCoeff());
    CHECK(all_close(M, Mb, 0.0, 1e-13));
    CHECK(symmetric_eigenvalues(M).minCoeff() > 0);

    // Energy and momenta against the node sums at the state itself.
    const auto bodies = e.body_motion(x.data());
    double T = 0, m = 0;
    Vector3d P = Vector3d::Zero(), c = Vector3d::Zero(), H = Vector3d::Zero();
    for (const kane::MassPoint& p : pts) {
      const Vector3d w = bodies[static_cast<std::size_t>(p.body)].R_NB *
                         bodies[static_cast<std::size_t>(p.body)].w_NB_B;
      T += 0.5 * p.mass * p.v_NP_N.squaredNorm() + 0.5 * w.dot(p.J_N * w);
      P += p.mass * p.v_NP_N;
      c += p.mass * p.p_NoP_N;
      m += p.mass;
      H += p.J_N * w;
    }
    c /= m;
    for (const kane::MassPoint& p : pts) H += (p.p_NoP_N - c).cross(p.mass * p.v_NP_N);
    const VectorXd u = Eigen::Map<const VectorXd>(x.data() + nq, nu);
    CHECK(close(e.kinetic_energy(x.data()), T, 0, 1e-13));
    CHECK(close(0.5 * u.dot(M * u), T, 0, 1e-12));
    CHECK(all_close(e.linear_momentum_N(x.data()), P, 1e-12 * m, 1e-12));
    CHECK(all_close(e.angular_momentum_N(x.data()), H, 1e-12, 1e-12));
  }
}

TEST_CASE("kane flex: the sparse L^T D L solve satisfies M u' = f and agrees with Eigen's LLT") {
  const System s = flex_tree(true);
  kane::KaneEngine e(s, {});
  const int nq = e.position_size(), nu = e.speed_size();
  std::mt19937 g(14);
  for (int trial = 0; trial < 5; ++trial) {
    std::vector<double> x = packed(e, random_flex_state(s, g)), xdot(x.size());
    e.rhs(0.1, x.data(), xdot.data());
    const Eigen::MatrixXd M = e.mass_matrix(x.data());
    const VectorXd f = e.generalized_forces(0.1, x.data());
    const VectorXd udot = Eigen::Map<const VectorXd>(xdot.data() + nq, nu);
    Eigen::ComputationInfo llt_info{};
    const VectorXd udot_llt = llt_solve(M, f, &llt_info);
    REQUIRE(llt_info == Eigen::Success);
    CHECK(all_close(udot, udot_llt, 1e-12, 1e-11));
  }
}

TEST_CASE(
    "kane flex: accelerations() agree with differences of the body frames' motion, eta'' is "
    "the modal part of xdot") {
  const System s = flex_tree(true);
  kane::KaneEngine e(s, {});
  std::mt19937 g(15);
  const double h = 1e-3;
  for (int trial = 0; trial < 3; ++trial) {
    std::vector<double> x = packed(e, random_flex_state(s, g)), xdot(x.size());
    e.rhs(0.2, x.data(), xdot.data());
    TreeAccel a;
    e.accelerations(0.2, x.data(), a);
    REQUIRE(a.eta_ddot.size() == s.bodies.size());
    const auto m0 = e.body_motion(x.data());
    double ev = 0, eR = 0, ea = 0, ew = 0;
    for (std::size_t b = 0; b < s.bodies.size(); ++b) {
      auto motion = [&](double k) { return e.body_motion(along(x, xdot, k).data())[b]; };
      const Vector3d v = derivative([&](double k) { return Vector3d(motion(k).p_NoBo_N); }, h);
      const Matrix3d Rd = derivative([&](double k) { return Matrix3d(motion(k).R_NB); }, h);
      const Vector3d ad = derivative([&](double k) { return Vector3d(motion(k).v_NBo_N); }, h);
      const Vector3d wd = derivative([&](double k) { return Vector3d(motion(k).w_NB_B); }, h);
      ev = std::max(ev, (v - m0[b].v_NBo_N).norm());
      eR = std::max(eR, (Rd - m0[b].R_NB * rot::skew(m0[b].w_NB_B)).cwiseAbs().maxCoeff());
      ea = std::max(ea, (ad - a.a_NBo_N[b]).norm());
      ew = std::max(ew, (wd - a.wdot_NB_B[b]).norm());
    }
    INFO("velocity " << ev << ", attitude rate " << eR << ", acceleration " << ea
                     << ", angular acceleration " << ew);
    CHECK(ev <= 1e-8);
    CHECK(eR <= 1e-8);
    CHECK(ea <= 1e-8);
    CHECK(ew <= 1e-8);
    for (const kane::Node& n : e.nodes()) {
      const VectorXd& dd = a.eta_ddot[static_cast<std::size_t>(n.body)];
      REQUIRE(dd.size() == n.nm);
      for (int l = 0; l < n.nm; ++l)
        CHECK(dd(l) == xdot[static_cast<std::size_t>(e.position_size() + n.u0 + n.nuj + l)]);
    }
  }
}

namespace {

// A flexible base with zero modes (its nodes' mass and inertia) carrying a flexible child with
// zero modes at nodes, and a rigid grandchild; `rigid` replaces both flexible bodies by rigid
// bodies with the same mass and inertia and the same joint points.
System zero_mode_tree(bool rigid) {
  std::mt19937 g(41);
  System s;
  s.name = rigid ? "rigid_twin" : "zero_modes";
  s.bodies.push_back(random_flex_body("hub", 5, 0, g, 1.0));
  s.bodies.push_back(random_flex_body("wing", 4, 0, g, 0.8));
  s.bodies.push_back(
      rigid_body("tip", 1.2, turned_inertia(0.02, 0.03, 0.04, quat_from_axis(0.4, {1, 0, 1}))));
  s.joints.push_back(
      free_joint("base", 0, Vector3d(0.4, -0.3, 0.9), quat_from_axis(0.3, {1, 2, 3})));
  Joint root =
      joint("root", JointType::Revolute, 0, 1, node_position(s, 0, 1), node_position(s, 1, 2));
  root.parent_node = 1;
  root.child_node = 2;
  root.axis_P = Vector3d(0.3, -0.2, 1).normalized();
  root.stiffness = 3;
  root.rate0 = 0.8;
  s.joints.push_back(root);
  Joint tip =
      joint("tipj", JointType::Spherical, 1, 2, node_position(s, 1, 0), Vector3d(0.1, 0.05, 0));
  tip.parent_node = 0;
  tip.w_PC_C0 = Vector3d(0.3, -0.5, 0.2);
  s.joints.push_back(tip);
  if (rigid) {
    for (int b = 0; b < 2; ++b) s.bodies[static_cast<std::size_t>(b)].flex.reset();
    for (Joint& j : s.joints) j.parent_node = j.child_node = -1;
  }
  return s;
}

}  // namespace

TEST_CASE("kane flex: flexible bodies with zero modes move exactly as rigid bodies") {
  const System flex = zero_mode_tree(false), rigid = zero_mode_tree(true);
  kane::KaneEngine ef(flex, {}), er(rigid, {});
  REQUIRE(ef.state_size() == er.state_size());
  REQUIRE(ef.columns() == er.columns());
  std::vector<double> xf = packed(ef, TreeState::initial(flex)),
                      xr = packed(er, TreeState::initial(rigid));
  std::vector<double> rf(ef.columns().size()), rr(rf.size());
  double diff = 0;
  rk4(ef, xf, 0.0, 1e-3, 3000, [&](double, const std::vector<double>&) {});
  rk4(er, xr, 0.0, 1e-3, 3000, [&](double, const std::vector<double>&) {});
  ef.output_row(3.0, xf.data(), rf.data());
  er.output_row(3.0, xr.data(), rr.data());
  for (std::size_t i = 0; i < rf.size(); ++i) diff = std::max(diff, std::abs(rf[i] - rr[i]));
  double state_diff = 0;
  for (std::size_t i = 0; i < xf.size(); ++i)
    state_diff = std::max(state_diff, std::abs(xf[i] - xr[i]));
  INFO("after 3 s: largest difference of the states " << state_diff << ", of the output rows "
                                                      << diff);
  CHECK(state_diff <= 1e-11);
  CHECK(diff <= 1e-10);
}

namespace {

// A free body whose one mode is momentum-free (sum m_i Phi_i = 0, sum m_i p_i x Phi_i = 0): three
// nodes on a line bending symmetrically (masses m, 2m, m; Phi_z = 1, -1, 1), with node inertias
// so that the rigid inertia is regular.
System vibrating_body(double k) {
  const double m = 2.0, L = 1.5;
  const Matrix3d J = diag(0.05, 0.07, 0.06);
  auto shape = [](double z) {
    Eigen::Matrix3Xd Phi(3, 1);
    Phi << 0, 0, z;
    return Phi;
  };
  Eigen::Matrix3Xd slope(3, 1);
  slope << 0, 0.4, 0;
  std::vector<FlexNode> nodes = {
      flex_node("left", m, Vector3d(-L, 0, 0), J, shape(1), slope),
      flex_node("middle", 2 * m, Vector3d(0, 0, 0), J, shape(-1), Eigen::Matrix3Xd::Zero(3, 1)),
      flex_node("right", m, Vector3d(L, 0, 0), J, shape(1), -slope)};
  System s;
  s.name = "vibrating_body";
  s.bodies.push_back(
      flex_body("beam", nodes, Eigen::MatrixXd::Constant(1, 1, k), Eigen::MatrixXd::Zero(1, 1)));
  s.joints.push_back(free_joint("base", 0, Vector3d::Zero()));
  return s;
}

}  // namespace

TEST_CASE(
    "kane flex: a momentum-free mode of a free body vibrates at sqrt(K / M_modal), the rigid "
    "motion stays zero") {
  const double k = 37.0, M_modal = 2.0 + 4.0 + 2.0;  // sum m_i |Phi_i|^2
  const double omega = std::sqrt(k / M_modal), period = 2 * M_PI / omega;
  const System s = vibrating_body(k);
  kane::KaneEngine e(s, {});
  TreeState st = TreeState::initial(s);
  const double eta0 = 1e-3;
  st.eta[0](0) = eta0;
  const RunResult r = simulate(e, s, st, rkf78(10 * period, period / 64, 1e-13));
  REQUIRE_FALSE(r.failure.has_value());
  const std::size_t ce = static_cast<std::size_t>(r.column("beam.q1")),
                    cr = static_cast<std::size_t>(r.column("beam.q1_rate"));
  // Zero crossings of eta, located by the cubic Hermite interpolant of (eta, eta') between rows
  // and Newton's method; the period is the mean spacing of the first and last crossing.
  std::vector<double> crossings;
  for (std::size_t i = 0; i + 1 < r.rows(); ++i) {
    const double t0 = r.at(i, 0), t1 = r.at(i + 1, 0), dt = t1 - t0;
    const double y0 = r.at(i, ce), y1 = r.at(i + 1, ce), d0 = r.at(i, cr) * dt,
                 d1 = r.at(i + 1, cr) * dt;
    if ((y0 > 0) == (y1 > 0)) continue;
    auto H = [&](double s_) {
      const double s2 = s_ * s_, s3 = s2 * s_;
      return (2 * s3 - 3 * s2 + 1) * y0 + (s3 - 2 * s2 + s_) * d0 + (-2 * s3 + 3 * s2) * y1 +
             (s3 - s2) * d1;
    };
    auto dH = [&](double s_) {
      const double s2 = s_ * s_;
      return (6 * s2 - 6 * s_) * y0 + (3 * s2 - 4 * s_ + 1) * d0 + (-6 * s2 + 6 * s_) * y1 +
             (3 * s2 - 2 * s_) * d1;
    };
    double x = y0 / (y0 - y1);
    for (int it = 0; it < 20; ++it) x -= H(x) / dH(x);
    crossings.push_back(t0 + x * dt);
  }
  REQUIRE(crossings.size() >= 19);
  const double measured =
      2 * (crossings.back() - crossings.front()) / static_cast<double>(crossings.size() - 1);
  // Rigid motion: the base's angular velocity and attitude, its position.
  double rigid = 0;
  for (const char* c : {"beam.wx", "beam.wy", "beam.wz", "beam.qx", "beam.qy", "beam.qz"})
    for (std::size_t i = 0; i < r.rows(); ++i)
      rigid = std::max(rigid, std::abs(r.at(i, static_cast<std::size_t>(r.column(c)))));
  double amplitude = 0;
  for (std::size_t i = 0; i < r.rows(); ++i) amplitude = std::max(amplitude, std::abs(r.at(i, ce)));
  INFO("period " << measured << " s, 2 pi / omega = " << period << " s, relative difference "
                 << (measured - period) / period << "; largest rigid rate/attitude component "
                 << rigid << "; amplitude " << amplitude);
  CHECK(close(measured, period, 0, 1e-8));
  CHECK(rigid <= 1e-15);
  CHECK(close(amplitude, eta0, 0, 1e-9));
}

TEST_CASE(
    "kane flex: H and E are conserved over a run with large deformation and rotation, joints "
    "at nodes of flexible parents and children") {
  const System s = flex_tree(false);
  kane::KaneEngine e(s, {});
  const RunResult r = simulate(e, s, flex_state(s, 0.15, 0.4), rkf78(60.0, 0.05, 1e-12));
  REQUIRE_FALSE(r.failure.has_value());
  double eta_max = 0, psi = 0;
  for (std::size_t c = 0; c < r.columns.size(); ++c)
    if (r.columns[c] == "bus.q1" || r.columns[c] == "panel.q1" || r.columns[c] == "boom.q2")
      for (std::size_t i = 0; i < r.rows(); ++i) eta_max = std::max(eta_max, std::abs(r.at(i, c)));
  for (std::size_t i = 0; i < r.rows(); ++i)
    psi = std::max(psi,
                   2 * std::acos(std::min(
                           1.0, std::abs(r.at(i, static_cast<std::size_t>(r.column("bus.qw")))))));
  const double dH = max_drift(r, "H"), dE = max_drift(r, "E");
  INFO("max |eta| = " << eta_max << ", largest base rotation " << psi
                      << " rad; relative drift of H " << dH << ", of E " << dE << " ("
                      << r.stats.rhs_calls << " rhs calls)");
  CHECK(eta_max >= 0.1);
  CHECK(psi >= 1.0);
  CHECK(dH <= 1e-10);
  CHECK(dE <= 1e-10);
}

TEST_CASE(
    "kane flex: power balance dE/dt = loads' power - eta'^T D eta' and dH/dt = external "
    "torques at random states") {
  const System s = flex_tree(true);
  kane::KaneEngine e(s, {});
  std::mt19937 g(16);
  const double t = 0.5, h = 3e-4;
  const int cE = column(e, "E");
  for (int trial = 0; trial < 5; ++trial) {
    std::vector<double> x = packed(e, random_flex_state(s, g)), xdot(x.size()),
                        row(e.columns().size());
    e.rhs(t, x.data(), xdot.data());
    const double dEdt = derivative(
        [&](double k) {
          e.output_row(t, along(x, xdot, k).data(), row.data());
          return row[static_cast<std::size_t>(cE)];
        },
        h);
    const Vector3d dHdt = derivative(
        [&](double k) { return Vector3d(e.angular_momentum_N(along(x, xdot, k).data())); }, h);
    const auto bodies = e.body_motion(x.data());
    double power = 0;
    Vector3d torque = Vector3d::Zero();
    for (const kane::Node& n : e.nodes()) {
      const Joint& J = s.joints[static_cast<std::size_t>(n.joint)];
      const double* u = x.data() + e.position_size() + n.u0;
      if (J.type == JointType::Revolute)
        power += (J.motor_revolute.value(t)(0) - J.damping * u[0]) * u[0];
      if (J.type == JointType::Spherical) {
        const Vector3d w(u[0], u[1], u[2]);
        power += (J.motor_spherical.value(t) - J.damping * w).dot(w);
      }
      const Body& B = s.bodies[static_cast<std::size_t>(n.body)];
      const kane::BodyMotion& m = bodies[static_cast<std::size_t>(n.body)];
      if (!B.torque.empty()) {
        const Vector3d T = B.torque_frame == Body::Frame::Body
                               ? Vector3d(m.R_NB * B.torque.value(t))
                               : Vector3d(B.torque.value(t));
        power += T.dot(m.R_NB * m.w_NB_B);
        torque += T;
      }
      if (n.nm > 0) {
        const Eigen::Map<const VectorXd> rate(u + n.nuj, n.nm);
        power -= rate.dot(B.flex->D * rate);
      }
    }
    INFO("dE/dt = " << dEdt << " W, power = " << power
                    << " W; |dH/dt - T| = " << (dHdt - torque).norm());
    CHECK(close(dEdt, power, 1e-8, 1e-8));
    CHECK(all_close(dHdt, torque, 1e-8, 1e-8));
  }
}

TEST_CASE(
    "kane flex: with modal damping alone E decreases monotonically at the rate eta'^T D eta'") {
  System s = flex_tree(false);
  for (Body& b : s.bodies)
    if (b.flex) b.flex->D = 0.02 * b.flex->K;
  kane::KaneEngine e(s, {});
  const RunResult r = simulate(e, s, flex_state(s, 0.1, 0.3), rkf78(10.0, 0.02, 1e-12));
  REQUIRE_FALSE(r.failure.has_value());
  const std::size_t cE = static_cast<std::size_t>(r.column("E"));
  // Monotone, and the energy lost equals the integral of eta'^T D eta' (trapezoid rule on the
  // rows: error O(dt^2), hence the loose tolerance; the exact rate is checked below).
  double increase = 0;
  for (std::size_t i = 0; i + 1 < r.rows(); ++i)
    increase = std::max(increase, r.at(i + 1, cE) - r.at(i, cE));
  auto dissipation = [&](std::size_t i) {
    double d = 0;
    for (const Body& b : s.bodies) {
      if (!b.flex) continue;
      const Eigen::Index n = b.flex->modes();
      VectorXd rate(n);
      for (Eigen::Index k = 0; k < n; ++k)
        rate(k) =
            r.at(i, static_cast<std::size_t>(r.column(
                        b.name + "." + b.flex->mode_names[static_cast<std::size_t>(k)] + "_rate")));
      d += rate.dot(b.flex->D * rate);
    }
    return d;
  };
  double integral = 0;
  for (std::size_t i = 0; i + 1 < r.rows(); ++i)
    integral += 0.5 * (dissipation(i) + dissipation(i + 1)) * (r.at(i + 1, 0) - r.at(i, 0));
  const double lost = r.at(0, cE) - r.at(r.rows() - 1, cE);
  INFO("E lost " << lost << " J, integral of eta'^T D eta' (trapezoid) " << integral
                 << " J; largest increase between rows " << increase << " J");
  CHECK(increase <= 1e-12 * std::abs(r.at(0, cE)));
  CHECK(lost > 0);
  CHECK(close(integral, lost, 0, 1e-3));
  // At random states, exactly: dE/dt = -eta'^T D eta' (five-point differences).
  std::mt19937 g(17);
  const int c = column(e, "E");
  for (int trial = 0; trial < 3; ++trial) {
    std::vector<double> x = packed(e, random_flex_state(s, g)), xdot(x.size()),
                        row(e.columns().size());
    e.rhs(0, x.data(), xdot.data());
    const double dEdt = derivative(
        [&](double k) {
          e.output_row(0, along(x, xdot, k).data(), row.data());
          return row[static_cast<std::size_t>(c)];
        },
        3e-4);
    double diss = 0;
    for (const kane::Node& n : e.nodes())
      if (n.nm > 0) {
        const Eigen::Map<const VectorXd> rate(x.data() + e.position_size() + n.u0 + n.nuj, n.nm);
        diss += rate.dot(s.bodies[static_cast<std::size_t>(n.body)].flex->D * rate);
      }
    INFO("dE/dt = " << dEdt << ", -eta'^T D eta' = " << -diss);
    CHECK(close(dEdt, -diss, 1e-9, 1e-8));
  }
}

namespace {

// A rigid hub and a flexible appendage joined at a node by a revolute motor, either with the
// appendage as the child (attached at its node 0) or as the base (the hub attached at its node 2).
System motor_at_node(bool flexible_child) {
  std::mt19937 g(51);
  System s;
  s.name = flexible_child ? "motor_flex_child" : "motor_flex_parent";
  Body hub = rigid_body("hub", 40, turned_inertia(3, 4, 5, quat_from_axis(0.2, {1, 1, 0})));
  Body wing = random_flex_body("wing", 5, 3, g, 1.0, 0.5, 0.8, 15.0);
  const double tau = 0.9;
  Joint j;
  if (flexible_child) {
    s.bodies = {hub, wing};
    s.joints.push_back(free_joint("base", 0, Vector3d(0.1, 0.2, -0.1)));
    j = joint("motor", JointType::Revolute, 0, 1, Vector3d(0.8, 0.1, 0), node_position(s, 1, 0));
    j.child_node = 0;
  } else {
    s.bodies = {wing, hub};
    s.joints.push_back(free_joint("base", 0, Vector3d(0.1, 0.2, -0.1)));
    j = joint("motor", JointType::Revolute, 0, 1, node_position(s, 0, 2), Vector3d(-0.5, 0, 0.2));
    j.parent_node = 2;
  }
  j.axis_P = Vector3d(0.1, 0.3, 1).normalized();
  j.motor_revolute.times = {0.0};
  j.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(tau)};
  s.joints.push_back(j);
  return s;
}

}  // namespace

TEST_CASE(
    "kane flex: a motor at a node frame does work tau (theta - theta0) through the node's "
    "rotation") {
  // The motor's torque is constant, so its work is tau times the change of the joint angle, which
  // is the rotation of the child-side joint frame relative to the parent-side one (both turning
  // with their nodes).  Nothing else does work: E(t) - E(0) = tau (theta(t) - theta(0)).
  for (bool flexible_child : {true, false}) {
    const System s = motor_at_node(flexible_child);
    kane::KaneEngine e(s, {});
    TreeState st = flex_state(s, 0.1, 0.3);
    const RunResult r = simulate(e, s, st, rkf78(8.0, 0.05, 1e-12));
    REQUIRE_FALSE(r.failure.has_value());
    const std::size_t cE = static_cast<std::size_t>(r.column("E")),
                      ca = static_cast<std::size_t>(r.column("motor.angle"));
    const double tau = s.joints[1].motor_revolute.values[0](0);
    double worst = 0, work = 0;
    for (std::size_t i = 0; i < r.rows(); ++i) {
      const double w = tau * (r.at(i, ca) - r.at(0, ca));
      work = std::max(work, std::abs(w));
      worst = std::max(worst, std::abs(r.at(i, cE) - r.at(0, cE) - w));
    }
    INFO(s.name << ": largest |E - E0 - tau (theta - theta0)| = " << worst << " J; largest work "
                << work << " J; E0 = " << r.at(0, cE) << " J");
    CHECK(work > 0.1);
    CHECK(worst <= 1e-10 * std::abs(r.at(0, cE)));
  }
}

TEST_CASE("kane flex: pack makes the total linear momentum zero, modal rates included") {
  const System s = flex_tree(true);
  kane::KaneEngine e(s, {});
  std::mt19937 g(18);
  for (int trial = 0; trial < 4; ++trial) {
    const TreeState st = random_flex_state(s, g);
    const std::vector<double> x = packed(e, st);
    Vector3d P = Vector3d::Zero();
    double m = 0;
    for (const kane::MassPoint& p : e.mass_points(x.data())) {
      P += p.mass * p.v_NP_N;
      m += p.mass;
    }
    INFO("|P| from the node velocities = " << P.norm());
    CHECK(P.norm() <= 1e-13 * m);
    // The modal coordinates and rates are the tree state's.
    for (const kane::Node& n : e.nodes())
      for (int l = 0; l < n.nm; ++l) {
        CHECK(x[static_cast<std::size_t>(n.q0 + n.nqj + l)] ==
              st.eta[static_cast<std::size_t>(n.body)](l));
        CHECK(x[static_cast<std::size_t>(e.position_size() + n.u0 + n.nuj + l)] ==
              st.eta_rate[static_cast<std::size_t>(n.body)](l));
      }
  }
}

TEST_CASE(
    "kane flex: state labels name the modal states, output rows carry eta, eta' and E with "
    "the strain energy") {
  const System s = vibrating_body(20.0);
  kane::KaneEngine e(s, {});
  const std::vector<std::string> expected = {
      "beam.x",  "beam.y",  "beam.z",  "beam.qw", "beam.qx", "beam.qy", "beam.qz",     "beam.q1",
      "beam.wx", "beam.wy", "beam.wz", "beam.vx", "beam.vy", "beam.vz", "beam.q1_rate"};
  REQUIRE(e.state_size() == static_cast<int>(expected.size()));
  for (int i = 0; i < e.state_size(); ++i)
    CHECK(e.state_label(i) == expected[static_cast<std::size_t>(i)]);
  TreeState st = TreeState::initial(s);
  st.eta[0](0) = 0.02;
  st.eta_rate[0](0) = -0.3;
  std::vector<double> x = packed(e, st), row(e.columns().size());
  e.output_row(0, x.data(), row.data());
  CHECK(row[static_cast<std::size_t>(column(e, "beam.q1"))] == 0.02);
  CHECK(row[static_cast<std::size_t>(column(e, "beam.q1_rate"))] == -0.3);
  // Momentum-free mode, body at rest otherwise: E = 1/2 Mm eta'^2 + 1/2 K eta^2.
  CHECK(close(row[static_cast<std::size_t>(column(e, "E"))], 0.5 * 8.0 * 0.09 + 0.5 * 20.0 * 0.0004,
              0, 1e-14));
  CHECK(close(row[static_cast<std::size_t>(column(e, "H"))], 0, 1e-15, 0));
}

TEST_CASE(
    "kane flex: inconsistent or singular modal data are refused with InputError naming the "
    "body or joint") {
  auto expect = [](const System& s, const std::string& a, const std::string& b) {
    CHECK_THROWS_WITH(make_kane_engine(s, {}), Catch::Contains(a) && Catch::Contains(b));
  };
  {
    System s = vibrating_body(10);
    s.bodies[0].mass += 1;
    expect(s, "body 'beam'", "differs from the sum of its node masses");
  }
  {
    System s = vibrating_body(10);
    s.bodies[0].I_BBo_B(0, 0) *= 1.1;
    expect(s, "body 'beam'", "inertia differs from the node sum");
  }
  {
    System s = vibrating_body(10);
    s.bodies[0].flex->K = Eigen::MatrixXd::Identity(2, 2);
    expect(s, "body 'beam'", "K (modal stiffness) is 2 x 2, the body has 1 modes");
  }
  {
    System s = vibrating_body(10);
    for (FlexNode& n : s.bodies[0].flex->nodes) n.Phi_B.setZero();
    expect(s, "body 'beam'", "mode 'q1' moves no mass");
  }
  {
    System s = vibrating_body(10);  // a mode that is a rigid translation
    for (FlexNode& n : s.bodies[0].flex->nodes) n.Phi_B << 0, 0, 1;
    expect(s, "body 'beam'", "cannot tell the modes and the rigid motions apart");
  }
  {
    System s = vibrating_body(10);
    s.bodies[0].flex->nodes[1].mass = -1;
    expect(s, "node 'middle'", "mass must be finite and not negative");
  }
  {
    System s = motor_at_node(true);
    s.joints[1].child_node = 7;
    expect(s, "joint 'motor'", "child_node 7 of body 'wing' does not exist");
  }
  {
    System s = motor_at_node(true);
    s.joints[1].parent_node = 0;
    expect(s, "joint 'motor'", "parent_node is set but body 'hub' is rigid");
  }
  {
    System s = motor_at_node(true);
    s.joints[1].p_CoJ_C += Vector3d(0.01, 0, 0);
    expect(s, "joint 'motor'", "child_point differs from the position of node 'wing_n0'");
  }
}
