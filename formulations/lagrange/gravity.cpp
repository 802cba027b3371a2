// The Lagrange engine's environment loads (issue 28; core/system.hpp Environment, core/orbit.hpp;
// README.md "Gravity"): uniform gravity, or the gravity gradient of a central body about a
// reference point O on a circular orbit.
//
// Route. In Lagrange's equations a conservative load may enter as a potential V(q*, t) in
// L = T - V (its gradient by the engine's automatic differentiation) or as generalised active
// forces from the forces and torques on the bodies by virtual power (Kane & Levinson 1985,
// "Dynamics: Theory and Applications", Sec. 4.4-4.5; Greenwood 2003, Sec. 2.4: the generalised
// force of a conservative load is -dV/dq, so both give the same equations). This engine takes the
// generalised forces: N_i += F . v(e_i) + M . w(e_i), with the body twists of the unit seeds
// Xi (the mass pass's, already computed), so
//   - the gradient pass (Dual<K> over eight widths) stays as it was: T and V there do not depend on
//     the positions p_NoBo_N, which it does not compute, nor on the free base's translation, which
//     it does not seed; a gravity potential would need both in every Dual<K> pass, slowing it with
//     or without an environment;
//   - the cost is one position walk and one dot product per supporting seed per body, and nothing
//     at all without an environment (one branch on Model::gravity);
//   - test_gravity_gradient_sign multiplies exactly the torque terms 3 n^2 zhat x (I_N zhat) in the
//     equations of motion, and nothing in E or J.
// The potentials are still written (outputs.cpp, gravity_potential below) for E and J, and they
// are exactly those of docs/environment.md / core/system.hpp: uniform V = -sum m g . p (p the CM,
// or the displaced node), orbit V = -1/2 m r_c^T T r_c + 3/2 n^2 zhat^T I_N zhat - 1/2 n^2 tr(I)
// per body (per node with m_i, r_i, J_i). The forces below are their exact negative gradients
// (derivation per case below), which the tests check through E (uniform) and J (orbit)
// conservation.
//
// Loads, r the position from O, T = n^2 (3 zhat zhat^T - 1) (Hughes 2004, "Spacecraft Attitude
// Dynamics", Sec. 8.1; Schaub & Junkins 2018, Sec. 4.3.2):
//   rigid body, uniform   F = m g at the CM Bo, no moment about Bo;
//   rigid body, orbit     F = m T r_c at Bo, and about Bo tau = 3 n^2 zhat x (I_N zhat),
//                         I_N = R_NB I_BBo_B R_NB^T (Hughes Sec. 8.1, Eq. (8.7));
//   flexible body: the node forces F_i = m_i a(r_i) at the displaced nodes r_i = p_Bo + R x_i
//   (x_i = p_i + u_i, body components) and the node torques 3 n^2 zhat x (J_i,N zhat) act with the
//   virtual power sum_i F_i . (v + w x x_i + Pt_i eta') + tau_i . w (J_i fixed in the body frame:
//   no work on eta), i.e. the resultant F at Bo, its moment about Bo M, and on the body's own eta'
//   the modal force Q = sum_i Pt_i^T F_i,B. With s = sum m_i x_i (FlexInertia::s) and I_w =
//   sum m_i (|x_i|^2 1 - x_i x_i^T) + J (FlexInertia::I_w, J = sum J_i):
//     uniform   F = m g,  M = (R s) x g,  Q = S1(eta)^T g_B   (S1 = ds/deta = sum m_i Pt_i);
//     orbit     F = T (m rho + R s) with rho = p_Bo - O,
//               M = (R s) x (T rho) + 3 n^2 zhat x ((I_w - J)_N zhat) + 3 n^2 zhat x (J_N zhat)
//               (sum_i m_i x x (T x) = 3 n^2 (Q_x zhat) x zhat with Q_x = sum m_i x x^T
//               = tr(I_p)/2 1 - I_p, I_p = I_w - J, hence 3 n^2 zhat x (I_p zhat)),
//               Q_k = (T_B rho_B) . ds/deta_k + d/deta_k [1/2 sum_i m_i x_i^T T_B x_i]
//                   = (T_B rho_B) . ds/deta_k
//                     + n^2/2 (tr dI_w/deta_k - 3 zhat_B^T dI_w/deta_k zhat_B)
//               (T_B = R^T T R; 1/2 sum m x^T T_B x = n^2/2 (tr I_p - 3 zhat_B^T I_p zhat_B) and J
//               does not depend on eta), ds/deta_k and dI_w/deta_k by Dual<1> on flex_inertia;
//               the node inertias' share, 3 n^2 zhat x (J_N zhat), is the one the sign hook flips.
#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "core/orbit.hpp"
#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/flex_body.hpp"
#include "formulations/lagrange/kinematics.hpp"
#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/passes.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

