// The crossdyn program's subcommands. Each add_*_command registers a CLI11 subcommand on `app`
// whose callback stores the command's exit status in `exit_code` (see core/errors.hpp ExitCode).
#pragma once

namespace CLI {
class App;
}

namespace crossdyn {

void add_run_command(CLI::App& app, int& exit_code);      // harness/run_command.cpp
void add_compare_command(CLI::App& app, int& exit_code);  // harness/compare_command.cpp
void add_verify_command(CLI::App& app, int& exit_code);   // harness/verify_command.cpp
void add_merge_command(CLI::App& app, int& exit_code);    // harness/verify_command.cpp
void add_draw_command(CLI::App& app, int& exit_code);     // harness/draw_command.cpp
void add_list_command(CLI::App& app, int& exit_code);     // harness/list_command.cpp
void add_converge_command(CLI::App& app, int& exit_code); // harness/converge_command.cpp
void add_study_command(CLI::App& app, int& exit_code);    // harness/study_command.cpp
void add_stability_command(CLI::App& app, int& exit_code); // harness/stability_command.cpp

}  // namespace crossdyn
