// The Kane engine's prismatic and universal joints (formulations/kane/joints/prismatic.cpp,
// universal.cpp; README.md "Joint units"): closed-form motions, conservation of H and E, the work
// of a prescribed slider's force, internal motors, the mass matrix against Kane's sums over the
// bodies, accelerations() against differences of the motion, and the two solvers against each
// other.
#include <catch2/catch.hpp>

#include "formulations/kane/kane_engine.hpp"
#include "tests/kane/kane_flex_systems.hpp"
#include "tests/kane/kane_systems.hpp"
#include "tests/support/close.hpp"

#include <algorithm>
#include <cmath>

using namespace crossdyn;
using namespace crossdyn::test::kane;
using crossdyn::test::all_close;
using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

// The output rows of an RK4 run (dt, steps) of one engine, and its columns by name.
struct Run {
  std::vector<std::string> names;
  std::vector<std::vector<double>> rows;

  double at(std::size_t row, const std::string& name) const {
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == name) return rows[row][i];
    FAIL("no column " << name);
    return 0;
  }
  // max over the rows of |value - first value|, divided by |first value| when relative.
  double drift(const std::string& name, bool relative = true) const {
    const double ref = at(0, name);
    double d = 0;
    for (std::size_t r = 0; r < rows.size(); ++r) d = std::max(d, std::abs(at(r, name) - ref));
    return relative ? d / std::abs(ref) : d;
  }
};

Run rk4_run(const System& s, double dt, int steps,
            kane::KaneSolver solver = kane::KaneSolver::Automatic) {
  kane::KaneEngine e(s, {}, solver);
  std::vector<double> x = packed(e, TreeState::initial(s));
  Run run;
  run.names = e.columns();
  rk4(e, x, 0.0, dt, steps, [&](double t, const std::vector<double>& xx) {
    std::vector<double> row(run.names.size());
    e.output_row(t, xx.data(), row.data());
    run.rows.push_back(row);
  });
  return run;
}

// A free box with a slider: the child slides along axis_P (parent frame) from the joint point
// p_PoJ_P; spring k to the neutral position.
System slider(double m1, const Matrix3d& I1, double m2, const Matrix3d& I2,
              const Vector3d& w_NB_B0, const Vector3d& axis_P, const Vector3d& p_PoJ_P,
              const Vector3d& p_CoJ_C, double k, double s0, double rate0) {
  System s;
  s.name = "slider";
  s.bodies.push_back(rigid_body("hub", m1, I1));
  s.bodies.push_back(rigid_body("slide", m2, I2));
  s.joints.push_back(free_joint("base", 0, w_NB_B0));
  Joint j = joint("rail", JointType::Prismatic, 0, 1, p_PoJ_P, p_CoJ_C);
  j.axis_P = axis_P;
  j.stiffness = k;
  j.neutral_angle = 0.2;
  j.angle0 = s0;
  j.rate0 = rate0;
  s.joints.push_back(j);
  return s;
}

// A spinning hub with a gimbaled payload (universal joint, springs on both axes).
System gimbal(double m1, const Matrix3d& I1, double m2, const Matrix3d& I2,
              const Vector3d& w_NB_B0, const Vector3d& axis1_P, const Vector3d& axis2_P,
              double k1, double k2, double a1, double a2) {
  System s;
  s.name = "gimbal";
  s.bodies.push_back(rigid_body("hub", m1, I1));
  s.bodies.push_back(rigid_body("payload", m2, I2));
  s.joints.push_back(free_joint("base", 0, w_NB_B0));
  Joint j = joint("cardan", JointType::Universal, 0, 1, Vector3d(0, 0, 1), Vector3d(0, 0, -0.5));
  j.axis_P = axis1_P;
  j.axis2_P = axis2_P;
  j.stiffness = k1;
  j.stiffness2 = k2;
  j.angle0 = a1;
  j.angle2_0 = a2;
  s.joints.push_back(j);
  return s;
}

