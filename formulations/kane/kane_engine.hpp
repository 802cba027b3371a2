// Kane's method for a tree of rigid and flexible (modal) bodies (engine "kane").
//
// Notation (Drake's monogram notation, core/system.hpp): N the inertial frame, B a body, Bo its
// centre of mass (CM), P and C a joint's parent and child, J the joint point, Ok the "reference
// point" of tree node k (its joint point J; for the base its CM).  w_NB_N is the angular velocity
// of B in N with N components; a trailing _N means N components, _B body components.  Every
// vector in the workspace has N components; positions are measured from the base CM B0o, so the
// dynamics never sees the (possibly large) inertial position of the base (a prescribed base:
// from No, see "Prescribed revolute joints" below).
//
// Tree nodes.  Node k is System::joints[k] together with its child body (exactly one joint per
// body), in the System's topological order: node 0 is the base (free, or a prescribed revolute
// joint to N), every node's parent node has a smaller index.
//
// State vector x = [ positions (n_q) | generalised speeds u (n_u) ]:
//   positions  base: p_NoBo_N (3), q_NB (4, w x y z);  revolute: angle (1);
//              spherical: q_J (4, w x y z; R_J = R(q_J), core/system.hpp);  fixed: none;
//              then, for a flexible child body, its modal coordinates eta (n).
//   speeds     base: u_1..3 = w_NB_B (base-frame components, Eq. (37)), u_4..6 = v_NBo_N (base CM
//              velocity, N components, Eq. (38));  revolute: the joint rate;
//              spherical: w_PC_C (relative angular velocity of the child-side joint frame,
//              components in that frame);  fixed: none;  then a flexible child's eta' (n).
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
// Flexible bodies (reference paper Eqs. (3)-(6), (39)-(40); docs/flexible-bodies.md pins the
// model).  A flexible body's modal coordinates eta are further positions and its modal rates eta'
// further generalised speeds of its tree node: node k's block is [joint coordinates | eta_C] and
// [joint speeds | eta_C'] (C the node's child body).  Node i of C (a mass point) sits at
// r_i = p_i + Phi_i eta from Co (the body-frame origin, the undeformed CM); a joint at node j
// has its point at r_j and its frame turned by E_j = exp([psi_j x]), psi_j = Psi_j eta.
//   Kinematics (docs "Joints at nodes"): with Jp, Jc the parent- and child-side joint frames,
//     R_NJp = R_NP E_Pj,  R_NJc = R_NJp R_PJ0 R_J,  R_NC = R_NJc E_Cj^T,
//     p_Ok = p_Po + R_NP r_Pj,  p_Co = p_Ok - R_NC r_Cj,
//     w_Jp = w_P + R_NP Jl(psi_Pj) Psi_Pj eta_P',  w_Jc = w_Jp + (joint rate),
//     w_C = w_Jc - R_NC Jl(psi_Cj) Psi_Cj eta_C'
//   (R = exp([psi x]) has R' R^T = [(Jl(psi) psi') x], Jl the left Jacobian; Barfoot, State
//   Estimation for Robotics, 2017, Sec. 7.1.5; for R^T the angular velocity is -R^T Jl psi').
//   Partial velocities.  Every speed r of node k moves the subtree S(k) with a rigid "twist"
//   (W_r, V_r) about Ok: V = V_r + W_r x (p - p_Ok) for every point of S(k), W_r for every frame
//   in it ([KLL] Sec. 2.14 for rigid bodies).  Joint speeds: V_r = 0 (base translations: W_r = 0,
//   V_r = n_r).  A modal speed eta_C,l' of a child attached at node j of C (the joint point is
//   held, so the body frame moves): W_l = -R_NC Jl(psi_Cj) Psi_Cj,l, V_l = -R_NC Phi_Cj,l
//   (Wm_N, Vm_N).  A modal speed also has an elastic part (paper Eq. (40); Kane, Ryan &
//   Banerjee 1987, the modal partial velocities of a beam on a moving base): node i of C moves
//   with R_NC Phi_i,l (C's node inertias J_i do not turn), and the subtree S(c) of every child c
//   attached at node j' of C moves rigidly with the node frame: twist
//   (R_NC Jl(psi_j') Psi_j',l, R_NC Phi_j',l) about Oc (Wp_N, Vp_N, stored on c).
//   Generalised inertia forces F_r* = -sum_i V_r^i . m_i a_i - sum_B W_r^B . (J_B alpha_B +
//   w_B x J_B w_B) (paper Eq. (36) with C's node masses as the particles) and active forces
//   (Eq. (35)) are then grouped as in the rigid case: the twist part of speed r works on the
//   subtree sums (s_k, J_k, F_k, M_k, which now hold C's deformed mass distribution and its
//   residual loads), the elastic part on C's nodes and on the attached children's sums.
//   The sums over C's nodes never run in rhs(): they are the modal integrals of FlexModel
//   (body frame, built once), so the cost per flexible body is O(n^2) in its mode count n and
//   independent of its number of nodes:
//     S = sum m_i Phi_i,  Hs = sum m_i [p_i x] Phi_i,  G_k = sum m_i p_i Phi_ik^T,
//     Q_kl = sum m_i Phi_ik Phi_il^T,  C_kl = sum m_i Phi_ik x Phi_il,  Mm = sum m_i Phi_i^T Phi_i,
//   from which at a state (FlexWork)  c = sum m_i r_i = c0 + S eta,  I = I0 + tr(dS) 1 - dS with
//   dS = sum m_i r_i r_i^T - sum m_i p_i p_i^T = sum_k eta_k (G_k + N_k),  N_k = sum m_i Phi_ik
//   r_i^T = G_k^T + sum_l eta_l Q_kl,  A_k = sum m_i r_i x Phi_ik = Hs_k + sum_l eta_l C_lk,
//   L = sum m_i r_i (Phi_i eta')^T = sum_k eta_k' N_k^T.
//   Hinge loads: a hinge's torque acts on Jc and reacts on Jp; their relative angular velocity
//   is the joint rate alone (R_NJc = R_NJp R_PJ0 R_J), so the pair contributes only to the
//   joint's own speeds, exactly as for rigid bodies, wherever the frames are attached.  (In the
//   split of docs "Loads at joints", the node-frame torques' generalised forces on eta,
//   (Jl Psi)^T tau_B on the parent and on the child, are each cancelled by the same torque's
//   work through the rigid motion the modal speed gives the other side.)  External body torques
//   act on C's frame: their work through W_l is part of the twist term.  Modal stiffness and
//   damping add -K eta - D eta' to the modal speeds' generalised active forces.
//   Reading chosen where docs/flexible-bodies.md leaves room: TreeAccel::a_NBo_N of a flexible
//   body is the acceleration of its frame origin Bo (the undeformed CM), as TreeState's velocities
//   are; body torques given in the inertial frame act on the body frame likewise.
//
// Prescribed revolute joints (docs/prescribed-motion.md; issue 13).  A prescribed joint has no
// position and no speed: its angle angle0 + theta(t), rate theta'(t) and theta''(t) come from its
// profile at the time of the call (set_time; the spin-up of [KRB] Eq. (61)).  Its partial angular
// velocity W_r (the axis) is still formed, but u_r is a known function of time (Kane and Levinson,
// Dynamics: Theory and Applications, 1985, Sec. 6.1, [KL85]): its W_r theta' enters the velocities
// and W_r theta'' the remainder accelerations, and Kane's equation of that speed is not solved but
// gives the joint torque:  tau = -(F_r + F_r*) = -W_r . M_k, M_k the moment about Ok of every
// external and inertia force on S(k) with the full accelerations (prescribed_torque_pass).  A
// prescribed base (joints[0], parent N) is the same joint with N as its parent (ground_, at rest);
// the positions of such a tree are measured from No instead of the base CM, the base has no speeds
// of its own (a flexible base keeps its modal speeds), and zero_linear_momentum does not apply.
//
// Geometric stiffening (docs/flexible-bodies.md "Geometric stiffening"; [KRB] Eq. (8), [Sharf]):
// u_i = Phi_i eta + e_i w_i, w_i = 1/2 eta^T G_i eta.  Every formula above holds with r_i = p_i +
// u_i and the shapes replaced by the partial velocities Phi~_i = d r_i / d eta = Phi_i + e_i (G_i
// eta)^T, plus the second-order acceleration b_i = e_i eta'^T G_i eta' (d2u_i/dt2 = Phi~_i eta'' +
// b_i) in every node's remainder acceleration.  The modal integrals then depend on eta beyond the
// linear terms, so for such a body they are summed over its nodes at each state (FlexWork; O(nodes
// n^2)); a joint at a node uses that node's r_i, Phi~_i and b_i.
//
// Two solvers for u' (KaneSolver below; both solve the same Kane's equations F_r + F_r* = 0 with
// the same partial velocities, the same remainder accelerations and the same loads):
//   composite  forms M and f by the composite-body sums above and solves M u' = f by the sparse
//              L^T D L.  Every scene (flexible bodies too).  Cost: forming M is O(n_bodies * depth)
//              and the factorisation fills the ancestor band, O(sum over speeds of depth^2); on a
//              serial chain of N spherical joints that is O(N^3) (4.25 ms at chain80).
//   order-N    eliminates Kane's equations along the tree, leaves first, without forming M: the
//              articulated-body recursion (kane_order_n.cpp gives the derivation and its sources).
//              O(n_bodies).  Rigid bodies only; a scene with any flexible body uses composite.
//              It declines prescribed joints too (its elimination assumes a free base and a speed
//              per revolute joint): a scene with one uses composite, and forcing order-N is
//              refused with InputError.
//   Automatic chooses order-N for an all-rigid scene whose deepest root-to-leaf path carries at
//   least KaneEngine::kOrderNMinDepth = 16 generalised speeds (the base's 6 included; chain5),
//   composite otherwise (every committed rigid scene but chain5; measured, kane_order_n.cpp).
//
// Bibliography
//   [KLL]  T. R. Kane, P. W. Likins, D. A. Levinson, Spacecraft Dynamics, McGraw-Hill, 1983.
//   [Feath] R. Featherstone, Rigid Body Dynamics Algorithms, Springer, 2008.
//   [KRB]  T. R. Kane, R. R. Ryan, A. K. Banerjee, "Dynamics of a cantilever beam attached to a
//          moving base", J. Guidance, Control, and Dynamics 10(2), 1987, 139-151.
//   [Barfoot] T. D. Barfoot, State Estimation for Robotics, Cambridge, 2017, Sec. 7.1.5.
//   [Paper] J. E. Cochran, T. S. No, N. G. Fitz-Coy, "Simulation of spacecraft attitude dynamics
//           using TREETOPS and model-specific computer codes", 1990 (docs/references.md).
//   [KL85] T. R. Kane, D. A. Levinson, Dynamics: Theory and Applications, McGraw-Hill, 1985.
//   [Sharf] I. Sharf, "Geometric stiffening in multibody dynamics formulations", J. Guidance,
//          Control, and Dynamics 18(4), 1995.
//   [Ban93] A. K. Banerjee, "Block-diagonal equations for multibody elastodynamics with geometric
//           stiffness and constraints", J. Guidance, Control, and Dynamics 16(6), 1993.
#pragma once

