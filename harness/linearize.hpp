// crossdyn linearize (issue 27): every engine's linear model about one operating point, in the same
// reduced coordinates, and its eigenvalues compared between engines (docs/commands/linearize.md).
//
// Reduced coordinates z (engine-neutral, named like the pinned output columns):
//   configuration  every non-prescribed joint's coordinates (revolute `<j>.angle`, prismatic
//                  `<j>.position`, universal `<j>.angle1`, `<j>.angle2`, spherical `<j>.phix/y/z`: the
//                  rotation vector phi of R_J = R_J* exp([phi x]) from the operating point's R_J*),
//                  then every flexible body's modal coordinates `<body>.<mode>`;
//   velocity       a free base's w_NB_B (`<base>.wx/wy/wz`), every joint's rates (`<j>.rate`,
//                  `<j>.rate1/2`, spherical w_PC_C `<j>.wx/wy/wz`), every modal rate.
// The base's attitude and position are held at the operating point: without gravity they are
// ignorable (no load depends on them but a torque given in N), so they add only the eigenvalues
// 0 and +-i |w| that are not compared; the base's linear velocity follows the scene's rule
// (System::zero_linear_momentum), and the internal motion does not depend on it (Galilean
// invariance). A prescribed joint (and a prescribed base) moves with its profile at the
// operating time.
//
// Each engine's model is its own: z => TreeState => the engine's pack() (its own coordinates:
// Euler angles and quasi-velocities, quaternions and generalised speeds, or every body's pose and
// velocity on the constraint manifold) => the engine's accelerations() => dz/dt, the rates of the
// configuration coordinates from the velocity coordinates (spherical: phi' = J_r(phi)^-1 w_PC_C,
// Sola, Deray and Atchuthan 2018, "A micro Lie theory", Eq. (143)). Newton-Euler's maximal
// coordinates are thereby reduced to the constraint manifold (pack places every body from the
// joint coordinates). The Jacobian A = d(dz/dt)/dz is taken by central differences with two
// Richardson extrapolations (sixth order; Press et al., Numerical Recipes, 3rd ed., Sec. 5.7), its
// error estimated per entry from the last extrapolation and rounding (stated in every output;
// the cross-check of the exact matrices below);
// B and D from the inputs, on which the equations are linear (a central difference is exact to
// rounding). Each engine's Jacobian in its own state coordinates (rhs) is given too, marked
// coordinate-dependent, never compared.
//
// Exact linearisation: where an engine offers its own tangent (Engine::accelerations_tangent: its
// own automatic differentiation through its pack() and equations of motion), A is that, exact to
// rounding, column by column along the variations of z at the operating point (ReducedMap::tangent,
// rate_tangent: every phi is zero there, so exp and J_r^-1 are differentiated in closed form);
// the differences above are then its cross-check, a "jacobian" check per engine
// (|A - A_fd| <= 100 x the differences' own error + 1e-9 max|A|). An engine without one keeps the differences, said
// in every output. C and each engine's own Jacobian likewise: from Engine::output_row_tangent and
// rhs_tangent where the engine offers them, their differences the cross-check ("jacobian" checks).
#pragma once

#include "core/engine.hpp"

#include <Eigen/Core>

#include <complex>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace crossdyn::harness {

enum class OperatingPoint {
  Initial,  // the scene's initial state (at --time)
  Neutral,  // joints at their springs' neutral angles, every joint and modal rate and coordinate
            // zero; a free base keeps its initial spin (a steady spin when along a principal axis)
  Equilibrium,  // Neutral, then the joint and modal coordinates solved for an equilibrium (a
                // spring against a constant motor, a spinning body's centrifugal deflection)
  Spin,     // Equilibrium about the whole spacecraft's principal axis nearest the initial base rate
};

struct LinearEngineChoice {
  LinearEngineChoice() = default;
  LinearEngineChoice(std::string label_, std::string engine_, EngineOptions options_ = {})
      : label(std::move(label_)), engine(std::move(engine_)), options(options_) {}
  std::string label;  // as printed ("kane", or a test double's "kane*gyro")
  std::string engine;
  EngineOptions options;
  // Test-only: builds the engine instead of make_engine(engine, ...), so that a test double (an
  // engine whose tangent is wrong) can be shown to fail its cross-check. Empty in every real run.
  std::function<std::unique_ptr<Engine>(const System&, const EngineOptions&)> factory;
  std::unique_ptr<Engine> make(const System& system) const;
};

struct LinearizeOptions {
  std::vector<LinearEngineChoice> engines;
  double time = 0;  // s, the operating time (a prescribed joint's profile and motors at t)
  OperatingPoint point = OperatingPoint::Initial;
  bool inputs_given = false;         // false: every motor and body torque the scene names
  std::vector<std::string> inputs;   // input names (linear_input_names)
  std::vector<std::string> outputs;  // pinned output columns
  double rtol = 1e-8;                // eigenvalue agreement: |l_a - l_b| <= rtol |l_a| + atol
  double atol = 1e-12;               // ... times the spectral radius
  double tf_rtol = 1e-7;             // transfer functions: |G_a - G_b| <= tf_rtol max_w |G_a|
  double residual_tol = 1e-9;        // an equilibrium: |dz/dt|inf <= residual_tol |A|inf max(|z|inf, 1)
  double zero_tol = 1e-6;            // |lambda| <= zero_tol * spectral radius: a rigid-body zero
  bool jacobian_only = false;        // a state that is not an equilibrium: Jacobians, no comparison
  double fd_step = 0;                // the first difference step, times max(|z_j|, 1); 0: chosen per column
};

