// Comparing engines on one scene (`crossdyn compare`: docs/commands/compare.md).
//
// What is compared, for every pair of engines that ran to the end (and the analytic solution
// where the scene has one, as the pseudo-engine "analytic"):
//   quantity          group      error at one output time
//   <body>.wx/wy/wz   w          |a - b|, rad/s
//   <body>.attitude   attitude   rotation angle between the two attitudes (q and -q agree), rad
//   <joint>.angle     angle      |a - b|, rad                 (revolute joints)
//   <joint>.rate      rate       |a - b|, rad/s               (revolute joints)
//   <joint>.wx/wy/wz  rate       |a - b|, rad/s               (spherical joints)
//   <body>.<mode>     modal      |a - b| (and <mode>_rate)    (flexible bodies)
//   <joint>.torque    torque     |a - b|, N m                 (prescribed revolute joints)
//   H, E              H, E       |a - b|
//   <body>.x/y/z      position   |a - b|, m (and the system CM, CMx CMy CMz)
//   Hx Hy Hz, Mx My Mz  H        |a - b| (the momentum vector about the CM and the external moment)
//   P                 E          |a - b|, W (the power of the non-conservative loads)
//   <joint>.Fx..Mz    load       |a - b|, N and N m (every joint but the free one)
//   other columns     extra      only when the scene's tolerances name them
// and for every engine alone (not the analytic solution), for each of H and E:
//   X.drift           drift      |X(t) - X(0)|               (a conserved X)
//   X.balance         balance    |X(t) - X(0) - W(t)|         (an X the scene does not conserve;
//                                W the integral of P, or of the vector M with H the vector)
//   X.rate            balance    |dX/dt - P| (E), |dH/dt - M| (H, a vector), at every output row:
//                                dX/dt the engine's own E (H) differentiated along its own motion
//                                (core/integrate.hpp, rate_columns); every scene, conserved or not
//
// The pass rule (written in every table and report):
//   pair:   max_t |a(t) - b(t)| <= atol + rtol * max_t |b(t)|
//   drift:  max_t |X(t) - X(0)| <= atol + rtol * |X(0)|
//   balance: max_t |X(t) - X(0) - W(t)| <= atol + rtol * max(max_t |X|, integral of |rate|) + Q,
//            Q the estimated error of W's quadrature on the output times (compare.cpp)
//   rate:   max_t |dX/dt - rate| <= atol + rtol * max_t max(|rate|, |dX/dt|) + D, D the largest
//            estimated error of the difference (the .err columns of rate_column_names())
// where b is the pair's reference: the earlier of the two in the run order (analytic first, then
// the engines in the order asked for). For attitude the scale max|b| is 1 (a unit quaternion), so
// atol + rtol is a bound on the angle in rad. "normalised error" = error / bound; <= 1 passes.
//
// Tolerances come from the scene's compare block. The key looked up for a quantity, first match
// wins: the quantity itself ("main.wx", "main.attitude", "H.drift"), then its vector ("main.w",
// "hinge1.w" for a spherical joint's wx/wy/wz; "gimbal.angle", "gimbal.rate" for a universal
// joint's two), then its group ("w", "rate", "angle", "position" (a prismatic joint's), "torque",
// "attitude", "modal", "H", "E", "load"), then the scene's default (System::compare.default_tolerance).
// Drift checks look up "H.drift" / "E.drift", then "drift"; balances "H.balance" / "E.balance",
// then "balance"; both default to atol = rtol = 1e-9. Exclusions match the same keys and carry
// their reason into every table.
//
// E is not conserved when the scene has joint dampers, modal damping (a flexible body's), motors,
// external torques or prescribed joints; H when it has external torques or a prescribed base (a
// prescribed joint inside the tree is internal: H stays). Such an X is balanced instead of
// drift-checked (issue 26): each engine's own power P and external moment M (core/output_layout)
// say how it must change, so a damper or motor whose load is wrong in one engine's equations of
// motion fails there even when the three engines agree. Engine runs that fail are recorded as a
// failed "run" check (engine, time, reason) and left out of the pairwise comparison; an engine
// that is not built yet (make_engine throws InputError "... not built yet") is skipped with a note.
//
// Bounding runs (docs/stopping.md): CompareOptions::max_steps and ::timeout
// limit each engine run (its set-up included, for the timeout). A run that hits either is a
// failed "run" check ("engine kane failed at t = 1.23 s: timed out after 30 s", or "step limit
// reached"), and the other engines still run. An interrupt (Ctrl-C, SIGTERM) ends the whole
// comparison: compare_scene throws cancel::Cancelled (core/cancel.hpp).
//
// Memory: rows are not held per quantity. Each run keeps its rows in memory while the program's
// row budget allows and in an unlinked temporary file beyond it (core/rows.hpp); compare_runs then
// reads the runs' rows once in lockstep (row k of every run together) to find each check's largest
// error, its time and the scale, and once more, only for the checks that failed, to find where the
// error first exceeded the bound. The numbers are the same as comparing whole columns in memory.
//
// Reading a run's rows (the report, verify): EngineRun::result.reader() or
// result.for_each_row(f) give the rows in order, one at a time, wherever they are stored, so a
// run's CSV can be written without holding all its rows; result.rows() counts them. Do not index
// result.data directly: it is empty when the rows were moved to a temporary file.
#pragma once

