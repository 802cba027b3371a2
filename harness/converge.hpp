// Model no more than a scene needs (issue 11, `crossdyn converge SCENE`): re-run a flexible scene
// with fewer modes and report how much each compared quantity changes, then name the smallest
// model that stays within the scene's tolerances.
//
// Mode groups. A flexible body's modes are grouped by their name without its trailing digits
// (the beam generator's `qx1, qx2` are the group `qx`: the bending plane of x; a nodal file's
// `bend1, bend2, torsion1` give `bend` and `torsion`). A model keeps the first c_g modes of every
// group g (c_g = 0 .. n_g, in the order the modes are listed), so every combination of counts is
// one model; the full model (every c_g = n_g) is the reference.
//
// Truncation (core/system.hpp FlexBody): keeping the mode subset S of a body keeps the columns S
// of every node's Phi_B and Psi_B, the rows and columns S of K, D and every node's G; the nodes, their masses,
// positions and rigid inertias are unchanged, so the rigid body (and every rigid quantity) is the
// same. This is a Galerkin (Ritz) truncation of the same modal basis: the model with fewer modes
// is exactly the full model with the dropped modal coordinates held at zero.
//
// Comparison. Each model is run by one engine (default kane) with the scene's run settings, and
// compared with the full model's run by compare_runs (harness/compare.hpp): every quantity of the
// smaller model's output layout (so the modal coordinates the smaller model keeps are compared
// too). The verdict is the accuracy a user asks of the model (`--accuracy`, default
// kConvergeAccuracy = 1e-3; issue 24), not the scene's compare tolerances (those say whether the
// engines agree, i.e. whether the code is right): each quantity's change is measured as the
// study's error metric measures an error (harness/study.hpp ErrorMetric: |model - full| over the
// scale S_q of q's kind of motion in the full model's run; attitudes: the rotation angle, rad),
//   relative change = max_t |x_q,model(t) - x_q,full(t)| / S_q,
// and a model is within the accuracy when its largest relative change is at most the accuracy.
// Quantities the metric does not judge (extra columns, excluded quantities) are shown, not judged.
// The change as a multiple of the compare tolerance (Check::normalised) is kept in the JSON. The
// smallest model is the model within the accuracy with the fewest modes (ties: the first in the
// table's order, which lists fewer modes of earlier groups first).
//
// Slicing. A body made by the beam generator (its FlexBody::scene_form is a `beam:` block) is
// also re-generated with half and twice its slices (every mode kept; the scene is written with
// write_scene_text and read back, so the reader's checks apply) and compared with the full model
// the same way: these rows say whether the slicing has converged, and do not compete for the
// smallest model.
//
// A re-sliced row is the same physical model with another discretisation: every joint point at a
// node of the beam stays at the same point of the beam (issue 23, class 7). `bottom` and `top`
// are the ends at any slicing. A slice node `slice<i>` is the centre of slice i, and halving or
// doubling N never makes it a slice centre again (slice30 of 60 is 0.033 m short of the middle;
// slice30 of 30 is at the tip, and of 120 at a quarter), so the re-sliced beam gets a massless
// node at exactly that point, named `<node>-of-<N>`, carrying the closed-form shape, slope and
// foreshortening of the continuous beam there (the generator's modes do not depend on the
// slicing; under unit-modal-mass normalisation they are rescaled with the new normalisation), and
// the joint is attached to it (parent side or child side, any joint type); a note says so. A
// joint point given as a point (`parent_point`/`child_point`) on a flexible body is fixed in the
// body frame, whose origin (the CM of a uniform beam) does not move with the slicing, so it is
// the same point already. Only the beam's mass lumping changes, so the slicing rows measure the
// discretisation error alone, and the "observed order" line (the change from N/2 to N over the
// change from N to 2N, 2^p for an error ~ N^-p; printed only when N is even) is its order: 2 for
// the midpoint sampling of the modal integrals.
#pragma once

#include "core/system.hpp"
#include "harness/compare.hpp"

#include <optional>
#include <string>
#include <vector>

