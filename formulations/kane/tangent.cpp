// The Kane engine's exact tangent of its accelerations (issue 27; Engine::accelerations_tangent):
// with x(e) = pack(s + e ds), a = accelerations(t, x(0)) and da = d/de accelerations(t, x(e)) at
// e = 0, by forward-mode automatic differentiation (Griewank and Walther 2008, "Evaluating
// Derivatives", 2nd ed., Ch. 3: the tangent mode) with the dual number of dual.hpp.
//
// What is differentiated: a twin of the engine's composite passes for rigid trees, templated on
// the scalar S and evaluated here for S = Dual.  It reads the same model tables (Node, System)
// and writes the same equations as the run's passes:
//   Pass 1-2 (kinematics.cpp, joints/*.cpp): R_NJc = R_NJp R_PJ0 R_J, p_Ok = p_Po + R_NP r_Pj,
//     p_Co = p_Ok - R_NC r_Cj; w_C = w_P + sum W_r u_r; v_Co = v_Ok + w_C x p_OkCo, v_Ok = v_Po
//     + w_P x p_PoOk (+ sum V_r u_r, prismatic);
//   Pass 3 (accelerations.cpp): the remainder accelerations alpha_t, a_t (u' = 0) and, given u',
//     the full ones;
//   Passes 4-6 (subtree_sums.cpp, mass_matrix.cpp, generalized_forces.cpp, gravity.cpp): Kane's
//     equations M u' = f with M_rs = sum_B m v_B,r . v_B,s + w_B,r . I_B w_B,s and
//     f_r = sum_B v_B,r . R_B + w_B,r . T_B + (hinge forces of speed r), where v_B,r, w_B,r are
//     the partial velocities of body B's CM and its partial angular velocities ([KL85] Ch. 5,
//     written body by body instead of the composite sums about Ok: the same sums, reordered),
//     R_B = -m a_t + F_grav, T_B = T_ext - I alpha_t - s_g w x I w + tau_grav
//     (s_g = EngineOptions::test_gyroscopic_sign, as in the run's passes);
//   Pass 7 (ltdl_solve.cpp): u' by a dense L D L^T factorisation (M is symmetric positive
//     definite), the same solution as the run's sparse L^T D L.
// pack()'s zero-linear-momentum rule (kane_engine.cpp) is differentiated too: v_B0o =
// -P0 / m_total with P0 the momentum at v_B0o = 0, from the twin's velocities.
//
// The run's paths (rhs(), accelerations()) are untouched; tests/kane/test_kane_tangent.cpp checks
// that the twin's value part is accelerations() to rounding and its derivative part a central
// difference of accelerations() (and its Richardson extrapolation).
//
// Flexible bodies (and geometric stiffening) go through a second twin, flex_dynamics: Kane's
// equations written particle by particle (C's node masses, its node inertias turning with C's
// frame: the sums FlexModel's integrals hold), over the positions of Pass 1 with the joints at
// nodes (docs/flexible-bodies.md), whose velocities, partial velocities and remainder
// accelerations are the Taylor coefficients in time (Jet: a + b t + c t^2 with dual
// coefficients, [GW08] Ch. 13) of those positions along q' = q'(u).  Not covered (tangent_
// false: the caller differentiates numerically): a flexible body with test_inertia_scale != 1
// (the scaled inertia is no longer the node sums) or a flipped test_gyroscopic_sign (a prismatic
// joint at a node of a flexible body is refused by the engine itself).
//
// Issue 27's output matrix C and own Jacobian (session 39): output_row_tangent differentiates
// the row's equations in duals (TangentTwin::output_jet: the twin's u' and Pass 1's positions as
// Jets, every body a set of mass points with a rotational inertia; the row itself is
// output_row()'s), rhs_tangent the kinematical equations and the twin's u' at x + e dx (any dx:
// the twins normalise quaternions where rhs() does).  Same coverage as accelerations_tangent.
#include "formulations/kane/dual.hpp"
#include "formulations/kane/kane_internal.hpp"

#include "core/errors.hpp"
#include "core/orbit.hpp"

#include <cmath>
#include <string>
#include <limits>
#include <vector>

namespace crossdyn::kane {

// A truncated Taylor polynomial in time, a + b t + c t^2, with dual coefficients (the flexible
// twin below): b is the rate and 2 c the acceleration of whatever it carries, exact to rounding
// (Taylor-mode arithmetic, [GW08] Ch. 13), and every coefficient carries its derivative along
// the tangent.  Internal to this file.
namespace {
struct Jet {
  Dual a, b, c;
  Jet() = default;
  Jet(double v) : a(v) {}  // NOLINT: a constant
  Jet(const Dual& v) : a(v) {}  // NOLINT: a constant in time
  Jet(const Dual& a_, const Dual& b_, const Dual& c_) : a(a_), b(b_), c(c_) {}
  Jet& operator+=(const Jet& o) {
    a += o.a;
    b += o.b;
    c += o.c;
    return *this;
  }
  Jet& operator-=(const Jet& o) {
    a -= o.a;
    b -= o.b;
    c -= o.c;
    return *this;
  }
  Jet& operator*=(const Jet& o) {
    *this = Jet(a * o.a, a * o.b + b * o.a, a * o.c + b * o.b + c * o.a);
    return *this;
  }
  Jet& operator/=(const Jet& o) {
    const Dual q0 = a / o.a, q1 = (b - q0 * o.b) / o.a, q2 = (c - q0 * o.c - q1 * o.b) / o.a;
    *this = Jet(q0, q1, q2);
    return *this;
  }
};
inline Jet operator-(const Jet& x) { return {-x.a, -x.b, -x.c}; }
inline Jet operator+(const Jet& x) { return x; }
inline Jet operator+(Jet x, const Jet& y) { return x += y; }
inline Jet operator-(Jet x, const Jet& y) { return x -= y; }
inline Jet operator*(Jet x, const Jet& y) { return x *= y; }
inline Jet operator/(Jet x, const Jet& y) { return x /= y; }
inline Jet operator+(Jet x, double y) { return x += Jet(y); }
inline Jet operator+(double y, Jet x) { return x += Jet(y); }
inline Jet operator-(Jet x, double y) { return x -= Jet(y); }
inline Jet operator-(double y, const Jet& x) { return Jet(y) - x; }
inline Jet operator*(const Jet& x, double y) { return {x.a * y, x.b * y, x.c * y}; }
inline Jet operator*(double y, const Jet& x) { return {x.a * y, x.b * y, x.c * y}; }
inline Jet operator/(const Jet& x, double y) { return {x.a / y, x.b / y, x.c / y}; }
inline Jet operator/(double y, const Jet& x) { return Jet(y) / x; }
inline bool operator<(const Jet& x, const Jet& y) { return x.a.v < y.a.v; }
inline bool operator>(const Jet& x, const Jet& y) { return x.a.v > y.a.v; }
inline bool operator<=(const Jet& x, const Jet& y) { return x.a.v <= y.a.v; }
inline bool operator>=(const Jet& x, const Jet& y) { return x.a.v >= y.a.v; }
inline bool operator==(const Jet& x, const Jet& y) { return x.a == y.a && x.b == y.b && x.c == y.c; }
inline bool operator!=(const Jet& x, const Jet& y) { return !(x == y); }
inline Jet sin(const Jet& x) {
  const Dual s = sin(x.a), co = cos(x.a);
  return {s, co * x.b, co * x.c - 0.5 * s * x.b * x.b};
}
inline Jet cos(const Jet& x) {
  const Dual s = sin(x.a), co = cos(x.a);
  return {co, -s * x.b, -s * x.c - 0.5 * co * x.b * x.b};
}
inline Jet sqrt(const Jet& x) {
  const Dual r0 = sqrt(x.a), r1 = x.b / (2.0 * r0);
  return {r0, r1, (x.c - r1 * r1) / (2.0 * r0)};
}
inline Jet abs(const Jet& x) { return x.a.v < 0 ? -x : x; }
inline double value(const Jet& x) { return x.a.v; }
}  // namespace

}  // namespace crossdyn::kane

namespace Eigen {
template <>
struct NumTraits<crossdyn::kane::Jet> : KaneRealNumTraits<crossdyn::kane::Jet, 6, 6, 18> {};
}  // namespace Eigen

namespace crossdyn::kane {

namespace {

template <class S>
using V3 = Eigen::Matrix<S, 3, 1>;
template <class S>
using M3 = Eigen::Matrix<S, 3, 3>;

template <class S>
V3<S> cst(const Vector3d& v) {
  return v.cast<S>();
}
template <class S>
M3<S> cst(const Matrix3d& m) {
  return m.cast<S>();
}

// The rotation matrix of the quaternion (w, x, y, z) at q, normalised where read (read_quat).
template <class S>
M3<S> quat_matrix(const S* q) {
  const S n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const S w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
  M3<S> R;
  R << 1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
      2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x),
      2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y);
  return R;
}

// Rodrigues' formula about the unit k (axis_angle_matrix of kane_internal.hpp), half-angle
// sine sh and cosine ch.
template <class S>
M3<S> axis_angle(const Vector3d& k, const S& sh, const S& ch) {
  const S s = 2.0 * sh * ch, v = 2.0 * sh * sh, c = 1.0 - v;
  M3<S> R;
  R << c + v * k.x() * k.x(), v * k.x() * k.y() - s * k.z(), v * k.x() * k.z() + s * k.y(),
      v * k.y() * k.x() + s * k.z(), c + v * k.y() * k.y(), v * k.y() * k.z() - s * k.x(),
      v * k.z() * k.x() - s * k.y(), v * k.z() * k.y() + s * k.x(), c + v * k.z() * k.z();
  return R;
}

// The rotation vector of the quaternion at q (normalised, canonical w >= 0; rot::
// rotation_vector): q.vec (angle / s), angle = 2 atan2(s, w), s = |q.vec|.  Below s = 1e-4 the
// factor 2 atan(z) / (z w), z = s / w, by its series to z^6 (error below 1e-31), which keeps
// the derivative finite at s = 0 (sqrt(s^2) has none there).
template <class S>
V3<S> rotation_vector(const S* q) {
  const S n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const double sign = value(q[0]) < 0 ? -1.0 : 1.0;
  const S w = sign * q[0] / n;
  const V3<S> v(sign * q[1] / n, sign * q[2] / n, sign * q[3] / n);
  const S s2 = v.squaredNorm();
  S f;
  if (std::sqrt(value(s2)) < 1e-4) {
    const S z2 = s2 / (w * w);
    f = (2.0 / w) * (1.0 - z2 * (1.0 / 3.0 - z2 * (1.0 / 5.0 - z2 / 7.0)));
  } else {
    const S s = sqrt(s2);
    f = 2.0 * atan2(s, w) / s;
  }
  return v * f;
}

