// The input format of the merge fuzz target (fuzz/part_fuzzer.cpp) and of its regression inputs
// (fuzz/part_regressions/):
//
//     the merge's arguments, one per line      e.g.  part0.json
//     %%                                             part1.json
//     the scene text (scene.yaml)                    --json
//     %%                                             m.json
//     part0.json's text                              %%
//     %%                                             name: x ...
//     part1.json's text ...                          %%
//                                                    {"tool": "crossdyn-part", ...}
//
// At most 4 parts. The argument rules are the command-line target's (fuzz/cli_input.hpp): at
// most 24 arguments of at most 200 bytes, no '/', no NUL, none starting with "..", and not the
// options that run programs (--report, --report-script, --python); otherwise nullopt.
#pragma once

#include "fuzz/cli_input.hpp"

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace crossdyn::fuzz {

struct PartInput {
  std::vector<std::string> args;  // after "merge"
  std::string scene;
  std::vector<std::string> parts;
};

inline std::optional<PartInput> parse_part_input(std::string_view data) {
  constexpr std::string_view kSeparator = "\n%%\n";
  constexpr std::size_t kMaxParts = 4;
  // The arguments and the separator line, as the command-line format reads them.
  const auto cli = parse_cli_input(data);
  if (!cli) return std::nullopt;
  PartInput in;
  in.args = cli->args;
  // The rest: the scene, then the parts, separated by "%%" lines.
  std::string_view rest = cli->scene;
  std::vector<std::string_view> sections;
  while (true) {
    const std::size_t at = rest.find(kSeparator);
    if (at == std::string_view::npos) {
      sections.push_back(rest);
      break;
    }
    sections.push_back(rest.substr(0, at + 1));
    rest = rest.substr(at + kSeparator.size());
  }
  if (sections.size() > 1 + kMaxParts) return std::nullopt;
  in.scene = std::string(sections.front());
  for (std::size_t k = 1; k < sections.size(); ++k) in.parts.emplace_back(sections[k]);
  return in;
}

}  // namespace crossdyn::fuzz