#include "core/engine.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace crossdyn::kane {

// The modal integrals of one flexible body (body frame), built once from its nodes (see above).
struct FlexModel {
  int n = 0;               // modes
  double mass = 0;         // sum m_i
  Eigen::Vector3d c0;      // sum m_i p_i (zero when Bo is the undeformed CM)
  Eigen::Matrix3d I0;      // sum J_i + m_i (|p_i|^2 1 - p_i p_i^T), times test_inertia_scale
  Eigen::Matrix3Xd S, Hs;  // 3 x n: sum m_i Phi_i, sum m_i [p_i x] Phi_i
  std::vector<Eigen::Matrix3d> G;  // n:     G_k  = sum m_i p_i Phi_ik^T
  std::vector<Eigen::Matrix3d> Q;  // n * n: Q_kl = sum m_i Phi_ik Phi_il^T   (index k n + l)
  std::vector<Eigen::Vector3d> C;  // n * n: C_kl = sum m_i Phi_ik x Phi_il   (index k n + l)
  Eigen::MatrixXd Mm;              // n x n: sum m_i Phi_i^T Phi_i (modal mass)
  Eigen::MatrixXd K, D;            // n x n: modal stiffness and damping
  // Geometric stiffening (FlexBody::geometric_stiffening; docs/flexible-bodies.md "Geometric
  // stiffening"): u_i = Phi_i eta + e_i (1/2 eta^T G_i eta).  The integrals above then depend on
  // eta beyond the linear terms, so they are summed over the nodes at each state (FlexWork,
  // flex_position / flex_velocity; O(nodes n^2)) from these per-node data.
  struct StiffNode {
    double m = 0;
    Eigen::Vector3d p, e;    // p_BoNi_B, e_i (unit, body frame)
    Eigen::Matrix3Xd Phi;    // 3 x n
    Eigen::MatrixXd G;       // n x n symmetric
  };
  bool stiff = false;
  std::vector<StiffNode> sn;
};