namespace {

Eigen::Matrix3d value_of(const Mat3<Dual<1>>& R) {
  Eigen::Matrix3d V;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) V(r, c) = R(r, c).v;
  return V;
}
Eigen::Vector3d value_of(const Vec3<Dual<1>>& v) {
  return {v(0).v, v(1).v, v(2).v};
}

}  // namespace

void gravity_forces(const Model& m, Workspace& w, double t) {
  const Kin<Dual<1>>& k = w.k1;
  // Body origins p_NoBo_N from the mass pass's pose (values of its Dual<1>): the pose pass's
  // position formula (kinematics.hpp), p_NoCo_N = p_NoPo_N + R_NP r_P - R_NC r_C, which its dual
  // passes skip.
  for (const Model::JointM& J : m.joints) {
    const auto c = static_cast<std::size_t>(J.child);
    if (J.absolute) {
      w.p_g_N[c] = Eigen::Vector3d(k.q[static_cast<std::size_t>(J.i0)].v,
                                   k.q[static_cast<std::size_t>(J.i0 + 1)].v,
                                   k.q[static_cast<std::size_t>(J.i0 + 2)].v);
      continue;
    }
    const Eigen::Vector3d r_C = J.child_node >= 0 ? value_of(k.r_C[c]) : J.p_CoJ_C;
    const Eigen::Vector3d from_joint = value_of(k.R_NB[c]) * r_C;
    if (J.parent < 0) {  // a prescribed base: its joint point is fixed in N
      w.p_g_N[c] = J.p_PoJ_P - from_joint;
      continue;
    }
    const auto P = static_cast<std::size_t>(J.parent);
    const Eigen::Vector3d r_P =
        J.parent_node >= 0 || J.slides > 0 ? value_of(k.r_P[c]) : J.p_PoJ_P;
    w.p_g_N[c] = w.p_g_N[P] + value_of(k.R_NB[P]) * r_P - from_joint;
  }

  const Environment& env = m.environment;
  OrbitFrame of;
  double n2 = 0;
  if (m.orbit) {
    of = orbit_frame(env, t);
    n2 = of.n * of.n;
  }
  const Eigen::Vector3d& z = of.zenith_N;
  // T v = n^2 (3 zhat (zhat . v) - v), the gravity gradient (Hughes 2004, Sec. 8.1).
  auto tidal = [&](const Eigen::Vector3d& v) -> Eigen::Vector3d {
    return n2 * (3.0 * z.dot(v) * z - v);
  };
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const Model::BodyM& B = m.bodies[b];
    const Eigen::Matrix3d R = value_of(k.R_NB[b]);
    Eigen::Vector3d F_N, M_N;
    const bool flex = B.flex >= 0;
    double* Q = w.Q_g.data();
    if (!flex) {
      if (m.orbit) {
        F_N = B.mass * tidal(w.p_g_N[b] - m.p_NoO_N);
        M_N = m.gg_sign * 3.0 * n2 * z.cross(R * (B.I_BBo_B * (R.transpose() * z)));
      } else {
        F_N = B.mass * env.g_N;
        M_N.setZero();
      }
    } else {
      const FlexInvariants& f = m.flex[static_cast<std::size_t>(B.flex)];
      const FlexInertia<double>& fi = w.fi0[b];  // at eta (mass pass)
      const Eigen::Vector3d s_N = R * fi.s;
      if (m.orbit) {
        const Eigen::Vector3d rho = w.p_g_N[b] - m.p_NoO_N;
        const Eigen::Vector3d Trho = tidal(rho);
        F_N = B.mass * Trho + tidal(s_N);
        const Eigen::Matrix3d I_N = R * fi.I_w * R.transpose();
        const Eigen::Matrix3d J_N = R * f.J * R.transpose();
        M_N = s_N.cross(Trho) + 3.0 * n2 * z.cross(I_N * z) +
              (m.gg_sign - 1.0) * 3.0 * n2 * z.cross(J_N * z);
        // Modal forces: ds/deta_k and dI_w/deta_k by Dual<1> seeded on eta_k.
        const Eigen::Vector3d Trho_B = R.transpose() * Trho, z_B = R.transpose() * z;
        FlexInertia<Dual<1>>& fg = w.fi_g[b];
        Dual<1>* eta = w.eta_g.data();
        for (int a = 0; a < B.nm; ++a)
          eta[a] = Dual<1>(w.k1.q[static_cast<std::size_t>(B.e0 + a)].v);
        for (int kk = 0; kk < B.nm; ++kk) {
          eta[kk].d[0] = 1.0;
          flex_inertia(f, eta, fg);
          eta[kk].d[0] = 0.0;
          Eigen::Matrix3d dI;
          Eigen::Vector3d ds;
          for (int r = 0; r < 3; ++r) {
            ds(r) = fg.s(r).d[0];
            for (int c = 0; c < 3; ++c) dI(r, c) = fg.I_w(r, c).d[0];
          }
          Q[kk] = Trho_B.dot(ds) + 0.5 * n2 * (dI.trace() - 3.0 * z_B.dot(dI * z_B));
        }
      } else {
        F_N = B.mass * env.g_N;
        M_N = s_N.cross(env.g_N);
        const Eigen::Vector3d g_B = R.transpose() * env.g_N;
        const Eigen::Matrix3Xd& S1 = fi.stiff ? fi.S1 : f.S1;
        for (int kk = 0; kk < B.nm; ++kk) Q[kk] = S1.col(kk).dot(g_B);
      }
    }
    w.F_g_N[b] = F_N;
    w.M_g_N[b] = M_N;
    // Virtual power F . v_Bo + M . w (Kane & Levinson 1985, Sec. 4.4: generalised active forces),
    // in body components, per supporting seed; plus Q on the body's own eta'.
    const Eigen::Vector3d F_B = R.transpose() * F_N, M_B = R.transpose() * M_N;
    const auto& X = w.Xi[b];
    for (int i : m.support[b]) w.N(i) += X.col(i).head<3>().dot(M_B) + X.col(i).tail<3>().dot(F_B);
    if (flex)
      for (int kk = 0; kk < B.nm; ++kk) w.N(B.e0 + kk) += Q[kk];
  }
}

