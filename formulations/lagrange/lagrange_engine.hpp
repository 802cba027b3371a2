// The Lagrange engine: Lagrange's equations in quasi-coordinates (Boltzmann-Hamel form), with the
// coordinates of MBODY (reference paper, Eqs. 15-23). Internal header: the harness uses only the
// factory in lagrange.hpp; tests use the inspection methods below.
//
// Coordinates and quasi-velocities (paper Eqs. 15-19), one block per joint in System::joints order:
//   joint       q* (generalised coordinates)               pi' (quasi-velocities)
//   free base   p_NoBo_N (3), Euler angles of R_NB (3)     v_NBo_N (3), w_NB_B (3)
//   revolute    angle (1)                                  rate (1)
//   spherical   Euler angles of R_J = R(q_J) (3)           w_PC_C (3), relative, child frame
//   fixed       -                                          -
//   then, when the joint's child is flexible, its modal coordinates eta (n) and rates eta' (n):
//   true coordinates and their true velocities, as in the paper's q* (Eq. 15, the q_j of the
//   vibrational modes).
// so q* and pi' have the same length n and block layout, and d(pi) = A(q*) dq* (Eq. 16) with A
// block-diagonal: identity except the Euler blocks, where A is the matrix of euler_chart.hpp.
// State x = (q*, pi'), size 2n.
//
// Flexible bodies (docs/flexible-bodies.md; flex_body.hpp). A flexible body's kinetic energy is
// written exactly, every term second order in eta kept, as a quadratic form in its body-axes
// twist (w_NB_B, v_NBo_B, eta') with an eta-dependent inertia M_B(eta) built from modal inertia
// invariants summed once over the nodes (Meirovitch 1991, J. Guidance 14(5): T of a flexible body
// in quasi-coordinates), so T, and everything the engine derives from it, costs O(modes^2) per
// body and nothing per node. V gains eta^T K eta / 2; modal damping is the generalised force
// -D eta'. A joint at a node: its point is the node's deformed position p_i + Phi_i eta and its
// frame the body frame turned by exp([psi x]), psi = Psi_i eta (exact Rodrigues form; the node
// frame's angular velocity relative to the body is Jl(psi) Psi_i eta'); these enter the pose and
// twist passes, so M, p, (dM/dt) pi' and the gradient of L come out of the same machinery as for
// rigid bodies. Hinge torques act on the child-side joint frame with the reaction on the
// parent-side one: their virtual power is tau . (relative rate), so they load the joint's rates
// only (lagrange_engine.cpp, "Joint dampers and motors"). Body torques act on the body frame and
// do no work on eta. The model is read as written in docs/flexible-bodies.md; where it leaves a
// choice: a joint's point on a node side is the node's own p_i (the constructor checks that
// Joint::p_PoJ_P / p_CoJ_C equal it), the body's mass and inertia are the node sums (Body::mass and
// Body::I_BBo_B are not used for a flexible body), and sum m_i p_i is kept in T as summed (zero
// to rounding for a body whose origin is its undeformed CM).
//
// Equations of motion (paper Eq. 23; Whittaker 1944, Ch. II, equations for quasi-coordinates;
// Meirovitch 1970, Ch. 4, Lagrange's equations in terms of quasi-coordinates), with B = A^-1
// (Eq. 22), T(q*, pi') the kinetic energy, V(q*) the hinge-spring potential, p = dT/dpi'. They
// follow from Lagrange's equations in q* (Eq. 20) with dT/dq*' = A^T p, multiplied by B^T:
//   d/dt p + B^T W^T p - B^T d(T - V)/dq* = N
//   W_lk = sum_j (dA_lk/dq*_j - dA_lj/dq*_k) q*'_j        (Hamel's transitivity terms: the
//                                                            paper's C matrix is B^T W^T)
// and N = B^T Q the generalised forces of dampers, motors and external torques for the
// quasi-velocities (virtual power N . pi'). T is quadratic in pi': T = pi'^T M(q*) pi' / 2, so
//   d/dt p = M pi'' + (dM/dt) pi'   and   M pi'' = N + B^T d(T - V)/dq* - (dM/dt) pi' - B^T W^T p.
// T is written once, as a function of (q*, pi'), and V as a function of q*; their derivatives are
// taken by forward-mode automatic differentiation (autodiff.hpp), and M and p come from T's
// polarisation on unit quasi-velocity seeds (lagrange_engine.cpp, "Passes"). Only the kinematic
// relation A (euler_chart.hpp) is written by hand; Hamel's terms are AD derivatives of it.
//
// Singularities. Each Euler-angle set (base, spherical joints) lives in one of six charts
// (euler_chart.hpp); the current chart per set is workspace state. after_step() re-charts a set
// whose middle angle passes kRechartDeg, re-initialised from the same attitude (outputs do not
// jump: they depend on the attitude and on pi', neither of which changes); with
// EngineOptions::rechart == false it throws RunFailure once the middle angle passes kFailDeg.
// Both tests also look at the step since the last accepted state (pack() starts it): a middle
// angle that crossed a lock (90 deg + k 180 deg) in between, as a long step does in a spin, is
// re-charted at once, or with rechart == false stops the run at the crossing time interpolated
// between the two states, whatever the integrator's steps (lagrange_engine.cpp, "after_step").
// after_step() also brings a first or third angle back to (-pi, pi] once it exceeds 4 pi (they grow
// without bound in a spin), so that the integrator's tolerances keep their meaning.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "core/engine.hpp"

