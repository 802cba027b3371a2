// Joint constraints of the Newton-Euler (maximal-coordinate) formulation: for one joint between a
// parent body P and a child body C, the position-level constraint g(x) = 0, its Jacobian
// J = [J_P J_C] with g' = J nu exactly, and the acceleration-level right-hand side gamma with
// g'' = J nu' - gamma, i.e. J nu' = gamma on the motion (gamma = -Jdot nu).
//
// Notation (Drake monogram, see core/system.hpp): R_NP, R_NC body attitudes; p_NoPo_N, p_NoCo_N
// body-frame origins; w_P = w_NP_P, w_C = w_NC_C inertial angular velocities in body axes. A rigid
// body's generalised velocity is nu_B = [v_NBo_N; w_NB_B] (paper Eqs. (1), (2)); a flexible body's
// is [v_NBo_N; w_NB_B; eta'] (modal_body.hpp), and J has columns for its modal rates too.
//
// Joint frames. Each side of a joint carries a joint frame: F on the parent side, G on the child
// side. On a rigid body (or a flexible body without a node) F is the body frame P and G the body
// frame C, and the joint point is fixed in the body (r_P = p_PoJ_P, r_C = p_CoJ_C). At node i of a
// flexible body (docs/flexible-bodies.md "Joints at nodes") the point is s = r + Phi_i eta and the
// frame is turned from the body frame by E = exp([psi x]), psi = Psi_i eta (so3.hpp). The joint
// relates F and G exactly as a rigid joint relates P and C: R_FG = R_PJ0 R_J(coordinates), revolute
// axis a_P in F. Kinematics of a node frame, body components (so3.hpp, Jl = left Jacobian):
//   s' = Phi eta' (relative to B),   w_NF = w_B + w_rel,   w_rel = Jl(psi) Psi eta',
//   w_F (F components) = E^T (w_B + w_rel),
//   d/dt w_F = E^T (alpha_B + Jl Psi eta'' + c - w_rel x w_B),   c = (d/dt Jl) Psi eta'
// (d/dt E^T = -E^T [w_rel x], since d/dt E E^T = [w_rel x]).
//
// Constraint rows (Kane, Likins & Levinson 1983, Sec. 2.4 and 2.6 for the kinematics; Haug 1989,
// "Computer Aided Kinematics and Dynamics of Mechanical Systems", Sec. 3.3 and 6.3 for the form
// J nu' = gamma):
//   rows 0-2, every joint (point coincidence, in N; s_P, s_C the joint point from each origin):
//     g = p_NoCo_N + R_NC s_C - p_NoPo_N - R_NP s_P
//     J_C = [ I, -R_NC [s_C x], R_NC Phi_C ],  J_P = [ -I, R_NP [s_P x], -R_NP Phi_P ]
//     gamma = -( R_NC (w_C x (w_C x s_C) + 2 w_C x s_C') - R_NP (w_P x (w_P x s_P) + 2 w_P x s_P') )
//   rotation rows, first in terms of the frames' angular velocities w_F, w_G (rows A_F, A_G, and
//   gamma_FG = -(A_F' w_F + A_G' w_G), the rigid rows of the frames F and G):
//   revolute, rows 3-4 (the child's copy of the axis stays on the parent's axis):
//     u = R_FG a_C (a_C = the axis in G, constant), b_1, b_2 unit vectors fixed in F, normal to a_P;
//     g_k = b_k . u;  g_k' = c_k . w_FG_F with c_k = u x b_k, w_FG_F = R_FG w_G - w_F
//     A_G = c_k^T R_FG,  A_F = -c_k^T
//     gamma_k = -( (u' x b_k) . w_FG_F + c_k . R_FG (w_FG_G x w_G) ),  u' = w_FG_F x u
//     (the F-frame derivative of w_FG_F is R_FG w_G' - w_F' + R_FG (w_FG_G x w_G), because
//      d/dt R_FG = R_FG [w_FG_G x]).
//   prescribed revolute (docs/prescribed-motion.md), row 5 as well: the angle itself, a rheonomic
//   constraint (Haug 1989, Sec. 6.3: driving constraints g(q, t) = 0, whose velocity and
//   acceleration equations carry -g_t and -g_tt):
//     g_5 = angle_wrapped (relative kinematics only; track subtracts the prescribed angle),
//     g_5' = a_P . w_FG_F  (the rate; track subtracts theta'(t)),
//     A_G = a_P^T R_FG, A_F = -a_P^T,
//     gamma_5 = -a_P . R_FG (w_FG_G x w_G)  (track adds theta''(t)),
//     from angle'' = a_P . (R_FG w_G' - w_F' + R_FG (w_FG_G x w_G)) (the F-frame derivative above).
//     Its multiplier is the constraint moment on G about the axis: the joint's torque.
//   fixed, rows 3-5 (relative attitude stays at the offset q_PJ0; prismatic: rows 2-4):
//     q_e = q_PJ0^* (x) q_FG, s = sign(q_e.w);  g = 2 s vec(q_e)
//     g' = E_q w_FG_G with E_q = s (q_e.w I + [vec(q_e) x])  (Shuster 1993 Eq. 305),
//     w_FG_G = w_G - R_GF w_F,  A_G = E_q, A_F = -E_q R_GF
//     gamma = -( E_q' w_FG_G + E_q (w_FG_G x R_GF w_F) )
//   spherical: rows 0-2 only.
//   universal (two-axis gimbal), row 3 (the rows 0-2 are the point's): the child's copy of the
//   second axis, u = R_FG n2_G (n2_G = R_PJ0^T n2_P, constant in G: R_FG = Rot(n1, a1)
//   Rot(n2, a2) R_PJ0 turns n2 by a1 only), keeps its angle to the first axis n1 (fixed in F):
//     g_3 = n1 . u - n1 . n2 (its value at zero angles), g_3' = c . w_FG_F with c = u x n1
//     (= -n, n = n1 x u: the relative angular velocity has no component along n), and A_G, A_F,
//     gamma_3 those of a revolute row with b = n1 (joints/axis_row.hpp).
//   prismatic (joints/prismatic.cpp): its own translation rows (point_rows), no node frames.
//     Po, Co the body origins, s_P = p_PoJ_P, s_C = p_CoJ_C; D_F = R_NP^T (p_NoCo_N + R_NC s_C -
//     p_NoPo_N), the child's joint point from Po (P components); d = D_F - s_P the separation of
//     the two joint points (s axis_P on the motion). For a unit vector c fixed in P (Kane, Likins
//     & Levinson 1983, Sec. 2.7, the point's velocity and acceleration in a moving frame):
//       g = c . d,  g' = c . u + (w_P x c) . D_F,  u = R_NP^T (v_C - v_P) + R_PC (w_C x s_C),
//       J_C = [ (R_NP c)^T, (s_C x R_CP c)^T ],  J_P = [ -(R_NP c)^T, (c x D_F)^T ],
//       gamma = -( (w_P x (w_P x c)) . D_F + 2 (w_P x c) . u + c . R_PC (w_C x (w_C x s_C)) )
//     rows 0-1: c = b1_P, b2_P (the separation normal to the axis is zero); rows 2-4: the fixed
//     joint's attitude lock above (R_PC = R_PJ0); prescribed, row 5: c = a_P, g_5 = s (track
//     subtracts angle0 + theta(t), g_5' and gamma_5 take -theta', +theta''); its multiplier is
//     the constraint force along the axis on the child: the joint's force.
//   Then, by the node-frame kinematics above (chain rule), on a flexible side:
//     J_P[rot, w_P] = A_F E_P^T,  J_P[rot, eta_P'] = A_F E_P^T Jl_P Psi_P,
//     gamma -= A_F E_P^T (c_P - w_rel_P x w_P)        (and the same for C with A_G);
//   on a rigid side J_P[rot, w_P] = A_F.
// Geometric stiffening (modal_body.hpp): at a node of a stiffened body the point is
// s = r + Phi eta + e w(eta), s' = Phi~ eta' with Phi~ = Phi + e (G eta)^T, s'' = Phi~ eta'' + e q,
// so rows 0-2 take Phi~ in place of Phi in their modal columns and gamma loses R e q on each side.
// Rows beyond rows() are zero (TreeKkt pads every joint block to 6 rows).
// Who writes what: constraint_rows() writes rows 0-2 and the node-frame chain rule, common to
// every type but one with its own point rows (prismatic); the rotation rows of each type, its
// coordinates and rates, and a prescribed joint's time terms are written by the type's unit
// (joints/joint_unit.hpp; joints/revolute.cpp, fixed.cpp, prismatic.cpp, universal.cpp).
#pragma once

