// The output layout: the one owner of the output columns (docs/conventions.md "Output columns").
//
// Every engine writes one row per output time through a RowWriter on this layout, so the names,
// the order, the units and the sign conventions of the pinned columns are written down here once:
//   t;
//   per body (System order)       <body>.wx .wy .wz   w_NB_B, rad/s
//                                 <body>.qw .qx .qy .qz  q_NB, scalar first, qw >= 0 (canonical)
//   per joint (System order)      revolute:  <joint>.angle (rad) <joint>.rate (rad/s)
//                                   prescribed revolute: then <joint>.torque (N m), the torque
//                                   about the axis the joint applies to its child
//                                 spherical: <joint>.wx .wy .wz  w_PC_C, rad/s
//                                 prismatic: <joint>.position (m) <joint>.rate (m/s)
//                                   prescribed prismatic: then <joint>.force (N), the force
//                                   along the axis the joint applies to its child
//                                 universal: <joint>.angle1 .angle2 (rad) .rate1 .rate2 (rad/s)
//   per flexible body             <body>.<mode> for every mode, then <body>.<mode>_rate
//   H                             |angular momentum about the system CM|, kg m^2/s
//   E                             kinetic + elastic + spring energy, J
// and after them (issue 26; docs/conventions.md "Positions, momentum, power and joint loads"):
//   per body                      <body>.x .y .z   p_NoBo_N, the body frame's origin in N, m (the
//                                   CM; for a flexible body its undeformed CM)
//   CMx CMy CMz                   p_NoScm_N, the system's CM in N (deformed bodies), m
//   Hx Hy Hz                      H_Scm_N, angular momentum about the system CM, N components
//   per joint but the free one    <joint>.Fx .Fy .Fz  F_C, the force the parent exerts on the
//                                   child through the joint (constraint reaction plus the joint's
//                                   spring, damper, motor or drive), child body frame, N
//                                 <joint>.Mx .My .Mz  M_J_C, the moment of the same loads about
//                                   the joint point J (the node's displaced point at a node),
//                                   child body frame, N m
//   P                             power of the non-conservative loads (motors, dampers, drives of
//                                   prescribed joints, external torques), W: dE/dt = P
//   Mx My Mz                      M_Scm_N, external moment about the system CM (external torques;
//                                   a prescribed base's reaction; gravity), N m: dH_N/dt = M_N
// and, in a scene on an orbit only (issue 28; core/orbit.hpp, docs/environment.md):
//   per body                      <body>.roll .pitch .yaw  B's attitude relative to the orbit frame
//                                   O (LVLH), R_OB = Rz(yaw) Ry(pitch) Rx(roll), rad
//                                 <body>.wox .woy .woz  w_OB_B = w_NB_B - R_BN w_NO_N, B's angular
//                                   velocity relative to the orbit frame, B components, rad/s
//                                   (both written by RowWriter::body from w_NB_B, q_NB and the
//                                   row's time)
//   J                             the Jacobi integral E - w_NO_N . H_O_N, J (conserved without
//                                   non-conservative loads; E then holds the gravity potential)
// then the engine's extra columns in the order it adds them (add_extra).
//
// Each column carries its kind and the body or joint it belongs to, so that the harness can group
// and compare columns without parsing their names.
#pragma once

#include "core/system.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace crossdyn {

enum class ColumnKind {
  Time,            // t
  BodyW,           // <body>.wx/wy/wz       component 0..2
  BodyQ,           // <body>.qw/qx/qy/qz    component 0..3
  // A joint coordinate and its rate, whatever the joint type: the unit says what it is ("rad" an
  // angle, "m" a length; "rad/s", "m/s"), component the coordinate's index in its joint
  // (revolute .angle/.rate 0; prismatic .position/.rate 0; universal .angle1/.rate1 0, .angle2/
  // .rate2 1). The harness groups and scales columns by kind and unit, never by joint type.
  JointCoordinate,
  JointRate,
  JointTorque,     // <joint>.torque       (prescribed revolute joints; .force, prismatic)
  SphericalW,      // <joint>.wx/wy/wz      component 0..2
  Modal,           // <body>.<mode>         component = mode index
  ModalRate,       // <body>.<mode>_rate    component = mode index
  MomentumH,       // H
  EnergyE,         // E
  BodyPosition,    // <body>.x/y/z          component 0..2 (unit m)
  SystemCM,        // CMx/CMy/CMz           component 0..2
  MomentumVector,  // Hx/Hy/Hz              component 0..2
  JointForce,      // <joint>.Fx/Fy/Fz      component 0..2
  JointMoment,     // <joint>.Mx/My/Mz      component 0..2
  Power,           // P
  ExternalMoment,  // Mx/My/Mz              component 0..2
  LvlhAngle,       // <body>.roll/pitch/yaw component 0..2 (orbit scenes)
  LvlhRate,        // <body>.wox/woy/woz    component 0..2 (orbit scenes)
  Jacobi,          // J                     (orbit scenes)
  Extra            // engine-specific
};

struct Column {
  std::string name;
  ColumnKind kind = ColumnKind::Extra;
  int body = -1;       // System::bodies index (BodyW, BodyQ, Modal, ModalRate)
  int joint = -1;      // System::joints index (JointCoordinate, JointRate, JointTorque, SphericalW)
  int component = -1;  // see ColumnKind
  std::string unit;    // SI unit of the values ("rad/s", "" for pure numbers)
};

