// validate_flex (core/flex/flex_model.hpp): one case per class of bad modal data, each message
// checked; and the helpers it is built from.
#include <catch2/catch.hpp>

#include <cmath>
#include <functional>
#include <string>

#include "core/errors.hpp"
#include "core/flex/beam.hpp"
#include "core/flex/flex_model.hpp"
#include "core/scene/scene.hpp"
#include "tests/support/close.hpp"

using namespace crossdyn;
using namespace crossdyn::flex;

namespace {

// A small valid body: a 4-slice free-free beam along z, one mode per plane (qx1, qy1),
// 10 nodes (bottom, the massless stations slice1..4, the mass points gauss1..4, top), K
// diagonal, D zero.
FlexBody small_body() {
  BeamSpec s;
  s.length = 4;
  s.axis = 2;
  s.mass_per_length = 10;
  s.section = {1, 1, 0};
  s.bending = {BeamPlane{1, 50}, BeamPlane{1, 50}, BeamPlane{}};
  s.slices = 4;
  return make_beam(s, "b").flex;
}

std::string message_of(const std::function<void(FlexBody&)>& change) {
  FlexBody f = small_body();
  change(f);
  try {
    validate_flex(f, "body 'beam'");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST_CASE("validate_flex accepts the generator's bodies and a body with no modes") {
  CHECK(message_of([](FlexBody&) {}) == "(no error)");
  CHECK(message_of([](FlexBody& f) {
          f.mode_names.clear();
          for (FlexNode& n : f.nodes) {
            n.Phi_B.resize(3, 0);
            n.Psi_B.resize(3, 0);
          }
          f.K.resize(0, 0);
          f.D.resize(0, 0);
        }) == "(no error)");
}

TEST_CASE("validate_flex: bad mode names") {
  CHECK(message_of([](FlexBody& f) { f.mode_names[1] = "qx1"; }) ==
        "body 'beam': duplicate mode name 'qx1'");
  CHECK(message_of([](FlexBody& f) { f.mode_names[0] = "1q"; }) ==
        "body 'beam': invalid name '1q': use 1 to 64 letters, digits, '_' or '-', starting with a letter");
  CHECK(message_of([](FlexBody& f) { f.mode_names[0] = "q.1"; }) ==
        "body 'beam': invalid name 'q.1': use 1 to 64 letters, digits, '_' or '-', starting with a letter");
  CHECK(message_of([](FlexBody& f) { f.mode_names[0] = std::string(65, 'q'); }) ==
        "body 'beam': invalid name '" + std::string(40, 'q') +
            "...': use 1 to 64 letters, digits, '_' or '-', starting with a letter");
  CHECK(message_of([](FlexBody& f) { f.mode_names[0] = "qx"; }) ==
        "body 'beam': mode name 'qx' clashes with the body's output column <body>.qx");
  CHECK(message_of([](FlexBody& f) { f.mode_names[0] = "wz"; }) ==
        "body 'beam': mode name 'wz' clashes with the body's output column <body>.wz");
  CHECK(message_of([](FlexBody& f) { f.mode_names[0] = "q1_rate"; }) ==
        "body 'beam': mode name 'q1_rate' ends in '_rate', which would clash with a mode's rate "
        "column <body>.<mode>_rate");
}

TEST_CASE("validate_flex: bad nodes") {
  CHECK(message_of([](FlexBody& f) { f.nodes.clear(); }) ==
        "body 'beam': the body has no nodes: at least one node must carry its mass");
  CHECK(message_of([](FlexBody& f) { f.nodes[3].name = "slice1"; }) ==
        "body 'beam': duplicate node name 'slice1'");
  CHECK(message_of([](FlexBody& f) { f.nodes[3].name = "slice 3"; }) ==
        "body 'beam': node: invalid name 'slice 3': use 1 to 64 letters, digits, '_' or '-', "
        "starting with a letter");
  CHECK(message_of([](FlexBody& f) { f.nodes[2].mass = -1; }) ==
        "body 'beam': node 'slice2': mass -1 kg: a node's mass must be finite and >= 0");
  CHECK(message_of([](FlexBody& f) { f.nodes[2].mass = NAN; }) ==
        "body 'beam': node 'slice2': mass nan kg: a node's mass must be finite and >= 0");
  CHECK(message_of([](FlexBody& f) { f.nodes[0].p_BoNi_B.x() = INFINITY; }) ==
        "body 'beam': node 'bottom': position is not finite");
  CHECK(message_of([](FlexBody& f) { f.nodes[1].J_Ni_B(0, 1) = 0.1; }) ==
        "body 'beam': node 'slice1': J: the inertia is not symmetric (entries differ by 0.1)");
  CHECK(message_of([](FlexBody& f) { f.nodes[1].J_Ni_B(0, 0) = -1; }) ==
        "body 'beam': node 'slice1': J: the inertia is not positive semi-definite (principal "
        "moments -1, 0, 0)");
  CHECK(message_of([](FlexBody& f) { f.nodes[1].J_Ni_B = Eigen::Vector3d(1, 1, 3).asDiagonal(); }) ==
        "body 'beam': node 'slice1': J: the inertia is not physically realisable: principal moments "
        "1, 1, 3 break the triangle inequality I1 + I2 >= I3");
  CHECK(message_of([](FlexBody& f) { f.nodes[4].Phi_B.resize(3, 1); }) ==
        "body 'beam': node 'slice4': mode shapes are 3 x 1 and slopes 3 x 2, expected 3 x 2 (one "
        "column per mode)");
  CHECK(message_of([](FlexBody& f) { f.nodes[4].Phi_B(2, 1) = NAN; }) ==
        "body 'beam': node 'slice4': mode 'qy1': shape is not finite");
  CHECK(message_of([](FlexBody& f) { f.nodes.back().Psi_B(0, 0) = INFINITY; }) ==
        "body 'beam': node 'top': mode 'qx1': slope is not finite");
}

TEST_CASE("validate_flex: bad mass distribution") {
  CHECK(message_of([](FlexBody& f) {
          for (FlexNode& n : f.nodes) n.mass = 0;
        }) == "body 'beam': the nodes' total mass is zero: at least one node needs mass");
  CHECK(message_of([](FlexBody& f) {
          for (FlexNode& n : f.nodes) n.p_BoNi_B.x() += 0.5;
        }) ==
        "body 'beam': the nodes' centre of mass is at [0.5, 0, 0] m, not at the body origin (node "
        "positions are from the undeformed CM: sum m_i p_i = 0)");
  CHECK(message_of([](FlexBody& f) {
          for (FlexNode& n : f.nodes) n.J_Ni_B.setZero();
        }) ==
        "body 'beam': the rigid inertia (node sum) is singular, principal moments 0, 53.33333333333333, "
        "53.33333333333333 kg "
        "m^2: the mass lies on a line; give the nodes a rotational inertia J");
}

TEST_CASE("validate_flex: modes that move no mass or are rigid motions") {
  CHECK(message_of([](FlexBody& f) {
          for (FlexNode& n : f.nodes)
            if (n.mass > 0) n.Phi_B.col(1).setZero();
        }) == "body 'beam': mode 'qy1' moves no mass (its shape is zero at every node with mass)");
  // A rigid translation along y exported as a mode (a common slip with finite-element output).
  CHECK(message_of([](FlexBody& f) {
          for (FlexNode& n : f.nodes) n.Phi_B.col(1) = Eigen::Vector3d::UnitY();
        }).rfind("body 'beam': mode 'qy1' is (nearly) a rigid-body motion of the body or a "
                 "combination of other modes (the mass matrix of rigid motion and modes, scaled to "
                 "unit diagonal, has smallest eigenvalue ", 0) == 0);
  // A rigid rotation about x as a mode: the displacement e_x x p_i. It is a rigid motion of the
  // model only when the nodes have no rotational inertia about x (J_i does not turn with the
  // modes, docs/flexible-bodies.md), as for lumped finite-element masses: here J_i = diag(0, c, c),
  // a realisable inertia (a rod along x) that keeps the body's inertia positive definite.
  const auto rotation_mode = [](double Jxx) {
    return message_of([Jxx](FlexBody& f) {
      for (FlexNode& n : f.nodes) {
        n.Phi_B.col(0) = Eigen::Vector3d::UnitX().cross(n.p_BoNi_B);
        if (n.mass > 0) n.J_Ni_B = Eigen::Vector3d(Jxx, 0.1, 0.1).asDiagonal();
      }
    });
  };
  CHECK(rotation_mode(0.1) == "(no error)");  // J_xx > 0: the mode does not move J, not rigid
  const std::string rot = rotation_mode(0);
  INFO(rot);
  CHECK(rot.find("mode 'qx1' is (nearly) a rigid-body motion") != std::string::npos);
  CHECK(rot.find("remove rigid-body modes from the data") != std::string::npos);
  // Two copies of one mode.
  CHECK(message_of([](FlexBody& f) {
          for (FlexNode& n : f.nodes) n.Phi_B.col(1) = n.Phi_B.col(0);
        }).find("is (nearly) a rigid-body motion of the body or a combination of other modes") !=
        std::string::npos);
}

TEST_CASE("validate_flex: K and D sizes, finiteness, symmetry, definiteness") {
  CHECK(message_of([](FlexBody& f) { f.K.resize(1, 1); }) ==
        "body 'beam': K is 1 x 1 but the body has 2 modes");
  CHECK(message_of([](FlexBody& f) { f.D.resize(2, 3); }) ==
        "body 'beam': D is 2 x 3 but the body has 2 modes");
  CHECK(message_of([](FlexBody& f) { f.K(0, 1) = NAN; }) == "body 'beam': K(qx1, qy1) is not finite");
  CHECK(message_of([](FlexBody& f) { f.K(1, 0) = 0.5; }) ==
        "body 'beam': K is not symmetric: K(qy1, qx1) = 0.5 but K(qx1, qy1) = 0");
  CHECK(message_of([](FlexBody& f) {
          f.K(0, 1) = f.K(1, 0) = 2 * f.K(0, 0);
        }).rfind("body 'beam': K is not positive semi-definite: eigenvalue -", 0) == 0);
  CHECK(message_of([](FlexBody& f) { f.D(1, 1) = -1e-3; }) ==
        "body 'beam': D is not positive semi-definite: eigenvalue -0.001 (the largest is 0), its "
        "eigenvector mostly along mode 'qy1'");
  // Within the tolerance: a rounding-level negative eigenvalue relative to the largest passes.
  CHECK(message_of([](FlexBody& f) { f.K(1, 1) = -1e-12 * f.K(0, 0); }) == "(no error)");
}

TEST_CASE("validate_flex: size limits") {
  CHECK(message_of([](FlexBody& f) {
          f.mode_names.resize(kMaxModes + 1, "m");
        }) == "body 'beam': 1001 modes: at most 1000 are accepted");
  CHECK(message_of([](FlexBody& f) { f.nodes.resize(kMaxNodes + 1, f.nodes[1]); }) ==
        "body 'beam': 200001 nodes: at most 200000 are accepted");
}

TEST_CASE("inertia_problem accepts realisable inertias at the triangle limit and rejects others") {
  CHECK(!inertia_problem(Eigen::Vector3d(1, 1, 2).asDiagonal()));  // a thin disc: I1 + I2 = I3
  CHECK(!inertia_problem(Eigen::Matrix3d::Zero()));                // a point mass
  CHECK(inertia_problem(Eigen::Vector3d(1, 1, 2.001).asDiagonal()));
}

namespace {

// The small body with every mode dropped (a rigid body made of nodes) and geometric stiffening
// switched on, then `change` applied.
std::string stiffened_without_modes(const std::function<void(FlexBody&)>& change) {
  return message_of([&change](FlexBody& f) {
    f.mode_names.clear();
    for (FlexNode& n : f.nodes) {
      n.Phi_B.resize(3, 0);
      n.Psi_B.resize(3, 0);
    }
    f.K.resize(0, 0);
    f.D.resize(0, 0);
    f.geometric_stiffening = true;
    change(f);
  });
}

// A spinning clamped beam (scenarios/spinup_beam.yaml, shorter) whose `bending` block is given.
std::string stiffened_beam_scene(const std::string& boundary, const std::string& bending) {
  return "name: s\n"
         "bodies:\n"
         "  - name: hub\n"
         "    mass: 100 kg\n"
         "    inertia: [10, 10, 10]\n"
         "  - name: beam\n"
         "    flexible:\n"
         "      beam:\n"
         "        length: 10 m\n"
         "        axis: x\n"
         "        mass_per_length: 1.2\n"
         "        section: [0, 0.02 m, 0.02 m]\n" +
         bending +
         "        boundary: " + boundary + "\n"
         "        slices: 10\n"
         "        geometric_stiffening: true\n"
         "joints:\n"
         "  - name: spin\n"
         "    type: revolute\n"
         "    child: hub\n"
         "    parent_point: [0, 0, 0]\n"
         "    child_point: [0, 0, 0]\n"
         "    axis: [0, 0, 1]\n"
         "    prescribed: {profile: spin-up, rate: 10 rad/s, ramp_time: 15 s}\n"
         "  - name: root\n"
         "    type: fixed\n"
         "    parent: hub\n"
         "    parent_point: [0, 0, 0]\n"
         "    child: beam\n"
         "    child_node: bottom\n"
         "run:\n"
         "  duration: 0.1 s\n"
         "  output_step: 0.05 s\n";
}

std::string scene_message(const std::string& text) {
  try {
    read_scene_text(text, "s.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

// The engines size their stiffening terms by the modes; a 0-mode stiffened body reached the
// Kane engine (a segfault) because validate_flex accepted it. Every way to build one is refused:
// the FlexBody check itself (whatever G and e hold), the beam generator and the scene reader at
// the key, for both clamped ends and every way of giving no modes.
TEST_CASE("class: geometric stiffening without modes is refused by validate_flex and the beam generator and the scene reader") {
  const std::string refused =
      "body 'beam': geometric stiffening needs modes: the body has none, so there is no "
      "deformation to foreshorten (switch geometric stiffening off: a body without modes is rigid)";
  CHECK(stiffened_without_modes([](FlexBody&) {}) == refused);  // no G at all
  CHECK(stiffened_without_modes([](FlexBody& f) {
          for (FlexNode& n : f.nodes) {
            n.G.resize(0, 0);
            n.e_B = Eigen::Vector3d::UnitZ();
          }
        }) == refused);  // G 0 x 0 with a unit e: every per-node check passes, the body does not
  CHECK(stiffened_without_modes([](FlexBody& f) { f.geometric_stiffening = false; }) ==
        "(no error)");  // the same body without stiffening is the rigid body it is
  // The beam generator: no bending block, both planes at 0 modes, for both clamped ends.
  for (BeamBoundary b : {BeamBoundary::ClampedBottom, BeamBoundary::ClampedTop}) {
    BeamSpec s;
    s.length = 4;
    s.axis = 2;
    s.mass_per_length = 10;
    s.section = {1, 1, 0};
    s.boundary = b;
    s.slices = 4;
    s.geometric_stiffening = true;
    CHECK_THROWS_WITH(make_beam(s, "beam"), Catch::Contains("geometric_stiffening") &&
                                                Catch::Contains("needs bending modes"));
    s.bending = {BeamPlane{0, 50}, BeamPlane{0, 50}, BeamPlane{}};
    CHECK_THROWS_WITH(make_beam(s, "beam"), Catch::Contains("needs bending modes"));
  }
  // The scene reader names the file, the line of the key and the key.
  for (const std::string boundary : {"clamped-bottom", "clamped-top"})
    for (const std::string& bending :
         {std::string(), std::string("        bending: {}\n"),
          std::string("        bending:\n          y: {modes: 0}\n          z: {modes: 0, EI: 1}\n")}) {
      INFO(boundary << "\n" << bending);
      const std::string m = scene_message(stiffened_beam_scene(boundary, bending));
      INFO(m);
      CHECK(m.rfind("s.yaml:", 0) == 0);
      CHECK(m.find("geometric_stiffening") != std::string::npos);
      CHECK(m.find("needs bending modes") != std::string::npos);
    }
  // With a mode the same scene is read (the test above is not refusing every stiffened beam).
  CHECK(scene_message(stiffened_beam_scene("clamped-bottom",
                                           "        bending:\n          y: {modes: 1, EI: 14000}\n")) ==
        "(no error)");
}
