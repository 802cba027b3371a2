// The Lagrange engine (see lagrange_engine.hpp for the coordinates and the equations).
//
// Passes of one right-hand-side evaluation, (t, x = (q*, pi')) => (q*', pi''):
//   charts        (q*) => A, B = A^-1 per Euler set; q*' = B pi'                  (Eqs. 16, 22)
//   pose          (q*) => R_PC per body, R_NB (the base's always; every body's in the double and
//                 mass passes) and p_NoBo_N (double pass only); node frames (r, exp([psi x]),
//                 Jl(psi) Psi) of joints at nodes; I_w, s, H of flexible bodies
//                                                                    [templated on the scalar]
//   twist         (pose, pi') => w_NB_B, v_NBo_B per body (body components: only the relative
//                 rotations R_PC enter, and the base's R_NB)          [templated on the scalar]
//   energy        (twists) => T,  (q*) => V                           [templated on the scalar]
//   mass pass     Dual<1> seeded with the motion q*' (time derivative at fixed pi'), twists for
//                 every unit seed pi' = e_i. T is quadratic in pi', so its derivatives in pi' are
//                 the symmetric bilinear form T(xi, eta) of the seeds (polarisation; the base
//                 translation seeds' twists are known, (0, R_NB^T e_a), and written without a
//                 pass):
//                   M_ij = d2T/dpi_i dpi_j = T(e_i, e_j),   p_i = dT/dpi_i = T(e_i, pi'),
//                 and the Dual<1> parts give d/dt p at pi'' = 0, i.e. (dM/dt) pi'.
//                 A rigid body's bilinear form is w_a . I w_b + m v_a . v_b (paper Eq. 26, with
//                 v in body components: the dot product does not depend on the frame); a
//                 flexible body's is Y_a . M_B(eta) Y_b with Y = (w, v_B, eta'), M_B applied by
//                 flex_momentum (flex_body.hpp).
//                 Generalised forces of body torques: N_i = tau . w(e_i) (virtual power).
//   gradient      Dual<K> (chunks of K <= 8) seeded with the quasi-displacements dq* = B e_r:
//                 L = T - V => B^T dL/dq* at fixed pi'.
//   hamel         A(a2, a3) on Dual<2> per Euler set (charts) => W, B^T W^T p.
//   solve         M pi'' = N + B^T dL/dq* - (dM/dt) pi' - B^T W^T p   (Cholesky, M is SPD).
// All scratch lives in the Workspace, sized in the constructor: rhs() does not allocate.
#include "formulations/lagrange/lagrange_engine.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <tuple>
#include <type_traits>
#include <utility>

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/scene/topology.hpp"
#include "core/rotation.hpp"
#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "formulations/lagrange/flex_body.hpp"

namespace crossdyn::lagrange {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr int kMaxChunk = 8;  // widest Dual<K> of the gradient pass

std::string format_number(double v, const char* fmt = "%.6g") {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

std::string format_vector(const Eigen::Vector3d& v) {
  return "(" + format_number(v.x(), "%.9g") + ", " + format_number(v.y(), "%.9g") + ", " +
         format_number(v.z(), "%.9g") + ")";
}

}  // namespace

// ------------------------------------------------------------------------------------------------
// Model: the System in the engine's terms, immutable after construction.
// ------------------------------------------------------------------------------------------------
struct LagrangeEngine::Model {
  struct BodyM {
    std::string name;
    double mass = 0;
    Eigen::Matrix3d I_BBo_B;  // times EngineOptions::test_inertia_scale (rigid bodies)
    Body::Frame torque_frame = Body::Frame::Body;
    PiecewiseConstant<3> torque;
    int flex = -1;  // index into Model::flex; -1 for a rigid body
    int e0 = -1;    // flexible: index of eta in q* (and of eta' in pi')
    int nm = 0;     // flexible: number of modes
  };
  struct JointM {
    std::string name;
    JointType type = JointType::Revolute;
    int parent = -1, child = -1;
    int i0 = 0;          // first index of this joint's block in q* and in pi'
    int dof = 0;         // joint coordinates (free 6, revolute 1, spherical 3, fixed 0)
    int size = 0;        // block size: dof, then the child's modal coordinates
    int euler_set = -1;  // index of its Euler-angle set (free, spherical), else -1
    Eigen::Vector3d p_PoJ_P, p_CoJ_C;
    Eigen::Matrix3d R_PJ0;
    Eigen::Quaterniond q_PJ0;
    Eigen::Vector3d axis_J;  // revolute axis in the joint (child) frame: R_PJ0^T axis_P
    // Revolute: R_PC(angle) = C0 + C1 sin(angle) + C2 (1 - cos(angle)), i.e. R_PJ0 times
    // Rodrigues' formula I + sin [n x] + (1 - cos) [n x]^2 (Kane, Likins & Levinson 1983,
    // Sec. 1.2).
    Eigen::Matrix3d C0, C1, C2;
    // Attachment at a node of a flexible parent (child): the node's shapes and slopes, and the
    // index of the parent's (child's) eta in q*. -1: a rigid attachment.
    int parent_node = -1, child_node = -1;
    int parent_e0 = -1, child_e0 = -1;
    Eigen::Matrix3Xd Phi_P, Psi_P, Phi_C, Psi_C;
    // Geometric stiffening of the parent (child) node: e_i and G_i (flex_body.hpp), so the node
    // moves by Phi eta + e (1/2 eta^T G eta) with velocity Pt eta', Pt = Phi + e (G eta)^T.
    bool stiff_P = false, stiff_C = false;
    Eigen::Vector3d e_P = Eigen::Vector3d::Zero(), e_C = Eigen::Vector3d::Zero();
    Eigen::MatrixXd Gs_P, Gs_C;
    std::vector<int> subtree;  // this joint and every joint below it, in topological order
    double stiffness = 0, neutral = 0, damping = 0;
    PiecewiseConstant<1> motor_revolute;
    PiecewiseConstant<3> motor_spherical;
    // Prescribed revolute joint (docs/prescribed-motion.md): the angle angle0 + theta(t) and its
    // rate are not state; the coordinate stays in q* and pi' (internal layout), filled from the
    // profile at t (LagrangeEngine::expand).
    bool prescribed = false;
    PrescribedMotion motion;
    double angle0 = 0;
  };
  struct EulerSetM {
    int i0 = 0;         // index of the first angle in q* (and of w in pi')
    std::string owner;  // base body name or spherical joint name
    std::string what;   // "attitude of body 'main'" / "relative attitude of joint 'j' (...)"
  };

