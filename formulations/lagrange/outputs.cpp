// The Lagrange engine's outputs: energies, momenta, output rows, the engine-neutral accelerations,
// the prescribed joints' torques and the terms of the equations (inspection). README.md,
// "Outputs".
#include <Eigen/Geometry>
#include <cstddef>
#include <vector>

#include "core/orbit.hpp"
#include "core/rotation.hpp"
#include "formulations/lagrange/energy.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "formulations/lagrange/flex_body.hpp"
#include "formulations/lagrange/joints/joint_unit.hpp"
#include "formulations/lagrange/kinematics.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/passes.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

LagrangeEngine::Terms LagrangeEngine::terms(double t, const double* x) {
  evaluate(t, expand(t, x));
  const Workspace& w = *ws_;
  Eigen::MatrixXd M = w.M;  // evaluate() fills the upper triangle only
  M.triangularView<Eigen::StrictlyLower>() = M.transpose();
  return Terms{M, w.p, w.Mdot_u, w.hamel, w.dL, w.N, w.qdot, w.udot};
}

double LagrangeEngine::kinetic_energy(const double* x, double t) {
  return kinetic_energy_full(expand(t, x));
}
double LagrangeEngine::potential_energy(const double* x, double t) {
  const double* xf = expand(t, x);
  double V = potential_energy_full(xf);
  if (model_->gravity) {
    kinetic_energy_full(xf);  // the double pose pass into k0
    V += gravity_potential(*model_, ws_->k0, t);
  }
  return V;
}
Eigen::Vector3d LagrangeEngine::orbit_reference_N() const {
  return model_->p_NoO_N;
}
Eigen::Vector3d LagrangeEngine::angular_momentum_N(const double* x, double t) {
  return angular_momentum_full(expand(t, x));
}
Eigen::Vector3d LagrangeEngine::linear_momentum_N(const double* x, double t) {
  return linear_momentum_full(expand(t, x));
}
std::vector<double> LagrangeEngine::prescribed_torques(double t, const double* x) {
  const Model& m = *model_;
  evaluate(t, expand(t, x));
  std::vector<double> tau(m.joints.size(), 0.0);
  for (std::size_t k = 0; k < m.prescribed_joints.size(); ++k)
    tau[static_cast<std::size_t>(m.prescribed_joints[k])] = ws_->torque(static_cast<Eigen::Index>(k));
  return tau;
}

double LagrangeEngine::kinetic_energy_full(const double* x) {
  Workspace& w = *ws_;
  for (int i = 0; i < model_->n; ++i) w.k0.q[static_cast<std::size_t>(i)] = x[i];
  pose_pass(*model_, w.chart.data(), w.k0, true);
  twist_pass(*model_, w.k0, x + model_->n, model_->all_joints);
  return kinetic_energy_of(*model_, w.k0, x + model_->n);
}

double LagrangeEngine::potential_energy_full(const double* x) {
  return potential_energy_of(*model_, ws_->chart.data(), x);
}

namespace {

// Per body, from the pose and twist passes in k: linear momentum P (N), angular momentum about Bo
// h (N) and first mass moment s = sum m_i x_i (N) (docs/flexible-bodies.md "Energy": the nodes'
// m_i x_i x v_i, plus R_NB J_i w). A flexible body's are R (h_v, h_w, m p_Bo + R s(eta)) with
// h_w = dT/dw and h_v = dT/dv of flex_body.hpp.
struct BodyMomenta {
  Eigen::Vector3d P, h, s;
};
BodyMomenta body_momenta(const Model& m, Kin<double>& k, const double* u, std::size_t b) {
  const Model::BodyM& B = m.bodies[b];
  if (B.flex < 0)
    return {k.R_NB[b] * (B.mass * k.v_NBo_B[b]), k.R_NB[b] * (B.I_BBo_B * k.w_NB_B[b]),
            B.mass * k.p_NoBo_N[b]};
  Eigen::Vector3d hw, hv;
  flex_momentum(m.flex[static_cast<std::size_t>(B.flex)], k.fi[b], k.w_NB_B[b], k.v_NBo_B[b],
                u + B.e0, hw, hv, static_cast<double*>(nullptr));
  return {k.R_NB[b] * hv, k.R_NB[b] * hw, B.mass * k.p_NoBo_N[b] + k.R_NB[b] * k.fi[b].s};
}

}  // namespace

