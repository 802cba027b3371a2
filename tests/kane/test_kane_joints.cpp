// The Kane engine with revolute, spherical and fixed joints: exact two-body results, a fixed joint
// against the merged rigid body, conservation of H and E, external and dissipative loads.
#include <catch2/catch.hpp>

#include "core/rotation.hpp"
#include "formulations/kane/kane_engine.hpp"
#include "tests/kane/kane_systems.hpp"
#include "tests/support/close.hpp"

#include <cmath>

using namespace crossdyn;
using namespace crossdyn::test::kane;
using crossdyn::test::all_close;
using crossdyn::test::close;

namespace {

int column(const Engine& e, const std::string& name) {
  const auto& c = e.columns();
  for (std::size_t i = 0; i < c.size(); ++i)
    if (c[i] == name) return static_cast<int>(i);
  FAIL("no column " << name);
  return -1;
}

// Runs `system` with RK4 at step dt for `steps` steps; returns every output row.
std::vector<std::vector<double>> run_rows(const System& system, double dt, int steps,
                                          const EngineOptions& o = {}) {
  kane::KaneEngine e(system, o);
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(TreeState::initial(system), x.data());
  std::vector<std::vector<double>> rows;
  rk4(e, x, 0.0, dt, steps, [&](double t, const std::vector<double>& xx) {
    std::vector<double> r(e.columns().size());
    e.output_row(t, xx.data(), r.data());
    rows.push_back(r);
  });
  return rows;
}

// Largest relative change of column c over the rows.
double max_relative_drift(const std::vector<std::vector<double>>& rows, int c) {
  double d = 0;
  const double ref = rows.front()[static_cast<std::size_t>(c)];
  for (const auto& r : rows) d = std::max(d, std::abs(r[static_cast<std::size_t>(c)] - ref));
  return d / std::abs(ref);
}

// Two bodies turning about a common z axis through both CMs, joined by a torsional spring of
// stiffness k: the relative angle obeys theta'' = -k (1/C0 + 1/C1) theta exactly (the joint
// torque -k theta acts on the child, +k theta on the base; no gyroscopic term since w stays along
// a principal axis of both bodies).
System coaxial_rotors(JointType type, double C0, double C1, double k, double theta0, double rate0,
                      double Omega0) {
  System s;
  s.name = "coaxial_rotors";
  s.bodies.push_back(rigid_body("rotor0", 20, diag(50, 60, C0)));
  s.bodies.push_back(rigid_body("rotor1", 4, diag(5, 6, C1)));
  s.joints.push_back(free_joint("base", 0, Eigen::Vector3d(0, 0, Omega0)));
  Joint j = joint("shaft", type, 0, 1, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  j.stiffness = k;
  if (type == JointType::Revolute) {
    j.axis_P = Eigen::Vector3d::UnitZ();
    j.angle0 = theta0;
    j.rate0 = rate0;
  } else {
    j.q_J0 = Eigen::Quaterniond(Eigen::AngleAxisd(theta0, Eigen::Vector3d::UnitZ()));
    j.w_PC_C0 = Eigen::Vector3d(0, 0, rate0);
  }
  s.joints.push_back(j);
  return s;
}

// Inertia about the point c (in the same axes) of a body with central inertia I, mass m and CM
// at r: I + m (|r - c|^2 1 - (r - c)(r - c)^T)  (parallel-axis theorem).
Eigen::Matrix3d about(const Eigen::Matrix3d& I, double m, const Eigen::Vector3d& r,
                      const Eigen::Vector3d& c) {
  const Eigen::Vector3d d = r - c;
  return I + m * (d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose());
}

}  // namespace

TEST_CASE("kane: revolute spring between coaxial rotors gives the exact harmonic relative motion") {
  const double C0 = 40, C1 = 8, k = 30, theta0 = 0.2, rate0 = 0.5, Omega0 = 0.3;
  const double omega = std::sqrt(k * (1 / C0 + 1 / C1));  // 2.1213 rad/s
  const double L = C0 * Omega0 + C1 * (Omega0 + rate0);   // axial angular momentum
  for (JointType type : {JointType::Revolute, JointType::Spherical}) {
    const System s = coaxial_rotors(type, C0, C1, k, theta0, rate0, Omega0);
    kane::KaneEngine e(s, {});
    const bool rev = type == JointType::Revolute;
    const int c_rate = column(e, rev ? "shaft.rate" : "shaft.wz");
    const int c_base = column(e, "rotor0.wz");
    const int c_qw = column(e, "rotor1.qw"), c_qz = column(e, "rotor1.qz");
    const int c_bqw = column(e, "rotor0.qw"), c_bqz = column(e, "rotor0.qz");
    const double dt = 1e-3;
    const auto rows = run_rows(s, dt, 10000);
    double err_theta = 0, err_rate = 0, err_base = 0, off_axis = 0;
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const auto& r = rows[i];
      const double t = r[0];
      const double theta = theta0 * std::cos(omega * t) + rate0 / omega * std::sin(omega * t);
      const double rate = -theta0 * omega * std::sin(omega * t) + rate0 * std::cos(omega * t);
      // Relative angle from the two attitudes (both turn about z only).
      const double a1 =
          2 * std::atan2(r[static_cast<std::size_t>(c_qz)], r[static_cast<std::size_t>(c_qw)]);
      const double a0 =
          2 * std::atan2(r[static_cast<std::size_t>(c_bqz)], r[static_cast<std::size_t>(c_bqw)]);
      const double rel = std::remainder(a1 - a0, 2 * M_PI);
      err_theta = std::max(err_theta, std::abs(rel - theta));
      err_rate = std::max(err_rate, std::abs(r[static_cast<std::size_t>(c_rate)] - rate));
      err_base = std::max(
          err_base, std::abs(r[static_cast<std::size_t>(c_base)] - (L - C1 * rate) / (C0 + C1)));
      off_axis = std::max({off_axis, std::abs(r[static_cast<std::size_t>(column(e, "rotor0.wx"))]),
                           std::abs(r[static_cast<std::size_t>(column(e, "rotor1.wy"))])});
    }
    INFO((rev ? "revolute" : "spherical")
         << ": max |theta - exact| = " << err_theta << ", |rate - exact| = " << err_rate
         << ", |base wz - exact| = " << err_base);
    CHECK(err_theta <= 1e-10);
    CHECK(err_rate <= 1e-10);
    CHECK(err_base <= 1e-10);
    CHECK(off_axis <= 1e-14);
  }
}