// Every joint type in one tree, with offsets, off-axis points and springs:
//   hub (free) -+- boom (prismatic, spring) -- arm (universal, springs) -- tip (revolute)
//               +- mast (spherical) -- probe (prismatic, spring, off-axis)
System mixed_new_tree() {
  System s;
  s.name = "mixed_new_tree";
  s.bodies.push_back(rigid_body("hub", 150, turned_inertia(80, 95, 120, quat_from_axis(0.3, {1, 2, 0}))));
  s.bodies.push_back(rigid_body("boom", 6, turned_inertia(0.4, 1.1, 1.2, quat_from_axis(0.8, {0, 1, 1}))));
  s.bodies.push_back(rigid_body("arm", 4, turned_inertia(0.2, 0.5, 0.6, quat_from_axis(-0.4, {1, 0, 1}))));
  s.bodies.push_back(rigid_body("tip", 1.5, turned_inertia(0.05, 0.08, 0.1, quat_from_axis(1.0, {2, 1, 0}))));
  s.bodies.push_back(rigid_body("mast", 5, turned_inertia(0.6, 0.7, 0.3, quat_from_axis(0.2, {0, 0, 1}))));
  s.bodies.push_back(rigid_body("probe", 2, turned_inertia(0.1, 0.12, 0.15, quat_from_axis(0.7, {1, 1, 1}))));
  s.joints.push_back(free_joint("base", 0, Vector3d(0.1, -0.2, 0.6), quat_from_axis(0.5, {1, -1, 2})));

  Joint boom = joint("rail", JointType::Prismatic, 0, 1, {1.0, 0.3, -0.2}, {-0.4, 0.1, 0.05});
  boom.axis_P = Vector3d(1, 0.2, -0.1);
  boom.q_PJ0 = quat_from_axis(0.3, {0, 1, 1});
  boom.stiffness = 30;
  boom.neutral_angle = 0.5;
  boom.angle0 = 0.3;
  boom.rate0 = 0.4;
  s.joints.push_back(boom);

  Joint arm = joint("cardan", JointType::Universal, 1, 2, {0.5, 0.1, 0.0}, {-0.3, 0.0, 0.1});
  arm.axis_P = Vector3d(0, 0, 1);
  arm.axis2_P = Vector3d(0.2, 1, 0.3);  // not perpendicular to the first
  arm.q_PJ0 = quat_from_axis(-0.5, {1, 0, 1});
  arm.stiffness = 4;
  arm.neutral_angle = 0.1;
  arm.stiffness2 = 6;
  arm.neutral_angle2 = -0.2;
  arm.angle0 = 0.7;
  arm.angle2_0 = -0.9;
  arm.rate0 = 0.5;
  arm.rate2_0 = -0.3;
  s.joints.push_back(arm);

  Joint tip = joint("wrist", JointType::Revolute, 2, 3, {0.3, -0.1, 0.2}, {-0.2, 0.0, 0.1});
  tip.axis_P = Vector3d(1, -1, 0.5);
  tip.angle0 = 0.4;
  tip.rate0 = -0.7;
  s.joints.push_back(tip);

  Joint mast = joint("ball", JointType::Spherical, 0, 4, {-0.8, 0.5, 0.6}, {0.0, 0.1, -0.7});
  mast.stiffness = 8;
  mast.q_J0 = quat_from_axis(0.4, {1, 2, -1});
  mast.w_PC_C0 = Vector3d(0.2, -0.1, 0.3);
  s.joints.push_back(mast);

  Joint probe = joint("slot", JointType::Prismatic, 4, 5, {0.2, -0.3, 0.4}, {0.1, 0.2, -0.3});
  probe.axis_P = Vector3d(-0.3, 1, 0.4);
  probe.stiffness = 12;
  probe.angle0 = -0.2;
  probe.rate0 = 0.6;
  s.joints.push_back(probe);
  return s;
}

// A random state of mixed_new_tree (every joint's coordinates and rates of order 1).
TreeState random_new_state(const System& s, std::mt19937& g) {
  std::normal_distribution<double> n;
  TreeState st = random_state(s, g);
  for (std::size_t j = 1; j < s.joints.size(); ++j) {
    st.joints[j].angle2 = n(g);
    st.joints[j].rate2 = n(g);
  }
  return st;
}

}  // namespace