// exp([psi x]) and its left Jacobian Jl(psi) for a node's rotation vector psi ([Barfoot] Sec.
// 7.1.5): R = 1 + (sin t / t) [psi x] + a [psi x]^2,  Jl = 1 + a [psi x] + b [psi x]^2, t = |psi|,
// a = (1 - cos t) / t^2, b = (t - sin t) / t^3 (power series below t = 1, no cancellation).
struct NodeRotation {
  Eigen::Vector3d psi = Eigen::Vector3d::Zero();
  double a = 0.5, b = 1.0 / 6.0, a1 = -1.0 / 12.0, b1 = -1.0 / 60.0;  // a1 = a'(t)/t, b1 = b'(t)/t
  void set(const Eigen::Vector3d& rotation_vector);
  Eigen::Matrix3d R() const;
  Eigen::Matrix3d Jl() const;
  // (d/dt Jl(psi)) psi' for psi changing at the rate psi'.
  Eigen::Vector3d Jl_dot_times(const Eigen::Vector3d& psi_rate) const;
};

// Immutable description of one tree node (joint k and its child body), built once.
struct Node {
  JointType type = JointType::Fixed;
  int joint = -1;           // System::joints index (== node index)
  int body = -1;            // System::bodies index of the child
  int parent = -1;          // parent node index, -1 for the base
  int q0 = 0, nq = 0;       // first position index in x, number of positions (joint + modal)
  int u0 = 0, nu = 0;       // first speed index in u (x index n_q + u0), number of speeds
  int nqj = 0, nuj = 0;     // the joint's own positions and speeds (the first of the block)
  int nm = 0;               // modal coordinates of a flexible child: eta at x[q0 + nqj],
                            // eta' at u[u0 + nuj]
  int flex = -1;            // the child's FlexModel (flex_ index), -1 for a rigid body
  // Prescribed revolute joint (docs/prescribed-motion.md): no position, no speed (nqj = nuj =
  // 0); angle0 + theta(t), theta'(t), theta''(t) from `motion`.  For the base (parent -1) the
  // parent frame is N: p_PoJ_P = p_NoJ_N, axis_P = axis_N, R_PJ0 = R_NJ0.
  bool prescribed = false;
  PrescribedMotion motion;
  double angle0 = 0;
  bool has_offset = false;  // R_PJ0 != identity
  Eigen::Matrix3d R_PJ0 = Eigen::Matrix3d::Identity();
  Eigen::Quaterniond q_PJ0 = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_PoJ_P = Eigen::Vector3d::Zero();
  Eigen::Vector3d p_CoJ_C = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_P = Eigen::Vector3d::UnitZ();  // revolute axis in P (unit)
  Eigen::Vector3d axis_J = Eigen::Vector3d::UnitZ();  // the same axis in C (= R_PJ0^T axis_P)
  double mass = 0;
  Eigen::Matrix3d I_BBo_B = Eigen::Matrix3d::Zero();  // scaled by test_inertia_scale (rigid)
  // Facts of the system read once so that rhs() skips work that would give zeros or copies
  // (kane_engine.cpp, position_pass and subtree_pass):
  //   axis_index  a revolute axis_J along a coordinate axis of Jc, axis_J = axis_sign e_i (i), so
  //               that R_J turns the two other columns only; -1 for any other axis;
  //   inertia     a rigid body's central inertia isotropic (I_BBo_N = I_BBo_B in every frame,
  //               w x I w = 0), diagonal in B, or general;
  //   body_torque the child body carries an external torque;  hinge_load the joint has a
  //               spring, damper or motor;
  //   sums_start  no child node (subtree_pass starts S(k)'s sums with the body's own terms);
  //   parent_start the highest-index child of its parent (the first whose sums reach it);
  //   leaf_rigid  a rigid body with no child node, not at a flexible parent's node: S(k) is the
  //               body alone, so its inertia about Ok is never formed (subtree_pass shifts I_BBo_N
  //               straight to the parent's point, mass_matrix_pass uses J W = I W + m d x (W x d));
  //   parent_free_base  the parent is a free base, whose remainder accelerations are zero.
  enum class Inertia { Isotropic, Diagonal, General };
  int axis_index = -1;
  double axis_sign = 1;
  Inertia inertia = Inertia::General;
  bool body_torque = false, hinge_load = false;
  bool sums_start = true, parent_start = false, leaf_rigid = false, parent_free_base = false;
  // Attachment at a node of a flexible parent whose shape or slope there is not zero: the
  // node's shapes Phi_Pj and slopes Psi_Pj (3 x pm, parent frame; pm the parent's modes).
  bool parent_attach = false;
  int pm = 0;
  Eigen::Matrix3Xd Phi_Pj, Psi_Pj;
  // Attachment at a node of this flexible child whose shape or slope is not zero (3 x nm).
  bool child_attach = false;
  Eigen::Matrix3Xd Phi_Cj, Psi_Cj;
  // Geometric stiffening at the attachment node (parent / child side): the node's e and G
  // (its displacement gains e (1/2 eta^T G eta)); stiff_* false when the body has none there.
  bool stiff_P = false, stiff_C = false;
  Eigen::Vector3d e_Pj = Eigen::Vector3d::Zero(), e_Cj = Eigen::Vector3d::Zero();
  Eigen::MatrixXd G_Pj, G_Cj;
  std::vector<int> attached_children;  // child nodes with parent_attach (flexible child body)
  // Ancestors of this node that carry speeds, nearest first, ending with the base (0), each
  // with the node below it on the path from here ("via": the child it moves this node through).
  struct Ancestor {
    int node = -1, via = -1;
  };
  std::vector<Ancestor> speed_ancestors;
};

