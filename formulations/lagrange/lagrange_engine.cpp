// The Lagrange engine (see lagrange_engine.hpp for the coordinates and the equations).
//
// Passes of one right-hand-side evaluation, (t, x = (q*, pi')) => (q*', pi''):
//   charts        (q*) => A, B = A^-1 per Euler set; q*' = B pi'                  (Eqs. 16, 22)
//   pose          (q*) => R_NB, R_PC, p_NoBo_N per body              [templated on the scalar]
//   twist         (pose, pi') => w_NB_B, v_NBo_N per body             [templated on the scalar]
//   energy        (twists) => T,  (q*) => V                           [templated on the scalar]
//   mass pass     Dual<1> seeded with the motion q*' (time derivative at fixed pi'), twists for
//                 every unit seed pi' = e_i. T is quadratic in pi', so its derivatives in pi' are
//                 the symmetric bilinear form T(xi, eta) of the seeds (polarisation):
//                   M_ij = d2T/dpi_i dpi_j = T(e_i, e_j),   p_i = dT/dpi_i = T(e_i, pi'),
//                 and the Dual<1> parts give d/dt p at pi'' = 0, i.e. (dM/dt) pi'.
//                 Generalised forces of body torques: N_i = tau . w(e_i) (virtual power).
//   gradient      Dual<K> (chunks of K <= 8) seeded with the quasi-displacements dq* = B e_r:
//                 L = T - V => B^T dL/dq* at fixed pi'.
//   hamel         Dual<3> on A(a) per Euler set => W, B^T W^T p.
//   solve         M pi'' = N + B^T dL/dq* - (dM/dt) pi' - B^T W^T p   (Cholesky, M is SPD).
// All scratch lives in the Workspace, sized in the constructor: rhs() does not allocate.
#include "formulations/lagrange/lagrange_engine.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <tuple>
#include <utility>

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/rotation.hpp"
#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/euler_chart.hpp"

namespace crossdyn::lagrange {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr int kMaxChunk = 8;  // widest Dual<K> of the gradient pass

std::string format_number(double v, const char* fmt = "%.6g") {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

}  // namespace

// ------------------------------------------------------------------------------------------------
// Model: the System in the engine's terms, immutable after construction.
// ------------------------------------------------------------------------------------------------
struct LagrangeEngine::Model {
  struct BodyM {
    std::string name;
    double mass = 0;
    Eigen::Matrix3d I_BBo_B;  // times EngineOptions::test_inertia_scale
    Body::Frame torque_frame = Body::Frame::Body;
    PiecewiseConstant<3> torque;
  };
  struct JointM {
    std::string name;
    JointType type = JointType::Revolute;
    int parent = -1, child = -1;
    int i0 = 0;          // first index of this joint's block in q* and in pi'
    int euler_set = -1;  // index of its Euler-angle set (free, spherical), else -1
    Eigen::Vector3d p_PoJ_P, p_CoJ_C;
    Eigen::Matrix3d R_PJ0;
    Eigen::Quaterniond q_PJ0;
    Eigen::Vector3d axis_J;  // revolute axis in the joint (child) frame: R_PJ0^T axis_P
    // Revolute: R_PC(angle) = C0 + C1 sin(angle) + C2 (1 - cos(angle)), i.e. R_PJ0 times
    // Rodrigues' formula I + sin [n x] + (1 - cos) [n x]^2 (Kane, Likins & Levinson 1983,
    // Sec. 1.2).
    Eigen::Matrix3d C0, C1, C2;
    std::vector<int> subtree;  // this joint and every joint below it, in topological order
    double stiffness = 0, neutral = 0, damping = 0;
    PiecewiseConstant<1> motor_revolute;
    PiecewiseConstant<3> motor_spherical;
  };
  struct EulerSetM {
    int i0 = 0;         // index of the first angle in q* (and of w in pi')
    std::string owner;  // base body name or spherical joint name
    std::string what;   // "attitude of body 'main'" / "relative attitude of joint 'j' (...)"
  };

