// The Lagrange engine's energies, templated on the scalar S: T from the twists of the pose and twist
// passes (kinematics.hpp), V from q*. Equations: README.md, "Energies". Internal header: included by
// lagrangian_gradient.cpp (Dual<K>) and outputs.cpp (double).
#pragma once

#include <cstddef>

#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "formulations/lagrange/flex_body.hpp"
#include "formulations/lagrange/kinematics.hpp"
#include "formulations/lagrange/model.hpp"

namespace crossdyn::lagrange {

namespace {  // internal linkage, as the passes of kinematics.hpp

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

// V(q*): the hinge springs (system.hpp), one per scalar coordinate k (revolute angle, universal
// angles, prismatic position) stiffness_k (q_k - neutral_k)^2 / 2, spherical k |phi|^2 / 2 with
// phi the rotation vector of R_J, written in the joint's Euler angles; and the flexible bodies'
// elastic energy eta^T K eta / 2 (docs/flexible-bodies.md "Energy").
template <class S>
S potential_energy_of(const Model& m, const int* chart, const S* q) {
  S V(0.0);
  for (const Model::JointM& J : m.joints) {
    if (!J.has_spring) continue;
    const S* qj = q + J.i0;
    for (int a = 0; a < J.scalar_coordinates; ++a) {
      const double ka = J.stiffness[static_cast<std::size_t>(a)];
      if (ka == 0.0) continue;
      const S d = qj[a] - J.neutral[static_cast<std::size_t>(a)];
      V += 0.5 * ka * d * d;
    }
    if (J.relative_euler && J.stiffness[0] != 0.0) {
      const Eigen::Matrix<S, 4, 1> qJ = euler_quaternion(
          kSequences[static_cast<std::size_t>(chart[J.euler_set])], qj[0], qj[1], qj[2]);
      V += 0.5 * J.stiffness[0] * rotation_angle_squared(qJ(0), qJ(1), qJ(2), qJ(3));
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

}  // namespace

}  // namespace crossdyn::lagrange
