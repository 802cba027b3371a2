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
#include "tests/support/linalg.hpp"
#include "tests/support/paths.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
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
  // The reader keeps only the stations joints use (core/flex/beam.hpp): none of pointing_flex's.
  CHECK(code.bodies[0].flex->nodes.size() == 202);
  std::vector<bool> used(code.bodies[0].flex->nodes.size(), false);
  const std::vector<int> index = flex::drop_unused_stations(*code.bodies[0].flex, used);
  for (Joint& J : code.joints)
    if (J.parent == 0 && J.parent_node >= 0) J.parent_node = index[static_cast<std::size_t>(J.parent_node)];
  CHECK(code.bodies[0].flex->nodes.size() == 102);
  CHECK(test::system_difference(file, code) == "");
}

// ---- issue 27 item 5: the default beam is the continuum beam ---------------------------------

TEST_CASE("class: a committed beam scene's flexible frequencies and modal integrals are the continuum's (pointing_flex in full, every beam scene's modal mass)") {
  // pointing_flex, read by the scene reader: 10 m, 50 kg/m, EI = 100 N m^2 in both planes,
  // free-free, two modes per plane with unit top displacement, 100 slices. Its flexible
  // frequencies sqrt(K_k / M_k) and the small-motion frequencies of the free body (the rest mass
  // matrix with the rigid motion) equal lambda_k^2 sqrt(EI / (rho A L^4)) to 1e-10 (they agree to
  // about 1e-15), its modal masses are rho A L / 4, its cross modal masses and coupling sums zero.
  const System s = read_scene(test::scene_path("pointing_flex"));
  const FlexBody& f = *s.bodies[0].flex;
  REQUIRE(f.modes() == 4);
  const double rhoA = 50, L = 10, EI = 100, M = rhoA * L;
  const Eigen::MatrixXd Mr = flex::rest_mass_matrix(f);
  const Eigen::MatrixXd Mee = Mr.bottomRightCorner(4, 4);
  Eigen::MatrixXd Kfull = Eigen::MatrixXd::Zero(10, 10);
  Kfull.bottomRightCorner(4, 4) = f.K;
  const Eigen::VectorXd w_free =
      test::generalized_symmetric_eigenvalues(Kfull, Mr).tail(4).cwiseMax(0).cwiseSqrt();
  for (int k = 0; k < 4; ++k) {
    const double lambda = flex::free_free_root(k % 2 + 1);
    const double w = lambda * lambda * std::sqrt(EI / (rhoA * std::pow(L, 4)));
    CAPTURE(k, w);
    CHECK(std::abs(std::sqrt(f.K(k, k) / Mee(k, k)) / w - 1) <= 1e-10);
    CHECK(std::abs(w_free(k % 2 == 0 ? k / 2 : 2 + k / 2) / w - 1) <= 1e-10);  // ascending: w1 w1 w2 w2
    CHECK(std::abs(Mee(k, k) / (M / 4) - 1) <= 1e-12);
    for (int l = 0; l < 4; ++l)
      if (l != k) CHECK(std::abs(Mee(k, l)) <= 1e-12 * M);
    // The coupling blocks: sum m Phi (rows 3..5) and sum m p x Phi (rows 0..2).
    CHECK(Mr.block(0, 6 + k, 6, 1).norm() <= 1e-12 * M * L);
  }
  // Every committed beam scene: the node-sum modal mass of each mode equals the continuum's
  // (rho A L / 4 with a unit end value; the scenes normalise at an end), the cross masses vanish.
  for (const char* name : {"free_beam_payload", "hub_flex_array", "spinup_beam", "spinup_beam_linear"}) {
    const System t = read_scene(test::scene_path(name));
    for (const Body& b : t.bodies) {
      if (!b.flex) continue;
      const Eigen::MatrixXd m = flex::rest_mass_matrix(*b.flex).bottomRightCorner(b.flex->modes(), b.flex->modes());
      CAPTURE(name, b.name);
      CHECK(b.flex->modes() > 0);
      for (int k = 0; k < b.flex->modes(); ++k) {
        CHECK(std::abs(m(k, k) / (b.mass / 4) - 1) <= 1e-12);
        for (int l = 0; l < b.flex->modes(); ++l)
          if (l != k) CHECK(std::abs(m(k, l)) <= 1e-12 * b.mass);
      }
    }
  }
}

