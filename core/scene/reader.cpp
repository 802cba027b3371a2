// Scene reader: YAML text => validated System in SI units (scene.hpp).
//
//   read_scene_text(text, label)  (text) => (System, warnings), in passes:
//     precheck_text    size, UTF-8, control characters
//     parse_yaml       one YAML document
//     read_header      name, description, source, analytic, zero_linear_momentum
//     read_bodies      mass, inertia, torque, center_of_mass, flexible (flex_block.hpp)
//     read_joints      type, bodies, points or nodes, axis, offset, loads, initial conditions
//     shift_points     joint points given from a body's reference origin => from its CM
//     order            topology (order_joints, topology.hpp) and the base velocity rule
//     read_run, read_compare, check_analytic
// Keys are checked against the schema (schema.hpp) by MapView; values are read as the schema row
// says (reader_values.cpp).
//
// Guards against hostile input (found or anticipated by fuzz/scene_fuzzer.cpp, see fuzz/README.md):
//   - a scene larger than kMaxSceneBytes is rejected before parsing;
//   - the text must be valid UTF-8 without C0 control characters other than tab, LF and CR;
//   - nesting depth: yaml-cpp 0.7's parser is recursive but guards its own depth (DepthGuard in
//     SingleDocParser, ErrorMsg::BAD_FILE "bad file" past a few hundred levels); that exception
//     becomes an InputError here. The size limit bounds the work in any case;
//   - anchors and aliases may make the node graph cyclic (`&a [*a]`): the reader only follows the
//     scene schema, which has a fixed depth, and never walks the node graph generically.
#include "core/scene/reader.hpp"

#include <yaml-cpp/anchor.h>
#include <yaml-cpp/eventhandler.h>

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <numbers>
#include <fstream>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

#include "core/errors.hpp"
#include "core/flex/beam.hpp"
#include "core/orbit.hpp"
#include "core/run_limits.hpp"
#include "core/scene/flex_block.hpp"

