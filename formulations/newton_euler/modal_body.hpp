// The Newton-Euler equations of one flexible (modal) body in the floating frame of reference: the
// paper's Eqs. (3)-(6) for the model of docs/flexible-bodies.md, with every term kept.
//
// Notation (core/system.hpp): B the body frame, origin Bo at the undeformed CM; R = R_NB;
// w = w_NB_B; node i: mass m_i, undeformed position p_i, rigid inertia J_i, shapes Phi_i (3 x n);
// r_i = p_i + u_i, u_i = Phi_i eta, u_i' = Phi_i eta' (body-frame derivative).
//
// Unknown accelerations of the body: nu' = [a (= d/dt v_NBo_N, N components); alpha (= d/dt w_NB_B,
// B components); eta''] (6 + n). Node i's acceleration, in B components (Kane, Likins & Levinson
// 1983, Sec. 2.7; the paper's Eq. (3) with R_2'' + P_2'' + U_2'' expanded):
//   R^T a_i = R^T a + alpha x r_i + w x (w x r_i) + 2 w x u_i' + Phi_i eta''.
// Multiplying Newton's law m_i a_i = f_i by the virtual displacements of node i,
// delta x_i = delta p + R (delta theta x r_i + Phi_i delta eta), summing over the nodes and adding
// the nodes' rigid inertias (J_i alpha + w x J_i w, virtual rotation delta theta) gives the three
// equations the paper writes: the translational one (Eq. (1): sum of the node forces), the rotational
// one about Bo (Eq. (6): r_i x Eq. (3), summed) and the modal one (Eqs. (4)-(5): Phi_l . Eq. (3),
// summed). They are the floating-frame-of-reference equations of Shabana (2005), "Dynamics of
// Multibody Systems", 3rd ed., Ch. 5 (the mass matrix written with the inertia shape integrals,
// and the quadratic velocity vector), written here for a lumped-mass (nodal) body, with the
// translational unknown in N components and the rotational one in B components:
//
//   M(eta, R) nu' = f_bias + f_applied + J^T lambda
//
//         [ m 1             -R [S x]     R Phi_bar ]      S      = sum m_i r_i = S0 + Phi_bar eta
//   M  =  [ [S x] R^T        I(eta)      Lambda    ]      I(eta) = sum J_i + sum m_i (|r_i|^2 1 - r_i r_i^T)
//         [ Phi_bar^T R^T    Lambda^T    M_ee      ]      Lambda = sum m_i [r_i x] Phi_i   (3 x n)
//                                                         M_ee   = sum m_i Phi_i^T Phi_i    (n x n)
//   f_bias = [ -R (w x (w x S) + 2 w x Phi_bar eta') ;
//              -w x I w - 2 sum m_i r_i x (w x u_i') ;
//              -[sum m_i Phi_ik . (w x (w x r_i))]_k - [2 sum m_i Phi_ik . (w x u_i')]_k - K eta - D eta' ]
// (the modal strain and damping forces -K eta - D eta' are internal: their resultant force and
// moment vanish, so they appear only in the modal rows).
//
// Invariants (Shabana 2005, Ch. 5, "inertia shape integrals", here node sums), precomputed from the nodes once,
// so that no per-state cost grows with the number of nodes:
//   m = sum m_i, S0 = sum m_i p_i, J_sum = sum J_i, Q0 = sum m_i p_i p_i^T,
//   Phi_bar = sum m_i Phi_i, Lambda0 = sum m_i [p_i x] Phi_i, M_ee = sum m_i Phi_i^T Phi_i,
//   C_k = sum m_i Phi_ik p_i^T, D_kl = sum m_i Phi_ik Phi_il^T (3 x 3 each),
//   G_kl = sum m_i Phi_ik x Phi_il (the columns of Lambda_k = sum m_i [Phi_ik x] Phi_i).
// Per state, with B_k = sum m_i Phi_ik r_i^T = C_k + sum_l eta_l D_kl (3 x 3, O(9 n^2) in all):
//   sum m_i r_i r_i^T = Q0 + sum_k eta_k (B_k + C_k^T)          (so I(eta) = J_sum + tr(.) 1 - (.))
//   Lambda[:, k]     = vex(B_k - B_k^T)  (= sum m_i r_i x Phi_ik; equals Lambda0 + sum_l eta_l Lambda_l)
//   sum m_i Phi_ik . (w x (w x r_i)) = w^T B_k w - |w|^2 tr B_k
//   sum m_i r_i x (w x u_i') = tr(P) w - P w,  P = sum m_i u_i' r_i^T = sum_k eta'_k B_k
//   sum m_i Phi_ik . (w x u_i') = -w . sum_l G_kl eta'_l.
// Cost per state: O(n^3) for the B_k (n small), independent of the number of nodes.
//
// Momentum and energy (docs/flexible-bodies.md "Energy"): linear momentum m v + R (w x S + Phi_bar
// eta'); angular momentum about Bo, relative to Bo's motion, R (I w + Lambda eta') + (R S) x v
// (the node sums of m_i (x_i - p) x v_i plus R J_i w); kinetic energy 1/2 nu^T M nu.
// Geometric stiffening (FlexBody::geometric_stiffening; docs/flexible-bodies.md "Geometric
// stiffening"; Kane, Ryan & Banerjee 1987, Eq. (8); Sharf 1995): u_i = Phi_i eta + e_i w_i,
// w_i = 1/2 eta^T G_i eta. Then, exactly (no term dropped),
//   u_i' = Phi~_i eta',  Phi~_i(eta) = Phi_i + e_i (G_i eta)^T   (the node's partial velocities),
//   u_i'' = Phi~_i eta'' + e_i q_i,  q_i = eta'^T G_i eta',
// so the equations above hold with Phi_i replaced by Phi~_i(eta) (virtual displacement
// delta x_i = delta p + R (delta theta x r_i + Phi~_i delta eta)), r_i = p_i + u_i with the
// second-order u_i, and the node acceleration gaining e_i q_i:
//   R^T a_i = R^T a + alpha x r_i + Phi~_i eta'' + c_i,  c_i = w x (w x r_i) + 2 w x u_i' + e_i q_i,
//   M = [m 1, -R [S x], R Phi~_bar; ., I(eta), Lambda~; ., ., M~_ee] with Phi~_bar = sum m_i Phi~_i,
//   Lambda~ = sum m_i [r_i x] Phi~_i, M~_ee = sum m_i Phi~_i^T Phi~_i,
//   f_bias = [-R sum m_i c_i; -sum m_i r_i x c_i - w x J_sum w; -sum m_i Phi~_i^T c_i - K eta - D eta'].
// Phi~ depends on eta, so the node-sum invariants above do not apply: these terms are node sums
// per state, O(nodes n^2) per call (the linear model keeps the invariants, unchanged).
#pragma once

