// The Lagrange engine's model: the System in the engine's terms, built once by the constructor
// (build_model.cpp) and immutable after; rhs() reads it and writes the Workspace (workspace.hpp).
// Coordinates and equations: README.md. Internal header (formulations/lagrange/*.cpp only).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

#include "formulations/lagrange/flex_body.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"

namespace crossdyn::lagrange {

struct JointUnit;  // joints/joint_unit.hpp

struct LagrangeEngine::Model {
  struct BodyM {
    std::string name;
    double mass = 0;
    Eigen::Matrix3d I_BBo_B;  // times EngineOptions::test_inertia_scale (rigid bodies)
    Body::Frame torque_frame = Body::Frame::Body;
    PiecewiseConstant<3> torque;
    int flex = -1;  // index into Model::flex; -1 for a rigid body
    int e0 = -1;    // flexible: index of eta in q* (and of eta' in pi')
    int nm = 0;     // flexible: number of modes
    // Flexible: the scene's modal damping D (FlexBody::D), for the power column P, which keeps the
    // scene's damper when EngineOptions::test_damper_scale scales FlexInvariants::Dmp (the
    // equations of motion's).
    Eigen::MatrixXd D_scene;
  };
  struct JointM {
    std::string name;
    JointType type = JointType::Revolute;
    const JointUnit* unit = nullptr;  // its joint type's unit (joints/joint_unit.hpp)
    int parent = -1, child = -1;
    int i0 = 0;          // first index of this joint's block in q* and in pi'
    int dof = 0;         // joint coordinates (free 6, revolute, prismatic 1, universal 2,
                         // spherical 3, fixed 0)
    int size = 0;        // block size: dof, then the child's modal coordinates
    int euler_set = -1;  // index of its Euler-angle set (free, spherical), else -1
    int translations = 0;  // its first coordinates that translate the child in N (free 3, else 0)
    // What its coordinates do, from its unit (joints/joint_unit.hpp; README.md "Kinematics"): the
    // pose and twist passes read these, not the type.
    bool absolute = false;       // the free base: R_NB from its Euler set, pi' = (v_NBo_N, w_NB_B)
    bool relative_euler = false;  // q* the Euler angles of R_J, pi' = w_PC_C (spherical)
    int axis_rotations = 0;  // first coordinates: rotations about axes,
                             // R_J = Rot(n_1, q_1) Rot(n_2, q_2) (revolute 1, universal 2)
    int slides = 0;          // next: slides of the joint point along slide_P (prismatic 1)
    int scalar_coordinates = 0;  // axis_rotations + slides: each with its own spring
    bool rigid_point = true;  // the joint point is fixed in both bodies (no node, no slide): the
                              // twist pass's short path
    Eigen::Vector3d p_PoJ_P, p_CoJ_C;
    Eigen::Matrix3d R_PJ0;
    Eigen::Quaterniond q_PJ0;
    Eigen::Vector3d axis_J;  // first rotation's axis in the joint frame: R_PJ0^T axis_P
    // The first rotation: R_PJ0 Rot(axis_J, q_1) = C0 + C1 sin(q_1) + C2 (1 - cos(q_1)), i.e.
    // R_PJ0 times Rodrigues' formula I + sin [n x] + (1 - cos) [n x]^2 (Kane, Likins & Levinson
    // 1983, Sec. 1.2).
    Eigen::Matrix3d C0, C1, C2;
    // The second rotation (axis_rotations 2): Rot(axis2_J, q_2) = I + sin(q_2) D1 + (1 - cos(q_2))
    // D2, D1 = [axis2_J x], D2 = D1^2, axis2_J = R_PJ0^T axis2_P; and the first axis in child
    // components, Rot(axis2_J, q_2)^T axis_J = axis_J - sin(q_2) b1 + (1 - cos(q_2)) b2 with
    // b1 = D1 axis_J, b2 = D2 axis_J.
    Eigen::Vector3d axis2_J = Eigen::Vector3d::Zero(), b1 = Eigen::Vector3d::Zero(),
                    b2 = Eigen::Vector3d::Zero();
    Eigen::Matrix3d D1 = Eigen::Matrix3d::Zero(), D2 = Eigen::Matrix3d::Zero();
    // The last rotation's axis in the child frame (axis_J, or axis2_J): its rate adds
    // axis_last_J rate to w_PC_C.
    Eigen::Vector3d axis_last_J = Eigen::Vector3d::Zero();
    Eigen::Vector3d slide_P = Eigen::Vector3d::Zero();  // slides: the unit axis in P
    // Attachment at a node of a flexible parent (child): the node's shapes and slopes, and the
    // index of the parent's (child's) eta in q*. -1: a rigid attachment.
    int parent_node = -1, child_node = -1;
    int parent_e0 = -1, child_e0 = -1;
    Eigen::Matrix3Xd Phi_P, Psi_P, Phi_C, Psi_C;
    // Geometric stiffening of the parent (child) node: e_i and G_i (flex_body.hpp), so the node
    // moves by Phi eta + e (1/2 eta^T G eta) with velocity Pt eta', Pt = Phi + e (G eta)^T.
    bool stiff_P = false, stiff_C = false;
    Eigen::Vector3d e_P = Eigen::Vector3d::Zero(), e_C = Eigen::Vector3d::Zero();
    Eigen::MatrixXd Gs_P, Gs_C;
    std::vector<int> subtree;  // this joint and every joint below it, in topological order
    // Hinge loads (system.hpp "Loads"; set by the unit's loads()): a spring per scalar coordinate
    // k (stiffness[k], neutral[k]), or with relative_euler the rotation-vector spring stiffness[0];
    // a damper damping[k] and a motor motor(t)[k] per quasi-velocity k < loaded.
    int loaded = 0;
    std::array<double, 3> stiffness{}, neutral{}, damping{};
    // The scene's dampers, for the power column P: `damping` is them times
    // EngineOptions::test_damper_scale (the equations of motion's; the same when it is 1).
    std::array<double, 3> damping_scene{};
    bool has_spring = false;  // a stiffness is not zero
    PiecewiseConstant<3> motor;
    // Prescribed revolute or prismatic joint (docs/prescribed-motion.md): the angle (position)
    // angle0 + theta(t) and its rate are not state; the coordinate stays in q* and pi' (internal
    // layout), filled from the profile at t (LagrangeEngine::expand).
    bool prescribed = false;
    PrescribedMotion motion;
    double angle0 = 0;
  };
  struct EulerSetM {
    int i0 = 0;         // index of the first angle in q* (and of w in pi')
    std::string owner;  // base body name or spherical joint name
    std::string what;   // "attitude of body 'main'" / "relative attitude of joint 'j' (...)"
  };