// The twin's per-node workspace (N components; positions from the base's frame origin B0o, or
// from No for a prescribed base's tree, as NodeWork).
template <class S>
struct TwinWork {
  M3<S> R = M3<S>::Identity(), W = M3<S>::Zero(), V = M3<S>::Zero(), I_N = M3<S>::Zero();
  V3<S> p_Ok = V3<S>::Zero(), p_Bo = V3<S>::Zero(), p_PoOk = V3<S>::Zero(),
        p_OkBo = V3<S>::Zero();
  V3<S> w = V3<S>::Zero(), v = V3<S>::Zero(), w_PC = V3<S>::Zero(), w_Jp = V3<S>::Zero(),
        v_PC = V3<S>::Zero(), alpha_PC_t = V3<S>::Zero();
  V3<S> alpha = V3<S>::Zero(), a = V3<S>::Zero();  // remainder, then full accelerations
  double pres_angle = 0, pres_rate = 0, pres_accel = 0;
};

}  // namespace

struct TangentTwin {
  // Passes 1-2 at (t, x): every node's frame, points, partial (angular) velocities, velocities.
  template <class S>
  static void kinematics(const KaneEngine& e, double t, const S* x, std::vector<TwinWork<S>>& w) {
    const S* u = x + e.n_q_;
    const TwinWork<S> ground;  // N: at rest, origin No
    w.assign(e.nodes_.size(), TwinWork<S>());
    for (std::size_t k = 0; k < e.nodes_.size(); ++k) {
      const Node& n = e.nodes_[k];
      TwinWork<S>& W = w[k];
      if (n.prescribed) {
        W.pres_angle = n.angle0 + n.motion.angle(t);
        W.pres_rate = n.motion.velocity(t);
        W.pres_accel = n.motion.accel(t);
      }
      if (n.shape == JointShape::Base6) {
        W.R = quat_matrix(x + n.q0 + 3);
        W.w = W.R * V3<S>(u[n.u0], u[n.u0 + 1], u[n.u0 + 2]);
        W.v = V3<S>(u[n.u0 + 3], u[n.u0 + 4], u[n.u0 + 5]);
        W.w_PC = W.w;
      } else {
        const TwinWork<S>& P = n.parent >= 0 ? w[static_cast<std::size_t>(n.parent)] : ground;
        V3<S> r_Pj = cst<S>(n.p_PoJ_P);
        const M3<S>& R_NJp = P.R;
        const M3<S> R_NJ0 = n.has_offset ? M3<S>(R_NJp * cst<S>(n.R_PJ0)) : R_NJp;
        M3<S> R_NJc;
        switch (n.shape) {
          case JointShape::Axis1: {
            const S half = 0.5 * (n.prescribed ? S(W.pres_angle) : x[n.q0]);
            R_NJc = R_NJ0 * axis_angle<S>(n.axis_J, sin(half), cos(half));
            W.W.col(0) = R_NJp * cst<S>(n.axis_P);
            W.w_PC = W.W.col(0) * (n.prescribed ? S(W.pres_rate) : u[n.u0]);
          } break;
          case JointShape::Rotation3:
            R_NJc = R_NJ0 * quat_matrix(x + n.q0);
            W.W = R_NJc;
            W.w_PC = W.W * V3<S>(u[n.u0], u[n.u0 + 1], u[n.u0 + 2]);
            break;
          case JointShape::Slide1: {
            const S s = n.prescribed ? S(W.pres_angle) : x[n.q0];
            R_NJc = R_NJ0;
            W.V.col(0) = R_NJp * cst<S>(n.axis_P);
            r_Pj += s * cst<S>(n.axis_P);
            W.v_PC = W.V.col(0) * (n.prescribed ? S(W.pres_rate) : u[n.u0]);
          } break;
          case JointShape::Gimbal2: {
            const S h1 = 0.5 * x[n.q0], h2 = 0.5 * x[n.q0 + 1];
            const M3<S> R_1 = R_NJ0 * axis_angle<S>(n.axis_J, sin(h1), cos(h1));
            W.W.col(0) = R_NJp * cst<S>(n.axis_P);
            W.W.col(1) = R_1 * cst<S>(n.axis2_J);
            R_NJc = R_1 * axis_angle<S>(n.axis2_J, sin(h2), cos(h2));
            const S u1 = u[n.u0], u2 = u[n.u0 + 1];
            W.w_PC = W.W.col(0) * u1 + W.W.col(1) * u2;
            W.alpha_PC_t = (u1 * u2) * W.W.col(0).cross(W.W.col(1));
          } break;
          default:  // None (fixed); Base6 above
            R_NJc = R_NJ0;
            break;
        }
        W.R = R_NJc;
        W.p_PoOk = P.R * r_Pj;
        W.p_Ok = P.p_Bo + W.p_PoOk;
        W.p_OkBo = -(W.R * cst<S>(n.p_CoJ_C));
        W.p_Bo = W.p_Ok + W.p_OkBo;
        V3<S> v_Ok = P.v + P.w.cross(W.p_PoOk);
        W.w_Jp = P.w;
        if (n.slides) v_Ok += W.v_PC;
        W.w = W.w_Jp + W.w_PC;
        W.v = v_Ok + W.w.cross(W.p_OkBo);
      }
      if (n.inertia == Node::Inertia::Isotropic)
        W.I_N = cst<S>(n.I_BBo_B);
      else
        W.I_N = W.R * cst<S>(n.I_BBo_B) * W.R.transpose();
    }
  }

  // Pass 3: udot null, the remainder accelerations; else the full ones.
  template <class S>
  static void propagate(const KaneEngine& e, std::vector<TwinWork<S>>& w, const S* udot) {
    const TwinWork<S> ground;
    for (std::size_t k = 0; k < e.nodes_.size(); ++k) {
      const Node& n = e.nodes_[k];
      TwinWork<S>& W = w[k];
      if (n.shape == JointShape::Base6) {
        if (udot != nullptr) {
          W.alpha = W.R * V3<S>(udot[n.u0], udot[n.u0 + 1], udot[n.u0 + 2]);
          W.a = V3<S>(udot[n.u0 + 3], udot[n.u0 + 4], udot[n.u0 + 5]);
        } else {
          W.alpha.setZero();
          W.a.setZero();
        }
        continue;
      }
      const TwinWork<S>& P = n.parent >= 0 ? w[static_cast<std::size_t>(n.parent)] : ground;
      V3<S> a_Ok = P.a + P.alpha.cross(W.p_PoOk) + P.w.cross(P.w.cross(W.p_PoOk));
      V3<S> alpha_C = P.alpha + W.w_Jp.cross(W.w_PC);
      if (n.axis_rates) alpha_C += W.alpha_PC_t;
      if (n.slides) {
        a_Ok += 2.0 * W.w_Jp.cross(W.v_PC);
        if (n.prescribed) a_Ok += W.V.col(0) * S(W.pres_accel);
        if (udot != nullptr)
          for (int i = 0; i < n.nuj; ++i) a_Ok += W.V.col(i) * udot[n.u0 + i];
      }
      if (n.prescribed) alpha_C += W.W.col(0) * S(W.pres_accel);
      if (udot != nullptr)
        for (int i = 0; i < n.nuj; ++i) alpha_C += W.W.col(i) * udot[n.u0 + i];
      W.a = a_Ok + alpha_C.cross(W.p_OkBo) + W.w.cross(W.w.cross(W.p_OkBo));
      W.alpha = alpha_C;
    }
  }

  // The hinge's generalised active forces (spring, damper, motor) added to f at node n's speeds
  // (hinge_torque_revolute, hinge_torque_spherical, the units' hinge verbs).
  template <class S>
  static void hinge(const KaneEngine& e, const Node& n, double t, const S* x, std::vector<S>& f) {
    if (n.nuj == 0 || n.shape == JointShape::Base6) return;
    const Joint& J = e.system_.joints[static_cast<std::size_t>(n.joint)];
    const S* u = x + e.n_q_;
    const std::size_t r = static_cast<std::size_t>(n.u0);
    auto scalar = [](double k, double neutral, double c, const S& q, const S& qd, double motor) {
      S tau = S(0.0);
      if (k != 0) tau -= k * (q - neutral);
      if (c != 0) tau -= c * qd;
      return tau + motor;
    };
    switch (n.shape) {
      case JointShape::Axis1:
      case JointShape::Slide1:
        f[r] += scalar(J.stiffness, J.neutral_angle, J.damping, x[n.q0], u[n.u0],
                       J.motor_revolute.empty() ? 0.0 : J.motor_revolute.value(t)(0));
        break;
      case JointShape::Gimbal2: {
        Eigen::Vector2d motor = Eigen::Vector2d::Zero();
        if (!J.motor_universal.empty()) motor = J.motor_universal.value(t);
        f[r] += scalar(J.stiffness, J.neutral_angle, J.damping, x[n.q0], u[n.u0], motor(0));
        f[r + 1] += scalar(J.stiffness2, J.neutral_angle2, J.damping2, x[n.q0 + 1], u[n.u0 + 1],
                           motor(1));
      } break;
      case JointShape::Rotation3: {
        V3<S> tau = V3<S>::Zero();
        if (J.stiffness != 0) tau -= J.stiffness * rotation_vector(x + n.q0);
        if (J.damping != 0) tau -= J.damping * V3<S>(u[n.u0], u[n.u0 + 1], u[n.u0 + 2]);
        if (!J.motor_spherical.empty()) tau += cst<S>(J.motor_spherical.value(t));
        for (std::size_t i = 0; i < 3; ++i) f[r + i] += tau(static_cast<Eigen::Index>(i));
      } break;
      default:
        break;
    }
  }