  std::vector<BodyM> bodies;
  std::vector<JointM> joints;
  std::vector<EulerSetM> euler_sets;
  std::vector<int> set_of_coordinate;     // per q* index: its Euler set or -1
  std::vector<int> gradient_dirs;         // quasi-coordinates the Lagrangian can depend on
  std::vector<int> coordinate_joint;      // per q* index: the joint whose block holds it
  std::vector<std::vector<int>> support;  // per body: the pi' indices its twist depends on
  std::vector<int> all_joints;            // 0, 1, ..., in topological order
  int n = 0;
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
struct Kin {
  std::vector<S> q;                      // q* as S, size n
  std::vector<Mat3<S>> R_NB, R_PC;       // per body (R_PC of the body's own joint)
  std::vector<Vec3<S>> p_NoBo_N;         // per body
  std::vector<Vec3<S>> w_NB_B, v_NBo_N;  // per body (twist pass)
  void resize(int n, int nb) {
    q.assign(static_cast<std::size_t>(n), S(0.0));
    R_NB.resize(static_cast<std::size_t>(nb));
    R_PC.resize(static_cast<std::size_t>(nb));
    p_NoBo_N.resize(static_cast<std::size_t>(nb));
    w_NB_B.resize(static_cast<std::size_t>(nb));
    v_NBo_N.resize(static_cast<std::size_t>(nb));
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

// pose: (q*) => R_NB, R_PC, p_NoBo_N. Joint kinematics of system.hpp:
// R_PC = R_PJ0 R_J, R_NC = R_NP R_PC, p_NoCo_N = p_NoPo_N + R_NP p_PoJ_P - R_NC p_CoJ_C.
template <class S>
void pose_pass(const Model& m, const int* chart, Kin<S>& k) {
  for (const Model::JointM& J : m.joints) {
    const auto c = static_cast<std::size_t>(J.child);
    const S* q = k.q.data() + J.i0;
    if (J.type == JointType::Free) {
      const EulerSequence& seq = kSequences[static_cast<std::size_t>(chart[J.euler_set])];
      k.R_NB[c] = euler_rotation(seq, q[3], q[4], q[5]);
      k.R_PC[c] = k.R_NB[c];
      k.p_NoBo_N[c] = Vec3<S>(q[0], q[1], q[2]);
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
    const auto P = static_cast<std::size_t>(J.parent);
    k.R_NB[c] = k.R_NB[P] * R_PC;
    k.p_NoBo_N[c] =
        k.p_NoBo_N[P] + times_const(k.R_NB[P], J.p_PoJ_P) - times_const(k.R_NB[c], J.p_CoJ_C);
  }
}

// twist: (pose, pi') => w_NB_B, v_NBo_N (angular velocities add along the tree; the joint point
// has one velocity seen from both bodies: v_Co = v_Po + w_P x r_PoJ - w_C x r_CoJ).
// Only the joints in `joints` (topological order) are visited: a seed's twists are zero outside the
// subtree of its joint, whose parent twist the caller sets to zero.
template <class S>
void twist_pass(const Model& m, Kin<S>& k, const double* u, const std::vector<int>& joints) {
  for (int j : joints) {
    const Model::JointM& J = m.joints[static_cast<std::size_t>(j)];
    const auto c = static_cast<std::size_t>(J.child);
    const double* uj = u + J.i0;
    if (J.type == JointType::Free) {
      k.v_NBo_N[c] = Vec3<S>(S(uj[0]), S(uj[1]), S(uj[2]));
      k.w_NB_B[c] = Vec3<S>(S(uj[3]), S(uj[4]), S(uj[5]));
      continue;
    }
    const auto P = static_cast<std::size_t>(J.parent);
    Vec3<S> w = k.R_PC[c].transpose() * k.w_NB_B[P];
    if (J.type == JointType::Revolute) {
      for (int a = 0; a < 3; ++a) w(a) += J.axis_J(a) * uj[0];
    } else if (J.type == JointType::Spherical) {
      for (int a = 0; a < 3; ++a) w(a) += uj[a];
    }
    k.w_NB_B[c] = w;
    k.v_NBo_N[c] =
        k.v_NBo_N[P] + k.R_NB[P] * cross(k.w_NB_B[P], J.p_PoJ_P) - k.R_NB[c] * cross(w, J.p_CoJ_C);
  }
}

// T = sum over bodies of (w^T I w + m v.v) / 2 (paper Eqs. 24-25).
template <class S>
S kinetic_energy_of(const Model& m, const Kin<S>& k) {
  S T(0.0);
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const Vec3<S> Iw = const_times(m.bodies[b].I_BBo_B, k.w_NB_B[b]);
    T += 0.5 * (k.w_NB_B[b].dot(Iw) + m.bodies[b].mass * k.v_NBo_N[b].squaredNorm());
  }
  return T;
}

// V(q*) of the hinge springs (system.hpp): revolute k (angle - neutral)^2 / 2, spherical
// k |phi|^2 / 2 with phi the rotation vector of R_J, written in the joint's Euler angles.
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
  std::vector<Eigen::Matrix3d> A, B;  // per Euler set at the current q*
  Kin<double> k0;
  Kin<Dual<1>> k1;
  GradientKins kg;
  std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>> Xi, Xi_dot;  // per body: twists of seeds
  Eigen::MatrixXd M;
  Eigen::LLT<Eigen::MatrixXd> llt;
  Eigen::VectorXd u, qdot, p, Mdot_u, hamel, dL, N, f, udot, seed;
  std::vector<Eigen::Quaterniond> q_NB;  // per body, output_row
};

// ------------------------------------------------------------------------------------------------
// Construction
// ------------------------------------------------------------------------------------------------
LagrangeEngine::LagrangeEngine(const System& system, const EngineOptions& options) {
  auto m = std::make_unique<Model>();
  const std::string where = (system.file.empty() ? system.name : system.file) + ": ";
  if (system.joints.empty() || system.joints[0].type != JointType::Free)
    throw InputError(where +
                     "joints: engine lagrange needs joints[0] to be the free joint of the "
                     "base body");
  if (!(options.test_inertia_scale > 0.0) || !std::isfinite(options.test_inertia_scale))
    throw InputError(where + "engine option test_inertia_scale must be positive, got " +
                     format_number(options.test_inertia_scale));
  for (const Body& b : system.bodies) {
    if (b.flex)
      throw InputError(where + "bodies: body '" + b.name +
                       "' is flexible (modal data): flexible bodies are not supported yet by "
                       "engine lagrange");
    Model::BodyM bm;
    bm.name = b.name;
    bm.mass = b.mass;
    bm.I_BBo_B = b.I_BBo_B * options.test_inertia_scale;
    bm.torque_frame = b.torque_frame;
    bm.torque = b.torque;
    m->bodies.push_back(std::move(bm));
    m->total_mass += b.mass;
  }
  int i0 = 0;
  for (std::size_t j = 0; j < system.joints.size(); ++j) {
    const Joint& J = system.joints[j];
    if (j > 0 && J.type == JointType::Free)
      throw InputError(where + "joints: joint '" + J.name +
                       "' is a second free joint; engine lagrange handles one tree");
    Model::JointM jm;
    jm.name = J.name;
    jm.type = J.type;
    jm.parent = J.parent;
    jm.child = J.child;
    jm.i0 = i0;
    jm.p_PoJ_P = J.p_PoJ_P;
    jm.p_CoJ_C = J.p_CoJ_C;
    jm.q_PJ0 = J.q_PJ0.normalized();
    jm.R_PJ0 = jm.q_PJ0.toRotationMatrix();
    jm.axis_J = jm.R_PJ0.transpose() * J.axis_P.normalized();
    const Eigen::Matrix3d K = rot::skew(jm.axis_J);
    jm.C0 = jm.R_PJ0;
    jm.C1 = jm.R_PJ0 * K;
    jm.C2 = jm.R_PJ0 * K * K;
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
    // State labels: q* block then (later) pi' block.
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
    i0 += J.dof();
    m->joints.push_back(std::move(jm));
  }
  m->n = i0;
  // Tree structure: subtrees, the joint of every coordinate, each body's supporting pi'.
  const std::size_t nj = m->joints.size();
  for (std::size_t j = 0; j < nj; ++j) {
    m->all_joints.push_back(static_cast<int>(j));
    for (int i = 0; i < system.joints[j].dof(); ++i)
      m->coordinate_joint.push_back(static_cast<int>(j));
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
      for (int i = 0;
           i < system.joints[static_cast<std::size_t>(joint_of_body[static_cast<std::size_t>(bb)])]
                   .dof();
           ++i)
        m->support[b].push_back(J.i0 + i);
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
  }
  m->set_of_coordinate.assign(static_cast<std::size_t>(m->n), -1);
  for (std::size_t s = 0; s < m->euler_sets.size(); ++s)
    for (int a = 0; a < 3; ++a)
      m->set_of_coordinate[static_cast<std::size_t>(m->euler_sets[s].i0 + a)] = static_cast<int>(s);
  // T and V do not depend on the base position (the first three coordinates).
  for (int r = 3; r < m->n; ++r) m->gradient_dirs.push_back(r);
  m->zero_linear_momentum = system.zero_linear_momentum;
  m->rechart = options.rechart;
  m->layout = OutputLayout(system);
  m->recharts_column = m->layout.add_extra("lagrange.recharts", "");

  // Workspace, sized once.
  auto w = std::make_unique<Workspace>();
  const int n = m->n;
  const int nb = static_cast<int>(m->bodies.size());
  const std::size_t ns = m->euler_sets.size();
  w->chart.assign(ns, kDefaultChart);
  w->A.assign(ns, Eigen::Matrix3d::Identity());
  w->B.assign(ns, Eigen::Matrix3d::Identity());
  w->k0.resize(n, nb);
  w->k1.resize(n, nb);
  std::apply([&](auto&... k) { (k.resize(n, nb), ...); }, w->kg);
  w->Xi.assign(static_cast<std::size_t>(nb), Eigen::Matrix<double, 6, Eigen::Dynamic>::Zero(6, n));
  w->Xi_dot = w->Xi;
  w->q_NB.assign(static_cast<std::size_t>(nb), Eigen::Quaterniond::Identity());
  w->M = Eigen::MatrixXd::Zero(n, n);
  // Size the factorisation's storage by factorising once (assigning LLT(n) would copy Eigen's
  // uninitialised m_info member, which UBSan reports as an invalid enum load).
  w->llt.compute(Eigen::MatrixXd::Identity(n, n));
  for (Eigen::VectorXd* v :
       {&w->u, &w->qdot, &w->p, &w->Mdot_u, &w->hamel, &w->dL, &w->N, &w->f, &w->udot, &w->seed})
    *v = Eigen::VectorXd::Zero(n);
  model_ = std::move(m);
  ws_ = std::move(w);
}

LagrangeEngine::~LagrangeEngine() = default;

int LagrangeEngine::state_size() const {
  return 2 * model_->n;
}
int LagrangeEngine::dof() const {
  return model_->n;
}
long LagrangeEngine::recharts() const {
  return ws_->recharts;
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

std::string LagrangeEngine::state_label(int i) const {
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
        qj[0] = js.angle;
        uj[0] = js.rate;
        break;
      case JointType::Spherical:
        set_angles(J.euler_set, js.q_J, qj);
        for (int i = 0; i < 3; ++i) uj[i] = js.w_PC_C(i);
        break;
      case JointType::Fixed:
        break;
    }
  }
  if (m.zero_linear_momentum) {
    // Every body's CM velocity contains the base velocity once: choose it so that sum m v = 0.
    for (int i = 0; i < 3; ++i) u[i] = 0.0;
    const Eigen::Vector3d P = linear_momentum_N(x);
    for (int i = 0; i < 3; ++i) u[i] = -P(i) / m.total_mass;
  }
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
      throw RunFailure("lagrange", t, state_label(m.euler_sets[s].i0 + 1),
                       m.euler_sets[s].what + " is at the singularity of its " + seq.name +
                           " Euler angles (second angle " + format_number(a[1] / kDeg) + " deg)");
    w.A[s] = euler_rate_matrix(seq, a[1], a[2]);
    w.B[s] = w.A[s].inverse();
  }
}

// ------------------------------------------------------------------------------------------------
// evaluate: (t, x) => M, p, (dM/dt) pi', B^T W^T p, B^T dL/dq*, N, q*', pi''.
// ------------------------------------------------------------------------------------------------
namespace {

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
  pose_pass(m, chart, k);
  twist_pass(m, k, x + n, m.all_joints);
  const Dual<K> L = kinetic_energy_of(m, k) - potential_energy_of(m, chart, k.q.data());
  for (int c = 0; c < K; ++c) w.dL(dirs[c]) = L.d[static_cast<std::size_t>(c)];
}

template <int... K>
void gradient_dispatch(std::integer_sequence<int, K...>, int width, const Model& m,
                       LagrangeEngine::Workspace& w, const int* chart, const double* x,
                       const int* dirs) {
  ((width == K + 1 ? gradient_chunk<K + 1>(m, w, chart, x, dirs) : void()), ...);
}

}  // namespace

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
  pose_pass(m, chart, w.k1);
  // Twists of the unit seeds pi' = e_i: nonzero only in the subtree of the joint of i (the
  // columns of other bodies stay zero from construction).
  w.seed.setZero();
  for (int i = 0; i < n; ++i) {
    cancel::poll();
    const Model::JointM& Ji =
        m.joints[static_cast<std::size_t>(m.coordinate_joint[static_cast<std::size_t>(i)])];
    if (Ji.parent >= 0) {
      w.k1.w_NB_B[static_cast<std::size_t>(Ji.parent)].setZero();
      w.k1.v_NBo_N[static_cast<std::size_t>(Ji.parent)].setZero();
    }
    w.seed(i) = 1.0;
    twist_pass(m, w.k1, w.seed.data(), Ji.subtree);
    w.seed(i) = 0.0;
    for (int j : Ji.subtree) {
      const auto b = static_cast<std::size_t>(m.joints[static_cast<std::size_t>(j)].child);
      for (int a = 0; a < 3; ++a) {
        w.Xi[b](a, i) = w.k1.w_NB_B[b](a).v;
        w.Xi[b](3 + a, i) = w.k1.v_NBo_N[b](a).v;
        w.Xi_dot[b](a, i) = w.k1.w_NB_B[b](a).d[0];
        w.Xi_dot[b](3 + a, i) = w.k1.v_NBo_N[b](a).d[0];
      }
    }
  }
  // T(xi, eta) = w_xi^T I w_eta + m v_xi . v_eta per body: M_ij = T(e_i, e_j), p = T(e_i, pi'),
  // d/dt p at fixed pi' = T(e_i', pi') + T(e_i, pi'') with ' the Dual<1> parts. Only the pi'
  // supporting the body (its own and its ancestors' joints) contribute.
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
    auto D = [&B](const Eigen::Matrix<double, 6, 1>& xi) {
      Eigen::Matrix<double, 6, 1> r;
      r << B.I_BBo_B * xi.head<3>(), B.mass * xi.tail<3>();
      return r;
    };
    Eigen::Matrix<double, 6, 1> xi = Eigen::Matrix<double, 6, 1>::Zero(), xid = xi;
    for (int i : sup) {
      xi += X.col(i) * w.u(i);
      xid += Xd.col(i) * w.u(i);
    }
    const Eigen::Matrix<double, 6, 1> Dxi = D(xi);
    for (std::size_t ii = 0; ii < sup.size(); ++ii) {
      const int i = sup[ii];
      const Eigen::Matrix<double, 6, 1> Dxi_i = D(X.col(i));
      for (std::size_t jj = ii; jj < sup.size(); ++jj) w.M(i, sup[jj]) += Dxi_i.dot(X.col(sup[jj]));
      w.p(i) += Dxi_i.dot(xi);
      w.Mdot_u(i) += Xd.col(i).dot(Dxi) + Dxi_i.dot(xid);
    }
    // Body torque: virtual power tau . w_NB_B(pi') => N_i = tau . w(e_i).
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
  }
  w.M.triangularView<Eigen::StrictlyLower>() = w.M.transpose();

  // Joint dampers and motors: the quasi-velocity of a joint is its relative rate, so a torque on
  // the child with the reaction on the parent does virtual power tau . rate.
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
    const EulerSequence& seq = kSequences[static_cast<std::size_t>(chart[s])];
    const Dual<3> a2 = Dual<3>::variable(x[i0 + 1], 1), a3 = Dual<3>::variable(x[i0 + 2], 2);
    const Mat3<Dual<3>> A = euler_rate_matrix(seq, a2, a3);
    const Eigen::Vector3d ad = w.qdot.segment<3>(i0);
    Eigen::Matrix3d W;
    for (int l = 0; l < 3; ++l)
      for (int kk = 0; kk < 3; ++kk) {
        double v = 0.0;
        for (int j = 0; j < 3; ++j)
          v += (A(l, kk).d[static_cast<std::size_t>(j)] - A(l, j).d[static_cast<std::size_t>(kk)]) *
               ad(j);
        W(l, kk) = v;
      }
    w.hamel.segment<3>(i0) = w.B[s].transpose() * (W.transpose() * w.p.segment<3>(i0));
  }

  // solve: M pi'' = N + B^T dL/dq* - (dM/dt) pi' - B^T W^T p.
  w.f = w.N + w.dL - w.Mdot_u - w.hamel;
  w.llt.compute(w.M);
  if (w.llt.info() != Eigen::Success)
    throw RunFailure("lagrange", t, "", "mass matrix is not positive definite");
  w.udot = w.f;
  w.llt.solveInPlace(w.udot);
}

