// Torque-free rigid body in closed form (see torque_free.hpp).
//
// References:
//   [LL]   Landau & Lifshitz, Mechanics, 3rd ed., Sec. 37 (the free asymmetric top): Eqs.
//          (37.10)-(37.12) for w(t) in Jacobi functions, and the same section's Euler angles of the
//          body in the frame aligned with H (theta, psi from H_B; phi' = h (I1 w1^2 + I2 w2^2) /
//          (H1^2 + H2^2)); Sec. 35 Eq. (35.2) for the 3-1-3 Euler angles.
//   [KLL]  Kane, Likins & Levinson, Spacecraft Dynamics (1983), Sec. 3.1 (torque-free motion).
//   [DLMF] NIST Digital Library of Mathematical Functions: 22.4 Table 22.4.3 (shifts by K, 2K),
//          22.5 (k = 1: sn = tanh, cn = dn = sech), 22.6.1 (sn^2 + cn^2 = 1, k^2 sn^2 + dn^2 = 1),
//          22.7.1-22.7.3 (descending Landen transformation), 22.8.1-22.8.3 (addition theorems),
//          22.10.4-22.10.6 (small-k expansions), 19.5.1 (K for small k), 19.8.12 (Landen for K),
//          19.7.9 (Pi with characteristic alpha^2 and k^2 / alpha^2), 19.25(i), 19.25.5, 19.25.14
//          (Legendre's F and Pi as Carlson's R_F, R_C, R_J), 19.16(i) (their homogeneity).
//   [BF]   Byrd & Friedman, Handbook of Elliptic Integrals (1971): 120.01 (Jacobi functions),
//          400.01 (integral of 1/(1 - n sn^2 u) = Pi(n; am u, k)).
//
// Method, inputs => outputs. Everything is computed in long double, whose exponent range keeps
// squares and products of any finite double input (down to 5e-324) free of underflow and overflow
// and whose 64-bit significand leaves 3 guard digits over the double result; the one quantity that
// needs more (h^2 - 2E Ib) is formed in 113-bit arithmetic.
//   0. (I_BBo_B, w0) => scaled problem. Euler's equations are homogeneous: w(t) = |w0| w^(|w0| t)
//      for the body with inertia I / I_max and initial rate w0 / |w0|. Steps 2-5 work on that
//      problem (|w^0| = 1, moments in (0, 1]), so no size of |w0| or of I over- or underflows.
//   1. (I) => principal frame P = (a, b, c) of B: I = R_BP diag(Ia, Ib, Ic) R_BP^T, a right-handed
//      choice of principal axes with Ib the intermediate moment and c the axis the polhode circles
//      (c = the largest moment when D = h^2 / (2E) >= Ib, else the smallest; (e3, -e2, e1) keeps
//      the frame right-handed for c = the smallest). A diagonal inertia is taken as given (moments
//      and axes exact); any other goes through Eigen's long double eigensolver (axes to ~1e-19).
//      Moment differences are taken from the unscaled moments (exact for a diagonal inertia),
//      never from nearly equal scaled ones.
//   2. (w0) => the constants of the motion, each written as a sum of terms of one sign, so that
//      none is a difference of nearly equal numbers (the textbook forms 2E Ic - h^2, h^2 - 2E Ia,
//      Ic - D lose every digit near a principal axis). With d_ij = |I_i - I_j|:
//        P~ = |h^2 - 2E Ia| = Ib d_ba wb^2 + Ic d_ca wc^2,
//        Q~ = |2E Ic - h^2| = Ia d_ca wa^2 + Ib d_cb wb^2,
//        R~ = |h^2 - 2E Ib| = Ic d_cb wc^2 - Ia d_ba wa^2 >= 0 (the distance from the separatrix),
//      since h^2 - 2E I_j = sum_i I_i (I_i - I_j) w_i^2. R~ alone is a difference; Ib's term has
//      cancelled identically, and its two terms are formed in 113-bit arithmetic from the unscaled
//      moments and components, where they are exact for a diagonal inertia, so that its relative
//      accuracy (and that of k', K ~ ln(4 / k') and the time of every flip) does not depend on how
//      close D is to Ib. Then [LL (37.10)-(37.12)]
//        lambda^2 = d_cb P~ / (Ia Ib Ic),   k^2 = d_ba Q~ / (d_cb P~),   k'^2 = d_ca R~ / (d_cb P~),
//      the complement k'^2 = 1 - k^2 taken from R~ directly (expanding d_ba Q~ + d_ca R~ = d_cb P~
//      shows the identity); the smaller of k^2, k'^2 is used as computed and the other as its
//      complement, so that the pair is consistent and neither limit (k -> 0, k -> 1) loses digits.
//   3. (w0, t) => w(t). The solution w_a = A_a cn(u0 + v), w_b = A_b sn(u0 + v),
//      w_c = A_c dn(u0 + v), v = lambda t [LL (37.10)], expanded with the addition theorems
//      [DLMF 22.8.1-22.8.3] and written with the initial components instead of u0 and A_i:
//        w_a = (wa0 cn v - (Ic - Ib) / (Ia lambda) wb0 wc0 sn v dn v) / Delta,
//        w_b = (wb0 cn v dn v + (Ic - Ia) / (Ib lambda) wa0 wc0 sn v) / Delta,
//        w_c = (wc0 dn v - (Ib - Ia) / (Ic lambda) wa0 wb0 sn v cn v) / Delta,
//        Delta = 1 - xi sn^2 v = eta + xi cn^2 v,   xi = k^2 sn^2 u0 = Ib d_ba wb0^2 / P~,
//                                                   eta = dn^2 u0 = Ic d_ca wc0^2 / P~.
//      (The signed coefficients are Euler's equations I_a w_a' = (I_b - I_c) w_b w_c, cyclic, at
//      v = 0; their magnitudes follow from A_i, k and lambda.) So every sign comes from w0 itself:
//      no quadrant of am u0, no sign convention for a zero component, exact w(0) = w0, and one
//      formula for both sides of the separatrix and on it (k = 1). Of the two forms of Delta the
//      one without cancellation is used.
//   4. Jacobi functions of any v and parameter (k^2, k'^2): reduce v by the period 4K (IEEE
//      remainder, exact), fold into [0, K] with Table 22.4.3, and for x in (K/2, K] use
//      sn(K - y) = cn y / dn y, cn(K - y) = k' sn y / dn y, dn(K - y) = k' / dn y, so that the
//      core only sees x in [0, K/2]. The core is the descending Landen transformation
//      [DLMF 22.7.1-22.7.3] down to a modulus below 1e-6 and the small-k expansions
//      [DLMF 22.10.4-22.10.6], then back up with products and quotients of positive numbers only
//      (dn from 1 - k^2 sn^2 or k'^2 + k^2 cn^2, DLMF 22.6.1, whichever has no cancellation): each
//      of sn, cn, dn keeps its relative accuracy, also at k' = 1e-300 (about 15 levels).
//      K = (pi / 2) prod (1 + k_n) [DLMF 19.8.12, 19.5.1] from the same chain. On the separatrix
//      (k' = 0 exactly): tanh and sech [DLMF 22.5], no reduction (K is infinite).
//   5. (w(t)) => attitude. Let L be an inertial frame with z_L along H. The body's 3-1-3 Euler
//      angles in L, R_LP = Rz(phi) Rx(theta) Rz(psi), have [LL Sec. 37, (35.2)]
//        H_P / h = (sin theta sin psi, sin theta cos psi, cos theta)   (theta, psi from w(t));
//        phi'    = h (Ia w_a^2 + Ib w_b^2) / (H_a^2 + H_b^2)
//                = h / Ic + h (Ic - Ia) / (Ic Ia) / (1 + N sn^2 u),   N = Ic d_ba / (Ia d_cb) >= 0
//      (the characteristic n = -N of Pi is never positive here: there is no n -> 1 limit), so
//      with du = lambda dt [BF 400.01] and G(u) = integral_0^u du / (1 + N sn^2 u) = Pi(-N; am u, k)
//        phi(t) = h t / Ic + h (Ic - Ia) / (Ic Ia lambda) (G(u0 + v) - G(u0)).
//      G(u) = 2 j G(K) + G(r) with u = 2 j K + r, |r| <= K (sn^2 has period 2K). Two forms, each
//      free of cancellation where it is used:
//      N <= 1: G = u + N S with S(u) = -integral_0^u sn^2 du / (1 + N sn^2), so
//        phi(t) = h t / Ia + h (Ic - Ia) N / (Ic Ia lambda) (S(u0 + v) - S(u0)),
//        S(r) = -(1/3) sn^3 R_J(cn^2, dn^2, 1, 1 + N sn^2)             [DLMF 19.25.14, 19.16(i)],
//        S(K) = (Pi(-N, k) - K) / N = -(1/3) R_J(0, k'^2, 1, 1 + N)   [DLMF 19.25(i)];
//      (the linear part u of G is kept out, so that lambda t << u0, a slow polhode, loses nothing
//      in u0 + v - u0);
//      N > 1 (Ic close to Ib): G directly, with the characteristic moved to -k^2 / N by
//      DLMF 19.7.9 (Pi(alpha^2) + Pi(k^2 / alpha^2) = F + sqrt(c) R_C(...), c = csc^2 phi, written
//      homogeneously in sn, cn, dn), a sum of two positive terms:
//        G(r) = (k^2 / (3 N)) sn^3 R_J(cn^2, dn^2, 1, 1 + k^2 sn^2 / N)
//               + sn R_C(cn^2 dn^2, (1 + N sn^2) (1 + k^2 sn^2 / N)),
//        G(K) = (k^2 / (3 N)) R_J(0, k'^2, 1, 1 + k^2 / N) + (pi / 2) sqrt(N / ((1 + N) (N + k^2))).
//      (Written as u + N S, G would be a small difference of two terms of size u, and its rounding
//      error, multiplied by 1 / lambda ~ 1 / sqrt(Ic - Ib), would grow without bound.)
//      On the separatrix (k = 1, sn = tanh): G(u) = (u + sqrt(N) atan(sqrt(N) tanh u)) / (1 + N)
//      and S(u) = (atan(sqrt(N) tanh u) / sqrt(N) - u) / (1 + N), increments taken directly.
//      u0 in [-K, K] is the phase with sn^2 u0 = Ib d_cb wb0^2 / Q~, cn^2 u0 = Ia d_ca wa0^2 / Q~,
//      dn^2 u0 = eta moving the way Euler's equations move sn^2 (d(sn^2)/du = 2 sn cn dn has the
//      sign of wa0 wb0 wc0 (Ic - Ib)): u0 = +-sn u0 R_F(cn^2 u0, dn^2 u0, 1) [DLMF 19.25.5].
//      L is chosen so that phi(0) = 0: R_NB(t) = R_NB(0) R_BP R_LP(0)^T R_LP(t) R_PB, and
//      w_B(t) = w0 + R_BP (w_P(t) - w_P(0)), both exact at t = 0.
//   Steady spin (w0 exactly along a principal axis or within a plane of equal moments, including
//   the sphere and w0 = 0): w constant, R_NB(t) = R_NB(0) Rot(w0, |w0| t). Any other w0, however
//   close to an axis, takes the general path, which is exact for it (an intermediate-axis spin
//   perturbed by 1e-15 does flip over, about ln(4 / k') / lambda after the start).
#include "analytic/torque_free.hpp"

