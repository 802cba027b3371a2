// Flexible (modal) bodies for the Lagrange engine (internal header: included only by
// formulations/lagrange/*.cpp and tests/lagrange).
//
// The model is docs/flexible-bodies.md (system.hpp, FlexBody): nodes i with mass m_i, undeformed
// position p_i from the body origin Bo, rigid inertia J_i, mode shapes Phi_i and slopes Psi_i
// (3 x n), modal coordinates eta with rates eta'. In body components, with v = v_NBo_B and w = w_NB_B,
//   r_i = p_i + Phi_i eta,   v_i = v + w x r_i + Phi_i eta'                (reference paper Eq. (3))
//   T_B = 1/2 sum_i m_i |v_i|^2 + 1/2 sum_i w . J_i w                     (exact, nothing dropped)
// T_B is a quadratic form in the body's quasi-velocities xi = (w, v, eta') (Meirovitch 1991,
// "Hybrid state equations of motion for flexible bodies in terms of quasi-coordinates", J. Guidance
// 14(5): T of a flexible body in the body-axes translational and angular velocities and the elastic
// rates; Meirovitch 1970, Sec. 4.x, Lagrange's equations in quasi-coordinates): T_B = xi . h / 2
// with the generalised momentum h = M_B(eta) xi, expanded here term by term:
//   h_w = dT/dw   = I_w(eta) w + s(eta) x v + H(eta) eta'
//   h_v = dT/dv   = w x s(eta) + m v + S1 eta'
//   h_e = dT/deta' = H(eta)^T w + S1^T v + M_ee eta'
// with
//   m       = sum m_i                              s(eta) = sum m_i r_i = s0 + S1 eta
//   S1      = sum m_i Phi_i                        s0     = sum m_i p_i   (0 to rounding)
//   Q(eta)  = sum m_i r_i r_i^T = P2 + sum_k eta_k (C_k + C_k^T) + sum_kl eta_k eta_l D_kl
//   I_w     = tr(Q) 1 - Q + J                      (= sum m_i (|r_i|^2 1 - r_i r_i^T) + sum J_i)
//   H(eta)  = sum m_i [r_i x] Phi_i = Hp + sum_k eta_k H_k     (column l of H_k: sum m_i Phi_ik x Phi_il)
//   M_ee    = sum m_i Phi_i^T Phi_i
// and the node sums P2 = sum m_i p_i p_i^T, C_k = sum m_i p_i Phi_ik^T, D_kl = sum m_i Phi_ik Phi_il^T,
// J = sum J_i, Hp = sum m_i [p_i x] Phi_i. These modal inertia invariants are computed once from the
// nodes (FlexInvariants), so evaluating T_B, h or M_B costs O(n^2) and does not depend on the number
// of nodes. The functions are templated on the scalar so that the engine's dual numbers
// (autodiff.hpp) differentiate through them.
//
// Geometric stiffening (docs/flexible-bodies.md "Geometric stiffening"; Kane, Ryan and Banerjee
// 1987, Eq. (8); Sharf 1995): u_i = Phi_i eta + e_i w_i, w_i = 1/2 eta^T G_i eta, so
//   r_i = p_i + Phi_i eta + e_i w_i,   du_i/dt = Pt_i(eta) eta',   Pt_i = Phi_i + e_i (G_i eta)^T
// (G_i symmetric). T_B keeps the form above with S1, H and M_ee now eta-dependent:
//   s = sum m_i r_i,  Q = sum m_i r_i r_i^T,  S1(eta) = sum m_i Pt_i,
//   H(eta) = sum m_i [r_i x] Pt_i,  M_ee(eta) = sum m_i Pt_i^T Pt_i,
// exact (no term dropped). These are summed over the nodes at every evaluation (flex_inertia:
// O(nodes n^2)); the invariants above stay for the linear model (FlexBody::geometric_stiffening
// false), whose arithmetic is unchanged.
//
// A node frame turns from the body frame by E = exp([psi x]), psi = Psi_i eta (exact: orthonormal
// for any eta), and its angular velocity relative to the body is Jl(psi) psi' in body components,
// Jl the left Jacobian of SO(3) (Barfoot, "State Estimation for Robotics", 2017, Sec. 7.1.3 for the
// Rodrigues form of exp, Sec. 7.1.5 for Jl):
//   E  = cos t 1 + (sin t / t) [psi x] + ((1 - cos t) / t^2) psi psi^T,               t = |psi|
//   Jl = (1 - (t - sin t) / t) 1 + ((1 - cos t) / t^2) [psi x] + ((t - sin t) / t^3) psi psi^T
// (from E = 1 + a1 [psi x] + a2 [psi x]^2, Jl = 1 + a2 [psi x] + a3 [psi x]^2 and
// [psi x]^2 = psi psi^T - t^2 1). The coefficients are functions of t^2; below t = 1 rad their
// Taylor series in t^2 are used (exact to rounding there, free of the closed forms' cancellation,
// and differentiable at psi = 0, where t = sqrt(t^2) is not).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <vector>

