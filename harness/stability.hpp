// Where each method fails (issue 13, `crossdyn stability`): a map of engine x integrator x step
// size (or tolerance) against one scene parameter, each cell classified, with the findings in
// words: where it fails, how, and the remedy.
//
// The sweep. For each value v of the parameter (a Knob: a hinge spring's stiffness, a joint's
// initial rate (a rotor speed), a prescribed joint's final rate, a flexible body's modal-stiffness
// scale, the run's duration, or the number of links of chainN), the scene with that value is
// studied as `crossdyn study` does (harness/study.hpp, one timed run per configuration, the same
// error metric: history error, max over quantities and output times of |x - r| / the quantity's
// scale), against a reference of its own.
//
// The reference of each value (issue 24, item 4): the analytic solution where the scene has one;
// otherwise the mean of two independent runs, two engines (kane and newton-euler first: minimal
// and maximal coordinates, the cheapest pair; else the map's first two), each with its own
// integrator (dop853, rkf78; a map of one engine: that engine with both), at rtol = atol =
// kReferenceTolerancePerLimit (1e-6) x the accuracy limit, within 1e-13 to 1e-8: 1e-12 for a
// limit of 1e-6. Their agreement (their history error against each other) is the reference's
// stated error, in each column's note; it must be at most half the accuracy limit, as before, and
// where it is above kReferenceRetry (0.1) x the limit (or they disagree beyond half of it) both are
// made again at 1e-13. Not the study's six runs at 1e-13 (every engine with rkf78 and dopri5):
// a map needs a reference somewhat better than its limit, and dopri5 at 1e-13 was the costliest
// run of most maps. Why 1e-6 x the limit and not looser: two runs can err alike (the same
// under-resolved fast mode), and their agreement then understates their error; on
// hub_flex_array with K x 100, two runs at 1e-10 agreed to 3.7e-8 but moved cells near the limit
// of 1e-6 by 7e-8 against the six runs at 1e-13; at 1e-12 they agree to 1.5e-9 (the six: 3.5e-10).
//
// The reference runs have their own time budget (StabilityOptions::reference_timeout, default
// 600 s each, `--reference-timeout`), independent of the per-run `--timeout`: a tiny --timeout
// makes cells too costly, never a whole column "no reference"; the map's notes say so.
//
// How the work is done (stability_values). The values are independent, and so are their cells
// once the value's reference is made: every reference run of every value, then, as each value's
// reference is made, its cells (an rk4 engine x integrator's steps in order, one chain: a shorter
// step after a too costly one is not run; each adaptive cell alone) go on a queue that
// StabilityOptions::jobs threads (`--jobs`, default the number of cores) take from. The engines,
// integrators and cancellation keep no shared mutable state (checked: no function-local statics
// or globals but constants, cancel::Deadline per thread, a CVODE context per run), each run's CPU
// time is its own thread's (study.hpp), and the map is put together in the order of the values:
// the same map for any number of threads, but for CPU times and what a wall-clock limit stops
// (with more threads than free cores, each run gets less of a core in the same wall-clock time).
// Ctrl-C ends every run (cancel::poll in each thread) and the command as before (exit 130, no
// outputs).
//
// Runs stopped as soon as their class is decided (StabilityOptions::give_up_factor, default
// kGiveUpFactor = 5; IntegratorSettings::give_up_factor): at every tenth of the step limit from
// the second on, a run's pace over the last tenth is extrapolated to the duration; one that would
// need more than 2 x the steps left ends at once as too costly, its reason saying "stopped early"
// with the prediction. Its class is the one it would earn at the limit unless its pace improved
// more than 2-fold for the rest of the run (on the committed examples, not one class changed);
// its steps and right-hand sides are those made until it stopped. The time limit (--timeout) is
// left to the wall clock: a pace in wall-clock seconds misjudged a run whose steps lengthened
// later (and depends on the machine's load). A run whose error passed the diverged limit, or
// whose drift passed the drift limit, is not stopped early: it could still fail later (too
// costly, singular), which would change its class.
//
// The classes (classify(); first match wins):
//   no reference  the reference could not be made at this value (the study refused it): such a
//                 column is a finding of its own, with the study's reason; its cells ('?') count
//                 in no class and get no remedy
//   singular      the run stopped at an Euler-angle singularity or gimbal lock (lagrange without
//                 re-charting)
//   too costly    the run hit the step limit or the time limit
//   diverged      the run stopped on a non-finite or exploding state, a non-positive-definite
//                 mass matrix or a step-size underflow; or it finished with a history error above
//                 ClassLimits::diverged_error (10: the error ten times the motion itself, which
//                 only a growing state gives; a wrong phase stays below 2)
//   drift         finished, but the relative drift of H or E, where the scene conserves it, is
//                 above ClassLimits::drift_limit (while the error may still be small)
//   accurate      history error <= ClassLimits::tolerance, the accuracy asked (`--accuracy`,
//                 default kStabilityAccuracy = 1e-6; issue 24: what a user asks of an
//                 integration, not the scene's compare tolerances, which check that the engines
//                 agree)
//   inaccurate    anything else that finished
//
// The stiffness of each column. |lambda|max, the spectral radius of the Jacobian d xdot / dx of
// each engine's right-hand side at the initial state (central differences, step 1e-6 (1 + |x_j|)),
// is the rate the fastest motion of that engine's state sets (engines differ: newton-euler's
// state holds a rotor's fast attitude, kane's and lagrange's only its constant rate): rk4's stability region reaches |h lambda| ~ 2.8 (2.83 on
// the imaginary axis, 2.79 on the real one; Hairer and Wanner, Solving ODEs II, Sec. IV.2), so
// a step above 2.8 / |lambda|max diverges. The findings quote h |lambda|max for every rk4 cell.
#pragma once