#include "core/errors.hpp"

#include <Eigen/Eigenvalues>
#include <boost/math/policies/policy.hpp>
#include <boost/math/special_functions/ellint_rc.hpp>
#include <boost/math/special_functions/ellint_rf.hpp>
#include <boost/math/special_functions/ellint_rj.hpp>
#include <boost/multiprecision/cpp_bin_float.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>

namespace crossdyn::analytic {

namespace {

using Real = long double;
using Vector3L = Eigen::Matrix<Real, 3, 1>;
using Matrix3L = Eigen::Matrix<Real, 3, 3>;
using QuaternionL = Eigen::Quaternion<Real>;

constexpr Real kPi = std::numbers::pi_v<Real>;

// Carlson's integrals report a domain error as NaN instead of throwing (the arguments are kept in
// the domain by construction; at() turns any non-finite result into a RunFailure, never an abort).
using NoThrow = boost::math::policies::policy<
    boost::math::policies::domain_error<boost::math::policies::errno_on_error>,
    boost::math::policies::pole_error<boost::math::policies::errno_on_error>,
    boost::math::policies::overflow_error<boost::math::policies::errno_on_error>,
    boost::math::policies::evaluation_error<boost::math::policies::errno_on_error>>;

Real carlson_rc(Real x, Real y) { return boost::math::ellint_rc(x, y, NoThrow()); }
Real carlson_rf(Real x, Real y, Real z) { return boost::math::ellint_rf(x, y, z, NoThrow()); }
Real carlson_rj(Real x, Real y, Real z, Real p) {
  return boost::math::ellint_rj(x, y, z, p, NoThrow());
}

// The descending Landen chain stops once k^2 is below this: the O(k^4) terms left out of
// DLMF 22.10.4-22.10.6 are then below 1e-24.
constexpr Real kSmallParameter = 1e-12L;

QuaternionL rot_z(Real angle) {
  return QuaternionL(std::cos(angle / 2), 0, 0, std::sin(angle / 2));
}
QuaternionL rot_x(Real angle) {
  return QuaternionL(std::cos(angle / 2), std::sin(angle / 2), 0, 0);
}

std::string text(double x) {
  std::ostringstream s;
  s.precision(17);
  s << x;
  return s.str();
}

struct Jacobi {
  Real sn, cn, dn;
};

// Jacobi's elliptic functions sn, cn, dn of parameter k^2 = m, given together with its complement
// m1 = 1 - m so that neither limit (k -> 0, k -> 1) loses digits. Method: see step 4 above.
class EllipticFunctions {
 public:
  EllipticFunctions() = default;
  EllipticFunctions(Real m, Real m1) : kp_(std::sqrt(m1)) {
    if (m1 == 0) {
      K_ = std::numeric_limits<Real>::infinity();
      return;
    }
    // Level 0 is the given modulus; level n + 1 has k_{n+1} = (1 - k'_n) / (1 + k'_n)
    // = k_n^2 / (1 + k'_n)^2 and k'_{n+1} = 2 sqrt(k'_n) / (1 + k'_n) [DLMF 22.7.1], both without
    // cancellation, and K(k_n) = (1 + k_{n+1}) K(k_{n+1}) [DLMF 19.8.12].
    Real k = std::sqrt(m), kp = kp_;
    levels_[0] = {k, kp};
    Real K_over_K_bottom = 1;
    while (k * k > kSmallParameter && count_ + 1 < levels_.size()) {
      const Real k1 = (k / (1 + kp)) * (k / (1 + kp));
      kp = 2 * std::sqrt(kp) / (1 + kp);
      k = k1;
      levels_[++count_] = {k, kp};
      K_over_K_bottom *= 1 + k;
    }
    K_ = kPi / 2 * (1 + k * k / 4) * K_over_K_bottom;  // [DLMF 19.5.1] at the bottom
  }