// Mutable per-node workspace (N components; positions from the base CM).
struct NodeWork {
  Eigen::Matrix3d R_NB;       // attitude of the node's body
  Eigen::Matrix3d I_BBo_N;    // its inertia about Bo, N axes (flexible: deformed, node sums)
  Eigen::Matrix3d W_N;        // partial angular velocities of the joint's speeds (columns)
  double sin_half = 0, cos_half = 1;  // revolute: sine and cosine of half the joint angle
  // Prescribed joint at the time of the last set_time(): angle, rate theta', acceleration theta''.
  double pres_angle = 0, pres_rate = 0, pres_accel = 0;
  Eigen::Vector3d p_B0oBo_N;  // body-frame origin from the base CM
  Eigen::Vector3d p_B0oOk_N;  // reference point Ok (joint point; base: its Bo) from the base CM
  Eigen::Vector3d p_PoOk_N;   // Ok from the parent's body-frame origin Po (R_NP r_Pj; base: 0)
  Eigen::Vector3d p_OkBo_N;   // the body-frame origin Bo from Ok (-R_NB r_Cj; base: 0)
  Eigen::Vector3d w_NB_N, v_NBo_N;
  Eigen::Vector3d w_NB_B;            // w_NB_N in body components (sum_momenta only)
  Eigen::Vector3d w_PC_N;            // relative angular velocity of the joint (Jc in Jp)
  Eigen::Vector3d w_NJp_N;           // angular velocity of Jp
  Eigen::Vector3d alpha_t_N, a_t_N;  // remainder accelerations (all u' = 0)
  Eigen::Vector3d alpha_N, a_N;      // full accelerations (accelerations() only)
  // Subtree S(k) sums about Ok (backward pass).
  double m_sub;
  Eigen::Vector3d s_sub_N;  // first moment  sum m (p - p_Ok)
  Eigen::Matrix3d J_sub_N;  // inertia about Ok
  Eigen::Vector3d F_sub_N;  // resultant of the residual forces
  Eigen::Vector3d M_sub_N;  // their moment about Ok
  // Parent side at a flexible parent's node (parent_attach): the elastic twists of the parent's
  // modal speeds (3 x pm), their values times eta_P', (d/dt Jl) psi' term, and the momenta of
  // S(k) about Ok in those twists (mass-matrix pass).
  NodeRotation rot_P;
  Eigen::Matrix3Xd Wp_N, Vp_N, pp_N, hp_N;
  Eigen::Vector3d w_att_N, v_att_N, jdot_att_N;
  // Child side at a node of this flexible body (child_attach): twists of its modal speeds
  // (3 x nm), their values times eta', and R_NC (d/dt Jl) psi'.
  NodeRotation rot_C;
  Eigen::Matrix3Xd Wm_N, Vm_N;
  Eigen::Vector3d w_m_N, v_m_N, jdot_m_N;
  // Geometric stiffening at the attachment nodes: G eta (parent side, child side) and the
  // second-order node accelerations R e (eta'^T G eta') (N components; zero without stiffening).
  Eigen::VectorXd gP, gC;
  Eigen::Vector3d b_att_N = Eigen::Vector3d::Zero(), b_m_N = Eigen::Vector3d::Zero();
};

