// The Lagrange engine's workspace: every mutable value of rhs() (scratch of the passes, their
// results, the current Euler charts), sized once by the constructor (build_model.cpp): rhs() does
// not allocate. Internal header (formulations/lagrange/*.cpp only).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <tuple>
#include <utility>
#include <vector>

#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/flex_body.hpp"
#include "formulations/lagrange/kinematics.hpp"
#include "formulations/lagrange/model.hpp"

namespace crossdyn::lagrange {

inline constexpr int kMaxChunk = 8;  // widest Dual<K> of the gradient pass (lagrangian_gradient.cpp)

template <class T>
struct Chunks;
template <int... K>
struct Chunks<std::integer_sequence<int, K...>> {
  using type = std::tuple<Kin<Dual<K + 1>>...>;
};
using GradientKins = Chunks<std::make_integer_sequence<int, kMaxChunk>>::type;

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
  // Joint loads (output_row; loads.cpp): per body the rates of its linear momentum dP_N and of its
  // angular momentum about its origin Bo plus v_Bo x P (dK_N, i.e. sum (r_i - p_Bo) x m_i a_i plus
  // the spin rates), and its external torque T_N, all N components; per joint the force F_N and
  // moment about the joint point M_J_N the parent exerts on the child, and the point r_J_N.
  std::vector<Eigen::Vector3d> dP_N, dK_N, T_N, F_N, M_J_N, r_J_N;
  // Momenta (output_row; outputs.cpp angular_momentum_full): per body its linear momentum P_b,
  // angular momentum about Bo h_b and first mass moment s_b (N); the system's linear momentum
  // P_sys and CM p_cm.
  std::vector<Eigen::Vector3d> P_b, h_b, s_b;
  Eigen::Vector3d P_sys = Eigen::Vector3d::Zero(), p_cm = Eigen::Vector3d::Zero();
  // Gravity (gravity.cpp; sized only with an environment): per body its origin p_NoBo_N at the
  // evaluated state, the gravity force F_g_N (the resultant, N components) and its moment about
  // Bo M_g_N, as the equations of motion use them (test_gravity_gradient_sign included); per
  // flexible body the modal generalised force of gravity (max_modes values, gravity.cpp scratch)
  // and, on an orbit, the Dual<1> inertia
  // and modal coordinates of the modal forces' derivatives.
  std::vector<Eigen::Vector3d> p_g_N, F_g_N, M_g_N;
  Eigen::VectorXd Q_g;
  std::vector<FlexInertia<Dual<1>>> fi_g;  // per body (orbit, flexible bodies)
  std::vector<Dual<1>> eta_g;              // max_modes: eta seeded on one mode
  // Prescribed joints: the full (q*, pi') at t (expand), the free block of M, its factor and
  // right-hand side, and the joints' torques (per Model::prescribed_joints).
  Eigen::VectorXd xf;
  Eigen::MatrixXd Mff, Uff;
  Eigen::VectorXd bf, inv_diag_f, torque;
};

}  // namespace crossdyn::lagrange
