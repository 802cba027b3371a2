// Scene warnings (see scene_warnings.hpp). The geometry checks were the drawing's
// (reports/crossdyn_report/scene_view.py geometry_warnings and symmetry_notes), moved here with
// the same thresholds and wording so that the terminal, the picture and the reports say the same.
#include "harness/scene_warnings.hpp"

#include "core/errors.hpp"
#include "harness/scene_geometry.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <optional>
#include <ostream>

namespace crossdyn::harness {

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

// printf's %.<digits>g, as the drawing wrote its numbers (common.py gfmt).
std::string warn_gfmt(double v, int digits) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

// A universal joint's axes closer than this to parallel draw the `gimbal-axes` warning (rad).
constexpr double kGimbalAxesWarnRad = 10 * std::numbers::pi / 180;

SceneWarning geometry_warning(const System& s, const std::string& code, const std::string& subject,
                              const std::string& message) {
  SceneWarning w;
  w.file = s.file;
  w.code = code;
  w.subject = subject;
  w.message = message;
  return w;
}

// Whether a point lies strictly inside a body's equivalent box (placed at `pose`).
bool warn_inside_box(const Vector3d& point, const geometry::EquivalentBox& box,
                     const geometry::BodyPose& pose) {
  const Matrix3d R = pose.R_NB * box.R_BX;
  const Vector3d local = R.transpose() * (point - pose.p_NoBo_N);
  for (int i = 0; i < 3; ++i)
    if (!(std::abs(local(i)) < 0.5 * box.size_m(i))) return false;
  return true;
}

// The unit direction (in N) in which a positive angle of a revolute joint moves the child's CM;
// none when the CM is on the axis.
std::optional<Vector3d> warn_positive_direction(const geometry::Configuration& c, const Joint& J,
                                                const geometry::JointPose& js) {
  const Vector3d r = c.bodies[static_cast<std::size_t>(J.child)].p_NoBo_N - js.p_NoJ_N_parent;
  const Vector3d v = js.axis_N_parent.cross(r);
  const double n = v.norm();
  if (n > 1e-9 * std::max(1.0, r.norm())) return Vector3d(v / n);
  return std::nullopt;
}

// "+z", "-x +y": the N axis closest to v, then the others whose component is above 0.3.
std::string warn_direction_name(const Vector3d& v) {
  std::array<int, 3> order{0, 1, 2};
  std::stable_sort(order.begin(), order.end(),
                   [&v](int a, int b) { return std::abs(v(a)) > std::abs(v(b)); });
  std::string out;
  for (int k : order)
    if (std::abs(v(k)) > 0.3 || out.empty())
      out += std::string(out.empty() ? "" : " ") + (v(k) > 0 ? "+" : "-") + "xyz"[k];
  return out;
}

// numpy.allclose(a, b, rtol, atol): |a - b| <= atol + rtol |b| elementwise.
bool warn_allclose(const Vector3d& a, const Vector3d& b, double rtol, double atol) {
  for (int i = 0; i < 3; ++i)
    if (!(std::abs(a(i) - b(i)) <= atol + rtol * std::abs(b(i)))) return false;
  return true;
}

}  // namespace

std::vector<SceneWarning> geometry_warnings(const System& system) {
  return configuration_warnings(system, geometry::initial_configuration(system));
}

