// crossdyn list [--scenarios DIR]: every scene with its one-line description, so that a new user
// sees what `crossdyn run NAME` accepts.
#include <CLI/CLI.hpp>

#include "core/errors.hpp"
#include "core/output.hpp"
#include "core/scene/scene.hpp"
#include "harness/commands.hpp"
#include "harness/locations.hpp"

#include <cctype>
#include <filesystem>
#include <iostream>
#include <memory>

namespace crossdyn {

namespace {

constexpr std::size_t kWidth = 100;  // characters per line

struct ListOptions {
  std::string folder;  // "" : harness::scene_folders()
};

// The first sentence of a description, on one line, at most `width` characters.
std::string one_line(const std::string& text, std::size_t width) {
  std::string s;
  for (char c : text) {
    const bool space = c == '\n' || c == '\t' || c == '\r' || c == ' ';
    if (space) {
      if (!s.empty() && s.back() != ' ') s += ' ';
    } else if (static_cast<unsigned char>(c) >= 0x20) {
      s += c;
    }
  }
  while (!s.empty() && s.back() == ' ') s.pop_back();
  // The first sentence: a full stop after a letter or digit ("link1 ... link5" is not one).
  for (std::size_t i = 1; i + 1 < s.size(); ++i)
    if (s[i] == '.' && s[i + 1] == ' ' && std::isalnum(static_cast<unsigned char>(s[i - 1])) &&
        s.compare(i >= 3 ? i - 3 : 0, 4, "e.g.") != 0 && s.compare(i >= 3 ? i - 3 : 0, 4, "i.e.") != 0) {
      s = s.substr(0, i + 1);
      break;
    }
  if (s.size() > width) {
    std::size_t cut = width - 3;
    while (cut > 0 && (static_cast<unsigned char>(s[cut]) & 0xC0) == 0x80) --cut;  // UTF-8
    s = s.substr(0, cut) + "...";
  }
  return s;
}

int list(const ListOptions& o) {
  std::vector<std::string> folders = o.folder.empty() ? harness::scene_folders()
                                                      : std::vector<std::string>{o.folder};
  if (folders.empty())
    throw InputError("no scenes folder: neither ./scenarios nor " + harness::source_tree() +
                     "/scenarios exists (give one with --scenarios DIR)");
  int status = kExitOk;
  for (std::size_t f = 0; f < folders.size(); ++f) {
    const harness::SceneFolder folder = harness::scan_scene_folder(folders[f]);
    const std::vector<std::string>& files = folder.scenes;
    std::cout << (f ? "\n" : "") << "scenes in " << folders[f] << "/ (" << files.size() << "):\n";
    std::vector<std::pair<std::string, std::string>> rows;
    std::size_t name_width = 4;
    for (const std::string& file : files) {
      std::string name = std::filesystem::path(file).stem().string(), text;
      try {
        const System s = read_scene(file, nullptr, Pipes::Refuse);
        text = one_line(s.description, kWidth);
      } catch (const InputError& e) {
        text = "cannot be read: " + std::string(e.what());
        status = kExitBadInput;
      }
      name_width = std::max(name_width, name.size());
      rows.emplace_back(name, text);
    }
    name_width = std::min<std::size_t>(name_width, 32);
    for (const auto& [name, text] : rows) {
      std::string line = "  " + name;
      line += std::string(name.size() < name_width ? name_width - name.size() + 2 : 2, ' ');
      line += one_line(text, line.size() + 20 < kWidth ? kWidth - line.size() : 20);
      std::cout << line << '\n';
    }
    for (const auto& [path, why] : folder.skipped)
      std::cout << "  skipped " << std::filesystem::path(path).filename().string() << ": " << why << '\n';
  }
  std::cout << "\nRun one with `crossdyn run NAME`, compare the engines with `crossdyn compare NAME`.\n";
  check_written(std::cout);
  return status;
}

}  // namespace

void add_list_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<ListOptions>();
  CLI::App* sub = app.add_subcommand(
      "list",
      "List the scenes (scenarios/ of the current folder, then of the source tree crossdyn was\n"
      "built from) with their one-line descriptions. Exit status 2 when a scene cannot be read.");
  sub->add_option("--scenarios", o->folder, "List the scenes of DIR instead");
  sub->callback([o, &exit_code] { exit_code = list(*o); });
}

}  // namespace crossdyn
