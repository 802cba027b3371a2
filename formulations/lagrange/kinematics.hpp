// The Lagrange engine's kinematics, templated on the scalar S (double, Dual<1>, Dual<K>): the pose
// pass (q*) => R_PC, R_NB, p_NoBo_N, node frames and flexible inertia, the twist pass
// (pose, pi') => w_NB_B, v_NBo_B, and base_attitude (the base's R_NB with its derivatives).
// Equations: README.md, "Kinematics". Internal header, heavy templates: included by the passes that
// instantiate them (mass_matrix.cpp on Dual<1>, lagrangian_gradient.cpp on Dual<1 ... 8>,
// outputs.cpp on double) and by workspace.hpp; keep it out of other headers.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <type_traits>
#include <vector>

#include "core/rotation.hpp"
#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "formulations/lagrange/flex_body.hpp"
#include "formulations/lagrange/model.hpp"

namespace crossdyn::lagrange {

template <class S>
using Mat3X = Eigen::Matrix<S, 3, Eigen::Dynamic>;

template <class S>
struct Kin {
  std::vector<S> q;                      // q* as S, size n
  std::vector<Mat3<S>> R_NB, R_PC;       // per body (R_PC of the body's own joint)
  std::vector<Vec3<S>> p_NoBo_N;         // per body
  std::vector<Vec3<S>> w_NB_B, v_NBo_B;  // per body (twist pass), body components
  // Flexible bodies (per body) and joints at nodes (per body, for the body's own joint).
  std::vector<FlexInertia<S>> fi;     // flexible body: I_w, s, H at its eta (pose pass)
  std::vector<Vec3<S>> r_P, r_C;      // joint at a parent (child) node: the node's position; r_P
                                      // also of a sliding joint point, p_PoJ_P + s axis_P
  std::vector<Vec3<S>> axis1_C;       // two axis rotations: the first axis in child components
  std::vector<Mat3<S>> E_C;           // joint at a child node: exp([psi_C x])
  std::vector<Mat3X<S>> G_P, G_C;     // joint at a parent (child) node: Jl(psi) Psi, 3 x modes
  std::vector<Mat3X<S>> Pt_P, Pt_C;   // ... with geometric stiffening: Phi + e (G eta)^T
  std::vector<S> Ge;                  // scratch: G eta, max_modes
  std::vector<S> he;                  // scratch: modal momentum, max_modes
  void resize(const Model& m) {
    const std::size_t nb = m.bodies.size();
    q.assign(static_cast<std::size_t>(m.n), S(0.0));
    R_NB.resize(nb);
    R_PC.resize(nb);
    p_NoBo_N.resize(nb);
    w_NB_B.resize(nb);
    v_NBo_B.resize(nb);
    fi.resize(nb);
    r_P.resize(nb);
    r_C.resize(nb);
    axis1_C.resize(nb);
    E_C.assign(nb, Mat3<S>::Identity());
    G_P.resize(nb);
    G_C.resize(nb);
    Pt_P.resize(nb);
    Pt_C.resize(nb);
    Ge.assign(static_cast<std::size_t>(m.max_modes), S(0.0));
    for (std::size_t b = 0; b < nb; ++b)
      fi[b].resize(m.bodies[b].nm,
                   m.bodies[b].flex >= 0 && m.flex[static_cast<std::size_t>(m.bodies[b].flex)].stiff);
    for (const Model::JointM& J : m.joints) {
      const auto c = static_cast<std::size_t>(J.child);
      G_P[c].resize(3, J.Psi_P.cols());
      G_C[c].resize(3, J.Psi_C.cols());
      if (J.stiff_P) Pt_P[c].resize(3, J.Phi_P.cols());
      if (J.stiff_C) Pt_C[c].resize(3, J.Phi_C.cols());
    }
    he.assign(static_cast<std::size_t>(m.max_modes), S(0.0));
  }
};

// The function templates below have internal linkage (an unnamed namespace) in every file that
// includes this header, as when the engine was one file: GCC's inliner then makes the same choices
// (callgrind: with external linkage the whole run cost 0.6 to 0.8% more instructions on chain5 and
// spear1_case1).
namespace {

template <class S>
Vec3<S> cross(const Vec3<S>& a, const Eigen::Vector3d& b) {
  return Vec3<S>(a.y() * b.z() - a.z() * b.y(), a.z() * b.x() - a.x() * b.z(),
                 a.x() * b.y() - a.y() * b.x());
}

// M (constant) times v (scalar S).
template <class S>
Vec3<S> const_times(const Eigen::Matrix3d& M, const Vec3<S>& v) {
  return Vec3<S>(M(0, 0) * v.x() + M(0, 1) * v.y() + M(0, 2) * v.z(),
                 M(1, 0) * v.x() + M(1, 1) * v.y() + M(1, 2) * v.z(),
                 M(2, 0) * v.x() + M(2, 1) * v.y() + M(2, 2) * v.z());
}

// M (scalar S) times v (constant).
template <class S>
Vec3<S> times_const(const Mat3<S>& M, const Eigen::Vector3d& v) {
  return Vec3<S>(M(0, 0) * v.x() + M(0, 1) * v.y() + M(0, 2) * v.z(),
                 M(1, 0) * v.x() + M(1, 1) * v.y() + M(1, 2) * v.z(),
                 M(2, 0) * v.x() + M(2, 1) * v.y() + M(2, 2) * v.z());
}

// R^T v and A B, written out: Eigen's generic products on a custom scalar build more temporaries.
template <class S>
Vec3<S> transpose_times(const Mat3<S>& R, const Vec3<S>& v) {
  Vec3<S> r;
  for (int a = 0; a < 3; ++a) r(a) = R(0, a) * v(0) + R(1, a) * v(1) + R(2, a) * v(2);
  return r;
}
template <class S>
void product(const Mat3<S>& A, const Mat3<S>& B, Mat3<S>& C) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) C(r, c) = A(r, 0) * B(0, c) + A(r, 1) * B(1, c) + A(r, 2) * B(2, c);
}

