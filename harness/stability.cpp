// `crossdyn stability`: where each method fails (see stability.hpp).
#include "harness/stability.hpp"

#include "core/engine.hpp"
#include "core/errors.hpp"
#include "core/output.hpp"
#include "core/progress.hpp"
#include "core/scene/scene.hpp"
#include "harness/compare.hpp"
#include "harness/engines.hpp"
#include "harness/numbers.hpp"

#include <cctype>
#include <new>
#include <cstdlib>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <exception>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

namespace crossdyn::harness {

namespace {


std::string g3(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

// "the reference run kane + rkf78 at 1e-13 failed: ..." from the study's refusal
// "<file>: no reference: the reference run ...".
std::string no_reference_reason(const std::string& note) {
  const std::string mark = "no reference: ";
  const std::size_t at = note.find(mark);
  return at == std::string::npos ? note : note.substr(at + mark.size());
}

bool contains(const std::string& text, const char* what) { return text.find(what) != std::string::npos; }

// rk4's stability boundary along the imaginary axis is 2 sqrt(2) = 2.83, along the real axis 2.79
// (Hairer and Wanner, Solving ODEs II, Sec. IV.2, Fig. 2.1): 2.8 for a mixed spectrum.
constexpr double kRk4Limit = 2.8;

}  // namespace

const char* class_name(StabilityClass c) {
  switch (c) {
    case StabilityClass::Accurate: return "accurate";
    case StabilityClass::Inaccurate: return "inaccurate";
    case StabilityClass::Drift: return "drift";
    case StabilityClass::Diverged: return "diverged";
    case StabilityClass::Singular: return "singular";
    case StabilityClass::TooCostly: return "too costly";
    case StabilityClass::NoReference: return "no reference";
  }
  return "?";
}

Classified classify(const CellFacts& f, const ClassLimits& lim) {
  if (!f.reference)
    return {StabilityClass::NoReference,
            f.failure.empty() ? std::string("no reference at this parameter value")
                              : "no reference at this parameter value (" + no_reference_reason(f.failure) + ")"};
  if (!f.ok) {
    const std::string& w = f.failure;
    if (contains(w, "singularity") || contains(w, "gimbal lock")) return {StabilityClass::Singular, w};
    if (contains(w, "step limit") || contains(w, "time limit") || contains(w, "timed out") ||
        contains(w, "deadline"))
      return {StabilityClass::TooCostly, w};
    return {StabilityClass::Diverged, w.empty() ? "the run failed" : w};
  }
  const double e = f.history_error;
  if (!std::isfinite(e) || e > lim.diverged_error)
    return {StabilityClass::Diverged,
            "history error " + sci(e, 2) + " > " + sci(lim.diverged_error, 2) + " (the state grew far beyond the motion)"};
  const bool drift_H = f.H_conserved && !(f.drift_H <= lim.drift_limit);
  const bool drift_E = f.E_conserved && !(f.drift_E <= lim.drift_limit);
  if (drift_H || drift_E) {
    std::string why;
    if (drift_H) why += "H drifts by " + sci(f.drift_H, 2);
    if (drift_E)
      why += std::string(why.empty() ? "" : ", ") + (f.orbit ? "J" : "E") + " drifts by " + sci(f.drift_E, 2);
    return {StabilityClass::Drift, why + " (relative) > " + sci(lim.drift_limit, 2)};
  }
  if (e <= lim.tolerance)
    return {StabilityClass::Accurate, "history error " + sci(e, 2) + " <= " + sci(lim.tolerance, 2)};
  return {StabilityClass::Inaccurate, "history error " + sci(e, 2) + " > " + sci(lim.tolerance, 2)};
}

// ---- knobs -----------------------------------------------------------------------------------

std::vector<std::string> available_knobs(const System& s) {
  std::vector<std::string> k;
  for (const Joint& j : s.joints) {
    const bool axial = j.type == JointType::Revolute || j.type == JointType::Prismatic;
    if (axial && j.prescribed)
      k.push_back(j.name + (j.prescribed->profile == PrescribedMotion::Profile::Deploy
                                ? ".prescribed_travel"
                                : ".prescribed_rate"));
    else if (axial) k.push_back(j.name + ".rate");
    if ((axial || j.type == JointType::Spherical || j.type == JointType::Universal) && !j.prescribed)
      k.push_back(j.name + ".stiffness");
    if (j.type == JointType::Free)
      for (const char* c : {".wx", ".wy", ".wz"}) k.push_back(j.name + c);
  }
  for (const Body& b : s.bodies)
    if (b.flex && b.flex->modes() > 0) {
      k.push_back(b.name + ".modal_stiffness");
      k.push_back(b.name + ".modal_damping");
    }
  k.push_back("duration");
  if (s.name.rfind("chain", 0) == 0) k.push_back("links");
  return k;
}

Knob parse_knob(const System& s, const std::string& spec) {
  Knob k;
  k.spec = spec;
  auto fail = [&](const std::string& what) {
    std::string list;
    for (const std::string& x : available_knobs(s)) list += (list.empty() ? "" : ", ") + x;
    throw InputError("--vary '" + spec + "': " + what + " (this scene offers: " + list + ")");
  };
  if (spec == "duration") {
    k.kind = Knob::Kind::Duration;
    k.unit = "s";
    k.description = "the run's duration (horizon)";
    return k;
  }
  if (spec == "links") {
    if (s.name.rfind("chain", 0) != 0) fail("`links` needs a chainN scene");
    k.kind = Knob::Kind::Links;
    k.description = "the number of links of chainN";
    return k;
  }
  const std::size_t dot = spec.rfind('.');
  if (dot == std::string::npos || dot == 0) fail("expected <joint or body>.<what>, duration or links");
  const std::string name = spec.substr(0, dot), what = spec.substr(dot + 1);
  int joint = -1;
  for (std::size_t j = 0; j < s.joints.size(); ++j)
    if (s.joints[j].name == name) joint = static_cast<int>(j);
  const int body = s.body_index(name);
  if (joint >= 0) {
    const Joint& J = s.joints[static_cast<std::size_t>(joint)];
    k.index = joint;
    const bool prismatic = J.type == JointType::Prismatic;
    const bool axial = J.type == JointType::Revolute || prismatic;
    const bool deploy = J.prescribed && J.prescribed->profile == PrescribedMotion::Profile::Deploy;
    const bool universal = J.type == JointType::Universal;
    if (what == "stiffness" && (axial || J.type == JointType::Spherical || universal) && !J.prescribed) {
      k.kind = Knob::Kind::JointStiffness;
      k.unit = prismatic ? "N/m" : "N m/rad";
      k.description = "the spring stiffness of joint '" + name + "'" + (universal ? " (both axes)" : "");
      return k;
    }
    if (what == "rate" && axial && !J.prescribed) {
      k.kind = Knob::Kind::JointRate;
      k.unit = prismatic ? "m/s" : "rad/s";
      k.description = "the initial rate of joint '" + name + "'";
      return k;
    }
    if (what == "prescribed_rate" && J.prescribed && !deploy) {
      k.kind = Knob::Kind::PrescribedRate;
      k.unit = prismatic ? "m/s" : "rad/s";
      k.description = "the final prescribed rate of joint '" + name + "'";
      return k;
    }
    if (what == "prescribed_travel" && deploy) {
      k.kind = Knob::Kind::PrescribedTravel;
      k.unit = prismatic ? "m" : "rad";
      k.description = "the prescribed deployment travel of joint '" + name + "'";
      return k;
    }
    if ((what == "wx" || what == "wy" || what == "wz") && J.type == JointType::Free) {
      k.kind = Knob::Kind::BaseRate;
      k.component = what[1] - 'x';
      k.unit = "rad/s";
      k.description = "the initial angular velocity " + what + " of free joint '" + name + "' (w_NB_B)";
      return k;
    }
    fail("joint '" + name + "' has no '" + what + "' to vary");
  }
  if (body >= 0) {
    if (what == "modal_stiffness" && s.bodies[static_cast<std::size_t>(body)].flex) {
      k.kind = Knob::Kind::ModalStiffness;
      k.index = body;
      k.description = "the modal stiffness of body '" + name + "' (scale on K)";
      return k;
    }
    if (what == "modal_damping" && s.bodies[static_cast<std::size_t>(body)].flex) {
      k.kind = Knob::Kind::ModalDamping;
      k.index = body;
      k.description = "the modal damping ratio of body '" + name + "' (every mode)";
      return k;
    }
    fail("body '" + name + "' has no '" + what + "' to vary");
  }
  fail("no joint or body '" + name + "'");
  return k;
}

System apply_knob(const System& s, const Knob& k, double v) {
  auto bad = [&](const std::string& what) {
    throw InputError("--values: " + g3(v) + " for " + k.spec + ": " + what);
  };
  if (!std::isfinite(v)) bad("not a finite number");
  // The scene reader's bounds on any value (core/scene/reader.hpp): a knob is a scene value.
  if (v != 0 && std::abs(v) < 1e-100) bad("too small to compute with (the allowed magnitudes are 0 and 1e-100 to 1e12)");
  if (std::abs(v) > 1e12) bad("absurd (the allowed magnitudes are 0 and 1e-100 to 1e12)");
  if (k.kind == Knob::Kind::Links) {
    if (v < 1 || v > 512 || v != std::floor(v)) bad("the number of links must be a whole number from 1 to 512");
    System c = read_scene_text(chain_scene_text(static_cast<int>(v)),
                               "chain" + std::to_string(static_cast<int>(v)) + " (generated)");
    c.run = s.run;
    c.compare = s.compare;
    return c;
  }
  System c = s;
  switch (k.kind) {
    case Knob::Kind::JointStiffness:
      if (v < 0) bad("a stiffness must be >= 0");
      c.joints[static_cast<std::size_t>(k.index)].stiffness = v;
      if (c.joints[static_cast<std::size_t>(k.index)].type == JointType::Universal)
        c.joints[static_cast<std::size_t>(k.index)].stiffness2 = v;  // both axes
      break;
    case Knob::Kind::JointRate:
      if (std::abs(v) > 1e4) bad("at most 1e4 " + k.unit);
      c.joints[static_cast<std::size_t>(k.index)].rate0 = v;
      break;
    case Knob::Kind::PrescribedRate:
      if (std::abs(v) > 1e4) bad("at most 1e4 " + k.unit);
      c.joints[static_cast<std::size_t>(k.index)].prescribed->rate = v;
      break;
    case Knob::Kind::PrescribedTravel:
      if (std::abs(v) > (k.unit == "m" ? 1e6 : 1e4)) bad(k.unit == "m" ? "at most 1e6 m" : "at most 1e4 rad");
      c.joints[static_cast<std::size_t>(k.index)].prescribed->travel = v;
      break;
    case Knob::Kind::BaseRate:
      if (std::abs(v) > 1e4) bad("at most 1e4 rad/s");
      c.joints[static_cast<std::size_t>(k.index)].w_NB_B0[k.component] = v;
      break;
    case Knob::Kind::ModalStiffness: {
      if (!(v > 0)) bad("the scale must be positive");
      FlexBody& f = *c.bodies[static_cast<std::size_t>(k.index)].flex;
      f.K *= v;
      break;
    }
    case Knob::Kind::ModalDamping: {
      if (!(v >= 0) || v > 100) bad("a damping ratio must be from 0 to 100");
      FlexBody& f = *c.bodies[static_cast<std::size_t>(k.index)].flex;
      if (!f.K.isDiagonal(0.0)) bad("the body's K is not diagonal, so its modes have no ratio of their own");
      f.D.setZero();
      for (int m = 0; m < f.modes(); ++m) {
        double M = 0;  // the node-sum modal mass sum_i m_i |Phi_im|^2
        for (const FlexNode& node : f.nodes) M += node.mass * node.Phi_B.col(m).squaredNorm();
        f.D(m, m) = 2 * v * std::sqrt(f.K(m, m) * M);
      }
      break;
    }
    case Knob::Kind::Duration:
      if (!(v > 0) || v > 1e7) bad("the duration must be positive and at most 1e7 s");
      c.run.duration = v;
      if (c.run.output_step > v) c.run.output_step = v;
      // At most 2000 output rows: a long horizon keeps the map's runs comparable.
      c.run.output_step = std::max(c.run.output_step, v / 2000);
      break;
    case Knob::Kind::Links: break;
  }
  return c;
}

System apply_settings(const System& system, const std::vector<std::string>& settings) {
  for (std::size_t i = 0; i < settings.size(); ++i) {  // a knob set twice is refused
    const std::string knob = settings[i].substr(0, settings[i].find('='));
    for (std::size_t j = 0; j < i; ++j)
      if (settings[j].substr(0, settings[j].find('=')) == knob)
        throw InputError("--set: '" + knob + "' is set twice ('" + settings[j] + "', '" + settings[i] + "')");
  }
  System out = system;
  for (const std::string& setting : settings) out = apply_setting(out, setting);
  return out;
}

System apply_setting(const System& system, const std::string& setting) {
  const std::size_t eq = setting.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == setting.size())
    throw InputError("--set '" + setting + "': expected KNOB=VALUE, e.g. array.modal_stiffness=1000");
  const std::string value = setting.substr(eq + 1);
  // strtod, not std::stod: 1e-320 and 1e400 are numbers, refused by apply_knob with the bounds
  // (std::stod's out_of_range made them "not a number").
  char* end = nullptr;
  const double v = std::strtod(value.c_str(), &end);
  if (end == value.c_str() || end != value.c_str() + value.size() || std::isspace(static_cast<unsigned char>(value[0])))
    throw InputError("--set '" + setting + "': '" + value + "' is not a number");
  return apply_knob(system, parse_knob(system, setting.substr(0, eq)), v);
}

// ---- the sweep ---------------------------------------------------------------------------------

std::vector<EngineSpec> parse_engine_variants(const std::string& text, const std::string& option) {
  std::vector<EngineSpec> out;
  if (text.empty()) return out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    const std::size_t colon = item.find(':');
    EngineSpec sp{item, item.substr(0, colon), {}};
    const std::vector<std::string> known = engine_names();
    if (std::find(known.begin(), known.end(), sp.engine) == known.end()) {
      std::string list;
      for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
      throw InputError(option + ": unknown engine '" + sp.engine + "' (known: " + list + ")");
    }
    if (colon != std::string::npos) {
      const std::string variant = item.substr(colon + 1);
      if (sp.engine == "newton-euler" && (variant == "none" || variant == "baumgarte" || variant == "projection"))
        sp.options.stabilization = variant;
      else if (sp.engine == "lagrange" && variant == "no-rechart")
        sp.options.rechart = false;
      else
        throw InputError(option + ": unknown variant '" + variant + "' of " + sp.engine +
                         " (newton-euler:none|baumgarte|projection, lagrange:no-rechart)");
    }
    for (const EngineSpec& e : out)
      if (e.label == sp.label) throw InputError(option + ": '" + sp.label + "' is listed twice");
    out.push_back(sp);
  }
  return out;
}

