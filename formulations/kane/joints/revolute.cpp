// The revolute joint: position its angle (1), speed its rate (1); a prescribed revolute joint
// has neither (its profile gives them at any t; README.md "Prescribed revolute joints").  Its
// kinematics and hinge torque are inlined in the passes (the hot path of every committed scene).
// Also the verbs every one-coordinate joint shares (scalar_joint_*; prismatic.cpp uses them).
#include "formulations/kane/joints/joint_unit.hpp"

#include "core/errors.hpp"
#include "formulations/kane/kane_engine.hpp"

#include <cmath>

namespace crossdyn::kane {

void scalar_joint_sizes(bool prescribed, int& nqj, int& nuj) {
  nqj = prescribed ? 0 : 1;
  nuj = prescribed ? 0 : 1;
}

void scalar_joint_q_rates(const Node& n, const double* /*x*/, const double* u, double* xdot) {
  if (!n.prescribed) xdot[n.q0] = u[n.u0];
}

void scalar_joint_pack(const Node& n, const TreeState& /*s*/, const TreeState::JointState& js,
                       double* x, double* u) {
  if (n.prescribed) return;
  x[n.q0] = js.angle;
  u[n.u0] = js.rate;
}

void scalar_joint_accel(const Node& n, const NodeWork& w, const Eigen::VectorXd& udot,
                        TreeAccel& a) {
  a.angle_ddot[static_cast<std::size_t>(n.joint)] = n.prescribed ? w.pres_accel : udot(n.u0);
}

double scalar_joint_spring_energy(const Node& n, const Joint& J, const double* x) {
  const double d = x[n.q0] - J.neutral_angle;
  return 0.5 * J.stiffness * d * d;
}

void scalar_joint_labels(const Node& n, int n_q, const std::string& j, const char* position,
                         std::vector<std::string>& out) {
  if (n.prescribed) return;
  out[static_cast<std::size_t>(n.q0)] = j + position;
  out[static_cast<std::size_t>(n_q + n.u0)] = j + ".rate";
}

// A prescribed joint writes its profile's position and rate, then its load (torque or force).
void scalar_joint_output(const Node& n, const NodeWork& w, double load, const double* x,
                         const double* u, void (RowWriter::*write)(int, double, double),
                         RowWriter& out) {
  if (n.prescribed) {
    (out.*write)(n.joint, w.pres_angle, w.pres_rate);
    out.joint_torque(n.joint, load);
  } else {
    (out.*write)(n.joint, x[n.q0], u[n.u0]);
  }
}

namespace {

void labels(const Node& n, int n_q, const std::string& /*b*/, const std::string& j,
            std::vector<std::string>& out) {
  scalar_joint_labels(n, n_q, j, ".angle", out);
}

void output(const Node& n, const NodeWork& w, double torque, const double* x, const double* u,
            RowWriter& out) {
  scalar_joint_output(n, w, torque, x, u, &RowWriter::revolute, out);
}

// The axis (unit, and along a coordinate axis of Jc when it is one: Node::axis_index) and the
// prescribed motion (docs/prescribed-motion.md: not a degree of freedom).
void build(const Joint& J, Node& n, const std::string& jname) {
  if (!(J.axis_P.norm() > 0)) throw InputError(jname + ": revolute axis must be non-zero");
  n.axis_P = J.axis_P.normalized();
  n.axis_J = n.R_PJ0.transpose() * n.axis_P;
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3, l = (i + 2) % 3;
    if (std::abs(n.axis_J(i)) == 1.0 && n.axis_J(j) == 0 && n.axis_J(l) == 0) {
      n.axis_index = i;
      n.axis_sign = n.axis_J(i);
    }
  }
  if (J.prescribed) {
    n.prescribed = true;
    n.motion = *J.prescribed;
    n.angle0 = J.angle0;
  }
}

}  // namespace

const JointUnit& revolute_joint_unit() {
  static const JointUnit unit{scalar_joint_sizes, -1,     labels,  scalar_joint_q_rates,
                              scalar_joint_pack,  scalar_joint_accel, scalar_joint_spring_energy,
                              output,             build,  nullptr, nullptr, nullptr, nullptr,
                              JointShape::Axis1};
  return unit;
}

}  // namespace crossdyn::kane