#include "core/system.hpp"
#include "formulations/newton_euler/scalar.hpp"
#include "formulations/newton_euler/tree_kkt.hpp"

#include <Eigen/Geometry>

namespace crossdyn::newton_euler {

// One side of a joint: a body and, on a flexible body, the node the joint is attached to.
struct JointSide {
  int body = -1;
  int modes = 0;        // the body's number of modes (0: rigid body)
  int node = -1;        // FlexBody::nodes index, or -1
  Eigen::Vector3d r = Eigen::Vector3d::Zero();  // undeformed joint point from Bo, body frame
  Eigen::Matrix3Xd Phi, Psi;  // 3 x modes: the node's shapes and slopes (zero without a node)
  bool stiff = false;         // geometric stiffening at this node: e, G below
  Eigen::Vector3d e = Eigen::Vector3d::Zero();
  Eigen::MatrixXd G;          // modes x modes
};

struct JointUnit;  // the joint type's verbs (joints/joint_unit.hpp)

// A joint's own coordinates in the engine: (angle, 0) revolute, (position s, 0) prismatic,
// (a1, a2) universal.
using JointCoords = Eigen::Vector2d;
template <class S> using JointCoordsT = Eigen::Matrix<S, 2, 1>;

// The constant description of one joint (built once from System::joints[j]).
struct JointModel {
  const JointUnit* unit = nullptr;    // chosen from Joint::type (joints/dispatch.cpp)
  int parent = -1, child = -1;
  int rows = 0;                       // 3 (spherical), 5 (revolute, prismatic; 6 prescribed),
                                      // 4 (universal), 6 (fixed), 0 (free)
  bool prescribed = false;            // revolute, prismatic with Joint::prescribed: row 5
  bool has_angle = false;             // coordinates in the engine's coords_ (from angle0, angle2_0)
  bool unwraps = false;               // angles unwrapped after every step (not prescribed)
  bool translates = false;            // its load has a force along a translation (prismatic)
  JointSide P, C;                     // parent side (frame F) and child side (frame G)
  Eigen::Quaterniond q_PJ0 = Eigen::Quaterniond::Identity();
  Eigen::Matrix3d R_PJ0 = Eigen::Matrix3d::Identity();
  Eigen::Vector3d a_P = Eigen::Vector3d::UnitZ();  // revolute axis in F
  Eigen::Vector3d a_C = Eigen::Vector3d::UnitZ();  // the same axis in G (= R_PJ0^T a_P, constant)
  Eigen::Vector3d b1_P, b2_P;         // unit, fixed in F, (a_P, b1_P, b2_P) right-handed
  Eigen::Vector3d e1_C, e2_C;         // unit, in G (J0) axes, (a_C, e1_C, e2_C) right-handed
  Eigen::Vector3d a2_P = Eigen::Vector3d::UnitY();  // universal: the second axis n2 in F (zero angles)
  Eigen::Vector3d a2_C = Eigen::Vector3d::UnitY();  // the same axis in G (R_PJ0^T a2_P, constant)
  double a12 = 0;                     // universal: a_P . a2_P, the row's value at zero angles
  // The joint's dampers as the equations of motion see them: Joint::damping, damping2 times
  // EngineOptions::test_damper_scale (the engine scales them after from(); 1 in every real run,
  // then they are the scene's values exactly). The power column P uses the scene's Joint values.
  double damping = 0, damping2 = 0;

