// The immutable model every engine consumes: bodies, joints and loads read from one scene file.
//
// Notation (Drake's monogram notation, see docs/style.md item 3):
//   N          the inertial (Newtonian) frame;  B, P, C   a body, a joint's parent, its child.
//   Bo         the origin of body frame B, which is always the body's centre of mass (CM).
//   p_PoJ_P    position from Po to the joint point J, expressed in frame P.
//   w_NB_B     angular velocity of B in N, expressed in B.
//   R_PC       rotation matrix taking C components to P components (v_P = R_PC v_C).
//   q_NB       unit quaternion, scalar first, with R(q_NB) = R_NB.
//
// Joint kinematics, shared by every engine (docs/conventions.md):
//   R_PC = R_PJ0 * R_J(coordinates), where R_PJ0 is the joint's fixed orientation offset (the
//   child frame's attitude in P at joint coordinate zero) and R_J the joint rotation:
//     revolute   R_J = Rot(axis_J, angle), axis_J = R_PJ0^T axis_P (the axis is given in P);
//     spherical  R_J = R(q_J), q_J the joint quaternion (identity at zero);
//     fixed      R_J = identity;
//     prismatic  R_J = identity; the child's joint point slides along axis_P by `position` s:
//                p_NoPo_N + R_NP (p_PoJ_P + s axis_P) = p_NoCo_N + R_NC p_CoJ_C;
//     universal  (two-axis gimbal) R_PC = Rot(axis_P, angle1) Rot(axis2_P, angle2) R_PJ0: the first
//                axis is fixed in P, the second turns with the first angle (both given in P at
//                zero angles; never parallel, so the joint has no configuration singularity);
//     free       the base: parent is N, R_NB = R(q_NB), no offset.
//   The joint point J coincides in both bodies: p_NoPo_N + R_NP p_PoJ_P = p_NoCo_N + R_NC p_CoJ_C
//   (prismatic: J displaced by s axis_P in P, above).
//   At a node of a flexible body (Joint::parent_node, child_node; FlexBody below) the point moves
//   with the node and the joint frame turns with the node's slope:
//     R_PC = exp([psi_P x]) R_PJ0 R_J exp([psi_C x])^T,
//     p_NoPo_N + R_NP (p_PoJ_P + u_P) = p_NoCo_N + R_NC (p_CoJ_C + u_C),
//   with u, psi the node's displacement and small rotation (zero for a rigid attachment); a
//   revolute axis turns with the parent side: exp([psi_P x]) axis_P.
//
// Loads, all acting on the child with the reaction on the parent:
//   revolute   tau = -stiffness (angle - neutral_angle) - damping rate + motor(t), about the axis;
//              potential energy V = stiffness (angle - neutral_angle)^2 / 2.
//   prismatic  F = -stiffness (position - neutral_angle) - damping rate + motor(t), a force along the
//              axis (N; stiffness N/m, neutral_angle the spring's rest position in m, damping N s/m);
//              V = stiffness (position - neutral_angle)^2 / 2.
//   universal  per axis k = 1, 2: tau_k = -stiffness_k (angle_k - neutral_k) - damping_k rate_k +
//              motor_k(t), the generalised force of angle k (axis 1: stiffness, neutral_angle,
//              damping; axis 2: stiffness2, neutral_angle2, damping2; motor_universal holds
//              [motor_1, motor_2]); V = sum_k stiffness_k (angle_k - neutral_k)^2 / 2, so that
//              tau_k = -dV/dangle_k for the spring. The torque on the child is the T in the plane
//              of the two current axes a_1, a_2 with T . a_k = tau_k: for perpendicular axes
//              T = tau_1 a_1 + tau_2 a_2, the torque about each axis; for oblique ones the dual
//              basis of (a_1, a_2) (with tau_k as torques about the axes the spring's energy
//              would not balance).
//   spherical  tau_C = -stiffness phi - damping w_PC_C + motor(t) (components in the child frame),
//              where phi is the rotation vector of q_J (log map); V = stiffness |phi|^2 / 2.
//              (phi is an eigenvector of the rotation-vector Jacobian, so -stiffness phi is exactly
//              the generalised force of V for any choice of coordinates.)
//   body       external torque, piecewise constant in time, in the body frame or in N.
//
// Prescribed motion (docs/prescribed-motion.md; issue 13): a revolute joint with `prescribed` set
// is not a degree of freedom: its angle is angle0 + theta(t), a given smooth function of time
// (PrescribedMotion below), and every engine reports the torque about the axis that the joint
// must apply to the child to make it so (output column <joint>.torque; a prescribed prismatic
// joint likewise: position angle0 + theta(t) in m, and <joint>.force, N; springs, dampers and
// motors are not allowed on a prescribed joint, so it is the whole joint torque). The base
// joint (joints[0]) is either the free joint or such a prescribed revolute joint whose parent is
// N (Joint::parent = -1): the base then turns about an axis fixed in N through a point fixed in N
// (Kane, Ryan and Banerjee 1987: a hub driven through a prescribed spin-up).
//
// Everything is SI (kg, m, s, rad, N, N m); the reader converts units.
#pragma once

