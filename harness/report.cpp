// JSON summary, JUnit XML and the HTML report folder (see report.hpp).
#include "harness/report.hpp"

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/scene/schema.hpp"
#include "core/input_file.hpp"
#include "core/integrate.hpp"
#include "core/output.hpp"
#include "harness/locations.hpp"
#include "harness/scene_geometry.hpp"
#include "harness/scene_warnings.hpp"
#include "harness/numbers.hpp"

#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>

extern char** environ;

namespace crossdyn::harness {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

namespace {

// NaN and infinity are not JSON numbers: they become null (documented in the report script).
json number(double v) { return json_number<json>(v); }

json vec(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }
json quat(const Eigen::Quaterniond& q) { return json::array({q.w(), q.x(), q.y(), q.z()}); }
json mat(const Eigen::Matrix3d& m) {
  json a = json::array();
  for (int i = 0; i < 3; ++i) a.push_back(json::array({m(i, 0), m(i, 1), m(i, 2)}));
  return a;
}

template <int D>
json schedule(const PiecewiseConstant<D>& f) {
  json a = json::array();
  for (std::size_t k = 0; k < f.times.size(); ++k) {
    json v = json::array();
    for (int i = 0; i < D; ++i) v.push_back(f.values[k](i));
    a.push_back({{"from_t", f.times[k]}, {"value", D == 1 ? v[0] : v}});
  }
  return a;
}

// The scene's data and assumptions, in SI, for the report page.
// The environment (issue 28) in words for the scene page: kind, field, orbit.
json environment_json(const Environment& e) {
  if (e.uniform()) return {{"kind", "uniform"}, {"g_N", {e.g_N.x(), e.g_N.y(), e.g_N.z()}}};
  if (e.orbit())
    return {{"kind", "orbit"},
            {"mu", e.mu},
            {"radius_m", e.radius},
            {"inclination_rad", e.inclination},
            {"raan_rad", e.raan},
            {"latitude0_rad", e.latitude0},
            {"mean_motion", e.mean_motion()}};
  return {{"kind", "none"}};
}

json system_json(const System& s) {
  json bodies = json::array();
  for (const Body& b : s.bodies) {
    json j = {{"name", b.name}, {"mass_kg", b.mass}, {"inertia_kg_m2", mat(b.I_BBo_B)}};
    if (b.flex) j["modes"] = b.flex->mode_names;
    if (!b.torque.empty()) {
      j["torque_N_m"] = schedule(b.torque);
      j["torque_frame"] = b.torque_frame == Body::Frame::Body ? "body" : "inertial";
    }
    bodies.push_back(j);
  }
  json joints = json::array();
  for (const Joint& J : s.joints) {
    json j = {{"name", J.name},
              {"type", std::string(scene::joint_type(J.type).name)},
              {"parent", J.parent < 0 ? "N (inertial)" : s.bodies[J.parent].name},
              {"child", s.bodies[J.child].name}};
    if (J.type == JointType::Free) {
      j["initial"] = {{"p_NoBo_N_m", vec(J.p_NoBo_N0)},
                      {"q_NB", quat(J.q_NB0)},
                      {"w_NB_B_rad_s", vec(J.w_NB_B0)},
                      {"v_NBo_N_m_s", vec(J.v_NBo_N0)}};
    } else {
      j["parent_point_m"] = vec(J.p_PoJ_P);
      j["child_point_m"] = vec(J.p_CoJ_C);
      if (!J.q_PJ0.coeffs().isApprox(Eigen::Quaterniond::Identity().coeffs()))
        j["orientation_offset_q"] = quat(J.q_PJ0);
      if (J.type == JointType::Revolute) {
        j["axis"] = vec(J.axis_P);
        j["initial"] = {{"angle_rad", J.angle0}, {"rate_rad_s", J.rate0}};
      } else if (J.type == JointType::Spherical) {
        j["initial"] = {{"q_J", quat(J.q_J0)}, {"w_PC_C_rad_s", vec(J.w_PC_C0)}};
      } else if (J.type == JointType::Prismatic) {
        j["axis"] = vec(J.axis_P);
        j["initial"] = {{"position_m", J.angle0}, {"rate_m_s", J.rate0}};
      } else if (J.type == JointType::Universal) {
        j["axes"] = {vec(J.axis_P), vec(J.axis2_P)};
        j["initial"] = {{"angles_rad", {J.angle0, J.angle2_0}}, {"rates_rad_s", {J.rate0, J.rate2_0}}};
      }
      if (J.type == JointType::Prismatic) {
        if (J.stiffness != 0) j["stiffness_N_m"] = J.stiffness;
        if (J.neutral_angle != 0) j["neutral_position_m"] = J.neutral_angle;
        if (J.damping != 0) j["damping_N_s_m"] = J.damping;
        if (!J.motor_revolute.empty()) j["motor_N"] = schedule(J.motor_revolute);
      } else if (J.type == JointType::Universal) {
        if (J.stiffness != 0 || J.stiffness2 != 0) j["stiffness_N_m_rad"] = {J.stiffness, J.stiffness2};
        if (J.neutral_angle != 0 || J.neutral_angle2 != 0)
          j["neutral_angle_rad"] = {J.neutral_angle, J.neutral_angle2};
        if (J.damping != 0 || J.damping2 != 0) j["damping_N_m_s_rad"] = {J.damping, J.damping2};
        if (!J.motor_universal.empty()) j["motor_N_m"] = schedule(J.motor_universal);
      } else {
      if (J.stiffness != 0) j["stiffness_N_m_rad"] = J.stiffness;
      if (J.neutral_angle != 0) j["neutral_angle_rad"] = J.neutral_angle;
      if (J.damping != 0) j["damping_N_m_s_rad"] = J.damping;
      if (!J.motor_revolute.empty()) j["motor_N_m"] = schedule(J.motor_revolute);
      if (!J.motor_spherical.empty()) j["motor_N_m"] = schedule(J.motor_spherical);
      }
    }
    joints.push_back(j);
  }
  json tolerances = json::array();
  for (const auto& [key, t] : s.compare.tolerances)
    tolerances.push_back({{"quantity", key}, {"atol", t.atol}, {"rtol", t.rtol}});
  json excluded = json::array();
  for (const auto& [key, reason] : s.compare.excluded)
    excluded.push_back({{"quantity", key}, {"reason", reason}});
  return {{"name", s.name},
          {"file", s.file},
          {"description", s.description},
          {"source", s.source},
          {"bodies", bodies},
          {"joints", joints},
          {"zero_linear_momentum", s.zero_linear_momentum},
          {"environment", environment_json(s.environment)},
          {"analytic", s.analytic},
          {"run", {{"duration_s", s.run.duration},
                   {"output_step_s", s.run.output_step},
                   {"integrator", s.run.integrator.str()},
                   {"rtol", s.run.rtol},
                   {"atol", s.run.atol},
                   {"dt_s", s.run.dt}}},
          {"compare", {{"default", {{"atol", s.compare.default_tolerance.atol},
                                    {"rtol", s.compare.default_tolerance.rtol}}},
                       {"tolerances", tolerances},
                       {"excluded", excluded}}}};
}

json check_json(const Check& c) {
  json j = {{"quantity", c.quantity},
            {"group", c.group},
            {"a", c.a},
            {"b", c.b},
            {"tolerance_key", c.tolerance_key},
            {"atol", number(c.tolerance.atol)},
            {"rtol", number(c.tolerance.rtol)},
            {"scale", number(c.scale)},
            {"bound", number(c.bound)},
            {"allowance", number(c.allowance)},
            {"error", number(c.error)},
            {"time", number(c.time)},
            {"first_exceeded", c.first_exceeded ? number(*c.first_exceeded) : json(nullptr)},
            {"normalised", number(c.normalised)},
            {"status", to_string(c.status)},
            {"note", c.note}};
  return j;
}

json group_json(const GroupSummary& g) {
  return {{"group", g.group},           {"status", to_string(g.status)},
          {"worst", number(g.worst)},   {"worst_check", g.worst_check},
          {"checks", g.checks},         {"failed", g.failed},
          {"excluded", g.excluded},     {"skipped", g.skipped}};
}

const char* run_state(EngineRun::State s) {
  switch (s) {
    case EngineRun::State::Ok: return "ok";
    case EngineRun::State::Failed: return "failed";
    case EngineRun::State::NotBuilt: return "skipped";
  }
  return "?";
}

// Unique page ids, one per scene: the scene's name (file stem when unreadable).
std::vector<std::string> scene_ids(const std::vector<SceneOutcome>& scenes) {
  std::vector<std::string> bases;
  for (const SceneOutcome& s : scenes)
    bases.push_back(file_safe(s.system ? s.system->name : fs::path(s.path).stem().string()));
  return unique_ids(bases, {"index", "summary", "data"}, '-');
}

json summary_document(const std::vector<SceneOutcome>& scenes,
                      const std::vector<std::vector<std::string>>& data_files,
                      const std::vector<std::string>& geometry_files = {}) {
  const std::vector<std::string> ids = scene_ids(scenes);
  json out_scenes = json::array();
  int n_checks = 0, n_failed = 0, n_scenes_failed = 0, n_bad = 0;
  std::size_t n_warnings = 0;
  for (std::size_t i = 0; i < scenes.size(); ++i) {
    const SceneOutcome& s = scenes[i];
    json j = {{"id", ids[i]}, {"path", s.path}, {"page", ids[i] + ".html"}};
    // The scene's warnings (harness/scene_warnings.hpp): not failures, so not in "passed".
    j["warnings"] = warnings_json(s.warnings);
    n_warnings += s.warnings.size();
    if (!s.comparison) {
      j["scene"] = fs::path(s.path).stem().string();
      j["passed"] = false;
      j["input_error"] = s.input_error;
      ++n_bad;
      out_scenes.push_back(j);
      continue;
    }
    const SceneComparison& c = *s.comparison;
    j["scene"] = c.scene;
    j["passed"] = c.passed();
    if (!c.passed()) ++n_scenes_failed;
    j["settings"] = {{"integrator", c.settings.method.str()},
                     {"rtol", c.settings.rtol},
                     {"atol", c.settings.atol},
                     {"dt_s", c.settings.dt},
                     {"duration_s", c.settings.duration},
                     {"output_step_s", c.settings.output_step}};
    if (s.system) j["system"] = system_json(*s.system);
    if (!s.converge_json.empty()) j["converge"] = json::parse(s.converge_json);
    if (!s.converge_note.empty()) j["converge_note"] = s.converge_note;
    if (i < geometry_files.size() && !geometry_files[i].empty()) j["geometry"] = geometry_files[i];
    json runs = json::array();
    for (std::size_t r = 0; r < c.runs.size(); ++r) {
      const EngineRun& run = c.runs[r];
      json jr = {{"label", run.label},
                 {"engine", run.engine},
                 {"state", run_state(run.state)},
                 {"note", run.note},
                 {"rows", run.result.rows()},
                 {"rhs_calls", run.result.stats.rhs_calls},
                 {"steps", run.result.stats.steps},
                 {"rejected", run.result.stats.rejected},
                 {"restarts", run.result.stats.restarts},
                 {"wall_seconds", run.result.stats.wall_seconds}};
      if (run.result.failure)
        jr["failure"] = {{"time", number(run.result.failure->time())},
                         {"quantity", run.result.failure->quantity()},
                         {"reason", run.result.failure->reason()}};
      if (i < data_files.size() && r < data_files[i].size() && !data_files[i][r].empty())
        jr["data"] = data_files[i][r];
      runs.push_back(jr);
    }
    j["runs"] = runs;
    json checks = json::array();
    for (const Check& k : c.checks) checks.push_back(check_json(k));
    j["checks"] = checks;
    json groups = json::array();
    for (const GroupSummary& g : summarise_groups(c)) groups.push_back(group_json(g));
    j["groups"] = groups;
    j["notes"] = c.notes;
    j["energy_not_conserved"] = s.system ? energy_not_conserved_reason(*s.system) : "";
    j["momentum_not_conserved"] = s.system ? momentum_not_conserved_reason(*s.system) : "";
    // Issue 28: on an orbit the Jacobi integral J is the conserved one (E changes).
    j["orbit"] = s.system && s.system->environment.orbit();
    j["jacobi_not_conserved"] = s.system ? jacobi_not_conserved_reason(*s.system) : "";
    // Where the loads switch: a balance's quadrature keeps its pieces apart there (compare.cpp).
    j["breakpoints"] = s.system ? s.system->breakpoints() : std::vector<double>{};
    n_checks += static_cast<int>(c.checks.size());
    n_failed += c.count(CheckStatus::Fail);
    out_scenes.push_back(j);
  }
  return {{"tool", "crossdyn"},
          {"format", 1},
          {"pass_rule",
           {{"pair", "max_t |a(t) - b(t)| <= atol + rtol * max_t |b(t)|, b = the reference "
                     "(the earlier of the two: analytic, then engines in the order asked)"},
            {"attitude", "error = rotation angle between the two attitudes (rad); max|b| = 1"},
            {"drift", "max_t |X(t) - X(0)| <= atol + rtol * |X(0)|"},
            {"balance", "max_t |X(t) - X(0) - W(t)| <= atol + rtol * max(max_t |X|, integral of |rate|) + "
                        "Q; W the integral of the engine's P (E) or M (H, a vector), Q its quadrature's "
                        "estimated error on the output times"},
            {"normalised", "error / (atol + rtol * scale); <= 1 passes"}}},
          {"group_order", group_order()},
          {"passed", n_failed == 0 && n_bad == 0},
          {"counts", {{"scenes", scenes.size()},
                      {"scenes_failed", n_scenes_failed},
                      {"scenes_unreadable", n_bad},
                      {"checks", n_checks},
                      {"checks_failed", n_failed},
                      {"warnings", n_warnings}}},
          {"scenes", out_scenes}};
}

std::string xml_escape(const std::string& s) {
  std::string out;
  for (char ch : s) {
    switch (ch) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default:
        // XML 1.0 forbids most control characters.
        if (static_cast<unsigned char>(ch) < 0x20 && ch != '\n' && ch != '\t' && ch != '\r') out += '?';
        else out += ch;
    }
  }
  return out;
}

std::string fmt_6g(double v) {
  if (!std::isfinite(v)) return sci(v);
  char b[64];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

}  // namespace

std::string describe_failure(const Check& c) {
  if (c.quantity == "comparison") return c.note;  // nothing compared (harness/verify.hpp)
  std::string who = c.b.empty() ? c.a : c.a + " vs " + c.b;
  if (c.group == "run")
    return who + ": run failed at t = " + fmt_6g(c.time) + " s: " + c.note;
  std::string line = c.quantity + ", " + who + ": max error " + sci(c.error, 4) + " at t = " +
                     fmt_6g(c.time) + " s > bound " + sci(c.bound, 4) + " (atol " +
                     sci(c.tolerance.atol, 2) + " + rtol " + sci(c.tolerance.rtol, 2) + " * " +
                     sci(c.scale, 4) + "), error/bound " + sci(c.normalised);
  if (c.first_exceeded) line += ", first over at t = " + fmt_6g(*c.first_exceeded) + " s";
  if (!c.note.empty()) line += " (" + c.note + ")";
  return line;
}

const std::vector<std::string>& group_order() {
  // Every group a Check can carry (compare.cpp), in table order; a group missing here would be
  // left out of verify's table and the report (tests/harness/test_compare.cpp checks the list).
  static const std::vector<std::string> order{
      "run", "t",    "w",       "attitude", "rate",      "angle",     "position", "modal",
      "torque", "load", "H",    "E",        "H.drift",   "E.drift",   "H.balance", "E.balance",
      "J.drift", "extra"};
  return order;
}

std::vector<GroupSummary> summarise_groups(const SceneComparison& c) {
  std::vector<GroupSummary> out;
  for (const std::string& g : group_order()) {
    GroupSummary s;
    s.group = g;
    bool any_pass = false;
    for (const Check& k : c.checks) {
      if (k.group != g) continue;
      ++s.checks;
      switch (k.status) {
        case CheckStatus::Fail: ++s.failed; break;
        case CheckStatus::Excluded: ++s.excluded; break;
        case CheckStatus::Skipped: ++s.skipped; break;
        case CheckStatus::Pass: any_pass = true; break;
      }
      if (k.group != "run" && (k.status == CheckStatus::Pass || k.status == CheckStatus::Fail) &&
          (std::isnan(k.normalised) || !(k.normalised <= s.worst)) && !std::isnan(s.worst)) {
        s.worst = k.normalised;
        s.worst_check = k.quantity + " " + (k.b.empty() ? k.a : k.a + " vs " + k.b);
      }
    }
    if (s.checks == 0) continue;
    s.status = s.failed ? CheckStatus::Fail
               : any_pass ? CheckStatus::Pass
               : s.excluded ? CheckStatus::Excluded : CheckStatus::Skipped;
    out.push_back(s);
  }
  return out;
}

std::string json_summary(const std::vector<SceneOutcome>& scenes,
                         const std::vector<std::vector<std::string>>& data_files) {
  return summary_document(scenes, data_files).dump(1) + "\n";
}

// A folder with no write bit in its mode is refused for every user, root included (as read-only
// files and folders are by AtomicFile, core/output.cpp): crossdyn creates nothing in it.
static void refuse_read_only_folder(const fs::path& folder) {
  struct stat st {};
  if (::stat(folder.c_str(), &st) != 0 || !S_ISDIR(st.st_mode) || (st.st_mode & 0222) != 0) return;
  char mode[16];
  std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
  throw InputError("cannot create a folder in '" + folder.string() + "': it is read-only (mode " +
                   mode + "); crossdyn creates nothing in read-only folders");
}

void make_directories(const std::string& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  // The nearest folder that exists is where the first new one would be made.
  fs::path existing = fs::absolute(dir, ec).lexically_normal();
  while (!ec && !fs::exists(existing, ec) && existing.has_relative_path()) existing = existing.parent_path();
  if (!ec && existing != fs::absolute(dir, ec).lexically_normal()) refuse_read_only_folder(existing);
  ec.clear();
  fs::create_directories(dir, ec);
  if (ec) throw InputError("cannot create folder '" + dir + "': " + ec.message());
}

void write_json_summary(const std::string& path, const std::vector<SceneOutcome>& scenes) {
  make_directories(fs::path(path).parent_path().string());
  write_file_atomic(path, json_summary(scenes));
}

std::string junit_xml(const std::vector<SceneOutcome>& scenes) {
  const std::vector<std::string> ids = scene_ids(scenes);
  std::ostringstream body;
  int all_tests = 0, all_failures = 0, all_errors = 0, all_skipped = 0;
  double all_time = 0;
  for (std::size_t i = 0; i < scenes.size(); ++i) {
    const SceneOutcome& s = scenes[i];
    const std::string classname = "crossdyn.verify." + ids[i];
    std::ostringstream cases;
    int tests = 0, failures = 0, errors = 0, skipped = 0;
    double time = 0;
    if (!s.comparison) {
      tests = errors = 1;
      cases << "    <testcase classname=\"" << xml_escape(classname)
            << "\" name=\"read scene\" time=\"0\">\n      <error type=\"InputError\" message=\""
            << xml_escape(s.input_error) << "\">" << xml_escape(s.input_error)
            << "</error>\n    </testcase>\n";
    } else {
      const SceneComparison& c = *s.comparison;
      for (const EngineRun& r : c.runs) time += r.result.stats.wall_seconds;
      // Test cases: each engine's run, then each quantity (over all pairs / engines).
      std::vector<std::pair<std::string, std::vector<const Check*>>> tcs;
      std::map<std::string, std::size_t> where;
      for (const Check& k : c.checks) {
        const std::string name = k.group == "run" ? "run " + k.a : k.quantity;
        auto it = where.find(name);
        if (it == where.end()) {
          where[name] = tcs.size();
          tcs.push_back({name, {}});
          it = where.find(name);
        }
        tcs[it->second].second.push_back(&k);
      }
      for (const auto& [name, checks] : tcs) {
        ++tests;
        double t = 0;
        for (const Check* k : checks)
          if (k->group == "run")
            for (const EngineRun& r : c.runs)
              if (r.label == k->a) t = r.result.stats.wall_seconds;
        cases << "    <testcase classname=\"" << xml_escape(classname) << "\" name=\""
              << xml_escape(name) << "\" time=\"" << fmt_6g(t) << "\"";
        std::vector<const Check*> failed, passed, excluded, skip;
        for (const Check* k : checks) {
          if (k->status == CheckStatus::Fail) failed.push_back(k);
          else if (k->status == CheckStatus::Pass) passed.push_back(k);
          else if (k->status == CheckStatus::Excluded) excluded.push_back(k);
          else skip.push_back(k);
        }
        if (!failed.empty()) {
          ++failures;
          std::string text;
          for (const Check* k : failed) text += describe_failure(*k) + "\n";
          cases << ">\n      <failure type=\"" << (failed[0]->group == "run" ? "RunFailure" : "tolerance")
                << "\" message=\"" << xml_escape(describe_failure(*failed[0]))
                << (failed.size() > 1 ? xml_escape(" (and " + std::to_string(failed.size() - 1) + " more)") : "")
                << "\">" << xml_escape(text) << "</failure>\n    </testcase>\n";
        } else if (passed.empty()) {
          ++skipped;
          const Check* k = excluded.empty() ? skip.front() : excluded.front();
          cases << ">\n      <skipped message=\""
                << xml_escape((k->status == CheckStatus::Excluded ? "excluded: " : "skipped: ") + k->note)
                << "\"/>\n    </testcase>\n";
        } else {
          std::string out;
          for (const Check* k : passed)
            if (k->group != "run")
              out += k->quantity + ", " + (k->b.empty() ? k->a : k->a + " vs " + k->b) +
                     ": error/bound " + sci(k->normalised) + "\n";
          if (out.empty()) cases << "/>\n";
          else cases << ">\n      <system-out>" << xml_escape(out) << "</system-out>\n    </testcase>\n";
        }
      }
    }
    // The scene's warnings: a property each ("warning": "<code>: <detail>") and the lines crossdyn
    // printed on stderr in the suite's <system-err>; a warning is neither a failure nor an error.
    std::string warning_properties, warning_lines;
    for (const SceneWarning& w : s.warnings) {
      warning_properties += "      <property name=\"warning\" value=\"" +
                            xml_escape(w.code + ": " + w.detail()) + "\"/>\n";
      warning_lines += warning_line(w) + "\n";
    }
    body << "  <testsuite name=\"" << xml_escape(ids[i]) << "\" tests=\"" << tests
         << "\" failures=\"" << failures << "\" errors=\"" << errors << "\" skipped=\"" << skipped
         << "\" time=\"" << fmt_6g(time) << "\">\n"
         << "    <properties>\n      <property name=\"file\" value=\"" << xml_escape(s.path)
         << "\"/>\n" << warning_properties << "    </properties>\n"
         << cases.str();
    if (!warning_lines.empty()) body << "    <system-err>" << xml_escape(warning_lines) << "</system-err>\n";
    body << "  </testsuite>\n";
    all_tests += tests;
    all_failures += failures;
    all_errors += errors;
    all_skipped += skipped;
    all_time += time;
  }
  std::ostringstream out;
  out << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      << "<testsuites name=\"crossdyn verify\" tests=\"" << all_tests << "\" failures=\""
      << all_failures << "\" errors=\"" << all_errors << "\" skipped=\"" << all_skipped
      << "\" time=\"" << fmt_6g(all_time) << "\">\n"
      << body.str() << "</testsuites>\n";
  return out.str();
}



std::string file_safe(std::string s, bool keep_dots, const std::string& empty) {
  for (char& ch : s)
    if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '-' && ch != '_' && !(keep_dots && ch == '.'))
      ch = '_';
  return s.empty() ? empty : s;
}

