// Flexible bodies in the scene format (docs/scene-format.md, core/scene/flex_block.hpp): the
// `flexible:` block (beam generator or nodal data files), joints at nodes, the rigid mass and
// inertia as node sums, round trips, and one case per class of error with its file:line:column,
// key path and what is wrong.
#include "core/errors.hpp"
#include "core/flex/beam.hpp"
#include "core/flex/nodal_csv.hpp"
#include "core/scene/scene.hpp"
#include "tests/cross/flex_systems.hpp"
#include "tests/scene/system_equal.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

using namespace crossdyn;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;

namespace {

const std::string kFlex = R"(name: flex
bodies:
  - name: beam
    flexible:
      beam:
        length: 10 m
        axis: z
        mass_per_length: 50
        section: [2, 2, 0]
        bending:
          x: {modes: 2, EI: 100}
          y: {modes: 2, EI: 100}
        slices: 20
  - name: payload
    mass: 100 kg
    inertia: [12.5, 39.6, 39.6]
joints:
  - name: base
    type: free
    child: beam
  - name: hinge
    type: revolute
    parent: beam
    parent_node: top
    child: payload
    child_point: [-1, 0, 0]
    axis: [0, 1, 0]
run:
  duration: 1 s
  output_step: 0.1 s
)";

std::string edit(const std::string& from, const std::string& to, const std::string& base = kFlex) {
  const std::size_t at = base.find(from);
  REQUIRE(at != std::string::npos);
  REQUIRE(base.find(from, at + 1) == std::string::npos);
  return base.substr(0, at) + to + base.substr(at + from.size());
}

