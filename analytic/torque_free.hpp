// Torque-free rigid body: the analytic solution (Euler's equations solved with Jacobi elliptic
// functions; Landau & Lifshitz, Mechanics, Sec. 37; Kane, Likins & Levinson 1983, Sec. 3.1),
// kept apart from every engine (../shared/STYLE.md item 7).
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

// A single rigid body with inertia I_BBo_B (any symmetric positive definite matrix), initial
// angular velocity w0_NB_B and attitude q0_NB, no torque. Returns the state at time t.
class TorqueFreeBody {
 public:
  TorqueFreeBody(const Eigen::Matrix3d& I_BBo_B, const Eigen::Vector3d& w0_NB_B,
                 const Eigen::Quaterniond& q0_NB);
  TorqueFreeState at(double t) const;

 private:
  struct Impl;
  std::shared_ptr<const Impl> impl_;
};

// True when the scene is a single free rigid body with no loads (System::analytic ==
// "torque-free" is checked against this).
bool is_torque_free(const System& system);

}  // namespace crossdyn::analytic
