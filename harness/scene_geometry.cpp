// Drawing geometry of a scene (see scene_geometry.hpp). Drawing code only: no engine uses it.
#include "harness/scene_geometry.hpp"
#include "harness/scene_warnings.hpp"

#include "core/engine.hpp"
#include "core/orbit.hpp"
#include "core/errors.hpp"
#include "core/scene/schema.hpp"
#include "core/rotation.hpp"

#include <Eigen/Eigenvalues>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>

namespace crossdyn::harness::geometry {

using json = nlohmann::ordered_json;
using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

EquivalentBox equivalent_box(const Body& body) {
  EquivalentBox box;
  const Matrix3d& I = body.I_BBo_B;
  const bool diagonal = I(0, 1) == 0 && I(0, 2) == 0 && I(1, 2) == 0 && I(1, 0) == 0 &&
                        I(2, 0) == 0 && I(2, 1) == 0;
  if (diagonal) {
    box.principal_moments = I.diagonal();
  } else {
    // Principal axes (eigenvectors), then ordered and signed to lie closest to the body axes so
    // that the box's x' is the body's x where it can be.
    const Eigen::SelfAdjointEigenSolver<Matrix3d> eig(0.5 * (I + I.transpose()));
    const Matrix3d V = eig.eigenvectors();
    std::array<int, 3> take{-1, -1, -1};
    std::array<bool, 3> used{false, false, false};
    for (int axis = 0; axis < 3; ++axis) {
      int best = -1;
      for (int k = 0; k < 3; ++k)
        if (!used[k] && (best < 0 || std::abs(V(axis, k)) > std::abs(V(axis, best)))) best = k;
      take[axis] = best;
      used[best] = true;
    }
    for (int axis = 0; axis < 3; ++axis) {
      Vector3d v = V.col(take[axis]);
      if (v(axis) < 0) v = -v;
      box.R_BX.col(axis) = v;
      box.principal_moments(axis) = eig.eigenvalues()(take[axis]);
    }
    if (box.R_BX.determinant() < 0) box.R_BX.col(2) = -box.R_BX.col(2);
  }
  const Vector3d& J = box.principal_moments;
  for (int i = 0; i < 3; ++i) {
    const double s2 = 6.0 * (J((i + 1) % 3) + J((i + 2) % 3) - J(i)) / body.mass;
    box.size_m(i) = std::sqrt(std::max(0.0, s2));
  }
  return box;
}

Matrix3d joint_rotation(const Joint& joint, double angle, const Quaterniond& q_J, double angle2) {
  const Matrix3d R_PJ0 = joint.q_PJ0.normalized().toRotationMatrix();
  switch (joint.type) {
    case JointType::Free: return Matrix3d::Identity();
    case JointType::Revolute:
      // R_PC = R_PJ0 Rot(axis_J, angle), axis_J = R_PJ0^T axis_P (core/system.hpp).
      return R_PJ0 * Eigen::AngleAxisd(angle, R_PJ0.transpose() * joint.axis_P.normalized()).toRotationMatrix();
    case JointType::Spherical: return R_PJ0 * q_J.normalized().toRotationMatrix();
    case JointType::Fixed:
    case JointType::Prismatic: return R_PJ0;
    case JointType::Universal:
      // R_PC = Rot(axis_P, angle1) Rot(axis2_P, angle2) R_PJ0 (core/system.hpp).
      return Eigen::AngleAxisd(angle, joint.axis_P.normalized()).toRotationMatrix() *
             Eigen::AngleAxisd(angle2, joint.axis2_P.normalized()).toRotationMatrix() * R_PJ0;
  }
  return Matrix3d::Identity();
}

Vector3d revolute_axis_in_child(const Joint& joint) {
  return joint.q_PJ0.normalized().toRotationMatrix().transpose() * joint.axis_P.normalized();
}

namespace {

// A node's displacement u = Phi eta and turn exp([psi x]), psi = Psi eta (core/system.hpp
// FlexBody); zero and identity for a rigid attachment or an undeformed body.
struct NodeMotion {
  Vector3d u = Vector3d::Zero();
  Matrix3d turn = Matrix3d::Identity();
};
NodeMotion node_motion(const Body& body, int node, const ModalCoordinates& eta, std::size_t b) {
  NodeMotion m;
  if (node < 0 || !body.flex || b >= eta.size() || eta[b].size() == 0) return m;
  const FlexNode& n = body.flex->nodes.at(static_cast<std::size_t>(node));
  if (n.Phi_B.cols() == eta[b].size()) m.u = n.Phi_B * eta[b];
  if (n.Psi_B.cols() == eta[b].size()) {
    const Vector3d psi = n.Psi_B * eta[b];
    if (psi.norm() > 0) m.turn = Eigen::AngleAxisd(psi.norm(), psi.normalized()).toRotationMatrix();
  }
  return m;
}

}  // namespace

Configuration place_bodies(const System& system, const std::vector<Matrix3d>& R_NB,
                           const Vector3d& p_NoBo_N_base, double t, const ModalCoordinates& eta,
                           const std::vector<double>& slide_m) {
  Configuration c;
  c.t = t;
  c.bodies.resize(system.bodies.size());
  c.joints.resize(system.joints.size());
  c.nodes_N.resize(system.bodies.size());
  for (std::size_t b = 0; b < system.bodies.size(); ++b) c.bodies[b].R_NB = R_NB.at(b);
  // Joints are in tree order (core/system.hpp): every parent is placed before its children.
  for (std::size_t j = 0; j < system.joints.size(); ++j) {
    const Joint& J = system.joints[j];
    BodyPose& C = c.bodies[J.child];
    JointPose& out = c.joints[j];
    if (J.type == JointType::Free) {
      C.p_NoBo_N = p_NoBo_N_base;
      out.p_NoJ_N_parent = out.p_NoJ_N_child = C.p_NoBo_N;
      continue;
    }
    if (J.parent < 0) {
      // A prescribed base (docs/prescribed-motion.md): the joint point and axis are fixed in N.
      C.p_NoBo_N = p_NoBo_N_base;
      const NodeMotion mc = node_motion(system.bodies[J.child], J.child_node, eta, J.child);
      out.p_NoJ_N_parent = J.p_PoJ_P;
      out.p_NoJ_N_child = C.p_NoBo_N + C.R_NB * (J.p_CoJ_C + mc.u);
      out.axis_N_parent = J.axis_P.normalized();
      out.axis_N_child = C.R_NB * mc.turn * revolute_axis_in_child(J);
      const Matrix3d R_NJ0 = J.q_PJ0.normalized().toRotationMatrix();
      out.phi_J = rot::rotation_vector(Quaterniond(R_NJ0.transpose() * C.R_NB * mc.turn));
      continue;
    }
    const BodyPose& P = c.bodies[J.parent];
    const NodeMotion mp = node_motion(system.bodies[J.parent], J.parent_node, eta, J.parent);
    const NodeMotion mc = node_motion(system.bodies[J.child], J.child_node, eta, J.child);
    // A prismatic joint's point on the parent side slides along the axis with the child (core/
    // system.hpp): p_PoJ_P + s axis_P.
    const double s_m = J.type == JointType::Prismatic && j < slide_m.size() ? slide_m[j] : 0.0;
    out.p_NoJ_N_parent = P.p_NoBo_N + P.R_NB * (J.p_PoJ_P + mp.u + s_m * J.axis_P.normalized());
    // p_NoCo_N = p_NoPo_N + R_NP (p_PoJ_P + u_P) - R_NC (p_CoJ_C + u_C)
    C.p_NoBo_N = out.p_NoJ_N_parent - C.R_NB * (J.p_CoJ_C + mc.u);
    out.p_NoJ_N_child = C.p_NoBo_N + C.R_NB * (J.p_CoJ_C + mc.u);
    // R_PC = exp([psi_P x]) R_PJ0 R_J exp([psi_C x])^T, so R_J = R_PJ0^T exp(psi_P)^T R_NP^T R_NC exp(psi_C).
    const Matrix3d R_PJ0 = J.q_PJ0.normalized().toRotationMatrix();
    const Matrix3d R_J = R_PJ0.transpose() * mp.turn.transpose() * P.R_NB.transpose() * C.R_NB * mc.turn;
    out.phi_J = rot::rotation_vector(Quaterniond(R_J));
    if (J.type == JointType::Revolute) {
      out.axis_N_parent = P.R_NB * mp.turn * J.axis_P.normalized();
      out.axis_N_child = C.R_NB * mc.turn * revolute_axis_in_child(J);
    }
    if (J.type == JointType::Prismatic) out.slide_N = P.R_NB * mp.turn * J.axis_P.normalized();
    if (J.type == JointType::Universal) {
      out.gimbal1_N = P.R_NB * mp.turn * J.axis_P.normalized();
      out.gimbal2_N = C.R_NB * mc.turn * R_PJ0.transpose() * J.axis2_P.normalized();
    }
  }
  double mass = 0;
  c.p_NoScm_N.setZero();
  for (std::size_t b = 0; b < system.bodies.size(); ++b) {
    const Body& B = system.bodies[b];
    mass += B.mass;
    c.p_NoScm_N += B.mass * c.bodies[b].p_NoBo_N;
    if (!B.flex) continue;
    for (std::size_t k = 0; k < B.flex->nodes.size(); ++k)
      c.nodes_N[b].push_back(c.bodies[b].p_NoBo_N +
                             c.bodies[b].R_NB * (B.flex->nodes[k].p_BoNi_B +
                                                 node_motion(B, static_cast<int>(k), eta, b).u));
  }
  if (mass > 0) c.p_NoScm_N /= mass;
  return c;
}

Configuration initial_configuration(const System& system) {
  std::vector<Matrix3d> R_NB(system.bodies.size(), Matrix3d::Identity());
  Vector3d p_base = Vector3d::Zero();
  const TreeState s0 = TreeState::initial(system);  // a prescribed base's pose at t = 0
  std::vector<double> slide_m(system.joints.size(), 0.0);
  for (std::size_t j = 0; j < system.joints.size(); ++j) slide_m[j] = s0.joints[j].angle;
  for (const Joint& J : system.joints) {
    if (J.type == JointType::Free || J.parent < 0) {
      R_NB[J.child] = s0.q_NB.normalized().toRotationMatrix();
      p_base = s0.p_NoBo_N;
    } else {
      // R_NC = R_NP R_PC (parents come first in tree order).
      R_NB[J.child] = R_NB[J.parent] * joint_rotation(J, J.angle0, J.q_J0, J.angle2_0);
    }
  }
  return place_bodies(system, R_NB, p_base, 0.0, {}, slide_m);
}

void center_at_origin(Configuration& c) {
  const Vector3d shift = c.p_NoScm_N;
  for (BodyPose& b : c.bodies) b.p_NoBo_N -= shift;
  for (std::vector<Vector3d>& nodes : c.nodes_N)
    for (Vector3d& p : nodes) p -= shift;
  for (JointPose& j : c.joints) {
    j.p_NoJ_N_parent -= shift;
    j.p_NoJ_N_child -= shift;
  }
  c.p_NoScm_N.setZero();
}

namespace {
const char* const kQuaternionColumns[] = {".qw", ".qx", ".qy", ".qz"};  // looked up in this order
}  // namespace

Configuration configuration_from_row(const System& system, const std::vector<std::string>& columns,
                                     const double* row) {
  auto column = [&columns](const std::string& name) {
    const auto it = std::find(columns.begin(), columns.end(), name);
    if (it == columns.end()) throw InputError("the run has no column '" + name + "' to draw from");
    return static_cast<std::size_t>(it - columns.begin());
  };
  std::vector<Matrix3d> R_NB;
  for (const Body& b : system.bodies) {
    std::array<double, 4> wxyz{};
    for (int k = 0; k < 4; ++k) wxyz[k] = row[column(b.name + kQuaternionColumns[k])];
    const Quaterniond q(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
    R_NB.push_back(q.normalized().toRotationMatrix());
  }
  ModalCoordinates eta(system.bodies.size());
  for (std::size_t b = 0; b < system.bodies.size(); ++b) {
    const Body& B = system.bodies[b];
    if (!B.flex) continue;
    eta[b].resize(B.flex->modes());
    for (int k = 0; k < B.flex->modes(); ++k) eta[b](k) = row[column(B.name + "." + B.flex->mode_names[static_cast<std::size_t>(k)])];
  }
  std::vector<double> slide_m(system.joints.size(), 0.0);
  for (std::size_t j = 0; j < system.joints.size(); ++j)
    if (system.joints[j].type == JointType::Prismatic)
      slide_m[j] = row[column(system.joints[j].name + ".position")];
  Configuration c = place_bodies(system, R_NB, Vector3d::Zero(), row[column("t")], eta, slide_m);
  center_at_origin(c);
  return c;
}

FramePicker::FramePicker(std::vector<std::string> columns, double duration, int panels)
    : columns_(std::move(columns)) {
  const auto it = std::find(columns_.begin(), columns_.end(), "t");
  if (it == columns_.end()) throw InputError("the run has no column 't' to draw from");
  t_col_ = static_cast<std::size_t>(it - columns_.begin());
  for (int k = 0; k < panels; ++k) want_.push_back(panels == 1 ? 0.0 : duration * k / (panels - 1));
  best_.resize(want_.size());
}

void FramePicker::add(const double* row) {
  const double t = row[t_col_];
  if (rows_ == 1) step_ = t - last_t_;
  last_t_ = t;
  ++rows_;
  for (std::size_t k = 0; k < want_.size(); ++k)
    if (best_[k].empty() || std::abs(t - want_[k]) < std::abs(best_[k][t_col_] - want_[k]))
      best_[k].assign(row, row + columns_.size());
}

std::vector<Configuration> FramePicker::frames(const System& system) const {
  std::vector<Configuration> out;
  double previous = -1;
  for (std::size_t k = 0; k < want_.size(); ++k) {
    if (best_[k].empty() || want_[k] > last_t_ + 0.5 * step_) break;  // the run ended before
    const double t = best_[k][t_col_];
    if (!out.empty() && t == previous) continue;  // two wanted times on one row
    previous = t;
    out.push_back(configuration_from_row(system, columns_, best_[k].data()));
  }
  return out;
}

std::vector<Configuration> motion_frames(const System& system, const std::vector<std::string>& columns,
                                         const std::vector<double>& data, double duration, int panels) {
  FramePicker picker(columns, duration, panels);
  const std::size_t width = columns.size();
  for (std::size_t r = 0; width && (r + 1) * width <= data.size(); ++r) picker.add(data.data() + r * width);
  return picker.frames(system);
}

namespace {

json vec(const Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }
json mat(const Matrix3d& m) {
  json a = json::array();
  for (int i = 0; i < 3; ++i) a.push_back(json::array({m(i, 0), m(i, 1), m(i, 2)}));
  return a;
}

json configuration_json(const Configuration& c, bool centred) {
  json bodies = json::array();
  for (std::size_t i = 0; i < c.bodies.size(); ++i) {
    json b = {{"p_NoBo_N", vec(c.bodies[i].p_NoBo_N)}, {"R_NB", mat(c.bodies[i].R_NB)}};
    if (i < c.nodes_N.size() && !c.nodes_N[i].empty()) {
      json nodes = json::array();
      for (const Vector3d& p : c.nodes_N[i]) nodes.push_back(vec(p));
      b["nodes_N"] = nodes;
    }
    bodies.push_back(b);
  }
  json joints = json::array();
  for (const JointPose& j : c.joints) {
    const double cos_mismatch = j.axis_N_parent.dot(j.axis_N_child);
    json extra = json::object();
    if (!j.slide_N.isZero()) extra["slide_N"] = vec(j.slide_N);
    if (!j.gimbal1_N.isZero()) extra["gimbal_axes_N"] = {vec(j.gimbal1_N), vec(j.gimbal2_N)};
    joints.push_back({{"p_NoJ_N_parent", vec(j.p_NoJ_N_parent)},
                      {"p_NoJ_N_child", vec(j.p_NoJ_N_child)},
                      {"gap_m", (j.p_NoJ_N_parent - j.p_NoJ_N_child).norm()},
                      {"axis_N_parent", vec(j.axis_N_parent)},
                      {"axis_N_child", vec(j.axis_N_child)},
                      {"axis_mismatch_rad", j.axis_N_parent.isZero()
                                                ? 0.0
                                                : std::atan2(j.axis_N_parent.cross(j.axis_N_child).norm(),
                                                             cos_mismatch)},
                      {"phi_J_rad", vec(j.phi_J)}});
    joints.back().update(extra);
  }
  return {{"t", c.t}, {"centred_at_cm", centred}, {"p_NoScm_N", vec(c.p_NoScm_N)},
          {"bodies", bodies}, {"joints", joints}};
}

}  // namespace

std::string geometry_json(const System& system, const Configuration& initial,
                          const std::vector<Configuration>& motion, const MotionSource& source,
                          const std::vector<SceneWarning>& warnings) {
  json bodies = json::array();
  const int base = system.base_body();
  for (std::size_t b = 0; b < system.bodies.size(); ++b) {
    const Body& B = system.bodies[b];
    const EquivalentBox box = equivalent_box(B);
    json nodes = json::array();
    if (B.flex)
      for (std::size_t k = 0; k < B.flex->nodes.size(); ++k)
        nodes.push_back({{"name", B.flex->nodes[k].name}, {"p_BoN_B", vec(B.flex->nodes[k].p_BoNi_B)}});
    bodies.push_back({{"name", B.name},
                      {"mass_kg", B.mass},
                      {"is_base", static_cast<int>(b) == base},
                      {"flexible", B.flex.has_value()},
                      {"shape", {{"type", "box"},
                                 {"what", "equivalent-inertia box: the uniform box with the body's "
                                          "mass and principal moments, centred at its CM"},
                                 {"R_BX", mat(box.R_BX)},
                                 {"size_m", vec(box.size_m)},
                                 {"principal_moments_kg_m2", vec(box.principal_moments)}}},
                      {"nodes", nodes}});
  }
  json joints = json::array();
  for (const Joint& J : system.joints) {
    json j = {{"name", J.name},
              {"type", std::string(scene::joint_type(J.type).name)},
              {"dof", J.dof()},
              {"prescribed", J.prescribed.has_value()},
              {"parent", J.parent},
              {"child", J.child},
              {"parent_node", J.parent_node},
              {"child_node", J.child_node},
              {"parent_point_P_m", vec(J.p_PoJ_P)},
              {"child_point_C_m", vec(J.p_CoJ_C)},
              {"R_PJ0", mat(J.q_PJ0.normalized().toRotationMatrix())},
              {"has_offset", !J.q_PJ0.normalized().toRotationMatrix().isIdentity(1e-15)}};
    if (J.type == JointType::Revolute) {
      j["axis_P"] = vec(J.axis_P.normalized());
      j["axis_C"] = vec(revolute_axis_in_child(J));
      j["initial_angle_rad"] = J.angle0;
      j["initial_rate_rad_s"] = J.rate0;
    }
    if (J.type == JointType::Prismatic) {
      j["slide_axis_P"] = vec(J.axis_P.normalized());
      j["initial_position_m"] = J.angle0;
      j["initial_rate_m_s"] = J.rate0;
    }
    if (J.type == JointType::Universal) {
      j["gimbal_axes_P"] = {vec(J.axis_P.normalized()), vec(J.axis2_P.normalized())};
      j["initial_angles_rad"] = {J.angle0, J.angle2_0};
      j["initial_rates_rad_s"] = {J.rate0, J.rate2_0};
    }
    if (J.type == JointType::Free) j["initial_w_NB_B_rad_s"] = vec(J.w_NB_B0);
    joints.push_back(j);
  }
  // On an orbit: the orbit frame O (LVLH; core/orbit.hpp) at each configuration's time, so that
  // the picture shows where nadir and the along-track direction are (a gravity-gradient scene's
  // attitude is set relative to them).
  const bool orbit = system.environment.orbit();
  const auto with_orbit = [&](json j, double t) {
    if (orbit) j["R_NO"] = mat(orbit_frame(system.environment, t).R_NO);
    return j;
  };
  json frames = json::array();
  for (const Configuration& c : motion) frames.push_back(with_orbit(configuration_json(c, true), c.t));
  json doc = {
      {"format", "crossdyn scene geometry"},
      {"version", 1},
      {"scene", system.name},
      {"file", system.file},
      {"conventions",
       json::array({"N: the inertial frame; its axes x, y, z are drawn at its origin",
                    "body frames: origin at the body's CM; axes x red, y green, z blue",
                    "each body is drawn as its equivalent-inertia box (same mass and principal "
                    "moments, along the principal axes)",
                    "joint point J: parent side p_NoPo_N + R_NP parent_point, child side "
                    "p_NoCo_N + R_NC child_point; the two must coincide",
                    "revolute: R_PC = R_offset Rot(axis_J, angle), axis_J = R_offset^T axis_P; the "
                    "arc shows where the child's CM goes for a positive angle (right-hand rule)",
                    "spherical: R_PC = R_offset R(q_J)"})},
      {"bodies", bodies},
      {"joints", joints},
      {"warnings", warnings_json(warnings)},
      {"initial", with_orbit(configuration_json(initial, false), initial.t)},
      {"motion", {{"engine", source.engine},
                  {"state", source.state},
                  {"note", source.note},
                  {"duration_s", source.duration},
                  {"frames", frames}}}};
  if (orbit)
    doc["orbit"] = {{"what", "O: the orbit frame (LVLH): o1 along-track, o2 the negative orbit normal, "
                             "o3 nadir; each configuration's R_NO (columns o1 o2 o3 in N), drawn at the "
                             "base's CM"}};
  return doc.dump(1) + "\n";
}

}  // namespace crossdyn::harness::geometry