std::string StabilityCell::setting_text() const {
  return (fixed_step ? "dt " : "rtol ") + g3(setting);
}

double jacobian_spectral_radius(const System& system, const std::string& engine_name) {
  try {
    std::unique_ptr<Engine> e = make_engine(engine_name, system, EngineOptions{});
    const int n = e->state_size();
    if (n <= 0 || n > 400) return kNaN;
    Eigen::VectorXd x(n), xp(n), xm(n), fp(n), fm(n);
    e->pack(TreeState::initial(system), x.data());
    Eigen::MatrixXd J(n, n);
    for (int j = 0; j < n; ++j) {
      const double h = 1e-6 * (1 + std::abs(x(j)));
      xp = x;
      xm = x;
      xp(j) += h;
      xm(j) -= h;
      e->rhs(0.0, xp.data(), fp.data());
      e->rhs(0.0, xm.data(), fm.data());
      J.col(j) = (fp - fm) / (2 * h);
    }
    if (!J.allFinite()) return kNaN;
    const Eigen::VectorXcd ev = Eigen::EigenSolver<Eigen::MatrixXd>(J, false).eigenvalues();
    double r = 0;
    for (Eigen::Index i = 0; i < ev.size(); ++i) r = std::max(r, std::abs(ev(i)));
    return r;
  } catch (const std::bad_alloc&) {
    throw;  // out of memory: the command's error (exit 3), not an unknown radius
  } catch (const std::exception&) {
    return kNaN;
  }
}

