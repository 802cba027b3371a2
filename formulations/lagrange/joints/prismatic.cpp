// The prismatic joint: q* = s, the joint point's slide along axis_P, pi' = s' (an ordinary
// generalised coordinate and speed, not a quasi-velocity); R_PC = R_PJ0 and
// p_PoCo_P = p_PoJ_P + s axis_P - R_PC p_CoJ_C (system.hpp; README.md "Coordinates",
// "Kinematics"). A prescribed one keeps s, s' in q* and pi', filled from the profile, as a
// prescribed revolute joint. joint_unit.hpp.
#include "formulations/lagrange/joints/joint_unit.hpp"

namespace crossdyn::lagrange {
namespace {

void coordinate_labels(const std::string& joint, const std::string&,
                       std::vector<std::string>& out) {
  out.push_back(joint + ".position");
}

void rate_labels(const std::string& joint, const std::string&, std::vector<std::string>& out) {
  out.push_back(joint + ".rate");
}

void euler_set(const std::string&, const std::string&, Model::EulerSetM&) {}

Eigen::Quaterniond attitude(const Model::JointM&, const double*, const EulerQ&) {
  return Eigen::Quaterniond::Identity();  // R_J = identity: the slide does not turn the child
}

void columns(RowWriter& out, int j, const double* qj, const double* uj) {
  out.prismatic(j, qj[0], uj[0]);
}

}  // namespace

// dof, euler_offset, translations, at_nodes, prescribable, absolute_attitude, axis_rotations,
// slides, no_nodes; then the functions.
extern const JointUnit kPrismaticJoint{1, -1, 0, false, true, false, 0, 1,
    "a prismatic joint cannot attach at a node of a flexible body in the lagrange engine (its "
    "point slides along an axis fixed in the parent's body frame; attach it at node -1)",
    coordinate_labels, rate_labels, euler_set, one_coordinate_loads, pack_one_coordinate, attitude,
    columns, one_coordinate_acceleration};

}  // namespace crossdyn::lagrange