Eigen::Vector3d LagrangeEngine::linear_momentum_full(const double* x) {
  kinetic_energy_full(x);  // pose and twist passes into k0
  Eigen::Vector3d P = Eigen::Vector3d::Zero();
  for (std::size_t b = 0; b < model_->bodies.size(); ++b)
    P += body_momenta(*model_, ws_->k0, x + model_->n, b).P;
  return P;
}

// The system's momenta from its bodies' (N components; body_momenta): H about the system CM c,
// sum_b (p_Bo x P_b + h_b) - x_c x P, x_c = sum_b s_b / m_total (the angular momentum about the
// origin, moved to the CM), the linear momentum P = sum_b P_b and x_c (P_N, p_NoScm_N).
template <class S>
Vec3<S> system_momenta(const Model& m, const std::vector<Vec3<S>>& p_NoBo_N,
                       const std::vector<Vec3<S>>& P_b, const std::vector<Vec3<S>>& h_b,
                       const std::vector<Vec3<S>>& s_b, Vec3<S>& P_N, Vec3<S>& p_NoScm_N) {
  Vec3<S> H = Vec3<S>::Zero(), P = Vec3<S>::Zero(), s = Vec3<S>::Zero();
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    H += p_NoBo_N[b].cross(P_b[b]) + h_b[b];
    P += P_b[b];
    s += s_b[b];
  }
  P_N = P;
  p_NoScm_N = s / m.total_mass;
  return H - (s / m.total_mass).cross(P);
}

// H about the system CM (system_momenta); leaves the bodies' and the system's momenta and CM in
// the workspace (w.P_b, w.h_b, w.s_b, w.P_sys, w.p_cm) and the pose and twist passes in k0.
Eigen::Vector3d LagrangeEngine::angular_momentum_full(const double* x) {
  kinetic_energy_full(x);
  const Model& m = *model_;
  Workspace& w = *ws_;
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const BodyMomenta bm = body_momenta(m, w.k0, x + m.n, b);
    w.P_b[b] = bm.P;
    w.h_b[b] = bm.h;
    w.s_b[b] = bm.s;
  }
  return system_momenta(m, w.k0.p_NoBo_N, w.P_b, w.h_b, w.s_b, w.P_sys, w.p_cm);
}

// P, the power of the non-conservative loads, from the scene's loads and the velocities
// (docs/conventions.md "Power and external moment"; the rate of work of a torque on a body is
// T . w, of a force on a point F . v: Greenwood 2003, Ch. 1, work and power): joint motors and
// dampers on their own quasi-velocities (revolute and prismatic rate, universal a1' and a2',
// spherical w_PC_C: (motor - damping rate) rate per component, the scene's damping), modal
// dampers -eta'^T D eta', prescribed drives (torque times rate) and external torques T . w_NB.
// u: pi' (full); torque: per Model::prescribed_joints.
template <class S>
S power_of(const Model& m, double t, const S* u, const std::vector<Vec3<S>>& T_N,
           const std::vector<Mat3<S>>& R_NB, const std::vector<Vec3<S>>& w_NB_B, const S* torque) {
  S P(0.0);
  for (const Model::JointM& J : m.joints) {
    if (J.loaded == 0) continue;
    const Eigen::Vector3d motor = J.motor.value(t);
    for (int a = 0; a < J.loaded; ++a) {
      const S rate = u[J.i0 + a];
      P += (motor(a) - J.damping_scene[static_cast<std::size_t>(a)] * rate) * rate;
    }
  }
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const Model::BodyM& B = m.bodies[b];
    P += T_N[b].dot(R_NB[b] * w_NB_B[b]);
    if (B.flex < 0) continue;
    const S* ed = u + B.e0;
    for (int r = 0; r < B.nm; ++r)
      for (int c = 0; c < B.nm; ++c) P -= ed[r] * B.D_scene(r, c) * ed[c];
  }
  for (std::size_t i = 0; i < m.prescribed_joints.size(); ++i) {
    const Model::JointM& J = m.joints[static_cast<std::size_t>(m.prescribed_joints[i])];
    P += torque[i] * u[J.i0];
  }
  return P;
}

