// The Newton-Euler engine (see newton_euler.hpp for the state layout, equations and outputs).
//
// Bibliography
//   [Paper]    Cochran, No & Fitz-Coy (1990), "Simulation of spacecraft attitude dynamics using
//              TREETOPS and model-specific computer codes" (full citation: docs/references.md).
//   [KLL83]    Kane, Likins & Levinson (1983), "Spacecraft Dynamics", McGraw-Hill.
//   [Baraff96] Baraff (1996), "Linear-time dynamics using Lagrange multipliers", SIGGRAPH 96.
//   [Baum72]   Baumgarte (1972), "Stabilization of constraints and integrals of motion in
//              dynamical systems", Comput. Methods Appl. Mech. Eng. 1, 1-16.
//   [HLW06]    Hairer, Lubich & Wanner (2006), "Geometric Numerical Integration", 2nd ed., IV.4.
//   [Shuster93] Shuster (1993), "A survey of attitude representations", J. Astronaut. Sci. 41(4).
//   [Shabana05] Shabana (2005), "Dynamics of Multibody Systems", 3rd ed., Cambridge, Ch. 5.
//   [Barfoot17] Barfoot (2017), "State Estimation for Robotics", Cambridge, Sec. 7.1.5.
//   [Feath08]  Featherstone (2008), "Rigid Body Dynamics Algorithms", Springer, Sec. 2.8 (the
//              transform of a force and a moment to another point and frame, Eq. 2.26 in its
//              3-vector form: M_Q = M_P + (p_P - p_Q) x F).
//   [Haug89]   Haug (1989), "Computer Aided Kinematics and Dynamics of Mechanical Systems",
//              Sec. 6.3 (Lagrange multipliers as the reaction forces of the constraints).
#include "formulations/newton_euler/newton_euler.hpp"

#include "core/errors.hpp"
#include "core/orbit.hpp"
#include "core/scene/topology.hpp"
#include "core/rotation.hpp"
#include "formulations/newton_euler/cx_row_writer.hpp"
#include "formulations/newton_euler/joint_constraints.hpp"
#include "formulations/newton_euler/joints/joint_unit.hpp"
#include "formulations/newton_euler/modal_body.hpp"
#include "formulations/newton_euler/scalar.hpp"
#include "formulations/newton_euler/tree_kkt.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <complex>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

namespace crossdyn {
namespace newton_euler {
namespace {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;
using Eigen::VectorXd;

constexpr const char* kEngineName = "newton-euler";

// Projection thresholds, per metre of the model's length scale L (the largest of 1 m, the joint
// lever arms |r_P| + |r_C| and the body origins' distances from the origin: round-off in g is
// ~1e-16 L). A state whose violation is below kProjectTrigger L is left alone (so that
// after_step() does not restart the integrator for round-off); Newton iterations stop at
// kNewtonTarget L or after kNewtonMaxIterations (each iteration squares the relative error, so one
// or two reach round-off from any violation an accepted step can produce).
constexpr double kProjectTrigger = 1e-12;      // m (and rad, m/s, rad/s) per metre of L
constexpr double kNewtonTarget = 1e-14;        // m per metre of L
constexpr int kNewtonMaxIterations = 4;
constexpr double kQuaternionNormTrigger = 1e-12;
// A flexible body's mass and rigid inertia must equal its node sums (core/system.hpp) to this
// relative tolerance: two different values would make engines disagree silently.
constexpr double kNodeSumRelTol = 1e-9;

enum class Stabilization { None, Baumgarte, Projection };

std::size_t at(int i) { return static_cast<std::size_t>(i); }

std::string where(const System& system) {
  return system.file.empty() ? std::string("scene '") + system.name + "'" : system.file;
}

// ---- the rigid body's equations on a scalar S (issue 27) ---------------------------------------
// The pieces of the right-hand side that the exact tangent (accelerations_tangent(), below) runs
// on S = std::complex<double> as well as on double (the run's path): written once, as templates
// instantiated in this file only. On the complex instantiation nothing may take |.| or conjugate
// (the complex step, Martins, Sturdza & Alonso 2003, ACM TOMS 29(3), needs every operation
// analytic): norms are square roots of sums of squares, dot and cross products are written out
// (Eigen's conjugate a complex argument or result), and
// branches read the real part. On double these helpers are the calls the engine always made
// (bit-for-bit the same arithmetic).
template <class S> using V3 = Vec3<S>;
template <class S> using M3 = Mat3<S>;

// A rigid body's moment row before the environment's loads (force_pass, [Paper] Eqs. (1), (2)):
// -w x I w plus its external torque (body frame, or N components turned into B).
template <class S>
V3<S> rigid_moment(const Body& body, const Matrix3d& I_B, double t, const M3<S>& R_NB,
                   const V3<S>& w_NB_B) {
  V3<S> M = -tcross<S>(w_NB_B, V3<S>(I_B * w_NB_B));
  if (!body.torque.empty()) {
    const Vector3d T = body.torque.value(t);
    if (body.torque_frame == Body::Frame::Body) M += T;
    else M += R_NB.transpose() * T;
  }
  return M;
}

// The environment's load on a rigid body (gravity_on_body(): equations there): the force in N
// components and the moment about its CM in B components. n2, zhat_N: the orbit's field at t.
template <class S>
void rigid_gravity(const Environment& env, double m, const Matrix3d& I_B, const Vector3d& p_NoO_N,
                   double n2, const Vector3d& zhat_N, const M3<S>& R_NB, const V3<S>& p_NoBo_N,
                   V3<S>& F_grav_N, V3<S>& M_grav_B) {
  if (env.uniform()) {
    F_grav_N = (m * env.g_N).template cast<S>();
    M_grav_B.setZero();
    return;
  }
  const V3<S> d_N = p_NoBo_N - p_NoO_N;
  const V3<S> z_B = R_NB.transpose() * zhat_N;
  const V3<S> Td_N = n2 * (3.0 * tdot<S>(zhat_N, d_N) * zhat_N - d_N);  // T d
  F_grav_N = m * Td_N;
  M_grav_B = 3.0 * n2 * tcross<S>(z_B, V3<S>(I_B * z_B));  // tau_gg_B
}

// pack(): a child body placed from its parent, the joint's node frames F, G and the joint's
// coordinates (q_J, w_FG_G, and r_F, v_F along a translation; the equations at pack()).
template <class S>
void place_child(const JointModel& m, const BodyKinematicsT<S>& P, const NodeFrameT<S>& F,
                 const NodeFrameT<S>& G, const Quat<S>& q_J, const V3<S>& w_FG_G, const V3<S>& r_F,
                 const V3<S>& v_F, BodyKinematicsT<S>& C) {
  S norm;
  const Quat<S> q_NF = P.q_NB * F.q_E;
  C.q_NB = unit_quaternion(Quat<S>(q_NF * m.q_PJ0.template cast<S>() * q_J * G.q_E.conjugate()), norm);
  C.R_NB = C.q_NB.toRotationMatrix();
  const M3<S> R_NF = P.R_NB * F.E;
  const M3<S> R_FG = R_NF.transpose() * C.R_NB * G.E;
  const V3<S> w_F = F.E.transpose() * (P.w_NB_B + F.w_rel_B);
  const V3<S> w_G = R_FG.transpose() * w_F + w_FG_G;
  C.w_NB_B = G.E * w_G - G.w_rel_B;
  const V3<S> s_F = F.s_B + r_F;
  C.p_NoBo_N = P.p_NoBo_N + P.R_NB * s_F - C.R_NB * G.s_B;
  C.v_NBo_N = P.v_NBo_N + P.R_NB * (tcross<S>(P.w_NB_B, s_F) + F.sdot_B + v_F) -
              C.R_NB * (tcross<S>(C.w_NB_B, G.s_B) + G.sdot_B);
}

// What the output columns read at one state, on S (output_row(): the run's workspace after
// dynamics(); output_row_tangent(): the complex step's passes, CxPass below): the bodies, each
// flexible body's modal terms, the joints' kinematics, rows and coordinates, the multipliers
// y = -lambda per KKT link and of a prescribed base's root rows, and the environment's load per body.
template <class S>
struct OutputState {
  const std::vector<BodyKinematicsT<S>>& bk;
  const std::vector<ModalTermsT<S>>& terms;
  const std::vector<JointKinematicsT<S>>& jk;
  const std::vector<ConstraintRowsT<S>>& cr;
  const std::vector<JointCoordsT<S>>& coords;
  const std::vector<Vec6<S>>& y;
  const Vec6<S>& y_root;
  const std::vector<V3<S>>& F_grav_N;
  const std::vector<V3<S>>& M_grav_B;
};

class NewtonEulerEngine final : public Engine {
 public:
  NewtonEulerEngine(const System& system, const EngineOptions& options);

  const char* name() const override { return kEngineName; }
  int state_size() const override { return nx_; }
  std::string state_label(int i) const override;
  void pack(const TreeState& s, double* x) override;
  void rhs(double t, const double* x, double* xdot) override;
  bool after_step(double t, double* x) override;
  bool projects() const override { return stabilization_ == Stabilization::Projection; }
  // Inside CVODE's BDF steps (core/integrate_cvode.cpp): projected to kNewtonTarget at every step,
  // not only above kProjectTrigger. A correction made only now and then is a jump in the
  // multistep history: at rtol 1e-12 on chain5 the error test then failed down to the minimum step.
  void project_state(double t, double* x) override {
    if (projects()) project(t, x, kNewtonTarget);
  }
  void accelerations(double t, const double* x, TreeAccel& a) override;
  const OutputLayout& layout() const override { return layout_; }
  void output_row(double t, const double* x, double* row) override;
  LinearSystem linear_system(double t, const double* x) override;
  bool accelerations_tangent(double t, const TreeState& s, const TreeTangent& ds, TreeAccel& a,
                             TreeAccel& da) override;
  bool output_row_tangent(double t, const TreeState& s, const TreeTangent& ds, double* row,
                          double* drow) override;
  bool rhs_tangent(double t, const double* x, const double* dx, double* xdot, double* dxdot) override;

 private:
  // State layout (newton_euler.hpp): body b's positions at pos(b), its velocities at vel(b); the
  // velocities are stacked in the order of the KKT unknowns (nu(b) = vel(b) - vel(0)).
  int pos(int b) const { return pos_[at(b)]; }
  int vel(int b) const { return vel_[at(b)]; }
  int nu(int b) const { return vel_[at(b)] - vel_[0]; }
  int modes(int b) const { return modes_[at(b)]; }

  // Named passes (see newton_euler.hpp).
  void body_pass(double t, const double* x);
  void mass_pass(double t);
  void joint_pass(double t);
  // The joints whose constraint rows exist: 1.. (a free base), 0.. (a prescribed base: joint 0's
  // rows are the base's root rows, TreeKkt).
  int first_joint() const { return prescribed_base_ ? 0 : 1; }
  const BodyKinematics& parent_kinematics(int j) const {
    const int p = joints_[at(j)].parent;
    return p < 0 ? ground_ : bk_[at(p)];
  }
  // A prescribed joint's torque about its axis on the child (its row 5's multiplier).
  template <class S> S torque(const OutputState<S>& st, int j) const;
  void force_pass(double t);
  // The environment's loads on body b (issue 28; core/system.hpp "Environment"): added to f_ and
  // kept in F_grav_N_, M_grav_B_ (force_pass(); equations at gravity_on_body()).
  struct GravityField {
    double n2 = 0;                                   // n^2 (orbit), 1/s^2
    Vector3d zhat_N = Vector3d::Zero();              // unit, central body to O (orbit)
  };
  GravityField gravity_field(double t) const;
  void gravity_on_body(int b, const GravityField& gf);
  // gravity_on_body()'s flexible branch on S (the run's, and the tangents' complex step): the
  // force and moment returned, the modal generalised forces added to f.
  template <class S>
  void flexible_gravity(int b, const GravityField& gf, const BodyKinematicsT<S>& k, ModalTermsT<S>& mt,
                        Eigen::Matrix<S, Eigen::Dynamic, 1>& f, V3<S>& F_grav_N, V3<S>& M_grav_B) const;
  template <class S> S gravity_potential(double t, const OutputState<S>& st) const;  // V of every mass
  void load_kkt();  // J and gamma_s into kkt_ (M is set by mass_pass)
  void solve_pass(double t);
  // (t, x) => the KKT system in kkt_ and f_: the passes up to the solve (dynamics(),
  // linear_system()).
  void assemble(double t, const double* x);
  void dynamics(double t, const double* x);

  void validate_flex(const std::string& file, int b, const Body& body, const EngineOptions& o);
  void write_state(double* x) const;  // bk_ => x (positions, attitudes, modes, velocities)
  void torque_on_frame(int b, const Vector3d& T_B, const Eigen::Matrix3Xd& JlPsi);
  Vector3d frame_angular_acceleration(const JointSide& side, const NodeFrame& fr, int b) const;
  bool project(double t, double* x, double trigger = kProjectTrigger);
  void update_turn_counters(double t, const double* x);
  double total_mass() const;
  Vector3d first_moment() const;     // sum over elements of m x (from bk_)
  Vector3d linear_momentum() const;  // sum over elements of m v (from bk_)
  void shift_all(const Vector3d& dp, const Vector3d& dv);
  // The output quantities on S (newton_euler.hpp "Outputs"), from an OutputState: the run's
  // (run_state(), valid after dynamics(); terms_ after mass_pass) or the complex step's.
  OutputState<double> run_state() const {
    return {bk_, terms_, jk_, cr_, coords_, y_, kkt_.y_root(), F_grav_N_, M_grav_B_};
  }
  Vector3d system_cm() const { return system_cm(run_state()); }
  template <class S> V3<S> system_cm(const OutputState<S>& st) const;  // p_NoScm_N (deformed bodies)
  template <class S> V3<S> angular_momentum(const OutputState<S>& st, const V3<S>& p_NoScm_N) const;
  template <class S> V3<S> linear_momentum(const OutputState<S>& st) const;
  template <class S> S energy(const OutputState<S>& st) const;
  // Joint j's load on its child (constraint + its spring, damper, motor), child frame, about the
  // joint point (newton_euler.hpp "Joint loads").
  template <class S>
  void joint_load(int j, double t, const OutputState<S>& st, V3<S>& F_C, V3<S>& M_J_C) const;
  // Every pinned column but the engine's extras, through out (RowWriter on double, CxRowWriter on
  // Cx): output_row()'s equations, written once.
  template <class S, class W> void write_outputs(double t, const OutputState<S>& st, W& out) const;