  // (t, x) => u' (Kane's equations M u' = f) and the full accelerations in w.
  template <class S>
  static void dynamics(const KaneEngine& e, double t, const S* x, std::vector<TwinWork<S>>& w,
                       std::vector<S>& udot) {
    kinematics(e, t, x, w);
    propagate<S>(e, w, nullptr);
    const std::size_t nn = e.nodes_.size(), nu = static_cast<std::size_t>(e.n_u_);
    // The environment (gravity.cpp): the orbit's tidal tensor T = n^2 (3 z z^T - 1) and zenith.
    M3<S> T_N = M3<S>::Zero();
    V3<S> z_N = V3<S>::Zero();
    double n2 = 0;
    if (e.orbit_) {
      const OrbitFrame o = orbit_frame(e.system_.environment, t);
      n2 = o.n * o.n;
      z_N = cst<S>(o.zenith_N);
      Matrix3d T = (3.0 * n2) * o.zenith_N * o.zenith_N.transpose();
      T.diagonal().array() -= n2;
      T_N = cst<S>(T);
    }
    V3<S> p_NoB0o = V3<S>::Zero();
    if (e.nodes_[0].shape == JointShape::Base6)
      p_NoB0o = V3<S>(x[e.nodes_[0].q0], x[e.nodes_[0].q0 + 1], x[e.nodes_[0].q0 + 2]);

    std::vector<S> M(nu * nu, S(0.0)), f(nu, S(0.0));
    struct Partial {
      std::size_t r;
      V3<S> W, V;  // the body's partial angular velocity, its CM's partial velocity
    };
    std::vector<Partial> partials;
    for (std::size_t k = 0; k < nn; ++k) {
      const Node& n = e.nodes_[k];
      const TwinWork<S>& W = w[k];
      // The body's residual loads: R_B at its CM Bo, T_B (Pass 4).
      V3<S> R_B = -n.mass * W.a, T_B;
      if (n.inertia == Node::Inertia::Isotropic)
        T_B = -(n.I_BBo_B(0, 0) * W.alpha);
      else
        T_B = -(W.I_N * W.alpha) - e.gyro_sign_ * W.w.cross(W.I_N * W.w);
      if (n.body_torque) {
        const Body& body = e.system_.bodies[static_cast<std::size_t>(n.body)];
        const V3<S> Tq = cst<S>(body.torque.value(t));
        if (body.torque_frame == Body::Frame::Body)
          T_B += W.R * Tq;
        else
          T_B += Tq;
      }
      if (e.gravity_) {
        if (!e.orbit_) {
          R_B += n.mass * cst<S>(e.g_N_);
        } else {
          const V3<S> r_c = p_NoB0o + W.p_Bo - cst<S>(e.p_NoO_N_);
          R_B += n.mass * (T_N * r_c);
          if (n.inertia != Node::Inertia::Isotropic) {
            const V3<S> z_B = W.R.transpose() * z_N;
            const V3<S> Iz_N = W.R * (cst<S>(n.I_BBo_B) * z_B);
            T_B += (3.0 * n2) * z_N.cross(Iz_N);
          }
        }
      }
      // The partial velocities of this body from every speed of its ancestors (and its own):
      // a speed r of node a moves S(a) with the twist (W_r, V_r at Ok_a).
      partials.clear();
      for (int a = static_cast<int>(k); a >= 0; a = e.nodes_[static_cast<std::size_t>(a)].parent) {
        const Node& A = e.nodes_[static_cast<std::size_t>(a)];
        const TwinWork<S>& WA = w[static_cast<std::size_t>(a)];
        const V3<S> d = W.p_Bo - WA.p_Ok;
        if (A.shape == JointShape::Base6) {
          for (int i = 0; i < 3; ++i) {
            const V3<S> om = WA.R.col(i);
            partials.push_back({static_cast<std::size_t>(A.u0 + i), om, om.cross(d)});
          }
          for (int i = 0; i < 3; ++i) {
            V3<S> vi = V3<S>::Zero();
            vi(i) = S(1.0);
            partials.push_back({static_cast<std::size_t>(A.u0 + 3 + i), V3<S>::Zero(), vi});
          }
          continue;
        }
        for (int i = 0; i < A.nuj; ++i) {
          const V3<S> om = WA.W.col(i);
          partials.push_back(
              {static_cast<std::size_t>(A.u0 + i), om, V3<S>(WA.V.col(i) + om.cross(d))});
        }
      }
      for (const Partial& pr : partials) {
        f[pr.r] += pr.V.dot(R_B) + pr.W.dot(T_B);
        const V3<S> IW = W.I_N * pr.W;
        for (const Partial& ps : partials)
          M[pr.r * nu + ps.r] += n.mass * pr.V.dot(ps.V) + ps.W.dot(IW);
      }
    }
    for (const Node& n : e.nodes_) hinge(e, n, t, x, f);

    // M u' = f by L D L^T (M symmetric positive definite; dense, unpivoted).
    std::vector<S> L(nu * nu, S(0.0)), D(nu, S(0.0));
    for (std::size_t j = 0; j < nu; ++j) {
      S dj = M[j * nu + j];
      for (std::size_t l = 0; l < j; ++l) dj -= L[j * nu + l] * L[j * nu + l] * D[l];
      if (!(value(dj) > 0))
        throw RunFailure("kane", t, "mass matrix", "not positive definite (a pivot of L D L^T <= 0)");
      D[j] = dj;
      for (std::size_t i = j + 1; i < nu; ++i) {
        S m = M[i * nu + j];
        for (std::size_t l = 0; l < j; ++l) m -= L[i * nu + l] * L[j * nu + l] * D[l];
        L[i * nu + j] = m / dj;
      }
    }
    udot.assign(nu, S(0.0));
    for (std::size_t i = 0; i < nu; ++i) {  // L y = f
      S y = f[i];
      for (std::size_t l = 0; l < i; ++l) y -= L[i * nu + l] * udot[l];
      udot[i] = y;
    }
    for (std::size_t i = 0; i < nu; ++i) udot[i] /= D[i];
    for (std::size_t i = nu; i-- > 0;) {  // L^T u' = y / D
      S y = udot[i];
      for (std::size_t l = i + 1; l < nu; ++l) y -= L[l * nu + i] * udot[l];
      udot[i] = y;
    }
    // A tree with no speed at all (a prescribed base's rigid tree): the remainder accelerations
    // above are the full ones.
    if (!udot.empty()) propagate<S>(e, w, udot.data());
  }

  // ---------------------------------------------------------------------------------------------
  // The flexible twin (a System with a flexible body).  Kane's equations with C's node masses as
  // the particles and its node inertias J_i turning with C's frame (README.md "Flexible bodies":
  // F_r* = -sum_i V_r^i . m_i a_i - sum_B W_r^B . (J_B alpha_B + w_B x J_B w_B)), written
  // particle by particle over the same positions as Pass 1 (docs/flexible-bodies.md "Joints at
  // nodes": R_NJp = R_NP E_Pj, R_NJc = R_NJp R_PJ0 R_J, R_NC = R_NJc E_Cj^T, p_Ok = p_Po + R_NP
  // r_Pj = p_Co + R_NC r_Cj, r = p + Phi eta (+ e 1/2 eta^T G eta, geometric stiffening), node i
  // at r_i likewise).  The velocities, partial velocities and remainder accelerations are the
  // time derivatives of these positions along q' = q'(u), u' = 0 (or the given u'), carried as
  // Taylor coefficients (Jet) of the positions; partial velocities are the rates at u = e_r
  // (prescribed rates zero).  The modal loads -K eta - D eta', the hinge loads, gravity (uniform:
  // m_i g; orbit: m_i T r_i and 3 n^2 z x (J z) on the node inertias) and body torques on C's
  // frame complete f.  The model's integrals (FlexModel) are these same node sums.

  struct JetFrame {
    M3<Jet> R;
    V3<Jet> p;            // the body-frame origin Bo (absolute, from No)
    std::vector<V3<Jet>> pts;  // a flexible body's nodes
    // The joint point Ok (absolute) and the parent-side joint frame R_NJp (output_jet; a free
    // base: Bo and the identity).
    V3<Jet> p_Ok;
    M3<Jet> R_NJp = M3<Jet>::Identity();
  };

  // exp([psi x]) (NodeRotation): R = 1 + (1 - x b) S + a S^2, x = |psi|^2, by the series below
  // x = 1 and the closed forms above.
  static M3<Jet> expso3(const V3<Jet>& psi) {
    const Jet x = psi.squaredNorm();
    Jet a, b;
    if (value(x) < 1.0) {
      double f = 1.0;  // 1 / k!
      std::vector<double> inv(28);
      for (int k = 0; k < 28; ++k) {
        if (k > 0) f /= k;
        inv[static_cast<std::size_t>(k)] = f;
      }
      Jet p = 1.0;
      a = 0.0;
      b = 0.0;
      for (int k = 0; k < 12; ++k) {
        a += p * inv[static_cast<std::size_t>(2 * k + 2)];
        b += p * inv[static_cast<std::size_t>(2 * k + 3)];
        p *= -x;
      }
    } else {
      const Jet th = sqrt(x), c = cos(th), sn = sin(th);
      a = (1.0 - c) / x;
      b = (th - sn) / (x * th);
    }
    M3<Jet> S;
    S << Jet(0.0), -psi(2), psi(1), psi(2), Jet(0.0), -psi(0), -psi(1), psi(0), Jet(0.0);
    M3<Jet> R = (1.0 - x * b) * S + a * (S * S);
    for (int i = 0; i < 3; ++i) R(i, i) += 1.0;
    return R;
  }

  // The displacement Phi eta (+ e 1/2 eta^T G eta) and the rotation vector Psi eta at a node.
  static V3<Jet> displacement(const Eigen::Matrix3Xd& Phi, bool stiff, const Vector3d& ev,
                              const Eigen::MatrixXd& G, const Jet* eta, int nm) {
    V3<Jet> u = V3<Jet>::Zero();
    for (int l = 0; l < std::min<int>(nm, static_cast<int>(Phi.cols())); ++l)
      u += Phi.col(l).cast<Jet>() * eta[l];
    if (stiff) {
      Jet q = 0.0;
      for (int k = 0; k < nm; ++k)
        for (int l = 0; l < nm; ++l) q += (0.5 * G(k, l)) * eta[k] * eta[l];
      u += ev.cast<Jet>() * q;
    }
    return u;
  }
  static V3<Jet> rotvec(const Eigen::Matrix3Xd& Psi, const Jet* eta, int nm) {
    V3<Jet> v = V3<Jet>::Zero();
    for (int l = 0; l < std::min<int>(nm, static_cast<int>(Psi.cols())); ++l)
      v += Psi.col(l).cast<Jet>() * eta[l];
    return v;
  }