TEST_CASE("kane new joints: a slider spring between two free bodies oscillates at sqrt(k / mu)") {
  // No rotation (the axis passes through both CMs, zero spin): the relative coordinate obeys
  // mu s'' = -k (s - s_n), mu = m1 m2 / (m1 + m2), so s(t) = s_n + (s0 - s_n) cos(w t) +
  // (v0 / w) sin(w t) with w = sqrt(k / mu).
  const double m1 = 40, m2 = 10, k = 250, s0 = 0.5, v0 = -0.3, sn = 0.2;
  const System s = slider(m1, diag(3, 4, 5), m2, diag(0.2, 0.3, 0.4), Vector3d::Zero(),
                          Vector3d(1, 0, 0), Vector3d(0, 0, 0), Vector3d(0, 0, 0), k, s0, v0);
  const Run run = rk4_run(s, 1e-3, 3000);
  const double w = std::sqrt(k * (m1 + m2) / (m1 * m2));
  double err = 0, err_rate = 0;
  for (std::size_t r = 0; r < run.rows.size(); ++r) {
    const double t = run.at(r, "t");
    const double s_t = sn + (s0 - sn) * std::cos(w * t) + v0 / w * std::sin(w * t);
    const double v_t = -(s0 - sn) * w * std::sin(w * t) + v0 * std::cos(w * t);
    err = std::max(err, std::abs(run.at(r, "rail.position") - s_t));
    err_rate = std::max(err_rate, std::abs(run.at(r, "rail.rate") - v_t));
  }
  INFO("max |s - s_exact| = " << err << " m, max |s' - s'_exact| = " << err_rate << " m/s");
  CHECK(err <= 1e-9);
  CHECK(err_rate <= 1e-8);
  // Linear momentum stays zero, the bodies never turn, E is conserved (spring included).
  for (const char* c : {"kane.P_N.x", "kane.P_N.y", "kane.P_N.z", "hub.wx", "slide.wz"})
    CHECK(run.drift(c, false) <= 1e-12);
  CHECK(run.drift("E") <= 1e-10);
  CHECK(run.at(0, "kane.V") == Approx(0.5 * k * (s0 - sn) * (s0 - sn)).epsilon(1e-14));
}

TEST_CASE("kane new joints: a free radial slider on a spinning hub conserves H and E") {
  // 3-D motion: spin not along a principal axis, the rail offset from the CM and tilted, the
  // slider's CM off the rail, an orientation offset, a spring and an initial rate.
  System s = slider(120, turned_inertia(40, 55, 70, quat_from_axis(0.4, {1, 2, 3})), 8,
                    turned_inertia(0.5, 0.8, 0.9, quat_from_axis(0.9, {0, 1, -1})),
                    Vector3d(0.3, -0.2, 1.2), Vector3d(1, 0.2, 0.1), Vector3d(0.5, 0.3, -0.2),
                    Vector3d(-0.1, 0.05, 0.1), 40, 0.6, 0.5);
  s.joints[1].q_PJ0 = quat_from_axis(0.6, {1, -1, 0});
  kane::KaneEngine e(s, {});
  CHECK(e.solver() == kane::KaneSolver::Composite);
  const Run run = rk4_run(s, 1e-3, 5000);
  double H0 = 0, dH = 0;
  for (std::size_t r = 0; r < run.rows.size(); ++r) {
    const Vector3d H(run.at(r, "kane.H_N.x"), run.at(r, "kane.H_N.y"), run.at(r, "kane.H_N.z"));
    const Vector3d Hf(run.at(0, "kane.H_N.x"), run.at(0, "kane.H_N.y"), run.at(0, "kane.H_N.z"));
    H0 = Hf.norm();
    dH = std::max(dH, (H - Hf).norm());
  }
  double smin = 1e300, smax = -1e300;
  for (std::size_t r = 0; r < run.rows.size(); ++r) {
    smin = std::min(smin, run.at(r, "rail.position"));
    smax = std::max(smax, run.at(r, "rail.position"));
  }
  INFO("|H - H0| / |H0| = " << dH / H0 << ", E drift " << run.drift("E") << ", s in [" << smin
                            << ", " << smax << "]");
  CHECK(dH / H0 <= 1e-9);
  CHECK(run.drift("E") <= 1e-9);
  CHECK(smax - smin > 0.1);  // it really slides
}