  // ---- the passes on Cx (issue 27; the complex step of the tangents, below) ----
  struct CxPass {
    std::vector<BodyKinematicsT<Cx>> bk;
    BodyKinematicsT<Cx> ground;  // N: identity attitude, at rest (ground_)
    std::vector<ModalTermsT<Cx>> terms;
    std::vector<JointKinematicsT<Cx>> jk;
    std::vector<ConstraintRowsT<Cx>> cr;
    std::vector<JointCoordsT<Cx>> coords;
    std::vector<V3<Cx>> F_grav_N, M_grav_B;
    Eigen::VectorXcd nu_dot;      // nu' (KKT order)
    std::vector<Vec6<Cx>> y;      // y = -lambda per link
    Vec6<Cx> y_root = Vec6<Cx>::Zero();
    OutputState<Cx> view() const { return {bk, terms, jk, cr, coords, y, y_root, F_grav_N, M_grav_B}; }
  };
  CxPass cx_pass() const;  // sized for this system
  // pack() on Cx: s + i h ds placed into w.bk (the attitudes normalised, zero_linear_momentum's shift).
  void pack_cx(double t, const TreeState& s, const TreeTangent& ds, double h, CxPass& w) const;
  // body_pass() on Cx: x (nx_ complex numbers) into w.bk.
  void body_pass_cx(double t, const Cx* x, CxPass& w) const;
  // mass_pass, joint_pass, force_pass, load_kkt and solve_pass on Cx, from w.bk: the real parts
  // solved by the engine's factorisation, then the imaginary parts (K_r z_i = b_i - K_i z_r).
  void dynamics_cx(double t, CxPass& w);
  [[noreturn]] void fail(double t, const std::string& quantity, const std::string& reason) const;

  // ---- model (constant after construction) ----
  System system_;
  Stabilization stabilization_ = Stabilization::Projection;
  double alpha_ = 0, beta_ = 0;
  int nb_ = 0, nj_ = 0, nx_ = 0, nv_ = 0;
  std::vector<int> modes_, pos_, vel_;
  std::vector<double> mass_;
  std::vector<Matrix3d> I_B_;            // rigid: inertia about the CM in body axes (scaled for tests)
  std::vector<int> flex_;                // body => index into inv_ / terms_, or -1 (rigid)
  std::vector<ModalInvariants> inv_;     // per flexible body
  std::vector<JointModel> joints_;       // per System joint
  double lever_scale_ = 0;               // m, largest |r_P| + |r_C| over the joints
  // The base is a prescribed revolute joint to N (System::base_is_free() false). Choice: the base
  // body keeps its 13 (+ modal) numbers in the state and its motion is the rheonomic constraint
  // of joint 0 to N (joint_constraints.hpp, "prescribed revolute", with N as a rigid parent that
  // does not move: ground_), solved in the KKT system as root rows (tree_kkt.hpp) and stabilised
  // like every other joint. So the constraint moment about the axis (the torque) comes out of the
  // same solve as every other multiplier, and a flexible base keeps its modal coordinates.
  bool prescribed_base_ = false;
  BodyKinematics ground_;                // N: identity attitude, at rest
  // The environment (System::environment): its kind (Kind::None: nothing computed), the uniform
  // field g_N, and on an orbit the reference point O, the system's CM in the initial state
  // (computed once, by the constructor, from TreeState::initial: a point fixed in N).
  Environment env_;
  Vector3d p_NoO_N_ = Vector3d::Zero();
  OutputLayout layout_;          // pinned columns, then the constraint violations
  int violation0_ = 0;           // the first extra column
  std::vector<std::string> labels_;
  // accelerations_tangent() covers this system (decided by the constructor): joints covered by
  // their unit's Cx verbs (every body, base, load and environment is covered).
  bool tangent_covered_ = false;

