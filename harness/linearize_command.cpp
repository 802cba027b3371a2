// crossdyn linearize SCENE: every engine's linear model about an equilibrium or a steady spin, its
// eigenvalues and transfer functions compared between engines (harness/linearize.hpp; issue 27;
// docs/commands/linearize.md).
#include <CLI/CLI.hpp>

#include "core/errors.hpp"
#include "core/output.hpp"
#include "harness/cli.hpp"
#include "harness/commands.hpp"
#include "harness/engines.hpp"
#include "harness/linearize.hpp"
#include "harness/locations.hpp"
#include "harness/report.hpp"
#include "harness/scene_warnings.hpp"
#include "harness/stability.hpp"
#include "harness/study.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>

namespace crossdyn {

namespace {

struct LinearizeCommandOptions {
  std::string scene;
  std::string engines;
  std::string operating_point = "initial";
  double time = 0;
  std::string inputs, outputs;
  bool inputs_given = false;
  double rtol = 1e-8;
  double tf_rtol = 1e-7;
  double residual_tol = 1e-9;
  double zero_tol = 1e-6;
  bool jacobian_only = false;
  double fd_step = 0;
  std::string json, csv, report;
  std::string python = "/usr/bin/python3";
  bool strict = false;
  std::vector<std::string> test_gyroscopic_sign;  // engines: add a copy with the sign flipped
  std::string vary, values;           // a root locus: the scene parameter and its values
  std::vector<std::string> settings;  // --set KNOB=VALUE before the sweep
};

// One value of a --vary sweep: its linearisation, or why it was refused there.
struct LocusPoint {
  double value = 0;
  std::optional<harness::LinearizeResult> result;
  std::string refused;
};

std::string short_num(double v, int digits = 4) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

// The root locus as text: per value, the first engine's modes (w_n rad/s / zeta), whether the
// engines agree, and the unstable modes.
std::string format_locus(const harness::Knob& knob, const std::vector<LocusPoint>& points, double rtol) {
  std::ostringstream o;
  o << "root locus: " << knob.description << (knob.unit.empty() ? "" : " (" + knob.unit + ")")
    << "; modes of the first engine as w_n rad/s / damping ratio\n";
  for (const LocusPoint& p : points) {
    o << "  " << std::left << std::setw(10) << short_num(p.value, 6) << ' ';
    if (!p.result) {
      o << "refused: " << p.refused << "\n";
      continue;
    }
    const harness::LinearizeResult& r = *p.result;
    int failed = 0;
    for (const harness::LinearCheck& c : r.checks) failed += !c.passed;
    o << (r.passed() ? "PASS" : "FAIL") << " (" << r.checks.size() - static_cast<std::size_t>(failed) << "/"
      << r.checks.size() << ")";
    for (const harness::EngineLinearModel& m : r.engines) {
      if (!m.failure.empty()) continue;
      o << "  " << m.zeros << " zero" << (m.zeros == 1 ? "" : "s") << ";";
      for (const harness::LinearMode& md : m.modes)
        o << ' ' << short_num(md.frequency) << '/' << short_num(md.damping_ratio, 2)
          << (md.lambda.real() > rtol * md.frequency ? "!" : "");
      break;
    }
    for (const std::string& f : r.findings)
      if (f.rfind(r.engines.front().label + ":", 0) == 0) o << "\n             " << f;
    o << "\n";
  }
  o << "(! marks a growing mode)\n";
  return o.str();
}

// The items of a list option (empty and repeated items are refused when the command line is
// parsed: list_option, harness/cli.hpp).
std::vector<std::string> split_list(const std::string& text) {
  std::vector<std::string> items;
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, ',');) items.push_back(item);
  return items;
}

void positive(double v, const std::string& option) {
  if (!(v > 0) || !std::isfinite(v)) throw InputError(option + ": must be a positive, finite number");
}

// What a linearize report owns at the top of its folder; anything else there is carried over.
bool linearize_owned(const std::filesystem::path& name) {
  const std::string ext = name.extension().string();
  return name == "linearize.json" || ext == ".html" || ext == ".png" ||
         (ext == ".json" && name.string().rfind("mode-", 0) == 0) ||
         name.string().find(".crossdyn-") != std::string::npos;
}

