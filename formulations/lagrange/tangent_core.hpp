// The Lagrange engine's exact variation of one evaluation (tangent.cpp): the equations of motion in
// Euler-angle form on E = Dual<1>, each value carrying its first-order variation along one outer
// direction (README.md, "Exact linearisation"). Shared by accelerations_tangent(), rhs_tangent()
// (tangent.cpp) and output_row_tangent() (output_tangent.cpp). Internal header
// (formulations/lagrange/*.cpp only).
#pragma once

#include <vector>

#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/model.hpp"

namespace crossdyn::lagrange::tangent {

using E = Dual<1>;  // a value and its variation along the outer direction

// Everything at one state (t, q*, pi'), in E, over every coordinate (prescribed ones included).
struct Core {
  std::vector<E> q, u;       // q*, pi' (the caller's)
  std::vector<E> qd;         // q*' = B pi'
  std::vector<E> qdd, ud;    // q*'', pi''
  std::vector<Mat3<E>> R;    // per body R_NB
  std::vector<Vec3<E>> p;    // per body p_NoBo_N (a flexible body's undeformed CM)
  std::vector<Vec3<E>> r_C;  // per body: its joint's point on it, p_CoJ_C or the node's (pose pass)
  // Per body: the twist w_NB_B, v_NBo_B and its rate (body components), xi = Xi pi',
  // xi' = Xi pi'' + (dXi/dt) pi'.
  std::vector<Vec3<E>> w, v, wd, vd;
  // Per body (Model::gravity only): the environment's resultant at Bo and its moment about Bo, N
  // components, as the equations of motion use them (gravity.cpp).
  std::vector<Vec3<E>> F_g, M_g;
  std::vector<E> torque;  // per Model::prescribed_joints: the joint's torque (solve.cpp)
  E T, V;                 // kinetic energy 1/2 q*'^T Mbar q*'; springs' and elastic potential
};

inline E seeded(double value, double variation) {
  E e(value);
  e.d[0] = variation;
  return e;
}

// pack() chooses the charts and records the last accepted state (after_step()): a tangent that
// packs puts them back on the way out, so a run's engine is left as it was.
template <class W>
struct Restore {
  W& w;
  std::vector<int> chart;
  std::vector<double> last_a2;
  double last_t;
  bool have_last;
  explicit Restore(W& ws)
      : w(ws), chart(ws.chart), last_a2(ws.last_a2), last_t(ws.last_t), have_last(ws.have_last) {}
  Restore(const Restore&) = delete;
  Restore& operator=(const Restore&) = delete;
  ~Restore() {
    w.chart = chart;
    w.last_a2 = last_a2;
    w.last_t = last_t;
    w.have_last = have_last;
  }
};

// The variation at (t, q, u) in the given charts (one per Euler set), q and u seeded by the caller
// (LagrangeEngine::pack_tangent: pack()'s variation, the zero-linear-momentum base velocity's
// included). False when a solve meets a zero
// pivot. Allocates.
bool evaluate(const Model& m, double t, const int* chart, std::vector<E> q, std::vector<E> u,
              Core& c);

}  // namespace crossdyn::lagrange::tangent
