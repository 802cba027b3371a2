// Where tests find the committed scenes and the build's programs.
#pragma once

#include <string>

namespace crossdyn::test {

inline std::string source_dir() { return CROSSDYN_SOURCE_DIR; }
inline std::string binary_dir() { return CROSSDYN_BINARY_DIR; }
inline std::string scene_path(const std::string& name) {
  return source_dir() + "/scenarios/" + name + ".yaml";
}

}  // namespace crossdyn::test
