// Kane's method for a tree of rigid and flexible (modal) bodies (engine "kane"): the engine class,
// its model tables (Node, FlexModel: built once by the constructor, model_building.cpp) and its
// workspace (NodeWork, FlexWork, ArticulatedWork: overwritten by every rhs()).
//
// formulations/kane/README.md gives the derivation (the state layout, Kane's equations, flexible
// bodies, prescribed joints, geometric stiffening, the two solvers, the fused rigid path), its
// sources ([KLL], [Feath], [KRB], [Barfoot], [Paper], [KL85], [Sharf], [Ban93]: its
// bibliography) and the file that implements each equation: one file per pass.
#pragma once

#include "core/engine.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace crossdyn::kane {

struct JointUnit;  // joints/joint_unit.hpp

// The modal integrals of one flexible body (body frame), built once from its nodes (README.md
// "Flexible bodies"; flex_model.cpp).
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
  Eigen::MatrixXd K, D;            // n x n: modal stiffness and damping (D in the equations of
                                   // motion: times EngineOptions::test_damper_scale)
  Eigen::MatrixXd D_P;             // n x n: the scene's modal damping, for the power column P
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

// The shape of a joint's own speeds, declared by its unit (JointUnit::shape) and kept as
// Node::shape: what the passes switch on (never on JointType, which only joints/dispatch.cpp
// reads), so that a new joint type whose speeds have an existing shape needs no edit in the
// passes (README.md "Joint units").  The passes inline the first three; the others (and None)
// take the unit's verbs (JointUnit::position, velocity, hinge) with Node::slides, axis_rates.
enum class JointShape : std::uint8_t {
  Base6,      // six base speeds w_NB_B, v_NBo_N of a free base, Bo = Ok (free)
  Axis1,      // one rotation about an axis fixed in Jp and Jc, Node::axis_P (revolute)
  Rotation3,  // three rotations w_PC_C, Jc components, position q_J (spherical)
  None,       // no speed (fixed)
  Slide1,     // one slide along an axis fixed in Jp (prismatic)
  Gimbal2,    // two rotations, the second axis turning with the first (universal)
};

