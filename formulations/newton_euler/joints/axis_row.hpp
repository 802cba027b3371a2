// One "axis" rotation row (joint_constraints.hpp, "revolute", rows 3-4): the child's copy u of an
// axis (u = R_FG u_G, u_G constant in G) keeps its angle to a unit vector b fixed in F:
//   g = b . u,  g' = c . w_FG_F with c = u x b,  A_G = c^T R_FG,  A_F = -c^T,
//   gamma = -( (u' x b) . w_FG_F + c . R_FG (w_FG_G x w_G) ),  u' = w_FG_F x u
// (Kane, Likins & Levinson 1983, Sec. 2.6; Haug 1989, Sec. 3.3). Used by the revolute joint (b =
// b1_P, b2_P normal to its axis) and the universal joint (b = the first axis, u the second).
// Inline: the revolute joint's rows are on the rigid scenes' hot path.
#pragma once

#include "formulations/newton_euler/joint_constraints.hpp"

namespace crossdyn::newton_euler {

// u, u_dot = w_FG_F x u and transport_F = R_FG (w_FG_G x w_G) are shared by a joint's rows.
template <class S>
void axis_row(const JointKinematicsT<S>& jk, const Vec3<S>& u, const Vec3<S>& u_dot,
              const Vec3<S>& transport_F, const Eigen::Vector3d& b, int row, ConstraintRowsT<S>& out) {
  const Vec3<S> c = tcross<S>(u, b);
  out.g(row) = tdot<S>(b, u);
  out.J_C.template block<1, 3>(row, 3).noalias() = c.transpose() * jk.R_FG;
  out.J_P.template block<1, 3>(row, 3) = -c.transpose();
  out.gdot(row) = tdot<S>(c, jk.w_FG_F);
  out.gamma(row) = -(tdot<S>(tcross<S>(u_dot, b), jk.w_FG_F) + tdot<S>(c, transport_F));
}

}  // namespace crossdyn::newton_euler
