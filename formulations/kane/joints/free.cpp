// The free joint (the base): positions p_NoBo_N (3) and q_NB (4, w x y z); speeds w_NB_B (3) and
// v_NBo_N (3) (README.md "Notation").
#include "formulations/kane/joints/joint_unit.hpp"

#include "core/rotation.hpp"
#include "formulations/kane/kane_engine.hpp"

#include <Eigen/Geometry>

namespace crossdyn::kane {
namespace {

void sizes(bool /*prescribed*/, int& nqj, int& nuj) {
  nqj = 7;
  nuj = 6;
}

void labels(const Node& n, int n_q, const std::string& b, const std::string& /*j*/,
            std::vector<std::string>& out) {
  auto put = [&out](int i, const std::string& s) { out[static_cast<std::size_t>(i)] = s; };
  for (int i = 0; i < 3; ++i) put(n.q0 + i, b + "." + "xyz"[i]);
  for (int i = 0; i < 4; ++i) put(n.q0 + 3 + i, b + ".q" + "wxyz"[i]);
  for (int i = 0; i < 3; ++i) put(n_q + n.u0 + i, b + ".w" + "xyz"[i]);
  for (int i = 0; i < 3; ++i) put(n_q + n.u0 + 3 + i, b + ".v" + "xyz"[i]);
}

// p_NoBo_N' = v_NBo_N;  q_NB' = 1/2 q_NB (x) (0, w_NB_B)  (KLL Sec. 1.13).
void q_rates(const Node& n, const double* x, const double* u, double* xdot) {
  for (int i = 0; i < 3; ++i) xdot[n.q0 + i] = u[n.u0 + 3 + i];
  const Eigen::Quaterniond q(x[n.q0 + 3], x[n.q0 + 4], x[n.q0 + 5], x[n.q0 + 6]);
  const Eigen::Vector4d qd = rot::quat_rate_body(q, Eigen::Map<const Eigen::Vector3d>(u + n.u0));
  for (int i = 0; i < 4; ++i) xdot[n.q0 + 3 + i] = qd(i);
}

void pack(const Node& n, const TreeState& s, const TreeState::JointState& /*js*/, double* x,
          double* u) {
  const Eigen::Quaterniond q = s.q_NB.normalized();
  for (int i = 0; i < 3; ++i) x[n.q0 + i] = s.p_NoBo_N(i);
  x[n.q0 + 3] = q.w();
  x[n.q0 + 4] = q.x();
  x[n.q0 + 5] = q.y();
  x[n.q0 + 6] = q.z();
  for (int i = 0; i < 3; ++i) u[n.u0 + i] = s.w_NB_B(i);
  for (int i = 0; i < 3; ++i) u[n.u0 + 3 + i] = s.v_NBo_N(i);
}

// The base's accelerations are the body's (wdot_NB_B, a_NBo_N), set for every node.
void accel(const Node&, const NodeWork&, const Eigen::VectorXd&, TreeAccel&) {}

double spring_energy(const Node&, const Joint&, const double*) { return 0.0; }
void output(const Node&, const NodeWork&, double, const double*, const double*, RowWriter&) {}

}  // namespace

const JointUnit& free_joint_unit() {
  static const JointUnit unit{sizes,  3,       labels,  q_rates, pack,    accel,   spring_energy,
                              output, nullptr, nullptr, nullptr, nullptr, nullptr, JointShape::Base6};
  return unit;
}

}  // namespace crossdyn::kane
