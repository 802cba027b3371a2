// The Lagrange engine's state: labels, the full (q*, pi') with prescribed joints (expand), and pack()
// (TreeState => x, choosing for every Euler set a chart far from its singularity). Coordinates:
// README.md, "Coordinates"; charts: README.md, "Singularities".
#include <cmath>
#include <string>

#include "core/errors.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "formulations/lagrange/joints/joint_unit.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

std::string LagrangeEngine::state_label(int i) const {
  const Model& m = *model_;
  if (i < 0 || i >= 2 * m.nf) return "x[" + std::to_string(i) + "]";
  return full_label(i < m.nf ? m.free_index[static_cast<std::size_t>(i)]
                             : m.n + m.free_index[static_cast<std::size_t>(i - m.nf)]);
}

// State x (free coordinates) => xf, the full (q*, pi') with the prescribed joints' angle
// angle0 + theta(t) and rate theta'(t) (docs/prescribed-motion.md, "The motion").
const double* LagrangeEngine::expand(double t, const double* x) {
  const Model& m = *model_;
  if (!m.has_prescribed) return x;
  Workspace& w = *ws_;
  double* xf = w.xf.data();
  for (int a = 0; a < m.nf; ++a) {
    const int i = m.free_index[static_cast<std::size_t>(a)];
    xf[i] = x[a];
    xf[m.n + i] = x[m.nf + a];
  }
  for (int j : m.prescribed_joints) {
    const Model::JointM& J = m.joints[static_cast<std::size_t>(j)];
    xf[J.i0] = J.angle0 + J.motion.angle(t);
    xf[m.n + J.i0] = J.motion.velocity(t);
  }
  return xf;
}

std::string LagrangeEngine::full_label(int i) const {
  if (i < 0 || i >= static_cast<int>(model_->labels.size())) return "x[" + std::to_string(i) + "]";
  std::string label = model_->labels[static_cast<std::size_t>(i)];
  if (i < model_->n && model_->set_of_coordinate[static_cast<std::size_t>(i)] >= 0)
    label += " (" + chart_name(model_->set_of_coordinate[static_cast<std::size_t>(i)]) + ")";
  return label;
}

// pack: TreeState => x, choosing for every Euler set a chart far from its singularity.
void LagrangeEngine::pack(const TreeState& s, double* x) {
  const Model& m = *model_;
  Workspace& w = *ws_;
  if (s.joints.size() != m.joints.size())
    throw InputError("engine lagrange: pack() got a state with " + std::to_string(s.joints.size()) +
                     " joints for a system with " + std::to_string(m.joints.size()));
  const int n = m.n;
  double* const xs = x;
  if (m.has_prescribed) x = w.xf.data();  // fill the full (q*, pi'), then keep the free part
  double* q = x;
  double* u = x + n;
  auto set_angles = [&](int set, const Eigen::Quaterniond& quat, double* angles) {
    const Eigen::Matrix3d R = quat.normalized().toRotationMatrix();
    int c = kDefaultChart;
    if (chart_singularity(kSequences[kDefaultChart], R) > std::sin(kPackDeg * kDeg))
      c = best_chart(R);
    w.chart[static_cast<std::size_t>(set)] = c;
    const Eigen::Vector3d a = euler_angles(kSequences[static_cast<std::size_t>(c)], R);
    for (int i = 0; i < 3; ++i) angles[i] = a(i);
  };
  for (std::size_t j = 0; j < m.joints.size(); ++j) {
    const Model::JointM& J = m.joints[j];
    const TreeState::JointState& js = s.joints[j];
    double* qj = q + J.i0;
    double* uj = u + J.i0;
    J.unit->pack(J, s, js, qj, uj, set_angles);
  }
  for (std::size_t b = 0; b < m.bodies.size(); ++b) {
    const Model::BodyM& B = m.bodies[b];
    if (B.flex < 0) continue;
    const auto nm = static_cast<Eigen::Index>(B.nm);
    if (b >= s.eta.size() || b >= s.eta_rate.size() || s.eta[b].size() != nm ||
        s.eta_rate[b].size() != nm)
      throw InputError("engine lagrange: pack() got a state without the " + std::to_string(nm) +
                       " modal coordinates and rates of flexible body '" + B.name + "'");
    for (Eigen::Index k = 0; k < nm; ++k) {
      q[B.e0 + k] = s.eta[b](k);
      u[B.e0 + k] = s.eta_rate[b](k);
    }
  }
  if (m.zero_linear_momentum) {
    // Every body's linear momentum contains its mass times the base velocity once (the base
    // velocity adds to every point's velocity): choose it so that the total is zero, modal rates
    // included (docs/flexible-bodies.md "Initial state and momentum").
    for (int i = 0; i < 3; ++i) u[i] = 0.0;
    const Eigen::Vector3d P = linear_momentum_full(x);
    for (int i = 0; i < 3; ++i) u[i] = -P(i) / m.total_mass;
  }
  if (m.has_prescribed)
    for (int a = 0; a < m.nf; ++a) {
      const int i = m.free_index[static_cast<std::size_t>(a)];
      xs[a] = x[i];
      xs[m.nf + a] = x[n + i];
    }
  // The run starts here (pack() is at t = 0): after_step() compares the first accepted state's
  // lock sheets with these.
  for (std::size_t set = 0; set < m.euler_sets.size(); ++set)
    w.last_a2[set] = q[m.euler_sets[set].i0 + 1];
  w.last_t = 0.0;
  w.have_last = true;
}

}  // namespace crossdyn::lagrange