  // ---- workspace (mutable, preallocated) ----
  std::vector<BodyKinematics> bk_;
  std::vector<ModalTerms> terms_;        // per flexible body
  std::vector<JointKinematics> jk_;
  std::vector<ConstraintRows> cr_;       // per System joint (index 0, the free joint, unused)
  std::vector<JointCoords> coords_;      // each joint's coordinates (continuous angles, a
                                         // prismatic position) at the current state
  std::vector<JointCoords> coords_ref_;  // the continuous angles after the last step/pack
  // pack() resets the joints' continuous-angle references: a pack() that is not the run's (the
  // tangents', the orbit's set-up) keeps one of these, which puts the run's back on the way out.
  struct CoordsGuard {
    NewtonEulerEngine& e;
    std::vector<JointCoords> coords, coords_ref;
    explicit CoordsGuard(NewtonEulerEngine& engine)
        : e(engine), coords(engine.coords_), coords_ref(engine.coords_ref_) {}
    CoordsGuard(const CoordsGuard&) = delete;
    CoordsGuard& operator=(const CoordsGuard&) = delete;
    ~CoordsGuard() {
      e.coords_ = coords;
      e.coords_ref_ = coords_ref;
    }
  };
  VectorXd f_, nu_dot_;                  // stacked per body (KKT order)
  std::vector<Vector6d> gamma_, y_;      // per KKT link (joint j is link j - 1)
  TreeKkt kkt_;
  // Per body, the environment's load at the last force_pass: the force F_grav_N (N components,
  // the resultant, through Bo for a rigid body) and the moment about Bo in B components, M_grav_B
  // (for the external moment column Mx My Mz).
  std::vector<Vector3d> F_grav_N_, M_grav_B_;
};

NewtonEulerEngine::NewtonEulerEngine(const System& system, const EngineOptions& options)
    : system_(system) {
  const std::string file = where(system);
  switch (options.stabilization.value()) {  // named in core/names.hpp, parsed where it entered
    case ConstraintStabilization::Projection: stabilization_ = Stabilization::Projection; break;
    case ConstraintStabilization::Baumgarte: stabilization_ = Stabilization::Baumgarte; break;
    case ConstraintStabilization::None: stabilization_ = Stabilization::None; break;
  }
  if (!std::isfinite(options.baumgarte_alpha) || options.baumgarte_alpha < 0 ||
      !std::isfinite(options.baumgarte_beta) || options.baumgarte_beta < 0)
    throw InputError("engine options baumgarte_alpha, baumgarte_beta: must be finite and >= 0 (got " +
                     std::to_string(options.baumgarte_alpha) + ", " +
                     std::to_string(options.baumgarte_beta) + ")");
  if (!std::isfinite(options.test_inertia_scale) || options.test_inertia_scale <= 0)
    throw InputError("engine option test_inertia_scale: must be finite and > 0 (got " +
                     std::to_string(options.test_inertia_scale) + ")");
  if (!std::isfinite(options.test_damper_scale))
    throw InputError("engine option test_damper_scale: must be finite (got " +
                     std::to_string(options.test_damper_scale) + ")");
  alpha_ = options.baumgarte_alpha;
  beta_ = options.baumgarte_beta;

  nb_ = static_cast<int>(system.bodies.size());
  nj_ = static_cast<int>(system.joints.size());
  // The tree (one free joint first, every parent the child of an earlier joint, one joint per
  // body, indices in range): the one public check, core/scene/topology.hpp.
  check_topology(system);
  flex_.assign(at(nb_), -1);
  for (int b = 0; b < nb_; ++b) {
    const Body& body = system.bodies[at(b)];
    const std::string key = file + ": bodies[" + std::to_string(b) + "] '" + body.name + "'";
    if (!(body.mass > 0) || !std::isfinite(body.mass))
      throw InputError(key + ": mass must be finite and > 0");
    const Matrix3d I = options.test_inertia_scale * body.I_BBo_B;
    if (!I.allFinite() || (I - I.transpose()).cwiseAbs().maxCoeff() > 1e-12 * I.cwiseAbs().maxCoeff() ||
        Eigen::LLT<Matrix3d>(I).info() != Eigen::Success)
      throw InputError(key + ": inertia must be symmetric positive definite");
    mass_.push_back(body.mass);
    I_B_.push_back(I);
    modes_.push_back(body.flex ? body.flex->modes() : 0);
    if (body.flex) {
      validate_flex(file, b, body, options);
      mass_.back() = inv_.back().m;  // the node sum (equal to body.mass to 1e-9)
    }
  }
  // State layout: positions (7 + n_b per body), then velocities (6 + n_b per body).
  for (int b = 0; b < nb_; ++b) {
    pos_.push_back(nx_);
    nx_ += 7 + modes(b);
  }
  for (int b = 0; b < nb_; ++b) {
    vel_.push_back(nx_);
    nx_ += 6 + modes(b);
    nv_ += 6 + modes(b);
  }

  // Joints: joints[0] free (the base), the rest in topological order.
  std::vector<KktLink> links;
  for (int j = 0; j < nj_; ++j) {
    const Joint& J = system.joints[at(j)];
    const std::string key = file + ": joints[" + std::to_string(j) + "] '" + J.name + "'";
    if (const JointUnit& unit = joint_unit(J.type); unit.validate) unit.validate(J, key);
    // Node attachments: only on flexible bodies, to an existing node.
    for (const auto& [node, body, what] :
         {std::tuple{J.parent_node, J.parent, "parent_node"}, std::tuple{J.child_node, J.child, "child_node"}}) {
      if (node < 0) continue;
      const Body* B = body >= 0 && body < nb_ ? &system.bodies[at(body)] : nullptr;
      if (!B || !B->flex)
        throw InputError(key + ": " + what + " is set but body " +
                         (B ? "'" + B->name + "'" : std::string("(none)")) + " is not flexible");
      if (node >= static_cast<int>(B->flex->nodes.size()))
        throw InputError(key + ": " + what + " " + std::to_string(node) + " is not a node of '" +
                         B->name + "' (" + std::to_string(B->flex->nodes.size()) + " nodes)");
    }
    joints_.push_back(JointModel::from(system, j));
    // EngineOptions::test_damper_scale: the dampers of the equations of motion (the unit's load
    // verb reads JointModel::damping, damping2); the scene's stay in system_ for P. Skipped at 1,
    // so that a real run's arithmetic is the scene's, unchanged.
    if (options.test_damper_scale != 1.0) {
      joints_.back().damping *= options.test_damper_scale;
      joints_.back().damping2 *= options.test_damper_scale;
    }
    lever_scale_ = std::max(lever_scale_, J.p_PoJ_P.norm() + J.p_CoJ_C.norm());
    if (j > 0) links.push_back(KktLink{J.parent, J.child, joints_.back().rows});
  }

  // Mass matrix blocks. Rigid (paper Eqs. (1), (2)): diag(m I3, I_B), constant, set once here.
  // Flexible: modal_body.hpp, set per state by mass_pass().
  std::vector<int> dofs;
  for (int b = 0; b < nb_; ++b) dofs.push_back(6 + modes(b));
  prescribed_base_ = !system.base_is_free();
  kkt_ = TreeKkt(dofs, links, prescribed_base_ ? joints_[0].rows : 0);
  for (int b = 0; b < nb_; ++b) {
    if (flex_[at(b)] >= 0) {
      terms_.emplace_back(modes(b));
      continue;
    }
    Matrix6d M = Matrix6d::Zero();
    M.topLeftCorner<3, 3>() = mass_[at(b)] * Matrix3d::Identity();
    M.bottomRightCorner<3, 3>() = I_B_[at(b)];
    if (!kkt_.set_mass(b, M))
      throw InputError(file + ": bodies[" + std::to_string(b) + "]: mass matrix not positive definite");
  }

  // Columns and labels. (The joints' constraint wrenches, once extras <joint>.fx .. .mz, are the
  // pinned total loads <joint>.Fx .. .Mz now: issue 26.)
  layout_ = OutputLayout(system);
  violation0_ = layout_.add_extra("constraint.pos", "m");
  layout_.add_extra("constraint.vel", "m/s");
  layout_.add_extra("constraint.ang", "rad");
  layout_.add_extra("constraint.angvel", "rad/s");
  labels_.resize(at(nx_));
  for (int b = 0; b < nb_; ++b) {
    const Body& body = system.bodies[at(b)];
    const std::string& n = body.name;
    const char* p[7] = {".x", ".y", ".z", ".qw", ".qx", ".qy", ".qz"};
    const char* v[6] = {".vx", ".vy", ".vz", ".wx", ".wy", ".wz"};
    for (int i = 0; i < 7; ++i) labels_[at(pos(b) + i)] = n + p[i];
    for (int i = 0; i < 6; ++i) labels_[at(vel(b) + i)] = n + v[i];
    for (int k = 0; k < modes(b); ++k) {
      labels_[at(pos(b) + 7 + k)] = n + "." + body.flex->mode_names[at(k)];
      labels_[at(vel(b) + 6 + k)] = n + "." + body.flex->mode_names[at(k)] + "_rate";
    }
  }

  // Workspace.
  bk_.resize(at(nb_));
  for (int b = 0; b < nb_; ++b) {
    bk_[at(b)].eta = VectorXd::Zero(modes(b));
    bk_[at(b)].eta_dot = VectorXd::Zero(modes(b));
  }
  for (const JointModel& m : joints_) {
    jk_.emplace_back(m);
    cr_.emplace_back(m);
  }
  coords_.assign(at(nj_), JointCoords::Zero());
  coords_ref_.assign(at(nj_), JointCoords::Zero());
  f_ = VectorXd::Zero(nv_);
  nu_dot_ = VectorXd::Zero(nv_);
  gamma_.assign(links.size(), Vector6d::Zero());
  y_.assign(links.size(), Vector6d::Zero());
  for (int j = 0; j < nj_; ++j)
    if (joints_[at(j)].has_angle)
      coords_ref_[at(j)] = coords_[at(j)] =
          JointCoords(system.joints[at(j)].angle0, system.joints[at(j)].angle2_0);

  // accelerations_tangent(): every joint's unit has verbs on Cx that cover it
  // (joints/joint_unit.hpp, JointVerbsCx::covers); bodies, bases and loads are all covered.
  tangent_covered_ = true;
  for (int j = first_joint(); j < nj_; ++j) {
    const JointUnit& u = *joints_[at(j)].unit;
    tangent_covered_ = tangent_covered_ && u.cx && u.cx->covers(system.joints[at(j)]);
  }

  // The environment. On an orbit, O = the system's CM at t = 0 (core/system.hpp "Environment"),
  // from this engine's own placement of the scene's initial state (pack(): the tree kinematics;
  // system_cm(): the deformed CM of every body), once; the workspace's joint coordinates are
  // restored afterwards (pack() sets them; the run's own pack() will again).
  env_ = system.environment;
  F_grav_N_.assign(at(nb_), Vector3d::Zero());
  M_grav_B_.assign(at(nb_), Vector3d::Zero());
  if (env_.orbit()) {
    const CoordsGuard restore(*this);
    std::vector<double> x0(at(nx_));
    pack(TreeState::initial(system), x0.data());
    body_pass(0.0, x0.data());
    mass_pass(0.0);
    p_NoO_N_ = system_cm();
  }
}

// A flexible body: consistent sizes, finite data, non-negative node masses, mass and rigid
// inertia equal to the node sums, and a positive-definite undeformed mass matrix (a mode that
// moves no mass, or a mode that is a rigid-body motion or a combination of other modes, would
// make it singular). The body's invariants are precomputed here.
void NewtonEulerEngine::validate_flex(const std::string& file, int b, const Body& body,
                                      const EngineOptions& o) {
  const FlexBody& flex = *body.flex;
  const std::string key = file + ": bodies[" + std::to_string(b) + "] '" + body.name + "'";
  const int n = flex.modes();
  if (flex.nodes.empty()) throw InputError(key + ": a flexible body needs at least one node");
  auto square = [&](const Eigen::MatrixXd& A, const char* what, bool may_be_empty) {
    if (may_be_empty && A.size() == 0) return;
    if (A.rows() != n || A.cols() != n || !A.allFinite())
      throw InputError(key + ": modal " + what + " matrix must be finite and " +
                       std::to_string(n) + " x " + std::to_string(n));
    if ((A - A.transpose()).cwiseAbs().maxCoeff() > 1e-12 * (1 + A.cwiseAbs().maxCoeff()))
      throw InputError(key + ": modal " + what + " matrix must be symmetric");
  };
  square(flex.K, "stiffness K", n == 0);
  square(flex.D, "damping D", true);
  for (std::size_t i = 0; i < flex.nodes.size(); ++i) {
    const FlexNode& node = flex.nodes[i];
    const std::string nk = key + ": node '" + node.name + "'";
    if (!(node.mass >= 0) || !std::isfinite(node.mass)) throw InputError(nk + ": mass must be finite and >= 0");
    if (!node.p_BoNi_B.allFinite() || !node.J_Ni_B.allFinite())
      throw InputError(nk + ": position and inertia must be finite");
    if ((n > 0 || node.Phi_B.size() > 0) && (node.Phi_B.cols() != n || !node.Phi_B.allFinite()))
      throw InputError(nk + ": mode shapes must be finite, 3 x " + std::to_string(n));
    if (node.Psi_B.size() > 0 && (node.Psi_B.cols() != n || !node.Psi_B.allFinite()))
      throw InputError(nk + ": mode slopes must be finite, 3 x " + std::to_string(n) + " (or absent)");
    if (flex.geometric_stiffening && n > 0 &&
        (node.G.rows() != n || node.G.cols() != n || !node.G.allFinite() || !node.e_B.allFinite() ||
         (node.G - node.G.transpose()).cwiseAbs().maxCoeff() > 1e-12 * (1 + node.G.cwiseAbs().maxCoeff())))
      throw InputError(nk + ": geometric stiffening needs a finite unit e and a symmetric " +
                       std::to_string(n) + " x " + std::to_string(n) + " G");
  }
  const double scale = o.test_inertia_scale;
  ModalInvariants probe = ModalInvariants::from(flex, Matrix3d::Zero());
  const Matrix3d I0 = probe.rigid_inertia();
  if (std::abs(probe.m - body.mass) > kNodeSumRelTol * body.mass)
    throw InputError(key + ": mass " + std::to_string(body.mass) +
                     " kg differs from the sum of its node masses " + std::to_string(probe.m) + " kg");
  if ((I0 - body.I_BBo_B).cwiseAbs().maxCoeff() > kNodeSumRelTol * body.I_BBo_B.cwiseAbs().maxCoeff())
    throw InputError(key + ": inertia differs from the node sum sum_i (J_i + m_i (|p_i|^2 1 - p_i p_i^T))");
  ModalInvariants inv = ModalInvariants::from(flex, (scale - 1.0) * I0);
  ModalTerms terms(n);
  modal_terms(inv, Matrix3d::Identity(), Vector3d::Zero(), VectorXd::Zero(n), VectorXd::Zero(n), terms);
  if (Eigen::LLT<Eigen::MatrixXd>(terms.M).info() != Eigen::Success ||
      Eigen::LLT<Eigen::MatrixXd>(inv.M_ee).info() != Eigen::Success ||
      terms.M.diagonal().minCoeff() <= 0)
    throw InputError(key + ": the undeformed body's mass matrix is not positive definite (a mode "
                     "moves no mass, or is a rigid-body motion or a combination of other modes)");
  for (const auto& [A, what] : {std::pair{&inv.K, "stiffness K"}, std::pair{&inv.Dmp, "damping D"}}) {
    if (n == 0) break;
    const double lowest = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(*A, Eigen::EigenvaluesOnly)
                              .eigenvalues()
                              .minCoeff();
    if (lowest < -1e-12 * (1 + A->cwiseAbs().maxCoeff()))
      throw InputError(key + ": modal " + what + " matrix must be positive semi-definite (eigenvalue " +
                       std::to_string(lowest) + ")");
  }
  // EngineOptions::test_damper_scale: the modal damper of the equations of motion (modal_terms'
  // -Dmp eta'), after the check above (on the scene's D, which P keeps). Skipped at 1.
  if (o.test_damper_scale != 1.0) inv.Dmp *= o.test_damper_scale;
  flex_[at(b)] = static_cast<int>(inv_.size());
  inv_.push_back(std::move(inv));
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

// x => body kinematics and modal coordinates. The attitude is the normalised quaternion (its norm
// is a free, unused direction of the state; projection resets it).
void NewtonEulerEngine::body_pass(double t, const double* x) {
  for (int b = 0; b < nb_; ++b) {
    BodyKinematics& k = bk_[at(b)];
    const double* xp = x + pos(b);
    const double* xv = x + vel(b);
    double n = 0;
    const Quaterniond q_unit = unit_quaternion(Quaterniond(xp[3], xp[4], xp[5], xp[6]), n);
    if (!(n > 1e-6) || !std::isfinite(n)) fail(t, labels_[at(pos(b) + 3)], "degenerate attitude quaternion");
    k.q_NB = q_unit;
    k.R_NB = k.q_NB.toRotationMatrix();
    k.p_NoBo_N = Vector3d(xp[0], xp[1], xp[2]);
    k.v_NBo_N = Vector3d(xv[0], xv[1], xv[2]);
    k.w_NB_B = Vector3d(xv[3], xv[4], xv[5]);
    if (modes(b) > 0) {
      k.eta = Eigen::Map<const VectorXd>(xp + 7, modes(b));
      k.eta_dot = Eigen::Map<const VectorXd>(xv + 6, modes(b));
    }
  }
}

// Body kinematics => each flexible body's mass matrix and velocity terms (modal_body.hpp), given
// to the KKT solver. Rigid bodies' blocks are constant (set by the constructor).
void NewtonEulerEngine::mass_pass(double t) {
  for (int b = 0; b < nb_; ++b) {
    const int fi = flex_[at(b)];
    if (fi < 0) continue;
    const BodyKinematics& k = bk_[at(b)];
    ModalTerms& mt = terms_[at(fi)];
    modal_terms(inv_[at(fi)], k.R_NB, k.w_NB_B, k.eta, k.eta_dot, mt);
    if (!kkt_.set_mass(b, mt.M))
      fail(t, system_.bodies[at(b)].name, "flexible body's mass matrix is not positive definite");
  }
}

// Body kinematics => node frames, relative joint kinematics, continuous revolute angles,
// constraint rows. A prescribed joint's row 5 gets its time terms here, by its unit's track verb
// (rheonomic constraint, Haug 1989, Sec. 6.3; docs/prescribed-motion.md "The motion";
// joints/revolute.cpp): g_5 = angle - (angle0 + theta(t)) (wrapped to (-pi, pi]),
// g_5' = rate - theta'(t), gamma_5 += theta''(t), so that projection and Baumgarte drive the
// joint to the prescribed angle and rate at t.
void NewtonEulerEngine::joint_pass(double t) {
  for (int j = first_joint(); j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    const BodyKinematics& P = parent_kinematics(j);
    const BodyKinematics& C = bk_[at(m.child)];
    joint_kinematics(m, P, C, jk_[at(j)]);
    ConstraintRows& cr = cr_[at(j)];
    constraint_rows(m, P, C, jk_[at(j)], cr);
    if (m.unit->track)
      m.unit->track(system_.joints[at(j)], m, t, jk_[at(j)], cr, coords_[at(j)], coords_ref_[at(j)]);
  }
}

// A torque T_B (body components) applied to a joint frame of body b: it turns the body and, on a
// flexible body, does work through the frame's rotation, w_rel = Jl Psi eta', so it has the
// generalised force (Jl Psi)^T T_B on eta (docs/flexible-bodies.md "Loads at joints").
void NewtonEulerEngine::torque_on_frame(int b, const Vector3d& T_B, const Eigen::Matrix3Xd& JlPsi) {
  f_.segment<3>(nu(b) + 3) += T_B;
  if (JlPsi.cols() > 0) f_.segment(nu(b) + 6, JlPsi.cols()).noalias() += JlPsi.transpose() * T_B;
}

// t => applied forces and moments, and the velocity terms, per body (paper Eqs. (1), (2), (7)
// with the constraint terms moved to the solve): rigid f_b = [F_ext_N; M_ext_B - w x I w];
// flexible f_b = f_bias (modal_body.hpp) + [F_ext_N; M_ext_B; 0].
// Joint loads follow core/system.hpp: on the child-side joint frame, the reaction on the parent-side
// joint frame, one vector for both so that internal loads never change the total angular momentum.
void NewtonEulerEngine::force_pass(double t) {
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematics& k = bk_[at(b)];
    const Body& body = system_.bodies[at(b)];
    const int fi = flex_[at(b)];
    if (fi < 0) {
      f_.segment<3>(nu(b)).setZero();  // external forces: the environment's, below
      f_.segment<3>(nu(b) + 3) = rigid_moment(body, I_B_[at(b)], t, k.R_NB, k.w_NB_B);
      continue;
    }
    f_.segment(nu(b), 6 + modes(b)) = terms_[at(fi)].f;
    if (!body.torque.empty()) {  // on the body frame: no work on eta
      const Vector3d T = body.torque.value(t);
      if (body.torque_frame == Body::Frame::Body) f_.segment<3>(nu(b) + 3) += T;
      else f_.segment<3>(nu(b) + 3) += k.R_NB.transpose() * T;
    }
  }
  if (!env_.none()) {  // gravity (issue 28): nothing computed without an environment
    const GravityField gf = gravity_field(t);
    for (int b = 0; b < nb_; ++b) gravity_on_body(b, gf);
  }
  for (int j = 1; j < nj_; ++j) {
    const Joint& J = system_.joints[at(j)];
    const JointModel& m = joints_[at(j)];
    const JointKinematics& jk = jk_[at(j)];
    Vector3d T_P;  // the torque on the child-side frame, in P body components
    Vector3d F_P;  // the force on the child at its joint point, P components (m.translates)
    if (!m.unit->load || !m.unit->load(J, m, jk, coords_[at(j)], t, T_P, F_P)) continue;
    torque_on_frame(m.child, jk.R_PC.transpose() * T_P, jk.G.JlPsi);
    torque_on_frame(m.parent, -T_P, jk.F.JlPsi);
    if (!m.translates) continue;
    // The force at the child's joint point, the reaction at the same point (r_PoJ_F from Po), so
    // that the pair has no moment ([KLL83] Sec. 4.5); no work on eta (not at a node).
    const Vector3d F_N = bk_[at(m.parent)].R_NB * F_P;
    f_.segment<3>(nu(m.child)) += F_N;
    f_.segment<3>(nu(m.child) + 3) += jk.G.s_B.cross(jk.R_PC.transpose() * F_P);
    f_.segment<3>(nu(m.parent)) -= F_N;
    f_.segment<3>(nu(m.parent) + 3) -= jk.r_PoJ_F.cross(F_P);
  }
}

// ---- the environment's loads (issue 28) -------------------------------------------------------
//
// Every mass element of the model feels the field at its own position (core/system.hpp
// "Environment"): a rigid body is its CM with its inertia, a flexible body its nodes
// x_i = p + R r_i, r_i = p_i + u_i (B components; modal_body.hpp) with their inertias J_i.
// In this engine an applied load enters body b's Newton and Euler equations as its generalised
// force on b's unknowns [a_N; alpha_B; eta''] (the reference paper's Eqs. (1), (2), (7); for a
// flexible body the virtual displacement of node i, delta x_i = delta p + R (delta theta x r_i +
// Phi~_i delta eta), modal_body.hpp; Kane & Levinson 1985, "Dynamics: Theory and Applications",
// Ch. 4, generalised active forces): a node force F_i (N components) gives
//   [ sum F_i ;  sum r_i x R^T F_i ;  sum Phi~_i^T R^T F_i ]
// and a torque on a node's inertia (fixed in B: it does not turn with the deformation) only the
// moment row. The sums over nodes are done with the body's mass-weighted invariants and per-state
// terms (terms_, after mass_pass): S = sum m_i r_i, I(eta) = J_sum + tr(Q) 1 - Q with
// Q = sum m_i r_i r_i^T, R Phi~_bar (the mass matrix's block M(0:3, 6:)), B_k = sum m_i Phi_ik r_i^T
// (the linear model; a stiffened body is summed node by node, as its mass matrix is).
//
// Uniform field g_N: F_i = m_i g. Per body
//   F_grav_N = m g;  M_grav_B = S x R^T g  (zero for a rigid body: no moment about its CM);
//   modal  (R Phi~_bar)^T g.
//   V = -g . (m p + R S)  (-sum m_i g . x_i).
// Orbit (second-order tidal field about O; Hughes 2004, "Spacecraft Attitude Dynamics", Sec. 8.1;
// Schaub & Junkins 2018, "Analytical Mechanics of Space Systems", Sec. 4.3):
// T = n^2 (3 zhat zhat^T - 1) (N components; T_B = R^T T R = n^2 (3 z_B z_B^T - 1), z_B = R^T zhat),
// d = p - p_NoO_N, F_i = m_i T (d + R r_i); node inertia torque 3 n^2 z_B x (J_i z_B). Per body
//   F_grav_N = T (m d + R S);
//   M_grav_B = S x (T_B d_B) + sum m_i r_i x (T_B r_i) + 3 n^2 z_B x (J_sum z_B)
//            = S x (T_B d_B) + 3 n^2 z_B x (I(eta) z_B)
//     (sum m_i r_i x T_B r_i = 3 n^2 (Q z_B) x z_B and z_B x I z_B = (Q z_B) x z_B + z_B x J_sum z_B);
//     a rigid body (S = 0, I = I_B): the gravity-gradient torque tau_gg_B = 3 n^2 z_B x (I_B z_B)
//     (Hughes Sec. 8.1);
//   modal  (R Phi~_bar)^T T d + [sum m_i Phi~_ik . T_B r_i]_k,
//     linear model: sum m_i Phi_ik . T_B r_i = tr(T_B B_k) = 3 n^2 z_B^T B_k z_B - n^2 tr B_k;
//   V = sum_i (-1/2 m_i x_i^T T x_i + 3/2 n^2 zhat^T J_i,N zhat - 1/2 n^2 tr J_i), x_i from O,
//     = -1/2 m d^T T d - d^T T R S + 3/2 n^2 z_B^T I(eta) z_B - 1/2 n^2 tr I(eta)
//     (with sum m_i r_i^T T_B r_i = 3 n^2 z_B^T Q z_B - n^2 tr Q, Q = tr(Q) 1 - (I - J_sum) and
//     tr Q = (tr I - tr J_sum) / 2), for a rigid body the per-body formula of core/system.hpp.
// EngineOptions::test_gravity_gradient_sign is not implemented here (core/engine.hpp: lagrange's).
NewtonEulerEngine::GravityField NewtonEulerEngine::gravity_field(double t) const {
  GravityField gf;
  if (!env_.orbit()) return gf;
  const OrbitFrame of = orbit_frame(env_, t);
  gf.n2 = of.n * of.n;
  gf.zhat_N = of.zenith_N;
  return gf;
}

void NewtonEulerEngine::gravity_on_body(int b, const GravityField& gf) {
  const BodyKinematics& k = bk_[at(b)];
  const int fi = flex_[at(b)];
  Vector3d F_grav_N, M_grav_B;
  if (fi < 0)
    rigid_gravity(env_, mass_[at(b)], I_B_[at(b)], p_NoO_N_, gf.n2, gf.zhat_N, k.R_NB, k.p_NoBo_N, F_grav_N, M_grav_B);
  else
    flexible_gravity<double>(b, gf, k, terms_[at(fi)], f_, F_grav_N, M_grav_B);
  f_.segment<3>(nu(b)) += F_grav_N;
  f_.segment<3>(nu(b) + 3) += M_grav_B;
  F_grav_N_[at(b)] = F_grav_N;
  M_grav_B_[at(b)] = M_grav_B;
}

// gravity_on_body()'s flexible branch on S (double for the run, Cx for the tangents' complex
// step: scalar.hpp's tdot, tcross; a stiffened body's node-by-node sum in the modal terms' scratch
// g, Phit, free again after mass_pass): the force and moment returned, the modal generalised
// forces added to f (KKT order).
template <class S>
void NewtonEulerEngine::flexible_gravity(int b, const GravityField& gf, const BodyKinematicsT<S>& k,
                                         ModalTermsT<S>& mt, Eigen::Matrix<S, Eigen::Dynamic, 1>& f,
                                         V3<S>& F_grav_N, V3<S>& M_grav_B) const {
  const double m = mass_[at(b)];
  const int n = modes(b);
  if (env_.uniform()) {
    F_grav_N = (m * env_.g_N).template cast<S>();
    M_grav_B = tcross<S>(mt.S, V3<S>(k.R_NB.transpose() * env_.g_N));
    if (n > 0) f.segment(nu(b) + 6, n).noalias() += mt.M.block(0, 6, 3, n).transpose() * env_.g_N;
    return;
  }
  const V3<S> d_N = k.p_NoBo_N - p_NoO_N_;
  const V3<S> z_B = k.R_NB.transpose() * gf.zhat_N;
  const V3<S> Td_N = gf.n2 * (3.0 * tdot<S>(gf.zhat_N, d_N) * gf.zhat_N - d_N);  // T d
  F_grav_N = m * Td_N;
  const V3<S> S_N = k.R_NB * mt.S;
  F_grav_N += gf.n2 * (3.0 * tdot<S>(gf.zhat_N, S_N) * gf.zhat_N - S_N);
  M_grav_B = tcross<S>(mt.S, V3<S>(k.R_NB.transpose() * Td_N)) +
             3.0 * gf.n2 * tcross<S>(z_B, V3<S>(mt.I * z_B));
  if (n == 0) return;
  auto f_modal = f.segment(nu(b) + 6, n);
  f_modal.noalias() += mt.M.block(0, 6, 3, n).transpose() * Td_N;
  const ModalInvariants& inv = inv_[at(flex_[at(b)])];
  if (!inv.stiffening) {
    for (int c = 0; c < n; ++c) {
      const M3<S>& Bk = mt.B[at(c)];
      f_modal(c) += gf.n2 * (3.0 * tdot<S>(z_B, V3<S>(Bk * z_B)) - Bk.trace());
    }
    return;
  }
  const Eigen::Matrix<S, Eigen::Dynamic, 1>& eta = k.eta;
  for (std::size_t i = 0; i < inv.node_m.size(); ++i) {
    mt.g.noalias() = inv.node_G[i] * eta;  // G_i eta
    V3<S> r = inv.node_p[i].template cast<S>() + 0.5 * tdot<S>(eta, mt.g) * inv.node_e[i].template cast<S>();
    r.noalias() += inv.node_Phi[i] * eta;  // r_i = p_i + u_i
    mt.Phit = inv.node_Phi[i].template cast<S>();
    mt.Phit.noalias() += inv.node_e[i].template cast<S>() * mt.g.transpose();  // Phi~_i
    const V3<S> TBr = gf.n2 * (3.0 * tdot<S>(z_B, r) * z_B - r);
    f_modal.noalias() += mt.Phit.transpose() * (inv.node_m[i] * TBr);
  }
}

// The environment's potential V (equations above gravity_field()); 0 without one. A flexible
// body's S and I(eta) from st.terms (valid after mass_pass).
template <class S>
S NewtonEulerEngine::gravity_potential(double t, const OutputState<S>& st) const {
  if (env_.none()) return S(0.0);
  const GravityField gf = gravity_field(t);
  S V = 0;
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematicsT<S>& k = st.bk[at(b)];
    const int fi = flex_[at(b)];
    const double m = mass_[at(b)];
    const V3<S> S_N = fi < 0 ? V3<S>::Zero() : V3<S>(k.R_NB * st.terms[at(fi)].S);
    if (env_.uniform()) {
      V -= tdot<S>(env_.g_N, m * k.p_NoBo_N + S_N);
      continue;
    }
    const M3<S> I_B = fi < 0 ? M3<S>(I_B_[at(b)].template cast<S>()) : st.terms[at(fi)].I;
    const V3<S> d_N = k.p_NoBo_N - p_NoO_N_;
    const V3<S> z_B = k.R_NB.transpose() * gf.zhat_N;
    const V3<S> Td_N = gf.n2 * (3.0 * tdot<S>(gf.zhat_N, d_N) * gf.zhat_N - d_N);
    V += -0.5 * m * tdot<S>(d_N, Td_N) - tdot<S>(Td_N, S_N) + 1.5 * gf.n2 * tdot<S>(z_B, I_B * z_B) -
         0.5 * gf.n2 * I_B.trace();
  }
  return V;
}

// (constraint rows) => J and gamma_s of the KKT system (kkt_): gamma_s = gamma, or with
// Baumgarte's terms.
void NewtonEulerEngine::load_kkt() {
  for (int j = 1; j < nj_; ++j) {
    const ConstraintRows& c = cr_[at(j)];
    const JointModel& m = joints_[at(j)];
    const int k = j - 1;
    kkt_.J_parent(k).leftCols<6>() = c.J_P;
    kkt_.J_child(k).leftCols<6>() = c.J_C;
    if (m.P.modes > 0) kkt_.J_parent(k).rightCols(m.P.modes) = c.Je_P;
    if (m.C.modes > 0) kkt_.J_child(k).rightCols(m.C.modes) = c.Je_C;
    gamma_[at(k)] = c.gamma;
    if (stabilization_ == Stabilization::Baumgarte)  // [Baum72]: g'' + alpha g' + beta g = 0
      gamma_[at(k)] -= alpha_ * c.gdot + beta_ * c.g;
  }
  if (prescribed_base_) {  // joint 0 to N: the root rows (N's columns are not unknowns)
    const ConstraintRows& c = cr_[0];
    kkt_.J_root().leftCols<6>() = c.J_C;
    if (joints_[0].C.modes > 0) kkt_.J_root().rightCols(joints_[0].C.modes) = c.Je_C;
    kkt_.gamma_root() = c.gamma;
    if (stabilization_ == Stabilization::Baumgarte)  // [Baum72]
      kkt_.gamma_root() -= alpha_ * c.gdot + beta_ * c.g;
  }
}

// (M, J, f, gamma) => accelerations nu_dot and multipliers (y = -lambda), [Baraff96].
void NewtonEulerEngine::solve_pass(double t) {
  if (!kkt_.factor()) fail(t, "constraints", "singular constraint system (KKT pivot not definite)");
  kkt_.solve(f_, gamma_, nu_dot_, y_);
  if (!nu_dot_.allFinite()) {
    int i = 0;
    while (std::isfinite(nu_dot_(i))) ++i;
    fail(t, labels_[at(vel_[0] + i)], "non-finite acceleration");
  }
}

void NewtonEulerEngine::assemble(double t, const double* x) {
  body_pass(t, x);
  mass_pass(t);
  joint_pass(t);
  force_pass(t);
  load_kkt();
}

void NewtonEulerEngine::dynamics(double t, const double* x) {
  assemble(t, x);
  solve_pass(t);
}

// ---- Engine interface -------------------------------------------------------------------------

void NewtonEulerEngine::rhs(double t, const double* x, double* xdot) {
  dynamics(t, x);
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematics& k = bk_[at(b)];
    const double* xp = x + pos(b);
    double* dp = xdot + pos(b);
    dp[0] = k.v_NBo_N.x();
    dp[1] = k.v_NBo_N.y();
    dp[2] = k.v_NBo_N.z();
    // q' = 1/2 q (x) (0, w_B) with the stored (not renormalised) q: its norm is then an exact
    // invariant of the equations ([KLL83] Sec. 1.13).
    const Eigen::Vector4d qd =
        rot::quat_rate_body(Quaterniond(xp[3], xp[4], xp[5], xp[6]), k.w_NB_B);
    for (int i = 0; i < 4; ++i) dp[3 + i] = qd(i);
    for (int i = 0; i < modes(b); ++i) dp[7 + i] = k.eta_dot(i);
  }
  Eigen::Map<VectorXd>(xdot + vel_[0], nv_) = nu_dot_;
}

// (t, x) => the KKT system solve_pass() hands to TreeKkt, written out dense (core/engine.hpp):
//   [ M  J^T ] [ nu'      ]   [ f       ]
//   [ J  0   ] [ -lambda  ] = [ gamma_s ]
// i.e. M nu' = f + J^T lambda (each body's Newton and Euler equations with the joint constraint
// forces, paper Eqs. (1), (2), (7); flexible blocks modal_body.hpp) and J nu' = gamma_s (the
// joints' acceleration equations, Haug 1989, Sec. 3.3 and 6.3, prescribed joints as rheonomic
// rows; gamma_s with Baumgarte's terms [Baum72] when that stabilisation is on). Sign convention:
// the engine's (tree_kkt.hpp): the multiplier unknowns are y = -lambda, so that A and b are the
// blocks TreeKkt takes, unchanged (lambda's wrench on a body is J_b^T lambda).
// Built by the same passes as rhs() (assemble(): M by mass_pass, f by force_pass, J and gamma_s
// by load_kkt), without the factorisation: so a system whose KKT pivots are not definite (where rhs()
// would fail) is still returned, for its condition number.
//   z = [nu'; y]: nu' stacked body by body in KKT order, then y joint by joint (a prescribed
//   base's root rows first, then joints 1, 2, ...), rows_k per joint (no padding).
// The state's velocities are the KKT unknowns themselves, in the same order: body b's
// [v_NBo_N (N components); w_NB_B (B components); eta'] at vel(b) = vel(0) + nu(b), and rhs()
// writes nu' there unchanged (the time derivative of w_NB_B's B components is alpha_NB_B, of
// v_NBo_N's N components a_NBo_N). So speed_index = vel(0) .. vel(0) + nv - 1 and no transform
// is needed. M's blocks are mirrored from their lower triangles: the only part TreeKkt's Cholesky
// reads (a flexible block is symmetric only to round-off). Allocates; never called by rhs().
Engine::LinearSystem NewtonEulerEngine::linear_system(double t, const double* x) {
  assemble(t, x);
  int m = kkt_.root_rows();
  for (int k = 0; k < kkt_.links(); ++k) m += kkt_.link(k).rows;
  LinearSystem ls;
  ls.A = Eigen::MatrixXd::Zero(nv_ + m, nv_ + m);
  ls.b = VectorXd::Zero(nv_ + m);
  for (int b = 0; b < nb_; ++b) {
    const int o = kkt_.offset(b), d = kkt_.dofs(b);
    ls.A.block(o, o, d, d) = kkt_.M(b).selfadjointView<Eigen::Lower>();
  }
  ls.b.head(nv_) = f_;
  // Row block r (rows rows_k at nv_ + r) of a joint's J on body b's columns, and its transpose.
  auto put = [&](int r, int rows, int b, const Eigen::MatrixXd& J_b) {
    const int o = kkt_.offset(b), d = kkt_.dofs(b);
    ls.A.block(nv_ + r, o, rows, d) = J_b.topRows(rows);
    ls.A.block(o, nv_ + r, d, rows) = J_b.topRows(rows).transpose();
  };
  int r = 0;
  if (kkt_.root_rows() > 0) {  // the prescribed base's joint to N: N's columns are not unknowns
    put(r, kkt_.root_rows(), kkt_.base(), kkt_.J_root());
    ls.b.segment(nv_ + r, kkt_.root_rows()) = kkt_.gamma_root().head(kkt_.root_rows());
    r += kkt_.root_rows();
  }
  for (int k = 0; k < kkt_.links(); ++k) {
    const KktLink& l = kkt_.link(k);
    put(r, l.rows, l.parent, kkt_.J_parent(k));
    put(r, l.rows, l.child, kkt_.J_child(k));
    ls.b.segment(nv_ + r, l.rows) = gamma_[at(k)].head(l.rows);
    r += l.rows;
  }
  for (int i = 0; i < nv_; ++i) ls.speed_index.push_back(vel_[0] + i);
  int modal = 0;
  for (int b = 0; b < nb_; ++b) modal += modes(b);
  ls.what = "KKT [M J^T; J 0], " + std::to_string(nv_) + " body speeds" +
            (modal > 0 ? " (" + std::to_string(modal) + " modal)" : std::string()) + " + " +
            std::to_string(m) + " constraints (factored in linear time along the tree)";
  return ls;
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
    for (int i = 0; i < modes(b); ++i) {
      xp[7 + i] = k.eta(i);
      xv[6 + i] = k.eta_dot(i);
    }
  }
}

