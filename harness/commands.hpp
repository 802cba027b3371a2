// The crossdyn program's subcommands. Each add_*_command registers a CLI11 subcommand on `app`
// whose callback stores the command's exit status in `exit_code` (see core/errors.hpp ExitCode).
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace crossdyn {

namespace harness {
struct Part;
}

// What `crossdyn merge` writes from the parts of a sweep (study, stability).
struct SweepMergeOutputs {
  std::string csv;                    // --csv FILE
  std::optional<std::string> report;  // --report DIR
  std::string json;                   // --json FILE (converge)
  bool quiet = false;
};
// The merges of sharded sweeps: the parts checked (harness/shard.hpp check_parts), then exactly
// what the unsharded command writes. Return the exit status.
int merge_study_parts(const std::vector<harness::Part>& parts, const SweepMergeOutputs& out);      // study_command.cpp
int merge_stability_parts(const std::vector<harness::Part>& parts, const SweepMergeOutputs& out);  // stability_command.cpp
int merge_converge_parts(const std::vector<harness::Part>& parts, const SweepMergeOutputs& out);   // converge_command.cpp

void add_run_command(CLI::App& app, int& exit_code);      // harness/run_command.cpp
void add_compare_command(CLI::App& app, int& exit_code);  // harness/compare_command.cpp
void add_verify_command(CLI::App& app, int& exit_code);   // harness/verify_command.cpp
void add_merge_command(CLI::App& app, int& exit_code);    // harness/verify_command.cpp
void add_draw_command(CLI::App& app, int& exit_code);     // harness/draw_command.cpp
void add_list_command(CLI::App& app, int& exit_code);     // harness/list_command.cpp
void add_converge_command(CLI::App& app, int& exit_code); // harness/converge_command.cpp
void add_study_command(CLI::App& app, int& exit_code);    // harness/study_command.cpp
void add_stability_command(CLI::App& app, int& exit_code); // harness/stability_command.cpp
void add_linearize_command(CLI::App& app, int& exit_code); // harness/linearize_command.cpp

}  // namespace crossdyn
