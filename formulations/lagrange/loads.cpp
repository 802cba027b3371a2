// The Lagrange engine's joint loads, power and external moment for the output row (issue 26;
// README.md, "Joint loads, power and external moment"). Not part of rhs(): output_row() calls
// these after evaluate() (the accelerations pi'' at the row's state) and after the double pose and
// twist passes into w.k0 (angular_momentum_full).
//
// Lagrange's equations in the minimal coordinates q* carry no constraint forces, so the loads are
// computed from the momentum principles of each joint's child subtree (Greenwood, "Advanced
// Dynamics", 2003, Ch. 1, systems of particles, Eqs. (1.103)-(1.110): Newton's law m_i a_i = F_i +
// internal forces summed over the particles, the internal forces cancelling in equal, opposite and
// collinear pairs, for the force and for the moment about a point; Meirovitch, "Methods of
// Analytical Dynamics", 1970, Ch. 1, the momentum principles of a system of particles). The only
// loads from outside a joint's child subtree are the joint's (from the parent), the external
// body torques T_b and gravity (issue 28: per body the resultant F_g at Bo and its moment M_g about
// Bo, gravity.cpp, as the equations of motion use them), so
//
//   F_N   = sum_{b in subtree} [ dP_b/dt - F_g_b ]
//   M_J_N = sum_{b in subtree} [ (p_Bo - r_J) x (dP_b/dt - F_g_b) + dK_b - T_b - M_g_b ]
//
// with P_b the body's linear momentum and dK_b = sum_i (r_i - p_Bo) x m_i a_i + d/dt(R_NB J_i w)
// its moment of the mass-acceleration about its origin Bo.
//
// momentum_rates and subtree_loads are templated on the scalar (passes.hpp) and instantiated here
// for double, the run's output_row(), and Dual<1>, output_row_tangent() (output_tangent.cpp), whose
// joint loads are thus this code on values carrying their variation (issue 27). The double
// instantiation does the operations of the code it replaced, in the same order: output rows are
// bit-identical (every column of the tangent tests' 48 states). outputs.cpp's system_momenta,
// power_of and external_moment_of likewise.
#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/flex_body.hpp"
#include "formulations/lagrange/kinematics.hpp"
#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/passes.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

// Body b's momentum rates in N from its momenta h_w, h_v in body components and their component
// rates: d/dt (R_NB h) = R_NB (h' + w x h) (Kane & Levinson 1985, Sec. 2.3, differentiation in
// two reference frames); dK_N = sum_i (r_i - p_Bo) x m_i a_i + spin rates = d/dt h_Bo + v_Bo x P
// (the moment of the mass-accelerations about the moving point Bo; Greenwood 2003, Ch. 1, Eqs.
// (1.103)-(1.110)); for a rigid body P = m v_Bo and the second term is zero.
template <class S>
void momentum_rates(const Model::BodyM& B, const Mat3<S>& R_NB, const Vec3<S>& w_B,
                    const Vec3<S>& v_B, const Vec3<S>& hw, const Vec3<S>& hv, const Vec3<S>& hwd,
                    const Vec3<S>& hvd, Vec3<S>& dP_N, Vec3<S>& dK_N) {
  dP_N = R_NB * (hvd + w_B.cross(hv));
  dK_N = R_NB * (hwd + w_B.cross(hw));
  if (B.flex >= 0) dK_N += (R_NB * v_B).cross(R_NB * hv);
}

// Each joint's load from its child subtree's momentum balance (header comment).
template <class S>
void subtree_loads(const Model& m, const std::vector<Vec3<S>>& p_NoBo_N,
                   const std::vector<Mat3<S>>& R_NB, const std::vector<Vec3<S>>& r_C_node,
                   const std::vector<Vec3<S>>& dP_N, const std::vector<Vec3<S>>& dK_N,
                   const std::vector<Vec3<S>>& T_N, const std::vector<Vec3<S>>& F_g_N,
                   const std::vector<Vec3<S>>& M_g_N, std::vector<Vec3<S>>& F_N,
                   std::vector<Vec3<S>>& M_J_N, std::vector<Vec3<S>>& r_J_N) {
  for (std::size_t j = 0; j < m.joints.size(); ++j) {
    const Model::JointM& J = m.joints[j];
    const auto c = static_cast<std::size_t>(J.child);
    // The joint point J on the child: p_CoJ_C, or the child node's displaced point r_C (pose
    // pass); a prismatic joint's point on the child, which slides on the parent (system.hpp).
    const Vec3<S> r_C = J.child_node >= 0 ? r_C_node[c] : Vec3<S>(J.p_CoJ_C.cast<S>());
    const Vec3<S> r_J = p_NoBo_N[c] + R_NB[c] * r_C;
    Vec3<S> F = Vec3<S>::Zero(), M = Vec3<S>::Zero();
    for (int jj : J.subtree) {
      const auto b = static_cast<std::size_t>(m.joints[static_cast<std::size_t>(jj)].child);
      F += dP_N[b];
      M += (p_NoBo_N[b] - r_J).cross(dP_N[b]) + dK_N[b] - T_N[b];
      if (m.gravity) {
        // Gravity on the subtree (gravity.cpp, evaluate() at this state): the resultant F_g at
        // Bo and its moment M_g about Bo are external loads too, so the joint carries the rest.
        F -= F_g_N[b];
        M -= (p_NoBo_N[b] - r_J).cross(F_g_N[b]) + M_g_N[b];
      }
    }
    F_N[j] = F;
    M_J_N[j] = M;
    r_J_N[j] = r_J;
  }
}