namespace {

std::string seconds_text(double s) { return s > 0 ? g3(s) + " s" : std::string("no limit"); }

// The reference runs' budget, said once in the map's notes (a study note: parts carry it).
std::string reference_budget_note(const StabilityOptions& o) {
  return "the reference runs had their own time budget, " + seconds_text(o.reference_timeout) +
         " each (--reference-timeout), independent of the per-run --timeout (" +
         seconds_text(o.timeout) + ")";
}

// How the reference of each value is made, said once in the map's notes (a study note).
std::string reference_method_note(const StabilityMap& m, double tolerance) {
  return "the reference at each value is the mean of two independent runs (two engines, each with "
         "its own integrator, dop853 and rkf78; one engine: at both) at rtol " +
         g3(tolerance) + " (atol 1e-4 x rtol; " + g3(kReferenceTolerancePerLimit) + " x the accuracy limit " +
         g3(m.limits.tolerance) + ", within 1e-13 to 1e-8), made again at 1e-13 where they agree "
         "to less than " + g3(kReferenceRetry) + " x the limit; each column states its runs and "
         "their agreement, the reference's own error";
}

// Runs ended early by their pace (StabilityOptions::give_up_factor), said once.
std::string give_up_note(const StabilityOptions& o) {
  return "a run whose pace over a tenth of its step limit showed it would need more than " +
         g3(o.give_up_factor) + " x the steps left to finish was stopped early as too costly (its "
         "reason says \"stopped early\" and gives the prediction; its steps and right-hand sides "
         "are those made until then)";
}

std::vector<EngineSpec> engine_specs_of(const StabilityOptions& o) {
  std::vector<EngineSpec> specs = o.engine_specs;
  if (specs.empty())
    for (const std::string& e : o.engines.empty() ? engine_names() : o.engines) specs.push_back({e, e, {}});
  return specs;
}

}  // namespace

