// Running the crossdyn program from a test: its exit status and everything it printed.
#pragma once

#include "tests/support/paths.hpp"

#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace crossdyn::test {

struct ProgramResult {
  int status = -1;     // exit status, -1 when it did not exit normally
  std::string output;  // stdout and stderr together
};

// Runs `<build>/crossdyn ARGS` through the shell (ARGS must be quoted by the caller) in `dir`.
inline ProgramResult run_crossdyn(const std::string& args, const std::string& dir = source_dir()) {
  const std::string cmd = "cd '" + dir + "' && '" + binary_dir() + "/crossdyn' " + args + " 2>&1";
  ProgramResult r;
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.output.append(buf, n);
  const int st = ::pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

}  // namespace crossdyn::test