#include "core/names.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

namespace crossdyn {

// A piecewise-constant function of time with values of dimension D (1 for a revolute motor,
// 3 for a spherical motor or a body torque). value(t) = values[k] for times[k] <= t < times[k+1];
// zero before times[0]. Empty means identically zero.
template <int D>
struct PiecewiseConstant {
  std::vector<double> times;                       // strictly increasing, times[0] >= 0
  std::vector<Eigen::Matrix<double, D, 1>> values;  // same length as times

  bool empty() const { return times.empty(); }
  Eigen::Matrix<double, D, 1> value(double t) const {
    Eigen::Matrix<double, D, 1> v = Eigen::Matrix<double, D, 1>::Zero();
    for (std::size_t k = 0; k < times.size() && times[k] <= t; ++k) v = values[k];
    return v;
  }
};

// A prescribed joint angle theta(t) (added to the joint's initial angle), its rate and its
// acceleration; C^3 in t. The one profile so far is Kane, Ryan and Banerjee's spin-up
// (J. Guidance 10(2), 1987, Eq. (61)), reaching the rate Omega_s = `rate` at T = `ramp_time`:
//   t <= T:  theta = (Omega_s / T) (t^2 / 2 + (T / (2 pi))^2 (cos(2 pi t / T) - 1))
//   t >  T:  theta = Omega_s (t - T / 2)
// so theta' = (Omega_s / T) (t - (T / (2 pi)) sin(2 pi t / T)) and
// theta'' = (Omega_s / T) (1 - cos(2 pi t / T)) up to T, then Omega_s and 0.
//   spin-up  theta = (rate/T) (t^2/2 + (T/2 pi)^2 (cos(2 pi t/T) - 1)) up to T, then rate (t - T/2)
//            (Kane, Ryan and Banerjee 1987, Eq. (60)): from rest to a constant rate.
//   deploy   theta = travel (t/T - sin(2 pi t/T) / (2 pi)) up to T, then travel: from rest to rest
//            through `travel` (a cycloidal motion law; rate and acceleration zero at both ends).
// Units are the joint's: rad for a revolute joint, m for a prismatic one.
struct PrescribedMotion {
  enum class Profile { SpinUp, Deploy };
  Profile profile = Profile::SpinUp;
  double rate = 0;        // spin-up: Omega_s, rad/s (prismatic: m/s)
  double ramp_time = 1;   // T, s, > 0
  double travel = 0;      // deploy: the distance travelled, rad (prismatic: m)