std::vector<std::string> unique_ids(const std::vector<std::string>& bases, std::set<std::string> taken,
                                    char separator) {
  std::vector<std::string> ids;
  for (const std::string& base : bases) {
    std::string id = base;
    for (int k = 2; taken.count(id); ++k) id = base + separator + std::to_string(k);
    taken.insert(id);
    ids.push_back(id);
  }
  return ids;
}

void check_python(const std::string& python) {
  if (python.empty()) throw InputError("--python: the program name is empty");
  const std::string me = "--python '" + python + "'";
  const std::string hint = " (give the path of a Python 3 with matplotlib, e.g. /usr/bin/python3)";
  struct stat st {};
  if (::stat(python.c_str(), &st) != 0) throw InputError(me + ": " + std::strerror(errno) + hint);
  if (S_ISDIR(st.st_mode)) throw InputError(me + " is a folder, not a program" + hint);
  if (!S_ISREG(st.st_mode)) throw InputError(me + " is not a regular file" + hint);
  if ((st.st_mode & 0111) == 0 || ::faccessat(AT_FDCWD, python.c_str(), X_OK, AT_EACCESS) != 0)
    throw InputError(me + " is not executable" + hint);
}

void run_python(const std::string& python, const std::vector<std::string>& args) {
  std::vector<std::string> all{python};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  // PYTHONDONTWRITEBYTECODE: no __pycache__ in the installed scripts' folder (the source tree).
  std::string no_bytecode = "PYTHONDONTWRITEBYTECODE=1";
  std::vector<char*> envp;
  for (char** e = environ; *e != nullptr; ++e)
    if (std::strncmp(*e, "PYTHONDONTWRITEBYTECODE=", 24) != 0) envp.push_back(*e);
  envp.push_back(no_bytecode.data());
  envp.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, python.c_str(), nullptr, nullptr, argv.data(), envp.data());
  if (rc != 0)
    throw InputError("cannot run '" + python + "' for '" + args.at(0) + "': " + std::strerror(rc));
  // Wait, polling the interrupt flag: Ctrl-C ends the script and the command (exit 130).
  cancel::test_interrupt_point("report");  // test hook: Ctrl-C while the script runs
  int status = 0;
  for (;;) {
    const pid_t done = waitpid(pid, &status, WNOHANG);
    if (done == pid) break;
    if (done < 0 && errno != EINTR)
      throw InputError("waiting for the report script failed: " + std::string(std::strerror(errno)));
    if (interrupt_requested()) {
      ::kill(pid, SIGTERM);
      while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
      }
      throw RunFailure("report", 0.0, "", "interrupted");
    }
    ::poll(nullptr, 0, 20);
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw InputError("'" + args.at(0) + "' failed (" +
                     (WIFEXITED(status) ? "exit status " + std::to_string(WEXITSTATUS(status))
                                        : std::string("killed by a signal")) +
                     "); see its messages above");
}

