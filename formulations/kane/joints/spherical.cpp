// The spherical joint: position q_J (4, w x y z; R_J = R(q_J)), speeds w_PC_C (3, the child-side
// joint frame's relative angular velocity in that frame) (README.md "Notation").
#include "formulations/kane/joints/joint_unit.hpp"

#include "core/rotation.hpp"
#include "formulations/kane/kane_engine.hpp"

#include <Eigen/Geometry>

namespace crossdyn::kane {
namespace {

void sizes(bool /*prescribed*/, int& nqj, int& nuj) {
  nqj = 4;
  nuj = 3;
}

void labels(const Node& n, int n_q, const std::string& /*b*/, const std::string& j,
            std::vector<std::string>& out) {
  auto put = [&out](int i, const std::string& s) { out[static_cast<std::size_t>(i)] = s; };
  for (int i = 0; i < 4; ++i) put(n.q0 + i, j + ".q" + "wxyz"[i]);
  for (int i = 0; i < 3; ++i) put(n_q + n.u0 + i, j + ".w" + "xyz"[i]);
}

// q_J' = 1/2 q_J (x) (0, w_PC_C): R_PC = R_PJ0 R(q_J) with R_PJ0 constant.
void q_rates(const Node& n, const double* x, const double* u, double* xdot) {
  const Eigen::Quaterniond q(x[n.q0], x[n.q0 + 1], x[n.q0 + 2], x[n.q0 + 3]);
  const Eigen::Vector4d qd = rot::quat_rate_body(q, Eigen::Map<const Eigen::Vector3d>(u + n.u0));
  for (int i = 0; i < 4; ++i) xdot[n.q0 + i] = qd(i);
}

void pack(const Node& n, const TreeState& /*s*/, const TreeState::JointState& js, double* x,
          double* u) {
  const Eigen::Quaterniond q = js.q_J.normalized();
  x[n.q0] = q.w();
  x[n.q0 + 1] = q.x();
  x[n.q0 + 2] = q.y();
  x[n.q0 + 3] = q.z();
  for (int i = 0; i < 3; ++i) u[n.u0 + i] = js.w_PC_C(i);
}

void accel(const Node& n, const NodeWork& /*w*/, const Eigen::VectorXd& udot, TreeAccel& a) {
  a.wdot_PC_C[static_cast<std::size_t>(n.joint)] = udot.segment<3>(n.u0);
}

// 1/2 k |theta|^2 with theta the rotation vector of q_J (normalised where read).
double spring_energy(const Node& n, const Joint& J, const double* x) {
  const Eigen::Quaterniond q =
      Eigen::Quaterniond(x[n.q0], x[n.q0 + 1], x[n.q0 + 2], x[n.q0 + 3]).normalized();
  return 0.5 * J.stiffness * rot::rotation_vector(q).squaredNorm();
}

void output(const Node& n, const NodeWork&, double, const double*, const double* u,
            RowWriter& out) {
  out.spherical(n.joint, Eigen::Vector3d(u[n.u0], u[n.u0 + 1], u[n.u0 + 2]));
}

}  // namespace

const JointUnit& spherical_joint_unit() {
  static const JointUnit unit{sizes,  0,       labels,  q_rates, pack,    accel,   spring_energy,
                              output, nullptr, nullptr, nullptr, nullptr, nullptr, JointShape::Rotation3};
  return unit;
}

}  // namespace crossdyn::kane