  std::vector<BodyM> bodies;
  std::vector<JointM> joints;
  std::vector<FlexInvariants> flex;       // per flexible body (BodyM::flex)
  std::vector<EulerSetM> euler_sets;
  std::vector<int> set_of_coordinate;     // per q* index: its Euler set or -1
  std::vector<int> gradient_dirs;         // quasi-coordinates the Lagrangian can depend on
  std::vector<int> coordinate_joint;      // per q* index: the joint whose block holds it
  std::vector<std::vector<int>> support;  // per body: the pi' indices its twist depends on
  std::vector<int> all_joints;            // 0, 1, ..., in topological order
  int n = 0;
  int max_modes = 0;
  // Prescribed joints: the state x holds the free coordinates only, nf of them (q*_f, pi'_f).
  int nf = 0;
  bool has_prescribed = false;
  bool base_free = true;               // joints[0] is the free joint (else a prescribed revolute)
  int base_set = -1;                   // the free base's Euler set (-1: prescribed base)
  std::vector<int> free_index;         // per state coordinate k < nf: its index in q*
  std::vector<int> state_of;           // per q* index: its state coordinate, -1 when prescribed
  std::vector<int> prescribed_joints;  // joint indices of the prescribed joints
  double total_mass = 0;
  bool zero_linear_momentum = true;
  bool rechart = true;
  std::vector<std::string> labels;   // state labels, size 2n
  OutputLayout layout;               // pinned columns, then extras
  int recharts_column = -1;          // extra column lagrange.recharts
};

// ------------------------------------------------------------------------------------------------
// Templated kinematics and energies (the passes). S is double, Dual<1>, Dual<3> or Dual<K>.
// ------------------------------------------------------------------------------------------------
namespace {

using Model = LagrangeEngine::Model;

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
  std::vector<Vec3<S>> r_P, r_C;      // joint at a parent (child) node: the node's position
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
    if (J.type == JointType::Free) {
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
    Mat3<S>& R_PC = k.R_PC[c];
    if (J.type == JointType::Revolute) {
      using std::cos;
      using std::sin;
      const S s = sin(q[0]), c1 = 1.0 - cos(q[0]);
      for (int r = 0; r < 3; ++r)
        for (int col = 0; col < 3; ++col)
          R_PC(r, col) = J.C0(r, col) + J.C1(r, col) * s + J.C2(r, col) * c1;
    } else if (J.type == JointType::Spherical) {
      const Mat3<S> R_J = euler_rotation(kSequences[static_cast<std::size_t>(chart[J.euler_set])],
                                         q[0], q[1], q[2]);
      for (int col = 0; col < 3; ++col) R_PC.col(col) = const_times(J.R_PJ0, Vec3<S>(R_J.col(col)));
    } else {
      R_PC = J.R_PJ0.cast<S>();
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
      const Vec3<S> to_joint =
          J.parent_node >= 0 ? Vec3<S>(k.R_NB[P] * k.r_P[c]) : times_const(k.R_NB[P], J.p_PoJ_P);
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
// (revolute: axis_J rate; spherical: w_PC_C), and the joint point has one velocity seen from both
// bodies, v_Co = v_Po + R_NP (w_P x r_P + Phi_P eta_P') - R_NC (w_C x r_C + Phi_C eta_C') in N
// (Kane & Levinson 1985, "Dynamics: Theory and Applications", Sec. 2.7, two points fixed on a
// rigid body, plus the nodes' elastic velocities), i.e. in C components (R_CN = R_PC^T R_PN):
//   v_Co_C = R_PC^T (v_Po_P + w_P x r_P + Phi_P eta_P') - (w_C x r_C + Phi_C eta_C').
// The base's v_NBo_B = R_NB^T v_NBo_N (its quasi-velocities are N components, Eq. 17).
// Only the joints in `joints` (topological order) are visited: a seed's twists are zero outside the
// subtree of its joint, whose parent twist the caller sets to zero.
template <class S>
void twist_pass(const Model& m, Kin<S>& k, const double* u, const std::vector<int>& joints) {
  for (int j : joints) {
    const Model::JointM& J = m.joints[static_cast<std::size_t>(j)];
    const auto c = static_cast<std::size_t>(J.child);
    const double* uj = u + J.i0;
    if (J.type == JointType::Free) {
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
    if (J.parent_node < 0 && J.child_node < 0) {  // rigid attachments on both sides
      const Vec3<S>& w_P = k.w_NB_B[P];
      const Vec3<S> v_J = k.v_NBo_B[P] + cross(w_P, J.p_PoJ_P);
      Vec3<S> w = transpose_times(R_PC, w_P);
      if (J.type == JointType::Revolute) {
        for (int a = 0; a < 3; ++a) w(a) += J.axis_J(a) * uj[0];
      } else if (J.type == JointType::Spherical) {
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
    } else {
      v_J = k.v_NBo_B[P] + cross(w_J, J.p_PoJ_P);
    }
    Vec3<S> w = transpose_times(R_PC, w_J);
    Eigen::Vector3d w_rel = Eigen::Vector3d::Zero();
    if (J.type == JointType::Revolute) w_rel = J.axis_J * uj[0];
    if (J.type == JointType::Spherical) w_rel = Eigen::Vector3d(uj[0], uj[1], uj[2]);
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

// T = sum over bodies: rigid (w^T I w + m v.v) / 2 (paper Eqs. 24-25); flexible xi . M_B xi / 2
// (flex_body.hpp), xi = (w_NB_B, v_NBo_B, eta'). u is pi' (the flexible bodies' eta').
template <class S>
S kinetic_energy_of(const Model& m, Kin<S>& k, const double* u) {
  S T(0.0);
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const Model::BodyM& B = m.bodies[b];
    if (B.flex >= 0) {
      T += flex_kinetic_energy(m.flex[static_cast<std::size_t>(B.flex)], k.fi[b], k.w_NB_B[b],
                               k.v_NBo_B[b], u + B.e0, k.he.data());
      continue;
    }
    const Vec3<S> Iw = const_times(B.I_BBo_B, k.w_NB_B[b]);
    T += 0.5 * (k.w_NB_B[b].dot(Iw) + B.mass * k.v_NBo_B[b].squaredNorm());
  }
  return T;
}

// V(q*): the hinge springs (system.hpp), revolute k (angle - neutral)^2 / 2, spherical
// k |phi|^2 / 2 with phi the rotation vector of R_J, written in the joint's Euler angles; and the
// flexible bodies' elastic energy eta^T K eta / 2 (docs/flexible-bodies.md "Energy").
template <class S>
S potential_energy_of(const Model& m, const int* chart, const S* q) {
  S V(0.0);
  for (const Model::JointM& J : m.joints) {
    if (J.stiffness == 0.0) continue;
    const S* qj = q + J.i0;
    if (J.type == JointType::Revolute) {
      const S d = qj[0] - J.neutral;
      V += 0.5 * J.stiffness * d * d;
    } else if (J.type == JointType::Spherical) {
      const Eigen::Matrix<S, 4, 1> qJ = euler_quaternion(
          kSequences[static_cast<std::size_t>(chart[J.euler_set])], qj[0], qj[1], qj[2]);
      V += 0.5 * J.stiffness * rotation_angle_squared(qJ(0), qJ(1), qJ(2), qJ(3));
    }
  }
  for (const Model::BodyM& B : m.bodies) {
    if (B.flex < 0) continue;
    const Eigen::MatrixXd& K = m.flex[static_cast<std::size_t>(B.flex)].K;
    const S* eta = q + B.e0;
    for (int k = 0; k < B.nm; ++k) {
      S row = 0.5 * K(k, k) * eta[k];
      for (int l = k + 1; l < B.nm; ++l) row += K(k, l) * eta[l];
      V += eta[k] * row;
    }
  }
  return V;
}

template <class T>
struct Chunks;
template <int... K>
struct Chunks<std::integer_sequence<int, K...>> {
  using type = std::tuple<Kin<Dual<K + 1>>...>;
};
using GradientKins = Chunks<std::make_integer_sequence<int, kMaxChunk>>::type;

}  // namespace

// ------------------------------------------------------------------------------------------------
// Workspace: every mutable value, preallocated.
// ------------------------------------------------------------------------------------------------
struct LagrangeEngine::Workspace {
  std::vector<int> chart;  // per Euler set, index into kSequences
  long recharts = 0;
  long wraps = 0;
  // The middle angle of every Euler set at the last accepted state (pack(), after_step()) and its
  // time, in the set's chart then: after_step() compares the lock sheet (lock_sheet()) with it.
  std::vector<double> last_a2;
  double last_t = 0;
  bool have_last = false;  // false until pack(): no previous state to compare with
  long lock_crossings = 0;  // locks crossed between accepted states (re-charting on: re-charted)
  std::vector<Eigen::Matrix3d> A, B;  // per Euler set at the current q*
  std::vector<Mat3<Dual<2>>> A_dual;  // per Euler set: A with dA/da2, dA/da3 (charts, hamel)
  Eigen::Matrix3d R_NB0;              // the base's attitude at the current q*
  Kin<double> k0;
  Kin<Dual<1>> k1;
  GradientKins kg;
  // Per body: twists of the seeds (w_NB_B, v_NBo_B) and their time derivatives at fixed pi'.
  std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>> Xi, Xi_dot;
  std::vector<FlexInertia<double>> fi0;  // per body: values of k1.fi (flexible bodies)
  std::vector<Dual<1>> he1;              // flexible mass pass: modal momentum and its rate
  Eigen::VectorXd he0, unit;             // flexible mass pass: a seed's modal momentum; e_k
  Eigen::MatrixXd M;
  Eigen::MatrixXd U;  // Cholesky factor of M (upper triangle), solve
  Eigen::Matrix<double, 6, Eigen::Dynamic> Y, Yd, DX;  // rigid mass pass: gathered seed twists,
                                                       // their rates, D times them

  Eigen::VectorXd u, qdot, p, Mdot_u, hamel, dL, N, f, udot, seed, inv_diag;
  std::vector<Eigen::Quaterniond> q_NB;  // per body, output_row
  // Prescribed joints: the full (q*, pi') at t (expand), the free block of M, its factor and
  // right-hand side, and the joints' torques (per Model::prescribed_joints).
  Eigen::VectorXd xf;
  Eigen::MatrixXd Mff, Uff;
  Eigen::VectorXd bf, inv_diag_f, torque;
};

// ------------------------------------------------------------------------------------------------
// Construction
// ------------------------------------------------------------------------------------------------
namespace {

// What the engine cannot run, or what would make its mass matrix singular: InputError naming the
// scene file, the body or joint and the reason.
void validate_flex(const System& system, const std::string& where) {
  for (const Body& b : system.bodies) {
    if (!b.flex) continue;
    const FlexBody& f = *b.flex;
    const std::string body = "bodies: body '" + b.name + "' (flexible): ";
    const auto n = static_cast<Eigen::Index>(f.modes());
    if (f.nodes.empty()) throw InputError(where + body + "has no nodes");
    if (f.K.rows() != n || f.K.cols() != n || f.D.rows() != n || f.D.cols() != n)
      throw InputError(where + body + "K and D must be " + std::to_string(n) + " x " +
                       std::to_string(n) + " (one row and column per mode)");
    if (!f.K.allFinite() || !f.D.allFinite())
      throw InputError(where + body + "K or D has a non-finite entry");
    for (const FlexNode& node : f.nodes) {
      if (node.Phi_B.cols() != n || node.Psi_B.cols() != n)
        throw InputError(where + body + "node '" + node.name + "' must have " +
                         std::to_string(n) + " mode shapes and slopes");
      if (f.geometric_stiffening && node.G.size() > 0 &&
          (node.G.rows() != n || node.G.cols() != n || !node.G.allFinite() || !node.e_B.allFinite()))
        throw InputError(where + body + "node '" + node.name + "' must have a finite " +
                         std::to_string(n) + " x " + std::to_string(n) +
                         " geometric stiffening matrix G and a finite direction e");
      if (!(node.mass >= 0) || !node.p_BoNi_B.allFinite() || !node.J_Ni_B.allFinite() ||
          !node.Phi_B.allFinite() || !node.Psi_B.allFinite())
        throw InputError(where + body + "node '" + node.name +
                         "' has a negative mass or a non-finite value");
    }
    // M_B(0) must be positive definite, or M is singular at zero deformation.
    const FlexInvariants inv(f, 1.0);
    const Eigen::VectorXd lambda =
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(inv.mass_matrix_at_rest(),
                                                       Eigen::EigenvaluesOnly)
            .eigenvalues();
    if (!(lambda.minCoeff() > 1e-12 * lambda.maxCoeff()))
      throw InputError(where + body +
                       "the mass matrix of its rigid motion and modes is singular at zero "
                       "deformation (eigenvalues from " +
                       format_number(lambda.minCoeff()) + " to " +
                       format_number(lambda.maxCoeff()) +
                       "): a mode has no kinetic energy, or repeats a rigid-body motion or "
                       "another mode");
  }
  for (std::size_t j = 0; j < system.joints.size(); ++j) {
    const Joint& J = system.joints[j];
    const std::string joint = "joints: joint '" + J.name + "': ";
    auto check_side = [&](int body, int node, const Eigen::Vector3d& point, const char* side,
                          const char* key) {
      if (node < 0) return;
      if (body < 0) throw InputError(where + joint + "a free joint has no " + side + " node");
      const Body& B = system.bodies[static_cast<std::size_t>(body)];
      if (!B.flex)
        throw InputError(where + joint + "attaches at node " + std::to_string(node) + " of its " +
                         side + " '" + B.name + "', which is rigid (no nodes)");
      if (node >= static_cast<int>(B.flex->nodes.size()))
        throw InputError(where + joint + "node index " + std::to_string(node) + " of its " +
                         side + " '" + B.name + "' is out of range (" +
                         std::to_string(B.flex->nodes.size()) + " nodes)");
      const FlexNode& nd = B.flex->nodes[static_cast<std::size_t>(node)];
      if ((point - nd.p_BoNi_B).norm() > 1e-9 * (1.0 + nd.p_BoNi_B.norm()))
        throw InputError(where + joint + key + " " + format_vector(point) +
                         " is not the undeformed position " + format_vector(nd.p_BoNi_B) +
                         " of node '" + nd.name + "' of body '" + B.name + "'");
    };
    if (J.type == JointType::Free && J.child_node >= 0)
      throw InputError(where + joint +
                       "the free joint cannot attach at a node: a flexible base moves with its "
                       "body frame");
    check_side(J.parent, J.parent_node, J.p_PoJ_P, "parent", "parent_point");
    if (J.type != JointType::Free) check_side(J.child, J.child_node, J.p_CoJ_C, "child", "child_point");
  }
}

}  // namespace

LagrangeEngine::LagrangeEngine(const System& system, const EngineOptions& options) {
  auto m = std::make_unique<Model>();
  const std::string where = (system.file.empty() ? system.name : system.file) + ": ";
  // The tree (one free joint first, every parent the child of an earlier joint, one joint per
  // body, indices in range): the one public check, core/scene/topology.hpp.
  check_topology(system);
  if (!(options.test_inertia_scale > 0.0) || !std::isfinite(options.test_inertia_scale))
    throw InputError(where + "engine option test_inertia_scale must be positive, got " +
                     format_number(options.test_inertia_scale));
  validate_flex(system, where);
  for (const Body& b : system.bodies) {
    Model::BodyM bm;
    bm.name = b.name;
    bm.mass = b.mass;
    bm.I_BBo_B = b.I_BBo_B * options.test_inertia_scale;
    bm.torque_frame = b.torque_frame;
    bm.torque = b.torque;
    if (b.flex) {
      // The flexible body's mass and inertia are its node sums (docs/flexible-bodies.md).
      bm.flex = static_cast<int>(m->flex.size());
      m->flex.emplace_back(*b.flex, options.test_inertia_scale);
      bm.nm = b.flex->modes();
      bm.mass = m->flex.back().m;
      bm.I_BBo_B = m->flex.back().rigid_inertia();
      m->max_modes = std::max(m->max_modes, bm.nm);
    }
    m->total_mass += bm.mass;
    m->bodies.push_back(std::move(bm));
  }
  int i0 = 0;
  for (std::size_t j = 0; j < system.joints.size(); ++j) {
    const Joint& J = system.joints[j];
    Model::JointM jm;
    jm.name = J.name;
    jm.type = J.type;
    jm.parent = J.parent;
    jm.child = J.child;
    jm.i0 = i0;
    // A prescribed revolute joint keeps its coordinate in q* (Joint::dof() is 0: not in the state).
    jm.dof = J.type == JointType::Revolute ? 1 : J.dof();
    if (J.type == JointType::Revolute && J.prescribed) {
      jm.prescribed = true;
      jm.motion = *J.prescribed;
      jm.angle0 = J.angle0;
      m->prescribed_joints.push_back(static_cast<int>(j));
    }
    Model::BodyM& child_body = m->bodies[static_cast<std::size_t>(J.child)];
    jm.size = jm.dof + child_body.nm;
    if (child_body.flex >= 0) child_body.e0 = i0 + jm.dof;
    jm.p_PoJ_P = J.p_PoJ_P;
    jm.p_CoJ_C = J.p_CoJ_C;
    jm.q_PJ0 = J.q_PJ0.normalized();
    jm.R_PJ0 = jm.q_PJ0.toRotationMatrix();
    jm.axis_J = jm.R_PJ0.transpose() * J.axis_P.normalized();
    const Eigen::Matrix3d K = rot::skew(jm.axis_J);
    jm.C0 = jm.R_PJ0;
    jm.C1 = jm.R_PJ0 * K;
    jm.C2 = jm.R_PJ0 * K * K;
    if (J.type != JointType::Free && J.parent_node >= 0) {
      const FlexNode& nd =
          system.bodies[static_cast<std::size_t>(J.parent)].flex->nodes[static_cast<std::size_t>(
              J.parent_node)];
      jm.parent_node = J.parent_node;
      jm.p_PoJ_P = nd.p_BoNi_B;
      jm.Phi_P = nd.Phi_B;
      jm.Psi_P = nd.Psi_B;
      if (system.bodies[static_cast<std::size_t>(J.parent)].flex->geometric_stiffening &&
          nd.G.size() > 0) {
        jm.stiff_P = true;
        jm.e_P = nd.e_B;
        jm.Gs_P = 0.5 * (nd.G + nd.G.transpose());
      }
    }
    if (J.type != JointType::Free && J.child_node >= 0) {
      const FlexNode& nd =
          system.bodies[static_cast<std::size_t>(J.child)].flex->nodes[static_cast<std::size_t>(
              J.child_node)];
      jm.child_node = J.child_node;
      jm.p_CoJ_C = nd.p_BoNi_B;
      jm.Phi_C = nd.Phi_B;
      jm.Psi_C = nd.Psi_B;
      if (system.bodies[static_cast<std::size_t>(J.child)].flex->geometric_stiffening &&
          nd.G.size() > 0) {
        jm.stiff_C = true;
        jm.e_C = nd.e_B;
        jm.Gs_C = 0.5 * (nd.G + nd.G.transpose());
      }
    }
    jm.stiffness = J.stiffness;
    jm.neutral = J.neutral_angle;
    jm.damping = J.damping;
    jm.motor_revolute = J.motor_revolute;
    jm.motor_spherical = J.motor_spherical;
    const std::string& child = system.bodies[static_cast<std::size_t>(J.child)].name;
    if (J.type == JointType::Free || J.type == JointType::Spherical) {
      jm.euler_set = static_cast<int>(m->euler_sets.size());
      Model::EulerSetM es;
      es.i0 = J.type == JointType::Free ? i0 + 3 : i0;
      es.owner = J.type == JointType::Free ? child : J.name;
      es.what = J.type == JointType::Free ? "attitude of body '" + child + "'"
                                          : "relative attitude of spherical joint '" + J.name +
                                                "' (body '" + child + "')";
      m->euler_sets.push_back(es);
    }
    // State labels: q* block (joint coordinates, then the child's modal coordinates).
    switch (J.type) {
      case JointType::Free:
        for (const char* s : {".x", ".y", ".z", ".euler1", ".euler2", ".euler3"})
          m->labels.push_back(child + s);
        break;
      case JointType::Revolute:
        m->labels.push_back(J.name + ".angle");
        break;
      case JointType::Spherical:
        for (const char* s : {".euler1", ".euler2", ".euler3"}) m->labels.push_back(J.name + s);
        break;
      case JointType::Fixed:
        break;
    }
    if (const auto& f = system.bodies[static_cast<std::size_t>(J.child)].flex)
      for (const std::string& mode : f->mode_names) m->labels.push_back(child + "." + mode);
    i0 += jm.size;
    m->joints.push_back(std::move(jm));
  }
  m->n = i0;
  for (Model::JointM& J : m->joints)
    if (J.parent_node >= 0) J.parent_e0 = m->bodies[static_cast<std::size_t>(J.parent)].e0;
  for (Model::JointM& J : m->joints)
    if (J.child_node >= 0) J.child_e0 = m->bodies[static_cast<std::size_t>(J.child)].e0;
  // Tree structure: subtrees, the joint of every coordinate, each body's supporting pi'.
  const std::size_t nj = m->joints.size();
  for (std::size_t j = 0; j < nj; ++j) {
    m->all_joints.push_back(static_cast<int>(j));
    for (int i = 0; i < m->joints[j].size; ++i) m->coordinate_joint.push_back(static_cast<int>(j));
  }
  std::vector<int> joint_of_body(m->bodies.size(), -1);
  for (std::size_t j = 0; j < nj; ++j)
    joint_of_body[static_cast<std::size_t>(m->joints[j].child)] = static_cast<int>(j);
  for (std::size_t j = 0; j < nj; ++j) {
    cancel::poll();
    // Joint k is below j when walking up from k's child reaches j's child.
    for (std::size_t k = j; k < nj; ++k) {
      int b = m->joints[k].child;
      while (b >= 0 && b != m->joints[j].child)
        b = m->joints[static_cast<std::size_t>(joint_of_body[static_cast<std::size_t>(b)])].parent;
      if (b >= 0) m->joints[j].subtree.push_back(static_cast<int>(k));
    }
  }
  m->support.resize(m->bodies.size());
  for (std::size_t b = 0; b < m->bodies.size(); ++b) {
    for (int bb = static_cast<int>(b); bb >= 0;) {
      const Model::JointM& J =
          m->joints[static_cast<std::size_t>(joint_of_body[static_cast<std::size_t>(bb)])];
      for (int i = 0; i < J.size; ++i) m->support[b].push_back(J.i0 + i);
      bb = J.parent;
    }
    std::sort(m->support[b].begin(), m->support[b].end());
  }
  for (const Joint& J : system.joints) {
    const std::string& child = system.bodies[static_cast<std::size_t>(J.child)].name;
    switch (J.type) {
      case JointType::Free:
        for (const char* s : {".vx", ".vy", ".vz", ".wx", ".wy", ".wz"})
          m->labels.push_back(child + s);
        break;
      case JointType::Revolute:
        m->labels.push_back(J.name + ".rate");
        break;
      case JointType::Spherical:
        for (const char* s : {".wx", ".wy", ".wz"}) m->labels.push_back(J.name + s);
        break;
      case JointType::Fixed:
        break;
    }
    if (const auto& f = system.bodies[static_cast<std::size_t>(J.child)].flex)
      for (const std::string& mode : f->mode_names)
        m->labels.push_back(child + "." + mode + "_rate");
  }
  m->set_of_coordinate.assign(static_cast<std::size_t>(m->n), -1);
  for (std::size_t s = 0; s < m->euler_sets.size(); ++s)
    for (int a = 0; a < 3; ++a)
      m->set_of_coordinate[static_cast<std::size_t>(m->euler_sets[s].i0 + a)] = static_cast<int>(s);
  // T and V do not depend on the free base's position (the first three coordinates). A
  // prescribed base's angle is kept: its derivative enters the joint torque.
  m->base_free = system.base_is_free();
  m->base_set = m->base_free ? m->joints[0].euler_set : -1;
  for (int r = m->base_free ? 3 : 0; r < m->n; ++r) m->gradient_dirs.push_back(r);
  m->has_prescribed = !m->prescribed_joints.empty();
  m->state_of.assign(static_cast<std::size_t>(m->n), -1);
  for (int i = 0; i < m->n; ++i) {
    const Model::JointM& J = m->joints[static_cast<std::size_t>(m->coordinate_joint[static_cast<std::size_t>(i)])];
    if (J.prescribed && i == J.i0) continue;
    m->state_of[static_cast<std::size_t>(i)] = static_cast<int>(m->free_index.size());
    m->free_index.push_back(i);
  }
  m->nf = static_cast<int>(m->free_index.size());
  // A prescribed base has no linear momentum of its own to choose (docs/prescribed-motion.md).
  m->zero_linear_momentum = system.zero_linear_momentum && m->base_free;
  m->rechart = options.rechart;
  m->layout = OutputLayout(system);
  m->recharts_column = m->layout.add_extra("lagrange.recharts", "");

  // Workspace, sized once.
  auto w = std::make_unique<Workspace>();
  const int n = m->n;
  const int nb = static_cast<int>(m->bodies.size());
  const std::size_t ns = m->euler_sets.size();
  w->chart.assign(ns, kDefaultChart);
  w->last_a2.assign(ns, 0.0);
  w->A.assign(ns, Eigen::Matrix3d::Identity());
  w->A_dual.assign(ns, Mat3<Dual<2>>::Identity());
  w->B.assign(ns, Eigen::Matrix3d::Identity());
  w->k0.resize(*m);
  w->k1.resize(*m);
  std::apply([&](auto&... k) { (k.resize(*m), ...); }, w->kg);
  w->Xi.assign(static_cast<std::size_t>(nb), Eigen::Matrix<double, 6, Eigen::Dynamic>::Zero(6, n));
  w->Xi_dot = w->Xi;
  w->fi0.resize(static_cast<std::size_t>(nb));
  for (std::size_t b = 0; b < m->bodies.size(); ++b)
    w->fi0[b].resize(m->bodies[b].nm, m->bodies[b].flex >= 0 &&
                                          m->flex[static_cast<std::size_t>(m->bodies[b].flex)].stiff);
  w->he1.assign(static_cast<std::size_t>(m->max_modes), Dual<1>(0.0));
  w->he0 = Eigen::VectorXd::Zero(m->max_modes);
  w->unit = Eigen::VectorXd::Zero(m->max_modes);
  w->q_NB.assign(static_cast<std::size_t>(nb), Eigen::Quaterniond::Identity());
  w->M = Eigen::MatrixXd::Zero(n, n);
  w->U = Eigen::MatrixXd::Zero(n, n);
  w->DX = Eigen::Matrix<double, 6, Eigen::Dynamic>::Zero(6, n);
  w->Y = w->DX;
  w->Yd = w->DX;
  for (Eigen::VectorXd* v :
       {&w->u, &w->qdot, &w->p, &w->Mdot_u, &w->hamel, &w->dL, &w->N, &w->f, &w->udot, &w->seed,
        &w->inv_diag})
    *v = Eigen::VectorXd::Zero(n);
  w->xf = Eigen::VectorXd::Zero(2 * n);
  w->Mff = Eigen::MatrixXd::Zero(m->nf, m->nf);
  w->Uff = w->Mff;
  w->bf = Eigen::VectorXd::Zero(m->nf);
  w->inv_diag_f = w->bf;
  w->torque = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(m->prescribed_joints.size()));
  model_ = std::move(m);
  ws_ = std::move(w);
}

LagrangeEngine::~LagrangeEngine() = default;

int LagrangeEngine::state_size() const {
  return 2 * model_->nf;
}
int LagrangeEngine::dof() const {
  return model_->nf;
}
long LagrangeEngine::recharts() const {
  return ws_->recharts;
}
long LagrangeEngine::lock_crossings() const {
  return ws_->lock_crossings;
}
int LagrangeEngine::euler_sets() const {
  return static_cast<int>(model_->euler_sets.size());
}
std::string LagrangeEngine::euler_set_owner(int s) const {
  return model_->euler_sets.at(static_cast<std::size_t>(s)).owner;
}
int LagrangeEngine::chart(int s) const {
  return ws_->chart.at(static_cast<std::size_t>(s));
}
std::string LagrangeEngine::chart_name(int s) const {
  return kSequences[static_cast<std::size_t>(chart(s))].name;
}
const OutputLayout& LagrangeEngine::layout() const {
  return model_->layout;
}
int LagrangeEngine::modal_index(int body) const {
  const int e0 = model_->bodies.at(static_cast<std::size_t>(body)).e0;
  return e0 < 0 ? -1 : model_->state_of[static_cast<std::size_t>(e0)];
}

std::string LagrangeEngine::state_label(int i) const {
  const Model& m = *model_;
  if (i < 0 || i >= 2 * m.nf) return "x[" + std::to_string(i) + "]";
  return full_label(i < m.nf ? m.free_index[static_cast<std::size_t>(i)]
                             : m.n + m.free_index[static_cast<std::size_t>(i - m.nf)]);
}

// State x (free coordinates) => xf, the full (q*, pi') with the prescribed joints' angle
// angle0 + theta(t) and rate theta'(t) (docs/prescribed-motion.md, "The motion").
const double* LagrangeEngine::expand(double t, const double* x) {
  const Model& m = *model_;
  if (!m.has_prescribed) return x;
  Workspace& w = *ws_;
  double* xf = w.xf.data();
  for (int a = 0; a < m.nf; ++a) {
    const int i = m.free_index[static_cast<std::size_t>(a)];
    xf[i] = x[a];
    xf[m.n + i] = x[m.nf + a];
  }
  for (int j : m.prescribed_joints) {
    const Model::JointM& J = m.joints[static_cast<std::size_t>(j)];
    xf[J.i0] = J.angle0 + J.motion.angle(t);
    xf[m.n + J.i0] = J.motion.velocity(t);
  }
  return xf;
}

std::string LagrangeEngine::full_label(int i) const {
  if (i < 0 || i >= static_cast<int>(model_->labels.size())) return "x[" + std::to_string(i) + "]";
  std::string label = model_->labels[static_cast<std::size_t>(i)];
  if (i < model_->n && model_->set_of_coordinate[static_cast<std::size_t>(i)] >= 0)
    label += " (" + chart_name(model_->set_of_coordinate[static_cast<std::size_t>(i)]) + ")";
  return label;
}

// ------------------------------------------------------------------------------------------------
// pack: TreeState => x, choosing for every Euler set a chart far from its singularity.
// ------------------------------------------------------------------------------------------------
void LagrangeEngine::pack(const TreeState& s, double* x) {
  const Model& m = *model_;
  Workspace& w = *ws_;
  if (s.joints.size() != m.joints.size())
    throw InputError("engine lagrange: pack() got a state with " + std::to_string(s.joints.size()) +
                     " joints for a system with " + std::to_string(m.joints.size()));
  const int n = m.n;
  double* const xs = x;
  if (m.has_prescribed) x = w.xf.data();  // fill the full (q*, pi'), then keep the free part
  double* q = x;
  double* u = x + n;
  auto set_angles = [&](int set, const Eigen::Quaterniond& quat, double* angles) {
    const Eigen::Matrix3d R = quat.normalized().toRotationMatrix();
    int c = kDefaultChart;
    if (chart_singularity(kSequences[kDefaultChart], R) > std::sin(kPackDeg * kDeg))
      c = best_chart(R);
    w.chart[static_cast<std::size_t>(set)] = c;
    const Eigen::Vector3d a = euler_angles(kSequences[static_cast<std::size_t>(c)], R);
    for (int i = 0; i < 3; ++i) angles[i] = a(i);
  };
  for (std::size_t j = 0; j < m.joints.size(); ++j) {
    const Model::JointM& J = m.joints[j];
    const TreeState::JointState& js = s.joints[j];
    double* qj = q + J.i0;
    double* uj = u + J.i0;
    switch (J.type) {
      case JointType::Free:
        for (int i = 0; i < 3; ++i) {
          qj[i] = s.p_NoBo_N(i);
          uj[i] = s.v_NBo_N(i);
          uj[3 + i] = s.w_NB_B(i);
        }
        set_angles(J.euler_set, s.q_NB, qj + 3);
        break;
      case JointType::Revolute:
        qj[0] = J.prescribed ? J.angle0 + J.motion.angle(0.0) : js.angle;  // pack() is at t = 0
        uj[0] = J.prescribed ? J.motion.velocity(0.0) : js.rate;
        break;
      case JointType::Spherical:
        set_angles(J.euler_set, js.q_J, qj);
        for (int i = 0; i < 3; ++i) uj[i] = js.w_PC_C(i);
        break;
      case JointType::Fixed:
        break;
    }
  }
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const Model::BodyM& B = m.bodies[b];
    if (B.flex < 0) continue;
    const auto nm = static_cast<Eigen::Index>(B.nm);
    if (b >= s.eta.size() || b >= s.eta_rate.size() || s.eta[b].size() != nm ||
        s.eta_rate[b].size() != nm)
      throw InputError("engine lagrange: pack() got a state without the " + std::to_string(nm) +
                       " modal coordinates and rates of flexible body '" + B.name + "'");
    for (Eigen::Index k = 0; k < nm; ++k) {
      q[B.e0 + k] = s.eta[b](k);
      u[B.e0 + k] = s.eta_rate[b](k);
    }
  }
  if (m.zero_linear_momentum) {
    // Every body's linear momentum contains its mass times the base velocity once (the base
    // velocity adds to every point's velocity): choose it so that the total is zero, modal rates
    // included (docs/flexible-bodies.md "Initial state and momentum").
    for (int i = 0; i < 3; ++i) u[i] = 0.0;
    const Eigen::Vector3d P = linear_momentum_full(x);
    for (int i = 0; i < 3; ++i) u[i] = -P(i) / m.total_mass;
  }
  if (m.has_prescribed)
    for (int a = 0; a < m.nf; ++a) {
      const int i = m.free_index[static_cast<std::size_t>(a)];
      xs[a] = x[i];
      xs[m.nf + a] = x[n + i];
    }
  // The run starts here (pack() is at t = 0): after_step() compares the first accepted state's
  // lock sheets with these.
  for (std::size_t set = 0; set < m.euler_sets.size(); ++set)
    w.last_a2[set] = q[m.euler_sets[set].i0 + 1];
  w.last_t = 0.0;
  w.have_last = true;
}

// ------------------------------------------------------------------------------------------------
// charts: (q*) => A, B per Euler set. Throws at an exactly singular chart.
// ------------------------------------------------------------------------------------------------
void LagrangeEngine::prepare_charts(double t, const double* x) {
  const Model& m = *model_;
  Workspace& w = *ws_;
  for (std::size_t s = 0; s < m.euler_sets.size(); ++s) {
    const double* a = x + m.euler_sets[s].i0;
    const EulerSequence& seq = kSequences[static_cast<std::size_t>(w.chart[s])];
    if (std::abs(std::cos(a[1])) < 1e-9)
      throw RunFailure("lagrange", t, full_label(m.euler_sets[s].i0 + 1),
                       m.euler_sets[s].what + " is at the singularity of its " + seq.name +
                           " Euler angles (second angle " + format_number(a[1] / kDeg) + " deg)");
    // A depends on a2 and a3 only (euler_chart.hpp): Dual<2> seeded on them (dA/da1 = 0), its
    // derivatives kept for Hamel's term.
    w.A_dual[s] = euler_rate_matrix(seq, Dual<2>::variable(a[1], 0), Dual<2>::variable(a[2], 1));
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) w.A[s](r, c) = w.A_dual[s](r, c).v;
    w.B[s] = w.A[s].inverse();
  }
}

// ------------------------------------------------------------------------------------------------
// evaluate: (t, x) => M, p, (dM/dt) pi', B^T W^T p, B^T dL/dq*, N, q*', pi''.
// ------------------------------------------------------------------------------------------------
namespace {

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

template <int K>
void gradient_chunk(const Model& m, LagrangeEngine::Workspace& w, const int* chart, const double* x,
                    const int* dirs) {
  Kin<Dual<K>>& k = std::get<K - 1>(w.kg);
  const int n = m.n;
  for (int i = 0; i < n; ++i) k.q[static_cast<std::size_t>(i)] = Dual<K>(x[i]);
  // Seed direction c: the quasi-displacement d(pi) = e_r, i.e. dq* = B e_r (Eq. 22).
  for (int c = 0; c < K; ++c) {
    const int r = dirs[c];
    const int set = m.set_of_coordinate[static_cast<std::size_t>(r)];
    if (set >= 0) {
      const int i0 = m.euler_sets[static_cast<std::size_t>(set)].i0;
      for (int a = 0; a < 3; ++a)
        k.q[static_cast<std::size_t>(i0 + a)].d[static_cast<std::size_t>(c)] =
            w.B[static_cast<std::size_t>(set)](a, r - i0);
    } else {
      k.q[static_cast<std::size_t>(r)].d[static_cast<std::size_t>(c)] = 1.0;
    }
  }
  // The base's quasi-displacement e_r of its rotation block turns it by e_r in body axes (dq* =
  // B e_r, so A dq* = e_r). A prescribed base has no Euler angles: pose_pass turns it itself.
  if (m.base_set >= 0) {
    const int b0 = m.euler_sets[static_cast<std::size_t>(m.base_set)].i0;
    std::array<Eigen::Vector3d, K> theta;
    for (int c = 0; c < K; ++c) {
      const int a = dirs[c] - b0;
      theta[static_cast<std::size_t>(c)] = Eigen::Vector3d::Zero();
      if (a >= 0 && a < 3) theta[static_cast<std::size_t>(c)](a) = 1.0;
    }
    const Mat3<Dual<K>> R_base = base_attitude<K>(w.R_NB0, theta);
    pose_pass(m, chart, k, false, &R_base);
  } else {
    pose_pass(m, chart, k, false);
  }
  twist_pass(m, k, x + n, m.all_joints);
  const Dual<K> L = kinetic_energy_of(m, k, x + n) - potential_energy_of(m, chart, k.q.data());
  for (int c = 0; c < K; ++c) w.dL(dirs[c]) = L.d[static_cast<std::size_t>(c)];
}

template <int... K>
void gradient_dispatch(std::integer_sequence<int, K...>, int width, const Model& m,
                       LagrangeEngine::Workspace& w, const int* chart, const double* x,
                       const int* dirs) {
  ((width == K + 1 ? gradient_chunk<K + 1>(m, w, chart, x, dirs) : void()), ...);
}

// Mass pass of one flexible body b (see the file comment): with Y_i = (Xi_i, e_i on the body's
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

// Mass pass of one rigid body (see the file comment): D = diag(I_BBo_B, m 1) the body's inertia
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
// with R R^T = 1). Defined after the Workspace.
void rigid_mass_pass(const Model::BodyM& B, const std::vector<int>& sup, const double* X,
                     const double* Xd, const double* u, const Mat3<Dual<1>>& R, bool translation,
                     LagrangeEngine::Workspace& w);

// solve: M x = b for symmetric positive definite M (upper triangle read), by Cholesky M = U^T U
// (Golub & Van Loan 2013, "Matrix Computations", 4th ed., Alg. 4.2.1, in its column (gaxpy) form:
// every inner product runs down two contiguous columns of U), then U^T y = b and U x = y.
// b => x in place; U is scratch of M's size and inv_diag of its diagonal's (the reciprocals of
// U's diagonal: one division per column, the rest multiplications). Returns false when M is not
// positive definite (a pivot <= 0, or NaN). A plain loop: at this engine's sizes (n up to a few
// dozen) it is faster than a blocked, dynamically dispatched factorisation. The kernel is written
// once, for a size known at compile time (N > 0, n <= kFixedCholesky: the loops unroll completely,
// about half the instructions at n = 8) and for one known at run time (N = 0); both do the same
// operations in the same order (unrolling reorders nothing), so their results are identical.
constexpr int kFixedCholesky = 12;

#define CROSSDYN_UNROLL _Pragma("GCC unroll 12")
template <int N>
bool cholesky_kernel(Eigen::Index n_runtime, const double* M, double* U, double* r, double* v) {
  const Eigen::Index n = N > 0 ? N : n_runtime;
  CROSSDYN_UNROLL for (Eigen::Index j = 0; j < n; ++j) {
    double* uj = U + j * n;
    const double* mj = M + j * n;
    double d = mj[j];
    CROSSDYN_UNROLL for (Eigen::Index i = 0; i < j; ++i) {
      const double* ui = U + i * n;
      double s = mj[i];
      CROSSDYN_UNROLL for (Eigen::Index k = 0; k < i; ++k) s -= ui[k] * uj[k];
      uj[i] = s * r[i];
      d -= uj[i] * uj[i];
    }
    if (!(d > 0.0)) return false;
    uj[j] = std::sqrt(d);
    r[j] = 1.0 / uj[j];
  }
  CROSSDYN_UNROLL for (Eigen::Index j = 0; j < n; ++j) {  // U^T y = b: row j of U^T is column j
    const double* uj = U + j * n;
    double s = v[j];
    CROSSDYN_UNROLL for (Eigen::Index k = 0; k < j; ++k) s -= uj[k] * v[k];
    v[j] = s * r[j];
  }
  CROSSDYN_UNROLL for (Eigen::Index j = n - 1; j >= 0; --j) {  // U x = y, column by column
    const double* uj = U + j * n;
    const double vj = v[j] * r[j];
    v[j] = vj;
    CROSSDYN_UNROLL for (Eigen::Index k = 0; k < j; ++k) v[k] -= uj[k] * vj;
  }
  return true;
}
#undef CROSSDYN_UNROLL

template <int... N>
bool cholesky_dispatch(std::integer_sequence<int, N...>, Eigen::Index n, const double* M, double* U,
                       double* r, double* v) {
  bool ok = false;
  const bool fixed =
      ((n == N + 1 ? (ok = cholesky_kernel<N + 1>(n, M, U, r, v), true) : false) || ...);
  return fixed ? ok : cholesky_kernel<0>(n, M, U, r, v);
}

bool cholesky_solve(const Eigen::MatrixXd& M, Eigen::MatrixXd& U, Eigen::VectorXd& inv_diag,
                    Eigen::VectorXd& x) {
  return cholesky_dispatch(std::make_integer_sequence<int, kFixedCholesky>(), M.rows(), M.data(),
                           U.data(), inv_diag.data(), x.data());
}

}  // namespace

namespace {

// Mass pass of one rigid body (declared above): the supporting columns are gathered into Y (6 x s)
// and their rates into Yd, then DY = D Y, G = Y^T D Y (s x s; its upper triangle goes into M),
// p_S += DY^T xi, (dM/dt pi')_S += Yd^T D xi + DY^T xidot. Fixed 6-row blocks, so every product
// is a vectorised 6-term inner product.
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
  // The translation rows in closed form (see the declaration); the translation seeds come first
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

// M holds its upper triangle only: M_ij = M(min(i, j), max(i, j)).
inline double LagrangeEngine::reduced_rhs(const Model& m, const Workspace& w, int a) {
  const int i = m.free_index[static_cast<std::size_t>(a)];
  double b = w.f(i);
  for (int j : m.prescribed_joints) {
    const int c = m.joints[static_cast<std::size_t>(j)].i0;
    b -= (i <= c ? w.M(i, c) : w.M(c, i)) * w.udot(c);
  }
  return b;
}

void LagrangeEngine::evaluate(double t, const double* x) {
  const Model& m = *model_;
  Workspace& w = *ws_;
  const int n = m.n;
  const int* chart = w.chart.data();
  w.u = Eigen::Map<const Eigen::VectorXd>(x + n, n);

  // charts: A, B; q*' = B pi' (Eq. 16 inverted).
  prepare_charts(t, x);
  w.qdot = w.u;
  for (std::size_t s = 0; s < m.euler_sets.size(); ++s) {
    const int i0 = m.euler_sets[s].i0;
    w.qdot.segment<3>(i0) = w.B[s] * w.u.segment<3>(i0);
  }

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
    if (Ji.type == JointType::Free && i - Ji.i0 < 3) {
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
  w.N.setZero();
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
    // Body torque (on the body frame): virtual power tau . w_NB_B(pi') => N_i = tau . w(e_i).
    if (!B.torque.empty()) {
      Eigen::Vector3d tau = B.torque.value(t);
      if (B.torque_frame == Body::Frame::Inertial) {
        Eigen::Matrix3d R;
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) R(r, c) = w.k1.R_NB[b](r, c).v;
        tau = R.transpose() * tau;
      }
      for (int i : sup) w.N(i) += X.col(i).head<3>().dot(tau);
    }
    // Modal damping: generalised force -D eta' (docs/flexible-bodies.md "Energy").
    if (B.flex >= 0) {
      const Eigen::MatrixXd& Dm = m.flex[static_cast<std::size_t>(B.flex)].Dmp;
      for (int k = 0; k < B.nm; ++k) {
        double f = 0;
        for (int l = 0; l < B.nm; ++l) f += Dm(k, l) * w.u(B.e0 + l);
        w.N(B.e0 + k) -= f;
      }
    }
  }

  // Joint dampers and motors: the torque tau acts on the child-side joint frame and -tau on the
  // parent-side one, so its virtual power is tau . (w_Jc - w_Jp) = tau . w_rel, and w_rel is the
  // joint's own quasi-velocity (axis rate, or w_PC_C in child-side joint-frame components) even
  // when a side is a node frame of a flexible body: the generalised force is tau on the joint's
  // rates and nothing on any eta' (the node frames' rotations cancel in the pair; the single-frame
  // forces (Jl Psi)^T tau_B of docs/flexible-bodies.md "Loads at joints" sum to zero here).
  for (const Model::JointM& J : m.joints) {
    if (J.type == JointType::Revolute) {
      w.N(J.i0) += -J.damping * w.u(J.i0) + J.motor_revolute.value(t)(0);
    } else if (J.type == JointType::Spherical) {
      w.N.segment<3>(J.i0) += -J.damping * w.u.segment<3>(J.i0) + J.motor_spherical.value(t);
    }
  }

  // gradient pass: B^T d(T - V)/dq* at fixed pi', in chunks of Dual<K <= 8>.
  w.dL.setZero();
  const int nd = static_cast<int>(m.gradient_dirs.size());
  for (int c0 = 0; c0 < nd; c0 += kMaxChunk) {
    cancel::poll();
    const int width = std::min(kMaxChunk, nd - c0);
    gradient_dispatch(std::make_integer_sequence<int, kMaxChunk>(), width, m, w, chart, x,
                      m.gradient_dirs.data() + c0);
  }

  // hamel: W_lk = sum_j (dA_lk/da_j - dA_lj/da_k) a'_j per Euler set; term B^T W^T p.
  w.hamel.setZero();
  for (std::size_t s = 0; s < m.euler_sets.size(); ++s) {
    const int i0 = m.euler_sets[s].i0;
    const Mat3<Dual<2>>& A = w.A_dual[s];  // charts: A and its derivatives in a2, a3
    const Eigen::Vector3d ad = w.qdot.segment<3>(i0);
    auto dA = [&A](int l, int kk, int j) {  // dA_lk/da_j
      return j == 0 ? 0.0 : A(l, kk).d[static_cast<std::size_t>(j - 1)];
    };
    Eigen::Matrix3d W;
    for (int l = 0; l < 3; ++l)
      for (int kk = 0; kk < 3; ++kk) {
        double v = 0.0;
        for (int j = 0; j < 3; ++j) v += (dA(l, kk, j) - dA(l, j, kk)) * ad(j);
        W(l, kk) = v;
      }
    w.hamel.segment<3>(i0) = w.B[s].transpose() * (W.transpose() * w.p.segment<3>(i0));
  }

  // solve: M pi'' = N + B^T dL/dq* - (dM/dt) pi' - B^T W^T p.
  w.f = w.N + w.dL - w.Mdot_u - w.hamel;
  if (!m.has_prescribed) {
    w.udot = w.f;
    if (!cholesky_solve(w.M, w.U, w.inv_diag, w.udot))
      throw RunFailure("lagrange", t, "", "mass matrix is not positive definite");
    return;
  }
  // Prescribed joints (docs/prescribed-motion.md): the equations above hold for every coordinate
  // with, on a prescribed coordinate c, the joint torque tau_c as an extra generalised force (its
  // virtual power is tau_c times the rate, as for a motor). Partitioned into free (f) and
  // prescribed (c) coordinates with pi''_c = theta''(t) known (Greenwood, "Advanced Dynamics"
  // 2003, Sec. 2.4, rheonomic constraints; Lagrange's equations of the constrained coordinate
  // give its constraint force):
  //   M_ff pi''_f = f_f - M_fc theta'',        tau_c = M_cf pi''_f + M_cc theta'' - f_c.
  // M holds its upper triangle only: M_ij = M(min(i, j), max(i, j)).
  auto Msym = [&w](int i, int j) { return i <= j ? w.M(i, j) : w.M(j, i); };
  for (int j : m.prescribed_joints) {
    const Model::JointM& J = m.joints[static_cast<std::size_t>(j)];
    w.udot(J.i0) = J.motion.accel(t);
  }
  const int nf = m.nf;
  for (int a = 0; a < nf; ++a) {
    const int i = m.free_index[static_cast<std::size_t>(a)];
    w.bf(a) = reduced_rhs(m, w, a);
    for (int bb = a; bb < nf; ++bb) w.Mff(a, bb) = Msym(i, m.free_index[static_cast<std::size_t>(bb)]);
  }
  if (!cholesky_solve(w.Mff, w.Uff, w.inv_diag_f, w.bf))
    throw RunFailure("lagrange", t, "", "mass matrix is not positive definite");
  for (int a = 0; a < nf; ++a) w.udot(m.free_index[static_cast<std::size_t>(a)]) = w.bf(a);
  for (std::size_t k = 0; k < m.prescribed_joints.size(); ++k) {
    const int c = m.joints[static_cast<std::size_t>(m.prescribed_joints[k])].i0;
    double tau = -w.f(c);
    for (int i = 0; i < n; ++i) tau += Msym(c, i) * w.udot(i);
    w.torque(static_cast<Eigen::Index>(k)) = tau;
  }
}

void LagrangeEngine::rhs(double t, const double* x, double* xdot) {
  const Model& m = *model_;
  evaluate(t, expand(t, x));
  const int n = m.nf;
  if (!m.has_prescribed) {
    for (int i = 0; i < n; ++i) {
      xdot[i] = ws_->qdot(i);
      xdot[n + i] = ws_->udot(i);
    }
  } else {
    for (int a = 0; a < n; ++a) {
      const int i = m.free_index[static_cast<std::size_t>(a)];
      xdot[a] = ws_->qdot(i);
      xdot[n + a] = ws_->udot(i);
    }
  }
  for (int i = 0; i < 2 * n; ++i)
    if (!std::isfinite(xdot[i]))
      throw RunFailure("lagrange", t, state_label(i), "non-finite derivative");
}

LagrangeEngine::Terms LagrangeEngine::terms(double t, const double* x) {
  evaluate(t, expand(t, x));
  const Workspace& w = *ws_;
  Eigen::MatrixXd M = w.M;  // evaluate() fills the upper triangle only
  M.triangularView<Eigen::StrictlyLower>() = M.transpose();
  return Terms{M, w.p, w.Mdot_u, w.hamel, w.dL, w.N, w.qdot, w.udot};
}

// ------------------------------------------------------------------------------------------------
// linear_system: (t, x) => the system of the solve pass written out (Engine::linear_system), for
// the conditioning study. Boltzmann-Hamel equations (paper Eq. 23; Whittaker 1944, Ch. II,
// equations for quasi-coordinates; Meirovitch 1970, Ch. 4, Lagrange's equations in terms of
// quasi-coordinates):
//   M(q*) pi'' = f,   f = N + B^T d(T - V)/dq* - (dM/dt) pi' - B^T W^T p,
// M and f exactly as evaluate() leaves them for its Cholesky solve. The unknowns pi'' are the
// derivatives of the quasi-velocities, joint rates and modal rates, i.e. of x's second half:
// speed_index[i] = nf + i. The Euler angles enter through A(q*) and B = A^-1 of the set's current
// chart (the one x is in; evaluate() reads the workspace's charts and changes none), as in rhs().
// With prescribed joints the system solved is the free block (Greenwood 2003, Sec. 2.4, rheonomic
// constraints; "solve" in evaluate()):
//   M_ff pi''_f = f_f - M_fc theta'',
// whose right-hand side evaluate() overwrites with pi''_f; it is formed again here by the same
// reduced_rhs().
// ------------------------------------------------------------------------------------------------
Engine::LinearSystem LagrangeEngine::linear_system(double t, const double* x) {
  const Model& m = *model_;
  evaluate(t, expand(t, x));
  const Workspace& w = *ws_;
  const int nf = m.nf;
  LinearSystem ls;
  ls.speed_index.resize(static_cast<std::size_t>(nf));
  for (int a = 0; a < nf; ++a) ls.speed_index[static_cast<std::size_t>(a)] = nf + a;
  const std::string count = std::to_string(nf) + " velocities (M factored by Cholesky)";
  if (!m.has_prescribed) {
    ls.A = w.M;  // evaluate() fills the upper triangle only (the one the Cholesky kernel reads)
    ls.b = w.f;
    ls.what = "Boltzmann-Hamel equations M(q*) pi'' = f, " + count;
  } else {
    ls.A = w.Mff;  // upper triangle, as above
    ls.b.resize(nf);
    for (int a = 0; a < nf; ++a) ls.b(a) = reduced_rhs(m, w, a);
    ls.what = "Boltzmann-Hamel equations M_ff(q*) pi_f'' = f_f - M_fc theta'', " + count + " (" +
              std::to_string(m.prescribed_joints.size()) + " prescribed joint" +
              (m.prescribed_joints.size() == 1 ? "" : "s") + " eliminated)";
  }
  ls.A.triangularView<Eigen::StrictlyLower>() = ls.A.transpose();
  return ls;
}

// ------------------------------------------------------------------------------------------------
// after_step: detect the approach to an Euler-angle singularity; re-chart or stop.
//
// A chart's singularity (gimbal lock) is where its middle angle a2 is 90 deg + k 180 deg (det A =
// -+cos a2 = 0; Kane, Likins & Levinson 1983, Sec. 1.16; Wertz 1978, App. E). The integrator
// carries a2 on continuously (it is not wrapped), so the locks cut the a2 axis into sheets
//   sheet(a2) = floor((a2 + 90 deg) / 180 deg)
// (sheet 0: |a2| < 90 deg). A step whose accepted states lie on different sheets crossed a lock in
// between, however far from it both states are (a long dense-output step in a spin goes from 60
// to 120 deg, or across several locks, and |cos a2| is large at both ends). So the test here is
// on the state AND on the step since the last accepted state (pack() or the last after_step()):
//   limit      |cos a2| < cos(kFailDeg) at the state: within 1 deg of a lock;
//   crossing   sheet(a2) differs from the last accepted state's (same chart: a re-chart records
//              its new a2).
// rechart == false: either one throws RunFailure naming the set and the angle; for a crossing the
// reported time is the crossing of the first lock passed, estimated by linear interpolation of a2
// between the two accepted states (the message says so and gives both states), not the time of
// the accepted step, which may be seconds later.
// rechart == true: the set is re-charted when the state is within 90 - kRechartDeg deg of a lock
// (as before) OR a lock was crossed since the last accepted state. The engine cannot reject an
// accepted step (Engine::after_step may only change the state or stop the run), so a step that
// jumped over the re-chart zone is kept: the integrator's error test accepted it like any other.
// The equations in the old chart hold on both sides of the lock (they are singular only AT it; a
// stage within 1e-9 of it stops the run, prepare_charts), and a motion through the lock itself (a
// pure spin) is smooth in that chart; for one passing near it, the step's accuracy rests on the
// error test alone, as for any accepted step. The state it ended in is a valid attitude on
// another sheet and is re-charted at once to the chart farthest from its singularity, so the
// angles are back on sheet 0 of a well-conditioned chart; lock_crossings() counts these.
// Outputs a dense-output step interpolated before after_step() ran are not changed: with
// rechart == false a failed run may have rows past the reported crossing time.
// ------------------------------------------------------------------------------------------------
namespace {

double lock_sheet(double a2) {
  return std::floor((a2 + 0.5 * std::numbers::pi) / std::numbers::pi);
}

}  // namespace

bool LagrangeEngine::after_step(double t, double* x) {
  const Model& m = *model_;
  Workspace& w = *ws_;
  bool changed = false;
  // Euler angles are never prescribed: work on their place in x directly.
  auto at = [&m](int i) { return m.state_of[static_cast<std::size_t>(i)]; };
  for (std::size_t s = 0; s < m.euler_sets.size(); ++s) {
    double* a = x + at(m.euler_sets[s].i0);
    const EulerSequence& seq = kSequences[static_cast<std::size_t>(w.chart[s])];
    const double cos_a2 = std::abs(std::cos(a[1]));  // 0 at gimbal lock
    const double a2_last = w.last_a2[s];
    const bool crossed = w.have_last && lock_sheet(a[1]) != lock_sheet(a2_last);
    if (!m.rechart && crossed) {
      // The first lock passed after a2_last, in the direction of travel, and when (linear).
      const double sheet = lock_sheet(a2_last);
      const double lock = (a[1] > a2_last ? sheet + 0.5 : sheet - 0.5) * std::numbers::pi;
      const double t_lock = w.last_t + (lock - a2_last) / (a[1] - a2_last) * (t - w.last_t);
      throw RunFailure(
          "lagrange", t_lock, full_label(m.euler_sets[s].i0 + 1),
          m.euler_sets[s].what + " reached gimbal lock of its " + seq.name +
              " Euler angles: second angle crossed " + format_number(lock / kDeg, "%.0f") +
              " deg (limit " + format_number(kFailDeg) +
              " deg) between the accepted states at t = " + format_number(w.last_t, "%.9g") +
              " s (" + format_number(a2_last / kDeg, "%.3f") + " deg) and t = " +
              format_number(t, "%.9g") + " s (" + format_number(a[1] / kDeg, "%.3f") +
              " deg), at t = " + format_number(t_lock, "%.9g") +
              " s by linear interpolation (the time reported), and re-charting is off "
              "(EngineOptions::rechart = false)");
    }
    if (!m.rechart && cos_a2 < std::cos(kFailDeg * kDeg))
      throw RunFailure("lagrange", t, full_label(m.euler_sets[s].i0 + 1),
                       m.euler_sets[s].what + " reached gimbal lock of its " + seq.name +
                           " Euler angles: second angle " + format_number(a[1] / kDeg, "%.3f") +
                           " deg (limit " + format_number(kFailDeg) +
                           " deg) and re-charting is off (EngineOptions::rechart = false)");
    if (m.rechart && (crossed || cos_a2 < std::cos(kRechartDeg * kDeg))) {
      // Re-chart: the same attitude in the chart farthest from its singularity. pi' (w_NB_B or
      // w_PC_C) does not depend on the chart, so nothing else changes.
      const Eigen::Matrix3d R = euler_rotation(seq, a[0], a[1], a[2]);
      const int c = best_chart(R);
      const Eigen::Vector3d an = euler_angles(kSequences[static_cast<std::size_t>(c)], R);
      for (int i = 0; i < 3; ++i) a[i] = an(i);
      w.chart[s] = c;
      ++w.recharts;
      if (crossed) ++w.lock_crossings;
      w.last_a2[s] = a[1];
      changed = true;
      continue;
    }
    w.last_a2[s] = a[1];
    // Keep the first and third angles bounded (they grow without limit while spinning) so that
    // the integrator's relative tolerance means the same thing all run long.
    for (int i : {0, 2})
      if (std::abs(a[i]) > 4.0 * std::numbers::pi) {
        a[i] = std::remainder(a[i], 2.0 * std::numbers::pi);
        ++w.wraps;
        changed = true;
      }
  }
  w.last_t = t;
  return changed;
}

// ------------------------------------------------------------------------------------------------
// Outputs and engine-neutral accelerations
// ------------------------------------------------------------------------------------------------
double LagrangeEngine::kinetic_energy(const double* x, double t) {
  return kinetic_energy_full(expand(t, x));
}
double LagrangeEngine::potential_energy(const double* x, double t) {
  return potential_energy_full(expand(t, x));
}
Eigen::Vector3d LagrangeEngine::angular_momentum_N(const double* x, double t) {
  return angular_momentum_full(expand(t, x));
}
Eigen::Vector3d LagrangeEngine::linear_momentum_N(const double* x, double t) {
  return linear_momentum_full(expand(t, x));
}
std::vector<double> LagrangeEngine::prescribed_torques(double t, const double* x) {
  const Model& m = *model_;
  evaluate(t, expand(t, x));
  std::vector<double> tau(m.joints.size(), 0.0);
  for (std::size_t k = 0; k < m.prescribed_joints.size(); ++k)
    tau[static_cast<std::size_t>(m.prescribed_joints[k])] = ws_->torque(static_cast<Eigen::Index>(k));
  return tau;
}

double LagrangeEngine::kinetic_energy_full(const double* x) {
  Workspace& w = *ws_;
  for (int i = 0; i < model_->n; ++i) w.k0.q[static_cast<std::size_t>(i)] = x[i];
  pose_pass(*model_, w.chart.data(), w.k0, true);
  twist_pass(*model_, w.k0, x + model_->n, model_->all_joints);
  return kinetic_energy_of(*model_, w.k0, x + model_->n);
}

double LagrangeEngine::potential_energy_full(const double* x) {
  return potential_energy_of(*model_, ws_->chart.data(), x);
}

namespace {

// Per body, from the pose and twist passes in k: linear momentum P (N), angular momentum about Bo
// h (N) and first mass moment s = sum m_i x_i (N) (docs/flexible-bodies.md "Energy": the nodes'
// m_i x_i x v_i, plus R_NB J_i w). A flexible body's are R (h_v, h_w, m p_Bo + R s(eta)) with
// h_w = dT/dw and h_v = dT/dv of flex_body.hpp.
struct BodyMomenta {
  Eigen::Vector3d P, h, s;
};
BodyMomenta body_momenta(const Model& m, Kin<double>& k, const double* u, std::size_t b) {
  const Model::BodyM& B = m.bodies[b];
  if (B.flex < 0)
    return {k.R_NB[b] * (B.mass * k.v_NBo_B[b]), k.R_NB[b] * (B.I_BBo_B * k.w_NB_B[b]),
            B.mass * k.p_NoBo_N[b]};
  Eigen::Vector3d hw, hv;
  flex_momentum(m.flex[static_cast<std::size_t>(B.flex)], k.fi[b], k.w_NB_B[b], k.v_NBo_B[b],
                u + B.e0, hw, hv, static_cast<double*>(nullptr));
  return {k.R_NB[b] * hv, k.R_NB[b] * hw, B.mass * k.p_NoBo_N[b] + k.R_NB[b] * k.fi[b].s};
}

}  // namespace

Eigen::Vector3d LagrangeEngine::linear_momentum_full(const double* x) {
  kinetic_energy_full(x);  // pose and twist passes into k0
  Eigen::Vector3d P = Eigen::Vector3d::Zero();
  for (std::size_t b = 0; b < model_->bodies.size(); ++b)
    P += body_momenta(*model_, ws_->k0, x + model_->n, b).P;
  return P;
}

// H about the system CM c: sum_b (p_Bo x P_b + h_b) - x_c x P, x_c = sum_b s_b / m_total (the
// angular momentum about the origin, moved to the CM).
Eigen::Vector3d LagrangeEngine::angular_momentum_full(const double* x) {
  kinetic_energy_full(x);
  const Model& m = *model_;
  Kin<double>& k = ws_->k0;
  Eigen::Vector3d H = Eigen::Vector3d::Zero(), P = Eigen::Vector3d::Zero(),
                  s = Eigen::Vector3d::Zero();
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const BodyMomenta bm = body_momenta(m, k, x + m.n, b);
    H += k.p_NoBo_N[b].cross(bm.P) + bm.h;
    P += bm.P;
    s += bm.s;
  }
  return H - (s / m.total_mass).cross(P);
}

void LagrangeEngine::output_row(double t, const double* xs, double* row) {
  const Model& m = *model_;
  Workspace& w = *ws_;
  const int n = m.n;
  const double* x = expand(t, xs);
  if (m.has_prescribed) evaluate(t, x);  // the prescribed joints' torques
  const double* u = x + n;
  const double E = kinetic_energy_full(x) + potential_energy_full(x);
  const double H = angular_momentum_full(x).norm();  // leaves the pose and twist passes in k0
  // Attitude quaternions: q_NC = q_NP q(psi_P) q_PJ0 q_J q(psi_C)^*, q_J from the joint's own
  // coordinates, q(psi) the node frame's rotation vector psi = Psi eta (exp map).
  auto node_q = [&](const Eigen::Matrix3Xd& Psi, int e0) {
    Eigen::Vector3d psi = Eigen::Vector3d::Zero();
    for (Eigen::Index k = 0; k < Psi.cols(); ++k) psi += Psi.col(k) * x[e0 + k];
    return rot::from_rotation_vector(psi);
  };
  for (const Model::JointM& J : m.joints) {
    const double* qj = x + J.i0;
    const auto c = static_cast<std::size_t>(J.child);
    auto euler_q = [&](const double* a) {
      const Eigen::Vector4d e = euler_quaternion(
          kSequences[static_cast<std::size_t>(w.chart[static_cast<std::size_t>(J.euler_set)])],
          a[0], a[1], a[2]);
      return Eigen::Quaterniond(e(0), e(1), e(2), e(3));
    };
    if (J.type == JointType::Free) {
      w.q_NB[c] = euler_q(qj + 3);
      continue;
    }
    Eigen::Quaterniond q_J = Eigen::Quaterniond::Identity();
    if (J.type == JointType::Revolute) q_J = Eigen::AngleAxisd(qj[0], J.axis_J);
    if (J.type == JointType::Spherical) q_J = euler_q(qj);
    Eigen::Quaterniond q = J.parent >= 0 ? w.q_NB[static_cast<std::size_t>(J.parent)]
                                         : Eigen::Quaterniond::Identity();  // a prescribed base
    if (J.parent_node >= 0) q = q * node_q(J.Psi_P, J.parent_e0);
    q = q * J.q_PJ0 * q_J;
    if (J.child_node >= 0) q = q * node_q(J.Psi_C, J.child_e0).conjugate();
    w.q_NB[c] = q.normalized();
  }
  RowWriter out(m.layout, row);
  out.time(t);
  for (std::size_t b = 0; b < m.bodies.size(); ++b)
    out.body(static_cast<int>(b), w.k0.w_NB_B[b], w.q_NB[b]);
  for (std::size_t j = 0; j < m.joints.size(); ++j) {
    const Model::JointM& J = m.joints[j];
    if (J.type == JointType::Revolute) out.revolute(static_cast<int>(j), x[J.i0], u[J.i0]);
    if (J.type == JointType::Spherical)
      out.spherical(static_cast<int>(j), Eigen::Vector3d(u[J.i0], u[J.i0 + 1], u[J.i0 + 2]));
  }
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const Model::BodyM& B = m.bodies[b];
    if (B.flex < 0) continue;
    out.modal(static_cast<int>(b), Eigen::Map<const Eigen::VectorXd>(x + B.e0, B.nm),
              Eigen::Map<const Eigen::VectorXd>(u + B.e0, B.nm));
  }
  for (std::size_t k = 0; k < m.prescribed_joints.size(); ++k)
    out.joint_torque(m.prescribed_joints[k], w.torque(static_cast<Eigen::Index>(k)));
  out.momentum(H);
  out.energy(E);
  out.extra(m.recharts_column, static_cast<double>(w.recharts));
}

void LagrangeEngine::accelerations(double t, const double* x, TreeAccel& a) {
  evaluate(t, expand(t, x));
  const Model& m = *model_;
  const Workspace& w = *ws_;
  const std::size_t nb = m.bodies.size(), nj = m.joints.size();
  a.wdot_NB_B.assign(nb, Eigen::Vector3d::Zero());
  a.a_NBo_N.assign(nb, Eigen::Vector3d::Zero());
  a.angle_ddot.assign(nj, 0.0);
  a.wdot_PC_C.assign(nj, Eigen::Vector3d::Zero());
  a.eta_ddot.assign(nb, Eigen::VectorXd());
  // Body twist xi = Xi(q*) pi' => xi' = Xi pi'' + (dXi/dt) pi'.
  for (std::size_t b = 0; b < nb; ++b) {
    const Eigen::Matrix<double, 6, 1> xid = w.Xi[b] * w.udot + w.Xi_dot[b] * w.u;
    a.wdot_NB_B[b] = xid.head<3>();
    const Model::BodyM& B = m.bodies[b];
    // The twist holds v_NBo_B, so a_NBo_N = R_NB (v_NBo_B' + w x v_NBo_B) (Kane & Levinson 1985,
    // Sec. 2.3, differentiation in two reference frames).
    const Eigen::Matrix<double, 6, 1> xi = w.Xi[b] * w.u;
    Eigen::Matrix3d R;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) R(r, c) = w.k1.R_NB[b](r, c).v;
    a.a_NBo_N[b] = R * (xid.tail<3>() + xi.head<3>().cross(xi.tail<3>()));
    if (B.flex >= 0) a.eta_ddot[b] = w.udot.segment(B.e0, B.nm);
  }
  for (std::size_t j = 0; j < nj; ++j) {
    const Model::JointM& J = m.joints[j];
    if (J.type == JointType::Revolute) a.angle_ddot[j] = w.udot(J.i0);
    if (J.type == JointType::Spherical) a.wdot_PC_C[j] = w.udot.segment<3>(J.i0);
  }
}

}  // namespace crossdyn::lagrange