  double angle(double t) const;     // theta(t), rad (0 at t = 0)
  double velocity(double t) const;  // theta'(t), rad/s
  double accel(double t) const;     // theta''(t), rad/s^2
  // Times where the profile changes formula (integrators stop there): {T}.
  std::vector<double> breakpoints() const { return {ramp_time}; }
};

// A flexible body: the modal model every engine implements exactly, with no term dropped
// (docs/conventions.md "Flexible bodies"; reference paper Eqs. (3)-(6) and (39)-(40), Example 2).
//
//   The body's mass is carried by nodes. Node i has mass m_i, undeformed position p_BoNi_B from the
//   body origin Bo (the undeformed CM: sum_i m_i p_BoNi_B = 0), an optional rigid rotational
//   inertia J_Ni_B about itself (fixed in the body frame: it does not turn with deformation), mode
//   shapes Phi_i (3 x n, translation per unit modal coordinate, body frame) and mode slopes Psi_i
//   (3 x n, small rotation vector per unit modal coordinate; zero where no joint attaches).
//   Deformation:       u_i = Phi_i eta,  psi_i = Psi_i eta   (paper Eq. (3): u = sum_k Phi_k q_k)
//   Kinetic energy:    T = 1/2 sum_i m_i |v_NBo_N + w x (p_i + u_i) + du_i/dt|^2 + 1/2 sum_i w . J_i w
//                      (exact for that displacement field: every term second order in eta kept)
//   Elastic energy:    V = 1/2 eta^T K eta;   modal damping force on eta: -D eta'.
//   The body's rigid mass and inertia (Body::mass, Body::I_BBo_B) are the node sums
//   m = sum m_i,  I = sum_i (J_i + m_i (|p_i|^2 1 - p_i p_i^T))   (the reader sets them).
//   A joint attached at node i (Joint::parent_node / child_node) has its point at p_i + u_i and
//   its frame turned from the body frame by the rotation exp([psi_i x]) (exact, so orthonormal).
//
//   Geometric stiffening (FlexBody::geometric_stiffening; docs/flexible-bodies.md "Geometric
//   stiffening"): the displacement gains a term second order in eta, the foreshortening of a
//   bent beam (Kane, Ryan and Banerjee 1987, Eq. (8); Sharf 1995):
//      u_i = Phi_i eta + e_i (1/2 eta^T G_i eta)
//   with e_i a unit vector (body frame) and G_i a symmetric n x n matrix per node. Every engine
//   keeps this term exactly in positions, velocities (du_i/dt = Phi_i eta' + e_i eta^T G_i eta')
//   and accelerations; the slopes psi_i stay linear. Without it (G_i empty) the model is the
//   linear one above.
struct FlexNode {
  std::string name;
  double mass = 0;                                        // m_i, kg
  Eigen::Vector3d p_BoNi_B = Eigen::Vector3d::Zero();     // undeformed position, m
  Eigen::Matrix3d J_Ni_B = Eigen::Matrix3d::Zero();       // rigid inertia about the node, kg m^2
  Eigen::Matrix3Xd Phi_B;                                 // 3 x n mode shapes, m per unit eta
  Eigen::Matrix3Xd Psi_B;                                 // 3 x n mode slopes, rad per unit eta
  // Geometric stiffening only (else e_B zero and G empty): second-order displacement
  // e_B (1/2 eta^T G eta), m per unit eta^2.
  Eigen::Vector3d e_B = Eigen::Vector3d::Zero();          // unit direction, body frame
  Eigen::MatrixXd G;                                      // n x n symmetric (0 x 0 when off)
};

struct FlexBody {
  std::vector<std::string> mode_names;  // n modes: output columns <body>.<mode>, <body>.<mode>_rate
  std::vector<FlexNode> nodes;
  Eigen::MatrixXd K;                    // n x n modal stiffness (symmetric, positive semi-definite)
  Eigen::MatrixXd D;                    // n x n modal damping (symmetric, positive semi-definite)
  // Every node carries the second-order displacement e_i (1/2 eta^T G_i eta) (see above).
  bool geometric_stiffening = false;
  std::string origin;                   // where the data came from ("beam generator: ...", a file)
  // The scene's `flexible:` block this body was read from, in the canonical form the scene
  // writer writes back (YAML, SI units, every key; core/scene/flex_block.hpp). Empty when built
  // in code. The engines ignore it.
  std::string scene_form;
  // The files the data was read from (the nodal file, then the modes file when separate), as the
  // reader opened them; empty for the beam generator. Outputs are checked against them
  // (System::input_files). The engines ignore it.
  std::vector<std::string> data_files;