void LagrangeEngine::rhs(double t, const double* x, double* xdot) {
  evaluate(t, x);
  const int n = model_->n;
  for (int i = 0; i < n; ++i) {
    xdot[i] = ws_->qdot(i);
    xdot[n + i] = ws_->udot(i);
  }
  for (int i = 0; i < 2 * n; ++i)
    if (!std::isfinite(xdot[i]))
      throw RunFailure("lagrange", t, state_label(i), "non-finite derivative");
}

LagrangeEngine::Terms LagrangeEngine::terms(double t, const double* x) {
  evaluate(t, x);
  const Workspace& w = *ws_;
  return Terms{w.M, w.p, w.Mdot_u, w.hamel, w.dL, w.N, w.qdot, w.udot};
}

// ------------------------------------------------------------------------------------------------
// after_step: detect the approach to an Euler-angle singularity; re-chart or stop.
// ------------------------------------------------------------------------------------------------
bool LagrangeEngine::after_step(double t, double* x) {
  const Model& m = *model_;
  Workspace& w = *ws_;
  bool changed = false;
  for (std::size_t s = 0; s < m.euler_sets.size(); ++s) {
    double* a = x + m.euler_sets[s].i0;
    const EulerSequence& seq = kSequences[static_cast<std::size_t>(w.chart[s])];
    const double cos_a2 = std::abs(std::cos(a[1]));  // 0 at gimbal lock
    if (!m.rechart && cos_a2 < std::cos(kFailDeg * kDeg))
      throw RunFailure("lagrange", t, state_label(m.euler_sets[s].i0 + 1),
                       m.euler_sets[s].what + " reached gimbal lock of its " + seq.name +
                           " Euler angles: second angle " + format_number(a[1] / kDeg, "%.3f") +
                           " deg (limit " + format_number(kFailDeg) +
                           " deg) and re-charting is off (EngineOptions::rechart = false)");
    if (m.rechart && cos_a2 < std::cos(kRechartDeg * kDeg)) {
      // Re-chart: the same attitude in the chart farthest from its singularity. pi' (w_NB_B or
      // w_PC_C) does not depend on the chart, so nothing else changes.
      const Eigen::Matrix3d R = euler_rotation(seq, a[0], a[1], a[2]);
      const int c = best_chart(R);
      const Eigen::Vector3d an = euler_angles(kSequences[static_cast<std::size_t>(c)], R);
      for (int i = 0; i < 3; ++i) a[i] = an(i);
      w.chart[s] = c;
      ++w.recharts;
      changed = true;
      continue;
    }
    // Keep the first and third angles bounded (they grow without limit while spinning) so that
    // the integrator's relative tolerance means the same thing all run long.
    for (int i : {0, 2})
      if (std::abs(a[i]) > 4.0 * std::numbers::pi) {
        a[i] = std::remainder(a[i], 2.0 * std::numbers::pi);
        ++w.wraps;
        changed = true;
      }
  }
  return changed;
}

