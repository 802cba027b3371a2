// The universal joint (two-axis gimbal): q* = (a1, a2), pi' = (a1', a2'), ordinary generalised
// coordinates and speeds. R_PC = Rot(axis_P, a1) Rot(axis2_P, a2) R_PJ0 = R_PJ0 Rot(n1, a1)
// Rot(n2, a2) with n_k = R_PJ0^T axis_k_P (Rot(a, t) R = R Rot(R^T a, t)), so
// w_PC_C = Rot(n2, a2)^T n1 a1' + n2 a2' (system.hpp; README.md "Coordinates", "Kinematics"). The
// axes are never parallel: no chart, no singularity. joint_unit.hpp.
#include "formulations/lagrange/joints/joint_unit.hpp"

namespace crossdyn::lagrange {
namespace {

void coordinate_labels(const std::string& joint, const std::string&,
                       std::vector<std::string>& out) {
  out.push_back(joint + ".angle1");
  out.push_back(joint + ".angle2");
}

void rate_labels(const std::string& joint, const std::string&, std::vector<std::string>& out) {
  out.push_back(joint + ".rate1");
  out.push_back(joint + ".rate2");
}

void euler_set(const std::string&, const std::string&, Model::EulerSetM&) {}

// system.hpp "Loads": tau_k = -stiffness_k (a_k - neutral_k) - damping_k a_k' + motor_k(t), the
// generalised force of a_k (virtual power tau_1 a1' + tau_2 a2'); the springs' is exactly the
// gradient of V = sum_k stiffness_k (a_k - neutral_k)^2 / 2 (energy.hpp).
void loads(const Joint& joint, Model::JointM& J) {
  J.loaded = 2;
  J.stiffness = {joint.stiffness, joint.stiffness2, 0.0};
  J.neutral = {joint.neutral_angle, joint.neutral_angle2, 0.0};
  J.damping = {joint.damping, joint.damping2, 0.0};
  J.motor.times = joint.motor_universal.times;
  for (const Eigen::Vector2d& v : joint.motor_universal.values)
    J.motor.values.emplace_back(v(0), v(1), 0.0);
}

void pack(const Model::JointM&, const TreeState&, const TreeState::JointState& js, double* qj,
          double* uj, const SetAngles&) {
  qj[0] = js.angle;
  qj[1] = js.angle2;
  uj[0] = js.rate;
  uj[1] = js.rate2;
}

// R_J = Rot(n1, a1) Rot(n2, a2) (the offset q_PJ0 is applied by the caller, on the left).
Eigen::Quaterniond attitude(const Model::JointM& J, const double* qj, const EulerQ&) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(qj[0], J.axis_J)) *
         Eigen::Quaterniond(Eigen::AngleAxisd(qj[1], J.axis2_J));
}

void columns(RowWriter& out, int j, const double* qj, const double* uj) {
  out.universal(j, qj[0], qj[1], uj[0], uj[1]);
}

void accelerations(TreeAccel& a, std::size_t j, const Eigen::VectorXd& udot, int i0) {
  a.angle_ddot[j] = udot(i0);
  a.angle2_ddot[j] = udot(i0 + 1);
}

}  // namespace

// dof, euler_offset, translations, at_nodes, prescribable, absolute_attitude, axis_rotations,
// slides, no_nodes; then the functions.
extern const JointUnit kUniversalJoint{2, -1, 0, false, false, false, 2, 0,
    "a universal joint cannot attach at a node of a flexible body in the lagrange engine "
    "(attach it at node -1)",
    coordinate_labels, rate_labels, euler_set, loads, pack, attitude, columns, accelerations};

}  // namespace crossdyn::lagrange