namespace crossdyn {

std::string SceneWarning::text() const {
  return file + (line > 0 ? ":" + std::to_string(line) + ":" + std::to_string(column) : "") +
         ": warning: " + (key.empty() ? "" : key + ": ") + message;
}

std::string SceneWarning::detail() const {
  return (line > 0 ? "line " + std::to_string(line) + ": " : std::string()) +
         (key.empty() ? "" : key + ": ") + message;
}

namespace scene {
namespace {

using units::Dimension;

// ---------------------------------------------------------------------------------------------
// Text and document

void precheck_text(const Reader& r, const std::string& text) {
  if (text.size() > kMaxSceneBytes)
    r.fail(YAML::Mark(), "",
           "the scene is larger than the limit of " + std::to_string(kMaxSceneBytes) +
               " bytes (a guard against hostile input; see fuzz/README.md)");
  auto position = [&text](std::size_t at) {
    YAML::Mark m;
    for (std::size_t i = 0; i < at; ++i) {
      if (text[i] == '\n')
        ++m.line, m.column = 0;
      else
        ++m.column;
    }
    return m;
  };
  const std::size_t bad = invalid_utf8_at(text);
  if (bad != std::string_view::npos) r.fail(position(bad), "", "the scene is not valid UTF-8 text");
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto u = static_cast<unsigned char>(text[i]);
    if ((u < 0x20 && u != '\t' && u != '\n' && u != '\r') || u == 0x7F)
      r.fail(position(i), "",
             "control character " + std::to_string(u) + " is not allowed in a scene file");
  }
}

// Records where each document starts; ignores everything else (used to count documents).
struct DocumentStarts : YAML::EventHandler {
  std::vector<YAML::Mark> starts;
  void OnDocumentStart(const YAML::Mark& mark) override { starts.push_back(mark); }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t,
                const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}
};

// True when `doc`, the first document of `text`, is certainly the only one, so that the second
// parse below (a third of a small run's start-up) can be skipped. yaml-cpp 0.7's scanner ends a
// block mapping whose keys start in column 0 only at the end of the stream or at a line that
// begins a directive ('%'), a document ("---") or a document end ("..."): its indentation cannot
// drop below column 0 (Scanner::PopIndentToHere), so nothing can follow it in the same stream.
// Any other shape (a flow or indented root, a scalar, a sequence), or any line beginning with one
// of those three (even inside a block scalar), or a byte-order mark, takes the full check.
bool only_document(const YAML::Node& doc, const std::string& text) {
  if (!doc.IsMap() || doc.Style() != YAML::EmitterStyle::Block || doc.Mark().is_null() ||
      doc.Mark().column != 0)
    return false;
  if (text.size() >= 3 && static_cast<unsigned char>(text[0]) == 0xEF) return false;  // a BOM
  for (std::size_t at = 0; at < text.size();) {
    const char c = text[at];
    if (c == '%' || text.compare(at, 3, "---") == 0 || text.compare(at, 3, "...") == 0) return false;
    const std::size_t end = text.find_first_of("\r\n", at);
    if (end == std::string::npos) break;
    at = end + 1;
  }
  return true;
}

// A unit after a flow list, "inertia: [30, 20, 12] kg m^2" or "{parent_point: [0, 1, 0] m}":
// YAML ends the value at ']', and yaml-cpp 0.7 stops at the unit with "end of map not found" (block
// mapping), "end of map flow not found" or "end of sequence flow not found" (flow), its mark at
// the unit's first character (tests/scene/test_scene_errors.cpp). Found from that mark: a unit
// (a letter, then no YAML indicator up to the end of the line, a comment or a flow ',', '}' or
// ']') right after a ']' on the same line, and the list that ']' closes. `end` is set to the end
// of the unit.
std::optional<UnitAfterList> find_unit_after_list(const std::string& text, const YAML::Mark& mark,
                                                  std::size_t& end) {
  if (mark.is_null() || mark.pos <= 0 || static_cast<std::size_t>(mark.pos) >= text.size())
    return std::nullopt;
  const auto at = static_cast<std::size_t>(mark.pos);
  // The mark must be where the text says it is (a byte-order mark or another encoding: not).
  const std::size_t line_start = text.rfind('\n', at - 1);
  const std::size_t column = line_start == std::string::npos ? at : at - line_start - 1;
  if (column != static_cast<std::size_t>(mark.column) ||
      std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n') != mark.line)
    return std::nullopt;
  const auto first = static_cast<unsigned char>(text[at]);
  if (!(std::isalpha(first) || first >= 0x80)) return std::nullopt;
  end = at;
  while (end < text.size() && text[end] != '\n' && text[end] != '\r' && text[end] != ',' &&
         text[end] != ']' && text[end] != '}' &&
         !(text[end] == '#' && (text[end - 1] == ' ' || text[end - 1] == '\t')))
    ++end;
  std::size_t unit_end = end;
  while (unit_end > at && (text[unit_end - 1] == ' ' || text[unit_end - 1] == '\t')) --unit_end;
  const std::string unit = text.substr(at, unit_end - at);
  if (unit.find_first_of(":[{\"'&*!|>`@%") != std::string::npos) return std::nullopt;
  std::size_t b = at;
  while (b > 0 && (text[b - 1] == ' ' || text[b - 1] == '\t')) --b;
  if (b == 0 || text[b - 1] != ']') return std::nullopt;
  const std::size_t close = b - 1;
  std::size_t open = std::string::npos;
  int depth = 0;
  for (std::size_t i = close + 1; i-- > 0;) {
    if (text[i] == ']') ++depth;
    if (text[i] == '[' && --depth == 0) {
      open = i;
      break;
    }
  }
  if (open == std::string::npos) return std::nullopt;
  // The key: "key:" before the '[', or before the list that holds it (a row of a matrix).
  std::string key;
  for (std::size_t from = open, level = 0; key.empty() && level < 4; ++level) {
    std::size_t k = from;
    while (k > 0 && (text[k - 1] == ' ' || text[k - 1] == '\t')) --k;
    if (k > 0 && text[k - 1] == ':') {
      const std::size_t key_end = k - 1;
      std::size_t key_begin = key_end;
      while (key_begin > 0 && (std::isalnum(static_cast<unsigned char>(text[key_begin - 1])) ||
                               text[key_begin - 1] == '_' || text[key_begin - 1] == '-'))
        --key_begin;
      key = text.substr(key_begin, key_end - key_begin);
      break;
    }
    if (k == 0 || (text[k - 1] != '[' && text[k - 1] != ',')) break;
    // An element of an enclosing flow list: find that list's '['.
    int d = 0;
    std::size_t i = k;
    for (; i-- > 0;) {
      if (text[i] == ']' || text[i] == '}') ++d;
      if (text[i] == '[' || text[i] == '{') {
        if (d == 0) break;
        --d;
      }
    }
    if (i == std::string::npos || text[i] != '[') break;
    from = i;
  }
  return UnitAfterList{open, mark, unit, text.substr(open, close + 1 - open), key, false};
}

// The document of `text`. A unit after a list (find_unit_after_list) is noted for the reader to
// report at its key, blanked, and the text parsed again (at most kMaxReportedErrors times); any
// other YAML error stops the reader, with the units after lists found before it.
Val parse_yaml(const Reader& r, const std::string& text) {
  YAML::Node doc;
  std::string patched;  // the text with each unit after a list found so far blanked
  const std::string* source = &text;
  for (;;) {
    try {
      doc = YAML::Load(*source);
      // One document only. Not YAML::LoadAll: yaml-cpp 0.7's document loop never ends when junk
      // follows a document's top-level scalar ("\"a\", b" yields empty documents forever; found
      // by the fuzzer, tests/scene/fuzz_regressions/loadall-hang-*.yaml). Two calls are bounded.
      if (only_document(doc, *source)) return Val{doc, "", doc.Mark()};
      std::istringstream in(*source);
      YAML::Parser parser(in);
      DocumentStarts starts;
      parser.HandleNextDocument(starts);
      if (parser.HandleNextDocument(starts))
        r.fail(starts.starts.size() > 1 ? starts.starts[1] : YAML::Mark(), "",
               "a second YAML document or text after the end of the first; a scene file holds one "
               "document");
      break;
    } catch (const YAML::Exception& e) {
      std::size_t end = 0;
      if (auto u = find_unit_after_list(*source, e.mark, end)) {
        r.note_unit_after_list(std::move(*u));
        if (r.units_after_lists() <= kMaxReportedErrors) {
          if (source == &text) patched = text;
          std::fill(patched.begin() + static_cast<std::ptrdiff_t>(e.mark.pos),
                    patched.begin() + static_cast<std::ptrdiff_t>(end), ' ');
          source = &patched;
          continue;
        }
        r.stop(e.mark);  // more than a message shows: stop with those
      }
      // yaml-cpp's depth guard reports ErrorMsg::BAD_FILE ("bad file"); say what it means.
      r.fail(e.mark, "",
             "malformed YAML: " +
                 (e.msg == "bad file" ? std::string("nesting too deep (yaml-cpp: bad file)")
                                      : e.msg));
    }
  }
  if (doc.IsNull()) {
    std::vector<std::string> required;
    for (const std::string& k : child_names(""))
      if (find(k)->required) required.push_back(k);
    r.fail(YAML::Mark(), "",
           "the scene is empty; expected a mapping with the keys " + join(required));
  }
  return Val{doc, "", doc.Mark().is_null() ? YAML::Mark() : doc.Mark()};
}

// ---------------------------------------------------------------------------------------------
// The scene's own keys

// The environment block (issue 28; docs/environment.md): uniform gravity, or a central body and
// the circular orbit of the system's CM.
void read_environment(const Reader& r, const MapView& top, System& s) {
  const auto f = top.get("environment");
  if (!f) return;
  const MapView m(r, f->val, "environment");
  Environment& e = s.environment;
  const auto g = m.get("gravity");
  const auto body = m.get("central_body");
  const auto orbit = m.get("orbit");
  if (g && body)
    r.fail(body->val, "give uniform `gravity` or a `central_body` with its `orbit`, not both");
  if (g) {
    e.kind = Environment::Kind::Uniform;
    e.g_N = r.vector(*g);
    if (orbit) r.fail(orbit->val, "an orbit needs a `central_body`, not uniform `gravity`");
    return;
  }
  if (!body && !orbit)
    r.fail(f->val, "the environment block is empty: give `gravity` (uniform), or `central_body` "
                   "and `orbit`");
  if (!body) r.fail(orbit->val, "an orbit needs a `central_body` (its mu) beside it");
  if (!orbit) m.missing("orbit", "a central body needs the `orbit` of the system's CM about it");
  e.kind = Environment::Kind::Orbit;
  const MapView b(r, body->val, "environment.central_body");
  const Field mu = b.at("mu");
  e.mu = r.number(mu);
  if (!(e.mu > 0)) r.fail(mu.val, "mu must be > 0 (Earth: 3.986004418e14 m^3/s^2)");
  if (auto x = b.get("radius")) {
    e.body_radius = r.number(*x);
    if (!(e.body_radius > 0)) r.fail(x->val, "the central body's radius must be > 0");
  }
  const MapView o(r, orbit->val, "environment.orbit");
  const auto radius = o.get("radius");
  const auto altitude = o.get("altitude");
  if (radius && altitude) r.fail(altitude->val, "give the orbit's `radius` or its `altitude`, not both");
  if (radius) {
    e.radius = r.number(*radius);
    if (!(e.radius > e.body_radius))
      r.fail(radius->val, e.body_radius > 0 ? "the orbit's radius must exceed the central body's "
                                              "radius (" + std::to_string(e.body_radius) + " m)"
                                            : std::string("the orbit's radius must be > 0"));
  } else if (altitude) {
    if (!(e.body_radius > 0))
      r.fail(altitude->val, "an altitude needs the central body's `radius` (or give the orbit's "
                            "`radius`)");
    const double h = r.number(*altitude);
    if (!(h > 0)) r.fail(altitude->val, "the altitude must be > 0");
    e.radius = e.body_radius + h;
  } else {
    o.missing("radius", "the orbit needs its `radius` (or `altitude`)");
  }
  if (auto x = o.get("inclination")) {
    e.inclination = r.number(*x);
    if (!(e.inclination >= 0 && e.inclination <= std::numbers::pi))
      r.fail(x->val, "the inclination must be between 0 and 180 deg");
  }
  if (auto x = o.get("raan")) e.raan = r.number(*x);
  if (auto x = o.get("argument_of_latitude")) e.latitude0 = r.number(*x);
}

void read_header(const Reader& r, const MapView& top, System& s) {
  r.attempt([&] { s.name = r.name(top.at("name")); });
  r.attempt([&] {
    if (auto f = top.get("description")) s.description = r.text(*f);
  });
  r.attempt([&] {
    if (auto f = top.get("source")) s.source = r.text(*f);
  });
  r.attempt([&] {
    if (auto f = top.get("analytic")) s.analytic = r.word(*f);
  });
  r.attempt([&] {
    if (auto f = top.get("zero_linear_momentum")) s.zero_linear_momentum = r.boolean(*f);
  });
}

// ---------------------------------------------------------------------------------------------
// Bodies

// What the later passes need to know of the bodies besides the System's fields.
struct BodyIndex {
  std::vector<Val> vals;                                 // each body's mapping, for messages
  std::unordered_map<std::string, int> index;            // name => index
  std::vector<std::string> names;                        // in file order ("" when unreadable)
  std::vector<std::optional<Eigen::Vector3d>> p_RoBo_R;  // center_of_mass, when given
  std::vector<bool> broken;  // read with errors (recorded): what depends on it is not checked
  bool all_named = true;     // false: a body had no readable name, so a joint may name it

  // The body a joint names, or an error naming the known ones (a skip when a body without a
  // readable name may be the one meant).
  int find(const Reader& r, const Field& f) const {
    const std::string n = r.name(f);
    const auto it = index.find(n);
    if (it == index.end()) {
      if (!all_named) r.skip();
      std::vector<std::string> known;
      for (const std::string& b : names)
        if (!b.empty()) known.push_back(b);
      r.fail(f.val, "unknown body '" + n + "'" + suggestion(n, known) + "; bodies: " + join(known));
    }
    return it->second;
  }
};

// The name of a body mapping that could not be read as a whole, when it has a plain one.
std::string plain_name(const YAML::Node& body) {
  if (!body.IsMap()) return "";
  std::string name;
  for (YAML::const_iterator it = body.begin(); it != body.end(); ++it) {
    const YAML::detail::iterator_value kv = *it;
    if (kv.first.IsScalar() && kv.first.Scalar() == "name" && kv.second.IsScalar())
      name = kv.second.Scalar();
  }
  return name;
}

// A flexible body's mass and inertia are its nodes' sums; when the scene gives them too they must
// agree (to kFlexRigidTolerance relative), a check of the modal data against the author's numbers.
inline constexpr double kFlexRigidTolerance = 1e-6;

void check_flex_rigid(const Reader& r, const MapView& m, const flex::FlexModel& model) {
  if (auto f = m.get("mass")) {
    const double given = r.number(*f);
    if (!(std::abs(given - model.mass) <= kFlexRigidTolerance * model.mass))
      r.fail(f->val, "the flexible body's nodes sum to " + shortest(model.mass) + " kg, but mass is " +
                         shortest(given) + " kg; they must agree to 1e-6 relative (omit mass to "
                         "take the node sum)");
  }
  if (auto f = m.get("inertia")) {
    const Eigen::Matrix3d given = r.inertia(*f);
    const double scale = model.I_BBo_B.cwiseAbs().maxCoeff();
    const double diff = (given - model.I_BBo_B).cwiseAbs().maxCoeff();
    if (!(diff <= kFlexRigidTolerance * scale)) {
      const Eigen::Matrix3d& I = model.I_BBo_B;
      r.fail(f->val, "the flexible body's nodes give the inertia [" + shortest(I(0, 0)) + ", " +
                         shortest(I(1, 1)) + ", " + shortest(I(2, 2)) + ", " + shortest(I(0, 1)) +
                         ", " + shortest(I(0, 2)) + ", " + shortest(I(1, 2)) +
                         "] kg m^2 (xx, yy, zz, xy, xz, yz), which differs from the one given by " +
                         shortest(diff) + " kg m^2; they must agree to 1e-6 of the largest entry "
                         "(omit inertia to take the node sum)");
    }
  }
}

// A body's keys after its name; each key's errors are recorded and the others read on. False
// when any had an error.
bool read_body(const Reader& r, const MapView& m, Body& b,
               std::optional<Eigen::Vector3d>& p_RoBo_R) {
  bool ok = true;
  if (auto ff = m.get("flexible")) {
    ok &= r.attempt([&] {
      if (auto com = m.get("center_of_mass"))
        r.fail(com->val, "a flexible body's origin is its nodes' centre of mass: center_of_mass is "
                         "not allowed (points on it are measured from that CM, or name a node)");
    });
    ok &= r.attempt([&] {
      flex::FlexModel model = read_flexible(r, *ff);
      check_flex_rigid(r, m, model);
      b.mass = model.mass;
      b.I_BBo_B = model.I_BBo_B;
      if (!(b.mass > 0) || b.mass > kMaxMass)
        r.fail(ff->val, "the nodes' total mass " + shortest(b.mass) + " kg is outside (0, 1e9] kg");
      b.flex = std::move(model.flex);
    });
  } else {
    // (A mistyped `flexible` is the error, not the mass and inertia a rigid body would need.)
    for (const char* key : {"mass", "inertia"})
      if (!m.get(key))
        ok &= r.attempt([&] {
          if (m.mistyped("flexible")) r.skip();
          m.missing(key, std::string("missing required key '") + key +
                             "' in a body (a rigid body needs mass and inertia; a flexible one "
                             "takes them from its nodes)");
        });
    if (const auto mass = m.get("mass"))
      ok &= r.attempt([&] {
        b.mass = r.number(*mass);
        if (!(b.mass > 0))
          r.fail(mass->val, "mass must be positive, found " + shortest(b.mass) + " kg");
        if (b.mass > kMaxMass)
          r.fail(mass->val, "absurd mass " + shortest(b.mass) + " kg (limit 1e9 kg)");
      });
    if (const auto inertia = m.get("inertia"))
      ok &= r.attempt([&] { b.I_BBo_B = r.inertia(*inertia); });
    if (const auto com = m.get("center_of_mass"))
      ok &= r.attempt([&] { p_RoBo_R = r.vector(*com); });
  }
  if (auto tf = m.get("torque"))
    ok &= r.attempt([&] {
      const MapView t(r, tf->val, "bodies[].torque");
      if (auto f = t.get("frame"))
        b.torque_frame = r.word(*f) == "inertial" ? Body::Frame::Inertial : Body::Frame::Body;
      b.torque = r.profile<3>(t.at("profile"), kAnyJoint);
    });
  return ok;
}

// Each body is read on its own: its errors are recorded, and a body with errors keeps its place
// (and its name, when readable) so that the joints naming it are read too.
BodyIndex read_bodies(const Reader& r, const MapView& top, System& s) {
  BodyIndex bi;
  std::vector<Val> items;
  if (!r.attempt([&] { items = r.list(top.at("bodies")); })) {
    bi.all_named = false;
    return bi;
  }
  for (const Val& item : items) {
    Body b;
    std::optional<Eigen::Vector3d> com;
    bool named = false, duplicate = false;
    const bool ok = r.attempt([&] {
      const MapView m(r, item, "bodies[]");
      const Field name = m.at("name");
      b.name = r.name(name);
      named = true;
      if (auto it = bi.index.find(b.name); it != bi.index.end()) {
        duplicate = true;
        r.record(name.val.mark, name.val.path,
                 "duplicate body name '" + b.name + "' (first at line " +
                     std::to_string(bi.vals[static_cast<std::size_t>(it->second)].mark.line + 1) +
                     ")");
      }
      if (!read_body(r, m, b, com)) r.skip();
    });
    if (!named) {
      b.name = plain_name(item.node);
      if (b.name.empty()) bi.all_named = false;
    }
    if (!b.name.empty() && !duplicate) bi.index.emplace(b.name, static_cast<int>(s.bodies.size()));
    bi.p_RoBo_R.push_back(com);
    bi.names.push_back(b.name);
    bi.vals.push_back(item);
    bi.broken.push_back(!ok || duplicate);
    s.bodies.push_back(std::move(b));
  }
  return bi;
}

// ---------------------------------------------------------------------------------------------
// Joints

// A joint as read, before the topology pass orders the joints.
struct RawJoint {
  Joint joint;
  Val node;
  Val type_val;
  Val child_val;
  std::optional<Val> parent_val;
  std::optional<Val> velocity_val;  // the free joint's initial velocity, if given
};

// A universal joint's two axes: at least this far from parallel (rad; 1 deg).
constexpr double kMinGimbalAxesAngle = std::numbers::pi / 180;

JointType type_of(const std::string& word) {
  for (const JointTypeInfo& t : joint_types())
    if (t.name == word) return t.type;
  throw std::logic_error("scene schema: joint type '" + word + "' without a row");
}

// Why a key does not apply to a joint type, where it helps to say.
std::string why_not(JointType type, const std::string& key) {
  if (key == "parent" && type == JointType::Free) return "its parent is the inertial frame N";
  if ((key == "parent_node" || key == "child_node") &&
      (type == JointType::Prismatic || type == JointType::Universal))
    return "prismatic and universal joints cannot be attached at a flexible body's node yet; "
           "attach the joint at a point (`" + key.substr(0, key.find('_')) + "_point`)";
  if (key == "initial" && type == JointType::Fixed)
    return "a fixed joint has no degrees of freedom, so no initial conditions";
  return "";
}

// A universal joint's pair value, [axis 1, axis 2], into its two fields.
void read_pair(const Reader& r, const Field& f, double& axis1, double& axis2) {
  const Eigen::Vector2d v = r.pair(f);
  axis1 = v[0];
  axis2 = v[1];
}

// Spring, damper and motor (revolute, spherical, prismatic and universal joints), each read on
// its own. A universal joint's values are pairs, [axis, axis2].
void read_loads(const Reader& r, const MapView& m, const std::string& type, Joint& J) {
  const unsigned bit = joint_type(J.type).bit;
  const bool prismatic = J.type == JointType::Prismatic, universal = J.type == JointType::Universal;
  auto non_negative = [&r](const Field& f, double v, const std::string& what,
                           const std::string& unit) {
    if (v < 0) r.fail(f.val, "negative " + what + " " + shortest(v) + " " + unit);
  };
  if (auto f = m.get("spring"))
    r.attempt([&] {
      const MapView sp(r, f->val, "joints[].spring", bit, type);
      const Field k = sp.at("stiffness");
      if (universal) {
        read_pair(r, k, J.stiffness, J.stiffness2);
        for (const double x : {J.stiffness, J.stiffness2}) non_negative(k, x, "stiffness", "N m/rad");
        if (auto a = sp.get("neutral_angle")) read_pair(r, *a, J.neutral_angle, J.neutral_angle2);
        return;
      }
      J.stiffness = r.number(k);
      non_negative(k, J.stiffness, "stiffness", prismatic ? "N/m" : "N m/rad");
      if (auto a = sp.get(prismatic ? "neutral_position" : "neutral_angle"))
        J.neutral_angle = r.number(*a);
    });
  if (auto f = m.get("damper"))
    r.attempt([&] {
      const MapView dm(r, f->val, "joints[].damper", bit, type);
      const Field c = dm.at("damping");
      if (universal) {
        read_pair(r, c, J.damping, J.damping2);
        for (const double x : {J.damping, J.damping2}) non_negative(c, x, "damping", "N m s/rad");
        return;
      }
      J.damping = r.number(c);
      non_negative(c, J.damping, "damping", prismatic ? "N s/m" : "N m s/rad");
    });
  if (auto f = m.get("motor"))
    r.attempt([&] {
      const MapView mo(r, f->val, "joints[].motor", bit, type);
      if (J.type == JointType::Revolute || prismatic)
        J.motor_revolute = r.profile<1>(mo.at("profile"), bit);
      else if (universal)
        J.motor_universal = r.profile<2>(mo.at("profile"), bit);
      else
        J.motor_spherical = r.profile<3>(mo.at("profile"), bit);
    });
}

// A prescribed revolute or prismatic joint (docs/prescribed-motion.md): the profile, and no loads
// of its own (its torque or force is whatever the motion takes) and no initial rate (the profile
// gives it).
void read_prescribed(const Reader& r, const MapView& m, const Field& f, const std::string& type,
                     Joint& J) {
  const bool prismatic = J.type == JointType::Prismatic;
  const MapView pm(r, f.val, "joints[].prescribed", joint_type(J.type).bit, type);
  PrescribedMotion p;
  const Field profile = pm.at("profile");
  const bool deploy = r.word(profile) == "deploy";
  p.profile = deploy ? PrescribedMotion::Profile::Deploy : PrescribedMotion::Profile::SpinUp;
  // Each profile takes its own value: spin-up a rate, deploy a travel.
  const char* needs = deploy ? "travel" : "rate";
  const char* other = deploy ? "rate" : "travel";
  if (auto wrong = pm.get(other))
    r.fail(wrong->val, std::string("the ") + (deploy ? "deploy" : "spin-up") + " profile takes `" +
                           needs + "`, not `" + other + "`");
  const auto given = pm.get(needs);
  if (!given)
    pm.missing(needs, std::string("missing required key '") + needs + "' in a prescribed " +
                          (deploy ? "deploy" : "spin-up") + " motion");
  const double v = r.number(*given);
  const double limit = deploy && prismatic ? 1e6 : 1e4;
  const std::string unit = deploy ? (prismatic ? "m" : "rad") : (prismatic ? "m/s" : "rad/s");
  if (!std::isfinite(v) || std::abs(v) > limit)
    r.fail(given->val, std::string("the prescribed ") + needs + " must be finite and at most " +
                           (limit > 1e5 ? "1e6 " : "1e4 ") + unit + " in size, found " +
                           shortest(v) + " " + unit);
  (deploy ? p.travel : p.rate) = v;
  const Field ramp = pm.at("ramp_time");
  p.ramp_time = r.number(ramp);
  if (!std::isfinite(p.ramp_time) || p.ramp_time <= 0 || p.ramp_time > 1e9)
    r.fail(ramp.val, "the ramp time must be positive and at most 1e9 s, found " +
                         shortest(p.ramp_time) + " s");
  const std::string load = prismatic ? "force (output <joint>.force)" : "torque (output <joint>.torque)";
  for (const char* l : {"spring", "damper", "motor"})
    if (auto given_load = m.get(l))
      r.fail(given_load->val, std::string("a prescribed joint takes no ") + l +
                                  ": its motion is given, and its " + load +
                                  " is what that motion takes");
  if (auto ic = m.get("initial"))
    if (auto rt = MapView(r, ic->val, "joints[].initial", joint_type(J.type).bit, type).get("rate"))
      r.fail(rt->val, "a prescribed joint's rate is its profile's (0 at t = 0 for spin-up and "
                      "deploy); remove initial.rate");
  J.prescribed = p;
}

void read_initial(const Reader& r, const MapView& m, const std::string& type, const System& s,
                  RawJoint& raw) {
  Joint& J = raw.joint;
  const auto f = m.get("initial");
  if (!f) return;
  const MapView ic(r, f->val, "joints[].initial", joint_type(J.type).bit, type);
  switch (J.type) {
    case JointType::Free:
      if (auto x = ic.get("position")) J.p_NoBo_N0 = r.vector(*x);
      if (auto x = ic.get("attitude")) J.q_NB0 = r.attitude(*x);
      if (auto x = ic.get("angular_velocity")) J.w_NB_B0 = r.vector(*x);
      if (auto x = ic.get("velocity")) {
        J.v_NBo_N0 = r.vector(*x);
        raw.velocity_val = x->val;
      }
      if (auto x = ic.get("frame"); x && r.word(*x) == "lvlh") {
        // Given relative to the orbit frame O at t = 0 (core/orbit.hpp): q_OB and w_OB_B.
        if (!s.environment.orbit())
          r.fail(x->val,
                 "frame: lvlh gives the attitude relative to the orbit frame, but the scene has "
                 "no orbit (environment.central_body and environment.orbit)");
        const OrbitFrame o = orbit_frame(s.environment, 0.0);
        const Eigen::Matrix3d R_NB = o.R_NO * J.q_NB0.toRotationMatrix();
        J.q_NB0 = Eigen::Quaterniond(R_NB).normalized();
        J.w_NB_B0 += R_NB.transpose() * o.w_NO_N;  // w_NB = w_NO + w_OB
      }
      break;
    case JointType::Revolute:
      if (auto x = ic.get("angle")) J.angle0 = r.number(*x);
      if (auto x = ic.get("rate")) J.rate0 = r.number(*x);
      break;
    case JointType::Prismatic:
      if (auto x = ic.get("position")) J.angle0 = r.number(*x);
      if (auto x = ic.get("rate")) J.rate0 = r.number(*x);
      break;
    case JointType::Universal:
      if (auto x = ic.get("angle")) read_pair(r, *x, J.angle0, J.angle2_0);
      if (auto x = ic.get("rate")) read_pair(r, *x, J.rate0, J.rate2_0);
      break;
    case JointType::Spherical:
      if (auto x = ic.get("attitude")) J.q_J0 = r.attitude(*x);
      if (auto x = ic.get("angular_velocity")) J.w_PC_C0 = r.vector(*x);
      break;
    case JointType::Fixed:
      break;
  }
}

// A joint's point on its parent or child (`side`): `<side>_point`, or `<side>_node` on a flexible
// body, whose undeformed position it then is (docs/flexible-bodies.md "Joints at nodes").
Eigen::Vector3d joint_point(const Reader& r, const MapView& m, const System& s,
                            const BodyIndex& bodies, int body, const std::string& side, int& node) {
  const auto point = m.get(side + "_point");
  const auto named = m.get(side + "_node");
  const Body& b = s.bodies[static_cast<std::size_t>(body)];
  // A node of a body read with errors (its flexible block, perhaps): that body's errors say it.
  if (named && bodies.broken[static_cast<std::size_t>(body)]) r.skip();
  if (!named) {
    if (!point)
      m.missing(side + "_point", "missing required key '" + side + "_point' in a joint (or '" +
                                     side + "_node' for a node of a flexible " + side + ")");
    return r.vector(*point);
  }
  if (point)
    r.fail(point->val, "give either " + side + "_point or " + side + "_node, not both (the joint "
                       "point is the node's position)");
  const std::string n = r.name(*named);
  if (!b.flex)
    r.fail(named->val, "the " + side + " '" + b.name + "' is a rigid body, without nodes; give " +
                           side + "_point");
  node = b.flex->node_index(n);
  if (node < 0) {
    std::vector<std::string> names;
    for (const FlexNode& x : b.flex->nodes) names.push_back(x.name);
    r.fail(named->val, "body '" + b.name + "' has no node '" + n + "'" + suggestion(n, names) +
                           "; its nodes: " + join(names, 6));
  }
  return b.flex->nodes[static_cast<std::size_t>(node)].p_BoNi_B;
}

// One joint into `raw`. Its name, type and keys come first (an error there ends the joint);
// then each part that does not depend on another is read on its own, its errors recorded.
void read_joint(const Reader& r, const Val& item, const System& s, const BodyIndex& bodies,
                const std::unordered_map<std::string, const RawJoint*>& earlier, RawJoint& raw) {
  MapView m(r, item, "joints[]");  // every joint type's keys, until the type is known
  Joint& j = raw.joint;
  r.attempt([&] {
    const Field name = m.at("name");
    j.name = r.name(name);
    if (auto it = earlier.find(j.name); it != earlier.end())
      r.fail(name.val, "duplicate joint name '" + j.name + "' (first at line " +
                           std::to_string(it->second->node.mark.line + 1) + ")");
    if (bodies.index.count(j.name))
      r.fail(name.val, "joint name '" + j.name + "' is also a body name; output columns \"" +
                           j.name + ".*\" would clash");
  });
  const Field type = m.at("type");
  const std::string type_word = r.word(type);
  j.type = type_of(type_word);
  m.narrow(joint_type(j.type).bit, type_word,
           [&j](const std::string& key) { return why_not(j.type, key); });

  raw.type_val = type.val;
  raw.child_val = m.at("child").val;
  const bool child = r.attempt([&] { j.child = bodies.find(r, m.at("child")); });
  const bool axial = j.type == JointType::Revolute || j.type == JointType::Prismatic;
  const auto prescribed = axial ? m.get("prescribed") : std::nullopt;
  if (j.type != JointType::Free) {
    r.attempt([&] {
      if (const auto parent = m.get("parent")) {
        raw.parent_val = parent->val;
        j.parent = bodies.find(r, *parent);
        j.p_PoJ_P = joint_point(r, m, s, bodies, j.parent, "parent", j.parent_node);
      } else {
        // Only a prescribed revolute joint may leave out its parent: it then holds the base and
        // turns it about an axis fixed in N (docs/prescribed-motion.md).
        if (!prescribed || j.type != JointType::Revolute)
          m.missing("parent", "missing required key 'parent' in a joint (only a revolute joint "
                              "with a `prescribed` motion may leave it out, to turn the base "
                              "about an axis fixed in N)");
        if (auto pn = m.get("parent_node"))
          r.fail(pn->val, "this joint has no parent body (its parent is the inertial frame N, "
                          "which has no nodes); give parent_point, a point in N");
        j.parent = -1;
        if (auto pp = m.get("parent_point")) j.p_PoJ_P = r.vector(*pp);
      }
    });
    if (child)
      r.attempt([&] { j.p_CoJ_C = joint_point(r, m, s, bodies, j.child, "child", j.child_node); });
    r.attempt([&] {
      if (auto f = m.get("offset")) j.q_PJ0 = r.attitude(*f);
    });
  }
  if (axial || j.type == JointType::Universal)
    r.attempt([&] { j.axis_P = r.direction(m.at("axis")); });
  if (j.type == JointType::Universal)
    r.attempt([&] {
      const Field a2 = m.at("axis2");
      j.axis2_P = r.direction(a2);
      // The two axes at least 1 deg apart: aligned axes leave one direction of the gimbal
      // without a joint speed and make the other two speeds one.
      const double between = std::atan2(j.axis_P.cross(j.axis2_P).norm(), j.axis_P.dot(j.axis2_P));
      if (between < kMinGimbalAxesAngle || between > std::numbers::pi - kMinGimbalAxesAngle)
        r.fail(a2.val, "axis2 is " + shortest(std::round(between * 180e3 / std::numbers::pi) / 1e3) +
                           " deg from axis: a universal joint's two axes must be at least 1 deg "
                           "apart (perpendicular is usual)");
    });
  if (prescribed) r.attempt([&] { read_prescribed(r, m, *prescribed, type_word, j); });
  if (j.type != JointType::Free && j.type != JointType::Fixed) read_loads(r, m, type_word, j);
  r.attempt([&] { read_initial(r, m, type_word, s, raw); });
}

// Each joint is read on its own; one with errors keeps its place, unread parts left default.
std::vector<RawJoint> read_joints(const Reader& r, const MapView& top, const System& s,
                                  const BodyIndex& bodies) {
  std::vector<RawJoint> raw;
  std::vector<Val> items;
  if (!r.attempt([&] { items = r.list(top.at("joints")); })) return raw;
  raw.reserve(items.size());  // `earlier` points into raw
  std::unordered_map<std::string, const RawJoint*> earlier;
  for (const Val& item : items) {
    raw.push_back(RawJoint{Joint{}, item, item, item, std::nullopt, std::nullopt});
    r.attempt([&] { read_joint(r, item, s, bodies, earlier, raw.back()); });
    if (!raw.back().joint.name.empty()) earlier.emplace(raw.back().joint.name, &raw.back());
  }
  return raw;
}

// center_of_mass: points of a body given from its reference origin Ro become points from its CM
// Bo (p_BoJ_B = p_RoJ_B - p_RoBo_B; the axes are the same). A body without center_of_mass has
// its points from the CM already and is left untouched (bit for bit).
void shift_points(std::vector<RawJoint>& raw, const BodyIndex& bodies) {
  auto com = [&bodies](int b) { return bodies.p_RoBo_R[static_cast<std::size_t>(b)]; };
  for (RawJoint& r : raw) {
    Joint& J = r.joint;
    if (J.type == JointType::Free) continue;
    if (J.parent >= 0)
      if (const auto c = com(J.parent)) J.p_PoJ_P -= *c;
    if (const auto c = com(J.child)) J.p_CoJ_C -= *c;
  }
}

// Topology (one parent per body, one free joint, no cycle, connected) and tree order, with each
// problem reported at the line that causes it; then the base velocity rule.
void order(const Reader& r, const Val& joints_val, std::vector<RawJoint>& raw,
           const BodyIndex& bodies, System& s) {
  std::vector<JointEdge> edges;
  std::vector<std::string> joint_names;
  for (const RawJoint& j : raw) {
    edges.push_back({j.joint.type == JointType::Free || j.joint.parent == -1, j.joint.parent,
                     j.joint.child});
    joint_names.push_back(j.joint.name);
  }
  const TopologyResult t = order_joints(static_cast<int>(s.bodies.size()), edges);
  if (const auto& p = t.problem) {
    using Kind = TopologyProblem::Kind;
    std::string what = p->describe(bodies.names, joint_names);
    auto joint = [&raw](int k) -> const RawJoint& { return raw[static_cast<std::size_t>(k)]; };
    switch (p->kind) {
      case Kind::SelfLoop:
        r.fail(*joint(p->joint).parent_val, what);
      case Kind::SecondFree:
        r.fail(joint(p->joint).type_val, what);
      case Kind::SecondParent: {
        const std::string line =
            " (line " + std::to_string(joint(p->other).node.mark.line + 1) + ")";
        what.insert(what.find(';'), line);  // "... parent joint 'hinge' (line 15); a body ..."
        r.fail(joint(p->joint).child_val, what);
      }
      case Kind::NoFree:
        r.fail(joints_val, what);
      case Kind::NoJoint: {
        const Val& b = bodies.vals[static_cast<std::size_t>(p->body)];
        r.fail(b.mark, b.path, what);
      }
      case Kind::Cycle:
        r.fail(*joint(p->joint).parent_val, what);
    }
  }
  for (int k : t.order) s.joints.push_back(raw[static_cast<std::size_t>(k)].joint);

  const RawJoint& free_joint = raw[static_cast<std::size_t>(t.order.front())];
  if (s.zero_linear_momentum && free_joint.velocity_val)
    r.fail(*free_joint.velocity_val,
           "the base velocity is computed when zero_linear_momentum is true (the default); remove "
           "it or set zero_linear_momentum: false");
}

// ---------------------------------------------------------------------------------------------
// Run and compare

// The limits are core/run_limits.hpp's, shared with the command line's overrides.
void read_run(const Reader& r, const MapView& top, System& s) {
  const MapView m(r, top.at("run").val, "run");
  auto limit = [&r](const Val& v, const std::string& problem) {
    if (!problem.empty()) r.fail(v, problem);
  };
  // Each key on its own; a check against another key only when that one was read.
  const bool duration = r.attempt([&] {
    const Field d = m.at("duration");
    s.run.duration = r.number(d);
    limit(d.val, run_limits::duration_problem(s.run.duration));
  });
  r.attempt([&] {
    const Field o = m.at("output_step");
    s.run.output_step = r.number(o);
    limit(o.val, run_limits::output_step_problem(
                     s.run.output_step, duration ? s.run.duration : s.run.output_step));
  });
  const bool integrator = r.attempt([&] {
    if (auto f = m.get("integrator")) s.run.integrator = r.word(*f);
  });
  for (const char* key : {"rtol", "atol"})
    if (auto f = m.get(key))
      r.attempt([&] {
        const double x = r.number(*f);
        limit(f->val, run_limits::tolerance_problem(key, x));
        (std::string(key) == "rtol" ? s.run.rtol : s.run.atol) = x;
      });
  if (auto f = m.get("dt"))
    r.attempt([&] {
      s.run.dt = r.number(*f);
      s.run.dt_given = true;
      limit(f->val, run_limits::dt_problem(s.run.dt));
      if (integrator && s.run.integrator.value() != Integrator::Rk4)
        limit(f->val, run_limits::first_step_problem(s.run.dt, IntegratorSettings{}.min_step));
    });
}

Tolerance read_tolerance(const Reader& r, const Val& v, Tolerance base) {
  const MapView t(r, v, "compare.tolerances.<quantity>");
  for (const char* key : {"atol", "rtol"})
    if (auto f = t.get(key)) {
      const double value = r.number(*f);
      if (value < 0) r.fail(f->val, "negative tolerance " + shortest(value));
      (std::string(key) == "atol" ? base.atol : base.rtol) = value;
    }
  return base;
}

// A profile step at or after the run's end is never applied (value(t) takes it from its time on):
// usually a time in the wrong unit, or a duration shortened without the profile. One warning
// per profile, at its first such step.
void check_profile_times(const Reader& r, const System& s) {
  int warned = -1;
  const std::vector<Reader::ProfileTime>& times = r.profile_times();
  for (std::size_t i = 0; i < times.size(); ++i) {
    const Reader::ProfileTime& p = times[i];
    if (p.profile == warned || p.t < s.run.duration) continue;
    warned = p.profile;
    int later = 0;
    for (std::size_t k = i + 1; k < times.size() && times[k].profile == p.profile; ++k) ++later;
    r.warn(p.val, "profile-after-end",
           "this step at t = " + shortest(p.t) + " s is " +
               (p.t == s.run.duration ? "at" : "after") + " the run's end (run.duration " +
               shortest(s.run.duration) + " s), so it is never applied" +
               (later == 0 ? std::string()
                           : " (nor " + std::string(later == 1 ? "is the 1 step" : "are the " +
                                 std::to_string(later) + " steps") + " after it)"));
  }
}

void read_compare(const Reader& r, const MapView& top, System& s) {
  const auto cf = top.get("compare");
  if (!cf) return;
  const MapView m(r, cf->val, "compare");
  if (auto tf = m.get("tolerances")) {
    const MapView t(r, tf->val, "compare.tolerances");
    // `default` first, whatever the key order: the others take what they omit from it.
    for (const MapView::Entry& e : t.entries())
      if (e.key == "default")
        r.attempt([&] {
          s.compare.default_tolerance = read_tolerance(r, e.value, s.compare.default_tolerance);
        });
    for (const MapView::Entry& e : t.entries()) {
      if (e.key == "default") continue;
      r.attempt([&] {
        r.name(Val{YAML::Node(e.key), e.value.path, e.key_mark}, "quantity name", true);
        s.compare.tolerances.emplace_back(
            e.key, read_tolerance(r, e.value, s.compare.default_tolerance));
      });
    }
  }
  if (auto ef = m.get("exclude")) {
    std::unordered_set<std::string> excluded;
    for (const Val& item : r.list(*ef))
      r.attempt([&] {
        const MapView x(r, item, "compare.exclude[]");
        const Field qf = x.at("quantity");
        const std::string q = r.name(qf);
        if (!excluded.insert(q).second) r.fail(qf.val, "quantity '" + q + "' is excluded twice");
        const Field rf = x.at("reason");
        const std::string reason = r.text(rf);
        if (reason.empty()) r.fail(rf.val, "give a reason for excluding '" + q + "'");
        s.compare.excluded.emplace_back(q, reason);
      });
  }
}

void check_analytic(const Reader& r, const MapView& top, const System& s) {
  if (s.analytic != "torque-free") return;
  const Val av = top.get("analytic")->val;
  if (s.bodies.size() != 1)
    r.fail(av, "the torque-free reference needs a single free rigid body; this scene has " +
                   std::to_string(s.bodies.size()) + " bodies");
  if (!s.bodies[0].torque.empty())
    r.fail(av, "the torque-free reference needs a body without external torque");
  if (!s.environment.none())
    r.fail(av, "the torque-free reference needs a body without gravity (the scene has an "
               "environment block)");
}

// A generated beam's stations (massless slice-centre nodes, core/flex/beam.hpp) that no joint
// uses are dropped: they carry no mass, so no output depends on them (every engine's CSV is
// byte-identical with and without them on the committed beam scenes), and the engines would
// spend time on each (with geometric stiffening they loop over every node per right-hand side:
// spinup_beam ran 1.5 to 1.8 times slower with all 50 kept). The joints' node indices follow.
void drop_unused_stations(System& s) {
  for (std::size_t b = 0; b < s.bodies.size(); ++b) {
    if (!s.bodies[b].flex) continue;
    FlexBody& f = *s.bodies[b].flex;
    std::vector<bool> used(f.nodes.size(), false);
    const auto mark = [&](int body, int node) {
      if (body == static_cast<int>(b) && node >= 0 && static_cast<std::size_t>(node) < used.size())
        used[static_cast<std::size_t>(node)] = true;
    };
    for (const Joint& J : s.joints) {
      mark(J.parent, J.parent_node);
      mark(J.child, J.child_node);
    }
    const std::vector<int> index = flex::drop_unused_stations(f, used);
    for (Joint& J : s.joints) {
      if (J.parent == static_cast<int>(b) && J.parent_node >= 0)
        J.parent_node = index[static_cast<std::size_t>(J.parent_node)];
      if (J.child == static_cast<int>(b) && J.child_node >= 0)
        J.child_node = index[static_cast<std::size_t>(J.child_node)];
    }
  }
}

System read(const Reader& r, const std::string& text) {
  precheck_text(r, text);
  const Val root = parse_yaml(r, text);
  const MapView top(r, root, "");
  System s;
  s.file = r.file();
  // Errors are recorded where they are independent (reader.hpp); a pass that needs all before it
  // runs only when nothing was recorded.
  read_header(r, top, s);
  r.attempt([&] { read_environment(r, top, s); });
  const BodyIndex bodies = read_bodies(r, top, s);
  std::vector<RawJoint> raw = read_joints(r, top, s, bodies);
  if (!r.failed()) {
    shift_points(raw, bodies);
    r.attempt([&] { order(r, top.at("joints").val, raw, bodies, s); });
    if (!r.failed()) drop_unused_stations(s);
  }
  r.attempt([&] { read_run(r, top, s); });
  if (!r.failed()) r.attempt([&] { check_profile_times(r, s); });
  r.attempt([&] { read_compare(r, top, s); });
  if (!r.failed()) {
    check_analytic(r, top, s);
    check_topology(s);  // the promise of scene.hpp, checked by the function engines call
  }
  return s;
}

}  // namespace
}  // namespace scene