  // Positions as Taylor polynomials in time: q (x[0, n_q)) with rates and half accelerations.
  static void jet_positions(const KaneEngine& e, const std::vector<Jet>& q,
                            const std::vector<Jet>& pres, std::vector<JetFrame>& F) {
    F.resize(e.nodes_.size());
    JetFrame ground;
    ground.R = M3<Jet>::Identity();
    ground.p = V3<Jet>::Zero();
    for (std::size_t k = 0; k < e.nodes_.size(); ++k) {
      const Node& n = e.nodes_[k];
      JetFrame& W = F[k];
      if (n.shape == JointShape::Base6) {
        W.R = quat_matrix(q.data() + n.q0 + 3);
        W.p = V3<Jet>(q[static_cast<std::size_t>(n.q0)], q[static_cast<std::size_t>(n.q0) + 1],
                      q[static_cast<std::size_t>(n.q0) + 2]);
        W.p_Ok = W.p;
      } else {
        const JetFrame& P = n.parent >= 0 ? F[static_cast<std::size_t>(n.parent)] : ground;
        V3<Jet> r_Pj = cst<Jet>(n.p_PoJ_P);
        M3<Jet> R_NJp = P.R;
        if (n.parent_attach) {
          const Node& pn = e.nodes_[static_cast<std::size_t>(n.parent)];
          const Jet* eta_P = q.data() + pn.q0 + pn.nqj;
          r_Pj += displacement(n.Phi_Pj, n.stiff_P, n.e_Pj, n.G_Pj, eta_P, pn.nm);
          R_NJp = P.R * expso3(rotvec(n.Psi_Pj, eta_P, pn.nm));
        }
        const M3<Jet> R_NJ0 = n.has_offset ? M3<Jet>(R_NJp * cst<Jet>(n.R_PJ0)) : R_NJp;
        M3<Jet> R_NJc;
        const Jet ang = n.prescribed ? pres[k] : q[static_cast<std::size_t>(n.q0)];
        switch (n.shape) {
          case JointShape::Axis1: {
            const Jet h = 0.5 * ang;
            R_NJc = R_NJ0 * axis_angle<Jet>(n.axis_J, sin(h), cos(h));
          } break;
          case JointShape::Rotation3:
            R_NJc = R_NJ0 * quat_matrix(q.data() + n.q0);
            break;
          case JointShape::Slide1:
            R_NJc = R_NJ0;
            r_Pj += ang * cst<Jet>(n.axis_P);
            break;
          case JointShape::Gimbal2: {
            const Jet h1 = 0.5 * q[static_cast<std::size_t>(n.q0)],
                      h2 = 0.5 * q[static_cast<std::size_t>(n.q0) + 1];
            R_NJc = R_NJ0 * axis_angle<Jet>(n.axis_J, sin(h1), cos(h1)) *
                    axis_angle<Jet>(n.axis2_J, sin(h2), cos(h2));
          } break;
          default:
            R_NJc = R_NJ0;
            break;
        }
        const V3<Jet> p_Ok = P.p + P.R * r_Pj;
        W.p_Ok = p_Ok;
        W.R_NJp = R_NJp;
        V3<Jet> r_Cj = cst<Jet>(n.p_CoJ_C);
        W.R = R_NJc;
        if (n.child_attach) {
          const Jet* eta = q.data() + n.q0 + n.nqj;
          r_Cj += displacement(n.Phi_Cj, n.stiff_C, n.e_Cj, n.G_Cj, eta, n.nm);
          W.R = R_NJc * expso3(rotvec(n.Psi_Cj, eta, n.nm)).transpose();
        }
        W.p = p_Ok - W.R * r_Cj;
      }
      W.pts.clear();
      if (n.flex >= 0) {
        const FlexBody& fb = *e.system_.bodies[static_cast<std::size_t>(n.body)].flex;
        const Jet* eta = q.data() + n.q0 + n.nqj;
        for (const FlexNode& nd : fb.nodes)
          W.pts.push_back(W.p + W.R * (cst<Jet>(nd.p_BoNi_B) +
                                       displacement(nd.Phi_B, fb.geometric_stiffening, nd.e_B,
                                                    nd.G, eta, n.nm)));
      }
    }
  }

  // q with its rate q'(u) and half acceleration (u' = udot, or 0 when udot is null); prescribed
  // joints at t (rates zero when partial).
  static void jet_state(const KaneEngine& e, double t, const Dual* x, const Dual* u,
                        const Dual* udot, bool partial, std::vector<Jet>& q,
                        std::vector<Jet>& pres) {
    q.assign(static_cast<std::size_t>(e.n_q_), Jet());
    pres.assign(e.nodes_.size(), Jet());
    for (int i = 0; i < e.n_q_; ++i) q[static_cast<std::size_t>(i)].a = x[i];
    auto ud = [udot](int i) { return udot ? udot[i] : Dual(0.0); };
    auto quat = [&](int q0, int u0) {
      // q' = q (x) (0, w) / 2, q'' = q' (x) (0, w) / 2 + q (x) (0, w') / 2.
      auto mul = [](const Dual* a, const Dual* w) {  // a (x) (0, w)
        return std::array<Dual, 4>{-(a[1] * w[0] + a[2] * w[1] + a[3] * w[2]),
                                   a[0] * w[0] + a[2] * w[2] - a[3] * w[1],
                                   a[0] * w[1] + a[3] * w[0] - a[1] * w[2],
                                   a[0] * w[2] + a[1] * w[1] - a[2] * w[0]};
      };
      const Dual w[3] = {u[u0], u[u0 + 1], u[u0 + 2]};
      const Dual wd[3] = {ud(u0), ud(u0 + 1), ud(u0 + 2)};
      const Dual* qa = x + q0;
      const std::array<Dual, 4> d1 = mul(qa, w);
      Dual q1[4];
      for (int i = 0; i < 4; ++i) q1[i] = 0.5 * d1[static_cast<std::size_t>(i)];
      const std::array<Dual, 4> d2a = mul(q1, w), d2b = mul(qa, wd);
      for (std::size_t i = 0; i < 4; ++i) {
        q[static_cast<std::size_t>(q0) + i].b = q1[i];
        q[static_cast<std::size_t>(q0) + i].c = 0.25 * (d2a[i] + d2b[i]);
      }
    };
    for (std::size_t k = 0; k < e.nodes_.size(); ++k) {
      const Node& n = e.nodes_[k];
      const std::size_t q0 = static_cast<std::size_t>(n.q0);
      if (n.prescribed) {
        pres[k] = Jet(Dual(n.angle0 + n.motion.angle(t)), Dual(partial ? 0.0 : n.motion.velocity(t)),
                      Dual(partial ? 0.0 : 0.5 * n.motion.accel(t)));
      }
      switch (n.shape) {
        case JointShape::Base6:
          for (std::size_t i = 0; i < 3; ++i) {
            q[q0 + i].b = u[n.u0 + 3 + static_cast<int>(i)];
            q[q0 + i].c = 0.5 * ud(n.u0 + 3 + static_cast<int>(i));
          }
          quat(n.q0 + 3, n.u0);
          break;
        case JointShape::Rotation3:
          quat(n.q0, n.u0);
          break;
        case JointShape::Axis1:
        case JointShape::Slide1:
        case JointShape::Gimbal2:
          if (n.prescribed) break;
          for (int i = 0; i < n.nuj; ++i) {
            q[q0 + static_cast<std::size_t>(i)].b = u[n.u0 + i];
            q[q0 + static_cast<std::size_t>(i)].c = 0.5 * ud(n.u0 + i);
          }
          break;
        default:
          break;
      }
      for (int l = 0; l < n.nm; ++l) {
        q[q0 + static_cast<std::size_t>(n.nqj + l)].b = u[n.u0 + n.nuj + l];
        q[q0 + static_cast<std::size_t>(n.nqj + l)].c = 0.5 * ud(n.u0 + n.nuj + l);
      }
    }
  }

