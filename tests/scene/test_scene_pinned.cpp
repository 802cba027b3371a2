// The committed scenes read to the same System as the reader that first accepted them.
//
// tests/scene/pinned/<scene>.yaml is write_scene_text's output for scenarios/<scene>.yaml, written
// by the reader of commit 1aca500 (before the reader moved to core/scene/) and, for a scene added
// later, by the reader that added it. Every number there is SI in its shortest round-trip form, so
// reading it gives the bits that reader produced; any change in how a committed scene is read
// (units, defaults, centre-of-mass shifts, joint order) shows here as a field that differs.
// Regenerate a pin only when a scene's physics is meant to change, and say so in the commit.
#include "core/scene/scene.hpp"
#include "tests/scene/system_equal.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

using namespace crossdyn;
namespace fs = std::filesystem;

namespace {

std::set<std::string> stems(const fs::path& dir) {
  std::set<std::string> s;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".yaml") s.insert(e.path().stem().string());
  return s;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST_CASE("every committed scene has a pin, and every pin a scene") {
  const fs::path scenes = test::source_dir() + "/scenarios";
  const fs::path pins = test::source_dir() + "/tests/scene/pinned";
  CHECK(stems(scenes) == stems(pins));
  CHECK(stems(scenes).size() >= 10);
}

TEST_CASE("every committed scene reads to its pinned System, field by field") {
  const fs::path pins = test::source_dir() + "/tests/scene/pinned";
  for (const std::string& name : stems(pins)) {
    INFO(name);
    const std::string path = test::scene_path(name);
    const System now = read_scene(path);
    const System pinned = read_scene_text(slurp(pins / (name + ".yaml")), path);
    CHECK(test::system_difference(now, pinned) == "");
  }
}
