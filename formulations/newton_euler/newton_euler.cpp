// The Newton-Euler engine (see newton_euler.hpp for the state layout, equations and outputs).
//
// Bibliography
//   [Paper]    Cochran, No & Fitz-Coy (1990), ../shared/reference/cochran-no-fitzcoy-1990-treetops.md
//   [KLL83]    Kane, Likins & Levinson (1983), "Spacecraft Dynamics", McGraw-Hill.
//   [Baraff96] Baraff (1996), "Linear-time dynamics using Lagrange multipliers", SIGGRAPH 96.
//   [Baum72]   Baumgarte (1972), "Stabilization of constraints and integrals of motion in
//              dynamical systems", Comput. Methods Appl. Mech. Eng. 1, 1-16.
//   [HLW06]    Hairer, Lubich & Wanner (2006), "Geometric Numerical Integration", 2nd ed., IV.4.
//   [Shuster93] Shuster (1993), "A survey of attitude representations", J. Astronaut. Sci. 41(4).
#include "formulations/newton_euler/newton_euler.hpp"

#include "core/errors.hpp"
#include "core/rotation.hpp"
#include "formulations/newton_euler/joint_constraints.hpp"
#include "formulations/newton_euler/tree_kkt.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace crossdyn {
namespace newton_euler {
namespace {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

constexpr const char* kEngineName = "newton-euler";

// Projection thresholds, per metre of the model's length scale L (the largest of 1 m, the joint
// lever arms |r_P| + |r_C| and the CM distances from the origin: round-off in g is ~1e-16 L).
// A state whose violation is below kProjectTrigger L is left alone (so that after_step() does not
// restart the integrator for round-off); Newton iterations stop at kNewtonTarget L or after
// kNewtonMaxIterations (each iteration squares the relative error, so one or two reach round-off
// from any violation an accepted step can produce).
constexpr double kProjectTrigger = 1e-12;      // m (and rad, m/s, rad/s) per metre of L
constexpr double kNewtonTarget = 1e-14;        // m per metre of L
constexpr int kNewtonMaxIterations = 4;
constexpr double kQuaternionNormTrigger = 1e-12;

enum class Stabilization { None, Baumgarte, Projection };

std::size_t at(int i) { return static_cast<std::size_t>(i); }

std::string where(const System& system) {
  return system.file.empty() ? std::string("scene '") + system.name + "'" : system.file;
}

class NewtonEulerEngine final : public Engine {
 public:
  NewtonEulerEngine(const System& system, const EngineOptions& options);

  const char* name() const override { return kEngineName; }
  int state_size() const override { return 13 * nb_; }
  std::string state_label(int i) const override;
  void pack(const TreeState& s, double* x) override;
  void rhs(double t, const double* x, double* xdot) override;
  bool after_step(double t, double* x) override;
  void accelerations(double t, const double* x, TreeAccel& a) override;
  const OutputLayout& layout() const override { return layout_; }
  void output_row(double t, const double* x, double* row) override;

 private:
  // State layout.
  int pos(int b) const { return 7 * b; }
  int vel(int b) const { return 7 * nb_ + 6 * b; }

  // Named passes (see newton_euler.hpp).
  void body_pass(double t, const double* x);
  void joint_pass();
  void force_pass(double t);
  void solve_pass(double t);
  void dynamics(double t, const double* x);

  void write_state(double* x) const;  // bk_ => x (positions, attitudes, velocities)
  bool project(double t, double* x);
  void update_turn_counters(double t, const double* x);
  double angular_momentum() const;
  double energy() const;
  [[noreturn]] void fail(double t, const std::string& quantity, const std::string& reason) const;

  // ---- model (constant after construction) ----
  System system_;
  Stabilization stabilization_ = Stabilization::Projection;
  double alpha_ = 0, beta_ = 0;
  int nb_ = 0, nj_ = 0;
  std::vector<double> mass_;
  std::vector<Matrix3d> I_B_;            // inertia about the CM in body axes (scaled for tests)
  std::vector<JointModel> joints_;       // per System joint
  double lever_scale_ = 0;               // m, largest |r_P| + |r_C| over the joints
  OutputLayout layout_;          // pinned columns, then joint wrenches, then constraint violations
  int wrench0_ = 0, violation0_ = 0;  // first extra column of each group
  std::vector<std::string> labels_;