StabilityMap stability_frame(const System& system, const Knob& knob, const StabilityOptions& o) {
  StabilityMap m;
  m.scene = system.name;
  m.file = system.file;
  m.knob = knob;
  for (const EngineSpec& sp : engine_specs_of(o)) m.engines.push_back(sp.label);
  m.integrators = o.integrators.empty()
                      ? std::vector<std::string>{"rk4", "dopri5", "dop853", "cvode-bdf"}
                      : o.integrators;
  m.limits.tolerance = o.tolerance ? *o.tolerance : kStabilityAccuracy;
  m.limits.drift_limit = o.drift_limit;
  return m;
}

namespace {

// The reference of a map (stability.hpp, "The reference"): the engines in the order they are
// tried (kane and newton-euler first: minimal and maximal coordinates, the cheapest pair), two
// runs, each engine with its own integrator.
std::vector<EngineSpec> reference_engines_of(const std::vector<EngineSpec>& specs) {
  std::vector<std::string> names;
  for (const EngineSpec& sp : specs)
    if (std::find(names.begin(), names.end(), sp.engine) == names.end()) names.push_back(sp.engine);
  std::vector<EngineSpec> out;
  for (const char* preferred : {"kane", "newton-euler", "lagrange"})
    if (std::find(names.begin(), names.end(), preferred) != names.end()) out.push_back({preferred, preferred, {}});
  for (const std::string& n : names)
    if (n != "kane" && n != "newton-euler" && n != "lagrange") out.push_back({n, n, {}});
  return out;
}

// The study options of one value (stability_value and stability_values).
StudyOptions study_options_of(const StabilityMap& m, const StabilityOptions& o, double reference_tolerance) {
  const std::vector<EngineSpec> specs = engine_specs_of(o);
  StudyOptions so;
  so.engine_specs = specs;
  so.integrators = m.integrators;
  so.tolerances = o.tolerances.empty() ? std::vector<double>{1e-3, 1e-6, 1e-9, 1e-12} : o.tolerances;
  so.dts = o.dts;
  so.repeat = 1;
  so.max_steps = o.max_steps;
  so.reference_max_steps = 20000000;  // the reference may be costly; its own time budget holds
  so.timeout = o.timeout;
  so.reference_timeout = o.reference_timeout;
  so.give_up_factor = o.give_up_factor;
  so.progress = nullptr;  // the scheduler draws it (the runs may be on several threads)
  so.reference_engines = reference_engines_of(specs);
  so.reference_integrators = {"dop853", "rkf78"};
  so.reference_run_limit = 2;
  so.reference_tolerance = reference_tolerance;
  // atol = 1e-4 x rtol, as the study's (StudyOptions::reference_atol_factor): with atol = rtol a
  // scene whose panel vibrates at 5e-6 /s had no reference at any value (its two runs differed by
  // 1.3e-5 of the modal rates' scale, issue 24's trial).
  // The reference must be better than what `accurate` means (half the limit), not the study's
  // 1e-11: stiff and fast scenes accumulate rounding at 1e-13 (the reference runs of
  // hub_flex_array with K x 1e4 agree to 3e-8), and a map of 1e-6 accuracy needs no better.
  // (Not the study's default either, which accepts a reference good to 1e-5 and declines targets.)
  so.reference_agreement = std::max(1e-11, 0.5 * m.limits.tolerance);
  return so;
}

// One value's work while the sweep runs: its scene, setup, reference runs and rows.
struct ValueWork {
  double value = 0;
  System scene;
  StabilityColumn column;
  std::unique_ptr<StudySetup> setup;
  std::vector<History> reference_runs;
  std::size_t reference_left = 0;
  std::unique_ptr<StudyBaseline> baseline;
  std::unique_ptr<ErrorMetric> metric;
  std::optional<std::string> refused;  // StudyRefused's text
  std::vector<double> cpu;             // per row
};

// A unit of work: a reference run of a value, or a chain of its rows.
struct Task {
  std::size_t value = 0;
  bool reference = false;
  std::size_t index = 0;  // the reference run, or the chain
};

// The sweep's runs on `jobs` threads (1: the calling thread alone). Tasks: first every value's
// reference runs, then, as each value's reference is made, its chains of rows. Shared state is
// only the queue and the counters, under one mutex; each task writes only its own value's
// reference slot or its chain's rows. The first exception (an interrupt: cancel::Cancelled)
// stops the other workers after their current run (which an interrupt also ends) and is
// rethrown here.
class Sweep {
 public:
  Sweep(std::vector<ValueWork>& work, const StabilityMap& m, const StabilityOptions& o)
      : work_(work), map_(m), o_(o) {}

  void run(int jobs) {
    for (std::size_t v = 0; v < work_.size(); ++v) {
      ValueWork& w = work_[v];
      if (w.refused) continue;
      w.reference_left = w.setup->reference_runs.size();
      w.reference_runs.assign(w.reference_left, History{});
      total_ += w.reference_left;
      if (w.reference_left == 0) reference_done(v);  // analytic: the cells at once
      for (std::size_t i = 0; i < w.reference_runs.size(); ++i) queue_.push_back({v, true, i});
    }
    for (ValueWork& w : work_)
      if (w.setup && !w.refused) total_ += w.setup->rows.size();
    if (jobs <= 1) {
      worker();
    } else {
      std::vector<std::thread> threads;
      for (int j = 0; j < jobs; ++j) threads.emplace_back([this] { worker(); });
      for (std::thread& t : threads) t.join();
    }
    if (error_) std::rethrow_exception(error_);
  }