// A node of a flexible body at eta (docs/flexible-bodies.md "Joints at nodes"):
//   r = p + Phi eta (deformed position), E = exp([psi x]) with psi = Psi eta (the node frame in the
//   body frame), G = Jl(psi) Psi (node frame's angular velocity relative to the body per unit eta',
//   body components; flex_body.hpp).
template <class S>
void node_frame(const Eigen::Vector3d& p, const Eigen::Matrix3Xd& Phi, const Eigen::Matrix3Xd& Psi,
                const S* eta, Vec3<S>& r, Mat3<S>& E, Mat3X<S>& G) {
  const auto nm = Phi.cols();
  Vec3<S> psi;
  for (int a = 0; a < 3; ++a) {
    r(a) = S(p(a));
    psi(a) = S(0.0);
  }
  for (Eigen::Index k = 0; k < nm; ++k)
    for (int a = 0; a < 3; ++a) {
      r(a) += Phi(a, k) * eta[k];
      psi(a) += Psi(a, k) * eta[k];
    }
  Mat3<S> Jl;
  rotvec_exp(psi, E, &Jl);
  for (Eigen::Index k = 0; k < nm; ++k)
    for (int a = 0; a < 3; ++a)
      G(a, k) = Jl(a, 0) * Psi(0, k) + Jl(a, 1) * Psi(1, k) + Jl(a, 2) * Psi(2, k);
}

// Geometric stiffening at a node (docs/flexible-bodies.md "Geometric stiffening"; Kane, Ryan and
// Banerjee 1987, Eq. (8)): r += e (1/2 eta^T Gs eta) and Pt = Phi + e (Gs eta)^T, the node's
// velocity relative to the body per unit eta' (du/dt = Pt eta'). Ge: scratch of nm values.
template <class S>
void node_stiffening(const Eigen::Matrix3Xd& Phi, const Eigen::Vector3d& e,
                     const Eigen::MatrixXd& Gs, const S* eta, S* Ge, Vec3<S>& r, Mat3X<S>& Pt) {
  const auto nm = Phi.cols();
  S w(0.0);
  for (Eigen::Index k = 0; k < nm; ++k) {
    S g(0.0);
    for (Eigen::Index l = 0; l < nm; ++l) g += Gs(k, l) * eta[l];
    Ge[k] = g;
    w += 0.5 * eta[k] * g;
  }
  for (int a = 0; a < 3; ++a) r(a) += e(a) * w;
  for (Eigen::Index k = 0; k < nm; ++k)
    for (int a = 0; a < 3; ++a) Pt(a, k) = Phi(a, k) + e(a) * Ge[k];
}

