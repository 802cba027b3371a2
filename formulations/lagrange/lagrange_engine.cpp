// The Lagrange engine (lagrange_engine.hpp; derivation and the file of every equation: README.md).
// This file: the accessors, evaluate() (the passes in order) and rhs(). One evaluation,
// (t, x = (q*, pi')) => (q*', pi''):
//   charts    A, B = A^-1 per Euler set; q*' = B pi'              (euler_charts.cpp)
//   mass      M, p, (dM/dt) pi'                                    (mass_matrix.cpp)
//   forces    N                                                    (generalised_forces.cpp)
//   gradient  B^T d(T - V)/dq*                                     (lagrangian_gradient.cpp)
//   hamel     B^T W^T p                                            (hamel_terms.cpp)
//   solve     M pi'' = N + B^T dL/dq* - (dM/dt) pi' - B^T W^T p    (solve.cpp)
// on the kinematics and energies of kinematics.hpp and energy.hpp. All scratch lives in the
// Workspace (workspace.hpp), sized in the constructor (build_model.cpp): rhs() does not allocate.
#include "formulations/lagrange/lagrange_engine.hpp"

#include <cmath>
#include <cstddef>
#include <string>

#include "core/errors.hpp"
#include "formulations/lagrange/euler_chart.hpp"
#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/passes.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

LagrangeEngine::~LagrangeEngine() = default;

int LagrangeEngine::state_size() const {
  return 2 * model_->nf;
}
int LagrangeEngine::dof() const {
  return model_->nf;
}
long LagrangeEngine::recharts() const {
  return ws_->recharts;
}
long LagrangeEngine::lock_crossings() const {
  return ws_->lock_crossings;
}
int LagrangeEngine::euler_sets() const {
  return static_cast<int>(model_->euler_sets.size());
}
std::string LagrangeEngine::euler_set_owner(int s) const {
  return model_->euler_sets.at(static_cast<std::size_t>(s)).owner;
}
int LagrangeEngine::chart(int s) const {
  return ws_->chart.at(static_cast<std::size_t>(s));
}
std::string LagrangeEngine::chart_name(int s) const {
  return kSequences[static_cast<std::size_t>(chart(s))].name;
}
const OutputLayout& LagrangeEngine::layout() const {
  return model_->layout;
}
int LagrangeEngine::modal_index(int body) const {
  const int e0 = model_->bodies.at(static_cast<std::size_t>(body)).e0;
  return e0 < 0 ? -1 : model_->state_of[static_cast<std::size_t>(e0)];
}

// evaluate: (t, x) => M, p, (dM/dt) pi', B^T W^T p, B^T dL/dq*, N, q*', pi'' (README.md, "Passes").
void LagrangeEngine::evaluate(double t, const double* x) {
  const Model& m = *model_;
  Workspace& w = *ws_;
  const int n = m.n;
  w.u = Eigen::Map<const Eigen::VectorXd>(x + n, n);

  // charts: A, B; q*' = B pi' (Eq. 16 inverted).
  prepare_charts(t, x);
  w.qdot = w.u;
  for (std::size_t s = 0; s < m.euler_sets.size(); ++s) {
    const int i0 = m.euler_sets[s].i0;
    w.qdot.segment<3>(i0) = w.B[s] * w.u.segment<3>(i0);
  }

  mass_pass(m, w, x);
  generalised_forces(m, w, t);
  lagrangian_gradient(m, w, x);
  hamel_terms(m, w);
  solve(m, w, t);
}

void LagrangeEngine::rhs(double t, const double* x, double* xdot) {
  const Model& m = *model_;
  evaluate(t, expand(t, x));
  const int n = m.nf;
  if (!m.has_prescribed) {
    for (int i = 0; i < n; ++i) {
      xdot[i] = ws_->qdot(i);
      xdot[n + i] = ws_->udot(i);
    }
  } else {
    for (int a = 0; a < n; ++a) {
      const int i = m.free_index[static_cast<std::size_t>(a)];
      xdot[a] = ws_->qdot(i);
      xdot[n + a] = ws_->udot(i);
    }
  }
  for (int i = 0; i < 2 * n; ++i)
    if (!std::isfinite(xdot[i]))
      throw RunFailure("lagrange", t, state_label(i), "non-finite derivative");
}

}  // namespace crossdyn::lagrange