// External moment about the system CM in N: the external torques, gravity's and, for a
// prescribed base, its joint's load on the base moved to the CM, M_J + (r_J - r_cm) x F (the
// moment of a force about another point; Greenwood 2003, Ch. 1); gravity's per body its resultant
// at Bo and moment about Bo (gravity.cpp), sum (p_Bo - p_cm) x F_g + M_g.
template <class S>
Vec3<S> external_moment_of(const Model& m, const std::vector<Vec3<S>>& T_N,
                           const std::vector<Vec3<S>>& F_N, const std::vector<Vec3<S>>& M_J_N,
                           const std::vector<Vec3<S>>& r_J_N, const Vec3<S>& p_NoScm_N,
                           const std::vector<Vec3<S>>& p_NoBo_N, const std::vector<Vec3<S>>& F_g_N,
                           const std::vector<Vec3<S>>& M_g_N) {
  Vec3<S> M_Scm_N = Vec3<S>::Zero();
  for (std::size_t b = 0; b < m.bodies.size(); ++b) M_Scm_N += T_N[b];
  if (!m.base_free) M_Scm_N += M_J_N[0] + (r_J_N[0] - p_NoScm_N).cross(F_N[0]);
  if (m.gravity)
    for (std::size_t b = 0; b < m.bodies.size(); ++b)
      M_Scm_N += (p_NoBo_N[b] - p_NoScm_N).cross(F_g_N[b]) + M_g_N[b];
  return M_Scm_N;
}

// output_row() (double) and output_row_tangent() (Dual<1>, output_tangent.cpp) run this code.
template Vec3<double> system_momenta<double>(const Model&, const std::vector<Vec3<double>>&,
                                             const std::vector<Vec3<double>>&,
                                             const std::vector<Vec3<double>>&,
                                             const std::vector<Vec3<double>>&, Vec3<double>&,
                                             Vec3<double>&);
template Vec3<Dual<1>> system_momenta<Dual<1>>(const Model&, const std::vector<Vec3<Dual<1>>>&,
                                               const std::vector<Vec3<Dual<1>>>&,
                                               const std::vector<Vec3<Dual<1>>>&,
                                               const std::vector<Vec3<Dual<1>>>&, Vec3<Dual<1>>&,
                                               Vec3<Dual<1>>&);
template double power_of<double>(const Model&, double, const double*,
                                 const std::vector<Vec3<double>>&,
                                 const std::vector<Mat3<double>>&,
                                 const std::vector<Vec3<double>>&, const double*);
template Dual<1> power_of<Dual<1>>(const Model&, double, const Dual<1>*,
                                   const std::vector<Vec3<Dual<1>>>&,
                                   const std::vector<Mat3<Dual<1>>>&,
                                   const std::vector<Vec3<Dual<1>>>&, const Dual<1>*);
template Vec3<double> external_moment_of<double>(
    const Model&, const std::vector<Vec3<double>>&, const std::vector<Vec3<double>>&,
    const std::vector<Vec3<double>>&, const std::vector<Vec3<double>>&, const Vec3<double>&,
    const std::vector<Vec3<double>>&, const std::vector<Vec3<double>>&,
    const std::vector<Vec3<double>>&);
template Vec3<Dual<1>> external_moment_of<Dual<1>>(
    const Model&, const std::vector<Vec3<Dual<1>>>&, const std::vector<Vec3<Dual<1>>>&,
    const std::vector<Vec3<Dual<1>>>&, const std::vector<Vec3<Dual<1>>>&, const Vec3<Dual<1>>&,
    const std::vector<Vec3<Dual<1>>>&, const std::vector<Vec3<Dual<1>>>&,
    const std::vector<Vec3<Dual<1>>>&);