  // The rate (b) and acceleration (2 c) of a point; the angular velocity and acceleration of a
  // frame: [w x] = R' R^T, [alpha x] = skew part of R'' R^T.
  static V3<Dual> rate(const V3<Jet>& p) { return V3<Dual>(p(0).b, p(1).b, p(2).b); }
  static V3<Dual> accel(const V3<Jet>& p) {
    return V3<Dual>(2.0 * p(0).c, 2.0 * p(1).c, 2.0 * p(2).c);
  }
  static M3<Dual> part(const M3<Jet>& R, int which) {
    M3<Dual> m;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) m(i, j) = which == 0 ? R(i, j).a : which == 1 ? R(i, j).b : R(i, j).c;
    return m;
  }
  static V3<Dual> vee_skew(const M3<Dual>& A) {
    return V3<Dual>(0.5 * (A(2, 1) - A(1, 2)), 0.5 * (A(0, 2) - A(2, 0)), 0.5 * (A(1, 0) - A(0, 1)));
  }
  static V3<Dual> ang_rate(const M3<Jet>& R) {
    return vee_skew(M3<Dual>(part(R, 1) * part(R, 0).transpose()));
  }
  static V3<Dual> ang_accel(const M3<Jet>& R) {
    return vee_skew(M3<Dual>(2.0 * part(R, 2) * part(R, 0).transpose()));
  }

  // The rotational inertia that turns with a body's frame, in its axes: a rigid body's I_BBo_B,
  // a flexible body's sum of node inertias J_i (its particles carry the rest).
  static Matrix3d frame_inertia(const KaneEngine& e, const Node& n) {
    if (n.flex < 0) return n.I_BBo_B;
    Matrix3d J = Matrix3d::Zero();
    for (const FlexNode& nd : e.system_.bodies[static_cast<std::size_t>(n.body)].flex->nodes)
      J += 0.5 * (nd.J_Ni_B + nd.J_Ni_B.transpose());
    return J;
  }

  // M u' = f by L D L^T (M symmetric positive definite; dense, unpivoted).
  static void ldlt_solve(double t, std::size_t nu, const std::vector<Dual>& M,
                         const std::vector<Dual>& f, std::vector<Dual>& udot) {
    std::vector<Dual> L(nu * nu, Dual(0.0)), D(nu, Dual(0.0));
    for (std::size_t j = 0; j < nu; ++j) {
      Dual dj = M[j * nu + j];
      for (std::size_t l = 0; l < j; ++l) dj -= L[j * nu + l] * L[j * nu + l] * D[l];
      if (!(value(dj) > 0))
        throw RunFailure("kane", t, "mass matrix", "not positive definite (a pivot of L D L^T <= 0)");
      D[j] = dj;
      for (std::size_t i = j + 1; i < nu; ++i) {
        Dual m = M[i * nu + j];
        for (std::size_t l = 0; l < j; ++l) m -= L[i * nu + l] * L[j * nu + l] * D[l];
        L[i * nu + j] = m / dj;
      }
    }
    udot.assign(nu, Dual(0.0));
    for (std::size_t i = 0; i < nu; ++i) {
      Dual y = f[i];
      for (std::size_t l = 0; l < i; ++l) y -= L[i * nu + l] * udot[l];
      udot[i] = y;
    }
    for (std::size_t i = 0; i < nu; ++i) udot[i] /= D[i];
    for (std::size_t i = nu; i-- > 0;) {
      Dual y = udot[i];
      for (std::size_t l = i + 1; l < nu; ++l) y -= L[l * nu + i] * udot[l];
      udot[i] = y;
    }
  }

  // (t, x) => u' and every node's frame (R, alpha, a of Bo) in w, for a System with flexible
  // bodies.
  static void flex_dynamics(const KaneEngine& e, double t, const Dual* x,
                            std::vector<TwinWork<Dual>>& w, std::vector<Dual>& udot) {
    const std::size_t nn = e.nodes_.size(), nu = static_cast<std::size_t>(e.n_u_);
    const Dual* u = x + e.n_q_;
    std::vector<Jet> q, pres;
    std::vector<JetFrame> F;
    // The remainder: velocities and accelerations at u' = 0.
    jet_state(e, t, x, u, nullptr, false, q, pres);
    jet_positions(e, q, pres, F);
    // Loads at the remainder accelerations: R_i on each particle, T_B on each frame.
    M3<Dual> T_N = M3<Dual>::Zero();
    V3<Dual> z_N = V3<Dual>::Zero();
    double n2 = 0;
    if (e.orbit_) {
      const OrbitFrame o = orbit_frame(e.system_.environment, t);
      n2 = o.n * o.n;
      z_N = cst<Dual>(o.zenith_N);
      Matrix3d T = (3.0 * n2) * o.zenith_N * o.zenith_N.transpose();
      T.diagonal().array() -= n2;
      T_N = cst<Dual>(T);
    }
    auto point_load = [&](double m, const V3<Jet>& p) {
      V3<Dual> R = -m * accel(p);
      if (e.gravity_) {
        if (!e.orbit_)
          R += m * cst<Dual>(e.g_N_);
        else
          R += m * (T_N * V3<Dual>(V3<Dual>(p(0).a, p(1).a, p(2).a) - cst<Dual>(e.p_NoO_N_)));
      }
      return R;
    };
    std::vector<std::vector<V3<Dual>>> Rp(nn);
    std::vector<V3<Dual>> TB(nn);
    std::vector<M3<Dual>> IN(nn);
    for (std::size_t k = 0; k < nn; ++k) {
      const Node& n = e.nodes_[k];
      const JetFrame& W = F[k];
      const M3<Dual> R = part(W.R, 0);
      IN[k] = R * cst<Dual>(frame_inertia(e, n)) * R.transpose();
      const V3<Dual> om = ang_rate(W.R);
      V3<Dual> T = -(IN[k] * ang_accel(W.R)) - e.gyro_sign_ * om.cross(IN[k] * om);
      if (n.body_torque) {
        const Body& body = e.system_.bodies[static_cast<std::size_t>(n.body)];
        const V3<Dual> Tq = cst<Dual>(body.torque.value(t));
        T += body.torque_frame == Body::Frame::Body ? V3<Dual>(R * Tq) : Tq;
      }
      if (e.gravity_ && e.orbit_) T += (3.0 * n2) * z_N.cross(IN[k] * z_N);
      TB[k] = T;
      if (n.flex < 0) {
        Rp[k].push_back(point_load(n.mass, W.p));
      } else {
        const FlexBody& fb = *e.system_.bodies[static_cast<std::size_t>(n.body)].flex;
        for (std::size_t i = 0; i < W.pts.size(); ++i) Rp[k].push_back(point_load(fb.nodes[i].mass, W.pts[i]));
      }
    }
    // Partial velocities of every particle and frame: the rates at u = e_r.
    std::vector<std::vector<std::vector<V3<Dual>>>> Vp(nu);
    std::vector<std::vector<V3<Dual>>> Wp(nu);
    std::vector<Dual> er(nu, Dual(0.0));
    for (std::size_t r = 0; r < nu; ++r) {
      er.assign(nu, Dual(0.0));
      er[r] = 1.0;
      jet_state(e, t, x, er.data(), nullptr, true, q, pres);
      jet_positions(e, q, pres, F);
      Vp[r].resize(nn);
      Wp[r].resize(nn);
      for (std::size_t k = 0; k < nn; ++k) {
        Wp[r][k] = ang_rate(F[k].R);
        if (e.nodes_[k].flex < 0)
          Vp[r][k].push_back(rate(F[k].p));
        else
          for (const V3<Jet>& p : F[k].pts) Vp[r][k].push_back(rate(p));
      }
    }
    std::vector<Dual> M(nu * nu, Dual(0.0)), f(nu, Dual(0.0));
    for (std::size_t k = 0; k < nn; ++k) {
      const Node& n = e.nodes_[k];
      std::vector<double> mass;
      if (n.flex < 0)
        mass.push_back(n.mass);
      else
        for (const FlexNode& nd : e.system_.bodies[static_cast<std::size_t>(n.body)].flex->nodes)
          mass.push_back(nd.mass);
      for (std::size_t r = 0; r < nu; ++r) {
        f[r] += Wp[r][k].dot(TB[k]);
        for (std::size_t i = 0; i < mass.size(); ++i) f[r] += Vp[r][k][i].dot(Rp[k][i]);
        const V3<Dual> IW = IN[k] * Wp[r][k];
        for (std::size_t s2 = r; s2 < nu; ++s2) {
          Dual m = Wp[s2][k].dot(IW);
          for (std::size_t i = 0; i < mass.size(); ++i) m += mass[i] * Vp[r][k][i].dot(Vp[s2][k][i]);
          M[r * nu + s2] += m;
          if (s2 != r) M[s2 * nu + r] += m;
        }
      }
      // Modal stiffness and damping.
      if (n.flex >= 0) {
        const FlexModel& FM = e.flex_[static_cast<std::size_t>(n.flex)];
        for (int l = 0; l < n.nm; ++l) {
          Dual g = 0.0;
          for (int m2 = 0; m2 < n.nm; ++m2)
            g += FM.K(l, m2) * x[n.q0 + n.nqj + m2] + FM.D(l, m2) * u[n.u0 + n.nuj + m2];
          f[static_cast<std::size_t>(n.u0 + n.nuj + l)] -= g;
        }
      }
    }
    for (const Node& n : e.nodes_) hinge(e, n, t, x, f);
    udot.clear();
    if (nu > 0) ldlt_solve(t, nu, M, f, udot);
    // The full accelerations.
    jet_state(e, t, x, u, nu > 0 ? udot.data() : nullptr, false, q, pres);
    jet_positions(e, q, pres, F);
    w.assign(nn, TwinWork<Dual>());
    for (std::size_t k = 0; k < nn; ++k) {
      w[k].R = part(F[k].R, 0);
      w[k].alpha = ang_accel(F[k].R);
      w[k].a = accel(F[k].p);
      if (e.nodes_[k].prescribed) w[k].pres_accel = e.nodes_[k].motion.accel(t);
    }
  }

  // pack()'s zero linear momentum for a System with flexible bodies: P0 = sum m_i v_i at
  // v_B0o = 0 (prescribed joints at t = 0).
  static V3<Dual> flex_momentum(const KaneEngine& e, const std::vector<Dual>& x0) {
    std::vector<Jet> q, pres;
    std::vector<JetFrame> F;
    jet_state(e, 0.0, x0.data(), x0.data() + e.n_q_, nullptr, false, q, pres);
    jet_positions(e, q, pres, F);
    V3<Dual> P = V3<Dual>::Zero();
    for (std::size_t k = 0; k < e.nodes_.size(); ++k) {
      const Node& n = e.nodes_[k];
      if (n.flex < 0) {
        P += n.mass * rate(F[k].p);
      } else {
        const FlexBody& fb = *e.system_.bodies[static_cast<std::size_t>(n.body)].flex;
        for (std::size_t i = 0; i < F[k].pts.size(); ++i) P += fb.nodes[i].mass * rate(F[k].pts[i]);
      }
    }
    return P;
  }

  // TreeState and TreeTangent => x(0) and dx/de (as duals) through pack(): the engine's own pack
  // for the values; the derivatives field by field (a quaternion q's right perturbation
  // q (x) (1, e dtheta / 2) gives dq = q (x) (0, dtheta) / 2, q normalised as pack() stores it),
  // and the zero-linear-momentum base velocity's derivative from the twin's momentum.
  static void pack(KaneEngine& e, const TreeState& s, const TreeTangent& ds,
                   std::vector<Dual>& x) {
    const std::size_t size = static_cast<std::size_t>(e.n_q_ + e.n_u_);
    std::vector<double> xv(size, 0.0);
    e.pack(s, xv.data());
    if (ds.joints.size() != e.nodes_.size())
      throw InputError(where(e.system_) + ": tree tangent has " + std::to_string(ds.joints.size()) +
                       " joints, the scene " + std::to_string(e.nodes_.size()));
    x.assign(size, Dual());
    for (std::size_t i = 0; i < size; ++i) x[i].v = xv[i];
    Dual* u = x.data() + e.n_q_;
    auto quat_tangent = [&x](int q0, const Vector3d& dtheta) {
      const double w = x[static_cast<std::size_t>(q0)].v;
      const Vector3d v(x[static_cast<std::size_t>(q0) + 1].v, x[static_cast<std::size_t>(q0) + 2].v,
                       x[static_cast<std::size_t>(q0) + 3].v);
      const Vector3d dv = 0.5 * (w * dtheta + v.cross(dtheta));
      x[static_cast<std::size_t>(q0)].d = -0.5 * v.dot(dtheta);
      for (std::size_t i = 0; i < 3; ++i)
        x[static_cast<std::size_t>(q0) + 1 + i].d = dv(static_cast<Eigen::Index>(i));
    };
    for (const Node& n : e.nodes_) {
      const TreeTangent::JointTangent& jt = ds.joints[static_cast<std::size_t>(n.joint)];
      const std::size_t q0 = static_cast<std::size_t>(n.q0), u0 = static_cast<std::size_t>(n.u0);
      switch (n.shape) {
        case JointShape::Base6:
          for (std::size_t i = 0; i < 3; ++i) {
            const Eigen::Index ii = static_cast<Eigen::Index>(i);
            x[q0 + i].d = ds.dp_NoBo_N(ii);
            u[u0 + i].d = ds.dw_NB_B(ii);
            u[u0 + 3 + i].d = ds.dv_NBo_N(ii);
          }
          quat_tangent(n.q0 + 3, ds.dtheta_B);
          break;
        case JointShape::Axis1:
        case JointShape::Slide1:
          if (n.prescribed) break;  // follows its profile
          x[q0].d = jt.angle;
          u[u0].d = jt.rate;
          break;
        case JointShape::Gimbal2:
          x[q0].d = jt.angle;
          x[q0 + 1].d = jt.angle2;
          u[u0].d = jt.rate;
          u[u0 + 1].d = jt.rate2;
          break;
        case JointShape::Rotation3:
          quat_tangent(n.q0, jt.dtheta_J);
          for (std::size_t i = 0; i < 3; ++i) u[u0 + i].d = jt.w_PC_C(static_cast<Eigen::Index>(i));
          break;
        default:
          break;
      }
      if (n.nm > 0) {  // a flexible child's modal coordinates and rates (per body)
        const std::size_t b = static_cast<std::size_t>(n.body);
        for (int l = 0; l < n.nm; ++l) {
          const Eigen::Index li = l;
          if (b < ds.eta.size() && ds.eta[b].size() > li)
            x[q0 + static_cast<std::size_t>(n.nqj + l)].d = ds.eta[b](li);
          if (b < ds.eta_rate.size() && ds.eta_rate[b].size() > li)
            u[u0 + static_cast<std::size_t>(n.nuj + l)].d = ds.eta_rate[b](li);
        }
      }
    }
    // Zero linear momentum (pack(): a free base only, prescribed joints at t = 0): the base
    // velocity -P0 / m_total, P0 = sum m v_Bo at v_B0o = 0; its value stays pack()'s.
    if (e.system_.zero_linear_momentum && e.system_.base_is_free()) {
      const std::size_t v0 = static_cast<std::size_t>(e.nodes_[0].u0) + 3;
      std::vector<Dual> x0(x);
      for (std::size_t i = 0; i < 3; ++i) x0[static_cast<std::size_t>(e.n_q_) + v0 + i] = Dual();
      V3<Dual> P = V3<Dual>::Zero();
      if (!e.flex_.empty()) {
        P = flex_momentum(e, x0);
      } else {
        std::vector<TwinWork<Dual>> w;
        kinematics<Dual>(e, 0.0, x0.data(), w);
        for (std::size_t k = 0; k < e.nodes_.size(); ++k) P += e.nodes_[k].mass * w[k].v;
      }
      for (std::size_t i = 0; i < 3; ++i)
        u[v0 + i].d = -P(static_cast<Eigen::Index>(i)).d / e.total_mass_;
    }
  }

  // ---------------------------------------------------------------------------------------------
  // The output row (output_row(): diagnostics.cpp, rigid_fast_path.cpp, loads.cpp, gravity.cpp,
  // the units' output verbs; RowWriter::body of core/output_layout.cpp for the orbit columns),
  // every column in layout() order, in dual numbers: output_jet below.  A quaternion in duals
  // (Hamilton's product) for the attitudes.
  struct Quat {
    Dual w, x, y, z;
    Quat operator*(const Quat& b) const {
      return {w * b.w - x * b.x - y * b.y - z * b.z, w * b.x + x * b.w + y * b.z - z * b.y,
              w * b.y - x * b.z + y * b.w + z * b.x, w * b.z + x * b.y - y * b.x + z * b.w};
    }
    Dual norm() const { return sqrt(w * w + x * x + y * y + z * z); }
    Quat normalized() const {
      const Dual n = norm();
      return {w / n, x / n, y / n, z / n};
    }
  };
  static Quat quat(const Quaterniond& q) { return {q.w(), q.x(), q.y(), q.z()}; }
  static Quat quat(const Dual* q) { return {q[0], q[1], q[2], q[3]}; }
  static Quat axis_quat(const Vector3d& k, const Dual& angle) {
    const Dual h = 0.5 * angle, s = sin(h);
    return {cos(h), s * k.x(), s * k.y(), s * k.z()};
  }
  static Dual asin_clamped(const Dual& a) {  // asin of a clamped to [-1, 1] (roll_pitch_yaw)
    if (a.v >= 1.0) return Dual(std::asin(1.0));
    if (a.v <= -1.0) return Dual(std::asin(-1.0));
    return {std::asin(a.v), a.d / std::sqrt(1.0 - a.v * a.v)};
  }

  // The unit quaternion of a rotation vector (rot::from_rotation_vector): (cos t/2, sin(t/2)/t
  // psi), t = |psi|, by the series in t^2 below t = 1e-2 (errors below 1e-20; the derivative
  // stays finite at psi = 0).
  static Quat quat_of_rotation_vector(const V3<Dual>& psi) {
    const Dual t2 = psi.squaredNorm();
    Dual c, f;
    if (t2.v < 1e-4) {
      c = 1.0 - t2 * (1.0 / 8.0 - t2 * (1.0 / 384.0 - t2 / 46080.0));
      f = 0.5 - t2 * (1.0 / 48.0 - t2 * (1.0 / 3840.0 - t2 / 645120.0));
    } else {
      const Dual th = sqrt(t2);
      c = cos(0.5 * th);
      f = sin(0.5 * th) / th;
    }
    return {c, f * psi(0), f * psi(1), f * psi(2)};
  }

  // The output row of any covered System (rigid trees and flexible bodies) from the positions of
  // Pass 1 as Taylor polynomials in time (jet_positions) along q' = q'(u), u' = the twin's u':
  // every mass point's position, velocity and acceleration (a rigid body's CM, a flexible body's
  // nodes, their masses m_i) and every frame's R, w, alpha, with the rotational inertia that
  // turns with it (a rigid body's I_BBo_B, a flexible body's node inertias J_i: frame_inertia).
  // The run's modal integrals (FlexModel, FlexWork) are these node sums (README.md "Flexible
  // bodies"), so its columns are, per body B (I_N = R J_B R^T):
  //   T = sum 1/2 m_i v_i.v_i + 1/2 w.I_N w,  P = sum m_i v_i,  H = sum m_i (x_i - cm) x v_i + I_N w;
  //   V = springs + 1/2 eta^T K eta + gravity (uniform -g . sum m_i x_i; orbit sum -1/2 m_i r_i^T
  //     T r_i + 3/2 n^2 z.I_N z - 1/2 n^2 tr J_B, r_i = x_i - p_O);
  //   joint loads: F_N = -F_sub, M_J_N = -M_sub, S(k)'s sums about Ok of R_i = -m_i a_i + F_g,i
  //     and T_B = T_ext - I_N alpha - s_g w x I_N w + 3 n^2 z x I_N z (orbit);
  //   a prescribed joint's drive -W . M_sub - V . F_sub, W (revolute) or V (prismatic) R_NJp
  //     axis_P;  attitudes q_NC = q_NJp q(psi_P) q_PJ0 q_J q(psi_C)^-1 (q(psi): quat_of_rotation_
  //     vector of the node rotations Psi eta);
  //   w_NB_B = R^T w;  the joint coordinates and rates from x (a prescribed joint: its profile);
  //   the quaternions written with qw >= 0 (the sign by value: RowWriter::body);
  //   power (motors and dampers with the scene's dampers, drives, body torques, the modal
  //   damping -eta'^T D eta' with the scene's D), the external moment (body torques, a
  //   prescribed base's reaction moved to the CM, gravity's moment about the CM), roll/pitch/yaw
  //   of R_OB = R_NO^T R_NB and w_OB_B = w_B - R^T w_NO (orbit), J = E - w_NO . (H + (p_cm -
  //   p_O) x P), kane's extras (T, V, H_N, P_N, the largest |q| - 1 of the stored quaternions).
  static void output_jet(const KaneEngine& e, double t, const Dual* x, std::vector<Dual>& row) {
    const std::size_t nn = e.nodes_.size();
    const Dual* u = x + e.n_q_;
    std::vector<Dual> udot;
    {
      std::vector<TwinWork<Dual>> w;
      if (e.flex_.empty())
        dynamics<Dual>(e, t, x, w, udot);
      else
        flex_dynamics(e, t, x, w, udot);
    }
    std::vector<Jet> q, pres;
    std::vector<JetFrame> F;
    jet_state(e, t, x, u, udot.empty() ? nullptr : udot.data(), false, q, pres);
    jet_positions(e, q, pres, F);
    const OutputLayout& L = e.layout_;
    row.assign(L.size(), Dual(std::numeric_limits<double>::quiet_NaN()));
    row[0] = t;
    auto val = [](const V3<Jet>& p) { return V3<Dual>(p(0).a, p(1).a, p(2).a); };

    OrbitFrame o;
    M3<Dual> T_N = M3<Dual>::Zero();
    V3<Dual> z_N = V3<Dual>::Zero();
    double n2 = 0;
    if (e.orbit_) {
      o = orbit_frame(e.system_.environment, t);
      n2 = o.n * o.n;
      z_N = cst<Dual>(o.zenith_N);
      Matrix3d T = (3.0 * n2) * o.zenith_N * o.zenith_N.transpose();
      T.diagonal().array() -= n2;
      T_N = cst<Dual>(T);
    }
    const V3<Dual> p_O = cst<Dual>(e.p_NoO_N_);

    // Per body: frame, mass points, loads.
    struct Pt {
      double m;
      V3<Dual> x, v, a, Fg;
    };
    std::vector<std::vector<Pt>> pts(nn);
    std::vector<M3<Dual>> R(nn), I_N(nn);
    std::vector<V3<Dual>> om(nn), al(nn), T_ext(nn, V3<Dual>::Zero()), tg(nn, V3<Dual>::Zero());
    std::vector<Matrix3d> J_B(nn);
    Dual M_total = 0.0;
    for (std::size_t k = 0; k < nn; ++k) {
      const Node& n = e.nodes_[k];
      R[k] = part(F[k].R, 0);
      om[k] = ang_rate(F[k].R);
      al[k] = ang_accel(F[k].R);
      J_B[k] = frame_inertia(e, n);
      I_N[k] = R[k] * cst<Dual>(J_B[k]) * R[k].transpose();
      auto add = [&](double m, const V3<Jet>& p) {
        Pt pt{m, val(p), rate(p), accel(p), V3<Dual>::Zero()};
        if (e.gravity_) pt.Fg = e.orbit_ ? V3<Dual>(m * (T_N * V3<Dual>(pt.x - p_O))) : V3<Dual>(m * cst<Dual>(e.g_N_));
        pts[k].push_back(pt);
      };
      if (n.flex < 0) {
        add(n.mass, F[k].p);
      } else {
        const FlexBody& fb = *e.system_.bodies[static_cast<std::size_t>(n.body)].flex;
        for (std::size_t i = 0; i < F[k].pts.size(); ++i) add(fb.nodes[i].mass, F[k].pts[i]);
      }
      if (n.body_torque) {
        const Body& body = e.system_.bodies[static_cast<std::size_t>(n.body)];
        const V3<Dual> Tq = cst<Dual>(body.torque.value(t));
        T_ext[k] = body.torque_frame == Body::Frame::Body ? V3<Dual>(R[k] * Tq) : Tq;
      }
      if (e.orbit_) tg[k] = (3.0 * n2) * z_N.cross(V3<Dual>(I_N[k] * z_N));
      for (const Pt& pt : pts[k]) M_total += pt.m;
    }

    // Joint loads: S(k)'s sums about Ok with the full accelerations.
    std::vector<V3<Dual>> F_sub(nn, V3<Dual>::Zero()), M_sub(nn, V3<Dual>::Zero());
    for (std::size_t k = 0; k < nn; ++k) {
      const V3<Dual> T_B = -(I_N[k] * al[k]) - e.gyro_sign_ * om[k].cross(V3<Dual>(I_N[k] * om[k])) +
                           T_ext[k] + tg[k];
      for (int a = static_cast<int>(k); a >= 0; a = e.nodes_[static_cast<std::size_t>(a)].parent) {
        const std::size_t ai = static_cast<std::size_t>(a);
        const V3<Dual> pOk = val(F[ai].p_Ok);
        M_sub[ai] += T_B;
        for (const Pt& pt : pts[k]) {
          const V3<Dual> Ri = -pt.m * pt.a + pt.Fg;
          F_sub[ai] += Ri;
          M_sub[ai] += V3<Dual>(pt.x - pOk).cross(Ri);
        }
      }
    }
    std::vector<Dual> pres_torque(nn, Dual(0.0));
    for (std::size_t k = 0; k < nn; ++k) {
      const Node& n = e.nodes_[k];
      if (!n.prescribed) continue;
      const V3<Dual> ax = part(F[k].R_NJp, 0) * cst<Dual>(n.axis_P);
      pres_torque[k] = n.slides ? Dual(-ax.dot(F_sub[k])) : Dual(-ax.dot(M_sub[k]));
    }

    // Momenta and energies.
    Dual T2 = 0.0;
    V3<Dual> P = V3<Dual>::Zero(), first_moment = V3<Dual>::Zero(), H = V3<Dual>::Zero();
    for (std::size_t k = 0; k < nn; ++k) {
      for (const Pt& pt : pts[k]) {
        T2 += pt.m * pt.v.dot(pt.v);
        P += pt.m * pt.v;
        first_moment += pt.m * pt.x;
      }
      const V3<Dual> h = I_N[k] * om[k];
      T2 += om[k].dot(h);
      H += h;
    }
    const V3<Dual> p_cm = first_moment / M_total;
    for (std::size_t k = 0; k < nn; ++k)
      for (const Pt& pt : pts[k]) H += V3<Dual>(pt.x - p_cm).cross(V3<Dual>(pt.m * pt.v));
    const Dual T = 0.5 * T2;
    Dual V = 0.0;
    for (const Node& n : e.nodes_) {
      if (n.hinge_load) {
        const Joint& J = e.system_.joints[static_cast<std::size_t>(n.joint)];
        if (J.stiffness != 0 || J.stiffness2 != 0) switch (n.shape) {
            case JointShape::Axis1:
            case JointShape::Slide1: {
              const Dual d = x[n.q0] - J.neutral_angle;
              V += 0.5 * J.stiffness * d * d;
            } break;
            case JointShape::Gimbal2: {
              const Dual d1 = x[n.q0] - J.neutral_angle, d2 = x[n.q0 + 1] - J.neutral_angle2;
              V += 0.5 * J.stiffness * d1 * d1 + 0.5 * J.stiffness2 * d2 * d2;
            } break;
            case JointShape::Rotation3:
              V += 0.5 * J.stiffness * rotation_vector(x + n.q0).squaredNorm();
              break;
            default:
              break;
          }
      }
      if (n.nm > 0) {  // strain energy 1/2 eta^T K eta
        const Eigen::MatrixXd& K = e.flex_[static_cast<std::size_t>(n.flex)].K;
        for (int l = 0; l < n.nm; ++l)
          for (int m = 0; m < n.nm; ++m) V += 0.5 * K(l, m) * x[n.q0 + n.nqj + l] * x[n.q0 + n.nqj + m];
      }
    }
    if (e.gravity_)
      for (std::size_t k = 0; k < nn; ++k) {
        for (const Pt& pt : pts[k]) {
          if (!e.orbit_) {
            V -= cst<Dual>(e.g_N_).dot(V3<Dual>(pt.m * pt.x));
          } else {
            const V3<Dual> r = pt.x - p_O;
            const Dual zr = z_N.dot(r);
            V -= 0.5 * pt.m * n2 * (3.0 * zr * zr - r.squaredNorm());
          }
        }
        if (e.orbit_) V += 1.5 * n2 * z_N.dot(V3<Dual>(I_N[k] * z_N)) - 0.5 * n2 * J_B[k].trace();
      }

    // Attitudes and body columns.
    std::vector<Quat> qN(nn);
    Dual quat_err = 0.0;
    auto track = [&quat_err](const Quat& qq) {
      const Dual err = abs(qq.norm() - 1.0);
      if (err.v > quat_err.v) quat_err = err;
    };
    for (std::size_t k = 0; k < nn; ++k) {
      const Node& n = e.nodes_[k];
      if (n.shape == JointShape::Base6) {
        const Quat qq = quat(x + n.q0 + 3);
        track(qq);
        qN[k] = qq.normalized();
      } else {
        Quat qJ{1.0, 0.0, 0.0, 0.0};
        switch (n.shape) {
          case JointShape::Axis1:
            qJ = axis_quat(n.axis_J, n.prescribed ? pres[k].a : x[n.q0]);
            break;
          case JointShape::Rotation3: {
            const Quat qq = quat(x + n.q0);
            track(qq);
            qJ = qq.normalized();
          } break;
          case JointShape::Gimbal2:
            qJ = axis_quat(n.axis_J, x[n.q0]) * axis_quat(n.axis2_J, x[n.q0 + 1]);
            break;
          default:
            break;
        }
        Quat qNJp = n.parent >= 0 ? qN[static_cast<std::size_t>(n.parent)] : Quat{1.0, 0.0, 0.0, 0.0};
        if (n.parent_attach) {
          const Node& pn = e.nodes_[static_cast<std::size_t>(n.parent)];
          V3<Dual> psi = V3<Dual>::Zero();
          for (int l = 0; l < std::min<int>(pn.nm, static_cast<int>(n.Psi_Pj.cols())); ++l)
            psi += cst<Dual>(Vector3d(n.Psi_Pj.col(l))) * x[pn.q0 + pn.nqj + l];
          qNJp = qNJp * quat_of_rotation_vector(psi);
        }
        Quat qq = n.has_offset ? qNJp * quat(n.q_PJ0) * qJ : qNJp * qJ;
        if (n.child_attach) {
          V3<Dual> psi = V3<Dual>::Zero();
          for (int l = 0; l < std::min<int>(n.nm, static_cast<int>(n.Psi_Cj.cols())); ++l)
            psi -= cst<Dual>(Vector3d(n.Psi_Cj.col(l))) * x[n.q0 + n.nqj + l];
          qq = qq * quat_of_rotation_vector(psi);  // q(psi_C)^-1 = q(-psi_C)
        }
        qN[k] = qq.normalized();
      }
      const V3<Dual> w_B = R[k].transpose() * om[k];
      const int b = n.body;
      const std::size_t cw = static_cast<std::size_t>(L.body_w(b));
      for (std::size_t i = 0; i < 3; ++i) row[cw + i] = w_B(static_cast<Eigen::Index>(i));
      const double sg = qN[k].w.v < 0 ? -1.0 : 1.0;
      const Quat qc{sg * qN[k].w, sg * qN[k].x, sg * qN[k].y, sg * qN[k].z};
      row[cw + 3] = qc.w;
      row[cw + 4] = qc.x;
      row[cw + 5] = qc.y;
      row[cw + 6] = qc.z;
      if (L.lvlh(b) >= 0) {
        const Dual qa[4] = {qc.w, qc.x, qc.y, qc.z};
        const M3<Dual> R_NB = quat_matrix(qa);
        const M3<Dual> Ro = cst<Dual>(Matrix3d(o.R_NO.transpose())) * R_NB;
        const Dual sp = -Ro(2, 0);
        const Dual pitch = asin_clamped(sp);
        Dual roll = 0.0, yaw;
        if (std::abs(sp.v) > 1.0 - 1e-12) {
          yaw = atan2(-Ro(0, 1), Ro(1, 1));
        } else {
          roll = atan2(Ro(2, 1), Ro(2, 2));
          yaw = atan2(Ro(1, 0), Ro(0, 0));
        }
        const V3<Dual> w_OB = w_B - R_NB.transpose() * cst<Dual>(o.w_NO_N);
        const std::size_t c0 = static_cast<std::size_t>(L.lvlh(b));
        row[c0] = roll;
        row[c0 + 1] = pitch;
        row[c0 + 2] = yaw;
        for (std::size_t i = 0; i < 3; ++i) row[c0 + 3 + i] = w_OB(static_cast<Eigen::Index>(i));
      }
    }

    // Joints, modal coordinates, positions, loads, power, external moment.
    Dual Pw = 0.0;
    V3<Dual> M_ext = V3<Dual>::Zero();
    for (std::size_t k = 0; k < nn; ++k) {
      const Node& n = e.nodes_[k];
      const Joint& J = e.system_.joints[k];
      const std::size_t c0 = static_cast<std::size_t>(L.joint_first(n.joint));
      switch (n.shape) {
        case JointShape::Axis1:
        case JointShape::Slide1:
          if (n.prescribed) {
            row[c0] = pres[k].a;
            row[c0 + 1] = pres[k].b;
            row[c0 + 2] = pres_torque[k];
          } else {
            row[c0] = x[n.q0];
            row[c0 + 1] = u[n.u0];
          }
          break;
        case JointShape::Rotation3:
          for (std::size_t i = 0; i < 3; ++i) row[c0 + i] = u[n.u0 + static_cast<int>(i)];
          break;
        case JointShape::Gimbal2:
          row[c0] = x[n.q0];
          row[c0 + 1] = x[n.q0 + 1];
          row[c0 + 2] = u[n.u0];
          row[c0 + 3] = u[n.u0 + 1];
          break;
        default:
          break;
      }
      if (n.nm > 0) {
        const std::size_t cm0 = static_cast<std::size_t>(L.modal_first(n.body));
        const std::size_t nm = static_cast<std::size_t>(n.nm);
        for (std::size_t l = 0; l < nm; ++l) {
          row[cm0 + l] = x[static_cast<std::size_t>(n.q0 + n.nqj) + l];
          row[cm0 + nm + l] = u[static_cast<std::size_t>(n.u0 + n.nuj) + l];
        }
        const Eigen::MatrixXd& D = e.flex_[static_cast<std::size_t>(n.flex)].D_P;
        for (int l = 0; l < n.nm; ++l)
          for (int m = 0; m < n.nm; ++m) Pw -= u[n.u0 + n.nuj + l] * D(l, m) * u[n.u0 + n.nuj + m];
      }
      const std::size_t cp = static_cast<std::size_t>(L.body_position(n.body));
      const V3<Dual> pBo = val(F[k].p);
      for (std::size_t i = 0; i < 3; ++i) row[cp + i] = pBo(static_cast<Eigen::Index>(i));
      if (n.shape != JointShape::Base6) {
        const V3<Dual> F_C = R[k].transpose() * V3<Dual>(-F_sub[k]),
                       M_C = R[k].transpose() * V3<Dual>(-M_sub[k]);
        const std::size_t cl = static_cast<std::size_t>(L.joint_load(n.joint));
        for (std::size_t i = 0; i < 3; ++i) {
          row[cl + i] = F_C(static_cast<Eigen::Index>(i));
          row[cl + 3 + i] = M_C(static_cast<Eigen::Index>(i));
        }
      }
      if (n.prescribed) {
        Pw += pres_torque[k] * pres[k].b;
      } else {
        switch (n.shape) {
          case JointShape::Axis1:
          case JointShape::Slide1: {
            const Dual r = u[n.u0];
            const double motor = J.motor_revolute.empty() ? 0.0 : J.motor_revolute.value(t)(0);
            Pw += (motor - n.damping_P * r) * r;
          } break;
          case JointShape::Gimbal2: {
            Eigen::Vector2d motor = Eigen::Vector2d::Zero();
            if (!J.motor_universal.empty()) motor = J.motor_universal.value(t);
            const Dual r1 = u[n.u0], r2 = u[n.u0 + 1];
            Pw += (motor(0) - n.damping_P * r1) * r1 + (motor(1) - n.damping2_P * r2) * r2;
          } break;
          case JointShape::Rotation3: {
            const V3<Dual> w_PC_C(u[n.u0], u[n.u0 + 1], u[n.u0 + 2]);
            Vector3d motor = Vector3d::Zero();
            if (!J.motor_spherical.empty()) motor = J.motor_spherical.value(t);
            Pw += V3<Dual>(cst<Dual>(motor) - n.damping_P * w_PC_C).dot(w_PC_C);
          } break;
          default:
            break;
        }
      }
      if (n.body_torque) {
        Pw += T_ext[k].dot(om[k]);
        M_ext += T_ext[k];
      }
      if (e.gravity_) {
        for (const Pt& pt : pts[k]) M_ext += V3<Dual>(pt.x - p_cm).cross(pt.Fg);
        M_ext += tg[k];
      }
    }
    if (e.nodes_[0].shape != JointShape::Base6)  // a prescribed base: N's load, moved to the CM
      M_ext += V3<Dual>(-M_sub[0]) + V3<Dual>(val(F[0].p_Ok) - p_cm).cross(V3<Dual>(-F_sub[0]));
    for (std::size_t i = 0; i < 3; ++i) {
      const Eigen::Index ii = static_cast<Eigen::Index>(i);
      row[static_cast<std::size_t>(L.H_vector()) + i] = H(ii);
      row[static_cast<std::size_t>(L.cm()) + i] = p_cm(ii);
      row[static_cast<std::size_t>(L.external_moment()) + i] = M_ext(ii);
    }
    // |H| at H = 0 (a system at rest) has no derivative: |e dH| is a cone. Its symmetric
    // derivative, 0 (what a central difference gives), rather than sqrt's 0/0.
    Dual H_norm = H.norm();
    if (H_norm.v == 0) H_norm.d = 0;
    row[static_cast<std::size_t>(L.H())] = H_norm;
    row[static_cast<std::size_t>(L.E())] = T + V;
    row[static_cast<std::size_t>(L.P())] = Pw;
    if (e.orbit_) {
      const V3<Dual> H_O = H + V3<Dual>(p_cm - p_O).cross(P);
      row[static_cast<std::size_t>(L.J())] = T + V - cst<Dual>(o.w_NO_N).dot(H_O);
    }
    std::size_t c = static_cast<std::size_t>(e.extra0_);
    row[c++] = T;
    row[c++] = V;
    for (Eigen::Index i = 0; i < 3; ++i) row[c++] = H(i);
    for (Eigen::Index i = 0; i < 3; ++i) row[c++] = P(i);
    row[c++] = quat_err;
  }

  // rhs() at x + e dx with dual x: the kinematical equations (the units' q_rates: q' = 1/2 q (x)
  // (0, w) with q as stored, not normalised; q' = u for the scalar joints and the modal
  // coordinates) and u' from the rigid or the flexible twin.
  static void rhs(const KaneEngine& e, double t, const Dual* x, Dual* xdot) {
    std::vector<TwinWork<Dual>> w;
    std::vector<Dual> udot;
    if (e.flex_.empty())
      dynamics<Dual>(e, t, x, w, udot);
    else
      flex_dynamics(e, t, x, w, udot);
    const Dual* u = x + e.n_q_;
    auto quat_rate = [&](int q0, int u0) {  // rot::quat_rate_body
      const Dual *q = x + q0, *wb = u + u0;
      xdot[q0] = 0.5 * (-(q[1] * wb[0]) - q[2] * wb[1] - q[3] * wb[2]);
      xdot[q0 + 1] = 0.5 * (q[0] * wb[0] + q[2] * wb[2] - q[3] * wb[1]);
      xdot[q0 + 2] = 0.5 * (q[0] * wb[1] + q[3] * wb[0] - q[1] * wb[2]);
      xdot[q0 + 3] = 0.5 * (q[0] * wb[2] + q[1] * wb[1] - q[2] * wb[0]);
    };
    for (const Node& n : e.nodes_) {
      switch (n.shape) {
        case JointShape::Base6:
          for (int i = 0; i < 3; ++i) xdot[n.q0 + i] = u[n.u0 + 3 + i];
          quat_rate(n.q0 + 3, n.u0);
          break;
        case JointShape::Rotation3:
          quat_rate(n.q0, n.u0);
          break;
        case JointShape::Axis1:
        case JointShape::Slide1:
        case JointShape::Gimbal2:
          if (n.prescribed) break;
          for (int i = 0; i < n.nuj; ++i) xdot[n.q0 + i] = u[n.u0 + i];
          break;
        default:
          break;
      }
      for (int l = 0; l < n.nm; ++l) xdot[n.q0 + n.nqj + l] = u[n.u0 + n.nuj + l];
    }
    for (int r = 0; r < e.n_u_; ++r) xdot[e.n_q_ + r] = udot[static_cast<std::size_t>(r)];
  }
};