double gravity_potential(const Model& m, const Kin<double>& k, double t) {
  const Environment& env = m.environment;
  double V = 0;
  if (m.orbit) {
    const OrbitFrame of = orbit_frame(env, t);
    const double n2 = of.n * of.n;
    const Eigen::Vector3d& z = of.zenith_N;
    auto tidal = [&](const Eigen::Vector3d& v) -> Eigen::Vector3d {
      return n2 * (3.0 * z.dot(v) * z - v);
    };
    for (std::size_t b = 0; b < m.bodies.size(); ++b) {
      const Model::BodyM& B = m.bodies[b];
      const Eigen::Matrix3d& R = k.R_NB[b];
      const Eigen::Vector3d rho = k.p_NoBo_N[b] - m.p_NoO_N;
      // Per node summed (gravity.cpp header): -1/2 m rho^T T rho - rho^T T (R s)
      // + 3/2 n^2 zhat^T I_N zhat - 1/2 n^2 tr(I), I = I_w(eta) and s = s(eta) for a flexible
      // body, I_BBo_B and 0 for a rigid one.
      const Eigen::Matrix3d& I = B.flex >= 0 ? k.fi[b].I_w : B.I_BBo_B;
      V += -0.5 * B.mass * rho.dot(tidal(rho)) + 1.5 * n2 * z.dot(R * (I * (R.transpose() * z))) -
           0.5 * n2 * I.trace();
      if (B.flex >= 0) V -= rho.dot(tidal(R * k.fi[b].s));
    }
  } else if (env.uniform()) {
    for (std::size_t b = 0; b < m.bodies.size(); ++b) {
      const Model::BodyM& B = m.bodies[b];
      // -g . sum m_i (p_Bo + R x_i) = -g . (m p_Bo + R s).
      Eigen::Vector3d s = B.mass * k.p_NoBo_N[b];
      if (B.flex >= 0) s += k.R_NB[b] * k.fi[b].s;
      V -= env.g_N.dot(s);
    }
  }
  return V;
}

}  // namespace crossdyn::lagrange
