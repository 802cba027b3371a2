// The Lagrange engine's Hamel (transitivity) terms B^T W^T p, per Euler set, from the derivatives of
// the kinematic matrix A kept by the charts (README.md, "Hamel's terms"; paper Eq. 23).
#include <cstddef>

#include "formulations/lagrange/autodiff.hpp"
#include "formulations/lagrange/model.hpp"
#include "formulations/lagrange/passes.hpp"
#include "formulations/lagrange/workspace.hpp"

namespace crossdyn::lagrange {

// W_lk = sum_j (dA_lk/da_j - dA_lj/da_k) a'_j per Euler set; term B^T W^T p.
void hamel_terms(const Model& m, Workspace& w) {
  w.hamel.setZero();
  for (std::size_t s = 0; s < m.euler_sets.size(); ++s) {
    const int i0 = m.euler_sets[s].i0;
    const Mat3<Dual<2>>& A = w.A_dual[s];  // charts: A and its derivatives in a2, a3
    const Eigen::Vector3d ad = w.qdot.segment<3>(i0);
    auto dA = [&A](int l, int kk, int j) {  // dA_lk/da_j
      return j == 0 ? 0.0 : A(l, kk).d[static_cast<std::size_t>(j - 1)];
    };
    Eigen::Matrix3d W;
    for (int l = 0; l < 3; ++l)
      for (int kk = 0; kk < 3; ++kk) {
        double v = 0.0;
        for (int j = 0; j < 3; ++j) v += (dA(l, kk, j) - dA(l, j, kk)) * ad(j);
        W(l, kk) = v;
      }
    w.hamel.segment<3>(i0) = w.B[s].transpose() * (W.transpose() * w.p.segment<3>(i0));
  }
}

}  // namespace crossdyn::lagrange