  int modes() const { return static_cast<int>(mode_names.size()); }
  int node_index(const std::string& n) const {
    for (std::size_t i = 0; i < nodes.size(); ++i)
      if (nodes[i].name == n) return static_cast<int>(i);
    return -1;
  }
};

struct Body {
  std::string name;
  double mass = 0;              // kg
  Eigen::Matrix3d I_BBo_B;      // inertia about the CM Bo, body axes, kg m^2 (flexible: undeformed)
  std::optional<FlexBody> flex;  // empty: rigid body

  // External torque on this body, piecewise constant.
  enum class Frame { Body, Inertial };
  Frame torque_frame = Frame::Body;
  PiecewiseConstant<3> torque;  // N m
};

enum class JointType { Free, Revolute, Spherical, Fixed, Prismatic, Universal };

struct Joint {
  std::string name;
  JointType type = JointType::Revolute;
  int parent = -1;              // body index; -1 for the free joint (parent is N)
  int child = -1;               // body index
  Eigen::Vector3d p_PoJ_P = Eigen::Vector3d::Zero();  // parent_point
  Eigen::Vector3d p_CoJ_C = Eigen::Vector3d::Zero();  // child_point
  Eigen::Vector3d axis_P = Eigen::Vector3d::UnitZ();  // revolute or prismatic axis, universal
                                                       // first axis: unit, in the parent frame
  Eigen::Vector3d axis2_P = Eigen::Vector3d::UnitY();  // universal second axis: unit, in the
                                                       // parent frame at zero angles
  Eigen::Quaterniond q_PJ0 = Eigen::Quaterniond::Identity();  // fixed orientation offset
  // Attachment to a node of a flexible parent or child (FlexBody::nodes index; -1: rigid). When
  // set, p_PoJ_P (p_CoJ_C) is that node's undeformed position, the joint point moves with the
  // node's displacement and the joint frame turns with its slope (see FlexBody).
  int parent_node = -1;
  int child_node = -1;

  // Hinge spring, damper and motor (revolute: scalar about the axis; spherical: see header;
  // prismatic: along the axis, in N/m, m, N s/m and N; universal: the first axis here, the second
  // in the *2 fields).
  double stiffness = 0;         // N m / rad (prismatic N / m)
  double neutral_angle = 0;     // rad, revolute spring's unstretched angle (prismatic: m)
  double damping = 0;           // N m s / rad (prismatic N s / m)
  PiecewiseConstant<1> motor_revolute;   // N m (prismatic: the force along the axis, N)
  PiecewiseConstant<3> motor_spherical;  // N m, child frame
  double stiffness2 = 0, neutral_angle2 = 0, damping2 = 0;  // universal second axis
  PiecewiseConstant<2> motor_universal;  // N m, [about axis 1, about axis 2]

  // Revolute or prismatic only: the angle (position) is prescribed, angle0 + prescribed->angle(t)
  // (see the header); then rate0 is prescribed->velocity(0) and the joint has no degree of freedom
  // (dof() 0).
  std::optional<PrescribedMotion> prescribed;

  // Initial conditions.
  double angle0 = 0, rate0 = 0;  // revolute rad, rad/s; prismatic m, m/s; universal first axis
  double angle2_0 = 0, rate2_0 = 0;                              // universal second axis
  Eigen::Quaterniond q_J0 = Eigen::Quaterniond::Identity();      // spherical joint attitude
  Eigen::Vector3d w_PC_C0 = Eigen::Vector3d::Zero();             // spherical, rad/s
  // Free joint (base) initial state.
  Eigen::Vector3d p_NoBo_N0 = Eigen::Vector3d::Zero();           // m
  Eigen::Quaterniond q_NB0 = Eigen::Quaterniond::Identity();
  Eigen::Vector3d w_NB_B0 = Eigen::Vector3d::Zero();             // rad/s
  Eigen::Vector3d v_NBo_N0 = Eigen::Vector3d::Zero();            // m/s (see zero_linear_momentum)

