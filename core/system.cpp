#include "core/system.hpp"

#include "core/engine.hpp"

#include <algorithm>

namespace crossdyn {

std::vector<double> System::breakpoints() const {
  std::vector<double> t;
  auto add = [&t](const std::vector<double>& times) { t.insert(t.end(), times.begin(), times.end()); };
  for (const Body& b : bodies) add(b.torque.times);
  for (const Joint& j : joints) {
    add(j.motor_revolute.times);
    add(j.motor_spherical.times);
  }
  std::sort(t.begin(), t.end());
  t.erase(std::unique(t.begin(), t.end()), t.end());
  t.erase(std::remove_if(t.begin(), t.end(), [](double x) { return x <= 0; }), t.end());
  return t;
}

TreeState TreeState::initial(const System& system) {
  TreeState s;
  s.joints.resize(system.joints.size());
  for (std::size_t j = 0; j < system.joints.size(); ++j) {
    const Joint& J = system.joints[j];
    switch (J.type) {
      case JointType::Free:
        s.p_NoBo_N = J.p_NoBo_N0;
        s.q_NB = J.q_NB0.normalized();
        s.v_NBo_N = J.v_NBo_N0;
        s.w_NB_B = J.w_NB_B0;
        break;
      case JointType::Revolute:
        s.joints[j].angle = J.angle0;
        s.joints[j].rate = J.rate0;
        break;
      case JointType::Spherical:
        s.joints[j].q_J = J.q_J0.normalized();
        s.joints[j].w_PC_C = J.w_PC_C0;
        break;
      case JointType::Fixed: break;
    }
  }
  s.eta.resize(system.bodies.size());
  s.eta_rate.resize(system.bodies.size());
  for (std::size_t b = 0; b < system.bodies.size(); ++b)
    if (system.bodies[b].flex) {
      const auto n = static_cast<Eigen::Index>(system.bodies[b].flex->modes());
      s.eta[b] = Eigen::VectorXd::Zero(n);
      s.eta_rate[b] = Eigen::VectorXd::Zero(n);
    }
  return s;
}

}  // namespace crossdyn
