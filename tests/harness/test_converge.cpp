// `crossdyn converge`: fewer modes, the same rigid body, and the smallest model named
// (harness/converge.hpp).
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <regex>
#include <sstream>
#include <fstream>
#include <limits>

#include "core/engine.hpp"
#include "core/errors.hpp"
#include "harness/converge.hpp"
#include "core/scene/scene.hpp"
#include "harness/engines.hpp"
#include "tests/support/paths.hpp"
#include "tests/cross/flex_systems.hpp"
#include "tests/harness/run_program.hpp"

using namespace crossdyn;
using namespace crossdyn::harness;

TEST_CASE("converge: the beam generator's modes form one group per bending plane") {
  const System s = test::pointing_flex_system(3);
  const std::vector<ModeGroup> g = mode_groups(s);
  REQUIRE(g.size() == 2);
  CHECK(g[0].name == "qx");
  CHECK(g[1].name == "qy");
  CHECK(g[0].modes == std::vector<int>{0, 1, 2});
  CHECK(g[1].modes == std::vector<int>{3, 4, 5});
  CHECK(model_label(s, g, {2, 0}) == "beam qx2 qy0");
  CHECK(mode_groups(test::pointing_flex_system(0)).empty());
}

TEST_CASE("converge: modes that the motion does not excite can be left out exactly, in every "
          "engine") {
  // Scene 2 moves in the beam's x-z plane only (hinges about y, motors about y, no y-plane
  // deflection): the y-plane modes are not excited. At such a state the full model's qy
  // accelerations vanish, and the model without them (truncate_modes: qx2 qy0) has the same
  // accelerations of every other coordinate, in every engine: the truncation is the full model
  // with the dropped coordinates held at zero.
  const System full = test::pointing_flex_system(2);
  const std::vector<ModeGroup> g = mode_groups(full);
  const System cut = truncate_modes(full, g, {2, 0});
  REQUIRE(cut.bodies[0].flex->modes() == 2);
  CHECK(cut.bodies[0].flex->mode_names == std::vector<std::string>{"qx1", "qx2"});
  CHECK(cut.bodies[0].mass == full.bodies[0].mass);
  CHECK(cut.bodies[0].I_BBo_B == full.bodies[0].I_BBo_B);
  CHECK(cut.bodies[0].flex->K == full.bodies[0].flex->K.topLeftCorner(2, 2));
  for (const std::string& engine : engine_names()) {
    auto ef = make_engine(engine, full);
    auto ec = make_engine(engine, cut);
    TreeState sf = TreeState::initial(full), sc = TreeState::initial(cut);
    sf.w_NB_B = sc.w_NB_B = Eigen::Vector3d(0.0, 0.03, 0.0);
    sf.joints[1].angle = sc.joints[1].angle = 0.4;
    sf.joints[1].rate = sc.joints[1].rate = 0.2;
    sf.joints[2].angle = sc.joints[2].angle = -0.3;
    sf.joints[2].rate = sc.joints[2].rate = -0.1;
    sf.eta[0](0) = sc.eta[0](0) = 0.01;
    sf.eta[0](1) = sc.eta[0](1) = -0.004;
    sf.eta_rate[0](0) = sc.eta_rate[0](0) = -0.02;
    sf.eta_rate[0](1) = sc.eta_rate[0](1) = 0.003;
    std::vector<double> xf(static_cast<std::size_t>(ef->state_size()));
    std::vector<double> xc(static_cast<std::size_t>(ec->state_size()));
    ef->pack(sf, xf.data());
    ec->pack(sc, xc.data());
    TreeAccel af, ac;
    ef->accelerations(1.0, xf.data(), af);  // motors at +1 N m
    ec->accelerations(1.0, xc.data(), ac);
    INFO(engine << ": full model qy accelerations " << af.eta_ddot[0].tail(2).transpose()
                << ", qx " << af.eta_ddot[0].head(2).transpose() << " (truncated "
                << ac.eta_ddot[0].transpose() << ")");
    REQUIRE(ac.eta_ddot[0].size() == 2);
    REQUIRE(af.eta_ddot[0].size() == 4);
    const double scale = af.eta_ddot[0].cwiseAbs().maxCoeff();
    REQUIRE(scale > 1e-4);  // the motion does excite the x-plane modes
    CHECK(af.eta_ddot[0].tail(2).cwiseAbs().maxCoeff() <= 1e-12 * scale);
    CHECK((ac.eta_ddot[0] - af.eta_ddot[0].head(2)).cwiseAbs().maxCoeff() <= 1e-12 * scale);
    for (std::size_t b = 0; b < full.bodies.size(); ++b) {
      CHECK((ac.wdot_NB_B[b] - af.wdot_NB_B[b]).norm() <= 1e-12 * (1 + af.wdot_NB_B[b].norm()));
      CHECK((ac.a_NBo_N[b] - af.a_NBo_N[b]).norm() <= 1e-12 * (1 + af.a_NBo_N[b].norm()));
    }
    for (std::size_t j = 0; j < full.joints.size(); ++j)
      CHECK(std::abs(ac.angle_ddot[j] - af.angle_ddot[j]) <= 1e-12 * (1 + std::abs(af.angle_ddot[j])));
  }
}

