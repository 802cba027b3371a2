// crossdyn draw SCENE [-o FILE.png]: a PNG of the scene, written atomically, never over an input;
// bad input is refused with exit status 2 before any run and without creating a file.
#include <catch2/catch.hpp>

#include "tests/harness/run_program.hpp"
#include "tests/support/paths.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

namespace {

const std::string kPanels = crossdyn::test::source_dir() + "/tests/harness/scenes/hinged_panels.yaml";

std::string read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

bool is_png(const fs::path& p) { return read_bytes(p).rfind("\x89PNG\r\n\x1a\n", 0) == 0; }

fs::path fresh_folder(const std::string& name) {
  const fs::path dir = fs::path(crossdyn::test::binary_dir()) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

bool only_file(const fs::path& dir, const std::string& name) {
  int n = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    ++n;
    if (e.path().filename() != name) return false;
  }
  return n == 1;
}

}  // namespace

TEST_CASE("draw: writes the picture of a scene to -o, or to <scene name>.png in the current folder") {
  const fs::path dir = fresh_folder("test-draw");
  auto r = crossdyn::test::run_crossdyn("draw '" + kPanels + "' -o '" + (dir / "panels.png").string() + "'");
  INFO(r.output);
  CHECK(r.status == 0);
  CHECK(r.output == "picture: " + (dir / "panels.png").string() + "\n");
  REQUIRE(fs::exists(dir / "panels.png"));
  CHECK(is_png(dir / "panels.png"));
  CHECK(fs::file_size(dir / "panels.png") > 30000);  // a drawing, not an empty canvas
  CHECK(only_file(dir, "panels.png"));               // no temporary left behind

  r = crossdyn::test::run_crossdyn("draw '" + kPanels + "' --no-motion", dir.string());
  INFO(r.output);
  CHECK(r.status == 0);
  CHECK(r.output == "picture: hinged_panels.png\n");
  CHECK(is_png(dir / "hinged_panels.png"));
}

TEST_CASE("draw: never writes over an input, and refuses bad input before running") {
  const fs::path dir = fresh_folder("test-draw-refused");
  // Not a PNG name (the class of `-o scene.yaml`): exit 2, nothing written.
  auto r = crossdyn::test::run_crossdyn("draw '" + kPanels + "' -o '" + (dir / "out.yaml").string() + "'");
  CHECK(r.status == 2);
  CHECK(r.output == "crossdyn: error: -o '" + (dir / "out.yaml").string() +
                        "': the picture is a PNG file; give a name ending in .png\n");
  CHECK(fs::is_empty(dir));

  // The scene itself, whatever its name: exit 2, the scene unchanged.
  fs::copy_file(kPanels, dir / "scene.png");
  const std::string before = read_bytes(dir / "scene.png");
  r = crossdyn::test::run_crossdyn("draw scene.png -o ./scene.png", dir.string());
  CHECK(r.status == 2);
  CHECK(r.output ==
        "crossdyn: error: -o './scene.png' is the same file as the scene file 'scene.png': an output "
        "must never overwrite an input (nothing was written)\n");
  CHECK(read_bytes(dir / "scene.png") == before);

  // A folder, or a folder that does not exist.
  r = crossdyn::test::run_crossdyn("draw '" + kPanels + "' -o '" + dir.string() + "/x.png/'");
  CHECK(r.status == 2);
  fs::create_directories(dir / "sub.png");
  r = crossdyn::test::run_crossdyn("draw '" + kPanels + "' -o '" + (dir / "sub.png").string() + "'");
  CHECK(r.status == 2);
  CHECK(r.output == "crossdyn: error: -o '" + (dir / "sub.png").string() +
                        "' is a folder; give a file name ending in .png\n");
  r = crossdyn::test::run_crossdyn("draw '" + kPanels + "' -o '" + (dir / "missing" / "x.png").string() + "'");
  CHECK(r.status == 2);
  CHECK(r.output.rfind("crossdyn: error: cannot write -o '" + (dir / "missing" / "x.png").string() + "'", 0) == 0);
  CHECK_FALSE(fs::exists(dir / "missing"));

  // A scene that cannot be read: its file and line, exit 2, no picture.
  { std::ofstream(dir / "broken.yaml") << "name: broken\nbodies: [1, 2\n"; }
  r = crossdyn::test::run_crossdyn("draw broken.yaml", dir.string());
  CHECK(r.status == 2);
  CHECK(r.output.rfind("crossdyn: error: broken.yaml:", 0) == 0);
  CHECK_FALSE(fs::exists(dir / "broken.png"));
  CHECK_FALSE(fs::exists(dir / "broken.yaml.png"));

  r = crossdyn::test::run_crossdyn("draw '" + kPanels + "' --geometry '" + (dir / "g.yaml").string() + "' -o '" +
                                   (dir / "p.png").string() + "'");
  CHECK(r.status == 2);
  CHECK(r.output == "crossdyn: error: --geometry '" + (dir / "g.yaml").string() +
                        "': the geometry is a JSON file; give a name ending in .json\n");
  CHECK_FALSE(fs::exists(dir / "p.png"));

  r = crossdyn::test::run_crossdyn("draw '" + kPanels + "' --panels 0 -o '" + (dir / "p.png").string() + "'");
  CHECK(r.status == 2);
  CHECK(r.output == "crossdyn: error: --panels 0: give 1 to 12\n");
}
