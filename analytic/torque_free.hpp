// Torque-free rigid body: the analytic solution (Euler's equations solved with Jacobi elliptic
// functions; Landau & Lifshitz, Mechanics, Sec. 37; Kane, Likins & Levinson 1983, Sec. 3.1),
// kept apart from every engine (docs/style.md item 7).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/system.hpp"

#include <memory>

namespace crossdyn::analytic {

struct TorqueFreeState {
  Eigen::Vector3d w_NB_B;
  Eigen::Quaterniond q_NB;
};

// A single rigid body with inertia I_BBo_B (any symmetric positive definite matrix, products of
// inertia and repeated moments included), initial angular velocity w0_NB_B (any finite vector,
// zero included) and attitude q0_NB (any non-zero quaternion), no torque. Every case of the closed
// form is handled: steady spins, spins at any distance from any principal axis, on and near the
// separatrix, axisymmetric and nearly axisymmetric bodies, the sphere, any |w0| and any t
// (tests/analytic/test_torque_free_cases.cpp holds it to ~1e-14 of a 34-digit integration).
// Throws crossdyn::InputError (core/errors.hpp) naming what is wrong for a non-finite or
// non-symmetric inertia, one that is not positive definite, a non-finite w0 or q0, a zero q0, or
// a non-finite t; nothing else throws except a RunFailure if a state were ever not finite.
class TorqueFreeBody {
 public:
  TorqueFreeBody(const Eigen::Matrix3d& I_BBo_B, const Eigen::Vector3d& w0_NB_B,
                 const Eigen::Quaterniond& q0_NB);
  // The state at time t (s), exact at t = 0 (w(0) = w0 bit for bit).
  TorqueFreeState at(double t) const;

 private:
  struct Impl;
  std::shared_ptr<const Impl> impl_;
};

// True when the scene is a single free rigid body with no loads (System::analytic ==
// "torque-free" is checked against this).
bool is_torque_free(const System& system);

}  // namespace crossdyn::analytic
