// Model no more than a scene needs: see converge.hpp.
#include "harness/converge.hpp"

#include "core/cancel.hpp"
#include "core/errors.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <sstream>

namespace crossdyn::harness {

namespace {

std::string group_name(const std::string& mode) {
  std::size_t end = mode.size();
  while (end > 0 && std::isdigit(static_cast<unsigned char>(mode[end - 1]))) --end;
  return end == 0 ? mode : mode.substr(0, end);
}

// Every combination of counts 0..n_g, the group listed last varying fastest.
std::vector<std::vector<int>> all_counts(const std::vector<ModeGroup>& groups) {
  std::vector<std::vector<int>> out{{}};
  for (const ModeGroup& g : groups) {
    std::vector<std::vector<int>> next;
    for (const auto& prefix : out)
      for (int c = 0; c <= static_cast<int>(g.modes.size()); ++c) {
        next.push_back(prefix);
        next.back().push_back(c);
      }
    out = std::move(next);
  }
  return out;
}

}  // namespace

std::vector<ModeGroup> mode_groups(const System& system) {
  std::vector<ModeGroup> groups;
  for (std::size_t b = 0; b < system.bodies.size(); ++b) {
    const auto& flex = system.bodies[b].flex;
    if (!flex) continue;
    for (int k = 0; k < flex->modes(); ++k) {
      const std::string name = group_name(flex->mode_names[static_cast<std::size_t>(k)]);
      auto it = std::find_if(groups.begin(), groups.end(), [&](const ModeGroup& g) {
        return g.body == static_cast<int>(b) && g.name == name;
      });
      if (it == groups.end()) {
        groups.push_back({static_cast<int>(b), name, {}});
        it = groups.end() - 1;
      }
      it->modes.push_back(k);
    }
  }
  return groups;
}

System truncate_modes(const System& system, const std::vector<ModeGroup>& groups,
                      const std::vector<int>& counts) {
  System s = system;
  for (std::size_t b = 0; b < s.bodies.size(); ++b) {
    auto& flex = s.bodies[b].flex;
    if (!flex) continue;
    std::vector<int> keep;  // kept mode indices, in the body's own order
    for (std::size_t g = 0; g < groups.size(); ++g)
      if (groups[g].body == static_cast<int>(b))
        for (int c = 0; c < counts[g]; ++c) keep.push_back(groups[g].modes[static_cast<std::size_t>(c)]);
    std::sort(keep.begin(), keep.end());
    const int n = static_cast<int>(keep.size());
    FlexBody t = *flex;
    t.mode_names.clear();
    for (int k : keep) t.mode_names.push_back(flex->mode_names[static_cast<std::size_t>(k)]);
    for (std::size_t i = 0; i < t.nodes.size(); ++i) {
      t.nodes[i].Phi_B.resize(3, n);
      t.nodes[i].Psi_B.resize(3, n);
      for (int c = 0; c < n; ++c) {
        t.nodes[i].Phi_B.col(c) = flex->nodes[i].Phi_B.col(keep[static_cast<std::size_t>(c)]);
        t.nodes[i].Psi_B.col(c) = flex->nodes[i].Psi_B.col(keep[static_cast<std::size_t>(c)]);
      }
    }
    t.K.resize(n, n);
    t.D.resize(n, n);
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) {
        t.K(r, c) = flex->K(keep[static_cast<std::size_t>(r)], keep[static_cast<std::size_t>(c)]);
        t.D(r, c) = flex->D(keep[static_cast<std::size_t>(r)], keep[static_cast<std::size_t>(c)]);
      }
    flex = std::move(t);
  }
  return s;
}

std::string model_label(const System& system, const std::vector<ModeGroup>& groups,
                        const std::vector<int>& counts) {
  std::string out;
  int body = -1;
  for (std::size_t g = 0; g < groups.size(); ++g) {
    if (groups[g].body != body) {
      body = groups[g].body;
      out += (out.empty() ? "" : "  ") + system.bodies[static_cast<std::size_t>(body)].name;
    }
    out += " " + groups[g].name + std::to_string(counts[g]);
  }
  return out;
}