std::vector<SceneWarning> configuration_warnings(const System& s, const geometry::Configuration& c) {
  std::vector<SceneWarning> out;
  std::vector<geometry::EquivalentBox> boxes;
  for (const Body& b : s.bodies) boxes.push_back(geometry::equivalent_box(b));
  const auto body_name = [&s](int b) { return s.bodies[static_cast<std::size_t>(b)].name; };

  for (std::size_t j = 0; j < s.joints.size(); ++j) {
    const Joint& J = s.joints[j];
    const geometry::JointPose& js = c.joints[j];
    if (J.type == JointType::Free) continue;
    const double gap = (js.p_NoJ_N_parent - js.p_NoJ_N_child).norm();
    if (gap > 1e-9)
      out.push_back(geometry_warning(s, "joint-gap", J.name,
                                     J.name + ": the parent's and the child's joint points are " +
                                         warn_gfmt(gap, 3) + " m apart"));
    if (!js.axis_N_parent.isZero()) {
      const double mismatch = std::atan2(js.axis_N_parent.cross(js.axis_N_child).norm(),
                                         js.axis_N_parent.dot(js.axis_N_child));
      if (mismatch > 1e-6)
        out.push_back(geometry_warning(s, "axis-mismatch", J.name,
                                       J.name + ": the axis fixed in the child is " +
                                           warn_gfmt(mismatch * 180 / std::numbers::pi, 3) +
                                           " deg off the parent's"));
    }
    // A child folded back into its parent: its CM inboard of the joint (on the parent's side,
    // more than 0.3 of the way back) and inside the parent's box. Usually a sign of child_point
    // or of the offset.
    if (J.parent < 0) continue;
    const geometry::BodyPose& P = c.bodies[static_cast<std::size_t>(J.parent)];
    const geometry::BodyPose& C = c.bodies[static_cast<std::size_t>(J.child)];
    const Vector3d out_of_parent = js.p_NoJ_N_parent - P.p_NoBo_N;
    const Vector3d to_child = C.p_NoBo_N - js.p_NoJ_N_parent;
    const bool inboard = out_of_parent.dot(to_child) < -0.3 * out_of_parent.norm() * to_child.norm();
    if (inboard && warn_inside_box(C.p_NoBo_N, boxes[static_cast<std::size_t>(J.parent)], P))
      out.push_back(geometry_warning(
          s, "cm-inboard", J.name,
          J.name + ": " + body_name(J.child) + "'s CM is inboard of the joint, inside " +
              body_name(J.parent) + "'s box: check the sign of child_point and the offset"));
  }

  // Pairs of revolute joints on one parent carrying identical bodies (same mass and box) at the
  // same or mirror-image points, where a positive angle does not move the two children as mirror
  // images: often a flipped axis sign, sometimes the design.
  std::vector<std::size_t> revolute;
  for (std::size_t j = 0; j < s.joints.size(); ++j)
    if (s.joints[j].type == JointType::Revolute) revolute.push_back(j);
  for (std::size_t k = 0; k < revolute.size(); ++k)
    for (std::size_t l = k + 1; l < revolute.size(); ++l) {
      const Joint& A = s.joints[revolute[k]];
      const Joint& B = s.joints[revolute[l]];
      if (A.parent != B.parent || A.parent < 0) continue;
      const Body& ba = s.bodies[static_cast<std::size_t>(A.child)];
      const Body& bb = s.bodies[static_cast<std::size_t>(B.child)];
      if (std::abs(ba.mass - bb.mass) > 1e-9 * std::max(1.0, std::abs(ba.mass)) ||
          !warn_allclose(boxes[static_cast<std::size_t>(A.child)].size_m,
                         boxes[static_cast<std::size_t>(B.child)].size_m, 1e-9, 1e-12))
        continue;
      const geometry::JointPose& sa = c.joints[revolute[k]];
      const geometry::JointPose& sb = c.joints[revolute[l]];
      const std::optional<Vector3d> da = warn_positive_direction(c, A, sa);
      const std::optional<Vector3d> db0 = warn_positive_direction(c, B, sb);
      if (!da || !db0) continue;
      Vector3d db = *db0;
      const Vector3d d = sa.p_NoJ_N_parent - sb.p_NoJ_N_parent;
      std::string where = "at one point";
      if (d.norm() > 1e-9) {
        const Vector3d n = d / d.norm();
        db = db - 2 * db.dot(n) * n;  // the mirror image of B's direction
        where = "at mirror-image points";
      }
      if (da->dot(db) < -0.5)
        out.push_back(geometry_warning(
            s, "mirror-axes", A.name + " and " + B.name,
            A.name + " and " + B.name + " carry identical bodies " + where + " of " +
                body_name(A.parent) +
                ", yet a positive angle moves them other than as mirror images (" + ba.name +
                " towards N " + warn_direction_name(*da) + ", " + bb.name + " towards N " +
                warn_direction_name(*db0) + ")"));
    }

  // A universal joint whose axes are close to parallel (the reader refuses less than 1 deg): its
  // two speeds turn the child about nearly the same line, and the direction across both is
  // stiff to reach; usually axes meant perpendicular.
  for (const Joint& J : s.joints) {
    if (J.type != JointType::Universal) continue;
    const Vector3d a = J.axis_P.normalized(), b = J.axis2_P.normalized();
    const double between = std::atan2(a.cross(b).norm(), std::abs(a.dot(b)));
    if (between < kGimbalAxesWarnRad)
      out.push_back(geometry_warning(
          s, "gimbal-axes", J.name,
          J.name + ": the universal joint's axes are " +
              std::to_string(static_cast<int>(std::lround(between * 180 / std::numbers::pi))) +
              " deg from parallel; a two-axis gimbal's axes are usually perpendicular"));
  }
  return out;
}

std::vector<SceneWarning> scene_warnings(const System& system,
                                         const std::vector<SceneWarning>& reader_warnings) {
  std::vector<SceneWarning> out = reader_warnings;
  for (SceneWarning& w : out) {
    if (w.code.empty()) w.code = "scene";
    if (w.subject.empty()) w.subject = w.key;
  }
  for (SceneWarning& w : geometry_warnings(system)) out.push_back(std::move(w));
  return out;
}

CheckedScene read_checked_scene(const std::string& path, Pipes pipes) {
  CheckedScene c;
  std::vector<SceneWarning> reader_warnings;
  c.system = read_scene(path, &reader_warnings, pipes);
  c.warnings = scene_warnings(c.system, reader_warnings);
  return c;
}

std::string warning_line(const SceneWarning& w) {
  return "crossdyn: warning: " + w.file + ": " + w.detail();
}

void print_warnings(const std::vector<SceneWarning>& warnings, std::ostream& err) {
  for (const SceneWarning& w : warnings) err << warning_line(w) << '\n';
  err.flush();
}

int strict_status(int status, bool strict, std::size_t warnings) {
  return strict && status == kExitOk && warnings > 0 ? kExitCheckFailed : status;
}

nlohmann::ordered_json warnings_json(const std::vector<SceneWarning>& warnings) {
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  for (const SceneWarning& w : warnings)
    out.push_back({{"code", w.code},
                   {"subject", w.subject},
                   {"line", w.line > 0 ? nlohmann::ordered_json(w.line) : nlohmann::ordered_json(nullptr)},
                   {"column", w.line > 0 ? nlohmann::ordered_json(w.column) : nlohmann::ordered_json(nullptr)},
                   {"message", w.detail()}});
  return out;
}

}  // namespace crossdyn::harness