#include "core/system.hpp"

#include <Eigen/Core>

#include <vector>

namespace crossdyn::newton_euler {

// The constant modal integrals of one flexible body.
struct ModalInvariants {
  int n = 0;                        // modes
  double m = 0;                     // kg
  Eigen::Vector3d S0 = Eigen::Vector3d::Zero();   // sum m_i p_i (zero for the model's origin)
  Eigen::Matrix3d J_sum = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d Q0 = Eigen::Matrix3d::Zero();
  Eigen::Matrix3Xd Phi_bar, Lambda0;   // 3 x n
  Eigen::MatrixXd M_ee;                // n x n
  std::vector<Eigen::Matrix3d> C;      // n
  std::vector<Eigen::Matrix3d> D;      // n x n, D[k * n + l]
  Eigen::Matrix3Xd G;                  // 3 x n^2, column k * n + l = G_kl
  Eigen::MatrixXd K, Dmp;              // modal stiffness and damping (n x n)
  // Geometric stiffening: the nodes themselves (per node mass, p_i, J_i, Phi_i, e_i, G_i).
  bool stiffening = false;
  std::vector<double> node_m;
  std::vector<Eigen::Vector3d> node_p, node_e;
  std::vector<Eigen::Matrix3Xd> node_Phi;
  std::vector<Eigen::MatrixXd> node_G;

