// The Lagrange engine's gradient pass: B^T d(T - V)/dq* at fixed pi', by forward-mode AD with the
// quasi-displacements dq* = B e_r as seeds, in chunks of Dual<K> (README.md, "Gradient pass").
// The fixed-size kernels: gradient_chunk<K> for K = 1 ... 8 instantiates the pose, twist and energy
// passes on every Dual<K> (most of the engine's compile time, on purpose for run-time speed); they
// are in this file alone so that the engine's other files compile quickly.
#include <algorithm>
#include <array>
#include <cstddef>
#include <tuple>
#include <utility>

#include "core/cancel.hpp"
#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/energy.hpp"
#include "formulations/lagrange/kinematics.hpp"
#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/passes.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

namespace {

template <int K>
void gradient_chunk(const Model& m, LagrangeEngine::Workspace& w, const int* chart, const double* x,
                    const int* dirs) {
  Kin<Dual<K>>& k = std::get<K - 1>(w.kg);
  const int n = m.n;
  for (int i = 0; i < n; ++i) k.q[static_cast<std::size_t>(i)] = Dual<K>(x[i]);
  // Seed direction c: the quasi-displacement d(pi) = e_r, i.e. dq* = B e_r (Eq. 22).
  for (int c = 0; c < K; ++c) {
    const int r = dirs[c];
    const int set = m.set_of_coordinate[static_cast<std::size_t>(r)];
    if (set >= 0) {
      const int i0 = m.euler_sets[static_cast<std::size_t>(set)].i0;
      for (int a = 0; a < 3; ++a)
        k.q[static_cast<std::size_t>(i0 + a)].d[static_cast<std::size_t>(c)] =
            w.B[static_cast<std::size_t>(set)](a, r - i0);
    } else {
      k.q[static_cast<std::size_t>(r)].d[static_cast<std::size_t>(c)] = 1.0;
    }
  }
  // The base's quasi-displacement e_r of its rotation block turns it by e_r in body axes (dq* =
  // B e_r, so A dq* = e_r). A prescribed base has no Euler angles: pose_pass turns it itself.
  if (m.base_set >= 0) {
    const int b0 = m.euler_sets[static_cast<std::size_t>(m.base_set)].i0;
    std::array<Eigen::Vector3d, K> theta;
    for (int c = 0; c < K; ++c) {
      const int a = dirs[c] - b0;
      theta[static_cast<std::size_t>(c)] = Eigen::Vector3d::Zero();
      if (a >= 0 && a < 3) theta[static_cast<std::size_t>(c)](a) = 1.0;
    }
    const Mat3<Dual<K>> R_base = base_attitude<K>(w.R_NB0, theta);
    pose_pass(m, chart, k, false, &R_base);
  } else {
    pose_pass(m, chart, k, false);
  }
  twist_pass(m, k, x + n, m.all_joints);
  const Dual<K> L = kinetic_energy_of(m, k, x + n) - potential_energy_of(m, chart, k.q.data());
  for (int c = 0; c < K; ++c) w.dL(dirs[c]) = L.d[static_cast<std::size_t>(c)];
}

template <int... K>
void gradient_dispatch(std::integer_sequence<int, K...>, int width, const Model& m,
                       LagrangeEngine::Workspace& w, const int* chart, const double* x,
                       const int* dirs) {
  ((width == K + 1 ? gradient_chunk<K + 1>(m, w, chart, x, dirs) : void()), ...);
}

}  // namespace

void size_gradient_workspace(const Model& m, Workspace& w) {
  std::apply([&](auto&... k) { (k.resize(m), ...); }, w.kg);
}

void lagrangian_gradient(const Model& m, Workspace& w, const double* x) {
  const int* chart = w.chart.data();
  w.dL.setZero();
  const int nd = static_cast<int>(m.gradient_dirs.size());
  for (int c0 = 0; c0 < nd; c0 += kMaxChunk) {
    cancel::poll();
    const int width = std::min(kMaxChunk, nd - c0);
    gradient_dispatch(std::make_integer_sequence<int, kMaxChunk>(), width, m, w, chart, x,
                      m.gradient_dirs.data() + c0);
  }
}

}  // namespace crossdyn::lagrange
