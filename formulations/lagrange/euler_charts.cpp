// The Lagrange engine's Euler-angle charts (euler_chart.hpp) at run time: prepare_charts (the
// kinematic matrix A, B = A^-1 and the derivatives of A for Hamel's term, per Euler set) and
// after_step (re-charting near a singularity, or stopping the run). Equations and the re-charting
// rules: README.md, "Singularities".
#include <cmath>
#include <numbers>
#include <string>

#include "core/errors.hpp"
#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "formulations/lagrange/lagrange_engine.hpp"
#include "formulations/lagrange/messages.hpp"
#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

// charts: (q*) => A, B per Euler set (paper Eqs. 16, 22). Throws at an exactly singular chart.
void LagrangeEngine::prepare_charts(double t, const double* x) {
  const Model& m = *model_;
  Workspace& w = *ws_;
  for (std::size_t s = 0; s < m.euler_sets.size(); ++s) {
    const double* a = x + m.euler_sets[s].i0;
    const EulerSequence& seq = kSequences[static_cast<std::size_t>(w.chart[s])];
    if (std::abs(std::cos(a[1])) < 1e-9)
      throw RunFailure("lagrange", t, full_label(m.euler_sets[s].i0 + 1),
                       m.euler_sets[s].what + " is at the singularity of its " + seq.name +
                           " Euler angles (second angle " + format_number(a[1] / kDeg) + " deg)");
    // A depends on a2 and a3 only (euler_chart.hpp): Dual<2> seeded on them (dA/da1 = 0), its
    // derivatives kept for Hamel's term.
    w.A_dual[s] = euler_rate_matrix(seq, Dual<2>::variable(a[1], 0), Dual<2>::variable(a[2], 1));
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) w.A[s](r, c) = w.A_dual[s](r, c).v;
    w.B[s] = w.A[s].inverse();
  }
}

// after_step: detect the approach to an Euler-angle singularity (a state within 90 - kRechartDeg
// deg of a lock, or a lock crossed since the last accepted state: sheet(a2) changed); re-chart or
// stop (README.md, "Singularities").
namespace {

double lock_sheet(double a2) {
  return std::floor((a2 + 0.5 * std::numbers::pi) / std::numbers::pi);
}

}  // namespace

bool LagrangeEngine::after_step(double t, double* x) {
  const Model& m = *model_;
  Workspace& w = *ws_;
  bool changed = false;
  // Euler angles are never prescribed: work on their place in x directly.
  auto at = [&m](int i) { return m.state_of[static_cast<std::size_t>(i)]; };
  for (std::size_t s = 0; s < m.euler_sets.size(); ++s) {
    double* a = x + at(m.euler_sets[s].i0);
    const EulerSequence& seq = kSequences[static_cast<std::size_t>(w.chart[s])];
    const double cos_a2 = std::abs(std::cos(a[1]));  // 0 at gimbal lock
    const double a2_last = w.last_a2[s];
    const bool crossed = w.have_last && lock_sheet(a[1]) != lock_sheet(a2_last);
    if (!m.rechart && crossed) {
      // The first lock passed after a2_last, in the direction of travel, and when (linear).
      const double sheet = lock_sheet(a2_last);
      const double lock = (a[1] > a2_last ? sheet + 0.5 : sheet - 0.5) * std::numbers::pi;
      const double t_lock = w.last_t + (lock - a2_last) / (a[1] - a2_last) * (t - w.last_t);
      throw RunFailure(
          "lagrange", t_lock, full_label(m.euler_sets[s].i0 + 1),
          m.euler_sets[s].what + " reached gimbal lock of its " + seq.name +
              " Euler angles: second angle crossed " + format_number(lock / kDeg, "%.0f") +
              " deg (limit " + format_number(kFailDeg) +
              " deg) between the accepted states at t = " + format_number(w.last_t, "%.9g") +
              " s (" + format_number(a2_last / kDeg, "%.3f") + " deg) and t = " +
              format_number(t, "%.9g") + " s (" + format_number(a[1] / kDeg, "%.3f") +
              " deg), at t = " + format_number(t_lock, "%.9g") +
              " s by linear interpolation (the time reported), and re-charting is off "
              "(EngineOptions::rechart = false)");
    }
    if (!m.rechart && cos_a2 < std::cos(kFailDeg * kDeg))
      throw RunFailure("lagrange", t, full_label(m.euler_sets[s].i0 + 1),
                       m.euler_sets[s].what + " reached gimbal lock of its " + seq.name +
                           " Euler angles: second angle " + format_number(a[1] / kDeg, "%.3f") +
                           " deg (limit " + format_number(kFailDeg) +
                           " deg) and re-charting is off (EngineOptions::rechart = false)");
    if (m.rechart && (crossed || cos_a2 < std::cos(kRechartDeg * kDeg))) {
      // Re-chart: the same attitude in the chart farthest from its singularity. pi' (w_NB_B or
      // w_PC_C) does not depend on the chart, so nothing else changes.
      const Eigen::Matrix3d R = euler_rotation(seq, a[0], a[1], a[2]);
      const int c = best_chart(R);
      const Eigen::Vector3d an = euler_angles(kSequences[static_cast<std::size_t>(c)], R);
      for (int i = 0; i < 3; ++i) a[i] = an(i);
      w.chart[s] = c;
      ++w.recharts;
      if (crossed) ++w.lock_crossings;
      w.last_a2[s] = a[1];
      changed = true;
      continue;
    }
    w.last_a2[s] = a[1];
    // Keep the first and third angles bounded (they grow without limit while spinning) so that
    // the integrator's relative tolerance means the same thing all run long.
    for (int i : {0, 2})
      if (std::abs(a[i]) > 4.0 * std::numbers::pi) {
        a[i] = std::remainder(a[i], 2.0 * std::numbers::pi);
        ++w.wraps;
        changed = true;
      }
  }
  w.last_t = t;
  return changed;
}

}  // namespace crossdyn::lagrange