 private:
  void worker() {
    for (;;) {
      Task t;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [this] { return error_ || !queue_.empty() || running_ == 0; });
        if (error_ || queue_.empty()) {
          wake_.notify_all();
          return;
        }
        t = queue_.front();
        queue_.pop_front();
        ++running_;
      }
      try {
        do_task(t);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!error_) error_ = std::current_exception();
      }
      std::lock_guard<std::mutex> lock(mutex_);
      --running_;
      wake_.notify_all();
    }
  }

  void do_task(const Task& t) {
    ValueWork& w = work_[t.value];
    if (t.reference) {
      show(map_.knob.spec + " = " + g3(w.value) + ", reference run " + w.setup->reference_runs[t.index].label);
      std::optional<std::string> refused;
      History h;
      try {
        h = study_reference_run(*w.setup, t.index);
      } catch (const StudyRefused& r) {
        refused = r.what();
      }
      std::lock_guard<std::mutex> lock(mutex_);
      count_run(w);
      if (refused && !w.refused) w.refused = refused;
      w.reference_runs[t.index] = std::move(h);
      if (--w.reference_left == 0) reference_done(t.value);  // under the mutex: cheap
      return;
    }
    const std::vector<std::size_t>& chain = w.setup->chains[t.index];
    for (std::size_t k = 0; k < chain.size(); ++k) {
      StudyRow& row = w.setup->rows[chain[k]];
      const std::string skip = study_skip_reason(w.setup->rows, chain, k);
      if (!skip.empty()) {
        row.failure = skip;
      } else {
        show(map_.knob.spec + " = " + g3(w.value) + ", " + row.engine + " + " + row.integrator +
             " at " + row.setting());
        w.cpu[chain[k]] = study_run_row(*w.setup, *w.metric, row, true);
      }
      std::lock_guard<std::mutex> lock(mutex_);
      count_run(w);
    }
  }

  // The reference runs of value v are done (the mutex is held): the baseline, a retry at the
  // tightest tolerance when the two runs agree to less than a tenth of the accuracy limit, or
  // the value's chains queued.
  void reference_done(std::size_t v) {
    ValueWork& w = work_[v];
    const double tight = 1e-13;
    const bool can_tighten = !w.setup->analytic && w.setup->options.reference_tolerance > tight;
    if (!w.refused) {
      try {
        StudyBaseline b = study_baseline(*w.setup, w.reference_runs);
        if (can_tighten && !(b.reference.agreement <= kReferenceRetry * map_.limits.tolerance)) {
          retry(v);
          return;
        }
        w.baseline = std::make_unique<StudyBaseline>(std::move(b));
      } catch (const StudyRefused& r) {
        if (can_tighten && r.exit_status() == kExitCheckFailed) {  // they disagree: tighter
          retry(v);
          return;
        }
        w.refused = r.what();
      }
    }
    if (w.refused) {
      done_ += w.setup->rows.size();  // no cell is run
      return;
    }
    w.metric = std::make_unique<ErrorMetric>(w.setup->system, w.baseline->history);
    w.cpu.assign(w.setup->rows.size(), 0.0);
    for (std::size_t c = 0; c < w.setup->chains.size(); ++c) queue_.push_back({v, false, c});
    wake_.notify_all();
  }

  void retry(std::size_t v) {
    ValueWork& w = work_[v];
    StudyOptions so = w.setup->options;
    so.reference_tolerance = 1e-13;
    w.setup = std::make_unique<StudySetup>(study_setup(w.scene, so));
    w.reference_left = w.setup->reference_runs.size();
    w.reference_runs.assign(w.reference_left, History{});
    total_ += w.reference_left;
    for (std::size_t i = 0; i < w.reference_left; ++i) queue_.push_front({v, true, i});
    wake_.notify_all();
  }

  // A run is done (the mutex is held): the progress line.
  void count_run(const ValueWork& w) {
    ++done_;
    show_locked(map_.knob.spec + " = " + g3(w.value) + ": " + std::to_string(done_) + " of " +
                std::to_string(total_) + " runs done");
  }
  // "<what>: 12 of 300 runs done".
  void show(const std::string& what) {
    std::lock_guard<std::mutex> lock(mutex_);
    show_locked(what + ": " + std::to_string(done_) + " of " + std::to_string(total_) + " runs done");
  }
  void show_locked(const std::string& text) {
    if (!o_.progress) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ < std::chrono::milliseconds(250)) return;
    last_ = now;
    o_.progress->phase(text);
  }

  std::vector<ValueWork>& work_;
  const StabilityMap& map_;
  const StabilityOptions& o_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Task> queue_;
  int running_ = 0;
  std::size_t done_ = 0, total_ = 0;
  std::exception_ptr error_;
  std::chrono::steady_clock::time_point last_{};
};

}  // namespace

std::vector<StabilityValue> stability_values(const System& system, const Knob& knob,
                                             const std::vector<double>& values, const StabilityMap& m,
                                             const StabilityOptions& o) {
  const std::vector<EngineSpec> specs = engine_specs_of(o);
  const double reference_tolerance =
      std::clamp(kReferenceTolerancePerLimit * m.limits.tolerance, 1e-13, 1e-8);
  // Each value's scene, |lambda|max and setup, here (cheap); the runs in the sweep.
  std::vector<ValueWork> work(values.size());
  for (std::size_t k = 0; k < values.size(); ++k) {
    ValueWork& w = work[k];
    w.value = values[k];
    w.scene = apply_knob(system, knob, values[k]);
    w.column.value = values[k];
    for (const EngineSpec& sp : specs) w.column.lambda_max.push_back(jacobian_spectral_radius(w.scene, sp.engine));
    StudyOptions so = study_options_of(m, o, reference_tolerance);
    if (so.dts.empty())
      for (int i = 0; i <= 6; ++i) so.dts.push_back(w.scene.run.output_step / std::pow(2.0, i));
    w.setup = std::make_unique<StudySetup>(study_setup(w.scene, so));
  }
  if (o.progress) o.progress->start(system.name + " stability", 0);
  Sweep(work, m, o).run(std::max(1, o.jobs));
  if (o.progress) o.progress->clear();

  std::vector<StabilityValue> out;
  for (ValueWork& w : work) {
    StabilityValue sv;
    StabilityColumn& col = sv.column;
    col = w.column;
    const System& s = w.scene;
    const StudySetup& u = *w.setup;
    auto lambda_of = [&](const std::string& label) {
      for (std::size_t e = 0; e < specs.size(); ++e)
        if (specs[e].label == label) return col.lambda_max[e];
      return kNaN;
    };
    const std::size_t c = 0;  // add_stability_value sets the map's column
    if (!w.refused) {
      const bool H_conserved = momentum_not_conserved_reason(s).empty();
      // On an orbit the conserved energy-like quantity is the Jacobi integral (StudyRow::drift_E).
      const bool orbit = s.environment.orbit();
      const bool E_conserved = orbit ? jacobi_not_conserved_reason(s).empty() : energy_not_conserved_reason(s).empty();
      col.reference_note = w.baseline->reference.description;
      sv.study_notes = u.notes;
      if (!u.analytic) {
        sv.study_notes.push_back(reference_method_note(m, reference_tolerance));
        sv.study_notes.push_back(reference_budget_note(o));
      }
      for (const StudyRow& r : u.rows)
        if (contains(r.failure, "stopped early")) {
          sv.study_notes.push_back(give_up_note(o));
          break;
        }
      for (std::size_t i = 0; i < u.rows.size(); ++i) {
        StudyRow r = u.rows[i];
        study_set_cpu(r, {w.cpu[i]});
        StabilityCell cell;
        cell.engine = r.engine;
        cell.integrator = r.integrator;
        cell.fixed_step = r.fixed_step;
        cell.setting = r.fixed_step ? r.dt : r.tolerance;
        cell.column = c;
        cell.cpu = r.cpu_median;
        cell.rhs_calls = r.rhs_calls;
        cell.steps = r.steps;
        cell.history_error = r.error.history;
        if (r.fixed_step) cell.h_lambda = r.dt * lambda_of(r.engine);
        CellFacts f;
        f.ok = r.ok;
        f.failure = r.failure;
        f.history_error = r.error.history;
        f.drift_H = r.drift_H;
        f.drift_E = r.drift_E;
        f.H_conserved = H_conserved;
        f.E_conserved = E_conserved;
        f.orbit = orbit;
        cell.facts = f;
        cell.result = classify(f, m.limits);
        sv.cells.push_back(cell);
      }
    } else {
      const std::string& why = *w.refused;
      col.reference = false;
      col.reference_note = why;
      sv.study_notes.push_back(reference_budget_note(o));
      sv.refused_note = "at " + knob.spec + " = " + g3(w.value) + ": " + why;
      for (const std::string& e : m.engines)
        for (const std::string& i : m.integrators) {
          const bool fixed = Choice<Integrator>(i) == Integrator::Rk4;
          for (double x : fixed ? u.options.dts : u.options.tolerances) {
            StabilityCell cell;
            cell.engine = e;
            cell.integrator = i;
            cell.fixed_step = fixed;
            cell.setting = x;
            cell.column = c;
            CellFacts f;
            f.reference = false;
            f.failure = why;  // why the reference could not be made: the cell says it
            cell.facts = f;
            cell.result = classify(f, m.limits);
            sv.cells.push_back(cell);
          }
        }
    }
    out.push_back(std::move(sv));
  }
  return out;
}

