// The key reference of docs/scene-format.md, generated from the schema table (schema.hpp).
// tests/scene/test_scene_docs.cpp fails when the committed file differs from this output;
// `build/tests/scene/crossdyn_scene_doc --write-docs docs/scene-format.md` rewrites it.
#include <algorithm>
#include <initializer_list>
#include <sstream>

#include "core/scene/schema.hpp"

namespace crossdyn::scene {
namespace {

using units::Dimension;

// '|' inside a table cell must be escaped.
std::string cell(std::string_view s) {
  std::string out;
  for (char c : s) {
    if (c == '|') out += '\\';
    out += c;
  }
  return out;
}

std::string type_text(const Key& k) {
  switch (k.type) {
    case Type::Text:
      return "text";
    case Type::Name:
      return "name";
    case Type::Bool:
      return "`true` \\| `false`";
    case Type::Word: {
      std::string s;
      for (const std::string& w : words(k)) s += (s.empty() ? "" : " \\| ") + ("`" + w + "`");
      return s;
    }
    case Type::Number:
      return "number";
    case Type::Quantity:
      return "quantity";
    case Type::Vector:
      return "3-vector";
    case Type::Pair:
      return "pair";
    case Type::Direction:
      return "direction";
    case Type::Attitude:
      return "attitude";
    case Type::Inertia:
      return "inertia";
    case Type::Map:
      return "mapping";
    case Type::List:
      return "list";
  }
  return "?";
}

std::string si_unit(Dimension d) {
  if (d == Dimension::None) return "";
  return "`" + units::unit_names(d).front() + "`";
}

std::string types_text(unsigned joints) {
  if (joints == kAnyJoint) return "all";
  std::string s;
  for (const JointTypeInfo& t : joint_types())
    if (joints & t.bit) s += (s.empty() ? "" : ", ") + std::string(t.name);
  return s;
}

bool under(std::string_view path, std::string_view block) {
  // A value form's own row heads its table; a block's own row is in the table above it.
  return (block.starts_with('(') && path == block) || path.starts_with(std::string(block) + ".") || path.starts_with(std::string(block) + "[");
}

// One table of the rows under `blocks` ("" for the scene's own keys: those without '.' or '[').
void table(std::ostringstream& md, std::string_view title,
           std::initializer_list<std::string_view> blocks, bool joint_column) {
  md << "### " << title << "\n\n";
  md << "| key | type | unit | required | default |" << (joint_column ? " joint types |" : "")
     << " meaning |\n";
  md << "| --- | --- | --- | --- | --- |" << (joint_column ? " --- |" : "") << " --- |\n";
  for (std::string_view block : blocks)
    for (const Key& k : keys()) {
      const bool top =
          k.path.find_first_of(".[") == std::string_view::npos && !k.path.starts_with('(');
      if (k.path.empty() || (block.empty() ? !top : !under(k.path, block))) continue;
      md << "| `" << k.path << "` | " << type_text(k) << " | " << si_unit(k.dimension) << " | "
         << (k.path.ends_with("[]") ? "" : k.required ? "yes" : "no") << " | "
         << cell(k.default_value) << " |";
      if (joint_column) md << " " << types_text(k.joints) << " |";
      md << " " << cell(k.doc) << " |\n";
    }
  md << "\n";
}

}  // namespace

std::string markdown_reference() {
  std::ostringstream md;
  md << "<!-- Generated from core/scene/schema.cpp: do not edit by hand; run\n"
        "     build/tests/scene/crossdyn_scene_doc --write-docs docs/scene-format.md -->\n\n";
  table(md, "The scene", {""}, false);
  table(md, "Bodies: `bodies[]`", {"bodies"}, false);
  table(md, "Joints: `joints[]`", {"joints"}, true);
  table(md, "Environment: `environment`", {"environment"}, false);
  table(md, "Run: `run`", {"run"}, false);
  table(md, "Compare: `compare`", {"compare"}, false);
  table(md, "Value forms", {"(list with unit)", "(axis-angle)"}, false);

  md << "### Joint types\n\n";
  md << "| type | degrees of freedom | keys | initial keys | meaning |\n";
  md << "| --- | --- | --- | --- | --- |\n";
  for (const JointTypeInfo& t : joint_types()) {
    auto list = [](const std::vector<std::string>& v) {
      std::string s;
      for (const std::string& k : v) s += (s.empty() ? "" : ", ") + ("`" + k + "`");
      return s.empty() ? std::string("none") : s;
    };
    md << "| `" << t.name << "` | " << t.dof << " | " << list(joint_keys(t.type)) << " | "
       << list(initial_keys(t.type)) << " | " << cell(t.doc) << " |\n";
  }
  md << "\n";

  md << "### Units\n\n";
  md << "| dimension | SI unit (bare numbers) | accepted units |\n";
  md << "| --- | --- | --- |\n";
  for (Dimension d : units::kDimensions) {
    std::string accepted;
    for (const std::string& u : units::unit_names(d))
      accepted += (accepted.empty() ? "" : ", ") + ("`" + u + "`");
    md << "| " << units::dimension_name(d) << " | " << si_unit(d) << " | " << accepted << " |\n";
  }
  return md.str();
}

std::string fuzz_dictionary() {
  std::ostringstream d;
  d << "# libFuzzer dictionary for scene files, generated from core/scene/schema.cpp by\n"
       "# build/tests/scene/crossdyn_scene_doc --dict (tests/scene/test_schema.cpp checks it).\n";
  std::vector<std::string> seen;
  auto add = [&](const std::string& entry) {
    if (std::find(seen.begin(), seen.end(), entry) != seen.end()) return;
    seen.push_back(entry);
    d << '"' << entry << "\"\n";
  };
  d << "# keys\n";
  for (const Key& k : keys()) {
    const std::string_view p = k.path;
    const std::size_t dot = p.rfind('.');
    const std::string_view name = dot == std::string_view::npos ? p : p.substr(dot + 1);
    if (name.empty() || name.starts_with('(') || name.ends_with("[]")) continue;
    add(name.starts_with('<') ? "default:" : std::string(name) + ":");
  }
  d << "# words\n";
  for (const Key& k : keys())
    for (const std::string& w : words(k)) add(w);
  add("true");
  add("false");
  d << "# units\n";
  for (units::Dimension dim : units::kDimensions)
    for (const std::string& u : units::unit_names(dim)) add(" " + u);
  d << "# other spellings, numbers and YAML syntax\n";
  for (const char* s : {" kg*m^2", " N*m", "1e308", "-0", ".inf", ".nan", "&a ", "*a", "? ", "- ", "[]", "{}",
                        "!!str ", "---", "...", "|", ">"})
    add(s);
  return d.str();
}

}  // namespace crossdyn::scene
