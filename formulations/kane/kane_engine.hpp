// Kane's method for a tree of rigid bodies (engine "kane").
//
// Notation (Drake's monogram notation, core/system.hpp): N the inertial frame, B a body, Bo its
// centre of mass (CM), P and C a joint's parent and child, J the joint point, Ok the "reference
// point" of tree node k (its joint point J; for the base its CM).  w_NB_N is the angular velocity
// of B in N with N components; a trailing _N means N components, _B body components.  Every
// vector in the workspace has N components; positions are measured from the base CM B0o, so the
// dynamics never sees the (possibly large) inertial position of the base.
//
// Tree nodes.  Node k is System::joints[k] together with its child body (exactly one joint per
// body), in the System's topological order: node 0 is the free base, every node's parent node
// has a smaller index.
//
// State vector x = [ positions (n_q) | generalised speeds u (n_u) ]:
//   positions  base: p_NoBo_N (3), q_NB (4, w x y z);  revolute: angle (1);
//              spherical: q_J (4, w x y z; R_J = R(q_J), core/system.hpp);  fixed: none.
//   speeds     base: u_1..3 = w_NB_B (base-frame components, Eq. (37)), u_4..6 = v_NBo_N (base CM
//              velocity, N components, Eq. (38));  revolute: the joint rate;
//              spherical: w_PC_C (relative angular velocity, child-frame components);  fixed: none.
// Quaternions are normalised where they are read; their kinematical equations
// q' = 1/2 q (x) (0, w) keep |q| constant, and after_step() renormalises only a visible drift.
//
// Kane's method (Kane, Likins & Levinson 1983 [KLL], pp. 87-90 for partial velocities and
// Ch. 4 for generalised forces, as the reference paper cites them; reference paper Eqs. (34)-(38)):
//   the velocity of every body's CM and its angular velocity are linear in u,
//     v_Bo = sum_r V_r^Bo u_r,   w_B = sum_r W_r^B u_r          (partial velocities V, W),
//   and for speed r of node k the partial angular velocity W_r is the same for every body of the
//   subtree S(k) below joint k (zero elsewhere), with V_r^Bo = W_r x (p_Bo - p_Ok) for a rotational
//   speed and V_r^Bo = n_i for the base's translational speeds u_4..6.
//   Kane's equations F_r + F_r* = 0 (Eq. 34) with
//     F_r  = sum_B V_r^Bo . R_B + W_r^B . T_B                                          (Eq. 35)
//     F_r* = sum_B V_r^Bo . (-m_B a_Bo) + W_r^B . (-I_B alpha_B - w_B x I_B w_B)        (Eq. 36)
//   Writing a_Bo = sum_s V_s^Bo u_s' + a_t,  alpha_B = sum_s W_s^B u_s' + alpha_t (the remainder
//   terms a_t, alpha_t are the accelerations at u' = 0) gives  M(q) u' = f(t, q, u)  with
//     M_rs = sum_B m_B V_r^Bo . V_s^Bo + W_r^B . I_B W_s^B                 (mass matrix)
//     f_r  = F_r + sum_B V_r^Bo . (-m_B a_t) + W_r^B . (-I_B alpha_t - w_B x I_B w_B).
//   Both sums over bodies are taken per subtree (the composite-body grouping of Featherstone 2008,
//   Sec. 6.2, applied to Kane's sums), so the cost is O(n_bodies * depth) instead of
//   O(n_bodies * n_u^2):
//     f_r = W_r . M_k for rotational speeds, where M_k is the moment about Ok of the subtree's
//           "residual" loads (-m a_t at each CM; T - I alpha_t - w x I w on each body), and
//           f = F_0 (their resultant) for the base's translational speeds;
//     M_rs = W_s . (h_r + (p_Ok - p_Oa) x p_r) for speed s of an ancestor node a, where p_r and
//           h_r (about Ok) are the linear and angular momentum of S(k) moving with the partial
//           motion of speed r: p_r = W_r x s_k, h_r = J_k W_r (s_k, J_k: first moment and inertia
//           of S(k) about Ok).
//   Joint constraint forces and torques are non-contributing (KLL Ch. 4); a hinge's spring,
//   damper and motor torque acts on the child and reacts on the parent, so it contributes only to
//   its own joint's speeds: f_r += tau (revolute), f_r += tau_C,i (spherical, child-frame
//   components, since W_r = c_i for speed w_PC_C,i).
//   M is symmetric positive definite.  It is solved with the square-root-free Cholesky
//   factorisation M = L^T D L taken in reverse order, which keeps the tree's branch-induced
//   sparsity (M_rs = 0 unless one of r, s is an ancestor speed of the other) with no fill-in
//   ([Feath] Sec. 6.5, Tables 6.3-6.4).  Eigen's LLT gives the same solution (tests/kane) but
//   costs more for these small matrices.
//
// Flexible bodies (paper Eqs. 39-40): not supported yet; the constructor throws InputError. They
// arrive as further per-body blocks of positions (eta) and speeds (eta'), with partial velocities
// Phi_k of the body's elements (Eq. 40) alongside the rigid ones; the node tables below keep
// position and speed offsets per block so that such blocks can be appended without changing the
// rigid passes.
//
// Bibliography
//   [KLL]  T. R. Kane, P. W. Likins, D. A. Levinson, Spacecraft Dynamics, McGraw-Hill, 1983.
//   [Feath] R. Featherstone, Rigid Body Dynamics Algorithms, Springer, 2008.
//   [Paper] J. E. Cochran, T. S. No, N. G. Fitz-Coy, "Simulation of spacecraft attitude dynamics
//           using TREETOPS and model-specific computer codes", 1990 (../shared/reference).
#pragma once

