// Structural properties of the Kane engine at single states: the mass matrix, the solve,
// momentum after pack, accelerations and velocities against finite differences, the power
// balance of every load, labels, columns and input errors.
#include <catch2/catch.hpp>

#include "core/errors.hpp"
#include "core/rotation.hpp"
#include "formulations/kane/kane.hpp"
#include "formulations/kane/kane_engine.hpp"
#include "tests/kane/kane_systems.hpp"
#include "tests/support/close.hpp"
#include "tests/support/linalg.hpp"
#include "tests/support/paths.hpp"
#include "core/scene/scene.hpp"


#include <algorithm>
#include <random>

using namespace crossdyn;
using namespace crossdyn::test::kane;
using crossdyn::test::all_close;
using crossdyn::test::close;
using crossdyn::test::llt_solve;
using crossdyn::test::symmetric_eigenvalues;

namespace {

std::vector<System> test_systems() { return {spear1_case1(), chain(5), mixed_tree()}; }

// A system with every load the engine knows: springs (mixed_tree), dampers, motors, body torques.
System loaded_tree() {
  System s = mixed_tree();
  for (Joint& j : s.joints) {
    if (j.type == JointType::Revolute) {
      j.damping = 0.4;
      j.motor_revolute.times = {0.0};
      j.motor_revolute.values = {Eigen::Matrix<double, 1, 1>(0.8)};
    }
    if (j.type == JointType::Spherical) {
      j.damping = 0.3;
      j.motor_spherical.times = {0.0};
      j.motor_spherical.values = {Eigen::Vector3d(0.2, -0.5, 0.1)};
    }
  }
  s.bodies[0].torque.times = {0.0};
  s.bodies[0].torque.values = {Eigen::Vector3d(1.0, 2.0, -0.5)};
  s.bodies[0].torque_frame = Body::Frame::Body;
  s.bodies[6].torque.times = {0.0};
  s.bodies[6].torque.values = {Eigen::Vector3d(-0.3, 0.1, 0.6)};
  s.bodies[6].torque_frame = Body::Frame::Inertial;
  return s;
}

}  // namespace

TEST_CASE("kane: M is symmetric positive definite and 1/2 u^T M u is the sum of body energies") {
  std::mt19937 g(5);
  for (const System& s : test_systems()) {
    kane::KaneEngine e(s, {});
    const int nq = e.position_size(), nu = e.speed_size();
    for (int trial = 0; trial < 5; ++trial) {
      std::vector<double> x = packed(e, random_state(s, g));
      const Eigen::MatrixXd M = e.mass_matrix(x.data());
      // Independent of the mass-matrix pass: M_rs by polarisation of the kinetic energy summed
      // over bodies, T(u) = sum 1/2 m v.v + 1/2 w.I w, with u = e_r, e_s, e_r + e_s.
      auto T_of = [&](const Eigen::VectorXd& u) {
        std::vector<double> y(x);
        for (int i = 0; i < nu; ++i) y[static_cast<std::size_t>(nq + i)] = u(i);
        return e.kinetic_energy(y.data());
      };
      Eigen::MatrixXd Mp(nu, nu);
      for (int r = 0; r < nu; ++r)
        for (int c = 0; c < nu; ++c) {
          const Eigen::VectorXd er = Eigen::VectorXd::Unit(nu, r),
                                ec = Eigen::VectorXd::Unit(nu, c);
          Mp(r, c) = r == c ? 2 * T_of(er) : T_of(er + ec) - T_of(er) - T_of(ec);
        }
      INFO(s.name << ": max |M - M_polarisation| = " << (M - Mp).cwiseAbs().maxCoeff()
                  << ", max |M| = " << M.cwiseAbs().maxCoeff());
      CHECK(all_close(M, Mp, 0.0, 1e-12));
      CHECK(all_close(Mp, Eigen::MatrixXd(Mp.transpose()), 0.0, 1e-12));  // symmetric
      const double lmin = symmetric_eigenvalues(M).minCoeff();
      CHECK(lmin > 0);
      const Eigen::VectorXd u = Eigen::Map<const Eigen::VectorXd>(x.data() + nq, nu);
      CHECK(close(0.5 * u.dot(M * u), e.kinetic_energy(x.data()), 0.0, 1e-13));
    }
  }
}