TEST_CASE("kane new joints: a prescribed deploying slider keeps H, and E changes by the work of its force") {
  System s = slider(120, turned_inertia(40, 55, 70, quat_from_axis(0.4, {1, 2, 3})), 8,
                    turned_inertia(0.5, 0.8, 0.9, quat_from_axis(0.9, {0, 1, -1})),
                    Vector3d(0.3, -0.2, 1.2), Vector3d(1, 0.2, 0.1), Vector3d(0.5, 0.3, -0.2),
                    Vector3d(-0.1, 0.05, 0.1), 0, 0.1, 0);
  PrescribedMotion deploy;
  deploy.profile = PrescribedMotion::Profile::Deploy;
  deploy.travel = 1.5;
  deploy.ramp_time = 2.0;
  s.joints[1].prescribed = deploy;
  kane::KaneEngine e(s, {});
  CHECK(e.speed_size() == 6);  // the slider is no degree of freedom
  const double dt = 1e-3;
  const Run run = rk4_run(s, dt, 3000);
  double dH = 0, work = 0, err_work = 0, Fmax = 0;
  const double E0 = run.at(0, "E");
  for (std::size_t r = 0; r < run.rows.size(); ++r) {
    const Vector3d H(run.at(r, "kane.H_N.x"), run.at(r, "kane.H_N.y"), run.at(r, "kane.H_N.z"));
    const Vector3d Hf(run.at(0, "kane.H_N.x"), run.at(0, "kane.H_N.y"), run.at(0, "kane.H_N.z"));
    dH = std::max(dH, (H - Hf).norm() / Hf.norm());
    const double F = run.at(r, "rail.force");
    CHECK(std::isfinite(F));
    Fmax = std::max(Fmax, std::abs(F));
    if (r > 0)  // trapezoid rule for the work of F along the axis, F s'
      work += 0.5 * dt * (F * run.at(r, "rail.rate") + run.at(r - 1, "rail.force") *
                                                           run.at(r - 1, "rail.rate"));
    err_work = std::max(err_work, std::abs(run.at(r, "E") - E0 - work));
    const double t = run.at(r, "t");
    CHECK(run.at(r, "rail.position") == Approx(0.1 + deploy.angle(t)).margin(1e-15));
  }
  INFO("|H - H0| / |H0| = " << dH << ", max |E - E0 - W| = " << err_work << " J, total work "
                            << work << " J, max |F| = " << Fmax << " N");
  CHECK(dH <= 1e-9);
  CHECK(std::abs(work) > 0.1);
  CHECK(err_work <= 1e-5 * std::abs(work));  // trapezoid error O(dt^2)
  // Pointwise: dE/dt along the motion equals F s' (five-point difference of E(t + h, x + h x')).
  std::vector<double> x = packed(e, TreeState::initial(s));
  const std::vector<std::string>& names = e.columns();
  auto col = [&](const std::string& c) {
    return static_cast<std::size_t>(std::find(names.begin(), names.end(), c) - names.begin());
  };
  const std::size_t cE = col("E"), cF = col("rail.force"), cr = col("rail.rate");
  int checked = 0;
  rk4(e, x, 0.0, 1e-3, 1600, [&](double t, const std::vector<double>& xx) {
    const long step = std::lround(t / 1e-3);
    if (step != 300 && step != 900 && step != 1600) return;
    std::vector<double> xd(xx.size()), row(names.size());
    e.rhs(t, xx.data(), xd.data());
    const double dE = derivative(
        [&](double h) {
          std::vector<double> r2(names.size());
          e.output_row(t + h, along(xx, xd, h).data(), r2.data());
          return r2[cE];
        },
        1e-4);
    e.output_row(t, xx.data(), row.data());
    INFO("t = " << t << ": dE/dt = " << dE << " W, F s' = " << row[cF] * row[cr] << " W");
    CHECK(std::abs(row[cF] * row[cr]) > 1e-3);
    CHECK(std::abs(dE - row[cF] * row[cr]) <= 1e-7 * (std::abs(dE) + 1));
    ++checked;
  });
  CHECK(checked == 3);
}