  // The node sums. extra_inertia is added to J_sum (EngineOptions::test_inertia_scale).
  static ModalInvariants from(const FlexBody& flex, const Eigen::Matrix3d& extra_inertia);
  // The undeformed rotational inertia about Bo: J_sum + tr(Q0) 1 - Q0.
  Eigen::Matrix3d rigid_inertia() const;
};

// One flexible body's terms at one state (a preallocated workspace: no allocation per state), on
// the scalar T (double for the run; std::complex<double> for the exact tangent, scalar.hpp).
template <class T>
struct ModalTermsT {
  using V3 = Eigen::Matrix<T, 3, 1>;
  using M3 = Eigen::Matrix<T, 3, 3>;
  using M3X = Eigen::Matrix<T, 3, Eigen::Dynamic>;
  using MX = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;
  using VX = Eigen::Matrix<T, Eigen::Dynamic, 1>;
  V3 S = V3::Zero();         // sum m_i r_i, B
  M3 I = M3::Zero();         // I(eta), about Bo, B
  M3X Lambda;                // 3 x n
  V3 p_rel = V3::Zero();     // Phi_bar eta', B
  V3 h_rel = V3::Zero();     // Lambda eta' = sum m_i r_i x u_i', B
  std::vector<M3> B;         // B_k
  MX M;                      // (6 + n) x (6 + n)
  VX f;                      // f_bias (6 + n)
  VX g;                      // stiffening scratch: G_i eta (n)
  M3X Phit;                  // stiffening scratch: Phi~_i (3 x n)

  explicit ModalTermsT(int n = 0);
};
using ModalTerms = ModalTermsT<double>;

// (invariants, R_NB, w_NB_B, eta, eta') => M, f_bias and the momentum terms. No allocation.
void modal_terms(const ModalInvariants& inv, const Eigen::Matrix3d& R_NB, const Eigen::Vector3d& w,
                 const Eigen::Ref<const Eigen::VectorXd>& eta,
                 const Eigen::Ref<const Eigen::VectorXd>& eta_dot, ModalTerms& out);
// The same on the scalar S, instantiated for double (what modal_terms calls) and
// std::complex<double> (modal_body.cpp; the exact tangent: no |.|, no conjugation, scalar.hpp).
template <class S>
void modal_terms_t(const ModalInvariants& inv, const Eigen::Matrix<S, 3, 3>& R_NB,
                 const Eigen::Matrix<S, 3, 1>& w, const Eigen::Ref<const Eigen::Matrix<S, Eigen::Dynamic, 1>>& eta,
                 const Eigen::Ref<const Eigen::Matrix<S, Eigen::Dynamic, 1>>& eta_dot, ModalTermsT<S>& out);

// With geometric stiffening, node i's second-order terms at eta, eta' (no allocation):
// w_i = 1/2 eta^T G_i eta, eta^T G_i eta' (= d/dt w_i) and q_i = eta'^T G_i eta'.
struct Foreshortening {
  double w = 0, w_dot = 0, q = 0;
};
Foreshortening foreshortening(const Eigen::MatrixXd& G, const Eigen::Ref<const Eigen::VectorXd>& eta,
                              const Eigen::Ref<const Eigen::VectorXd>& eta_dot);

// S = sum m_i r_i and p_rel = sum m_i u_i' (body frame) at (eta, eta'), for either model.
void modal_first_moments(const ModalInvariants& inv, const Eigen::Ref<const Eigen::VectorXd>& eta,
                         const Eigen::Ref<const Eigen::VectorXd>& eta_dot, Eigen::Vector3d& S,
                         Eigen::Vector3d& p_rel);

}  // namespace crossdyn::newton_euler