// ------------------------------------------------------------------------------------------------
// Outputs and engine-neutral accelerations
// ------------------------------------------------------------------------------------------------
double LagrangeEngine::kinetic_energy(const double* x) {
  Workspace& w = *ws_;
  for (int i = 0; i < model_->n; ++i) w.k0.q[static_cast<std::size_t>(i)] = x[i];
  pose_pass(*model_, w.chart.data(), w.k0);
  twist_pass(*model_, w.k0, x + model_->n, model_->all_joints);
  return kinetic_energy_of(*model_, w.k0);
}

double LagrangeEngine::potential_energy(const double* x) {
  return potential_energy_of(*model_, ws_->chart.data(), x);
}

Eigen::Vector3d LagrangeEngine::linear_momentum_N(const double* x) {
  kinetic_energy(x);  // pose and twist passes into k0
  Eigen::Vector3d P = Eigen::Vector3d::Zero();
  for (std::size_t b = 0; b < model_->bodies.size(); ++b)
    P += model_->bodies[b].mass * ws_->k0.v_NBo_N[b];
  return P;
}

Eigen::Vector3d LagrangeEngine::angular_momentum_N(const double* x) {
  kinetic_energy(x);
  const Model& m = *model_;
  const Kin<double>& k = ws_->k0;
  Eigen::Vector3d p_c = Eigen::Vector3d::Zero(), v_c = Eigen::Vector3d::Zero();
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    p_c += m.bodies[b].mass * k.p_NoBo_N[b];
    v_c += m.bodies[b].mass * k.v_NBo_N[b];
  }
  p_c /= m.total_mass;
  v_c /= m.total_mass;
  Eigen::Vector3d H = Eigen::Vector3d::Zero();
  for (std::size_t b = 0; b < m.bodies.size(); ++b)
    H += k.R_NB[b] * (m.bodies[b].I_BBo_B * k.w_NB_B[b]) +
         m.bodies[b].mass * (k.p_NoBo_N[b] - p_c).cross(k.v_NBo_N[b] - v_c);
  return H;
}