// Immutable description of one tree node (joint k and its child body), built once.
struct Node {
  JointShape shape = JointShape::None;  // its unit's JointUnit::shape
  const JointUnit* unit = nullptr;  // the joint type's unit (joints/joint_unit.hpp), chosen once
  int joint = -1;           // System::joints index (== node index)
  int body = -1;            // System::bodies index of the child
  int parent = -1;          // parent node index, -1 for the base
  int q0 = 0, nq = 0;       // first position index in x, number of positions (joint + modal)
  int u0 = 0, nu = 0;       // first speed index in u (x index n_q + u0), number of speeds
  int nqj = 0, nuj = 0;     // the joint's own positions and speeds (the first of the block)
  int nm = 0;               // modal coordinates of a flexible child: eta at x[q0 + nqj],
                            // eta' at u[u0 + nuj]
  int flex = -1;            // the child's FlexModel (flex_ index), -1 for a rigid body
  // Prescribed revolute or prismatic joint (docs/prescribed-motion.md): no position, no speed
  // (nqj = nuj = 0); angle0 + theta(t), theta'(t), theta''(t) from `motion` (prismatic: m).  For the base (parent -1) the
  // parent frame is N: p_PoJ_P = p_NoJ_N, axis_P = axis_N, R_PJ0 = R_NJ0.
  bool prescribed = false;
  PrescribedMotion motion;
  double angle0 = 0;
  bool has_offset = false;  // R_PJ0 != identity
  Eigen::Matrix3d R_PJ0 = Eigen::Matrix3d::Identity();
  Eigen::Quaterniond q_PJ0 = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_PoJ_P = Eigen::Vector3d::Zero();
  Eigen::Vector3d p_CoJ_C = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_P = Eigen::Vector3d::UnitZ();  // revolute, prismatic, universal first
                                                       // axis in P (unit)
  Eigen::Vector3d axis_J = Eigen::Vector3d::UnitZ();  // the same axis in C (= R_PJ0^T axis_P)
  Eigen::Vector3d axis2_J = Eigen::Vector3d::UnitY();  // universal second axis at zero angles,
                                                        // in J0 (= R_PJ0^T axis2_P; unit)
  // Set by the joint's unit (joints/joint_unit.hpp): some joint speed has a partial velocity at Ok
  // (V_N column; prismatic), some partial angular velocity turns with the joint's own coordinates
  // (universal: its second axis turns with the first angle).
  bool slides = false, axis_rates = false;
  double mass = 0;
  Eigen::Matrix3d I_BBo_B = Eigen::Matrix3d::Zero();  // scaled by test_inertia_scale (rigid)
  // Facts of the system read once so that rhs() skips work that would give zeros or copies
  // (position_pass, kinematics.cpp; subtree_pass, subtree_sums.cpp):
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
  // The scene's joint dampers (damping, damping2), for the power column P (output_row): the
  // equations of motion read System::joints, whose dampers carry EngineOptions::
  // test_damper_scale (KaneModel::system_), P never does.
  double damping_P = 0, damping2_P = 0;
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
  Eigen::Matrix3d V_N;        // their partial velocities at Ok (columns; Node::slides only)
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
  Eigen::Vector3d v_PC_N;            // velocity of Ok in Jp, sum V_r u_r (Node::slides only)
  Eigen::Vector3d alpha_PC_t_N;      // sum (d/dt W_r) u_r - w_Jp x w_PC (Node::axis_rates only)
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
  // The environment's loads (gravity.cpp; Kane's generalised active forces of the node forces
  // through the nodes' elastic partial velocities R Phi~_il): Q_grav_l = sum_i R Phi~_il . F_i
  // (n entries; only with an environment).
  Eigen::VectorXd Q_grav;
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

// Which solver forms u' (README.md, "Two solvers").
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

// The engine's model: the System, the node tables and every fact derived from them, built once by
// the constructor (model_building.cpp) and only read afterwards (docs/style.md item 1; not
// declared const because the constructor fills it in place).
struct KaneModel {
  // damper_scale: EngineOptions::test_damper_scale, folded into system_'s joint dampers (1: an
  // exact copy).
  KaneModel(const System& system, double damper_scale);
  const System system_;  // the engine's own copy (loads are read from it)
  std::vector<Node> nodes_;
  std::vector<FlexModel> flex_;  // per flexible body (Node::flex)
  int n_q_ = 0, n_u_ = 0;
  double total_mass_ = 0;
  std::vector<std::string> labels_;
  OutputLayout layout_;  // pinned columns, then kane's extras from extra0_ on
  int extra0_ = 0;       // first extra column
  KaneSolver solver_ = KaneSolver::Composite;
  // EngineOptions::test_gyroscopic_sign (a test double, issue 27): multiplies every w x (I w)
  // term (rigid_fast_path.cpp, subtree_sums.cpp); 1 in every real run (an exact product).
  double gyro_sign_ = 1.0;
  int max_speed_depth_ = 0;
  // accelerations_tangent covers this System (tangent.cpp): decided once by the constructor
  // (rigid trees: no flexible body).
  bool tangent_ = false;
  // output_row_tangent covers this System (as tangent_; decided once by the constructor).
  bool output_tangent_ = false;
  std::vector<int> lambda_;  // parent speed of each speed ([Feath] lambda(i)), -1 for none
  // The inertial frame N as the parent of a prescribed base (at rest, R = 1, origin No).
  NodeWork ground_;
  bool has_prescribed_ = false;
  bool rigid_fast_ = false;     // rhs() takes rigid_rhs(), output_row() rigid_output_row()
  bool has_potential_ = false;  // a hinge spring or a flexible body (potential_energy() not 0)
  // The environment (System::environment, issue 28; gravity.cpp, README.md "Gravity"): gravity_
  // is false without one, and then no pass computes or adds anything for it.
  bool gravity_ = false, orbit_ = false;
  Eigen::Vector3d g_N_ = Eigen::Vector3d::Zero();  // uniform field, m/s^2
  // Orbit: O, the system's CM at t = 0 from the scene's initial state (TreeState::initial, packed
  // as a run packs it), a point fixed in N, computed once by the constructor.
  Eigen::Vector3d p_NoO_N_ = Eigen::Vector3d::Zero();
};

// The engine's workspace: sized by the constructor, overwritten by every rhs() (which never
// allocates).
struct KaneWorkspace {
  std::vector<NodeWork> work_;
  std::vector<FlexWork> flex_work_;   // per flexible body (Node::flex)
  std::vector<ArticulatedWork> art_;  // order-N workspace (sized only when solver_ == OrderN)
  // Mass matrix (lower triangle, row major); after solve() its factors L and D.
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> M_;
  Eigen::VectorXd f_, udot_;
  std::vector<Eigen::Quaterniond> q_N_;    // output_row: every body's attitude
  std::vector<double> prescribed_torque_;  // per node (prescribed joints only)
  // output_row (load_pass, loads.cpp): per node the loads its joint passes from the parent to
  // the child, F_C and M_J_C (child body frame; the free base's stay zero), and the same in N.
  std::vector<Eigen::Vector3d> F_C_, M_J_C_, F_N_, M_J_N_;
  // The environment's loads at the state of the last gravity_pass (gravity.cpp), per node: the
  // resultant F_grav_N on the child body, applied at its frame origin Bo, and the moment of the
  // body's gravity forces about Bo, tau_grav_N (N components; sized only with an environment).
  std::vector<Eigen::Vector3d> F_grav_N_, tau_grav_N_;
};

// The engine: its model and its workspace (private bases, so that the passes name their members
// directly), and the passes, one file each (README.md).
class KaneEngine final : public Engine, private KaneModel, private KaneWorkspace {
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
  // The exact tangent of accelerations() (Engine::accelerations_tangent; tangent.cpp): forward-
  // mode automatic differentiation (a dual number, dual.hpp) through a templated twin of the
  // composite passes for rigid trees; false (a and da untouched) for a System with a flexible
  // body.
  bool accelerations_tangent(double t, const TreeState& s, const TreeTangent& ds, TreeAccel& a,
                             TreeAccel& da) override;
  // The exact tangent of output_row() (Engine::output_row_tangent; tangent.cpp): the twin's
  // u' and its positions as Taylor polynomials in time fed to a dual-number copy of the row's
  // equations (every column; the row itself is output_row()'s); false (row and drow untouched)
  // where accelerations_tangent is.
  bool output_row_tangent(double t, const TreeState& s, const TreeTangent& ds, double* row,
                          double* drow) override;
  // The exact tangent of rhs() in x (Engine::rhs_tangent; tangent.cpp): the kinematical equations
  // and the rigid or flexible twin at x + e dx (quaternions as stored: the twin normalises where
  // rhs() does); xdot is rhs()'s.  False (untouched) where accelerations_tangent is.
  bool rhs_tangent(double t, const double* x, const double* dx, double* xdot,
                   double* dxdot) override;
  // For tests: the twin's own row (its value part, to compare with output_row()) and drow, as
  // output_row_tangent computes them.
  bool output_row_twin(double t, const TreeState& s, const TreeTangent& ds, double* row,
                       double* drow);

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
  // The environment (gravity.cpp): its potential energy at (t, x) (uniform: -sum m g . p; orbit:
  // the tidal potential; 0 without one), the orbit's reference point O (the system CM at t = 0),
  // and the Jacobi integral J = E - w_NO_N . H_O_N at (t, x) (E with every potential).
  double gravity_potential_energy(double t, const double* x);
  const Eigen::Vector3d& orbit_origin_N() const { return p_NoO_N_; }
  double jacobi_integral(double t, const double* x);
  int max_speed_depth() const { return max_speed_depth_; }  // speeds on the deepest path
  bool has_tangent() const { return tangent_; }  // accelerations_tangent covers the System
  bool has_output_tangent() const { return output_tangent_; }  // output_row_tangent covers it

