// Drawing geometry of a scene: where every body, joint point and joint axis is in the inertial
// frame N, for the scene pictures (`crossdyn draw`, the report's scene pages). This is drawing
// code, not physics: no engine may use it (the engines each place their bodies their own way; the
// harness links them, they never link this).
//
// Notation as in core/system.hpp: p_NoBo_N is the position of body B's CM Bo from N's origin No, in
// N; R_NB takes B components to N components; P and C are a joint's parent and child.
//
// Placement (core/system.hpp "Joint kinematics"): the joint point J is one point of both bodies,
//   p_NoJ_N = p_NoPo_N + R_NP p_PoJ_P = p_NoCo_N + R_NC p_CoJ_C,
// so, going from the base outwards,
//   p_NoCo_N = p_NoPo_N + R_NP p_PoJ_P - R_NC p_CoJ_C.
// Attitudes come either from the scene's initial joint coordinates (R_NC = R_NP R_PC with
// R_PC = R_PJ0 R_J(coordinates)) or from a run's output columns <body>.qw .qx .qy .qz. The outputs
// carry no position, so a configuration made from a run is placed with the system centre of mass
// at N's origin (it stays there when the total linear momentum is zero).
// A joint at a node of a flexible body (core/system.hpp FlexBody) moves with the node: the
// parent_point / child_point above become p_PoJ_P + u_P and p_CoJ_C + u_C, with u = Phi_node eta
// from the run's modal columns <body>.<mode> (zero at t = 0: bodies start undeformed), and the
// joint frame turns with the node's slope psi = Psi_node eta.
#pragma once

#include "core/scene/scene.hpp"
#include "core/system.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>
#include <string>
#include <vector>