TEST_CASE("converge on Scene 2 finds that the y-plane modes can be left out and the x-plane modes "
          "cannot") {
  System s = test::pointing_flex_system(2);
  s.run.duration = 20.0;
  s.run.output_step = 0.5;
  s.compare.default_tolerance = {1e-8, 1e-8};
  CompareOptions o;
  o.engines = {{"kane", "kane", {}}};
  const ConvergeResult r = converge_scene(s, o);
  INFO(format_converge(r));
  REQUIRE(r.models.size() == 9);
  CHECK(r.models.front().full);
  const ConvergeModel& best = r.models[static_cast<std::size_t>(r.smallest)];
  CHECK(best.counts == std::vector<int>{2, 0});
  for (const ConvergeModel& m : r.models) {
    if (m.full) continue;
    // Leaving out an x-plane mode changes the answer beyond the tolerance; y-plane modes do not.
    CHECK(m.passed == (m.counts[0] == 2));
  }
}

TEST_CASE("converge refuses a scene without modes and a scene with too many models") {
  CompareOptions o;
  o.engines = {{"kane", "kane", {}}};
  System rigid = test::pointing_flex_system(0);
  rigid.file = "rigid.yaml";
  CHECK_THROWS_WITH(converge_scene(rigid, o),
                    Catch::Contains("rigid.yaml") && Catch::Contains("needs a flexible body"));
  System many = test::pointing_flex_system(16);  // 17 x 17 = 289 models
  many.file = "many.yaml";
  CHECK_THROWS_WITH(converge_scene(many, o),
                    Catch::Contains("289 models") && Catch::Contains("the limit is 256"));
}

TEST_CASE("crossdyn converge on a rigid scene, with an unknown engine or an output that is the "
          "scene: exit status 2 and the reason") {
  auto r = test::run_crossdyn("converge scenarios/spear1_case1.yaml -q");
  CHECK(r.status == 2);
  CHECK_THAT(r.output, Catch::Contains("spear1_case1.yaml") &&
                           Catch::Contains("needs a flexible body with at least one mode"));
  r = test::run_crossdyn("converge scenarios/spear1_case1.yaml --engine knae -q");
  CHECK(r.status == 2);
  CHECK_THAT(r.output, Catch::Contains("unknown engine 'knae'"));
  r = test::run_crossdyn("converge scenarios/spear1_case1.yaml --json scenarios/spear1_case1.yaml");
  CHECK(r.status == 2);
  CHECK_THAT(r.output, Catch::Contains("--json") && Catch::Contains("scene file"));
  r = test::run_crossdyn("convrge scenarios/spear1_case1.yaml");
  CHECK(r.status == 2);
  CHECK_THAT(r.output, Catch::Contains("did you mean 'converge'"));
}

TEST_CASE("converge on the committed pointing_flex scene: two x-plane modes, and no slicing "
          "error (the beam's integrals are exact)") {
  System s = read_scene(test::scene_path("pointing_flex"));
  s.run.duration = 20.0;
  CompareOptions o;
  o.engines = {{"kane", "kane", {}}};
  const ConvergeResult r = converge_scene(s, o);
  const std::string table = format_converge(r);
  INFO(table);
  CHECK(r.models[static_cast<std::size_t>(r.smallest)].counts == std::vector<int>{2, 0});
  // The slicing rows: the beam with 50 and 200 slices (the scene has 100).
  std::vector<const ConvergeModel*> sliced;
  for (const ConvergeModel& m : r.models)
    if (m.slices > 0) sliced.push_back(&m);
  REQUIRE(sliced.size() == 2);
  CHECK(sliced[0]->slices == 50);
  CHECK(sliced[1]->slices == 200);
  // The generator's modal integrals are exact (Gauss-Legendre mass points, core/flex/beam.hpp):
  // the beam at 50 and 200 slices is the beam at 100, the changes rounding and integration noise
  // (measured 6.9e-15 and 3.7e-15 over 60 s; before, 7.6e-3 at 100 slices, falling as N^-2), and
  // converge says there is no order to measure.
  CHECK(sliced[0]->worst_relative < 1e-11);
  CHECK(sliced[1]->worst_relative < 1e-11);
  CHECK_THAT(table, Catch::Contains("slicing order of beam: none to measure") &&
                        Catch::Contains("the answer does not depend on the slicing"));
  CHECK_THAT(table, !Catch::Contains("observed order"));
}