TEST_CASE("class: stations no joint uses are dropped when a scene is read and used ones stay at the slice centre, on either side, and nothing else changes") {
  // The beam generator makes bottom, slice1..N (massless stations at the old slice centres),
  // gauss1..N (the mass) and top; the reader keeps the ends, the mass points and the stations a
  // joint names (parent_node or child_node), and drops the rest.
  struct Case {
    std::string label;
    System system;
    std::vector<std::string> stations;  // kept, in order
  };
  std::vector<Case> cases;
  cases.push_back({"pointing_flex (ends only)", read_scene(test::scene_path("pointing_flex")), {}});
  cases.push_back({"free_beam_payload (slice30, parent side)", read_scene(test::scene_path("free_beam_payload")), {"slice30"}});
  cases.push_back({"hub_flex_array (bottom, child side)", read_scene(test::scene_path("hub_flex_array")), {}});
  // Stations on both sides and two joints at one station.
  cases.push_back({"kFlex with slice3 (child side) and slice17 twice (parent side)",
                   read_scene_text(edit("    child_point: [-1, 0, 0]\n    axis: [0, 1, 0]\n",
                                        "    child_point: [-1, 0, 0]\n    axis: [0, 1, 0]\n"
                                        "  - {name: h2, type: revolute, parent: beam, parent_node: slice17, child: p2, child_point: [0, 0, 0], axis: [1, 0, 0]}\n"
                                        "  - {name: h3, type: fixed, parent: beam, parent_node: slice17, child: p3, child_point: [0, 0, 0.1]}\n"
                                        "  - {name: h4, type: spherical, parent: payload, parent_point: [1, 0, 0], child: tail, child_node: slice3}\n",
                                        edit("    inertia: [12.5, 39.6, 39.6]\n",
                                             "    inertia: [12.5, 39.6, 39.6]\n"
                                             "  - {name: p2, mass: 1, inertia: [0.1, 0.1, 0.1]}\n"
                                             "  - {name: p3, mass: 1, inertia: [0.1, 0.1, 0.1]}\n"
                                             "  - name: tail\n    flexible: {beam: {length: 2, axis: x, mass_per_length: 1, section: [0, 0.1, 0.1], bending: {y: {modes: 1, EI: 10}}, slices: 8}}\n")),
                                   "flex.yaml"),
                   {"slice17"}});
  for (const Case& c : cases) {
    CAPTURE(c.label);
    const System& s = c.system;
    for (std::size_t b = 0; b < s.bodies.size(); ++b) {
      if (!s.bodies[b].flex) continue;
      const FlexBody& f = *s.bodies[b].flex;
      CAPTURE(s.bodies[b].name);
      // The generator's full body, every station kept.
      const int N = static_cast<int>(std::count_if(f.nodes.begin(), f.nodes.end(),
                                                   [](const FlexNode& n) { return n.mass > 0; }));
      std::vector<std::string> names;
      for (const FlexNode& n : f.nodes)
        if (n.name.rfind("slice", 0) == 0) names.push_back(n.name);
      if (s.bodies[b].name == "tail") CHECK(names == std::vector<std::string>{"slice3"});
      else CHECK(names == c.stations);
      CHECK(f.nodes.front().name == "bottom");
      CHECK(f.nodes.back().name == "top");
      CHECK(f.nodes.size() == static_cast<std::size_t>(N + 2) + names.size());
      // Every joint at a node: the node it names, at the exact slice centre or end.
      for (const Joint& J : s.joints)
        for (bool parent : {true, false}) {
          if ((parent ? J.parent : J.child) != static_cast<int>(b)) continue;
          const int node = parent ? J.parent_node : J.child_node;
          if (node < 0) continue;
          const FlexNode& n = f.nodes[static_cast<std::size_t>(node)];
          CAPTURE(J.name, n.name);
          CHECK((parent ? J.p_PoJ_P : J.p_CoJ_C) == n.p_BoNi_B);
          CHECK(n.mass == 0.0);
          const int a = n.p_BoNi_B.x() != 0 ? 0 : n.p_BoNi_B.y() != 0 ? 1 : 2;
          const double half = std::abs(f.nodes.front().p_BoNi_B(a));
          if (n.name.rfind("slice", 0) == 0) {
            const int i = std::stoi(n.name.substr(5));
            CHECK(std::abs(n.p_BoNi_B(a) - (-half + (i - 0.5) * 2 * half / N)) <= 1e-15 * half);
          }
        }
      // Nothing depends on the dropped stations: the rigid properties, the rest mass matrix (every
      // modal integral the engines use) and the mass points are those of the generator's full body.
      const flex::RigidProperties r = flex::rigid_properties(f);
      CHECK(r.mass == s.bodies[b].mass);
      CHECK(r.I == s.bodies[b].I_BBo_B);
    }
  }
  // The full body against the pruned one, bit for bit: pointing_flex built in code keeps all.
  const System file = read_scene(test::scene_path("pointing_flex"));
  const System code = test::pointing_flex_system();
  const FlexBody& pruned = *file.bodies[0].flex;
  const FlexBody& full = *code.bodies[0].flex;
  REQUIRE(full.nodes.size() == 202);
  CHECK(flex::rest_mass_matrix(pruned) == flex::rest_mass_matrix(full));
  CHECK(flex::rigid_properties(pruned).I == flex::rigid_properties(full).I);
  CHECK(pruned.K == full.K);
  for (int i = 1; i <= 100; ++i) {
    const FlexNode& a = pruned.nodes[static_cast<std::size_t>(pruned.node_index("gauss" + std::to_string(i)))];
    const FlexNode& z = full.nodes[static_cast<std::size_t>(full.node_index("gauss" + std::to_string(i)))];
    CHECK((a.mass == z.mass && a.p_BoNi_B == z.p_BoNi_B && a.Phi_B == z.Phi_B && a.Psi_B == z.Psi_B));
  }
  // A nodal data file's massless nodes are never dropped, whatever their names.
  FlexBody csv = full;
  csv.origin = "nodal data file n.csv";
  CHECK(flex::drop_unused_stations(csv, {}).size() == 202);
  CHECK(csv.nodes.size() == 202);
}