namespace {

// The report script: as given, else the installed one (never one found next to the scenes).
std::string find_script(const std::string& given) {
  if (!given.empty()) {
    // Opened without blocking and checked on the descriptor: a FIFO, device or directory would
    // hang or feed python forever (core/input_file.hpp).
    if (const std::string why = input_file_problem(given, Pipes::Refuse); !why.empty())
      throw InputError("--report-script: '" + given + "' cannot be used: " + why);
    return given;
  }
  const fs::path p = fs::path(installed_reports_dir()) / "make_report.py";
  if (!fs::is_regular_file(p))
    throw InputError("the report script '" + p.string() + "' is missing (it is part of the crossdyn "
                     "source tree this program was built from)");
  return p.string();
}

// The files a report owns at the top of its folder: replaced as a whole by the next report.
// Everything else in the folder (a junit.xml written there, a user's notes) is carried over.
bool report_owned(const fs::path& name) {
  const std::string n = name.string();
  const std::string ext = name.extension().string();
  return n == "summary.json" || n == "data" || ext == ".html" || ext == ".png" ||
         n.find(".tmp.") != std::string::npos;
}

bool is_crossdyn_report(const fs::path& dir) {
  std::ifstream in(dir / "summary.json");
  if (!in) return false;
  try {
    const json j = json::parse(in);
    return j.is_object() && j.value("tool", "") == "crossdyn";
  } catch (const std::exception&) {
    return false;
  }
}

// True when `p` is `dir` or inside it (both made absolute and free of symbolic links).
bool inside(const fs::path& p, const fs::path& dir) {
  std::error_code ec;
  const fs::path a = fs::weakly_canonical(fs::absolute(p), ec);
  if (ec) return false;
  const fs::path rel = a.lexically_relative(dir);
  return !rel.empty() && *rel.begin() != "..";
}

// The --report folder, absolute, with a symbolic link to a folder followed; the root refused.
fs::path resolve_report_dir(const std::string& given) {
  if (given.empty()) throw InputError("--report: the folder name is empty");
  fs::path dir = fs::absolute(given).lexically_normal();
  if (!dir.has_filename()) dir = dir.parent_path();  // "out/"
  std::error_code ec;
  dir = fs::weakly_canonical(dir, ec);  // a symbolic link to a folder: the folder it names
  if (ec) throw InputError("--report: cannot resolve '" + given + "': " + ec.message());
  if (dir == dir.root_path()) throw InputError("--report: '" + given + "' is the root folder");
  return dir;
}

// The report folder, absolute, with a symbolic link to a folder followed. Refuses what a report
// must not replace (see write_report in report.hpp).
fs::path report_folder(const std::string& given, const std::vector<SceneOutcome>& scenes,
                       const std::string& script) {
  const fs::path dir = resolve_report_dir(given);
  std::error_code ec;
  const fs::file_status st = fs::status(dir, ec);
  if (fs::exists(st)) {
    if (!fs::is_directory(st))
      throw InputError("--report: '" + given + "' is a file, not a folder");
    if (!is_crossdyn_report(dir))
      for (const fs::directory_entry& e : fs::directory_iterator(dir, ec))
        if (report_owned(e.path().filename()))
          throw InputError("--report: '" + given + "' is not a crossdyn report folder (it has no "
                           "summary.json written by crossdyn) but holds '" +
                           e.path().filename().string() + "', which the report would replace; "
                           "give a new folder, an empty one or an earlier report");
  }
  if (inside(fs::current_path(), dir))
    throw InputError("--report: '" + given + "' holds the current folder; the report replaces its "
                     "folder as a whole");
  for (const SceneOutcome& s : scenes)
    if (inside(s.path, dir))
      throw InputError("--report: '" + given + "' holds the scene file '" + s.path +
                       "'; the report replaces its folder as a whole");
  if (inside(script, dir))
    throw InputError("--report: '" + given + "' holds the report script '" + script + "'");
  return dir;
}

bool process_alive(long pid) { return pid > 0 && (::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM); }

// Removes DIR.partial-<pid>-* folders of processes that are gone (a run killed while writing).
void remove_stale_partials(const fs::path& dir) {
  const std::string prefix = dir.filename().string() + ".partial-";
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(dir.parent_path(), ec)) {
    const std::string n = e.path().filename().string();
    if (n.compare(0, prefix.size(), prefix) != 0) continue;
    const long pid = std::strtol(n.c_str() + prefix.size(), nullptr, 10);
    if (!process_alive(pid)) fs::remove_all(e.path(), ec);
  }
}

}  // namespace