// ---- issue 23, class 7: a re-sliced row is the same physical model ----------------------------

namespace {

const FlexNode& node_of(const System& s, int body, int node) {
  return s.bodies[static_cast<std::size_t>(body)].flex->nodes[static_cast<std::size_t>(node)];
}

int body_named(const System& s, const std::string& name) {
  for (std::size_t b = 0; b < s.bodies.size(); ++b)
    if (s.bodies[b].name == name) return static_cast<int>(b);
  return -1;
}

// The beam's slices: its mass points (the stations and ends are massless).
int slices_of(const FlexBody& f) {
  return static_cast<int>(std::count_if(f.nodes.begin(), f.nodes.end(), [](const FlexNode& x) { return x.mass > 0; }));
}

// The beam generator's own node `name` of body `b`'s beam at `slices` slices: a scene with a joint
// there, so that the reader keeps that station (core/flex/beam.hpp).
FlexNode native_node(const System& s, int b, int slices, const std::string& name) {
  const std::string form = std::regex_replace(s.bodies[static_cast<std::size_t>(b)].flex->scene_form,
                                              std::regex(R"(\bslices: *[0-9]+)"),
                                              "slices: " + std::to_string(slices));
  const System p = read_scene_text("name: probe\nbodies:\n  - name: beam\n    flexible: " + form +
                                       "\n  - {name: probe, mass: 1, inertia: [1, 1, 1]}\njoints:\n"
                                       "  - {name: base, type: free, child: beam}\n"
                                       "  - {name: at, type: fixed, parent: beam, parent_node: " + name +
                                       ", child: probe, child_point: [0, 0, 0]}\n"
                                       "run: {duration: 1, output_step: 0.1}\n",
                                   "probe.yaml");
  return p.bodies[0].flex->nodes[static_cast<std::size_t>(p.joints[1].parent_node)];
}

// The attachment of joint `j` on body `b` (its parent or child side).
struct Side {
  int node;
  Eigen::Vector3d point;
};
Side side_of(const System& s, std::size_t j, int b) {
  const Joint& J = s.joints[j];
  return J.parent == b ? Side{J.parent_node, J.p_PoJ_P} : Side{J.child_node, J.p_CoJ_C};
}

// A hub with two beams, every kind of attachment: `boom` (free-free, unit modal mass) hangs from
// the hub by its slice node slice3 (child side, spherical) and carries a payload at slice7
// (parent side, revolute) and one by a point between its nodes (parent_point, fixed); `mast`
// (clamped at its root, geometric stiffening) is welded to the hub at `bottom` (child side) and
// carries a tip mass at `top` and a second one at slice4 (parent side, both revolute), and a
// third joint at slice4 too (one node, two joints).
constexpr const char* kAttachments = R"(
name: attachments
bodies:
  - {name: hub, mass: 100, inertia: [10, 10, 10]}
  - name: boom
    flexible:
      beam: {length: 4, axis: x, mass_per_length: 5, section: [0, 0.1, 0.1],
             bending: {y: {modes: 2, EI: 300}, z: {modes: 1, EI: 200}}, slices: 12,
             normalisation: mass, damping: {ratios: [0.01]}}
  - {name: pay1, mass: 1, inertia: [0.01, 0.01, 0.01]}
  - {name: pay2, mass: 1, inertia: [0.01, 0.01, 0.01]}
  - name: mast
    flexible:
      beam: {length: 3, axis: z, mass_per_length: 4, section: [0.1, 0.1, 0],
             bending: {x: {modes: 2, EI: 400}}, boundary: clamped-bottom, slices: 12,
             geometric_stiffening: true}
  - {name: tip, mass: 0.5, inertia: [0.01, 0.01, 0.01]}
  - {name: mid, mass: 0.5, inertia: [0.01, 0.01, 0.01]}
  - {name: mid2, mass: 0.5, inertia: [0.01, 0.01, 0.01]}
joints:
  - {name: base, type: free, child: hub, initial: {angular_velocity: [0.01, 0.02, 0.03]}}
  - {name: hang, type: spherical, parent: hub, parent_point: [1, 0, 0], child: boom,
     child_node: slice3}
  - {name: p1, type: revolute, parent: boom, parent_node: slice7, child: pay1,
     child_point: [0, -0.2, 0], axis: [0, 0, 1]}
  - {name: p2, type: fixed, parent: boom, parent_point: [0.7, 0, 0.05], child: pay2,
     child_point: [0, 0, -0.1]}
  - {name: weld, type: fixed, parent: hub, parent_point: [0, 0, 1], child: mast, child_node: bottom}
  - {name: t1, type: revolute, parent: mast, parent_node: top, child: tip, child_point: [0, 0, -0.1],
     axis: [1, 0, 0]}
  - {name: m1, type: revolute, parent: mast, parent_node: slice4, child: mid,
     child_point: [-0.1, 0, 0], axis: [0, 1, 0]}
  - {name: m2, type: revolute, parent: mast, parent_node: slice4, child: mid2,
     child_point: [0.1, 0, 0], axis: [0, 1, 0]}
run: {duration: 1, output_step: 0.1}
)";

}  // namespace

