// Torque-free rigid body in closed form (see torque_free.hpp).
//
// References:
//   [LL]   Landau & Lifshitz, Mechanics, 3rd ed., Sec. 37 ("Euler's equations" solved for the
//          free asymmetric top), Eqs. (37.10)-(37.12) for w(t), Sec. 35 Eq. (35.2) and Sec. 37's
//          closing paragraphs for the Euler angles of the body in the frame aligned with H.
//   [KLL]  Kane, Likins & Levinson, Spacecraft Dynamics (1983), Sec. 3.1 (torque-free motion).
//   [BF]   Byrd & Friedman, Handbook of Elliptic Integrals (1971): 120.01 (Jacobi functions),
//          110.06 (amplitude), 400.01 (integral of 1/(1 - n sn^2 u) = Pi(n; am u, k)).
//   [AS]   Abramowitz & Stegun (1964), 16.1 and 17.2 (elliptic integrals, Legendre's forms).
//
// Method, inputs => outputs:
//   1. (I_BBo_B) => principal frame P of B: I = R_BP diag(Ia, Ib, Ic) R_BP^T, a right-handed
//      permutation (a, b, c) of the principal axes with Ib the intermediate moment and c the axis
//      the polhode circles (c = largest moment when D = h^2 / (2E) >= Ib, else the smallest).
//   2. (w0) => the constants h = |I w|, 2E = w . I w and the Jacobi solution in P [LL (37.10)]:
//        w_a = s_a A_a cn(u),  w_b = sigma A_b sn(u),  w_c = sigma_c A_c dn(u),  u = lambda t + u0,
//        A_a^2 = 2E (Ic - D) / (Ia (Ic - Ia)),  A_b^2 = 2E (Ic - D) / (Ib (Ic - Ib)),
//        A_c^2 = 2E (D - Ia) / (Ic (Ic - Ia)),  lambda^2 = 2E (Ic - Ib)(D - Ia) / (Ia Ib Ic),
//        k^2 = (Ib - Ia)(Ic - D) / ((Ic - Ib)(D - Ia)).
//      These hold with any ordering in which (a, b, c) is right-handed and D lies between Ib and
//      Ic, which lets one formula serve both of Landau's cases (37.10) and "interchange 1 and 3".
//      Substituting into Euler's first equation fixes the sign: sigma = s_a sigma_c sign(Ic - Ib);
//      s_a = 1 except on the separatrix (k = 1), where cn = dn = sech and sn = tanh [BF 122.00].
//      The axisymmetric top is k = 0 (cn = cos, sn = sin, dn = 1) [KLL Sec. 3.1].
//   3. (w(t)) => attitude. Let L be an inertial frame with z_L along H. The body's 3-1-3 Euler
//      angles in L, R_LP = Rz(phi) Rx(theta) Rz(psi), have [LL (35.2), Sec. 37]
//        H_P / h = (sin theta sin psi, sin theta cos psi, cos theta)   (theta, psi from w(t));
//        phi'    = h (H_a^2 / Ia + H_b^2 / Ib) / (H_a^2 + H_b^2)
//                = h / Ic + h (Ic - Ia) / (Ic Ia) / (1 - n sn^2 u),   n = -Ic (Ib - Ia) / (Ia (Ic - Ib)),
//      so, with du = lambda dt [BF 400.01],
//        phi(t) - phi(0) = h t / Ic + h (Ic - Ia) / (Ic Ia lambda) [Pi(n; am u, k) - Pi(n; am u0, k)]
//      (on the separatrix the integral is elementary, see separatrix_integral()). L is chosen so
//      that phi(0) = 0: R_NL = R_NP(0) (Rx(theta0) Rz(psi0))^T, which indeed has z_L = H_N / h.
//   Steady spin (w parallel to a principal axis, including the sphere and the symmetric plane of
//   an axisymmetric body): w constant, R_NB(t) = R_NB(0) Rot(w, |w| t).
#include "analytic/torque_free.hpp"

#include <Eigen/Eigenvalues>
#include <boost/math/special_functions/ellint_1.hpp>
#include <boost/math/special_functions/ellint_3.hpp>
#include <boost/math/special_functions/jacobi_elliptic.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace crossdyn::analytic {

namespace {

constexpr double kPi = std::numbers::pi;

// Principal moments closer than this (relative to the largest) are taken as equal, so that an
// axisymmetric body given in rotated axes is solved exactly as one (k = 0).
constexpr double kEqualMoments = 1e-13;

double sign_of(double x) { return x < 0 ? -1.0 : 1.0; }

Eigen::Quaterniond rot_z(double angle) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()));
}
Eigen::Quaterniond rot_x(double angle) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitX()));
}

}  // namespace

struct TorqueFreeBody::Impl {
  enum class Kind { Steady, Elliptic, Separatrix };
  Kind kind = Kind::Steady;

  // Initial state (steady spin uses only these).
  Eigen::Vector3d w0_NB_B;
  Eigen::Quaterniond q0_NB;

