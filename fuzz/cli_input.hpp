// The input format of the command-line fuzz target (fuzz/cli_fuzzer.cpp) and of its regression
// inputs (fuzz/cli_regressions/, replayed by tests/cli/test_fuzz_regressions.cpp):
//
//     one argument per line          e.g.  run
//     ...                                  scene.yaml
//     %%                                   --duration=0.1
//     the scene text                       %%
//                                          name: x ...
//
// The scene text is written to scene.yaml and scenarios/scene.yaml in a scratch folder, which is
// the current folder of the command. Inputs outside the fuzzed space are refused (nullopt), so that
// nothing is written outside the scratch folder and no other program runs: more than 24
// arguments or one longer than 200 bytes, a '/' (but in --shard's K/N) or a NUL in an argument
// (paths stay inside the folder), an argument starting with "..", and the options that run programs (--report,
// --report-script, --python).
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace crossdyn::fuzz {

struct CliInput {
  std::vector<std::string> args;  // without the program name
  std::string scene;
};

inline std::optional<CliInput> parse_cli_input(std::string_view data) {
  CliInput in;
  std::size_t pos = 0;
  bool scene = false;
  while (pos < data.size()) {
    std::size_t end = data.find('\n', pos);
    if (end == std::string_view::npos) end = data.size();
    const std::string_view line = data.substr(pos, end - pos);
    pos = end + 1;
    if (line == "%%") {
      scene = true;
      break;
    }
    in.args.emplace_back(line);
  }
  if (scene && pos < data.size()) in.scene = std::string(data.substr(pos));
  if (in.args.size() > 24) return std::nullopt;
  // "K/N" after --shard (or in --shard=K/N) is a slice, not a path: its '/' is allowed.
  const auto slice = [](std::string_view v) {
    const std::size_t at = v.find('/');
    if (at == std::string_view::npos || at == 0 || at + 1 == v.size()) return false;
    for (std::size_t k = 0; k < v.size(); ++k)
      if (k != at && (v[k] < '0' || v[k] > '9')) return false;
    return true;
  };
  for (std::size_t i = 0; i < in.args.size(); ++i) {
    const std::string& a = in.args[i];
    const bool shard_value = (i > 0 && in.args[i - 1] == "--shard" && slice(a)) ||
                             (a.rfind("--shard=", 0) == 0 && slice(std::string_view(a).substr(8)));
    if (a.size() > 200 || (a.find('/') != std::string::npos && !shard_value) ||
        a.find('\0') != std::string::npos || a.rfind("..", 0) == 0 || a.rfind("--report", 0) == 0 ||
        a.rfind("--python", 0) == 0)
      return std::nullopt;
  }
  return in;
}

}  // namespace crossdyn::fuzz