// Engine-neutral state => maximal coordinates, with this engine's own tree kinematics
// (core/system.hpp "Joint kinematics"; joint_constraints.hpp for the node frames F, G):
//   R_NG = R_NF R_PJ0 R_J, R_NC = R_NG E_C^T;  w_G = R_GF w_F + w_FG_G, w_C = E_C w_G - w_rel_C;
//   p_C = p_P + R_NP (s_P + r) - R_NC s_C;
//   v_C = v_P + R_NP (w_P x (s_P + r) + s_P' + r') - R_NC (w_C x s_C + s_C')
// [KLL83 Sec. 2.7], r = s axis_P and r' = s' axis_P along a prismatic joint (its unit's pack; zero
// for the others; a translating joint is not at a node, so F = P there).
void NewtonEulerEngine::pack(const TreeState& s, double* x) {
  if (static_cast<int>(s.joints.size()) != nj_)
    throw InputError(where(system_) + ": TreeState has " + std::to_string(s.joints.size()) +
                     " joints, the scene " + std::to_string(nj_));
  for (int b = 0; b < nb_; ++b) {
    if (modes(b) == 0) continue;
    const auto n = static_cast<Eigen::Index>(modes(b));
    if (at(b) >= s.eta.size() || at(b) >= s.eta_rate.size() || s.eta[at(b)].size() != n ||
        s.eta_rate[at(b)].size() != n || !s.eta[at(b)].allFinite() || !s.eta_rate[at(b)].allFinite())
      throw InputError(where(system_) + ": TreeState: body '" + system_.bodies[at(b)].name +
                       "' needs " + std::to_string(n) + " finite modal coordinates and rates");
    bk_[at(b)].eta = s.eta[at(b)];
    bk_[at(b)].eta_dot = s.eta_rate[at(b)];
  }
  const int base = joints_[0].child;
  BodyKinematics& B = bk_[at(base)];
  double q_norm = 0;
  B.q_NB = unit_quaternion(s.q_NB, q_norm);
  B.R_NB = B.q_NB.toRotationMatrix();
  B.p_NoBo_N = s.p_NoBo_N;
  B.v_NBo_N = s.v_NBo_N;
  B.w_NB_B = s.w_NB_B;
  for (int j = first_joint(); j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    // A prescribed joint's angle and rate come from the TreeState like any other (engine.hpp:
    // they must follow the profile at the time the run starts; TreeState::initial gives t = 0).
    const TreeState::JointState& js = s.joints[at(j)];
    const BodyKinematics& P = parent_kinematics(j);
    BodyKinematics& C = bk_[at(m.child)];
    NodeFrame& F = jk_[at(j)].F;
    NodeFrame& G = jk_[at(j)].G;
    node_frame(m.P, P, F);
    node_frame(m.C, C, G);  // depends only on the child's modal state
    Quaterniond q_J = Quaterniond::Identity();
    Vector3d w_FG_G = Vector3d::Zero();
    Vector3d r_F = Vector3d::Zero(), v_F = Vector3d::Zero();
    if (m.unit->pack) m.unit->pack(m, js, q_J, w_FG_G, r_F, v_F, coords_ref_[at(j)]);
    place_child(m, P, F, G, q_J, w_FG_G, r_F, v_F, C);
  }
  if (system_.zero_linear_momentum && !prescribed_base_) shift_all(Vector3d::Zero(), -linear_momentum() / total_mass());
  write_state(x);
  for (int j = 1; j < nj_; ++j) coords_[at(j)] = coords_ref_[at(j)];
}

