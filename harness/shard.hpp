// Sharding `crossdyn verify`, `study`, `stability` and `converge` across processes or machines,
// and merging the parts (docs/sharding.md). The unit of work: a scene (verify, study),
// a parameter value (stability), a model (converge); all are sliced by plan_units and their
// parts checked by check_parts. Study, stability and converge parts ("sweep parts") carry the
// command, its options and one JSON item per unit (sweep_part_json); the commands turn their
// results into items and back (the *_item_json / *_from functions below) and put them together
// as the unsharded command does (harness/*_command.cpp merge_*_parts).
//
// `verify --shard K/N --part FILE` (K = 0 .. N-1, zero-based like Slurm's SLURM_ARRAY_TASK_ID and
// GNU parallel's {%}-1) compares only the scenes of slice K and writes a part file (JSON, below).
// `crossdyn merge PARTS...` checks the parts belong together and writes exactly the summary table,
// JSON summary, JUnit XML and report that an unsharded `verify` over the same scenes writes.
//
// The slicing (assign_shards): each scene's identity is the SHA-256 of its file name (without
// folder) and its bytes, and its cost a static estimate (scene_cost). The scenes are sorted by
// cost (largest first; equal costs by identity) and each goes to the shard with the least cost so
// far (longest processing time first; equal loads: the lowest K). The result depends only on the
// set of scenes, never on the order they were named in, and is the same in every shard.
//
// The part file: {"tool": "crossdyn-part", "format": 1, "version": harness::version(),
// "command": "verify" (absent: verify), "shard": {"index": K, "count": N}, "scenes": [{"path",
// "sha256", "cost", "shard"} for every scene of the whole run, in the run's order], "outcomes": [the full SceneOutcome of every scene
// of slice K: the scene as read (write_scene_text), the comparison with its runs' rows, checks and
// notes, converge's result, the scene's warnings (all their fields; merge makes the geometry ones
// again from the scene and refuses a part without them)]}. Doubles are written in shortest round-trip form, and NaN and
// infinities as the strings "nan", "inf", "-inf", so a merged file carries the same numbers to
// the last bit. Run times (wall_seconds) are each part's own. A sweep part has "options" ([[option,
// value], ...]), "scenes" (the units, each with its "item"), "frame" and "items" instead.
#pragma once

#include "harness/converge.hpp"
#include "harness/report.hpp"
#include "harness/stability.hpp"
#include "harness/study.hpp"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace crossdyn::harness {

// --shard K/N: slice K (0-based) of N.
struct ShardSpec {
  int index = 0;
  int count = 1;
};
// Parses "K/N" (0 <= K < N, 1 <= N <= 10000); InputError naming --shard and the value otherwise.
ShardSpec parse_shard(const std::string& text);

// One unit of work of a sharded run, as listed in every part: a scene (verify, study), or one
// parameter value of a scene (stability: `item` names it, "value 2: 5000").
struct ShardScene {
  std::string path;    // as the command was given it (scene_files)
  std::string sha256;  // of the file's bytes; "" when it cannot be read
  double cost = 0;     // scene_cost, or the command's estimate
  int shard = 0;       // plan_units
  std::string item;    // "" for a whole scene; otherwise which part of it
};

// SHA-256 of a file's bytes, "" when it cannot be read.
std::string file_sha256(const std::string& path);

// The static cost estimate of comparing one scene: output rows (duration / output_step, or the
// rk4 steps duration / dt when more) x bodies x (1 + modes), times 3 engines, plus one kane run
// per converge model for flexible scenes (as verify runs them). 1 for a scene that cannot be read
// (it costs nothing but still has to land somewhere). Cheap: reads the scene, runs nothing.
double scene_cost(const std::string& path);

// The static cost estimate of one engine run of a scene as read: output rows (or rk4 steps)
// x bodies x (1 + modes). scene_cost is this times the runs verify makes; study and stability
// multiply it by their configurations (for stability on the scene with the value applied, so a
// longer duration or more links cost more).
double system_run_cost(const System& system);

// The scenes of a run (path, hash, cost) with their shard among `count` (see the file comment).
std::vector<ShardScene> plan_shards(const std::vector<std::string>& files, int count);
// The same for units whose path, item and cost are given: fills sha256 and shard. A unit's
// identity is the SHA-256 of its file name, its bytes and (when not empty) its item, so the
// slices do not depend on the order of the units.
std::vector<ShardScene> plan_units(std::vector<ShardScene> units, int count);

// The options a sweep's result depends on, as (option, value) pairs in a fixed order: every part
// of a run must carry the same (merge names the first that differs).
using PartOptions = std::vector<std::pair<std::string, std::string>>;

// A file the result depends on (a scene's nodal CSV data, ...) and its SHA-256 when the part
// was written.
struct PartInput {
  std::string path;
  std::string sha256;
};
// The files the units read besides their own files (a scene's nodal CSV data, resolved as the
// scene reader resolves them), each once, with its SHA-256 now ("" when it cannot be read).
// Every part carries them ("inputs"); merge refuses parts whose inputs differ or changed since.
std::vector<PartInput> unit_inputs(const std::vector<ShardScene>& units);