ConvergeResult converge_scene(const System& system, const CompareOptions& options) {
  ConvergeResult r;
  r.scene = system.name;
  r.groups = mode_groups(system);
  if (r.groups.empty())
    throw InputError(system.file + ": converge needs a flexible body with at least one mode; " +
                     "this scene has none (a rigid scene has no modes to leave out)");
  const std::vector<std::vector<int>> combos = all_counts(r.groups);
  if (combos.size() > static_cast<std::size_t>(kMaxConvergeModels))
    throw InputError(system.file + ": converge would run " + std::to_string(combos.size()) +
                     " models (every count of modes in " + std::to_string(r.groups.size()) +
                     " mode groups); the limit is " + std::to_string(kMaxConvergeModels));
  CompareOptions one = options;
  one.analytic = false;
  if (one.engines.empty()) one.engines.push_back({"kane", "kane", {}});
  one.engines.resize(1);
  r.engine = one.engines[0].label;

  auto run_model = [&](const std::vector<int>& counts) {
    ConvergeModel m;
    m.counts = counts;
    for (int c : counts) m.modes += c;
    m.label = model_label(system, r.groups, counts);
    System s = truncate_modes(system, r.groups, counts);
    SceneComparison c = compare_scene(s, one);
    m.run = std::move(c.runs.at(0));
    m.run.label = m.label;
    return std::pair{std::move(m), std::move(s)};
  };

  // The full model first: every other model is compared with it.
  std::vector<int> full_counts;
  for (const ModeGroup& g : r.groups) full_counts.push_back(static_cast<int>(g.modes.size()));
  auto [full, full_system] = run_model(full_counts);
  full.full = true;
  full.label += " (full)";
  full.run.label = "full";
  full.passed = full.run.state == EngineRun::State::Ok && !full.run.result.failure;
  if (!full.passed)
    throw RunFailure(r.engine, full.run.result.failure ? full.run.result.failure->time() : 0.0, "",
                     "the full model did not run to the end, so nothing can be compared with it: " +
                         (full.run.result.failure ? std::string(full.run.result.failure->what())
                                                  : full.run.note));
  const EngineRun full_run = full.run;
  r.models.push_back(std::move(full));

  for (const auto& counts : combos) {
    if (counts == full_counts) continue;
    cancel::poll();
    auto [m, s] = run_model(counts);
    if (m.run.state != EngineRun::State::Ok || m.run.result.failure) {
      m.passed = false;
      m.worst_normalised = std::numeric_limits<double>::infinity();
      m.worst_quantity = "run: " + (m.run.result.failure ? std::string(m.run.result.failure->what())
                                                         : m.run.note);
      r.models.push_back(std::move(m));
      continue;
    }
    SceneComparison c = compare_runs(s, {full_run, m.run});
    m.passed = true;
    for (Check& k : c.checks) {
      if (k.b.empty() || k.group == "run" || k.group == "t") {
        if (k.status == CheckStatus::Fail) m.passed = false;  // "t": output times differ
        continue;
      }
      if (k.status == CheckStatus::Fail) m.passed = false;
      if (k.status != CheckStatus::Excluded && !(k.normalised <= m.worst_normalised)) {
        m.worst_normalised = k.normalised;
        m.worst_quantity = k.quantity;
      }
      m.checks.push_back(std::move(k));
    }
    r.models.push_back(std::move(m));
  }
  // The smallest passing model (the full model always qualifies).
  r.smallest = 0;
  for (std::size_t i = 1; i < r.models.size(); ++i)
    if (r.models[i].passed && r.models[i].modes < r.models[static_cast<std::size_t>(r.smallest)].modes)
      r.smallest = static_cast<int>(i);
  return r;
}

std::string format_converge(const ConvergeResult& r) {
  std::vector<std::vector<std::string>> rows{
      {"model", "modes", "largest change / tolerance", "in", "verdict"}};
  for (std::size_t i = 0; i < r.models.size(); ++i) {
    const ConvergeModel& m = r.models[i];
    rows.push_back({m.label, std::to_string(m.modes), m.full ? "reference" : sci(m.worst_normalised),
                    m.full ? "" : m.worst_quantity,
                    m.full ? "" : (m.passed ? "within" : "CHANGES")});
  }
  std::ostringstream out;
  out << "converge " << r.scene << " (engine " << r.engine
      << "): every model against the full model, the scene's tolerances; \"largest change / "
         "tolerance\" <= 1 is within them\n\n"
      << text_table(rows) << '\n';
  const ConvergeModel& s = r.models[static_cast<std::size_t>(r.smallest)];
  out << "smallest model within the scene's tolerances: " << s.label << " (" << s.modes << " of "
      << r.models.front().modes << " modes)\n";
  return out.str();
}

std::string converge_json(const ConvergeResult& r) {
  using json = nlohmann::ordered_json;
  auto num = [](double v) -> json { return std::isfinite(v) ? json(v) : json(nullptr); };
  json j;
  j["scene"] = r.scene;
  j["engine"] = r.engine;
  json groups = json::array();
  for (const ModeGroup& g : r.groups)
    groups.push_back({{"body", g.body}, {"group", g.name}, {"modes", g.modes.size()}});
  j["groups"] = groups;
  json models = json::array();
  for (const ConvergeModel& m : r.models) {
    json checks = json::array();
    for (const Check& k : m.checks)
      checks.push_back({{"quantity", k.quantity}, {"error", num(k.error)}, {"bound", num(k.bound)},
                        {"normalised", num(k.normalised)}, {"status", to_string(k.status)}});
    models.push_back({{"label", m.label}, {"counts", m.counts}, {"modes", m.modes},
                      {"full", m.full}, {"passed", m.passed},
                      {"worst_normalised", num(m.worst_normalised)},
                      {"worst_quantity", m.worst_quantity}, {"checks", checks}});
  }
  j["models"] = models;
  j["smallest"] = r.models[static_cast<std::size_t>(r.smallest)].label;
  return j.dump(2) + "\n";
}

}  // namespace crossdyn::harness