// --report DIR: refused before the work when unusable (harness/report.hpp).
std::unique_ptr<harness::StagedFolder> open_report(const LinearizeCommandOptions& o) {
  if (o.report.empty()) return nullptr;
  harness::check_python(o.python);
  return harness::stage_report_folder(o.report, "linearize.json", "linearize", linearize_owned);
}

void write_report(harness::StagedFolder& staged, const std::string& python, const nlohmann::json& summary) {
  const std::filesystem::path summary_path = staged.path() / "linearize.json";
  write_file_atomic(summary_path.string(), summary.dump(1) + "\n");
  harness::run_python(python, {harness::installed_report_script(), summary_path.string(), staged.path().string()});
}

// Every output of the command, opened (and so refused when unusable: exit 2) before the work:
// --json FILE, --csv DIR's files (their names are known from the engines), --report DIR.
struct Outputs {
  std::optional<AtomicFile> json;
  std::vector<std::pair<std::string, std::unique_ptr<AtomicFile>>> csv;  // file name => file
  std::unique_ptr<harness::StagedFolder> report;

  std::ostream* csv_stream(const std::string& name) {
    for (auto& [n, f] : csv)
      if (n == name) return &f->stream();
    return nullptr;
  }
  void commit() {
    std::vector<AtomicFile*> files;
    if (json) files.push_back(&*json);
    for (auto& f : csv) files.push_back(f.second.get());
    commit_together(files, {report.get()});
  }
};

// The CSV files --csv DIR gets (harness::linearization_csv's names; a root locus: one file).
std::vector<std::string> csv_names(const harness::LinearizeOptions& options, bool locus) {
  if (locus) return {"root_locus.csv"};
  std::vector<std::string> n{"states.csv", "inputs.csv", "outputs.csv"};
  for (const harness::LinearEngineChoice& e : options.engines)
    for (const char* m : {"A", "B", "C", "D", "eigenvalues", "own_A"})
      n.push_back(harness::file_safe(e.label + "." + m + ".csv", true));
  return n;
}

void open_outputs(Outputs& out, const LinearizeCommandOptions& o, const std::vector<std::string>& csv) {
  // The report folder first and --csv's folder last: a refused output leaves no folder behind.
  out.report = open_report(o);
  if (!o.json.empty()) {
    if (o.json != "-") harness::make_directories(std::filesystem::path(o.json).parent_path().string());
    out.json.emplace(o.json, "--json");
  }
  if (!o.csv.empty()) {
    harness::make_directories(o.csv);
    for (const std::string& name : csv)
      out.csv.emplace_back(name, std::make_unique<AtomicFile>((std::filesystem::path(o.csv) / name).string(), "--csv"));
  }
}

nlohmann::json locus_json(const System& system, const harness::Knob& knob, const std::vector<LocusPoint>& points) {
  nlohmann::json j;
  j["scene"] = system.name;
  j["vary"] = knob.spec;
  j["unit"] = knob.unit;
  j["points"] = nlohmann::json::array();
  for (const LocusPoint& p : points) {
    nlohmann::json q;
    q["value"] = p.value;
    if (p.result)
      q["linearization"] = nlohmann::json::parse(harness::linearization_json(*p.result));
    else
      q["refused"] = p.refused;
    j["points"].push_back(q);
  }
  return j;
}

