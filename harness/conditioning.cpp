// The conditioning of each engine's linear solve and the deviation of its accelerations from the
// other engines' (conditioning.hpp gives the definitions and sources).
#include "harness/conditioning.hpp"

#include "core/errors.hpp"
#include "harness/engines.hpp"
#include "harness/numbers.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <memory>

namespace crossdyn::harness {

namespace {


// Every entry of a TreeAccel in one vector per kind (the kinds of conditioning.hpp).
std::vector<std::vector<double>> kinds_of(const TreeAccel& a) {
  std::vector<std::vector<double>> k(5);
  for (const Eigen::Vector3d& v : a.wdot_NB_B) k[0].insert(k[0].end(), v.data(), v.data() + 3);
  for (const Eigen::Vector3d& v : a.a_NBo_N) k[1].insert(k[1].end(), v.data(), v.data() + 3);
  k[2] = a.angle_ddot;
  for (const Eigen::Vector3d& v : a.wdot_PC_C) k[3].insert(k[3].end(), v.data(), v.data() + 3);
  for (const Eigen::VectorXd& v : a.eta_ddot) k[4].insert(k[4].end(), v.data(), v.data() + v.size());
  return k;
}

}  // namespace

double condition_number(const Eigen::MatrixXd& A) {
  if (A.size() == 0 || A.rows() != A.cols() || !A.allFinite()) return kNaN;
  Eigen::VectorXd s;  // singular values
  const double scale = A.cwiseAbs().maxCoeff();
  if (scale == 0) return std::numeric_limits<double>::infinity();
  if ((A - A.transpose()).cwiseAbs().maxCoeff() <= 1e-12 * scale) {
    // Golub & Van Loan Sec. 8.6.1: the singular values of a symmetric matrix are |eigenvalues|.
    const Eigen::MatrixXd S = 0.5 * (A + A.transpose());
    s = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(S, Eigen::EigenvaluesOnly).eigenvalues().cwiseAbs();
  } else {
    // One-sided Jacobi SVD (Golub & Van Loan Sec. 8.6.3): square A needs no QR preconditioner.
    // Not BDCSVD: it instantiates a second SVD and made this file a 35 s compile (issue 29).
    s = Eigen::JacobiSVD<Eigen::MatrixXd, Eigen::NoQRPreconditioner>(A).singularValues();
  }
  const double hi = s.maxCoeff(), lo = s.minCoeff();
  if (!(lo > 0)) return std::numeric_limits<double>::infinity();
  return hi / lo;
}

SolveConditioning solve_conditioning(Engine& engine, double t, const double* x) {
  SolveConditioning c;
  const Engine::LinearSystem ls = engine.linear_system(t, x);
  if (ls.A.size() == 0) return c;
  c.size = static_cast<int>(ls.A.rows());
  c.what = ls.what;
  c.condition = condition_number(ls.A);
  return c;
}

std::vector<double> acceleration_deviation(const System& system,
                                           const std::vector<std::string>& engines,
                                           const std::vector<EngineOptions>& options) {
  const std::size_t n = engines.size();
  std::vector<double> dev(n, kNaN);
  if (n < 2) return dev;
  std::vector<std::vector<std::vector<double>>> acc(n);  // engine, kind, entry
  std::vector<bool> ok(n, false);
  const TreeState s0 = TreeState::initial(system);
  for (std::size_t e = 0; e < n; ++e) {
    try {
      const EngineOptions o = e < options.size() ? options[e] : EngineOptions{};
      std::unique_ptr<Engine> engine = make_engine(engines[e], system, o);
      std::vector<double> x(static_cast<std::size_t>(engine->state_size()));
      engine->pack(s0, x.data());
      TreeAccel a;
      engine->accelerations(0.0, x.data(), a);
      acc[e] = kinds_of(a);
      ok[e] = true;
      for (const auto& kind : acc[e])
        for (double v : kind) ok[e] = ok[e] && std::isfinite(v);
    } catch (const InputError&) {
    } catch (const RunFailure&) {
    }
  }
  // S_kind over every engine that gave accelerations.
  std::vector<double> scale;
  for (std::size_t e = 0; e < n; ++e)
    if (ok[e]) {
      scale.resize(acc[e].size(), 0.0);
      for (std::size_t k = 0; k < acc[e].size(); ++k)
        for (double v : acc[e][k]) scale[k] = std::max(scale[k], std::abs(v));
    }
  for (double& s : scale)
    if (s == 0) s = 1;
  for (std::size_t e = 0; e < n; ++e) {
    if (!ok[e]) continue;
    for (std::size_t f = 0; f < n; ++f) {
      if (f == e || !ok[f] || acc[f].size() != acc[e].size()) continue;
      double worst = 0;
      bool same_shape = true;
      for (std::size_t k = 0; k < acc[e].size() && same_shape; ++k) {
        same_shape = acc[f][k].size() == acc[e][k].size();
        for (std::size_t i = 0; same_shape && i < acc[e][k].size(); ++i)
          worst = std::max(worst, std::abs(acc[e][k][i] - acc[f][k][i]) / scale[k]);
      }
      if (same_shape && !(worst >= dev[e])) dev[e] = worst;  // dev[e] NaN until the first
    }
  }
  return dev;
}

}  // namespace crossdyn::harness
