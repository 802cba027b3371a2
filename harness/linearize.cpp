// Linear models of every engine about one operating point (harness/linearize.hpp; issue 27).
#include "harness/linearize.hpp"

#include "core/orbit.hpp"

#include "core/errors.hpp"
#include "core/output.hpp"
#include "core/rotation.hpp"
#include "harness/cli.hpp"
#include "harness/engines.hpp"
#include "harness/report.hpp"
#include "harness/scene_geometry.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <numbers>
#include <set>
#include <sstream>

namespace crossdyn::harness {

namespace {

using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;
using cd = std::complex<double>;

std::string num(double v, int digits = 6) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

std::string num(cd v, int digits = 10) {
  if (v.imag() == 0) return num(v.real(), digits);
  return num(v.real(), digits) + (v.imag() < 0 ? " - " : " + ") + num(std::abs(v.imag()), digits) + "i";
}

// ------------------------------------------------------------------------------------------------
// The reduced coordinates.

struct Coordinate {
  // BasePhi: on an orbit, the base's attitude relative to the orbit frame (R_OB = R_OB* exp([phi
  // x])), whose rate BaseW is then w_OB_B, the base's angular velocity relative to that frame.
  enum class Kind { BaseW, BasePhi, Angle, Angle2, Phi, Eta, Rate, Rate2, W, EtaRate };
  Kind kind;
  int index = 0;      // joint (Angle .. W) or body (Eta, EtaRate)
  int component = 0;  // x/y/z, or mode
  std::string name;
  std::string mode_name;  // the configuration it belongs to (a mode's coordinate name)
  int rate = -1;          // a configuration coordinate whose rate is in z: that rate's index
};

// A revolute joint's axis in the child frame: axis_C = R_PJ0^T axis_P (core/system.hpp).
Vector3d axis_in_child(const Joint& J) {
  return (J.q_PJ0.normalized().toRotationMatrix().transpose() * J.axis_P).normalized();
}

// A rotor whose angle is ignorable (a cyclic coordinate, like the base's attitude): a revolute
// joint, not prescribed, without a spring, whose child is a rigid body carrying nothing else (no
// joint outboard of it, no external torque), with its CM on the axis and its inertia symmetric
// about it. Its angle is left out of z (its rate stays): a wheel spinning at a constant rate is
// then a relative equilibrium, a gyrostat's (dual_spin).
bool cyclic_rotor(const System& s, std::size_t j) {
  const Joint& J = s.joints[j];
  if (j == 0 || J.type != JointType::Revolute || J.prescribed || J.stiffness != 0 || J.child_node >= 0) return false;
  const Body& C = s.bodies[static_cast<std::size_t>(J.child)];
  if (C.flex || !C.torque.empty()) return false;
  for (const Joint& K : s.joints)
    if (K.parent == J.child) return false;
  const Vector3d a_C = axis_in_child(J);
  const double tol = 1e-12 * std::max(C.I_BBo_B.norm(), 1e-300);
  const double Ia = a_C.dot(C.I_BBo_B * a_C);
  const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - a_C * a_C.transpose();
  const Eigen::Matrix3d It = P * C.I_BBo_B * P;  // transverse part: isotropic in the plane?
  const double t = 0.5 * It.trace();
  return (C.I_BBo_B * a_C - Ia * a_C).norm() <= tol && (It - t * P).norm() <= tol &&
         J.p_CoJ_C.cross(a_C).norm() <= 1e-12 * std::max(J.p_CoJ_C.norm(), 1.0);
}

class ReducedMap {
 public:
  // One pass over the joints and bodies: each degree of freedom's configuration coordinates go
  // to the first half of z, its velocities to the second (a free base's w first).
  // t: the operating time (on an orbit, where the orbit frame is then).
  ReducedMap(const System& s, const TreeState& op, double t) : system_(s), op_(op) {
    using K = Coordinate::Kind;
    orbit_ = s.environment.orbit() && s.base_is_free();
    if (orbit_) {
      const OrbitFrame f = orbit_frame(s.environment, t);
      R_NO_ = f.R_NO;
      w_NO_N_ = f.w_NO_N;
      R_OB_op_ = R_NO_.transpose() * op.q_NB.normalized().toRotationMatrix();
    }
    std::vector<Coordinate> q, v;
    // One degree of freedom: its configuration coordinate, its velocity, the mode name of both.
    auto dof = [&](K qk, K vk, int index, int component, const std::string& qname, const std::string& vname,
                   const std::string& mode) {
      v.push_back({vk, index, component, vname, mode});
      q.push_back({qk, index, component, qname, mode, static_cast<int>(v.size()) - 1});  // its rate, in v
    };
    if (orbit_) {
      // On an orbit the base's attitude relative to the orbit frame is a coordinate (the gravity
      // gradient depends on it), and its rate the angular velocity relative to that frame, w_OB_B
      // (the output's <base>.wox/woy/woz): a body turning with the orbit is at rest in z.
      const std::string base = s.bodies[static_cast<std::size_t>(s.base_body())].name;
      for (int c = 0; c < 3; ++c)
        dof(K::BasePhi, K::BaseW, 0, c, base + ".phi" + "xyz"[c], base + ".wo" + "xyz"[c],
            base + ".phi" + "xyz"[c]);
    } else if (s.base_is_free()) {
      const std::string base = s.bodies[static_cast<std::size_t>(s.base_body())].name;
      for (int c = 0; c < 3; ++c) v.push_back({K::BaseW, 0, c, base + ".w" + "xyz"[c], base + ".w"});
    }
    for (std::size_t j = 0; j < s.joints.size(); ++j) {
      const Joint& J = s.joints[j];
      const int ji = static_cast<int>(j);
      if (J.prescribed) continue;
      switch (J.type) {
        case JointType::Revolute:
          if (cyclic_rotor(s, j))
            v.push_back({K::Rate, ji, 0, J.name + ".rate", J.name + ".angle"});  // its angle is ignorable
          else
            dof(K::Angle, K::Rate, ji, 0, J.name + ".angle", J.name + ".rate", J.name + ".angle");
          break;
        case JointType::Prismatic:
          dof(K::Angle, K::Rate, ji, 0, J.name + ".position", J.name + ".rate", J.name + ".position");
          break;
        case JointType::Universal:
          dof(K::Angle, K::Rate, ji, 0, J.name + ".angle1", J.name + ".rate1", J.name + ".angle1");
          dof(K::Angle2, K::Rate2, ji, 0, J.name + ".angle2", J.name + ".rate2", J.name + ".angle2");
          break;
        case JointType::Spherical:
          for (int c = 0; c < 3; ++c)
            dof(K::Phi, K::W, ji, c, J.name + ".phi" + "xyz"[c], J.name + ".w" + "xyz"[c], J.name + ".phi");
          break;
        case JointType::Free:
        case JointType::Fixed: break;
      }
    }
    for (std::size_t b = 0; b < s.bodies.size(); ++b)
      if (s.bodies[b].flex)
        for (int k = 0; k < s.bodies[b].flex->modes(); ++k) {
          const std::string n = s.bodies[b].name + "." + s.bodies[b].flex->mode_names[static_cast<std::size_t>(k)];
          dof(K::Eta, K::EtaRate, static_cast<int>(b), k, n, n + "_rate", n);
        }
    // z = (q, v): each configuration coordinate's rate index moves past q.
    configuration_ = static_cast<int>(q.size());
    for (Coordinate& c : q) c.rate += configuration_;
    coords_ = q;
    coords_.insert(coords_.end(), v.begin(), v.end());
  }

  int size() const { return static_cast<int>(coords_.size()); }
  int configuration_size() const { return configuration_; }
  const Coordinate& coordinate(int i) const { return coords_[static_cast<std::size_t>(i)]; }
  std::vector<std::string> names() const {
    std::vector<std::string> n;
    for (const Coordinate& c : coords_) n.push_back(c.name);
    return n;
  }

  // The operating point's z (its spherical phi are zero by definition).
  VectorXd z0() const {
    VectorXd z(size());
    for (int i = 0; i < size(); ++i) {
      const Coordinate& c = coords_[static_cast<std::size_t>(i)];
      const auto j = static_cast<std::size_t>(c.index);
      switch (c.kind) {
        case Coordinate::Kind::BaseW:
          z(i) = orbit_ ? w_OB_B_op()(c.component) : op_.w_NB_B(c.component);
          break;
        case Coordinate::Kind::BasePhi: z(i) = 0; break;
        case Coordinate::Kind::Angle: z(i) = op_.joints[j].angle; break;
        case Coordinate::Kind::Angle2: z(i) = op_.joints[j].angle2; break;
        case Coordinate::Kind::Phi: z(i) = 0; break;
        case Coordinate::Kind::Eta: z(i) = op_.eta[j](c.component); break;
        case Coordinate::Kind::Rate: z(i) = op_.joints[j].rate; break;
        case Coordinate::Kind::Rate2: z(i) = op_.joints[j].rate2; break;
        case Coordinate::Kind::W: z(i) = op_.joints[j].w_PC_C(c.component); break;
        case Coordinate::Kind::EtaRate: z(i) = op_.eta_rate[j](c.component); break;
      }
    }
    return z;
  }

  TreeState state(const VectorXd& z) const {
    TreeState s = op_;
    std::vector<Vector3d> phi(system_.joints.size(), Vector3d::Zero());
    for (int i = 0; i < size(); ++i) {
      const Coordinate& c = coords_[static_cast<std::size_t>(i)];
      const auto j = static_cast<std::size_t>(c.index);
      switch (c.kind) {
        case Coordinate::Kind::BaseW: s.w_NB_B(c.component) = z(i); break;
        case Coordinate::Kind::BasePhi: break;  // below
        case Coordinate::Kind::Angle: s.joints[j].angle = z(i); break;
        case Coordinate::Kind::Angle2: s.joints[j].angle2 = z(i); break;
        case Coordinate::Kind::Phi: phi[j](c.component) = z(i); break;
        case Coordinate::Kind::Eta: s.eta[j](c.component) = z(i); break;
        case Coordinate::Kind::Rate: s.joints[j].rate = z(i); break;
        case Coordinate::Kind::Rate2: s.joints[j].rate2 = z(i); break;
        case Coordinate::Kind::W: s.joints[j].w_PC_C(c.component) = z(i); break;
        case Coordinate::Kind::EtaRate: s.eta_rate[j](c.component) = z(i); break;
      }
    }
    for (std::size_t j = 0; j < phi.size(); ++j)
      if (system_.joints[j].type == JointType::Spherical && !system_.joints[j].prescribed)
        s.joints[j].q_J = (op_.joints[j].q_J * rot::from_rotation_vector(phi[j])).normalized();
    if (orbit_) {
      // R_NB = R_NO R_OB* exp([phi x]), w_NB_B = w_OB_B + R_BN w_NO_N (s.w_NB_B holds w_OB_B here).
      Eigen::Matrix3d R_NB;
      Vector3d w_OB_B;
      base_pose(z, R_NB, w_OB_B);
      s.q_NB = Eigen::Quaterniond(R_NB).normalized();
      s.w_NB_B = w_OB_B + R_NB.transpose() * w_NO_N_;
    }
    return s;
  }

