// The Lagrange engine's mass pass: M = d2T/dpi'2, p = dT/dpi' and (dM/dt) pi' from T's polarisation
// on the unit quasi-velocity seeds, with Dual<1> along the motion for the time derivatives
// (README.md, "Mass pass"; paper Eq. 26).
#include <cstddef>
#include <vector>

#include "core/cancel.hpp"
#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "formulations/lagrange/flex_body.hpp"
#include "formulations/lagrange/kinematics.hpp"
#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/passes.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

namespace {

// Mass pass of one flexible body b (README.md, "Mass pass"): with Y_i = (Xi_i, e_i on the body's
// own eta' block) the seed twists and xi = sum Y_i pi'_i the body's twist,
//   M_ij += Y_i . M_B Y_j,   p_i += Y_i . M_B xi,
//   (dM/dt pi')_i += Ydot_i . M_B xi + Y_i . d/dt(M_B xi)   (d/dt at fixed pi', Dual<1> parts).
void flex_mass_pass(const Model& m, LagrangeEngine::Workspace& w, std::size_t b) {
  const Model::BodyM& B = m.bodies[b];
  const FlexInvariants& f = m.flex[static_cast<std::size_t>(B.flex)];
  const std::vector<int>& sup = m.support[b];
  const auto& X = w.Xi[b];
  const auto& Xd = w.Xi_dot[b];
  const FlexInertia<Dual<1>>& fi1 = w.k1.fi[b];
  FlexInertia<double>& fi0 = w.fi0[b];
  for (int r = 0; r < 3; ++r) {
    fi0.s(r) = fi1.s(r).v;
    for (int c = 0; c < 3; ++c) fi0.I_w(r, c) = fi1.I_w(r, c).v;
    for (int k = 0; k < B.nm; ++k) fi0.H(r, k) = fi1.H(r, k).v;
    if (fi0.stiff)
      for (int k = 0; k < B.nm; ++k) fi0.S1(r, k) = fi1.S1(r, k).v;
  }
  if (fi0.stiff)
    for (int k = 0; k < B.nm; ++k)
      for (int l = 0; l < B.nm; ++l) fi0.Mee(k, l) = fi1.Mee(k, l).v;
  // The body's twist (w, v_B) and its rate at fixed pi', as Dual<1>.
  Vec3<Dual<1>> wt, vt;
  for (int a = 0; a < 3; ++a) {
    double x0 = 0, x1 = 0, d0 = 0, d1 = 0;
    for (int i : sup) {
      x0 += X(a, i) * w.u(i);
      x1 += X(3 + a, i) * w.u(i);
      d0 += Xd(a, i) * w.u(i);
      d1 += Xd(3 + a, i) * w.u(i);
    }
    wt(a) = Dual<1>(x0);
    wt(a).d[0] = d0;
    vt(a) = Dual<1>(x1);
    vt(a).d[0] = d1;
  }
  const double* ed = w.u.data() + B.e0;
  Vec3<Dual<1>> hw1, hv1;
  flex_momentum(f, fi1, wt, vt, ed, hw1, hv1, w.he1.data());
  auto own = [&B](int i) { return i >= B.e0 && i < B.e0 + B.nm; };
  for (std::size_t ii = 0; ii < sup.size(); ++ii) {
    const int i = sup[ii];
    double p = 0, pd = 0;
    for (int a = 0; a < 3; ++a) {
      p += X(a, i) * hw1(a).v + X(3 + a, i) * hv1(a).v;
      pd += Xd(a, i) * hw1(a).v + Xd(3 + a, i) * hv1(a).v + X(a, i) * hw1(a).d[0] +
            X(3 + a, i) * hv1(a).d[0];
    }
    if (own(i)) {
      p += w.he1[static_cast<std::size_t>(i - B.e0)].v;
      pd += w.he1[static_cast<std::size_t>(i - B.e0)].d[0];
    }
    w.p(i) += p;
    w.Mdot_u(i) += pd;
    // M_B Y_i, then its products with Y_j for j >= i.
    if (own(i)) w.unit(i - B.e0) = 1.0;
    const Vec3<double> wi = X.col(i).head<3>(), vi = X.col(i).tail<3>();
    Vec3<double> hw, hv;
    flex_momentum(f, fi0, wi, vi, w.unit.data(), hw, hv, w.he0.data());
    if (own(i)) w.unit(i - B.e0) = 0.0;
    for (std::size_t jj = ii; jj < sup.size(); ++jj) {
      const int j = sup[jj];
      double mij = X.col(j).head<3>().dot(hw) + X.col(j).tail<3>().dot(hv);
      if (own(j)) mij += w.he0(j - B.e0);
      w.M(i, j) += mij;
    }
  }
}


// Mass pass of one rigid body (README.md, "Mass pass"): D = diag(I_BBo_B, m 1) the body's inertia
// for the twist (w_NB_B, v_NBo_B) (paper Eq. 26), Y_i the seed twists (columns of X, 6 x n, and of
// their rates Xd), xi = sum Y_i pi'_i:
//   M_ij += Y_i . D Y_j (j >= i, upper triangle),   p_i += D Y_i . xi,
//   (dM/dt pi')_i += Ydot_i . D xi + D Y_i . xidot.
// Only the supporting columns sup are visited. With a free base (`translation`), the first three
// of sup are its translation seeds, Y_a = (0, R^T e_a) with R = R_NB of the body (its Dual<1>
// rate R'), and their rows are written in closed form instead of as inner products:
//   M_ab += m e_a . R R^T e_b = m delta_ab,       M_aj += m (R v_j)_a  (v_j: Y_j's linear part),
//   p_a += m (R v_xi)_a,                           (dM/dt pi')_a += m (R' v_xi + R v_xidot)_a,
// i.e. the N components of the seeds' linear momenta (the same bilinear form, paper Eq. 26,
// with R R^T = 1).
// The supporting columns are gathered into Y (6 x s) and their rates into Yd, then DY = D Y,
// G = Y^T D Y (s x s; its upper triangle goes into M), p_S += DY^T xi,
// (dM/dt pi')_S += Yd^T D xi + DY^T xidot. Fixed 6-row blocks, so every product is a vectorised
// 6-term inner product.
void rigid_mass_pass(const Model::BodyM& B, const std::vector<int>& sup, const double* X,
                     const double* Xd, const double* u, const Mat3<Dual<1>>& R, bool translation,
                     LagrangeEngine::Workspace& w) {
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  const int t = translation ? 3 : 0;  // sup[0..t) are the base translation seeds
  const auto s = static_cast<Eigen::Index>(sup.size()) - t;
  const int* const sr = sup.data() + t;  // the other columns
  auto Y = w.Y.leftCols(s);
  auto Yd = w.Yd.leftCols(s);
  auto DY = w.DX.leftCols(s);
  Vec6 xi = Vec6::Zero(), xid = Vec6::Zero();
  for (int k = 0; k < t; ++k) {
    const int i = sup[static_cast<std::size_t>(k)];
    xi += Eigen::Map<const Vec6>(X + 6 * i) * u[i];
    xid += Eigen::Map<const Vec6>(Xd + 6 * i) * u[i];
  }
  for (Eigen::Index k = 0; k < s; ++k) {
    const int i = sr[k];
    Y.col(k) = Eigen::Map<const Vec6>(X + 6 * i);
    Yd.col(k) = Eigen::Map<const Vec6>(Xd + 6 * i);
    xi += Y.col(k) * u[i];
    xid += Yd.col(k) * u[i];
  }
  DY.topRows<3>().noalias() = B.I_BBo_B * Y.topRows<3>();
  DY.bottomRows<3>() = B.mass * Y.bottomRows<3>();
  Vec6 Dxi;
  Dxi << B.I_BBo_B * xi.head<3>(), B.mass * xi.tail<3>();
  for (Eigen::Index a = 0; a < s; ++a) {
    const int i = sr[a];
    const auto Dya = DY.col(a);
    for (Eigen::Index b = a; b < s; ++b) w.M(i, sr[b]) += Dya.dot(Y.col(b));
    w.p(i) += Dya.dot(xi);
    w.Mdot_u(i) += Yd.col(a).dot(Dxi) + Dya.dot(xid);
  }
  if (t == 0) return;
  // The translation rows in closed form (see above); the translation seeds come first
  // in sup, so their entries are in M's upper triangle as M(a, j).
  Eigen::Matrix3d R0, R1;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      R0(r, c) = R(r, c).v;
      R1(r, c) = R(r, c).d[0];
    }
  for (int a = 0; a < 3; ++a) {
    const int ia = sup[static_cast<std::size_t>(a)];
    w.M(ia, ia) += B.mass;
  }
  for (Eigen::Index k = 0; k < s; ++k) {
    const Eigen::Vector3d Rv = R0 * DY.col(k).tail<3>();
    for (int a = 0; a < 3; ++a) w.M(sup[static_cast<std::size_t>(a)], sr[k]) += Rv(a);
  }
  const Eigen::Vector3d mv = B.mass * xi.tail<3>(), mvd = B.mass * xid.tail<3>();
  const Eigen::Vector3d pa = R0 * mv, pda = R1 * mv + R0 * mvd;
  for (int a = 0; a < 3; ++a) {
    const int ia = sup[static_cast<std::size_t>(a)];
    w.p(ia) += pa(a);
    w.Mdot_u(ia) += pda(a);
  }
}

}  // namespace

