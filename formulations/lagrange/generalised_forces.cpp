// The Lagrange engine's generalised forces N for the quasi-velocities (virtual power N . pi'): body
// torques, modal damping, joint dampers and motors, gravity (gravity.cpp) (README.md, "Generalised
// forces").
#include <cstddef>
#include <vector>

#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/passes.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

void generalised_forces(const Model& m, Workspace& w, double t) {
  w.N.setZero();
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const Model::BodyM& B = m.bodies[b];
    const std::vector<int>& sup = m.support[b];
    const auto& X = w.Xi[b];
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
  // A prismatic joint's force F along the axis on the child, -F on the parent at the same point:
  // virtual power F axis . (relative velocity of the point) = F s'. A universal joint's tau_k is
  // the generalised force of a_k (system.hpp), virtual power tau_1 a1' + tau_2 a2'. So every
  // loaded quasi-velocity k gets -damping_k pi'_k + motor_k(t) (Model::JointM, set by the unit).
  for (const Model::JointM& J : m.joints) {
    if (J.loaded == 0) continue;
    const Eigen::Vector3d motor = J.motor.value(t);
    for (int a = 0; a < J.loaded; ++a)
      w.N(J.i0 + a) += -J.damping[static_cast<std::size_t>(a)] * w.u(J.i0 + a) + motor(a);
  }

  // The environment's gravity (gravity.cpp): nothing without one.
  if (m.gravity) gravity_forces(m, w, t);
}

}  // namespace crossdyn::lagrange
