// The revolute joint: q* = angle, pi' = rate; a prescribed one keeps them in q* and pi', filled
// from the profile (README.md "Coordinates"). joint_unit.hpp.
#include "formulations/lagrange/joints/joint_unit.hpp"

namespace crossdyn::lagrange {
namespace {

void coordinate_labels(const std::string& joint, const std::string&,
                       std::vector<std::string>& out) {
  out.push_back(joint + ".angle");
}

void rate_labels(const std::string& joint, const std::string&, std::vector<std::string>& out) {
  out.push_back(joint + ".rate");
}

void euler_set(const std::string&, const std::string&, Model::EulerSetM&) {}

Eigen::Quaterniond attitude(const Model::JointM& J, const double* qj, const EulerQ&) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(qj[0], J.axis_J));
}

void columns(RowWriter& out, int j, const double* qj, const double* uj) {
  out.revolute(j, qj[0], uj[0]);
}

}  // namespace

void pack_one_coordinate(const Model::JointM& J, const TreeState&, const TreeState::JointState& js,
                         double* qj, double* uj, const SetAngles&) {
  qj[0] = J.prescribed ? J.angle0 + J.motion.angle(0.0) : js.angle;  // pack() is at t = 0
  uj[0] = J.prescribed ? J.motion.velocity(0.0) : js.rate;
}

// system.hpp "Loads": tau (revolute) or F (prismatic) = -stiffness (q - neutral) - damping q' +
// motor(t), the generalised force of the coordinate (its virtual power tau q' or F s').
void one_coordinate_loads(const Joint& joint, Model::JointM& J) {
  J.loaded = 1;
  J.stiffness[0] = joint.stiffness;
  J.neutral[0] = joint.neutral_angle;
  J.damping[0] = joint.damping;
  J.motor.times = joint.motor_revolute.times;
  for (const Eigen::Matrix<double, 1, 1>& v : joint.motor_revolute.values)
    J.motor.values.emplace_back(v(0), 0.0, 0.0);
}

void one_coordinate_acceleration(TreeAccel& a, std::size_t j, const Eigen::VectorXd& udot, int i0) {
  a.angle_ddot[j] = udot(i0);
}

void no_loads(const Joint&, Model::JointM&) {}

// dof, euler_offset, translations, at_nodes, prescribable, absolute_attitude, axis_rotations,
// slides, no_nodes; then the functions.
extern const JointUnit kRevoluteJoint{1, -1, 0, true, true, false, 1, 0, "",
    coordinate_labels, rate_labels, euler_set, one_coordinate_loads, pack_one_coordinate, attitude,
    columns, one_coordinate_acceleration};

}  // namespace crossdyn::lagrange