TEST_CASE("class 7, converge's re-sliced rows compare the same physical model: every joint at a "
          "node keeps its point, at half and twice the slices") {
  struct Case {
    std::string label;
    System system;
  };
  std::vector<Case> cases;
  cases.push_back({"free_beam_payload (the issue's example)", read_scene(test::scene_path("free_beam_payload"))});
  cases.push_back({"pointing_flex (top and bottom)", read_scene(test::scene_path("pointing_flex"))});
  cases.push_back({"hub_flex_array (root, child side)", read_scene(test::scene_path("hub_flex_array"))});
  cases.push_back({"attachments (every side and kind)", read_scene_text(kAttachments, "attachments.yaml")});
  int slice_attachments = 0, end_attachments = 0, point_attachments = 0;
  for (const Case& c : cases) {
    const System& s = c.system;
    for (std::size_t b = 0; b < s.bodies.size(); ++b) {
      if (!s.bodies[b].flex) continue;
      const FlexBody& from = *s.bodies[b].flex;
      const int n = slices_of(from);
      for (int slices : {n / 2, 2 * n}) {
        CAPTURE(c.label, s.bodies[b].name, slices);
        std::vector<std::string> kept;
        const std::optional<System> r = reslice(s, static_cast<int>(b), slices, &kept);
        REQUIRE(r);
        const FlexBody& to = *r->bodies[b].flex;
        CHECK(static_cast<int>(std::count_if(to.nodes.begin(), to.nodes.end(), [](const FlexNode& x) {
                return x.mass > 0;
              })) == slices);
        // The rigid body is the same; only the lumping of its mass changed.
        CHECK(std::abs(r->bodies[b].mass - s.bodies[b].mass) <= 1e-12 * s.bodies[b].mass);
        CHECK((r->bodies[b].I_BBo_B - s.bodies[b].I_BBo_B).norm() <= 1e-12 * s.bodies[b].I_BBo_B.norm());
        for (std::size_t j = 0; j < s.joints.size(); ++j) {
          const Joint& J = s.joints[j];
          for (bool parent : {true, false}) {
            if ((parent ? J.parent : J.child) != static_cast<int>(b)) continue;
            CAPTURE(J.name, parent);
            const Side a = side_of(s, j, static_cast<int>(b));
            const Side z = side_of(*r, j, static_cast<int>(b));
            // The same point of the beam, to the bit.
            CHECK(z.point == a.point);
            if (a.node < 0) {  // a point between nodes: fixed in the body frame, as before
              CHECK(z.node == -1);
              ++point_attachments;
              continue;
            }
            const FlexNode& na = from.nodes[static_cast<std::size_t>(a.node)];
            const FlexNode& nz = to.nodes[static_cast<std::size_t>(z.node)];
            CHECK(nz.p_BoNi_B == na.p_BoNi_B);
            if (na.name == "bottom" || na.name == "top") {
              CHECK(nz.name == na.name);  // the ends are nodes at any slicing
              ++end_attachments;
              continue;
            }
            ++slice_attachments;
            CHECK(nz.name == na.name + "-of-" + std::to_string(n));
            CHECK(nz.mass == 0);
            CHECK_THAT(kept.empty() ? std::string() : kept.front(), Catch::Contains("massless node"));
            bool named = false;
            for (const std::string& k : kept)
              named = named || (k.find("joint '" + J.name + "'") != std::string::npos &&
                                k.find("node " + na.name + " of the " + std::to_string(n)) != std::string::npos);
            CHECK(named);
            // The re-sliced beam's own node of that name (if any) is elsewhere: the old defect.
            const int same_name = to.node_index(na.name);
            if (same_name >= 0) CHECK(to.nodes[static_cast<std::size_t>(same_name)].p_BoNi_B != na.p_BoNi_B);
          }
        }
        // Two joints at one node share one added node.
        for (std::size_t j = 0; j + 1 < s.joints.size(); ++j)
          for (std::size_t k = j + 1; k < s.joints.size(); ++k)
            if (s.joints[j].parent == static_cast<int>(b) && s.joints[k].parent == static_cast<int>(b) &&
                s.joints[j].parent_node >= 0 && s.joints[j].parent_node == s.joints[k].parent_node)
              CHECK(r->joints[j].parent_node == r->joints[k].parent_node);
      }
    }
  }
  // Each at half and twice the slices: drive; hang, p1, m1, m2.
  CHECK(slice_attachments == 2 * 5);
  CHECK(end_attachments > 0);
  CHECK(point_attachments >= 2);  // p2 (and the free joints' unused child points)
}