class OutputLayout {
 public:
  OutputLayout() = default;  // no columns (engines assign the real one in their constructors)
  explicit OutputLayout(const System& system);

  // Appends an engine-specific column after the pinned ones; returns its index.
  int add_extra(std::string name, std::string unit);

  const std::vector<Column>& columns() const { return columns_; }
  const std::vector<std::string>& names() const { return names_; }
  std::size_t size() const { return columns_.size(); }
  std::size_t pinned_size() const { return pinned_; }

  // Index of the first column of each block (-1 when the block does not exist).
  int body_w(int body) const { return body_w_[static_cast<std::size_t>(body)]; }
  int body_q(int body) const { return body_w_[static_cast<std::size_t>(body)] + 3; }
  int joint_first(int joint) const { return joint_[static_cast<std::size_t>(joint)]; }
  int modal_first(int body) const { return modal_[static_cast<std::size_t>(body)]; }
  int H() const { return H_; }
  int E() const { return E_; }
  int body_position(int body) const { return body_p_[static_cast<std::size_t>(body)]; }
  int cm() const { return cm_; }
  int H_vector() const { return Hv_; }
  // -1 for a joint without load columns (the free joint: it carries no load).
  int joint_load(int joint) const { return load_[static_cast<std::size_t>(joint)]; }
  int P() const { return P_; }
  int external_moment() const { return M_; }
  // Orbit scenes only (-1 otherwise): body b's roll, pitch, yaw; the Jacobi integral.
  int lvlh(int body) const { return lvlh_.empty() ? -1 : lvlh_[static_cast<std::size_t>(body)]; }
  int J() const { return J_; }
  const Environment& environment() const { return environment_; }

 private:
  int push(Column c);
  std::vector<Column> columns_;
  std::vector<std::string> names_;
  std::size_t pinned_ = 0;
  std::vector<int> body_w_, joint_, modal_, body_p_, load_, lvlh_;
  int H_ = -1, E_ = -1, cm_ = -1, Hv_ = -1, P_ = -1, M_ = -1, J_ = -1;
  Environment environment_;
};

// Fills one row of an OutputLayout. Every pinned value must be written once per row; the writer
// starts the row as NaN, so a value an engine forgets shows up as a non-finite output (a run
// failure naming the column), never as a silent zero.
class RowWriter {
 public:
  RowWriter(const OutputLayout& layout, double* row);

  void time(double t) { row_[0] = t; }
  // Body b's angular velocity w_NB_B and attitude q_NB (written with qw >= 0: q and -q are the
  // same attitude, and one sign makes engines' columns directly comparable). On an orbit also its
  // roll, pitch and yaw relative to the orbit frame at the row's time: call time() first.
  void body(int b, const Eigen::Vector3d& w_NB_B, const Eigen::Quaterniond& q_NB);
  void revolute(int joint, double angle, double rate);
  // A prescribed revolute joint's torque about its axis on the child (N m); a prescribed
  // prismatic joint's force along its axis on the child (N).
  void joint_torque(int joint, double torque);
  void spherical(int joint, const Eigen::Vector3d& w_PC_C);
  void prismatic(int joint, double position, double rate);
  void universal(int joint, double angle1, double angle2, double rate1, double rate2);
  // A flexible body's modal coordinates and their rates (sizes: the body's mode count).
  void modal(int b, const Eigen::Ref<const Eigen::VectorXd>& eta,
             const Eigen::Ref<const Eigen::VectorXd>& eta_rate);
  // The angular momentum about the system CM, N components: writes Hx, Hy, Hz and H = |H_N|.
  void momentum(const Eigen::Vector3d& H_Scm_N);
  void energy(double E) { row_[layout_.E()] = E; }
  // Body b's frame origin p_NoBo_N (its CM; a flexible body's undeformed CM), m.
  void body_position(int b, const Eigen::Vector3d& p_NoBo_N);
  // The system's CM p_NoScm_N (every body's mass where it is, deformed), m.
  void system_cm(const Eigen::Vector3d& p_NoScm_N);
  // The loads the parent exerts on the child through joint j: force F_C (N) and moment about the
  // joint point M_J_C (N m), both in the child body frame. Not for the free joint.
  void joint_load(int joint, const Eigen::Vector3d& F_C, const Eigen::Vector3d& M_J_C);
  // Power of the non-conservative loads (W), and the external moment about the system CM in N
  // (N m): dE/dt = P, dH_Scm_N/dt = M_Scm_N.
  void power(double P) { row_[layout_.P()] = P; }
  void external_moment(const Eigen::Vector3d& M_Scm_N);
  // Orbit scenes: the Jacobi integral J = E - w_NO_N . H_O_N (H about the reference point O).
  void jacobi(double J) { row_[layout_.J()] = J; }
  void extra(int column, double value) { row_[column] = value; }

 private:
  const OutputLayout& layout_;
  double* row_;
};

// The pinned column names of a scene (OutputLayout(system).names()).
std::vector<std::string> pinned_columns(const System& system);

}  // namespace crossdyn
