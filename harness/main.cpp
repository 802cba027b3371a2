// crossdyn: run one multibody scene through independently written dynamics engines and compare.
// Exit status: 0 success, 1 a check failed, 2 bad input, 3 a run failed, 130 interrupted.
#include <CLI/CLI.hpp>

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "harness/commands.hpp"

#include <cstdio>
#include <iostream>
#include <string>

namespace {
constexpr int kExitInterrupted = 130;

// Ctrl-C or SIGTERM: whatever the command was doing, say so once and exit 130 (core/cancel.hpp;
// the watchdog exits the same way if this is not reached within cancel::kForcedExitDelay).
int interrupted(const std::string& where = "") {
  crossdyn::cancel::acknowledge_interrupt();
  std::cerr << "crossdyn: interrupted" << (where.empty() ? "" : " (" + where + ")") << '\n';
  return kExitInterrupted;
}
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
  crossdyn::cancel::install_signal_handlers("crossdyn");
  try {
    app.parse(argc, argv);
  } catch (const crossdyn::cancel::Cancelled&) {
    return interrupted();
  } catch (const CLI::ParseError& e) {
    if (crossdyn::cancel::interrupted()) return interrupted();
    const int code = app.exit(e);
    return code == 0 ? crossdyn::kExitOk : crossdyn::kExitBadInput;
  } catch (const crossdyn::InputError& e) {
    // An interrupted system call or child process can surface as an input error: 130 wins.
    if (crossdyn::cancel::interrupted()) return interrupted();
    std::cerr << "crossdyn: error: " << e.what() << '\n';
    return crossdyn::kExitBadInput;
  } catch (const crossdyn::RunFailure& e) {
    if (crossdyn::cancel::interrupted()) {
      char t[64];
      std::snprintf(t, sizeof t, "%.9g", e.time());
      return interrupted("engine " + e.engine() + " at t = " + t + " s");
    }
    std::cerr << "crossdyn: run failed: " << e.what() << '\n';
    return crossdyn::kExitRunFailed;
  }
  if (crossdyn::cancel::interrupted()) return interrupted();
  return exit_code;
}