// Per flexible body: the modal integrals evaluated at the state (body frame unless _N).
struct FlexWork {
  Eigen::Vector3d c_B, c_N;          // first moment about Bo, sum m_i r_i
  Eigen::Matrix3d I_B;               // inertia about Bo (deformed, with the J_i)
  Eigen::Matrix3Xd A_B, S_N, A_N;    // 3 x n: A_k; R_NC S; R_NC A
  std::vector<Eigen::Matrix3d> N_B;  // n: N_k
  Eigen::Vector3d cdot_N;            // R_NC S eta'           (linear momentum of deformation)
  Eigen::Vector3d hdef_N;            // R_NC A eta'           (its angular momentum about Bo)
  Eigen::Matrix3d L_B;               // sum m_i r_i (Phi_i eta')^T
  Eigen::Matrix3Xd Ce_B;             // 3 x n: sum_l eta_l' C_lk
  Eigen::Matrix3Xd pm_N, hm_N;       // 3 x n: momenta of S(k) about Ok per modal speed
  // Geometric stiffening only (FlexModel::stiff), node sums at the state, with the effective
  // shapes Phi~_i = Phi_i + e_i (G_i eta)^T (the partial velocities of node i for eta'):
  //   S_B = sum m_i Phi~_i,  Mm = sum m_i Phi~_i^T Phi~_i  (replacing FlexModel::S, Mm);
  //   b_i = e_i (eta'^T G_i eta') (the node's second-order acceleration at eta'' = 0):
  //   bsum_N = R sum m_i b_i,  bmom_N = R sum m_i r_i x b_i,  bgen_l = sum m_i Phi~_il . b_i.
  Eigen::Matrix3Xd S_B;
  Eigen::MatrixXd Mm;
  std::vector<Eigen::Matrix3Xd> Phit;  // per node
  std::vector<Eigen::Vector3d> r;      // per node: p_i + u_i
  std::vector<Eigen::VectorXd> g;      // per node: G_i eta
  Eigen::Vector3d bsum_N = Eigen::Vector3d::Zero(), bmom_N = Eigen::Vector3d::Zero();
  Eigen::VectorXd bgen;
};