double NewtonEulerEngine::total_mass() const {
  double m = 0;
  for (double mb : mass_) m += mb;
  return m;
}

// Per body (modal_body.hpp): first moment m p + R S, linear momentum m v + R (w x S + Phi_bar eta'),
// S = S0 + Phi_bar eta (zero for a rigid body).
Vector3d NewtonEulerEngine::first_moment() const {
  Vector3d sum = Vector3d::Zero();
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematics& k = bk_[at(b)];
    sum += mass_[at(b)] * k.p_NoBo_N;
    if (flex_[at(b)] < 0) continue;
    Vector3d S, p_rel;
    modal_first_moments(inv_[at(flex_[at(b)])], k.eta, k.eta_dot, S, p_rel);
    sum += k.R_NB * S;
  }
  return sum;
}

Vector3d NewtonEulerEngine::linear_momentum() const {
  Vector3d sum = Vector3d::Zero();
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematics& k = bk_[at(b)];
    sum += mass_[at(b)] * k.v_NBo_N;
    if (flex_[at(b)] < 0) continue;
    Vector3d S, p_rel;
    modal_first_moments(inv_[at(flex_[at(b)])], k.eta, k.eta_dot, S, p_rel);
    sum += k.R_NB * (k.w_NB_B.cross(S) + p_rel);
  }
  return sum;
}

// Every body translated by dp and given the extra velocity dv: a rigid translation of the whole
// system, which leaves every joint condition as it was (g and J nu depend on differences only).
void NewtonEulerEngine::shift_all(const Vector3d& dp, const Vector3d& dv) {
  for (BodyKinematics& k : bk_) {
    k.p_NoBo_N += dp;
    k.v_NBo_N += dv;
  }
}

// Mass-metric projection onto {g = 0} then {J nu = 0} [HLW06 Sec. IV.4]: the corrections solve
// [M J^T; J 0] [delta; y] = [0; -g] (Newton, a few iterations) and [0; -J nu] (once), delta over
// every unknown, the modal coordinates and rates included (a joint at a node is closed by moving
// eta as well as the bodies). They are internal impulses/displacements, so the system's CM moves
// only at second order and the velocity step keeps the linear momentum; but a flexible body's
// momentum m v + R (w x S + Phi_bar eta') also depends on R and eta, which the position step moves.
// A final rigid translation of the whole system (the mass-metric projection onto "CM and linear
// momentum as before", which leaves every joint condition unchanged) restores both exactly.
bool NewtonEulerEngine::project(double t, double* x, double trigger) {
  bool changed = false;
  for (int b = 0; b < nb_; ++b) {
    double* q = x + pos(b) + 3;
    const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (std::abs(n - 1) > std::min(trigger, kQuaternionNormTrigger)) {
      for (int i = 0; i < 4; ++i) q[i] /= n;
      changed = true;
    }
  }
  if (nj_ < 2 && !prescribed_base_) return changed;
  double L = std::max(1.0, lever_scale_);
  for (int b = 0; b < nb_; ++b)
    L = std::max(L, std::abs(x[pos(b)]) + std::abs(x[pos(b) + 1]) + std::abs(x[pos(b) + 2]));
  auto max_violation = [this](bool velocity) {
    double v = 0;
    for (int j = first_joint(); j < nj_; ++j)
      v = std::max(v, (velocity ? cr_[at(j)].gdot : cr_[at(j)].g).cwiseAbs().maxCoeff());
    return v;
  };
  auto load_rows = [this](bool velocity) {
    for (int j = 1; j < nj_; ++j) {
      const ConstraintRows& c = cr_[at(j)];
      const JointModel& m = joints_[at(j)];
      kkt_.J_parent(j - 1).leftCols<6>() = c.J_P;
      kkt_.J_child(j - 1).leftCols<6>() = c.J_C;
      if (m.P.modes > 0) kkt_.J_parent(j - 1).rightCols(m.P.modes) = c.Je_P;
      if (m.C.modes > 0) kkt_.J_child(j - 1).rightCols(m.C.modes) = c.Je_C;
      gamma_[at(j - 1)] = velocity ? Vector6d(-c.gdot) : Vector6d(-c.g);
    }
    if (prescribed_base_) {
      const ConstraintRows& c = cr_[0];
      kkt_.J_root().leftCols<6>() = c.J_C;
      if (joints_[0].C.modes > 0) kkt_.J_root().rightCols(joints_[0].C.modes) = c.Je_C;
      kkt_.gamma_root() = velocity ? Vector6d(-c.gdot) : Vector6d(-c.g);
    }
    f_.setZero();
  };
  body_pass(t, x);
  mass_pass(t);  // the metric: the mass matrix at the step's state
  joint_pass(t);
  const Vector3d moment0 = first_moment(), momentum0 = linear_momentum();
  if (max_violation(false) > trigger * L) {
    for (int iter = 0; iter < kNewtonMaxIterations; ++iter) {
      load_rows(false);
      if (!kkt_.factor()) fail(t, "constraints", "singular constraint system in projection");
      kkt_.solve(f_, gamma_, nu_dot_, y_);  // nu_dot_ holds the displacement delta
      for (int b = 0; b < nb_; ++b) {
        BodyKinematics& k = bk_[at(b)];
        k.p_NoBo_N += nu_dot_.segment<3>(nu(b));
        // A small rotation in body axes, as w_NB_B dt: q <- q (x) exp(delta_B).
        k.q_NB = (k.q_NB * rot::from_rotation_vector(nu_dot_.segment<3>(nu(b) + 3))).normalized();
        k.R_NB = k.q_NB.toRotationMatrix();
        if (modes(b) > 0) k.eta += nu_dot_.segment(nu(b) + 6, modes(b));
      }
      joint_pass(t);
      changed = true;
      if (max_violation(false) <= kNewtonTarget * L) break;
    }
  }
  if (max_violation(true) > trigger * L) {
    load_rows(true);
    if (!kkt_.factor()) fail(t, "constraints", "singular constraint system in projection");
    kkt_.solve(f_, gamma_, nu_dot_, y_);
    for (int b = 0; b < nb_; ++b) {
      BodyKinematics& k = bk_[at(b)];
      k.v_NBo_N += nu_dot_.segment<3>(nu(b));
      k.w_NB_B += nu_dot_.segment<3>(nu(b) + 3);
      if (modes(b) > 0) k.eta_dot += nu_dot_.segment(nu(b) + 6, modes(b));
    }
    changed = true;
  }
  if (!changed) return false;
  const double m = total_mass();
  // A prescribed base is held by N: no rigid translation (it would break the root rows).
  if (!prescribed_base_)
    shift_all((moment0 - first_moment()) / m, (momentum0 - linear_momentum()) / m);
  write_state(x);
  return true;
}

void NewtonEulerEngine::update_turn_counters(double t, const double* x) {
  body_pass(t, x);
  for (int j = 1; j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    if (!m.unwraps) continue;
    joint_kinematics(m, bk_[at(m.parent)], bk_[at(m.child)], jk_[at(j)]);
    JointCoords& ref = coords_ref_[at(j)];
    ref(0) = unwrap_angle(jk_[at(j)].angle_wrapped, ref(0));
    ref(1) = unwrap_angle(jk_[at(j)].angle2_wrapped, ref(1));  // universal (else 0)
  }
}

bool NewtonEulerEngine::after_step(double t, double* x) {
  const bool changed = stabilization_ == Stabilization::Projection && project(t, x);
  update_turn_counters(t, x);
  return changed;
}

// The F-frame derivative of a joint frame's angular velocity w_F (joint_constraints.hpp):
// E^T (alpha_B + Jl Psi eta'' + c - w_rel x w_B); alpha_B on a rigid side.
Vector3d NewtonEulerEngine::frame_angular_acceleration(const JointSide& side, const NodeFrame& fr,
                                                       int b) const {
  const Vector3d alpha = nu_dot_.segment<3>(nu(b) + 3);
  if (side.modes == 0) return alpha;
  return fr.E.transpose() * (alpha + fr.JlPsi * nu_dot_.segment(nu(b) + 6, side.modes) + fr.c_B -
                             fr.w_rel_B.cross(bk_[at(b)].w_NB_B));
}

void NewtonEulerEngine::accelerations(double t, const double* x, TreeAccel& a) {
  dynamics(t, x);
  a.wdot_NB_B.assign(at(nb_), Vector3d::Zero());
  a.a_NBo_N.assign(at(nb_), Vector3d::Zero());
  a.angle_ddot.assign(at(nj_), 0.0);
  a.angle2_ddot.assign(at(nj_), 0.0);
  a.wdot_PC_C.assign(at(nj_), Vector3d::Zero());
  a.eta_ddot.assign(at(nb_), VectorXd());
  for (int b = 0; b < nb_; ++b) {
    a.a_NBo_N[at(b)] = nu_dot_.segment<3>(nu(b));
    a.wdot_NB_B[at(b)] = nu_dot_.segment<3>(nu(b) + 3);
    if (modes(b) > 0) a.eta_ddot[at(b)] = nu_dot_.segment(nu(b) + 6, modes(b));
  }
  if (prescribed_base_) a.angle_ddot[0] = system_.joints[0].prescribed->accel(t);
  for (int j = 1; j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    const JointKinematics& jk = jk_[at(j)];
    if (!m.unit->accelerations) continue;
    const JointAccelInputs in{bk_[at(m.parent)],
                              bk_[at(m.child)],
                              jk,
                              frame_angular_acceleration(m.P, jk.F, m.parent),
                              frame_angular_acceleration(m.C, jk.G, m.child),
                              nu_dot_.segment<6>(nu(m.parent)),
                              nu_dot_.segment<6>(nu(m.child))};
    m.unit->accelerations(system_.joints[at(j)], m, in, t, a, j);
  }
}

