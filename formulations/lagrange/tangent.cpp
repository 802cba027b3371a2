// The Lagrange engine's exact linearisation (issue 27; core/engine.hpp accelerations_tangent):
// a = accelerations(t, pack(s)) and its variation da along a TreeTangent ds, exact to rounding.
//
// How (README.md, "Exact linearisation"): nested forward-mode automatic differentiation
// (Griewank & Walther 2008, "Evaluating Derivatives", 2nd ed., Ch. 3, the tangent mode, and
// Ch. 13, higher derivatives by nesting), no differences and no complex step. The scalar
// E = Dual<1> carries every value with its variation along ds (the outer direction); the scalar
// S = Dual<1, E> carries, on top, one derivative with respect to a coordinate q*_k (the inner
// direction). Through the engine's own kinematics and energies (kinematics.hpp pose and twist
// passes, energy.hpp's potential, euler_chart.hpp's A) on S, the same Lagrangian as rhs()'s,
//   L(q*, q*') = 1/2 q*'^T Abar^T M(q*) Abar q*' - V(q*),   pi' = Abar(q*) q*'
// (Abar: A on every Euler set's block, 1 elsewhere; M_ij = T(e_i, e_j) from the unit-seed twists
// as in the mass pass), gives Lagrange's equations in q*
//   Mbar q*'' = Abar^T N - (sum_l dMbar/dq*_l q*'_l) q*' + 1/2 q*'^T (dMbar/dq*_k) q*' - dV/dq*_k,
// solved in E, then pi'' = Abar q*'' + (d Abar/dt) q*': the same equations of motion as the
// Boltzmann-Hamel form rhs() solves (paper Eq. 23 is these with d(pi) = A dq*, Eqs. 16-22), so
// their value parts equal accelerations()'s to rounding (checked below: the variation is returned
// only when they agree). The state's own variation is pack()'s, in the chart pack() chose: a right
// perturbation R exp(e [dtheta x]) of an Euler set's rotation moves its angles by B dtheta
// (B = A^-1: w = A a', euler_chart.hpp), and with System::zero_linear_momentum the base velocity's
// variation is that of -P_rest / m_total, P_rest the linear momentum of the other quasi-velocities.
//
// Covered (Model::tangent, decided once by the constructor): every system the engine runs. A free
// or prescribed base; revolute, prismatic, universal, spherical and fixed joints (at nodes too);
// hinge springs, dampers and motors; body torques (body or inertial frame); prescribed joints
// (their coordinates at the profile's t, no variation, theta''(t) known); flexible bodies (M_B(eta)
// by flex_momentum, elastic V, modal damping, geometric stiffening); uniform gravity and the
// orbit's gravity gradient (gravity.cpp's loads as generalised active forces, its flexible bodies'
// modal forces with ds/deta and dI_w/deta from the inner derivative). It returns false only if
// its values disagree with accelerations() (never seen in the tests).
//
// Cost: n inner directions, each n twist passes (O(n^2) passes and O(n^4) products): for
// linearisation and tests, never rhs(). Allocates.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "core/errors.hpp"
#include "core/orbit.hpp"
#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/energy.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "formulations/lagrange/joints/joint_unit.hpp"
#include "formulations/lagrange/kinematics.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/tangent_core.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