StabilityValue stability_value(const System& system, const Knob& knob, double v,
                               const StabilityMap& m, const StabilityOptions& o) {
  return std::move(stability_values(system, knob, {v}, m, o).front());
}

void add_stability_value(StabilityMap& m, StabilityValue v) {
  const std::size_t c = m.columns.size();
  for (const std::string& n : v.study_notes)
    if (std::find(m.notes.begin(), m.notes.end(), n) == m.notes.end()) m.notes.push_back(n);
  if (!v.refused_note.empty()) m.notes.push_back(v.refused_note);
  for (StabilityCell& cell : v.cells) {
    cell.column = c;
    m.cells.push_back(std::move(cell));
  }
  m.columns.push_back(std::move(v.column));
}

StabilityMap stability_scene(const System& system, const Knob& knob, const std::vector<double>& values,
                             const StabilityOptions& o) {
  if (values.empty()) throw InputError("--values: give at least one value");
  StabilityMap m = stability_frame(system, knob, o);
  for (StabilityValue& v : stability_values(system, knob, values, m, o)) add_stability_value(m, std::move(v));
  m.findings = stability_findings(m);
  return m;
}

// ---- findings ------------------------------------------------------------------------------------

namespace {

// What the cells of one engine x integrator say, for its remedies.
struct Evidence {
  bool fixed = false;
  std::string engine, integrator;
  double first_diverging_h_lambda = kNaN;  // rk4: h |lambda|max of the first diverging cell
  bool timed_out = false, step_limit = false;  // too costly: by the per-run time or step limit
  // Over the values where some cell is inaccurate: the coarsest setting accurate at all of them
  // (NaN: one has no accurate setting), and those with none ("<knob> 0.1, 0.01 rad/s").
  double accurate_everywhere = kNaN;
  std::string never_accurate;
};

// The remedy for one way of failing, only as far as the cells support it.
std::string remedy(StabilityClass c, const Evidence& ev) {
  const bool implicit = ev.integrator.rfind("cvode-", 0) == 0;
  const std::string step = ev.fixed ? "dt " : "rtol ";
  switch (c) {
    case StabilityClass::Diverged:
      if (ev.fixed)
        return std::isfinite(ev.first_diverging_h_lambda) && ev.first_diverging_h_lambda > kRk4Limit
                   ? "take h |lambda|max below 2.8 (rk4's stability limit), or an adaptive method, "
                     "which shortens its steps by itself"
                   : "a shorter step, or an adaptive method, which shortens its steps by itself";
      return "tighten the tolerance; if every method diverges the model itself is unstable "
             "(look at the reference)";
    case StabilityClass::Singular:
      return "turn Euler-angle re-charting on (lagrange's default) or use an engine with "
             "quaternions (kane, newton-euler)";
    case StabilityClass::TooCostly: {
      // Stopped only by the per-run time limit: that is all the cells show (not stiffness).
      if (ev.timed_out && !ev.step_limit)
        return "allow each run more time (--timeout: every too costly run here was stopped by it), "
               "or a method that needs fewer steps here";
      std::string r;
      if (ev.fixed)
        r = "a longer step where it stays stable (h |lambda|max below 2.8) and accurate, or an "
            "adaptive method";
      else if (implicit)
        r = ev.engine.rfind("newton-euler", 0) == 0
                ? "newton-euler's constraint projection restarts the multistep history after "
                  "every step: use an explicit adaptive method (dop853) or another engine"
                : "this multistep method cannot take long steps here: use an explicit adaptive "
                  "method (dop853), or leave out the fast modes that do not change the answer";
      else
        r = "the scene is stiff for an explicit method: use the implicit cvode-bdf, or leave out "
            "the fast modes or stiff springs that do not change the answer";
      r += "; or allow each run more steps (--max-steps)";
      if (ev.timed_out) r += " or more time (--timeout)";
      return r;
    }
    case StabilityClass::Drift:
      return std::string(ev.fixed ? "a shorter step" : "tighten the tolerance") +
             (ev.engine.rfind("newton-euler", 0) == 0
                  ? ", and keep newton-euler's projection stabilisation on"
                  : "");
    case StabilityClass::Inaccurate:
      if (std::isfinite(ev.accurate_everywhere))
        return std::string(ev.fixed ? "a shorter step" : "a tighter tolerance") + ": " + step +
               g3(ev.accurate_everywhere) + " or less was accurate wherever it was inaccurate";
      return std::string(ev.fixed ? "a shorter step" : "a tighter tolerance") +
             " than any tried, or another method: no setting tried was accurate at " +
             ev.never_accurate;
    case StabilityClass::NoReference:
    case StabilityClass::Accurate: return "";
  }
  return "";
}

// "<knob> 1 ... 100 N m/rad (3 values)" or "<knob> 5 N m/rad" for columns a..b.
std::string value_range(const StabilityMap& m, std::size_t a, std::size_t b) {
  const std::string unit = m.knob.unit.empty() ? "" : " " + m.knob.unit;
  std::ostringstream o;
  o << m.knob.spec << " " << g3(m.columns[a].value);
  if (b > a) o << " ... " << g3(m.columns[b].value) << unit << " (" << b - a + 1 << " values)";
  else o << unit;
  return o.str();
}

}  // namespace