void mass_pass(const Model& m, Workspace& w, const double* x) {
  const int n = m.n;
  const int* chart = w.chart.data();
  // mass pass: Dual<1> along the motion (q* + q*' dt at fixed pi').
  for (int i = 0; i < n; ++i) {
    Dual<1>& qi = w.k1.q[static_cast<std::size_t>(i)];
    qi = Dual<1>(x[i]);
    qi.d[0] = w.qdot(i);
  }
  // The base's attitude and its rate along the motion, R_NB [w_NB_B x] (base_attitude).
  if (m.base_set >= 0) {
    const int b0 = m.euler_sets[static_cast<std::size_t>(m.base_set)].i0;
    w.R_NB0 = euler_rotation(kSequences[static_cast<std::size_t>(chart[m.base_set])], x[b0],
                             x[b0 + 1], x[b0 + 2]);
    const Mat3<Dual<1>> R_base =
        base_attitude<1>(w.R_NB0, {Eigen::Vector3d(w.u(b0), w.u(b0 + 1), w.u(b0 + 2))});
    pose_pass(m, chart, w.k1, true, &R_base);
  } else {
    pose_pass(m, chart, w.k1, true);  // a prescribed base: R_NB from its angle (pose_pass)
  }
  // Twists of the unit seeds pi' = e_i: nonzero only in the subtree of the joint of i (the
  // columns of other bodies stay zero from construction).
  w.seed.setZero();
  for (int i = 0; i < n; ++i) {
    cancel::poll();
    const Model::JointM& Ji =
        m.joints[static_cast<std::size_t>(m.coordinate_joint[static_cast<std::size_t>(i)])];
    if (i - Ji.i0 < Ji.translations) {
      // A base translation seed v_NBo_N = e_a moves every body with w = 0 and v_NBo_N = e_a
      // (twist_pass with this seed gives exactly these values: every other term is a product
      // with a zero twist or a zero rate), so its columns are filled without the pass:
      // (0, R_NB^T e_a) in body components, with the Dual<1> rate of R_NB.
      const int a0 = i - Ji.i0;
      for (int j : Ji.subtree) {
        const auto b = static_cast<std::size_t>(m.joints[static_cast<std::size_t>(j)].child);
        for (int a = 0; a < 3; ++a) {
          w.Xi[b](a, i) = 0.0;
          w.Xi_dot[b](a, i) = 0.0;
          w.Xi[b](3 + a, i) = w.k1.R_NB[b](a0, a).v;
          w.Xi_dot[b](3 + a, i) = w.k1.R_NB[b](a0, a).d[0];
        }
      }
      continue;
    }
    if (Ji.parent >= 0) {
      w.k1.w_NB_B[static_cast<std::size_t>(Ji.parent)].setZero();
      w.k1.v_NBo_B[static_cast<std::size_t>(Ji.parent)].setZero();
    }
    w.seed(i) = 1.0;
    twist_pass(m, w.k1, w.seed.data(), Ji.subtree);
    w.seed(i) = 0.0;
    for (int j : Ji.subtree) {
      const auto b = static_cast<std::size_t>(m.joints[static_cast<std::size_t>(j)].child);
      const Vec3<Dual<1>>& v = w.k1.v_NBo_B[b];
      for (int a = 0; a < 3; ++a) {
        w.Xi[b](a, i) = w.k1.w_NB_B[b](a).v;
        w.Xi[b](3 + a, i) = v(a).v;
        w.Xi_dot[b](a, i) = w.k1.w_NB_B[b](a).d[0];
        w.Xi_dot[b](3 + a, i) = v(a).d[0];
      }
    }
  }
  // T(xi, eta) = w_xi^T I w_eta + m v_xi . v_eta per rigid body: M_ij = T(e_i, e_j),
  // p = T(e_i, pi'), d/dt p at fixed pi' = T(e_i', pi') + T(e_i, pi'') with ' the Dual<1> parts.
  // Only the pi' supporting the body (its own and its ancestors' joints) contribute.
  w.M.setZero();
  w.p.setZero();
  w.Mdot_u.setZero();
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    cancel::poll();
    const Model::BodyM& B = m.bodies[b];
    const std::vector<int>& sup = m.support[b];
    const auto& X = w.Xi[b];
    const auto& Xd = w.Xi_dot[b];
    if (B.flex >= 0) {
      flex_mass_pass(m, w, b);
    } else {
      rigid_mass_pass(B, sup, X.data(), Xd.data(), w.u.data(), w.k1.R_NB[b], m.base_free, w);
    }
  }
}

}  // namespace crossdyn::lagrange
