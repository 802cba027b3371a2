// Field-by-field, bit-exact comparison of two Systems, for the scene reader's round-trip property
// read_scene_text(write_scene_text(s)) == s (tests/scene/test_scene.cpp, fuzz/scene_fuzzer.cpp).
// Exact equality is intended here: the writer prints every double in its shortest round-trip form,
// so reading it back must give the same bits (this is not a comparison of computed results).
#pragma once

#include <sstream>
#include <string>

#include "core/system.hpp"

namespace crossdyn::test {

// "" when a and b are equal, else the first difference found ("joints[2].axis_P").
inline std::string system_difference(const System& a, const System& b) {
  std::ostringstream why;
  auto eq = [&why](const std::string& what, bool same) {
    if (!same && why.tellp() == 0) why << what;
    return same;
  };
  auto q_eq = [](const Eigen::Quaterniond& x, const Eigen::Quaterniond& y) {
    return x.coeffs() == y.coeffs();
  };
  auto pc1 = [](const PiecewiseConstant<1>& x, const PiecewiseConstant<1>& y) {
    return x.times == y.times && x.values == y.values;
  };
  auto pc2 = [](const PiecewiseConstant<2>& x, const PiecewiseConstant<2>& y) {
    return x.times == y.times && x.values == y.values;
  };
  auto pc3 = [](const PiecewiseConstant<3>& x, const PiecewiseConstant<3>& y) {
    return x.times == y.times && x.values == y.values;
  };
  eq("name", a.name == b.name);
  eq("file", a.file == b.file);
  eq("description", a.description == b.description);
  eq("source", a.source == b.source);
  eq("zero_linear_momentum", a.zero_linear_momentum == b.zero_linear_momentum);
  eq("analytic", a.analytic == b.analytic);
  {
    const Environment& x = a.environment;
    const Environment& y = b.environment;
    eq("environment", x.kind == y.kind && x.g_N == y.g_N && x.mu == y.mu &&
                          x.body_radius == y.body_radius && x.radius == y.radius &&
                          x.inclination == y.inclination && x.raan == y.raan &&
                          x.latitude0 == y.latitude0);
  }
  if (eq("bodies.size", a.bodies.size() == b.bodies.size()))
    for (std::size_t i = 0; i < a.bodies.size(); ++i) {
      const Body& x = a.bodies[i];
      const Body& y = b.bodies[i];
      const std::string p = "bodies[" + std::to_string(i) + "].";
      eq(p + "name", x.name == y.name);
      eq(p + "mass", x.mass == y.mass);
      eq(p + "I_BBo_B", x.I_BBo_B == y.I_BBo_B);
      if (eq(p + "flex", x.flex.has_value() == y.flex.has_value()) && x.flex) {
        const FlexBody& f = *x.flex;
        const FlexBody& g = *y.flex;
        eq(p + "flex.mode_names", f.mode_names == g.mode_names);
        eq(p + "flex.K", f.K.rows() == g.K.rows() && f.K.cols() == g.K.cols() && f.K == g.K);
        eq(p + "flex.D", f.D.rows() == g.D.rows() && f.D.cols() == g.D.cols() && f.D == g.D);
        eq(p + "flex.origin", f.origin == g.origin);
        eq(p + "flex.scene_form", f.scene_form == g.scene_form);
        eq(p + "flex.geometric_stiffening", f.geometric_stiffening == g.geometric_stiffening);
        if (eq(p + "flex.nodes.size", f.nodes.size() == g.nodes.size()))
          for (std::size_t k = 0; k < f.nodes.size(); ++k) {
            const FlexNode& u = f.nodes[k];
            const FlexNode& v = g.nodes[k];
            const std::string q = p + "flex.nodes[" + std::to_string(k) + "].";
            eq(q + "name", u.name == v.name);
            eq(q + "mass", u.mass == v.mass);
            eq(q + "p_BoNi_B", u.p_BoNi_B == v.p_BoNi_B);
            eq(q + "J_Ni_B", u.J_Ni_B == v.J_Ni_B);
            eq(q + "Phi_B", u.Phi_B.cols() == v.Phi_B.cols() && u.Phi_B == v.Phi_B);
            eq(q + "Psi_B", u.Psi_B.cols() == v.Psi_B.cols() && u.Psi_B == v.Psi_B);
            eq(q + "e_B", u.e_B == v.e_B);
            eq(q + "G", u.G.rows() == v.G.rows() && u.G.cols() == v.G.cols() && u.G == v.G);
          }
      }
      eq(p + "torque_frame", x.torque_frame == y.torque_frame);
      eq(p + "torque", pc3(x.torque, y.torque));
    }
  if (eq("joints.size", a.joints.size() == b.joints.size()))
    for (std::size_t i = 0; i < a.joints.size(); ++i) {
      const Joint& x = a.joints[i];
      const Joint& y = b.joints[i];
      const std::string p = "joints[" + std::to_string(i) + "].";
      eq(p + "name", x.name == y.name);
      eq(p + "type", x.type == y.type);
      eq(p + "parent", x.parent == y.parent);
      eq(p + "child", x.child == y.child);
      eq(p + "p_PoJ_P", x.p_PoJ_P == y.p_PoJ_P);
      eq(p + "p_CoJ_C", x.p_CoJ_C == y.p_CoJ_C);
      eq(p + "parent_node", x.parent_node == y.parent_node);
      eq(p + "child_node", x.child_node == y.child_node);
      eq(p + "axis_P", x.axis_P == y.axis_P);
      eq(p + "axis2_P", x.axis2_P == y.axis2_P);
      eq(p + "q_PJ0", q_eq(x.q_PJ0, y.q_PJ0));
      eq(p + "stiffness", x.stiffness == y.stiffness);
      eq(p + "neutral_angle", x.neutral_angle == y.neutral_angle);
      eq(p + "damping", x.damping == y.damping);
      eq(p + "motor_revolute", pc1(x.motor_revolute, y.motor_revolute));
      eq(p + "motor_spherical", pc3(x.motor_spherical, y.motor_spherical));
      eq(p + "stiffness2", x.stiffness2 == y.stiffness2);
      eq(p + "neutral_angle2", x.neutral_angle2 == y.neutral_angle2);
      eq(p + "damping2", x.damping2 == y.damping2);
      eq(p + "motor_universal", pc2(x.motor_universal, y.motor_universal));
      eq(p + "angle2_0", x.angle2_0 == y.angle2_0);
      eq(p + "rate2_0", x.rate2_0 == y.rate2_0);
      eq(p + "prescribed", x.prescribed.has_value() == y.prescribed.has_value() &&
                               (!x.prescribed || (x.prescribed->profile == y.prescribed->profile &&
                                                  x.prescribed->rate == y.prescribed->rate &&
                                                  x.prescribed->travel == y.prescribed->travel &&
                                                  x.prescribed->ramp_time == y.prescribed->ramp_time)));
      eq(p + "angle0", x.angle0 == y.angle0);
      eq(p + "rate0", x.rate0 == y.rate0);
      eq(p + "q_J0", q_eq(x.q_J0, y.q_J0));
      eq(p + "w_PC_C0", x.w_PC_C0 == y.w_PC_C0);
      eq(p + "p_NoBo_N0", x.p_NoBo_N0 == y.p_NoBo_N0);
      eq(p + "q_NB0", q_eq(x.q_NB0, y.q_NB0));
      eq(p + "w_NB_B0", x.w_NB_B0 == y.w_NB_B0);
      eq(p + "v_NBo_N0", x.v_NBo_N0 == y.v_NBo_N0);
    }
  eq("run.duration", a.run.duration == b.run.duration);
  eq("run.output_step", a.run.output_step == b.run.output_step);
  eq("run.integrator", a.run.integrator == b.run.integrator);
  eq("run.rtol", a.run.rtol == b.run.rtol);
  eq("run.atol", a.run.atol == b.run.atol);
  eq("run.dt", a.run.dt == b.run.dt);
  eq("compare.default", a.compare.default_tolerance.atol == b.compare.default_tolerance.atol &&
                            a.compare.default_tolerance.rtol == b.compare.default_tolerance.rtol);
  if (eq("compare.tolerances.size", a.compare.tolerances.size() == b.compare.tolerances.size()))
    for (std::size_t i = 0; i < a.compare.tolerances.size(); ++i) {
      const auto& [qa, ta] = a.compare.tolerances[i];
      const auto& [qb, tb] = b.compare.tolerances[i];
      eq("compare.tolerances[" + std::to_string(i) + "]",
         qa == qb && ta.atol == tb.atol && ta.rtol == tb.rtol);
    }
  eq("compare.excluded", a.compare.excluded == b.compare.excluded);
  return why.str();
}

}  // namespace crossdyn::test