  // ---- workspace (mutable, preallocated) ----
  std::vector<BodyKinematics> bk_;
  std::vector<JointKinematics> jk_;
  std::vector<ConstraintRows> cr_;       // per System joint (index 0, the free joint, unused)
  std::vector<double> angle_;            // revolute: continuous angle at the current state
  std::vector<double> angle_ref_;        // revolute: continuous angle after the last step/pack
  std::vector<Vector6d> f_, nu_dot_;     // per body
  std::vector<Vector6d> gamma_, y_;      // per KKT link (joint j is link j - 1)
  TreeKkt kkt_;
};

NewtonEulerEngine::NewtonEulerEngine(const System& system, const EngineOptions& options)
    : system_(system) {
  const std::string file = where(system);
  if (options.stabilization == "projection") stabilization_ = Stabilization::Projection;
  else if (options.stabilization == "baumgarte") stabilization_ = Stabilization::Baumgarte;
  else if (options.stabilization == "none") stabilization_ = Stabilization::None;
  else
    throw InputError("engine option stabilization: unknown value '" + options.stabilization +
                     "' (known: projection, baumgarte, none)");
  if (!std::isfinite(options.baumgarte_alpha) || options.baumgarte_alpha < 0 ||
      !std::isfinite(options.baumgarte_beta) || options.baumgarte_beta < 0)
    throw InputError("engine options baumgarte_alpha, baumgarte_beta: must be finite and >= 0 (got " +
                     std::to_string(options.baumgarte_alpha) + ", " +
                     std::to_string(options.baumgarte_beta) + ")");
  if (!std::isfinite(options.test_inertia_scale) || options.test_inertia_scale <= 0)
    throw InputError("engine option test_inertia_scale: must be finite and > 0 (got " +
                     std::to_string(options.test_inertia_scale) + ")");
  alpha_ = options.baumgarte_alpha;
  beta_ = options.baumgarte_beta;

  nb_ = static_cast<int>(system.bodies.size());
  nj_ = static_cast<int>(system.joints.size());
  if (nb_ == 0) throw InputError(file + ": bodies: the scene has no bodies");
  if (nj_ != nb_)
    throw InputError(file + ": joints: expected exactly one joint per body (" + std::to_string(nb_) +
                     " bodies, " + std::to_string(nj_) + " joints)");
  for (int b = 0; b < nb_; ++b) {
    const Body& body = system.bodies[at(b)];
    const std::string key = file + ": bodies[" + std::to_string(b) + "] '" + body.name + "'";
    if (body.flex)
      throw InputError(key + ": flexible bodies (modal data) are not supported yet by the " +
                       std::string(kEngineName) + " engine");
    if (!(body.mass > 0) || !std::isfinite(body.mass))
      throw InputError(key + ": mass must be finite and > 0");
    const Matrix3d I = options.test_inertia_scale * body.I_BBo_B;
    if (!I.allFinite() || (I - I.transpose()).cwiseAbs().maxCoeff() > 1e-12 * I.cwiseAbs().maxCoeff() ||
        Eigen::LLT<Matrix3d>(I).info() != Eigen::Success)
      throw InputError(key + ": inertia must be symmetric positive definite");
    mass_.push_back(body.mass);
    I_B_.push_back(I);
  }

  // Joints: joints[0] free (the base), the rest in topological order.
  std::vector<bool> placed(at(nb_), false);
  std::vector<KktLink> links;
  for (int j = 0; j < nj_; ++j) {
    const Joint& J = system.joints[at(j)];
    const std::string key = file + ": joints[" + std::to_string(j) + "] '" + J.name + "'";
    if ((j == 0) != (J.type == JointType::Free))
      throw InputError(key + ": the first joint, and only it, must be the free joint of the base");
    if (J.child < 0 || J.child >= nb_ || placed[at(J.child)])
      throw InputError(key + ": child must be a body not already attached by an earlier joint");
    if (j > 0) {
      if (J.parent < 0 || J.parent >= nb_ || !placed[at(J.parent)])
        throw InputError(key + ": parent must be a body attached by an earlier joint");
      if (J.axis_P.norm() < 1e-12 && J.type == JointType::Revolute)
        throw InputError(key + ": axis must be a non-zero vector");
    }
    placed[at(J.child)] = true;
    joints_.push_back(JointModel::from(J));
    lever_scale_ = std::max(lever_scale_, J.p_PoJ_P.norm() + J.p_CoJ_C.norm());
    if (j > 0) links.push_back(KktLink{J.parent, J.child, joints_.back().rows});
  }

  // Mass matrix blocks (paper Eqs. (1), (2)): diag(m I3, I_B).
  kkt_ = TreeKkt(nb_, links);
  for (int b = 0; b < nb_; ++b) {
    Matrix6d M = Matrix6d::Zero();
    M.topLeftCorner<3, 3>() = mass_[at(b)] * Matrix3d::Identity();
    M.bottomRightCorner<3, 3>() = I_B_[at(b)];
    if (!kkt_.set_mass(b, M))
      throw InputError(file + ": bodies[" + std::to_string(b) + "]: mass matrix not positive definite");
  }

  // Columns and labels.
  layout_ = OutputLayout(system);
  wrench0_ = static_cast<int>(layout_.size());
  for (int j = 1; j < nj_; ++j) {
    for (const char* s : {".fx", ".fy", ".fz"}) layout_.add_extra(system.joints[at(j)].name + s, "N");
    for (const char* s : {".mx", ".my", ".mz"})
      layout_.add_extra(system.joints[at(j)].name + s, "N m");
  }
  violation0_ = layout_.add_extra("constraint.pos", "m");
  layout_.add_extra("constraint.vel", "m/s");
  layout_.add_extra("constraint.ang", "rad");
  layout_.add_extra("constraint.angvel", "rad/s");
  labels_.resize(at(13 * nb_));
  for (int b = 0; b < nb_; ++b) {
    const std::string& n = system.bodies[at(b)].name;
    const char* p[7] = {".x", ".y", ".z", ".qw", ".qx", ".qy", ".qz"};
    const char* v[6] = {".vx", ".vy", ".vz", ".wx", ".wy", ".wz"};
    for (int i = 0; i < 7; ++i) labels_[at(pos(b) + i)] = n + p[i];
    for (int i = 0; i < 6; ++i) labels_[at(vel(b) + i)] = n + v[i];
  }

  // Workspace.
  bk_.resize(at(nb_));
  jk_.resize(at(nj_));
  cr_.resize(at(nj_));
  angle_.assign(at(nj_), 0.0);
  angle_ref_.assign(at(nj_), 0.0);
  f_.assign(at(nb_), Vector6d::Zero());
  nu_dot_.assign(at(nb_), Vector6d::Zero());
  gamma_.assign(links.size(), Vector6d::Zero());
  y_.assign(links.size(), Vector6d::Zero());
  for (int j = 0; j < nj_; ++j)
    if (system.joints[at(j)].type == JointType::Revolute)
      angle_ref_[at(j)] = angle_[at(j)] = system.joints[at(j)].angle0;
}

std::string NewtonEulerEngine::state_label(int i) const {
  if (i < 0 || i >= state_size()) return "state[" + std::to_string(i) + "]";
  return labels_[at(i)];
}

void NewtonEulerEngine::fail(double t, const std::string& quantity,
                             const std::string& reason) const {
  throw RunFailure(kEngineName, t, quantity, reason);
}

// ---- passes ----------------------------------------------------------------------------------

// x => body kinematics. The attitude is the normalised quaternion (its norm is a free, unused
// direction of the state; projection resets it).
void NewtonEulerEngine::body_pass(double t, const double* x) {
  for (int b = 0; b < nb_; ++b) {
    BodyKinematics& k = bk_[at(b)];
    const double* xp = x + pos(b);
    const double* xv = x + vel(b);
    const Quaterniond q(xp[3], xp[4], xp[5], xp[6]);
    const double n = q.norm();
    if (!(n > 1e-6) || !std::isfinite(n)) fail(t, labels_[at(pos(b) + 3)], "degenerate attitude quaternion");
    k.q_NB = Quaterniond(q.coeffs() / n);
    k.R_NB = k.q_NB.toRotationMatrix();
    k.p_NoBo_N = Vector3d(xp[0], xp[1], xp[2]);
    k.v_NBo_N = Vector3d(xv[0], xv[1], xv[2]);
    k.w_NB_B = Vector3d(xv[3], xv[4], xv[5]);
  }
}

// Body kinematics => relative joint kinematics, continuous revolute angles, constraint rows.
void NewtonEulerEngine::joint_pass() {
  for (int j = 1; j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    const BodyKinematics& P = bk_[at(m.parent)];
    const BodyKinematics& C = bk_[at(m.child)];
    joint_kinematics(m, P, C, jk_[at(j)]);
    if (m.type == JointType::Revolute)
      angle_[at(j)] = unwrap_angle(jk_[at(j)].angle_wrapped, angle_ref_[at(j)]);
    constraint_rows(m, P, C, jk_[at(j)], cr_[at(j)]);
  }
}

// t => applied forces and moments, and the gyroscopic term, per body (paper Eqs. (1), (2), (7)
// with the constraint terms moved to the solve): f_b = [F_ext_N; M_ext_B - w x I w].
// Joint loads follow core/system.hpp: on the child, the reaction on the parent, one N-frame torque
// vector for both so that internal loads never change the total angular momentum.
void NewtonEulerEngine::force_pass(double t) {
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematics& k = bk_[at(b)];
    const Body& body = system_.bodies[at(b)];
    Vector6d& f = f_[at(b)];
    f.head<3>().setZero();  // the model has no external forces (no gravity)
    f.tail<3>() = -k.w_NB_B.cross(I_B_[at(b)] * k.w_NB_B);
    if (!body.torque.empty()) {
      const Vector3d T = body.torque.value(t);
      if (body.torque_frame == Body::Frame::Body) f.tail<3>() += T;
      else f.tail<3>() += k.R_NB.transpose() * T;
    }
  }
  for (int j = 1; j < nj_; ++j) {
    const Joint& J = system_.joints[at(j)];
    const JointModel& m = joints_[at(j)];
    const JointKinematics& jk = jk_[at(j)];
    if (m.type == JointType::Revolute) {
      const double tau = -J.stiffness * (angle_[at(j)] - J.neutral_angle) - J.damping * jk.rate +
                         (J.motor_revolute.empty() ? 0.0 : J.motor_revolute.value(t)(0));
      if (tau == 0) continue;
      const Vector3d T_P = tau * m.a_P;  // on the child, in P
      f_[at(m.child)].tail<3>() += jk.R_PC.transpose() * T_P;
      f_[at(m.parent)].tail<3>() -= T_P;
    } else if (m.type == JointType::Spherical) {
      Vector3d tau_C = -J.damping * jk.w_PC_C;
      if (J.stiffness != 0)
        tau_C -= J.stiffness * rot::rotation_vector(m.q_PJ0.conjugate() * jk.q_PC);
      if (!J.motor_spherical.empty()) tau_C += J.motor_spherical.value(t);
      f_[at(m.child)].tail<3>() += tau_C;
      f_[at(m.parent)].tail<3>() -= jk.R_PC * tau_C;
    }
  }
}

// (M, J, f, gamma) => accelerations nu_dot and multipliers (y = -lambda), [Baraff96].
void NewtonEulerEngine::solve_pass(double t) {
  for (int j = 1; j < nj_; ++j) {
    const ConstraintRows& c = cr_[at(j)];
    const int k = j - 1;
    kkt_.J_parent(k) = c.J_P;
    kkt_.J_child(k) = c.J_C;
    gamma_[at(k)] = c.gamma;
    if (stabilization_ == Stabilization::Baumgarte)  // [Baum72]: g'' + alpha g' + beta g = 0
      gamma_[at(k)] -= alpha_ * c.gdot + beta_ * c.g;
  }
  if (!kkt_.factor()) fail(t, "constraints", "singular constraint system (KKT pivot not definite)");
  kkt_.solve(f_, gamma_, nu_dot_, y_);
  for (int b = 0; b < nb_; ++b)
    if (!nu_dot_[at(b)].allFinite()) {
      int i = 0;
      while (i < 5 && std::isfinite(nu_dot_[at(b)](i))) ++i;
      fail(t, labels_[at(vel(b) + i)], "non-finite acceleration");
    }
}

void NewtonEulerEngine::dynamics(double t, const double* x) {
  body_pass(t, x);
  joint_pass();
  force_pass(t);
  solve_pass(t);
}

// ---- Engine interface -------------------------------------------------------------------------

void NewtonEulerEngine::rhs(double t, const double* x, double* xdot) {
  dynamics(t, x);
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematics& k = bk_[at(b)];
    const double* xp = x + pos(b);
    double* dp = xdot + pos(b);
    double* dv = xdot + vel(b);
    dp[0] = k.v_NBo_N.x();
    dp[1] = k.v_NBo_N.y();
    dp[2] = k.v_NBo_N.z();
    // q' = 1/2 q (x) (0, w_B) with the stored (not renormalised) q: its norm is then an exact
    // invariant of the equations ([KLL83] Sec. 1.13).
    const Eigen::Vector4d qd =
        rot::quat_rate_body(Quaterniond(xp[3], xp[4], xp[5], xp[6]), k.w_NB_B);
    for (int i = 0; i < 4; ++i) dp[3 + i] = qd(i);
    for (int i = 0; i < 6; ++i) dv[i] = nu_dot_[at(b)](i);
  }
}