TEST_CASE(
    "kane: revolute pendulum with a spring on a very massive base: omega^2 = k / (I_zz + m d^2)") {
  // The base (1e12 kg, 1e12 kg m^2) barely moves, so the child turns about the fixed hinge axis:
  // (I_zz + m d^2) theta'' = -k theta, up to relative corrections of order m / M = 2e-12.
  const double m = 2, Izz = 0.3, d = 1.5, k = 9, theta0 = 0.1;
  const double omega = std::sqrt(k / (Izz + m * d * d));  // 1.3693 rad/s
  System s;
  s.bodies.push_back(rigid_body("ground", 1e12, diag(1e12, 1e12, 1e12)));
  s.bodies.push_back(rigid_body("bob", m, diag(0.1, 0.2, Izz)));
  s.joints.push_back(free_joint("base", 0, Eigen::Vector3d::Zero()));
  Joint j = joint("pivot", JointType::Revolute, 0, 1, {1, 0, 0}, {-d, 0, 0});
  j.axis_P = Eigen::Vector3d::UnitZ();
  j.stiffness = k;
  j.angle0 = theta0;
  s.joints.push_back(j);
  kane::KaneEngine e(s, {});
  const int c = column(e, "pivot.angle");
  const auto rows = run_rows(s, 1e-3, 10000);
  double err = 0;
  for (const auto& r : rows)
    err = std::max(err, std::abs(r[static_cast<std::size_t>(c)] - theta0 * std::cos(omega * r[0])));
  INFO("max |theta - theta0 cos(omega t)| over 10 s = " << err << " rad");
  CHECK(err <= 1e-9 * theta0);
}