namespace crossdyn::lagrange {

inline constexpr double kPackDeg = 60.0;     // pack(): keep the default chart up to this |a2|
inline constexpr double kRechartDeg = 75.0;  // after_step(): re-chart beyond this |a2|
inline constexpr double kFailDeg = 89.0;     // rechart == false: stop beyond this |a2|

class LagrangeEngine final : public Engine {
 public:
  LagrangeEngine(const System& system, const EngineOptions& options);
  ~LagrangeEngine() override;
  LagrangeEngine(const LagrangeEngine&) = delete;
  LagrangeEngine& operator=(const LagrangeEngine&) = delete;

  const char* name() const override { return "lagrange"; }
  int state_size() const override;
  std::string state_label(int i) const override;
  void pack(const TreeState& s, double* x) override;
  void rhs(double t, const double* x, double* xdot) override;
  bool after_step(double t, double* x) override;
  void accelerations(double t, const double* x, TreeAccel& a) override;
  const OutputLayout& layout() const override;
  void output_row(double t, const double* x, double* row) override;
  // The system the solve pass factors at (t, x), in the chart x is in (the workspace's current
  // charts; nothing is re-charted): A = M (d2T/dpi'2, symmetric), b = N + B^T dL/dq* - (dM/dt) pi'
  // - B^T W^T p (paper Eq. 23; Whittaker 1944, Ch. II; Meirovitch 1970, Ch. 4), z = pi'', i.e.
  // speed_index = nf ... 2 nf - 1. With prescribed joints, the free block the engine solves
  // (lagrange_engine.cpp, "solve"): A = M_ff, b = f_f - M_fc theta''. Allocates.
  LinearSystem linear_system(double t, const double* x) override;

  // ---- Inspection (tests, reports) ----
  // The state x holds the free coordinates and quasi-velocities only; a prescribed joint's angle
  // and rate come from its profile at t (docs/prescribed-motion.md). Methods below taking a state
  // x take the time t for that (ignored when nothing is prescribed).
  int dof() const;                           // the number of free quasi-velocities (x is 2 dof())
  long recharts() const;                     // charts switched since construction
  long lock_crossings() const;               // of which after a lock crossed within a step
  int euler_sets() const;                    // number of Euler-angle sets
  std::string euler_set_owner(int s) const;  // "main" (base body) or the spherical joint's name
  int chart(int s) const;                    // current chart of set s (index into kSequences)
  std::string chart_name(int s) const;       // "3-2-1", ...
  int modal_index(int body) const;           // index of a flexible body's eta in x (-1: rigid)
  // Every term of the equations of motion at (t, x) (header comment).
  struct Terms {
    Eigen::MatrixXd M;       // mass matrix d2T/dpi'2
    Eigen::VectorXd p;       // dT/dpi'
    Eigen::VectorXd Mdot_u;  // (dM/dt) pi'
    Eigen::VectorXd hamel;   // B^T W^T p
    Eigen::VectorXd dL;      // B^T d(T - V)/dq*
    Eigen::VectorXd N;       // generalised forces
    Eigen::VectorXd qdot;    // q*' = B pi'
    Eigen::VectorXd udot;    // pi''
  };
  // Terms are over every coordinate, prescribed ones included (udot: theta'' there).
  Terms terms(double t, const double* x);
  double kinetic_energy(const double* x, double t = 0.0);
  double potential_energy(const double* x, double t = 0.0);
  Eigen::Vector3d angular_momentum_N(const double* x, double t = 0.0);  // about the system CM, N
  Eigen::Vector3d linear_momentum_N(const double* x, double t = 0.0);
  // Torques of the prescribed revolute joints at (t, x), System::joints order (0 for the others).
  std::vector<double> prescribed_torques(double t, const double* x);

  struct Model;      // immutable, built from the System (lagrange_engine.cpp)
  struct Workspace;  // mutable scratch and the current charts (lagrange_engine.cpp)

 private:
  // Below, xf is the full (q*, pi'), prescribed coordinates included (expand).
  const double* expand(double t, const double* x);  // state x => xf at t (x itself if none)
  void evaluate(double t, const double* xf);  // (t, xf) => every term and pi'' in the workspace
  // With prescribed joints: the free block's right-hand side f_f - M_fc theta'' at free
  // coordinate a (evaluate()'s solve; theta'' held in udot at the prescribed coordinates).
  static double reduced_rhs(const Model& m, const Workspace& w, int a);
  void prepare_charts(double t, const double* xf);
  std::string full_label(int i) const;  // label of index i of xf
  double kinetic_energy_full(const double* xf);
  double potential_energy_full(const double* xf);
  Eigen::Vector3d angular_momentum_full(const double* xf);
  Eigen::Vector3d linear_momentum_full(const double* xf);
  std::unique_ptr<const Model> model_;
  std::unique_ptr<Workspace> ws_;
};

}  // namespace crossdyn::lagrange