void NewtonEulerEngine::write_state(double* x) const {
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematics& k = bk_[at(b)];
    double* xp = x + pos(b);
    double* xv = x + vel(b);
    for (int i = 0; i < 3; ++i) {
      xp[i] = k.p_NoBo_N(i);
      xv[i] = k.v_NBo_N(i);
      xv[3 + i] = k.w_NB_B(i);
    }
    xp[3] = k.q_NB.w();
    xp[4] = k.q_NB.x();
    xp[5] = k.q_NB.y();
    xp[6] = k.q_NB.z();
  }
}

// Engine-neutral state => maximal coordinates, with this engine's own tree kinematics
// (core/system.hpp "Joint kinematics"): R_NC = R_NP R_PJ0 R_J, w_C = R_CP w_P + w_PC_C,
// p_C = p_P + R_NP r_P - R_NC r_C, v_C = v_P + R_NP (w_P x r_P) - R_NC (w_C x r_C) [KLL83 Sec. 2.7].
void NewtonEulerEngine::pack(const TreeState& s, double* x) {
  if (static_cast<int>(s.joints.size()) != nj_)
    throw InputError(where(system_) + ": TreeState has " + std::to_string(s.joints.size()) +
                     " joints, the scene " + std::to_string(nj_));
  const int base = joints_[0].child;
  BodyKinematics& B = bk_[at(base)];
  B.q_NB = s.q_NB.normalized();
  B.R_NB = B.q_NB.toRotationMatrix();
  B.p_NoBo_N = s.p_NoBo_N;
  B.v_NBo_N = s.v_NBo_N;
  B.w_NB_B = s.w_NB_B;
  for (int j = 1; j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    const TreeState::JointState& js = s.joints[at(j)];
    const BodyKinematics& P = bk_[at(m.parent)];
    BodyKinematics& C = bk_[at(m.child)];
    Quaterniond q_J = Quaterniond::Identity();
    Vector3d w_PC_C = Vector3d::Zero();
    if (m.type == JointType::Revolute) {
      q_J = Quaterniond(Eigen::AngleAxisd(js.angle, m.a_C));
      w_PC_C = js.rate * m.a_C;
      angle_ref_[at(j)] = js.angle;
    } else if (m.type == JointType::Spherical) {
      q_J = js.q_J.normalized();
      w_PC_C = js.w_PC_C;
    }
    C.q_NB = (P.q_NB * m.q_PJ0 * q_J).normalized();
    C.R_NB = C.q_NB.toRotationMatrix();
    const Matrix3d R_PC = P.R_NB.transpose() * C.R_NB;
    C.w_NB_B = R_PC.transpose() * P.w_NB_B + w_PC_C;
    C.p_NoBo_N = P.p_NoBo_N + P.R_NB * m.r_P - C.R_NB * m.r_C;
    C.v_NBo_N = P.v_NBo_N + P.R_NB * P.w_NB_B.cross(m.r_P) - C.R_NB * C.w_NB_B.cross(m.r_C);
  }
  if (system_.zero_linear_momentum) {
    Vector3d momentum = Vector3d::Zero();
    double total_mass = 0;
    for (int b = 0; b < nb_; ++b) {
      momentum += mass_[at(b)] * bk_[at(b)].v_NBo_N;
      total_mass += mass_[at(b)];
    }
    const Vector3d v_cm = momentum / total_mass;
    for (int b = 0; b < nb_; ++b) bk_[at(b)].v_NBo_N -= v_cm;
  }
  write_state(x);
  for (int j = 1; j < nj_; ++j) angle_[at(j)] = angle_ref_[at(j)];
}