  Real K() const { return K_; }
  Real kp() const { return kp_; }

  Jacobi at(Real u) const {
    if (kp_ == 0) {  // separatrix, k = 1 [DLMF 22.5]
      const Real x = std::fabs(u);
      const Real sech = 1 / std::cosh(x);
      return {std::copysign(std::tanh(x), u), sech, sech};
    }
    const Real r = std::remainder(u, 4 * K_);  // [-2K, 2K]; period 4K [DLMF Table 22.4.3]
    Real x = std::fabs(r);
    bool negate_cn = false;
    if (x > K_) {  // sn(2K - x) = sn x, cn(2K - x) = -cn x, dn(2K - x) = dn x
      x = 2 * K_ - x;
      negate_cn = true;
    }
    Jacobi j;
    if (x > K_ / 2) {  // sn(K - y) = cd y, cn(K - y) = k' sd y, dn(K - y) = k' nd y
      const Jacobi y = core(K_ - x);
      j = {y.cn / y.dn, kp_ * y.sn / y.dn, kp_ / y.dn};
    } else {
      j = core(x);
    }
    if (r < 0) j.sn = -j.sn;  // sn odd, cn and dn even
    if (negate_cn) j.cn = -j.cn;
    return j;
  }

 private:
  struct Level {
    Real k, kp;
  };

