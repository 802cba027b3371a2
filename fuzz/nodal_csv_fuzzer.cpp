// libFuzzer target for the nodal data files of flexible bodies (core/flex/nodal_csv.hpp;
// fuzz/README.md "Nodal data files" says how to build and run it).
//
// Why its own target rather than scene_fuzzer with a file: the scene reader reaches these files
// only through `bodies[].flexible.nodes` / `modes` (core/scene/flex_block.cpp read_nodes), which
// reads two files from disk and hands their bytes to read_nodal_csv_text. Fuzzing the two texts
// directly puts every mutation into the CSV parser and validate_flex instead of spending most of
// them on YAML, needs no files, and keeps scene_fuzzer's corpus about scenes. (The path from a
// scene to the files is covered by cli_fuzzer's seeds that name scenarios/data/.)
//
// Input: the nodes file's text, then optionally a line "%%" and the modes file's text. Without
// the "%%" line there is no modes file (read_nodal_csv_text with an empty modes label).
//
// Properties checked on every input:
//   1. read_nodal_csv_text either returns a FlexModel or throws InputError whose message names
//      the file (starts with "n.csv" or "m.csv"); anything else (another exception, a crash, a
//      sanitizer report, a hang, memory above the RSS limit) is a finding;
//   2. an accepted body survives the round trip: write_nodal_csv writes it, the reader reads the
//      two texts back without error, and names, masses, J, shapes, slopes, K and D are the same
//      bit for bit, positions the same but for the (rounding-level) CM shift of the second read,
//      as tests/flex/test_nodal_csv.cpp asserts for the beam generator's bodies.
#include "core/errors.hpp"
#include "core/flex/nodal_csv.hpp"

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

namespace {

[[noreturn]] void finding(const std::string& what, const crossdyn::flex::NodalCsv& csv) {
  std::fprintf(stderr, "round trip: %s\n--- nodes written ---\n%s\n--- modes written ---\n%s\n",
               what.c_str(), csv.nodes.c_str(), csv.modes.c_str());
  std::abort();
}

bool same(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() && a == b;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view all(reinterpret_cast<const char*>(data), size);
  std::string_view nodes = all, modes;
  std::string modes_label;
  if (all.rfind("%%\n", 0) == 0) {
    nodes = {};
    modes = all.substr(3);
    modes_label = "m.csv";
  } else if (const std::size_t at = all.find("\n%%\n"); at != std::string_view::npos) {
    nodes = all.substr(0, at + 1);
    modes = all.substr(at + 4);
    modes_label = "m.csv";
  }
  crossdyn::flex::FlexModel model;
  try {
    model = crossdyn::flex::read_nodal_csv_text(nodes, "n.csv", modes, modes_label);
  } catch (const crossdyn::InputError& e) {
    const std::string_view m = e.what();
    if (m.rfind("n.csv", 0) != 0 && m.rfind("m.csv", 0) != 0) {
      std::fprintf(stderr, "the message does not name the file: %s\n", e.what());
      std::abort();
    }
    return 0;  // rejected with a message: the expected outcome for most inputs
  }

  // The round trip (the writer always writes a modes file, with only its header for 0 modes).
  const crossdyn::FlexBody& f = model.flex;
  const crossdyn::flex::NodalCsv csv = crossdyn::flex::write_nodal_csv(f);
  crossdyn::flex::FlexModel back;
  try {
    back = crossdyn::flex::read_nodal_csv_text(csv.nodes, "n.csv", csv.modes, "m.csv");
  } catch (const crossdyn::InputError& e) {
    finding(std::string("the written files were rejected: ") + e.what(), csv);
  }
  const crossdyn::FlexBody& g = back.flex;
  if (g.mode_names != f.mode_names) finding("mode names differ", csv);
  if (!same(g.K, f.K)) finding("K differs", csv);
  if (!same(g.D, f.D)) finding("D differs", csv);
  if (g.geometric_stiffening != f.geometric_stiffening) finding("geometric_stiffening differs", csv);
  if (g.nodes.size() != f.nodes.size()) finding("the number of nodes differs", csv);
  for (std::size_t i = 0; i < f.nodes.size(); ++i) {
    const crossdyn::FlexNode& u = f.nodes[i];
    const crossdyn::FlexNode& v = g.nodes[i];
    const std::string at = "node " + std::to_string(i) + " ('" + u.name + "'): ";
    if (v.name != u.name) finding(at + "name differs", csv);
    if (v.mass != u.mass) finding(at + "mass differs", csv);
    if (v.J_Ni_B != u.J_Ni_B) finding(at + "J differs", csv);
    if (!same(v.Phi_B, u.Phi_B)) finding(at + "shape differs", csv);
    if (!same(v.Psi_B, u.Psi_B)) finding(at + "slope differs", csv);
    // The second read shifts by the written nodes' CM, which is zero to rounding.
    if (v.p_BoNi_B != Eigen::Vector3d(u.p_BoNi_B - back.p_RoBo_R))
      finding(at + "position differs beyond the CM shift", csv);
  }
  return 0;
}