TEST_CASE("kane: a fixed joint moves exactly like the merged rigid body") {
  // A: base + fixed child (offset attitude and points).  B: one body with the combined mass and
  // the combined inertia about the combined CM, in the base's axes (its frame parallel to A's
  // base).
  const double m0 = 50, m1 = 12;
  const Eigen::Matrix3d I0 = turned_inertia(20, 30, 35, quat_from_axis(0.3, {1, 0, 1}));
  const Eigen::Matrix3d I1 = turned_inertia(2, 3, 4, quat_from_axis(-0.8, {0, 1, 2}));
  const Eigen::Quaterniond q_PJ0 = quat_from_axis(0.9, {1, 1, 0});
  const Eigen::Vector3d p_PoJ_P(0.8, -0.3, 0.5), p_CoJ_C(-0.2, 0.4, 0.1);
  const Eigen::Vector3d w0(0.4, -0.7, 1.1);
  const Eigen::Quaterniond q0 = quat_from_axis(0.6, {2, -1, 1});

  System A;
  A.bodies.push_back(rigid_body("b0", m0, I0));
  A.bodies.push_back(rigid_body("b1", m1, I1));
  A.joints.push_back(free_joint("base", 0, w0, q0));
  Joint f = joint("weld", JointType::Fixed, 0, 1, p_PoJ_P, p_CoJ_C);
  f.q_PJ0 = q_PJ0;
  A.joints.push_back(f);

  const Eigen::Matrix3d R = q_PJ0.toRotationMatrix();
  const Eigen::Vector3d r1 = p_PoJ_P - R * p_CoJ_C;  // b1's CM in b0's frame
  const Eigen::Vector3d c = m1 * r1 / (m0 + m1);
  const Eigen::Matrix3d Im =
      about(I0, m0, Eigen::Vector3d::Zero(), c) + about(R * I1 * R.transpose(), m1, r1, c);
  System B = single_body(Im, w0, m0 + m1);
  B.joints[0].q_NB0 = q0;

  const auto ra = run_rows(A, 1e-3, 10000), rb = run_rows(B, 1e-3, 10000);
  kane::KaneEngine ea(A, {}), eb(B, {});
  double err = 0;
  for (std::size_t i = 0; i < ra.size(); ++i)
    for (const char* q : {".wx", ".wy", ".wz", ".qw", ".qx", ".qy", ".qz"})
      err = std::max(
          err, std::abs(ra[i][static_cast<std::size_t>(column(ea, std::string("b0") + q))] -
                        rb[i][static_cast<std::size_t>(column(eb, std::string("body") + q))]));
  INFO("max difference of w and q over 10 s = " << err);
  CHECK(err <= 1e-11);
  CHECK(close(ra.back()[static_cast<std::size_t>(column(ea, "H"))],
              rb.back()[static_cast<std::size_t>(column(eb, "H"))], 0, 1e-12));
  CHECK(close(ra.back()[static_cast<std::size_t>(column(ea, "E"))],
              rb.back()[static_cast<std::size_t>(column(eb, "E"))], 0, 1e-12));
}

