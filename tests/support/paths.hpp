// Where tests find the committed scenes and the build's programs.
#pragma once

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

namespace crossdyn::test {

inline std::string source_dir() { return CROSSDYN_SOURCE_DIR; }
inline std::string binary_dir() { return CROSSDYN_BINARY_DIR; }
inline std::string scene_path(const std::string& name) {
  return source_dir() + "/scenarios/" + name + ".yaml";
}

// Every committed scene: the *.yaml and *.yml files of scenarios/ (not its data/ folder of modal
// files), sorted.
inline std::vector<std::string> committed_scenes() {
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(source_dir() + "/scenarios"))
    if (e.is_regular_file() && (e.path().extension() == ".yaml" || e.path().extension() == ".yml"))
      files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace crossdyn::test
