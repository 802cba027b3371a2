// crossdyn: run one multibody scene through independently written dynamics engines and compare.
// Exit status: 0 success, 1 a check failed, 2 bad input, 3 a run failed, 130 interrupted.
#include <CLI/CLI.hpp>

#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "harness/commands.hpp"

#include <csignal>
#include <iostream>

namespace {
extern "C" void on_sigint(int) { crossdyn::request_interrupt(); }
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "crossdyn: can I trust this simulation? Runs one multibody spacecraft scene through three\n"
      "independently written dynamics engines (Kane, Lagrange with quasi-coordinates,\n"
      "Newton-Euler) and shows where they agree.\n\n"
      "Exit status: 0 success, 1 a comparison failed, 2 bad input, 3 a run failed, 130 interrupted."};
  app.require_subcommand(1);
  int exit_code = crossdyn::kExitOk;
  crossdyn::add_run_command(app, exit_code);
  crossdyn::add_compare_command(app, exit_code);
  crossdyn::add_verify_command(app, exit_code);
  crossdyn::add_draw_command(app, exit_code);
  std::signal(SIGINT, on_sigint);
  std::signal(SIGTERM, on_sigint);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? crossdyn::kExitOk : crossdyn::kExitBadInput;
  } catch (const crossdyn::InputError& e) {
    std::cerr << "crossdyn: error: " << e.what() << '\n';
    return crossdyn::kExitBadInput;
  } catch (const crossdyn::RunFailure& e) {
    std::cerr << "crossdyn: run failed: " << e.what() << '\n';
    return e.reason() == "interrupted" ? 130 : crossdyn::kExitRunFailed;
  }
  return exit_code;
}