#include "core/engine.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace crossdyn::kane {

// Immutable description of one tree node (joint k and its child body), built once.
struct Node {
  JointType type = JointType::Fixed;
  int joint = -1;           // System::joints index (== node index)
  int body = -1;            // System::bodies index of the child
  int parent = -1;          // parent node index, -1 for the base
  int q0 = 0, nq = 0;       // first position index in x, number of positions
  int u0 = 0, nu = 0;       // first speed index in u (x index n_q + u0), number of speeds
  bool has_offset = false;  // R_PJ0 != identity
  Eigen::Matrix3d R_PJ0 = Eigen::Matrix3d::Identity();
  Eigen::Quaterniond q_PJ0 = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_PoJ_P = Eigen::Vector3d::Zero();
  Eigen::Vector3d p_CoJ_C = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_P = Eigen::Vector3d::UnitZ();  // revolute axis in P (unit)
  Eigen::Vector3d axis_J = Eigen::Vector3d::UnitZ();  // the same axis in C (= R_PJ0^T axis_P)
  double mass = 0;
  Eigen::Matrix3d I_BBo_B = Eigen::Matrix3d::Zero();  // scaled by test_inertia_scale
  // Ancestors of this node that carry speeds, nearest first, ending with the base (0).
  std::vector<int> speed_ancestors;
};

// Mutable per-node workspace (N components; positions from the base CM).
struct NodeWork {
  Eigen::Matrix3d R_NB;       // attitude of the node's body
  Eigen::Matrix3d I_BBo_N;    // its central inertia, N axes: R_NB I_BBo_B R_NB^T
  Eigen::Matrix3d W_N;        // partial angular velocities of the node's speeds (columns)
  Eigen::Vector3d p_B0oBo_N;  // CM position from the base CM
  Eigen::Vector3d p_B0oOk_N;  // reference point Ok (joint point; base: its CM) from the base CM
  Eigen::Vector3d w_NB_N, v_NBo_N;
  Eigen::Vector3d w_PC_N;            // relative angular velocity of the joint
  Eigen::Vector3d alpha_t_N, a_t_N;  // remainder accelerations (all u' = 0)
  Eigen::Vector3d alpha_N, a_N;      // full accelerations (accelerations() only)
  // Subtree S(k) sums about Ok (backward pass).
  double m_sub;
  Eigen::Vector3d s_sub_N;  // first moment  sum m (p_Bo - p_Ok)
  Eigen::Matrix3d J_sub_N;  // inertia about Ok
  Eigen::Vector3d F_sub_N;  // resultant of the residual forces
  Eigen::Vector3d M_sub_N;  // their moment about Ok
};