// The second of two axis rotations (universal; Model::JointM): R_PC <- R_PC Rot(axis2_J, a2) with
// Rot = I + sin(a2) D1 + (1 - cos(a2)) D2 (Rodrigues' formula, Kane, Likins & Levinson 1983,
// Sec. 1.2), and the first axis in child components, Rot(axis2_J, a2)^T axis_J =
// axis_J - sin(a2) b1 + (1 - cos(a2)) b2 (its rate's share of w_PC_C, twist_pass).
template <class S>
void second_rotation(const Model::JointM& J, const S& a2, Mat3<S>& R_PC, Vec3<S>& axis1_C) {
  using std::cos;
  using std::sin;
  const S s = sin(a2), c1 = 1.0 - cos(a2);
  Mat3<S> R2;
  for (int r = 0; r < 3; ++r)
    for (int col = 0; col < 3; ++col)
      R2(r, col) = (r == col ? 1.0 : 0.0) + J.D1(r, col) * s + J.D2(r, col) * c1;
  const Mat3<S> R1 = R_PC;
  // R_PC = R1 R2, written out: a second call of product() stops GCC inlining it into pose_pass
  // (0.4% more instructions on spear1_case1).
  for (int r = 0; r < 3; ++r)
    for (int col = 0; col < 3; ++col)
      R_PC(r, col) = R1(r, 0) * R2(0, col) + R1(r, 1) * R2(1, col) + R1(r, 2) * R2(2, col);
  for (int a = 0; a < 3; ++a) axis1_C(a) = J.axis_J(a) - J.b1(a) * s + J.b2(a) * c1;
}

