// The free joint (the base): q* = (p_NoBo_N, Euler angles of R_NB), pi' = (v_NBo_N, w_NB_B)
// (README.md "Coordinates"). joint_unit.hpp.
#include "formulations/lagrange/joints/joint_unit.hpp"

namespace crossdyn::lagrange {
namespace {

void coordinate_labels(const std::string&, const std::string& body,
                       std::vector<std::string>& out) {
  for (const char* s : {".x", ".y", ".z", ".euler1", ".euler2", ".euler3"}) out.push_back(body + s);
}

void rate_labels(const std::string&, const std::string& body, std::vector<std::string>& out) {
  for (const char* s : {".vx", ".vy", ".vz", ".wx", ".wy", ".wz"}) out.push_back(body + s);
}

void euler_set(const std::string&, const std::string& body, Model::EulerSetM& es) {
  es.owner = body;
  es.what = "attitude of body '" + body + "'";
}

void pack(const Model::JointM& J, const TreeState& s, const TreeState::JointState&, double* qj,
          double* uj, const SetAngles& set_angles) {
  for (int i = 0; i < 3; ++i) {
    qj[i] = s.p_NoBo_N(i);
    uj[i] = s.v_NBo_N(i);
    uj[3 + i] = s.w_NB_B(i);
  }
  set_angles(J.euler_set, s.q_NB, qj + 3);
}

Eigen::Quaterniond attitude(const Model::JointM&, const double* qj, const EulerQ& euler_q) {
  return euler_q(qj + 3);
}

void columns(RowWriter&, int, const double*, const double*) {}

void accelerations(TreeAccel&, std::size_t, const Eigen::VectorXd&, int) {}

}  // namespace

// dof, euler_offset, translations, at_nodes, prescribable, absolute_attitude, axis_rotations,
// slides, no_nodes; then the functions.
extern const JointUnit kFreeJoint{6, 3, 3, false, false, true, 0, 0,
    "the free joint cannot attach at a node: a flexible base moves with its body frame",
    coordinate_labels, rate_labels, euler_set, no_loads, pack, attitude, columns, accelerations};

}  // namespace crossdyn::lagrange