// A part file's text: the shard, every scene of the run and the outcomes of slice `shard`
// (`own`, in the run's order), the options the outcomes depend on and the inputs (unit_inputs).
std::string part_json(const ShardSpec& shard, const std::vector<ShardScene>& scenes,
                      const std::vector<SceneOutcome>& own, const PartOptions& options = {});

// A number in the shortest text that reads back the same ("1e-06", not 9.9999999999999995e-07);
// a list of them comma-separated, "(default)" when empty. For PartOptions.
std::string shortest_text(double value);
std::string shortest_list(const std::vector<double>& values);

// A part file of `study` or `stability` (command): the same header as verify's plus the options,
// a `frame` (JSON text the command needs to put the units back together; "null" for none) and one
// JSON text per unit of slice `shard`, in the run's order (`items`).
std::string sweep_part_json(const std::string& command, const PartOptions& options,
                            const ShardSpec& shard, const std::vector<ShardScene>& units,
                            const std::string& frame, const std::vector<std::string>& items);


struct Part {
  std::string file;  // where it was read from (messages)
  std::vector<PartInput> inputs;   // every file the units read besides the unit files themselves
  std::string version;
  std::string command = "verify";  // the crossdyn command that wrote it
  PartOptions options;             // sweep parts: the options of the run
  ShardSpec shard;
  std::vector<ShardScene> scenes;
  std::vector<SceneOutcome> outcomes;  // verify
  std::string frame = "null";          // sweep parts (JSON text)
  std::vector<std::string> items;      // sweep parts: one JSON text per unit of the slice
};
// The limits of merge's memory (docs/commands/merge.md, "Limits"): a part file larger than
// kMaxPartFileBytes is refused before it is read, and the parsed form of all the parts of one
// merge together may take at most kPartMemoryBudget (each value charged its DOM size while it is
// parsed, so a part that would pass it is refused before the memory is taken). Exit status 2.
inline constexpr std::uintmax_t kMaxPartFileBytes = std::uintmax_t{256} << 20;
inline constexpr std::size_t kPartMemoryBudget = std::size_t{256} << 20;

// Reads a part file; InputError naming the file and, for a part that is not well formed, the
// field ("/outcomes/0/comparison/runs/1/data") and what is wrong. `budget` (bytes): what the
// parts may still take (kPartMemoryBudget for all the parts of a merge), decreased by this one.
Part read_part(const std::string& file);
Part read_part(const std::string& file, std::size_t& budget);

// The whole run's outcomes, in the run's order, from parts that belong together (moved out of
// `parts`, whose outcomes are left empty: the run data is held once). Every outcome's checks
// and notes are made again from its scene and runs (compare_runs, require_comparison) and must
// equal the part's, field by field (InputError naming the part, scene, check and field). InputError
// (exit 2) naming what is wrong when they do not: another crossdyn version than `version`, a
// different N, a shard given twice (which K, which files) or missing (which K), different scene
// lists or scene hashes, or a scene file on disk that no longer matches its hash (checked for the
// files that can be found; `checked` is set to how many were).
std::vector<SceneOutcome> merge_parts(std::vector<Part>& parts, const std::string& version,
                                      int* checked = nullptr);
// The checks of merge_parts for parts of any command (also: parts of different commands, parts
// made with different options, naming the option and both values), then the items of every unit
// in the run's order (sweep parts).
void check_parts(const std::vector<Part>& parts, const std::string& version, int* checked = nullptr);
std::vector<std::string> merge_items(const std::vector<Part>& parts, const std::string& version,
                                     int* checked = nullptr);

// ---- The items of study and stability parts (JSON text, numbers exact as above) ----------------

// One scene of a sharded study: its study, or why it was refused and the exit status that gives.
struct StudyItem {
  std::optional<SceneStudy> study;
  std::string refused;
  int exit_status = 0;
};
std::string study_item_json(const StudyItem& item);
StudyItem study_item_from(const std::string& text);
// A stability map without its columns (the frame every part carries), and one value's column.
std::string stability_frame_json(const StabilityMap& frame);
StabilityMap stability_frame_from(const std::string& text);
std::string stability_value_json(const StabilityValue& value);
StabilityValue stability_value_from(const std::string& text);
// converge: the frame (scene, engine, groups, the full model) and one job's model (or the note
// saying why a slicing row was not made). A model is carried with its checks and verdict, not
// its run's rows (nothing converge writes uses them).
std::string converge_frame_json(const ConvergeResult& frame);  // frame.models: the full model only
ConvergeResult converge_frame_from(const std::string& text);
std::string converge_item_json(const std::optional<ConvergeModel>& model, const std::string& note);
std::pair<std::optional<ConvergeModel>, std::string> converge_item_from(const std::string& text);

}  // namespace crossdyn::harness