#include "core/system.hpp"
#include "formulations/lagrange/autodiff.hpp"

namespace crossdyn::lagrange {

// ------------------------------------------------------------------------------------------------
// The rotation vector: exp([psi x]) and its left Jacobian.
// ------------------------------------------------------------------------------------------------
inline constexpr double kRotvecSeriesT2 = 1.0;  // series below t^2 = 1 (t = 1 rad)

// 1 / j! for j = 0 .. 25.
inline constexpr std::array<double, 26> kInverseFactorials = [] {
  std::array<double, 26> r{};
  double f = 1.0;
  r[0] = 1.0;
  for (std::size_t j = 1; j < r.size(); ++j) {
    f *= static_cast<double>(j);
    r[j] = 1.0 / f;
  }
  return r;
}();

// a1 = sin t / t, a2 = (1 - cos t) / t^2, a3 = (t - sin t) / t^3 and c = cos t for t2 = t^2.
// Below t = 1 the series a1 = sum_k (-t2)^k / (2k+1)!, a2 = sum_k (-t2)^k / (2k+2)!,
// a3 = sum_k (-t2)^k / (2k+3)! (Abramowitz & Stegun 4.3.65-66), k <= 10: the first term left out
// is below 4e-23, and c = 1 - t2 a2 is an identity. Above, the closed forms lose at most
// 6 eps / t^2 to cancellation (a3) and its derivative about 30 eps: both below 1e-14 there.
template <class S>
void rotvec_coefficients(const S& t2, S& c, S& a1, S& a2, S& a3) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  if (value_of(t2) < kRotvecSeriesT2) {
    constexpr int kTerms = 10;
    const auto& f = kInverseFactorials;
    const S x = -t2;  // Horner in x, from k = kTerms down to 0
    a1 = S(f[2 * kTerms + 1]);
    a2 = S(f[2 * kTerms + 2]);
    a3 = S(f[2 * kTerms + 3]);
    for (int k = kTerms - 1; k >= 0; --k) {
      a1 = a1 * x + f[static_cast<std::size_t>(2 * k + 1)];
      a2 = a2 * x + f[static_cast<std::size_t>(2 * k + 2)];
      a3 = a3 * x + f[static_cast<std::size_t>(2 * k + 3)];
    }
    c = 1.0 - t2 * a2;
    return;
  }
  const S t = sqrt(t2);
  const S s = sin(t), h = sin(0.5 * t);
  c = cos(t);
  a1 = s / t;
  a2 = 2.0 * h * h / t2;  // 1 - cos t = 2 sin^2(t/2): no cancellation
  a3 = (t - s) / (t2 * t);
}

// E = exp([psi x]) and, when Jl is not null, the left Jacobian Jl(psi) (header comment).
template <class S>
void rotvec_exp(const Vec3<S>& psi, Mat3<S>& E, Mat3<S>* Jl) {
  const S t2 = psi.squaredNorm();
  S c, a1, a2, a3;
  rotvec_coefficients(t2, c, a1, a2, a3);
  for (int r = 0; r < 3; ++r)
    for (int col = 0; col < 3; ++col) E(r, col) = a2 * psi(r) * psi(col);
  for (int r = 0; r < 3; ++r) E(r, r) += c;
  const Vec3<S> p1 = a1 * psi;
  E(0, 1) -= p1.z();
  E(1, 0) += p1.z();
  E(0, 2) += p1.y();
  E(2, 0) -= p1.y();
  E(1, 2) -= p1.x();
  E(2, 1) += p1.x();
  if (Jl == nullptr) return;
  Mat3<S>& L = *Jl;
  const S d = 1.0 - a3 * t2;
  for (int r = 0; r < 3; ++r)
    for (int col = 0; col < 3; ++col) L(r, col) = a3 * psi(r) * psi(col);
  for (int r = 0; r < 3; ++r) L(r, r) += d;
  const Vec3<S> p2 = a2 * psi;
  L(0, 1) -= p2.z();
  L(1, 0) += p2.z();
  L(0, 2) += p2.y();
  L(2, 0) -= p2.y();
  L(1, 2) -= p2.x();
  L(2, 1) += p2.x();
}

