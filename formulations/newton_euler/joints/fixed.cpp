// The fixed joint: no relative motion, the relative attitude held at q_PJ0 (joint_constraints.hpp,
// "fixed, rows 3-5", after Shuster 1993, "A survey of attitude representations", Eq. 305). Its unit
// (joint_unit.hpp) implements those rows and the joint's attitude violation; it has no
// coordinates, load or output columns of its own.
#include "formulations/newton_euler/joints/joint_unit.hpp"

#include "core/rotation.hpp"

#include <algorithm>

namespace crossdyn::newton_euler {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

namespace {

void model(const Joint& /*joint*/, JointModel& m) { m.rows = 6; }

// joint_constraints.hpp, "fixed".
void rotation_rows(const JointModel& m, const JointKinematics& jk, ConstraintRows& out) {
  lock_rotation_rows(m, jk, 3, out);
}

// The rotation angle away from the offset, and the relative angular velocity.
void violation(const JointModel& m, const JointKinematics& jk, const ConstraintRows& /*cr*/,
               double& /*pos_violation*/, double& /*vel_violation*/, double& ang_violation,
               double& angvel_violation) {
  ang_violation = std::max(ang_violation, rot::angle_between(m.q_PJ0, jk.q_FG));
  angvel_violation = std::max(angvel_violation, jk.w_FG_G.norm());
}

}  // namespace

// joint_constraints.hpp, "fixed", in rows row0..row0+2 (joint_unit.hpp: also the prismatic joint's).
void lock_rotation_rows(const JointModel& m, const JointKinematics& jk, int row0,
                        ConstraintRows& out) {
  const Vector3d& w_F = jk.w_F;
  const Quaterniond q_e = m.q_PJ0.conjugate() * jk.q_FG;
  const double s = q_e.w() < 0 ? -1.0 : 1.0;
  const Vector3d& w = jk.w_FG_G;
  const Matrix3d E = s * (q_e.w() * Matrix3d::Identity() + rot::skew(q_e.vec()));
  const double qw_dot = -0.5 * q_e.vec().dot(w);
  const Vector3d qv_dot = 0.5 * (q_e.w() * w + q_e.vec().cross(w));
  const Matrix3d E_dot = s * (qw_dot * Matrix3d::Identity() + rot::skew(qv_dot));
  const Matrix3d R_GF = jk.R_FG.transpose();
  out.g.segment<3>(row0) = 2.0 * s * q_e.vec();
  out.J_C.block<3, 3>(row0, 3) = E;
  out.J_P.block<3, 3>(row0, 3).noalias() = -E * R_GF;
  out.gdot.segment<3>(row0) = E * w;
  out.gamma.segment<3>(row0) = -(E_dot * w + E * w.cross(R_GF * w_F));
}

const JointUnit kFixedJoint{"fixed", model,   nullptr, nullptr, nullptr, rotation_rows, nullptr,
                            nullptr, nullptr, nullptr, nullptr, nullptr, violation, nullptr};

}  // namespace crossdyn::newton_euler
