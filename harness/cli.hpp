// The crossdyn program as a function: parses the command line, runs the command and maps every
// outcome to an exit status and a message (docs/outputs.md "Exit status"). main()
// (harness/main.cpp) adds only the signal handlers; the fuzz target (fuzz/cli_fuzzer.cpp) calls it
// in-process.
//
//   0   success                          1   a comparison failed (or compared nothing)
//   2   bad input: scene file, command line, an output that would overwrite an input or cannot
//       be written at all, a scene folder that cannot be read (filesystem errors)
//   3   a run failed, a write failed (disk full, I/O error), out of memory, an internal error
//   130 interrupted (Ctrl-C, SIGTERM)
//   141 standard output is a pipe whose reader went away (`crossdyn run x | head -1`): the
//       command stops at once, silently, with the status a process killed by SIGPIPE has
#pragma once

#include <exception>
#include <ostream>
#include <string>
#include <vector>

namespace CLI {
class Option;
}

namespace crossdyn {

inline constexpr int kExitInterrupted = 130;
inline constexpr int kExitBrokenPipe = 141;  // 128 + SIGPIPE

int crossdyn_main(int argc, char** argv);

// The exit status for an exception that ended a command, after writing its message to `err`.
int exit_status_for(const std::exception_ptr& e, std::ostream& err);

// "did you mean" for an unknown word among `known` (closest by edit distance, or `word` is a
// prefix of one); "" when none is close.
std::string closest_match(const std::string& word, const std::vector<std::string>& known);

// Makes `option` a comma-separated list option (--engines, --integrators, --tolerances, --dts,
// --values): an empty list (`--engines ''`) is refused, not read as "the default", and so are an
// empty item (`a,,b`, a trailing comma) and an item given twice (`kane,kane`): one rule for every
// list option (docs/command-line.md "Overrides and list options"). Numeric lists also refuse a
// value given twice in another spelling (1e-6,1e-06) where they are parsed (harness/study.cpp
// parse_values).
CLI::Option* list_option(CLI::Option* option);

// An integer option (--max-steps, --repeat, --panels, --max-links): its text must be a decimal
// whole number an int holds ("1e30", "0x10", "99999999999999999999" are refused with a sentence,
// never converted, saturated or read as octal). Applied to every INT option by crossdyn_main.
void whole_number_option(CLI::Option* option);

// Every option that takes a value refuses an empty one (`--scenarios ''` is an error, not the
// default folder; `--output ''`, `--report-script ''` likewise). Applied by crossdyn_main.
void non_empty_option(CLI::Option* option);

}  // namespace crossdyn