namespace tangent {

namespace {

using S = Dual<1, E>;  // a value with its variation (E), and one derivative along a coordinate q*_k

// Dense n x n matrix of E, row-major.
struct MatE {
  int n = 0;
  std::vector<E> a;
  explicit MatE(int size) : n(size), a(static_cast<std::size_t>(size * size), E(0.0)) {}
  E& operator()(int r, int c) { return a[static_cast<std::size_t>(r * n + c)]; }
  const E& operator()(int r, int c) const { return a[static_cast<std::size_t>(r * n + c)]; }
};

// A z = b in E by Gaussian elimination with partial pivoting on the values (A is Mbar, symmetric
// positive definite, or a 3 x 3 A of a chart away from its singularity). b becomes z; A is
// overwritten. Returns false when a pivot is zero.
bool solve_in_place(MatE A, std::vector<E>& b) {
  const int n = A.n;
  for (int c = 0; c < n; ++c) {
    int p = c;
    for (int r = c + 1; r < n; ++r)
      if (std::abs(A(r, c).v) > std::abs(A(p, c).v)) p = r;
    if (A(p, c).v == 0.0) return false;
    if (p != c) {
      for (int k = 0; k < n; ++k) std::swap(A(p, k), A(c, k));
      std::swap(b[static_cast<std::size_t>(p)], b[static_cast<std::size_t>(c)]);
    }
    for (int r = c + 1; r < n; ++r) {
      const E f = A(r, c) / A(c, c);
      for (int k = c; k < n; ++k) A(r, k) -= f * A(c, k);
      b[static_cast<std::size_t>(r)] -= f * b[static_cast<std::size_t>(c)];
    }
  }
  for (int r = n - 1; r >= 0; --r) {
    E z = b[static_cast<std::size_t>(r)];
    for (int k = r + 1; k < n; ++k) z -= A(r, k) * b[static_cast<std::size_t>(k)];
    b[static_cast<std::size_t>(r)] = z / A(r, r);
  }
  return true;
}

// A flexible body's first mass moment s(eta) and S1(eta) = ds/deta at the values (E).
struct FlexB {
  Vec3<E> s = Vec3<E>::Zero();
  Mat3<E> I_w = Mat3<E>::Zero();
  std::vector<Vec3<E>> S1, ds;  // per mode: S1(eta) and ds/deta_k (= S1 without stiffening)
  std::vector<Mat3<E>> dI;      // per mode: dI_w/deta_k
  void resize_modes(Eigen::Index n) {
    S1.resize(static_cast<std::size_t>(n));
    ds.resize(static_cast<std::size_t>(n));
    dI.resize(static_cast<std::size_t>(n));
  }
};

}  // namespace

// The variation of one evaluation (tangent_core.hpp; the method: the header comment above).
bool evaluate(const Model& m, double t, const int* chart, std::vector<E> qE, std::vector<E> uE,
              Core& out) {
  const int n = m.n;
  const auto un = static_cast<std::size_t>(n);
  const std::size_t nb = m.bodies.size(), ns = m.euler_sets.size();
  // Inner directions k: with q* + eps e_k, the unit-seed twists Xi (6 x n per body), Mbar, V and
  // the charts' A on S. Kept: values (E) and d/dq*_k (E).
  std::vector<std::vector<Vec3<E>>> Xw(nb, std::vector<Vec3<E>>(un)), Xv = Xw;  // Xi value
  // dXi/dq*_k: [k][b][i]
  std::vector<std::vector<std::vector<Vec3<E>>>> dXw(un, Xw), dXv(un, Xw);
  std::vector<Mat3<E>> R(nb);
  std::vector<Vec3<E>> rP(nb);  // a sliding joint point r_P (pose pass), per child body
  std::vector<Vec3<E>> rC(nb);  // a joint point at a child node r_C (pose pass), per child body
  std::vector<FlexB> flexB(nb);  // flexible bodies
  MatE Mbar(n);
  std::vector<MatE> dMbar(un, MatE(n));
  std::vector<E> dV(un);
  std::vector<Mat3<E>> A(ns);
  std::vector<std::vector<Mat3<E>>> dA(un, std::vector<Mat3<E>>(ns));
  Kin<S> k;
  k.resize(m);
  std::vector<double> seed(un, 0.0);
  std::vector<std::vector<Vec3<S>>> Sw(nb, std::vector<Vec3<S>>(un)), Sv = Sw;
  std::vector<S> MS(un * un), AbS(un * un), T1(un * un);
  for (std::size_t kd = 0; kd < un; ++kd) {
    for (std::size_t i = 0; i < un; ++i) k.q[i] = S(qE[i]);
    k.q[kd].d[0] = E(1.0);
    pose_pass(m, chart, k, true);
    for (std::size_t i = 0; i < un; ++i) {
      seed[i] = 1.0;
      twist_pass(m, k, seed.data(), m.all_joints);
      seed[i] = 0.0;
      for (std::size_t b = 0; b < nb; ++b) {
        Sw[b][i] = k.w_NB_B[b];
        Sv[b][i] = k.v_NBo_B[b];
        for (int r = 0; r < 3; ++r) {
          dXw[kd][b][i](r) = k.w_NB_B[b](r).d[0];
          dXv[kd][b][i](r) = k.v_NBo_B[b](r).d[0];
          if (kd == 0) {
            Xw[b][i](r) = k.w_NB_B[b](r).v;
            Xv[b][i](r) = k.v_NBo_B[b](r).v;
          }
        }
      }
    }
    if (kd == 0)
      for (std::size_t b = 0; b < nb; ++b)
        for (int r = 0; r < 3; ++r) {
          for (int c = 0; c < 3; ++c) R[b](r, c) = k.R_NB[b](r, c).v;
          rP[b](r) = k.r_P[b](r).v;
          rC[b](r) = k.r_C[b](r).v;
        }
    // M_ij = T(e_i, e_j) (the mass pass's): a rigid body's w_i . I w_j + m v_i . v_j; a flexible
    // body's Y_i . M_B(eta) Y_j with Y_j = (w_j, v_j, e_j on its own eta' block) (flex_body.hpp).
    for (std::size_t i = 0; i < un * un; ++i) MS[i] = S(0.0);
    for (std::size_t b = 0; b < nb; ++b) {
      const Model::BodyM& Bm = m.bodies[b];
      if (Bm.flex < 0) {
        for (std::size_t i = 0; i < un; ++i)
          for (std::size_t j = i; j < un; ++j) {
            const S mij = Sw[b][i].dot(const_times(Bm.I_BBo_B, Sw[b][j])) +
                          Bm.mass * Sv[b][i].dot(Sv[b][j]);
            MS[i * un + j] += mij;
            if (j != i) MS[j * un + i] += mij;
          }
        continue;
      }
      const FlexInvariants& f = m.flex[static_cast<std::size_t>(Bm.flex)];
      const auto e0 = static_cast<std::size_t>(Bm.e0), nm = static_cast<std::size_t>(Bm.nm);
      std::vector<double> ed(nm, 0.0);
      std::vector<S> he(nm);
      Vec3<S> hw, hv;
      for (std::size_t j = 0; j < un; ++j) {
        const bool own_j = j >= e0 && j < e0 + nm;
        if (own_j) ed[j - e0] = 1.0;
        flex_momentum(f, k.fi[b], Sw[b][j], Sv[b][j], ed.data(), hw, hv, he.data());
        if (own_j) ed[j - e0] = 0.0;
        for (std::size_t i = 0; i < un; ++i) {
          S mij = Sw[b][i].dot(hw) + Sv[b][i].dot(hv);
          if (i >= e0 && i < e0 + nm) mij += he[i - e0];
          MS[i * un + j] += mij;
        }
      }
      // Its linear momentum R (m v + w x s + S1 eta') without the base translation's share
      // (zero linear momentum below; outputs.cpp body_momenta), at the values.
      if (kd == 0) {
        FlexB fb;
        fb.s = Vec3<E>(k.fi[b].s(0).v, k.fi[b].s(1).v, k.fi[b].s(2).v);
        fb.resize_modes(static_cast<Eigen::Index>(nm));
        for (std::size_t c = 0; c < nm; ++c)
          for (int r = 0; r < 3; ++r)
            fb.S1[c](r) = k.fi[b].stiff ? k.fi[b].S1(r, static_cast<Eigen::Index>(c)).v
                                        : E(f.S1(r, static_cast<Eigen::Index>(c)));
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) fb.I_w(r, c) = k.fi[b].I_w(r, c).v;
        flexB[b].s = fb.s;
        flexB[b].I_w = fb.I_w;
        flexB[b].S1 = fb.S1;
        flexB[b].ds.resize(nm);
        flexB[b].dI.resize(nm);
      }
      // The derivatives along the body's own modal coordinate (this inner direction).
      if (kd >= e0 && kd < e0 + nm) {
        for (int r = 0; r < 3; ++r) {
          flexB[b].ds[kd - e0](r) = k.fi[b].s(r).d[0];
          for (int c = 0; c < 3; ++c) flexB[b].dI[kd - e0](r, c) = k.fi[b].I_w(r, c).d[0];
        }
      }
    }
    // Abar (A on the Euler sets' blocks, 1 elsewhere) and Mbar = Abar^T M Abar.
    for (std::size_t i = 0; i < un * un; ++i) AbS[i] = S(0.0);
    for (std::size_t i = 0; i < un; ++i) AbS[i * un + i] = S(1.0);
    for (std::size_t set = 0; set < ns; ++set) {
      const auto i0 = static_cast<std::size_t>(m.euler_sets[set].i0);
      const Mat3<S> As = euler_rate_matrix(kSequences[static_cast<std::size_t>(chart[set])],
                                           k.q[i0 + 1], k.q[i0 + 2]);
      for (std::size_t r = 0; r < 3; ++r)
        for (std::size_t c = 0; c < 3; ++c) {
          AbS[(i0 + r) * un + i0 + c] = As(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c));
          dA[kd][set](static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) =
              As(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)).d[0];
          if (kd == 0)
            A[set](static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) =
                As(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)).v;
        }
    }
    for (std::size_t i = 0; i < un; ++i)  // T1 = M Abar
      for (std::size_t j = 0; j < un; ++j) {
        S sum(0.0);
        for (std::size_t l = 0; l < un; ++l)
          if (AbS[l * un + j] != S(0.0)) sum += MS[i * un + l] * AbS[l * un + j];
        T1[i * un + j] = sum;
      }
    for (std::size_t i = 0; i < un; ++i)  // Mbar = Abar^T T1
      for (std::size_t j = 0; j < un; ++j) {
        S sum(0.0);
        for (std::size_t l = 0; l < un; ++l)
          if (AbS[l * un + i] != S(0.0)) sum += AbS[l * un + i] * T1[l * un + j];
        const auto ii = static_cast<int>(i), jj = static_cast<int>(j);
        dMbar[kd](ii, jj) = sum.d[0];
        if (kd == 0) Mbar(ii, jj) = sum.v;
      }
    dV[kd] = potential_energy_of(m, chart, k.q.data()).d[0];
  }

  // q*' = B pi' (A on each Euler set solved in E), 1 elsewhere.
  std::vector<E> qd = uE;
  for (std::size_t set = 0; set < ns; ++set) {
    const auto i0 = static_cast<std::size_t>(m.euler_sets[set].i0);
    MatE A3(3);
    std::vector<E> rhs3(3);
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) A3(r, c) = A[set](r, c);
      rhs3[static_cast<std::size_t>(r)] = uE[i0 + static_cast<std::size_t>(r)];
    }
    if (!solve_in_place(A3, rhs3)) return false;
    for (std::size_t r = 0; r < 3; ++r) qd[i0 + r] = rhs3[r];
  }

  // N: body torques (tau . w(e_i)), joint dampers and motors (generalised_forces.cpp).
  std::vector<E> N(un, E(0.0));
  for (std::size_t b = 0; b < nb; ++b) {
    const Model::BodyM& Bm = m.bodies[b];
    if (Bm.torque.empty()) continue;
    const Eigen::Vector3d tau = Bm.torque.value(t);
    Vec3<E> tau_B;
    if (Bm.torque_frame == Body::Frame::Inertial)
      tau_B = transpose_times(R[b], Vec3<E>(tau.cast<E>()));
    else
      tau_B = tau.cast<E>();
    for (std::size_t i = 0; i < un; ++i) N[i] += Xw[b][i].dot(tau_B);
  }
  for (std::size_t b = 0; b < nb; ++b) {  // modal damping -D eta'
    const Model::BodyM& Bm = m.bodies[b];
    if (Bm.flex < 0) continue;
    const Eigen::MatrixXd& Dm = m.flex[static_cast<std::size_t>(Bm.flex)].Dmp;
    for (int c = 0; c < Bm.nm; ++c)
      for (int l = 0; l < Bm.nm; ++l)
        N[static_cast<std::size_t>(Bm.e0 + c)] -= Dm(c, l) * uE[static_cast<std::size_t>(Bm.e0 + l)];
  }
  for (const Model::JointM& J : m.joints) {
    if (J.loaded == 0) continue;
    const Eigen::Vector3d motor = J.motor.value(t);
    for (int c = 0; c < J.loaded; ++c) {
      const auto i = static_cast<std::size_t>(J.i0 + c);
      N[i] += -J.damping[static_cast<std::size_t>(c)] * uE[i] + motor(c);
    }
  }
  // The environment's loads (gravity.cpp), F at Bo and M about it: N_i += F . v(e_i) + M . w(e_i).
  // Uniform: F = m g, M = 0. Orbit: F = m T (p_Bo - O), M = gg_sign 3 n^2 zhat x (I_N zhat), with
  // the body origins from the pose pass's position formula (kinematics.hpp) on E.
  std::vector<Vec3<E>> p(nb);
  for (const Model::JointM& J : m.joints) {
    const auto c = static_cast<std::size_t>(J.child);
    if (J.absolute) {
      for (int r = 0; r < 3; ++r) p[c](r) = qE[static_cast<std::size_t>(J.i0 + r)];
      continue;
    }
    const Vec3<E> r_C = J.child_node >= 0 ? rC[c] : Vec3<E>(J.p_CoJ_C.cast<E>());
    if (J.parent < 0) {  // a prescribed base: its joint point is fixed in N
      p[c] = Vec3<E>(J.p_PoJ_P.cast<E>()) - R[c] * r_C;
      continue;
    }
    const auto P = static_cast<std::size_t>(J.parent);
    const Vec3<E> r_P =
        J.parent_node >= 0 || J.slides > 0 ? rP[c] : Vec3<E>(J.p_PoJ_P.cast<E>());
    p[c] = p[P] + R[P] * r_P - R[c] * r_C;
  }
  std::vector<Vec3<E>> F_g(nb, Vec3<E>::Zero()), M_g(nb, Vec3<E>::Zero());
  if (m.gravity) {
    const Environment& env = m.environment;
    OrbitFrame of;
    double n2 = 0;
    if (m.orbit) {
      of = orbit_frame(env, t);
      n2 = of.n * of.n;
    }
    const Vec3<E> z = of.zenith_N.cast<E>();
    for (std::size_t b = 0; b < nb; ++b) {
      const Model::BodyM& Bm = m.bodies[b];
      Vec3<E> F, M = Vec3<E>::Zero();
      auto tidal = [&](const Vec3<E>& v) { return Vec3<E>(n2 * Vec3<E>(3.0 * z.dot(v) * z - v)); };
      if (Bm.flex >= 0) {
        // gravity.cpp's flexible body: F at Bo, M about it, Q on its own eta'.
        const FlexB& fb = flexB[b];
        const FlexInvariants& f = m.flex[static_cast<std::size_t>(Bm.flex)];
        const Vec3<E> s_N = R[b] * fb.s;
        const auto e0 = static_cast<std::size_t>(Bm.e0);
        if (m.orbit) {
          const Vec3<E> rho = p[b] - Vec3<E>(m.p_NoO_N.cast<E>());
          const Vec3<E> Trho = tidal(rho);
          F = Bm.mass * Trho + tidal(s_N);
          const Vec3<E> z_B = transpose_times(R[b], z);
          const Vec3<E> Iz = R[b] * Vec3<E>(fb.I_w * z_B);
          const Vec3<E> Jz = R[b] * Vec3<E>(const_times(f.J, z_B));
          M = s_N.cross(Trho) + 3.0 * n2 * Vec3<E>(z.cross(Iz)) +
              (m.gg_sign - 1.0) * 3.0 * n2 * Vec3<E>(z.cross(Jz));
          const Vec3<E> Trho_B = transpose_times(R[b], Trho);
          for (std::size_t c = 0; c < fb.ds.size(); ++c) {
            const Mat3<E>& dI = fb.dI[c];
            N[e0 + c] += Trho_B.dot(fb.ds[c]) +
                         0.5 * n2 * (dI.trace() - 3.0 * z_B.dot(Vec3<E>(dI * z_B)));
          }
        } else {
          const Vec3<E> g = env.g_N.cast<E>();
          F = Bm.mass * g;
          M = s_N.cross(g);
          const Vec3<E> g_B = transpose_times(R[b], g);
          for (std::size_t c = 0; c < fb.S1.size(); ++c) N[e0 + c] += fb.S1[c].dot(g_B);
        }
      } else if (m.orbit) {
        const Vec3<E> rho = p[b] - Vec3<E>(m.p_NoO_N.cast<E>());
        F = Bm.mass * tidal(rho);
        const Vec3<E> Iz = R[b] * Vec3<E>(const_times(Bm.I_BBo_B, transpose_times(R[b], z)));
        M = m.gg_sign * 3.0 * n2 * Vec3<E>(z.cross(Iz));
      } else {
        F = Bm.mass * env.g_N.cast<E>();
      }
      F_g[b] = F;
      M_g[b] = M;
      const Vec3<E> F_B = transpose_times(R[b], F), M_B = transpose_times(R[b], M);
      for (std::size_t i = 0; i < un; ++i) N[i] += Xw[b][i].dot(M_B) + Xv[b][i].dot(F_B);
    }
  }
  // Abar^T N (Abar is block diagonal).
  std::vector<E> rhs = N;
  for (std::size_t set = 0; set < ns; ++set) {
    const auto i0 = static_cast<std::size_t>(m.euler_sets[set].i0);
    for (int c = 0; c < 3; ++c) {
      E sum(0.0);
      for (int r = 0; r < 3; ++r) sum += A[set](r, c) * N[i0 + static_cast<std::size_t>(r)];
      rhs[i0 + static_cast<std::size_t>(c)] = sum;
    }
  }
  // - (d Mbar/dt) q*' + 1/2 q*'^T (dMbar/dq*_k) q*' - dV/dq*_k.
  for (std::size_t kd = 0; kd < un; ++kd) {
    const int kk = static_cast<int>(kd);
    E quad(0.0);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        quad += qd[static_cast<std::size_t>(i)] * dMbar[kd](i, j) * qd[static_cast<std::size_t>(j)];
    E mdot(0.0);
    for (std::size_t l = 0; l < un; ++l) {
      E row(0.0);
      for (int j = 0; j < n; ++j) row += dMbar[l](kk, j) * qd[static_cast<std::size_t>(j)];
      mdot += row * qd[l];
    }
    rhs[kd] += 0.5 * quad - mdot - dV[kd];
  }
  // Prescribed coordinates c: q*''_c = theta''(t) known (Abar is 1 there), the free block solves
  // Mbar_ff q*''_f = rhs_f - Mbar_fc theta'' (solve.cpp; docs/prescribed-motion.md).
  std::vector<E> qdd(un, E(0.0));
  std::vector<bool> known(un, false);
  for (int j : m.prescribed_joints) {
    const Model::JointM& J = m.joints[static_cast<std::size_t>(j)];
    known[static_cast<std::size_t>(J.i0)] = true;
    qdd[static_cast<std::size_t>(J.i0)] = E(J.motion.accel(t));
  }
  std::vector<int> fr;
  for (int i = 0; i < n; ++i)
    if (!known[static_cast<std::size_t>(i)]) fr.push_back(i);
  const int nf = static_cast<int>(fr.size());
  MatE Mff(nf);
  std::vector<E> bff(static_cast<std::size_t>(nf));
  for (int a = 0; a < nf; ++a) {
    const int i = fr[static_cast<std::size_t>(a)];
    E b = rhs[static_cast<std::size_t>(i)];
    for (int c = 0; c < n; ++c)
      if (known[static_cast<std::size_t>(c)]) b -= Mbar(i, c) * qdd[static_cast<std::size_t>(c)];
    bff[static_cast<std::size_t>(a)] = b;
    for (int c = 0; c < nf; ++c) Mff(a, c) = Mbar(i, fr[static_cast<std::size_t>(c)]);
  }
  if (!solve_in_place(Mff, bff)) return false;
  for (int a = 0; a < nf; ++a)
    qdd[static_cast<std::size_t>(fr[static_cast<std::size_t>(a)])] = bff[static_cast<std::size_t>(a)];
  // pi'' = Abar q*'' + (d Abar/dt) q*'.
  std::vector<E> ud = qdd;
  for (std::size_t set = 0; set < ns; ++set) {
    const auto i0 = static_cast<std::size_t>(m.euler_sets[set].i0);
    Mat3<E> Adot = Mat3<E>::Zero();
    for (std::size_t l = 0; l < un; ++l) Adot += dA[l][set] * qd[l];
    for (int r = 0; r < 3; ++r) {
      E sum(0.0);
      for (int c = 0; c < 3; ++c) {
        const auto ic = i0 + static_cast<std::size_t>(c);
        sum += A[set](r, c) * qdd[ic] + Adot(r, c) * qd[ic];
      }
      ud[i0 + static_cast<std::size_t>(r)] = sum;
    }
  }

  // Per body the twist xi = Xi pi' and its rate xi' = Xi pi'' + (dXi/dt) pi' (outputs.cpp).
  out.w.assign(nb, Vec3<E>::Zero());
  out.v = out.wd = out.vd = out.w;
  for (std::size_t b = 0; b < nb; ++b) {
    Vec3<E> xw = Vec3<E>::Zero(), xv = xw, xwd = xw, xvd = xw;
    for (std::size_t i = 0; i < un; ++i) {
      xw += Xw[b][i] * uE[i];
      xv += Xv[b][i] * uE[i];
      xwd += Xw[b][i] * ud[i];
      xvd += Xv[b][i] * ud[i];
      for (std::size_t l = 0; l < un; ++l) {
        const E rate = qd[l] * uE[i];
        xwd += dXw[l][b][i] * rate;
        xvd += dXv[l][b][i] * rate;
      }
    }
    out.w[b] = xw;
    out.v[b] = xv;
    out.wd[b] = xwd;
    out.vd[b] = xvd;
  }
  // A prescribed coordinate c's torque: its row of Lagrange's equations in q* (Abar is 1 there, so
  // the row is the Boltzmann-Hamel form's, solve.cpp), tau_c = Mbar_c. q*'' - rhs_c.
  out.torque.assign(m.prescribed_joints.size(), E(0.0));
  for (std::size_t kp = 0; kp < m.prescribed_joints.size(); ++kp) {
    const int c = m.joints[static_cast<std::size_t>(m.prescribed_joints[kp])].i0;
    E tau = -rhs[static_cast<std::size_t>(c)];
    for (int i = 0; i < n; ++i) tau += Mbar(c, i) * qdd[static_cast<std::size_t>(i)];
    out.torque[kp] = tau;
  }
  // T = 1/2 pi'^T M pi' = 1/2 q*'^T Mbar q*'; V the springs' and elastic potential (energy.hpp).
  E T(0.0);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      T += qd[static_cast<std::size_t>(i)] * Mbar(i, j) * qd[static_cast<std::size_t>(j)];
  out.T = 0.5 * T;
  out.V = potential_energy_of(m, chart, qE.data());
  std::vector<Vec3<E>> r_C(nb);
  for (const Model::JointM& J : m.joints) {
    const auto c = static_cast<std::size_t>(J.child);
    r_C[c] = J.child_node >= 0 ? rC[c] : Vec3<E>(J.p_CoJ_C.cast<E>());
  }
  out.q = std::move(qE);
  out.u = std::move(uE);
  out.qd = std::move(qd);
  out.qdd = std::move(qdd);
  out.ud = std::move(ud);
  out.R = std::move(R);
  out.p = std::move(p);
  out.r_C = std::move(r_C);
  out.F_g = std::move(F_g);
  out.M_g = std::move(M_g);
  return true;
}

}  // namespace tangent

