// The Lagrange engine at single states: every term of the Boltzmann-Hamel equations against an
// independent evaluation (closed forms, finite differences of the engine's own energies) and the
// balance laws the accelerations must satisfy.
#include <catch2/catch.hpp>
#include <random>
#include <set>

#include "core/errors.hpp"
#include "core/rotation.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "formulations/lagrange/lagrange.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "tests/lagrange/flex_scenes.hpp"
#include "tests/lagrange/scenes.hpp"
#include "tests/support/close.hpp"
#include "tests/support/linalg.hpp"

using namespace crossdyn;
using crossdyn::lagrange::LagrangeEngine;
using crossdyn::test::all_close;
using crossdyn::test::close;
using crossdyn::test::ldlt_solve;
using crossdyn::test::symmetric_eigenvalues;

namespace {

std::vector<System> rigid_scenes() {
  return {test::spear1(), test::spear1(-10, true), test::chain(5), test::mixed_tree(false),
          test::mixed_tree(true)};
}

// Rigid and flexible (joints at nodes of flexible parents and children; test_flex.cpp).
std::vector<System> term_scenes() {
  std::vector<System> s = rigid_scenes();
  s.push_back(test::flex_tree(false));
  s.push_back(test::flex_tree(true));
  return s;
}

std::vector<double> packed(LagrangeEngine& e, const TreeState& s) {
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(s, x.data());
  return x;
}

// x + h * xdot (a point on the tangent of the motion through x).
std::vector<double> advanced(const std::vector<double>& x, const std::vector<double>& xdot,
                             double h) {
  std::vector<double> y(x);
  for (std::size_t i = 0; i < x.size(); ++i) y[i] += h * xdot[i];
  return y;
}

Eigen::Matrix3d random_inertia(std::mt19937& g) {
  std::uniform_real_distribution<double> u(0.5, 3.0);
  const Eigen::Matrix3d R = test::random_quaternion(g).toRotationMatrix();
  return R * Eigen::Vector3d(u(g), u(g), u(g)).asDiagonal() * R.transpose();
}

}  // namespace

TEST_CASE("lagrange: a single free body reproduces Euler's equations", "[lagrange][terms]") {
  std::mt19937 g(21);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 50; ++trial) {
    System s;
    s.bodies = {test::make_body("B", 7.0, {1, 1, 1})};
    s.bodies[0].I_BBo_B = random_inertia(g);
    const Eigen::Vector3d tau(u(g), u(g), u(g));
    const bool inertial = trial % 2 == 1;
    s.bodies[0].torque_frame = inertial ? Body::Frame::Inertial : Body::Frame::Body;
    s.bodies[0].torque.times = {0.0};
    s.bodies[0].torque.values = {tau};
    s.joints = {test::free_joint(0, Eigen::Vector3d::Zero())};
    LagrangeEngine e(s, {});
    TreeState st = TreeState::initial(s);
    st.q_NB = test::random_quaternion(g);
    st.w_NB_B = 3.0 * Eigen::Vector3d(u(g), u(g), u(g));
    const std::vector<double> x = packed(e, st);
    const LagrangeEngine::Terms t = e.terms(0.5, x.data());
    const Eigen::Matrix3d& I = s.bodies[0].I_BBo_B;
    const Eigen::Vector3d w = st.w_NB_B;
    const Eigen::Vector3d tau_B = inertial ? st.q_NB.toRotationMatrix().transpose() * tau : tau;
    // I w' = tau - w x I w (Euler 1758; Kane, Likins & Levinson 1983, Eq. 3.1.1); v' = 0.
    const Eigen::Vector3d wdot = ldlt_solve(I, tau_B - w.cross(I * w));
    CHECK(all_close(t.udot.segment<3>(3), wdot, 1e-13, 1e-12));
    CHECK(all_close(t.udot.head<3>(), Eigen::Vector3d::Zero(), 1e-14, 0));
    // The gyroscopic term is Hamel's term alone: B^T W^T p = w x I w; T has no q* dependence.
    CHECK(all_close(t.hamel.segment<3>(3), w.cross(I * w), 1e-13, 1e-12));
    CHECK(t.dL.cwiseAbs().maxCoeff() < 1e-13);
    CHECK(t.Mdot_u.cwiseAbs().maxCoeff() < 1e-13);
    CHECK(all_close(t.M.bottomRightCorner<3, 3>(), I, 1e-14, 1e-14));
    CHECK(all_close(t.M.topLeftCorner<3, 3>(), 7.0 * Eigen::Matrix3d::Identity(), 1e-14, 1e-14));
  }
}