TEST_CASE("kane new joints: a gimbal on a heavy base oscillates about each axis at sqrt(k / I)") {
  // Payload CM 0.5 m below the joint point; small angles about x (axis 1) and y (axis 2): each
  // axis obeys I_k a_k'' = -k_k a_k, I_k the payload's inertia about that axis through the joint
  // point, I = I_CM + m 0.5^2 (the base 1e6 times heavier, so it barely moves).  Speeds 7 and 8
  // (indices 6, 7) are the gimbal's, after the base's six.
  const double m = 2, k1 = 6, k2 = 14;
  const Matrix3d I2 = diag(0.1, 0.2, 0.3);
  const double I_1 = 0.1 + m * 0.25, I_2 = 0.2 + m * 0.25;
  const double w1 = std::sqrt(k1 / I_1), w2 = std::sqrt(k2 / I_2);
  const double a1 = 1e-4, a2 = -2e-4;
  const System s = gimbal(2e6, diag(1e6, 1.2e6, 1.4e6), m, I2, Vector3d::Zero(), Vector3d(1, 0, 0),
                          Vector3d(0, 1, 0), k1, k2, a1, a2);
  // The linearised frequencies with the base's motion included: w_k^2 = k_k (M^-1)_kk at rest.
  kane::KaneEngine e(s, {});
  std::vector<double> x = packed(e, TreeState::initial(s));
  const Eigen::MatrixXd Minv = e.mass_matrix(x.data()).inverse();
  const double w1_lin = std::sqrt(k1 * Minv(6, 6)), w2_lin = std::sqrt(k2 * Minv(7, 7));
  INFO("linearised w1 = " << w1_lin << ", w2 = " << w2_lin);
  CHECK(std::abs(w1_lin / w1 - 1) <= 1e-5);  // the base: about 3e-6
  CHECK(std::abs(w2_lin / w2 - 1) <= 1e-5);
  const Run run = rk4_run(s, 1e-3, 4000);
  double e1 = 0, e2 = 0, l1 = 0, l2 = 0;
  for (std::size_t r = 0; r < run.rows.size(); ++r) {
    const double t = run.at(r, "t");
    e1 = std::max(e1, std::abs(run.at(r, "cardan.angle1") - a1 * std::cos(w1 * t)));
    e2 = std::max(e2, std::abs(run.at(r, "cardan.angle2") - a2 * std::cos(w2 * t)));
    l1 = std::max(l1, std::abs(run.at(r, "cardan.angle1") - a1 * std::cos(w1_lin * t)));
    l2 = std::max(l2, std::abs(run.at(r, "cardan.angle2") - a2 * std::cos(w2_lin * t)));
  }
  INFO("w1 = " << w1 << ", w2 = " << w2 << " rad/s; max errors " << e1 / a1 << ", "
               << e2 / std::abs(a2) << " of the amplitudes");
  CHECK(e1 <= 1e-4 * a1);
  CHECK(e2 <= 1e-4 * std::abs(a2));
  INFO("against the linearised frequencies: " << l1 / a1 << ", " << l2 / std::abs(a2));
  CHECK(l1 <= 1e-5 * a1);
  CHECK(l2 <= 1e-5 * std::abs(a2));
}