// pose: (q*) => R_NB, R_PC, p_NoBo_N. Joint kinematics of system.hpp:
// R_PC = exp([psi_P x]) R_PJ0 R_J exp([psi_C x])^T, R_NC = R_NP R_PC,
// p_NoCo_N = p_NoPo_N + R_NP r_P - R_NC r_C with r_P = p_PoJ_P + u_P, r_C = p_CoJ_C + u_C
// (psi, u zero at a rigid attachment).
// The positions p_NoBo_N are computed in the double pass only (outputs and momenta): neither T nor
// V depends on them (T through the twists, which need r_P and r_C but not p_NoBo_N), so the
// dual-number passes skip them. The twists are in body components (twist_pass), so they need the
// relative rotations R_PC and the base's R_NB only: the attitudes R_NB of the other bodies are
// computed when `absolute` (double pass: outputs and momenta; mass pass: the base translation
// seeds' twists R_NB^T e_a and torques given in N), not in the gradient pass.
// R_base, when given, is the base's R_NB with its derivatives (base_attitude), used instead of
// differentiating the Euler-angle product.
template <class S>
void pose_pass(const Model& m, const int* chart, Kin<S>& k, bool absolute,
               const Mat3<S>* R_base = nullptr) {
  constexpr bool kPositions = std::is_same_v<S, double>;
  for (const Model::JointM& J : m.joints) {
    const auto c = static_cast<std::size_t>(J.child);
    const S* q = k.q.data() + J.i0;
    const Model::BodyM& C = m.bodies[c];
    if (J.absolute) {
      if (R_base != nullptr) {
        k.R_NB[c] = *R_base;
      } else {
        const EulerSequence& seq = kSequences[static_cast<std::size_t>(chart[J.euler_set])];
        k.R_NB[c] = euler_rotation(seq, q[3], q[4], q[5]);
      }
      if constexpr (kPositions) k.p_NoBo_N[c] = Vec3<S>(q[0], q[1], q[2]);
      if (C.flex >= 0)
        flex_inertia(m.flex[static_cast<std::size_t>(C.flex)], k.q.data() + C.e0, k.fi[c]);
      continue;
    }
    // What the joint's coordinates do (Model::JointM, set from its unit): rotations about axes
    // (revolute, universal), the Euler angles of R_J (spherical), slides of the joint point
    // (prismatic); none (fixed): R_PC = R_PJ0.
    Mat3<S>& R_PC = k.R_PC[c];
    if (J.axis_rotations > 0) {
      using std::cos;
      using std::sin;
      const S s = sin(q[0]), c1 = 1.0 - cos(q[0]);
      for (int r = 0; r < 3; ++r)
        for (int col = 0; col < 3; ++col)
          R_PC(r, col) = J.C0(r, col) + J.C1(r, col) * s + J.C2(r, col) * c1;
      if (J.axis_rotations > 1) second_rotation(J, q[1], R_PC, k.axis1_C[c]);
    } else if (J.relative_euler) {
      const Mat3<S> R_J = euler_rotation(kSequences[static_cast<std::size_t>(chart[J.euler_set])],
                                         q[0], q[1], q[2]);
      for (int col = 0; col < 3; ++col) R_PC.col(col) = const_times(J.R_PJ0, Vec3<S>(R_J.col(col)));
    } else {
      R_PC = J.R_PJ0.cast<S>();
    }
    if (J.slides > 0) {
      // A sliding joint point (prismatic; system.hpp): r_P = p_PoJ_P + s axis_P.
      const S& sl = q[J.axis_rotations];
      for (int a = 0; a < 3; ++a) k.r_P[c](a) = J.p_PoJ_P(a) + J.slide_P(a) * sl;
    }
    if (J.parent_node >= 0) {
      Mat3<S> E_P;
      node_frame(J.p_PoJ_P, J.Phi_P, J.Psi_P, k.q.data() + J.parent_e0, k.r_P[c], E_P, k.G_P[c]);
      if (J.stiff_P)
        node_stiffening(J.Phi_P, J.e_P, J.Gs_P, k.q.data() + J.parent_e0, k.Ge.data(), k.r_P[c],
                        k.Pt_P[c]);
      R_PC = E_P * R_PC;
    }
    if (J.child_node >= 0) {
      node_frame(J.p_CoJ_C, J.Phi_C, J.Psi_C, k.q.data() + J.child_e0, k.r_C[c], k.E_C[c],
                 k.G_C[c]);
      if (J.stiff_C)
        node_stiffening(J.Phi_C, J.e_C, J.Gs_C, k.q.data() + J.child_e0, k.Ge.data(), k.r_C[c],
                        k.Pt_C[c]);
      R_PC = R_PC * k.E_C[c].transpose();
    }
    if (J.parent < 0) {
      // A prescribed base turning about an axis fixed in N (docs/prescribed-motion.md,
      // "A prescribed base"): R_NB = R_NJ0 Rot(axis_J, angle) exp([psi_C x])^T (the parent frame
      // is N), p_NoBo_N = p_NoJ_N - R_NB (p_BoJ_B + u_J).
      k.R_NB[c] = R_PC;
      if constexpr (kPositions) {
        const Vec3<S> from_joint =
            J.child_node >= 0 ? Vec3<S>(R_PC * k.r_C[c]) : times_const(R_PC, J.p_CoJ_C);
        k.p_NoBo_N[c] = J.p_PoJ_P - from_joint;
      }
      if (C.flex >= 0)
        flex_inertia(m.flex[static_cast<std::size_t>(C.flex)], k.q.data() + C.e0, k.fi[c]);
      continue;
    }
    const auto P = static_cast<std::size_t>(J.parent);
    if (absolute) product(k.R_NB[P], R_PC, k.R_NB[c]);
    if constexpr (kPositions) {
      const Vec3<S> to_joint = J.parent_node >= 0 || J.slides > 0
                                   ? Vec3<S>(k.R_NB[P] * k.r_P[c])
                                   : times_const(k.R_NB[P], J.p_PoJ_P);
      const Vec3<S> from_joint =
          J.child_node >= 0 ? Vec3<S>(k.R_NB[c] * k.r_C[c]) : times_const(k.R_NB[c], J.p_CoJ_C);
      k.p_NoBo_N[c] = k.p_NoBo_N[P] + to_joint - from_joint;
    }
    if (C.flex >= 0)
      flex_inertia(m.flex[static_cast<std::size_t>(C.flex)], k.q.data() + C.e0, k.fi[c]);
  }
}