TEST_CASE("lagrange: Hamel's term of every Euler set is w x p in every chart",
          "[lagrange][terms]") {
  // For a set whose quasi-velocity is the angular velocity of the rotated frame in that frame,
  // the transitivity terms are the structure constants of SO(3) whatever the chart (Meirovitch
  // 1970, Ch. 4; paper Eq. 29: C = [Omega~]).
  std::mt19937 g(22);
  std::set<std::string> charts_seen;
  for (const System& s : {test::mixed_tree(true), test::chain(5)}) {
    LagrangeEngine e(s, {});
    for (int trial = 0; trial < 200; ++trial) {
      const std::vector<double> x = packed(e, test::random_state(s, g));
      const LagrangeEngine::Terms t = e.terms(0.0, x.data());
      for (int k = 0; k < e.euler_sets(); ++k) {
        charts_seen.insert(e.chart_name(k));
        // Euler set k's block: the base angles are at 3..5, a spherical joint's at its own block;
        // find it from the state labels.
        int i0 = -1;
        for (int i = 0; i < e.dof(); ++i)
          if (e.state_label(i).rfind(e.euler_set_owner(k) + ".euler1", 0) == 0) i0 = i;
        REQUIRE(i0 >= 0);
        const Eigen::Vector3d w = Eigen::Map<const Eigen::Vector3d>(x.data() + e.dof() + i0);
        const Eigen::Vector3d p = t.p.segment<3>(i0);
        CHECK(all_close(t.hamel.segment<3>(i0), w.cross(p), 1e-12, 1e-12));
      }
    }
  }
  CHECK(charts_seen.size() == lagrange::kSequences.size());
}

TEST_CASE(
    "lagrange: the mass matrix is the Hessian of T in the quasi-velocities, symmetric and "
    "positive definite",
    "[lagrange][terms]") {
  std::mt19937 g(23);
  for (const System& s : term_scenes()) {
    INFO("scene " << s.name);
    LagrangeEngine e(s, {});
    const int n = e.dof();
    for (int trial = 0; trial < 10; ++trial) {
      std::vector<double> x = packed(e, test::random_flex_state(s, g));
      const LagrangeEngine::Terms t = e.terms(0.0, x.data());
      const double T = e.kinetic_energy(x.data());
      const Eigen::VectorXd u = Eigen::Map<const Eigen::VectorXd>(x.data() + n, n);
      // T is homogeneous quadratic in pi': T = pi'^T M pi' / 2 and p = M pi'.
      CHECK(close(0.5 * u.dot(t.M * u), T, 1e-12, 1e-13));
      CHECK(all_close(t.p, t.M * u, 1e-12, 1e-13));
      // Second differences of the engine's T in pi' are exact for a quadratic, with any step.
      auto T_at = [&](int i, double hi, int j, double hj) {
        std::vector<double> y(x);
        y[static_cast<std::size_t>(n + i)] += hi;
        y[static_cast<std::size_t>(n + j)] += hj;
        return e.kinetic_energy(y.data());
      };
      Eigen::MatrixXd H(n, n);
      const double h = 1.0;
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j)
          H(i, j) =
              (T_at(i, h, j, h) - T_at(i, h, j, -h) - T_at(i, -h, j, h) + T_at(i, -h, j, -h)) /
              (4 * h * h);
      const double scale = t.M.cwiseAbs().maxCoeff();
      CHECK(all_close(t.M, H, 1e-12 * scale, 0));
      CHECK(all_close(t.M, t.M.transpose(), 0, 0));
      const Eigen::VectorXd lambda = symmetric_eigenvalues(t.M);
      CHECK(lambda.minCoeff() > 0);
      // The solve (the engine's own Cholesky factorisation): pi'' satisfies
      // M pi'' = N + B^T dL/dq* - (dM/dt) pi' - B^T W^T p, checked against an independent LDLT.
      const Eigen::VectorXd f = t.N + t.dL - t.Mdot_u - t.hamel;
      const Eigen::VectorXd udot_ref = ldlt_solve(t.M, f);
      CHECK(all_close(t.udot, udot_ref, 1e-10 * (1 + udot_ref.norm()), 0));
      CHECK(all_close(t.M * t.udot, f, 1e-12 * scale * (1 + t.udot.norm()), 0));
    }
  }
}