TEST_CASE("class 7, the added node carries the continuous beam's shape, slope and foreshortening "
          "at that point: equal to the native node of a beam sliced three times finer") {
  // A slice centre of N slices is the centre of slice 3i - 1 of 3N slices: there the generator's
  // own node and the added node must agree (unit top displacement, unit modal mass, clamped with
  // geometric stiffening).
  struct Case {
    System system;
    std::string body, joint;
  };
  const System attach = read_scene_text(kAttachments, "attachments.yaml");
  const std::vector<Case> cases = {
      {read_scene(test::scene_path("free_beam_payload")), "boom", "drive"},
      {attach, "boom", "hang"},
      {attach, "boom", "p1"},
      {attach, "mast", "m1"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.body, c.joint);
    const int b = body_named(c.system, c.body);
    REQUIRE(b >= 0);
    const FlexBody& from = *c.system.bodies[static_cast<std::size_t>(b)].flex;
    const int n = slices_of(from);
    std::size_t j = 0;
    while (c.system.joints[j].name != c.joint) ++j;
    const FlexNode& at = node_of(c.system, b, side_of(c.system, j, b).node);
    REQUIRE(at.name.rfind("slice", 0) == 0);
    const int i = std::stoi(at.name.substr(5));
    const std::optional<System> r = reslice(c.system, b, 3 * n);
    REQUIRE(r);
    const FlexNode& added = node_of(*r, b, side_of(*r, j, b).node);
    const FlexNode native = native_node(c.system, b, 3 * n, "slice" + std::to_string(3 * i - 1));
    CHECK(native.name == "slice" + std::to_string(3 * i - 1));
    CHECK((native.p_BoNi_B - added.p_BoNi_B).norm() <= 1e-15 * 4);
    const double scale = native.Phi_B.cwiseAbs().maxCoeff() + native.Psi_B.cwiseAbs().maxCoeff();
    CHECK((native.Phi_B - added.Phi_B).cwiseAbs().maxCoeff() <= 1e-12 * scale);
    CHECK((native.Psi_B - added.Psi_B).cwiseAbs().maxCoeff() <= 1e-12 * scale);
    CHECK(native.G.size() == added.G.size());
    if (native.G.size() > 0)
      CHECK((native.G - added.G).cwiseAbs().maxCoeff() <= 1e-12 * (1 + native.G.cwiseAbs().maxCoeff()));
  }
}

TEST_CASE("class 7, a re-sliced row the beam generator refuses is a note with the reason, without "
          "a location in text the user never wrote") {
  std::ifstream in(test::scene_path("free_beam_payload"));
  std::stringstream text;
  text << in.rdbuf();
  std::string t = text.str();
  t.replace(t.find("slices: 60"), 10, "slices: 8");
  t.replace(t.find("parent_node: slice30"), 20, "parent_node: slice4");
  System s = read_scene_text(t, "eight.yaml");
  s.run.duration = 0.5;
  CompareOptions o;
  o.engines = {{"kane", "kane", {}}};
  std::vector<ConvergeJob> jobs;
  const ConvergeResult r = converge_frame(s, o, &jobs);
  const ConvergeModel full = converge_full_model(s, r, o);
  int refused = 0, made = 0;
  for (const ConvergeJob& job : jobs) {
    if (job.slices == 0) continue;
    std::string note;
    const std::optional<ConvergeModel> m = converge_job(s, r, job, full.run, o, &note);
    CAPTURE(job.slices, note);
    if (job.slices == 4) {
      ++refused;
      CHECK_FALSE(m);
      CHECK(note == "boom with 4 slices: not run (the beam generator refuses it: slices: 4 slices "
                    "cannot resolve mode 3 (about 4 half-waves): use at least 8)");
    } else {
      ++made;
      REQUIRE(m);
      CHECK_THAT(note, Catch::Contains("joint 'drive' (parent side) stays at node slice4 of the "
                                       "8-slice beam, at (-0.25, 0, 0) m, a massless node of the "
                                       "16-slice beam (slice4-of-8)"));
    }
  }
  CHECK(refused == 1);
  CHECK(made == 1);
}

