// crossdyn: run one multibody scene through independently written dynamics engines and compare.
// The program itself is crossdyn_main (harness/cli.cpp: commands, messages, exit statuses); main
// adds the signal handlers.
#include "core/integrate.hpp"
#include "harness/cli.hpp"

#include <csignal>

namespace {
extern "C" void on_sigint(int) { crossdyn::request_interrupt(); }
}  // namespace

int main(int argc, char** argv) {
  std::signal(SIGINT, on_sigint);
  std::signal(SIGTERM, on_sigint);
  return crossdyn::crossdyn_main(argc, argv);
}
