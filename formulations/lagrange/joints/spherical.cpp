// The spherical joint: q* = Euler angles of R_J, pi' = w_PC_C (relative, child frame) (README.md
// "Coordinates"). joint_unit.hpp.
#include "formulations/lagrange/joints/joint_unit.hpp"

namespace crossdyn::lagrange {
namespace {

void coordinate_labels(const std::string& joint, const std::string&,
                       std::vector<std::string>& out) {
  for (const char* s : {".euler1", ".euler2", ".euler3"}) out.push_back(joint + s);
}

void rate_labels(const std::string& joint, const std::string&, std::vector<std::string>& out) {
  for (const char* s : {".wx", ".wy", ".wz"}) out.push_back(joint + s);
}

void euler_set(const std::string& joint, const std::string& body, Model::EulerSetM& es) {
  es.owner = joint;
  es.what = "relative attitude of spherical joint '" + joint + "' (body '" + body + "')";
}

// system.hpp "Loads": the rotation-vector spring (energy.hpp) and tau_C = -damping w_PC_C +
// motor(t) on the three quasi-velocities w_PC_C (virtual power tau_C . w_PC_C).
void loads(const Joint& joint, Model::JointM& J) {
  J.loaded = 3;
  J.stiffness[0] = joint.stiffness;
  J.damping = {joint.damping, joint.damping, joint.damping};
  J.motor = joint.motor_spherical;
}

void pack(const Model::JointM& J, const TreeState&, const TreeState::JointState& js, double* qj,
          double* uj, const SetAngles& set_angles) {
  set_angles(J.euler_set, js.q_J, qj);
  for (int i = 0; i < 3; ++i) uj[i] = js.w_PC_C(i);
}

Eigen::Quaterniond attitude(const Model::JointM&, const double* qj, const EulerQ& euler_q) {
  return euler_q(qj);
}

void columns(RowWriter& out, int j, const double*, const double* uj) {
  out.spherical(j, Eigen::Vector3d(uj[0], uj[1], uj[2]));
}

void accelerations(TreeAccel& a, std::size_t j, const Eigen::VectorXd& udot, int i0) {
  a.wdot_PC_C[j] = udot.segment<3>(i0);
}

}  // namespace

// dof, euler_offset, translations, at_nodes, prescribable, absolute_attitude, axis_rotations,
// slides, no_nodes; then the functions.
extern const JointUnit kSphericalJoint{3, 0, 0, true, false, false, 0, 0, "",
    coordinate_labels, rate_labels, euler_set, loads, pack, attitude, columns, accelerations};

}  // namespace crossdyn::lagrange