// A new folder next to the report folder, removed again unless released.
class PartialFolder {
 public:
  explicit PartialFolder(const fs::path& dir) {
    refuse_read_only_folder(dir.parent_path());
    std::random_device random;
    for (int attempt = 0; attempt < 100; ++attempt) {
      char suffix[16];
      std::snprintf(suffix, sizeof suffix, "%08x", random());
      path_ = dir.parent_path() /
              (dir.filename().string() + ".partial-" + std::to_string(::getpid()) + "-" + suffix);
      if (::mkdir(path_.c_str(), 0777) == 0) return;  // 0777 & ~umask, as any new folder
      if (errno != EEXIST)
        throw InputError("cannot create folder '" + path_.string() + "': " + std::strerror(errno));
    }
    throw InputError("cannot create a new folder next to '" + dir.string() + "'");
  }
  ~PartialFolder() {
    std::error_code ec;
    if (!path_.empty()) fs::remove_all(path_, ec);
  }
  PartialFolder(const PartialFolder&) = delete;
  PartialFolder& operator=(const PartialFolder&) = delete;
  const fs::path& path() const { return path_; }
  void release() { path_.clear(); }

 private:
  fs::path path_;
};

namespace {

// Copies into `to` what the current report folder holds that the report does not own.
void carry_over(const fs::path& from, const fs::path& to, bool (*owned)(const fs::path&)) {
  std::error_code ec;
  if (!fs::is_directory(from, ec)) return;
  for (const fs::directory_entry& e : fs::directory_iterator(from)) {
    const fs::path name = e.path().filename();
    if (owned(name) || fs::exists(fs::symlink_status(to / name))) continue;
    if (e.is_symlink()) fs::copy_symlink(e.path(), to / name);
    else if (e.is_regular_file()) {
      fs::create_hard_link(e.path(), to / name, ec);  // the old folder is removed next
      if (ec) fs::copy_file(e.path(), to / name);
    } else if (e.is_directory()) fs::copy(e.path(), to / name, fs::copy_options::recursive);
  }
}

// The drawing geometry of a scene: t = 0 from the scene, later pictures from the kane run (or the
// first run that has output), see harness/scene_geometry.hpp.
std::string scene_geometry(const System& system, const SceneComparison& c,
                           const std::vector<SceneWarning>& warnings) {
  namespace g = geometry;
  g::MotionSource source;
  source.duration = c.settings.duration;
  const EngineRun* run = nullptr;
  for (int pass = 0; pass < 3 && !run; ++pass)
    for (const EngineRun& r : c.runs)
      if (!r.result.columns.empty() &&
          (pass == 0 ? r.engine == "kane" : pass == 1 ? r.engine != "analytic" : true)) {
        run = &r;
        break;
      }
  std::vector<g::Configuration> frames;
  if (!run) {
    source.state = "not run";
    source.note = "no run produced output";
  } else {
    source.engine = run->label;
    source.state = run->result.failure ? "failed" : "ok";
    if (run->result.failure) source.note = run->result.failure->what();
    try {
      frames = g::motion_frames(system, run->result.columns, run->result.data, c.settings.duration);
    } catch (const InputError& e) {
      source.note += std::string(source.note.empty() ? "" : "; ") + e.what();
    }
  }
  return g::geometry_json(system, g::initial_configuration(system), frames, source, warnings);
}

}  // namespace