TEST_CASE("kane: the L^T D L solve in rhs agrees with Eigen's LLT of M") {
  std::mt19937 g(6);
  for (const System& s : {spear1_case1(), chain(5), mixed_tree(), loaded_tree()}) {
    kane::KaneEngine e(s, {});
    const int nq = e.position_size(), nu = e.speed_size();
    for (int trial = 0; trial < 5; ++trial) {
      std::vector<double> x = packed(e, random_state(s, g)), xdot(x.size());
      e.rhs(0.3, x.data(), xdot.data());
      const Eigen::MatrixXd M = e.mass_matrix(x.data());
      const Eigen::VectorXd f = e.generalized_forces(0.3, x.data());
      Eigen::ComputationInfo llt_info{};
      const Eigen::VectorXd udot_ref = llt_solve(M, f, &llt_info);
      REQUIRE(llt_info == Eigen::Success);
      const Eigen::VectorXd udot = Eigen::Map<const Eigen::VectorXd>(xdot.data() + nq, nu);
      INFO(s.name << ": max |u' - u'_LLT| = " << (udot - udot_ref).cwiseAbs().maxCoeff());
      CHECK(all_close(udot, udot_ref, 1e-13, 1e-11));
    }
  }
}

// solve() walks a rigid base's 6 x 6 block with loops of constant size (unrolled); with the
// block's size read at run time (a flexible base's path) it must give the same u'.
TEST_CASE("kane: the fixed-size base-block solve equals the run-time-size one at random states") {
  std::mt19937 g(11);
  std::vector<System> systems = {spear1_case1(), chain(5), mixed_tree(), loaded_tree()};
  for (const std::string& file : crossdyn::test::committed_scenes()) {
    System s = read_scene(file);
    if (std::none_of(s.bodies.begin(), s.bodies.end(), [](const Body& b) { return b.flex; }))
      systems.push_back(std::move(s));
  }
  for (const System& s : systems) {
    kane::KaneEngine e(s, {}, kane::KaneSolver::Composite);
    for (int trial = 0; trial < 5; ++trial) {
      const std::vector<double> x = packed(e, random_state(s, g));
      const Eigen::VectorXd fixed = e.composite_udot(0.3, x.data(), true);
      const Eigen::VectorXd general = e.composite_udot(0.3, x.data(), false);
      INFO(s.name << ": max |u'_fixed - u'_general| = "
                  << (fixed - general).cwiseAbs().maxCoeff());
      CHECK(all_close(fixed, general, 1e-13 * (1.0 + general.cwiseAbs().maxCoeff()), 1e-13));
    }
  }
}

TEST_CASE("kane: pack sets the base velocity so that the total linear momentum is zero") {
  std::mt19937 g(7);
  for (System s : test_systems()) {
    double mass = 0;
    for (const Body& b : s.bodies) mass += b.mass;
    for (int trial = 0; trial < 5; ++trial) {
      const TreeState st = random_state(s, g);
      s.zero_linear_momentum = true;
      kane::KaneEngine e(s, {});
      std::vector<double> x = packed(e, st);
      const double P = e.linear_momentum_N(x.data()).norm();
      INFO(s.name << ": |P| after pack = " << P << " kg m/s");
      CHECK(P <= 1e-13 * mass);  // speeds are of order 1 m/s
      // Without the flag the base velocity is the given one.
      s.zero_linear_momentum = false;
      kane::KaneEngine e2(s, {});
      x = packed(e2, st);
      for (int i = 0; i < 3; ++i)
        CHECK(close(x[static_cast<std::size_t>(e2.position_size() + 3 + i)], st.v_NBo_N(i), 0, 0));
      CHECK(e2.linear_momentum_N(x.data()).norm() > 1e-3 * mass);
    }
  }
}