TEST_CASE("kane: a fixed joint below a hinged body equals the merged hinged body") {
  // A: core -(revolute, spring)- arm -(fixed)- tool.  B: core -(revolute)- arm+tool merged.
  const double m0 = 80, ma = 6, mt = 3;
  const Eigen::Matrix3d I0 = turned_inertia(30, 45, 50, quat_from_axis(0.2, {0, 0, 1}));
  const Eigen::Matrix3d Ia = turned_inertia(0.5, 2.0, 2.2, quat_from_axis(0.4, {1, 0, 0}));
  const Eigen::Matrix3d It = turned_inertia(0.2, 0.3, 0.25, quat_from_axis(1.0, {1, -1, 1}));
  const Eigen::Quaterniond q_weld = quat_from_axis(-0.5, {0, 1, 1});
  const Eigen::Vector3d weld_P(0.7, 0.1, 0.0), weld_C(-0.1, 0.0, 0.2);
  const Eigen::Vector3d hinge_P(1.0, 0.3, -0.2), hinge_C(-0.9, 0.05, 0.0);
  const Eigen::Vector3d axis = Eigen::Vector3d(0.2, 0.3, 1.0).normalized();

  auto make = [&](bool merged) {
    System s;
    s.bodies.push_back(rigid_body("core", m0, I0));
    const Eigen::Matrix3d R = q_weld.toRotationMatrix();
    const Eigen::Vector3d rt = weld_P - R * weld_C;  // tool CM in the arm frame
    const Eigen::Vector3d c = mt * rt / (ma + mt);   // merged CM in the arm frame
    if (merged) {
      const Eigen::Matrix3d Im =
          about(Ia, ma, Eigen::Vector3d::Zero(), c) + about(R * It * R.transpose(), mt, rt, c);
      s.bodies.push_back(rigid_body("arm", ma + mt, Im));
    } else {
      s.bodies.push_back(rigid_body("arm", ma, Ia));
      s.bodies.push_back(rigid_body("tool", mt, It));
    }
    s.joints.push_back(
        free_joint("base", 0, Eigen::Vector3d(0.1, 0.2, -0.3), quat_from_axis(0.3, {1, 2, 3})));
    Joint h = joint("elbow", JointType::Revolute, 0, 1, hinge_P,
                    merged ? Eigen::Vector3d(hinge_C - c) : hinge_C);
    h.axis_P = axis;
    h.stiffness = 4;
    h.angle0 = 0.5;
    h.rate0 = -0.8;
    s.joints.push_back(h);
    if (!merged) {
      Joint w = joint("weld", JointType::Fixed, 1, 2, weld_P, weld_C);
      w.q_PJ0 = q_weld;
      s.joints.push_back(w);
    }
    return s;
  };
  const System A = make(false), B = make(true);
  kane::KaneEngine ea(A, {}), eb(B, {});
  const auto ra = run_rows(A, 1e-3, 5000), rb = run_rows(B, 1e-3, 5000);
  double err = 0;
  for (std::size_t i = 0; i < ra.size(); ++i)
    for (const char* q : {"core.wx", "core.wy", "core.wz", "core.qx", "core.qy", "core.qz",
                          "arm.wx", "arm.qw", "elbow.angle", "elbow.rate", "H", "E"})
      err = std::max(err, std::abs(ra[i][static_cast<std::size_t>(column(ea, q))] -
                                   rb[i][static_cast<std::size_t>(column(eb, q))]));
  INFO("max difference over 5 s = " << err);
  CHECK(err <= 1e-11);
}

TEST_CASE("kane: H and E are conserved in a tree with every joint type (RK4, dt = 1 ms, 5 s)") {
  for (const System& s : {mixed_tree(), chain(5), spear1_case1()}) {
    kane::KaneEngine e(s, {});
    const auto rows = run_rows(s, 1e-3, 5000);
    const double dH = max_relative_drift(rows, column(e, "H"));
    const double dE = max_relative_drift(rows, column(e, "E"));
    INFO(s.name << ": max |H - H0| / H0 = " << dH << ", max |E - E0| / E0 = " << dE);
    CHECK(dH <= 1e-11);
    CHECK(dE <= 1e-11);
    // Linear momentum stays zero (it starts at zero; no external force).
    double P = 0;
    for (const auto& r : rows)
      for (const char* c : {"kane.P_N.x", "kane.P_N.y", "kane.P_N.z"})
        P = std::max(P, std::abs(r[static_cast<std::size_t>(column(e, c))]));
    CHECK(P <= 1e-9);
  }
}