// The run's output_row() (double) and output_row_tangent() (Dual<1>: output_tangent.cpp).
template void momentum_rates<double>(const Model::BodyM&, const Mat3<double>&, const Vec3<double>&,
                                     const Vec3<double>&, const Vec3<double>&, const Vec3<double>&,
                                     const Vec3<double>&, const Vec3<double>&, Vec3<double>&,
                                     Vec3<double>&);
template void momentum_rates<Dual<1>>(const Model::BodyM&, const Mat3<Dual<1>>&,
                                      const Vec3<Dual<1>>&, const Vec3<Dual<1>>&,
                                      const Vec3<Dual<1>>&, const Vec3<Dual<1>>&,
                                      const Vec3<Dual<1>>&, const Vec3<Dual<1>>&, Vec3<Dual<1>>&,
                                      Vec3<Dual<1>>&);
template void subtree_loads<double>(const Model&, const std::vector<Vec3<double>>&,
                                    const std::vector<Mat3<double>>&,
                                    const std::vector<Vec3<double>>&,
                                    const std::vector<Vec3<double>>&,
                                    const std::vector<Vec3<double>>&,
                                    const std::vector<Vec3<double>>&,
                                    const std::vector<Vec3<double>>&,
                                    const std::vector<Vec3<double>>&, std::vector<Vec3<double>>&,
                                    std::vector<Vec3<double>>&, std::vector<Vec3<double>>&);
template void subtree_loads<Dual<1>>(const Model&, const std::vector<Vec3<Dual<1>>>&,
                                     const std::vector<Mat3<Dual<1>>>&,
                                     const std::vector<Vec3<Dual<1>>>&,
                                     const std::vector<Vec3<Dual<1>>>&,
                                     const std::vector<Vec3<Dual<1>>>&,
                                     const std::vector<Vec3<Dual<1>>>&,
                                     const std::vector<Vec3<Dual<1>>>&,
                                     const std::vector<Vec3<Dual<1>>>&,
                                     std::vector<Vec3<Dual<1>>>&, std::vector<Vec3<Dual<1>>>&,
                                     std::vector<Vec3<Dual<1>>>&);

void joint_loads(const Model& m, Workspace& w, double t) {
  const Kin<double>& k = w.k0;
  const double* u = w.u.data();
  const double* ud = w.udot.data();
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const Model::BodyM& B = m.bodies[b];
    // The body twist's rate in body components: xi = Xi(q*) pi' => xi' = Xi pi'' + (dXi/dt) pi'
    // (as accelerations(), outputs.cpp).
    const Eigen::Matrix<double, 6, 1> xid = w.Xi[b] * w.udot + w.Xi_dot[b] * w.u;
    const Eigen::Vector3d& w_B = k.w_NB_B[b];
    const Eigen::Vector3d& v_B = k.v_NBo_B[b];
    const Eigen::Vector3d wd_B = xid.head<3>(), vd_B = xid.tail<3>();
    const Eigen::Matrix3d& R_NB = k.R_NB[b];
    // Body momenta in body components: h_v (linear) and h_w (angular, about Bo), and their
    // component rates h_v', h_w'.
    Eigen::Vector3d hw, hv, hwd, hvd;
    if (B.flex < 0) {
      // Rigid: h_v = m v_NBo_B, h_w = I w_NB_B about the CM Bo.
      hv = B.mass * v_B;
      hw = B.I_BBo_B * w_B;
      hvd = B.mass * vd_B;
      hwd = B.I_BBo_B * wd_B;
    } else {
      // Flexible: h = M_B(eta) xi (flex_body.hpp, Meirovitch 1991 J. Guidance 14(5)), so
      // h' = (dM_B/dt) xi + M_B xi': the Dual<1> inertia of the mass pass (w.k1.fi, along q*')
      // on the twist with its rate gives (dM_B/dt) xi + M_B (w', v', 0); M_B (0, 0, eta'') adds
      // the modal accelerations.
      const FlexInvariants& f = m.flex[static_cast<std::size_t>(B.flex)];
      flex_momentum(f, w.fi0[b], w_B, v_B, u + B.e0, hw, hv, static_cast<double*>(nullptr));
      Vec3<Dual<1>> wt, vt, hw1, hv1;
      for (int a = 0; a < 3; ++a) {
        wt(a) = Dual<1>(w_B(a));
        wt(a).d[0] = wd_B(a);
        vt(a) = Dual<1>(v_B(a));
        vt(a).d[0] = vd_B(a);
      }
      flex_momentum(f, w.k1.fi[b], wt, vt, u + B.e0, hw1, hv1, static_cast<Dual<1>*>(nullptr));
      const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
      Eigen::Vector3d hwe, hve;
      flex_momentum(f, w.fi0[b], zero, zero, ud + B.e0, hwe, hve, static_cast<double*>(nullptr));
      for (int a = 0; a < 3; ++a) {
        hwd(a) = hw1(a).d[0] + hwe(a);
        hvd(a) = hv1(a).d[0] + hve(a);
      }
    }
    momentum_rates(B, R_NB, w_B, v_B, hw, hv, hwd, hvd, w.dP_N[b], w.dK_N[b]);
    // External torque (system.hpp "Loads": body frame or N).
    w.T_N[b].setZero();
    if (!B.torque.empty()) {
      const Eigen::Vector3d tau = B.torque.value(t);
      w.T_N[b] = B.torque_frame == Body::Frame::Inertial ? tau : Eigen::Vector3d(R_NB * tau);
    }
  }
  subtree_loads(m, k.p_NoBo_N, k.R_NB, k.r_C, w.dP_N, w.dK_N, w.T_N, w.F_g_N, w.M_g_N, w.F_N,
                w.M_J_N, w.r_J_N);
}

}  // namespace crossdyn::lagrange
