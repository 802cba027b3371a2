// Scene writer: System => scene text (scene.hpp).
//
// Every number is SI in its shortest round-trip form (std::to_chars), so that
// read_scene_text(write_scene_text(s)) == s field by field, bit for bit. Every key is written
// through its schema row (Out::key): the writer cannot write a key the schema does not hold, nor a
// reader convenience (center_of_mass: the System is already in the CM frame). An angle whose
// magnitude is above 2 pi is written with " rad", so that reading it back draws no warning.
// tests/scene/test_scene.cpp checks that the rich scene's written form holds every written key.
// A flexible body is written as the `flexible:` block it was read from (FlexBody::scene_form), a
// joint at a node by the node's name.
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <numbers>
#include <stdexcept>

#include "core/scene/scene.hpp"
#include "core/scene/schema.hpp"
#include "core/scene/text.hpp"

namespace crossdyn {
namespace {

using scene::shortest;

class Out {
 public:
  Out() { out_.SetIndent(2); }
  YAML::Emitter& yaml() { return out_; }

  // Emits the key of schema row `path` (for joint types `joints`) and readies its value.
  YAML::Emitter& key(std::string_view path, unsigned joints = scene::kAnyJoint) {
    const scene::Key* k = scene::find(path, joints);
    if (k == nullptr || !k->written)
      throw std::logic_error("scene writer: '" + std::string(path) + "' is not a written key");
    const std::size_t dot = path.rfind('.');
    const std::string name(dot == std::string_view::npos ? path : path.substr(dot + 1));
    return out_ << YAML::Key << name << YAML::Value;
  }

  // A number of the row's dimension: SI, bare; an angle above a full turn with " rad".
  void number(double x, const scene::Key* row = nullptr) {
    const bool rad =
        row && row->dimension == units::Dimension::Angle && std::abs(x) > 2 * std::numbers::pi;
    out_ << shortest(x) + (rad ? " rad" : "");
  }
  void number(std::string_view path, double x, unsigned joints = scene::kAnyJoint) {
    key(path, joints);
    number(x, scene::find(path, joints));
  }

  template <typename V>
  void flow(const V& v) {
    out_ << YAML::Flow << YAML::BeginSeq;
    for (Eigen::Index i = 0; i < v.size(); ++i) number(v[i]);
    out_ << YAML::EndSeq;
  }
  void quaternion(const Eigen::Quaterniond& q) {
    flow(Eigen::Vector4d(q.w(), q.x(), q.y(), q.z()));
  }

  // A profile under `path` ("joints[].motor.profile").
  template <int D>
  void profile(std::string_view path, const PiecewiseConstant<D>& p, unsigned joints) {
    key(path, joints);
    const std::string item = std::string(path) + "[]";
    out_ << YAML::BeginSeq;
    for (std::size_t k = 0; k < p.times.size(); ++k) {
      out_ << YAML::Flow << YAML::BeginMap;
      number(item + ".t", p.times[k], joints);
      key(item + ".value", joints);
      if constexpr (D == 1)
        number(p.values[k][0]);
      else
        flow(p.values[k]);
      out_ << YAML::EndMap;
    }
    out_ << YAML::EndSeq;
  }