TEST_CASE("kane: symmetric SPEAR-1 deployment keeps the spin axis and opposite hinge rates") {
  // Mirror symmetry about main's x-z plane: main turns about x only, hinge2 = -hinge1.
  const System s = spear1_case1();
  kane::KaneEngine e(s, {});
  const auto rows = run_rows(s, 1e-3, 5000);
  double asym = 0;
  for (const auto& r : rows) {
    auto v = [&](const char* c) { return r[static_cast<std::size_t>(column(e, c))]; };
    asym = std::max({asym, std::abs(v("main.wy")), std::abs(v("main.wz")), std::abs(v("main.qy")),
                     std::abs(v("main.qz")), std::abs(v("hinge1.rate") + v("hinge2.rate")),
                     std::abs(v("hinge1.angle") + v("hinge2.angle"))});
  }
  INFO("largest departure from symmetry over 5 s = " << asym);
  CHECK(asym <= 1e-12);
  // The spin slows while the booms swing out (moment of inertia about x grows): the paper's
  // Figs. 4-6 trend.  Initially 90 deg/s.
  const int wx = column(e, "main.wx");
  double min_wx = 1e300;
  for (const auto& r : rows) min_wx = std::min(min_wx, r[static_cast<std::size_t>(wx)]);
  CHECK(min_wx < 0.99 * M_PI / 2);
}

TEST_CASE("kane: dampers dissipate, internal loads keep H, an inertial torque T changes H by T t") {
  System s = mixed_tree();
  for (Joint& j : s.joints)
    if (j.type == JointType::Revolute || j.type == JointType::Spherical) j.damping = 0.7;
  SECTION("damping only: E never increases, H is conserved") {
    kane::KaneEngine e(s, {});
    const auto rows = run_rows(s, 1e-3, 3000);
    const int cE = column(e, "E");
    double rise = 0;
    for (std::size_t i = 1; i < rows.size(); ++i)
      rise = std::max(
          rise, rows[i][static_cast<std::size_t>(cE)] - rows[i - 1][static_cast<std::size_t>(cE)]);
    const double loss =
        rows.front()[static_cast<std::size_t>(cE)] - rows.back()[static_cast<std::size_t>(cE)];
    INFO("largest rise of E in one step = " << rise << " J, loss over 3 s = " << loss << " J");
    CHECK(rise <= 1e-12);
    CHECK(loss > 0.1);
    CHECK(max_relative_drift(rows, column(e, "H")) <= 1e-11);
  }
  SECTION("a constant inertial torque on one body: H_N(t) = H_N(0) + T t") {
    const Eigen::Vector3d T(0.3, -0.2, 0.5);
    s.bodies[3].torque.times = {0.0};
    s.bodies[3].torque.values = {T};
    s.bodies[3].torque_frame = Body::Frame::Inertial;
    s.joints[1].motor_revolute.times = {0.0, 1.0};  // internal: changes E, not H
    s.joints[1].motor_revolute.values = {Eigen::Matrix<double, 1, 1>(2.0),
                                         Eigen::Matrix<double, 1, 1>(-1.0)};
    kane::KaneEngine e(s, {});
    std::vector<double> x(static_cast<std::size_t>(e.state_size()));
    e.pack(TreeState::initial(s), x.data());
    const Eigen::Vector3d H0 = e.angular_momentum_N(x.data());
    double err = 0;
    // Steps of 1 ms land on the motor's switch at t = 1 s.
    rk4(e, x, 0.0, 1e-3, 2000, [&](double t, const std::vector<double>& xx) {
      err = std::max(err, (e.angular_momentum_N(xx.data()) - (H0 + T * t)).norm());
    });
    INFO("max |H_N - (H_N0 + T t)| over 2 s = " << err << " kg m^2/s");
    CHECK(err <= 1e-10 * H0.norm());
  }
}