  // Rigid attachments on both sides (the bodies' modes are not known).
  static JointModel from(const Joint& joint);
  // With the bodies of `system`: node attachments and modal columns of flexible sides.
  static JointModel from(const System& system, int j);
};

// One body's kinematic state, read from the engine's state vector.
// The structures below are templates on the scalar S (scalar.hpp): double in the run, Cx in the
// complex step of accelerations_tangent() (newton_euler.cpp, issue 27).
template <class S>
struct BodyKinematicsT {
  Quat<S> q_NB = Quat<S>::Identity();  // unit
  Mat3<S> R_NB = Mat3<S>::Identity();
  Vec3<S> p_NoBo_N = Vec3<S>::Zero();
  Vec3<S> v_NBo_N = Vec3<S>::Zero();
  Vec3<S> w_NB_B = Vec3<S>::Zero();
  Eigen::Matrix<S, Eigen::Dynamic, 1> eta, eta_dot;  // modal coordinates and rates (size 0: rigid body)
};
using BodyKinematics = BodyKinematicsT<double>;

// A joint frame on one side at the current state (see the header comment).
template <class S>
struct NodeFrameT {
  Vec3<S> s_B = Vec3<S>::Zero();      // joint point from Bo, body frame
  Vec3<S> sdot_B = Vec3<S>::Zero();   // Phi~ eta': its rate relative to the body
  Eigen::Matrix<S, 3, Eigen::Dynamic> Phi;  // 3 x modes: Phi~ (= Phi when not stiffened)
  Vec3<S> a_B = Vec3<S>::Zero();      // e q: s'' = Phi~ eta'' + a_B (stiffened)
  Eigen::Matrix<S, Eigen::Dynamic, 1> g;    // scratch: G eta
  Mat3<S> E = Mat3<S>::Identity();    // exp([psi x]): the frame in the body frame
  Quat<S> q_E = Quat<S>::Identity();
  Vec3<S> w_rel_B = Vec3<S>::Zero();  // Jl(psi) Psi eta'
  Vec3<S> c_B = Vec3<S>::Zero();      // (d/dt Jl(psi)) Psi eta'
  Eigen::Matrix<S, 3, Eigen::Dynamic> JlPsi;  // 3 x modes: Jl(psi) Psi
};
using NodeFrame = NodeFrameT<double>;

// Relative kinematics of a joint's child-side frame G in its parent-side frame F.
template <class S>
struct JointKinematicsT {
  NodeFrameT<S> F, G;
  Quat<S> q_FG = Quat<S>::Identity();
  Mat3<S> R_FG = Mat3<S>::Identity();
  Mat3<S> R_PC = Mat3<S>::Identity();  // the bodies' relative attitude
  Vec3<S> w_F = Vec3<S>::Zero();       // w_NF in F components
  Vec3<S> w_G = Vec3<S>::Zero();       // w_NG in G components
  Vec3<S> w_FG_G = Vec3<S>::Zero();    // w_G - R_GF w_F
  Vec3<S> w_FG_F = Vec3<S>::Zero();    // R_FG w_G - w_F
  S angle_wrapped = 0;  // revolute: in (-pi, pi], the rotation of G about the axis;
                             // prismatic: the position s; universal: a1 in (-pi, pi]
  S rate = 0;              // revolute: a_P . w_FG_F; prismatic s'; universal a1'
  S angle2_wrapped = 0, rate2 = 0;       // universal: a2 in (-pi, pi], a2'
  // Prismatic: the child's joint point from Po (D_F, P components) and its velocity relative to
  // Po's, R_NP^T (v_C - v_P) + R_PC (w_C x s_C) (u, P components).
  Vec3<S> r_PoJ_F = Vec3<S>::Zero();
  Vec3<S> v_PoJ_F = Vec3<S>::Zero();

