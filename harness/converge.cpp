// Model no more than a scene needs: see converge.hpp.
#include "harness/converge.hpp"

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/scene/scene.hpp"
#include "harness/study.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <regex>
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
      // Geometric stiffening: the foreshortening e (1/2 eta^T G eta) with the dropped modes held
      // at zero keeps the rows and columns of G of the kept modes.
      if (flex->nodes[i].G.size() > 0) {
        t.nodes[i].G.resize(n, n);
        for (int r = 0; r < n; ++r)
          for (int c = 0; c < n; ++c)
            t.nodes[i].G(r, c) = flex->nodes[i].G(keep[static_cast<std::size_t>(r)],
                                                  keep[static_cast<std::size_t>(c)]);
      }
    }
    if (n == 0 && t.geometric_stiffening) {
      // No modes, no foreshortening (e (1/2 eta^T G eta) with eta empty is zero): the linear
      // model, which the engines expect when G is empty.
      t.geometric_stiffening = false;
      for (FlexNode& x : t.nodes) {
        x.G.resize(0, 0);
        x.e_B.setZero();
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

int beam_slices(const FlexBody& f) {
  std::smatch m;
  static const std::regex kSlices(R"(\bslices: *([0-9]+))");
  return std::regex_search(f.scene_form, m, kSlices) ? std::stoi(m[1].str()) : 0;
}

namespace {

// A joint attached at a node of body `body` (Joint::parent_node or child_node).
struct Attachment {
  std::size_t joint;
  bool parent_side;
  int node;
};

std::vector<Attachment> attachments_of(const System& s, int body) {
  std::vector<Attachment> out;
  for (std::size_t j = 0; j < s.joints.size(); ++j) {
    const Joint& J = s.joints[j];
    if (J.parent == body && J.parent_node >= 0) out.push_back({j, true, J.parent_node});
    if (J.child == body && J.child_node >= 0) out.push_back({j, false, J.child_node});
  }
  return out;
}

std::string point_text(const Eigen::Vector3d& p) {
  char b[96];
  std::snprintf(b, sizeof b, "(%.4g, %.4g, %.4g) m", p.x(), p.y(), p.z());
  return b;
}

// Per mode k, the factor r_k that turns the `from` beam's normalised shapes into the `to` beam's
// (the same closed-form modes, the same order). Normalised to a unit end displacement the shapes
// do not depend on the slicing (r_k = 1); normalised to unit modal mass (a node sum) they differ
// by the ratio of the two beams' displacements at an end node where the mode does not vanish.
std::vector<double> shape_ratios(const FlexBody& from, int from_top, const FlexBody& to, int to_top) {
  std::vector<double> r(static_cast<std::size_t>(from.modes()), 1.0);
  const FlexNode* ends_from[] = {&from.nodes.front(), &from.nodes[static_cast<std::size_t>(from_top)]};
  const FlexNode* ends_to[] = {&to.nodes.front(), &to.nodes[static_cast<std::size_t>(to_top)]};
  for (int k = 0; k < from.modes(); ++k) {
    const int e = ends_from[1]->Phi_B.col(k).norm() >= ends_from[0]->Phi_B.col(k).norm() ? 1 : 0;
    const Eigen::Vector3d a = ends_from[e]->Phi_B.col(k), b = ends_to[e]->Phi_B.col(k);
    if (a.squaredNorm() > 0) r[static_cast<std::size_t>(k)] = b.dot(a) / a.squaredNorm();
  }
  return r;
}

}  // namespace

std::optional<System> reslice(const System& system, int body, int slices,
                              std::vector<std::string>* kept) {
  const std::size_t b = static_cast<std::size_t>(body);
  const auto& flex = system.bodies[b].flex;
  static const std::regex kSlices(R"(\bslices: *[0-9]+)");
  if (!flex || flex->scene_form.rfind("{beam:", 0) != 0 ||
      !std::regex_search(flex->scene_form, kSlices))
    return std::nullopt;
  const int old_slices = beam_slices(*flex);
  // The joints at the beam's nodes are written at `bottom` (a node of every slicing) and put back
  // below, each at the same physical point: a node's name would name another point of the
  // re-sliced beam (slice30 is mid-beam of 60 slices, the tip of 30) or none at all.
  const std::vector<Attachment> at = attachments_of(system, body);
  System s = system;
  auto& form = s.bodies[b].flex->scene_form;
  form = std::regex_replace(form, kSlices, "slices: " + std::to_string(slices));
  for (const Attachment& a : at) {
    Joint& J = s.joints[a.joint];
    (a.parent_side ? J.parent_node : J.child_node) = 0;
  }
  System out = read_scene_text(write_scene_text(s), system.file.empty() ? system.name : system.file);
  out.name = system.name;
  out.file = system.file;
  // Every joint point at a node keeps its physical place (the same point of the continuous beam):
  // the end nodes `bottom` and `top` are ends at any slicing; a slice node is a slice centre, and
  // halving or doubling the slices never puts a slice centre there again, so the re-sliced beam
  // gets a massless node at that point, with the continuous beam's shape, slope and
  // foreshortening there. These do not depend on the slicing (beam.hpp: closed-form modes sampled
  // at the node), so they are the original node's, scaled by shape_ratios for unit-modal-mass
  // normalisation. The beam's mass, inertia and modes are those of the new slicing.
  FlexBody& to = *out.bodies[b].flex;
  const FlexBody& from = *flex;
  // The generator's ends: bottom (node 0) and top, found by name (the reader keeps only the
  // stations joints use, core/flex/beam.hpp, so the index of top depends on the joints).
  const int from_top = from.node_index("top");
  const int to_top = to.node_index("top");
  const std::size_t to_generated = to.nodes.size();  // the nodes below are added after these
  const std::vector<double> r = shape_ratios(from, from_top, to, to_top);
  std::vector<std::pair<int, int>> placed;  // (node of `from`, node of `to`)
  for (const Attachment& a : at) {
    int node = a.node == 0 ? 0 : a.node == from_top ? to_top : -1;
    for (const auto& [f, t] : placed)
      if (f == a.node) node = t;
    const FlexNode& original = from.nodes[static_cast<std::size_t>(a.node)];
    if (node < 0) {
      FlexNode x = original;
      x.name = original.name + "-of-" + std::to_string(old_slices);
      x.mass = 0;
      x.J_Ni_B.setZero();
      for (int k = 0; k < from.modes(); ++k) {
        x.Phi_B.col(k) *= r[static_cast<std::size_t>(k)];
        x.Psi_B.col(k) *= r[static_cast<std::size_t>(k)];
        if (x.G.size() > 0) {
          x.G.row(k) *= r[static_cast<std::size_t>(k)];
          x.G.col(k) *= r[static_cast<std::size_t>(k)];
        }
      }
      to.nodes.push_back(std::move(x));
      node = static_cast<int>(to.nodes.size()) - 1;
      placed.emplace_back(a.node, node);
    }
    if (static_cast<std::size_t>(node) >= to_generated && kept)
      kept->push_back("joint '" + system.joints[a.joint].name + "' (" +
                        (a.parent_side ? "parent" : "child") + " side) stays at node " +
                        original.name + " of the " + std::to_string(old_slices) +
                        "-slice beam, at " + point_text(original.p_BoNi_B) +
                        ", a massless node of the " + std::to_string(slices) + "-slice beam (" +
                        original.name + "-of-" + std::to_string(old_slices) + ")");
    Joint& J = out.joints[a.joint];
    (a.parent_side ? J.parent_node : J.child_node) = node;
    (a.parent_side ? J.p_PoJ_P : J.p_CoJ_C) = to.nodes[static_cast<std::size_t>(node)].p_BoNi_B;
  }
  return out;
}

namespace {

CompareOptions one_engine(const CompareOptions& options) {
  CompareOptions one = options;
  one.rates = false;  // the models are compared on their states, one engine each
  one.analytic = false;
  one.diagnose = false;  // a model's run is what converge measures, not a verdict to diagnose
  if (one.engines.empty()) one.engines.push_back({"kane", "kane", {}});
  one.engines.resize(1);
  return one;
}

std::vector<int> full_counts_of(const ConvergeResult& frame) {
  std::vector<int> full;
  for (const ModeGroup& g : frame.groups) full.push_back(static_cast<int>(g.modes.size()));
  return full;
}

// Runs `s` as model `m` and compares it with the full model's run; `metric` holds the full
// model's scales (its quantities are the full model's: a smaller model's are a subset).
void run_and_compare(ConvergeModel& m, const System& s, const EngineRun& full_run,
                     const ErrorMetric& metric, const CompareOptions& one, double accuracy) {
  SceneComparison c = compare_scene(s, one);
  m.run = std::move(c.runs.at(0));
  m.run.label = m.label;
  auto failed = [&m](const std::string& why) {
    m.passed = false;
    m.checks.clear();
    m.scales.clear();
    m.worst_relative = m.worst_normalised = std::numeric_limits<double>::infinity();
    m.worst_quantity = "run: " + why;
  };
  if (m.run.state != EngineRun::State::Ok || m.run.result.failure) {
    failed(m.run.result.failure ? std::string(m.run.result.failure->what()) : m.run.note);
    return;
  }
  SceneComparison d = compare_runs(s, {full_run, m.run});
  for (Check& k : d.checks) {
    if (k.b.empty() || k.group == "run" || k.group == "t") {
      if (k.status == CheckStatus::Fail) {  // "t": the output times differ
        failed(k.group == "t" ? "its output times differ from the full model's" : k.note);
        return;
      }
      continue;
    }
    m.scales.push_back(k.status == CheckStatus::Excluded ? std::numeric_limits<double>::quiet_NaN()
                                                         : metric.scale(k.quantity));
    m.checks.push_back(std::move(k));
  }
  judge_converge_model(m, accuracy);
}

}  // namespace

void judge_converge_model(ConvergeModel& m, double accuracy) {
  if (m.full || m.worst_quantity.rfind("run: ", 0) == 0) return;  // nothing compared
  m.worst_relative = 0;
  m.worst_normalised = 0;
  m.worst_quantity.clear();
  for (std::size_t i = 0; i < m.checks.size(); ++i) {
    const Check& k = m.checks[i];
    if (k.status == CheckStatus::Excluded) continue;
    if (!(k.normalised <= m.worst_normalised)) m.worst_normalised = k.normalised;
    const double scale = i < m.scales.size() ? m.scales[i] : std::numeric_limits<double>::quiet_NaN();
    if (!(scale > 0)) continue;  // a quantity the metric does not judge
    const double relative = std::isfinite(k.error) ? k.error / scale : std::numeric_limits<double>::infinity();
    if (!(relative <= m.worst_relative) || m.worst_quantity.empty()) {
      if (!(relative <= m.worst_relative)) m.worst_relative = relative;
      if (m.worst_quantity.empty() || relative >= m.worst_relative) m.worst_quantity = k.quantity;
    }
  }
  m.passed = m.worst_relative <= accuracy;
}

ConvergeResult converge_frame(const System& system, const CompareOptions& options,
                              std::vector<ConvergeJob>* jobs, double accuracy) {
  if (!(accuracy > 0) || !std::isfinite(accuracy) || accuracy >= 1)
    throw InputError("--accuracy: " + sci(accuracy) +
                     " is not an accuracy: give the largest relative change a model may make, "
                     "above 0 and below 1 (e.g. 1e-3: 0.1 % of each quantity's scale)");
  ConvergeResult r;
  r.accuracy = accuracy;
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
  r.engine = one_engine(options).engines[0].label;
  if (jobs) {
    jobs->clear();
    const std::vector<int> full = full_counts_of(r);
    for (const auto& counts : combos)
      if (counts != full) jobs->push_back({counts, -1, 0});
    // Slicing rows: every beam-generator body with half and twice its slices, every mode kept.
    for (std::size_t b = 0; b < system.bodies.size(); ++b) {
      const auto& flex = system.bodies[b].flex;
      if (!flex || flex->modes() == 0) continue;
      const int n = beam_slices(*flex);
      if (n == 0) continue;
      for (int slices : {n / 2, 2 * n}) jobs->push_back({full, static_cast<int>(b), slices});
    }
  }
  return r;
}

ConvergeModel converge_full_model(const System& system, const ConvergeResult& frame,
                                  const CompareOptions& options) {
  ConvergeModel full;
  full.counts = full_counts_of(frame);
  for (int c : full.counts) full.modes += c;
  full.label = model_label(system, frame.groups, full.counts) + " (full)";
  const System s = truncate_modes(system, frame.groups, full.counts);
  SceneComparison c = compare_scene(s, one_engine(options));
  full.run = std::move(c.runs.at(0));
  full.run.label = "full";
  full.full = true;
  full.passed = full.run.state == EngineRun::State::Ok && !full.run.result.failure;
  if (!full.passed)
    throw RunFailure(frame.engine, full.run.result.failure ? full.run.result.failure->time() : 0.0, "",
                     "the full model did not run to the end, so nothing can be compared with it: " +
                         (full.run.result.failure ? std::string(full.run.result.failure->what())
                                                  : full.run.note));
  return full;
}

std::optional<ConvergeModel> converge_job(const System& system, const ConvergeResult& frame,
                                          const ConvergeJob& job, const EngineRun& full_run,
                                          const CompareOptions& options, std::string* note) {
  cancel::poll();
  const CompareOptions one = one_engine(options);
  const History full_history = pinned_history(system, full_run.result);
  const ErrorMetric metric(system, full_history);
  ConvergeModel m;
  m.counts = job.counts;
  for (int c : job.counts) m.modes += c;
  m.label = model_label(system, frame.groups, job.counts);
  if (job.slices == 0) {
    run_and_compare(m, truncate_modes(system, frame.groups, job.counts), full_run, metric, one,
                    frame.accuracy);
    return m;
  }
  const std::size_t b = static_cast<std::size_t>(job.slice_body);
  std::optional<System> s;
  std::vector<std::string> kept;
  try {
    s = reslice(system, job.slice_body, job.slices, &kept);
  } catch (const InputError& e) {
    // The reader's location is in the re-written scene text, not in the user's file: say what the
    // beam generator refuses without it ("slices: 4 slices cannot resolve mode 3 ...").
    static const std::regex kWhere(R"(^.*?:[0-9]+:[0-9]+: (bodies\[[0-9]+\]\.flexible\.beam\.)?)");
    if (note)
      *note = system.bodies[b].name + " with " + std::to_string(job.slices) +
              " slices: not run (the beam generator refuses it: " +
              std::regex_replace(std::string(e.what()), kWhere, "", std::regex_constants::format_first_only) +
              ")";
    return std::nullopt;
  }
  if (!s) return std::nullopt;
  if (note && !kept.empty()) {
    *note = system.bodies[b].name + " with " + std::to_string(job.slices) + " slices: ";
    for (std::size_t k = 0; k < kept.size(); ++k) *note += (k ? "; " : "") + kept[k];
  }
  m.slices = job.slices;
  m.slice_body = job.slice_body;
  m.label += ", " + system.bodies[b].name + " " + std::to_string(job.slices) + " slices";
  run_and_compare(m, *s, full_run, metric, one, frame.accuracy);
  return m;
}

void converge_finish(ConvergeResult& r) {
  // The smallest passing model (the full model always qualifies; slicing rows do not compete).
  r.smallest = 0;
  for (std::size_t i = 1; i < r.models.size(); ++i)
    if (r.models[i].passed && r.models[i].slices == 0 &&
        r.models[i].modes < r.models[static_cast<std::size_t>(r.smallest)].modes)
      r.smallest = static_cast<int>(i);
}

ConvergeResult converge_scene(const System& system, const CompareOptions& options, double accuracy) {
  std::vector<ConvergeJob> jobs;
  ConvergeResult r = converge_frame(system, options, &jobs, accuracy);
  // The full model first: every other model is compared with it.
  r.models.push_back(converge_full_model(system, r, options));
  const EngineRun full_run = r.models.front().run;
  for (const ConvergeJob& job : jobs) {
    std::string note;
    std::optional<ConvergeModel> m = converge_job(system, r, job, full_run, options, &note);
    if (m) r.models.push_back(std::move(*m));
    if (!note.empty()) r.notes.push_back(note);
  }
  converge_finish(r);
  return r;
}

std::string format_converge(const ConvergeResult& r) {
  std::vector<std::vector<std::string>> rows{
      {"model", "modes", "largest change", "in", "verdict"}};
  for (std::size_t i = 0; i < r.models.size(); ++i) {
    const ConvergeModel& m = r.models[i];
    rows.push_back({m.label, std::to_string(m.modes), m.full ? "reference" : sci(m.worst_relative),
                    m.full ? "" : m.worst_quantity,
                    m.full ? "" : m.passed ? "within"
                                  : m.worst_quantity.rfind("run: ", 0) == 0 ? "RUN FAILED"
                                                                            : "CHANGES"});
  }
  std::ostringstream out;
  out << "converge " << r.scene << " (engine " << r.engine << "): every model against the full model\n"
      << "accuracy " << sci(r.accuracy)
      << " (--accuracy): a model is within it when no quantity changes by more than " << sci(r.accuracy)
      << " of its scale\n  (the size of its kind of motion in the full model, as `crossdyn study` "
         "measures errors; attitudes in rad).\n  This is what you ask of the model; the scene's "
         "compare tolerances are for checking that the engines agree.\n\n"
      << text_table(rows) << '\n';
  const ConvergeModel& s = r.models[static_cast<std::size_t>(r.smallest)];
  out << "smallest model within the accuracy " << sci(r.accuracy) << ": " << s.label << " (" << s.modes
      << " of " << r.models.front().modes << " modes";
  if (!s.full) out << "; largest change " << sci(s.worst_relative) << ", in " << s.worst_quantity;
  out << ")\n";
  // The re-sliced body, from the row's label ("..., boom 30 slices"): several beams may be re-sliced.
  auto sliced = [](const ConvergeModel& m) {
    const std::size_t at = m.label.rfind(", ");
    const std::string tail = at == std::string::npos ? std::string() : m.label.substr(at + 2);
    const std::size_t space = tail.find(' ');
    return space == std::string::npos ? std::string() : tail.substr(0, space) + " ";
  };
  for (const ConvergeModel& m : r.models)
    if (m.slices > 0 && m.worst_quantity.rfind("run: ", 0) == 0)
      out << "slicing: " << sliced(m) << "with " << m.slices << " slices: the run did not reach the end ("
          << m.worst_quantity.substr(5) << "), so nothing was compared\n";
    else if (m.slices > 0)
      out << "slicing: " << sliced(m) << "with " << m.slices << " slices: the answer "
          << (m.passed ? "stays within" : "changes beyond") << " the accuracy (largest change "
          << sci(m.worst_relative) +
                 (m.worst_quantity.empty() ? std::string() : ", in " + m.worst_quantity)
          << ")\n";
  // Observed order of the slicing error: the change from N/2 to N slices over the change from N
  // to 2N is 2^p for an error ~ N^-p, both measured on one quantity (the coarse row's largest).
  for (std::size_t i = 0; i + 1 < r.models.size(); ++i) {
    const ConvergeModel& a = r.models[i];
    const ConvergeModel& b = r.models[i + 1];
    if (!(a.slices > 0 && b.slices > a.slices && b.slice_body == a.slice_body)) continue;
    if (b.slices != 4 * a.slices) {
      out << "slicing order" << (sliced(a).empty() ? "" : " of " + sliced(a).substr(0, sliced(a).size() - 1))
          << ": not measured (" << a.slices << " and " << b.slices
          << " slices are not half and twice the scene's: its slices are odd)\n";
      continue;
    }
    double fine = std::numeric_limits<double>::quiet_NaN();
    for (std::size_t i = 0; i < b.checks.size() && i < b.scales.size(); ++i)
      if (b.checks[i].quantity == a.worst_quantity) fine = b.checks[i].error / b.scales[i];
    // The beam generator's modal integrals are exact (core/flex/beam.hpp): once its blocks resolve
    // the modes, the slicing changes nothing but rounding and the integrator's path, and a ratio
    // of two such changes is no order.
    constexpr double kSlicingNoise = 1e-9;
    if (std::isfinite(a.worst_relative) && std::isfinite(fine) && a.worst_relative <= kSlicingNoise &&
        fine <= kSlicingNoise) {
      const std::string body = sliced(a);
      char line[400];
      std::snprintf(line, sizeof line,
                    "slicing order%s%s: none to measure (the changes in %s, %.2g and %.2g, are "
                    "rounding and integration noise: the answer does not depend on the slicing)\n",
                    body.empty() ? "" : " of ", body.empty() ? "" : body.substr(0, body.size() - 1).c_str(),
                    a.worst_quantity.c_str(), a.worst_relative, fine);
      out << line;
    } else if (std::isfinite(a.worst_relative) && std::isfinite(fine) && a.worst_relative > 0 && fine > 0) {
      const double ratio = a.worst_relative / fine;
      const std::string body = sliced(a);
      char line[400];
      std::snprintf(line, sizeof line,
                    "slicing order%s%s: the change in %s falls %.2f times per doubling of the "
                    "slices (observed order %.2f)\n", body.empty() ? "" : " of ",
                    body.empty() ? "" : body.substr(0, body.size() - 1).c_str(), a.worst_quantity.c_str(),
                    ratio, std::log2(ratio));
      out << line;
      // A change that does not fall with the slicing is not the slicing's (the beam generator is
      // exact): it is the runs' own error, as large as the quantity itself when that quantity is
      // small (a flexible boom on orbit, its modal rates 2e-7 against the default atol 1e-10:
      // 1.8e-2 at the defaults, 1.4e-10 at --rtol 1e-12 --atol 1e-14).
      if (ratio < 1.5)
        out << "  (not falling with the slicing: the runs' integration error, not the slicing; "
               "run converge with a smaller --rtol and --atol to measure it)\n";
    }
  }
  for (const std::string& n : r.notes) out << "note: " << n << '\n';
  return out.str();
}

std::string converge_json(const ConvergeResult& r) {
  using json = nlohmann::ordered_json;
  auto num = [](double v) -> json { return std::isfinite(v) ? json(v) : json(nullptr); };
  json j;
  j["scene"] = r.scene;
  j["engine"] = r.engine;
  j["accuracy"] = r.accuracy;
  json groups = json::array();
  for (const ModeGroup& g : r.groups)
    groups.push_back({{"body", g.body}, {"group", g.name}, {"modes", g.modes.size()}});
  j["groups"] = groups;
  json models = json::array();
  for (const ConvergeModel& m : r.models) {
    json checks = json::array();
    for (std::size_t i = 0; i < m.checks.size(); ++i) {
      const Check& k = m.checks[i];
      const double scale = i < m.scales.size() ? m.scales[i] : std::numeric_limits<double>::quiet_NaN();
      checks.push_back({{"quantity", k.quantity}, {"error", num(k.error)}, {"scale", num(scale)},
                        {"relative", num(scale > 0 ? k.error / scale : std::numeric_limits<double>::quiet_NaN())},
                        {"bound", num(k.bound)}, {"normalised", num(k.normalised)},
                        {"status", to_string(k.status)}});
    }
    models.push_back({{"label", m.label}, {"counts", m.counts}, {"modes", m.modes},
                      {"full", m.full}, {"slices", m.slices}, {"passed", m.passed},
                      {"worst_relative", num(m.worst_relative)},
                      {"worst_normalised", num(m.worst_normalised)},
                      {"worst_quantity", m.worst_quantity}, {"checks", checks}});
  }
  j["models"] = models;
  j["smallest"] = r.models[static_cast<std::size_t>(r.smallest)].label;
  j["notes"] = r.notes;
  return j.dump(2) + "\n";
}

}  // namespace crossdyn::harness