  // 0 <= x <= K/2: every value positive (cn >= sqrt(k' / (1 + k'))).
  Jacobi core(Real x) const {
    Real z = x;
    for (std::size_t n = 1; n <= count_; ++n) z /= 1 + levels_[n].k;
    // Bottom: DLMF 22.10.4-22.10.6 with m = k^2 < 1e-12.
    const Real m = levels_[count_].k * levels_[count_].k;
    const Real s0 = std::sin(z), c0 = std::cos(z);
    const Real shift = m / 4 * (z - s0 * c0);
    Real sn = s0 - shift * c0, cn = c0 + shift * s0, dn = 1 - m / 2 * s0 * s0;
    // Up: DLMF 22.7.2, 22.7.3 from level n to n - 1; dn from DLMF 22.6.1, as 1 - k^2 sn^2 or
    // k'^2 + k^2 cn^2, whichever has no cancellation (the first gives dn(0) = 1 exactly).
    for (std::size_t n = count_; n >= 1; --n) {
      const Real k1 = levels_[n].k;
      const Real den = 1 + k1 * sn * sn;
      sn = (1 + k1) * sn / den;
      cn = cn * dn / den;
      const Real k = levels_[n - 1].k, ks2 = k * sn * k * sn;
      dn = ks2 <= 0.5L ? std::sqrt(1 - ks2) : std::hypot(levels_[n - 1].kp, k * cn);
    }
    return {sn, cn, dn};
  }