void LagrangeEngine::output_row(double t, const double* xs, double* row) {
  const Model& m = *model_;
  Workspace& w = *ws_;
  const int n = m.n;
  const double* x = expand(t, xs);
  // The accelerations pi'' at (t, x) (the joint loads) and the prescribed joints' torques.
  evaluate(t, x);
  const double* u = x + n;
  double E = kinetic_energy_full(x) + potential_energy_full(x);
  // The environment's potential (gravity.cpp) on the pose pass just made into k0.
  if (m.gravity) E += gravity_potential(m, w.k0, t);
  const Eigen::Vector3d H_Scm_N = angular_momentum_full(x);  // leaves the pose and twist passes
                                                             // in k0
  // Attitude quaternions: q_NC = q_NP q(psi_P) q_PJ0 q_J q(psi_C)^*, q_J from the joint's own
  // coordinates, q(psi) the node frame's rotation vector psi = Psi eta (exp map).
  auto node_q = [&](const Eigen::Matrix3Xd& Psi, int e0) {
    Eigen::Vector3d psi = Eigen::Vector3d::Zero();
    for (Eigen::Index k = 0; k < Psi.cols(); ++k) psi += Psi.col(k) * x[e0 + k];
    return rot::from_rotation_vector(psi);
  };
  for (const Model::JointM& J : m.joints) {
    const double* qj = x + J.i0;
    const auto c = static_cast<std::size_t>(J.child);
    auto euler_q = [&](const double* a) {
      const Eigen::Vector4d e = euler_quaternion(
          kSequences[static_cast<std::size_t>(w.chart[static_cast<std::size_t>(J.euler_set)])],
          a[0], a[1], a[2]);
      return Eigen::Quaterniond(e(0), e(1), e(2), e(3));
    };
    const Eigen::Quaterniond q_J = J.unit->attitude(J, qj, euler_q);
    if (J.unit->absolute_attitude) {
      w.q_NB[c] = q_J;
      continue;
    }
    Eigen::Quaterniond q = J.parent >= 0 ? w.q_NB[static_cast<std::size_t>(J.parent)]
                                         : Eigen::Quaterniond::Identity();  // a prescribed base
    if (J.parent_node >= 0) q = q * node_q(J.Psi_P, J.parent_e0);
    q = q * J.q_PJ0 * q_J;
    if (J.child_node >= 0) q = q * node_q(J.Psi_C, J.child_e0).conjugate();
    w.q_NB[c] = q.normalized();
  }
  RowWriter out(m.layout, row);
  out.time(t);
  for (std::size_t b = 0; b < m.bodies.size(); ++b)
    out.body(static_cast<int>(b), w.k0.w_NB_B[b], w.q_NB[b]);
  for (std::size_t j = 0; j < m.joints.size(); ++j) {
    const Model::JointM& J = m.joints[j];
    J.unit->columns(out, static_cast<int>(j), x + J.i0, u + J.i0);
  }
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const Model::BodyM& B = m.bodies[b];
    if (B.flex < 0) continue;
    out.modal(static_cast<int>(b), Eigen::Map<const Eigen::VectorXd>(x + B.e0, B.nm),
              Eigen::Map<const Eigen::VectorXd>(u + B.e0, B.nm));
  }
  for (std::size_t k = 0; k < m.prescribed_joints.size(); ++k)
    out.joint_torque(m.prescribed_joints[k], w.torque(static_cast<Eigen::Index>(k)));
  out.momentum(H_Scm_N);
  out.energy(E);

  // Issue 26 (docs/conventions.md "Positions, momentum, power and joint loads").
  // Body frame origins p_NoBo_N (a flexible body's undeformed CM) and the system CM
  // p_NoScm_N = sum_b s_b / m_total, s_b the first mass moment (deformed nodes; body_momenta).
  const Kin<double>& k = w.k0;
  for (std::size_t b = 0; b < m.bodies.size(); ++b)
    out.body_position(static_cast<int>(b), k.p_NoBo_N[b]);
  const Eigen::Vector3d p_NoScm_N = w.p_cm;  // system_momenta (angular_momentum_full above)
  out.system_cm(p_NoScm_N);

  // On an orbit, the Jacobi integral J = E - w_NO_N . H_O_N (core/system.hpp, Environment), with
  // the angular momentum about O (fixed in N) H_O_N = H_Scm_N + M (p_cm - p_NoO_N) x v_cm
  // (Greenwood 2003, Ch. 1, the angular momentum about another point), M v_cm the total linear
  // momentum.
  if (m.orbit) {
    const Eigen::Vector3d& P_N = w.P_sys;
    const Eigen::Vector3d H_O_N = H_Scm_N + (p_NoScm_N - m.p_NoO_N).cross(P_N);
    out.jacobi(E - orbit_frame(m.environment, t).w_NO_N.dot(H_O_N));
  }

  // Joint loads from each child subtree's momentum balance (loads.cpp), in the child body frame.
  joint_loads(m, w, t);
  for (std::size_t j = 0; j < m.joints.size(); ++j) {
    const Model::JointM& J = m.joints[j];
    if (J.absolute) continue;  // the free joint carries nothing
    const Eigen::Matrix3d& R_NC = k.R_NB[static_cast<std::size_t>(J.child)];
    out.joint_load(static_cast<int>(j), R_NC.transpose() * w.F_N[j],
                   R_NC.transpose() * w.M_J_N[j]);
  }

  // P and the external moment about the system CM (power_of, external_moment_of below).
  out.power(power_of(m, t, u, w.T_N, k.R_NB, k.w_NB_B, w.torque.data()));
  out.external_moment(external_moment_of(m, w.T_N, w.F_N, w.M_J_N, w.r_J_N, p_NoScm_N,
                                         k.p_NoBo_N, w.F_g_N, w.M_g_N));

  out.extra(m.recharts_column, static_cast<double>(w.recharts));
}