TEST_CASE(
    "lagrange: AD terms equal finite differences of T and V along the motion and along "
    "quasi-displacements",
    "[lagrange][terms]") {
  std::mt19937 g(24);
  for (const System& s : term_scenes()) {
    INFO("scene " << s.name);
    LagrangeEngine e(s, {});
    const int n = e.dof();
    for (int trial = 0; trial < 5; ++trial) {
      const std::vector<double> x = packed(e, test::random_flex_state(s, g));
      const LagrangeEngine::Terms t = e.terms(0.0, x.data());
      const double h = 1e-5;  // central differences: truncation O(h^2) ~ 1e-10 relative
      // (dM/dt) pi' at fixed pi': d/dt of p along q*' (xdot with pi'' = 0).
      std::vector<double> xd(x.size(), 0.0);
      for (int i = 0; i < n; ++i) xd[static_cast<std::size_t>(i)] = t.qdot(i);
      const Eigen::VectorXd p_plus = e.terms(0.0, advanced(x, xd, h).data()).p;
      const Eigen::VectorXd p_minus = e.terms(0.0, advanced(x, xd, -h).data()).p;
      const Eigen::VectorXd fd = (p_plus - p_minus) / (2 * h);
      CHECK(all_close(t.Mdot_u, fd, 1e-7 * (1 + fd.norm()), 0));
      // B^T d(T - V)/dq*: the derivative of L along dq* = B e_r, at fixed pi'.
      e.terms(0.0, x.data());
      const LagrangeEngine::Terms t0 = e.terms(0.0, x.data());
      Eigen::VectorXd dL_fd = Eigen::VectorXd::Zero(n);
      for (int r = 0; r < n; ++r) {
        // B e_r: B is the identity off the Euler blocks; in an Euler block it maps the unit
        // quasi-velocity e_r to angle rates, which qdot of a state with pi' = e_r gives.
        std::vector<double> unit(x);
        for (int i = 0; i < n; ++i) unit[static_cast<std::size_t>(n + i)] = i == r ? 1.0 : 0.0;
        const Eigen::VectorXd Be = e.terms(0.0, unit.data()).qdot;
        auto L_at = [&](double hh) {
          std::vector<double> y(x);
          for (int i = 0; i < n; ++i) y[static_cast<std::size_t>(i)] += hh * Be(i);
          return e.kinetic_energy(y.data()) - e.potential_energy(y.data());
        };
        dL_fd(r) = (L_at(h) - L_at(-h)) / (2 * h);
      }
      CHECK(all_close(t0.dL, dL_fd, 1e-7 * (1 + dL_fd.norm()), 0));
    }
  }
}

TEST_CASE(
    "lagrange: a spherical spring's generalised force is -k phi for the relative angular "
    "velocity",
    "[lagrange][terms]") {
  // system.hpp: V = k |phi|^2 / 2 with phi the rotation vector of q_J; its generalised force for
  // w_PC_C is exactly -k phi. The engine differentiates V written in Euler angles by AD.
  std::mt19937 g(25);
  System s = test::chain(2);
  s.joints[1].stiffness = 2.5;
  LagrangeEngine e(s, {});
  for (int trial = 0; trial < 100; ++trial) {
    TreeState st = TreeState::initial(s);
    st.q_NB = test::random_quaternion(g);
    st.w_NB_B.setZero();
    st.joints[1].w_PC_C.setZero();
    st.joints[1].q_J = test::random_quaternion(g);
    if (trial < 3)
      st.joints[1].q_J =
          Eigen::Quaterniond(Eigen::AngleAxisd(1e-9 * trial, Eigen::Vector3d(0.6, 0, 0.8)));
    const std::vector<double> x = packed(e, st);
    const LagrangeEngine::Terms t = e.terms(0.0, x.data());
    const Eigen::Vector3d phi = rot::rotation_vector(st.joints[1].q_J);
    CHECK(all_close(t.dL.segment<3>(6), -2.5 * phi, 1e-12, 1e-11));
    CHECK(close(e.potential_energy(x.data()), 0.5 * 2.5 * phi.squaredNorm(), 1e-15, 1e-12));
  }
}