namespace crossdyn::harness {

// One mode group of one flexible body.
struct ModeGroup {
  int body = -1;               // System::bodies index
  std::string name;            // "qx"
  std::vector<int> modes;      // the body's mode indices in this group, in order
};
std::vector<ModeGroup> mode_groups(const System& system);

// The system with, for each group g, only the first counts[g] modes of the group kept.
System truncate_modes(const System& system, const std::vector<ModeGroup>& groups,
                      const std::vector<int>& counts);

// "beam qx2 qy0" (bodies named; groups in mode_groups order).
std::string model_label(const System& system, const std::vector<ModeGroup>& groups,
                        const std::vector<int>& counts);

struct ConvergeModel {
  std::vector<int> counts;     // per group
  int modes = 0;               // total modes kept
  std::string label;
  bool full = false;           // the reference
  int slices = 0;              // > 0: a slicing row (the beam re-generated with this many slices)
  int slice_body = -1;         // the body of a slicing row
  EngineRun run;
  std::vector<Check> checks;   // against the full model (pairwise checks only)
  // Per check, the scale S_q of its quantity in the full model's run (study.hpp's metric); NaN
  // for a check the metric does not judge. relative change = Check::error / S_q.
  std::vector<double> scales;
  double worst_relative = 0;   // max over judged checks of the relative change (0 for the full model)
  std::string worst_quantity;  // where it is ("run: ..." when the run did not reach the end)
  double worst_normalised = 0; // max over checks of error / compare bound (the scene's tolerances)
  bool passed = false;         // ran to the end, worst_relative <= the accuracy (the full model: ran)
};

// The default of `converge --accuracy`: a model within 0.1 % of the full model's motion.
inline constexpr double kConvergeAccuracy = 1e-3;

// The verdict of a model that ran from its checks and scales: worst_relative, worst_quantity,
// worst_normalised and passed against `accuracy` (merge recomputes parts' models with it).
void judge_converge_model(ConvergeModel& m, double accuracy);

struct ConvergeResult {
  std::string scene;
  std::string engine;
  std::vector<ModeGroup> groups;
  double accuracy = kConvergeAccuracy;  // --accuracy: the largest relative change within it
  std::vector<ConvergeModel> models;  // the full model first, then every other model
  int smallest = -1;                  // index into models of the smallest passing model
  std::vector<std::string> notes;     // slicing rows that could not be made, and why
};

// The system with the beam-generator body `body` re-generated with `slices` slices, or nullopt
// when the body is not a beam-generator body. Throws InputError when the reader refuses it.
// Every joint at a node of the body keeps its physical point (see "Slicing" above); for each
// joint that needed a massless node, *kept (when given) gets a sentence saying so.
std::optional<System> reslice(const System& system, int body, int slices,
                              std::vector<std::string>* kept = nullptr);

// At most this many models (the product of (n_g + 1) over the groups); more is an InputError.
inline constexpr int kMaxConvergeModels = 256;

// Runs every model with `options.engines[0]` (the one engine) and compares each with the full
// model. Throws InputError when the scene has no flexible body with modes, or too many models;
// cancel::Cancelled when interrupted.
ConvergeResult converge_scene(const System& system, const CompareOptions& options,
                              double accuracy = kConvergeAccuracy);

// converge_scene in pieces (`converge --shard` runs some models, `merge` puts them back): the
// result without models (scene, engine, groups) and the jobs of the scene in table order (every
// model but the full one, then the slicing rows); the full model (RunFailure when it does not
// run to the end); one job against the full model's run (nullopt, with `note` set when the
// reader refuses it, for a slicing row that cannot be made); and, after the models are in
// place (the full model first), the smallest model.
struct ConvergeJob {
  std::vector<int> counts;
  int slice_body = -1;  // a slicing row: the beam-generator body re-generated
  int slices = 0;       // with this many slices (0: a model with `counts` modes)
};
ConvergeResult converge_frame(const System& system, const CompareOptions& options,
                              std::vector<ConvergeJob>* jobs, double accuracy = kConvergeAccuracy);
ConvergeModel converge_full_model(const System& system, const ConvergeResult& frame,
                                  const CompareOptions& options);
std::optional<ConvergeModel> converge_job(const System& system, const ConvergeResult& frame,
                                          const ConvergeJob& job, const EngineRun& full_run,
                                          const CompareOptions& options, std::string* note);
void converge_finish(ConvergeResult& result);

// The table (one row per model: modes, largest relative change and its quantity, within the
// accuracy or not) and the conclusion line.
std::string format_converge(const ConvergeResult& r);

// JSON: scene, engine, accuracy, groups, models (label, counts, modes, passed, worst relative
// change and its quantity, worst normalised, checks with their relative change), smallest.
std::string converge_json(const ConvergeResult& r);

}  // namespace crossdyn::harness