// --vary KNOB --values LIST: the linearisation at every value (a root locus). A value whose
// operating point is not an equilibrium is listed as refused, not an error of the sweep.
int locus_command(const LinearizeCommandOptions& o, const harness::LinearizeOptions& options, const System& scene,
                  std::size_t warnings, Outputs& out) {
  if (o.vary.empty() || o.values.empty())
    throw InputError("--vary and --values go together (a root locus: the scene parameter and its values)");
  System system = scene;
  system = harness::apply_settings(system, o.settings);
  const harness::Knob knob = harness::parse_knob(system, o.vary);
  const std::vector<double> values = harness::parse_parameter_values(o.values);
  for (double v : values) (void)harness::apply_knob(system, knob, v);  // refuse bad values first
  std::vector<LocusPoint> points;
  for (double v : values) {
    LocusPoint p;
    p.value = v;
    try {
      p.result = harness::linearize(harness::apply_knob(system, knob, v), options);
    } catch (const InputError& e) {
      const std::string what = e.what();
      if (what.find("is not an equilibrium") == std::string::npos) throw;
      p.refused = what;
    }
    points.push_back(std::move(p));
  }
  if (out.json) out.json->stream() << locus_json(system, knob, points).dump(1) << "\n";
  if (out.report) {
    nlohmann::json s{{"tool", "crossdyn"}, {"kind", "linearize"}, {"scene", system.name}};
    s["locus"] = locus_json(system, knob, points);
    s["locus"]["description"] = knob.description;
    write_report(*out.report, o.python, s);
  }
  if (std::ostream* f = out.csv_stream("root_locus.csv")) {
    *f << "value,engine,re,im,frequency,damping_ratio\n";
    for (const LocusPoint& p : points) {
      if (!p.result) continue;
      for (const harness::EngineLinearModel& m : p.result->engines)
        for (const std::complex<double>& l : m.eigenvalues)
          *f << format_value(p.value) << ',' << m.label << ',' << format_value(l.real()) << ',' << format_value(l.imag())
             << ',' << format_value(std::abs(l)) << ',' << format_value(std::abs(l) > 0 ? -l.real() / std::abs(l) : 0.0)
             << "\n";
    }
  }
  std::cout << format_locus(knob, points, options.rtol);
  check_written(std::cout);
  out.commit();
  if (out.report) std::cout << "report: " << (std::filesystem::path(o.report) / "index.html").string() << "\n";
  bool passed = true;
  for (const LocusPoint& p : points) passed = passed && (!p.result || p.result->passed());
  return harness::strict_status(passed ? kExitOk : kExitCheckFailed, o.strict, warnings);
}