TEST_CASE("lagrange: accelerations satisfy the momentum balances and match the motion",
          "[lagrange][terms]") {
  std::mt19937 g(26);
  for (const System& s : rigid_scenes()) {
    INFO("scene " << s.name);
    LagrangeEngine e(s, {});
    const int nx = e.state_size();
    for (int trial = 0; trial < 5; ++trial) {
      const double t0 = 0.3;
      const std::vector<double> x = packed(e, test::random_state(s, g));
      std::vector<double> xdot(static_cast<std::size_t>(nx));
      e.rhs(t0, x.data(), xdot.data());
      TreeAccel a;
      e.accelerations(t0, x.data(), a);
      // Net external force is zero: sum m a = 0 (Newton; the CM moves uniformly).
      Eigen::Vector3d F = Eigen::Vector3d::Zero();
      double mass = 0;
      for (std::size_t b = 0; b < s.bodies.size(); ++b) {
        F += s.bodies[b].mass * a.a_NBo_N[b];
        mass += s.bodies[b].mass;
      }
      CHECK(F.norm() < 1e-12 * mass);
      // dH/dt about the system CM = external torques (joint loads are internal pairs).
      Eigen::Vector3d tau_N = Eigen::Vector3d::Zero();
      std::vector<double> row(e.columns().size());
      e.output_row(t0, x.data(), row.data());
      for (std::size_t b = 0; b < s.bodies.size(); ++b) {
        const std::size_t c = 1 + 7 * b;
        const Eigen::Quaterniond q(row[c + 3], row[c + 4], row[c + 5], row[c + 6]);
        const Eigen::Vector3d tau = s.bodies[b].torque.value(t0);
        tau_N += s.bodies[b].torque_frame == Body::Frame::Inertial ? tau : q * tau;
      }
      const double h = 1e-5;
      const Eigen::Vector3d dH = (e.angular_momentum_N(advanced(x, xdot, h).data()) -
                                  e.angular_momentum_N(advanced(x, xdot, -h).data())) /
                                 (2 * h);
      CHECK(all_close(dH, tau_N, 1e-7 * (1 + tau_N.norm() + e.angular_momentum_N(x.data()).norm()),
                      0));
      // dE/dt = power of dampers, motors and body torques.
      double power = 0;
      {
        std::vector<double> r(e.columns().size());
        e.output_row(t0, x.data(), r.data());
        for (std::size_t b = 0; b < s.bodies.size(); ++b) {
          const std::size_t c = 1 + 7 * b;
          const Eigen::Vector3d w(r[c], r[c + 1], r[c + 2]);
          const Eigen::Quaterniond q(r[c + 3], r[c + 4], r[c + 5], r[c + 6]);
          const Eigen::Vector3d tau = s.bodies[b].torque.value(t0);
          power +=
              w.dot(s.bodies[b].torque_frame == Body::Frame::Inertial ? q.conjugate() * tau : tau);
        }
        std::size_t c = 1 + 7 * s.bodies.size();
        for (const Joint& j : s.joints) {
          if (j.type == JointType::Revolute) {
            const double rate = r[c + 1];
            power += rate * (-j.damping * rate + j.motor_revolute.value(t0)(0));
            c += 2;
          } else if (j.type == JointType::Spherical) {
            const Eigen::Vector3d w(r[c], r[c + 1], r[c + 2]);
            power += w.dot(-j.damping * w + j.motor_spherical.value(t0));
            c += 3;
          }
        }
      }
      auto energy = [&](const std::vector<double>& y) {
        return e.kinetic_energy(y.data()) + e.potential_energy(y.data());
      };
      const double dE = (energy(advanced(x, xdot, h)) - energy(advanced(x, xdot, -h))) / (2 * h);
      CHECK(close(dE, power, 1e-7 * (1 + energy(x)), 0));
      // The engine-neutral accelerations are the time derivatives of the outputs.
      std::vector<double> rp(e.columns().size()), rm(e.columns().size());
      e.output_row(t0, advanced(x, xdot, h).data(), rp.data());
      e.output_row(t0, advanced(x, xdot, -h).data(), rm.data());
      for (std::size_t b = 0; b < s.bodies.size(); ++b) {
        const std::size_t c = 1 + 7 * b;
        const Eigen::Vector3d fd((rp[c] - rm[c]) / (2 * h), (rp[c + 1] - rm[c + 1]) / (2 * h),
                                 (rp[c + 2] - rm[c + 2]) / (2 * h));
        CHECK(all_close(a.wdot_NB_B[b], fd, 1e-7 * (1 + fd.norm()), 0));
      }
      std::size_t c = 1 + 7 * s.bodies.size();
      for (std::size_t j = 0; j < s.joints.size(); ++j) {
        if (s.joints[j].type == JointType::Revolute) {
          CHECK(close(a.angle_ddot[j], (rp[c + 1] - rm[c + 1]) / (2 * h), 1e-7, 1e-7));
          c += 2;
        } else if (s.joints[j].type == JointType::Spherical) {
          for (int k = 0; k < 3; ++k)
            CHECK(close(a.wdot_PC_C[j](k), (rp[c + k] - rm[c + k]) / (2 * h), 1e-7, 1e-7));
          c += 3;
        }
      }
    }
  }
}