 private:
  YAML::Emitter out_;
};

bool is_identity(const Eigen::Quaterniond& q) {
  return q.w() == 1 && q.x() == 0 && q.y() == 0 && q.z() == 0;
}

void write_body(Out& o, const Body& b) {
  YAML::Emitter& y = o.yaml();
  y << YAML::BeginMap;
  o.key("bodies[].name") << b.name;
  o.number("bodies[].mass", b.mass);
  o.key("bodies[].inertia");
  const Eigen::Matrix3d& I = b.I_BBo_B;
  if (I(0, 1) == 0 && I(0, 2) == 0 && I(1, 2) == 0)
    o.flow(Eigen::Vector3d(I(0, 0), I(1, 1), I(2, 2)));
  else
    o.flow((Eigen::Matrix<double, 6, 1>() << I(0, 0), I(1, 1), I(2, 2), I(0, 1), I(0, 2), I(1, 2))
               .finished());
  if (b.flex) {
    // The block as the reader read it, in its canonical form (flex_block.hpp): the reader builds
    // the same FlexBody from it again (the beam generator is deterministic; a nodal data file is
    // read again, so the written scene must be read from the same folder). Mass and inertia are
    // written too: they are the node sums, so the reader's agreement check passes exactly.
    if (b.flex->scene_form.empty())
      throw std::logic_error("scene writer: flexible body '" + b.name +
                             "' was not read from a scene (no scene form to write)");
    o.key("bodies[].flexible") << YAML::Load(b.flex->scene_form);
  }
  if (!b.torque.empty()) {
    o.key("bodies[].torque") << YAML::BeginMap;
    o.key("bodies[].torque.frame")
        << (b.torque_frame == Body::Frame::Inertial ? "inertial" : "body");
    o.profile("bodies[].torque.profile", b.torque, scene::kAnyJoint);
    y << YAML::EndMap;
  }
  y << YAML::EndMap;
}

void write_initial(Out& o, const System& s, const Joint& j, unsigned bit) {
  YAML::Emitter& y = o.yaml();
  switch (j.type) {
    case JointType::Free:
      o.key("joints[].initial", bit) << YAML::BeginMap;
      o.key("joints[].initial.position", bit);
      o.flow(j.p_NoBo_N0);
      o.key("joints[].initial.attitude", bit);
      o.quaternion(j.q_NB0);
      o.key("joints[].initial.angular_velocity", bit);
      o.flow(j.w_NB_B0);
      if (!s.zero_linear_momentum) {
        o.key("joints[].initial.velocity", bit);
        o.flow(j.v_NBo_N0);
      }
      y << YAML::EndMap;
      break;
    case JointType::Revolute:
      o.key("joints[].initial", bit) << YAML::Flow << YAML::BeginMap;
      o.number("joints[].initial.angle", j.angle0, bit);
      if (!j.prescribed) o.number("joints[].initial.rate", j.rate0, bit);
      y << YAML::EndMap;
      break;
    case JointType::Prismatic:
      o.key("joints[].initial", bit) << YAML::Flow << YAML::BeginMap;
      o.number("joints[].initial.position", j.angle0, bit);
      if (!j.prescribed) o.number("joints[].initial.rate", j.rate0, bit);
      y << YAML::EndMap;
      break;
    case JointType::Universal:
      o.key("joints[].initial", bit) << YAML::BeginMap;
      o.key("joints[].initial.angle", bit);
      o.flow(Eigen::Vector2d(j.angle0, j.angle2_0));
      o.key("joints[].initial.rate", bit);
      o.flow(Eigen::Vector2d(j.rate0, j.rate2_0));
      y << YAML::EndMap;
      break;
    case JointType::Spherical:
      o.key("joints[].initial", bit) << YAML::BeginMap;
      o.key("joints[].initial.attitude", bit);
      o.quaternion(j.q_J0);
      o.key("joints[].initial.angular_velocity", bit);
      o.flow(j.w_PC_C0);
      y << YAML::EndMap;
      break;
    case JointType::Fixed:
      break;
  }
}

void write_joint(Out& o, const System& s, const Joint& j) {
  YAML::Emitter& y = o.yaml();
  const scene::JointTypeInfo& type = scene::joint_type(j.type);
  const unsigned bit = type.bit;
  auto body_name = [&s](int b) { return s.bodies.at(static_cast<std::size_t>(b)).name; };
  y << YAML::BeginMap;
  o.key("joints[].name", bit) << j.name;
  o.key("joints[].type", bit) << std::string(type.name);
  if (j.type != JointType::Free && j.parent >= 0)
    o.key("joints[].parent", bit) << body_name(j.parent);
  o.key("joints[].child", bit) << body_name(j.child);
  if (j.type != JointType::Free) {
    auto node_name = [&s](int b, int node) {
      return s.bodies.at(static_cast<std::size_t>(b)).flex->nodes.at(static_cast<std::size_t>(node))
          .name;
    };
    if (j.parent_node >= 0) {
      o.key("joints[].parent_node", bit) << node_name(j.parent, j.parent_node);
    } else {
      o.key("joints[].parent_point", bit);
      o.flow(j.p_PoJ_P);
    }
    if (j.child_node >= 0) {
      o.key("joints[].child_node", bit) << node_name(j.child, j.child_node);
    } else {
      o.key("joints[].child_point", bit);
      o.flow(j.p_CoJ_C);
    }
    if (!is_identity(j.q_PJ0)) {
      o.key("joints[].offset", bit);
      o.quaternion(j.q_PJ0);
    }
  }
  const bool universal = j.type == JointType::Universal, prismatic = j.type == JointType::Prismatic;
  const bool axial = j.type == JointType::Revolute || prismatic;
  if (axial || universal) {
    o.key("joints[].axis", bit);
    o.flow(j.axis_P);
  }
  if (universal) {
    o.key("joints[].axis2", bit);
    o.flow(j.axis2_P);
  }
  if (axial && j.prescribed) {
    const bool deploy = j.prescribed->profile == PrescribedMotion::Profile::Deploy;
    o.key("joints[].prescribed", bit) << YAML::Flow << YAML::BeginMap;
    o.key("joints[].prescribed.profile", bit) << (deploy ? "deploy" : "spin-up");
    if (deploy)
      o.number("joints[].prescribed.travel", j.prescribed->travel, bit);
    else
      o.number("joints[].prescribed.rate", j.prescribed->rate, bit);
    o.number("joints[].prescribed.ramp_time", j.prescribed->ramp_time, bit);
    y << YAML::EndMap;
  }
  if (j.type != JointType::Free && j.type != JointType::Fixed) {
    const bool neutral = axial ? j.neutral_angle != 0 : universal && (j.neutral_angle != 0 || j.neutral_angle2 != 0);
    if (j.stiffness != 0 || j.stiffness2 != 0 || neutral) {
      o.key("joints[].spring", bit) << YAML::Flow << YAML::BeginMap;
      if (universal) {
        o.key("joints[].spring.stiffness", bit);
        o.flow(Eigen::Vector2d(j.stiffness, j.stiffness2));
        o.key("joints[].spring.neutral_angle", bit);
        o.flow(Eigen::Vector2d(j.neutral_angle, j.neutral_angle2));
      } else {
        o.number("joints[].spring.stiffness", j.stiffness, bit);
        if (axial)
          o.number(prismatic ? "joints[].spring.neutral_position" : "joints[].spring.neutral_angle",
                   j.neutral_angle, bit);
      }
      y << YAML::EndMap;
    }
    if (j.damping != 0 || j.damping2 != 0) {
      o.key("joints[].damper", bit) << YAML::Flow << YAML::BeginMap;
      if (universal) {
        o.key("joints[].damper.damping", bit);
        o.flow(Eigen::Vector2d(j.damping, j.damping2));
      } else {
        o.number("joints[].damper.damping", j.damping, bit);
      }
      y << YAML::EndMap;
    }
    const bool motor = axial       ? !j.motor_revolute.empty()
                       : universal ? !j.motor_universal.empty()
                                   : !j.motor_spherical.empty();
    if (motor) {
      o.key("joints[].motor", bit) << YAML::BeginMap;
      if (axial)
        o.profile("joints[].motor.profile", j.motor_revolute, bit);
      else if (universal)
        o.profile("joints[].motor.profile", j.motor_universal, bit);
      else
        o.profile("joints[].motor.profile", j.motor_spherical, bit);
      y << YAML::EndMap;
    }
  }
  write_initial(o, s, j, bit);
  y << YAML::EndMap;
}

// The environment (issue 28): the orbit by its radius (SI), every angle written.
void write_environment(Out& o, const Environment& e) {
  if (e.none()) return;
  YAML::Emitter& y = o.yaml();
  o.key("environment") << YAML::BeginMap;
  if (e.uniform()) {
    o.key("environment.gravity");
    o.flow(e.g_N);
  } else {
    o.key("environment.central_body") << YAML::BeginMap;
    o.number("environment.central_body.mu", e.mu);
    if (e.body_radius > 0) o.number("environment.central_body.radius", e.body_radius);
    y << YAML::EndMap;
    o.key("environment.orbit") << YAML::BeginMap;
    o.number("environment.orbit.radius", e.radius);
    o.number("environment.orbit.inclination", e.inclination);
    o.number("environment.orbit.raan", e.raan);
    o.number("environment.orbit.argument_of_latitude", e.latitude0);
    y << YAML::EndMap;
  }
  y << YAML::EndMap;
}

void write_run(Out& o, const RunSpec& run) {
  o.key("run") << YAML::BeginMap;
  o.number("run.duration", run.duration);
  o.number("run.output_step", run.output_step);
  o.key("run.integrator") << run.integrator.str();
  o.number("run.rtol", run.rtol);
  o.number("run.atol", run.atol);
  if (run.dt_given) o.number("run.dt", run.dt);  // else the default, and the first step estimated
  o.yaml() << YAML::EndMap;
}

void write_compare(Out& o, const CompareSpec& c) {
  YAML::Emitter& y = o.yaml();
  auto tolerance = [&](const Tolerance& t) {
    y << YAML::Flow << YAML::BeginMap;
    o.number("compare.tolerances.<quantity>.atol", t.atol);
    o.number("compare.tolerances.<quantity>.rtol", t.rtol);
    y << YAML::EndMap;
  };
  o.key("compare") << YAML::BeginMap;
  o.key("compare.tolerances") << YAML::BeginMap;
  y << YAML::Key << "default" << YAML::Value;
  tolerance(c.default_tolerance);
  for (const auto& [quantity, t] : c.tolerances) {
    y << YAML::Key << quantity << YAML::Value;
    tolerance(t);
  }
  y << YAML::EndMap;
  if (!c.excluded.empty()) {
    o.key("compare.exclude") << YAML::BeginSeq;
    for (const auto& [quantity, reason] : c.excluded) {
      y << YAML::BeginMap;
      o.key("compare.exclude[].quantity") << quantity;
      o.key("compare.exclude[].reason") << YAML::DoubleQuoted << reason;
      y << YAML::EndMap;
    }
    y << YAML::EndSeq;
  }
  y << YAML::EndMap;
}

}  // namespace

std::string write_scene_text(const System& s) {
  Out o;
  YAML::Emitter& y = o.yaml();
  y << YAML::BeginMap;
  o.key("name") << s.name;
  o.key("description") << YAML::DoubleQuoted << s.description;
  o.key("source") << YAML::DoubleQuoted << s.source;
  if (!s.analytic.empty()) o.key("analytic") << s.analytic;
  o.key("zero_linear_momentum") << (s.zero_linear_momentum ? "true" : "false");
  write_environment(o, s.environment);
  o.key("bodies") << YAML::BeginSeq;
  for (const Body& b : s.bodies) write_body(o, b);
  y << YAML::EndSeq;
  o.key("joints") << YAML::BeginSeq;
  for (const Joint& j : s.joints) write_joint(o, s, j);
  y << YAML::EndSeq;
  write_run(o, s.run);
  write_compare(o, s.compare);
  y << YAML::EndMap;
  return std::string(y.c_str()) + "\n";
}

}  // namespace crossdyn