  // Principal frame P = (a, b, c) and its moments.
  Eigen::Matrix3d R_BP;          // columns: the P axes in B components
  Eigen::Quaterniond q_PB;       // R_PB = R_BP^T
  Eigen::Vector3d I_P;           // (Ia, Ib, Ic)
  double h = 0;                  // |H|, kg m^2/s

  // Jacobi solution (step 2).
  double A_a = 0, A_b = 0, A_c = 0, lambda = 0, k = 0, K = 0;
  double s_a = 1, sigma = 1, sigma_c = 1, u0 = 0;
  // Attitude (step 3).
  double n = 0, Pi_complete = 0, phi_coeff = 0, G0 = 0;
  Eigen::Quaterniond q_NL;

  // u => w_NB_P (step 2).
  Eigen::Vector3d w_P(double u) const {
    double sn, cn, dn;
    if (kind == Kind::Separatrix) {
      sn = std::tanh(u);
      cn = dn = 1.0 / std::cosh(u);
    } else {
      // sn, cn have period 4K: reduce first so that Boost's AGM sees a small argument.
      const double m = std::round(u / (4 * K));
      const double ur = u - 4 * K * m;
      sn = boost::math::jacobi_elliptic(k, ur, &cn, static_cast<double*>(nullptr));
      dn = std::sqrt(std::max(0.0, 1 - k * k * sn * sn));  // [BF 121.00], dn > 0
    }
    return {s_a * A_a * cn, sigma * A_b * sn, sigma_c * A_c * dn};
  }

  // The integral of du / (1 - n sn^2 u) from 0 to u (step 3) [BF 400.01].
  double G(double u) const {
    if (kind == Kind::Separatrix) return separatrix_integral(u);
    const double m = std::round(u / (4 * K));
    const double ur = u - 4 * K * m;
    double cn;
    const double sn = boost::math::jacobi_elliptic(k, ur, &cn, static_cast<double*>(nullptr));
    // am(ur) in [-pi, pi] with the sign of ur (am is increasing, am(0) = 0) [BF 110.06].
    double am = std::atan2(sn, cn);
    if (ur < 0 && am > kPi / 2) am -= 2 * kPi;
    if (ur > 0 && am < -kPi / 2) am += 2 * kPi;
    // Pi(n; phi + 2 pi) = Pi(n; phi) + 4 Pi(n) [AS 17.4.3 for the third kind likewise].
    return 4 * m * Pi_complete + boost::math::ellint_3(k, n, am);
  }

  // k = 1: sn = tanh u, so with x = tanh u, du = dx / (1 - x^2) and, for n = -m <= 0,
  // int dx / ((1 - x^2)(1 + m x^2)) = (atanh x + sqrt(m) atan(sqrt(m) x)) / (1 + m).
  double separatrix_integral(double u) const {
    const double m = -n;
    const double r = std::sqrt(m);
    return (u + r * std::atan(r * std::tanh(u))) / (1 + m);
  }
};

