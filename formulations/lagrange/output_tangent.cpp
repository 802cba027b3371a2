// The Lagrange engine's exact output variation (issue 27; core/engine.hpp output_row_tangent):
// row = output_row(t, pack(s)) and drow, its variation along a TreeTangent ds, every column of the
// layout, exact to rounding.
//
// How (README.md, "Exact linearisation"): forward-mode automatic differentiation (Griewank &
// Walther 2008, "Evaluating Derivatives", 2nd ed., Ch. 3, the tangent mode; Ch. 13, nesting), no
// differences. tangent::evaluate (tangent.cpp) gives, on E = Dual<1> (each value with its
// variation along ds), pack()'s state and its variation, the accelerations q*'', pi'', every
// body's R_NB, origin, twist and twist rate, the environment's loads, the prescribed joints'
// torques and T, V. The columns are then output_row()'s formulas (outputs.cpp, loads.cpp,
// gravity.cpp's potential) on E:
//   momenta, H, CM, positions, E, J       from the bodies' momenta on E (flex_momentum, with the
//                                          modal rates on E too);
//   joint loads, external moment, P       loads.cpp's momentum balance of each child subtree, the
//                                          momentum rates h' = d/dt (M_B(eta) xi) of a flexible
//                                          body by a nested Dual<1, E> along the motion (q*' on
//                                          the pose pass, xi' and eta'' on the twist and rates),
//                                          so their variation carries the accelerations';
//   joint and modal columns               linear in (q*, pi'): the joint unit's own columns() on
//                                          the variations;
//   quaternions                           R_NB's variation is R_NB [dtheta x] (dtheta =
//                                          vee(R_NB^T dR_NB), a right perturbation), so the
//                                          written (canonical, qw >= 0) q varies by
//                                          1/2 q (x) (0, dtheta) (rot::quat_rate_body; Kane, Likins
//                                          & Levinson 1983, Sec. 1.13), with the sign it takes;
//   roll, pitch, yaw; wox, woy, woz       R_OB = R_NO^T R_NB turns by the same dtheta, so the
//                                          3-2-1 angles vary by the inverse of their body-rate
//                                          matrix times dtheta (written out below; Diebel 2006,
//                                          "Representing Attitude", the 3-2-1 sequence);
//                                          w_OB_B = w_NB_B - R_NB^T w_NO_N by
//                                          dw + dtheta x (R_NB^T w_NO_N).
// The values of every column so computed are compared with output_row()'s (a guard, as in
// accelerations_tangent(): a formula here that is not output_row()'s returns false, never a wrong
// variation); row is output_row()'s own. Allocates; never the hot path.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "core/orbit.hpp"
#include "core/rotation.hpp"
#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/flex_body.hpp"
#include "formulations/lagrange/joints/joint_unit.hpp"
#include "formulations/lagrange/kinematics.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/passes.hpp"
#include "formulations/lagrange/tangent_core.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

namespace {

using tangent::E;
using S = Dual<1, E>;  // a value with its variation, and its time derivative along the motion

Eigen::Vector3d value(const Vec3<E>& v) {
  return {v(0).v, v(1).v, v(2).v};
}
Eigen::Vector3d variation(const Vec3<E>& v) {
  return {v(0).d[0], v(1).d[0], v(2).d[0]};
}
Vec3<E> constant(const Eigen::Vector3d& v) {
  return v.cast<E>();
}

}  // namespace