  // Whether the joint has a damper or a motor on any of its coordinates, whatever its type (the
  // one place that knows which fields each type's loads use: the harness asks here).
  bool has_damper() const { return damping != 0 || damping2 != 0; }
  bool has_motor() const {
    return !motor_revolute.empty() || !motor_spherical.empty() || !motor_universal.empty();
  }
  bool has_spring() const { return stiffness != 0 || stiffness2 != 0; }

  // Number of generalised speeds this joint contributes (free 6, revolute and prismatic 1 (0 when
  // prescribed), spherical 3, fixed 0, universal 2).
  int dof() const {
    switch (type) {
      case JointType::Free: return 6;
      case JointType::Revolute:
      case JointType::Prismatic: return prescribed ? 0 : 1;
      case JointType::Spherical: return 3;
      case JointType::Fixed: return 0;
      case JointType::Universal: return 2;
    }
    return 0;
  }
};

// Tolerance on one compared quantity: pass when |a - b| <= atol + rtol * max_t |b| over the run.
struct Tolerance {
  double atol = 1e-8;
  double rtol = 1e-8;
};

struct CompareSpec {
  Tolerance default_tolerance;
  // Per quantity: a column name ("main.wx"), a class ("attitude", "H", "E", "H.drift",
  // "E.drift"), or "<body>.w" / "<joint>.rate"-style prefixes as the harness documents.
  std::vector<std::pair<std::string, Tolerance>> tolerances;
  std::vector<std::pair<std::string, std::string>> excluded;  // quantity, reason
};

struct RunSpec {
  double duration = 0;          // s, > 0
  double output_step = 0;       // s, > 0
  Choice<Integrator> integrator = Integrator::Rkf78;  // core/names.hpp
  double rtol = 1e-10, atol = 1e-10;
  double dt = 1e-3;             // fixed step for rk4; first trial step for adaptive methods
  bool dt_given = false;        // the scene sets run.dt (else adaptive methods estimate their
                                // first step: core/integrate.hpp, IntegratorSettings::first_step)
};

// The spacecraft's environment (issue 28; docs/environment.md). Without one (Kind::None) N is an
// inertial frame with no gravity. Every engine evaluates the loads below from its own state, in its
// own code (no engine calls another's, and none calls a shared load formula).
//
//   Uniform   gravity g_N (m/s^2, N components) on every mass: the force m g on each rigid body's CM
//             and on each flexible node (exact for a uniform field: no moment about any body's CM).
//             Potential V = -sum m g . p_NoX_N (part of E).
//   Orbit     a central body's point-mass field (mu = G M, m^3/s^2) seen from a reference point O
//             on a circular orbit of radius R about it (core/orbit.hpp: O's position, the orbit
//             frame, n = sqrt(mu / R^3)). N is then the non-rotating frame whose origin moves with
//             O (axes those of the central body's inertial frame); O is the system's CM at t = 0
//             (each engine computes it from its own initial state). The field is expanded to second
//             order about O (Hughes 2004, "Spacecraft Attitude Dynamics", Sec. 8.1; Schaub and
//             Junkins 2018, Sec. 4.3.2): with r the position from O and zhat the unit vector from the
//             central body to O, the tidal acceleration is
//               a(r) = T r,  T = n^2 (3 zhat zhat^T - 1)                (the gravity gradient)
//             on every mass: force m T r_c on each rigid body's CM (r_c from O) and the torque about
//             its CM  tau = 3 n^2 zhat x (I_N zhat)  (I_N the body's inertia in N); on each flexible
//             node the force m_i T r_i and, with a node inertia J_i, 3 n^2 zhat x (J_i,N zhat).
//             Potential (per body, about its CM; per node likewise)
//               V = -1/2 m r_c^T T r_c + 3/2 n^2 zhat^T I_N zhat - 1/2 n^2 tr(I)
//             so E = T + V(t) is not conserved (zhat turns with the orbit) but the Jacobi integral
//               J = E - w_NO_N . H_O_N   (H_O_N the angular momentum about O, in N)
//             is, without non-conservative loads. The third-order terms dropped are (|r| / R) of the
//             second-order ones (1.5e-6 for a 10 m spacecraft at 7000 km). O's motion is prescribed
//             (a circular orbit): the system's attitude and shape change its orbit only at third
//             order, and a CM that leaves O (zero_linear_momentum: false) moves under T (Hill's
//             equations, non-rotating form).
struct Environment {
  enum class Kind { None, Uniform, Orbit };
  Kind kind = Kind::None;
  Eigen::Vector3d g_N = Eigen::Vector3d::Zero();  // Uniform: m/s^2, N components
  // Orbit: the central body and the circular orbit of O (angles in N = the central body's
  // inertial axes: inclination i and right ascension of the ascending node raan of the orbit
  // plane, argument of latitude u0 of O at t = 0 measured from the ascending node).
  double mu = 0;           // m^3/s^2
  double body_radius = 0;  // m (0: not given; only for `altitude` and the report)
  double radius = 0;       // R, m, > body_radius
  double inclination = 0, raan = 0, latitude0 = 0;  // rad

