// Where each method fails (issue 13, `crossdyn stability`): a map of engine x integrator x step
// size (or tolerance) against one scene parameter, each cell classified, with the findings in
// words: where it fails, how, and the remedy.
//
// The sweep. For each value v of the parameter (a Knob: a hinge spring's stiffness, a joint's
// initial rate (a rotor speed), a prescribed joint's final rate, a flexible body's modal-stiffness
// scale, the run's duration, or the number of links of chainN), the scene with that value is
// studied exactly as `crossdyn study` does (harness/study.hpp, one timed run per configuration):
// the same reference (analytic, or the engines' agreement at 1e-13, here required to half the
// accuracy limit rather than the study's 1e-11), the same error metric
// (history error: max over quantities and output times of |x - r| / the quantity's scale).
//
// The reference runs have their own time budget (StabilityOptions::reference_timeout, default
// 600 s each, `--reference-timeout`), independent of the per-run `--timeout`: a tiny --timeout
// makes cells too costly, never a whole column "no reference"; the map's notes say so.
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
//   <joint>.stiffness         a revolute or spherical joint's spring stiffness, N m/rad
//   <joint>.rate              a revolute joint's initial rate (a rotor's speed), rad/s
//   <joint>.prescribed_rate   a prescribed joint's final rate Omega_s, rad/s
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
                    Duration, Links };
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