// ---- the exact tangent (issue 27; core/engine.hpp) ---------------------------------------------
//
// The complex step (Martins, Sturdza & Alonso 2003, "The complex-step derivative approximation",
// ACM TOMS 29(3); the tangent mode of Griewank & Walther 2008, "Evaluating Derivatives", 2nd ed.,
// Ch. 3): the state is s + i h ds with h = 1e-30, and the engine's own pack() and equations run on
// Cx = std::complex<double>: the templates shared with the double path (scalar.hpp; the joint
// kinematics and constraint rows, joint_constraints.hpp; the units' verbs, joints/*.cpp; the
// rigid body's moment and gravity and the placement of pack(), above; a flexible body's mass
// matrix and velocity terms, modal_body.hpp's modal_terms_t; the node frames' so3 maps on Cx,
// so3.hpp), with the passes below mirroring body_pass, mass_pass, joint_pass, force_pass
// (gravity on a flexible body's nodes: flexible_gravity, templated), load_kkt, solve_pass and
// accelerations() (a node frame's angular acceleration as frame_angular_acceleration()). da = Im(a(s + i h ds)) / h, exact to rounding (no subtraction; the error is O(h^2)).
// Rotations turn on the right, q (1, i h dtheta / 2) (TreeTangent), normalised by
// sqrt(w^2 + x^2 + y^2 + z^2) (analytic, never |.|). A prescribed joint has no tangent (its
// profile at t).
// The solve: K z = b with K = [M J^T; J 0] = K_r + i K_i (a rigid body's M is real and constant;
// a flexible body's depends on the state, M_i its imaginary part; J's modal columns too), z = z_r + i z_i, b = b_r + i b_i: to O(h^2), K_r z_r = b_r and K_r z_i = b_i - K_i z_r, two
// solves with the engine's own factorisation (TreeKkt) of the real KKT matrix (which is the run's:
// K_r equals the double path's to rounding); no complex factorisation, so nothing conjugates.
// A prescribed base is placed from N by joint 0 (its profile at t, no tangent; the TreeState's
// base pose is not read, as in pack()), and its root rows enter the two solves like a link's
// (K_i's root block J_R,i, zero here since the base is real, kept for the form).
// Covered (tangent_covered_, decided by the constructor): rigid and flexible (modal) bodies,
// geometrically stiffened or not, with a free or prescribed base; revolute, prismatic, universal,
// fixed and spherical joints (at nodes or not), any environment, body torques, joint springs,
// dampers, motors, modal stiffness and damping, prescribed joints, any stabilisation. A joint
// type whose unit had no Cx verbs would return false before writing anything (the caller then
// differentiates numerically and says so); every type this engine has now has them.
NewtonEulerEngine::CxPass NewtonEulerEngine::cx_pass() const {
  CxPass w;
  w.bk.resize(at(nb_));
  w.terms.reserve(inv_.size());
  for (const ModalInvariants& inv : inv_) w.terms.emplace_back(inv.n);
  for (const JointModel& m : joints_) {
    w.jk.emplace_back(m);
    w.cr.emplace_back(m);
  }
  w.coords.assign(at(nj_), JointCoordsT<Cx>::Zero());
  w.F_grav_N.assign(at(nb_), V3<Cx>::Zero());
  w.M_grav_B.assign(at(nb_), V3<Cx>::Zero());
  w.nu_dot = Eigen::VectorXcd::Zero(nv_);
  w.y.assign(at(nj_ - 1), Vec6<Cx>::Zero());
  return w;
}

// pack() on Cx: the base, then every child from its parent (place_child), the attitudes normalised
// as body_pass() does, then zero_linear_momentum's rigid shift (shift_all(0, -linear_momentum() /
// total_mass())). Rotations turn on the right, q (1, i h dtheta / 2) (TreeTangent).
void NewtonEulerEngine::pack_cx(double t, const TreeState& s, const TreeTangent& ds, double h,
                                CxPass& w) const {
  const Cx ih(0.0, h);
  auto turned = [&](const Quaterniond& q, const Vector3d& dtheta) {  // q (1, i h dtheta / 2)
    const Quat<Cx> dq(Cx(1.0), 0.5 * ih * dtheta.x(), 0.5 * ih * dtheta.y(), 0.5 * ih * dtheta.z());
    return Quat<Cx>(q.cast<Cx>() * dq);
  };
  std::vector<BodyKinematicsT<Cx>>& bk = w.bk;
  Cx norm;
  // Flexible bodies' modal coordinates and rates, eta + i h d eta (read by the node frames).
  for (int b = 0; b < nb_; ++b) {
    if (modes(b) == 0) continue;
    const auto n = static_cast<Eigen::Index>(modes(b));
    if (at(b) >= s.eta.size() || at(b) >= s.eta_rate.size() || s.eta[at(b)].size() != n ||
        s.eta_rate[at(b)].size() != n)
      throw InputError(where(system_) + ": TreeState: body '" + system_.bodies[at(b)].name +
                       "' needs " + std::to_string(n) + " modal coordinates and rates");
    BodyKinematicsT<Cx>& k = bk[at(b)];
    k.eta = s.eta[at(b)].cast<Cx>();
    k.eta_dot = s.eta_rate[at(b)].cast<Cx>();
    if (at(b) < ds.eta.size() && ds.eta[at(b)].size() == n) k.eta += ih * ds.eta[at(b)].cast<Cx>();
    if (at(b) < ds.eta_rate.size() && ds.eta_rate[at(b)].size() == n)
      k.eta_dot += ih * ds.eta_rate[at(b)].cast<Cx>();
  }
  // A prescribed base: placed from N by joint 0 below (its profile at t: no tangent), as pack()
  // does; the TreeState's base pose is then not read.
  {
    BodyKinematicsT<Cx>& B = bk[at(joints_[0].child)];
    B.q_NB = unit_quaternion(turned(s.q_NB, ds.dtheta_B), norm);
    B.R_NB = B.q_NB.toRotationMatrix();
    B.p_NoBo_N = s.p_NoBo_N.cast<Cx>() + ih * ds.dp_NoBo_N.cast<Cx>();
    B.v_NBo_N = s.v_NBo_N.cast<Cx>() + ih * ds.dv_NBo_N.cast<Cx>();
    B.w_NB_B = s.w_NB_B.cast<Cx>() + ih * ds.dw_NB_B.cast<Cx>();
  }
  std::vector<JointKinematicsT<Cx>> jk = w.jk;  // node frames for the placement only
  for (int j = first_joint(); j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    const TreeState::JointState& js = s.joints[at(j)];
    const TreeTangent::JointTangent dj = m.prescribed ? TreeTangent::JointTangent{} : ds.joints[at(j)];
    const JointStateT<Cx> jc{js.angle + ih * dj.angle, js.rate + ih * dj.rate,
                             js.angle2 + ih * dj.angle2, js.rate2 + ih * dj.rate2,
                             turned(js.q_J, dj.dtheta_J), js.w_PC_C.cast<Cx>() + ih * dj.w_PC_C.cast<Cx>()};
    const BodyKinematicsT<Cx>& P = m.parent < 0 ? w.ground : bk[at(m.parent)];
    BodyKinematicsT<Cx>& C = bk[at(m.child)];
    NodeFrameT<Cx>& F = jk[at(j)].F;
    NodeFrameT<Cx>& G = jk[at(j)].G;
    node_frame(m.P, P, F);
    node_frame(m.C, C, G);
    Quat<Cx> q_J = Quat<Cx>::Identity();
    V3<Cx> w_FG_G = V3<Cx>::Zero(), r_F = V3<Cx>::Zero(), v_F = V3<Cx>::Zero();
    if (m.unit->cx->pack) m.unit->cx->pack(m, jc, q_J, w_FG_G, r_F, v_F);
    place_child(m, P, F, G, q_J, w_FG_G, r_F, v_F, C);
  }
  // body_pass(): the stored attitude normalised again (the momentum shift below changes only the
  // velocities, so the two commute).
  for (int b = 0; b < nb_; ++b) {
    BodyKinematicsT<Cx>& k = bk[at(b)];
    k.q_NB = unit_quaternion(k.q_NB, norm);
    if (!(real_part(norm) > 1e-6)) fail(t, labels_[at(pos(b) + 3)], "degenerate attitude quaternion");
    k.R_NB = k.q_NB.toRotationMatrix();
  }
  if (system_.zero_linear_momentum && !prescribed_base_) {
    // linear_momentum(): m v + R (w x S + p_rel) per body (modal_body.hpp; S and p_rel depend on
    // R, w, eta, eta', not on v), then shift_all.
    std::vector<ModalTermsT<Cx>> terms = w.terms;
    V3<Cx> L = V3<Cx>::Zero();
    for (int b = 0; b < nb_; ++b) {
      const BodyKinematicsT<Cx>& k = bk[at(b)];
      L += mass_[at(b)] * k.v_NBo_N;
      const int fi = flex_[at(b)];
      if (fi < 0) continue;
      modal_terms_t<Cx>(inv_[at(fi)], k.R_NB, k.w_NB_B, k.eta, k.eta_dot, terms[at(fi)]);
      L += k.R_NB * (tcross<Cx>(k.w_NB_B, terms[at(fi)].S) + terms[at(fi)].p_rel);
    }
    const V3<Cx> dv = -L / total_mass();
    for (BodyKinematicsT<Cx>& k : bk) k.v_NBo_N += dv;
  }
}

// body_pass() on Cx (rhs_tangent()): the stored attitude normalised by sqrt(w^2 + x^2 + y^2 + z^2)
// (analytic: a tangent off the unit sphere varies it), positions, velocities, modal coordinates.
void NewtonEulerEngine::body_pass_cx(double t, const Cx* x, CxPass& w) const {
  for (int b = 0; b < nb_; ++b) {
    BodyKinematicsT<Cx>& k = w.bk[at(b)];
    const Cx* xp = x + pos(b);
    const Cx* xv = x + vel(b);
    Cx n;
    k.q_NB = unit_quaternion(Quat<Cx>(xp[3], xp[4], xp[5], xp[6]), n);
    if (!(n.real() > 1e-6) || !std::isfinite(n.real()))
      fail(t, labels_[at(pos(b) + 3)], "degenerate attitude quaternion");
    k.R_NB = k.q_NB.toRotationMatrix();
    k.p_NoBo_N = V3<Cx>(xp[0], xp[1], xp[2]);
    k.v_NBo_N = V3<Cx>(xv[0], xv[1], xv[2]);
    k.w_NB_B = V3<Cx>(xv[3], xv[4], xv[5]);
    if (modes(b) > 0) {
      k.eta = Eigen::Map<const Eigen::VectorXcd>(xp + 7, modes(b));
      k.eta_dot = Eigen::Map<const Eigen::VectorXcd>(xv + 6, modes(b));
    }
  }
}

