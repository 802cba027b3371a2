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
template <class S>
void rotation_rows(const JointModel& m, const JointKinematicsT<S>& jk, ConstraintRowsT<S>& out) {
  lock_rotation_rows<S>(m, jk, 3, out);
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
template <class S>
void lock_rotation_rows(const JointModel& m, const JointKinematicsT<S>& jk, int row0,
                        ConstraintRowsT<S>& out) {
  const Vec3<S>& w_F = jk.w_F;
  const Quat<S> q_e = m.q_PJ0.template cast<S>().conjugate() * jk.q_FG;
  const double s = real_part(q_e.w()) < 0 ? -1.0 : 1.0;
  const Vec3<S>& w = jk.w_FG_G;
  const Mat3<S> E = s * (q_e.w() * Mat3<S>::Identity() + tskew<S>(q_e.vec()));
  const S qw_dot = -0.5 * tdot<S>(q_e.vec(), w);
  const Vec3<S> qv_dot = 0.5 * (q_e.w() * w + tcross<S>(q_e.vec(), w));
  const Mat3<S> E_dot = s * (qw_dot * Mat3<S>::Identity() + tskew<S>(qv_dot));
  const Mat3<S> R_GF = jk.R_FG.transpose();
  out.g.template segment<3>(row0) = 2.0 * s * q_e.vec();
  out.J_C.template block<3, 3>(row0, 3) = E;
  out.J_P.template block<3, 3>(row0, 3).noalias() = -E * R_GF;
  out.gdot.template segment<3>(row0) = E * w;
  out.gamma.template segment<3>(row0) = -(E_dot * w + E * tcross<S>(w, Vec3<S>(R_GF * w_F)));
}
template void lock_rotation_rows(const JointModel&, const JointKinematicsT<double>&, int,
                                 ConstraintRowsT<double>&);
template void lock_rotation_rows(const JointModel&, const JointKinematicsT<Cx>&, int,
                                 ConstraintRowsT<Cx>&);

namespace {

// Every fixed joint is covered by the tangent.
bool covers(const Joint& /*J*/) { return true; }

const JointVerbsCx kCx{covers,  nullptr, nullptr, rotation_rows<Cx>, nullptr, nullptr,
                       nullptr, nullptr, nullptr, nullptr,           nullptr};

}  // namespace

const JointUnit kFixedJoint{"fixed", model,   nullptr, nullptr,   nullptr, rotation_rows<double>,
                            nullptr, nullptr, nullptr, nullptr,   nullptr, nullptr,
                            violation, nullptr, &kCx};

}  // namespace crossdyn::newton_euler