TEST_CASE("kane new joints: a gimbal at large angles on a spinning base conserves H and E") {
  System s = gimbal(50, turned_inertia(20, 25, 30, quat_from_axis(0.2, {1, 1, 0})), 6,
                    turned_inertia(0.8, 1.0, 1.3, quat_from_axis(0.5, {0, 1, 2})),
                    Vector3d(0.2, 0.1, 1.5), Vector3d(0, 0, 1), Vector3d(1, 0.3, 0.2), 3, 5, 1.2,
                    -0.8);
  s.joints[1].rate0 = 0.8;
  s.joints[1].rate2_0 = -1.1;
  s.joints[1].q_PJ0 = quat_from_axis(0.7, {1, 0, -1});
  s.joints[1].neutral_angle2 = 0.3;
  const Run run = rk4_run(s, 1e-3, 5000);
  double dH = 0;
  const Vector3d H0(run.at(0, "kane.H_N.x"), run.at(0, "kane.H_N.y"), run.at(0, "kane.H_N.z"));
  double amax = 0;
  for (std::size_t r = 0; r < run.rows.size(); ++r) {
    const Vector3d H(run.at(r, "kane.H_N.x"), run.at(r, "kane.H_N.y"), run.at(r, "kane.H_N.z"));
    dH = std::max(dH, (H - H0).norm() / H0.norm());
    amax = std::max(amax, std::abs(run.at(r, "cardan.angle2")));
  }
  INFO("|H - H0| / |H0| = " << dH << ", E drift " << run.drift("E") << ", max |a2| " << amax);
  CHECK(dH <= 1e-9);
  CHECK(run.drift("E") <= 1e-9);
  CHECK(amax > 0.5);
}

TEST_CASE("kane new joints: every joint type in one tree conserves H, E and zero P") {
  const System s = mixed_new_tree();
  const Run run = rk4_run(s, 1e-3, 4000);
  INFO("H drift " << run.drift("H") << ", E drift " << run.drift("E"));
  CHECK(run.drift("H") <= 1e-9);
  CHECK(run.drift("E") <= 1e-9);
  for (const char* c : {"kane.P_N.x", "kane.P_N.y", "kane.P_N.z"})
    CHECK(run.drift(c, false) <= 1e-10);
}

TEST_CASE("kane new joints: motors are internal (P and H unchanged) and change E") {
  System s = mixed_new_tree();
  s.joints[1].motor_revolute.times = {0.0, 0.5};
  s.joints[1].motor_revolute.values = {Eigen::Matrix<double, 1, 1>(3.0),
                                       Eigen::Matrix<double, 1, 1>(-2.0)};
  s.joints[2].motor_universal.times = {0.0, 0.7};
  s.joints[2].motor_universal.values = {Eigen::Vector2d(0.5, -0.8), Eigen::Vector2d(-0.3, 0.4)};
  s.joints[5].motor_revolute.times = {0.0};
  s.joints[5].motor_revolute.values = {Eigen::Matrix<double, 1, 1>(1.5)};
  kane::KaneEngine e(s, {});
  std::vector<double> x = packed(e, TreeState::initial(s));
  const Vector3d H0 = e.angular_momentum_N(x.data()), P0 = e.linear_momentum_N(x.data());
  double dH = 0, dP = 0;
  // Steps of 1 ms land on the motors' switches.
  rk4(e, x, 0.0, 1e-3, 1500, [&](double, const std::vector<double>& xx) {
    dH = std::max(dH, (e.angular_momentum_N(xx.data()) - H0).norm());
    dP = std::max(dP, (e.linear_momentum_N(xx.data()) - P0).norm());
  });
  INFO("max |H - H0| = " << dH << ", max |P - P0| = " << dP);
  CHECK(dH <= 1e-10 * H0.norm());
  CHECK(dP <= 1e-10);
  const Run free_run = rk4_run(mixed_new_tree(), 1e-3, 1500), motor_run = rk4_run(s, 1e-3, 1500);
  const double dE = std::abs(motor_run.at(motor_run.rows.size() - 1, "E") -
                             free_run.at(free_run.rows.size() - 1, "E"));
  INFO("E with motors - E without at 1.5 s = " << dE << " J");
  CHECK(dE > 1e-3);
}