TEST_CASE("class 7, converge on the issue's example: the slicing rows measure the discretisation "
          "alone, which the exact integrals make nothing") {
  System s = read_scene(test::scene_path("free_beam_payload"));
  s.run.duration = 2.0;
  CompareOptions o;
  o.engines = {{"kane", "kane", {}}};
  std::vector<ConvergeJob> jobs;
  ConvergeResult r = converge_frame(s, o, &jobs);
  r.models.push_back(converge_full_model(s, r, o));
  for (const ConvergeJob& job : jobs) {
    if (job.slices == 0) continue;
    std::string note;
    std::optional<ConvergeModel> m = converge_job(s, r, job, r.models.front().run, o, &note);
    REQUIRE(m);
    r.models.push_back(std::move(*m));
    CHECK_THAT(note, Catch::Contains("joint 'drive'") && Catch::Contains("slice30 of the 60-slice beam"));
    r.notes.push_back(note);
  }
  converge_finish(r);
  const std::string table = format_converge(r);
  INFO(table);
  REQUIRE(r.models.size() == 3);
  CHECK(r.models[1].slices == 30);
  CHECK(r.models[2].slices == 120);
  // The joint no longer moves (the moved joint gave 1.5e9 times the tolerance), and the mass
  // lumping no longer changes anything: the generator's integrals are exact (Gauss-Legendre mass
  // points, core/flex/beam.hpp), so 30 and 120 slices give the 60-slice answer to rounding and
  // integration noise (`crossdyn converge` over the whole scene: 8.6e-14 and 5.2e-14; before, a
  // change falling as N^-2).
  CHECK(r.models[1].worst_relative < 1e-9);
  CHECK(r.models[2].worst_relative < 1e-9);
  CHECK_THAT(table, Catch::Contains("massless node"));
  CHECK_THAT(table, Catch::Contains("slicing order of boom: none to measure"));
  CHECK_THAT(table, !Catch::Contains("observed order"));
}

TEST_CASE("class 11, converge's sentences follow from its rows: the order on one quantity, a "
          "failed re-sliced run said as such") {
  auto check = [](const std::string& q, double change) {
    Check k;
    k.quantity = q;
    k.b = "x";
    k.error = k.normalised = change;
    return k;
  };
  ConvergeResult r;
  r.scene = "s";
  r.engine = "kane";
  ConvergeModel full;
  full.full = true;
  full.label = "beam qx2 (full)";
  full.modes = 2;
  full.passed = true;
  ConvergeModel coarse = full, fine = full;
  coarse.full = fine.full = false;
  coarse.passed = fine.passed = false;
  coarse.slices = 25;
  fine.slices = 100;
  coarse.slice_body = fine.slice_body = 0;
  coarse.label = "beam qx2, beam 25 slices";
  fine.label = "beam qx2, beam 100 slices";
  // The coarse row's largest change is in a.wx (400); the fine row's largest is elsewhere (b.wx
  // 300), and a.wx changed 25 there: the order is measured on a.wx, 400 / 25 = 16 per doubling.
  // (Scales 1: the relative change is the error.)
  coarse.checks = {check("a.wx", 400), check("b.wx", 100)};
  coarse.scales = {1, 1};
  judge_converge_model(coarse, 1e-3);
  CHECK(coarse.worst_relative == 400);
  CHECK(coarse.worst_quantity == "a.wx");
  fine.checks = {check("a.wx", 25), check("b.wx", 300)};
  fine.scales = {1, 1};
  judge_converge_model(fine, 1e-3);
  CHECK(fine.worst_quantity == "b.wx");
  r.models = {full, coarse, fine};
  converge_finish(r);
  std::string text = format_converge(r);
  INFO(text);
  CHECK_THAT(text, Catch::Contains("slicing order of beam: the change in a.wx falls 16.00 times per "
                                   "doubling of the slices (observed order 4.00)"));
  // A re-sliced run that failed: said so, and no order from it.
  r.models[2].checks.clear();
  r.models[2].scales.clear();
  r.models[2].worst_relative = r.models[2].worst_normalised = std::numeric_limits<double>::infinity();
  r.models[2].worst_quantity = "run: kane: non-finite state at t = 0.5 s";
  text = format_converge(r);
  INFO(text);
  CHECK_THAT(text, Catch::Contains("slicing: beam with 100 slices: the run did not reach the end "
                                   "(kane: non-finite state at t = 0.5 s), so nothing was compared"));
  CHECK_THAT(text, !Catch::Contains("observed order") && !Catch::Contains("100 slices: the answer"));
  CHECK_THAT(text, Catch::Contains("RUN FAILED"));
  // Odd slices (25: rows of 12 and 50): not half and twice, so no order is claimed.
  r.models[1].slices = 12;
  r.models[2] = coarse;
  r.models[2].slices = 50;
  text = format_converge(r);
  INFO(text);
  CHECK_THAT(text, Catch::Contains("slicing order of beam: not measured (12 and 50 slices are not "
                                   "half and twice the scene's: its slices are odd)"));
  CHECK_THAT(text, !Catch::Contains("observed order"));
  // Changes at rounding level (both at most 1e-9): no order is claimed from their ratio, and the
  // sentence says why; one change above it: the order is measured as before.
  for (double coarse_change : {4e-14, 1e-9, 2e-9}) {
    ConvergeModel a = coarse, b = coarse;
    a.slices = 25;
    b.slices = 100;
    a.checks = {check("a.wx", coarse_change), check("b.wx", 1e-15)};
    b.checks = {check("a.wx", 1e-14), check("b.wx", 3e-15)};
    a.scales = b.scales = {1, 1};
    judge_converge_model(a, 1e-3);
    judge_converge_model(b, 1e-3);
    r.models = {full, a, b};
    converge_finish(r);
    text = format_converge(r);
    INFO(text);
    if (coarse_change <= 1e-9) {
      CHECK_THAT(text, Catch::Contains("slicing order of beam: none to measure (the changes in a.wx") &&
                           Catch::Contains("are rounding and integration noise"));
      CHECK_THAT(text, !Catch::Contains("observed order"));
    } else {
      CHECK_THAT(text, Catch::Contains("observed order") && !Catch::Contains("none to measure"));
    }
  }
}