  std::vector<BodyM> bodies;
  std::vector<JointM> joints;
  std::vector<FlexInvariants> flex;       // per flexible body (BodyM::flex)
  std::vector<EulerSetM> euler_sets;
  std::vector<int> set_of_coordinate;     // per q* index: its Euler set or -1
  std::vector<int> gradient_dirs;         // quasi-coordinates the Lagrangian can depend on
  std::vector<int> coordinate_joint;      // per q* index: the joint whose block holds it
  std::vector<std::vector<int>> support;  // per body: the pi' indices its twist depends on
  std::vector<int> all_joints;            // 0, 1, ..., in topological order
  int n = 0;
  int max_modes = 0;
  // Prescribed joints: the state x holds the free coordinates only, nf of them (q*_f, pi'_f).
  int nf = 0;
  bool has_prescribed = false;
  bool base_free = true;               // joints[0] is the free joint (else a prescribed revolute)
  int base_set = -1;                   // the free base's Euler set (-1: prescribed base)
  std::vector<int> free_index;         // per state coordinate k < nf: its index in q*
  std::vector<int> state_of;           // per q* index: its state coordinate, -1 when prescribed
  std::vector<int> prescribed_joints;  // joint indices of the prescribed joints
  double total_mass = 0;
  // The environment (issue 28; core/system.hpp Environment, core/orbit.hpp; README.md "Gravity"):
  // its loads enter N as generalised active forces (gravity.cpp). `gravity` is false without one,
  // and rhs() then computes nothing for it.
  Environment environment;
  bool gravity = false;
  bool orbit = false;
  // EngineOptions::test_gravity_gradient_sign: multiplies the torques 3 n^2 zhat x (I_N zhat) (and
  // the flexible bodies' share of them) in the equations of motion only, not in E or J.
  double gg_sign = 1.0;
  // On an orbit: O, the system's CM at t = 0 from the scene's initial state (a point fixed in N),
  // set once by the constructor.
  Eigen::Vector3d p_NoO_N = Eigen::Vector3d::Zero();
  bool zero_linear_momentum = true;
  bool rechart = true;
  std::vector<std::string> labels;   // state labels, size 2n
  OutputLayout layout;               // pinned columns, then extras
  int recharts_column = -1;          // extra column lagrange.recharts
  // accelerations_tangent() covers this system (tangent.cpp): every system, since issue 27's last
  // step (flexible bodies in an environment). Decided once by the constructor.
  bool tangent = false;
};

using Model = LagrangeEngine::Model;

// What the engine cannot run, or what would make its mass matrix singular: InputError naming the
// scene file (where), the body or joint and the reason (validate_flex.cpp; build_model.cpp calls it).
void validate_flex(const System& system, const std::string& where);
using Workspace = LagrangeEngine::Workspace;

}  // namespace crossdyn::lagrange
