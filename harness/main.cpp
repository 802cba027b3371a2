// crossdyn: run one multibody scene through independently written dynamics engines and compare.
// The program itself is crossdyn_main (harness/cli.cpp: commands, messages, exit statuses); main
// installs the signal handlers and the forced-exit watchdog (core/cancel.hpp).
#include "core/cancel.hpp"
#include "harness/cli.hpp"

#include <unistd.h>

#include <cstring>
#include <exception>
#include <new>
#include <system_error>

namespace {

// Whatever ends in std::terminate (an exception leaving a thread or a noexcept function; above
// all std::bad_alloc where no handler can catch it) is exit status 3 with a one-line message,
// never an abort (SIGABRT, 134): docs/outputs.md "Exit status". Outputs are never half-written
// (they are temporaries until renamed); a temporary left behind is removed by the next run that
// writes there (core/output.hpp). Nothing here allocates.
[[noreturn]] void on_terminate() noexcept {
  const char* message = "crossdyn: internal error: the program cannot continue\n";
  const char* detail = nullptr;
  if (const std::exception_ptr e = std::current_exception()) {
    try {
      std::rethrow_exception(e);
    } catch (const std::bad_alloc&) {
      message = "crossdyn: error: out of memory (the work needs more memory than this process may use)\n";
    } catch (const std::system_error& x) {
      // A thread (the watchdog, core/cancel.cpp) that cannot be started: its stack is memory.
      if (x.code() == std::errc::resource_unavailable_try_again || x.code() == std::errc::not_enough_memory)
        message = "crossdyn: error: out of memory (cannot start a thread: its stack does not fit in "
                  "the memory this process may use)\n";
      else
        detail = x.what();
    } catch (const std::exception& x) {
      detail = x.what();
    } catch (...) {
    }
  }
  const auto say = [](const char* text) {
    const ssize_t ignored = ::write(2, text, std::strlen(text));
    (void)ignored;
  };
  if (detail) {
    say("crossdyn: internal error: ");
    say(detail);
    say("\n");
  } else {
    say(message);
  }
  ::_exit(3);
}

}  // namespace

int main(int argc, char** argv) {
  std::set_terminate(on_terminate);
  crossdyn::cancel::install_signal_handlers("crossdyn");
  return crossdyn::crossdyn_main(argc, argv);
}
