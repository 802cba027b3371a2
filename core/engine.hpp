// The one interface every dynamics engine implements, and the engine-neutral state used to start
// engines from the same point and compare them there. Engines never call each other: they meet
// only through this interface (see docs/development.md "Independence").
//
// Life of an engine object (const model, mutable workspace; docs/style.md item 1):
//   Engine e(system, options);   // preallocates its workspace; may throw InputError
//   e.pack(tree_state, x);       // engine-neutral state => the engine's own state vector x
//   e.rhs(t, x, xdot);           // (t, x) => xdot; no heap allocation; called by the integrator
//   e.after_step(t, x);          // after each accepted step: renormalise, project, re-chart
//   e.output_row(t, x, row);     // (t, x) => one CSV row, layout() order (core/output_layout.hpp)
#pragma once

#include "core/names.hpp"
#include "core/output_layout.hpp"
#include "core/system.hpp"

#include <memory>
#include <string>
#include <vector>

namespace crossdyn {

// Engine-neutral generalised state of a tree of rigid and flexible bodies.
// joints[j] describes System::joints[j]; only the fields of that joint's type are used.
struct TreeState {
  // Base (the free joint, joints[0]). When the base is a prescribed revolute joint to N
  // (System::base_is_free() false), these follow from its prescribed angle (initial() sets them
  // for t = 0).
  //
  // Prescribed joints (docs/prescribed-motion.md): their angle and rate here, and a prescribed
  // base's pose and velocity above, must be those of the profile at the time the run starts
  // (initial() gives t = 0). Engines that keep body poses in their state (newton-euler) place
  // bodies from them; the others take the prescribed motion from the profile at t.
  Eigen::Vector3d p_NoBo_N = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_NB = Eigen::Quaterniond::Identity();
  Eigen::Vector3d v_NBo_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d w_NB_B = Eigen::Vector3d::Zero();
  struct JointState {
    double angle = 0, rate = 0;    // revolute (rad, rad/s), prismatic (m, m/s), universal axis 1
    double angle2 = 0, rate2 = 0;  // universal axis 2
    Eigen::Quaterniond q_J = Eigen::Quaterniond::Identity();   // spherical (R_J of system.hpp)
    Eigen::Vector3d w_PC_C = Eigen::Vector3d::Zero();          // spherical
  };
  std::vector<JointState> joints;
  // Per body (System::bodies order) modal coordinates eta and their rates (size 0 for a rigid
  // body). For a flexible base, p_NoBo_N, q_NB, v_NBo_N, w_NB_B describe its body frame (origin at
  // the undeformed CM), not the deformed CM.
  std::vector<Eigen::VectorXd> eta, eta_rate;

  // The scene's initial conditions (System::joints[*] initial values). When
  // System::zero_linear_momentum is set, v_NBo_N is a placeholder: pack() must replace it by the
  // base velocity that makes the total linear momentum zero.
  static TreeState initial(const System& system);
  // A prescribed base (System::base_is_free() false, rigidly attached) at joint angle `angle` and
  // rate `rate`: sets p_NoBo_N, q_NB, v_NBo_N, w_NB_B (docs/prescribed-motion.md "Kinematics").
  void place_prescribed_base(const Joint& base, double angle, double rate);
};

// A first-order variation (tangent) of a TreeState, the direction of an exact linearisation
// (issue 27, harness/linearize.hpp): the state s + e ds for a small e, with
//   p_NoBo_N + e dp_NoBo_N, v_NBo_N + e dv_NBo_N, w_NB_B + e dw_NB_B (components as in TreeState),
//   R_NB exp(e [dtheta_B x])     the base's attitude turned about body-frame axes (a right
//                                 perturbation: Sola, Deray and Atchuthan 2018, "A micro Lie
//                                 theory", Eq. (25)),
//   R_J exp(e [dtheta_J x])      a spherical joint's rotation, likewise in its child frame,
// and every other field of TreeState plus e times the field of the same name here. Sized by
// zero(system); a prescribed joint's (and a prescribed base's) fields are ignored: it follows its
// profile. When System::zero_linear_momentum is set, dv_NBo_N is ignored like v_NBo_N: the base
// velocity is the one pack() derives, and so is its variation.
struct TreeTangent {
  Eigen::Vector3d dp_NoBo_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d dtheta_B = Eigen::Vector3d::Zero();
  Eigen::Vector3d dv_NBo_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d dw_NB_B = Eigen::Vector3d::Zero();
  struct JointTangent {
    double angle = 0, rate = 0, angle2 = 0, rate2 = 0;
    Eigen::Vector3d dtheta_J = Eigen::Vector3d::Zero();
    Eigen::Vector3d w_PC_C = Eigen::Vector3d::Zero();
  };
  std::vector<JointTangent> joints;
  std::vector<Eigen::VectorXd> eta, eta_rate;