bool KaneEngine::accelerations_tangent(double t, const TreeState& s, const TreeTangent& ds,
                                       TreeAccel& a, TreeAccel& da) {
  if (!tangent_) return false;
  std::vector<Dual> x;
  TangentTwin::pack(*this, s, ds, x);
  std::vector<TwinWork<Dual>> w;
  std::vector<Dual> udot;
  if (flex_.empty())
    TangentTwin::dynamics<Dual>(*this, t, x.data(), w, udot);
  else
    TangentTwin::flex_dynamics(*this, t, x.data(), w, udot);

  const std::size_t nb = system_.bodies.size(), nj = system_.joints.size();
  TreeAccel ra, rd;
  for (TreeAccel* r : {&ra, &rd}) {
    r->wdot_NB_B.assign(nb, Vector3d::Zero());
    r->a_NBo_N.assign(nb, Vector3d::Zero());
    r->angle_ddot.assign(nj, 0.0);
    r->angle2_ddot.assign(nj, 0.0);
    r->wdot_PC_C.assign(nj, Vector3d::Zero());
    r->eta_ddot.assign(nb, Eigen::VectorXd());
  }
  auto split = [](const V3<Dual>& v, Vector3d& val, Vector3d& der) {
    for (Eigen::Index i = 0; i < 3; ++i) {
      val(i) = v(i).v;
      der(i) = v(i).d;
    }
  };
  for (const Node& n : nodes_) {
    const TwinWork<Dual>& W = w[static_cast<std::size_t>(n.joint)];
    const std::size_t b = static_cast<std::size_t>(n.body), j = static_cast<std::size_t>(n.joint);
    const std::size_t u0 = static_cast<std::size_t>(n.u0);
    split(W.R.transpose() * W.alpha, ra.wdot_NB_B[b], rd.wdot_NB_B[b]);
    split(W.a, ra.a_NBo_N[b], rd.a_NBo_N[b]);
    switch (n.shape) {
      case JointShape::Axis1:
      case JointShape::Slide1:
        if (n.prescribed) {
          ra.angle_ddot[j] = W.pres_accel;  // theta''(t): no variation
        } else {
          ra.angle_ddot[j] = udot[u0].v;
          rd.angle_ddot[j] = udot[u0].d;
        }
        break;
      case JointShape::Gimbal2:
        ra.angle_ddot[j] = udot[u0].v;
        rd.angle_ddot[j] = udot[u0].d;
        ra.angle2_ddot[j] = udot[u0 + 1].v;
        rd.angle2_ddot[j] = udot[u0 + 1].d;
        break;
      case JointShape::Rotation3:
        split(V3<Dual>(udot[u0], udot[u0 + 1], udot[u0 + 2]), ra.wdot_PC_C[j], rd.wdot_PC_C[j]);
        break;
      default:
        break;
    }
    if (n.nm > 0) {
      ra.eta_ddot[b].resize(n.nm);
      rd.eta_ddot[b].resize(n.nm);
      for (int l = 0; l < n.nm; ++l) {
        ra.eta_ddot[b](l) = udot[u0 + static_cast<std::size_t>(n.nuj + l)].v;
        rd.eta_ddot[b](l) = udot[u0 + static_cast<std::size_t>(n.nuj + l)].d;
      }
    }
  }
  a = std::move(ra);
  da = std::move(rd);
  return true;
}