int linearize_command(const LinearizeCommandOptions& o) {
  harness::LinearizeOptions options;
  const std::vector<std::string> known = engine_names();
  for (const std::string& name : o.engines.empty() ? known : harness::parse_names(o.engines, "--engines", known, "engine"))
    options.engines.push_back({name, name, {}});
  for (const std::string& spec : o.test_gyroscopic_sign) {
    const std::string name = harness::parse_names(spec, "--test-gyroscopic-sign", known, "engine").at(0);
    harness::LinearEngineChoice c{name + "*gyro", name, {}};
    c.options.test_gyroscopic_sign = -1.0;
    options.engines.push_back(c);
  }
  if (o.operating_point == "initial")
    options.point = harness::OperatingPoint::Initial;
  else if (o.operating_point == "neutral")
    options.point = harness::OperatingPoint::Neutral;
  else if (o.operating_point == "equilibrium")
    options.point = harness::OperatingPoint::Equilibrium;
  else if (o.operating_point == "spin")
    options.point = harness::OperatingPoint::Spin;
  else
    throw InputError("--operating-point: '" + o.operating_point + "' is not one of initial, neutral, equilibrium, spin");
  if (!(o.time >= 0) || !std::isfinite(o.time)) throw InputError("--time: must be a finite time >= 0 s");
  options.time = o.time;
  positive(o.rtol, "--rtol");
  positive(o.tf_rtol, "--tf-rtol");
  positive(o.residual_tol, "--residual-tol");
  positive(o.zero_tol, "--zero-tol");
  options.rtol = o.rtol;
  options.tf_rtol = o.tf_rtol;
  options.residual_tol = o.residual_tol;
  options.zero_tol = o.zero_tol;
  options.jacobian_only = o.jacobian_only;
  if (o.fd_step != 0) positive(o.fd_step, "--fd-step");
  options.fd_step = o.fd_step;
  options.inputs_given = o.inputs_given;
  if (o.inputs_given && o.inputs != "none") options.inputs = split_list(o.inputs);
  if (!o.outputs.empty()) options.outputs = split_list(o.outputs);

  const std::string scene = harness::resolve_scene(o.scene);
  const harness::CheckedScene checked = harness::read_checked_scene(scene);
  const System& system = checked.system;
  harness::print_warnings(checked.warnings, std::cerr);
  // Every output against every input, and each opened before the work (exit 2 when unusable).
  const bool locus = !o.vary.empty() || !o.values.empty();
  const std::vector<std::string> csv = csv_names(options, locus);
  std::vector<NamedPath> outputs{{"standard output", "-"}};
  if (!o.json.empty()) outputs.push_back({"--json", o.json});
  std::error_code ec;
  if (!o.csv.empty()) {
    if (std::filesystem::exists(o.csv, ec) && !std::filesystem::is_directory(o.csv, ec))
      throw InputError("--csv '" + o.csv + "': a folder is needed (it gets one CSV file per matrix)");
    for (const std::string& name : csv) outputs.push_back({"--csv", (std::filesystem::path(o.csv) / name).string()});
  }
  std::vector<NamedPath> folders;
  if (!o.report.empty()) folders.push_back({"--report", o.report});
  std::vector<NamedPath> inputs = harness::scene_inputs(system);
  if (!o.report.empty()) inputs.push_back({"the report script", harness::installed_report_script()});
  check_outputs_are_not_inputs(outputs, inputs, folders);
  Outputs out;
  open_outputs(out, o, csv);

  if (locus) return locus_command(o, options, system, checked.warnings.size(), out);
  const System set = harness::apply_settings(system, o.settings);
  // The linear models (may refuse a point that is not an equilibrium: exit 2, nothing written).
  const harness::LinearizeResult r = harness::linearize(set, options);
  if (out.report) {
    nlohmann::json s{{"tool", "crossdyn"}, {"kind", "linearize"}, {"scene", set.name}};
    s["linearization"] = nlohmann::json::parse(harness::linearization_json(r));
    s["mode_pictures"] = nlohmann::json::array();
    // The first engine's modes drawn (at most 12), each from its own output rows.
    for (std::size_t e = 0; e < r.engines.size(); ++e) {
      if (!r.engines[e].failure.empty() || !r.equilibrium) continue;
      for (std::size_t k = 0; k < r.engines[e].modes.size() && k < 12; ++k) {
        const std::string geometry = harness::mode_geometry(set, options, r, e, k);
        nlohmann::json pic{{"engine", r.engines[e].label}, {"mode", k + 1}, {"coordinate", r.engines[e].modes[k].coordinate}};
        if (!geometry.empty()) {
          const std::string name = "mode-" + std::to_string(k + 1) + ".json";
          write_file_atomic((out.report->path() / name).string(), geometry);
          pic["geometry"] = name;
        }
        s["mode_pictures"].push_back(pic);
      }
      break;
    }
    write_report(*out.report, o.python, s);
  }
  if (out.json) out.json->stream() << harness::linearization_json(r);
  for (const auto& [name, content] : harness::linearization_csv(r))
    if (std::ostream* f = out.csv_stream(name)) *f << content;
  std::cout << harness::format_linearization(r);
  check_written(std::cout);
  out.commit();
  if (out.report) std::cout << "report: " << (std::filesystem::path(o.report) / "index.html").string() << "\n";
  return harness::strict_status(r.passed() ? kExitOk : kExitCheckFailed, o.strict, checked.warnings.size());
}

}  // namespace