#include "core/system.hpp"
#include "harness/study.hpp"

#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace crossdyn {
class ProgressLine;
}

namespace crossdyn::harness {

class StagedFolder;  // harness/report.hpp


enum class StabilityClass { Accurate, Inaccurate, Drift, Diverged, Singular, TooCostly, NoReference };
inline constexpr StabilityClass kStabilityClasses[] = {
    StabilityClass::Accurate, StabilityClass::Inaccurate, StabilityClass::Drift,
    StabilityClass::Diverged, StabilityClass::Singular,   StabilityClass::TooCostly,
    StabilityClass::NoReference};
// "accurate", "inaccurate", "drift", "diverged", "singular", "too costly", "no reference".
const char* class_name(StabilityClass c);

// What a cell's classification looks at.
struct CellFacts {
  bool reference = true;      // false: no reference at this parameter value
  bool ok = false;            // the run finished
  std::string failure;        // why it did not (RunFailure text); without a reference, why none
                              // could be made (the study's refusal)
  double history_error = std::numeric_limits<double>::quiet_NaN();
  double drift_H = std::numeric_limits<double>::quiet_NaN();
  double drift_E = std::numeric_limits<double>::quiet_NaN();
  bool H_conserved = false, E_conserved = false;  // by the scene (compare.hpp's reasons empty)
  bool orbit = false;  // drift_E is the Jacobi integral J's (E_conserved: J's, on an orbit)
};

// The default of `stability --accuracy`: a history error of 1e-6 of each quantity's scale. Tighter
// than converge's 1e-3 (a model's purpose) because the map is about how methods fail: at 1e-3
// nearly every cell of a stable run would be accurate.
inline constexpr double kStabilityAccuracy = 1e-6;

struct ClassLimits {
  double tolerance = 1e-6;      // history error at most this: accurate
  double drift_limit = 1e-6;    // relative drift of a conserved H or E above this: drift
  // History error above this: diverged. Ten times the motion's own size: only growth does that
  // (a wrong phase or a damped amplitude stays below 2).
  double diverged_error = 10.0;
};

struct Classified {
  StabilityClass cls = StabilityClass::Inaccurate;
  std::string why;  // one phrase: "history error 3.2e-05 > 1e-06", "step limit reached ..."
};
Classified classify(const CellFacts& facts, const ClassLimits& limits);

// The swept scene parameter (`--vary`):
//   <joint>.stiffness         a revolute, spherical or prismatic joint's spring stiffness, N m/rad
//                             (prismatic N/m); a universal joint's, both axes at once
//   <joint>.rate              a revolute joint's initial rate (a rotor's speed), rad/s; a
//                             prismatic joint's, m/s
//   <joint>.prescribed_rate   a prescribed spin-up's final rate Omega_s, rad/s (prismatic m/s)
//   <joint>.prescribed_travel a prescribed deployment's travel, rad (prismatic m)
//   <joint>.wx, .wy, .wz      a free joint's initial angular velocity component w_NB_B, rad/s
//                             (how close a tumbling base passes to an Euler-angle lock)
//   <body>.modal_stiffness    a flexible body's modal stiffness K, scaled by the value
//   <body>.modal_damping      a flexible body's modal damping ratio zeta, the same for every mode:
//                             D = diag(2 zeta sqrt(K_kk M_kk)), M_kk = sum_i m_i |Phi_ik|^2 (the
//                             node-sum modal mass; K diagonal, as the beam generator makes it)
//   duration                  the run's duration (the horizon), s
//   links                     the number of links of chainN (the scene must be a chainN)
struct Knob {
  enum class Kind { JointStiffness, JointRate, PrescribedRate, BaseRate, ModalStiffness, ModalDamping,
                    Duration, Links, PrescribedTravel };  // (part files store the number: append)
  Kind kind = Kind::Duration;
  std::string spec;         // as given: "hinge.stiffness"
  int index = -1;           // the joint or body
  int component = 0;        // BaseRate: 0, 1, 2 for x, y, z
  std::string unit;         // "N m/rad", "rad/s", "" (a scale), "s", "" (links)
  std::string description;  // "the spring stiffness of joint 'hinge'"
};
// Parses `spec` against the scene; InputError naming what is wrong and listing the knobs the
// scene has.
Knob parse_knob(const System& system, const std::string& spec);
// The scene with the knob set to `value` (InputError when the value is out of range).
System apply_knob(const System& system, const Knob& knob, double value);
// The knobs this scene offers, for messages and --help ("hinge.stiffness", "duration", ...).
std::vector<std::string> available_knobs(const System& system);
// "--set KNOB=VALUE": the scene with that knob set before the sweep (several may be given, applied
// in order). InputError naming the option for a malformed setting, an unknown knob or a bad value.
System apply_setting(const System& system, const std::string& setting);
// Every --set in order, a knob set twice refused.
System apply_settings(const System& system, const std::vector<std::string>& settings);
// --values: a list 1,10,100 or a range 1..1e4 (one per decade); InputError naming --values.
// (harness/stability_command.cpp; linearize's --vary uses it too.)
std::vector<double> parse_parameter_values(const std::string& text);

struct StabilityCell {
  std::string engine, integrator;
  bool fixed_step = false;
  double setting = 0;           // dt (rk4) or rtol = atol
  std::size_t column = 0;       // into StabilityMap::columns
  CellFacts facts;              // what `result` was classified from (parts carry it: merge re-classifies)
  Classified result;
  double history_error = std::numeric_limits<double>::quiet_NaN();
  double cpu = 0;               // s, one run
  long rhs_calls = 0, steps = 0;
  double h_lambda = std::numeric_limits<double>::quiet_NaN();  // rk4: dt |lambda|max (its engine's)
  std::string setting_text() const;  // "dt 0.0125" or "rtol 1e-08"
};

struct StabilityColumn {
  double value = 0;
  bool reference = true;
  std::string reference_note;  // why there is none, or the reference's description
  // |lambda|max per engine (StabilityMap::engines order), 1/s: each engine's own state, so an
  // engine that integrates a fast rotor's attitude (newton-euler) sees its speed here.
  std::vector<double> lambda_max;
};

struct StabilityMap {
  std::string scene, file;
  Knob knob;
  std::vector<StabilityColumn> columns;  // one per parameter value, in the order given
  std::vector<StabilityCell> cells;
  ClassLimits limits;
  std::vector<std::string> engines, integrators;  // in map order
  std::vector<std::string> findings;  // per engine x integrator: where, how, remedy (sentences)
  std::vector<std::string> notes;
};

// The reference of a value: two runs at rtol = atol = this x the accuracy limit (within 1e-13 to
// 1e-8), made again at 1e-13 when they agree to less than kReferenceRetry x the limit.
inline constexpr double kReferenceTolerancePerLimit = 1e-6;
inline constexpr double kReferenceRetry = 0.1;
// StabilityOptions::give_up_factor's default. 5 before the stop of 2026-11-27; at 2 and at 1.5 not
// one class changed in the 8 committed example maps (1,862 cells, compared cell by cell), and the
// maps took 76 s instead of 81 (the 1000 s dopri5 runs at 1e-12 that end at their step limit
// stopped at a fifth of it). 2: a run stopped early would have needed its pace to double for the
// rest of the run to finish within the limit.
inline constexpr double kGiveUpFactor = 2;

struct StabilityOptions {
  std::vector<std::string> engines;      // empty: every engine
  // Engine variants (label, engine, options), e.g. "newton-euler:none": when not empty, these
  // instead of `engines` (parse_engine_variants).
  std::vector<EngineSpec> engine_specs;
  std::vector<std::string> integrators;  // empty: rk4, dopri5, dop853, cvode-bdf
  std::vector<double> tolerances;        // empty: 1e-3, 1e-6, 1e-9, 1e-12
  std::vector<double> dts;               // empty: output step / 1, 2, 4, ..., 64
  std::optional<double> tolerance;       // --accuracy: the accurate class's limit; empty: kStabilityAccuracy
  double drift_limit = 1e-6;
  std::optional<long> max_steps = 200000;
  double timeout = 20;                   // per run, s
  // Each reference run's own budget, s (0: none), independent of `timeout` (StudyOptions).
  double reference_timeout = 600;
  // A run whose pace shows it needs more than this many times the steps left of its step limit
  // is stopped early as too costly (IntegratorSettings::give_up_factor; 0: every run goes to its
  // limits).
  double give_up_factor = kGiveUpFactor;
  // Runs at once, on this many threads (`--jobs`; 1: the calling thread only). The map is the
  // same for any number (cells, classes, errors, counts), but for the CPU times and what a
  // wall-clock limit (--timeout, --reference-timeout) stops.
  int jobs = 1;
  ProgressLine* progress = nullptr;
};

// Runs the sweep. Throws InputError for bad options, cancel::Cancelled when interrupted.
StabilityMap stability_scene(const System& system, const Knob& knob, const std::vector<double>& values,
                             const StabilityOptions& options);

// The sweep in pieces (what stability_scene does; `stability --shard` runs some values, `merge`
// puts them back): the map without columns, one value's column with its cells (column 0) and the
// notes it adds, and appending a value to the map (its cells' column set, its notes added in
// stability_scene's way). After the last value, set the findings (stability_findings).
struct StabilityValue {
  StabilityColumn column;
  std::vector<StabilityCell> cells;
  std::vector<std::string> study_notes;  // the study's notes: added when not in the map yet
  std::string refused_note;              // no reference: "at <knob> = <value>: why"
};
StabilityMap stability_frame(const System& system, const Knob& knob, const StabilityOptions& options);
StabilityValue stability_value(const System& system, const Knob& knob, double value,
                               const StabilityMap& frame, const StabilityOptions& options);
// Several values at once (what stability_scene and `stability --shard` run): every value's
// reference runs and cells on options.jobs threads, the values in the order given.
std::vector<StabilityValue> stability_values(const System& system, const Knob& knob,
                                             const std::vector<double>& values,
                                             const StabilityMap& frame, const StabilityOptions& options);
void add_stability_value(StabilityMap& map, StabilityValue value);

// "kane,newton-euler:none,newton-euler:baumgarte,lagrange:no-rechart": engines, each optionally
// with a variant (newton-euler: none | baumgarte | projection, its constraint stabilisation;
// lagrange: no-rechart). InputError naming `option` for anything else.
std::vector<EngineSpec> parse_engine_variants(const std::string& text, const std::string& option);

// |lambda|max of `engine`'s right-hand side at the scene's initial state (see the header); NaN
// when the engine cannot be made or the Jacobian is not finite.
double jacobian_spectral_radius(const System& system, const std::string& engine);

// The findings (StabilityMap::findings) from the cells.
std::vector<std::string> stability_findings(const StabilityMap& map);

// Text: the maps as character grids (one per engine), the legend and the findings.
std::string format_stability(const StabilityMap& map);
std::string stability_csv(const StabilityMap& map);
// JSON (kind "stability") and the report folder (index.html, <scene>-stability.html, maps as PNG).
std::string stability_json(const std::vector<StabilityMap>& maps);
// In two steps, as study's (study.hpp stage_study_report): stage before the work, write into the
// staged folder after it, commit_together swaps it in.
std::unique_ptr<StagedFolder> stage_stability_report(const std::string& dir);
void write_stability_report(StagedFolder& dir, const std::vector<StabilityMap>& maps,
                            const std::string& python = "/usr/bin/python3");

}  // namespace crossdyn::harness