// Mass-metric projection onto {g = 0} then {J nu = 0} [HLW06 Sec. IV.4]: the corrections solve
// [M J^T; J 0] [delta; y] = [0; -g] (Newton, a few iterations) and [0; -J nu] (once). They are
// internal impulses/displacements: total linear momentum and the CM position are unchanged, and
// so is the angular momentum once the joint points coincide.
bool NewtonEulerEngine::project(double t, double* x) {
  bool changed = false;
  for (int b = 0; b < nb_; ++b) {
    double* q = x + pos(b) + 3;
    const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (std::abs(n - 1) > kQuaternionNormTrigger) {
      for (int i = 0; i < 4; ++i) q[i] /= n;
      changed = true;
    }
  }
  if (nj_ < 2) return changed;
  double L = std::max(1.0, lever_scale_);
  for (int b = 0; b < nb_; ++b)
    L = std::max(L, std::abs(x[pos(b)]) + std::abs(x[pos(b) + 1]) + std::abs(x[pos(b) + 2]));
  auto max_violation = [this](bool velocity) {
    double v = 0;
    for (int j = 1; j < nj_; ++j)
      v = std::max(v, (velocity ? cr_[at(j)].gdot : cr_[at(j)].g).cwiseAbs().maxCoeff());
    return v;
  };
  body_pass(t, x);
  joint_pass();
  if (max_violation(false) > kProjectTrigger * L) {
    for (int iter = 0; iter < kNewtonMaxIterations; ++iter) {
      for (int j = 1; j < nj_; ++j) {
        kkt_.J_parent(j - 1) = cr_[at(j)].J_P;
        kkt_.J_child(j - 1) = cr_[at(j)].J_C;
        gamma_[at(j - 1)] = -cr_[at(j)].g;
      }
      for (int b = 0; b < nb_; ++b) f_[at(b)].setZero();
      if (!kkt_.factor()) fail(t, "constraints", "singular constraint system in projection");
      kkt_.solve(f_, gamma_, nu_dot_, y_);  // nu_dot_ holds the displacement delta
      for (int b = 0; b < nb_; ++b) {
        BodyKinematics& k = bk_[at(b)];
        k.p_NoBo_N += nu_dot_[at(b)].head<3>();
        // A small rotation in body axes, as w_NB_B dt: q <- q (x) exp(delta_B).
        k.q_NB = (k.q_NB * rot::from_rotation_vector(nu_dot_[at(b)].tail<3>())).normalized();
        k.R_NB = k.q_NB.toRotationMatrix();
      }
      joint_pass();
      changed = true;
      if (max_violation(false) <= kNewtonTarget * L) break;
    }
  }
  if (max_violation(true) > kProjectTrigger * L) {
    for (int j = 1; j < nj_; ++j) {
      kkt_.J_parent(j - 1) = cr_[at(j)].J_P;
      kkt_.J_child(j - 1) = cr_[at(j)].J_C;
      gamma_[at(j - 1)] = -cr_[at(j)].gdot;
    }
    for (int b = 0; b < nb_; ++b) f_[at(b)].setZero();
    if (!kkt_.factor()) fail(t, "constraints", "singular constraint system in projection");
    kkt_.solve(f_, gamma_, nu_dot_, y_);
    for (int b = 0; b < nb_; ++b) {
      bk_[at(b)].v_NBo_N += nu_dot_[at(b)].head<3>();
      bk_[at(b)].w_NB_B += nu_dot_[at(b)].tail<3>();
    }
    changed = true;
  }
  if (changed) write_state(x);
  return changed;
}