TEST_CASE("kane: velocities and accelerations agree with central differences along the motion") {
  // For the state x(h) = x + h xdot: d/dh of every body's position is its CM velocity, of R_NB is
  // [w x] R_NB, of its velocities the accelerations() values (five-point differences, O(h^4)).
  std::mt19937 g(8);
  const double h = 1e-3;
  for (const System& s : {mixed_tree(), loaded_tree(), chain(5)}) {
    kane::KaneEngine e(s, {});
    for (int trial = 0; trial < 3; ++trial) {
      std::vector<double> x = packed(e, random_state(s, g)), xdot(x.size());
      e.rhs(0.2, x.data(), xdot.data());
      TreeAccel a;
      e.accelerations(0.2, x.data(), a);
      REQUIRE(a.wdot_NB_B.size() == s.bodies.size());
      REQUIRE(a.angle_ddot.size() == s.joints.size());
      const auto m0 = e.body_motion(x.data());
      double ev = 0, eR = 0, ea = 0, ew = 0;
      for (std::size_t b = 0; b < s.bodies.size(); ++b) {
        auto motion = [&](double step) { return e.body_motion(along(x, xdot, step).data())[b]; };
        const Eigen::Vector3d v =
            derivative([&](double k) { return Eigen::Vector3d(motion(k).p_NoBo_N); }, h);
        const Eigen::Matrix3d Rd =
            derivative([&](double k) { return Eigen::Matrix3d(motion(k).R_NB); }, h);
        const Eigen::Vector3d ad =
            derivative([&](double k) { return Eigen::Vector3d(motion(k).v_NBo_N); }, h);
        const Eigen::Vector3d wd =
            derivative([&](double k) { return Eigen::Vector3d(motion(k).w_NB_B); }, h);
        ev = std::max(ev, (v - m0[b].v_NBo_N).norm());
        eR = std::max(eR, (Rd - m0[b].R_NB * rot::skew(m0[b].w_NB_B)).cwiseAbs().maxCoeff());
        ea = std::max(ea, (ad - a.a_NBo_N[b]).norm());
        ew = std::max(ew, (wd - a.wdot_NB_B[b]).norm());
      }
      INFO(s.name << ": velocity " << ev << ", attitude rate " << eR << ", acceleration " << ea
                  << ", angular acceleration " << ew);
      CHECK(ev <= 1e-9);
      CHECK(eR <= 1e-9);
      CHECK(ea <= 1e-9);
      CHECK(ew <= 1e-9);
      // Joint accelerations are the speed derivatives.
      for (const kane::Node& n : e.nodes()) {
        const std::size_t j = static_cast<std::size_t>(n.joint);
        const double* ud = xdot.data() + e.position_size() + n.u0;
        const JointType type = s.joints[j].type;
        if (type == JointType::Revolute) CHECK(close(a.angle_ddot[j], ud[0], 1e-14, 1e-13));
        if (type == JointType::Spherical)
          CHECK(all_close(a.wdot_PC_C[j], Eigen::Vector3d(ud[0], ud[1], ud[2]), 1e-14, 1e-13));
      }
    }
  }
}

TEST_CASE("kane: power balance dE/dt = loads' power and dH/dt = external torque at random states") {
  // E = T + V (springs). dE/dt = sum over hinges (motor - damping * rate) . rate + sum over
  // bodies T_ext . w_B; dH_N/dt = sum of the external torques in N (hinge loads are internal).
  // Checked by five-point differences along xdot, t fixed (loads are constant here).
  const System s = loaded_tree();
  kane::KaneEngine e(s, {});
  std::mt19937 g(9);
  const double h = 3e-4;
  const int cE = [&] {
    for (std::size_t i = 0; i < e.columns().size(); ++i)
      if (e.columns()[i] == "E") return static_cast<int>(i);
    return -1;
  }();
  for (int trial = 0; trial < 5; ++trial) {
    std::vector<double> x = packed(e, random_state(s, g)), xdot(x.size()), row(e.columns().size());
    e.rhs(0.5, x.data(), xdot.data());
    const double dEdt = derivative(
        [&](double step) {
          const std::vector<double> y = along(x, xdot, step);
          e.output_row(0.5, y.data(), row.data());
          return row[static_cast<std::size_t>(cE)];
        },
        h);
    const Eigen::Vector3d dHdt = derivative(
        [&](double step) {
          return Eigen::Vector3d(e.angular_momentum_N(along(x, xdot, step).data()));
        },
        h);
    const auto motion = e.body_motion(x.data());
    double power = 0;
    Eigen::Vector3d torque_N = Eigen::Vector3d::Zero();
    for (const kane::Node& n : e.nodes()) {
      const Joint& J = s.joints[static_cast<std::size_t>(n.joint)];
      const double* u = x.data() + e.position_size() + n.u0;
      if (J.type == JointType::Revolute)
        power += (J.motor_revolute.value(0.5)(0) - J.damping * u[0]) * u[0];
      if (J.type == JointType::Spherical) {
        const Eigen::Vector3d w(u[0], u[1], u[2]);
        power += (J.motor_spherical.value(0.5) - J.damping * w).dot(w);
      }
      const Body& B = s.bodies[static_cast<std::size_t>(n.body)];
      const kane::BodyMotion& m = motion[static_cast<std::size_t>(n.body)];
      if (!B.torque.empty()) {
        const Eigen::Vector3d T = B.torque.value(0.5);
        const Eigen::Vector3d T_N =
            B.torque_frame == Body::Frame::Body ? Eigen::Vector3d(m.R_NB * T) : T;
        power += T_N.dot(m.R_NB * m.w_NB_B);
        torque_N += T_N;
      }
    }
    INFO("dE/dt = " << dEdt << " W, power of the loads = " << power << " W, difference "
                    << dEdt - power << "; |dH/dt - T| = " << (dHdt - torque_N).norm());
    CHECK(close(dEdt, power, 1e-8, 1e-8));
    CHECK(all_close(dHdt, torque_N, 1e-8, 1e-8));
  }
}