  std::array<Level, 64> levels_{};
  std::size_t count_ = 0;
  Real kp_ = 1, K_ = kPi / 2;
};

}  // namespace

struct TorqueFreeBody::Impl {
  enum class Kind { Steady, General };
  Kind kind = Kind::Steady;

  // Initial state, and the scale of step 0.
  Eigen::Vector3d w0_NB_B;
  QuaternionL q0_NB;
  Real rate = 0;  // |w0|, rad/s

  // Steady spin: the axis w0 / |w0| in B.
  Vector3L axis_B = Vector3L::Zero();

  // Principal frame P = (a, b, c) (step 1); scaled moments and initial rate in P.
  Matrix3L R_BP = Matrix3L::Identity();
  QuaternionL q_BP = QuaternionL::Identity();
  Vector3L I_P = Vector3L::Ones();
  Vector3L w0_P = Vector3L::Zero();
  Real h = 0;  // scaled |H|

  // Steps 2-4: frequency, Jacobi functions, addition-theorem coefficients.
  Real lambda = 0, m = 0, xi = 0, eta = 1;
  Real coef_a = 0, coef_b = 0, coef_c = 0;  // (Ic - Ib) / (Ia lambda) wb0 wc0, ...
  EllipticFunctions ell;

  // Step 5: attitude.
  Real N = 0, sqrt_N = 0, u0 = 0;
  Real S_K = 0, G_K = 0;  // S(K), G(K) of the form in use
  Real phase_coeff = 0;   // of S (N <= 1) or of G (N > 1) in phi
  QuaternionL q_LP0_conj = QuaternionL::Identity();

  // Scaled w_P at v = lambda * (scaled time) (step 3).
  Vector3L w_P(Real v) const {
    const Jacobi j = ell.at(v);
    const Real xs = xi * j.sn * j.sn;
    const Real delta = xs <= 0.5L ? 1 - xs : eta + xi * j.cn * j.cn;
    return Vector3L(w0_P(0) * j.cn - coef_a * j.sn * j.dn,
                    w0_P(1) * j.cn * j.dn + coef_b * j.sn,
                    w0_P(2) * j.dn - coef_c * j.sn * j.cn) /
           delta;
  }

  // u = 2 j K + r, |r| <= K; returns j and the Jacobi functions of r.
  Real reduce(Real u, Jacobi& e, Real& r) const {
    const Real two_K = 2 * ell.K();
    r = std::remainder(u, two_K);
    e = ell.at(r);
    return std::nearbyint((u - r) / two_K);
  }