bool LagrangeEngine::output_row_tangent(double t, const TreeState& s, const TreeTangent& ds,
                                        double* row, double* drow) {
  const Model& m = *model_;
  if (!m.tangent) return false;
  Workspace& w = *ws_;
  const tangent::Restore<Workspace> restore(w);
  const int n = m.n;
  const auto un = static_cast<std::size_t>(n);
  std::vector<double> xs(static_cast<std::size_t>(state_size())), dxf;
  pack_tangent(s, ds, "output_row_tangent", xs.data(), dxf);
  const OutputLayout& L = m.layout;
  const std::size_t ncol = L.size();
  std::vector<double> r0(ncol);
  output_row(t, xs.data(), r0.data());
  const double* xf = expand(t, xs.data());
  std::vector<E> qE(un), uE(un);
  for (std::size_t i = 0; i < un; ++i) {
    qE[i] = tangent::seeded(xf[i], dxf[i]);
    uE[i] = tangent::seeded(xf[un + i], dxf[un + i]);
  }
  tangent::Core c;
  const int* chart = w.chart.data();
  if (!tangent::evaluate(m, t, chart, std::move(qE), std::move(uE), c))
    return false;
  const std::size_t nb = m.bodies.size(), nj = m.joints.size();

  // The values (vrow, to compare with output_row()'s) and variations (dr) of every column.
  std::vector<double> vrow(ncol), dr(ncol);
  RowWriter vout(L, vrow.data()), dout(L, dr.data());  // both start as NaN
  auto put = [&](int col, const E& x) {
    vrow[static_cast<std::size_t>(col)] = x.v;
    dr[static_cast<std::size_t>(col)] = x.d[0];
  };
  auto put3 = [&](int col, const Vec3<E>& x) {
    for (int a = 0; a < 3; ++a) put(col + a, x(a));
  };
  vout.time(t);
  dout.time(0.0);

  // The flexible bodies' inertia at q* and its rate along the motion: the pose pass on S with
  // q* + tau q*'.
  Kin<S> k;
  k.resize(m);
  for (std::size_t i = 0; i < un; ++i) {
    k.q[i] = S(c.q[i]);
    k.q[i].d[0] = c.qd[i];
  }
  pose_pass(m, chart, k, true);

  // Per body (outputs.cpp body_momenta, loads.cpp joint_loads): momenta P (N), h about Bo (N), the
  // first mass moment s (N), and the momentum rates dP_N, dK_N, the external torque T_N.
  std::vector<Vec3<E>> P(nb), h(nb), sm(nb), dP(nb), dK(nb), T_N(nb);
  for (std::size_t b = 0; b < nb; ++b) {
    const Model::BodyM& B = m.bodies[b];
    const Mat3<E>& R = c.R[b];
    const Vec3<E>&wb = c.w[b], &vb = c.v[b];
    Vec3<E> hw, hv, hwd, hvd;
    if (B.flex < 0) {
      hv = B.mass * vb;
      hw = const_times(B.I_BBo_B, wb);
      hvd = B.mass * c.vd[b];
      hwd = const_times(B.I_BBo_B, c.wd[b]);
      sm[b] = B.mass * c.p[b];
    } else {
      // h = M_B(eta) xi and h' = d/dt (M_B(eta) xi) at once: xi + tau xi' and eta' + tau eta''
      // on the pose pass along the motion.
      const FlexInvariants& f = m.flex[static_cast<std::size_t>(B.flex)];
      Vec3<S> wS, vS, hwS, hvS;
      for (int a = 0; a < 3; ++a) {
        wS(a) = S(wb(a));
        wS(a).d[0] = c.wd[b](a);
        vS(a) = S(vb(a));
        vS(a).d[0] = c.vd[b](a);
      }
      std::vector<S> ed(static_cast<std::size_t>(B.nm));
      for (int i = 0; i < B.nm; ++i) {
        ed[static_cast<std::size_t>(i)] = S(c.u[static_cast<std::size_t>(B.e0 + i)]);
        ed[static_cast<std::size_t>(i)].d[0] = c.ud[static_cast<std::size_t>(B.e0 + i)];
      }
      flex_momentum(f, k.fi[b], wS, vS, ed.data(), hwS, hvS, static_cast<S*>(nullptr));
      Vec3<E> s_B;
      for (int a = 0; a < 3; ++a) {
        hw(a) = hwS(a).v;
        hwd(a) = hwS(a).d[0];
        hv(a) = hvS(a).v;
        hvd(a) = hvS(a).d[0];
        s_B(a) = k.fi[b].s(a).v;
      }
      sm[b] = B.mass * c.p[b] + R * s_B;
    }
    P[b] = R * hv;
    h[b] = R * hw;
    momentum_rates(B, R, wb, vb, hw, hv, hwd, hvd, dP[b], dK[b]);  // loads.cpp's
    T_N[b] = Vec3<E>::Zero();
    if (!B.torque.empty()) {
      const Eigen::Vector3d tau = B.torque.value(t);
      T_N[b] = B.torque_frame == Body::Frame::Inertial ? constant(tau) : Vec3<E>(R * constant(tau));
    }
  }

  // Bodies: w_NB_B, q_NB (output_row()'s value, canonical), roll, pitch, yaw and w_OB_B.
  OrbitFrame of;
  if (m.orbit) of = orbit_frame(m.environment, t);
  double attitude_diff = 0.0;
  for (std::size_t b = 0; b < nb; ++b) {
    const int col = L.body_w(static_cast<int>(b));
    put3(col, c.w[b]);
    Eigen::Matrix3d Rv, dR;
    for (int r = 0; r < 3; ++r)
      for (int cc = 0; cc < 3; ++cc) {
        Rv(r, cc) = c.R[b](r, cc).v;
        dR(r, cc) = c.R[b](r, cc).d[0];
      }
    const Eigen::Matrix3d Om = Rv.transpose() * dR;  // [dtheta x] to rounding
    const Eigen::Vector3d dth(0.5 * (Om(2, 1) - Om(1, 2)), 0.5 * (Om(0, 2) - Om(2, 0)),
                              0.5 * (Om(1, 0) - Om(0, 1)));
    const auto qc = static_cast<std::size_t>(L.body_q(static_cast<int>(b)));
    const Eigen::Quaterniond q(r0[qc], r0[qc + 1], r0[qc + 2], r0[qc + 3]);
    attitude_diff = std::max(attitude_diff, (q.toRotationMatrix() - Rv).cwiseAbs().maxCoeff());
    const Eigen::Vector4d dq = rot::quat_rate_body(q, dth);
    for (std::size_t a = 0; a < 4; ++a) {
      vrow[qc + a] = r0[qc + a];
      dr[qc + a] = dq(static_cast<Eigen::Index>(a));
    }
    const int lv = L.lvlh(static_cast<int>(b));
    if (lv >= 0) {
      const auto l0 = static_cast<std::size_t>(lv);
      // (roll, pitch, yaw)' from the body rates of R_OB = Rz(yaw) Ry(pitch) Rx(roll):
      // w_B = (r' - y' sp, p' cr + y' sr cp, -p' sr + y' cr cp).
      const double roll = r0[l0], pitch = r0[l0 + 1];
      const double sr = std::sin(roll), cr = std::cos(roll), cp = std::cos(pitch),
                   tp = std::tan(pitch);
      const double a = dth(1) * sr + dth(2) * cr;
      const Eigen::Vector3d drpy(dth(0) + a * tp, dth(1) * cr - dth(2) * sr, a / cp);
      const Eigen::Vector3d wNO_B = Rv.transpose() * of.w_NO_N;
      const Eigen::Vector3d dwo = variation(c.w[b]) + dth.cross(wNO_B);
      const Eigen::Vector3d wo = value(c.w[b]) - wNO_B;
      for (std::size_t i = 0; i < 3; ++i) {
        vrow[l0 + i] = r0[l0 + i];
        dr[l0 + i] = drpy(static_cast<Eigen::Index>(i));
        vrow[l0 + 3 + i] = wo(static_cast<Eigen::Index>(i));
        dr[l0 + 3 + i] = dwo(static_cast<Eigen::Index>(i));
      }
    }
  }
  // Joint and modal columns: linear in (q*, pi'), the units' own columns() on values and variations.
  std::vector<double> qv(un), uv(un), dqv(un), duv(un);
  for (std::size_t i = 0; i < un; ++i) {
    qv[i] = c.q[i].v;
    uv[i] = c.u[i].v;
    dqv[i] = c.q[i].d[0];
    duv[i] = c.u[i].d[0];
  }
  for (std::size_t j = 0; j < nj; ++j) {
    const Model::JointM& J = m.joints[j];
    J.unit->columns(vout, static_cast<int>(j), qv.data() + J.i0, uv.data() + J.i0);
    J.unit->columns(dout, static_cast<int>(j), dqv.data() + J.i0, duv.data() + J.i0);
  }
  for (std::size_t b = 0; b < nb; ++b) {
    const Model::BodyM& B = m.bodies[b];
    if (B.flex < 0) continue;
    vout.modal(static_cast<int>(b), Eigen::Map<const Eigen::VectorXd>(qv.data() + B.e0, B.nm),
               Eigen::Map<const Eigen::VectorXd>(uv.data() + B.e0, B.nm));
    dout.modal(static_cast<int>(b), Eigen::Map<const Eigen::VectorXd>(dqv.data() + B.e0, B.nm),
               Eigen::Map<const Eigen::VectorXd>(duv.data() + B.e0, B.nm));
  }
  for (std::size_t kp = 0; kp < m.prescribed_joints.size(); ++kp)
    put(L.joint_first(m.prescribed_joints[kp]) + 2, c.torque[kp]);

  // H about the system CM, the CM (outputs.cpp's system_momenta), positions.
  for (std::size_t b = 0; b < nb; ++b) put3(L.body_position(static_cast<int>(b)), c.p[b]);
  Vec3<E> Ptot, p_cm;
  const Vec3<E> H_Scm = system_momenta(m, c.p, P, h, sm, Ptot, p_cm);
  put3(L.H_vector(), H_Scm);
  {
    using std::sqrt;
    const E sq = H_Scm.squaredNorm();
    put(L.H(), sq.v > 0.0 ? E(sqrt(sq)) : E(0.0));  // |H|: its variation H . dH / |H|
  }
  put3(L.cm(), p_cm);

  // E = T + V + the environment's potential (gravity.cpp gravity_potential, on E).
  E energy = c.T + c.V;
  const Environment& env = m.environment;
  const double n2 = of.n * of.n;
  const Vec3<E> z = constant(of.zenith_N);
  auto tidal = [&](const Vec3<E>& v) { return Vec3<E>(n2 * Vec3<E>(3.0 * z.dot(v) * z - v)); };
  if (m.orbit) {
    for (std::size_t b = 0; b < nb; ++b) {
      const Model::BodyM& B = m.bodies[b];
      const Mat3<E>& R = c.R[b];
      const Vec3<E> rho = c.p[b] - constant(m.p_NoO_N);
      Mat3<E> I;
      if (B.flex >= 0) {
        for (int r = 0; r < 3; ++r)
          for (int cc = 0; cc < 3; ++cc) I(r, cc) = k.fi[b].I_w(r, cc).v;
      } else {
        I = B.I_BBo_B.cast<E>();
      }
      energy += -0.5 * B.mass * rho.dot(tidal(rho)) +
                1.5 * n2 * z.dot(Vec3<E>(R * Vec3<E>(I * transpose_times(R, z)))) -
                0.5 * n2 * I.trace();
      if (B.flex >= 0) energy -= rho.dot(tidal(Vec3<E>(sm[b] - B.mass * c.p[b])));
    }
  } else if (m.gravity && env.uniform()) {
    for (std::size_t b = 0; b < nb; ++b) energy -= constant(env.g_N).dot(sm[b]);
  }
  put(L.E(), energy);
  if (m.orbit) {
    const Vec3<E> H_O = H_Scm + Vec3<E>(p_cm - constant(m.p_NoO_N)).cross(Ptot);
    put(L.J(), energy - constant(of.w_NO_N).dot(H_O));
  }

  // Joint loads, in the child body frame: loads.cpp's momentum balance of each child subtree.
  std::vector<Vec3<E>> F_N(nj), M_J(nj), r_J(nj);
  subtree_loads(m, c.p, c.R, c.r_C, dP, dK, T_N, c.F_g, c.M_g, F_N, M_J, r_J);
  for (std::size_t j = 0; j < nj; ++j) {
    const Model::JointM& J = m.joints[j];
    if (J.absolute) continue;  // the free joint carries nothing
    const auto ch = static_cast<std::size_t>(J.child);
    const int col = L.joint_load(static_cast<int>(j));
    put3(col, transpose_times(c.R[ch], F_N[j]));
    put3(col + 3, transpose_times(c.R[ch], M_J[j]));
  }

  // P and the external moment about the system CM: outputs.cpp's power_of, external_moment_of.
  put(L.P(), power_of(m, t, c.u.data(), T_N, c.R, c.w, c.torque.data()));
  put3(L.external_moment(),
       external_moment_of(m, T_N, F_N, M_J, r_J, p_cm, c.p, c.F_g, c.M_g));

  // The engine's extra column (charts switched): no variation.
  vrow[static_cast<std::size_t>(m.recharts_column)] = r0[static_cast<std::size_t>(m.recharts_column)];
  dr[static_cast<std::size_t>(m.recharts_column)] = 0.0;

  // Guard: every column written, and the values output_row()'s to rounding (per column kind,
  // relative to the kind's largest value, or to 1e-3 of the row's largest when the kind is smaller:
  // a joint that carries no moment has moments of rounding size), the attitudes R_NB's.
  std::vector<double> kind_scale(static_cast<std::size_t>(ColumnKind::Extra) + 1, 0.0);
  double row_scale = 0.0;
  for (std::size_t i = 1; i < ncol; ++i) {
    const auto kk = static_cast<std::size_t>(L.columns()[i].kind);
    kind_scale[kk] = std::max(kind_scale[kk], std::abs(r0[i]));
    row_scale = std::max(row_scale, std::abs(r0[i]));
  }
  for (double& sc : kind_scale) sc = std::max(sc, 1e-3 * row_scale);
  for (std::size_t i = 0; i < ncol; ++i) {
    if (!std::isfinite(dr[i]) || !std::isfinite(vrow[i])) return false;
    const auto kk = static_cast<std::size_t>(L.columns()[i].kind);
    if (!(std::abs(vrow[i] - r0[i]) <= 1e-8 * kind_scale[kk] + 1e-12)) return false;
  }
  if (!(attitude_diff <= 1e-10)) return false;
  std::copy(r0.begin(), r0.end(), row);
  std::copy(dr.begin(), dr.end(), drow);
  return true;
}

}  // namespace crossdyn::lagrange