// Every sentence follows from the cells it summarises (issue 23, class 11): a column without a
// reference is a finding of its own with the study's reason, and its cells ('?') are counted in
// no class and get no remedy; per engine x integrator the failing cells are counted by class over
// the measured values only, and each class present gets the remedy the cells support.
std::vector<std::string> stability_findings(const StabilityMap& m) {
  std::vector<std::string> out;
  // The values without a reference, neighbouring ones with the same reason said once.
  std::size_t measured_columns = 0;
  {
    std::ostringstream o;
    for (std::size_t a = 0; a < m.columns.size();) {
      if (m.columns[a].reference) {
        ++measured_columns;
        ++a;
        continue;
      }
      const std::string why = no_reference_reason(m.columns[a].reference_note);
      std::size_t b = a;
      while (b + 1 < m.columns.size() && !m.columns[b + 1].reference &&
             no_reference_reason(m.columns[b + 1].reference_note) == why)
        ++b;
      o << (o.tellp() > 0 ? "; at " : "") << value_range(m, a, b) << ": "
        << (why.empty() ? "the reference could not be made" : why);
      a = b + 1;
    }
    if (o.tellp() > 0)
      out.push_back("No reference at " + o.str() + ". The cells there ('?') measure nothing: they " +
                    "count in no class below and have no remedy.");
  }
  for (const std::string& e : m.engines)
    for (const std::string& i : m.integrators) {
      std::vector<const StabilityCell*> cells;
      for (const StabilityCell& c : m.cells)
        if (c.engine == e && c.integrator == i) cells.push_back(&c);
      if (cells.empty()) continue;
      Evidence ev;
      ev.fixed = cells.front()->fixed_step;
      ev.engine = e;
      ev.integrator = i;
      // Per column: the coarsest accurate setting, and the failure classes of the others; then
      // neighbouring columns with the same outcome said once ("x 1 ... 100 (3 values): ...").
      std::vector<std::string> outcome(m.columns.size());
      std::map<StabilityClass, int> how;
      int failing_cells = 0, measured_cells = 0;
      bool accurate_everywhere = true;
      double coarsest_everywhere = std::numeric_limits<double>::infinity();
      std::vector<std::size_t> never;
      for (std::size_t c = 0; c < m.columns.size(); ++c) {
        if (!m.columns[c].reference) {
          outcome[c] = "no reference";
          continue;
        }
        double coarsest = kNaN;
        bool inaccurate = false;
        int in_column = 0;
        std::set<std::string> fails;
        for (const StabilityCell* x : cells) {
          if (x->column != c) continue;
          ++in_column;
          ++measured_cells;
          if (x->result.cls == StabilityClass::Accurate) {
            if (std::isnan(coarsest) || x->setting > coarsest) coarsest = x->setting;
            continue;
          }
          if (x->result.cls == StabilityClass::NoReference) continue;  // not in a measured column
          fails.insert(class_name(x->result.cls));
          ++how[x->result.cls];
          ++failing_cells;
          if (x->result.cls == StabilityClass::Inaccurate) inaccurate = true;
          if (x->result.cls == StabilityClass::Diverged && ev.fixed && std::isfinite(x->h_lambda) &&
              std::isnan(ev.first_diverging_h_lambda))
            ev.first_diverging_h_lambda = x->h_lambda;
          if (x->result.cls == StabilityClass::TooCostly) {
            if (contains(x->result.why, "timed out") || contains(x->result.why, "time limit"))
              ev.timed_out = true;
            if (contains(x->result.why, "step limit")) ev.step_limit = true;
          }
        }
        if (in_column == 0) {  // the engine was left out at this value (the notes say why)
          outcome[c] = "not run";
          continue;
        }
        if (inaccurate && std::isnan(coarsest)) {
          accurate_everywhere = false;
          never.push_back(c);
        } else if (inaccurate) {
          coarsest_everywhere = std::min(coarsest_everywhere, coarsest);
        }
        std::ostringstream o;
        if (std::isnan(coarsest)) o << "never accurate";
        else o << "accurate up to " << (ev.fixed ? "dt " : "rtol ") << g3(coarsest);
        if (!fails.empty()) {
          o << ", else ";
          bool first = true;
          for (const std::string& f : fails) {
            o << (first ? "" : "/") << f;
            first = false;
          }
        }
        outcome[c] = o.str();
      }
      if (accurate_everywhere && std::isfinite(coarsest_everywhere))
        ev.accurate_everywhere = coarsest_everywhere;
      for (std::size_t k = 0; k < never.size(); ++k)
        ev.never_accurate += (k ? ", " : m.knob.spec + " ") + g3(m.columns[never[k]].value);
      if (!never.empty() && !m.knob.unit.empty()) ev.never_accurate += " " + m.knob.unit;
      std::ostringstream where;
      for (std::size_t a = 0; a < outcome.size();) {
        std::size_t b = a;
        while (b + 1 < outcome.size() && outcome[b + 1] == outcome[a]) ++b;
        where << (a ? "; " : "") << value_range(m, a, b) << ": " << outcome[a];
        a = b + 1;
      }
      std::string sentence = e + " + " + i + ": ";
      if (measured_columns == 0) {
        sentence += "no reference at any value tried, so nothing was measured.";
      } else if (measured_cells == 0) {
        sentence += "not run at any value with a reference, so nothing was measured (" + where.str() +
                    "; the notes say why).";
      } else if (failing_cells == 0) {
        sentence += measured_columns == m.columns.size()
                        ? "accurate at every setting and value tried."
                        : "accurate at every setting tried at the " + std::to_string(measured_columns) +
                              " value" + (measured_columns == 1 ? "" : "s") +
                              " with a reference (" + where.str() + ").";
      } else {
        // Each way it fails, counted over the measured cells, most severe first.
        std::string counts;
        std::vector<StabilityClass> present;
        for (StabilityClass c : {StabilityClass::Diverged, StabilityClass::Singular,
                                 StabilityClass::TooCostly, StabilityClass::Drift,
                                 StabilityClass::Inaccurate})
          if (how.count(c)) {
            present.push_back(c);
            counts += (counts.empty() ? "" : ", ") + std::to_string(how[c]) + " " + class_name(c);
          }
        sentence += where.str() + ". Fails in " + std::to_string(failing_cells) + " of " +
                    std::to_string(measured_cells) + " measured cells: " + counts;
        if (std::isfinite(ev.first_diverging_h_lambda))
          sentence += " (first diverging step has h |lambda|max = " + g3(ev.first_diverging_h_lambda) + ")";
        sentence += ". Remedy: ";
        for (std::size_t k = 0; k < present.size(); ++k)
          sentence += (k ? "; " : "") +
                      (present.size() > 1 ? std::string(class_name(present[k])) + ": " : std::string()) +
                      remedy(present[k], ev);
        sentence += ".";
      }
      out.push_back(sentence);
    }
  return out;
}