TEST_CASE("converge: truncating a geometrically stiffened beam keeps the kept modes' rows and "
          "columns of every node's G, and none with no modes (spinup_beam)") {
  const System full = read_scene(test::scene_path("spinup_beam"));
  const std::vector<ModeGroup> g = mode_groups(full);
  REQUIRE(g.size() == 1);
  const int b = g[0].body;
  const FlexBody& ff = *full.bodies[static_cast<std::size_t>(b)].flex;
  REQUIRE(ff.geometric_stiffening);
  for (int keep = 0; keep <= static_cast<int>(g[0].modes.size()); ++keep) {
    CAPTURE(keep);
    const System cut = truncate_modes(full, g, {keep});
    const FlexBody& fc = *cut.bodies[static_cast<std::size_t>(b)].flex;
    CHECK(fc.geometric_stiffening == (keep > 0));
    for (std::size_t i = 0; i < fc.nodes.size(); ++i) {
      if (keep == 0) {
        CHECK(fc.nodes[i].G.size() == 0);
        continue;
      }
      REQUIRE(fc.nodes[i].G.rows() == keep);
      REQUIRE(fc.nodes[i].G.cols() == keep);
      CHECK(fc.nodes[i].G == ff.nodes[i].G.topLeftCorner(keep, keep));
    }
    // Every engine takes the truncated model (0 modes used to reach an engine with a full-size G).
    for (const std::string& engine : engine_names()) {
      CAPTURE(engine);
      auto e = make_engine(engine, cut);
      std::vector<double> x(static_cast<std::size_t>(e->state_size())), xdot(x.size());
      e->pack(TreeState::initial(cut), x.data());
      e->rhs(0.5, x.data(), xdot.data());
      CHECK(std::all_of(xdot.begin(), xdot.end(), [](double v) { return std::isfinite(v); }));
    }
  }
}