// ------------------------------------------------------------------------------------------------
// Modal inertia invariants of one flexible body (header comment), from its nodes.
// ------------------------------------------------------------------------------------------------
struct FlexInvariants {
  int n = 0;                   // modes
  double m = 0;                // sum m_i
  Eigen::Vector3d s0;          // sum m_i p_i
  Eigen::Matrix3Xd S1;         // sum m_i Phi_i                          3 x n
  std::array<double, 6> P2{};  // sum m_i p_i p_i^T, upper triangle xx xy xz yy yz zz
  std::vector<std::array<double, 6>> C;  // per k: C_k + C_k^T, upper triangle
  std::vector<std::array<double, 6>> D;  // per k <= l (index k n + l): D_kl + D_lk (k < l), D_kk
  Eigen::Matrix3d J;                     // sum J_i (plus the test inertia scaling, below)
  Eigen::Matrix3Xd Hp;                   // sum m_i [p_i x] Phi_i                 3 x n
  Eigen::Matrix3Xd Hk;                   // column k n + l: sum m_i Phi_ik x Phi_il   3 x n^2
  Eigen::MatrixXd Mee;                   // sum m_i Phi_i^T Phi_i                 n x n
  Eigen::MatrixXd K;                     // modal stiffness, symmetric part        n x n
  Eigen::MatrixXd Dmp;                   // modal damping as given                 n x n
  // Geometric stiffening: the nodes themselves (header comment), summed at every evaluation.
  struct StiffNode {
    double m = 0;
    Eigen::Vector3d p, e;   // p_BoNi_B, e_i (body frame)
    Eigen::Matrix3Xd Phi;   // 3 x n
    Eigen::MatrixXd G;      // n x n symmetric
  };
  bool stiff = false;
  std::vector<StiffNode> nodes;

  // inertia_scale multiplies the body's rigid inertia about Bo (EngineOptions::test_inertia_scale):
  // J gains (scale - 1) times the undeformed rigid inertia.
  FlexInvariants(const FlexBody& f, double inertia_scale);
  // The undeformed rigid inertia about Bo, sum (J_i + m_i (|p_i|^2 1 - p_i p_i^T)).
  Eigen::Matrix3d rigid_inertia() const;
  // M_B at eta = 0, (6 + n) x (6 + n), rows and columns (w, v, eta').
  Eigen::MatrixXd mass_matrix_at_rest() const;
};

// The eta-dependent parts of M_B(eta): I_w, s and H (header comment).
template <class S>
struct FlexInertia {
  Mat3<S> I_w;
  Vec3<S> s;
  Eigen::Matrix<S, 3, Eigen::Dynamic> H;  // 3 x n, sized once (resize)
  // Geometric stiffening only: S1(eta), M_ee(eta) (header comment) and scratch G_i eta.
  bool stiff = false;
  Eigen::Matrix<S, 3, Eigen::Dynamic> S1;
  Eigen::Matrix<S, Eigen::Dynamic, Eigen::Dynamic> Mee;
  std::vector<S> Ge;
  void resize(int n, bool stiffening = false) {
    H.resize(3, n);
    stiff = stiffening;
    if (!stiff) return;
    S1.resize(3, n);
    Mee.resize(n, n);
    Ge.assign(static_cast<std::size_t>(n), S(0.0));
  }
};

