// Scenes of issue 13 (prescribed motion, geometric stiffening) as text, for the Newton-Euler
// tests: the scan platform, Kane, Ryan and Banerjee's spin-up beam (with or without geometric
// stiffening), and variations built from them. Read with read_scene_text.
#pragma once

#include <string>

namespace crossdyn::test::ne {

// A free bus carrying a platform on a prescribed revolute joint (the scan_platform scene).
inline std::string scan_platform_text(double rate = 2.0, double ramp = 5.0) {
  return R"(name: scan_platform_test
bodies:
  - name: bus
    mass: 800 kg
    inertia: [600, 500, 400]
  - name: platform
    mass: 60 kg
    inertia: [2.6, 5.8, 6.8]
joints:
  - name: base
    type: free
    child: bus
    initial:
      angular_velocity: [0.01, -0.02, 0.005]
  - name: scan
    type: revolute
    parent: bus
    parent_point: [0.5, 0, 0]
    child: platform
    child_point: [-0.3, 0, 0]
    axis: [1, 0, 0]
    offset: {axis: [0, 1, 0], angle: 10 deg}
    prescribed: {profile: spin-up, rate: )" +
         std::to_string(rate) + R"( rad/s, ramp_time: )" + std::to_string(ramp) + R"( s}
run:
  duration: 10 s
  output_step: 0.05 s
  integrator: dop853
  rtol: 1e-12
  atol: 1e-12
)";
}

// A hub turned by a prescribed base joint to N, carrying a clamped beam (the spinup_beam scenes:
// L = 10 m, rho A = 1.2 kg/m, EI = 14000 N m^2, three in-plane modes along y, 50 slices).
inline std::string spinup_beam_text(bool stiffening, double rate = 10.0, double ramp = 15.0) {
  return R"(name: spinup_beam_test
bodies:
  - name: hub
    mass: 100 kg
    inertia: [10, 10, 10]
  - name: beam
    flexible:
      beam:
        length: 10 m
        axis: x
        mass_per_length: 1.2
        section: [0, 0.02 m, 0.02 m]
        bending:
          y: {modes: 3, EI: 14000}
        boundary: clamped-bottom
        slices: 50
        geometric_stiffening: )" +
         std::string(stiffening ? "true" : "false") + R"(
joints:
  - name: spin
    type: revolute
    child: hub
    parent_point: [0, 0, 0]
    child_point: [0, 0, 0]
    axis: [0, 0, 1]
    prescribed: {profile: spin-up, rate: )" +
         std::to_string(rate) + R"( rad/s, ramp_time: )" + std::to_string(ramp) + R"( s}
  - name: root
    type: fixed
    parent: hub
    parent_point: [0, 0, 0]
    child: beam
    child_node: bottom
run:
  duration: 20 s
  output_step: 0.05 s
  integrator: dop853
  rtol: 1e-12
  atol: 1e-12
)";
}

// A free hub spinning about z with a clamped, geometrically stiffened beam at 0.5 m from its
// axis: no prescribed motion, nothing external (E and H are conserved).
inline std::string free_spinning_beam_text() {
  return R"(name: free_spinning_beam_test
bodies:
  - name: hub
    mass: 50 kg
    inertia: [20, 20, 30]
  - name: beam
    flexible:
      beam:
        length: 4 m
        axis: x
        mass_per_length: 1.2
        section: [0, 0.02 m, 0.02 m]
        bending:
          y: {modes: 3, EI: 2000}
          z: {modes: 2, EI: 3000}
        boundary: clamped-bottom
        slices: 20
        geometric_stiffening: true
joints:
  - name: base
    type: free
    child: hub
    initial:
      angular_velocity: [0.05, -0.1, 3]
  - name: root
    type: fixed
    parent: hub
    parent_point: [0.5, 0, 0]
    child: beam
    child_node: bottom
run:
  duration: 5 s
  output_step: 0.05 s
  integrator: dop853
  rtol: 1e-12
  atol: 1e-12
)";
}

// free_spinning_beam_text() with a rigid tip body on a revolute joint at the beam's free end
// (node `top`, where the foreshortening G is largest): a spring hinge, or a prescribed one.
inline std::string beam_with_tip_text(bool prescribed) {
  std::string t = free_spinning_beam_text();
  t.replace(t.find("joints:"), 7, R"(  - name: tip
    mass: 2 kg
    inertia: [0.02, 0.03, 0.04]
joints:)");
  t.replace(t.find("run:"), 4, std::string(R"(  - name: wrist
    type: revolute
    parent: beam
    parent_node: top
    child: tip
    child_point: [-0.2, 0.05, 0]
    axis: [0, 1, 1]
)") + (prescribed ? "    prescribed: {profile: spin-up, rate: 4 rad/s, ramp_time: 2 s}\n"
                  : "    spring: {stiffness: 30}\n    initial: {angle: 0.4, rate: -1}\n") +
                           "run:");
  return t;
}

}  // namespace crossdyn::test::ne