// twist: (pose, pi') => w_NB_B, v_NBo_B, both in body components. Angular velocities add along
// the tree through the joint frames (docs/flexible-bodies.md "Joints at nodes"):
//   w_C = R_PC^T (w_P + G_P eta_P') + E_C w_rel - G_C eta_C'     (C components)
// with w_rel the joint's relative angular velocity in child-side joint-frame components
// (revolute: axis_J rate; spherical: w_PC_C; universal: Rot(n_2, a2)^T n_1 a1' + n_2 a2', the
// first axis turned by the second rotation, second_rotation; prismatic: 0), and the joint point
// has one velocity seen from both bodies, v_Co = v_Po + R_NP (w_P x r_P + Phi_P eta_P') -
// R_NC (w_C x r_C + Phi_C eta_C') in N (Kane & Levinson 1985, "Dynamics: Theory and
// Applications", Sec. 2.7, two points fixed on a rigid body, plus the nodes' elastic velocities),
// i.e. in C components (R_CN = R_PC^T R_PN):
//   v_Co_C = R_PC^T (v_Po_P + w_P x r_P + Phi_P eta_P') - (w_C x r_C + Phi_C eta_C').
// A sliding joint point (prismatic) adds its velocity along the axis in P, axis_P s' (Sec. 2.8).
// The base's v_NBo_B = R_NB^T v_NBo_N (its quasi-velocities are N components, Eq. 17).
// Only the joints in `joints` (topological order) are visited: a seed's twists are zero outside the
// subtree of its joint, whose parent twist the caller sets to zero.
template <class S>
void twist_pass(const Model& m, Kin<S>& k, const double* u, const std::vector<int>& joints) {
  for (int j : joints) {
    const Model::JointM& J = m.joints[static_cast<std::size_t>(j)];
    const auto c = static_cast<std::size_t>(J.child);
    const double* uj = u + J.i0;
    if (J.absolute) {
      const Mat3<S>& R = k.R_NB[c];
      for (int a = 0; a < 3; ++a)
        k.v_NBo_B[c](a) = R(0, a) * uj[0] + R(1, a) * uj[1] + R(2, a) * uj[2];
      k.w_NB_B[c] = Vec3<S>(S(uj[3]), S(uj[4]), S(uj[5]));
      continue;
    }
    if (J.parent < 0) {
      // A prescribed base (parent N, at rest): w_NB_B = rate axis_J (docs/prescribed-motion.md,
      // "A prescribed base"), turned by the child node frame when the joint is at a node as below
      // (w_C = E_C w_rel - G_C eta_C'); the joint point is fixed in N, so
      // v_NBo_B = -(w_C x r_C + Phi_C eta_C') (Kane & Levinson 1985, Sec. 2.7).
      Vec3<S> w, v_C;
      if (J.child_node >= 0) {
        const double* ed = u + J.child_e0;
        w = times_const(k.E_C[c], Eigen::Vector3d(J.axis_J * uj[0]));
        const Mat3X<S>& G = k.G_C[c];
        for (Eigen::Index l = 0; l < G.cols(); ++l)
          for (int a = 0; a < 3; ++a) w(a) -= G(a, l) * ed[l];
        v_C = w.cross(k.r_C[c]);
        if (J.stiff_C) {
          for (Eigen::Index l = 0; l < G.cols(); ++l)
            for (int a = 0; a < 3; ++a) v_C(a) += k.Pt_C[c](a, l) * ed[l];
        } else {
          for (Eigen::Index l = 0; l < G.cols(); ++l)
            for (int a = 0; a < 3; ++a) v_C(a) += J.Phi_C(a, l) * ed[l];
        }
      } else {
        for (int a = 0; a < 3; ++a) w(a) = S(J.axis_J(a) * uj[0]);
        v_C = cross(w, J.p_CoJ_C);
      }
      k.w_NB_B[c] = w;
      for (int a = 0; a < 3; ++a) k.v_NBo_B[c](a) = -v_C(a);
      continue;
    }
    const auto P = static_cast<std::size_t>(J.parent);
    const Mat3<S>& R_PC = k.R_PC[c];
    if (J.rigid_point) {  // rigid attachments on both sides, the joint point fixed in both
      const Vec3<S>& w_P = k.w_NB_B[P];
      const Vec3<S> v_J = k.v_NBo_B[P] + cross(w_P, J.p_PoJ_P);
      Vec3<S> w = transpose_times(R_PC, w_P);
      if (J.axis_rotations > 0) {
        const double rate = uj[J.axis_rotations - 1];
        for (int a = 0; a < 3; ++a) w(a) += J.axis_last_J(a) * rate;
        if (J.axis_rotations > 1)
          for (int a = 0; a < 3; ++a) w(a) += k.axis1_C[c](a) * uj[0];
      } else if (J.relative_euler) {
        for (int a = 0; a < 3; ++a) w(a) += uj[a];
      }
      k.v_NBo_B[c] = transpose_times(R_PC, v_J) - cross(w, J.p_CoJ_C);
      k.w_NB_B[c] = w;
      continue;
    }
    // Parent side: the joint point's velocity (v_Po + w_P x r_P + Phi_P eta_P') and the
    // parent-side joint frame's angular velocity, both in P components.
    Vec3<S> w_J = k.w_NB_B[P];
    Vec3<S> v_J;
    if (J.parent_node >= 0) {
      const double* ed = u + J.parent_e0;
      v_J = k.v_NBo_B[P] + w_J.cross(k.r_P[c]);
      const Mat3X<S>& G = k.G_P[c];
      for (Eigen::Index l = 0; l < G.cols(); ++l)
        for (int a = 0; a < 3; ++a) {
          if (J.stiff_P)
            v_J(a) += k.Pt_P[c](a, l) * ed[l];
          else
            v_J(a) += J.Phi_P(a, l) * ed[l];
          w_J(a) += G(a, l) * ed[l];
        }
    } else if (J.slides > 0) {
      // A sliding joint point r_P = p_PoJ_P + s axis_P (pose_pass): its velocity in P is
      // v_Po + w_P x r_P + axis_P s' (Kane & Levinson 1985, Sec. 2.8, one point moving on a
      // rigid body).
      v_J = k.v_NBo_B[P] + w_J.cross(k.r_P[c]);
      const double rate = uj[J.axis_rotations];
      for (int a = 0; a < 3; ++a) v_J(a) += J.slide_P(a) * rate;
    } else {
      v_J = k.v_NBo_B[P] + cross(w_J, J.p_PoJ_P);
    }
    Vec3<S> w = transpose_times(R_PC, w_J);
    // (Two axis rotations, the universal joint's, only at a rigid joint point: the short path
    // above; build_model.cpp checks it.)
    Eigen::Vector3d w_rel = Eigen::Vector3d::Zero();
    if (J.axis_rotations > 0) w_rel = J.axis_last_J * uj[J.axis_rotations - 1];
    if (J.relative_euler) w_rel = Eigen::Vector3d(uj[0], uj[1], uj[2]);
    Vec3<S> v_C;
    if (J.child_node >= 0) {
      const double* ed = u + J.child_e0;
      w += times_const(k.E_C[c], w_rel);
      const Mat3X<S>& G = k.G_C[c];
      for (Eigen::Index l = 0; l < G.cols(); ++l)
        for (int a = 0; a < 3; ++a) w(a) -= G(a, l) * ed[l];
      v_C = w.cross(k.r_C[c]);
      if (J.stiff_C) {
        for (Eigen::Index l = 0; l < G.cols(); ++l)
          for (int a = 0; a < 3; ++a) v_C(a) += k.Pt_C[c](a, l) * ed[l];
      } else {
        for (Eigen::Index l = 0; l < G.cols(); ++l)
          for (int a = 0; a < 3; ++a) v_C(a) += J.Phi_C(a, l) * ed[l];
      }
    } else {
      for (int a = 0; a < 3; ++a) w(a) += w_rel(a);
      v_C = cross(w, J.p_CoJ_C);
    }
    k.w_NB_B[c] = w;
    k.v_NBo_B[c] = transpose_times(R_PC, v_J) - v_C;
  }
}