  // Every field zero, sized for the system (joints, and per body its modes).
  static TreeTangent zero(const System& system);
};

// s + e ds as defined above (rotations turned on the right by exact exponentials): the state a
// tangent points to, for differencing an engine along it. ds sized by TreeTangent::zero for s's
// system (a body whose modal sizes differ keeps its modal coordinates).
TreeState moved_along(const TreeState& s, const TreeTangent& ds, double e);

// Engine-neutral accelerations at one state, for cross-checking engines (STYLE item 6).
struct TreeAccel {
  std::vector<Eigen::Vector3d> wdot_NB_B;  // per body: d/dt of w_NB_B components (rad/s^2)
  std::vector<Eigen::Vector3d> a_NBo_N;    // per body: CM acceleration in N (m/s^2)
  std::vector<double> angle_ddot;          // per joint: revolute angle acceleration (prismatic:
                                           // position, m/s^2; universal: the first angle's; else
                                           // 0; a prescribed joint's theta''(t))
  std::vector<double> angle2_ddot;         // per joint: universal second angle's (else 0)
  std::vector<Eigen::Vector3d> wdot_PC_C;  // per joint: spherical d/dt of w_PC_C components
  std::vector<Eigen::VectorXd> eta_ddot;   // per body: modal accelerations (size 0: rigid)
};

struct EngineOptions {
  // Newton-Euler constraint stabilisation: projection (default), baumgarte, none (core/names.hpp).
  Choice<ConstraintStabilization> stabilization = ConstraintStabilization::Projection;
  double baumgarte_alpha = 10.0;  // 1/s, velocity-error gain  (Baumgarte 1972)
  double baumgarte_beta = 25.0;   // 1/s^2, position-error gain
  // Lagrange: re-chart Euler angles near their singularity (false: stop with an error there).
  bool rechart = true;
  // Test-only hook: scale every body's inertia tensor (not its mass) seen by this engine instance,
  // so that the harness can be shown to catch a wrong engine. 1 in every real run.
  double test_inertia_scale = 1.0;
  // Test-only hook (issue 26): scale every joint damper's and every modal damper's load in the
  // equations of motion by this factor, but not in the power column P, which keeps the scene's
  // damper (P = -c rate^2, -eta'^T D eta'). A damper whose load is wrong in the equations of
  // motion then fails the energy balance E(t) - E(0) = integral of P. 1 in every real run.
  double test_damper_scale = 1.0;
  // Test-only hook (issue 27): +1, or -1 to flip the sign of the gyroscopic term w x (I w) of
  // every rigid body's (and a flexible body's rigid-inertia) moment equation in an engine that
  // implements it (kane), so that `crossdyn linearize` can be shown to catch a wrong gyroscopic
  // sign at a steady spin. 1 in every real run.
  double test_gyroscopic_sign = 1.0;
  // Test-only hook (issue 28): +1, or -1 to flip the sign of the gravity-gradient torque
  // 3 n^2 zhat x (I_N zhat) on every rigid body (and on every flexible node's own inertia J_i) in the
  // equations of motion of an engine that implements it (lagrange), but not in E or J, so that the
  // harness can be shown to catch it. 1 in every real run.
  double test_gravity_gradient_sign = 1.0;
};

class Engine {
 public:
  virtual ~Engine() = default;
  virtual const char* name() const = 0;
  virtual int state_size() const = 0;
  // Human-readable name of state component i (used in failure messages: "main.wx", "hinge1.angle").
  virtual std::string state_label(int i) const = 0;