  friend struct TangentTwin;  // tangent.cpp

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
  // output_row (loads.cpp): after dynamics(t, x), every joint's load from its child's subtree
  // momentum balance (prescribed_torque_pass's full sums) => F_C_, M_J_C_, F_N_, M_J_N_ and the
  // prescribed torques.
  void load_pass(double t);
  // After load_pass and the velocities of the row (w_NB_N, w_NB_B of every body, set by
  // sum_momenta or rigid_output_row): the power of the non-conservative loads P, the external
  // moment about the system CM p_NoScm_N (N components); both written with the positions to out.
  // p_NoB0o_N: the base's body-frame origin from No (a prescribed base's tree: zero).
  void write_issue26_columns(double t, const double* x, const Eigen::Vector3d& p_NoB0o_N,
                             const Eigen::Vector3d& p_NoScm_N, RowWriter& out) const;
  void mass_matrix_pass();                                 // subtree sums => M_ (lower triangle)
  // The environment's loads (gravity.cpp), after the position pass (R_NB, p_B0oBo_N, the
  // flexible bodies' integrals at eta): => F_grav_N_, tau_grav_N_, FlexWork::Q_grav.  Only when
  // gravity_.  p_NoB0o_N: the base's body-frame origin from No (base_origin).
  void gravity_pass(double t, const Eigen::Vector3d& p_NoB0o_N);
  // Their potential at the positions of the last position pass (flexible bodies: c_N, I_B).
  double gravity_potential(double t, const Eigen::Vector3d& p_NoB0o_N) const;
  // J = E - w_NO_N . H_O_N, H_O_N = H_Scm_N + (p_cm - p_NoO_N) x P_N (orbit only).
  double jacobi(double t, double E, const Eigen::Vector3d& H_Scm_N, const Eigen::Vector3d& P_N,
                const Eigen::Vector3d& p_NoScm_N) const;
  // Gravity's moment about the system CM (for the external moment column), after gravity_pass
  // and a position pass at the same x.
  Eigen::Vector3d gravity_moment(const Eigen::Vector3d& p_NoB0o_N,
                                 const Eigen::Vector3d& p_NoScm_N) const;
  // The base's body-frame origin B0o from No: a free base's from x, a prescribed base's tree is
  // measured from No (zero).
  Eigen::Vector3d base_origin(const double* x) const;
  // Constructor, last: O from the initial state.
  void init_environment();
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
  // the solve writing u' into xdot (rigid_fast_path.cpp; README.md "Rigid trees").
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
    Eigen::Vector3d cm;  // the system CM from the base's body-frame origin B0o (N components)
  };
  Momenta sum_momenta(const double* u);
};

}  // namespace crossdyn::kane