void LagrangeEngine::accelerations(double t, const double* x, TreeAccel& a) {
  evaluate(t, expand(t, x));
  const Model& m = *model_;
  const Workspace& w = *ws_;
  const std::size_t nb = m.bodies.size(), nj = m.joints.size();
  a.wdot_NB_B.assign(nb, Eigen::Vector3d::Zero());
  a.a_NBo_N.assign(nb, Eigen::Vector3d::Zero());
  a.angle_ddot.assign(nj, 0.0);
  a.angle2_ddot.assign(nj, 0.0);
  a.wdot_PC_C.assign(nj, Eigen::Vector3d::Zero());
  a.eta_ddot.assign(nb, Eigen::VectorXd());
  // Body twist xi = Xi(q*) pi' => xi' = Xi pi'' + (dXi/dt) pi'.
  for (std::size_t b = 0; b < nb; ++b) {
    const Eigen::Matrix<double, 6, 1> xid = w.Xi[b] * w.udot + w.Xi_dot[b] * w.u;
    a.wdot_NB_B[b] = xid.head<3>();
    const Model::BodyM& B = m.bodies[b];
    // The twist holds v_NBo_B, so a_NBo_N = R_NB (v_NBo_B' + w x v_NBo_B) (Kane & Levinson 1985,
    // Sec. 2.3, differentiation in two reference frames).
    const Eigen::Matrix<double, 6, 1> xi = w.Xi[b] * w.u;
    Eigen::Matrix3d R;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) R(r, c) = w.k1.R_NB[b](r, c).v;
    a.a_NBo_N[b] = R * (xid.tail<3>() + xi.head<3>().cross(xi.tail<3>()));
    if (B.flex >= 0) a.eta_ddot[b] = w.udot.segment(B.e0, B.nm);
  }
  for (std::size_t j = 0; j < nj; ++j) {
    const Model::JointM& J = m.joints[j];
    J.unit->accelerations(a, j, w.udot, J.i0);
  }
}

}  // namespace crossdyn::lagrange