void check_report(const std::vector<std::string>& scene_files, const ReportOptions& options) {
  const std::string script = find_script(options.script);
  check_python(options.python);
  std::vector<SceneOutcome> scenes;
  for (const std::string& f : scene_files) {
    SceneOutcome o;
    o.path = f;
    scenes.push_back(std::move(o));
  }
  const fs::path dir = report_folder(options.dir, scenes, script);
  make_directories(dir.parent_path().string());
  StagedFolder probe(dir, report_owned);  // can a folder be made beside it? (removed at once)
}

std::unique_ptr<StagedFolder> build_report(const std::vector<SceneOutcome>& scenes,
                                           const ReportOptions& options) {
  const std::string script = find_script(options.script);
  const fs::path dir = report_folder(options.dir, scenes, script);
  make_directories(dir.parent_path().string());
  auto staged = std::make_unique<StagedFolder>(dir, report_owned);
  const fs::path& out = staged->path();
  const std::vector<std::string> ids = scene_ids(scenes);
  std::vector<std::vector<std::string>> data_files(scenes.size());
  std::vector<std::string> geometry_files(scenes.size());
  for (std::size_t i = 0; i < scenes.size(); ++i) {
    if (!scenes[i].comparison) continue;
    const fs::path data_dir = out / "data" / ids[i];
    make_directories(data_dir.string());
    std::set<std::string> used{"geometry"};
    for (const EngineRun& r : scenes[i].comparison->runs) {
      if (r.result.columns.empty()) {
        data_files[i].push_back("");
        continue;
      }
      std::string name = file_safe(r.label);
      while (used.count(name)) name += "_";
      used.insert(name);
      const fs::path rel = fs::path("data") / ids[i] / (name + ".csv");
      AtomicFile f((out / rel).string());
      write_csv_header(f.stream(), r.result.columns);
      for (std::size_t k = 0; k < r.result.rows(); ++k)
        write_csv_row(f.stream(), r.result.data.data() + k * r.result.columns.size(), r.result.columns.size());
      f.commit();
      data_files[i].push_back(rel.generic_string());
    }
    if (scenes[i].system) {
      const fs::path rel = fs::path("data") / ids[i] / "geometry.json";
      write_file_atomic((out / rel).string(), scene_geometry(*scenes[i].system, *scenes[i].comparison,
                                                         scenes[i].warnings));
      geometry_files[i] = rel.generic_string();
    }
  }
  const std::string summary = (out / "summary.json").string();
  write_file_atomic(summary, summary_document(scenes, data_files, geometry_files).dump(1) + "\n");
  run_python(options.python, {script, summary, out.string()});
  return staged;
}