#include "core/engine.hpp"
#include "core/integrate.hpp"
#include "core/system.hpp"

#include <optional>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace crossdyn::harness {

// One engine to run: its label in tables ("kane"), the registry name, and its options.
struct EngineSpec {
  std::string label;
  std::string engine;
  EngineOptions options;
};

struct CompareOptions {
  std::vector<EngineSpec> engines;          // empty: every engine of engine_names()
  std::optional<Choice<Integrator>> integrator;  // overrides of the scene's run block
  std::optional<double> rtol, atol, dt;
  bool analytic = true;                     // add "analytic" where System::analytic is set
  std::optional<long> max_steps;            // per run: IntegratorSettings::max_steps
  std::optional<double> timeout;            // per run, s of wall-clock time (set-up included)
  bool progress = false;                    // progress line on stderr (when it is a terminal)
  // The runs carry the rates of their own E and H (IntegratorSettings::rate_columns) and each
  // engine's P and M are checked against them row by row (E.rate, H.rate). Off for converge's
  // model runs, which compare states only.
  bool rates = true;
  // When checks fail and every engine's run finished, run the scene again at tolerances 100 times
  // tighter (adaptive integrators) and say, with the figures, whether the differences fall with
  // them (integration error) or stay (physics): diagnose(). Off for that second run.
  bool diagnose = true;
};

// The command-line options compare and verify share (harness/compare_command.cpp).
struct CompareCliOptions {
  std::string engines;                      // "kane,lagrange"; empty: all
  std::optional<std::string> integrator;
  std::optional<double> rtol, atol, dt;
  bool no_analytic = false;
  bool no_diagnosis = false;                // --no-diagnosis: no second run at tighter tolerances
  std::optional<long> max_steps;            // --max-steps N
  std::optional<double> timeout;            // --timeout SECONDS
  bool quiet = false;                       // --quiet: no progress line
  std::vector<std::string> test_inertia_scale;  // hidden: "ENGINE=FACTOR"
};
void add_compare_cli_options(CLI::App& sub, CompareCliOptions& o);
// Validates and converts; throws InputError naming the option and the bad value.
CompareOptions to_compare_options(const CompareCliOptions& o);

// Default rtol of E.rate and H.rate (their atol is the drift default): the difference of E along
// the motion, with its own error estimate in the bound, against P.
inline constexpr double kDefaultRateTolerance = 1e-7;
// Default drift tolerance (H.drift, E.drift) when the scene sets none.
inline constexpr double kDefaultDriftTolerance = 1e-9;

enum class CheckStatus { Pass, Fail, Excluded, Skipped };
const char* to_string(CheckStatus s);