std::string error_of(const std::string& text, const std::string& label = "flex.yaml") {
  try {
    read_scene_text(text, label);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST_CASE("scene flex: a beam body gets the generator's nodes, and its node sums as mass and inertia") {
  const System s = read_scene_text(kFlex, "flex.yaml");
  const Body& beam = s.bodies[0];
  REQUIRE(beam.flex);
  CHECK(beam.flex->mode_names == std::vector<std::string>{"qx1", "qx2", "qy1", "qy2"});
  CHECK(beam.flex->nodes.size() == 22);
  CHECK(beam.mass == Approx(500).epsilon(1e-15));
  // the 2 x 2 x 10 m box: diag(4333.33..., 4333.33..., 333.33...)
  CHECK(beam.I_BBo_B(0, 0) == Approx(500.0 * (4 + 100) / 12).epsilon(1e-14));
  CHECK(beam.I_BBo_B(2, 2) == Approx(500.0 * 8 / 12).epsilon(1e-14));
  // equal to the generator called directly
  flex::BeamSpec spec;
  spec.length = 10;
  spec.mass_per_length = 50;
  spec.section = {2, 2, 0};
  spec.bending = {flex::BeamPlane{2, 100}, flex::BeamPlane{2, 100}, flex::BeamPlane{}};
  spec.slices = 20;
  const flex::FlexModel direct = flex::make_beam(spec, "beam");
  CHECK(beam.flex->K == direct.flex.K);
  CHECK(beam.mass == direct.mass);
  CHECK(beam.I_BBo_B == direct.I_BBo_B);
  // the joint at the top node: its undeformed position
  const Joint& hinge = s.joints[1];
  CHECK(hinge.parent_node == beam.flex->node_index("top"));
  CHECK(hinge.p_PoJ_P == Eigen::Vector3d(0, 0, 5));
  CHECK(hinge.child_node == -1);
}

TEST_CASE("scene flex: read(write(s)) == s field by field, FlexBody and nodes included") {
  const System s = read_scene_text(kFlex, "flex.yaml");
  const std::string written = write_scene_text(s);
  INFO(written);
  const System back = read_scene_text(written, "flex.yaml");
  CHECK(test::system_difference(s, back) == "");
  CHECK(write_scene_text(back) == written);
  // system_difference sees a change in one node's shape
  System changed = back;
  changed.bodies[0].flex->nodes[3].Phi_B(0, 1) += 1e-16;
  CHECK(test::system_difference(s, changed) == "bodies[0].flex.nodes[3].Phi_B");
}

TEST_CASE("scene flex: nodal data files, relative to the scene file's folder, round trip") {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("crossdyn_flex_" + std::to_string(::getpid()));
  fs::create_directories(dir / "data");
  // the beam written as CSV files, read back through a scene
  const System beam = read_scene_text(kFlex, "flex.yaml");
  const flex::NodalCsv csv = flex::write_nodal_csv(*beam.bodies[0].flex);
  std::ofstream(dir / "data" / "n.csv") << csv.nodes;
  std::ofstream(dir / "data" / "m.csv") << csv.modes;
  const std::string text = edit(R"(      beam:
        length: 10 m
        axis: z
        mass_per_length: 50
        section: [2, 2, 0]
        bending:
          x: {modes: 2, EI: 100}
          y: {modes: 2, EI: 100}
        slices: 20
)",
                                "      nodes: data/n.csv\n      modes: data/m.csv\n");
  const std::string label = (dir / "s.yaml").string();
  const System s = read_scene_text(text, label);
  REQUIRE(s.bodies[0].flex);
  CHECK(s.bodies[0].flex->K == beam.bodies[0].flex->K);
  CHECK(s.bodies[0].mass == beam.bodies[0].mass);
  CHECK(s.joints[1].p_PoJ_P == beam.joints[1].p_PoJ_P);
  const System back = read_scene_text(write_scene_text(s), label);
  CHECK(test::system_difference(s, back) == "");
  // an error inside the CSV names the scene's key and the CSV's file:line:column and column
  std::ofstream(dir / "data" / "m.csv") << "mode,frequency_hz\nqx1,1\nqx2,-1\n";
  CHECK_THAT(error_of(text, label),
             StartsWith(label + ":5:14: bodies[0].flexible.nodes: " + (dir / "data/m.csv").string() +
                        ":3:5: column 'frequency_hz': negative frequency -1 Hz"));
  fs::remove(dir / "data" / "n.csv");
  CHECK(error_of(text, label) == label + ":5:14: bodies[0].flexible.nodes: " +
                                     (dir / "data/n.csv").string() + ": no such file");
  fs::remove_all(dir);
}

TEST_CASE("scene flex: mass and inertia given for a flexible body must agree with the node sums") {
  // the paper's rounded Table 3 values agree to 1e-6
  CHECK(error_of(edit("  - name: beam\n", "  - name: beam\n    mass: 500 kg\n    inertia: [4333.33, "
                                          "4333.33, 333.33]\n")) == "(no error)");
  CHECK(error_of(edit("  - name: beam\n", "  - name: beam\n    mass: 510 kg\n")) ==
        "flex.yaml:4:11: bodies[0].mass: the flexible body's nodes sum to 500 kg, but mass is 510 "
        "kg; they must agree to 1e-6 relative (omit mass to take the node sum)");
  CHECK_THAT(error_of(edit("  - name: beam\n", "  - name: beam\n    inertia: [4333, 4333, 333]\n")),
             StartsWith("flex.yaml:4:14: bodies[0].inertia: the flexible body's nodes give the "
                        "inertia [4333.333333333") &&
                 Contains("they must agree to 1e-6 of the largest entry"));
  CHECK(error_of(edit("  - name: beam\n", "  - name: beam\n    center_of_mass: [0, 0, 1]\n")) ==
        "flex.yaml:4:21: bodies[0].center_of_mass: a flexible body's origin is its nodes' centre "
        "of mass: center_of_mass is not allowed (points on it are measured from that CM, or name a "
        "node)");
  // a rigid body still needs both
  CHECK(error_of(edit("    mass: 100 kg\n", "")) ==
        "flex.yaml:14:5: bodies[1]: missing required key 'mass' in a body (a rigid body needs "
        "mass and inertia; a flexible one takes them from its nodes)");
}

TEST_CASE("scene flex: bad beam descriptions name the key, its line and column") {
  CHECK(error_of(edit("slices: 20", "slices: 2.5")) ==
        "flex.yaml:13:17: bodies[0].flexible.beam.slices: the number of slices must be an integer "
        "from 1 to 10000, found 2.5");
  CHECK(error_of(edit("slices: 20", "slices: 1000000")) ==
        "flex.yaml:13:17: bodies[0].flexible.beam.slices: the number of slices must be an integer "
        "from 1 to 10000, found 1e+06");
  CHECK(error_of(edit("x: {modes: 2, EI: 100}", "x: {modes: 51, EI: 100}")) ==
        "flex.yaml:11:22: bodies[0].flexible.beam.bending.x.modes: the number of modes must be an "
        "integer from 0 to 50, found 51");
  CHECK(error_of(edit("x: {modes: 2, EI: 100}", "x: {modes: 2, EI: -1}")) ==
        "flex.yaml:11:29: bodies[0].flexible.beam.bending.x.EI: the bending stiffness must be "
        "positive, found -1 N m^2");
  CHECK(error_of(edit("x: {modes: 2, EI: 100}", "x: {modes: 2}")) ==
        "flex.yaml:11:14: bodies[0].flexible.beam.bending.x: the bending stiffness must be "
        "positive, found 0 N m^2");
  CHECK(error_of(edit("slices: 20", "slices: 5")) ==
        "flex.yaml:13:17: bodies[0].flexible.beam.slices: 5 slices cannot resolve mode 2 (about 3 "
        "half-waves): use at least 6");
  CHECK(error_of(edit("length: 10 m", "length: -10 m")) ==
        "flex.yaml:6:17: bodies[0].flexible.beam.length: the beam's length must be positive, found "
        "-10 m");
  CHECK(error_of(edit("section: [2, 2, 0]", "section: [2, 2, 1]")) ==
        "flex.yaml:9:18: bodies[0].flexible.beam.section: the beam lies along z: give the "
        "section's sides across it only (its length is `length`)");
  CHECK_THAT(error_of(edit("        slices: 20\n", "        slices: 20\n        bending_x: 1\n")),
             StartsWith("flex.yaml:14:9: bodies[0].flexible.beam.bending_x: unknown key "
                        "'bending_x' in a beam (did you mean 'bending'?)"));
  CHECK(error_of(edit("        slices: 20\n", "        slices: 20\n        damping: {ratios: [0.1], "
                                               "alpha: 1}\n")) ==
        "flex.yaml:14:18: bodies[0].flexible.beam.damping: give either damping ratios or Rayleigh "
        "alpha and beta, not both");
  CHECK(error_of(edit("        slices: 20\n", "        slices: 20\n        damping: {ratios: [0.1, "
                                               "0.2]}\n")) ==
        "flex.yaml:14:27: bodies[0].flexible.beam.damping.ratios: give one damping ratio for every "
        "mode or one per mode (4), found 2");
  CHECK(error_of(edit("    flexible:\n", "    flexible:\n      nodes: x.csv\n")) ==
        "flex.yaml:5:7: bodies[0].flexible: give either 'beam' or 'nodes', not both");
}

TEST_CASE("scene flex: joints at nodes") {
  CHECK(error_of(edit("    parent_node: top\n", "    parent_node: tip\n")) ==
        "flex.yaml:24:18: joints[1].parent_node: body 'beam' has no node 'tip' (did you mean "
        "'top'?); its nodes: bottom, slice1, slice2, slice3, slice4, slice5, ...");
  CHECK(error_of(edit("    parent_node: top\n", "    parent_node: top\n    parent_point: [0, 0, "
                                                 "5]\n")) ==
        "flex.yaml:25:19: joints[1].parent_point: give either parent_point or parent_node, not "
        "both (the joint point is the node's position)");
  CHECK(error_of(edit("    parent_node: top\n", "")) ==
        "flex.yaml:21:5: joints[1]: missing required key 'parent_point' in a joint (or "
        "'parent_node' for a node of a flexible parent)");
  CHECK(error_of(edit("    child_point: [-1, 0, 0]\n", "    child_node: top\n")) ==
        "flex.yaml:26:17: joints[1].child_node: the child 'payload' is a rigid body, without "
        "nodes; give child_point");
  CHECK_THAT(error_of(edit("    child: beam\n", "    child: beam\n    parent_node: top\n")),
             StartsWith("flex.yaml:21:5: joints[0].parent_node: 'parent_node' does not apply to a "
                        "free joint"));
}

TEST_CASE("scene flex: scenarios/pointing_flex.yaml is Scene 2 as the engines' tests build it in code") {
  const System file = read_scene(test::scene_path("pointing_flex"));
  System code = test::pointing_flex_system();
  // What only a file has: its name, path, texts, compare block and the flexible body's scene form.
  code.name = file.name;
  code.file = file.file;
  code.description = file.description;
  code.source = file.source;
  code.compare = file.compare;
  code.bodies[0].flex->scene_form = file.bodies[0].flex->scene_form;
  code.bodies[0].flex->origin = file.bodies[0].flex->origin;
  CHECK(test::system_difference(file, code) == "");
}
