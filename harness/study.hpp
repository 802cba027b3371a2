// Speed against accuracy (issue 12, `crossdyn study`): a work-precision study of the engines and
// integrators on a scene, and the scaling of the right-hand-side cost with chain length.
//
// What is timed. For each scene x engine x integrator x tolerance (adaptive methods, rtol = atol
// = the tolerance) or step dt (rk4), the CPU time of one simulate() call (core/integrate.hpp):
// packing the initial state, every step and right-hand side, the engine's after_step(), and at
// every output time the engine's output row plus copying its pinned values into memory kept
// aside (IntegratorSettings::keep_rows = false: no CSV, no row store). The engine is constructed
// before the clock starts and the error is computed after it stops. CPU time is the run's own
// thread's (clock_gettime CLOCK_THREAD_CPUTIME_ID: the engines and integrators start no threads,
// so it is the run's whole cost, also while other runs go on in other threads, as in
// `stability --jobs`); the figure is the median of `repeat` runs, repeated interleaved (repeat 1
// of every configuration, then repeat 2, ...), all in this process.
//
// The error metric (one number per run, the same for the end state and the whole history).
// Every compared quantity q of the scene (compare.hpp's pinned quantities: body w components,
// body attitudes, joint angles and rates, modal coordinates and rates, H, E) has an error
//   e_q(t) = |x_q(t) - r_q(t)| / S_q          (attitude: rotation angle between x and r / S_q)
// against the reference r, where the scale S_q is the size of q's kind of motion in the reference:
//   body w components      S = max_t |w_body(t)|   (the body's angular velocity vector)
//   attitudes, joint angles S = max(1 rad, how far it turned in the reference): a joint angle's
//                          max_t |theta(t) - theta(0)|, a body's integral of |w_NB| dt (an
//                          angle's error grows with its size: rtol |theta|, and rounding)
//   joint rates            S = max over the scene's joints and t of |rate| or |w_PC_C|
//   modal coordinates      S = max over the body's modes and t of |eta|  (rates likewise)
//   H, E                   S = max_t |H|, max_t |E|, at least sum_b I_b w_b and sum_b I_b w_b^2 / 2
//                          (I_b = trace(I_BBo_B) / 2, w_b its body's w scale): a scene whose H is
//                          zero is judged against its bodies' momentum, not rounding noise
// (S = 1 when the reference's whole kind is zero). The end-state error is max_q e_q(T), the
// history error max_q max_t e_q(t) over the output times.
//
// The reference. A scene with an analytic solution (System::analytic = torque-free) uses it
// (compare.hpp analytic_run). Otherwise every engine is run with two integrators (rkf78 and dop853)
// at the tightest tolerance (rtol 1e-13, atol 1e-17); every pair of these runs must agree to
// StudyOptions::reference_agreement (history error,
// same metric, scales from the first run) or the study refuses the scene (StudyRefused: which
// pair, by how much, on which quantity). The reference is then the mean of these runs (attitudes:
// the mean quaternion, normalised), so no configuration is measured against itself. The
// reference runs have their own time budget (StudyOptions::reference_timeout, 600 s each),
// independent of the per-run timeout; a refusal because of it says so.
//
// A configuration that fails (step limit, step-size underflow, non-finite state, timeout) is a row
// with its failure reason, not an abort; an interrupt ends the study (cancel::Cancelled).
#pragma once

#include "core/system.hpp"
#include "harness/compare.hpp"

#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace crossdyn {
class ProgressLine;
}

namespace crossdyn::harness {

class StagedFolder;  // harness/report.hpp

// The study refuses a scene: the reference could not be made (engines disagree: exit status 1;
// a reference run failed: 3).
class StudyRefused : public std::runtime_error {
 public:
  StudyRefused(const std::string& what, int exit_status)
      : std::runtime_error(what), exit_status_(exit_status) {}
  int exit_status() const { return exit_status_; }