  // dz/dt from the engine-neutral accelerations at z.
  VectorXd rate(const VectorXd& z, const TreeAccel& a) const {
    VectorXd zd(size());
    std::vector<Vector3d> phi(system_.joints.size(), Vector3d::Zero()), w(system_.joints.size(), Vector3d::Zero());
    for (int i = 0; i < size(); ++i) {
      const Coordinate& c = coords_[static_cast<std::size_t>(i)];
      if (c.kind == Coordinate::Kind::Phi) phi[static_cast<std::size_t>(c.index)](c.component) = z(i);
      if (c.kind == Coordinate::Kind::W) w[static_cast<std::size_t>(c.index)](c.component) = z(i);
    }
    const int base = system_.base_body();
    // On an orbit: d/dt w_OB_B = w_NB_B' + w_NB_B x (R_BN w_NO_N) (w_NO_N constant on a circular
    // orbit, R_BN' = -[w_NB_B x] R_BN), and phi' = J_r(phi)^-1 w_OB_B.
    Vector3d wdot_OB_B = Vector3d::Zero(), phi_dot = Vector3d::Zero();
    if (orbit_) {
      Eigen::Matrix3d R_NB;
      Vector3d w_OB_B;
      base_pose(z, R_NB, w_OB_B);
      const Vector3d w_NO_B = R_NB.transpose() * w_NO_N_;
      const Vector3d w_NB_B = w_OB_B + w_NO_B;
      wdot_OB_B = a.wdot_NB_B[static_cast<std::size_t>(base)] + w_NB_B.cross(w_NO_B);
      phi_dot = right_jacobian_inverse(base_phi(z)) * w_OB_B;
    }
    for (int i = 0; i < size(); ++i) {
      const Coordinate& c = coords_[static_cast<std::size_t>(i)];
      const auto j = static_cast<std::size_t>(c.index);
      switch (c.kind) {
        case Coordinate::Kind::BaseW:
          zd(i) = orbit_ ? wdot_OB_B(c.component) : a.wdot_NB_B[static_cast<std::size_t>(base)](c.component);
          break;
        case Coordinate::Kind::BasePhi: zd(i) = phi_dot(c.component); break;
        case Coordinate::Kind::Angle:
        case Coordinate::Kind::Angle2:
        case Coordinate::Kind::Eta: zd(i) = z(c.rate); break;
        case Coordinate::Kind::Phi: zd(i) = (right_jacobian_inverse(phi[j]) * w[j])(c.component); break;
        case Coordinate::Kind::Rate: zd(i) = a.angle_ddot[j]; break;
        case Coordinate::Kind::Rate2: zd(i) = a.angle2_ddot[j]; break;
        case Coordinate::Kind::W: zd(i) = a.wdot_PC_C[j](c.component); break;
        case Coordinate::Kind::EtaRate: zd(i) = a.eta_ddot[j](c.component); break;
      }
    }
    return zd;
  }

  // The variation of state(z) at z0 along dz (exact: every phi is zero at z0, where
  // d/de R* exp(e [dphi x]) = R* [dphi x], a right perturbation dtheta = dphi; TreeTangent).
  // On an orbit w_NB_B = w_OB_B + R_NB^T w_NO_N, so d w_NB_B = dw_OB_B + (R_NB^T w_NO_N) x dphi.
  TreeTangent tangent(const VectorXd& dz) const {
    TreeTangent d = TreeTangent::zero(system_);
    for (int i = 0; i < size(); ++i) {
      const Coordinate& c = coords_[static_cast<std::size_t>(i)];
      const auto j = static_cast<std::size_t>(c.index);
      switch (c.kind) {
        case Coordinate::Kind::BaseW: d.dw_NB_B(c.component) = dz(i); break;
        case Coordinate::Kind::BasePhi: d.dtheta_B(c.component) = dz(i); break;
        case Coordinate::Kind::Angle: d.joints[j].angle = dz(i); break;
        case Coordinate::Kind::Angle2: d.joints[j].angle2 = dz(i); break;
        case Coordinate::Kind::Phi: d.joints[j].dtheta_J(c.component) = dz(i); break;
        case Coordinate::Kind::Eta: d.eta[j](c.component) = dz(i); break;
        case Coordinate::Kind::Rate: d.joints[j].rate = dz(i); break;
        case Coordinate::Kind::Rate2: d.joints[j].rate2 = dz(i); break;
        case Coordinate::Kind::W: d.joints[j].w_PC_C(c.component) = dz(i); break;
        case Coordinate::Kind::EtaRate: d.eta_rate[j](c.component) = dz(i); break;
      }
    }
    if (orbit_) d.dw_NB_B += w_NO_B_op().cross(d.dtheta_B);
    return d;
  }

  // The variation of rate(z, a) at z = z0() along dz, given the accelerations a at z0 and their variation
  // da (Engine::accelerations_tangent). At phi = 0, J_r(phi)^-1 = 1 + [phi x]/2 + O(|phi|^2), so
  // d(J_r^-1 w) = dw + dphi x w / 2; on an orbit d/dt w_OB_B = w_NB_B' + w_NB_B x w_NO_B with
  // w_NO_B = R_NB^T w_NO_N, d w_NO_B = w_NO_B x dphi (rate()).
  VectorXd rate_tangent(const VectorXd& z, const VectorXd& dz, const TreeAccel& da) const {
    VectorXd dzd(size());
    std::vector<Vector3d> dphi(system_.joints.size(), Vector3d::Zero()), w(system_.joints.size(), Vector3d::Zero()),
        dw(system_.joints.size(), Vector3d::Zero());
    Vector3d dphi_B = Vector3d::Zero(), w_OB_B = Vector3d::Zero(), dw_OB_B = Vector3d::Zero();
    for (int i = 0; i < size(); ++i) {
      const Coordinate& c = coords_[static_cast<std::size_t>(i)];
      const auto j = static_cast<std::size_t>(c.index);
      if (c.kind == Coordinate::Kind::Phi) dphi[j](c.component) = dz(i);
      if (c.kind == Coordinate::Kind::W) {
        w[j](c.component) = z(i);
        dw[j](c.component) = dz(i);
      }
      if (c.kind == Coordinate::Kind::BasePhi) dphi_B(c.component) = dz(i);
      if (c.kind == Coordinate::Kind::BaseW) {
        w_OB_B(c.component) = z(i);
        dw_OB_B(c.component) = dz(i);
      }
    }
    const auto base = static_cast<std::size_t>(system_.base_body());
    Vector3d dwdot_OB_B = Vector3d::Zero(), dphi_dot_B = Vector3d::Zero();
    if (orbit_) {
      const Vector3d w_NO_B = w_NO_B_op();
      const Vector3d dw_NO_B = w_NO_B.cross(dphi_B);
      const Vector3d w_NB_B = w_OB_B + w_NO_B, dw_NB_B = dw_OB_B + dw_NO_B;
      dwdot_OB_B = da.wdot_NB_B[base] + dw_NB_B.cross(w_NO_B) + w_NB_B.cross(dw_NO_B);
      dphi_dot_B = dw_OB_B + 0.5 * dphi_B.cross(w_OB_B);
    }
    for (int i = 0; i < size(); ++i) {
      const Coordinate& c = coords_[static_cast<std::size_t>(i)];
      const auto j = static_cast<std::size_t>(c.index);
      switch (c.kind) {
        case Coordinate::Kind::BaseW: dzd(i) = orbit_ ? dwdot_OB_B(c.component) : da.wdot_NB_B[base](c.component); break;
        case Coordinate::Kind::BasePhi: dzd(i) = dphi_dot_B(c.component); break;
        case Coordinate::Kind::Angle:
        case Coordinate::Kind::Angle2:
        case Coordinate::Kind::Eta: dzd(i) = dz(c.rate); break;
        case Coordinate::Kind::Phi: dzd(i) = (dw[j] + 0.5 * dphi[j].cross(w[j]))(c.component); break;
        case Coordinate::Kind::Rate: dzd(i) = da.angle_ddot[j]; break;
        case Coordinate::Kind::Rate2: dzd(i) = da.angle2_ddot[j]; break;
        case Coordinate::Kind::W: dzd(i) = da.wdot_PC_C[j](c.component); break;
        case Coordinate::Kind::EtaRate: dzd(i) = da.eta_ddot[j](c.component); break;
      }
    }
    return dzd;
  }

 private:
  // On an orbit: the base's phi and w_OB_B in z, and its attitude R_NB = R_NO R_OB* exp([phi x]).
  Vector3d base_phi(const VectorXd& z) const {
    Vector3d phi = Vector3d::Zero();
    for (int i = 0; i < size(); ++i)
      if (coords_[static_cast<std::size_t>(i)].kind == Coordinate::Kind::BasePhi)
        phi(coords_[static_cast<std::size_t>(i)].component) = z(i);
    return phi;
  }
  void base_pose(const VectorXd& z, Eigen::Matrix3d& R_NB, Vector3d& w_OB_B) const {
    w_OB_B.setZero();
    for (int i = 0; i < size(); ++i)
      if (coords_[static_cast<std::size_t>(i)].kind == Coordinate::Kind::BaseW)
        w_OB_B(coords_[static_cast<std::size_t>(i)].component) = z(i);
    R_NB = R_NO_ * R_OB_op_ * rot::from_rotation_vector(base_phi(z)).toRotationMatrix();
  }
  Vector3d w_NO_B_op() const { return R_OB_op_.transpose() * R_NO_.transpose() * w_NO_N_; }
  Vector3d w_OB_B_op() const {
    return op_.w_NB_B - op_.q_NB.normalized().toRotationMatrix().transpose() * w_NO_N_;
  }
  void add(Coordinate::Kind k, int index, int component, std::string name, std::string mode) {
    coords_.push_back({k, index, component, std::move(name), std::move(mode)});
  }
  // J_r(phi)^-1 = 1 + [phi x]/2 + (1/a^2 - (1 + cos a) / (2 a sin a)) [phi x]^2, a = |phi|
  // (Sola, Deray and Atchuthan 2018, Eq. (144)); w = J_r(phi) phi' for R = R* exp([phi x]) and
  // R' = R [w x].
  static Eigen::Matrix3d right_jacobian_inverse(const Vector3d& phi) {
    const Eigen::Matrix3d P = rot::skew(phi);
    const double a = phi.norm();
    // Series below 1e-4 rad: 1/12 + a^2/720 + ...
    const double c = a < 1e-4 ? 1.0 / 12.0 + a * a / 720.0
                              : 1.0 / (a * a) - (1.0 + std::cos(a)) / (2.0 * a * std::sin(a));
    return Eigen::Matrix3d::Identity() + 0.5 * P + c * P * P;
  }