  bool none() const { return kind == Kind::None; }
  bool uniform() const { return kind == Kind::Uniform; }
  bool orbit() const { return kind == Kind::Orbit; }
  // The orbit's mean motion n = sqrt(mu / R^3), rad/s (0 without an orbit).
  double mean_motion() const;
};

struct System {
  std::string name;             // scene name (file stem)
  std::string file;             // path the scene was read from ("" when built in code)
  std::string description;
  std::string source;
  std::vector<Body> bodies;     // bodies[joints[j].child] ...
  // Joints in topological order: joints[0] is the base body's joint (the free joint, or a
  // prescribed revolute joint whose parent is N: parent -1, parent point, axis and offset in N),
  // and every joint's parent appears as the child of an earlier joint. Exactly one joint per body.
  std::vector<Joint> joints;
  bool zero_linear_momentum = true;  // base CM velocity chosen so total linear momentum is zero
  std::string analytic;              // "" or "torque-free" (single free rigid body, no loads)
  Environment environment;           // gravity; none by default
  RunSpec run;
  CompareSpec compare;

  // Every file this System was read from: the scene file, then each flexible body's data files
  // (FlexBody::data_files); empty when built in code. No output may replace one of them.
  std::vector<std::string> input_files() const {
    std::vector<std::string> files;
    if (!file.empty()) files.push_back(file);
    for (const Body& b : bodies)
      if (b.flex) files.insert(files.end(), b.flex->data_files.begin(), b.flex->data_files.end());
    return files;
  }

  int base_body() const { return joints.empty() ? -1 : joints[0].child; }
  // The base moves freely (joints[0] is free), or its motion is prescribed (a prescribed
  // revolute joint to N).
  bool base_is_free() const { return !joints.empty() && joints[0].type == JointType::Free; }
  int joint_of_body(int b) const {
    for (std::size_t j = 0; j < joints.size(); ++j)
      if (joints[j].child == b) return static_cast<int>(j);
    return -1;
  }
  int body_index(const std::string& n) const {
    for (std::size_t b = 0; b < bodies.size(); ++b)
      if (bodies[b].name == n) return static_cast<int>(b);
    return -1;
  }
  // Times at which any load changes value (integrators stop there so steps do not straddle them).
  std::vector<double> breakpoints() const;
};

}  // namespace crossdyn
