// The prismatic joint (core/system.hpp): R_PC = R_PJ0, and the child's joint point slides along
// axis_P (unit, parent frame) by the position s, p_PoOk = p_PoJ_P + s axis_P.  Position s (1),
// speed s' (1); a prescribed joint has neither (s = angle0 + theta(t) of its profile, in m).
//
// Partial velocities (Kane and Levinson 1985 [KL85] Sec. 2.14, 2.16; README.md "Joint units"):
// the speed s' moves the child's subtree S(k) in translation, W_r = 0 and V_r = axis_N =
// R_NJp axis_P for every point of S(k) (Ok = the child's joint point, fixed in C).  The velocity
// of Ok is v_Po + w_P x p_PoOk + axis_N s' ([KL85] Sec. 2.8, a point moving on a rigid body), so
// its acceleration gains 2 w_Jp x axis_N s' + axis_N s'' (the axis is fixed in Jp).  The spring,
// damper and motor force F = -k (s - neutral) - c s' + motor acts along the axis on C and reacts
// on P: its generalised active force is F for s' and nothing for every other speed (the relative
// partial velocity of the pair is zero for those; [KL85] Sec. 4.x, action and reaction).
#include "formulations/kane/joints/joint_unit.hpp"

#include "core/errors.hpp"
#include "formulations/kane/kane_engine.hpp"

namespace crossdyn::kane {
namespace {

void labels(const Node& n, int n_q, const std::string& /*b*/, const std::string& j,
            std::vector<std::string>& out) {
  scalar_joint_labels(n, n_q, j, ".position", out);
}

void output(const Node& n, const NodeWork& w, double force, const double* x, const double* u,
            RowWriter& out) {
  scalar_joint_output(n, w, force, x, u, &RowWriter::prismatic, out);
}

void build(const Joint& J, Node& n, const std::string& jname) {
  if (n.parent < 0) throw InputError(jname + ": a prismatic joint cannot be the base joint");
  if (J.parent_node >= 0 || J.child_node >= 0)
    throw InputError(jname + ": a prismatic joint at a node of a flexible body is not supported");
  if (!(J.axis_P.norm() > 0)) throw InputError(jname + ": prismatic axis must be non-zero");
  n.axis_P = J.axis_P.normalized();
  n.axis_J = n.R_PJ0.transpose() * n.axis_P;
  n.slides = true;
  if (J.prescribed) {
    n.prescribed = true;
    n.motion = *J.prescribed;
    n.angle0 = J.angle0;
  }
}

// R_NJc = R_NJ0 (no rotation); V_r = R_NJp axis_P (W_r = 0: W_N's column stays zero); the joint
// point moved to p_PoJ_P + s axis_P.
void position(const Node& n, const double* x, const Eigen::Matrix3d& R_NJp,
              const Eigen::Matrix3d& R_NJ0, Eigen::Matrix3d& R_NJc, NodeWork& w,
              Eigen::Vector3d& r_Pj) {
  const double s = n.prescribed ? w.pres_angle : x[n.q0];
  R_NJc = R_NJ0;
  w.V_N.col(0).noalias() = R_NJp * n.axis_P;
  r_Pj += s * n.axis_P;
}

// w_PC = 0, v_PC = axis_N s' (a prescribed joint: theta'(t)).
void velocity(const Node& n, const double* u, NodeWork& w) {
  w.w_PC_N.setZero();
  w.v_PC_N = w.V_N.col(0) * (n.prescribed ? w.pres_rate : u[n.u0]);
}

void hinge(const Node& n, const Joint& J, double t, const double* x, const double* u, double* f) {
  const double motor = J.motor_revolute.empty() ? 0.0 : J.motor_revolute.value(t)(0);
  f[0] += scalar_hinge(J.stiffness, J.neutral_angle, J.damping, x[n.q0], u[n.u0], motor);
}

}  // namespace

const JointUnit& prismatic_joint_unit() {
  static const JointUnit unit{scalar_joint_sizes, -1,     labels,  scalar_joint_q_rates,
                              scalar_joint_pack,  scalar_joint_accel, scalar_joint_spring_energy,
                              output,             build,  position, velocity, hinge, nullptr,
                              JointShape::Slide1};
  return unit;
}

}  // namespace crossdyn::kane
