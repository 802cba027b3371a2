// A tiny program for tests/core/test_cancel.cpp: it installs crossdyn's signal handling, then does
// what the mode says, so that the safety net (forced exit) can be tested in a real process.
//   cancel_child block FILE   register FILE as a temporary, then wait without ever polling
//   cancel_child ack          wait for the interrupt flag, acknowledge it, then hang
//   cancel_child child        start `sleep 1000`, register it, print its pid, then hang
//   cancel_child poll         poll() in a loop; on Cancelled print its message and exit 130
//   cancel_child hold         hold the forced exit (outputs being renamed), raise SIGINT twice,
//                             outlive the forced-exit delay, print "held" on stderr, release
// Each mode prints "ready" on stdout once it is waiting.
#include "core/cancel.hpp"

#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <spawn.h>
#include <string>
#include <unistd.h>

extern char** environ;

namespace {
void hang() {
  for (;;) ::usleep(10'000);  // never polls
}
void ready() {
  std::printf("ready\n");
  std::fflush(stdout);
}
}  // namespace

int main(int argc, char** argv) {
  using namespace crossdyn;
  if (argc < 2) return 2;
  const std::string mode = argv[1];
  cancel::install_signal_handlers("cancel_child");
  if (mode == "block" && argc == 3) {
    std::ofstream(argv[2]) << "partial";
    if (cancel::register_temporary(argv[2]) < 0) return 3;
    ready();
    hang();
  } else if (mode == "ack") {
    ready();
    while (!cancel::interrupted()) ::usleep(1000);
    cancel::acknowledge_interrupt();
    std::fprintf(stderr, "acknowledged\n");
    hang();
  } else if (mode == "child") {
    pid_t pid = 0;
    char sleep_path[] = "/bin/sleep", arg[] = "1000";
    char* args[] = {sleep_path, arg, nullptr};
    if (::posix_spawn(&pid, sleep_path, nullptr, nullptr, args, environ) != 0) return 3;
    if (cancel::register_child(pid) < 0) return 3;
    std::printf("pid %d\n", static_cast<int>(pid));
    ready();
    hang();
  } else if (mode == "hold") {
    ready();
    {
      const cancel::HoldForcedExit hold;
      ::raise(SIGINT);
      ::raise(SIGINT);  // without the hold: _exit(130) here
      ::usleep(static_cast<useconds_t>(cancel::kForcedExitDelay * 2e6));  // past the watchdog's delay
      std::fprintf(stderr, "held\n");
    }  // the forced exit happens here
    std::fprintf(stderr, "not exited\n");
    return 0;
  } else if (mode == "poll") {
    ready();
    try {
      for (;;) cancel::poll();
    } catch (const cancel::Cancelled& c) {
      std::fprintf(stderr, "caught: %s\n", c.what());
      return 130;
    }
  }
  return 2;
}