// The inputs a scene offers: `<joint>.motor` (revolute N m, prismatic N), `<joint>.motor1`,
// `.motor2` (universal), `<joint>.motorx/y/z` (spherical, child frame), `<body>.Tx/Ty/Tz` (a
// body's external torque in its torque frame); `named` only those the scene gives a load.
std::vector<std::string> linear_input_names(const System& system, bool named_only);

struct LinearMode {
  std::complex<double> lambda;
  double frequency = 0;      // |lambda|, rad/s (the undamped natural frequency)
  double damping_ratio = 0;  // -Re(lambda) / |lambda|
  std::string coordinate;    // the coordinate its eigenvector moves most
  double allowance = 0;      // its error from A's (finite differences): condition x n x A's error
  Eigen::VectorXcd shape;    // its right eigenvector in z (unit norm)
};

// How one matrix of an engine's linear model was obtained: exact (the engine's own tangent,
// Engine::accelerations_tangent, output_row_tangent or rhs_tangent) with its finite differences as
// the cross-check, or by those differences alone.
struct MatrixMethod {
  bool exact = false;
  double error = 0;          // estimated max error of its entries: rounding when exact, else the differences'
  double fd_difference = 0;  // exact: max |M - M_fd| against its finite differences (the cross-check)
  double fd_error = 0;       // the finite differences' own estimated error (the cross-check's bound: 100 x this + 1e-9 max|M|)
  struct Entry {
    Eigen::Index row = 0, col = 0;
    double exact = 0, differences = 0;
  } worst;                   // the entry where they differ most
};

struct EngineLinearModel {
  std::string label;
  std::string failure;         // "" or why the engine could not be linearised (RunFailure)
  Eigen::MatrixXd A, B, C, D;  // dz/dt = A dz + B du, dy = C dz + D du
  MatrixMethod a_method;       // A's (accelerations_tangent)
  MatrixMethod c_method;       // C's (output_row_tangent)
  Eigen::VectorXd residual;    // dz/dt at the operating point
  double relative_residual = 0;
  std::vector<std::complex<double>> eigenvalues;  // every eigenvalue of A
  std::vector<double> allowances;                 // each one's error bound from A's error
  std::vector<LinearMode> modes;                  // non-zero ones, Im >= 0, by frequency
  int zeros = 0;                                   // eigenvalues grouped as rigid-body zeros
  double zero_bound = 0;                           // |lambda| below this is a zero
  std::vector<std::string> own_states;             // the engine's own state labels
  Eigen::MatrixXd own_A;                           // d(rhs)/dx, coordinate-dependent
  MatrixMethod own_method;                         // own_A's (rhs_tangent)
};

struct LinearCheck {
  std::string kind;       // "eigenvalue", "zeros", "transfer", "analytic"
  std::string what;       // mode coordinate, pair "y <- u at w", ...
  std::string engine_a, engine_b;
  std::complex<double> a, b;
  double error = 0, bound = 0;
  bool passed = false;
  std::string note;
};

struct LinearizeResult {
  std::string scene;
  double time = 0;
  std::string how;          // how the operating point was chosen, in words
  bool equilibrium = false;
  std::vector<std::string> states, inputs, outputs;
  TreeState op;  // the operating point
  Eigen::VectorXd z0;
  std::vector<EngineLinearModel> engines;
  std::vector<double> frequencies;  // transfer-function frequencies, rad/s
  std::vector<LinearCheck> checks;
  std::vector<std::string> findings;
  bool passed() const;
};

// Throws InputError for an unknown input or output name, and (unless jacobian_only) when the
// operating point is not an equilibrium of the reduced equations, naming the residual.
LinearizeResult linearize(const System& system, const LinearizeOptions& options);

std::string format_linearization(const LinearizeResult& r);
std::string linearization_json(const LinearizeResult& r);
// File name => content: states.csv, inputs.csv, outputs.csv, and per engine <label>.A.csv,
// .B.csv, .C.csv, .D.csv, .eigenvalues.csv, .own_A.csv (docs/commands/linearize.md).
std::vector<std::pair<std::string, std::string>> linearization_csv(const LinearizeResult& r);

// The report's drawing of mode k of engine e (harness/scene_geometry.hpp's geometry JSON): the
// scene at the operating point, then at four times of the mode's motion
// z(t) = z0 + a Re(shape e^(lambda t)) (a quarter period apart; for a real lambda, 1/(2|lambda|)),
// the amplitude a exaggerated so that the largest configuration coordinate moves by 0.35 (rad or
// m). Each configuration is the engine's own output row at that state. "" when the mode moves no
// configuration coordinate (a mode of the base's angular velocity alone).
std::string mode_geometry(const System& system, const LinearizeOptions& options, const LinearizeResult& r,
                          std::size_t engine, std::size_t mode);

}  // namespace crossdyn::harness