// One body's motion at a state, for tests and diagnostics.
struct BodyMotion {
  Eigen::Matrix3d R_NB;
  Eigen::Vector3d p_NoBo_N, w_NB_B, v_NBo_N;
};

class KaneEngine final : public Engine {
 public:
  KaneEngine(const System& system, const EngineOptions& options);
  KaneEngine(const KaneEngine&) = delete;
  KaneEngine& operator=(const KaneEngine&) = delete;

  const char* name() const override { return "kane"; }
  int state_size() const override { return n_q_ + n_u_; }
  std::string state_label(int i) const override;
  void pack(const TreeState& s, double* x) override;
  void rhs(double t, const double* x, double* xdot) override;
  bool after_step(double t, double* x) override;
  void accelerations(double t, const double* x, TreeAccel& a) override;
  const OutputLayout& layout() const override { return layout_; }
  void output_row(double t, const double* x, double* row) override;

  // Introspection for tests (allocate; not for the hot path).
  int position_size() const { return n_q_; }
  int speed_size() const { return n_u_; }
  const std::vector<Node>& nodes() const { return nodes_; }
  Eigen::MatrixXd mass_matrix(const double* x);                   // full symmetric M(q)
  Eigen::VectorXd generalized_forces(double t, const double* x);  // f = F_r + F_r*|_{u'=0}
  double kinetic_energy(const double* x);                         // sum over bodies
  double potential_energy(const double* x) const;                 // hinge springs
  Eigen::Vector3d linear_momentum_N(const double* x);
  Eigen::Vector3d angular_momentum_N(const double* x);   // about the system CM
  std::vector<BodyMotion> body_motion(const double* x);  // per System::bodies index

 private:
  // Named passes; "=>" reads inputs => writes outputs (all into work_ / M_ / f_).
  void position_pass(const double* x);  // q => R_NB, I_BBo_N, W_N, p_B0oBo_N, p_B0oOk_N
  void velocity_pass(const double* u);  // (q, u) => w_NB_N, v_NBo_N, w_PC_N
  void remainder_pass();                // (q, u) => alpha_t_N, a_t_N
  void subtree_pass(double t);          // => m_sub, s_sub, J_sub, F_sub, M_sub
  void mass_matrix_pass();              // subtree sums => M_ (lower triangle)
  void generalized_force_pass(double t, const double* x);  // subtree sums, hinges => f_
  bool solve();                                // (M_, f_) => udot_ (false: M not positive definite)
  void acceleration_pass(const double* udot);  // u' => alpha_N, a_N
  void dynamics(double t, const double* x);    // all of the above up to udot_

  double hinge_torque_revolute(const Node& n, double t, const double* x) const;
  Eigen::Vector3d hinge_torque_spherical(const Node& n, double t, const double* x) const;
  Eigen::Quaterniond read_quat(const double* x, int i) const;
  double sum_kinetic_energy() const;  // after position and velocity passes
  Eigen::Vector3d sum_linear_momentum() const;
  Eigen::Vector3d sum_angular_momentum() const;

  const System system_;  // the engine's own copy (loads are read from it)
  std::vector<Node> nodes_;
  int n_q_ = 0, n_u_ = 0;
  double total_mass_ = 0;
  std::vector<std::string> labels_;
  OutputLayout layout_;  // pinned columns, then kane's extras from extra0_ on

  // Workspace, sized in the constructor; rhs() never allocates.
  std::vector<NodeWork> work_;
  std::vector<int> lambda_;  // parent speed of each speed ([Feath] lambda(i)), -1 for none
  // Mass matrix (lower triangle, row major); after solve() its factors L and D.
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> M_;
  Eigen::VectorXd f_, udot_;
  std::vector<Eigen::Quaterniond> q_N_;  // output_row: every body's attitude
  int extra0_ = 0;                        // first extra column
};

}  // namespace crossdyn::kane