void write_report(const std::vector<SceneOutcome>& scenes, const ReportOptions& options) {
  const std::unique_ptr<StagedFolder> staged = build_report(scenes, options);
  commit_together({}, {staged.get()});
}

std::unique_ptr<StagedFolder> stage_report_folder(const std::string& given, const std::string& marker,
                                                  const std::string& kind,
                                                  bool (*owned)(const fs::path& name)) {
  const fs::path dir = resolve_report_dir(given);
  std::error_code ec;
  const fs::file_status st = fs::status(dir, ec);
  if (fs::exists(st)) {
    if (!fs::is_directory(st)) throw InputError("--report: '" + given + "' is a file, not a folder");
    bool ours = false;
    if (std::ifstream in(dir / marker); in) {
      try {
        const json j = json::parse(in);
        ours = j.is_object() && j.value("tool", "") == "crossdyn" && j.value("kind", "") == kind;
      } catch (const std::exception&) {
        ours = false;
      }
    }
    if (!ours && !fs::is_empty(dir, ec))
      throw InputError("--report: '" + given + "' is neither empty nor a crossdyn " + kind +
                       " report (no " + marker + " written by crossdyn " + kind + "); give a new "
                       "folder, an empty one or an earlier " + kind + " report");
  }
  if (inside(fs::current_path(), dir))
    throw InputError("--report: '" + given + "' holds the current folder; the report replaces its "
                     "folder as a whole");
  make_directories(dir.parent_path().string());
  return std::make_unique<StagedFolder>(dir, owned);
}