// ------------------------------------------------------------------------------------------------
// Issue 27's output and rhs tangents (Engine::output_row_tangent, rhs_tangent), by the same dual
// numbers through the same twin.

bool KaneEngine::output_row_twin(double t, const TreeState& s, const TreeTangent& ds, double* row,
                                 double* drow) {
  if (!output_tangent_) return false;
  std::vector<Dual> x, r;
  TangentTwin::pack(*this, s, ds, x);
  TangentTwin::output_jet(*this, t, x.data(), r);
  for (std::size_t i = 0; i < r.size(); ++i) {
    row[i] = r[i].v;
    drow[i] = r[i].d;
  }
  drow[0] = 0.0;  // the time column
  return true;
}

bool KaneEngine::output_row_tangent(double t, const TreeState& s, const TreeTangent& ds,
                                    double* row, double* drow) {
  if (!output_tangent_) return false;
  std::vector<double> twin_row(layout_.size());
  output_row_twin(t, s, ds, twin_row.data(), drow);
  // The row itself is output_row()'s at pack(s), to the last bit (the twin's value part agrees
  // with it to rounding: tests/kane/test_kane_tangent.cpp).
  std::vector<double> x(static_cast<std::size_t>(n_q_ + n_u_));
  pack(s, x.data());
  output_row(t, x.data(), row);
  return true;
}

bool KaneEngine::rhs_tangent(double t, const double* x, const double* dx, double* xdot,
                             double* dxdot) {
  if (!tangent_) return false;
  const std::size_t size = static_cast<std::size_t>(n_q_ + n_u_);
  std::vector<Dual> xd(size), xdotd(size);
  for (std::size_t i = 0; i < size; ++i) xd[i] = Dual(x[i], dx[i]);
  TangentTwin::rhs(*this, t, xd.data(), xdotd.data());
  for (std::size_t i = 0; i < size; ++i) dxdot[i] = xdotd[i].d;
  // xdot is rhs()'s own (the twin's value part agrees with it to rounding).
  rhs(t, x, xdot);
  return true;
}

}  // namespace crossdyn::kane