void NewtonEulerEngine::dynamics_cx(double t, CxPass& w) {
  const std::vector<BodyKinematicsT<Cx>>& bk = w.bk;
  // mass_pass(): each flexible body's mass matrix and velocity terms (modal_body.hpp) on Cx.
  for (int b = 0; b < nb_; ++b) {
    const int fi = flex_[at(b)];
    if (fi < 0) continue;
    const BodyKinematicsT<Cx>& k = bk[at(b)];
    modal_terms_t<Cx>(inv_[at(fi)], k.R_NB, k.w_NB_B, k.eta, k.eta_dot, w.terms[at(fi)]);
    if (!kkt_.set_mass(b, w.terms[at(fi)].M.real()))
      fail(t, system_.bodies[at(b)].name, "flexible body's mass matrix is not positive definite");
  }
  // joint_pass(): relative kinematics, rows, coordinates (unwrapped against coords_ref_).
  for (int j = first_joint(); j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    const BodyKinematicsT<Cx>& P = m.parent < 0 ? w.ground : bk[at(m.parent)];
    const BodyKinematicsT<Cx>& C = bk[at(m.child)];
    joint_kinematics(m, P, C, w.jk[at(j)]);
    constraint_rows(m, P, C, w.jk[at(j)], w.cr[at(j)]);
    if (m.unit->cx->track)
      m.unit->cx->track(system_.joints[at(j)], m, t, w.jk[at(j)], w.cr[at(j)], w.coords[at(j)],
                        coords_ref_[at(j)]);
  }
  // force_pass(): every body's moment row, the environment's loads, the joints' loads.
  Eigen::VectorXcd f = Eigen::VectorXcd::Zero(nv_);
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematicsT<Cx>& k = bk[at(b)];
    const Body& body = system_.bodies[at(b)];
    const int fi = flex_[at(b)];
    if (fi < 0) {
      f.segment<3>(nu(b) + 3) = rigid_moment<Cx>(body, I_B_[at(b)], t, k.R_NB, k.w_NB_B);
      continue;
    }
    f.segment(nu(b), 6 + modes(b)) = w.terms[at(fi)].f;
    if (!body.torque.empty()) {  // on the body frame: no work on eta
      const Vector3d T = body.torque.value(t);
      if (body.torque_frame == Body::Frame::Body) f.segment<3>(nu(b) + 3) += T.cast<Cx>();
      else f.segment<3>(nu(b) + 3) += k.R_NB.transpose() * T;
    }
  }
  if (!env_.none()) {
    const GravityField gf = gravity_field(t);
    for (int b = 0; b < nb_; ++b) {
      const BodyKinematicsT<Cx>& k = bk[at(b)];
      V3<Cx>& F_grav_N = w.F_grav_N[at(b)];
      V3<Cx>& M_grav_B = w.M_grav_B[at(b)];
      const int fi = flex_[at(b)];
      if (fi < 0) {
        rigid_gravity<Cx>(env_, mass_[at(b)], I_B_[at(b)], p_NoO_N_, gf.n2, gf.zhat_N, k.R_NB,
                          k.p_NoBo_N, F_grav_N, M_grav_B);
      } else {
        flexible_gravity<Cx>(b, gf, k, w.terms[at(fi)], f, F_grav_N, M_grav_B);
      }
      f.segment<3>(nu(b)) += F_grav_N;
      f.segment<3>(nu(b) + 3) += M_grav_B;
    }
  }
  for (int j = 1; j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    const JointKinematicsT<Cx>& k = w.jk[at(j)];
    V3<Cx> T_P, F_P;
    if (!m.unit->cx->load || !m.unit->cx->load(system_.joints[at(j)], m, k, w.coords[at(j)], t, T_P, F_P))
      continue;
    // torque_on_frame(): on the body and, through a node frame, on eta ((Jl Psi)^T T_B).
    const V3<Cx> T_C = k.R_PC.transpose() * T_P;
    f.segment<3>(nu(m.child) + 3) += T_C;
    if (m.C.modes > 0) f.segment(nu(m.child) + 6, m.C.modes).noalias() += k.G.JlPsi.transpose() * T_C;
    f.segment<3>(nu(m.parent) + 3) -= T_P;
    if (m.P.modes > 0) f.segment(nu(m.parent) + 6, m.P.modes).noalias() -= k.F.JlPsi.transpose() * T_P;
    if (!m.translates) continue;
    const V3<Cx> F_N = bk[at(m.parent)].R_NB * F_P;
    f.segment<3>(nu(m.child)) += F_N;
    f.segment<3>(nu(m.child) + 3) += tcross<Cx>(k.G.s_B, V3<Cx>(k.R_PC.transpose() * F_P));
    f.segment<3>(nu(m.parent)) -= F_N;
    f.segment<3>(nu(m.parent) + 3) -= tcross<Cx>(k.r_PoJ_F, F_P);
  }
  // load_kkt(): the real parts into the engine's KKT system, the imaginary parts kept (K_i, b_i).
  const int links = nj_ - 1;
  std::vector<Eigen::MatrixXd> JiP(at(links)), JiC(at(links));  // 6 x dofs(parent), 6 x dofs(child)
  std::vector<Vector6d> gamma_r(at(links)), gamma_i(at(links));
  for (int j = 1; j < nj_; ++j) {
    const ConstraintRowsT<Cx>& c = w.cr[at(j)];
    const int k = j - 1;
    Vec6<Cx> gamma_s = c.gamma;
    if (stabilization_ == Stabilization::Baumgarte) gamma_s -= alpha_ * c.gdot + beta_ * c.g;  // [Baum72]
    const JointModel& m = joints_[at(j)];
    kkt_.J_parent(k).leftCols<6>() = c.J_P.real();
    kkt_.J_child(k).leftCols<6>() = c.J_C.real();
    JiP[at(k)] = Eigen::MatrixXd::Zero(6, 6 + m.P.modes);
    JiC[at(k)] = Eigen::MatrixXd::Zero(6, 6 + m.C.modes);
    JiP[at(k)].leftCols<6>() = c.J_P.imag();
    JiC[at(k)].leftCols<6>() = c.J_C.imag();
    if (m.P.modes > 0) {
      kkt_.J_parent(k).rightCols(m.P.modes) = c.Je_P.real();
      JiP[at(k)].rightCols(m.P.modes) = c.Je_P.imag();
    }
    if (m.C.modes > 0) {
      kkt_.J_child(k).rightCols(m.C.modes) = c.Je_C.real();
      JiC[at(k)].rightCols(m.C.modes) = c.Je_C.imag();
    }
    gamma_r[at(k)] = gamma_s.real();
    gamma_i[at(k)] = gamma_s.imag();
  }
  Eigen::MatrixXd JiR = Eigen::MatrixXd::Zero(6, 6 + modes(joints_[0].child));  // a prescribed base's root rows
  Vector6d gamma_root_i = Vector6d::Zero();
  if (prescribed_base_) {
    const ConstraintRowsT<Cx>& c = w.cr[0];
    Vec6<Cx> gamma_s = c.gamma;
    if (stabilization_ == Stabilization::Baumgarte) gamma_s -= alpha_ * c.gdot + beta_ * c.g;  // [Baum72]
    kkt_.J_root().leftCols<6>() = c.J_C.real();
    JiR.leftCols<6>() = c.J_C.imag();
    const int n0 = joints_[0].C.modes;
    if (n0 > 0) {
      kkt_.J_root().rightCols(n0) = c.Je_C.real();
      JiR.rightCols(n0) = c.Je_C.imag();
    }
    kkt_.gamma_root() = gamma_s.real();
    gamma_root_i = gamma_s.imag();
  }
  // solve_pass(): K_r z_r = b_r, then K_r z_i = b_i - K_i z_r.
  if (!kkt_.factor()) fail(t, "constraints", "singular constraint system (KKT pivot not definite)");
  VectorXd nu_r = VectorXd::Zero(nv_), nu_i = VectorXd::Zero(nv_);
  std::vector<Vector6d> y_r(at(links), Vector6d::Zero()), y_i(at(links), Vector6d::Zero());
  kkt_.solve(f.real(), gamma_r, nu_r, y_r);
  const Vector6d y_root_r = kkt_.y_root();
  VectorXd f_i = f.imag();
  if (prescribed_base_) {
    const int ob = nu(joints_[0].child), db = static_cast<int>(JiR.cols());
    f_i.segment(ob, db).noalias() -= JiR.transpose() * y_root_r;
    gamma_root_i.noalias() -= JiR * nu_r.segment(ob, db);
    kkt_.gamma_root() = gamma_root_i;
  }
  for (int b = 0; b < nb_; ++b) {  // M_i: a flexible body's mass matrix depends on the state
    const int fi = flex_[at(b)];
    if (fi < 0) continue;
    const int d = 6 + modes(b);
    f_i.segment(nu(b), d).noalias() -= w.terms[at(fi)].M.imag() * nu_r.segment(nu(b), d);
  }
  for (int k = 0; k < links; ++k) {
    const KktLink& l = kkt_.link(k);
    const int rows = l.rows;
    const int op = nu(l.parent), oc = nu(l.child);
    const auto dp = JiP[at(k)].cols(), dc = JiC[at(k)].cols();
    f_i.segment(op, dp).noalias() -= JiP[at(k)].topRows(rows).transpose() * y_r[at(k)].head(rows);
    f_i.segment(oc, dc).noalias() -= JiC[at(k)].topRows(rows).transpose() * y_r[at(k)].head(rows);
    gamma_i[at(k)].noalias() -= JiP[at(k)] * nu_r.segment(op, dp) + JiC[at(k)] * nu_r.segment(oc, dc);
  }
  kkt_.solve(f_i, gamma_i, nu_i, y_i);
  if (!nu_i.allFinite()) fail(t, "tangent", "non-finite acceleration tangent");
  w.nu_dot.real() = nu_r;
  w.nu_dot.imag() = nu_i;
  for (int k = 0; k < links; ++k) {
    w.y[at(k)].real() = y_r[at(k)];
    w.y[at(k)].imag() = y_i[at(k)];
  }
  w.y_root.real() = y_root_r;
  w.y_root.imag() = kkt_.y_root();
}

bool NewtonEulerEngine::accelerations_tangent(double t, const TreeState& s, const TreeTangent& ds,
                                              TreeAccel& a, TreeAccel& da) {
  if (!tangent_covered_) return false;
  const CoordsGuard restore(*this);  // pack() below is not the run's

  // a: the run's own path, at x(0) = pack(s).
  std::vector<double> x0(at(nx_));
  pack(s, x0.data());
  accelerations(t, x0.data(), a);

  constexpr double h = 1e-30;
  CxPass w = cx_pass();
  pack_cx(t, s, ds, h, w);
  dynamics_cx(t, w);
  const std::vector<BodyKinematicsT<Cx>>& bk = w.bk;
  const Eigen::VectorXcd& nu_dot = w.nu_dot;
  // accelerations(): the bodies' entries, then the joints' from the complex body accelerations.
  da.wdot_NB_B.assign(at(nb_), Vector3d::Zero());
  da.a_NBo_N.assign(at(nb_), Vector3d::Zero());
  da.angle_ddot.assign(at(nj_), 0.0);
  da.angle2_ddot.assign(at(nj_), 0.0);
  da.wdot_PC_C.assign(at(nj_), Vector3d::Zero());
  da.eta_ddot.assign(at(nb_), VectorXd());
  for (int b = 0; b < nb_; ++b) {
    da.a_NBo_N[at(b)] = nu_dot.segment<3>(nu(b)).imag() / h;
    da.wdot_NB_B[at(b)] = nu_dot.segment<3>(nu(b) + 3).imag() / h;
    if (modes(b) > 0) da.eta_ddot[at(b)] = nu_dot.segment(nu(b) + 6, modes(b)).imag() / h;
  }
  for (int j = 1; j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    if (!m.unit->cx->accelerations) continue;
    // frame_angular_acceleration(): E^T (alpha_B + Jl Psi eta'' + c - w_rel x w_B) at a node.
    auto frame_alpha = [&](const JointSide& side, const NodeFrameT<Cx>& fr, int b) {
      const V3<Cx> alpha = nu_dot.segment<3>(nu(b) + 3);
      if (side.modes == 0) return alpha;
      return V3<Cx>(fr.E.transpose() * (alpha + fr.JlPsi * nu_dot.segment(nu(b) + 6, side.modes) + fr.c_B -
                                        tcross<Cx>(fr.w_rel_B, bk[at(b)].w_NB_B)));
    };
    const JointAccelInputsT<Cx> in{bk[at(m.parent)],
                                   bk[at(m.child)],
                                   w.jk[at(j)],
                                   frame_alpha(m.P, w.jk[at(j)].F, m.parent),
                                   frame_alpha(m.C, w.jk[at(j)].G, m.child),
                                   nu_dot.segment<6>(nu(m.parent)),
                                   nu_dot.segment<6>(nu(m.child))};
    JointAccelT<Cx> aj;
    m.unit->cx->accelerations(system_.joints[at(j)], m, in, t, aj);
    da.angle_ddot[at(j)] = aj.angle_ddot.imag() / h;
    da.angle2_ddot[at(j)] = aj.angle2_ddot.imag() / h;
    da.wdot_PC_C[at(j)] = aj.wdot_PC_C.imag() / h;
  }
  return true;
}

// The exact tangent of output_row() (core/engine.hpp; issue 27): the complex step of the same
// equations, written once (write_outputs(), templated on the scalar and the writer), on the state
// pack(s + i h ds) (pack_cx) and its solve (dynamics_cx: the joint loads' multipliers
// y = y_r + i y_i from the two real solves, so their variation carries the accelerations'). row is
// output_row(t, pack(s)) itself. The extra columns (constraint.pos, .vel, .ang, .angvel) have
// derivative zero: pack(s + e ds) places every child by its joint's own coordinates, so each
// joint's rows g and g' vanish for every e (a prescribed joint's and a prescribed base's rows are
// functions of their coordinates, which have no tangent: constant), and so does their largest norm;
// their |.| and max() are not differentiated at round-off (Griewank & Walther 2008, Ch. 3:
// nonsmooth elementaries have no tangent there).
bool NewtonEulerEngine::output_row_tangent(double t, const TreeState& s, const TreeTangent& ds, double* row,
                                           double* drow) {
  if (!tangent_covered_) return false;
  const CoordsGuard restore(*this);
  std::vector<double> x0(at(nx_));
  pack(s, x0.data());
  output_row(t, x0.data(), row);

  constexpr double h = 1e-30;
  CxPass w = cx_pass();
  pack_cx(t, s, ds, h, w);
  dynamics_cx(t, w);
  CxRowWriter out(layout_, row, drow, h);
  write_outputs<Cx>(t, w.view(), out);
  for (int c = violation0_; c < violation0_ + 4; ++c) drow[c] = 0.0;
  return true;
}

// The exact Jacobian-vector product of rhs() in this engine's own coordinates (core/engine.hpp;
// issue 27): the complex step through body_pass (the attitude's normalisation included: dx may
// leave the unit sphere; the stored, unnormalised q in q' = 1/2 q (x) (0, w), as rhs() has it),
// mass_pass, joint_pass (the coordinates unwrapped against the run's references, as rhs() finds
// them), force_pass, load_kkt (Baumgarte's terms alpha g' + beta g included: dx may leave the
// constraint manifold) and the solve (dynamics_cx). xdot is rhs(t, x) itself.
bool NewtonEulerEngine::rhs_tangent(double t, const double* x, const double* dx, double* xdot,
                                    double* dxdot) {
  if (!tangent_covered_) return false;
  rhs(t, x, xdot);
  constexpr double h = 1e-30;
  std::vector<Cx> xc(at(nx_));
  for (int i = 0; i < nx_; ++i) xc[at(i)] = Cx(x[i], h * dx[i]);
  CxPass w = cx_pass();
  body_pass_cx(t, xc.data(), w);
  dynamics_cx(t, w);
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematicsT<Cx>& k = w.bk[at(b)];
    const Cx* xp = xc.data() + pos(b);
    double* dp = dxdot + pos(b);
    for (int i = 0; i < 3; ++i) dp[i] = k.v_NBo_N(i).imag() / h;
    // rot::quat_rate_body on Cx: 1/2 q (x) (0, w_B), q the stored quaternion.
    const Cx qw = xp[3], qx = xp[4], qy = xp[5], qz = xp[6];
    const V3<Cx>& wb = k.w_NB_B;
    const Cx qd[4] = {0.5 * (-qx * wb.x() - qy * wb.y() - qz * wb.z()),
                      0.5 * (qw * wb.x() + qy * wb.z() - qz * wb.y()),
                      0.5 * (qw * wb.y() + qz * wb.x() - qx * wb.z()),
                      0.5 * (qw * wb.z() + qx * wb.y() - qy * wb.x())};
    for (int i = 0; i < 4; ++i) dp[3 + i] = qd[i].imag() / h;
    for (int i = 0; i < modes(b); ++i) dp[7 + i] = k.eta_dot(i).imag() / h;
  }
  for (int i = 0; i < nv_; ++i) dxdot[vel_[0] + i] = w.nu_dot(i).imag() / h;
  return true;
}

// The system's CM x_c = sum_i m_i x_i / sum_i m_i over every mass element, deformed [KLL83
// Sec. 4.5]: per body m p_NoBo_N + R_NB S (S = sum m_i r_i, modal_body.hpp; zero for a rigid body).
template <class S>
V3<S> NewtonEulerEngine::system_cm(const OutputState<S>& st) const {
  V3<S> first_moment = V3<S>::Zero();
  double total = 0;
  for (int b = 0; b < nb_; ++b) {
    first_moment += mass_[at(b)] * st.bk[at(b)].p_NoBo_N;
    if (flex_[at(b)] >= 0) first_moment += st.bk[at(b)].R_NB * st.terms[at(flex_[at(b)])].S;
    total += mass_[at(b)];
  }
  return first_moment / total;
}