// pack(s) into xs, and the variation of the full (q*, pi') along ds that pack() gives (the header
// comment): dxf, 2n values (the zero-linear-momentum base velocity's variation excepted: Core's).
// Leaves the charts pack() chose in the workspace.
void LagrangeEngine::pack_tangent(const TreeState& s, const TreeTangent& ds, const char* caller,
                                  double* xs, std::vector<double>& dxf) {
  const Model& m = *model_;
  if (ds.joints.size() != m.joints.size())
    throw InputError(std::string("engine lagrange: ") + caller + "() got a tangent with " +
                     std::to_string(ds.joints.size()) + " joints for a system with " +
                     std::to_string(m.joints.size()));
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const Model::BodyM& Bm = m.bodies[b];
    if (Bm.flex < 0) continue;
    if (b >= ds.eta.size() || b >= ds.eta_rate.size() || ds.eta[b].size() != Bm.nm ||
        ds.eta_rate[b].size() != Bm.nm)
      throw InputError(std::string("engine lagrange: ") + caller + "() got a tangent without the " +
                       std::to_string(Bm.nm) + " modal variations of flexible body '" + Bm.name +
                       "'");
  }
  pack(s, xs);
  const int n = m.n;
  const auto un = static_cast<std::size_t>(n);
  // pack()'s full (q*, pi'): a prescribed joint at its profile's t = 0 (pack() is at t = 0).
  const double* x = expand(0.0, xs);
  const int* chart = ws_->chart.data();
  dxf.assign(2 * un, 0.0);
  double* dq = dxf.data();
  double* du = dxf.data() + n;
  auto B_of = [&](int set) {
    const int i0 = m.euler_sets[static_cast<std::size_t>(set)].i0;
    const EulerSequence& seq = kSequences[static_cast<std::size_t>(chart[set])];
    return Eigen::Matrix3d(euler_rate_matrix(seq, x[i0 + 1], x[i0 + 2]).inverse());
  };
  for (std::size_t j = 0; j < m.joints.size(); ++j) {
    const Model::JointM& J = m.joints[j];
    const TreeTangent::JointTangent& jt = ds.joints[j];
    if (J.prescribed) continue;  // it follows its profile: no variation
    double* q = dq + J.i0;
    double* u = du + J.i0;
    if (J.absolute) {
      const Eigen::Vector3d da_set = B_of(J.euler_set) * ds.dtheta_B;
      for (int i = 0; i < 3; ++i) {
        q[i] = ds.dp_NoBo_N(i);
        q[3 + i] = da_set(i);
        u[i] = ds.dv_NBo_N(i);
        u[3 + i] = ds.dw_NB_B(i);
      }
    } else if (J.relative_euler) {
      const Eigen::Vector3d da_set = B_of(J.euler_set) * jt.dtheta_J;
      for (int i = 0; i < 3; ++i) {
        q[i] = da_set(i);
        u[i] = jt.w_PC_C(i);
      }
    } else {
      // Scalar coordinates (revolute, prismatic: angle; universal: angle, angle2; fixed: none).
      if (J.dof > 0) {
        q[0] = jt.angle;
        u[0] = jt.rate;
      }
      if (J.dof > 1) {
        q[1] = jt.angle2;
        u[1] = jt.rate2;
      }
    }
  }
  for (const Model::BodyM& Bm : m.bodies) {  // modal coordinates and rates
    if (Bm.flex < 0) continue;
    const auto b = static_cast<std::size_t>(&Bm - m.bodies.data());
    for (int c = 0; c < Bm.nm; ++c) {
      dq[Bm.e0 + c] = ds.eta[b](c);
      du[Bm.e0 + c] = ds.eta_rate[b](c);
    }
  }
  const Model::JointM& J0 = m.joints[0];
  if (!m.zero_linear_momentum || J0.translations == 0) return;
  // Zero linear momentum: pack()'s base velocity is -P_rest / m_total, P_rest the linear momentum
  // of the other quasi-velocities (outputs.cpp body_momenta: R_NB h_v per body) at pack()'s own
  // state (a prescribed joint at its profile's t = 0), so its variation is that of -P_rest /
  // m_total along (dq, du): the pose pass on E and the twists of the unit seeds (P_rest is linear
  // in pi'), the flexible bodies' h_v = m v + w x s + S1 eta' by flex_momentum on E.
  using tangent::E;
  const std::size_t nb = m.bodies.size();
  Kin<E> k;
  k.resize(m);
  std::vector<E> uE(un);
  for (std::size_t i = 0; i < un; ++i) {
    k.q[i] = tangent::seeded(x[i], dq[i]);
    uE[i] = tangent::seeded(x[un + i], du[i]);
  }
  pose_pass(m, chart, k, true);
  std::vector<Vec3<E>> wb(nb, Vec3<E>::Zero()), vb(nb, Vec3<E>::Zero());
  std::vector<double> seed(un, 0.0);
  for (int i = 0; i < n; ++i) {
    if (i >= J0.i0 && i < J0.i0 + J0.translations) continue;
    const auto ui = static_cast<std::size_t>(i);
    seed[ui] = 1.0;
    twist_pass(m, k, seed.data(), m.all_joints);
    seed[ui] = 0.0;
    for (std::size_t b = 0; b < nb; ++b) {
      wb[b] += k.w_NB_B[b] * uE[ui];
      vb[b] += k.v_NBo_B[b] * uE[ui];
    }
  }
  Vec3<E> P = Vec3<E>::Zero();
  for (std::size_t b = 0; b < nb; ++b) {
    const Model::BodyM& Bm = m.bodies[b];
    Vec3<E> hv = Bm.mass * vb[b];
    if (Bm.flex >= 0) {
      Vec3<E> hw;
      flex_momentum(m.flex[static_cast<std::size_t>(Bm.flex)], k.fi[b], wb[b], vb[b],
                    uE.data() + Bm.e0, hw, hv, static_cast<E*>(nullptr));
    }
    P += Vec3<E>(k.R_NB[b] * hv);
  }
  for (int a = 0; a < J0.translations; ++a) du[J0.i0 + a] = -P(a).d[0] / m.total_mass;
}