// Per-node workspace of the order-N solver (kane_order_n.cpp); N components, about Ok.
// The articulated inertia of S(k) about Ok maps the acceleration increments (alpha, a_Ok) of
// node k's body frame to the subtree's inertia forces: M_Ok = Iww alpha + Iwv a_Ok,
// F = Iwv^T alpha + Ivv a_Ok (Iww, Ivv symmetric).
struct ArticulatedWork {
  Eigen::Matrix3d Iww_N, Iwv_N, Ivv_N;  // articulated inertia of S(k) about Ok
  Eigen::Vector3d Z_M_N, Z_F_N;         // bias loads of S(k): moment about Ok and resultant
  Eigen::Matrix3d U_M_N, U_F_N;         // U = I^A S (moment and force rows; nuj columns used)
  Eigen::Matrix3d D_inv;                // (S^T I^A S)^-1 (nuj x nuj block used)
  Eigen::Vector3d g;                    // tau + S^T Z (nuj entries used)
  Eigen::Vector3d dalpha_N, da_Ok_N;    // acceleration increments of k's body frame at Ok
};

// Which solver forms u' (see "Two solvers" above).
enum class KaneSolver { Automatic, Composite, OrderN };
const char* kane_solver_name(KaneSolver s);  // "automatic", "composite", "order-n"

// One mass point (a node of a flexible body, or a rigid body's CM with its inertia), computed
// point by point from the body frames, for tests (no modal integrals).
struct MassPoint {
  int body = -1, node = -1;  // System::bodies index; FlexBody::nodes index or -1 (rigid CM)
  double mass = 0;
  Eigen::Matrix3d J_N;  // rotational inertia carried by the body frame, N axes
  Eigen::Vector3d p_NoP_N, v_NP_N;
};

// A joint's frames and point as seen from both sides (for tests).
struct JointFrames {
  Eigen::Matrix3d R_NJp, R_NJc;
  Eigen::Vector3d p_NoJ_N_parent, p_NoJ_N_child;
};

// One body's motion at a state, for tests and diagnostics.
struct BodyMotion {
  Eigen::Matrix3d R_NB;
  Eigen::Vector3d p_NoBo_N, w_NB_B, v_NBo_N;
};

class KaneEngine final : public Engine {
 public:
  // Crossover of KaneSolver::Automatic, in speeds on the deepest root-to-leaf path: order-N at
  // and above it (kane_order_n.cpp gives the measurement).
  static const int kOrderNMinDepth;