  // S(u) for N <= 1 (step 5).
  Real S(Real u) const {
    Jacobi e;
    Real r;
    const Real j = reduce(u, e, r);
    const Real s2 = e.sn * e.sn;
    return 2 * j * S_K - e.sn * s2 * carlson_rj(e.cn * e.cn, e.dn * e.dn, 1, 1 + N * s2) / 3;
  }

  // G(u) for N > 1 (step 5).
  Real G(Real u) const {
    Jacobi e;
    Real r;
    const Real j = reduce(u, e, r);
    const Real s2 = e.sn * e.sn, c2 = e.cn * e.cn, d2 = e.dn * e.dn, mN = m / N;
    return 2 * j * G_K + mN / 3 * e.sn * s2 * carlson_rj(c2, d2, 1, 1 + mN * s2) +
           e.sn * carlson_rc(c2 * d2, (1 + N * s2) * (1 + mN * s2));
  }

  // phi(t) (step 5), v = lambda tau.
  Real phi(Real tau, Real v) const {
    const Real Ia = I_P(0), Ic = I_P(2);
    if (N == 0) return h * tau / Ia;  // G(u) = u
    if (ell.kp() == 0) {              // separatrix
      const Real atan_diff =
          std::atan(sqrt_N * std::tanh(u0 + v)) - std::atan(sqrt_N * std::tanh(u0));
      if (N <= 1) return h * tau / Ia + phase_coeff * (atan_diff / sqrt_N - v) / (1 + N);
      return h * tau / Ic + phase_coeff * (v + sqrt_N * atan_diff) / (1 + N);
    }
    if (N <= 1) return h * tau / Ia + phase_coeff * (S(u0 + v) - S(u0));
    return h * tau / Ic + phase_coeff * (G(u0 + v) - G(u0));
  }