TorqueFreeBody::TorqueFreeBody(const Eigen::Matrix3d& I_BBo_B, const Eigen::Vector3d& w0_NB_B,
                               const Eigen::Quaterniond& q0_NB) {
  auto impl = std::make_shared<Impl>();
  Impl& s = *impl;
  s.w0_NB_B = w0_NB_B;
  s.q0_NB = q0_NB.normalized();
  if (!I_BBo_B.allFinite() || !w0_NB_B.allFinite() || !q0_NB.coeffs().allFinite())
    throw std::invalid_argument("TorqueFreeBody: non-finite inertia, angular velocity or attitude");

  // Step 1: principal axes, ascending moments, right-handed.
  const Eigen::Matrix3d I_sym = 0.5 * (I_BBo_B + I_BBo_B.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(I_sym);
  if (eig.info() != Eigen::Success || eig.eigenvalues()(0) <= 0)
    throw std::invalid_argument("TorqueFreeBody: inertia is not positive definite");
  Eigen::Vector3d I = eig.eigenvalues();
  Eigen::Matrix3d V = eig.eigenvectors();
  if (V.determinant() < 0) V.col(2) = -V.col(2);
  const double tol = kEqualMoments * I(2);
  if (I(1) - I(0) <= tol) I(0) = I(1) = 0.5 * (I(0) + I(1));
  if (I(2) - I(1) <= tol) I(1) = I(2) = 0.5 * (I(1) + I(2));
  if (I(1) - I(0) <= tol && I(2) - I(1) <= tol) I.setConstant(I.mean());

  const Eigen::Vector3d w_V = V.transpose() * w0_NB_B;
  const Eigen::Vector3d H_V = I.cwiseProduct(w_V);
  s.h = H_V.norm();
  const double two_E = w_V.dot(H_V);

  // Steady spin: I w parallel to w (Euler: I w' = -w x I w = 0) [KLL Sec. 3.1].
  if (s.h == 0 || w_V.cross(H_V).norm() <= 1e-14 * w_V.norm() * s.h) {
    s.kind = Impl::Kind::Steady;
    impl_ = impl;
    return;
  }

  const double D = s.h * s.h / two_E;
  // Choose (a, b, c): c = polhode axis; (e3, -e2, e1) keeps the frame right-handed for c = 1.
  if (D >= I(1)) {
    s.R_BP = V;
    s.I_P = I;
  } else {
    s.R_BP.col(0) = V.col(2);
    s.R_BP.col(1) = -V.col(1);
    s.R_BP.col(2) = V.col(0);
    s.I_P = Eigen::Vector3d(I(2), I(1), I(0));
  }
  s.q_PB = Eigen::Quaterniond(Eigen::Matrix3d(s.R_BP.transpose()));
  const double Ia = s.I_P(0), Ib = s.I_P(1), Ic = s.I_P(2);
  const Eigen::Vector3d w_P0 = s.R_BP.transpose() * w0_NB_B;

  // Step 2: amplitudes, frequency and modulus [LL (37.10)-(37.12)], written so that every factor
  // is positive for either choice of c.
  s.A_a = std::sqrt(two_E * (Ic - D) / (Ia * (Ic - Ia)));
  s.A_b = std::sqrt(two_E * (Ic - D) / (Ib * (Ic - Ib)));
  s.A_c = std::sqrt(two_E * (D - Ia) / (Ic * (Ic - Ia)));
  s.lambda = std::sqrt(two_E * (Ic - Ib) * (D - Ia) / (Ia * Ib * Ic));
  const double k2 = std::clamp((Ib - Ia) * (Ic - D) / ((Ic - Ib) * (D - Ia)), 0.0, 1.0);
  s.k = std::sqrt(k2);
  s.n = -Ic * (Ib - Ia) / (Ia * (Ic - Ib));
  s.sigma_c = sign_of(w_P0(2));
  const double sign_cb = sign_of(Ic - Ib);

  if (k2 >= 1 - 1e-15) {
    // Separatrix (D = Ib): w_a = s_a A_a sech u, w_b = sigma A_b tanh u, w_c = sigma_c A_c sech u.
    s.kind = Impl::Kind::Separatrix;
    s.k = 1;
    s.s_a = sign_of(w_P0(0));
    s.sigma = s.s_a * s.sigma_c * sign_cb;
    s.u0 = std::atanh(std::clamp(w_P0(1) / (s.sigma * s.A_b), -1 + 1e-16, 1 - 1e-16));
  } else {
    s.kind = Impl::Kind::Elliptic;
    s.s_a = 1;
    s.sigma = s.sigma_c * sign_cb;
    s.K = boost::math::ellint_1(s.k);
    s.Pi_complete = boost::math::ellint_3(s.k, s.n);
    // Initial amplitude: cn(u0) = w_a / A_a, sn(u0) = w_b / (sigma A_b); u0 = F(am u0, k).
    const double am0 = std::atan2(w_P0(1) / (s.sigma * s.A_b), w_P0(0) / s.A_a);
    s.u0 = boost::math::ellint_1(s.k, am0);
  }
  s.phi_coeff = s.h * (Ic - Ia) / (Ic * Ia * s.lambda);
  s.G0 = s.G(s.u0);

  // Step 3: the H-aligned inertial frame L with phi(0) = 0.
  const Eigen::Vector3d H_P0 = s.I_P.cwiseProduct(s.w_P(s.u0));
  const double theta0 = std::atan2(std::hypot(H_P0(0), H_P0(1)), H_P0(2));
  const double psi0 = std::atan2(H_P0(0), H_P0(1));
  const Eigen::Quaterniond q_NP0 = s.q0_NB * s.q_PB.conjugate();
  s.q_NL = q_NP0 * (rot_x(theta0) * rot_z(psi0)).conjugate();
  impl_ = impl;
}

TorqueFreeState TorqueFreeBody::at(double t) const {
  const Impl& s = *impl_;
  TorqueFreeState out;
  if (s.kind == Impl::Kind::Steady) {
    out.w_NB_B = s.w0_NB_B;
    const double rate = s.w0_NB_B.norm();
    out.q_NB = rate == 0 ? s.q0_NB
                         : s.q0_NB * Eigen::Quaterniond(Eigen::AngleAxisd(
                                         rate * t, s.w0_NB_B / rate));
    out.q_NB.normalize();
    return out;
  }
  const double u = s.lambda * t + s.u0;
  const Eigen::Vector3d w_NB_P = s.w_P(u);
  const Eigen::Vector3d H_P = s.I_P.cwiseProduct(w_NB_P);
  const double theta = std::atan2(std::hypot(H_P(0), H_P(1)), H_P(2));
  const double psi = std::atan2(H_P(0), H_P(1));
  const double phi = s.h * t / s.I_P(2) + s.phi_coeff * (s.G(u) - s.G0);
  out.w_NB_B = s.R_BP * w_NB_P;
  out.q_NB = (s.q_NL * rot_z(phi) * rot_x(theta) * rot_z(psi) * s.q_PB).normalized();
  return out;
}

bool is_torque_free(const System& system) {
  if (system.bodies.size() != 1 || system.joints.size() != 1) return false;
  const Body& b = system.bodies[0];
  const Joint& j = system.joints[0];
  return j.type == JointType::Free && !b.flex && b.torque.empty();
}

}  // namespace crossdyn::analytic