struct Check {
  std::string quantity;   // "main.wx", "main.attitude", "H", "H.drift", "run", "t"
  std::string group;      // "w", "attitude", "angle", "position", "rate", "torque", "modal", "H",
                          // "E", "extra",
                          // "H.drift", "E.drift", "H.balance", "E.balance", "load", "run", "t"
  std::string a, b;       // engine labels: a compared with the reference b; b empty for one engine
  std::string tolerance_key;  // scene key the tolerance came from, or "default"
  Tolerance tolerance;
  double scale = 0;       // max_t |b| (attitude: 1; drift: |X(0)|)
  double bound = 0;       // atol + rtol * scale (+ allowance)
  double allowance = 0;   // balance: the estimated error of its quadrature (compare.cpp)
  double error = 0;       // max_t |a - b|, or max_t |X(t) - X(0)|
  double time = 0;        // s, where the largest error occurred (run: when the engine failed)
  std::optional<double> first_exceeded;  // s, first output time with error > bound
  double normalised = 0;  // error / bound
  CheckStatus status = CheckStatus::Pass;
  std::string note;       // reason for exclusion, skip or failure
};

struct EngineRun {
  std::string label;
  std::string engine;     // registry name, or "analytic"
  enum class State { Ok, Failed, NotBuilt };
  State state = State::Ok;
  std::string note;       // failure message or why it was skipped
  RunResult result;
};

struct SceneComparison {
  std::string scene;      // System::name
  std::string file;       // System::file
  IntegratorSettings settings;
  std::vector<EngineRun> runs;
  std::vector<Check> checks;
  std::vector<std::string> notes;

  bool passed() const;    // no check has status Fail
  int count(CheckStatus s) const;
};

// A pairwise or drift check's bound, normalised error and status from its error, scale and
// tolerance, by the pass rule above (what compare_runs does; merge re-judges parts with it).
void judge_check(Check& c);

// The compare logic on runs already sampled at the same output times (testable with synthetic
// RunResults): pairwise checks, drift checks, run-failure checks, exclusions, notes.
SceneComparison compare_runs(const System& system, std::vector<EngineRun> runs);

// Whether c failed with every engine's run complete (what diagnose() can tell apart).
bool diagnosable(const SceneComparison& c);
// A note on c from the same scene compared again at rtol, atol (100 times tighter), starting
// "tolerances 100 times tighter": either every failed check's difference fell at least 10-fold
// (integration error, with the largest one's figures, and whether everything passes there) or one
// did not (not integration error: the engines disagree there; the largest such). It replaces
// compare_runs' advice on loads. compare_scene calls it; a test can too.
void diagnose(SceneComparison& c, const SceneComparison& tight, double rtol, double atol);

// Runs the engines (and the analytic solution) on `system`, one after the other, then
// compare_runs. Throws InputError for bad options or an engine's complaint about the scene (other
// than "not built yet"), and cancel::Cancelled when the program is interrupted.
SceneComparison compare_scene(const System& system, const CompareOptions& options);

// The analytic torque-free solution as a run: pinned columns (t, w, q, H, E) at `times`.
RunResult analytic_run(const System& system, const std::vector<double>& times);

// Output times of a run: k * output_step for k = 0..n, plus the duration when not a multiple.
std::vector<double> output_times(const IntegratorSettings& settings);

// Why a scene's E (or H) is not conserved, or "" when it is.
std::string energy_not_conserved_reason(const System& system);
std::string momentum_not_conserved_reason(const System& system);
// On an orbit (issue 28): why the Jacobi integral J is not conserved, or "" when it is.
std::string jacobi_not_conserved_reason(const System& system);

// Human-readable table of every check (compare's output).
std::string format_comparison(const SceneComparison& c, bool failures_only = false);

// "1.23e-04" style number for tables ("0" for zero, "inf", "nan").
std::string sci(double v, int digits = 3);

// Rows of cells => left-aligned text columns separated by two spaces; row 0 is the header and is
// underlined.
std::string text_table(const std::vector<std::vector<std::string>>& rows);

}  // namespace crossdyn::harness