// Geometric stiffening: (eta) => I_w, s, H, S1, M_ee summed over the nodes (header comment).
template <class S>
void flex_inertia_nodes(const FlexInvariants& f, const S* eta, FlexInertia<S>& out) {
  const int n = f.n;
  std::array<S, 6> Q;
  for (auto& q : Q) q = S(0.0);
  Vec3<S> s(S(0.0), S(0.0), S(0.0));
  for (int k = 0; k < n; ++k) {
    for (int a = 0; a < 3; ++a) out.H(a, k) = out.S1(a, k) = S(0.0);
    for (int l = 0; l < n; ++l) out.Mee(k, l) = S(0.0);
  }
  for (const FlexInvariants::StiffNode& nd : f.nodes) {
    // G_i eta, w_i = 1/2 eta^T G_i eta, r_i = p_i + Phi_i eta + e_i w_i.
    S wi(0.0);
    for (int k = 0; k < n; ++k) {
      S g(0.0);
      for (int l = 0; l < n; ++l) g += nd.G(k, l) * eta[l];
      out.Ge[static_cast<std::size_t>(k)] = g;
      wi += 0.5 * eta[k] * g;
    }
    Vec3<S> r;
    for (int a = 0; a < 3; ++a) {
      S x = nd.p(a) + nd.e(a) * wi;
      for (int k = 0; k < n; ++k) x += nd.Phi(a, k) * eta[k];
      r(a) = x;
    }
    s += nd.m * r;
    Q[0] += nd.m * r(0) * r(0);
    Q[1] += nd.m * r(0) * r(1);
    Q[2] += nd.m * r(0) * r(2);
    Q[3] += nd.m * r(1) * r(1);
    Q[4] += nd.m * r(1) * r(2);
    Q[5] += nd.m * r(2) * r(2);
    // Pt_i column k = Phi_i,k + e_i (G_i eta)_k.
    for (int k = 0; k < n; ++k) {
      Vec3<S> pk;
      for (int a = 0; a < 3; ++a) pk(a) = nd.Phi(a, k) + nd.e(a) * out.Ge[static_cast<std::size_t>(k)];
      const Vec3<S> rxp = r.cross(pk);
      for (int a = 0; a < 3; ++a) {
        out.S1(a, k) += nd.m * pk(a);
        out.H(a, k) += nd.m * rxp(a);
      }
      for (int l = k; l < n; ++l) {
        S d(0.0);
        for (int a = 0; a < 3; ++a)
          d += pk(a) * (nd.Phi(a, l) + nd.e(a) * out.Ge[static_cast<std::size_t>(l)]);
        out.Mee(k, l) += nd.m * d;
      }
    }
  }
  for (int k = 0; k < n; ++k)
    for (int l = 0; l < k; ++l) out.Mee(k, l) = out.Mee(l, k);
  const S tr = Q[0] + Q[3] + Q[5];
  Mat3<S>& I = out.I_w;
  I(0, 0) = tr - Q[0] + f.J(0, 0);
  I(1, 1) = tr - Q[3] + f.J(1, 1);
  I(2, 2) = tr - Q[5] + f.J(2, 2);
  I(0, 1) = -Q[1] + f.J(0, 1);
  I(1, 0) = -Q[1] + f.J(1, 0);
  I(0, 2) = -Q[2] + f.J(0, 2);
  I(2, 0) = -Q[2] + f.J(2, 0);
  I(1, 2) = -Q[4] + f.J(1, 2);
  I(2, 1) = -Q[4] + f.J(2, 1);
  out.s = s;
}

