#include "formulations/newton_euler/joint_constraints.hpp"

#include "core/rotation.hpp"
#include "formulations/newton_euler/joints/joint_unit.hpp"
#include "formulations/newton_euler/so3.hpp"

#include <cmath>
#include <numbers>

namespace crossdyn::newton_euler {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;
using rot::skew;

namespace {

JointSide side(const System* system, int body, const Vector3d& r, int node) {
  JointSide s;
  s.body = body;
  s.r = r;
  s.node = node;
  if (system && body >= 0) {
    const Body& b = system->bodies[static_cast<std::size_t>(body)];
    if (b.flex) {
      s.modes = b.flex->modes();
      s.Phi = Eigen::Matrix3Xd::Zero(3, s.modes);
      s.Psi = Eigen::Matrix3Xd::Zero(3, s.modes);
      if (node >= 0 && s.modes > 0) {
        const FlexNode& n = b.flex->nodes[static_cast<std::size_t>(node)];
        s.Phi = n.Phi_B;
        if (n.Psi_B.cols() == s.modes) s.Psi = n.Psi_B;  // an empty Psi: no slopes at this node
        if (b.flex->geometric_stiffening && n.G.rows() == s.modes && n.G.cols() == s.modes) {
          s.stiff = true;
          s.e = n.e_B;
          s.G = n.G;
        }
      }
    }
  }
  if (s.modes == 0) {
    s.Phi.resize(3, 0);
    s.Psi.resize(3, 0);
  }
  return s;
}

JointModel model(const Joint& joint, const System* system) {
  JointModel m;
  m.unit = &joint_unit(joint.type);
  m.parent = joint.parent;
  m.child = joint.child;
  m.P = side(system, joint.parent, joint.p_PoJ_P, joint.parent_node);
  m.C = side(system, joint.child, joint.p_CoJ_C, joint.child_node);
  m.q_PJ0 = joint.q_PJ0.normalized();
  m.R_PJ0 = m.q_PJ0.toRotationMatrix();
  m.a_P = joint.axis_P.normalized();
  m.a_C = m.R_PJ0.transpose() * m.a_P;  // system.hpp: axis_J = R_PJ0^T axis_P
  m.b1_P = m.a_P.unitOrthogonal();
  m.b2_P = m.a_P.cross(m.b1_P);
  m.e1_C = m.a_C.unitOrthogonal();
  m.e2_C = m.a_C.cross(m.e1_C);
  m.damping = joint.damping;
  m.damping2 = joint.damping2;
  m.unit->model(joint, m);  // rows, prescribed, has_angle, unwraps, translates, the type's constants
  return m;
}

}  // namespace

JointModel JointModel::from(const Joint& joint) { return model(joint, nullptr); }

JointModel JointModel::from(const System& system, int j) {
  return model(system.joints[static_cast<std::size_t>(j)], &system);
}

template <class S>
JointKinematicsT<S>::JointKinematicsT(const JointModel& m) {
  F.JlPsi = Eigen::Matrix<S, 3, Eigen::Dynamic>::Zero(3, m.P.modes);
  G.JlPsi = Eigen::Matrix<S, 3, Eigen::Dynamic>::Zero(3, m.C.modes);
  F.Phi = m.P.Phi.template cast<S>();
  G.Phi = m.C.Phi.template cast<S>();
  F.g = Eigen::Matrix<S, Eigen::Dynamic, 1>::Zero(m.P.modes);
  G.g = Eigen::Matrix<S, Eigen::Dynamic, 1>::Zero(m.C.modes);
  F.s_B = m.P.r.template cast<S>();
  G.s_B = m.C.r.template cast<S>();
}

template <class S>
ConstraintRowsT<S>::ConstraintRowsT(const JointModel& m)
    : Je_P(Eigen::Matrix<S, 6, Eigen::Dynamic>::Zero(6, m.P.modes)),
      Je_C(Eigen::Matrix<S, 6, Eigen::Dynamic>::Zero(6, m.C.modes)) {}

double unwrap_angle(double wrapped, double reference) {
  constexpr double two_pi = 2.0 * std::numbers::pi;
  return wrapped + two_pi * std::round((reference - wrapped) / two_pi);
}

template <class Sc>
void node_frame(const JointSide& side, const BodyKinematicsT<Sc>& B, NodeFrameT<Sc>& out) {
  out.s_B = side.r.template cast<Sc>();
  if (side.modes == 0) return;  // rigid: the constants set by JointKinematics(m)
  if constexpr (!kIsReal<Sc>) {
    // The same on the complex step (scalar.hpp): no |.| (so3::coefficients_sq of psi . psi, the
    // node's quaternion so3::quaternion), no conjugation (tdot, tskew).
    const Vec3<Sc> e = side.e.template cast<Sc>();
    out.s_B.noalias() += side.Phi * B.eta;
    if (side.stiff) {
      out.g.noalias() = side.G * B.eta;
      out.s_B += (0.5 * tdot<Sc>(B.eta, out.g)) * e;
      out.Phi = side.Phi.template cast<Sc>();
      out.Phi.noalias() += e * out.g.transpose();
      Sc q = 0.0;
      for (int k = 0; k < side.modes; ++k)
        for (int l = 0; l < side.modes; ++l) q += B.eta_dot(k) * side.G(k, l) * B.eta_dot(l);
      out.a_B = q * e;
    }
    out.sdot_B.noalias() = out.Phi * B.eta_dot;
    Vec3<Sc> psi, psi_dot;
    psi.noalias() = side.Psi * B.eta;
    psi_dot.noalias() = side.Psi * B.eta_dot;
    const so3::CoefficientsCx c = so3::coefficients_sq(tdot<Sc>(psi, psi));
    const Mat3<Sc> S = tskew<Sc>(psi), S2 = S * S, Sd = tskew<Sc>(psi_dot);
    const Sc pp = tdot<Sc>(psi, psi_dot);
    out.E = Mat3<Sc>::Identity() + c.s * S + c.a * S2;
    out.q_E = so3::quaternion(psi);
    const Mat3<Sc> Jl = Mat3<Sc>::Identity() + c.a * S + c.b * S2;
    const Mat3<Sc> Jl_dot = c.a1 * pp * S + c.a * Sd + c.b1 * pp * S2 + c.b * (Sd * S + S * Sd);
    out.JlPsi.noalias() = Jl * side.Psi;
    out.w_rel_B.noalias() = Jl * psi_dot;
    out.c_B.noalias() = Jl_dot * psi_dot;
  } else {
  out.s_B.noalias() += side.Phi * B.eta;
  if (side.stiff) {  // header "Geometric stiffening": s = r + Phi eta + e w, s' = Phi~ eta'
    out.g.noalias() = side.G * B.eta;
    out.s_B += (0.5 * B.eta.dot(out.g)) * side.e;
    out.Phi = side.Phi;
    out.Phi.noalias() += side.e * out.g.transpose();
    double q = 0;
    for (int k = 0; k < side.modes; ++k)
      for (int l = 0; l < side.modes; ++l) q += B.eta_dot(k) * side.G(k, l) * B.eta_dot(l);
    out.a_B = q * side.e;
  }
  out.sdot_B.noalias() = out.Phi * B.eta_dot;
  Vector3d psi, psi_dot;
  psi.noalias() = side.Psi * B.eta;
  psi_dot.noalias() = side.Psi * B.eta_dot;
  // so3.hpp: exp, Jl and d/dt Jl from one set of coefficients.
  const so3::Coefficients c = so3::coefficients(psi.norm());
  const Matrix3d S = skew(psi), S2 = S * S, Sd = skew(psi_dot);
  const double pp = psi.dot(psi_dot);
  out.E = Matrix3d::Identity() + c.s * S + c.a * S2;
  out.q_E = rot::from_rotation_vector(psi);
  const Matrix3d Jl = Matrix3d::Identity() + c.a * S + c.b * S2;
  const Matrix3d Jl_dot = c.a1 * pp * S + c.a * Sd + c.b1 * pp * S2 + c.b * (Sd * S + S * Sd);
  out.JlPsi.noalias() = Jl * side.Psi;
  out.w_rel_B.noalias() = Jl * psi_dot;
  out.c_B.noalias() = Jl_dot * psi_dot;
  }
}

template <class S>
void joint_kinematics(const JointModel& m, const BodyKinematicsT<S>& P, const BodyKinematicsT<S>& C,
                      JointKinematicsT<S>& out) {
  node_frame(m.P, P, out.F);
  node_frame(m.C, C, out.G);
  out.R_PC.noalias() = P.R_NB.transpose() * C.R_NB;
  const Quat<S> q_PC = P.q_NB.conjugate() * C.q_NB;
  if (m.P.modes == 0 && m.C.modes == 0) {  // F = P, G = C
    out.q_FG = q_PC;
    out.R_FG = out.R_PC;
    out.w_F = P.w_NB_B;
    out.w_G = C.w_NB_B;
  } else {
    // R_FG = E_P^T R_PC E_C; w_F = E_P^T (w_P + w_rel_P), w_G likewise.
    out.q_FG = out.F.q_E.conjugate() * q_PC * out.G.q_E;
    out.R_FG.noalias() = out.F.E.transpose() * out.R_PC * out.G.E;
    out.w_F.noalias() = out.F.E.transpose() * (P.w_NB_B + out.F.w_rel_B);
    out.w_G.noalias() = out.G.E.transpose() * (C.w_NB_B + out.G.w_rel_B);
  }
  out.w_FG_G = out.w_G - out.R_FG.transpose() * out.w_F;
  out.w_FG_F = out.R_FG * out.w_G - out.w_F;
  if (const auto relative = relative_verb<S>(*m.unit)) {  // the type's own coordinates (revolute: angle, rate)
    relative(m, P, C, out);
  } else {
    out.angle_wrapped = 0;
    out.rate = 0;
  }
}

template <class S>
void constraint_rows(const JointModel& m, const BodyKinematicsT<S>& P, const BodyKinematicsT<S>& C,
                     const JointKinematicsT<S>& jk, ConstraintRowsT<S>& out) {
  const auto point_rows = point_rows_verb<S>(*m.unit);
  const auto rotation_rows = rotation_rows_verb<S>(*m.unit);
  out.J_P.setZero();
  out.J_C.setZero();
  out.Je_P.setZero();
  out.Je_C.setZero();
  out.g.setZero();
  out.gdot.setZero();
  out.gamma.setZero();
  if (m.rows == 0) return;  // free: no rows
  if (point_rows) {  // prismatic: its own translation rows, no node frames (validate)
    point_rows(m, P, C, jk, out);
    if (rotation_rows) rotation_rows(m, jk, out);
    return;
  }

  // Rows 0-2: the joint point is the same point of both sides (system.hpp, "Joint kinematics").
  const Vec3<S>& w_P = P.w_NB_B;
  const Vec3<S>& w_C = C.w_NB_B;
  const Vec3<S>& s_P = jk.F.s_B;
  const Vec3<S>& s_C = jk.G.s_B;
  out.g.template head<3>() = C.p_NoBo_N + C.R_NB * s_C - P.p_NoBo_N - P.R_NB * s_P;
  out.J_C.template block<3, 3>(0, 0).setIdentity();
  out.J_C.template block<3, 3>(0, 3).noalias() = -C.R_NB * tskew<S>(s_C);
  out.J_P.template block<3, 3>(0, 0) = -Mat3<S>::Identity();
  out.J_P.template block<3, 3>(0, 3).noalias() = P.R_NB * tskew<S>(s_P);
  out.gdot.template head<3>() = C.v_NBo_N + C.R_NB * (tcross<S>(w_C, s_C) + jk.G.sdot_B) -
                                P.v_NBo_N - P.R_NB * (tcross<S>(w_P, s_P) + jk.F.sdot_B);
  out.gamma.template head<3>() =
      -(C.R_NB * (tcross<S>(w_C, tcross<S>(w_C, s_C)) + 2.0 * tcross<S>(w_C, jk.G.sdot_B)) -
        P.R_NB * (tcross<S>(w_P, tcross<S>(w_P, s_P)) + 2.0 * tcross<S>(w_P, jk.F.sdot_B)));
  if (m.C.modes > 0) out.Je_C.template topRows<3>().noalias() = C.R_NB * jk.G.Phi;
  if (m.P.modes > 0) out.Je_P.template topRows<3>().noalias() = -P.R_NB * jk.F.Phi;
  if (m.C.stiff) out.gamma.template head<3>() -= C.R_NB * jk.G.a_B;
  if (m.P.stiff) out.gamma.template head<3>() += P.R_NB * jk.F.a_B;

  // Rotation rows in terms of w_F and w_G (the frames' rigid rows, the type's rotation_rows verb),
  // written in the w_P and w_C columns, then mapped through the node frames below.
  if (!rotation_rows) return;  // spherical: rows 0-2 only
  rotation_rows(m, jk, out);

  // Node frames: w_F = E^T (w_B + Jl Psi eta'), d/dt w_F = E^T (alpha_B + Jl Psi eta'' + c -
  // w_rel x w_B) (header comment): rows A (w.r.t. w_F) become A E^T (w.r.t. w_B) and A E^T Jl Psi
  // (w.r.t. eta'), and gamma loses A E^T (c - w_rel x w_B).
  if (m.P.modes > 0) {
    const Mat3<S> A = out.J_P.template block<3, 3>(3, 3) * jk.F.E.transpose();
    out.J_P.template block<3, 3>(3, 3) = A;
    out.Je_P.template bottomRows<3>().noalias() = A * jk.F.JlPsi;
    out.gamma.template tail<3>() -= A * (jk.F.c_B - tcross<S>(jk.F.w_rel_B, w_P));
  }
  if (m.C.modes > 0) {
    const Mat3<S> A = out.J_C.template block<3, 3>(3, 3) * jk.G.E.transpose();
    out.J_C.template block<3, 3>(3, 3) = A;
    out.Je_C.template bottomRows<3>().noalias() = A * jk.G.JlPsi;
    out.gamma.template tail<3>() -= A * (jk.G.c_B - tcross<S>(jk.G.w_rel_B, w_C));
  }
}

template struct JointKinematicsT<double>;
template struct JointKinematicsT<Cx>;
template struct ConstraintRowsT<double>;
template struct ConstraintRowsT<Cx>;
template void node_frame(const JointSide&, const BodyKinematicsT<double>&, NodeFrameT<double>&);
template void node_frame(const JointSide&, const BodyKinematicsT<Cx>&, NodeFrameT<Cx>&);
template void joint_kinematics(const JointModel&, const BodyKinematicsT<double>&,
                               const BodyKinematicsT<double>&, JointKinematicsT<double>&);
template void joint_kinematics(const JointModel&, const BodyKinematicsT<Cx>&,
                               const BodyKinematicsT<Cx>&, JointKinematicsT<Cx>&);
template void constraint_rows(const JointModel&, const BodyKinematicsT<double>&,
                              const BodyKinematicsT<double>&, const JointKinematicsT<double>&,
                              ConstraintRowsT<double>&);
template void constraint_rows(const JointModel&, const BodyKinematicsT<Cx>&,
                              const BodyKinematicsT<Cx>&, const JointKinematicsT<Cx>&,
                              ConstraintRowsT<Cx>&);

}  // namespace crossdyn::newton_euler