void add_linearize_command(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<LinearizeCommandOptions>();
  CLI::App* sub = app.add_subcommand(
      "linearize",
      "Linearise every engine's equations about an equilibrium or a steady spin (the scene's\n"
      "initial state at --time, or --operating-point neutral) in the same reduced coordinates\n"
      "(joint coordinates and rates, a free base's angular velocity, modal coordinates and\n"
      "rates), and compare their eigenvalues (frequency and damping per mode) and transfer\n"
      "functions between engines. A state that is not an equilibrium is refused with its\n"
      "residual (exit 2) unless --jacobian-only. Unstable modes are reported as findings.\n"
      "Exit status 0 all agree, 1 a check failed, 2 bad input, 3 a write failed.");
  sub->add_option("scene", o->scene, "Scene file (YAML), or a scene name (crossdyn list)")->required();
  list_option(sub->add_option("--engines", o->engines,
                              "Comma-separated engines (default: kane,lagrange,newton-euler)"));
  sub->add_option("--operating-point", o->operating_point,
                  "initial (the scene's initial state, default); neutral (joints at their springs' "
                  "neutral angles, every rate and modal coordinate zero, the base's spin kept); "
                  "equilibrium (neutral, then the joint and modal coordinates solved for an "
                  "equilibrium); spin (equilibrium about the whole spacecraft's principal axis "
                  "nearest the initial base rate, |I w0| kept)");
  sub->add_option("--time", o->time, "Operating time, s (prescribed joints' profiles and motors at it; default 0)");
  list_option(sub->add_option("--inputs", o->inputs,
                  "Comma-separated inputs: <joint>.motor, .motor1/.motor2 (universal), .motorx/y/z "
                  "(spherical), <body>.Tx/Ty/Tz; `none` for none (default: every motor and body "
                  "torque the scene names)"))
      ->each([o](const std::string&) { o->inputs_given = true; });
  list_option(sub->add_option("--outputs", o->outputs, "Comma-separated pinned output columns (C and D; default none)"));
  sub->add_option("--rtol", o->rtol, "Eigenvalue agreement: |l_a - l_b| <= rtol |l_a| + 1e-12 |l|max (default 1e-8)");
  sub->add_option("--tf-rtol", o->tf_rtol, "Transfer-function agreement, relative to the largest |G| (default 1e-7)");
  sub->add_option("--residual-tol", o->residual_tol,
                  "An equilibrium: |dz/dt| <= this x |A| max(|z|, 1) (default 1e-9)");
  sub->add_option("--zero-tol", o->zero_tol,
                  "An eigenvalue below this x the spectral radius is a rigid-body zero (default 1e-6)");
  sub->add_flag("--jacobian-only", o->jacobian_only,
                "At a state that is not an equilibrium: write each engine's Jacobian "
                "(coordinate-dependent, never compared) instead of refusing");
  sub->add_option("--fd-step", o->fd_step,
                  "The first central-difference step of the Jacobians, times max(|z_j|, 1), halved twice "
                  "for the extrapolation (default: per column, the one of 1e-1 .. 1e-3 with the "
                  "smallest estimated error)");
  sub->add_option("--json", o->json, "Write A, B, C, D, eigenvalues and checks as JSON to FILE (atomically)");
  sub->add_option("--csv", o->csv, "Write one CSV file per matrix into the folder DIR");
  sub->add_option("--report", o->report,
                  "Write pages into DIR: the eigenvalues of every engine overlaid, their differences, "
                  "each mode drawn on the scene (or the root locus with --vary)");
  sub->add_option("--python", o->python, "Python with matplotlib and Jinja2 for --report (default /usr/bin/python3)");
  sub->add_flag("--strict", o->strict, "Exit with status 1 when the scene has a warning");
  sub->add_option("--vary", o->vary,
                  "A root locus: linearise at every value of this scene parameter (the knobs of "
                  "`crossdyn stability --vary`: <joint>.stiffness, <joint>.rate, <joint>.wx/wy/wz, "
                  "<joint>.prescribed_rate, <body>.modal_stiffness, <body>.modal_damping, ...)");
  list_option(sub->add_option("--values", o->values, "With --vary: a list 1,10,100 or a range 1..1e4 (one per decade)"));
  sub->add_option("--set", o->settings, "KNOB=VALUE: a scene parameter set first (the knobs of --vary; several allowed)");
  // Test hook (hidden): a copy of ENGINE with its gyroscopic term's sign flipped.
  sub->add_option("--test-gyroscopic-sign", o->test_gyroscopic_sign,
                  "Add a copy of ENGINE with the sign of its gyroscopic term w x I w flipped; for tests")
      ->group("");
  sub->callback([o, &exit_code] { exit_code = linearize_command(*o); });
}

}  // namespace crossdyn
