// docs/scene-format.md cannot drift from the schema: its key reference is generated from
// core/scene/schema.cpp (tests/scene/scene_doc.cpp), and every key of its tables is a key of the
// schema and the reverse. The documents travel with the repository: no file of it points outside it.
#include "core/scene/schema.hpp"
#include "tests/scene/generated_block.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

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

namespace {

// Text that points outside the repository: the shared folder next to a developer's clone, or an
// absolute path of the machine it was written on. Written in two pieces so that this file does not
// hold them.
const std::string kOutside[] = {std::string("../") + "shared", std::string("/") + "work/"};

// 1-based numbers of the lines of `text` that hold one of kOutside.
std::vector<std::size_t> outside_lines(const std::string& text) {
  std::vector<std::size_t> lines;
  std::istringstream in(text);
  std::string line;
  for (std::size_t n = 1; std::getline(in, line); ++n)
    for (const std::string& o : kOutside)
      if (line.find(o) != std::string::npos) {
        lines.push_back(n);
        break;
      }
  return lines;
}

// Every file of the repository, relative to the source tree: `git ls-files` when the tree is a git
// checkout, else every file found walking it (not .git, build trees, generated reports).
std::vector<std::string> repository_files() {
  std::vector<std::string> files;
  const std::string cmd = "git -C '" + test::source_dir() + "' ls-files -z 2>/dev/null";
  if (FILE* f = ::popen(cmd.c_str(), "r")) {
    std::string out;
    char buf[4096];
    for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, f)) > 0;) out.append(buf, n);
    const int status = ::pclose(f);
    std::istringstream in(out);
    if (status == 0)
      for (std::string name; std::getline(in, name, '\0');)
        if (!name.empty()) files.push_back(name);
  }
  if (!files.empty()) return files;
  const fs::path root = test::source_dir();
  for (auto it = fs::recursive_directory_iterator(root); it != fs::recursive_directory_iterator();
       ++it) {
    const fs::path rel = fs::relative(it->path(), root);
    if (it->is_directory() &&
        (rel.filename() == ".git" || fs::exists(it->path() / "CMakeCache.txt") ||
         rel == "reports/latest" || rel == "reports/example/data")) {
      it.disable_recursion_pending();
      continue;
    }
    if (it->is_regular_file()) files.push_back(rel.string());
  }
  return files;
}

}  // namespace

TEST_CASE("outside_lines finds every line that points outside the repository") {
  const std::string text = std::string("fine\nsee ../") + "shared/STYLE.md\nok\n/" +
                           "work/main/x\n../share is fine\n";
  CHECK(outside_lines(text) == std::vector<std::size_t>{2, 4});
  CHECK(outside_lines("docs/style.md item 3\n").empty());
}

TEST_CASE("the documents the repository relies on are in it, and none points outside it") {
  for (const char* name : {"scene-format.md", "conventions.md", "scenarios.md", "style.md",
                           "references.md", "flexible-bodies.md"})
    CHECK(fs::exists(test::source_dir() + "/docs/" + name));
  // Every source, script, document and data file (binary files, such as pictures, are skipped).
  const std::vector<std::string> files = repository_files();
  REQUIRE(files.size() > 100);
  std::size_t scanned = 0;
  for (const std::string& name : files) {
    const std::string text = slurp(test::source_dir() + "/" + name);
    if (text.find('\0') != std::string::npos) continue;
    ++scanned;
    for (std::size_t line : outside_lines(text))
      FAIL_CHECK(name << ":" << line << ": points outside the repository (its own docs/ hold "
                      "the style, the scenes, the conventions and the references)");
  }
  CHECK(scanned > 100);
  // The figure docs/scene-format.md shows is committed with the script that draws it.
  CHECK(fs::exists(test::source_dir() + "/docs/figures/joint_frames.png"));
  CHECK(fs::exists(test::source_dir() + "/docs/figures/make_figures.py"));
}