// ---------------------------------------------------------------- StagedFolder

StagedFolder::StagedFolder(fs::path dir, bool (*owned)(const fs::path&))
    : dir_(std::move(dir)), owned_(owned) {
  remove_stale_partials(dir_);
  partial_ = std::make_unique<PartialFolder>(dir_);
}

StagedFolder::~StagedFolder() {
  partial_.reset();  // removes the new folder (or, after an exchange, the previous report)
  if (lock_fd_ >= 0) ::close(lock_fd_);
}

const fs::path& StagedFolder::path() const { return partial_->path(); }

void StagedFolder::prepare() {
  if (lock_fd_ < 0) {
    lock_fd_ = ::open(dir_.parent_path().c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (lock_fd_ < 0)
      throw InputError("cannot open folder '" + dir_.parent_path().string() + "': " + std::strerror(errno));
    while (::flock(lock_fd_, LOCK_EX) != 0)
      if (errno != EINTR)
        throw InputError("cannot lock folder '" + dir_.parent_path().string() + "': " + std::strerror(errno));
  }
  try {
    carry_over(dir_, partial_->path(), owned_);
  } catch (const fs::filesystem_error& e) {
    throw InputError("cannot keep the files of '" + dir_.string() + "' that are not part of the report: " +
                     e.code().message() + (e.path1().empty() ? "" : " ('" + e.path1().string() + "')"));
  }
}

// Swaps the finished folder in for the report folder: DIR is never missing or half-written.
void StagedFolder::publish() {
  if (lock_fd_ < 0) prepare();
  const fs::path& from = partial_->path();
  if (::rename(from.c_str(), dir_.c_str()) == 0) {  // no folder there, or an empty one
    partial_->release();
    return;
  }
  if (errno != EEXIST && errno != ENOTEMPTY)
    throw OutputError("the report folder '" + dir_.string() + "'", errno);
  // One rename exchanges the two folders.
  if (::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, dir_.c_str(), RENAME_EXCHANGE) == 0)
    return;  // the partial folder now holds the previous report, removed by the destructor
  if (errno != EINVAL && errno != ENOSYS)
    throw OutputError("the report folder '" + dir_.string() + "'", errno);
  // A file system without RENAME_EXCHANGE: two renames (DIR is briefly missing, never mixed).
  const fs::path old = from.string() + ".old";
  if (::rename(dir_.c_str(), old.c_str()) != 0 || ::rename(from.c_str(), dir_.c_str()) != 0)
    throw OutputError("the report folder '" + dir_.string() + "'", errno);
  partial_->release();
  std::error_code ec;
  fs::remove_all(old, ec);
}

}  // namespace crossdyn::harness
