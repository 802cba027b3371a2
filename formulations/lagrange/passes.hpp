// The passes of one evaluation of the Lagrange engine, (t, q*, pi') => pi'' (README.md, "Passes"),
// each a function of the immutable Model and the Workspace it fills. LagrangeEngine::evaluate()
// (lagrange_engine.cpp) calls them in this order, after the charts (euler_charts.cpp). Internal
// header: declarations only, so that each pass's templates stay in its own file.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "formulations/lagrange/model.hpp"

namespace crossdyn::lagrange {

template <class S>
struct Kin;  // kinematics.hpp

// mass_matrix.cpp: M (upper triangle), p = dT/dpi', (dM/dt) pi', the seed twists Xi and their rates
// Xi_dot, the base's R_NB0 and the Dual<1> pose in w.k1. Needs the charts (w.B, w.qdot).
void mass_pass(const Model& m, Workspace& w, const double* x);
// generalised_forces.cpp: N, the generalised forces of body torques, modal damping and joint
// dampers and motors. Needs the mass pass (w.Xi, w.k1.R_NB).
void generalised_forces(const Model& m, Workspace& w, double t);
// gravity.cpp (generalised_forces calls it when Model::gravity): the environment's loads, added to
// N as generalised active forces; per body w.p_g_N, w.F_g_N, w.M_g_N (the equations of motion's).
// Needs the mass pass (w.k1 pose, w.Xi, w.fi0).
void gravity_forces(const Model& m, Workspace& w, double t);
// gravity.cpp: the environment's potential at time t (0 without one), from the double pose pass in
// k (p_NoBo_N, R_NB, the flexible bodies' fi).
double gravity_potential(const Model& m, const Kin<double>& k, double t);
// lagrangian_gradient.cpp: B^T d(T - V)/dq* at fixed pi' (w.dL), in chunks of Dual<K <= 8>. Needs
// the charts (w.B) and the mass pass (w.R_NB0).
void lagrangian_gradient(const Model& m, Workspace& w, const double* x);
// lagrangian_gradient.cpp: sizes the gradient pass's Kin<Dual<K>> for the model (the constructor's;
// there so that the Dual<K> kinematics are instantiated in that file only).
void size_gradient_workspace(const Model& m, Workspace& w);
// hamel_terms.cpp: Hamel's transitivity term B^T W^T p (w.hamel). Needs the charts (w.A_dual) and p.
void hamel_terms(const Model& m, Workspace& w);
// solve.cpp: f = N + B^T dL/dq* - (dM/dt) pi' - B^T W^T p, then M pi'' = f (w.udot), or its free
// block with prescribed joints (and their torques, w.torque). Throws RunFailure at time t when M
// is not positive definite.
void solve(const Model& m, Workspace& w, double t);

// loads.cpp (outputs, not rhs()): per body its momentum rates and external torque, per joint the
// force and moment about its point that the parent exerts on the child, all in N (w.dP_N, w.dK_N,
// w.T_N, w.F_N, w.M_J_N, w.r_J_N), from the child subtree's momentum balance. Needs evaluate() at
// the state (w.Xi, w.Xi_dot, w.u, w.udot, w.k1.fi, w.fi0) and the double pose and twist passes
// into w.k0 at the same state.
void joint_loads(const Model& m, Workspace& w, double t);
// loads.cpp, the parts of joint_loads() on the scalar S, instantiated for double (output_row()) and
// Dual<1> (output_row_tangent(), output_tangent.cpp), so both run the same code: a body's momentum
// rates in N (dP_N, dK_N) from its momenta in body components and their rates, and every joint's
// load (F_N, M_J_N about its point r_J_N, all N) from its child subtree's momentum balance. r_C_node
// per body: its joint's point at a child node (read only for a joint at a node); F_g_N, M_g_N read
// only when Model::gravity.
template <class S>
void momentum_rates(const Model::BodyM& B, const Mat3<S>& R_NB, const Vec3<S>& w_B,
                    const Vec3<S>& v_B, const Vec3<S>& hw, const Vec3<S>& hv, const Vec3<S>& hwd,
                    const Vec3<S>& hvd, Vec3<S>& dP_N, Vec3<S>& dK_N);
template <class S>
void subtree_loads(const Model& m, const std::vector<Vec3<S>>& p_NoBo_N,
                   const std::vector<Mat3<S>>& R_NB, const std::vector<Vec3<S>>& r_C_node,
                   const std::vector<Vec3<S>>& dP_N, const std::vector<Vec3<S>>& dK_N,
                   const std::vector<Vec3<S>>& T_N, const std::vector<Vec3<S>>& F_g_N,
                   const std::vector<Vec3<S>>& M_g_N, std::vector<Vec3<S>>& F_N,
                   std::vector<Vec3<S>>& M_J_N, std::vector<Vec3<S>>& r_J_N);

// outputs.cpp, on the scalar S like the two above (double: output_row(); Dual<1>:
// output_row_tangent()): the system's momenta from its bodies' (returns H about the system CM;
// P_N, p_NoScm_N: the linear momentum and the CM), the power P of the non-conservative loads (u:
// pi', full; torque: per Model::prescribed_joints) and the external moment about the system CM,
// N components.
template <class S>
Vec3<S> system_momenta(const Model& m, const std::vector<Vec3<S>>& p_NoBo_N,
                       const std::vector<Vec3<S>>& P_b, const std::vector<Vec3<S>>& h_b,
                       const std::vector<Vec3<S>>& s_b, Vec3<S>& P_N, Vec3<S>& p_NoScm_N);
template <class S>
S power_of(const Model& m, double t, const S* u, const std::vector<Vec3<S>>& T_N,
           const std::vector<Mat3<S>>& R_NB, const std::vector<Vec3<S>>& w_NB_B, const S* torque);
template <class S>
Vec3<S> external_moment_of(const Model& m, const std::vector<Vec3<S>>& T_N,
                           const std::vector<Vec3<S>>& F_N, const std::vector<Vec3<S>>& M_J_N,
                           const std::vector<Vec3<S>>& r_J_N, const Vec3<S>& p_NoScm_N,
                           const std::vector<Vec3<S>>& p_NoBo_N, const std::vector<Vec3<S>>& F_g_N,
                           const std::vector<Vec3<S>>& M_g_N);

}  // namespace crossdyn::lagrange
