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

void pack(const Model::JointM& J, const TreeState&, const TreeState::JointState& js, double* qj,
          double* uj, const SetAngles&) {
  qj[0] = J.prescribed ? J.angle0 + J.motion.angle(0.0) : js.angle;  // pack() is at t = 0
  uj[0] = J.prescribed ? J.motion.velocity(0.0) : js.rate;
}

Eigen::Quaterniond attitude(const Model::JointM& J, const double* qj, const EulerQ&) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(qj[0], J.axis_J));
}

void columns(RowWriter& out, int j, const double* qj, const double* uj) {
  out.revolute(j, qj[0], uj[0]);
}

void accelerations(TreeAccel& a, std::size_t j, const Eigen::VectorXd& udot, int i0) {
  a.angle_ddot[j] = udot(i0);
}

}  // namespace

// dof, euler_offset, translations, at_nodes, prescribable, absolute_attitude; then the functions.
extern const JointUnit kRevoluteJoint{1, -1, 0, true, true, false,
    coordinate_labels, rate_labels, euler_set, pack, attitude, columns, accelerations};

}  // namespace crossdyn::lagrange
