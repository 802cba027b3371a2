#include "core/system.hpp"

#include "core/engine.hpp"
#include "core/rotation.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace crossdyn {

// Kane, Ryan and Banerjee 1987, Eq. (61) (see system.hpp).
// The profiles of system.hpp (PrescribedMotion): spin-up (Kane, Ryan and Banerjee 1987, Eq. (60))
// and deploy (the cycloidal rest-to-rest law).
double PrescribedMotion::angle(double t) const {
  const double T = ramp_time;
  const double c = T / (2 * std::numbers::pi);
  if (profile == Profile::Deploy) return t >= T ? travel : travel * (t / T - std::sin(t / c) * c / T);
  if (t > T) return rate * (t - T / 2);
  return (rate / T) * (t * t / 2 + c * c * (std::cos(t / c) - 1));
}
double PrescribedMotion::velocity(double t) const {
  const double T = ramp_time;
  const double c = T / (2 * std::numbers::pi);
  if (profile == Profile::Deploy) return t >= T ? 0 : (travel / T) * (1 - std::cos(t / c));
  if (t > T) return rate;
  return (rate / T) * (t - c * std::sin(t / c));
}
double PrescribedMotion::accel(double t) const {
  const double T = ramp_time;
  const double c = T / (2 * std::numbers::pi);
  if (profile == Profile::Deploy) return t >= T ? 0 : (travel / (T * c)) * std::sin(t / c);
  if (t > T) return 0;
  return (rate / T) * (1 - std::cos(t / c));
}

std::vector<double> System::breakpoints() const {
  std::vector<double> t;
  auto add = [&t](const std::vector<double>& times) { t.insert(t.end(), times.begin(), times.end()); };
  for (const Body& b : bodies) add(b.torque.times);
  for (const Joint& j : joints) {
    add(j.motor_revolute.times);
    add(j.motor_spherical.times);
    add(j.motor_universal.times);
    if (j.prescribed) add(j.prescribed->breakpoints());
  }
  std::sort(t.begin(), t.end());
  t.erase(std::unique(t.begin(), t.end()), t.end());
  t.erase(std::remove_if(t.begin(), t.end(), [](double x) { return x <= 0; }), t.end());
  return t;
}

// A prescribed base turning about an axis fixed in N (system.hpp): R_NB = R_NJ0 Rot(axis_J, angle),
// axis_J = R_NJ0^T axis_N; the joint point is fixed in N.
void TreeState::place_prescribed_base(const Joint& J, double angle, double rate) {
  const Eigen::Vector3d axis_J = J.q_PJ0.conjugate() * J.axis_P;
  q_NB = (J.q_PJ0 * Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis_J))).normalized();
  w_NB_B = rate * axis_J;
  const Eigen::Vector3d p_JBo_N = -(q_NB * J.p_CoJ_C);
  p_NoBo_N = J.p_PoJ_P + p_JBo_N;
  v_NBo_N = (q_NB * w_NB_B).cross(p_JBo_N);
}

TreeTangent TreeTangent::zero(const System& system) {
  TreeTangent d;
  d.joints.resize(system.joints.size());
  d.eta.resize(system.bodies.size());
  d.eta_rate.resize(system.bodies.size());
  for (std::size_t b = 0; b < system.bodies.size(); ++b) {
    const auto n = system.bodies[b].flex ? static_cast<Eigen::Index>(system.bodies[b].flex->modes()) : 0;
    d.eta[b] = Eigen::VectorXd::Zero(n);
    d.eta_rate[b] = Eigen::VectorXd::Zero(n);
  }
  return d;
}

TreeState moved_along(const TreeState& s, const TreeTangent& ds, double e) {
  TreeState r = s;
  r.p_NoBo_N += e * ds.dp_NoBo_N;
  r.q_NB = s.q_NB * rot::from_rotation_vector(e * ds.dtheta_B);
  r.v_NBo_N += e * ds.dv_NBo_N;
  r.w_NB_B += e * ds.dw_NB_B;
  for (std::size_t j = 0; j < r.joints.size() && j < ds.joints.size(); ++j) {
    const TreeTangent::JointTangent& dj = ds.joints[j];
    TreeState::JointState& js = r.joints[j];
    js.angle += e * dj.angle;
    js.rate += e * dj.rate;
    js.angle2 += e * dj.angle2;
    js.rate2 += e * dj.rate2;
    js.q_J = s.joints[j].q_J * rot::from_rotation_vector(e * dj.dtheta_J);
    js.w_PC_C += e * dj.w_PC_C;
  }
  for (std::size_t b = 0; b < r.eta.size(); ++b) {
    if (b < ds.eta.size() && ds.eta[b].size() == r.eta[b].size()) r.eta[b] += e * ds.eta[b];
    if (b < ds.eta_rate.size() && ds.eta_rate[b].size() == r.eta_rate[b].size()) r.eta_rate[b] += e * ds.eta_rate[b];
  }
  return r;
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
      case JointType::Prismatic:
        s.joints[j].angle = J.angle0;
        s.joints[j].rate = J.prescribed ? J.prescribed->velocity(0) : J.rate0;
        if (j == 0) s.place_prescribed_base(J, J.angle0, s.joints[j].rate);
        break;
      case JointType::Spherical:
        s.joints[j].q_J = J.q_J0.normalized();
        s.joints[j].w_PC_C = J.w_PC_C0;
        break;
      case JointType::Universal:
        s.joints[j].angle = J.angle0;
        s.joints[j].rate = J.rate0;
        s.joints[j].angle2 = J.angle2_0;
        s.joints[j].rate2 = J.rate2_0;
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
