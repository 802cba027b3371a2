// docs/scene-format.md cannot drift from the schema: its key reference is generated from
// core/scene/schema.cpp (tests/scene/scene_doc.cpp), and every key of its tables is a key of the
// schema and the reverse. The documents travel with the repository: none points outside it.
#include "core/scene/schema.hpp"
#include "tests/scene/generated_block.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

using namespace crossdyn;
namespace fs = std::filesystem;

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The first cells of every table whose header starts "| key |", without their backticks.
std::set<std::string> table_keys(const std::string& md) {
  std::set<std::string> keys;
  std::istringstream in(md);
  std::string line;
  bool key_table = false;
  while (std::getline(in, line)) {
    if (!line.starts_with("|")) {
      key_table = false;
      continue;
    }
    if (line.starts_with("| key |")) {
      key_table = true;
      continue;
    }
    if (!key_table || line.starts_with("| ---")) continue;
    const std::size_t a = line.find('`'), b = line.find('`', a + 1);
    if (a != std::string::npos && b != std::string::npos && a < line.find('|', 1))
      keys.insert(line.substr(a + 1, b - a - 1));
  }
  return keys;
}

}  // namespace

TEST_CASE("docs/scene-format.md holds the key reference generated from the schema") {
  const std::string doc = slurp(test::source_dir() + "/docs/scene-format.md");
  const auto block = test::generated_block(doc);
  REQUIRE(block);
  INFO("regenerate: build/tests/scene/crossdyn_scene_doc --write-docs docs/scene-format.md");
  CHECK(*block == scene::markdown_reference());
}

TEST_CASE("every key of the schema is in docs/scene-format.md, and every key there is in the "
          "schema") {
  const std::set<std::string> documented =
      table_keys(slurp(test::source_dir() + "/docs/scene-format.md"));
  std::set<std::string> schema;
  for (const scene::Key& k : scene::keys())
    if (!k.path.empty()) schema.insert(std::string(k.path));
  for (const std::string& k : schema) {
    INFO("in the schema, not in the document: " << k);
    CHECK(documented.count(k) == 1);
  }
  for (const std::string& k : documented) {
    INFO("in the document, not in the schema: " << k);
    CHECK(schema.count(k) == 1);
  }
}

TEST_CASE("the documents the repository relies on are in it, and none points outside it") {
  std::vector<fs::path> files{test::source_dir() + "/README.md"};
  for (const char* name : {"scene-format.md", "conventions.md", "scenarios.md"}) {
    const fs::path p = test::source_dir() + "/docs/" + name;
    CHECK(fs::exists(p));
    files.push_back(p);
  }
  for (const char* dir : {"/scenarios", "/docs"})
    for (const auto& e : fs::directory_iterator(test::source_dir() + dir))
      if (e.is_regular_file()) files.push_back(e.path());
  for (const fs::path& p : files) {
    INFO(p);
    CHECK(slurp(p).find("../shared") == std::string::npos);
  }
  // The figure docs/scene-format.md shows is committed with the script that draws it.
  CHECK(fs::exists(test::source_dir() + "/docs/figures/joint_frames.png"));
  CHECK(fs::exists(test::source_dir() + "/docs/figures/make_figures.py"));
}