System read_scene_text(const std::string& text, const std::string& file_label,
                       std::vector<SceneWarning>* warnings) {
  const scene::Reader reader(file_label);
  System s;
  try {
    s = scene::read(reader, text);
  } catch (const YAML::Exception& e) {  // anything yaml-cpp throws past parsing
    reader.record(e.mark, "", "malformed YAML: " + e.msg);
  } catch (const InputError& e) {  // an error that ends the reading, after those recorded
    reader.keep(e);
  } catch (const scene::Reader::Skip&) {  // (every skip follows a recorded error)
  }
  reader.finish();  // every error, if any
  if (warnings)
    warnings->insert(warnings->end(), reader.warnings().begin(), reader.warnings().end());
  return s;
}

// Why `path` cannot be read as a scene, or "" when it can be opened: missing, a directory, no
// permission, a symbolic link loop, a socket or device (see input_file.hpp); FIFOs and pipes are
// read (`<(...)`) unless `pipes` refuses them.
std::string scene_open_problem(const std::string& path, Pipes pipes) {
  return input_file_problem(path, pipes, "scene file");
}

System read_scene(const std::string& path, std::vector<SceneWarning>* warnings, Pipes pipes) {
  const InputFile in = read_input_file(path, scene::kMaxSceneBytes, pipes, "scene file");
  if (!in.problem.empty())
    throw InputError(path + ":1:1: cannot open the scene file: " + in.problem);
  if (in.pipe && in.text.empty())
    throw InputError(path + ":1:1: the scene is empty: nothing was written to the pipe");
  return read_scene_text(in.text, path, warnings);  // more than kMaxSceneBytes: precheck_text says so
}

}  // namespace crossdyn