  // TreeState => x (size state_size()).
  virtual void pack(const TreeState& s, double* x) = 0;
  // (t, x) => xdot. Must not allocate. Must not throw except RunFailure and cancel::Cancelled
  // (long loops call cancel::poll(), core/cancel.hpp; so may the constructor).
  virtual void rhs(double t, const double* x, double* xdot) = 0;
  // Called after every accepted step. May change x (renormalise quaternions, project onto the
  // constraint manifold, switch Euler-angle charts); returns true when it did, so the integrator
  // restarts (FSAL and dense-output steppers must not reuse stale derivatives). May throw
  // RunFailure (for example at an Euler-angle singularity with re-charting off).
  virtual bool after_step(double t, double* x) { (void)t; (void)x; return false; }
  // The constraint projection of after_step() alone, for an integrator that projects inside its
  // steps (CVODE's BDF: CVodeSetProjFn, so that its multistep history stays on the manifold and
  // need not be restarted after every step). May be called on trial states of steps that are later
  // rejected: it moves x onto the constraint manifold and changes nothing else in the engine.
  // projects() says whether the engine has such a projection in this run.
  virtual bool projects() const { return false; }
  virtual void project_state(double t, double* x) { (void)t; (void)x; }
  // (t, x) => engine-neutral accelerations.
  virtual void accelerations(double t, const double* x, TreeAccel& a) = 0;
  // Output columns (core/output_layout.hpp): the pinned ones first, then engine-specific extras.
  virtual const OutputLayout& layout() const = 0;
  const std::vector<std::string>& columns() const { return layout().names(); }
  // (t, x) => one row of layout().size() values, written through a RowWriter on layout().
  virtual void output_row(double t, const double* x, double* row) = 0;

  // The exact first-order variation of accelerations() along a tangent (issue 27): with
  // x(e) = pack(s + e ds) (TreeTangent),
  //   a  = accelerations(t, x(0)),   da = d/de accelerations(t, x(e)) at e = 0, every field,
  // differentiated by the engine's own means through its own pack() and equations of motion
  // (automatic differentiation or complex step, never differences), so that its linear model
  // carries only rounding. Returns false when the engine offers none (the caller then differentiates
  // numerically and says so). Allocates; for linearisation and tests, never the hot path. May throw
  // RunFailure like accelerations().
  virtual bool accelerations_tangent(double t, const TreeState& s, const TreeTangent& ds, TreeAccel& a,
                                     TreeAccel& da) {
    (void)t;
    (void)s;
    (void)ds;
    (void)a;
    (void)da;
    return false;
  }

  // The exact first-order variation of output_row() along a tangent (issue 27: the output matrix C
  // of a linear model), by the same means and rules as accelerations_tangent(): with
  // x(e) = pack(s + e ds),
  //   row = output_row(t, x(0)),   drow = d/de output_row(t, x(e)) at e = 0,
  // every column of layout() (each array layout().size() long; the time column's derivative 0).
  // Columns that depend on the accelerations (joint loads, a prescribed base's reaction, external
  // moments) carry their variation through the accelerations' own. A quaternion column's derivative
  // is that of the sign output_row() writes (canonical, qw >= 0: the sign of the value part). Returns
  // false when the engine offers none (the caller then differences output_row() and says so).
  // Allocates; never the hot path. May throw RunFailure like output_row().
  virtual bool output_row_tangent(double t, const TreeState& s, const TreeTangent& ds, double* row,
                                  double* drow) {
    (void)t;
    (void)s;
    (void)ds;
    (void)row;
    (void)drow;
    return false;
  }

  // The exact first-order variation of rhs() in the engine's own coordinates (issue 27: the
  // Jacobian d(rhs)/dx that `crossdyn linearize` reports per engine as own_A):
  //   xdot = rhs(t, x),   dxdot = d/de rhs(t, x + e dx) at e = 0,
  // for any dx of state_size() (also one that leaves the engine's constraint manifold or a
  // quaternion's unit sphere: rhs() as it is evaluated there), with the engine's internal choices
  // (an Euler-angle chart) as rhs() would find them. Same means and rules as
  // accelerations_tangent(); false when the engine offers none.
  virtual bool rhs_tangent(double t, const double* x, const double* dx, double* xdot, double* dxdot) {
    (void)t;
    (void)x;
    (void)dx;
    (void)xdot;
    (void)dxdot;
    return false;
  }

  // The linear system the engine solves for its accelerations at (t, x), written out dense:
  // A z = b, A square and symmetric (a mass matrix, or a KKT matrix [M J^T; J 0]), so that its
  // conditioning can be measured (harness: `crossdyn study --scaling`, the condition number
  // sigma_max / sigma_min against chain length). z(i) = xdot[speed_index[i]] for i <
  // speed_index.size() (the speed equations' unknowns, as rhs() would return them at (t, x)); the
  // rest of z, if any, are multipliers. `what` names the system in a few words ("Kane's equations
  // M u' = f, 24 generalised speeds"). Allocates; for tests and diagnostics, never the hot path.
  // An engine that does not provide it returns A empty.
  struct LinearSystem {
    Eigen::MatrixXd A;
    Eigen::VectorXd b;
    std::vector<int> speed_index;
    std::string what;
  };
  virtual LinearSystem linear_system(double t, const double* x) {
    (void)t;
    (void)x;
    return {};
  }
};

}  // namespace crossdyn