 private:
  int exit_status_;
};

// Pinned values of a run at its output times: rows x columns (pinned_columns(system) order).
struct History {
  std::vector<double> data;
  std::size_t columns = 0;
  std::size_t rows() const { return columns ? data.size() / columns : 0; }
  const double* row(std::size_t k) const { return data.data() + k * columns; }
};

// The pinned values of a finished run's rows (every engine writes the pinned columns first).
History pinned_history(const System& system, const RunResult& run);

// How a run differs from the reference (see the header comment).
struct StudyError {
  double end = std::numeric_limits<double>::quiet_NaN();
  double history = std::numeric_limits<double>::quiet_NaN();
  std::string end_quantity, history_quantity;
};

// The error metric: the quantities of a scene and their scales from the reference.
class ErrorMetric {
 public:
  ErrorMetric(const System& system, const History& reference);
  // Error of `run` against the reference (rows beyond the shorter of the two are not compared).
  StudyError error(const History& run) const;
  // Error of `a` against `b` with this metric's scales (the reference-agreement check).
  StudyError error(const History& a, const History& b) const;
  // The scale S_q of a compared quantity, by name ("hub.wx", "hub.attitude", "H"), NaN for a
  // name the metric does not compare. converge judges its models' changes with it (--accuracy).
  double scale(const std::string& quantity) const;