namespace crossdyn::harness::geometry {

// The uniform box with the body's mass and principal moments of inertia, along its principal axes
// and centred at its CM. For principal moments I1, I2, I3 about axes x', y', z' of the box,
// I1 = m (b^2 + c^2) / 12 and so on, hence a^2 = 6 (I2 + I3 - I1) / m (the triangle inequality the
// reader enforces keeps this >= 0; a flat plate has one side 0).
struct EquivalentBox {
  Eigen::Matrix3d R_BX = Eigen::Matrix3d::Identity();  // columns: the box axes x', y', z' in B
  Eigen::Vector3d size_m = Eigen::Vector3d::Zero();     // side lengths along x', y', z'
  Eigen::Vector3d principal_moments = Eigen::Vector3d::Zero();  // kg m^2, about x', y', z'
};
EquivalentBox equivalent_box(const Body& body);

struct BodyPose {
  Eigen::Vector3d p_NoBo_N = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R_NB = Eigen::Matrix3d::Identity();
};

// One joint in N, seen from each of its two bodies. For a tree placed by place_bodies the two
// points coincide; the gap is kept so that a configuration from another source (a body position
// given independently, a prescribed motion) shows a mismatch as two points joined by a red line.
struct JointPose {
  Eigen::Vector3d p_NoJ_N_parent = Eigen::Vector3d::Zero();  // p_NoPo_N + R_NP p_PoJ_P (base: Bo)
  Eigen::Vector3d p_NoJ_N_child = Eigen::Vector3d::Zero();   // p_NoCo_N + R_NC p_CoJ_C
  // Revolute: the axis in N as fixed in the parent (R_NP axis_P) and as fixed in the child
  // (R_NC axis_C, axis_C = R_PJ0^T axis_P, see revolute_axis_in_child); they agree when the two
  // bodies' attitudes are related by a rotation about the axis. Zero for other joint types.
  Eigen::Vector3d axis_N_parent = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_N_child = Eigen::Vector3d::Zero();
  // Prismatic: the sliding axis in N (R_NP axis_P). Universal: the first axis fixed in the parent
  // (R_NP axis_P) and the second as it has turned with the first angle (R_NC R_PJ0^T axis2_P, the
  // same line seen from the child: Rot(axis2, angle2) leaves it unchanged). Zero otherwise.
  Eigen::Vector3d slide_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d gimbal1_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d gimbal2_N = Eigen::Vector3d::Zero();
  // Rotation vector (rad) of the joint rotation R_J = R_PJ0^T R_NP^T R_NC recovered from the two
  // attitudes, in the joint frame (revolute: angle * axis_J; spherical: log of q_J).
  Eigen::Vector3d phi_J = Eigen::Vector3d::Zero();
};

struct Configuration {
  double t = 0;
  std::vector<BodyPose> bodies;   // System::bodies order
  std::vector<JointPose> joints;  // System::joints order
  // Per body, its flexible nodes in N (p_NoBo_N + R_NB (p_BoNi_B + u_i)); empty for a rigid body.
  std::vector<std::vector<Eigen::Vector3d>> nodes_N;
  // The rigid bodies' CMs and the flexible bodies' body-frame origins (their undeformed CMs),
  // weighted by mass: the system CM of the undeformed bodies.
  Eigen::Vector3d p_NoScm_N = Eigen::Vector3d::Zero();
};

// Modal coordinates per body (System::bodies order; size 0 for a rigid body, and an empty vector
// for "every body undeformed").
using ModalCoordinates = std::vector<Eigen::VectorXd>;

// R_PC of a joint at its coordinates (free joint: identity; the base attitude is not a joint
// rotation here).
Eigen::Matrix3d joint_rotation(const Joint& joint, double angle, const Eigen::Quaterniond& q_J,
                               double angle2 = 0);

// The revolute axis as fixed in the child frame: R_PC^T axis_P = R_PJ0^T axis_P at every angle.
Eigen::Vector3d revolute_axis_in_child(const Joint& joint);

// Places every body from its attitude (R_NB per body, System::bodies order) by walking the joints
// from the base, whose CM is put at p_NoBo_N_base; fills the joint poses, the flexible nodes and
// the system CM. `eta`: the flexible bodies' modal coordinates (empty: undeformed). `slide_m`: per
// joint (System::joints order) a prismatic joint's position, m (empty: every slider at 0).
Configuration place_bodies(const System& system, const std::vector<Eigen::Matrix3d>& R_NB,
                           const Eigen::Vector3d& p_NoBo_N_base, double t = 0,
                           const ModalCoordinates& eta = {},
                           const std::vector<double>& slide_m = {});

// The configuration at t = 0 from the scene's initial conditions (base at its given position).
Configuration initial_configuration(const System& system);

// The configuration of one output row (columns as the run wrote them): attitudes from the
// <body>.qw .qx .qy .qz columns, flexible bodies' modal coordinates from <body>.<mode>, system CM
// at N's origin. Throws InputError naming a missing column.
Configuration configuration_from_row(const System& system, const std::vector<std::string>& columns,
                                     const double* row);

// Moves a configuration so that its system centre of mass is at N's origin.
void center_at_origin(Configuration& c);

// Which run the later pictures were taken from, and what happened to it.
struct MotionSource {
  std::string engine;       // "kane" (or the first engine that ran), "" when none
  std::string state;        // "ok", "failed", "not run"
  std::string note;         // failure or why there is no run
  double duration = 0;      // s, the scene's run length (the last picture's intended time)
};

// Picks, from a run's rows arriving in time order, the rows nearest to `panels` evenly spaced
// times 0, T/(n-1), ..., T (T = duration), keeping only those rows (a long run is not held in
// memory). A run that ended early has no picture for the times past its last row (more than half
// an output step after it).
class FramePicker {
 public:
  FramePicker(std::vector<std::string> columns, double duration, int panels = 4);
  void add(const double* row);
  // The picked configurations, each with its system CM at N's origin, in time order.
  std::vector<Configuration> frames(const System& system) const;
  int panels() const { return static_cast<int>(want_.size()); }

 private:
  std::vector<std::string> columns_;
  std::size_t t_col_ = 0;
  std::vector<double> want_;                 // the times asked for
  std::vector<std::vector<double>> best_;    // per wanted time: the nearest row so far
  double last_t_ = -1, step_ = 0;
  long rows_ = 0;
};

// FramePicker over a run already in memory (row-major, columns.size() values per row).
std::vector<Configuration> motion_frames(const System& system, const std::vector<std::string>& columns,
                                         const std::vector<double>& data, double duration,
                                         int panels = 4);

// The geometry document the drawing script reads (reports/scene_view.py), format documented there
// and in reports/README.md: the bodies (equivalent boxes), joints (points, axes, offsets), the
// t = 0 configuration in N, the later configurations (CM at the origin) and the scene's warnings
// (harness/scene_warnings.hpp: the picture prints these, and makes none of its own).
std::string geometry_json(const System& system, const Configuration& initial,
                          const std::vector<Configuration>& motion, const MotionSource& source,
                          const std::vector<SceneWarning>& warnings);

}  // namespace crossdyn::harness::geometry
