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
// difference of accelerations() (and its Richardson extrapolation).  Flexible bodies are not
// covered (tangent_ false: the caller differentiates numerically).
#include "formulations/kane/dual.hpp"
#include "formulations/kane/kane_internal.hpp"

#include "core/errors.hpp"
#include "core/orbit.hpp"

#include <cmath>
#include <string>
#include <vector>

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
    }
    // Zero linear momentum (pack(): a free base only, prescribed joints at t = 0): the base
    // velocity -P0 / m_total, P0 = sum m v_Bo at v_B0o = 0; its value stays pack()'s.
    if (e.system_.zero_linear_momentum && e.system_.base_is_free()) {
      const std::size_t v0 = static_cast<std::size_t>(e.nodes_[0].u0) + 3;
      std::vector<Dual> x0(x);
      for (std::size_t i = 0; i < 3; ++i) x0[static_cast<std::size_t>(e.n_q_) + v0 + i] = Dual();
      std::vector<TwinWork<Dual>> w;
      kinematics<Dual>(e, 0.0, x0.data(), w);
      V3<Dual> P = V3<Dual>::Zero();
      for (std::size_t k = 0; k < e.nodes_.size(); ++k) P += e.nodes_[k].mass * w[k].v;
      for (std::size_t i = 0; i < 3; ++i)
        u[v0 + i].d = -P(static_cast<Eigen::Index>(i)).d / e.total_mass_;
    }
  }
};

bool KaneEngine::accelerations_tangent(double t, const TreeState& s, const TreeTangent& ds,
                                       TreeAccel& a, TreeAccel& da) {
  if (!tangent_) return false;
  std::vector<Dual> x;
  TangentTwin::pack(*this, s, ds, x);
  std::vector<TwinWork<Dual>> w;
  std::vector<Dual> udot;
  TangentTwin::dynamics<Dual>(*this, t, x.data(), w, udot);

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
  }
  a = std::move(ra);
  da = std::move(rd);
  return true;
}

}  // namespace crossdyn::kane