// ---- text and CSV ------------------------------------------------------------------------------

namespace {

char class_letter(StabilityClass c) {
  switch (c) {
    case StabilityClass::Accurate: return '.';
    case StabilityClass::Inaccurate: return 'i';
    case StabilityClass::Drift: return 'd';
    case StabilityClass::Diverged: return 'X';
    case StabilityClass::Singular: return 'S';
    case StabilityClass::TooCostly: return 'C';
    case StabilityClass::NoReference: return '?';
  }
  return ' ';
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char ch : s) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return q + "\"";
}

}  // namespace

std::string format_stability(const StabilityMap& m) {
  std::ostringstream o;
  o << "Stability map of " << m.scene << " against " << m.knob.description << " ("
    << m.knob.spec << (m.knob.unit.empty() ? "" : ", " + m.knob.unit) << ")\n";
  o << "accurate: history error <= " << sci(m.limits.tolerance, 2)
    << " (--accuracy, relative to each quantity's scale; not the scene's compare tolerances)"
    << "; drift: relative H or E drift > "
    << sci(m.limits.drift_limit, 2) << " where conserved\n";
  o << "legend: . accurate  i inaccurate  d drift  X diverged  S singular  C too costly  ? no reference\n";
  o << "|lambda|max: the largest |eigenvalue| of each engine's Jacobian at t = 0, 1/s\n\n";
  for (std::size_t ei = 0; ei < m.engines.size(); ++ei) {
    const std::string& e = m.engines[ei];
    o << e << " (|lambda|max";
    for (const StabilityColumn& c : m.columns) o << ' ' << g3(c.lambda_max[ei]);
    o << ")\n" << std::string(24, ' ');
    for (const StabilityColumn& c : m.columns) {
      std::string v = g3(c.value);
      v.resize(9, ' ');
      o << v;
    }
    o << '\n';
    for (const std::string& i : m.integrators) {
      std::vector<double> settings;
      for (const StabilityCell& c : m.cells)
        if (c.engine == e && c.integrator == i &&
            std::find(settings.begin(), settings.end(), c.setting) == settings.end())
          settings.push_back(c.setting);
      for (double st : settings) {
        std::string label = "  " + i + (Choice<Integrator>(i) == Integrator::Rk4 ? " dt " : " tol ") + g3(st);
        label.resize(24, ' ');
        o << label;
        for (std::size_t c = 0; c < m.columns.size(); ++c) {
          char ch = ' ';
          for (const StabilityCell& x : m.cells)
            if (x.engine == e && x.integrator == i && x.setting == st && x.column == c)
              ch = class_letter(x.result.cls);
          o << ch << std::string(8, ' ');
        }
        o << '\n';
      }
    }
    o << '\n';
  }
  o << "Findings:\n";
  for (const std::string& f : m.findings) o << "- " << f << '\n';
  for (const std::string& n : m.notes) o << "note: " << n << '\n';
  return o.str();
}

std::string stability_csv(const StabilityMap& m) {
  std::ostringstream o;
  o << "scene,parameter,value,engine,lambda_max,integrator,setting_kind,setting,class,why,history_error,"
       "cpu_ms,rhs_calls,steps,h_lambda\n";
  auto num = [](double v) { return std::isfinite(v) ? sci(v, 4) : std::string(); };
  for (const StabilityCell& c : m.cells) {
    const StabilityColumn& col = m.columns[c.column];
    const auto e = static_cast<std::size_t>(
        std::find(m.engines.begin(), m.engines.end(), c.engine) - m.engines.begin());
    o << m.scene << ',' << m.knob.spec << ',' << sci(col.value, 6) << ',' << c.engine << ','
      << num(e < col.lambda_max.size() ? col.lambda_max[e] : kNaN) << ',' << c.integrator << ',' << (c.fixed_step ? "dt" : "tolerance") << ','
      << sci(c.setting, 6) << ',' << class_name(c.result.cls) << ',' << csv_field(c.result.why) << ','
      << num(c.history_error) << ',' << (c.result.cls == StabilityClass::NoReference ? "" : num(1e3 * c.cpu))
      << ',' << c.rhs_calls << ',' << c.steps << ',' << num(c.h_lambda) << '\n';
  }
  return o.str();
}

}  // namespace crossdyn::harness