  const System& system_;
  TreeState op_;
  std::vector<Coordinate> coords_;
  int configuration_ = 0;
  bool orbit_ = false;  // a free base on an orbit: BasePhi and w_OB_B
  Eigen::Matrix3d R_NO_ = Eigen::Matrix3d::Identity(), R_OB_op_ = Eigen::Matrix3d::Identity();
  Vector3d w_NO_N_ = Vector3d::Zero();
};

// ------------------------------------------------------------------------------------------------
// The operating point.

// The whole spacecraft's inertia about its CM with its joints at st's coordinates
// (harness/scene_geometry's placement of the bodies; flexible bodies undeformed), in the base frame.
Eigen::Matrix3d composite_inertia_B(const System& s, const TreeState& st) {
  System n = s;
  for (std::size_t j = 0; j < s.joints.size(); ++j) {
    n.joints[j].angle0 = st.joints[j].angle;
    n.joints[j].angle2_0 = st.joints[j].angle2;
    n.joints[j].q_J0 = st.joints[j].q_J;
  }
  const geometry::Configuration c = geometry::initial_configuration(n);
  const int base = s.base_body();
  Eigen::Matrix3d I_N = Eigen::Matrix3d::Zero();
  double mass = 0;
  Vector3d first = Vector3d::Zero();
  for (std::size_t b = 0; b < s.bodies.size(); ++b) {
    mass += s.bodies[b].mass;
    first += s.bodies[b].mass * c.bodies[b].p_NoBo_N;
  }
  const Vector3d cm = first / mass;
  for (std::size_t b = 0; b < s.bodies.size(); ++b) {
    const Eigen::Matrix3d& R = c.bodies[b].R_NB;
    const Vector3d r = c.bodies[b].p_NoBo_N - cm;
    I_N += R * s.bodies[b].I_BBo_B * R.transpose() +
           s.bodies[b].mass * (r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose());
  }
  const Eigen::Matrix3d& R_NB = c.bodies[static_cast<std::size_t>(base)].R_NB;
  return R_NB.transpose() * I_N * R_NB;
}

// Turns the base's spin onto the whole spacecraft's principal axis nearest it, at the rate that
// keeps |I w0|. Returns the words for the operating point's description.
std::string spin_about_principal_axis(const System& s, TreeState& st) {
  const Eigen::Matrix3d I_B = composite_inertia_B(s, st);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(I_B);
  const Vector3d w0 = st.w_NB_B;
  int k = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(es.eigenvectors().col(a).dot(w0)) > std::abs(es.eigenvectors().col(k).dot(w0))) k = a;
  const Vector3d e = es.eigenvectors().col(k) * (es.eigenvectors().col(k).dot(w0) < 0 ? -1.0 : 1.0);
  st.w_NB_B = (I_B * w0).norm() / es.eigenvalues()(k) * e;
  const double Imin = es.eigenvalues().minCoeff(), Imax = es.eigenvalues().maxCoeff();
  std::ostringstream o;
  o << "; the base's spin turned onto the whole spacecraft's "
    << (es.eigenvalues()(k) >= Imax ? "major" : es.eigenvalues()(k) <= Imin ? "minor" : "intermediate")
    << " principal axis nearest the initial rate (moments " << num(es.eigenvalues()(0), 5) << ", "
    << num(es.eigenvalues()(1), 5) << ", " << num(es.eigenvalues()(2), 5) << " kg m^2 there), keeping |I w0|";
  return o.str();
}

TreeState operating_state(const System& s, double t, OperatingPoint point, std::string& how) {
  TreeState st = TreeState::initial(s);
  bool moved = false;
  for (std::size_t j = 0; j < s.joints.size(); ++j) {
    const Joint& J = s.joints[j];
    TreeState::JointState& js = st.joints[j];
    if (J.prescribed) {
      js.angle = J.angle0 + J.prescribed->angle(t);
      js.rate = J.prescribed->velocity(t);
      if (j == 0) st.place_prescribed_base(J, js.angle, js.rate);
      moved = moved || t != 0;
      continue;
    }
    if (point == OperatingPoint::Initial) continue;
    switch (J.type) {
      case JointType::Revolute:
      case JointType::Prismatic:
        js.angle = J.stiffness != 0 ? J.neutral_angle : J.angle0;
        if (J.type != JointType::Revolute || !cyclic_rotor(s, j)) js.rate = 0;  // a wheel keeps spinning
        break;
      case JointType::Universal:
        js.angle = J.stiffness != 0 ? J.neutral_angle : J.angle0;
        js.angle2 = J.stiffness2 != 0 ? J.neutral_angle2 : J.angle2_0;
        js.rate = js.rate2 = 0;
        break;
      case JointType::Spherical:
        if (J.stiffness != 0) js.q_J = Eigen::Quaterniond::Identity();
        js.w_PC_C.setZero();
        break;
      case JointType::Free:
      case JointType::Fixed: break;
    }
  }
  if (s.environment.orbit() && s.base_is_free() && t != 0) {
    // The base keeps its attitude and its rate relative to the orbit frame: R_NB(t) = R_NO(t)
    // R_NO(0)^T R_NB(0) (w_NB_B is then unchanged: w_OB_B and R_BO are).
    const Eigen::Matrix3d R = orbit_frame(s.environment, t).R_NO * orbit_frame(s.environment, 0).R_NO.transpose();
    st.q_NB = (Eigen::Quaterniond(R) * st.q_NB).normalized();
  }
  if (point != OperatingPoint::Initial)
    for (std::size_t b = 0; b < s.bodies.size(); ++b)
      if (s.bodies[b].flex) {
        st.eta[b].setZero();
        st.eta_rate[b].setZero();
      }
  std::ostringstream o;
  o << (point != OperatingPoint::Initial
            ? "the scene's initial state with every joint at its spring's neutral angle (its initial "
              "angle where it has no spring), every joint rate, modal coordinate and modal rate zero"
            : "the scene's initial state");
  if (point == OperatingPoint::Spin && s.base_is_free() && st.w_NB_B.norm() > 0) o << spin_about_principal_axis(s, st);
  if (s.base_is_free()) {
    const Vector3d& w = st.w_NB_B;
    o << "; the base turns at w_NB_B = (" << num(w.x()) << ", " << num(w.y()) << ", " << num(w.z())
      << ") rad/s" << (w.norm() == 0 ? " (at rest)" : "");
  }
  if (moved) o << "; prescribed joints at their profiles' t = " << num(t) << " s";
  how = o.str();
  return st;
}

// ------------------------------------------------------------------------------------------------
// Finite differences with two Richardson extrapolations.

// A column of a Jacobian and its estimated error per entry. `eval(z, f)` writes f at a point (an
// engine that fails there throws RunFailure).
struct Derivative {
  VectorXd d, error;
};

template <class F>
Derivative richardson(const F& eval, const VectorXd& z, int j, double h0, int m) {
  auto central = [&](double h) {
    VectorXd zp = z, zm = z, fp(m), fm(m);
    zp(j) += h;
    zm(j) -= h;
    eval(zp, fp);
    eval(zm, fm);
    return VectorXd((fp - fm) / (2 * h));
  };
  const VectorXd D1 = central(h0), D2 = central(h0 / 2), D4 = central(h0 / 4);
  const VectorXd R1a = (4 * D2 - D1) / 3, R1b = (4 * D4 - D2) / 3;
  const VectorXd R2 = (16 * R1b - R1a) / 15;
  Derivative out{R2, (R2 - R1b).cwiseAbs()};
  return out;
}

// The step chosen per column as in Ridders' method (Numerical Recipes, 3rd ed., Sec. 5.7): of the
// first steps h0 = c max(|z_j|, 1), c in {1e-1, 3e-2, 1e-2, 3e-3, 1e-3} (or the one given), the
// one whose estimated error is smallest. Large steps suit an engine whose accelerations carry
// the rounding of a constrained solve (newton-euler's KKT system: at 1e-3 its difference noise
// moved a spinning beam's eigenvalue by 3e-9 relative), small ones a strongly curved function.
template <class F>
Derivative best_derivative(const F& eval, const VectorXd& z, int j, double fixed_step, int m) {
  static constexpr double kSteps[] = {1e-1, 3e-2, 1e-2, 3e-3, 1e-3};
  const double scale = std::max(std::abs(z(j)), 1.0);
  Derivative best;
  double best_error = std::numeric_limits<double>::infinity();
  for (double c : kSteps) {
    const double h0 = (fixed_step > 0 ? fixed_step : c) * scale;
    Derivative d = richardson(eval, z, j, h0, m);
    const double e = m ? d.error.maxCoeff() : 0.0;
    if (e < best_error || best.d.size() == 0) {
      best_error = e;
      best = std::move(d);
    }
    if (fixed_step > 0) break;
  }
  return best;
}

// An exact matrix adopted in place of its finite differences M_fd (which become its cross-check):
// how far they differ, at which entry, and the differences' own estimated error (how.error until
// now); how.error becomes the exact matrix's rounding.
void adopt_exact(MatrixXd& M_fd, const MatrixXd& exact, double rounding, MatrixMethod& how) {
  // A tangent with a non-finite entry (an engine's 0/0) is not adopted: the differences stay, and
  // the outputs say "by finite differences" (Eigen's maxCoeff would pass over a NaN).
  if (!exact.allFinite()) return;
  how.fd_error = how.error;
  Eigen::Index wi = 0, wj = 0;
  how.fd_difference = exact.size() ? (exact - M_fd).cwiseAbs().maxCoeff(&wi, &wj) : 0.0;
  if (exact.size()) how.worst = {wi, wj, exact(wi, wj), M_fd(wi, wj)};
  how.exact = true;
  how.error = rounding;
  M_fd = exact;
}

// One engine evaluated at a point of z: dz/dt through its pack() and accelerations(), and the
// chosen output columns through its output_row().
struct Probe {
  Engine* engine = nullptr;
  const ReducedMap* map = nullptr;
  double t = 0;
  std::vector<int> output_columns;
  std::vector<double> x, row;
  TreeAccel accel;