TEST_CASE("kane new joints: the mass matrix is Kane's sum m V_r.V_s + W_r.I W_s over the bodies") {
  // Velocities are linear in u (no u-independent term for a free base): with u = e_r, each
  // body's v_Bo and w_B are its partial velocities V_r and W_r ([KL85] Sec. 2.14), so
  // M_rs = sum_B m V_r.V_s + W_r.I_B W_s (Eq. (36)'s coefficients of u').
  const System s = mixed_new_tree();
  kane::KaneEngine e(s, {});
  std::mt19937 g(3);
  for (int trial = 0; trial < 3; ++trial) {
    std::vector<double> x = packed(e, random_new_state(s, g));
    const int nq = e.position_size(), nu = e.speed_size();
    std::vector<std::vector<kane::BodyMotion>> partial(static_cast<std::size_t>(nu));
    for (int r = 0; r < nu; ++r) {
      std::vector<double> xr(x);
      for (int i = 0; i < nu; ++i) xr[static_cast<std::size_t>(nq + i)] = i == r ? 1.0 : 0.0;
      partial[static_cast<std::size_t>(r)] = e.body_motion(xr.data());
    }
    Eigen::MatrixXd M_ref = Eigen::MatrixXd::Zero(nu, nu);
    for (int r = 0; r < nu; ++r)
      for (int c = 0; c < nu; ++c)
        for (std::size_t b = 0; b < s.bodies.size(); ++b) {
          const kane::BodyMotion& A = partial[static_cast<std::size_t>(r)][b];
          const kane::BodyMotion& B = partial[static_cast<std::size_t>(c)][b];
          const Matrix3d I_N = A.R_NB * s.bodies[b].I_BBo_B * A.R_NB.transpose();
          M_ref(r, c) += s.bodies[b].mass * A.v_NBo_N.dot(B.v_NBo_N) +
                         (A.R_NB * A.w_NB_B).dot(I_N * (B.R_NB * B.w_NB_B));
        }
    const Eigen::MatrixXd M = e.mass_matrix(x.data());
    INFO("max |M - M_ref| = " << (M - M_ref).cwiseAbs().maxCoeff());
    CHECK(all_close(M, M_ref, 1e-12, 1e-12));
  }
}

TEST_CASE("kane new joints: accelerations() agree with rhs() and with differences of the motion") {
  const System s = mixed_new_tree();
  kane::KaneEngine e(s, {});
  std::mt19937 g(5);
  const std::vector<Joint>& J = s.joints;
  for (int trial = 0; trial < 3; ++trial) {
    std::vector<double> x = packed(e, random_new_state(s, g)), xdot(x.size());
    e.rhs(0.2, x.data(), xdot.data());
    TreeAccel a;
    e.accelerations(0.2, x.data(), a);
    const int nq = e.position_size();
    for (std::size_t j = 1; j < J.size(); ++j) {
      const kane::Node& n = e.nodes()[j];
      const auto ud = [&](int i) { return xdot[static_cast<std::size_t>(nq + n.u0 + i)]; };
      if (J[j].type == JointType::Prismatic || J[j].type == JointType::Revolute)
        CHECK(a.angle_ddot[j] == ud(0));
      if (J[j].type == JointType::Universal) {
        CHECK(a.angle_ddot[j] == ud(0));
        CHECK(a.angle2_ddot[j] == ud(1));
      }
    }
    // Body accelerations against five-point differences of the velocities along the motion.
    const double h = 1e-4;
    for (std::size_t b = 0; b < s.bodies.size(); ++b) {
      const Vector3d a_fd = derivative(
          [&](double hh) { return Vector3d(e.body_motion(along(x, xdot, hh).data())[b].v_NBo_N); },
          h);
      const Vector3d wd_fd = derivative(
          [&](double hh) { return Vector3d(e.body_motion(along(x, xdot, hh).data())[b].w_NB_B); },
          h);
      INFO("body " << s.bodies[b].name);
      CHECK(all_close(a.a_NBo_N[b], a_fd, 1e-8, 1e-9));
      CHECK(all_close(a.wdot_NB_B[b], wd_fd, 1e-8, 1e-9));
    }
  }
}

TEST_CASE("kane new joints: the order-N solver and the composite solver give the same u'") {
  // These scenes leave the fused rigid path (JointUnit::fused false): the general composite
  // passes and the order-N recursion must agree.
  const System s = mixed_new_tree();
  kane::KaneEngine comp(s, {}, kane::KaneSolver::Composite), on(s, {}, kane::KaneSolver::OrderN);
  CHECK(on.solver() == kane::KaneSolver::OrderN);
  std::mt19937 g(9);
  for (int trial = 0; trial < 4; ++trial) {
    std::vector<double> x = packed(comp, random_new_state(s, g)), x1(x.size()), x2(x.size());
    comp.rhs(0.4, x.data(), x1.data());
    on.rhs(0.4, x.data(), x2.data());
    double scale = 0, diff = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      scale = std::max(scale, std::abs(x1[i]));
      diff = std::max(diff, std::abs(x1[i] - x2[i]));
    }
    INFO("max |xdot_composite - xdot_order_n| = " << diff << " (scale " << scale << ")");
    CHECK(diff <= 1e-12 * scale);
  }
}