void NewtonEulerEngine::update_turn_counters(double t, const double* x) {
  body_pass(t, x);
  for (int j = 1; j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    if (m.type != JointType::Revolute) continue;
    const Matrix3d R_PC = bk_[at(m.parent)].R_NB.transpose() * bk_[at(m.child)].R_NB;
    angle_ref_[at(j)] = unwrap_angle(revolute_angle_wrapped(m, R_PC), angle_ref_[at(j)]);
  }
}

bool NewtonEulerEngine::after_step(double t, double* x) {
  const bool changed = stabilization_ == Stabilization::Projection && project(t, x);
  update_turn_counters(t, x);
  return changed;
}

void NewtonEulerEngine::accelerations(double t, const double* x, TreeAccel& a) {
  dynamics(t, x);
  a.wdot_NB_B.assign(at(nb_), Vector3d::Zero());
  a.a_NBo_N.assign(at(nb_), Vector3d::Zero());
  a.angle_ddot.assign(at(nj_), 0.0);
  a.wdot_PC_C.assign(at(nj_), Vector3d::Zero());
  for (int b = 0; b < nb_; ++b) {
    a.a_NBo_N[at(b)] = nu_dot_[at(b)].head<3>();
    a.wdot_NB_B[at(b)] = nu_dot_[at(b)].tail<3>();
  }
  for (int j = 1; j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    const JointKinematics& jk = jk_[at(j)];
    const Vector3d& w_P = bk_[at(m.parent)].w_NB_B;
    const Vector3d& w_C = bk_[at(m.child)].w_NB_B;
    const Vector3d alpha_P = nu_dot_[at(m.parent)].tail<3>();
    const Vector3d alpha_C = nu_dot_[at(m.child)].tail<3>();
    if (m.type == JointType::Revolute) {
      // angle'' = a_P . d/dt(w_PC_P) (P-frame derivative; d/dt R_PC = R_PC [w_PC_C x]).
      a.angle_ddot[at(j)] =
          m.a_P.dot(jk.R_PC * alpha_C - alpha_P + jk.R_PC * jk.w_PC_C.cross(w_C));
    } else if (m.type == JointType::Spherical) {
      // C-frame derivative of w_PC_C = w_C - R_CP w_P, with d/dt R_CP = -[w_PC_C x] R_CP.
      const Vector3d w_P_C = jk.R_PC.transpose() * w_P;
      a.wdot_PC_C[at(j)] = alpha_C - jk.R_PC.transpose() * alpha_P + jk.w_PC_C.cross(w_P_C);
    }
  }
}

