// The fixed joint: no coordinates (README.md "Coordinates"). joint_unit.hpp.
#include "formulations/lagrange/joints/joint_unit.hpp"

namespace crossdyn::lagrange {
namespace {

void labels(const std::string&, const std::string&, std::vector<std::string>&) {}

void euler_set(const std::string&, const std::string&, Model::EulerSetM&) {}

void pack(const Model::JointM&, const TreeState&, const TreeState::JointState&, double*, double*,
          const SetAngles&) {}

Eigen::Quaterniond attitude(const Model::JointM&, const double*, const EulerQ&) {
  return Eigen::Quaterniond::Identity();
}

void columns(RowWriter&, int, const double*, const double*) {}

void accelerations(TreeAccel&, std::size_t, const Eigen::VectorXd&, int) {}

}  // namespace

// dof, euler_offset, translations, at_nodes, prescribable, absolute_attitude, axis_rotations,
// slides, no_nodes; then the functions.
extern const JointUnit kFixedJoint{0, -1, 0, true, false, false, 0, 0, "",
    labels, labels, euler_set, no_loads, pack, attitude, columns, accelerations};

}  // namespace crossdyn::lagrange