 private:
  struct Quantity {
    std::string name;
    std::vector<int> columns;  // into the pinned columns (attitude: qw qx qy qz)
    bool attitude = false;
    double scale = 1;
  };
  std::vector<Quantity> quantities_;
  const History* reference_;
};

struct StudyOptions {
  std::vector<std::string> engines;      // empty: every engine of engine_names()
  // When not empty, the configurations' engines instead (a label per variant, e.g.
  // "newton-euler:none" with its stabilisation; StudyRow::engine is the label).
  std::vector<EngineSpec> engine_specs;
  std::vector<std::string> integrators;  // empty: every integrator of integrator_names()
  std::vector<double> tolerances;        // adaptive methods: rtol = atol = each; empty: 1e-4..1e-13
  std::vector<double> dts;               // rk4 steps; empty: output step / 2^k, k = 0..7
  int repeat = 3;                        // timed runs per configuration (median)
  std::optional<long> max_steps;         // per run
  double timeout = 60;                   // per run, s of wall-clock time (0: none)
  // The reference when the scene has no analytic solution.
  // empty: the engines studied (`engines`, or every engine when that is empty), default options
  std::vector<EngineSpec> reference_engines;
  // rkf78 lands on every output time; dop853's dense output is of order 7. (dopri5's is of order
  // 4 and not error-controlled: at 1e-13 its interpolated outputs were the reference's worst
  // error, 1.8e-6 on a 60 s scene, issue 24.)
  std::vector<std::string> reference_integrators{"rkf78", "dop853"};
  double reference_tolerance = 1e-13;  // rtol
  // The reference runs' atol = reference_tolerance x this: the error control is relative for
  // every component down to 1e-4 of the tolerance. With atol = rtol a component of small size
  // (a panel's modal rate of 5e-6 /s) is controlled only absolutely, to 2e-8 of itself per step:
  // the reference runs of such a scene differed by 2e-5 of its scale (issue 24).
  double reference_atol_factor = 1e-4;
  // The reference runs' largest pairwise history error (their spread, the reference's own error
  // estimate) the study accepts. Above it the scene is refused: with the default, 1e-5, the
  // loosest target (1e-4) would be measured against a reference less than ten times better.
  // Below it every target at least kReferenceMargin x the spread is measured and the others are
  // declined with the reason (recommendation()).
  double reference_agreement = 1e-5;
  // 0: every reference engine with every reference integrator. N > 0: N runs only, the first N
  // usable reference engines each with the next reference integrator in turn (kane + dop853,
  // newton-euler + rkf78), or, when one engine is usable, that engine with the first N
  // integrators (`stability`: two independent runs, not six).
  int reference_run_limit = 0;
  std::optional<long> reference_max_steps;  // the reference runs' step limit (empty: max_steps)
  // Each reference run's own time budget, s of wall-clock time (0: none): independent of the
  // per-run `timeout`, which is for the configurations (issue 23, class 11: a tiny --timeout
  // must not leave the study without a reference).
  double reference_timeout = 600;
  bool use_analytic = true;
  // The accuracies a user asks (`study --accuracy`): a recommendation for each, the cheapest
  // configuration whose end-state error (this header's metric, relative to each quantity's scale)
  // is within it. Empty: recommendation_targets(). Not the scene's compare tolerances, which say
  // whether the engines agree.
  std::vector<double> targets;
  // > 0: a configuration run whose pace shows it cannot finish within its step limit is
  // ended early as too costly (IntegratorSettings::give_up_factor; `stability` uses it). 0: every
  // run goes to its limits.
  double give_up_factor = 0;
  ProgressLine* progress = nullptr;      // optional progress display
};

// The default tolerances: 1e-4, 1e-5, ..., 1e-13.
std::vector<double> default_tolerances();
// "1e-4..1e-13" (one per decade, either direction) or "1e-4,1e-6,1e-8"; InputError naming
// `option` for anything else (non-positive, not a number, more than 40 values).
std::vector<double> parse_values(const std::string& text, const std::string& option, bool allow_range);
// "kane,lagrange": names from `known`, each once, in the order given; InputError naming `option`
// and the `noun` ("engine") for an empty, unknown or repeated name. Empty text: none.
std::vector<std::string> parse_names(const std::string& text, const std::string& option,
                                     const std::vector<std::string>& known, const std::string& noun);

struct StudyRow {
  std::string engine, integrator;
  bool fixed_step = false;      // rk4: dt is the setting; otherwise tolerance
  double tolerance = 0, dt = 0;
  bool ok = false;
  std::string failure;          // why the run failed (ok = false)
  double cpu_median = 0, cpu_min = 0, cpu_max = 0;  // s
  int repeats = 0;
  long rhs_calls = 0, steps = 0, rejected = 0;
  StudyError error;
  // Conservation drift of the run itself: max_t |X(t) - X(0)| / max(|X(0)|, 1e-300) for X = H
  // and E (NaN when the run failed). Meaningful only where the scene conserves X.
  double drift_H = std::numeric_limits<double>::quiet_NaN();
  double drift_E = std::numeric_limits<double>::quiet_NaN();  // on an orbit: of J (the Jacobi integral)
  bool front_end = false, front_history = false;  // on the Pareto front (cpu, error)
  std::string setting() const;  // "rtol 1e-08" or "dt 0.0125"
};

struct StudyReference {
  std::string kind;                 // "analytic" or "engines"
  std::string description;          // one sentence for tables and the report
  std::vector<std::string> runs;    // "kane + rkf78 at 1e-13", ...
  double agreement = 0;             // worst pairwise history error of the reference runs
  // Worst pairwise end-state error: the reference's own error at the end, against which the
  // end-state targets are measured (history targets: `agreement`). NaN: not known (an old part).
  double agreement_end = std::numeric_limits<double>::quiet_NaN();
  // The spread the targets of one kind are measured against: agreement_end for end-state
  // targets where known, else agreement.
  double spread(bool history) const {
    return history || !(agreement_end >= 0) ? agreement : agreement_end;
  }
  std::string worst_pair;           // "lagrange + dopri5 vs kane + rkf78"
  double cpu_seconds = 0;           // making the reference (not part of any row)
};

struct SceneStudy {
  std::string scene, file;
  double duration = 0, output_step = 0;
  StudyReference reference;
  std::vector<double> targets;      // the accuracies recommendations are made for (StudyOptions)
  std::vector<StudyRow> rows;
  std::vector<std::string> notes;   // engines not built, and the like
};

// Runs the study on one scene. Throws StudyRefused when the reference cannot be made,
// InputError for bad options, cancel::Cancelled when interrupted.
SceneStudy study_scene(const System& system, const StudyOptions& options);

// ---- The study in pieces ----
// What study_scene does, for a caller that runs the pieces itself, for example on several
// threads (`stability --jobs`): the reference runs are independent of each other, and so are the
// chains of configurations once the reference is made. study_scene is
//   StudySetup u = study_setup(system, options);
//   runs[i] = study_reference_run(u, i)            for each of u.reference_runs (none: analytic)
//   StudyBaseline b = study_baseline(u, runs);     ErrorMetric metric(u.system, b.history);
//   for each chain of u.chains, in its order: study_skip_reason, else study_run_row
//   study_set_cpu on every row
// The pieces share nothing mutable but the rows each chain writes (u.rows[chain[k]]): two threads
// may run two chains of one setup at once. Progress is drawn only through options.progress,
// which is not thread-safe: leave it null when running pieces on several threads.
struct StudyReferenceRun {
  EngineSpec spec;
  std::string integrator;
  std::string label;  // "kane + rkf78 at 1e-13"
};
struct StudySetup {
  System system;
  StudyOptions options;
  IntegratorSettings settings;          // the scene's run: keep_rows false, the options' max_steps
  std::vector<double> times;            // the output times
  std::size_t pinned = 0;               // pinned columns
  int H = -1, E = -1;                   // their H and E columns
  bool analytic = false;                // the reference is the analytic solution
  std::vector<StudyReferenceRun> reference_runs;  // empty when analytic
  std::vector<EngineSpec> specs;        // the configurations' engines
  std::vector<StudyRow> rows;           // the configurations, not yet run
  // Indices into rows, each run in its order: one rk4 engine x integrator's steps (a shorter step
  // after a too costly one is not run), or one adaptive configuration alone.
  std::vector<std::vector<std::size_t>> chains;
  std::vector<std::string> notes;       // engines left out, with the reason
};
struct StudyBaseline {
  StudyReference reference;  // cpu_seconds not set
  History history;
};
// InputError for bad options; engines that cannot run the scene are left out (notes).
StudySetup study_setup(const System& system, const StudyOptions& options);
// One reference run's history; StudyRefused when it fails.
History study_reference_run(const StudySetup& setup, std::size_t i);
// The reference from the runs (in reference_runs order), or the analytic solution; StudyRefused
// when the runs disagree by more than options.reference_agreement (or fewer than two).
StudyBaseline study_baseline(const StudySetup& setup, const std::vector<History>& runs);
// Why rows[chain[k]] is not run (an rk4 step shorter than one of its chain that went past the
// step or time limit), or "".
std::string study_skip_reason(const std::vector<StudyRow>& rows, const std::vector<std::size_t>& chain,
                              std::size_t k);
// Runs `row` once; `first`: its first run, which sets ok, failure, the counts, error and drift.
// Returns the run's CPU time, s (cancel::Cancelled when interrupted).
double study_run_row(const StudySetup& setup, const ErrorMetric& metric, StudyRow& row, bool first);
// The row's CPU figures from its runs' times (median, min, max, repeats) when it finished.
void study_set_cpu(StudyRow& row, const std::vector<double>& cpu);

// The Pareto front of points (cost, error): true where no other point has cost <= and
// error <= with one of them strictly smaller. Points with a non-finite cost or error are never on
// it. Errors below `floor` count as `floor` (error 0 and 1e-17 are the same accuracy).
std::vector<bool> pareto_front(const std::vector<double>& cost, const std::vector<double>& error,
                               double floor = 1e-16);
// Sets every row's front_end and front_history; errors below the reference's accuracy
// (max(1e-15, reference.agreement)) count as equal.
void mark_fronts(SceneStudy& s);

// True when the row's step size was set by the output times, not by its own setting: rkf78 (and
// rk4) end a step at every output time (core/integrate.hpp), so when rkf78 took at most 10 % more
// steps than there are output intervals, nearly every step ended at an output time and its error
// measures the output step, not its tolerance; rk4 with dt above the output step takes the output
// step. The dense methods (dopri5, dop853, bulirsch-stoer, cvode-*) interpolate the output times
// and are never capped.
bool step_set_by_output_times(const SceneStudy& s, const StudyRow& r);

// The cheapest row (least median CPU) whose end-state error (or history error) is <= target.
std::optional<std::size_t> cheapest_within(const SceneStudy& s, double target, bool history = false);
// "for 1e-08 end-state error on spear1_case1 use kane + dopri5 at rtol 1e-09: 0.41 ms of CPU", or
// what the study found instead when no configuration reaches the target.
std::string recommendation(const SceneStudy& s, double target, bool history = false);
// The default accuracies recommendations are made for (`--accuracy`): 1e-4, 1e-6, 1e-8, 1e-10.
const std::vector<double>& recommendation_targets();
// A target is measured only when it is at least this many times the reference's own error (the
// spread of the reference runs): below that, the reference's error would be part of what is
// measured.
inline constexpr double kReferenceMargin = 10;
// The smallest target the study's reference supports: 0 for an analytic reference, else
// kReferenceMargin x the reference runs' spread (at the end for end-state targets, over the run
// for history targets: StudyReference::spread).
double smallest_supported_target(const SceneStudy& s, bool history = false);

// Text table (fits 100 columns), the reference and the recommendations.
std::string format_study(const SceneStudy& s);
// CSV: the header line (study_csv_header) and one line per row; `scene` in every line.
std::string study_csv_header();
std::string study_csv_rows(const SceneStudy& s);

// ---- The scaling of the right-hand side with chain length (chainN, docs/scenarios.md Scene 3) ----

// The chainN scene as YAML (what scripts/make_chain.py N writes).
std::string chain_scene_text(int links);

// Least-squares slope of log(y) against log(x) over the upper half of the points (by x; the
// middle point of an odd count included); NaN with fewer than two usable (positive, finite) points.
double fit_exponent(const std::vector<double>& x, const std::vector<double>& y);

struct ScalingOptions {
  std::vector<std::string> engines;  // empty: every engine
  int max_links = 128;
  double budget = 0.2;               // s of CPU per point (at least min_batches batches)
  int min_batches = 5;
  ProgressLine* progress = nullptr;
};
struct ScalingPoint {
  int links = 0;
  double seconds_per_call = 0;  // median over batches of batch CPU / calls
  long calls = 0;
  bool ok = true;
  std::string note;
  // The engine's linear solve at the initial state (harness/conditioning.hpp): its condition
  // number (NaN: the engine gives no system) and size, and the deviation of the engine's
  // accelerations from the closest other engine's (NaN with one engine).
  double condition = std::numeric_limits<double>::quiet_NaN();
  int system_size = 0;
  double accel_deviation = std::numeric_limits<double>::quiet_NaN();
};
struct ScalingLine {
  std::string engine;
  std::vector<ScalingPoint> points;
  double exponent = std::numeric_limits<double>::quiet_NaN();
  double condition_exponent = std::numeric_limits<double>::quiet_NaN();  // fit_exponent of kappa
  std::string system;  // Engine::LinearSystem::what at the largest N
};
struct ScalingStudy {
  std::vector<int> links;  // 2, 4, 8, ... up to max_links, and max_links
  std::vector<ScalingLine> lines;
  double budget = 0;
};
// The link counts: 2, 3, 4, 6, 8, 12, 16, ... (a factor of about 1.5) up to max_links.
std::vector<int> scaling_links(int max_links);
ScalingStudy scaling_study(const ScalingOptions& options);
std::string format_scaling(const ScalingStudy& s);
std::string scaling_csv(const ScalingStudy& s);

// ---- Output ----

// The JSON the report script reads (reports/make_report.py, "kind": "study").
std::string study_json(const std::vector<SceneStudy>& scenes, const std::optional<ScalingStudy>& scaling,
                       const std::string& what_is_timed);
// What is timed, one paragraph (the help text, the report, the JSON).
const std::string& study_timing_text();
// What the error is, one paragraph.
const std::string& study_error_text();

// The report folder, in two steps (harness/report.hpp StagedFolder): stage_study_report, before
// the work, refuses (InputError) a DIR that is a file, or a non-empty folder without a crossdyn
// study.json, and makes the staging folder; write_study_report writes study.json,
// <scene>-study.csv, scaling.csv there and runs the report script, which writes index.html,
// <scene>-study.html and the PNG charts; commit_together then swaps the folder in (the files
// of DIR that a study report does not own are kept).
std::unique_ptr<StagedFolder> stage_study_report(const std::string& dir);
void write_study_report(StagedFolder& dir, const std::vector<SceneStudy>& scenes,
                        const std::optional<ScalingStudy>& scaling,
                        const std::string& python = "/usr/bin/python3");

}  // namespace crossdyn::harness