void LagrangeEngine::output_row(double t, const double* x, double* row) {
  const Model& m = *model_;
  Workspace& w = *ws_;
  const int n = m.n;
  const double* u = x + n;
  const double E = kinetic_energy(x) + potential_energy(x);
  const double H = angular_momentum_N(x).norm();  // leaves the pose and twist passes in k0
  // Attitude quaternions: q_NC = q_NP q_PJ0 q_J, q_J from the joint's own coordinates.
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
    w.q_NB[c] = (w.q_NB[static_cast<std::size_t>(J.parent)] * J.q_PJ0 * q_J).normalized();
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
  out.momentum(H);
  out.energy(E);
  out.extra(m.recharts_column, static_cast<double>(w.recharts));
}

void LagrangeEngine::accelerations(double t, const double* x, TreeAccel& a) {
  evaluate(t, x);
  const Model& m = *model_;
  const Workspace& w = *ws_;
  const std::size_t nb = m.bodies.size(), nj = m.joints.size();
  a.wdot_NB_B.assign(nb, Eigen::Vector3d::Zero());
  a.a_NBo_N.assign(nb, Eigen::Vector3d::Zero());
  a.angle_ddot.assign(nj, 0.0);
  a.wdot_PC_C.assign(nj, Eigen::Vector3d::Zero());
  // Body twist xi = Xi(q*) pi' => xi' = Xi pi'' + (dXi/dt) pi'.
  for (std::size_t b = 0; b < nb; ++b) {
    const Eigen::Matrix<double, 6, 1> xid = w.Xi[b] * w.udot + w.Xi_dot[b] * w.u;
    a.wdot_NB_B[b] = xid.head<3>();
    a.a_NBo_N[b] = xid.tail<3>();
  }
  for (std::size_t j = 0; j < nj; ++j) {
    const Model::JointM& J = m.joints[j];
    if (J.type == JointType::Revolute) a.angle_ddot[j] = w.udot(J.i0);
    if (J.type == JointType::Spherical) a.wdot_PC_C[j] = w.udot.segment<3>(J.i0);
  }
}

}  // namespace crossdyn::lagrange