  // solver: Automatic in every real run; Composite or OrderN force a path (tests, benchmarks).
  // OrderN on a scene with a flexible body is refused with InputError.
  KaneEngine(const System& system, const EngineOptions& options,
             KaneSolver solver = KaneSolver::Automatic);
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
  // Kane's equations at (t, x) written out dense (Engine::linear_system): A = the full symmetric
  // M(q) of Pass 5, b = f(t, q, u) of Pass 6 (F_r + F_r* = 0, [Paper] Eq. (34)), z = u', so
  // speed_index = n_q .. n_q + n_u - 1 (joint and modal speeds; a prescribed joint has none).
  // Formed by the composite passes whichever solver rhs() takes (order-N never forms M).
  LinearSystem linear_system(double t, const double* x) override;

  // Introspection for tests (allocate; not for the hot path).  Prescribed joints take their
  // angle, rate and acceleration at the time of the last set_time() (rhs, accelerations,
  // output_row, pack, composite_udot and generalized_forces set it themselves).
  void set_time(double t);
  int position_size() const { return n_q_; }
  int speed_size() const { return n_u_; }
  const std::vector<Node>& nodes() const { return nodes_; }
  Eigen::MatrixXd mass_matrix(const double* x);                   // full symmetric M(q)
  Eigen::VectorXd generalized_forces(double t, const double* x);  // f = F_r + F_r*|_{u'=0}
  double kinetic_energy(const double* x);                         // sum over bodies
  double potential_energy(const double* x) const;                 // hinge springs + 1/2 eta^T K eta
  Eigen::Vector3d linear_momentum_N(const double* x);
  Eigen::Vector3d angular_momentum_N(const double* x);     // about the system CM
  std::vector<BodyMotion> body_motion(const double* x);    // per System::bodies index (frame Bo)
  std::vector<MassPoint> mass_points(const double* x);     // every node and rigid CM, in N
  std::vector<JointFrames> joint_frames(const double* x);  // per joint (System order)
  const std::vector<FlexModel>& flex_models() const { return flex_; }
  // u' by the composite solver (formed M and f, sparse L^T D L), with the base block's loops of
  // constant size 6 (fixed_base_block, a rigid base: the path of every run) or of its size read
  // at run time: tests check that the two agree.
  Eigen::VectorXd composite_udot(double t, const double* x, bool fixed_base_block);
  KaneSolver solver() const { return solver_; }  // the path in use (never Automatic)
  int max_speed_depth() const { return max_speed_depth_; }  // speeds on the deepest path

 private:
  // Named passes; "=>" reads inputs => writes outputs (all into work_ / M_ / f_).
  // q => R_NB, I_BBo_N, W_N, p_B0oBo_N, p_B0oOk_N; attachment twists Wp, Vp, Wm, Vm;
  //   flexible bodies' integrals at eta (flex_position)
  // rigid_inertia false (output_row): I_BBo_N of rigid bodies is not formed (the energy and
  // momentum sums use I_BBo_B); everything else reads it.
  void position_pass(const double* x, bool rigid_inertia = true);
  // (q, u) => w_NB_N, v_NBo_N, w_PC_N, w_NJp_N, w_att, v_att, w_m, v_m, Jl-rate terms;
  //   flexible bodies' rate terms (flex_velocity)
  void velocity_pass(const double* u);
  void remainder_pass();                                   // (q, u) => alpha_t_N, a_t_N
  // => m_sub, s_sub, J_sub, F_sub, M_sub.  full: with the full accelerations alpha_N, a_N and
  // udot_'s modal accelerations (after acceleration_pass; prescribed joints' torques) instead of
  // the remainder ones.
  void subtree_pass(double t, bool full = false);
  // After dynamics(t, x): the torque of each prescribed joint into prescribed_torque_ (per node).
  void prescribed_torque_pass(double t);
  void mass_matrix_pass();                                 // subtree sums => M_ (lower triangle)
  void generalized_force_pass(double t, const double* x);  // subtree sums, hinges, K, D => f_
  // (M_, f_) => udot_ (false: M not positive definite).  fixed_base_block: a rigid base's 6 x 6
  // block with constant loop bounds (every real run); false: its size read at run time (tests).
  bool solve(bool fixed_base_block = true);
  // Order-N solver (kane_order_n.cpp), after the remainder pass:
  //   q, u, alpha_t, a_t, loads => per node I^A, Z, U, D^-1, g      (backward, leaves first)
  void articulated_pass(double t, const double* x);
  //   I^A, Z, U, D^-1, g => udot_, increments dalpha, da_Ok          (forward, base first)
  void articulated_solve(double t);
  void acceleration_pass(const double* udot);  // u' => alpha_N, a_N
  // rhs() of a rigid tree with a free base on the composite solver (rigid_fast_): Passes 1-3 and
  // the kinematical equations fused into one forward loop, Passes 4-6 into one backward loop,
  // the solve writing u' into xdot (kane_engine.cpp, "Rigid trees").
  void rigid_rhs(double t, const double* x, double* xdot);
  // output_row() of such a tree (no prescribed joint): Passes 1-2, the attitudes and the sums
  // of sum_momenta() in one loop, the row written as it goes.
  void rigid_output_row(double t, const double* x, double* row);
  void dynamics(double t, const double* x);    // all of the above up to udot_
  // The remainder (full false) or full accelerations, into alpha_t/a_t or alpha/a.
  void propagate_accelerations(const double* udot, bool full);
  void flex_position(const Node& n, NodeWork& w, const double* eta);
  void flex_velocity(const Node& n, NodeWork& w, const double* eta_rate);
  // Mass-matrix row r (speed of node k) against k's speed ancestors, from the momenta p, h
  // (about Ok) of S(k) moving with speed r's partial velocities.
  void mass_matrix_ancestors(const Node& n, int r, const Eigen::Vector3d& p,
                             const Eigen::Vector3d& h);
  // Its joint-speed part for one ancestor (rigid trees need no more); returns h about the
  // ancestor's point.  And J_k W (a rigid leaf's without forming J_k).
  Eigen::Vector3d mass_matrix_ancestor_joint(const NodeWork& w, const Node::Ancestor& an, int r,
                                             const Eigen::Vector3d& p, const Eigen::Vector3d& h);
  Eigen::Vector3d subtree_inertia_times(const Node& n, const NodeWork& w,
                                        const Eigen::Vector3d& W) const;

