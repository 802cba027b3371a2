// crossdyn draw SCENE [-o FILE.png]: a picture of the scene as crossdyn understood it: every body
// as its equivalent-inertia box with its axes, every joint point seen from both bodies, every
// revolute axis, spherical joint and offset, at t = 0 in 3-D; and the configuration at a few later
// times from a kane run at the scene's settings. The geometry is computed here
// (harness/scene_geometry.hpp) and drawn by reports/draw_scene.py with matplotlib.
#include <CLI/CLI.hpp>

#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "core/output.hpp"
#include "core/scene/scene.hpp"
#include "harness/commands.hpp"
#include "harness/report.hpp"
#include "harness/engines.hpp"
#include "harness/locations.hpp"
#include "harness/scene_geometry.hpp"
#include "harness/scene_warnings.hpp"

#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>

namespace crossdyn {

namespace {

namespace fs = std::filesystem;

struct DrawOptions {
  std::string scene;
  std::string output;  // "" : <scene name>.png in the current folder
  std::string python = "/usr/bin/python3";
  std::string geometry;  // "" : not kept
  bool no_motion = false;
  bool strict = false;
  int panels = 4;
};

// A private temporary folder, removed with everything in it when destroyed.
class TempFolder {
 public:
  TempFolder() {
    const char* tmp = std::getenv("TMPDIR");
    std::string pattern = (tmp && *tmp ? std::string(tmp) : std::string("/tmp")) + "/crossdyn-draw-XXXXXX";
    if (!::mkdtemp(pattern.data())) throw InputError("cannot create a temporary folder '" + pattern + "'");
    path_ = pattern;
  }
  ~TempFolder() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempFolder(const TempFolder&) = delete;
  TempFolder& operator=(const TempFolder&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

std::string lower(std::string s) {
  for (char& ch : s) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return s;
}

int draw(const DrawOptions& o) {
  const std::string scene = harness::resolve_scene(o.scene);
  const harness::CheckedScene checked = harness::read_checked_scene(scene);
  const System& system = checked.system;
  harness::print_warnings(checked.warnings, std::cerr);
  const std::string out = o.output.empty() ? harness::file_safe(system.name, true, "scene") + ".png" : o.output;
  // The picture is a PNG: a name without .png is a mistake (and keeps `-o scene.yaml` from ever
  // replacing an input).
  if (lower(fs::path(out).extension().string()) != ".png")
    throw InputError("-o '" + out + "': the picture is a PNG file; give a name ending in .png");
  std::error_code ec;
  if (fs::is_directory(out, ec)) throw InputError("-o '" + out + "' is a folder; give a file name ending in .png");
  if (!o.geometry.empty() && lower(fs::path(o.geometry).extension().string()) != ".json")
    throw InputError("--geometry '" + o.geometry + "': the geometry is a JSON file; give a name ending in .json");
  const fs::path script = fs::path(harness::installed_reports_dir()) / "draw_scene.py";
  // Every output against every input: the scene, its data files, the drawing script.
  std::vector<NamedPath> outputs{{"standard output", "-"}, {"-o", out}};
  if (!o.geometry.empty()) outputs.push_back({"--geometry", o.geometry});
  std::vector<NamedPath> inputs = harness::scene_inputs(system);
  inputs.push_back({"the drawing script", script.string()});
  check_outputs_are_not_inputs(outputs, inputs);
  if (o.panels < 1 || o.panels > 12) throw InputError("--panels " + std::to_string(o.panels) + ": give 1 to 12");
  if (!fs::is_regular_file(script))
    throw InputError("the drawing script '" + script.string() + "' is missing (it is part of the "
                     "crossdyn source tree this program was built from)");
  harness::check_python(o.python);
  // Both opened now, so that an unusable one is refused (exit 2) before the run.
  AtomicFile file(out, "-o");
  std::optional<AtomicFile> geometry_file;
  if (!o.geometry.empty()) geometry_file.emplace(o.geometry, "--geometry");

  namespace g = harness::geometry;
  const IntegratorSettings settings = IntegratorSettings::from(system.run);
  g::MotionSource source;
  source.duration = settings.duration;
  std::vector<g::Configuration> frames;
  if (o.no_motion) {
    source.state = "not run";
    source.note = "not asked for (--no-motion)";
  } else {
    // The later configurations: a kane run at the scene's own settings, keeping only the rows drawn.
    const std::unique_ptr<Engine> engine = make_engine("kane", system);
    g::FramePicker picker(engine->columns(), settings.duration, o.panels);
    IntegratorSettings s = settings;
    s.keep_rows = false;
    const RunResult r = simulate(*engine, system, TreeState::initial(system), s,
                                 [&picker](const double* row) { picker.add(row); });
    if (r.failure && r.failure->reason() == "interrupted") throw *r.failure;
    source.engine = "kane";
    source.state = r.failure ? "failed" : "ok";
    if (r.failure) source.note = r.failure->what();
    frames = picker.frames(system);
  }

  const TempFolder tmp;
  const fs::path geometry = tmp.path() / "geometry.json";
  const fs::path picture = tmp.path() / "picture.png";
  const std::string document = g::geometry_json(system, g::initial_configuration(system), frames, source,
                                                checked.warnings);
  write_file_atomic(geometry.string(), document);
  harness::run_python(o.python, {script.string(), geometry.string(), picture.string()});
  std::ifstream in(picture, std::ios::binary);
  if (!in) throw InputError("the drawing script wrote no picture");
  file.stream() << in.rdbuf();
  if (geometry_file) geometry_file->stream() << document;
  // The picture and the geometry replace the old ones together (or neither does).
  commit_together({&file, geometry_file ? &*geometry_file : nullptr});
  std::cout << "picture: " << out << '\n';
  if (geometry_file) std::cout << "geometry: " << o.geometry << '\n';
  if (source.state == "failed")
    std::cerr << "crossdyn draw: the kane run failed (" << source.note << "); the picture shows "
              << frames.size() << " of " << o.panels << " later times\n";
  return harness::strict_status(kExitOk, o.strict, checked.warnings.size());
}

}  // namespace

void add_draw_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<DrawOptions>();
  CLI::App* sub = app.add_subcommand(
      "draw",
      "Draw the scene as crossdyn reads it: at t = 0 in 3-D (each body as its equivalent-inertia\n"
      "box with its x/y/z axes, joint points seen from both bodies, revolute axes with the\n"
      "direction of a positive angle, spherical joints, offsets applied, names), and the\n"
      "configuration at a few later times from a kane run at the scene's settings. Look at it\n"
      "before trusting a new scene: the engines all agree on a wrong axis sign or joint point.\n"
      "The scene's warnings (a child folded into its parent, mirror-image panels that do not move\n"
      "as mirror images, an angle without a unit above 2 pi, ...) are printed on stderr and in\n"
      "the picture.");
  sub->add_option("scene", o->scene, "Scene file (YAML), or a scene name (crossdyn list)")->required();
  sub->add_option("--output,-o", o->output,
                  "The PNG file to write, atomically (default: <scene name>.png in the current folder)");
  sub->add_flag("--no-motion", o->no_motion, "Only the picture at t = 0 (no kane run)");
  sub->add_option("--geometry", o->geometry,
                  "Also write the drawing geometry (JSON, format in reports/crossdyn_report/scene_view.py)");
  sub->add_option("--panels", o->panels, "Number of times drawn from the run: 0, T/(n-1), ..., T (default 4)");
  sub->add_option("--python", o->python,
                  "Python with matplotlib (default: /usr/bin/python3, Debian's)");
  sub->add_flag("--strict", o->strict,
                "Exit with status 1 when the scene has a warning (the picture is still written)");
  sub->callback([o, &exit_code] { exit_code = draw(*o); });
}

}  // namespace crossdyn