// The base's attitude R_NB (value R) as Dual<K> for the derivative directions theta_c, each an
// angular displacement in body axes (w_NB_B = A(a) a', paper Eq. 16, so a displacement of the
// Euler angles da turns the base by A da in body axes): R_NB(theta) = R (I + [theta x]) + O(theta^2)
// (Poisson's kinematic equation dR_NB/dt = R_NB [w_NB_B x], the angular velocity in body axes of
// Kane, Likins & Levinson 1983, Ch. 1), so dR_NB/dtheta_c = R [theta_c x]. The identity in the
// charts' terms, R^T dR = [(A da) x] for every sequence, is checked to 1e-14 against AD of the
// Euler product in tests/lagrange/test_euler_chart.cpp.
// Exact, and without differentiating the three rotations of the Euler product.
template <int K>
Mat3<Dual<K>> base_attitude(const Eigen::Matrix3d& R, const std::array<Eigen::Vector3d, K>& theta) {
  Mat3<Dual<K>> D;
  for (int r = 0; r < 3; ++r)
    for (int col = 0; col < 3; ++col) D(r, col) = Dual<K>(R(r, col));
  for (int c = 0; c < K; ++c) {
    if (theta[static_cast<std::size_t>(c)].isZero(0.0)) continue;
    const Eigen::Matrix3d dR = R * rot::skew(theta[static_cast<std::size_t>(c)]);
    for (int r = 0; r < 3; ++r)
      for (int col = 0; col < 3; ++col) D(r, col).d[static_cast<std::size_t>(c)] = dR(r, col);
  }
  return D;
}

}  // namespace

}  // namespace crossdyn::lagrange