// H_Scm_N = sum_i m_i (x_i - x_c) x (v_i - v_c) + sum R_NB J w about the system CM x_c over every
// mass element [KLL83 Sec. 4.5], N components. Per body (modal_body.hpp): linear momentum L_b =
// m v + R (w x S + Phi_bar eta'), angular momentum about its origin h_b = (R S) x v + R (I w +
// Lambda eta'); then H = sum_b h_b + (p_b - x_c) x L_b (the sum of m_i (x_i - x_c) over all
// elements is zero). The column H is its norm (RowWriter::momentum).
template <class S>
V3<S> NewtonEulerEngine::angular_momentum(const OutputState<S>& st, const V3<S>& x_c) const {
  V3<S> h = V3<S>::Zero();
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematicsT<S>& k = st.bk[at(b)];
    const int fi = flex_[at(b)];
    V3<S> L = mass_[at(b)] * k.v_NBo_N;
    if (fi < 0) {
      h += k.R_NB * (I_B_[at(b)] * k.w_NB_B);
    } else {
      const ModalTermsT<S>& mt = st.terms[at(fi)];
      const V3<S> S_N = k.R_NB * mt.S;
      L += k.R_NB * (tcross<S>(k.w_NB_B, mt.S) + mt.p_rel);
      h += tcross<S>(S_N, k.v_NBo_N) + k.R_NB * (mt.I * k.w_NB_B + mt.h_rel);
    }
    h += tcross<S>(k.p_NoBo_N - x_c, L);
  }
  return h;
}

// The linear momentum sum_b m v + R (w x S + p_rel) (linear_momentum(); on Cx from the modal
// terms' S and p_rel, the same sums as modal_first_moments()).
template <class S>
V3<S> NewtonEulerEngine::linear_momentum(const OutputState<S>& st) const {
  if constexpr (kIsReal<S>) {
    (void)st;
    return linear_momentum();  // the run's: st is run_state() (bk_)
  } else {
    V3<S> sum = V3<S>::Zero();
    for (int b = 0; b < nb_; ++b) {
      const BodyKinematicsT<S>& k = st.bk[at(b)];
      sum += mass_[at(b)] * k.v_NBo_N;
      const int fi = flex_[at(b)];
      if (fi < 0) continue;
      sum += k.R_NB * (tcross<S>(k.w_NB_B, st.terms[at(fi)].S) + st.terms[at(fi)].p_rel);
    }
    return sum;
  }
}

// Kinetic energy 1/2 nu^T M nu of every body (modal_body.hpp), plus the modal strain energy
// 1/2 eta^T K eta and the joint springs' potential (core/system.hpp).
template <class S>
S NewtonEulerEngine::energy(const OutputState<S>& st) const {
  using MX = Eigen::Matrix<S, Eigen::Dynamic, Eigen::Dynamic>;
  S e = 0;
  for (int b = 0; b < nb_; ++b) {
    const BodyKinematicsT<S>& k = st.bk[at(b)];
    const int fi = flex_[at(b)];
    e += 0.5 * mass_[at(b)] * tsquared_norm<S>(k.v_NBo_N);
    if (fi < 0) {
      e += 0.5 * tdot<S>(k.w_NB_B, I_B_[at(b)] * k.w_NB_B);
      continue;
    }
    const ModalTermsT<S>& mt = st.terms[at(fi)];
    const ModalInvariants& inv = inv_[at(fi)];
    const S modal_kinetic = inv.stiffening ? tdot<S>(k.eta_dot, MX(mt.M.bottomRightCorner(inv.n, inv.n)) * k.eta_dot)
                                           : tdot<S>(k.eta_dot, inv.M_ee * k.eta_dot);
    e += tdot<S>(k.v_NBo_N, k.R_NB * (tcross<S>(k.w_NB_B, mt.S) + mt.p_rel)) +
         0.5 * tdot<S>(k.w_NB_B, mt.I * k.w_NB_B) + tdot<S>(k.w_NB_B, mt.h_rel) + 0.5 * modal_kinetic +
         0.5 * tdot<S>(k.eta, inv.K * k.eta);
  }
  for (int j = 1; j < nj_; ++j) {
    const Joint& J = system_.joints[at(j)];
    const JointModel& m = joints_[at(j)];
    const auto potential = potential_verb<S>(*m.unit);
    if ((J.stiffness == 0 && J.stiffness2 == 0) || !potential) continue;
    potential(J, m, st.jk[at(j)], st.coords[at(j)], e);
  }
  return e;
}

// The multiplier of a prescribed joint's angle row (joint_constraints.hpp): the constraint
// generalised force J^T lambda it adds is the moment lambda_5 R_GF a_P on the child-side frame G
// and -lambda_5 a_P on the parent-side frame F, so lambda_5 = -y_5 is the torque about the axis on
// the child (docs/prescribed-motion.md "State, output, accelerations"; rows 3-4 act about
// c_k = u x b_k, normal to the axis). A prescribed prismatic joint's row 5 is its position along
// the axis (joints/prismatic.cpp): J_C^T lambda_5 is the force lambda_5 R_NP a_P at the child's
// joint point, so -y_5 is its force along the axis on the child.
template <class S>
S NewtonEulerEngine::torque(const OutputState<S>& st, int j) const {
  if (j == 0) return -st.y_root(5);
  return -st.y[at(j - 1)](5);
}

// Joint j's load on its child: everything that passes from the parent to the child through the
// joint (docs/conventions.md "Joint loads"), reduced to a force F_C and a moment M_J_C about the
// joint point J, both in the child's body frame C.
//   Constraint part [Haug89 Sec. 6.3; Paper Eqs. (1), (2), (7)]: the multipliers lambda = -y of
//   the solve at (t, x) (the same KKT system as rhs(), so the same accelerations: their reading at
//   this state, Baumgarte's terms included when that stabilisation is on) act on the child as the
//   generalised force J_C^T lambda in its [v_NCo_N; w_NC_C] columns: the constraint force F_N
//   (N components) and its moment about Co, M_Co_C (C components: the generalised force of w in
//   body axes is the moment about the origin; on a flexible child at a node the force acts at the
//   displaced point s_C = p_i + u_i and the rows' couples on the node frame G, E A^T lambda).
//   Moved to J (s_C = jk.G.s_B, the joint point from Co in C; a prismatic joint's point on the
//   child) [Feath08 Eq. 2.26]: M_J_C = M_Co_C - s_C x F_C, F_C = R_CN F_N.
//   Applied part (core/system.hpp "Loads", the unit's load verb, as force_pass() applies it): the
//   torque T_P on the child-side frame (P components) and, along a translation, the force F_P at
//   the child's joint point: F_C += R_CP F_P (at J: no moment about J), M_J_C += R_CP T_P.
template <class S>
void NewtonEulerEngine::joint_load(int j, double t, const OutputState<S>& st, V3<S>& F_C,
                                   V3<S>& M_J_C) const {
  const JointModel& m = joints_[at(j)];
  const JointKinematicsT<S>& jk = st.jk[at(j)];
  const Vec6<S>& y = j == 0 ? st.y_root : st.y[at(j - 1)];
  const Vec6<S> wrench = -(st.cr[at(j)].J_C.transpose() * y);  // [F_N; M_Co_C]
  F_C.noalias() = st.bk[at(m.child)].R_NB.transpose() * wrench.template head<3>();
  M_J_C = wrench.template tail<3>() - tcross<S>(jk.G.s_B, F_C);
  V3<S> T_P, F_P;
  const auto load = load_verb<S>(*m.unit);
  if (load && load(system_.joints[at(j)], m, jk, st.coords[at(j)], t, T_P, F_P)) {
    M_J_C.noalias() += jk.R_PC.transpose() * T_P;
    if (m.translates) F_C.noalias() += jk.R_PC.transpose() * F_P;
  }
}

// The pinned columns at one state (core/output_layout.hpp; equations in newton_euler.hpp
// "Outputs"), on S through the writer W.
template <class S, class W>
void NewtonEulerEngine::write_outputs(double t, const OutputState<S>& st, W& out) const {
  out.time(t);
  for (int b = 0; b < nb_; ++b) {
    out.body(b, st.bk[at(b)].w_NB_B, st.bk[at(b)].q_NB);
    if (modes(b) > 0) out.modal(b, st.bk[at(b)].eta, st.bk[at(b)].eta_dot);
  }
  for (int j = first_joint(); j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    if (const auto output = output_verb<S>(*m.unit))  // the pinned joint columns (core/output_layout.hpp)
      output(out, j, system_.joints[at(j)], m, st.jk[at(j)], st.coords[at(j)],
             m.prescribed ? torque(st, j) : S(0.0), t);
  }
  const V3<S> p_NoScm_N = system_cm(st);
  const V3<S> H_Scm_N = angular_momentum(st, p_NoScm_N);
  out.momentum(H_Scm_N);
  const S E = energy(st) + gravity_potential(t, st);  // kinetic, strain, springs; gravity's V
  out.energy(E);
  if (env_.orbit()) {
    // The Jacobi integral J = E - w_NO_N . H_O_N (core/system.hpp "Environment"; Schaub &
    // Junkins 2018, Sec. 4.3), H about O: H_O_N = H_Scm_N + M (p_cm - p_NoO_N) x v_cm
    // [KLL83 Sec. 4.5], v_cm the system CM's velocity (linear momentum / M).
    const double M = total_mass();
    const V3<S> v_cm_N = linear_momentum(st) / M;
    const V3<S> H_O_N = H_Scm_N + M * tcross<S>(p_NoScm_N - p_NoO_N_, v_cm_N);
    out.jacobi(E - tdot<S>(orbit_frame(env_, t).w_NO_N, H_O_N));
  }
  for (int b = 0; b < nb_; ++b) out.body_position(b, st.bk[at(b)].p_NoBo_N);
  out.system_cm(p_NoScm_N);

  // Joint loads; the power P of the non-conservative loads and the external moment about the
  // system CM, M_Scm_N (docs/conventions.md "Power and external moment"; newton_euler.hpp).
  S P = 0;
  V3<S> M_Scm_N = V3<S>::Zero();
  for (int j = first_joint(); j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    V3<S> F_C, M_J_C;
    joint_load(j, t, st, F_C, M_J_C);
    out.joint_load(j, F_C, M_J_C);
    if (const auto power = power_verb<S>(*m.unit))  // motors, dampers (the scene's), a drive
      P += power(system_.joints[at(j)], m, st.jk[at(j)], m.prescribed ? torque(st, j) : S(0.0), t);
    if (j == 0) {  // a prescribed base: N's load on it is external, moved to the CM [Feath08 2.26]
      const BodyKinematicsT<S>& B = st.bk[at(m.child)];
      const V3<S> F_N = B.R_NB * F_C;
      const V3<S> p_NoJ_N = B.p_NoBo_N + B.R_NB * st.jk[0].G.s_B;
      M_Scm_N += B.R_NB * M_J_C + tcross<S>(p_NoJ_N - p_NoScm_N, F_N);
    }
  }
  for (int b = 0; b < nb_; ++b) {
    const Body& body = system_.bodies[at(b)];
    const BodyKinematicsT<S>& k = st.bk[at(b)];
    // Gravity (force_pass() of this state's solve): its resultant F_grav_N through Bo and its
    // moment about Bo, moved to the system CM [Feath08 Eq. 2.26]. Conservative: not in P.
    if (!env_.none())
      M_Scm_N += tcross<S>(k.p_NoBo_N - p_NoScm_N, st.F_grav_N[at(b)]) + k.R_NB * st.M_grav_B[at(b)];
    if (!body.torque.empty()) {  // external torque: power T . w_NB (on the body frame), moment T
      const Vector3d T = body.torque.value(t);
      const bool in_B = body.torque_frame == Body::Frame::Body;
      const V3<S> T_B = in_B ? V3<S>(T.template cast<S>()) : V3<S>(k.R_NB.transpose() * T);
      P += tdot<S>(T_B, k.w_NB_B);
      M_Scm_N += in_B ? V3<S>(k.R_NB * T) : V3<S>(T.template cast<S>());
    }
    // Modal damping, the scene's D (core/system.hpp "FlexBody"): power -eta'^T D eta'.
    if (!body.flex || body.flex->D.size() == 0) continue;
    const Eigen::MatrixXd& D = body.flex->D;
    for (int r = 0; r < modes(b); ++r)
      for (int c = 0; c < modes(b); ++c) P -= k.eta_dot(r) * D(r, c) * k.eta_dot(c);
  }
  out.power(P);
  out.external_moment(M_Scm_N);
}

// One output row at (t, x) (core/output_layout.hpp; equations in newton_euler.hpp "Outputs").
void NewtonEulerEngine::output_row(double t, const double* x, double* row) {
  dynamics(t, x);  // the joint loads need this state's accelerations and multipliers
  RowWriter out(layout_, row);
  write_outputs(t, run_state(), out);

  double pos_violation = 0, vel_violation = 0, ang_violation = 0, angvel_violation = 0;
  for (int j = 1; j < nj_; ++j) {
    const JointModel& m = joints_[at(j)];
    const JointKinematics& jk = jk_[at(j)];
    const ConstraintRows& cr = cr_[at(j)];
    if (!m.unit->point_rows) {  // the common rows 0-2: the joint point (else the unit's)
      pos_violation = std::max(pos_violation, cr.g.head<3>().norm());
      vel_violation = std::max(vel_violation, cr.gdot.head<3>().norm());
    }
    if (m.unit->violation)
      m.unit->violation(m, jk, cr, pos_violation, vel_violation, ang_violation, angvel_violation);
  }
  if (prescribed_base_) {
    const ConstraintRows& cr = cr_[0];
    pos_violation = std::max(pos_violation, cr.g.head<3>().norm());
    vel_violation = std::max(vel_violation, cr.gdot.head<3>().norm());
    ang_violation = std::max(ang_violation, cr.g.tail<3>().cwiseAbs().maxCoeff());
    angvel_violation = std::max(angvel_violation, cr.gdot.tail<3>().cwiseAbs().maxCoeff());
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