bool LagrangeEngine::accelerations_tangent(double t, const TreeState& s, const TreeTangent& ds,
                                           TreeAccel& a, TreeAccel& da) {
  using tangent::E;
  const Model& m = *model_;
  if (!m.tangent) return false;
  // pack() chooses the charts and records the last accepted state (after_step()): both are put
  // back on the way out, so a run's engine is left as it was.
  const tangent::Restore<Workspace> restore(*ws_);
  const int n = m.n;
  const auto un = static_cast<std::size_t>(n);
  std::vector<double> xs(static_cast<std::size_t>(state_size())), dxf;
  pack_tangent(s, ds, "accelerations_tangent", xs.data(), dxf);
  TreeAccel a0;
  accelerations(t, xs.data(), a0);
  const double* xf = expand(t, xs.data());
  std::vector<E> qE(un), uE(un);
  for (std::size_t i = 0; i < un; ++i) {
    qE[i] = tangent::seeded(xf[i], dxf[i]);
    uE[i] = tangent::seeded(xf[un + i], dxf[un + i]);
  }
  tangent::Core c;
  if (!tangent::evaluate(m, t, ws_->chart.data(), std::move(qE), std::move(uE), c))
    return false;

  // The accelerations (outputs.cpp): per body wdot = xi'_w, a_NBo_N = R_NB (xi'_v + w x v); per
  // joint its unit's share of pi''.
  const std::size_t nb = m.bodies.size(), nj = m.joints.size();
  TreeAccel av = a0, dav = a0;
  const auto variation = [](const Vec3<E>& v) { return Eigen::Vector3d(v(0).d[0], v(1).d[0], v(2).d[0]); };
  const auto value = [](const Vec3<E>& v) { return Eigen::Vector3d(v(0).v, v(1).v, v(2).v); };
  for (std::size_t b = 0; b < nb; ++b) {
    const Vec3<E> acc = c.R[b] * Vec3<E>(c.vd[b] + c.w[b].cross(c.v[b]));
    av.wdot_NB_B[b] = value(c.wd[b]);
    dav.wdot_NB_B[b] = variation(c.wd[b]);
    av.a_NBo_N[b] = value(acc);
    dav.a_NBo_N[b] = variation(acc);
    const Model::BodyM& Bm = m.bodies[b];
    if (Bm.flex >= 0) {
      av.eta_ddot[b].resize(Bm.nm);
      dav.eta_ddot[b].resize(Bm.nm);
      for (int k = 0; k < Bm.nm; ++k) {
        av.eta_ddot[b](k) = c.ud[static_cast<std::size_t>(Bm.e0 + k)].v;
        dav.eta_ddot[b](k) = c.ud[static_cast<std::size_t>(Bm.e0 + k)].d[0];
      }
    }
  }
  Eigen::VectorXd ud_value(n), ud_variation(n);
  for (int i = 0; i < n; ++i) {
    ud_value(i) = c.ud[static_cast<std::size_t>(i)].v;
    ud_variation(i) = c.ud[static_cast<std::size_t>(i)].d[0];
  }
  for (std::size_t j = 0; j < nj; ++j) {
    const Model::JointM& J = m.joints[j];
    J.unit->accelerations(av, j, ud_value, J.i0);
    J.unit->accelerations(dav, j, ud_variation, J.i0);
  }

  // The value parts are accelerations()'s to rounding: otherwise something here is not what
  // rhs() solves, and no variation is returned (the caller differentiates numerically).
  double scale = 0.0, diff = 0.0;
  auto compare = [&](double x0, double x1) {
    scale = std::max(scale, std::abs(x0));
    diff = std::max(diff, std::abs(x0 - x1));
  };
  for (std::size_t b = 0; b < nb; ++b) {
    for (int r = 0; r < 3; ++r) {
      compare(a0.wdot_NB_B[b](r), av.wdot_NB_B[b](r));
      compare(a0.a_NBo_N[b](r), av.a_NBo_N[b](r));
    }
    if (a0.eta_ddot[b].size() != av.eta_ddot[b].size()) return false;
    for (Eigen::Index k = 0; k < a0.eta_ddot[b].size(); ++k)
      compare(a0.eta_ddot[b](k), av.eta_ddot[b](k));
  }
  for (std::size_t j = 0; j < nj; ++j) {
    compare(a0.angle_ddot[j], av.angle_ddot[j]);
    compare(a0.angle2_ddot[j], av.angle2_ddot[j]);
    for (int r = 0; r < 3; ++r) compare(a0.wdot_PC_C[j](r), av.wdot_PC_C[j](r));
  }
  if (!(diff <= 1e-8 * scale + 1e-12)) return false;
  a = a0;
  da = dav;
  return true;
}