  // R_LP from H_P = I_P w_P (theta, psi) and phi (step 5).
  QuaternionL q_LP(const Vector3L& w, Real phi_angle) const {
    const Vector3L H = I_P.cwiseProduct(w);
    const Real theta = std::atan2(std::hypot(H(0), H(1)), H(2));
    const Real psi = std::atan2(H(0), H(1));
    return rot_z(phi_angle) * rot_x(theta) * rot_z(psi);
  }
};

TorqueFreeBody::TorqueFreeBody(const Eigen::Matrix3d& I_BBo_B, const Eigen::Vector3d& w0_NB_B,
                               const Eigen::Quaterniond& q0_NB) {
  const std::string who = "torque-free analytic reference: ";
  if (!I_BBo_B.allFinite()) throw InputError(who + "the inertia has a non-finite entry");
  if (!w0_NB_B.allFinite())
    throw InputError(who + "the initial angular velocity has a non-finite component");
  if (!q0_NB.coeffs().allFinite())
    throw InputError(who + "the initial attitude has a non-finite component");
  const QuaternionL q0 = q0_NB.cast<Real>();
  if (q0.norm() == 0) throw InputError(who + "the initial attitude quaternion is zero");

  auto impl = std::make_shared<Impl>();
  Impl& s = *impl;
  s.w0_NB_B = w0_NB_B;
  s.q0_NB = q0.normalized();

  const Matrix3L I_B = I_BBo_B.cast<Real>();
  const Real scale = I_B.cwiseAbs().maxCoeff();
  if (scale == 0) throw InputError(who + "the inertia is zero");
  for (int i = 0; i < 3; ++i)
    for (int j = i + 1; j < 3; ++j)
      if (std::fabs(I_B(i, j) - I_B(j, i)) > 1e-9L * scale)
        throw InputError(who + "the inertia is not symmetric: I(" + std::to_string(i + 1) + "," +
                         std::to_string(j + 1) + ") = " + text(I_BBo_B(i, j)) + " but I(" +
                         std::to_string(j + 1) + "," + std::to_string(i + 1) +
                         ") = " + text(I_BBo_B(j, i)));

  // Step 1: principal moments (ascending, unscaled) and axes.
  Vector3L I_raw;
  Matrix3L V;  // columns: the principal axes in B
  if (I_B.isDiagonal(0)) {
    std::array<int, 3> order = {0, 1, 2};
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return I_B(a, a) < I_B(b, b); });
    V.setZero();
    for (int i = 0; i < 3; ++i) {
      I_raw(i) = I_B(order[i], order[i]);
      V(order[i], i) = 1;
    }
  } else {
    const Eigen::SelfAdjointEigenSolver<Matrix3L> eig((I_B + I_B.transpose()) / 2);
    if (eig.info() != Eigen::Success)
      throw InputError(who + "the eigensolver failed on the inertia");
    I_raw = eig.eigenvalues();
    V = eig.eigenvectors();
  }
  if (!(I_raw(0) > 0))
    throw InputError(who + "the inertia is not positive definite (principal moments " +
                     text(static_cast<double>(I_raw(0))) + ", " +
                     text(static_cast<double>(I_raw(1))) + ", " +
                     text(static_cast<double>(I_raw(2))) + ")");
  if (V.determinant() < 0) V.col(2) = -V.col(2);

  const Vector3L w_B = w0_NB_B.cast<Real>();
  s.rate = w_B.norm();
  if (s.rate == 0) {
    s.kind = Impl::Kind::Steady;
    impl_ = impl;
    return;
  }
  const Vector3L w_raw = V.transpose() * w_B;  // exact for a diagonal inertia

  // Steady spin: w0 within one eigenspace (exactly: any other w0 takes the general path).
  bool steady = true;
  for (int i = 0; i < 3; ++i)
    for (int j = i + 1; j < 3; ++j)
      if (I_raw(i) != I_raw(j) && w_raw(i) != 0 && w_raw(j) != 0) steady = false;
  if (steady) {
    s.kind = Impl::Kind::Steady;
    s.axis_B = w_B / s.rate;
    impl_ = impl;
    return;
  }
  s.kind = Impl::Kind::General;

  // Step 2, R~ first: its sign chooses (a, b, c).
  using Quad = boost::multiprecision::cpp_bin_float_quad;
  const Quad I1(I_raw(0)), I2(I_raw(1)), I3(I_raw(2)), w1(w_raw(0)), w3(w_raw(2));
  const Quad R_quad = I3 * (I3 - I2) * w3 * w3 - I1 * (I2 - I1) * w1 * w1;
  const Real R_signed = static_cast<Real>(R_quad / (I3 * I3)) / (s.rate * s.rate);
  Vector3L I_P_raw;
  if (R_signed >= 0) {
    s.R_BP = V;
    I_P_raw = I_raw;
  } else {
    s.R_BP.col(0) = V.col(2);
    s.R_BP.col(1) = -V.col(1);
    s.R_BP.col(2) = V.col(0);
    I_P_raw = Vector3L(I_raw(2), I_raw(1), I_raw(0));
  }
  s.q_BP = QuaternionL(s.R_BP).normalized();
  s.I_P = I_P_raw / I_raw(2);                     // step 0: moments in (0, 1]
  s.w0_P = s.R_BP.transpose() * w_B / s.rate;    // step 0: |w| = 1
  const Real Ia = s.I_P(0), Ib = s.I_P(1), Ic = s.I_P(2);
  const Real wa = s.w0_P(0), wb = s.w0_P(1), wc = s.w0_P(2);
  // Signed and absolute differences, from the unscaled moments.
  const Real c_ba = (I_P_raw(1) - I_P_raw(0)) / I_raw(2), c_cb = (I_P_raw(2) - I_P_raw(1)) / I_raw(2),
             c_ca = (I_P_raw(2) - I_P_raw(0)) / I_raw(2);
  const Real d_ba = std::fabs(c_ba), d_cb = std::fabs(c_cb), d_ca = std::fabs(c_ca);

  // One-signed sums. Non-steady motion has d_cb > 0, P~ > 0 and Q~ > 0 (else w0 would lie in an
  // eigenspace).
  const Real P = Ib * d_ba * wb * wb + Ic * d_ca * wc * wc;
  const Real Q = Ia * d_ca * wa * wa + Ib * d_cb * wb * wb;
  const Real R = std::fabs(R_signed);
  s.h = s.I_P.cwiseProduct(s.w0_P).norm();
  s.lambda = std::sqrt(d_cb * P / (Ia * Ib * Ic));
  const Real m_direct = d_ba * Q / (d_cb * P), m1_direct = d_ca * R / (d_cb * P);
  const Real m1 = m1_direct <= m_direct ? m1_direct : 1 - m_direct;
  s.m = m1_direct <= m_direct ? 1 - m1 : m_direct;
  s.ell = EllipticFunctions(s.m, m1);

  // Step 3: Delta's terms and the signed addition-theorem coefficients.
  s.xi = Ib * d_ba * wb * wb / P;
  s.eta = Ic * d_ca * wc * wc / P;
  s.coef_a = c_cb / (Ia * s.lambda) * wb * wc;
  s.coef_b = c_ca / (Ib * s.lambda) * wa * wc;
  s.coef_c = c_ba / (Ic * s.lambda) * wa * wb;

  // Step 5: N, u0, the complete integral of the form in use, the coefficient in phi.
  s.N = Ic * d_ba / (Ia * d_cb);
  s.sqrt_N = std::sqrt(s.N);
  const Real sn2_u0 = Ib * d_cb * wb * wb / Q;
  const Real cn2_u0 = Ia * d_ca * wa * wa / Q;
  const bool forward = (wa * wb * wc) * c_cb >= 0;
  s.u0 = (forward ? 1 : -1) * std::sqrt(sn2_u0) * carlson_rf(cn2_u0, s.eta, 1);
  const Real coeff_G = s.h * c_ca / (Ic * Ia * s.lambda);  // h (Ic - Ia) / (Ic Ia lambda)
  if (s.N <= 1) {
    s.phase_coeff = coeff_G * s.N;
    if (s.N > 0 && m1 > 0) s.S_K = -carlson_rj(0, m1, 1, 1 + s.N) / 3;
  } else {
    s.phase_coeff = coeff_G;
    const Real mN = s.m / s.N;
    if (m1 > 0)
      s.G_K = mN / 3 * carlson_rj(0, m1, 1, 1 + mN) +
              kPi / 2 * std::sqrt(s.N / ((1 + s.N) * (s.N + s.m)));
  }
  s.q_LP0_conj = s.q_LP(s.w0_P, 0).conjugate();
  impl_ = impl;
}