// |sum_b m_b (p_b - p_cm) x (v_b - v_cm) + R_NB I_b w_b|, about the system CM [KLL83 Sec. 4.5].
double NewtonEulerEngine::angular_momentum() const {
  Vector3d p_cm = Vector3d::Zero(), v_cm = Vector3d::Zero();
  double total = 0;
  for (int b = 0; b < nb_; ++b) {
    p_cm += mass_[at(b)] * bk_[at(b)].p_NoBo_N;
    v_cm += mass_[at(b)] * bk_[at(b)].v_NBo_N;
    total += mass_[at(b)];
  }
  p_cm /= total;
  v_cm /= total;
  Vector3d h = Vector3d::Zero();
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematics& k = bk_[at(b)];
    h += mass_[at(b)] * (k.p_NoBo_N - p_cm).cross(k.v_NBo_N - v_cm) +
         k.R_NB * (I_B_[at(b)] * k.w_NB_B);
  }
  return h.norm();
}

// Kinetic energy of every body plus the joint springs' potential (core/system.hpp).
double NewtonEulerEngine::energy() const {
  double e = 0;
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematics& k = bk_[at(b)];
    e += 0.5 * mass_[at(b)] * k.v_NBo_N.squaredNorm() + 0.5 * k.w_NB_B.dot(I_B_[at(b)] * k.w_NB_B);
  }
  for (int j = 1; j < nj_; ++j) {
    const Joint& J = system_.joints[at(j)];
    if (J.stiffness == 0) continue;
    if (J.type == JointType::Revolute) {
      const double d = angle_[at(j)] - J.neutral_angle;
      e += 0.5 * J.stiffness * d * d;
    } else if (J.type == JointType::Spherical) {
      const Vector3d phi = rot::rotation_vector(joints_[at(j)].q_PJ0.conjugate() * jk_[at(j)].q_PC);
      e += 0.5 * J.stiffness * phi.squaredNorm();
    }
  }
  return e;
}

