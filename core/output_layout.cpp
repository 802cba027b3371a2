// The output layout (see output_layout.hpp).
#include "core/output_layout.hpp"

#include "core/orbit.hpp"

#include <limits>

namespace crossdyn {

int OutputLayout::push(Column c) {
  names_.push_back(c.name);
  columns_.push_back(std::move(c));
  return static_cast<int>(columns_.size()) - 1;
}

OutputLayout::OutputLayout(const System& s)
    : body_w_(s.bodies.size(), -1), joint_(s.joints.size(), -1), modal_(s.bodies.size(), -1),
      body_p_(s.bodies.size(), -1), load_(s.joints.size(), -1) {
  push({"t", ColumnKind::Time, -1, -1, -1, "s"});
  for (std::size_t b = 0; b < s.bodies.size(); ++b) {
    const int bi = static_cast<int>(b);
    const std::string& n = s.bodies[b].name;
    body_w_[b] = static_cast<int>(columns_.size());
    for (int i = 0; i < 3; ++i)
      push({n + ".w" + "xyz"[i], ColumnKind::BodyW, bi, -1, i, "rad/s"});
    for (int i = 0; i < 4; ++i) push({n + ".q" + "wxyz"[i], ColumnKind::BodyQ, bi, -1, i, ""});
  }
  for (std::size_t j = 0; j < s.joints.size(); ++j) {
    const int ji = static_cast<int>(j);
    const Joint& J = s.joints[j];
    if (J.type == JointType::Revolute) {
      joint_[j] = static_cast<int>(columns_.size());
      push({J.name + ".angle", ColumnKind::JointCoordinate, J.child, ji, 0, "rad"});
      push({J.name + ".rate", ColumnKind::JointRate, J.child, ji, 0, "rad/s"});
      if (J.prescribed) push({J.name + ".torque", ColumnKind::JointTorque, J.child, ji, 0, "N m"});
    } else if (J.type == JointType::Prismatic) {
      joint_[j] = static_cast<int>(columns_.size());
      push({J.name + ".position", ColumnKind::JointCoordinate, J.child, ji, 0, "m"});
      push({J.name + ".rate", ColumnKind::JointRate, J.child, ji, 0, "m/s"});
      if (J.prescribed) push({J.name + ".force", ColumnKind::JointTorque, J.child, ji, 0, "N"});
    } else if (J.type == JointType::Universal) {
      joint_[j] = static_cast<int>(columns_.size());
      for (int i = 0; i < 2; ++i)
        push({J.name + ".angle" + "12"[i], ColumnKind::JointCoordinate, J.child, ji, i, "rad"});
      for (int i = 0; i < 2; ++i)
        push({J.name + ".rate" + "12"[i], ColumnKind::JointRate, J.child, ji, i, "rad/s"});
    } else if (J.type == JointType::Spherical) {
      joint_[j] = static_cast<int>(columns_.size());
      for (int i = 0; i < 3; ++i)
        push({J.name + ".w" + "xyz"[i], ColumnKind::SphericalW, J.child, ji, i, "rad/s"});
    }
  }
  for (std::size_t b = 0; b < s.bodies.size(); ++b) {
    const Body& B = s.bodies[b];
    if (!B.flex) continue;
    const int bi = static_cast<int>(b);
    modal_[b] = static_cast<int>(columns_.size());
    const auto& modes = B.flex->mode_names;
    for (std::size_t k = 0; k < modes.size(); ++k)
      push({B.name + "." + modes[k], ColumnKind::Modal, bi, -1, static_cast<int>(k), "m"});
    for (std::size_t k = 0; k < modes.size(); ++k)
      push({B.name + "." + modes[k] + "_rate", ColumnKind::ModalRate, bi, -1,
            static_cast<int>(k), "m/s"});
  }
  H_ = push({"H", ColumnKind::MomentumH, -1, -1, -1, "kg m^2/s"});
  E_ = push({"E", ColumnKind::EnergyE, -1, -1, -1, "J"});
  // Issue 26: positions, the momentum vector, joint loads, power and external moment. After E, so
  // that the columns above keep their places.
  for (std::size_t b = 0; b < s.bodies.size(); ++b) {
    body_p_[b] = static_cast<int>(columns_.size());
    for (int i = 0; i < 3; ++i)
      push({s.bodies[b].name + "." + "xyz"[i], ColumnKind::BodyPosition, static_cast<int>(b), -1, i, "m"});
  }
  cm_ = static_cast<int>(columns_.size());
  for (int i = 0; i < 3; ++i) push({std::string("CM") + "xyz"[i], ColumnKind::SystemCM, -1, -1, i, "m"});
  Hv_ = static_cast<int>(columns_.size());
  for (int i = 0; i < 3; ++i)
    push({std::string("H") + "xyz"[i], ColumnKind::MomentumVector, -1, -1, i, "kg m^2/s"});
  for (std::size_t j = 0; j < s.joints.size(); ++j) {
    const Joint& J = s.joints[j];
    if (J.type == JointType::Free) continue;
    const int ji = static_cast<int>(j);
    load_[j] = static_cast<int>(columns_.size());
    for (int i = 0; i < 3; ++i)
      push({J.name + ".F" + "xyz"[i], ColumnKind::JointForce, J.child, ji, i, "N"});
    for (int i = 0; i < 3; ++i)
      push({J.name + ".M" + "xyz"[i], ColumnKind::JointMoment, J.child, ji, i, "N m"});
  }
  P_ = push({"P", ColumnKind::Power, -1, -1, -1, "W"});
  M_ = static_cast<int>(columns_.size());
  for (int i = 0; i < 3; ++i)
    push({std::string("M") + "xyz"[i], ColumnKind::ExternalMoment, -1, -1, i, "N m"});
  // Issue 28: the attitude relative to the orbit frame and the Jacobi integral, on an orbit only.
  environment_ = s.environment;
  if (s.environment.orbit()) {
    lvlh_.assign(s.bodies.size(), -1);
    static const char* const kAngles[3] = {".roll", ".pitch", ".yaw"};
    for (std::size_t b = 0; b < s.bodies.size(); ++b) {
      lvlh_[b] = static_cast<int>(columns_.size());
      for (int i = 0; i < 3; ++i)
        push({s.bodies[b].name + kAngles[i], ColumnKind::LvlhAngle, static_cast<int>(b), -1, i, "rad"});
      for (int i = 0; i < 3; ++i)
        push({s.bodies[b].name + ".wo" + "xyz"[i], ColumnKind::LvlhRate, static_cast<int>(b), -1, i, "rad/s"});
    }
    J_ = push({"J", ColumnKind::Jacobi, -1, -1, -1, "J"});
  }
  pinned_ = columns_.size();
}

int OutputLayout::add_extra(std::string name, std::string unit) {
  return push({std::move(name), ColumnKind::Extra, -1, -1, -1, std::move(unit)});
}

RowWriter::RowWriter(const OutputLayout& layout, double* row) : layout_(layout), row_(row) {
  for (std::size_t i = 0; i < layout.size(); ++i) row_[i] = std::numeric_limits<double>::quiet_NaN();
}

void RowWriter::body(int b, const Eigen::Vector3d& w_NB_B, const Eigen::Quaterniond& q_NB) {
  double* w = row_ + layout_.body_w(b);
  for (int i = 0; i < 3; ++i) w[i] = w_NB_B(i);
  // q and -q are the same attitude: write the one with qw >= 0.
  const double s = q_NB.w() < 0 ? -1.0 : 1.0;
  w[3] = s * q_NB.w();
  w[4] = s * q_NB.x();
  w[5] = s * q_NB.y();
  w[6] = s * q_NB.z();
  if (layout_.lvlh(b) >= 0) {
    // R_OB = R_NO^T R_NB at the row's time (core/orbit.hpp).
    const OrbitFrame o = orbit_frame(layout_.environment(), row_[0]);
    const Eigen::Matrix3d R_NB = q_NB.toRotationMatrix();
    const Eigen::Vector3d a = roll_pitch_yaw(o.R_NO.transpose() * R_NB);
    const Eigen::Vector3d w_OB_B = w_NB_B - R_NB.transpose() * o.w_NO_N;
    for (int i = 0; i < 3; ++i) {
      row_[layout_.lvlh(b) + i] = a(i);
      row_[layout_.lvlh(b) + 3 + i] = w_OB_B(i);
    }
  }
}

void RowWriter::revolute(int joint, double angle, double rate) {
  double* r = row_ + layout_.joint_first(joint);
  r[0] = angle;
  r[1] = rate;
}

void RowWriter::joint_torque(int joint, double torque) {
  row_[layout_.joint_first(joint) + 2] = torque;
}

void RowWriter::spherical(int joint, const Eigen::Vector3d& w_PC_C) {
  double* r = row_ + layout_.joint_first(joint);
  for (int i = 0; i < 3; ++i) r[i] = w_PC_C(i);
}

void RowWriter::prismatic(int joint, double position, double rate) {
  double* r = row_ + layout_.joint_first(joint);
  r[0] = position;
  r[1] = rate;
}

void RowWriter::universal(int joint, double angle1, double angle2, double rate1, double rate2) {
  double* r = row_ + layout_.joint_first(joint);
  r[0] = angle1;
  r[1] = angle2;
  r[2] = rate1;
  r[3] = rate2;
}

void RowWriter::modal(int b, const Eigen::Ref<const Eigen::VectorXd>& eta,
                      const Eigen::Ref<const Eigen::VectorXd>& eta_rate) {
  double* r = row_ + layout_.modal_first(b);
  const Eigen::Index n = eta.size();
  for (Eigen::Index k = 0; k < n; ++k) r[k] = eta(k);
  for (Eigen::Index k = 0; k < n; ++k) r[n + k] = eta_rate(k);
}

void RowWriter::momentum(const Eigen::Vector3d& H_Scm_N) {
  row_[layout_.H()] = H_Scm_N.norm();
  for (int i = 0; i < 3; ++i) row_[layout_.H_vector() + i] = H_Scm_N(i);
}

void RowWriter::body_position(int b, const Eigen::Vector3d& p_NoBo_N) {
  for (int i = 0; i < 3; ++i) row_[layout_.body_position(b) + i] = p_NoBo_N(i);
}

void RowWriter::system_cm(const Eigen::Vector3d& p_NoScm_N) {
  for (int i = 0; i < 3; ++i) row_[layout_.cm() + i] = p_NoScm_N(i);
}

void RowWriter::joint_load(int joint, const Eigen::Vector3d& F_C, const Eigen::Vector3d& M_J_C) {
  double* r = row_ + layout_.joint_load(joint);
  for (int i = 0; i < 3; ++i) {
    r[i] = F_C(i);
    r[3 + i] = M_J_C(i);
  }
}

void RowWriter::external_moment(const Eigen::Vector3d& M_Scm_N) {
  for (int i = 0; i < 3; ++i) row_[layout_.external_moment() + i] = M_Scm_N(i);
}

std::vector<std::string> pinned_columns(const System& system) { return OutputLayout(system).names(); }

}  // namespace crossdyn