TorqueFreeState TorqueFreeBody::at(double t) const {
  if (!std::isfinite(t))
    throw InputError("torque-free analytic reference: the time " + text(t) + " is not finite");
  const Impl& s = *impl_;
  const Real tau = s.rate * static_cast<Real>(t);  // step 0: scaled time
  TorqueFreeState out;
  QuaternionL q_B0B;  // R_B(0)B(t)
  if (s.kind == Impl::Kind::Steady) {
    out.w_NB_B = s.w0_NB_B;
    q_B0B = QuaternionL(std::cos(tau / 2), 0, 0, 0);
    q_B0B.vec() = s.axis_B * std::sin(tau / 2);
  } else {
    const Real v = s.lambda * tau;
    const Vector3L w = s.w_P(v);
    q_B0B = s.q_BP * (s.q_LP0_conj * s.q_LP(w, s.phi(tau, v))) * s.q_BP.conjugate();
    const Vector3L w_B = s.w0_NB_B.cast<Real>() + s.rate * (s.R_BP * (w - s.w0_P));
    out.w_NB_B = w_B.cast<double>();
  }
  out.q_NB = (s.q0_NB * q_B0B).normalized().cast<double>();
  out.q_NB.normalize();
  if (!out.w_NB_B.allFinite() || !out.q_NB.coeffs().allFinite())
    throw RunFailure("analytic", t, "w, q",
                     "the torque-free closed form is not finite here (|w0| = " +
                         text(static_cast<double>(s.rate)) + " rad/s)");
  return out;
}

bool is_torque_free(const System& system) {
  if (system.bodies.size() != 1 || system.joints.size() != 1) return false;
  const Body& b = system.bodies[0];
  const Joint& j = system.joints[0];
  return j.type == JointType::Free && !b.flex && b.torque.empty();
}

}  // namespace crossdyn::analytic
