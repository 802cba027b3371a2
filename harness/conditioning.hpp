// How well-posed each engine's linear solve is, and what it costs in digits: the condition number
// of the system an engine solves for its accelerations (Engine::linear_system) and the deviation
// of its accelerations from the other engines' at the same state. `crossdyn study --scaling`
// reports both against chain length (harness/study.hpp, ScalingPoint).
//
// Condition number: kappa_2(A) = sigma_max / sigma_min (Golub & Van Loan, Matrix Computations,
// 4th ed., Sec. 2.6.2); for a symmetric A the singular values are |eigenvalues| (ibid., Sec. 8.6.1),
// which is how it is computed when A is symmetric (every engine's A is: a mass matrix or a KKT
// matrix). A backward-stable solve of A z = b loses about log10(kappa) digits of z in the worst
// case (ibid., Sec. 3.5.1), so kappa is an upper bound; the deviation below is what was lost.
//
// The deviation of engine e: at the scene's initial state, every engine's engine-neutral
// accelerations (TreeAccel: body angular and CM accelerations, joint angle and spherical-rate
// accelerations, modal accelerations), and
//   dev_e = min over the other engines f of ( max over kinds and entries of |a_e - a_f| / S_kind ),
// S_kind the largest |entry| of that kind over all engines (1 when all are zero): how far e is
// from the engine closest to it. When one engine has lost digits and the others have not, its
// dev is its error and theirs stay at rounding; when all differ, each dev is at least half the
// largest error among the engines compared.
#pragma once

#include "core/engine.hpp"
#include "core/system.hpp"

#include <limits>
#include <string>
#include <vector>

namespace crossdyn::harness {

// kappa_2(A); +inf when A is singular; NaN when A is empty, not square or not finite.
double condition_number(const Eigen::MatrixXd& A);

struct SolveConditioning {
  double condition = std::numeric_limits<double>::quiet_NaN();  // NaN: the engine gives no system
  int size = 0;                                                 // rows of A
  std::string what;                                             // Engine::LinearSystem::what
};
// The engine's system at (t, x) and its condition number.
SolveConditioning solve_conditioning(Engine& engine, double t, const double* x);

// dev_e for each engine (the order given) at the scene's initial state; NaN for all with fewer
// than two engines, and for an engine that cannot be made or whose accelerations are not finite.
// options[e] (when given) are engine e's options (tests: a deliberately wrong engine).
std::vector<double> acceleration_deviation(const System& system,
                                           const std::vector<std::string>& engines,
                                           const std::vector<EngineOptions>& options = {});

}  // namespace crossdyn::harness