  void eval(const VectorXd& z, VectorXd& zdot, VectorXd* y) {
    engine->pack(map->state(z), x.data());
    engine->accelerations(t, x.data(), accel);
    zdot = map->rate(z, accel);
    if (y) {
      engine->output_row(t, x.data(), row.data());
      y->resize(static_cast<Eigen::Index>(output_columns.size()));
      for (std::size_t k = 0; k < output_columns.size(); ++k)
        (*y)(static_cast<Eigen::Index>(k)) = row[static_cast<std::size_t>(output_columns[k])];
    }
  }
};

// An input: a component of a joint's motor or of a body's external torque.
struct InputRef {
  std::string name;
  enum class Kind { Revolute, Universal, Spherical, Body } kind;
  int index = 0, component = 0;
};

std::vector<InputRef> all_inputs(const System& s) {
  std::vector<InputRef> in;
  for (std::size_t j = 0; j < s.joints.size(); ++j) {
    const Joint& J = s.joints[j];
    const int ji = static_cast<int>(j);
    if (J.prescribed) continue;
    switch (J.type) {
      case JointType::Revolute:
      case JointType::Prismatic: in.push_back({J.name + ".motor", InputRef::Kind::Revolute, ji, 0}); break;
      case JointType::Universal:
        in.push_back({J.name + ".motor1", InputRef::Kind::Universal, ji, 0});
        in.push_back({J.name + ".motor2", InputRef::Kind::Universal, ji, 1});
        break;
      case JointType::Spherical:
        for (int c = 0; c < 3; ++c)
          in.push_back({J.name + ".motor" + "xyz"[c], InputRef::Kind::Spherical, ji, c});
        break;
      case JointType::Free:
      case JointType::Fixed: break;
    }
  }
  for (std::size_t b = 0; b < s.bodies.size(); ++b)
    for (int c = 0; c < 3; ++c)
      in.push_back({s.bodies[b].name + ".T" + "xyz"[c], InputRef::Kind::Body, static_cast<int>(b), c});
  return in;
}

bool input_named_by_scene(const System& s, const InputRef& u) {
  if (u.kind == InputRef::Kind::Body) return !s.bodies[static_cast<std::size_t>(u.index)].torque.empty();
  return s.joints[static_cast<std::size_t>(u.index)].has_motor();
}

double input_value(const System& s, const InputRef& u, double t) {
  const auto i = static_cast<std::size_t>(u.index);
  switch (u.kind) {
    case InputRef::Kind::Revolute: return s.joints[i].motor_revolute.value(t)(0);
    case InputRef::Kind::Universal: return s.joints[i].motor_universal.value(t)(u.component);
    case InputRef::Kind::Spherical: return s.joints[i].motor_spherical.value(t)(u.component);
    case InputRef::Kind::Body: return s.bodies[i].torque.value(t)(u.component);
  }
  return 0;
}

// The scene with every load of the input's kind frozen at its value at t, input u's at value + delta.
System with_input(const System& s, const InputRef& u, double t, double delta) {
  System c = s;
  const auto i = static_cast<std::size_t>(u.index);
  auto freeze = [t](auto& f, int component, double add) {
    auto v = f.value(t);
    v(component) += add;
    f.times = {0.0};
    f.values = {v};
  };
  switch (u.kind) {
    case InputRef::Kind::Revolute: freeze(c.joints[i].motor_revolute, 0, delta); break;
    case InputRef::Kind::Universal: freeze(c.joints[i].motor_universal, u.component, delta); break;
    case InputRef::Kind::Spherical: freeze(c.joints[i].motor_spherical, u.component, delta); break;
    case InputRef::Kind::Body: freeze(c.bodies[i].torque, u.component, delta); break;
  }
  return c;
}

// Eigenvalues grouped: zeros, then the modes (Im >= 0) by frequency.
void eigen_analysis(EngineLinearModel& m, const ReducedMap& map, double zero_tol) {
  const int n = static_cast<int>(m.A.rows());
  m.eigenvalues.clear();
  m.modes.clear();
  m.zeros = 0;
  if (n == 0) return;
  Eigen::EigenSolver<MatrixXd> es(m.A, true);
  if (es.info() != Eigen::Success) throw RunFailure(m.label, 0, "eigenvalues", "the eigenvalue solver did not converge");
  double rho = 0;
  for (int i = 0; i < n; ++i) rho = std::max(rho, std::abs(es.eigenvalues()(i)));
  m.zero_bound = zero_tol * rho;
  // The finite differences' error carried to each eigenvalue: |d lambda| <~ kappa |E|2 with
  // kappa = |x| |y| / |y^T x| (x, y its right and left eigenvectors, y one of A^T's; Golub and Van
  // Loan, Matrix Computations, 4th ed., Sec. 7.2.2) and |E|2 <= n max|E_ij| <= n a_error. Each
  // eigenvalue's own: a defective one (a joint turning freely: the zero of a 2 x 2 Jordan block)
  // gets an infinite kappa alone, and it is grouped with the zeros, never compared. (Taking y from
  // V^-1 made every kappa infinite as soon as one eigenvalue was defective, and every bound with it.)
  const Eigen::MatrixXcd V = es.eigenvectors();
  const Eigen::EigenSolver<MatrixXd> left(m.A.transpose(), true);
  for (int i = 0; i < n; ++i) {
    const cd l = es.eigenvalues()(i);
    m.eigenvalues.push_back(l);
    int k = 0;
    for (int q = 1; q < n; ++q)
      if (std::abs(left.eigenvalues()(q) - l) < std::abs(left.eigenvalues()(k) - l)) k = q;
    const Eigen::VectorXcd y = left.eigenvectors().col(k);
    const double overlap = std::abs(y.dot(V.col(i).conjugate()));  // |y^T x| (dot conjugates its left side)
    const double kappa = overlap > 0 ? V.col(i).norm() * y.norm() / overlap : std::numeric_limits<double>::infinity();
    // Times 10: the extrapolation's error is an estimate, not a bound (newton-euler's, whose
    // accelerations carry its constrained solve's rounding, was exceeded 2.7-fold at a mode
    // near a double zero: spinup_beam_linear at 3.7 rad/s).
    m.allowances.push_back(10 * kappa * n * m.a_method.error);
    if (std::abs(l) <= m.zero_bound || rho == 0) {
      ++m.zeros;
      continue;
    }
    if (l.imag() < 0) continue;
    LinearMode mode;
    mode.lambda = l;
    mode.frequency = std::abs(l);
    mode.damping_ratio = -l.real() / std::abs(l);
    mode.allowance = m.allowances.back();
    mode.shape = es.eigenvectors().col(i).normalized();
    // The coordinate it moves most: velocity components divided by |lambda| (a rate's amplitude
    // is |lambda| times its coordinate's), so configurations and velocities weigh alike.
    // Named by every coordinate within half of the largest (a symmetric pair: "a + b").
    const Eigen::VectorXcd v = es.eigenvectors().col(i);
    std::vector<std::pair<double, std::string>> weight;  // by coordinate, largest first
    for (int k = 0; k < n; ++k) {
      const double w = std::abs(v(k)) / (k < map.configuration_size() ? 1.0 : std::abs(l));
      const std::string& name = map.coordinate(k).mode_name;
      auto it = std::find_if(weight.begin(), weight.end(), [&](const auto& p) { return p.second == name; });
      if (it == weight.end())
        weight.emplace_back(w, name);
      else
        it->first = std::max(it->first, w);
    }
    std::stable_sort(weight.begin(), weight.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    for (const auto& [w, name] : weight)
      if (w >= 0.5 * weight.front().first && weight.front().first > 0)
        mode.coordinate += (mode.coordinate.empty() ? "" : " + ") + name;
    m.modes.push_back(mode);
  }
  std::sort(m.modes.begin(), m.modes.end(), [](const LinearMode& a, const LinearMode& b) {
    return a.frequency != b.frequency ? a.frequency < b.frequency : a.lambda.real() < b.lambda.real();
  });
}

// Transfer matrix C (i w - A)^-1 B + D.
Eigen::MatrixXcd transfer(const EngineLinearModel& m, double w) {
  Eigen::MatrixXcd Z = -m.A.cast<cd>();
  Z.diagonal().array() += cd(0, w);
  const Eigen::MatrixXcd X = Z.partialPivLu().solve(m.B.cast<cd>());
  return m.C.cast<cd>() * X + m.D.cast<cd>();
}

// What rounding and the matrices' own errors allow one engine's transfer function to be off by, per
// pair (output a, input b) at the frequency w. With R = (iwI - A)^-1 and X = R B, to first order
// dG = dC X + C R (dA X + dB) + dD (the perturbed solve: Golub and Van Loan, Matrix Computations,
// 4th ed., Sec. 2.6.2), so |dG_ab| <= e_C sum_j |X_jb| + (sum |C_a.| |R|) (e_A sum_j |X_jb| + e_B)
// + e_D, each e the largest error of its matrix's entries; plus the rounding of the sum itself,
// 4 n eps sum_j |C_aj| |X_jb|. A pair that a conservation law or a symmetry makes zero at every
// frequency (|H| <- an internal motor: C_H A = 0 and C_H B = 0) is a cancellation of terms that
// large: its bound must be theirs, not a fraction of another pair's |G| (a user's scene failed
// |H| <- gimbal.motor1 at 2.1e-12 against 3.3e-15 so).
Eigen::MatrixXd transfer_allowance(const EngineLinearModel& m, double w) {
  const double eps = std::numeric_limits<double>::epsilon();
  const Eigen::Index n = m.A.rows();
  Eigen::MatrixXcd Z = -m.A.cast<cd>();
  Z.diagonal().array() += cd(0, w);
  const Eigen::PartialPivLU<Eigen::MatrixXcd> lu = Z.partialPivLu();
  const MatrixXd X = lu.solve(m.B.cast<cd>()).cwiseAbs();
  const MatrixXd R = lu.inverse().cwiseAbs();
  const MatrixXd Ca = m.C.cwiseAbs();
  const double e_A = m.a_method.error + 16 * eps * (n ? m.A.cwiseAbs().maxCoeff() : 0.0);
  const double e_B = 16 * eps * (m.B.size() ? m.B.cwiseAbs().maxCoeff() : 0.0);
  const double e_D = 16 * eps * (m.D.size() ? m.D.cwiseAbs().maxCoeff() : 0.0);
  const Eigen::VectorXd CR = (Ca * R).rowwise().sum();            // per output
  const Eigen::RowVectorXd Xsum = X.colwise().sum();              // per input
  MatrixXd allow = 4.0 * static_cast<double>(std::max<Eigen::Index>(n, 1)) * eps * (Ca * X + m.D.cwiseAbs());
  allow += m.c_method.error * Eigen::VectorXd::Ones(m.C.rows()) * Xsum;
  allow += CR * (e_A * Xsum + Eigen::RowVectorXd::Constant(Xsum.size(), e_B));
  allow.array() += e_D;
  return allow;
}

// One "analytic" check per engine and expected eigenvalue (those with Im >= 0): the engine's
// nearest eigenvalue within rtol |expected| + 1e-14 + that eigenvalue's allowance (eigen_analysis).
void closed_form_checks(LinearizeResult& r, const std::vector<cd>& expected, const std::string& what, double rtol) {
  for (const cd& x : expected) {
    if (x.imag() < 0) continue;
    for (const EngineLinearModel& m : r.engines) {
      if (!m.failure.empty()) continue;
      LinearCheck c;
      c.kind = "analytic";
      c.what = what;
      c.engine_a = m.label;
      c.engine_b = "analytic";
      c.b = x;
      double best = std::numeric_limits<double>::infinity(), allowance = 0;
      for (std::size_t q = 0; q < m.eigenvalues.size(); ++q)
        if (std::abs(m.eigenvalues[q] - x) < best) {
          best = std::abs(m.eigenvalues[q] - x);
          c.a = m.eigenvalues[q];
          allowance = m.allowances[q];
        }
      c.error = best;
      c.bound = rtol * std::abs(x) + 1e-14 + allowance;
      c.passed = c.error <= c.bound;
      r.checks.push_back(c);
    }
  }
}

// The eigenvalues of M q'' + D q' + K q = 0 (first-order form [0 1; -M^-1 K  -M^-1 D]).
std::vector<cd> quadratic_eigenvalues(const MatrixXd& M, const MatrixXd& D, const MatrixXd& K) {
  const Eigen::Index n = M.rows();
  MatrixXd Z = MatrixXd::Zero(2 * n, 2 * n);
  const Eigen::PartialPivLU<MatrixXd> lu(M);
  Z.topRightCorner(n, n).setIdentity();
  Z.bottomLeftCorner(n, n) = -lu.solve(K);
  Z.bottomRightCorner(n, n) = -lu.solve(D);
  const Eigen::EigenSolver<MatrixXd> es(Z, false);
  std::vector<cd> out;
  for (Eigen::Index k = 0; k < 2 * n; ++k) out.push_back(es.eigenvalues()(k));
  return out;
}

// A lone free rigid body without loads: the analytic eigenvalues of Euler's equations about a
// steady spin w = Omega e_k along principal axis k (i, j the others): lambda^2 =
// Omega^2 (I_j - I_k)(I_k - I_i) / (I_i I_j) (Hughes, Spacecraft Attitude Dynamics, 1986, Sec. 4.4,
// Eq. (19)): +-i Omega sqrt((I_k - I_i)(I_k - I_j) / (I_i I_j)) about the major and minor axes
// (the nutation frequency seen in the body), +-Omega sqrt(...) real about the intermediate one.
void analytic_checks(const System& s, const TreeState& op, LinearizeResult& r, double rtol) {
  if (s.bodies.size() != 1 || !s.base_is_free() || s.bodies[0].flex || !s.bodies[0].torque.empty()) return;
  const Eigen::Matrix3d I = s.bodies[0].I_BBo_B;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(I);
  const Vector3d w = op.w_NB_B;
  if (w.norm() == 0) return;
  int k = -1;
  for (int c = 0; c < 3; ++c)
    if (std::abs(std::abs(es.eigenvectors().col(c).dot(w)) - w.norm()) <= 1e-12 * w.norm()) k = c;
  if (k < 0) {
    r.findings.push_back("the lone body's spin is not along a principal axis: no analytic eigenvalues "
                         "(the operating point is then not a steady spin)");
    return;
  }
  const int i = (k + 1) % 3, j = (k + 2) % 3;
  const Vector3d Ip = es.eigenvalues();
  const double Om = w.norm();
  const double l2 = Om * Om * (Ip(j) - Ip(k)) * (Ip(k) - Ip(i)) / (Ip(i) * Ip(j));
  const cd expected = l2 < 0 ? cd(0, std::sqrt(-l2)) : cd(std::sqrt(l2), 0);
  const std::string axis = (Ip(k) >= Ip.maxCoeff()) ? "major" : (Ip(k) <= Ip.minCoeff()) ? "minor" : "intermediate";
  closed_form_checks(r, {expected}, std::string(l2 < 0 ? "nutation frequency" : "growth rate") + " of a spin about the " + axis +
                     " axis (Euler's equations)", rtol);
}

// A lone free rigid body on a circular orbit, turning with the orbit frame with its principal
// axes along the orbit frame's (x along-track, y the negative orbit normal, z nadir): its pitch
// libration lambda^2 = -3 n^2 (Ix - Iz) / Iy and its coupled roll-yaw motion
//   lambda^4 + n^2 (1 + 3 k1 + k1 k3) lambda^2 + 4 k1 k3 n^4 = 0,  k1 = (Iy - Iz) / Ix,
//   k3 = (Iy - Ix) / Iz  (Wie 2008, "Space Vehicle Dynamics and Control", 2nd ed., Sec. 6.4.2;
// Hughes 2004, Sec. 9.3: stable in the Lagrange region Iy > Ix > Iz).
void gravity_gradient_checks(const System& s, const TreeState& op, double t, LinearizeResult& r, double rtol) {
  if (s.bodies.size() != 1 || !s.base_is_free() || s.bodies[0].flex || !s.bodies[0].torque.empty()) return;
  const Eigen::Matrix3d& I = s.bodies[0].I_BBo_B;
  const OrbitFrame f = orbit_frame(s.environment, t);
  const Eigen::Matrix3d R_OB = f.R_NO.transpose() * op.q_NB.normalized().toRotationMatrix();
  const Vector3d w_OB_B = op.w_NB_B - op.q_NB.normalized().toRotationMatrix().transpose() * f.w_NO_N;
  const double off = (I - Eigen::Matrix3d(I.diagonal().asDiagonal())).cwiseAbs().maxCoeff();
  if ((R_OB - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-12 || off > 1e-12 * I.norm() ||
      w_OB_B.norm() > 1e-12 * f.n) {
    r.findings.push_back("the lone body on the orbit is not at rest in the orbit frame with its principal "
                         "axes along it: no analytic libration eigenvalues");
    return;
  }
  const double n = f.n, Ix = I(0, 0), Iy = I(1, 1), Iz = I(2, 2);
  auto root = [](cd l2) { return std::sqrt(l2); };
  std::vector<cd> pitch{root(cd(-3 * n * n * (Ix - Iz) / Iy, 0))};
  pitch.push_back(-pitch[0]);
  const double k1 = (Iy - Iz) / Ix, k3 = (Iy - Ix) / Iz;
  const double b = n * n * (1 + 3 * k1 + k1 * k3), c = 4 * k1 * k3 * n * n * n * n;
  const cd disc = std::sqrt(cd(b * b - 4 * c, 0));
  std::vector<cd> roll_yaw;
  for (const cd l2 : {(-b + disc) / 2.0, (-b - disc) / 2.0}) {
    roll_yaw.push_back(root(l2));
    roll_yaw.push_back(-root(l2));
  }
  closed_form_checks(r, pitch, "gravity-gradient pitch libration, n sqrt(3 (Ix - Iz) / Iy)", rtol);
  closed_form_checks(r, roll_yaw, "gravity-gradient roll-yaw libration", rtol);
}

// A gyrostat: a free rigid platform carrying one wheel (cyclic_rotor) whose axis a is a principal
// axis of the whole, the platform spinning at omega about a and the wheel at Omega_r relative to
// it, h_r = J_s Omega_r (J_s the wheel's axial moment). Euler's equations of the whole,
// d/dt (I w + h_r a) + w x (I w + h_r a) = 0, linearised about w = omega a:
//   lambda^2 = -(omega (I_3 - I_1) + h_r)(omega (I_3 - I_2) + h_r) / (I_1 I_2)
// (Hughes, Spacecraft Attitude Dynamics, 1986, Sec. 7.2, the gyrostat's nutation; I the whole
// spacecraft's inertia about its CM, I_3 about a): a nutation frequency when both factors share a
// sign, a growth rate otherwise (a minor-axis spin is stabilised by a fast enough wheel).
void gyrostat_checks(const System& s, const TreeState& op, LinearizeResult& r, double rtol) {
  if (s.bodies.size() != 2 || s.joints.size() != 2 || !s.base_is_free() || !cyclic_rotor(s, 1)) return;
  for (const Body& b : s.bodies)
    if (b.flex || !b.torque.empty()) return;
  const Joint& J = s.joints[1];
  if (J.has_motor() || J.has_damper()) return;
  const Vector3d a = J.axis_P.normalized();  // in the platform's frame
  const Eigen::Matrix3d I = composite_inertia_B(s, op);
  const double I3 = a.dot(I * a);
  if ((I * a - I3 * a).norm() > 1e-12 * I.norm()) return;  // a not principal: no steady spin
  const Vector3d w = op.w_NB_B;
  if ((w - w.dot(a) * a).norm() > 1e-12 * std::max(w.norm(), 1e-300)) return;
  const double omega = w.dot(a);
  // The transverse principal moments: the two eigenvalues of I whose eigenvectors are not a.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(I);
  int k3 = 0;
  for (int q = 1; q < 3; ++q)
    if (std::abs(es.eigenvectors().col(q).dot(a)) > std::abs(es.eigenvectors().col(k3).dot(a))) k3 = q;
  const double I1 = es.eigenvalues()((k3 + 1) % 3), I2 = es.eigenvalues()((k3 + 2) % 3);
  const Vector3d a_C = axis_in_child(J);
  const double hr = a_C.dot(s.bodies[static_cast<std::size_t>(J.child)].I_BBo_B * a_C) * op.joints[1].rate;
  const double l2 = -(omega * (I3 - I1) + hr) * (omega * (I3 - I2) + hr) / (I1 * I2);
  if (l2 == 0) return;
  const cd expected = l2 < 0 ? cd(0, std::sqrt(-l2)) : cd(std::sqrt(l2), 0);
  closed_form_checks(r, {expected},
                     std::string(l2 < 0 ? "nutation frequency" : "growth rate") + " of a gyrostat (h_r = " + num(hr, 6) +
                         " N m s, platform spin " + num(omega, 6) + " rad/s; Euler's equations of the whole)",
                     rtol);
}

// One flexible body rigidly carried by a prescribed base turning at a constant rate Omega about
// its fixed axis a (every other joint fixed or prescribed at rest: the modal coordinates are the
// only degrees of freedom): its modal equations in the turning frame, derived here from the
// Lagrangian L = 1/2 sum_i m_i |rho_i' + w x rho_i|^2 - 1/2 eta^T K eta with w = Omega a and
// rho_i = r_i + Phi_i eta + e_i (1/2 eta^T G_i eta) (system.hpp's node model; r_i from a point of
// the axis), independently of every engine (Meirovitch, "Methods of Analytical Dynamics", 1970,
// Sec. 4.9, a Lagrangian in a rotating frame; Kane, Ryan and Banerjee 1987 for the
// foreshortening):
//   M eta'' + (D + Gy) eta' + (K - Omega^2 S - Omega^2 C) eta = 0,
//   M = sum m_i Phi_i^T Phi_i,   Gy = 2 Omega sum m_i Phi_i^T [a x] Phi_i,
//   S = sum m_i Phi_i^T (1 - a a^T) Phi_i           (centrifugal softening),
//   C = sum m_i (r_i . e_i - (r_i . a)(e_i . a)) G_i (geometric stiffening: G_i <= 0 stiffens).
// Its eigenvalues are the spinning beam's rotating-frame ones, with or without stiffening; at
// Omega = 0 a cantilever's (a clamped beam on a base at rest).
void spinning_flexible_checks(const System& s, double t, LinearizeResult& r, double rtol) {
  if (s.base_is_free() || s.joints.empty() || !s.joints[0].prescribed) return;
  int flex = -1;
  for (std::size_t b = 0; b < s.bodies.size(); ++b)
    if (s.bodies[b].flex) {
      if (flex >= 0) return;
      flex = static_cast<int>(b);
    }
  if (flex < 0) return;
  for (std::size_t j = 1; j < s.joints.size(); ++j)
    if (s.joints[j].type != JointType::Fixed && !s.joints[j].prescribed) return;
  for (std::size_t j = 1; j < s.joints.size(); ++j)
    if (s.joints[j].prescribed && (s.joints[j].prescribed->velocity(t) != 0 || s.joints[j].prescribed->accel(t) != 0)) return;
  const Joint& base = s.joints[0];
  if (base.prescribed->accel(t) != 0) return;
  const double Om = base.prescribed->velocity(t);
  const FlexBody& F = *s.bodies[static_cast<std::size_t>(flex)].flex;
  const geometry::Configuration c = geometry::initial_configuration(s);
  const Eigen::Matrix3d R = c.bodies[static_cast<std::size_t>(flex)].R_NB;
  const Vector3d a = base.axis_P.normalized(), o = base.p_PoJ_P;
  const Eigen::Matrix3d ax = rot::skew(a);
  const int n = F.modes();
  MatrixXd M = MatrixXd::Zero(n, n), Gy = MatrixXd::Zero(n, n), S = MatrixXd::Zero(n, n), C = MatrixXd::Zero(n, n);
  for (std::size_t i = 0; i < F.nodes.size(); ++i) {
    const FlexNode& node = F.nodes[i];
    const Eigen::Matrix3Xd Phi = R * node.Phi_B;
    const Vector3d ri = c.nodes_N[static_cast<std::size_t>(flex)][i] - o;
    M += node.mass * Phi.transpose() * Phi;
    Gy += 2 * Om * node.mass * Phi.transpose() * ax * Phi;
    S += node.mass * Phi.transpose() * (Eigen::Matrix3d::Identity() - a * a.transpose()) * Phi;
    if (F.geometric_stiffening && node.G.size() > 0) {
      const Vector3d e = R * node.e_B;
      C += node.mass * (ri.dot(e) - ri.dot(a) * e.dot(a)) * node.G;
    }
  }
  closed_form_checks(r, quadratic_eigenvalues(M, F.D + Gy, F.K - Om * Om * S - Om * Om * C),
                     "rotating-frame eigenvalue of the flexible body spinning at " + num(Om) + " rad/s (" +
                         (F.geometric_stiffening ? "with" : "without") + " geometric stiffening; modal Lagrangian)",
                     rtol);
}

// A lone free flexible body at rest without loads: its modes with the rigid body's translation and
// rotation condensed out (both are cyclic, their momenta zero), from the linearised kinetic energy
// T = 1/2 sum_i m_i |v + w x p_i + Phi_i eta'|^2 + 1/2 w . J w (sum m_i p_i = 0, the body origin
// being the undeformed CM):
//   M_eff = M - L^T L / m - R^T I^-1 R,  L = sum m_i Phi_i,  R = sum m_i [p_i x] Phi_i,
//   M_eff eta'' + D eta' + K eta = 0
// (Meirovitch, "Fundamentals of Vibrations", 2001, Sec. 7.4 on the free-free body's rigid-body
// modes; L and R vanish for modes orthogonal to the rigid-body motions, so that these are then
// the body's own frequencies, a free-free beam's lambda_k^2 sqrt(EI / (rho A L^4))).
void free_flexible_checks(const System& s, const TreeState& op, LinearizeResult& r, double rtol) {
  if (s.bodies.size() != 1 || !s.base_is_free() || !s.bodies[0].flex || !s.bodies[0].torque.empty()) return;
  if (op.w_NB_B.norm() != 0 || op.eta[0].norm() != 0 || op.eta_rate[0].norm() != 0) return;
  const FlexBody& F = *s.bodies[0].flex;
  const int n = F.modes();
  if (n == 0) return;
  MatrixXd M = MatrixXd::Zero(n, n);
  Eigen::Matrix3Xd L = Eigen::Matrix3Xd::Zero(3, n), R = Eigen::Matrix3Xd::Zero(3, n);
  for (const FlexNode& node : F.nodes) {
    M += node.mass * node.Phi_B.transpose() * node.Phi_B;
    L += node.mass * node.Phi_B;
    for (int k = 0; k < n; ++k) R.col(k) += node.mass * node.p_BoNi_B.cross(node.Phi_B.col(k));
  }
  const MatrixXd Meff = M - L.transpose() * L / s.bodies[0].mass -
                        R.transpose() * (s.bodies[0].I_BBo_B.inverse() * R);
  closed_form_checks(r, quadratic_eigenvalues(Meff, F.D, F.K),
                     "free flexible body at rest: its modes with the rigid motions condensed out", rtol);
}

// The joint and modal coordinates of an equilibrium near `op` (every joint rate kept), and with
// `free_spin` the base's w too (a steady spin: w x (I w + h) = 0 with a wheel's momentum h, which
// need not be along a principal axis): Gauss-Newton on the velocity rows of dz/dt
// (accelerations) of the first engine's equations, minimum-norm steps (a joint without a spring,
// free to turn, stays where it is; the spin keeps its rate, a direction the residual does not
// see); the other engines' residuals are checked afterwards like any operating point's.
TreeState settle(const System& system, const TreeState& op, const LinearizeOptions& o, bool free_spin,
                 std::string& how) {
  const ReducedMap map(system, op, o.time);
  const int n = map.size(), nc = map.configuration_size(), nv = n - nc;
  // The unknowns: the configuration coordinates, and the base's w when free.
  std::vector<int> unknowns;
  for (int i = 0; i < n; ++i)
    if (i < nc || (free_spin && map.coordinate(i).kind == Coordinate::Kind::BaseW)) unknowns.push_back(i);
  const int nu = static_cast<int>(unknowns.size());
  if (nu == 0 || nv == 0) return op;
  const LinearEngineChoice& choice = o.engines.front();
  const std::unique_ptr<Engine> engine = choice.make(system);
  Probe probe;
  probe.engine = engine.get();
  probe.map = &map;
  probe.t = o.time;
  probe.x.resize(static_cast<std::size_t>(engine->state_size()));
  VectorXd f;
  auto residual = [&](const VectorXd& zz) {
    probe.eval(zz, f, nullptr);
    return VectorXd(f.tail(nv));
  };
  struct Solved {
    VectorXd z, res;
    int iterations = 0;
    bool converged = false;
  };
  // Gauss-Newton (Levenberg-Marquardt with a tiny mu) from z.
  auto solve = [&](VectorXd z) {
    VectorXd res = residual(z);
    int iterations = 0;
    double scale = 0;
    bool converged = false;
    int polish = 0;
    for (; iterations < 40; ++iterations) {
      MatrixXd J(nv, nu);
      for (int k = 0; k < nu; ++k) {
        const int j = unknowns[static_cast<std::size_t>(k)];
        const double h = 1e-6 * std::max(std::abs(z(j)), 1.0);
        VectorXd zp = z, zm = z;
        zp(j) += h;
        zm(j) -= h;
        J.col(k) = (residual(zp) - residual(zm)) / (2 * h);
      }
      scale = std::max(scale, J.lpNorm<Eigen::Infinity>() * std::max(z.lpNorm<Eigen::Infinity>(), 1.0));
      // Converged: then up to three more steps while the residual still falls (to rounding).
      if (res.lpNorm<Eigen::Infinity>() <= 1e-3 * o.residual_tol * scale) {
        converged = true;
        if (++polish > 3 || res.lpNorm<Eigen::Infinity>() == 0) break;
      }
      // Levenberg-Marquardt's (J^T J + mu D)^-1 J^T r with a tiny mu and Marquardt's scaling D =
      // diag(J^T J) (each coordinate damped against its own stiffness: on an orbit the attitude's
      // gravity-gradient stiffness, n^2 ~ 1e-6, sits beside a spring's 20, and damping against
      // the trace stalled the attitude 1 deg from its equilibrium), floored at 1e-30 of the trace
      // so that a coordinate the residual does not see (a joint without a spring) stays put.
      MatrixXd JtJ = J.transpose() * J;
      const double floor = 1e-30 * std::max(JtJ.trace(), 1e-300);
      for (Eigen::Index d = 0; d < JtJ.rows(); ++d) JtJ(d, d) += 1e-12 * std::max(JtJ(d, d), floor);
      const VectorXd step = JtJ.partialPivLu().solve(J.transpose() * res);
      // Halve the step until the residual falls (at most 30 times).
      double a = 1;
      VectorXd next = z, next_res;
      for (int k = 0; k < 30; ++k, a /= 2) {
        for (int k = 0; k < nu; ++k) next(unknowns[static_cast<std::size_t>(k)]) = z(unknowns[static_cast<std::size_t>(k)]) - a * step(k);
        next_res = residual(next);
        if (next_res.norm() < res.norm()) break;
      }
      if (!(next_res.norm() < res.norm())) break;
      z = next;
      res = next_res;
    }
    return Solved{z, res, iterations, converged};
  };
  Solved best = solve(map.z0());
  std::string restarts;
  if (!best.converged && nc > 0) {
    // Stalled: the start is a stationary point of the residual's norm (a pendulum released
    // horizontal under gravity: no first-order change of its torque there), or too far. Restart
    // from each configuration coordinate moved by -0.5 and +0.5 (rad or m) and keep, of the
    // equilibria found, the one of least energy E (the engine's own output): a hanging pendulum,
    // not the inverted one.
    std::vector<double> row(engine->layout().size());
    std::vector<double> x(static_cast<std::size_t>(engine->state_size()));
    auto energy = [&](const VectorXd& zz) {
      engine->pack(map.state(zz), x.data());
      engine->output_row(o.time, x.data(), row.data());
      return row[static_cast<std::size_t>(engine->layout().E())];
    };
    int found = 0;
    double best_E = INFINITY;
    for (int k = 0; k < nc; ++k)
      for (double d : {-0.5, 0.5}) {
        VectorXd z = map.z0();
        z(k) += d;
        Solved s = solve(z);
        if (!s.converged) continue;
        ++found;
        const double E = energy(s.z);
        if (E < best_E) {
          best_E = E;
          best = s;
        }
      }
    restarts = found == 0 ? "; restarted from each configuration coordinate moved by -0.5 and +0.5: "
                            "no equilibrium found"
                          : "; from the initial state the solve stalled, so it restarted from each "
                            "configuration coordinate moved by -0.5 and +0.5 and kept, of the " +
                                std::to_string(found) + " solutions, the one of least energy E";
  }
  how += std::string("; its joint and modal coordinates") + (free_spin ? " and the spin" : "") +
         " solved for an equilibrium with " + choice.label + "'s equations (" +
         std::to_string(best.iterations) + " Gauss-Newton step" + (best.iterations == 1 ? "" : "s") +
         ", acceleration residual " + num(best.res.lpNorm<Eigen::Infinity>(), 3) + restarts + ")";
  const VectorXd& z = best.z;
  return map.state(z);
}

}  // namespace

std::vector<std::string> linear_input_names(const System& system, bool named_only) {
  std::vector<std::string> names;
  for (const InputRef& u : all_inputs(system))
    if (!named_only || input_named_by_scene(system, u)) names.push_back(u.name);
  return names;
}

std::unique_ptr<Engine> LinearEngineChoice::make(const System& system) const {
  return factory ? factory(system, options) : make_engine(engine, system, options);
}

bool LinearizeResult::passed() const {
  for (const LinearCheck& c : checks)
    if (!c.passed) return false;
  for (const EngineLinearModel& m : engines)
    if (!m.failure.empty()) return false;
  return true;
}

LinearizeResult linearize(const System& system, const LinearizeOptions& o) {
  // On an orbit the base's attitude relative to the orbit frame is a coordinate (ReducedMap), and
  // a relative equilibrium turns with the orbit frame, not about a principal axis: `spin` does
  // not apply there.
  if (system.environment.orbit() && o.point == OperatingPoint::Spin)
    throw InputError(system.file + ": --operating-point spin is a torque-free steady spin; on an orbit "
                     "use neutral or equilibrium (the attitude and the rate relative to the orbit "
                     "frame are in z: a body turning with the orbit is at rest there)");
  LinearizeResult r;
  r.scene = system.name;
  r.time = o.time;
  TreeState op = operating_state(system, o.time, o.point, r.how);
  if ((o.point == OperatingPoint::Equilibrium || o.point == OperatingPoint::Spin) && !o.engines.empty()) {
    // Spin: from the principal axis nearest the initial rate (operating_state), the joints and the
    // spin are solved together (the axis moves as the joints settle, and a wheel tilts it).
    const bool free_spin = o.point == OperatingPoint::Spin && system.base_is_free() && op.w_NB_B.norm() > 0;
    op = settle(system, op, o, free_spin, r.how);
  }
  r.op = op;
  const ReducedMap map(system, op, o.time);
  r.states = map.names();
  r.z0 = map.z0();
  const int n = map.size();

  // Inputs and outputs, checked before any engine runs.
  const std::vector<InputRef> known_inputs = all_inputs(system);
  std::vector<InputRef> inputs;
  if (!o.inputs_given) {
    for (const InputRef& u : known_inputs)
      if (input_named_by_scene(system, u)) inputs.push_back(u);
  } else {
    for (const std::string& name : o.inputs) {
      auto it = std::find_if(known_inputs.begin(), known_inputs.end(), [&](const InputRef& u) { return u.name == name; });
      if (it == known_inputs.end()) {
        std::string list;
        std::vector<std::string> names;
        for (const InputRef& u : known_inputs) {
          list += (list.empty() ? "" : ", ") + u.name;
          names.push_back(u.name);
        }
        const std::string near = closest_match(name, names);
        throw InputError("--inputs: '" + name + "' is not an input of this scene" +
                         (near.empty() ? "" : " (did you mean '" + near + "'?)") + "; its inputs: " +
                         (list.empty() ? std::string("none") : list));
      }
      inputs.push_back(*it);
    }
  }
  for (const InputRef& u : inputs) r.inputs.push_back(u.name);
  const int m_in = static_cast<int>(inputs.size());
  r.outputs = o.outputs;

  for (const LinearEngineChoice& choice : o.engines) {
    EngineLinearModel m;
    m.label = choice.label;
    const std::unique_ptr<Engine> engine = choice.make(system);
    Probe probe;
    probe.engine = engine.get();
    probe.map = &map;
    probe.t = o.time;
    probe.x.resize(static_cast<std::size_t>(engine->state_size()));
    probe.row.resize(engine->columns().size());
    for (const std::string& y : o.outputs) {
      const std::vector<std::string>& cols = engine->columns();
      auto it = std::find(cols.begin(), cols.end(), y);
      if (it == cols.end() || y == "t") {
        const std::string near = closest_match(y, cols);
        throw InputError("--outputs: '" + y + "' is not an output column of this scene" +
                         (near.empty() || near == "t" ? "" : " (did you mean '" + near + "'?)") + "; see `crossdyn run " +
                         system.name + "`'s header, the pinned columns of docs/conventions.md");
      }
      probe.output_columns.push_back(static_cast<int>(it - cols.begin()));
    }
    const int p = static_cast<int>(o.outputs.size());
    try {
      VectorXd zd0, y0;
      probe.eval(r.z0, zd0, &y0);
      m.residual = zd0;
      m.A.resize(n, n);
      m.C.resize(p, n);
      MatrixXd Aerr(n, n), Cerr(p, n);
      for (int j = 0; j < n; ++j) {
        const Derivative dA = best_derivative(
            [&](const VectorXd& z, VectorXd& f) {
              VectorXd y;
              probe.eval(z, f, p > 0 ? &y : nullptr);
              if (p > 0) {
                f.conservativeResize(n + p);
                f.tail(p) = y;
              }
            },
            r.z0, j, o.fd_step, n + p);
        m.A.col(j) = dA.d.head(n);
        Aerr.col(j) = dA.error.head(n);
        if (p > 0) {
          m.C.col(j) = dA.d.tail(p);
          Cerr.col(j) = dA.error.tail(p);
        }
      }
      // Rounding: each difference carries ~ eps |f| / h, amplified ~ 3 by the extrapolations.
      const double eps = std::numeric_limits<double>::epsilon();
      const double fscale = std::max(zd0.lpNorm<Eigen::Infinity>(), m.A.lpNorm<Eigen::Infinity>() * std::max(r.z0.lpNorm<Eigen::Infinity>(), 1.0));
      m.a_method.error = (n ? Aerr.maxCoeff() : 0.0) + 8 * eps * fscale;
      const double yscale = p ? std::max(y0.lpNorm<Eigen::Infinity>(), 1.0) : 1.0;
      m.c_method.error = p && n ? Cerr.maxCoeff() + 8 * eps * yscale : 0.0;
      // Exact: the engine's own tangents, column by column along the variations of z at the
      // operating point; the differences above their cross-check.
      if (n > 0) {
        const TreeState s0 = map.state(r.z0);
        MatrixXd Ax(n, n), Cx(p, n);
        TreeAccel a0, da;
        std::vector<double> row(engine->columns().size()), drow(row.size());
        bool a_exact = true, c_exact = p > 0;
        for (int j = 0; j < n && (a_exact || c_exact); ++j) {
          const VectorXd e = VectorXd::Unit(n, j);
          const TreeTangent dz = map.tangent(e);
          if (a_exact) a_exact = engine->accelerations_tangent(o.time, s0, dz, a0, da);
          if (a_exact) Ax.col(j) = map.rate_tangent(r.z0, e, da);
          if (c_exact) c_exact = engine->output_row_tangent(o.time, s0, dz, row.data(), drow.data());
          if (c_exact)
            for (int k = 0; k < p; ++k) Cx(k, j) = drow[static_cast<std::size_t>(probe.output_columns[static_cast<std::size_t>(k)])];
        }
        // Rounding of the engine's own evaluation: a few eps of the scale of its terms.
        if (a_exact) adopt_exact(m.A, Ax, 16 * eps * fscale, m.a_method);
        if (c_exact) adopt_exact(m.C, Cx, 16 * eps * yscale * std::max(1.0, m.C.lpNorm<Eigen::Infinity>()), m.c_method);
      }
      const double denom = (n ? m.A.lpNorm<Eigen::Infinity>() : 0.0) * std::max(r.z0.lpNorm<Eigen::Infinity>(), 1.0);
      const double res = n ? zd0.lpNorm<Eigen::Infinity>() : 0.0;
      m.relative_residual = denom > 0 ? res / denom : (res > 0 ? std::numeric_limits<double>::infinity() : 0.0);

      // B and D: the equations are linear in the loads, so one central difference is exact to
      // rounding (delta = max(1, |u|) in the load's unit).
      m.B.resize(n, m_in);
      m.D.resize(p, m_in);
      for (int k = 0; k < m_in; ++k) {
        const InputRef& u = inputs[static_cast<std::size_t>(k)];
        const double delta = std::max(1.0, std::abs(input_value(system, u, o.time)));
        VectorXd f[2], y[2];
        for (int side = 0; side < 2; ++side) {
          const System s = with_input(system, u, o.time, side == 0 ? delta : -delta);
          const std::unique_ptr<Engine> e = choice.make(s);
          Probe q = probe;
          q.engine = e.get();
          q.eval(r.z0, f[side], p > 0 ? &y[side] : nullptr);
        }
        m.B.col(k) = (f[0] - f[1]) / (2 * delta);
        if (p > 0) m.D.col(k) = (y[0] - y[1]) / (2 * delta);
      }

      // The engine's own coordinates: d(rhs)/dx at the packed operating point.
      const int nx = engine->state_size();
      std::vector<double> x0(static_cast<std::size_t>(nx));
      engine->pack(op, x0.data());
      const VectorXd X0 = Eigen::Map<const VectorXd>(x0.data(), nx);
      m.own_A.resize(nx, nx);
      for (int i = 0; i < nx; ++i) m.own_states.push_back(engine->state_label(i));
      for (int j = 0; j < nx; ++j) {
        const Derivative d = best_derivative(
            [&](const VectorXd& x, VectorXd& f) {
              f.resize(nx);
              engine->rhs(o.time, x.data(), f.data());
            },
            X0, j, o.fd_step, nx);
        m.own_A.col(j) = d.d;
        m.own_method.error = std::max(m.own_method.error, nx ? d.error.maxCoeff() : 0.0);
      }
      if (nx > 0) {
        MatrixXd Ox(nx, nx);
        std::vector<double> f0(static_cast<std::size_t>(nx)), df(f0.size());
        bool exact = true;
        for (int j = 0; j < nx && exact; ++j) {
          const VectorXd e = VectorXd::Unit(nx, j);
          exact = engine->rhs_tangent(o.time, x0.data(), e.data(), f0.data(), df.data());
          if (exact) Ox.col(j) = Eigen::Map<const VectorXd>(df.data(), nx);
        }
        const double oscale = std::max(Eigen::Map<const VectorXd>(f0.data(), nx).lpNorm<Eigen::Infinity>(),
                                       m.own_A.lpNorm<Eigen::Infinity>() * std::max(X0.lpNorm<Eigen::Infinity>(), 1.0));
        if (exact) adopt_exact(m.own_A, Ox, 16 * eps * oscale, m.own_method);
      }
      eigen_analysis(m, map, o.zero_tol);
    } catch (const RunFailure& f) {
      m.failure = f.what();
    }
    r.engines.push_back(std::move(m));
  }

  // An equilibrium (of the reduced equations) in every engine, or refused.
  r.equilibrium = true;
  for (const EngineLinearModel& m : r.engines)
    if (m.failure.empty() && !(m.relative_residual <= o.residual_tol)) r.equilibrium = false;
  if (!r.equilibrium && !o.jacobian_only) {
    std::ostringstream msg;
    msg << system.file << ": the operating point (" << r.how << ", t = " << num(o.time)
        << " s) is not an equilibrium or a steady spin: ";
    bool first = true;
    for (const EngineLinearModel& m : r.engines) {
      if (!m.failure.empty()) continue;
      Eigen::Index k = 0;
      m.residual.cwiseAbs().maxCoeff(&k);
      msg << (first ? "" : "; ") << m.label << " d/dt " << r.states[static_cast<std::size_t>(k)] << " = "
          << num(m.residual(k)) << " (|dz/dt| " << num(m.relative_residual, 3) << " of |A| max(|z|, 1), allowed "
          << num(o.residual_tol, 3) << ")";
      first = false;
    }
    bool spin_rows = false;
    for (const EngineLinearModel& m : r.engines) {
      if (!m.failure.empty()) continue;
      Eigen::Index k = 0;
      m.residual.cwiseAbs().maxCoeff(&k);
      spin_rows = spin_rows || map.coordinate(static_cast<int>(k)).kind == Coordinate::Kind::BaseW;
    }
    if (spin_rows && o.point != OperatingPoint::Spin)
      msg << ". The base's spin is not about a principal axis of the whole spacecraft there: try "
             "--operating-point spin";
    std::string loads;
    for (const InputRef& u : known_inputs)
      if (const double v = input_value(system, u, o.time); v != 0) loads += (loads.empty() ? "" : ", ") + u.name + " = " + num(v);
    if (!loads.empty()) msg << ". Loads at t = " << num(o.time) << " s: " << loads << " (a --time where they are off?)";
    msg << ". Try " << (o.point == OperatingPoint::Neutral ? "" : "--operating-point neutral, ")
        << "another --time, or --jacobian-only for each engine's Jacobian there (coordinate-dependent, "
           "not compared)";
    throw InputError(msg.str());
  }
  // Each exact matrix against its own finite differences (the cross-check that the engine's tangent
  // is right): A, C and the engine's own Jacobian, at an equilibrium or not.
  for (const EngineLinearModel& m : r.engines) {
    if (!m.failure.empty()) continue;
    auto cross_check = [&](const MatrixMethod& how, const MatrixXd& M, const std::string& entry) {
      if (!how.exact || M.size() == 0) return;
      LinearCheck c;
      c.kind = "jacobian";
      c.what = entry + " (the largest difference)";
      c.engine_a = m.label;
      c.engine_b = m.label + " differences";
      c.a = how.worst.exact;
      c.b = how.worst.differences;
      c.error = how.fd_difference;
      // The differences' error is an estimate, not a bound: newton-euler's differences exceeded
      // theirs 8.5-fold on spinup_beam at t = 20 s and 3.4-fold on iftomm_pendulum (its constrained
      // solve's rounding times m L^2 / I = 1e6), where its exact A agrees with the other engines' to
      // 5e-11. Hence 100 x the estimate plus 1e-9 of the matrix's largest entry: a missing or wrong
      // term of a tangent moves entries by far more (a gravity-gradient entry of 4e-6 |A| changed by
      // 1% is 40 times this floor).
      c.bound = 100 * how.fd_error + 1e-9 * M.cwiseAbs().maxCoeff();
      c.passed = c.error <= c.bound;
      r.checks.push_back(c);
    };
    const auto state = [&](Eigen::Index i) { return r.states[static_cast<std::size_t>(i)]; };
    cross_check(m.a_method, m.A,
                "A exact vs its finite differences, entry d/dt " + state(m.a_method.worst.row) + " / d " + state(m.a_method.worst.col));
    if (!r.outputs.empty())
      cross_check(m.c_method, m.C,
                  "C exact vs its finite differences, entry d " + r.outputs[static_cast<std::size_t>(m.c_method.worst.row)] +
                      " / d " + state(m.c_method.worst.col));
    if (!m.own_states.empty())
      cross_check(m.own_method, m.own_A,
                  "own-coordinate A exact vs its finite differences, entry d/dt " +
                      m.own_states[static_cast<std::size_t>(m.own_method.worst.row)] + " / d " +
                      m.own_states[static_cast<std::size_t>(m.own_method.worst.col)]);
  }
  if (!r.equilibrium) return r;  // Jacobians only, nothing compared between engines

  // Eigenvalues: each engine against the first that ran.
  const EngineLinearModel* ref = nullptr;
  for (const EngineLinearModel& m : r.engines)
    if (m.failure.empty()) {
      ref = &m;
      break;
    }
  if (!ref) return r;
  double rho = 0;
  for (const cd& l : ref->eigenvalues) rho = std::max(rho, std::abs(l));
  for (const EngineLinearModel& m : r.engines) {
    if (&m == ref || !m.failure.empty()) continue;
    LinearCheck z;
    z.kind = "zeros";
    z.what = "rigid-body zero eigenvalues";
    z.engine_a = ref->label;
    z.engine_b = m.label;
    z.a = ref->zeros;
    z.b = m.zeros;
    z.error = std::abs(ref->zeros - m.zeros);
    z.bound = 0;
    z.passed = ref->zeros == m.zeros;
    r.checks.push_back(z);
    // Match every non-zero eigenvalue (with its conjugate) to the nearest unmatched one.
    std::vector<cd> other;
    std::vector<double> other_allowance;
    for (std::size_t k = 0; k < m.eigenvalues.size(); ++k)
      if (!(std::abs(m.eigenvalues[k]) <= m.zero_bound)) {
        other.push_back(m.eigenvalues[k]);
        other_allowance.push_back(m.allowances[k]);
      }
    std::vector<bool> used(other.size(), false);
    for (const LinearMode& mode : ref->modes) {
      LinearCheck c;
      c.kind = "eigenvalue";
      c.what = mode.coordinate;
      c.engine_a = ref->label;
      c.engine_b = m.label;
      c.a = mode.lambda;
      // Plus both eigenvalues' allowances for the finite differences (eigen_analysis).
      c.bound = o.rtol * std::abs(mode.lambda) + o.atol * rho;
      double best = std::numeric_limits<double>::infinity();
      std::size_t bi = other.size();
      for (std::size_t k = 0; k < other.size(); ++k)
        if (!used[k] && std::abs(other[k] - mode.lambda) < best) {
          best = std::abs(other[k] - mode.lambda);
          bi = k;
        }
      if (bi < other.size()) {
        used[bi] = true;
        c.b = other[bi];
        c.bound += mode.allowance + other_allowance[bi];
        // Its conjugate partner, too.
        if (mode.lambda.imag() != 0) {
          double bc = std::numeric_limits<double>::infinity();
          std::size_t ci = other.size();
          for (std::size_t k = 0; k < other.size(); ++k)
            if (!used[k] && std::abs(other[k] - std::conj(mode.lambda)) < bc) {
              bc = std::abs(other[k] - std::conj(mode.lambda));
              ci = k;
            }
          if (ci < other.size()) used[ci] = true;
        }
        c.error = best;
        c.passed = best <= c.bound;
      } else {
        c.note = "no eigenvalue left to match";
        c.error = std::numeric_limits<double>::infinity();
      }
      r.checks.push_back(c);
    }
  }

  // Transfer functions at a few frequencies between (and beyond) the modes.
  if (!r.inputs.empty() && !r.outputs.empty()) {
    std::vector<double> f;
    for (const LinearMode& mode : ref->modes)
      if (f.empty() || mode.frequency > f.back() * (1 + 1e-6)) f.push_back(mode.frequency);
    if (f.empty()) {
      r.frequencies = {1.0};
    } else {
      r.frequencies.push_back(0.5 * f.front());
      const std::size_t gaps = f.size() - 1;
      std::set<std::size_t> pick;
      if (gaps > 0) {
        pick.insert(0);
        pick.insert(gaps / 2);
        pick.insert(gaps - 1);
      }
      for (std::size_t k : pick) r.frequencies.push_back(std::sqrt(f[k] * f[k + 1]));
      r.frequencies.push_back(2.0 * f.back());
    }
    std::vector<Eigen::MatrixXcd> Gref;
    std::vector<MatrixXd> Aref;
    for (double w : r.frequencies) {
      Gref.push_back(transfer(*ref, w));
      Aref.push_back(transfer_allowance(*ref, w));
    }
    const auto p = static_cast<Eigen::Index>(r.outputs.size()), q = static_cast<Eigen::Index>(r.inputs.size());
    for (const EngineLinearModel& m : r.engines) {
      if (&m == ref || !m.failure.empty()) continue;
      std::vector<MatrixXd> Am;
      for (double w : r.frequencies) Am.push_back(transfer_allowance(m, w));
      for (Eigen::Index a = 0; a < p; ++a)
        for (Eigen::Index b = 0; b < q; ++b) {
          double scale = 0;
          for (const Eigen::MatrixXcd& G : Gref) scale = std::max(scale, std::abs(G(a, b)));
          LinearCheck c;
          c.kind = "transfer";
          c.engine_a = ref->label;
          c.engine_b = m.label;
          // Plus both engines' allowances for rounding and their matrices' errors (largest over
          // the frequencies; transfer_allowance).
          double allowance = 0;
          for (std::size_t k = 0; k < r.frequencies.size(); ++k)
            allowance = std::max(allowance, Aref[k](a, b) + Am[k](a, b));
          c.bound = o.tf_rtol * scale + allowance;
          c.passed = true;
          for (std::size_t k = 0; k < r.frequencies.size(); ++k) {
            const cd gb = transfer(m, r.frequencies[k])(a, b);
            const double e = std::abs(gb - Gref[k](a, b));
            if (e >= c.error) {
              c.error = e;
              c.a = Gref[k](a, b);
              c.b = gb;
              c.what = r.outputs[static_cast<std::size_t>(a)] + " <- " + r.inputs[static_cast<std::size_t>(b)] +
                       " at " + num(r.frequencies[k]) + " rad/s";
            }
          }
          c.passed = c.error <= c.bound;
          r.checks.push_back(c);
        }
    }
  }

  // The closed forms below are for a scene without gravity; on an orbit, a lone rigid body's
  // libration (gravity_gradient_checks).
  if (system.environment.none()) {
    analytic_checks(system, op, r, 1e-10);
    gyrostat_checks(system, op, r, 1e-10);
    spinning_flexible_checks(system, o.time, r, 1e-10);
    free_flexible_checks(system, op, r, 1e-10);
  }
  if (system.environment.orbit()) gravity_gradient_checks(system, op, o.time, r, 1e-10);

  // Unstable modes are findings (each engine's own, so a disagreement shows).
  for (const EngineLinearModel& m : r.engines) {
    if (!m.failure.empty()) continue;
    for (const LinearMode& mode : m.modes)
      if (mode.lambda.real() > o.rtol * mode.frequency + o.atol * rho)
        r.findings.push_back(m.label + ": unstable mode " + mode.coordinate + ", lambda = " + num(mode.lambda, 8) +
                             " (grows by e in " + num(1.0 / mode.lambda.real(), 4) + " s)");
  }
  return r;
}

// ------------------------------------------------------------------------------------------------
// Outputs.

namespace {
// "exact (...)" or "by finite differences (...)": how a matrix was obtained, in the outputs' words.
std::string method_words(const MatrixMethod& how) {
  if (how.exact)
    return "exact (the engine's own tangent; its finite differences within " + num(how.fd_difference, 2) +
           ", their own error " + num(how.fd_error, 2) + ")";
  return "by finite differences (the engine offers no exact tangent here), error <= " + num(how.error, 2);
}
}  // namespace

std::string format_linearization(const LinearizeResult& r) {
  std::ostringstream o;
  o << "linearize " << r.scene << " at t = " << num(r.time) << " s\n";
  o << "operating point: " << r.how << "\n";
  o << "reduced state (" << r.states.size() << "):";
  for (const std::string& s : r.states) o << ' ' << s;
  o << "\ninputs (" << r.inputs.size() << "):";
  for (const std::string& s : r.inputs) o << ' ' << s;
  if (r.inputs.empty()) o << " none";
  o << "\noutputs (" << r.outputs.size() << "):";
  for (const std::string& s : r.outputs) o << ' ' << s;
  if (r.outputs.empty()) o << " none (--outputs)";
  o << "\n\n";
  for (const EngineLinearModel& m : r.engines) {
    if (!m.failure.empty()) {
      o << m.label << ": FAILED: " << m.failure << "\n";
      continue;
    }
    o << m.label << ": residual |dz/dt| " << num(m.residual.size() ? m.residual.lpNorm<Eigen::Infinity>() : 0.0, 3)
      << " (" << num(m.relative_residual, 3) << " relative); |A| " << num(m.A.size() ? m.A.lpNorm<Eigen::Infinity>() : 0.0, 3)
      << "; " << m.zeros << " zero eigenvalue" << (m.zeros == 1 ? "" : "s") << " (|lambda| <= " << num(m.zero_bound, 2)
      << "); own state " << m.own_states.size() << "\n";
    o << "  A " << method_words(m.a_method) << "\n";
    if (!r.outputs.empty()) o << "  C " << method_words(m.c_method) << "\n";
    o << "  own-coordinate A " << method_words(m.own_method) << "\n";
  }
  if (!r.equilibrium) {
    o << "\nnot an equilibrium: each engine's Jacobian is in the outputs (coordinate-dependent), nothing "
         "compared between engines\n";
  }
  // The modes table: one row per mode of the first engine.
  const EngineLinearModel* ref = nullptr;
  for (const EngineLinearModel& m : r.engines)
    if (m.failure.empty() && r.equilibrium) {
      ref = &m;
      break;
    }
  if (ref) {
    o << "\nmodes (w_n rad/s, zeta) ";
    for (const EngineLinearModel& m : r.engines)
      if (m.failure.empty()) o << " | " << m.label;
    o << "\n";
    int width = 10;
    for (const LinearMode& md : ref->modes) width = std::max(width, static_cast<int>(md.coordinate.size()));
    for (std::size_t k = 0; k < ref->modes.size(); ++k) {
      const LinearMode& md = ref->modes[k];
      char b[400];
      std::snprintf(b, sizeof b, "  %2zu %-*.300s", k + 1, width, md.coordinate.c_str());
      o << b;
      for (const EngineLinearModel& m : r.engines) {
        if (!m.failure.empty()) continue;
        // The matching mode of m: nearest lambda.
        const LinearMode* best = nullptr;
        for (const LinearMode& x : m.modes)
          if (!best || std::abs(x.lambda - md.lambda) < std::abs(best->lambda - md.lambda)) best = &x;
        if (best) {
          std::snprintf(b, sizeof b, " | %.12g %+.3g", best->frequency, best->damping_ratio);
          o << b;
        } else {
          o << " | -";
        }
      }
      o << "  lambda = " << num(md.lambda, 10) << "\n";
    }
  }
  o << "\nchecks:\n";
  int failed = 0;
  for (const LinearCheck& c : r.checks) {
    if (!c.passed) ++failed;
    o << "  " << (c.passed ? "PASS " : "FAIL ") << c.kind << ' ' << c.what << ": " << c.engine_a << ' ' << num(c.a, 12)
      << " vs " << c.engine_b << ' ' << num(c.b, 12) << ", |difference| " << num(c.error, 2) << " (bound "
      << num(c.bound, 2) << ")" << (c.note.empty() ? "" : "; " + c.note) << "\n";
  }
  if (!r.frequencies.empty()) {
    o << "transfer functions at";
    for (double w : r.frequencies) o << ' ' << num(w, 4);
    o << " rad/s\n";
  }
  if (!r.findings.empty()) {
    o << "\nfindings:\n";
    for (const std::string& f : r.findings) o << "  " << f << "\n";
  }
  int engine_failures = 0;
  for (const EngineLinearModel& m : r.engines)
    if (!m.failure.empty()) ++engine_failures;
  o << "\n" << (r.passed() ? "PASS" : "FAIL") << ": " << r.checks.size() << " checks, " << failed << " failed";
  if (engine_failures) o << ", " << engine_failures << " engine(s) failed";
  o << "\n";
  return o.str();
}

namespace {
nlohmann::json matrix_json(const MatrixXd& M) {
  nlohmann::json rows = nlohmann::json::array();
  for (Eigen::Index i = 0; i < M.rows(); ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (Eigen::Index j = 0; j < M.cols(); ++j) row.push_back(M(i, j));
    rows.push_back(row);
  }
  return rows;
}
std::string method_name(const MatrixMethod& how) { return how.exact ? "exact" : "finite differences"; }
nlohmann::json cross_check_json(const MatrixMethod& how) {
  return {{"max_difference", how.fd_difference}, {"differences_error", how.fd_error}};
}
nlohmann::json complex_json(cd v) { return nlohmann::json{{"re", v.real()}, {"im", v.imag()}}; }

std::string csv_matrix(const std::vector<std::string>& header, const MatrixXd& M) {
  std::ostringstream o;
  write_csv_header(o, header);
  for (Eigen::Index i = 0; i < M.rows(); ++i) {
    for (Eigen::Index j = 0; j < M.cols(); ++j) o << (j ? "," : "") << format_value(M(i, j));
    o << "\n";
  }
  return o.str();
}
std::string csv_names(const std::vector<std::string>& names) {
  std::ostringstream o;
  o << "index,name\n";
  for (std::size_t i = 0; i < names.size(); ++i) o << i + 1 << ',' << names[i] << "\n";
  return o.str();
}
}  // namespace

std::string linearization_json(const LinearizeResult& r) {
  nlohmann::json j;
  j["scene"] = r.scene;
  j["time"] = r.time;
  j["operating_point"] = {{"how", r.how}, {"equilibrium", r.equilibrium}};
  j["states"] = r.states;
  j["inputs"] = r.inputs;
  j["outputs"] = r.outputs;
  std::vector<double> z0(r.z0.data(), r.z0.data() + r.z0.size());
  j["z0"] = z0;
  j["engines"] = nlohmann::json::array();
  for (const EngineLinearModel& m : r.engines) {
    nlohmann::json e;
    e["label"] = m.label;
    if (!m.failure.empty()) {
      e["failure"] = m.failure;
      j["engines"].push_back(e);
      continue;
    }
    e["A"] = matrix_json(m.A);
    e["B"] = matrix_json(m.B);
    e["C"] = matrix_json(m.C);
    e["D"] = matrix_json(m.D);
    e["A_error"] = m.a_method.error;
    e["A_method"] = method_name(m.a_method);
    if (m.a_method.exact) e["A_cross_check"] = cross_check_json(m.a_method);
    e["C_error"] = m.c_method.error;
    e["C_method"] = method_name(m.c_method);
    if (m.c_method.exact) e["C_cross_check"] = cross_check_json(m.c_method);
    std::vector<double> res(m.residual.data(), m.residual.data() + m.residual.size());
    e["residual"] = res;
    e["relative_residual"] = m.relative_residual;
    e["eigenvalues"] = nlohmann::json::array();
    for (const cd& l : m.eigenvalues) e["eigenvalues"].push_back(complex_json(l));
    e["zeros"] = m.zeros;
    e["zero_bound"] = m.zero_bound;
    e["modes"] = nlohmann::json::array();
    for (const LinearMode& md : m.modes)
      e["modes"].push_back({{"lambda", complex_json(md.lambda)},
                            {"frequency", md.frequency},
                            {"damping_ratio", md.damping_ratio},
                            {"coordinate", md.coordinate}});
    e["own_coordinates"] = {{"note", "the engine's own state; coordinate-dependent, never compared"},
                            {"states", m.own_states},
                            {"A", matrix_json(m.own_A)},
                            {"A_error", m.own_method.error},
                            {"A_method", method_name(m.own_method)}};
    if (m.own_method.exact) e["own_coordinates"]["A_cross_check"] = cross_check_json(m.own_method);
    j["engines"].push_back(e);
  }
  j["frequencies"] = r.frequencies;
  j["checks"] = nlohmann::json::array();
  for (const LinearCheck& c : r.checks)
    j["checks"].push_back({{"kind", c.kind},
                           {"what", c.what},
                           {"engine_a", c.engine_a},
                           {"engine_b", c.engine_b},
                           {"a", complex_json(c.a)},
                           {"b", complex_json(c.b)},
                           {"error", std::isfinite(c.error) ? nlohmann::json(c.error) : nlohmann::json(nullptr)},
                           {"bound", c.bound},
                           {"passed", c.passed},
                           {"note", c.note}});
  j["findings"] = r.findings;
  j["passed"] = r.passed();
  return j.dump(1) + "\n";
}

std::vector<std::pair<std::string, std::string>> linearization_csv(const LinearizeResult& r) {
  std::vector<std::pair<std::string, std::string>> files;
  files.emplace_back("states.csv", csv_names(r.states));
  files.emplace_back("inputs.csv", csv_names(r.inputs));
  files.emplace_back("outputs.csv", csv_names(r.outputs));
  for (const EngineLinearModel& m : r.engines) {
    // A failed engine's files hold their header row only (the files are opened before the work).
    files.emplace_back(file_safe(m.label + ".A.csv", true), csv_matrix(r.states, m.A));
    files.emplace_back(file_safe(m.label + ".B.csv", true), csv_matrix(r.inputs, m.B));
    files.emplace_back(file_safe(m.label + ".C.csv", true), csv_matrix(r.states, m.C));
    files.emplace_back(file_safe(m.label + ".D.csv", true), csv_matrix(r.inputs, m.D));
    MatrixXd E(static_cast<Eigen::Index>(m.eigenvalues.size()), 2);
    for (std::size_t k = 0; k < m.eigenvalues.size(); ++k) {
      E(static_cast<Eigen::Index>(k), 0) = m.eigenvalues[k].real();
      E(static_cast<Eigen::Index>(k), 1) = m.eigenvalues[k].imag();
    }
    files.emplace_back(file_safe(m.label + ".eigenvalues.csv", true), csv_matrix({"re", "im"}, E));
    files.emplace_back(file_safe(m.label + ".own_A.csv", true), csv_matrix(m.own_states, m.own_A));
  }
  return files;
}

}  // namespace crossdyn::harness

namespace crossdyn::harness {

std::string mode_geometry(const System& system, const LinearizeOptions& o, const LinearizeResult& r,
                          std::size_t engine, std::size_t mode) {
  const EngineLinearModel& m = r.engines.at(engine);
  const LinearMode& md = m.modes.at(mode);
  const ReducedMap map(system, r.op, r.time);
  const int nc = map.configuration_size();
  double largest = 0;
  for (int i = 0; i < nc; ++i) largest = std::max(largest, std::abs(md.shape(i)));
  if (!(largest > 1e-9 * md.shape.norm())) return "";
  const double a = 0.35 / largest;
  const LinearEngineChoice& choice = o.engines.at(engine);
  const std::unique_ptr<Engine> e = choice.make(system);
  std::vector<double> x(static_cast<std::size_t>(e->state_size())), row(e->columns().size());
  auto configuration = [&](const VectorXd& z, double t) {
    e->pack(map.state(z), x.data());
    e->output_row(o.time, x.data(), row.data());
    geometry::Configuration c = geometry::configuration_from_row(system, e->columns(), row.data());
    c.t = t;
    return c;
  };
  const double step = md.lambda.imag() != 0 ? 0.5 * std::numbers::pi / std::abs(md.lambda.imag()) : 0.5 / std::abs(md.lambda.real());
  std::vector<geometry::Configuration> frames;
  for (int k = 0; k < 4; ++k) {
    const double t = k * step;
    const VectorXd dz = (a * md.shape * std::exp(md.lambda * t)).real();
    frames.push_back(configuration(r.z0 + dz, t));
  }
  geometry::MotionSource source;
  source.engine = m.label;
  source.state = "ok";
  source.note = "mode " + std::to_string(mode + 1) + " (" + md.coordinate + ")";
  source.duration = 3 * step;
  return geometry::geometry_json(system, configuration(r.z0, 0.0), frames, source, {});
}

}  // namespace crossdyn::harness
