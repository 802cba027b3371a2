// crossdyn: run one multibody scene through independently written dynamics engines and compare.
// The program itself is crossdyn_main (harness/cli.cpp: commands, messages, exit statuses); main
// installs the signal handlers and the forced-exit watchdog (core/cancel.hpp).
#include "core/cancel.hpp"
#include "harness/cli.hpp"

int main(int argc, char** argv) {
  crossdyn::cancel::install_signal_handlers("crossdyn");
  return crossdyn::crossdyn_main(argc, argv);
}
