// The revolute joint: position its angle (1), speed its rate (1); a prescribed revolute joint
// has neither (its profile gives them at any t; README.md "Prescribed revolute joints").
#include "formulations/kane/joints/joint_unit.hpp"

#include "formulations/kane/kane_engine.hpp"

namespace crossdyn::kane {
namespace {

void sizes(bool prescribed, int& nqj, int& nuj) {
  nqj = prescribed ? 0 : 1;
  nuj = prescribed ? 0 : 1;
}

void labels(const Node& n, int n_q, const std::string& /*b*/, const std::string& j,
            std::vector<std::string>& out) {
  if (n.prescribed) return;
  out[static_cast<std::size_t>(n.q0)] = j + ".angle";
  out[static_cast<std::size_t>(n_q + n.u0)] = j + ".rate";
}

void q_rates(const Node& n, const double* /*x*/, const double* u, double* xdot) {
  if (!n.prescribed) xdot[n.q0] = u[n.u0];
}

void pack(const Node& n, const TreeState& /*s*/, const TreeState::JointState& js, double* x,
          double* u) {
  if (n.prescribed) return;
  x[n.q0] = js.angle;
  u[n.u0] = js.rate;
}

void accel(const Node& n, const NodeWork& w, const Eigen::VectorXd& udot, TreeAccel& a) {
  a.angle_ddot[static_cast<std::size_t>(n.joint)] = n.prescribed ? w.pres_accel : udot(n.u0);
}

double spring_energy(const Node& n, double stiffness, double neutral_angle, const double* x) {
  const double d = x[n.q0] - neutral_angle;
  return 0.5 * stiffness * d * d;
}

void output(const Node& n, const NodeWork& w, double torque, const double* x, const double* u,
            RowWriter& out) {
  if (n.prescribed) {
    out.revolute(n.joint, w.pres_angle, w.pres_rate);
    out.joint_torque(n.joint, torque);
  } else {
    out.revolute(n.joint, x[n.q0], u[n.u0]);
  }
}

}  // namespace

const JointUnit& revolute_joint_unit() {
  static const JointUnit unit{sizes, -1, labels, q_rates, pack, accel, spring_energy, output};
  return unit;
}

}  // namespace crossdyn::kane