TEST_CASE("converge: the verdict is the accuracy asked, each quantity's change relative to its "
          "scale in the full model, not the scene's compare tolerances (issue 24)") {
  System s = read_scene(test::scene_path("hub_flex_array"));
  CompareOptions o;
  o.engines = {{"kane", "kane", {}}};
  std::vector<int> smallest_modes;
  for (double accuracy : {1e-1, 1e-2, 1e-3, 1e-6}) {
    const ConvergeResult r = converge_scene(s, o, accuracy);
    INFO(format_converge(r));
    CHECK(r.accuracy == accuracy);
    int fewest = r.models.front().modes;
    for (const ConvergeModel& m : r.models) {
      if (m.full) continue;
      REQUIRE(m.worst_quantity.rfind("run: ", 0) != 0);
      // The verdict is the largest relative change against the accuracy.
      CHECK(m.passed == (m.worst_relative <= accuracy));
      double worst = 0;
      for (std::size_t i = 0; i < m.checks.size(); ++i)
        if (m.scales[i] > 0 && m.checks[i].status != CheckStatus::Excluded)
          worst = std::max(worst, m.checks[i].error / m.scales[i]);
      CHECK(m.worst_relative == worst);
      if (m.passed && m.slices == 0) fewest = std::min(fewest, m.modes);
    }
    CHECK(r.models[static_cast<std::size_t>(r.smallest)].modes == fewest);
    smallest_modes.push_back(fewest);
  }
  // A looser accuracy needs no more modes, and this scene's answers differ: one x-plane mode
  // changes the array's rate by 7.6e-2 of its scale, two the hub's by 1.9e-3, three by rounding only.
  CHECK(smallest_modes[0] <= smallest_modes[1]);
  CHECK(smallest_modes[1] <= smallest_modes[2]);
  CHECK(smallest_modes[2] <= smallest_modes[3]);
  CHECK(smallest_modes[0] < smallest_modes[2]);

  // A w component's scale is its body's largest |w| in the full model's run (study.hpp's metric).
  const ConvergeResult r = converge_scene(s, o, 1e-3);
  const RunResult& full = r.models.front().run.result;
  const int wx = full.column("hub.wx");
  double w_max = 0;
  for (std::size_t k = 0; k < full.rows(); ++k) {
    const double x = full.at(k, static_cast<std::size_t>(wx)), y = full.at(k, static_cast<std::size_t>(wx + 1)),
                 z = full.at(k, static_cast<std::size_t>(wx + 2));
    w_max = std::max(w_max, std::sqrt(x * x + y * y + z * z));
  }
  const ConvergeModel& some = r.models[1];
  bool seen = false;
  for (std::size_t i = 0; i < some.checks.size(); ++i)
    if (some.checks[i].quantity == "hub.wz") {
      CHECK(some.scales[i] == Approx(w_max).epsilon(1e-12));
      seen = true;
    }
  CHECK(seen);

  // The scene's compare tolerances (the engines' agreement) do not move the verdict.
  System loose = s;
  loose.compare.default_tolerance = {1e-1, 1e-1};
  loose.compare.tolerances.clear();
  const ConvergeResult again = converge_scene(loose, o, 1e-3);
  REQUIRE(again.models.size() == r.models.size());
  for (std::size_t i = 0; i < r.models.size(); ++i) {
    CHECK(again.models[i].passed == r.models[i].passed);
    CHECK(again.models[i].worst_relative == r.models[i].worst_relative);
  }
  CHECK(again.smallest == r.smallest);
}

TEST_CASE("converge: a model that keeps no modes of a scene whose every joint is prescribed runs "
          "(no state to integrate), in every engine (issue 24)") {
  const System s = read_scene(test::scene_path("spinup_beam_linear"));
  for (const char* engine : {"kane", "lagrange", "newton-euler"}) {
    CompareOptions o;
    o.engines = {{engine, engine, {}}};
    const ConvergeResult r = converge_scene(s, o, 1e-3);
    INFO(format_converge(r));
    REQUIRE(r.models.size() > 1);
    CHECK(r.models[1].modes == 0);
    CHECK(r.models[1].worst_quantity.rfind("run: ", 0) == std::string::npos);
    // A rigid beam is not the spinning linear beam: the rigid model changes the answer.
    CHECK_FALSE(r.models[1].passed);
  }
}

TEST_CASE("crossdyn converge --accuracy: said in the output with what it is not, refused outside "
          "(0, 1) naming the option (issue 24)") {
  auto r = test::run_crossdyn("converge hub_nodal_panel -q --accuracy 1e-2");
  CHECK(r.status == 0);
  CHECK_THAT(r.output, Catch::Contains("accuracy 1.00e-02 (--accuracy)") &&
                           Catch::Contains("compare tolerances are for checking that the engines agree") &&
                           Catch::Contains("smallest model within the accuracy 1.00e-02"));
  for (const char* bad : {"0", "1", "-1e-3", "nan", "inf", "2"}) {
    r = test::run_crossdyn(std::string("converge hub_nodal_panel -q --accuracy ") + bad);
    INFO(bad << ": " << r.output);
    CHECK(r.status == 2);
    CHECK_THAT(r.output, Catch::Contains("--accuracy"));
  }
}
