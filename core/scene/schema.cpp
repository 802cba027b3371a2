// The scene schema table (schema.hpp) and the queries the reader, the writer and the
// documentation generator ask of it.
#include "core/scene/schema.hpp"

#include "core/names.hpp"

#include <array>
#include <stdexcept>
#include <unordered_map>
#include <vector>

namespace crossdyn::scene {
namespace {

using units::Dimension;
using enum Type;

// clang-format off
constexpr std::array kKeys = std::to_array<Key>({
// ----- the scene ------------------------------------------------------------------------------
{.path = "", .type = Map, .noun = "the scene",
 .doc = "The scene file: one YAML mapping."},
{.path = "name", .type = Name, .required = true, .noun = "scene name",
 .doc = "The scene's name; committed scenes are named after their file. Letters, digits, `_`, `-` "
        "and `.`, starting with a letter."},
{.path = "description", .type = Text, .default_value = "empty", .noun = "description",
 .doc = "What the scene is."},
{.path = "source", .type = Text, .default_value = "empty", .noun = "source",
 .doc = "Where the data come from, and every assumption made where the source is silent."},
{.path = "analytic", .type = Word, .default_value = "none", .words = "torque-free",
 .noun = "analytic reference",
 .doc = "An analytic reference that `compare` and `verify` add as a fourth solution: "
        "`torque-free`, the free rigid body without loads (a single body, no torque)."},
{.path = "zero_linear_momentum", .type = Bool, .default_value = "true",
 .doc = "true: the base's initial velocity is computed so that the total linear momentum is zero "
        "(the system's centre of mass stays at rest). false: the free joint's `initial.velocity` "
        "gives it (default zero). It changes no rotational result."},
{.path = "environment", .type = Map, .default_value = "none", .noun = "the environment block",
 .doc = "Gravity (docs/environment.md): `gravity` (uniform), or `central_body` with `orbit` (the "
        "gravity gradient of a central body, the system's CM on a circular orbit). Without it N "
        "is inertial and nothing pulls."},
{.path = "bodies", .type = List, .required = true, .noun = "a list of bodies",
 .doc = "The bodies, at least one. Their order is the order of the output columns."},
{.path = "joints", .type = List, .required = true, .noun = "a list of joints",
 .doc = "The joints, one per body: exactly one `free` joint holds the base body; every other body "
        "is the child of one joint. Any order: the reader puts them in tree order."},
{.path = "run", .type = Map, .required = true, .noun = "the run block",
 .doc = "How long to run, how often to write a row, and the integrator."},
{.path = "compare", .type = Map, .noun = "the compare block",
 .doc = "Tolerances and exclusions for `crossdyn compare` and `verify`."},

// ----- bodies ---------------------------------------------------------------------------------
{.path = "bodies[]", .type = Map, .noun = "a body",
 .doc = "One body: rigid, or flexible when it has a `flexible` block."},
{.path = "bodies[].name", .type = Name, .required = true, .noun = "body name",
 .doc = "The body's name, unique among bodies and joints; output columns are `<name>.wx` etc."},
{.path = "bodies[].mass", .type = Quantity, .dimension = Dimension::Mass,
 .default_value = "flexible: the node sum",
 .doc = "Mass, > 0 and at most 1e9 kg. Required for a rigid body. A flexible body's mass is the sum "
        "of its nodes' masses; when also given here it must agree with that sum to 1e-6 relative "
        "(a check of the modal data), and the node sum is used."},
{.path = "bodies[].inertia", .type = Inertia, .dimension = Dimension::Inertia,
 .default_value = "flexible: the node sum",
 .doc = "Inertia about the centre of mass, in body axes: symmetric, positive definite, principal "
        "moments obeying I1 + I2 >= I3. Required for a rigid body. A flexible body's is the node "
        "sum sum_i (J_i + m_i (|p_i|^2 1 - p_i p_i^T)) (undeformed); when also given here every "
        "entry must agree with it to 1e-6 of its largest entry, and the node sum is used."},
{.path = "bodies[].center_of_mass", .type = Vector, .dimension = Dimension::Length,
 .default_value = "[0, 0, 0]", .noun = "a point", .written = false,
 .doc = "The centre of mass in the body's own reference frame R (axes = body axes). When given, "
        "every point of this body (`parent_point` of the joints it carries, `child_point` of its "
        "own joint) is measured from R's origin, and the reader moves them to the CM; `inertia` "
        "stays about the CM. The base's `initial.position` and `velocity` remain those of its CM. Not on a flexible body (its nodes' CM is its origin)."},
{.path = "bodies[].flexible", .type = Map, .noun = "a flexible block: {beam: ...} or {nodes: file}",
 .doc = "Makes the body flexible (docs/flexible-bodies.md): its mass is carried by nodes with mode "
        "shapes, from EITHER `beam` (a uniform Euler-Bernoulli beam the reader builds) OR `nodes` "
        "(a nodal data file, docs/flexible-data.md). Points on it (`parent_point`, `child_point`) "
        "are measured from its undeformed CM, the nodes' CM; a joint at a node names it with "
        "`parent_node`/`child_node`."},
{.path = "bodies[].flexible.beam", .type = Map, .noun = "a beam",
 .doc = "A uniform beam along one body axis, centred on the body origin: its mass at `slices` "
        "Gauss-Legendre points `gauss1 ...` (its modal integrals the continuum beam's), the "
        "massless end nodes `bottom` (at -length/2) and `top` (+length/2) and the massless "
        "stations `slice1 ...` at the slice centres, where joints may attach (the reader keeps "
        "those a joint names); modes `qx1, qx2, ...` displace it along x, `qy1, ...` along y "
        "(core/flex/beam.hpp)."},
{.path = "bodies[].flexible.beam.length", .type = Quantity, .dimension = Dimension::Length,
 .required = true,
 .doc = "The beam's length L, > 0."},
{.path = "bodies[].flexible.beam.axis", .type = Word, .default_value = "z", .words = "x|y|z",
 .noun = "beam axis",
 .doc = "The body axis the beam lies along."},
{.path = "bodies[].flexible.beam.mass_per_length", .type = Number, .required = true,
 .doc = "rho A in kg/m (a bare SI number), > 0: the beam's mass is mass_per_length * length."},
{.path = "bodies[].flexible.beam.section", .type = Vector, .dimension = Dimension::Length,
 .required = true, .noun = "the section's sides",
 .doc = "The box section's sides along x, y, z, 0 along the long axis: `[2, 2, 0]` for a beam "
        "along z (for the mass points' own inertia, so that the body's inertia is the box's)."},
{.path = "bodies[].flexible.beam.bending", .type = Map, .noun = "the bending planes",
 .doc = "Per displacement axis (the two axes across the beam): modes and stiffness. An axis not "
        "given has no modes."},
{.path = "bodies[].flexible.beam.bending.x", .type = Map, .noun = "a bending plane",
 .doc = "Bending with displacement along x."},
{.path = "bodies[].flexible.beam.bending.x.modes", .type = Number, .required = true,
 .doc = "The number of modes, 0 to 50 (integer)."},
{.path = "bodies[].flexible.beam.bending.x.EI", .type = Number, .default_value = "0",
 .doc = "Bending stiffness EI in N m^2 (a bare SI number), > 0 when modes > 0."},
{.path = "bodies[].flexible.beam.bending.y", .type = Map, .noun = "a bending plane",
 .doc = "Bending with displacement along y."},
{.path = "bodies[].flexible.beam.bending.y.modes", .type = Number, .required = true,
 .doc = "As for x."},
{.path = "bodies[].flexible.beam.bending.y.EI", .type = Number, .default_value = "0",
 .doc = "As for x."},
{.path = "bodies[].flexible.beam.bending.z", .type = Map, .noun = "a bending plane",
 .doc = "Bending with displacement along z."},
{.path = "bodies[].flexible.beam.bending.z.modes", .type = Number, .required = true,
 .doc = "As for x."},
{.path = "bodies[].flexible.beam.bending.z.EI", .type = Number, .default_value = "0",
 .doc = "As for x."},
{.path = "bodies[].flexible.beam.boundary", .type = Word, .default_value = "free-free",
 .words = "free-free|clamped-bottom|clamped-top", .noun = "boundary condition",
 .doc = "Free-free, or clamped (cantilevered) at the `bottom` or `top` end: the clamp is the "
        "body frame itself, so a cantilever is attached to its hub at that end."},
{.path = "bodies[].flexible.beam.slices", .type = Number, .default_value = "100",
 .doc = "The number of slices N (integer, 1 to 10000; at least 2 (k + 1) for mode k): N mass "
        "points and N stations `slice<i>` at -length/2 + (i - 1/2) length/N."},
{.path = "bodies[].flexible.beam.normalisation", .type = Word, .default_value = "auto",
 .words = "auto|top|bottom|mass", .noun = "normalisation",
 .doc = "Each shape scaled to unit displacement at the `top` end (`auto`: top, or bottom when "
        "clamped at the top), at the `bottom` end, or to unit modal mass (1 kg)."},
{.path = "bodies[].flexible.beam.geometric_stiffening", .type = Bool, .default_value = "false",
 .doc = "Geometric stiffening (clamped beams only): every node also moves towards the clamp by the "
        "foreshortening of the bent centre line, 1/2 integral_0^s |u'|^2 (docs/flexible-bodies.md "
        "\"Geometric stiffening\"), which gives a spinning beam its centrifugal stiffness (Kane, Ryan "
        "and Banerjee 1987). false: the linear modal model, which softens without bound when spun "
        "fast."},
{.path = "bodies[].flexible.beam.damping", .type = Map, .noun = "a modal damping",
 .doc = "Modal damping: EITHER `ratios` OR Rayleigh `alpha`, `beta`; none when not given."},
{.path = "bodies[].flexible.beam.damping.ratios", .type = List, .noun = "a list of damping ratios",
 .doc = "The damping ratio zeta (>= 0): one for every mode, or one per mode in mode order (qx1, "
        "qx2, ..., qy1, ...): D_k = 2 zeta_k omega_k M_k."},
{.path = "bodies[].flexible.beam.damping.ratios[]", .type = Number,
 .doc = "One damping ratio, >= 0."},
{.path = "bodies[].flexible.beam.damping.alpha", .type = Number, .default_value = "0",
 .doc = "Rayleigh D = alpha M + beta K: alpha in 1/s (a bare number), >= 0."},
{.path = "bodies[].flexible.beam.damping.beta", .type = Number, .default_value = "0",
 .doc = "Rayleigh beta in s (a bare number), >= 0."},
{.path = "bodies[].flexible.nodes", .type = Text, .noun = "a nodal data file",
 .doc = "A nodal data file (CSV, docs/flexible-data.md): one row per node with its mass, position, "
        "inertia and per mode its shape and slope. A relative path is relative to the scene "
        "file's folder."},
{.path = "bodies[].flexible.modes", .type = Text, .noun = "a modes file",
 .doc = "With `nodes`: the modes file (CSV, one row per mode: frequency and damping ratio, or rows "
        "of K and D); required when the nodes file has mode columns."},
{.path = "bodies[].torque", .type = Map, .noun = "a body torque",
 .doc = "An external torque on the body, piecewise constant in time."},
{.path = "bodies[].torque.frame", .type = Word, .default_value = "body", .words = "body|inertial",
 .noun = "torque frame",
 .doc = "The frame of the torque's components: the body frame, or the inertial frame N."},
{.path = "bodies[].torque.profile", .type = List, .required = true,
 .noun = "a profile: a list of {t: time, value: ...}",
 .doc = "The torque from each time on: `[{t: 0, value: [0, 0, 0.1]}, {t: 10 s, value: [0, 0, "
        "0]}]`; zero before the first time; times >= 0, strictly increasing."},
{.path = "bodies[].torque.profile[]", .type = Map, .noun = "a profile entry",
 .doc = "One step of the profile."},
{.path = "bodies[].torque.profile[].t", .type = Quantity, .dimension = Dimension::Time,
 .required = true,
 .doc = "When this value starts."},
{.path = "bodies[].torque.profile[].value", .type = Vector, .dimension = Dimension::Torque,
 .required = true,
 .doc = "The torque from t on, in `frame`."},

// ----- joints ---------------------------------------------------------------------------------
{.path = "joints[]", .type = Map, .noun = "a joint",
 .doc = "One joint: it connects its parent body (the inertial frame N for the free joint) to its "
        "child body."},
{.path = "joints[].name", .type = Name, .required = true, .noun = "joint name",
 .doc = "The joint's name, unique among joints and bodies; output columns are `<name>.angle` etc."},
{.path = "joints[].type", .type = Word, .required = true, .words = "free|revolute|spherical|fixed|prismatic|universal",
 .noun = "joint type",
 .doc = "The joint type (table \"Joint types\" below)."},
{.path = "joints[].parent", .type = Name, .joints = kJointed,
 .noun = "parent body name",
 .doc = "The parent body's name. Required, except on a prescribed revolute joint that holds the "
        "base: without a parent its parent is the inertial frame N (then `parent_point`, `axis` and "
        "`offset` are in N), and it replaces the free joint (docs/prescribed-motion.md)."},
{.path = "joints[].child", .type = Name, .required = true, .noun = "child body name",
 .doc = "The child body's name; a body is the child of exactly one joint."},
{.path = "joints[].parent_point", .type = Vector, .dimension = Dimension::Length,
 .joints = kJointed, .noun = "a point",
 .doc = "The joint point J from the parent's CM, in the parent frame: p_PoJ_P (from the parent's "
        "reference origin when the parent gives `center_of_mass`). Required unless `parent_node` "
        "is given (then not allowed)."},
{.path = "joints[].child_point", .type = Vector, .dimension = Dimension::Length,
 .joints = kJointed, .noun = "a point",
 .doc = "The same point J from the child's CM, in the child frame: p_CoJ_C. It usually points back "
        "towards the parent: a boom whose CM is 2 m out along its +x has `[-2, 0, 0]`. Required "
        "unless `child_node` is given (then not allowed)."},
{.path = "joints[].parent_node", .type = Name, .joints = kRevolute | kSpherical | kFixed, .noun = "node name",
 .doc = "A node of a flexible parent: the joint point is the node's undeformed position (so "
        "`parent_point` is not given), and the point and the joint frame move with the node's "
        "displacement and slope (docs/flexible-bodies.md \"Joints at nodes\")."},
{.path = "joints[].child_node", .type = Name, .joints = kRevolute | kSpherical | kFixed, .noun = "node name",
 .doc = "The same for a flexible child (instead of `child_point`)."},
{.path = "joints[].axis", .type = Direction, .required = true, .joints = kRevolute,
 .noun = "an axis",
 .doc = "The hinge axis in the PARENT frame (normalised by the reader); the angle is positive by "
        "the right-hand rule about it. R_PC = Rot(axis, angle) R_offset."},
{.path = "joints[].axis", .type = Direction, .required = true, .joints = kPrismatic,
 .noun = "an axis",
 .doc = "The sliding axis in the PARENT frame (normalised by the reader): the child's joint point "
        "is `position` along it from the parent's joint point; R_PC = R_offset."},
{.path = "joints[].axis", .type = Direction, .required = true, .joints = kUniversal,
 .noun = "an axis",
 .doc = "The first (outer) gimbal axis, fixed in the PARENT frame (normalised by the reader). "
        "R_PC = Rot(axis, angle1) Rot(axis2, angle2) R_offset."},
{.path = "joints[].axis2", .type = Direction, .required = true, .joints = kUniversal,
 .noun = "an axis",
 .doc = "The second (inner) gimbal axis, in the PARENT frame at zero angles; it turns with the "
        "first angle. Not parallel to `axis` (at least 1 deg apart; perpendicular is usual)."},
{.path = "joints[].offset", .type = Attitude, .default_value = "identity", .joints = kJointed,
 .doc = "The child frame's attitude in the parent frame at joint coordinate zero, R_PJ0 (v_P = "
        "R_PJ0 v_C): a quaternion, an axis-angle, or a rotation matrix whose columns are the "
        "child's axes in the parent frame."},
{.path = "joints[].prescribed", .type = Map, .joints = kAxial, .noun = "a prescribed motion",
 .doc = "The joint's angle (prismatic: position) is prescribed: its initial value + theta(t) "
        "(docs/prescribed-motion.md); the joint is then no degree of freedom, the output gains "
        "`<joint>.torque` (prismatic: `<joint>.force`), what the motion takes, and `spring`, "
        "`damper`, `motor` and `initial.rate` are not allowed."},
{.path = "joints[].prescribed.profile", .type = Word, .required = true, .joints = kAxial,
 .words = "spin-up|deploy", .noun = "a motion profile",
 .doc = "`spin-up`: Kane, Ryan and Banerjee's (1987) smooth spin-up from rest to `rate` over "
        "`ramp_time`, theta = (rate/T) (t^2/2 + (T/2 pi)^2 (cos(2 pi t/T) - 1)) up to T, then "
        "constant rate. `deploy`: from rest to rest through `travel` over `ramp_time`, theta = "
        "travel (t/T - sin(2 pi t/T)/(2 pi)) up to T, then travel (a telescoping boom's "
        "extension, a panel's deployment)."},
{.path = "joints[].prescribed.rate", .type = Quantity, .dimension = Dimension::AngularRate,
 .joints = kRevolute,
 .doc = "`spin-up` only, and required there: the final rate Omega_s, finite, |rate| at most 1e4 "
        "rad/s."},
{.path = "joints[].prescribed.rate", .type = Quantity, .dimension = Dimension::Velocity,
 .joints = kPrismatic,
 .doc = "`spin-up` only, and required there: the final extension rate, finite, at most 1e4 m/s "
        "in size."},
{.path = "joints[].prescribed.travel", .type = Quantity, .dimension = Dimension::Angle,
 .joints = kRevolute,
 .doc = "`deploy` only, and required there: the angle turned, finite, at most 1e4 rad in size."},
{.path = "joints[].prescribed.travel", .type = Quantity, .dimension = Dimension::Length,
 .joints = kPrismatic,
 .doc = "`deploy` only, and required there: the distance extended (negative: retracted), "
        "finite, at most 1e6 m in size."},
{.path = "joints[].prescribed.ramp_time", .type = Quantity, .dimension = Dimension::Time,
 .required = true, .joints = kAxial,
 .doc = "The spin-up or deployment time T, > 0."},
{.path = "joints[].spring", .type = Map, .joints = kMoving, .noun = "a {type} joint's spring",
 .doc = "A spring: revolute tau = -stiffness (angle - neutral_angle); spherical tau_C = "
        "-stiffness phi, phi the joint's rotation vector; prismatic F = -stiffness (position - "
        "neutral_position) along the axis; universal one torsional spring per axis."},
{.path = "joints[].spring.stiffness", .type = Quantity, .dimension = Dimension::Stiffness,
 .required = true, .joints = kRevolute | kSpherical,
 .doc = "Spring stiffness, >= 0."},
{.path = "joints[].spring.stiffness", .type = Quantity, .dimension = Dimension::LinearStiffness,
 .required = true, .joints = kPrismatic,
 .doc = "Spring stiffness along the axis, >= 0."},
{.path = "joints[].spring.stiffness", .type = Pair, .dimension = Dimension::Stiffness,
 .required = true, .joints = kUniversal, .noun = "a pair of stiffnesses",
 .doc = "[about axis, about axis2], each >= 0."},
{.path = "joints[].spring.neutral_angle", .type = Quantity, .dimension = Dimension::Angle,
 .default_value = "0", .joints = kRevolute,
 .doc = "The angle at which the spring is unstretched."},
{.path = "joints[].spring.neutral_angle", .type = Pair, .dimension = Dimension::Angle,
 .default_value = "[0, 0]", .joints = kUniversal, .noun = "a pair of angles",
 .doc = "[angle1, angle2] at which the springs are unstretched."},
{.path = "joints[].spring.neutral_position", .type = Quantity, .dimension = Dimension::Length,
 .default_value = "0", .joints = kPrismatic,
 .doc = "The position at which the spring is unstretched."},
{.path = "joints[].damper", .type = Map, .joints = kMoving, .noun = "a damper",
 .doc = "A viscous damper: tau = -damping rate (spherical: -damping w_PC_C; prismatic: a force "
        "-damping rate along the axis; universal: per axis)."},
{.path = "joints[].damper.damping", .type = Quantity, .dimension = Dimension::Damping,
 .required = true, .joints = kRevolute | kSpherical,
 .doc = "Damping coefficient, >= 0."},
{.path = "joints[].damper.damping", .type = Quantity, .dimension = Dimension::LinearDamping,
 .required = true, .joints = kPrismatic,
 .doc = "Damping coefficient along the axis, >= 0."},
{.path = "joints[].damper.damping", .type = Pair, .dimension = Dimension::Damping,
 .required = true, .joints = kUniversal, .noun = "a pair of damping coefficients",
 .doc = "[about axis, about axis2], each >= 0."},
{.path = "joints[].motor", .type = Map, .joints = kMoving, .noun = "a motor",
 .doc = "A motor torque (prismatic: force) on the child (reaction on the parent), piecewise "
        "constant in time."},
{.path = "joints[].motor.profile", .type = List, .required = true, .joints = kMoving,
 .noun = "a profile: a list of {t: time, value: ...}",
 .doc = "The torque from each time on; zero before the first time; times >= 0, strictly "
        "increasing."},
{.path = "joints[].motor.profile[]", .type = Map, .joints = kMoving, .noun = "a profile entry",
 .doc = "One step of the profile."},
{.path = "joints[].motor.profile[].t", .type = Quantity, .dimension = Dimension::Time,
 .required = true, .joints = kMoving,
 .doc = "When this value starts."},
{.path = "joints[].motor.profile[].value", .type = Quantity, .dimension = Dimension::Torque,
 .required = true, .joints = kRevolute,
 .doc = "The torque about the axis from t on."},
{.path = "joints[].motor.profile[].value", .type = Vector, .dimension = Dimension::Torque,
 .required = true, .joints = kSpherical,
 .doc = "The torque on the child from t on, child-frame components."},
{.path = "joints[].motor.profile[].value", .type = Quantity, .dimension = Dimension::Force,
 .required = true, .joints = kPrismatic,
 .doc = "The force along the axis from t on."},
{.path = "joints[].motor.profile[].value", .type = Pair, .dimension = Dimension::Torque,
 .required = true, .joints = kUniversal, .noun = "a pair of torques",
 .doc = "[about axis, about axis2] from t on."},
{.path = "joints[].initial", .type = Map, .default_value = "all zero", .joints = kFree | kMoving,
 .noun = "the initial conditions of a {type} joint",
 .doc = "The joint's coordinates and rates at t = 0 (a fixed joint has none)."},
{.path = "joints[].initial.position", .type = Vector, .dimension = Dimension::Length,
 .default_value = "[0, 0, 0]", .joints = kFree, .noun = "a position",
 .doc = "The base body's CM in N, p_NoBo_N (its CM even when it gives `center_of_mass`)."},
{.path = "joints[].initial.attitude", .type = Attitude, .default_value = "identity",
 .joints = kFree,
 .doc = "The base's attitude q_NB (v_N = R(q_NB) v_B)."},
{.path = "joints[].initial.attitude", .type = Attitude, .default_value = "identity",
 .joints = kSpherical,
 .doc = "The joint quaternion q_J: R_PC = R_offset R(q_J)."},
{.path = "joints[].initial.angular_velocity", .type = Vector, .dimension = Dimension::AngularRate,
 .default_value = "[0, 0, 0]", .joints = kFree, .noun = "an angular velocity",
 .doc = "The base's inertial angular velocity in its own frame, w_NB_B."},
{.path = "joints[].initial.angular_velocity", .type = Vector, .dimension = Dimension::AngularRate,
 .default_value = "[0, 0, 0]", .joints = kSpherical, .noun = "an angular velocity",
 .doc = "The child's angular velocity relative to the parent, in the child frame, w_PC_C."},
{.path = "joints[].initial.frame", .type = Word, .default_value = "inertial",
 .joints = kFree, .words = "inertial|lvlh", .noun = "a frame", .written = false,
 .doc = "`lvlh` (on an orbit): `attitude` is q_OB, the base's attitude relative to the orbit frame "
        "O at t = 0, and `angular_velocity` is w_OB_B, its rate relative to O (zero: turning "
        "with the orbit); the reader converts both to N (the writer writes them in N). "
        "`inertial`: q_NB and w_NB_B."},
{.path = "joints[].initial.velocity", .type = Vector, .dimension = Dimension::Velocity,
 .default_value = "[0, 0, 0]", .joints = kFree, .noun = "a velocity",
 .doc = "The base CM's velocity in N, v_NBo_N; only with `zero_linear_momentum: false` (else it is "
        "computed)."},
{.path = "joints[].initial.position", .type = Quantity, .dimension = Dimension::Length,
 .default_value = "0", .joints = kPrismatic,
 .doc = "The slider's position along the axis (0: the joint points coincide)."},
{.path = "joints[].initial.angle", .type = Quantity, .dimension = Dimension::Angle,
 .default_value = "0", .joints = kRevolute,
 .doc = "The hinge angle."},
{.path = "joints[].initial.angle", .type = Pair, .dimension = Dimension::Angle,
 .default_value = "[0, 0]", .joints = kUniversal, .noun = "a pair of angles",
 .doc = "[angle1, angle2], the gimbal angles."},
{.path = "joints[].initial.rate", .type = Quantity, .dimension = Dimension::AngularRate,
 .default_value = "0", .joints = kRevolute,
 .doc = "The hinge rate."},
{.path = "joints[].initial.rate", .type = Quantity, .dimension = Dimension::Velocity,
 .default_value = "0", .joints = kPrismatic,
 .doc = "The slider's rate along the axis."},
{.path = "joints[].initial.rate", .type = Pair, .dimension = Dimension::AngularRate,
 .default_value = "[0, 0]", .joints = kUniversal, .noun = "a pair of rates",
 .doc = "[rate1, rate2], the gimbal angles' rates."},

// ----- environment ----------------------------------------------------------------------------
{.path = "environment.gravity", .type = Vector, .dimension = Dimension::Acceleration,
 .noun = "an acceleration",
 .doc = "Uniform gravity g in N (m/s^2; `g0` is 9.80665 m/s^2): the force m g on every mass. Not "
        "with `central_body`."},
{.path = "environment.central_body", .type = Map, .noun = "the central body",
 .doc = "A point-mass central body (a planet); needs `orbit`. Not with `gravity`."},
{.path = "environment.central_body.mu", .type = Quantity,
 .dimension = Dimension::GravitationalParameter, .required = true,
 .doc = "mu = G M, > 0 (Earth: 3.986004418e14 m^3/s^2)."},
{.path = "environment.central_body.radius", .type = Quantity, .dimension = Dimension::Length,
 .default_value = "not given",
 .doc = "The body's radius, > 0 (Earth: 6378137 m); needed for `orbit.altitude`."},
{.path = "environment.orbit", .type = Map, .noun = "the orbit",
 .doc = "The circular orbit of the system's CM at t = 0 (the reference point O), in the central "
        "body's inertial axes (N's axes): `radius` or `altitude`, and the plane's angles."},
{.path = "environment.orbit.radius", .type = Quantity, .dimension = Dimension::Length,
 .default_value = "from altitude",
 .doc = "The orbit's radius R from the central body's centre, > its radius. Give this or "
        "`altitude`."},
{.path = "environment.orbit.altitude", .type = Quantity, .dimension = Dimension::Length,
 .default_value = "from radius", .written = false,
 .doc = "R minus `central_body.radius`, > 0. Give this or `radius`."},
{.path = "environment.orbit.inclination", .type = Quantity, .dimension = Dimension::Angle,
 .default_value = "0",
 .doc = "The orbit plane's inclination i to N's x-y plane, 0 to 180 deg."},
{.path = "environment.orbit.raan", .type = Quantity, .dimension = Dimension::Angle,
 .default_value = "0",
 .doc = "Right ascension of the ascending node: the angle from N's x axis to the node line."},
{.path = "environment.orbit.argument_of_latitude", .type = Quantity,
 .dimension = Dimension::Angle, .default_value = "0",
 .doc = "Where O is at t = 0: the angle from the ascending node along the orbit (0: O on the "
        "node line, at x_N when raan and i are 0)."},

// ----- run ------------------------------------------------------------------------------------
{.path = "run.duration", .type = Quantity, .dimension = Dimension::Time, .required = true,
 .doc = "The run's length, from t = 0, > 0."},
{.path = "run.output_step", .type = Quantity, .dimension = Dimension::Time, .required = true,
 .doc = "Time between output rows, > 0 and at most the duration; at most 1e7 rows."},
{.path = "run.integrator", .type = Word, .default_value = name_of(RunSpec{}.integrator.value()),
 .words = kNameWords<Integrator>, .noun = "integrator",
 .doc = "The integrator (docs/integrators.md): rk4 takes fixed steps `dt`; the others adapt "
        "their step to `rtol` and `atol`."},
{.path = "run.rtol", .type = Number, .default_value = "1e-10",
 .doc = "Relative tolerance of the adaptive integrators, > 0."},
{.path = "run.atol", .type = Number, .default_value = "1e-10",
 .doc = "Absolute tolerance of the adaptive integrators, > 0."},
{.path = "run.dt", .type = Quantity, .dimension = Dimension::Time, .default_value = "1 ms",
 .doc = "rk4's fixed step; when given, also the adaptive integrators' first trial step (else "
        "they estimate it from the derivatives at the start). > 0."},

// ----- compare --------------------------------------------------------------------------------
{.path = "compare.tolerances", .type = Map, .noun = "the tolerances",
 .doc = "Pass when max_t |a - b| <= atol + rtol max_t |b|, per compared quantity."},
{.path = "compare.tolerances.<quantity>", .type = Map, .default_value = "atol 1e-8, rtol 1e-8",
 .noun = "a tolerance",
 .doc = "`default`: the tolerance of every quantity not named; any other key names a quantity (a "
        "column such as `main.wx`, a joint's columns such as `gimbal.angle`, or a class: `angle`, "
        "`position`, `rate`, `torque`, `w`, `attitude`, `modal`, `load`, `H`, `E`, `H.drift`, "
        "`E.drift`, `H.balance`, `E.balance`) and takes what it does not give from `default`."},
{.path = "compare.tolerances.<quantity>.atol", .type = Number, .default_value = "from default",
 .doc = "Absolute tolerance, >= 0."},
{.path = "compare.tolerances.<quantity>.rtol", .type = Number, .default_value = "from default",
 .doc = "Relative tolerance, >= 0."},
{.path = "compare.exclude", .type = List, .noun = "a list of {quantity, reason}",
 .doc = "Quantities not compared, each with the reason."},
{.path = "compare.exclude[]", .type = Map, .noun = "an exclusion",
 .doc = "One exclusion."},
{.path = "compare.exclude[].quantity", .type = Name, .required = true, .noun = "quantity name",
 .doc = "The quantity (as in `tolerances`), excluded once."},
{.path = "compare.exclude[].reason", .type = Text, .required = true, .noun = "reason",
 .doc = "Why it is not compared (not empty)."},

// ----- value forms (wherever a value of that type is accepted; the writer writes SI lists) -----
{.path = "(list with unit)", .type = Map, .noun = "a list with a unit", .written = false,
 .doc = "A list of numbers with one unit for all: `{value: [0, 0, 10], unit: deg/s}`; accepted "
        "for every 3-vector and inertia."},
{.path = "(list with unit).value", .type = List, .required = true, .noun = "a list of numbers",
 .written = false,
 .doc = "The numbers, bare (no unit of their own)."},
{.path = "(list with unit).unit", .type = Text, .default_value = "SI", .written = false,
 .doc = "Their unit, of the key's dimension."},
{.path = "(axis-angle)", .type = Map, .noun = "an axis-angle rotation", .written = false,
 .doc = "An attitude as a rotation by `angle` about `axis`: `{axis: [0, 0, 1], angle: 90 deg}`."},
{.path = "(axis-angle).axis", .type = Direction, .required = true, .noun = "an axis",
 .written = false,
 .doc = "The rotation axis, in the frame the attitude is expressed in (normalised)."},
{.path = "(axis-angle).angle", .type = Quantity, .dimension = Dimension::Angle, .required = true,
 .written = false,
 .doc = "The rotation angle, right-hand rule. A bare number is radians (a warning above 2 pi)."},
});
// clang-format on

constexpr std::array kJointTypes = std::to_array<JointTypeInfo>({
    {"free", JointType::Free, kFree, 6,
     "The base body's six degrees of freedom relative to N; exactly one per scene."},
    {"revolute", JointType::Revolute, kRevolute, 1,
     "One angle about `axis` (parent frame): R_PC = Rot(axis_P, angle) R_offset."},
    {"spherical", JointType::Spherical, kSpherical, 3,
     "Three rotational degrees of freedom: R_PC = R_offset R(q_J)."},
    {"fixed", JointType::Fixed, kFixed, 0, "No relative motion: R_PC = R_offset."},
    {"prismatic", JointType::Prismatic, kPrismatic, 1,
     "One position along `axis` (parent frame): the child slides, R_PC = R_offset."},
    {"universal", JointType::Universal, kUniversal, 2,
     "A two-axis gimbal: R_PC = Rot(axis, angle1) Rot(axis2, angle2) R_offset, no body between."},
});

// "joints[].initial.angle" => parent "joints[].initial", name "angle". The parent of a list item
// row "bodies[]" is "bodies" with the name "[]".
std::pair<std::string_view, std::string_view> split(std::string_view path) {
  if (path.ends_with("[]")) return {path.substr(0, path.size() - 2), "[]"};
  const std::size_t dot = path.rfind('.');
  if (dot == std::string_view::npos) return {"", path};
  return {path.substr(0, dot), path.substr(dot + 1)};
}

// Does `pattern` (which may hold "<...>" components) match `path`?
bool matches(std::string_view pattern, std::string_view path) {
  while (true) {
    const std::size_t pd = pattern.find('.'), qd = path.find('.');
    const std::string_view a = pattern.substr(0, pd), b = path.substr(0, qd);
    if (!(a == b || (a.starts_with('<') && a.ends_with('>') && !b.empty()))) return false;
    if (pd == std::string_view::npos || qd == std::string_view::npos)
      return pd == std::string_view::npos && qd == std::string_view::npos;
    pattern.remove_prefix(pd + 1);
    path.remove_prefix(qd + 1);
  }
}

}  // namespace

std::span<const Key> keys() { return kKeys; }
std::span<const JointTypeInfo> joint_types() { return kJointTypes; }

const JointTypeInfo& joint_type(JointType t) {
  for (const JointTypeInfo& j : kJointTypes)
    if (j.type == t) return j;
  throw std::logic_error("scene schema: joint type without a row");
}

namespace {

// The rows by path, for find(): a pattern without a "<...>" component matches exactly its own
// path, so those rows are found by hashing; the few wildcard rows are matched one by one. (The
// reader asks a few hundred times per scene; a scan of the whole table each time was a sixth of
// a short `crossdyn run`.)
struct RowIndex {
  std::unordered_map<std::string_view, std::vector<std::size_t>> exact;  // rows in table order
  std::vector<std::size_t> wildcard;                                     // rows in table order
  RowIndex() {
    for (std::size_t i = 0; i < kKeys.size(); ++i) {
      if (kKeys[i].path.find('<') == std::string_view::npos)
        exact[kKeys[i].path].push_back(i);
      else
        wildcard.push_back(i);
    }
  }
};

}  // namespace

const Key* find(std::string_view path, unsigned joints) {
  static const RowIndex index;
  // The first row in table order that applies to `joints` and matches, as a scan would find.
  std::size_t best = kKeys.size();
  if (const auto it = index.exact.find(path); it != index.exact.end())
    for (const std::size_t i : it->second)
      if ((kKeys[i].joints & joints) != 0) {
        best = i;
        break;
      }
  for (const std::size_t i : index.wildcard) {
    if (i > best) break;
    if ((kKeys[i].joints & joints) != 0 && matches(kKeys[i].path, path)) {
      best = i;
      break;
    }
  }
  return best < kKeys.size() ? &kKeys[best] : nullptr;
}

std::vector<std::string> child_names(std::string_view parent, unsigned joints) {
  std::vector<std::string> names;
  for (const Key& k : kKeys) {
    const auto [p, name] = split(k.path);
    if (k.path.empty() || p != parent || name == "[]" || (k.joints & joints) == 0) continue;
    if (std::find(names.begin(), names.end(), name) == names.end()) names.emplace_back(name);
  }
  return names;
}

std::vector<std::string> joint_keys(JointType t) {
  return child_names("joints[]", joint_type(t).bit);
}

std::vector<std::string> initial_keys(JointType t) {
  return child_names("joints[].initial", joint_type(t).bit);
}

std::vector<std::string> words(const Key& key) {
  std::vector<std::string> w;
  std::string_view s = key.words;
  while (!s.empty()) {
    const std::size_t bar = s.find('|');
    w.emplace_back(s.substr(0, bar));
    if (bar == std::string_view::npos) break;
    s.remove_prefix(bar + 1);
  }
  return w;
}

std::string noun(const Key& key, std::string_view type_name) {
  std::string n(key.noun);
  if (const std::size_t at = n.find("{type}"); at != std::string::npos) n.replace(at, 6, type_name);
  return n;
}

}  // namespace crossdyn::scene
