// Where crossdyn finds things (see locations.hpp).
#include "harness/locations.hpp"

#include "core/errors.hpp"
#include "core/output.hpp"
#include "core/scene/scene.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <new>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#ifndef CROSSDYN_SOURCE_DIR
#error "CROSSDYN_SOURCE_DIR must be defined (harness/CMakeLists.txt)"
#endif
#ifndef CROSSDYN_VERSION
#define CROSSDYN_VERSION "unknown"
#endif

namespace crossdyn::harness {

namespace fs = std::filesystem;

namespace {

bool exists_any(const std::string& p) {  // the name exists (even a broken link)
  struct stat st {};
  return ::lstat(p.c_str(), &st) == 0;
}

bool is_folder(const std::string& p) {
  struct stat st {};
  return ::stat(p.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

}  // namespace

std::string source_tree() { return CROSSDYN_SOURCE_DIR; }

std::string version() { return CROSSDYN_VERSION; }

std::string installed_reports_dir() { return source_tree() + "/reports"; }
std::string installed_report_script() { return installed_reports_dir() + "/make_report.py"; }

std::vector<std::string> scene_folders() {
  std::vector<std::string> out;
  if (is_folder("scenarios")) out.push_back("scenarios");
  const std::string tree = source_tree() + "/scenarios";
  std::error_code ec;
  if (is_folder(tree) && !(out.size() == 1 && fs::equivalent(out[0], tree, ec)))
    out.push_back(tree);
  return out;
}

std::string resolve_scene(const std::string& scene) {
  if (scene.empty()) throw InputError("the scene name is empty");
  if (exists_any(scene) || scene.find('/') != std::string::npos) return scene;
  std::vector<std::string> tried{scene};
  for (const std::string& folder : scene_folders())
    for (const char* ext : {"", ".yaml", ".yml"}) {
      const std::string p = folder + "/" + scene + ext;
      if (exists_any(p)) return p;
      tried.push_back(p);
    }
  std::string list;
  for (const std::string& t : tried) list += "\n  " + t;
  throw InputError("cannot find the scene '" + scene + "': no such file; tried" + list +
                   "\n(`crossdyn list` shows the scenes)");
}

namespace {

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

}  // namespace

SceneFolder scan_scene_folder(const std::string& folder) {
  std::error_code ec;
  const fs::file_status st = fs::status(folder, ec);
  if (ec || !fs::is_directory(st)) {
    if (ec == std::errc::no_such_file_or_directory || (!ec && !fs::exists(st)))
      throw InputError("the scenes folder '" + folder + "' does not exist");
    if (ec == std::errc::permission_denied)
      throw InputError("cannot open the scenes folder '" + folder + "': permission denied");
    if (ec) throw InputError("cannot open the scenes folder '" + folder + "': " + ec.message());
    throw InputError("'" + folder + "' is not a folder");
  }
  SceneFolder out;
  fs::directory_iterator it(folder, ec);
  const auto cannot_list = [&folder](const std::error_code& e) {
    return InputError("cannot list the scenes folder '" + folder + "': " +
                      (e == std::errc::permission_denied ? std::string("permission denied")
                                                         : e.message()));
  };
  if (ec) throw cannot_list(ec);
  for (; it != fs::directory_iterator(); it.increment(ec)) {
    const fs::path p = it->path();
    const std::string name = p.filename().string(), low = lower(name);
    const bool scene_ext = ends_with(low, ".yaml") || ends_with(low, ".yml");
    if (scene_ext && name.size() > 4 && name[0] != '.') {
      out.scenes.push_back(p.string());  // whatever its type: reading it says why it cannot be
    } else if (scene_ext) {
      out.skipped.push_back({p.string(), "a hidden file (a name starting with '.' is not a scene)"});
    } else if (low.find(".yaml") != std::string::npos || low.find(".yml") != std::string::npos) {
      out.skipped.push_back({p.string(), "the name does not end in .yaml or .yml (an editor backup?)"});
    }
  }
  if (ec) throw cannot_list(ec);
  std::sort(out.scenes.begin(), out.scenes.end());
  std::sort(out.skipped.begin(), out.skipped.end());
  return out;
}

std::vector<std::string> scene_files_in(const std::string& folder) {
  return scan_scene_folder(folder).scenes;
}

}  // namespace crossdyn::harness

namespace crossdyn::harness {

void require_shardable_scene(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || S_ISREG(st.st_mode) || S_ISDIR(st.st_mode)) return;
  const char* what = S_ISFIFO(st.st_mode) ? "a pipe or FIFO" : S_ISCHR(st.st_mode) ? "a character device"
                     : S_ISSOCK(st.st_mode) ? "a socket" : "not a regular file";
  throw InputError("--shard: the scene '" + path + "' is " + what +
                   "; every shard reads its scenes again, so a sharded run needs regular files "
                   "(save it to a file first)");
}

}  // namespace crossdyn::harness

namespace crossdyn::harness {

std::vector<NamedPath> scene_inputs(const System& system) {
  std::vector<NamedPath> out;
  const std::vector<std::string> files = system.input_files();
  for (std::size_t i = 0; i < files.size(); ++i)
    out.push_back({i == 0 && files[i] == system.file ? "the scene file"
                                                     : "the data file of scene '" + system.file + "'",
                   files[i]});
  return out;
}

std::vector<NamedPath> scene_file_inputs(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return {{"the scene file", path}};
  try {
    return scene_inputs(read_scene(path));
  } catch (const std::bad_alloc&) {
    throw;  // out of memory is not an unreadable scene
  } catch (const std::exception&) {
    // A scene that cannot be read does not say which data files it reads: every regular file of
    // its folder whose name the text holds counts as one (cli_fuzzer: `verify bad.yaml --shard 0/2
    // --part panel_modes.csv` wrote the part over the data file of a scene with a bad byte).
    std::vector<NamedPath> inputs{{"the scene file", path}};
    std::ifstream in(path, std::ios::binary);
    std::string text(1u << 20, '\0');
    in.read(text.data(), static_cast<std::streamsize>(text.size()));
    text.resize(static_cast<std::size_t>(in.gcount()));
    std::error_code ec;
    const std::filesystem::path folder = std::filesystem::path(path).parent_path();
    for (std::filesystem::directory_iterator it(folder.empty() ? "." : folder, ec), end; !ec && it != end;
         it.increment(ec)) {
      const std::string name = it->path().filename().string();
      std::error_code ec2;
      if (name.empty() || text.find(name) == std::string::npos || !it->is_regular_file(ec2)) continue;
      if (it->path() == std::filesystem::path(path)) continue;
      inputs.push_back({"a data file the scene names", it->path().string()});
    }
    return inputs;
  }
}

}  // namespace crossdyn::harness