  // Sizes the node frames' modal parts (once, outside the right-hand side).
  explicit JointKinematicsT(const JointModel& m);
  JointKinematicsT() = default;
};
using JointKinematics = JointKinematicsT<double>;

// The constraint rows of one joint at one state.
template <class S>
struct ConstraintRowsT {
  Mat6<S> J_P = Mat6<S>::Zero();    // columns [v_P; w_P]
  Mat6<S> J_C = Mat6<S>::Zero();    // columns [v_C; w_C]
  Eigen::Matrix<S, 6, Eigen::Dynamic> Je_P, Je_C;  // columns eta_P', eta_C' (6 x modes)
  Vec6<S> g = Vec6<S>::Zero();      // position violation (rows 0-2 m, 3-5 rad-like)
  Vec6<S> gdot = Vec6<S>::Zero();   // J nu: velocity violation
  Vec6<S> gamma = Vec6<S>::Zero();  // -Jdot nu

  explicit ConstraintRowsT(const JointModel& m);
  ConstraintRowsT() = default;
};
using ConstraintRows = ConstraintRowsT<double>;

// The functions below are defined in joint_constraints.cpp (revolute_angle_wrapped in
// joints/revolute.cpp) and instantiated there for S = double and S = Cx (scalar.hpp); on Cx a
// flexible side's node frame uses so3::coefficients_sq and so3::quaternion (no |.|).

// (side, body state) => the joint frame on that side.
template <class S>
void node_frame(const JointSide& side, const BodyKinematicsT<S>& B, NodeFrameT<S>& out);

// (P, C body states) => node frames and relative kinematics of joint `m`. No allocation once
// `out` is sized (JointKinematics(m)).
template <class S>
void joint_kinematics(const JointModel& m, const BodyKinematicsT<S>& P, const BodyKinematicsT<S>& C,
                      JointKinematicsT<S>& out);

// (P, C body states, relative kinematics) => constraint rows. No allocation once `out` is sized.
template <class S>
void constraint_rows(const JointModel& m, const BodyKinematicsT<S>& P, const BodyKinematicsT<S>& C,
                     const JointKinematicsT<S>& jk, ConstraintRowsT<S>& out);

// Angle of a revolute joint's child-side frame about its axis: atan2 of the rotated e1 in (e1, e2)
// (joints/revolute.cpp).
template <class S>
S revolute_angle_wrapped(const JointModel& m, const Mat3<S>& R_FG);

// The branch of `wrapped` (+ 2 pi k) nearest to `reference` (the branch chosen on the real part).
double unwrap_angle(double wrapped, double reference);
inline Cx unwrap_angle(const Cx& wrapped, double reference) {
  return wrapped + (unwrap_angle(wrapped.real(), reference) - wrapped.real());
}

}  // namespace crossdyn::newton_euler