  // A rigid body's residual torque -I alpha - w x I w about Bo, and its external torque at t
  // (only when Node::body_torque) added to T_B (N components).
  Eigen::Vector3d rigid_residual_torque(const Node& n, const NodeWork& w,
                                        const Eigen::Vector3d& alpha) const;
  void add_body_torque(const Node& n, const NodeWork& w, double t, Eigen::Vector3d& T_B) const;
  double hinge_torque_revolute(const Node& n, double t, const double* x) const;
  Eigen::Vector3d hinge_torque_spherical(const Node& n, double t, const double* x) const;
  Eigen::Quaterniond read_quat(const double* x, int i) const;
  // Kinetic energy, linear momentum and angular momentum about the system CM, after the position
  // (with or without rigid_inertia) and velocity passes; writes every NodeWork::w_NB_B.
  struct Momenta {
    double T;
    Eigen::Vector3d P, H;
  };
  Momenta sum_momenta(const double* u);

  const System system_;  // the engine's own copy (loads are read from it)
  std::vector<Node> nodes_;
  std::vector<FlexModel> flex_;  // per flexible body (Node::flex)
  int n_q_ = 0, n_u_ = 0;
  double total_mass_ = 0;
  std::vector<std::string> labels_;
  OutputLayout layout_;  // pinned columns, then kane's extras from extra0_ on

  // Workspace, sized in the constructor; rhs() never allocates.
  std::vector<NodeWork> work_;
  std::vector<FlexWork> flex_work_;  // per flexible body (Node::flex)
  KaneSolver solver_ = KaneSolver::Composite;
  int max_speed_depth_ = 0;
  std::vector<ArticulatedWork> art_;  // order-N workspace (sized only when solver_ == OrderN)
  std::vector<int> lambda_;          // parent speed of each speed ([Feath] lambda(i)), -1 for none
  // Mass matrix (lower triangle, row major); after solve() its factors L and D.
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> M_;
  Eigen::VectorXd f_, udot_;
  std::vector<Eigen::Quaterniond> q_N_;  // output_row: every body's attitude
  int extra0_ = 0;                       // first extra column
  // The inertial frame N as the parent of a prescribed base (at rest, R = 1, origin No).
  NodeWork ground_;
  bool has_prescribed_ = false;
  bool rigid_fast_ = false;     // rhs() takes rigid_rhs(), output_row() rigid_output_row()
  bool has_potential_ = false;  // a hinge spring or a flexible body (potential_energy() not 0)
  std::vector<double> prescribed_torque_;  // per node (prescribed joints only)
};

}  // namespace crossdyn::kane
