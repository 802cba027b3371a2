// The Newton-Euler engine: maximal coordinates, one set of Newton-Euler equations per body, the
// joint constraint forces and moments as unknowns (reference paper, "Newton-Euler Equations",
// Eqs. (1), (2), (7); the paper's model-specific code for Example 1), with flexible (modal) bodies
// written from the paper's Eqs. (3)-(6) (modal_body.hpp).
//
// State x (n bodies; body b has n_b modes, n_b = 0 for a rigid body):
//   positions, body by body:   p_NoBo_N (3), q_NB (4, scalar first; kept near unit norm), eta (n_b)
//   then velocities, likewise: v_NBo_N (3), w_NB_B (3), eta' (n_b)
// Labels "<body>.x/.y/.z/.qw/.qx/.qy/.qz/.<mode>" and "<body>.vx/.vy/.vz/.wx/.wy/.wz/.<mode>_rate"
// (e.g. "beam.qx1", "beam.qx1_rate"). For a flexible body, Bo is the origin of its body frame, the
// undeformed CM (docs/flexible-bodies.md); TreeAccel::a_NBo_N is that origin's acceleration.
//
// Equations (per right-hand-side call, named passes in newton_euler.cpp):
//   body_pass      x => R_NB, p, v, w, eta, eta' of every body
//   mass_pass      => each flexible body's (6 + n_b)-square mass matrix and velocity terms from
//                  its precomputed modal invariants (modal_body.hpp: the paper's Eqs. (3)-(6), the
//                  floating-frame-of-reference equations); rigid blocks diag(m I3, I_B) are constant
//   joint_pass     => joint frames at nodes (point p_i + Phi_i eta, frame exp([Psi_i eta x])),
//                  relative joint kinematics, constraint rows g, J, gamma with columns in the modal
//                  rates of flexible sides (joint_constraints.hpp); what depends on the joint
//                  type is in the type's unit (joints/joint_unit.hpp, one file per type)
//   force_pass     t => f_b = [F_ext (gravity's, below; else zero);
//                              M_ext + spring/damper/motor torques - w x I w]   (Eqs. (1), (7));
//                  flexible: the velocity terms, -K eta - D eta', the body torque (on the body
//                  frame: no work on eta) and the joint torques on node frames with their modal
//                  generalised forces (Jl Psi)^T T; then the environment's loads (issue 28;
//                  core/system.hpp "Environment"; nothing computed without one): uniform gravity
//                  m g, or on an orbit the tidal force T (m d + R S) (T = n^2 (3 zhat zhat^T - 1),
//                  d = p - p_NoO_N, O the system's CM in the initial state) and the moment about Bo
//                  S x T_B d_B + 3 n^2 z_B x (I z_B) (the gravity-gradient torque, Hughes 2004,
//                  "Spacecraft Attitude Dynamics", Sec. 8.1); a flexible body's nodes add their
//                  modal generalised forces (R Phi~_bar)^T g, or (R Phi~_bar)^T T d +
//                  [tr(T_B B_k)]_k, from the mass-weighted node sums (newton_euler.cpp,
//                  gravity_on_body(), for the derivation)
//   solve_pass     [M J^T; J 0] [nu'; -lambda] = [f; gamma_s], factorised in O(bodies) with blocks
//                  of size 6 or 6 + n_b (tree_kkt.hpp): M nu' = f + J^T lambda, J nu' = gamma_s;
//                  the constraint wrench on body b is J_b^T lambda. gamma_s = gamma (stabilisation
//                  none or projection), or gamma - alpha g' - beta g (Baumgarte 1972:
//                  g'' + alpha g' + beta g = 0).
//   xdot           p' = v, q' = 1/2 q (x) (0, w), eta' = eta', v' = a, w' = alpha, eta'' .
//   linear_system  (t, x) => the same KKT system written out dense, A = [M J^T; J 0] (symmetric;
//                  z = [nu'; -lambda]), b = [f; gamma_s], speed_index = the velocity block of the
//                  state (it holds nu itself); a diagnostic (core/engine.hpp), not called by rhs.
// Cost per call: O(bodies) for the tree, O(n_b^3) per flexible body (modal terms and its block),
// independent of the number of nodes (the node sums are done once, at construction).
// Stabilisation (EngineOptions::stabilization): "projection" (default) projects positions (Newton
// iterations over p, q and eta) and then velocities (over v, w and eta') onto the constraint
// manifold, in the mass metric, after every accepted step whose violation exceeds 1e-12 per metre
// of the model's size, then restores the system's CM and linear momentum by a rigid translation
// (Hairer, Lubich & Wanner 2006, "Geometric Numerical Integration", Sec. IV.4; Hairer & Wanner
// 1996, Sec. VII.2); "baumgarte"; "none" (drift shows).
//
// Prescribed motion (docs/prescribed-motion.md; issue 13). A prescribed revolute joint is a
// rheonomic constraint (Haug 1989, "Computer Aided Kinematics and Dynamics of Mechanical Systems",
// Sec. 6.3, driving constraints): besides its five revolute rows it has a sixth, the joint angle
// minus angle0 + theta(t), whose velocity and acceleration equations carry -theta'(t) and
// +theta''(t) (joint_constraints.hpp), so projection and Baumgarte drive it to the prescribed
// angle and rate at t. Its multiplier is the constraint moment about the axis on the child: the
// output <joint>.torque. <joint>.angle and .rate are the profile's; TreeAccel::angle_ddot is
// theta''(t). A prescribed prismatic joint likewise (joints/prismatic.cpp): its row 5 is the
// position minus angle0 + theta(t), its multiplier the force along the axis on the child, output
// <joint>.force. A prescribed base (joints[0] revolute with parent N) keeps its body's numbers in the
// state (the layout above is unchanged); its joint to N is the same rheonomic constraint with N as
// a parent at rest, solved as root rows of the KKT system (tree_kkt.hpp) and stabilised like every
// joint (projection moves no rigid translation then: the base is held; zero_linear_momentum does
// not apply). For a base attached at a node of a flexible body the joint frame turns with the node
// (R_NB = R_NJ0 Rot(axis_J, angle) exp([psi x])^T, the general "Joints at nodes" rule).
//
// Geometric stiffening (docs/flexible-bodies.md; modal_body.hpp): u_i = Phi_i eta + e_i 1/2 eta^T
// G_i eta kept exactly; a stiffened body's mass matrix and velocity terms are node sums per state
// (O(nodes n^2) per call for that body), joint points at its nodes move with the same u_i.
//
// Outputs (core/output_layout.hpp; docs/conventions.md "Positions, momentum, power and joint
// loads"), written by output_row() at (t, x) after one solve of the KKT system at that state (the
// same passes as rhs(), so the loads are those of the accelerations rhs() returns there):
//   <body>.x .y .z  p_NoBo_N from the state (a flexible body's undeformed CM, its frame origin).
//   CMx CMy CMz     p_NoScm_N = sum_b (m_b p_b + R_NB S_b) / sum_b m_b, S_b = sum_i m_i (p_i + u_i)
//                   (modal_body.hpp; zero for a rigid body) [KLL83 Sec. 4.5].
//   Hx Hy Hz, H     H_Scm_N = sum_b h_b + (p_b - x_c) x L_b (angular_momentum(), H its norm).
//   E               kinetic + strain + joint springs, plus gravity's potential (uniform:
//                   -g . (m p + R S) per body; orbit: -1/2 m d^T T d - d^T T R S +
//                   3/2 n^2 z_B^T I z_B - 1/2 n^2 tr I per body, the node sums of core/system.hpp's
//                   per-mass formula).
//   J               (orbit only) the Jacobi integral E - w_NO_N . H_O_N, H_O_N = H_Scm_N +
//                   M (p_cm - p_NoO_N) x v_cm [KLL83 Sec. 4.5].
//   <joint>.Fx..Mz  joint j's total load on its child (joint_load()): the constraint part is the
//                   generalised force J_C^T lambda of the joint's multipliers (lambda = -y) on the
//                   child's [v_NCo_N; w_NC_C] columns, i.e. the force F_N and the moment about Co
//                   in C components (Haug 1989, Sec. 6.3: multipliers as reaction forces; the
//                   reference paper's Eqs. (1), (2), (7)), moved to the joint point J by
//                   M_J = M_Co - s_C x F (Featherstone 2008, "Rigid Body Dynamics Algorithms",
//                   Sec. 2.8, Eq. 2.26), s_C the (displaced) joint point from Co; plus the joint's
//                   own spring, damper and motor from its unit's load verb (a torque, and a
//                   prismatic joint's force at the child's point): F_C = R_CN F_N + R_CP F_P,
//                   M_J_C = M_Co_C - s_C x F_C + R_CP T_P. A prescribed joint's drive is a
//                   multiplier (row 5): inside the constraint part. A prescribed base: N's load on
//                   it (the root rows' multipliers). Not for the free joint.
//   P               sum over joints of the unit's power verb (motor and damper with the scene's
//                   values, a prescribed joint's drive torque(j) theta'(t)), external torques
//                   T_B . w_NB_B, modal dampers -eta'^T D eta' (the scene's D): dE/dt = P on the
//                   constraint manifold, since the other multipliers do no work (lambda^T J nu
//                   = lambda_5 theta' for the prescribed rows only) and springs and the strain
//                   energy are in E.
//   Mx My Mz        M_Scm_N: external torques in N, plus a prescribed base's load moved to the CM,
//                   R_NB M_J_C + (p_NoJ_N - p_NoScm_N) x R_NB F_C (Featherstone 2008, Eq. 2.26),
//                   plus gravity's, sum_b (p_b - p_NoScm_N) x F_grav_N + R_NB M_grav_B (zero for
//                   uniform gravity; the tidal forces and gravity-gradient torques on an orbit).
//                   Joint loads include gravity through the multipliers; P does not (conservative).
// EngineOptions::test_damper_scale s multiplies the dampers of the equations of motion (each
// JointModel's damping, damping2 and a flexible body's Dmp, at construction, skipped when s = 1);
// P keeps the scene's dampers, so a wrong damper in the equations shows in E(t) - E(0) = int P.
//
// Extra output columns after the pinned ones (the joints' constraint wrenches <joint>.fx .. .mz
// of earlier versions are gone: the pinned <joint>.Fx .. .Mz, total loads, supersede them):
//   constraint.pos (m) and constraint.vel (m/s): largest distance between the two copies of a
//     joint point, and the largest relative velocity of those copies, over the joints (prismatic:
//     their separation and its rate normal to the axis, and a prescribed one's position and rate
//     away from the profile);
//   constraint.ang (rad), constraint.angvel (rad/s): largest attitude violation (revolute: angle
//     between the two copies of the axis; fixed, prismatic: rotation angle away from the offset;
//     universal: the change of the angle between its axes) and the norm of the forbidden relative
//     angular velocity (between the joint frames); a prescribed revolute joint adds |angle -
//     prescribed angle| and |rate - prescribed rate| to them, and a prescribed base its joint to N
//     (largest row of g and g').
//
// Exact tangent (issue 27; core/engine.hpp, accelerations_tangent()): the complex step (Martins,
// Sturdza & Alonso 2003, ACM TOMS 29(3); the tangent mode of Griewank & Walther 2008, "Evaluating
// Derivatives", 2nd ed., Ch. 3) through this engine's own pack() and equations, templated on the
// scalar (scalar.hpp: double for the run, std::complex<double> for the step; explicit
// instantiations in the .cpp files only): joint kinematics and constraint rows
// (joint_constraints.hpp), the joint units' verbs (joints/*.cpp, JointVerbsCx), the rigid body's
// moment and gravity and pack()'s placement (newton_euler.cpp). The KKT system is solved as two
// real systems with the engine's own factorisation (K_r z_r = b_r, K_r z_i = b_i - K_i z_r).
// Covered: rigid and flexible (modal) bodies, with or without geometric stiffening (modal_body's
// terms, the node frames' so3 maps and the nodes' gravity on the scalar; a flexible body's M
// depends on the state: its imaginary part is in K_i), a free or prescribed base (its motion the
// profile at t: zero tangent), revolute, prismatic, universal, fixed and spherical joints (at
// nodes too), prescribed joints, springs, dampers, motors, modal stiffness and damping, body
// torques, uniform gravity and the orbit, every stabilisation. Returns false (decided by the
// constructor) only for a joint whose unit has no Cx verbs: none of this engine's types.
//
// Exact tangents of output_row() and rhs() (issue 27; core/engine.hpp, output_row_tangent(),
// rhs_tangent()): the same complex step through the same passes (pack_cx or body_pass_cx, then
// dynamics_cx in newton_euler.cpp), the output columns written once on the scalar
// (write_outputs<S, W>: RowWriter on double, CxRowWriter on Cx, cx_row_writer.hpp); README.md
// "Exact tangents of the output row and of the right-hand side". Covered exactly where
// accelerations_tangent() is.
//
// Readings of the flexible model (docs/flexible-bodies.md) chosen here:
//   - a joint on a flexible body without a node (Joint::parent_node / child_node = -1) is attached
//     to the body frame: its point and frame do not move with the deformation;
//   - a node without slopes (FlexNode::Psi_B empty) has psi = 0;
//   - the body's mass and inertia must equal the node sums (InputError otherwise); the equations
//     use the node sums, and S0 = sum m_i p_i is kept in them (zero for the model's origin);
//   - EngineOptions::test_inertia_scale s adds (s - 1) times the undeformed rotational inertia to a
//     flexible body's sum of node inertias J_i.

#pragma once

#include "core/engine.hpp"

#include <memory>

namespace crossdyn {

// Throws InputError (naming the scene file and the body or joint) for a free joint other than
// joints[0], a node on a rigid body or out of range, inconsistent or non-finite modal data, a
// flexible body's mass or inertia different from its node sums, a singular undeformed mass matrix
// (a mode with no mass, or a rigid-body or dependent mode), K or D not symmetric positive
// semi-definite, an unknown stabilisation name, negative Baumgarte gains or a non-positive
// test_inertia_scale, or a non-finite test_damper_scale. EngineOptions::test_gravity_gradient_sign
// is ignored (core/engine.hpp: only the lagrange engine implements it).
std::unique_ptr<Engine> make_newton_euler_engine(const System& system, const EngineOptions& options);

}  // namespace crossdyn