TEST_CASE("kane new joints: flexible bodies on a slider and a gimbal (at their frames) keep H and E") {
  // A flexible hub (free) -- prismatic -- a flexible boom -- universal -- a rigid tip; the joints
  // at the flexible bodies' frames (node -1), springs and K only (energy conserving).
  std::mt19937 g(21);
  System s;
  s.name = "flex_slider_gimbal";
  s.bodies.push_back(random_flex_body("hub", 5, 2, g, 1.0, 0.3, 0.3, 60.0));
  s.bodies.push_back(random_flex_body("boom", 4, 3, g, 0.5, 0.3, 0.3, 40.0));
  s.bodies.push_back(rigid_body("tip", 1.5, turned_inertia(0.05, 0.08, 0.1, quat_from_axis(1.0, {2, 1, 0}))));
  s.joints.push_back(free_joint("base", 0, Vector3d(0.2, -0.1, 0.8)));
  Joint rail = joint("rail", JointType::Prismatic, 0, 1, {0.8, 0.2, -0.1}, {-0.3, 0.1, 0.05});
  rail.axis_P = Vector3d(1, 0.3, -0.2);
  rail.stiffness = 25;
  rail.angle0 = 0.2;
  rail.rate0 = 0.5;
  s.joints.push_back(rail);
  Joint cardan = joint("cardan", JointType::Universal, 1, 2, {0.4, -0.1, 0.2}, {-0.2, 0.0, 0.1});
  cardan.axis_P = Vector3d(0, 1, 0);
  cardan.axis2_P = Vector3d(1, 0, 0.2);
  cardan.stiffness = 3;
  cardan.stiffness2 = 2;
  cardan.angle0 = 0.5;
  cardan.rate2_0 = 0.7;
  s.joints.push_back(cardan);
  kane::KaneEngine e(s, {});
  std::vector<double> x = packed(e, flex_state(s, 0.05, 0.3));
  const std::vector<std::string>& names = e.columns();
  std::vector<double> row(names.size());
  const auto iE = std::find(names.begin(), names.end(), "E") - names.begin();
  auto energy = [&](double t, const std::vector<double>& xx) {
    e.output_row(t, xx.data(), row.data());
    return row[static_cast<std::size_t>(iE)];
  };
  const double E0 = energy(0, x);
  const Vector3d H0 = e.angular_momentum_N(x.data());
  double dE = 0, dH = 0;
  rk4(e, x, 0.0, 5e-4, 4000, [&](double t, const std::vector<double>& xx) {
    dE = std::max(dE, std::abs(energy(t, xx) - E0));
    dH = std::max(dH, (e.angular_momentum_N(xx.data()) - H0).norm());
  });
  INFO("|E - E0| / E0 = " << dE / E0 << ", |H - H0| / |H0| = " << dH / H0.norm());
  CHECK(dE <= 1e-9 * E0);
  CHECK(dH <= 1e-9 * H0.norm());
}

TEST_CASE("kane new joints: refused where the engine does not take them") {
  System s = mixed_new_tree();
  SECTION("a prismatic joint at a node") {
    s.joints[1].child_node = 0;
    CHECK_THROWS_AS(kane::KaneEngine(s, {}), InputError);
  }
  SECTION("parallel universal axes") {
    s.joints[2].axis2_P = Vector3d(0, 0, -2);
    CHECK_THROWS_AS(kane::KaneEngine(s, {}), InputError);
  }
  SECTION("a prescribed universal joint") {
    s.joints[2].prescribed = PrescribedMotion{};
    CHECK_THROWS_AS(kane::KaneEngine(s, {}), InputError);
  }
}