// (eta) => I_w(eta), s(eta), H(eta). O(n^2); writes into preallocated storage.
template <class S>
void flex_inertia(const FlexInvariants& f, const S* eta, FlexInertia<S>& out) {
  if (f.stiff) {
    flex_inertia_nodes(f, eta, out);
    return;
  }
  const int n = f.n;
  std::array<S, 6> Q;
  for (std::size_t a = 0; a < 6; ++a) Q[a] = S(f.P2[a]);
  for (int k = 0; k < n; ++k) {
    const auto& Ck = f.C[static_cast<std::size_t>(k)];
    for (std::size_t a = 0; a < 6; ++a) Q[a] += eta[k] * Ck[a];
    for (int l = k; l < n; ++l) {
      const S e = eta[k] * eta[l];
      const auto& Dkl = f.D[static_cast<std::size_t>(k * n + l)];
      for (std::size_t a = 0; a < 6; ++a) Q[a] += e * Dkl[a];
    }
  }
  const S tr = Q[0] + Q[3] + Q[5];
  Mat3<S>& I = out.I_w;
  I(0, 0) = tr - Q[0] + f.J(0, 0);
  I(1, 1) = tr - Q[3] + f.J(1, 1);
  I(2, 2) = tr - Q[5] + f.J(2, 2);
  I(0, 1) = -Q[1] + f.J(0, 1);
  I(1, 0) = -Q[1] + f.J(1, 0);
  I(0, 2) = -Q[2] + f.J(0, 2);
  I(2, 0) = -Q[2] + f.J(2, 0);
  I(1, 2) = -Q[4] + f.J(1, 2);
  I(2, 1) = -Q[4] + f.J(2, 1);
  for (int a = 0; a < 3; ++a) {
    S sa(f.s0(a));
    for (int k = 0; k < n; ++k) sa += f.S1(a, k) * eta[k];
    out.s(a) = sa;
  }
  for (int l = 0; l < n; ++l)
    for (int a = 0; a < 3; ++a) {
      S h(f.Hp(a, l));
      for (int k = 0; k < n; ++k) h += eta[k] * f.Hk(a, k * n + l);
      out.H(a, l) = h;
    }
}

// h = M_B(eta) xi for xi = (w, v, ed): h_w, h_v and, when he is not null, h_e (n values). The
// modal rates ed are double on the run's path (D deduced: the same code as with double alone), or S
// when they carry a variation too (tangent.cpp, output_tangent.cpp).
template <class S, class D>
void flex_momentum(const FlexInvariants& f, const FlexInertia<S>& fi, const Vec3<S>& w,
                   const Vec3<S>& v, const D* ed, Vec3<S>& hw, Vec3<S>& hv, S* he) {
  const int n = f.n;
  const Vec3<S>& s = fi.s;
  for (int a = 0; a < 3; ++a) {
    S x = fi.I_w(a, 0) * w(0) + fi.I_w(a, 1) * w(1) + fi.I_w(a, 2) * w(2);
    S y = f.m * v(a);
    if (fi.stiff) {
      for (int k = 0; k < n; ++k) {
        x += fi.H(a, k) * ed[k];
        y += fi.S1(a, k) * ed[k];
      }
    } else {
      for (int k = 0; k < n; ++k) {
        x += fi.H(a, k) * ed[k];
        y += f.S1(a, k) * ed[k];
      }
    }
    hw(a) = x;
    hv(a) = y;
  }
  // + s x v and + w x s
  hw(0) += s(1) * v(2) - s(2) * v(1);
  hw(1) += s(2) * v(0) - s(0) * v(2);
  hw(2) += s(0) * v(1) - s(1) * v(0);
  hv(0) += w(1) * s(2) - w(2) * s(1);
  hv(1) += w(2) * s(0) - w(0) * s(2);
  hv(2) += w(0) * s(1) - w(1) * s(0);
  if (he == nullptr) return;
  if (fi.stiff) {
    for (int k = 0; k < n; ++k) {
      S x = fi.H(0, k) * w(0) + fi.H(1, k) * w(1) + fi.H(2, k) * w(2) + fi.S1(0, k) * v(0) +
            fi.S1(1, k) * v(1) + fi.S1(2, k) * v(2);
      for (int l = 0; l < n; ++l) x += fi.Mee(k, l) * ed[l];
      he[k] = x;
    }
    return;
  }
  for (int k = 0; k < n; ++k) {
    S x = fi.H(0, k) * w(0) + fi.H(1, k) * w(1) + fi.H(2, k) * w(2) + f.S1(0, k) * v(0) +
          f.S1(1, k) * v(1) + f.S1(2, k) * v(2);
    for (int l = 0; l < n; ++l) x += f.Mee(k, l) * ed[l];
    he[k] = x;
  }
}

// T_B = xi . M_B xi / 2 (he: scratch of n values).
template <class S>
S flex_kinetic_energy(const FlexInvariants& f, const FlexInertia<S>& fi, const Vec3<S>& w,
                      const Vec3<S>& v, const double* ed, S* he) {
  Vec3<S> hw, hv;
  flex_momentum(f, fi, w, v, ed, hw, hv, he);
  S T = w.dot(hw) + v.dot(hv);
  for (int k = 0; k < f.n; ++k) T += ed[k] * he[k];
  return 0.5 * T;
}

}  // namespace crossdyn::lagrange
