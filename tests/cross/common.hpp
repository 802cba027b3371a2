// Shared pieces of the cross-engine tests: random engine-neutral states and run helpers.
#pragma once

#include "core/engine.hpp"
#include "harness/engines.hpp"
#include "core/integrate.hpp"
#include "core/scene/scene.hpp"
#include "tests/support/paths.hpp"

#include <map>
#include <random>

namespace crossdyn::test {

// The pinned rigid scenes every engine must agree on (docs/scenarios.md).
inline const std::vector<std::string>& pinned_rigid_scenes() {
  static const std::vector<std::string> s{"spear1_case1", "spear1_case2", "spear1_case1_spherical",
                                          "chain5"};
  return s;
}

inline Eigen::Quaterniond random_quaternion(std::mt19937& g) {
  std::normal_distribution<double> n;
  return Eigen::Quaterniond(n(g), n(g), n(g), n(g)).normalized();
}

// A random state of the scene's tree: any attitude, rates of the order of the scene's own.
inline TreeState random_state(const System& system, std::mt19937& g) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&](double scale) -> Eigen::Vector3d { return Eigen::Vector3d(u(g), u(g), u(g)) * scale; };
  TreeState s = TreeState::initial(system);
  s.p_NoBo_N = vec(5.0);
  s.q_NB = random_quaternion(g);
  s.v_NBo_N = vec(1.0);
  s.w_NB_B = vec(2.0);
  for (std::size_t j = 0; j < system.joints.size(); ++j) {
    s.joints[j].angle = 3.0 * u(g);
    s.joints[j].rate = 2.0 * u(g);
    s.joints[j].q_J = random_quaternion(g);
    s.joints[j].w_PC_C = vec(1.0);
  }
  return s;
}

// A state consistent with the prescribed motion at time t: a prescribed joint's angle (position)
// and rate, and a prescribed (rigidly attached) base's pose and velocity, as the profile gives
// them at t (docs/prescribed-motion.md). Engines that keep every body's pose in their state
// (newton-euler) take the prescribed coordinates from the TreeState; the others from the profile.
inline void follow_profile(const System& system, TreeState& s, double t) {
  for (std::size_t j = 0; j < system.joints.size(); ++j) {
    const Joint& J = system.joints[j];
    if (!J.prescribed) continue;
    s.joints[j].angle = J.angle0 + J.prescribed->angle(t);
    s.joints[j].rate = J.prescribed->velocity(t);
    if (j == 0) s.place_prescribed_base(J, s.joints[j].angle, s.joints[j].rate);
  }
}

// random_state with small modal coordinates and rates (0.05) and the prescribed joints on their
// profiles at t.
inline TreeState random_tree_state(const System& system, std::mt19937& g, double t) {
  TreeState s = random_state(system, g);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (std::size_t b = 0; b < system.bodies.size(); ++b) {
    for (int k = 0; k < s.eta[b].size(); ++k) s.eta[b](k) = 0.05 * u(g);
    for (int k = 0; k < s.eta_rate[b].size(); ++k) s.eta_rate[b](k) = 0.05 * u(g);
  }
  follow_profile(system, s, t);
  return s;
}

// One engine at (t, s): its engine-neutral accelerations and its output row.
struct EngineAt {
  TreeAccel accel;
  std::vector<double> row;
};
inline EngineAt evaluate(Engine& e, const TreeState& s, double t) {
  std::vector<double> x(static_cast<std::size_t>(e.state_size()));
  e.pack(s, x.data());
  EngineAt at;
  e.accelerations(t, x.data(), at.accel);
  at.row.resize(e.layout().size());
  e.output_row(t, x.data(), at.row.data());
  return at;
}

// Issue 26's columns (core/output_layout.hpp) are judged against the size of what they belong to,
// not each component's own largest value: a joint's six load components together (an unloaded
// axis carries a moment at rounding level, 1e-14 N m, against which no difference means anything),
// a body's position, the CM, H and M as vectors (against 1 m and the momentum's size), P alone.
// "" for the other pinned columns.
inline std::string new_column_scale_group(const Column& c) {
  switch (c.kind) {
    case ColumnKind::BodyPosition:
    case ColumnKind::SystemCM: return "position";
    case ColumnKind::MomentumVector:
    case ColumnKind::ExternalMoment: return "H";  // M's scale: H's per second at least
    case ColumnKind::Power: return "P";
    case ColumnKind::JointForce:
    case ColumnKind::JointMoment: return "load" + std::to_string(c.joint);
    default: return "";
  }
}

// Per pinned column of `layout`, the scale of its new_column_scale_group over every row of `ref`
// (positions at least 1 m; 0 for the other columns).
inline std::vector<double> new_column_scales(const OutputLayout& layout, const RunResult& ref) {
  std::map<std::string, double> group;
  for (std::size_t c = 0; c < layout.pinned_size(); ++c) {
    const std::string g = new_column_scale_group(layout.columns()[c]);
    if (g.empty()) continue;
    double& s = group[g];
    if (g == "position") s = std::max(s, 1.0);
    for (std::size_t i = 0; i < ref.rows(); ++i) s = std::max(s, std::abs(ref.at(i, c)));
  }
  std::vector<double> out(layout.pinned_size(), 0.0);
  for (std::size_t c = 0; c < layout.pinned_size(); ++c) {
    const std::string g = new_column_scale_group(layout.columns()[c]);
    if (!g.empty()) out[c] = group[g];
  }
  return out;
}

inline RunResult run_engine(const std::string& engine, const System& system,
                            const std::string& method, double tol, double duration = -1,
                            const EngineOptions& options = {}) {
  auto e = make_engine(engine, system, options);
  IntegratorSettings s = IntegratorSettings::from(system.run);
  s.method = method;
  s.rtol = s.atol = tol;
  if (duration > 0) s.duration = duration;
  return simulate(*e, system, TreeState::initial(system), s);
}

}  // namespace crossdyn::test
