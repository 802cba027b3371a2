// A body's `flexible:` block (flex_block.hpp): the beam generator's spec or nodal data files.
#include "core/scene/flex_block.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <map>

#include "core/errors.hpp"
#include "core/flex/beam.hpp"
#include "core/flex/nodal_csv.hpp"

namespace crossdyn::scene {
namespace {

using flex::BeamBoundary;
using flex::BeamDamping;
using flex::BeamNormalisation;
using flex::BeamSpec;

constexpr const char* kAxes[] = {"x", "y", "z"};
constexpr const char* kBoundaries[] = {"free-free", "clamped-bottom", "clamped-top"};
constexpr const char* kNormalisations[] = {"auto", "top", "bottom", "mass"};

template <std::size_t N>
int index_of(const char* const (&words)[N], const std::string& w) {
  for (std::size_t i = 0; i < N; ++i)
    if (w == words[i]) return static_cast<int>(i);
  throw std::logic_error("scene schema: word '" + w + "' without a meaning");
}

// An integer count from a Number row, in [lo, hi].
int count(const Reader& r, const Field& f, int lo, int hi, const std::string& what) {
  const double x = r.number(f);
  if (!(x >= lo && x <= hi) || x != std::floor(x))
    r.fail(f.val, what + " must be an integer from " + std::to_string(lo) + " to " +
                      std::to_string(hi) + ", found " + shortest(x));
  return static_cast<int>(x);
}

// The spec's canonical text (flow YAML, SI): what the writer writes back.
std::string beam_form(const BeamSpec& s) {
  YAML::Emitter y;
  y << YAML::Flow << YAML::BeginMap << YAML::Key << "beam" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "length" << YAML::Value << shortest(s.length);
  y << YAML::Key << "axis" << YAML::Value << kAxes[s.axis];
  y << YAML::Key << "mass_per_length" << YAML::Value << shortest(s.mass_per_length);
  y << YAML::Key << "section" << YAML::Value << YAML::BeginSeq;
  for (double side : s.section) y << shortest(side);
  y << YAML::EndSeq;
  y << YAML::Key << "bending" << YAML::Value << YAML::BeginMap;
  for (int d = 0; d < 3; ++d) {
    if (d == s.axis) continue;
    const flex::BeamPlane& p = s.bending[static_cast<std::size_t>(d)];
    y << YAML::Key << kAxes[d] << YAML::Value << YAML::BeginMap;
    y << YAML::Key << "modes" << YAML::Value << p.modes;
    y << YAML::Key << "EI" << YAML::Value << shortest(p.EI);
    y << YAML::EndMap;
  }
  y << YAML::EndMap;
  y << YAML::Key << "boundary" << YAML::Value << kBoundaries[static_cast<int>(s.boundary)];
  y << YAML::Key << "slices" << YAML::Value << s.slices;
  y << YAML::Key << "normalisation" << YAML::Value
    << kNormalisations[static_cast<int>(s.normalisation)];
  if (s.geometric_stiffening) y << YAML::Key << "geometric_stiffening" << YAML::Value << true;
  if (s.damping.kind != BeamDamping::Kind::None) {
    y << YAML::Key << "damping" << YAML::Value << YAML::BeginMap;
    if (s.damping.kind == BeamDamping::Kind::Ratio) {
      y << YAML::Key << "ratios" << YAML::Value << YAML::BeginSeq;
      for (double z : s.damping.ratios) y << shortest(z);
      y << YAML::EndSeq;
    } else {
      y << YAML::Key << "alpha" << YAML::Value << shortest(s.damping.alpha);
      y << YAML::Key << "beta" << YAML::Value << shortest(s.damping.beta);
    }
    y << YAML::EndMap;
  }
  y << YAML::EndMap << YAML::EndMap;
  return y.c_str();
}

std::string nodes_form(const std::string& nodes, const std::string& modes) {
  YAML::Emitter y;
  y << YAML::Flow << YAML::BeginMap;
  y << YAML::Key << "nodes" << YAML::Value << YAML::DoubleQuoted << nodes;
  if (!modes.empty()) y << YAML::Key << "modes" << YAML::Value << YAML::DoubleQuoted << modes;
  y << YAML::EndMap;
  return y.c_str();
}

flex::FlexModel read_beam(const Reader& r, const Field& f) {
  const MapView m(r, f.val, "bodies[].flexible.beam");
  BeamSpec s;
  std::map<std::string, Val> where;  // spec key (beam_spec_problems) => its value, for messages
  auto note = [&where](const std::string& key, const Field& x) { where.emplace(key, x.val); };

  const Field length = m.at("length");
  note("length", length);
  s.length = r.number(length);
  if (auto a = m.get("axis")) {
    note("axis", *a);
    s.axis = index_of(kAxes, r.word(*a));
  }
  const Field rho = m.at("mass_per_length");
  note("mass_per_length", rho);
  s.mass_per_length = r.number(rho);
  const Field section = m.at("section");
  const Eigen::Vector3d sides = r.vector(section);
  for (int d = 0; d < 3; ++d) {
    s.section[static_cast<std::size_t>(d)] = sides(d);
    note(std::string("section.") + kAxes[d], section);
  }
  if (auto b = m.get("bending")) {
    const MapView planes(r, b->val, "bodies[].flexible.beam.bending");
    for (int d = 0; d < 3; ++d) {
      const auto pf = planes.get(kAxes[d]);
      if (!pf) continue;
      const std::string key = std::string("bending.") + kAxes[d];
      note(key, *pf);
      const MapView p(r, pf->val, "bodies[].flexible.beam." + key);
      flex::BeamPlane& plane = s.bending[static_cast<std::size_t>(d)];
      const Field modes = p.at("modes");
      note(key + ".modes", modes);
      plane.modes = count(r, modes, 0, kMaxSceneBeamModes, "the number of modes");
      if (auto ei = p.get("EI")) {
        note(key + ".EI", *ei);
        plane.EI = r.number(*ei);
      }
    }
  }
  if (auto b = m.get("boundary")) {
    note("boundary", *b);
    s.boundary = static_cast<BeamBoundary>(index_of(kBoundaries, r.word(*b)));
  }
  if (auto n = m.get("slices")) {
    note("slices", *n);
    s.slices = count(r, *n, 1, kMaxSceneSlices, "the number of slices");
  }
  if (auto n = m.get("normalisation")) {
    note("normalisation", *n);
    s.normalisation = static_cast<BeamNormalisation>(index_of(kNormalisations, r.word(*n)));
  }
  if (auto g = m.get("geometric_stiffening")) {
    note("geometric_stiffening", *g);
    s.geometric_stiffening = r.boolean(*g);
  }
  if (auto df = m.get("damping")) {
    note("damping", *df);
    const MapView dm(r, df->val, "bodies[].flexible.beam.damping");
    const auto ratios = dm.get("ratios");
    const auto alpha = dm.get("alpha"), beta = dm.get("beta");
    if (ratios && (alpha || beta))
      r.fail(df->val, "give either damping ratios or Rayleigh alpha and beta, not both");
    if (ratios) {
      note("damping.ratios", *ratios);
      s.damping.kind = BeamDamping::Kind::Ratio;
      const std::vector<Val> items = r.list(ratios->val, "a list of damping ratios", true);
      if (items.size() > 2 * static_cast<std::size_t>(kMaxSceneBeamModes))
        r.fail(ratios->val, "more damping ratios than modes");
      const Key* row = find("bodies[].flexible.beam.damping.ratios[]");
      for (const Val& item : items) s.damping.ratios.push_back(r.number(Field{item, row}));
    } else if (alpha || beta) {
      s.damping.kind = BeamDamping::Kind::Rayleigh;
      if (alpha) {
        note("damping.alpha", *alpha);
        s.damping.alpha = r.number(*alpha);
      }
      if (beta) {
        note("damping.beta", *beta);
        s.damping.beta = r.number(*beta);
      }
    }
  }
  if (const auto problems = flex::beam_spec_problems(s); !problems.empty()) {
    const flex::SpecProblem& p = problems.front();
    // The value named, or the nearest enclosing key that was given, or the beam block.
    std::string key = p.key;
    while (!key.empty() && !where.count(key)) {
      const std::size_t dot = key.rfind('.');
      key = dot == std::string::npos ? "" : key.substr(0, dot);
    }
    r.fail(key.empty() ? f.val : where.at(key), p.what);
  }
  flex::FlexModel model;
  try {
    model = flex::make_beam(s, "the beam generator");
  } catch (const InputError& e) {
    r.fail(f.val, e.what());
  }
  model.flex.scene_form = beam_form(s);
  return model;
}

flex::FlexModel read_nodes(const Reader& r, const MapView& m) {
  const Field nodes = *m.get("nodes");
  const std::string nodes_path = r.text(nodes);
  std::string modes_path;
  if (auto mf = m.get("modes")) modes_path = r.text(*mf);
  if (nodes_path.empty()) r.fail(nodes.val, "the nodal data file's path is empty");
  namespace fs = std::filesystem;
  // A relative path is relative to the scene file's folder.
  const fs::path dir = fs::path(r.file()).parent_path();
  auto resolve = [&dir](const std::string& p) {
    if (p.empty() || fs::path(p).is_absolute() || dir.empty()) return p;
    return (dir / p).string();
  };
  flex::FlexModel model;
  try {
    model = flex::read_nodal_csv(resolve(nodes_path), resolve(modes_path));
  } catch (const InputError& e) {
    r.fail(nodes.val, e.what());
  }
  if (model.flex.modes() > kMaxSceneFlexModes)
    r.fail(nodes.val, std::to_string(model.flex.modes()) + " modes: a scene's flexible body has at "
                      "most " + std::to_string(kMaxSceneFlexModes));
  model.flex.scene_form = nodes_form(nodes_path, modes_path);
  model.flex.data_files.push_back(resolve(nodes_path));
  if (!modes_path.empty()) model.flex.data_files.push_back(resolve(modes_path));
  return model;
}

}  // namespace

flex::FlexModel read_flexible(const Reader& r, const Field& f) {
  const MapView m(r, f.val, "bodies[].flexible");
  const auto beam = m.get("beam");
  const auto nodes = m.get("nodes");
  const auto modes = m.get("modes");
  if (beam && nodes) r.fail(f.val, "give either 'beam' or 'nodes', not both");
  if (beam && modes) r.fail(modes->val, "'modes' goes with a nodal data file ('nodes'), not 'beam'");
  if (!beam && !nodes)
    r.fail(f.val, "missing 'beam' (a beam generator spec) or 'nodes' (a nodal data file)");
  return beam ? read_beam(r, *beam) : read_nodes(r, m);
}

}  // namespace crossdyn::scene