void NewtonEulerEngine::output_row(double t, const double* x, double* row) {
  dynamics(t, x);  // the constraint forces need the accelerations
  RowWriter out(layout_, row);
  out.time(t);
  for (int b = 0; b < nb_; ++b) out.body(b, bk_[at(b)].w_NB_B, bk_[at(b)].q_NB);
  for (int j = 1; j < nj_; ++j) {
    const JointType type = joints_[at(j)].type;
    if (type == JointType::Revolute) out.revolute(j, angle_[at(j)], jk_[at(j)].rate);
    if (type == JointType::Spherical) out.spherical(j, jk_[at(j)].w_PC_C);
  }
  out.momentum(angular_momentum());
  out.energy(energy());
  int c = wrench0_;
  // Constraint wrench on the child, J_C^T lambda = [F_N; M_Co_C], lambda = -y; moved to the joint
  // point and expressed in P.
  double pos_violation = 0, vel_violation = 0, ang_violation = 0, angvel_violation = 0;
  for (int j = 1; j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    const JointKinematics& jk = jk_[at(j)];
    const ConstraintRows& cr = cr_[at(j)];
    const Vector6d wrench = -(cr.J_C.transpose() * y_[at(j - 1)]);
    const Matrix3d& R_NC = bk_[at(m.child)].R_NB;
    const Vector3d F_N = wrench.head<3>();
    const Vector3d M_J_C = wrench.tail<3>() - m.r_C.cross(R_NC.transpose() * F_N);
    const Vector3d F_P = bk_[at(m.parent)].R_NB.transpose() * F_N;
    const Vector3d M_P = jk.R_PC * M_J_C;
    for (int i = 0; i < 3; ++i) out.extra(c + i, F_P(i));
    for (int i = 0; i < 3; ++i) out.extra(c + 3 + i, M_P(i));
    c += 6;
    pos_violation = std::max(pos_violation, cr.g.head<3>().norm());
    vel_violation = std::max(vel_violation, cr.gdot.head<3>().norm());
    if (m.type == JointType::Revolute) {
      const Vector3d u = jk.R_PC * m.a_C;
      ang_violation = std::max(ang_violation, std::atan2(m.a_P.cross(u).norm(), m.a_P.dot(u)));
      angvel_violation =
          std::max(angvel_violation, (jk.w_PC_P - m.a_P.dot(jk.w_PC_P) * m.a_P).norm());
    } else if (m.type == JointType::Fixed) {
      ang_violation = std::max(ang_violation, rot::angle_between(m.q_PJ0, jk.q_PC));
      angvel_violation = std::max(angvel_violation, jk.w_PC_C.norm());
    }
  }
  out.extra(violation0_, pos_violation);
  out.extra(violation0_ + 1, vel_violation);
  out.extra(violation0_ + 2, ang_violation);
  out.extra(violation0_ + 3, angvel_violation);
}

}  // namespace
}  // namespace newton_euler

std::unique_ptr<Engine> make_newton_euler_engine(const System& system, const EngineOptions& options) {
  return std::make_unique<newton_euler::NewtonEulerEngine>(system, options);
}

}  // namespace crossdyn