// rhs_tangent: xdot = rhs(t, x) and its variation along dx in the state's own coordinates (the
// free q*, pi'; a prescribed joint's coordinates follow their profile, no variation), in the
// workspace's current charts, as rhs() finds them. The Euler-angle form on E (Core) differentiates
// the same equations rhs() solves in Boltzmann-Hamel form; q*' = B(q*) pi' on E directly. Any dx:
// the Lagrange engine's coordinates carry no constraint and no unit norm.
bool LagrangeEngine::rhs_tangent(double t, const double* x, const double* dx, double* xdot,
                                 double* dxdot) {
  using tangent::E;
  const Model& m = *model_;
  if (!m.tangent) return false;
  const int n = m.n, nf = m.nf;
  const auto un = static_cast<std::size_t>(n);
  std::vector<double> f(static_cast<std::size_t>(2 * nf));
  rhs(t, x, f.data());
  const double* xf = expand(t, x);
  std::vector<E> qE(un), uE(un);
  for (std::size_t i = 0; i < un; ++i) {
    qE[i] = E(xf[i]);
    uE[i] = E(xf[un + i]);
  }
  for (int a = 0; a < nf; ++a) {
    const auto i = static_cast<std::size_t>(m.free_index[static_cast<std::size_t>(a)]);
    qE[i].d[0] = dx[a];
    uE[i].d[0] = dx[nf + a];
  }
  tangent::Core c;
  if (!tangent::evaluate(m, t, ws_->chart.data(), std::move(qE), std::move(uE), c))
    return false;
  std::vector<double> df(f.size());
  double scale = 0.0, diff = 0.0;
  for (int a = 0; a < nf; ++a) {
    const auto i = static_cast<std::size_t>(m.free_index[static_cast<std::size_t>(a)]);
    const auto qa = static_cast<std::size_t>(a), ua = static_cast<std::size_t>(nf + a);
    df[qa] = c.qd[i].d[0];
    df[ua] = c.ud[i].d[0];
    scale = std::max({scale, std::abs(f[qa]), std::abs(f[ua])});
    diff = std::max({diff, std::abs(f[qa] - c.qd[i].v), std::abs(f[ua] - c.ud[i].v)});
  }
  // The value parts are rhs()'s to rounding (as in accelerations_tangent()).
  if (!(diff <= 1e-8 * scale + 1e-12)) return false;
  std::copy(f.begin(), f.end(), xdot);
  std::copy(df.begin(), df.end(), dxdot);
  return true;
}

}  // namespace crossdyn::lagrange