TEST_CASE(
    "lagrange: pack() then output_row() reproduces the state, from a chart far from "
    "singular",
    "[lagrange][pack]") {
  std::mt19937 g(27);
  for (const System& s : rigid_scenes()) {
    INFO("scene " << s.name);
    LagrangeEngine e(s, {});
    const int n = e.dof();
    for (int trial = 0; trial < 50; ++trial) {
      const TreeState st = test::random_state(s, g);
      const std::vector<double> x = packed(e, st);
      std::vector<double> row(e.columns().size());
      e.output_row(0.0, x.data(), row.data());
      // Attitudes: q_NC = q_NP q_PJ0 q_J, computed here from the TreeState.
      std::vector<Eigen::Quaterniond> q(s.bodies.size());
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
        q[c] = q[static_cast<std::size_t>(J.parent)] * J.q_PJ0 * qJ;
      }
      for (std::size_t b = 0; b < s.bodies.size(); ++b) {
        const std::size_t c = 1 + 7 * b;
        const Eigen::Quaterniond qo(row[c + 3], row[c + 4], row[c + 5], row[c + 6]);
        CHECK(rot::angle_between(qo, q[b]) < 1e-13);
        CHECK(qo.w() >= 0);
        CHECK(close(qo.norm(), 1.0, 1e-15, 0));
      }
      CHECK(all_close(Eigen::Vector3d(row[1], row[2], row[3]), st.w_NB_B, 1e-15, 0));
      std::size_t c = 1 + 7 * s.bodies.size();
      for (std::size_t j = 0; j < s.joints.size(); ++j) {
        if (s.joints[j].type == JointType::Revolute) {
          CHECK(row[c] == st.joints[j].angle);
          CHECK(row[c + 1] == st.joints[j].rate);
          c += 2;
        } else if (s.joints[j].type == JointType::Spherical) {
          CHECK(all_close(Eigen::Vector3d(row[c], row[c + 1], row[c + 2]), st.joints[j].w_PC_C, 0,
                          0));
          c += 3;
        }
      }
      // Every Euler set starts at most kPackDeg from its chart's centre.
      for (int k = 0; k < e.euler_sets(); ++k)
        for (int i = 0; i < n; ++i)
          if (e.state_label(i).rfind(e.euler_set_owner(k) + ".euler2", 0) == 0)
            CHECK(std::abs(x[static_cast<std::size_t>(i)]) <=
                  lagrange::kPackDeg * test::kDegree + 1e-12);
      // Total linear momentum is zero (System::zero_linear_momentum).
      CHECK(e.linear_momentum_N(x.data()).norm() < 1e-12);
    }
  }
}

TEST_CASE("lagrange: options, columns and labels", "[lagrange]") {
  System s = test::spear1();
  LagrangeEngine e(s, {});
  CHECK(std::string(e.name()) == "lagrange");
  CHECK(e.state_size() == 2 * (6 + 2));
  std::vector<std::string> expected = pinned_columns(s);
  expected.push_back("lagrange.recharts");
  CHECK(e.columns() == expected);
  CHECK(e.state_label(0) == "main.x");
  CHECK(e.state_label(4) == "main.euler2 (3-2-1)");
  CHECK(e.state_label(6) == "hinge1.angle");
  CHECK(e.state_label(8 + 3) == "main.wx");
  CHECK(e.state_label(8 + 7) == "hinge2.rate");

  // test_inertia_scale multiplies every inertia (not the mass).
  EngineOptions scaled;
  scaled.test_inertia_scale = 2.0;
  LagrangeEngine e2(s, scaled);
  std::vector<double> x(16), x2(16);
  e.pack(TreeState::initial(s), x.data());
  e2.pack(TreeState::initial(s), x2.data());
  const LagrangeEngine::Terms t1 = e.terms(0, x.data()), t2 = e2.terms(0, x2.data());
  CHECK(all_close(t2.M.topLeftCorner<3, 3>(), t1.M.topLeftCorner<3, 3>(), 0, 0));  // mass
  CHECK(close(t2.M(3, 3), t1.M(3, 3) + 100.0 + 2 * 10.0, 1e-12, 0));  // + I_main,xx + 2 I_boom,xx
}