TEST_CASE("kane: the dynamics do not depend on the norm of the stored quaternions") {
  std::mt19937 g(10);
  const System s = mixed_tree();
  kane::KaneEngine e(s, {});
  std::vector<double> x = packed(e, random_state(s, g)), y(x), xd(x.size()), yd(x.size());
  for (const kane::Node& n : e.nodes()) {
    const JointType type = s.joints[static_cast<std::size_t>(n.joint)].type;
    const int q = type == JointType::Free ? n.q0 + 3 : type == JointType::Spherical ? n.q0 : -1;
    if (q >= 0)
      for (int i = 0; i < 4; ++i) y[static_cast<std::size_t>(q + i)] *= 1.25;
  }
  e.rhs(0, x.data(), xd.data());
  e.rhs(0, y.data(), yd.data());
  for (int i = e.position_size(); i < e.state_size(); ++i)
    CHECK(close(yd[static_cast<std::size_t>(i)], xd[static_cast<std::size_t>(i)], 1e-13, 1e-12));
}

TEST_CASE("kane: after_step renormalises only a visible quaternion drift") {
  const System s = spear1_case1();
  kane::KaneEngine e(s, {});
  std::vector<double> x = packed(e, TreeState::initial(s));
  std::vector<double> y(x);
  for (int i = 3; i < 7; ++i) y[static_cast<std::size_t>(i)] *= 1 + 1e-13;
  CHECK_FALSE(e.after_step(0, y.data()));
  for (int i = 3; i < 7; ++i)
    y[static_cast<std::size_t>(i)] = 1.001 * x[static_cast<std::size_t>(i)];
  CHECK(e.after_step(0, y.data()));
  CHECK(close(Eigen::Map<const Eigen::Vector4d>(y.data() + 3).norm(), 1.0, 1e-15, 0));
}

TEST_CASE("kane: columns begin with the pinned columns: state labels are readable") {
  const System s = spear1_case1();
  auto engine = make_kane_engine(s, {});
  REQUIRE(std::string(engine->name()) == "kane");
  const std::vector<std::string> pinned = pinned_columns(s);
  REQUIRE(engine->columns().size() >= pinned.size());
  CHECK(std::equal(pinned.begin(), pinned.end(), engine->columns().begin()));
  const std::vector<std::string> expected = {
      "main.x",  "main.y",       "main.z",       "main.qw",     "main.qx",    "main.qy",
      "main.qz", "hinge1.angle", "hinge2.angle", "main.wx",     "main.wy",    "main.wz",
      "main.vx", "main.vy",      "main.vz",      "hinge1.rate", "hinge2.rate"};
  REQUIRE(engine->state_size() == static_cast<int>(expected.size()));
  for (int i = 0; i < engine->state_size(); ++i)
    CHECK(engine->state_label(i) == expected[static_cast<std::size_t>(i)]);

  // Output attitudes have qw >= 0 whatever the stored sign.
  TreeState st = TreeState::initial(s);
  st.q_NB = Eigen::Quaterniond(-0.6, 0.0, 0.8, 0.0);
  std::vector<double> x(static_cast<std::size_t>(engine->state_size())),
      row(engine->columns().size());
  engine->pack(st, x.data());
  engine->output_row(0, x.data(), row.data());
  CHECK(close(row[4], 0.6, 1e-15, 0));   // main.qw
  CHECK(close(row[6], -0.8, 1e-15, 0));  // main.qy
}

TEST_CASE("kane: malformed trees are refused with InputError") {
  System t = spear1_case1();
  std::swap(t.joints[0], t.joints[1]);
  CHECK_THROWS_AS(make_kane_engine(t, {}), InputError);
  System u = spear1_case1();
  u.joints[2].parent = 2;  // its own child: not an earlier joint's child
  CHECK_THROWS_AS(make_kane_engine(u, {}), InputError);
  EngineOptions o;
  o.test_inertia_scale = 0;
  CHECK_THROWS_AS(make_kane_engine(spear1_case1(), o), InputError);
}
