// Speed against accuracy: the work-precision study and the scaling study (see study.hpp).
#include "harness/study.hpp"

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/integrate.hpp"
#include "core/output_layout.hpp"
#include "core/output.hpp"
#include "core/progress.hpp"
#include "core/rotation.hpp"
#include "core/scene/scene.hpp"
#include "harness/conditioning.hpp"
#include "harness/engines.hpp"
#include "harness/numbers.hpp"

#include <time.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <set>
#include <sstream>

namespace crossdyn::harness {

namespace {


// CPU time of the calling thread, s (clock_gettime(2), CLOCK_THREAD_CPUTIME_ID): a run's own
// time, also when other runs go on in other threads (`stability --jobs`).
double cpu_now() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// "1e-08" style for settings (tolerances, steps): at most 3 significant digits, and an exponent
// below 1e-3 ("1e-04", not %g's "0.0001", so that a tolerance list reads alike).
std::string setting_text(double v) {
  char b[64];
  if (v > 0 && v < 1e-3) {
    std::snprintf(b, sizeof b, "%.2e", v);  // "1.00e-04": drop the mantissa's trailing zeros
    std::string t = b;
    const std::size_t e = t.find('e');
    std::string mantissa = t.substr(0, e);
    while (mantissa.find('.') != std::string::npos && (mantissa.back() == '0' || mantissa.back() == '.'))
      mantissa.pop_back();
    return mantissa + t.substr(e);
  }
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

double median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// `text` wrapped at 100 characters, continuation lines indented by two spaces.
std::string wrap100(const std::string& text) {
  std::string out, line = text.rfind("  ", 0) == 0 ? "  " : "";
  std::istringstream words(text);
  for (std::string w; words >> w;) {
    if (!line.empty() && line.size() + 1 + w.size() > 100) {
      out += line + "\n";
      line = "  ";
    }
    line += (line.empty() || line == "  " ? "" : " ") + w;
  }
  return out + line + "\n";
}

// The progress display, redrawn at most 4 times a second (phase() draws at once).
struct Progress {
  ProgressLine* line = nullptr;
  std::chrono::steady_clock::time_point last{};
  void show(const std::string& text, bool force = false) {
    if (!line) return;
    const auto now = std::chrono::steady_clock::now();
    if (!force && now - last < std::chrono::milliseconds(250)) return;
    last = now;
    line->phase(text);
  }
};

// One timed run: the engine is made before the clock starts; the clock covers simulate() only.
struct TimedRun {
  RunResult result;  // rows not kept: stats and failure
  History history;   // the pinned values at the output times
  double cpu = 0;    // s
};

TimedRun timed_run(const std::string& label, const std::string& engine_name, const EngineOptions& eo,
                   const System& system, const IntegratorSettings& settings, double timeout,
                   std::size_t pinned, std::size_t output_rows) {
  TimedRun out;
  std::optional<cancel::Deadline> deadline;
  if (timeout > 0) deadline.emplace(timeout);
  std::unique_ptr<Engine> engine;
  try {
    engine = make_engine(engine_name, system, eo);
  } catch (const cancel::Cancelled& c) {
    if (c.reason() == cancel::Reason::Interrupt) throw;
    out.result.failure = RunFailure(label, 0.0, "", std::string(c.what()) + " while setting up the engine");
    return out;
  }
  const std::vector<std::string> pinned_names = pinned_columns(system);
  const std::vector<std::string>& cols = engine->columns();
  if (cols.size() < pinned || !std::equal(pinned_names.begin(), pinned_names.end(), cols.begin()))
    throw std::logic_error("engine " + engine_name + " does not write the pinned columns first");
  out.history.columns = pinned;
  out.history.data.reserve(pinned * (output_rows + 1));
  History& h = out.history;
  // Stores only what the error needs (no allocation: reserved above).
  const RowCallback on_row = [&h, pinned](const double* row) {
    if (h.data.size() + pinned <= h.data.capacity()) h.data.insert(h.data.end(), row, row + pinned);
  };
  const TreeState initial = TreeState::initial(system);
  const double c0 = cpu_now();
  try {
    out.result = simulate(*engine, system, initial, settings, on_row);
  } catch (const InputError&) {
    throw;
  } catch (const RunFailure& f) {
    out.result.failure = f;
  } catch (const cancel::Cancelled& c) {
    if (c.reason() == cancel::Reason::Interrupt) throw;
    out.result.failure = RunFailure(label, 0.0, "", c.what());
  }
  out.cpu = cpu_now() - c0;
  if (out.result.failure && cancel::interrupted()) throw cancel::Cancelled(cancel::Reason::Interrupt, 0);
  return out;
}

// max_t |X(t) - X(0)| / max(|X(0)|, 1e-300) of column c (StudyRow::drift_H, drift_E).
double relative_drift(const History& h, std::size_t c) {
  if (h.rows() == 0) return kNaN;
  const double x0 = h.row(0)[c];
  double worst = 0;
  for (std::size_t k = 0; k < h.rows(); ++k) {
    const double d = std::abs(h.row(k)[c] - x0);
    if (!(d <= worst)) worst = d;  // NaN propagates
  }
  return worst / std::max(std::abs(x0), 1e-300);
}

std::string run_label(const std::string& engine, const std::string& integrator, double tol) {
  return engine + " + " + integrator + " at " + setting_text(tol);
}

// The mean of runs sampled at the same times; attitudes: the quaternions turned to the first
// run's hemisphere, averaged and normalised.
History mean_history(const System& system, const std::vector<History>& runs) {
  History m;
  m.columns = runs.at(0).columns;
  std::size_t rows = runs[0].rows();
  for (const History& h : runs) rows = std::min(rows, h.rows());
  m.data.assign(rows * m.columns, 0.0);
  const OutputLayout layout(system);
  std::vector<int> q_first;  // the qw column of each body
  for (std::size_t c = 0; c < m.columns && c < layout.columns().size(); ++c)
    if (layout.columns()[c].kind == ColumnKind::BodyQ && layout.columns()[c].component == 0)
      q_first.push_back(static_cast<int>(c));
  const double n = static_cast<double>(runs.size());
  for (std::size_t k = 0; k < rows; ++k) {
    double* out = m.data.data() + k * m.columns;
    for (const History& h : runs) {
      const double* r = h.row(k);
      std::vector<double> sign(m.columns, 1.0);
      for (int q : q_first) {
        double dot = 0;
        for (int i = 0; i < 4; ++i) dot += r[q + i] * runs[0].row(k)[q + i];
        if (dot < 0)
          for (int i = 0; i < 4; ++i) sign[static_cast<std::size_t>(q + i)] = -1;
      }
      for (std::size_t c = 0; c < m.columns; ++c) out[c] += sign[c] * r[c] / n;
    }
    for (int q : q_first) {
      double norm = 0;
      for (int i = 0; i < 4; ++i) norm += out[q + i] * out[q + i];
      norm = std::sqrt(norm);
      if (norm > 0)
        for (int i = 0; i < 4; ++i) out[q + i] /= norm;
    }
  }
  return m;
}

}  // namespace

// ---- The error metric ----

ErrorMetric::ErrorMetric(const System& system, const History& reference) : reference_(&reference) {
  const OutputLayout layout(system);
  const auto& cols = layout.columns();
  // Scale groups (study.hpp): "w:<body>", "rate", "modal:<body>", "modal_rate:<body>", "H", "E";
  // attitudes and joint angles: their travel, below.
  std::vector<std::string> group(cols.size());
  for (std::size_t c = 0; c < cols.size(); ++c) {
    const Column& col = cols[c];
    Quantity q;
    q.name = col.name;
    q.columns = {static_cast<int>(c)};
    switch (col.kind) {
      case ColumnKind::BodyW: group[c] = "w:" + std::to_string(col.body); break;
      case ColumnKind::BodyQ:
        if (col.component != 0) continue;
        q.name = system.bodies[static_cast<std::size_t>(col.body)].name + ".attitude";
        q.columns = {static_cast<int>(c), static_cast<int>(c + 1), static_cast<int>(c + 2),
                     static_cast<int>(c + 3)};
        q.attitude = true;
        break;
      // Angles: their travel (below). Lengths and speeds have their own scales: a slider's
      // position against its own largest value, the rates of lengths (m/s) together.
      case ColumnKind::JointCoordinate:
        if (col.unit == "m") group[c] = "position:" + std::to_string(col.joint);
        break;
      case ColumnKind::JointRate: group[c] = col.unit == "m/s" ? "length_rate" : "rate"; break;
      case ColumnKind::SphericalW: group[c] = "rate"; break;
      case ColumnKind::JointTorque: group[c] = "torque"; break;
      case ColumnKind::Modal: group[c] = "modal:" + std::to_string(col.body); break;
      case ColumnKind::ModalRate: group[c] = "modal_rate:" + std::to_string(col.body); break;
      case ColumnKind::MomentumH: group[c] = "H"; break;
      case ColumnKind::EnergyE: group[c] = "E"; break;
      // Issue 26's outputs are not in the error metric: they follow from the state above (loads
      // and power from its accelerations), and the metric stays the one every study measured.
      case ColumnKind::BodyPosition:
      case ColumnKind::SystemCM:
      case ColumnKind::MomentumVector:
      case ColumnKind::JointForce:
      case ColumnKind::JointMoment:
      case ColumnKind::Power:
      case ColumnKind::ExternalMoment:
      case ColumnKind::LvlhAngle:  // issue 28: q_NB and w_NB_B seen from the orbit frame
      case ColumnKind::LvlhRate:
      case ColumnKind::Jacobi:
      case ColumnKind::Time:
      case ColumnKind::Extra: continue;
    }
    quantities_.push_back(q);
  }
  // Per group: max over the reference's rows of |value| (w and spherical w: the vector's norm).
  std::map<std::string, double> scale;
  for (std::size_t k = 0; k < reference.rows(); ++k) {
    const double* r = reference.row(k);
    for (std::size_t c = 0; c < cols.size() && c < reference.columns; ++c) {
      if (group[c].empty()) continue;
      double v = std::abs(r[c]);
      const bool vector = cols[c].kind == ColumnKind::BodyW || cols[c].kind == ColumnKind::SphericalW;
      if (vector && cols[c].component == 0 && c + 2 < reference.columns)
        v = std::sqrt(r[c] * r[c] + r[c + 1] * r[c + 1] + r[c + 2] * r[c + 2]);
      if (std::isfinite(v)) scale[group[c]] = std::max(scale[group[c]], v);
    }
  }
  // Floors for H and E (issue 24): a scene whose angular momentum is zero (a deployment from
  // rest, counter-rotating wheels) has max_t |H| at rounding level (3e-13 N m s on
  // pointing_flex), and every run's H would be judged against that noise. The floor is the
  // momentum and energy its bodies' rotations carry, each alone:
  //   S_H >= sum_b I_b w_b,   S_E >= sum_b I_b w_b^2 / 2,
  // with w_b = max_t |w_NB| (the body's w scale) and I_b = trace(I_BBo_B) / 2, which is at least
  // the largest principal moment and at most 1.5 times it (triangle inequality of inertias).
  double H_floor = 0, E_floor = 0;
  // And, for E, the kinetic energy of each body's CM motion, 1/2 m_b max_t |v_b|^2, v_b from its
  // position columns' differences over the output times: a pendulum's energy is mostly its bob's
  // translation, and a conserved E that starts at zero (kinetic + a potential zero at the start,
  // iftomm_pendulum) has max_t |E| at integration-noise level (1e-11 J against m g L = 9.81 J).
  // The reference's time column, and each body's w and position columns (here and for the
  // angles' travel below).
  int time_column = -1;
  std::vector<std::array<int, 3>> w_columns(system.bodies.size(), {-1, -1, -1});
  std::vector<int> p_columns(system.bodies.size(), -1);  // <body>.x (then .y, .z)
  for (std::size_t c = 0; c < cols.size() && c < reference.columns; ++c) {
    if (cols[c].kind == ColumnKind::Time) time_column = static_cast<int>(c);
    if (cols[c].body < 0 || static_cast<std::size_t>(cols[c].body) >= w_columns.size()) continue;
    const auto b = static_cast<std::size_t>(cols[c].body);
    if (cols[c].kind == ColumnKind::BodyW && cols[c].component >= 0 && cols[c].component < 3)
      w_columns[b][static_cast<std::size_t>(cols[c].component)] = static_cast<int>(c);
    if (cols[c].kind == ColumnKind::BodyPosition && cols[c].component == 0) p_columns[b] = static_cast<int>(c);
  }
  {
    const int tc = time_column;
    const std::vector<int>& pc = p_columns;
    for (std::size_t b = 0; b < system.bodies.size() && tc >= 0; ++b) {
      if (pc[b] < 0) continue;
      double v2 = 0;
      for (std::size_t k = 1; k < reference.rows(); ++k) {
        const double* r0 = reference.row(k - 1);
        const double* r1 = reference.row(k);
        const double dt = r1[tc] - r0[tc];
        if (!(dt > 0)) continue;
        double d2 = 0;
        for (int i = 0; i < 3; ++i) d2 += (r1[pc[b] + i] - r0[pc[b] + i]) * (r1[pc[b] + i] - r0[pc[b] + i]);
        if (std::isfinite(d2)) v2 = std::max(v2, d2 / (dt * dt));
      }
      E_floor += 0.5 * system.bodies[b].mass * v2;
    }
  }
  for (std::size_t b = 0; b < system.bodies.size(); ++b) {
    const auto w = scale.find("w:" + std::to_string(b));
    if (w == scale.end() || !std::isfinite(w->second)) continue;
    const double I = 0.5 * system.bodies[b].I_BBo_B.trace();
    if (!(I > 0) || !std::isfinite(I)) continue;
    H_floor += I * w->second;
    E_floor += 0.5 * I * w->second * w->second;
  }
  // A prescribed joint's torque (force) that is zero but for rounding (a rig's held base whose
  // drive carries nothing about its axis: iftomm_pendulum's ground, 1e-16 N m) would be judged
  // against that noise too (study found no reference there: "1.55" relative on frame.torque). Its
  // floor: the largest joint load the reference carries, moment or force (issue 26's columns), the
  // size of what the scene's joints transmit (the pendulum's weight times its arm, 9.81 N m).
  double load_floor = 0;
  for (std::size_t c = 0; c < cols.size() && c < reference.columns; ++c)
    if (cols[c].kind == ColumnKind::JointMoment || cols[c].kind == ColumnKind::JointForce)
      for (std::size_t k = 0; k < reference.rows(); ++k) {
        const double v = std::abs(reference.row(k)[c]);
        if (std::isfinite(v)) load_floor = std::max(load_floor, v);
      }
  for (const auto& [g, floor] : {std::pair<const char*, double>{"H", H_floor}, {"E", E_floor},
                                 {"torque", load_floor}})
    if (scale.count(g)) scale[g] = std::max(scale[g], floor);
  for (Quantity& q : quantities_) {
    const std::string& g = group[static_cast<std::size_t>(q.columns[0])];
    q.scale = g.empty() || !(scale[g] > 0) ? 1.0 : scale[g];
  }
  // Angles (issue 24): a joint angle's or a body attitude's scale is how far it turned in the
  // reference, at least 1 rad: S = max(1 rad, travel). An integrator controls an angle's error
  // relative to its size (rtol |theta|), and rounding alone grows with it: a wheel that turned
  // 12,000 rad in 60 s differed by 1.9e-8 rad (1.6e-12 of its travel) between two runs at rtol
  // 1e-13, so in absolute radians no target below 1e-7 could be measured on any scene with a
  // fast rotor. A body that turns less than a radian (a pointing hub, a hinge) keeps the absolute
  // measure. Travel: a joint angle's max_t |theta(t) - theta(0)|; a body's integral of |w_NB|
  // over the run (trapezoidal rule on the output times: |w| is smooth where the angle is not
  // sampled finely enough to be unwrapped).
  for (Quantity& q : quantities_) {
    const Column& col = cols[static_cast<std::size_t>(q.columns[0])];
    double travel = 0;
    if (col.kind == ColumnKind::JointCoordinate && col.unit == "rad" && reference.rows() > 0) {
      const double a0 = reference.row(0)[q.columns[0]];
      for (std::size_t k = 0; k < reference.rows(); ++k)
        travel = std::max(travel, std::abs(reference.row(k)[q.columns[0]] - a0));
    } else if (q.attitude && time_column >= 0 && col.body >= 0 &&
               static_cast<std::size_t>(col.body) < w_columns.size()) {
      const std::array<int, 3>& w = w_columns[static_cast<std::size_t>(col.body)];
      if (w[0] < 0 || w[1] < 0 || w[2] < 0) continue;
      auto speed = [&](std::size_t k) {
        const double* r = reference.row(k);
        return std::sqrt(r[w[0]] * r[w[0]] + r[w[1]] * r[w[1]] + r[w[2]] * r[w[2]]);
      };
      for (std::size_t k = 1; k < reference.rows(); ++k)
        travel += 0.5 * (speed(k) + speed(k - 1)) *
                  (reference.row(k)[time_column] - reference.row(k - 1)[time_column]);
    } else {
      continue;
    }
    if (std::isfinite(travel)) q.scale = std::max(1.0, travel);
  }
}

StudyError ErrorMetric::error(const History& run) const { return error(run, *reference_); }

double ErrorMetric::scale(const std::string& quantity) const {
  for (const Quantity& q : quantities_)
    if (q.name == quantity) return q.scale;
  return std::numeric_limits<double>::quiet_NaN();
}

History pinned_history(const System& system, const RunResult& run) {
  History h;
  h.columns = pinned_columns(system).size();
  if (run.columns.size() < h.columns) return History{{}, h.columns};
  h.data.reserve(h.columns * run.rows());
  const std::size_t n = h.columns;
  run.for_each_row([&h, n](const double* row) { h.data.insert(h.data.end(), row, row + n); });
  return h;
}

StudyError ErrorMetric::error(const History& a, const History& b) const {
  StudyError e;
  const std::size_t n = std::min(a.rows(), b.rows());
  if (n == 0) return e;
  e.history = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const double* A = a.row(k);
    const double* B = b.row(k);
    const bool last = k + 1 == n;
    if (last) e.end = 0;
    for (const Quantity& q : quantities_) {
      double v;
      if (q.attitude) {
        const Eigen::Quaterniond qa(A[q.columns[0]], A[q.columns[1]], A[q.columns[2]], A[q.columns[3]]);
        const Eigen::Quaterniond qb(B[q.columns[0]], B[q.columns[1]], B[q.columns[2]], B[q.columns[3]]);
        v = rot::angle_between(qa.normalized(), qb.normalized()) / q.scale;
      } else {
        v = std::abs(A[q.columns[0]] - B[q.columns[0]]) / q.scale;
      }
      if (!std::isfinite(v)) v = std::numeric_limits<double>::infinity();
      if (v > e.history || e.history_quantity.empty()) {
        if (v > e.history) e.history = v;
        if (v >= e.history) e.history_quantity = q.name;
      }
      if (last && (v > e.end || e.end_quantity.empty())) {
        if (v > e.end) e.end = v;
        if (v >= e.end) e.end_quantity = q.name;
      }
    }
  }
  return e;
}

// ---- Options ----

std::vector<double> default_tolerances() {
  std::vector<double> t;
  for (int e = 4; e <= 13; ++e) t.push_back(std::pow(10.0, -e));
  return t;
}

std::vector<std::string> parse_names(const std::string& text, const std::string& option,
                                     const std::vector<std::string>& known, const std::string& noun) {
  std::vector<std::string> out;
  if (text.empty()) return out;
  std::stringstream in(text);
  std::string name;
  while (std::getline(in, name, ',')) {
    if (name.empty()) throw InputError(option + ": empty " + noun + " name in '" + text + "'");
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      std::string list;
      for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
      throw InputError(option + ": unknown " + noun + " '" + name + "' (known: " + list + ")");
    }
    if (std::find(out.begin(), out.end(), name) != out.end())
      throw InputError(option + ": '" + name + "' is listed twice");
    out.push_back(name);
  }
  return out;
}

std::vector<double> parse_values(const std::string& text, const std::string& option, bool allow_range) {
  auto number = [&](const std::string& s) {
    char* end = nullptr;  // strtod, not std::stod: 1e-320 and 1e400 get the sentences below
    const double v = s.empty() ? kNaN : std::strtod(s.c_str(), &end);
    if (s.empty() || end != s.c_str() + s.size() || std::isspace(static_cast<unsigned char>(s[0])))
      throw InputError(option + ": '" + s + "' is not a number (in '" + text + "')");
    if (!(v > 0) || !std::isfinite(v))
      throw InputError(option + ": " + s + " must be a positive, finite number");
    if (v < 1e-100 || v > 1e12)
      throw InputError(option + ": " + s + " is outside the allowed range, 1e-100 to 1e12");
    return v;
  };
  std::vector<double> out;
  const std::size_t dots = text.find("..");
  if (dots != std::string::npos) {
    if (!allow_range)
      throw InputError(option + ": give a list of values (a,b,c), not a range ('" + text + "')");
    const double a = number(text.substr(0, dots)), b = number(text.substr(dots + 2));
    const double la = std::log10(a), lb = std::log10(b);
    const long n = std::lround(std::abs(lb - la));
    if (std::abs(std::abs(lb - la) - static_cast<double>(n)) > 1e-9)
      throw InputError(option + ": a range runs from one power of ten to another, one value per "
                       "decade (e.g. 1e-4..1e-13); got '" + text + "'");
    const double step = lb >= la ? 1.0 : -1.0;
    // Each value is the double nearest its decimal spelling (1e-11, not 1e-6 * 1e-5 =
    // 1.0000000000000001e-11): mantissa and exponent of a, read back as text.
    const long e0 = std::lround(std::floor(la + 1e-9));
    char mantissa[32];
    std::snprintf(mantissa, sizeof mantissa, "%.14g", a / std::pow(10.0, static_cast<double>(e0)));
    for (long k = 0; k <= n; ++k) {
      const std::string spelled = std::string(mantissa) + "e" +
                                  std::to_string(e0 + static_cast<long>(step) * k);
      out.push_back(std::strtod(spelled.c_str(), nullptr));
    }
  } else {
    std::stringstream in(text);
    std::string item;
    while (std::getline(in, item, ',')) out.push_back(number(item));
    if (out.empty()) throw InputError(option + ": no values given");
  }
  if (out.size() > 40) throw InputError(option + ": at most 40 values, got " + std::to_string(out.size()));
  for (std::size_t i = 0; i < out.size(); ++i)  // 1e-6,1e-06: one value twice (as for every list)
    for (std::size_t j = 0; j < i; ++j)
      if (out[i] == out[j])
        throw InputError(option + ": the value " + setting_text(out[i]) + " is listed twice in '" + text + "'");
  return out;
}

std::string StudyRow::setting() const {
  return fixed_step ? "dt " + setting_text(dt) : "rtol " + setting_text(tolerance);
}

// ---- The study ----

namespace {
// A run stopped by its cost: the step limit or the time limit (core/run_limits.hpp messages).
bool cost_limit_failure(const std::string& why) {
  return why.find("step limit") != std::string::npos || why.find("timed out") != std::string::npos ||
         why.find("time limit") != std::string::npos;
}
}  // namespace

StudySetup study_setup(const System& system, const StudyOptions& options) {
  StudySetup u;
  u.system = system;
  u.options = options;
  const IntegratorSettings base = IntegratorSettings::from(system.run);
  u.times = output_times(base);
  const OutputLayout layout(system);
  u.pinned = layout.pinned_size();
  u.H = layout.H();
  // On an orbit E changes (the gravity-gradient potential turns with the orbit frame): the
  // energy-like quantity a run must keep is the Jacobi integral J (docs/environment.md).
  u.E = system.environment.orbit() ? layout.J() : layout.E();
  Progress progress{options.progress};
  if (options.progress) options.progress->start(system.name, base.duration);

  std::vector<std::string> engines = options.engines.empty() ? engine_names() : options.engines;
  std::vector<std::string> integrators =
      options.integrators.empty() ? integrator_names() : options.integrators;
  for (const std::string& i : integrators) (void)Choice<Integrator>(i);  // InputError if unknown
  const std::vector<double> tolerances = options.tolerances.empty() ? default_tolerances() : options.tolerances;
  std::vector<double> dts = options.dts;
  if (dts.empty())
    for (int k = 0; k <= 7; ++k) dts.push_back(base.output_step / std::pow(2.0, k));
  if (options.repeat < 1) throw InputError("--repeat: must be at least 1");

  // Engines that cannot run the scene are left out with the reason.
  // The reference from the engines studied (a scene one engine cannot run is a question for that
  // engine's user alone): one engine named gives that engine at two integrators.
  std::vector<EngineSpec> reference_specs = options.reference_engines;
  if (reference_specs.empty())
    for (const std::string& e : engines) reference_specs.push_back({e, e, {}});
  std::set<std::string> unusable;
  auto usable = [&](const std::string& engine, const EngineOptions& eo) {
    if (unusable.count(engine)) return false;
    try {
      progress.show(system.name + ": setting up " + engine, true);
      make_engine(engine, system, eo);
      return true;
    } catch (const InputError& e) {
      unusable.insert(engine);
      u.notes.push_back(engine + " left out: " + e.what());
      return false;
    }
  };

  u.settings = base;
  u.settings.keep_rows = false;
  if (options.max_steps) u.settings.max_steps = *options.max_steps;

  // The reference runs (none: the analytic solution).
  u.analytic = options.use_analytic && system.analytic == "torque-free";
  if (!u.analytic) {
    std::vector<const EngineSpec*> usable_specs;
    for (const EngineSpec& spec : reference_specs)
      if (usable(spec.engine, spec.options)) usable_specs.push_back(&spec);
    const std::vector<std::string>& ri = options.reference_integrators;
    auto add = [&](const EngineSpec& spec, const std::string& integ) {
      u.reference_runs.push_back({spec, integ, run_label(spec.label, integ, options.reference_tolerance)});
    };
    if (options.reference_run_limit <= 0) {
      for (const EngineSpec* spec : usable_specs)
        for (const std::string& integ : ri) add(*spec, integ);
    } else if (usable_specs.size() >= 2) {  // one run per engine, the integrators in turn
      for (std::size_t k = 0; k < usable_specs.size() && k < static_cast<std::size_t>(options.reference_run_limit); ++k)
        add(*usable_specs[k], ri.at(k % ri.size()));
    } else if (usable_specs.size() == 1) {  // one engine: at each integrator
      for (std::size_t k = 0; k < ri.size() && k < static_cast<std::size_t>(options.reference_run_limit); ++k)
        add(*usable_specs[0], ri[k]);
    }
  }

  // The configurations, and the chains they run in.
  u.specs = options.engine_specs;
  if (u.specs.empty())
    for (const std::string& e : engines) u.specs.push_back({e, e, {}});
  for (const EngineSpec& spec : u.specs) {
    if (!usable(spec.engine, spec.options)) continue;
    for (const std::string& integ : integrators) {
      const bool fixed = Choice<Integrator>(integ) == Integrator::Rk4;
      if (fixed) u.chains.emplace_back();
      for (double v : fixed ? dts : tolerances) {
        StudyRow r;
        r.engine = spec.label;
        r.integrator = integ;
        r.fixed_step = fixed;
        (fixed ? r.dt : r.tolerance) = v;
        if (!fixed) u.chains.emplace_back();
        u.chains.back().push_back(u.rows.size());
        u.rows.push_back(r);
      }
    }
  }
  return u;
}

History study_reference_run(const StudySetup& u, std::size_t i) {
  const StudyReferenceRun& run = u.reference_runs.at(i);
  const StudyOptions& options = u.options;
  IntegratorSettings rs = u.settings;
  rs.method = run.integrator;
  rs.rtol = options.reference_tolerance;
  rs.atol = options.reference_tolerance * options.reference_atol_factor;
  rs.land_on_outputs = true;  // no interpolated reference values (IntegratorSettings)
  if (options.reference_max_steps) rs.max_steps = *options.reference_max_steps;
  Progress progress{options.progress};
  progress.show(u.system.name + ": reference run " + run.label, true);
  TimedRun r = timed_run(run.spec.label, run.spec.engine, run.spec.options, u.system, rs,
                         options.reference_timeout, u.pinned, u.times.size());
  if (r.result.failure) {
    const std::string why = r.result.failure->what();
    throw StudyRefused(u.system.file + ": no reference: the reference run " + run.label +
                           " failed: " + why +
                           (why.find("timed out") != std::string::npos
                                ? " (the reference runs' own time budget, not the per-run "
                                  "timeout)"
                                : ""),
                       kExitRunFailed);
  }
  return std::move(r.history);
}

StudyBaseline study_baseline(const StudySetup& u, const std::vector<History>& runs) {
  StudyBaseline b;
  const System& system = u.system;
  const StudyOptions& options = u.options;
  if (u.analytic) {
    const RunResult a = analytic_run(system, u.times);
    b.history.columns = a.columns.size();
    a.for_each_row([&b](const double* row) {
      b.history.data.insert(b.history.data.end(), row, row + b.history.columns);
    });
    if (b.history.columns != u.pinned) throw std::logic_error("analytic run: not the pinned columns");
    b.reference.kind = "analytic";
    b.reference.description = "the closed-form torque-free solution (analytic/torque_free.hpp)";
    b.reference.runs = {"analytic"};
    return b;
  }
  if (runs.size() < 2)
    throw StudyRefused(system.file + ": no reference: fewer than two reference runs could be made "
                                     "(the scene has no analytic solution)",
                       kExitRunFailed);
  for (const StudyReferenceRun& r : u.reference_runs) b.reference.runs.push_back(r.label);
  const ErrorMetric agreement(system, runs[0]);
  double worst = -1, worst_end = -1;
  std::string worst_quantity, worst_end_quantity;
  for (std::size_t j = 1; j < runs.size(); ++j)
    for (std::size_t i = 0; i < j; ++i) {
      const StudyError e = agreement.error(runs[j], runs[i]);
      const double v = std::isnan(e.history) ? std::numeric_limits<double>::infinity() : e.history;
      const double v_end = std::isnan(e.end) ? std::numeric_limits<double>::infinity() : e.end;
      if (v > worst) {
        worst = v;
        worst_quantity = e.history_quantity;
        b.reference.worst_pair = b.reference.runs[j] + " vs " + b.reference.runs[i];
      }
      if (v_end > worst_end) {
        worst_end = v_end;
        worst_end_quantity = e.end_quantity;
      }
    }
  b.reference.agreement = worst;
  b.reference.agreement_end = std::min(worst_end, worst);
  if (!(worst <= options.reference_agreement))
    throw StudyRefused(system.file + ": no reference: the reference runs do not agree at the "
                       "tightest settings: " + b.reference.worst_pair + " differ by " + sci(worst) +
                       " (largest on " + worst_quantity + ") > " + sci(options.reference_agreement) +
                       " (history error, the study's metric): every target would be measured "
                       "against a reference no better than that; compare the engines on this "
                       "scene (`crossdyn compare`) to see which one differs",
                       kExitCheckFailed);
  b.history = mean_history(system, runs);
  b.reference.kind = "engines";
  std::string which;
  if (options.reference_run_limit > 0) {  // the runs named one by one
    for (std::size_t k = 0; k < u.reference_runs.size(); ++k)
      which += std::string(k == 0 ? "" : k + 1 == u.reference_runs.size() ? " and " : ", ") +
               u.reference_runs[k].spec.label + " + " + u.reference_runs[k].integrator;
  } else {
    which = "every engine with ";
    for (std::size_t k = 0; k < options.reference_integrators.size(); ++k)
      which += (k == 0 ? "" : " and ") + options.reference_integrators[k];
  }
  b.reference.description =
      "the mean of " + std::to_string(runs.size()) + " runs (" + which +
      (options.reference_atol_factor == 1.0
           ? " at rtol = atol = " + setting_text(options.reference_tolerance)
           : " at rtol " + setting_text(options.reference_tolerance) + ", atol " +
                 setting_text(options.reference_tolerance * options.reference_atol_factor)) +
      "), which agree to " + sci(worst) + " over the run (worst pair: " + b.reference.worst_pair +
      ", largest on " + worst_quantity + ") and to " + sci(b.reference.agreement_end) +
      " at the end (largest on " + worst_end_quantity + "): the reference is good to about " +
      sci(worst, 2) + " over the run and " + sci(b.reference.agreement_end, 2) +
      " at the end, so history-error targets below " + sci(kReferenceMargin * worst, 2) +
      " and end-state targets below " + sci(kReferenceMargin * b.reference.agreement_end, 2) +
      " are not measured";
  return b;
}

std::string study_skip_reason(const std::vector<StudyRow>& rows, const std::vector<std::size_t>& chain,
                              std::size_t k) {
  // An rk4 run with a shorter step than one that already went past the step or time limit is
  // not made: it takes more steps, for certain (duration / dt). Only rk4: an adaptive method
  // is not bound to take more steps at a tighter tolerance (on chain5 with 8 links,
  // newton-euler + cvode-bdf reached the 200000-step limit at rtol 1e-9 and finished at
  // 1e-12), so skipping those would give a cell a class it did not earn.
  const StudyRow& row = rows[chain[k]];
  if (!row.fixed_step) return "";
  for (std::size_t j = 0; j < k; ++j) {
    const StudyRow& p = rows[chain[j]];
    if (p.engine == row.engine && p.integrator == row.integrator && !p.ok &&
        cost_limit_failure(p.failure) && p.dt > row.dt)
      return "not run: " + p.setting() + " already failed (" + p.failure +
             "), and a shorter step takes more steps";
  }
  return "";
}

double study_run_row(const StudySetup& u, const ErrorMetric& metric, StudyRow& row, bool first) {
  IntegratorSettings rs = u.settings;
  rs.method = row.integrator;
  if (row.fixed_step) rs.dt = row.dt;
  else rs.rtol = rs.atol = row.tolerance;
  rs.give_up_factor = u.options.give_up_factor;
  const EngineSpec* spec = nullptr;
  for (const EngineSpec& sp : u.specs)
    if (sp.label == row.engine) spec = &sp;
  if (!spec) throw std::logic_error("study: no engine '" + row.engine + "'");
  TimedRun r = timed_run(spec->label, spec->engine, spec->options, u.system, rs, u.options.timeout,
                         u.pinned, u.times.size());
  if (first) {
    row.rhs_calls = r.result.stats.rhs_calls;
    row.steps = r.result.stats.steps;
    row.rejected = r.result.stats.rejected;
    if (r.result.failure) {
      row.failure = r.result.failure->what();
      return r.cpu;
    }
    row.ok = true;
    row.error = metric.error(r.history);
    row.drift_H = relative_drift(r.history, static_cast<std::size_t>(u.H));
    row.drift_E = relative_drift(r.history, static_cast<std::size_t>(u.E));
  }
  return r.cpu;
}

void study_set_cpu(StudyRow& row, const std::vector<double>& cpu) {
  if (!row.ok || cpu.empty()) return;
  row.repeats = static_cast<int>(cpu.size());
  row.cpu_median = median(cpu);
  row.cpu_min = *std::min_element(cpu.begin(), cpu.end());
  row.cpu_max = *std::max_element(cpu.begin(), cpu.end());
}

SceneStudy study_scene(const System& system, const StudyOptions& options) {
  StudySetup u = study_setup(system, options);
  Progress progress{options.progress};
  SceneStudy s;
  s.scene = system.name;
  s.file = system.file;
  s.targets = options.targets.empty() ? recommendation_targets() : options.targets;
  s.duration = u.settings.duration;
  s.output_step = u.settings.output_step;

  // The reference.
  const double ref_c0 = cpu_now();
  std::vector<History> runs;
  for (std::size_t i = 0; i < u.reference_runs.size(); ++i) runs.push_back(study_reference_run(u, i));
  const StudyBaseline baseline = study_baseline(u, runs);
  s.reference = baseline.reference;
  s.reference.cpu_seconds = cpu_now() - ref_c0;
  s.notes = u.notes;
  const ErrorMetric metric(system, baseline.history);

  // The configurations: interleaved repeats, repeat 1 of every configuration (in its chain's
  // order), then repeat 2, ...
  std::vector<StudyRow>& rows = u.rows;
  std::vector<std::vector<double>> cpu(rows.size());
  std::size_t done = 0;
  const std::size_t total = rows.size() * static_cast<std::size_t>(options.repeat);
  for (int rep = 0; rep < options.repeat; ++rep)
    for (const std::vector<std::size_t>& chain : u.chains)
      for (std::size_t k = 0; k < chain.size(); ++k) {
        StudyRow& row = rows[chain[k]];
        ++done;
        if (rep > 0 && !row.ok) continue;
        if (rep == 0) {
          const std::string skip = study_skip_reason(rows, chain, k);
          if (!skip.empty()) {
            row.failure = skip;
            continue;
          }
        }
        progress.show(system.name + " " + row.engine + " " + row.integrator + " " + row.setting() +
                      ": run " + std::to_string(done) + " of " + std::to_string(total));
        cpu[chain[k]].push_back(study_run_row(u, metric, row, rep == 0));
      }
  for (std::size_t i = 0; i < rows.size(); ++i) study_set_cpu(rows[i], cpu[i]);
  if (options.progress) options.progress->clear();
  s.rows = std::move(rows);
  mark_fronts(s);
  return s;
}

std::vector<bool> pareto_front(const std::vector<double>& cost, const std::vector<double>& error,
                               double floor) {
  const std::size_t n = std::min(cost.size(), error.size());
  std::vector<bool> front(cost.size(), false);
  auto e_of = [&](std::size_t i) { return std::max(error[i], floor); };
  auto usable = [&](std::size_t i) { return std::isfinite(cost[i]) && std::isfinite(error[i]); };
  for (std::size_t i = 0; i < n; ++i) {
    if (!usable(i)) continue;
    bool dominated = false;
    for (std::size_t j = 0; j < n && !dominated; ++j)
      if (j != i && usable(j) && cost[j] <= cost[i] && e_of(j) <= e_of(i) &&
          (cost[j] < cost[i] || e_of(j) < e_of(i)))
        dominated = true;
    front[i] = !dominated;
  }
  return front;
}

void mark_fronts(SceneStudy& s) {
  std::vector<double> cost, end, hist;
  for (const StudyRow& r : s.rows) {
    cost.push_back(r.ok ? r.cpu_median : kNaN);
    end.push_back(r.ok ? r.error.end : kNaN);
    hist.push_back(r.ok ? r.error.history : kNaN);
  }
  // Errors below the reference's own accuracy (its runs' agreement) are all the same accuracy.
  auto floor = [&s](bool history) {
    const double a = s.reference.spread(history);
    return std::max(1e-15, std::isfinite(a) ? a : 0.0);
  };
  const std::vector<bool> fe = pareto_front(cost, end, floor(false)),
                          fh = pareto_front(cost, hist, floor(true));
  for (std::size_t i = 0; i < s.rows.size(); ++i) {
    s.rows[i].front_end = fe[i];
    s.rows[i].front_history = fh[i];
  }
}

std::optional<std::size_t> cheapest_within(const SceneStudy& s, double target, bool history) {
  std::optional<std::size_t> best;
  for (std::size_t i = 0; i < s.rows.size(); ++i) {
    const StudyRow& r = s.rows[i];
    const double e = history ? r.error.history : r.error.end;
    if (!r.ok || !(e <= target)) continue;
    if (!best || r.cpu_median < s.rows[*best].cpu_median) best = i;
  }
  return best;
}

const std::vector<double>& recommendation_targets() {
  static const std::vector<double> t{1e-4, 1e-6, 1e-8, 1e-10};
  return t;
}

namespace {
std::string ms(double seconds) { return fmt_g(seconds * 1e3, 3) + " ms"; }
std::string config_text(const StudyRow& r) {
  return r.engine + " + " + r.integrator + " at " + r.setting();
}
}  // namespace

bool step_set_by_output_times(const SceneStudy& s, const StudyRow& r) {
  if (!r.ok || !(s.output_step > 0)) return false;
  if (r.integrator == "rk4") return r.dt > s.output_step * (1 + 1e-12);
  if (r.integrator != "rkf78") return false;
  const double intervals = std::ceil(s.duration / s.output_step - 1e-9);
  return static_cast<double>(r.steps) <= 1.1 * intervals;
}

double smallest_supported_target(const SceneStudy& s, bool history) {
  return s.reference.kind == "engines" ? kReferenceMargin * s.reference.spread(history) : 0.0;
}

std::string recommendation(const SceneStudy& s, double target, bool history) {
  const std::string what = history ? "history error" : "end-state error";
  if (target < smallest_supported_target(s, history))
    return "for " + sci(target, 1) + " " + what + " on " + s.scene + ": not measured: the reference is " +
           "good to " + sci(s.reference.spread(history), 2) + (history ? " over the run" : " at the end") +
           " on this scene (the spread of its runs); targets below " +
           sci(smallest_supported_target(s, history), 2) + " are not measured";
  const auto best = cheapest_within(s, target, history);
  if (best) {
    const StudyRow& r = s.rows[*best];
    std::string out = "for " + sci(target, 1) + " " + what + " on " + s.scene + " use " + config_text(r) +
                      ": " + ms(r.cpu_median) + " of integration CPU (" + what + " " +
                      sci(history ? r.error.history : r.error.end, 2) + ", " +
                      std::to_string(r.rhs_calls) + " right-hand sides)";
    // What limits it: a row whose steps the output times set says so (the issue 24 trial:
    // rkf78 at rtol 1e-7 "reached" 1e-10 because it stepped every output step).
    if (step_set_by_output_times(s, r))
      out += "; its step was set by the output step (" + fmt_g(s.output_step, 6) + " s), not by its " +
             (r.fixed_step ? "dt" : "tolerance") + ": with fewer output times it would take longer "
             "steps and be less accurate";
    return out;
  }
  const StudyRow* closest = nullptr;
  for (const StudyRow& r : s.rows) {
    const double e = history ? r.error.history : r.error.end;
    if (r.ok && std::isfinite(e) &&
        (!closest || e < (history ? closest->error.history : closest->error.end)))
      closest = &r;
  }
  std::string out = "no configuration reached " + sci(target, 1) + " " + what + " on " + s.scene;
  if (closest)
    out += " (the smallest: " + sci(history ? closest->error.history : closest->error.end, 2) +
           " with " + config_text(*closest) + ")";
  else
    out += " (no configuration ran to the end)";
  return out;
}

std::string format_study(const SceneStudy& s) {
  std::ostringstream out;
  out << wrap100("scene " + s.scene + " (" + s.file + "): " + fmt_g(s.duration, 6) + " s, output every " +
                 fmt_g(s.output_step, 6) + " s");
  out << wrap100("reference: " + s.reference.description);
  {
    std::string list;
    for (double t : s.targets) list += (list.empty() ? "" : ", ") + sci(t, 0);
    out << wrap100("accuracy asked (--accuracy): " + list + ": each recommendation names the cheapest "
                   "configuration whose end-state error (below) is within it. The scene's compare "
                   "tolerances are not used here: they check that the engines agree.");
  }
  out << "cpu: median CPU of the integration (simulate() only, no CSV), ms; error: max over the\n"
         "compared quantities of |x - ref| / scale (attitudes, angles: rad / how far they turned,\n"
         "at least 1 rad), at the end (end) and over every output time (history); front: on the\n"
         "Pareto front of cpu and end error (e), history error (h)\n\n";
  std::vector<std::vector<std::string>> rows{
      {"engine", "integrator", "setting", "cpu ms", "rhs", "steps", "rej", "end err", "hist err", "front"}};
  std::vector<std::string> failures;
  bool any_capped = false;
  for (const StudyRow& r : s.rows) {
    if (!r.ok) {
      rows.push_back({r.engine, r.integrator, r.setting(), "failed", std::to_string(r.rhs_calls),
                      std::to_string(r.steps), std::to_string(r.rejected), "-", "-", ""});
      failures.push_back(config_text(r) + ": " + r.failure);
      continue;
    }
    const bool capped = step_set_by_output_times(s, r);
    any_capped = any_capped || capped;
    rows.push_back({r.engine, r.integrator, r.setting() + (capped ? "*" : ""), fmt_g(r.cpu_median * 1e3, 3),
                    std::to_string(r.rhs_calls), std::to_string(r.steps), std::to_string(r.rejected),
                    sci(r.error.end, 2), sci(r.error.history, 2),
                    std::string(r.front_end ? "e" : "") + (r.front_history ? "h" : "")});
  }
  out << text_table(rows);
  if (any_capped)
    out << wrap100("* step set by the output times, not by the setting: every step ended at an output "
                   "time (every " + fmt_g(s.output_step, 6) + " s), so the error measures the output "
                   "step (rkf78 and rk4 land on each output time; the dense methods interpolate)");
  if (!failures.empty()) {
    out << "\nfailed configurations:\n";
    for (const std::string& f : failures) out << wrap100("  " + f);
  }
  out << "\n";
  for (double t : s.targets) out << wrap100(recommendation(s, t));
  for (const std::string& n : s.notes) out << wrap100("note: " + n);
  return out.str();
}

namespace {
// Empty for a value that does not exist; otherwise the project's CSV number (core/output.hpp:
// shortest text that reads back exactly).
std::string csv_number(double v) { return std::isfinite(v) ? format_value(v) : std::string(); }
std::string csv_text(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c == '\n' ? ' ' : c);
  return q + "\"";
}
}  // namespace

std::string study_csv_header() {
  return "scene,engine,integrator,rtol,dt,status,cpu_ms_median,cpu_ms_min,cpu_ms_max,repeats,"
         "rhs_calls,steps,rejected,end_error,history_error,end_quantity,history_quantity,"
         "front_end,front_history,failure\n";
}

std::string study_csv_rows(const SceneStudy& s) {
  std::ostringstream out;
  for (const StudyRow& r : s.rows) {
    out << csv_text(s.scene) << ',' << r.engine << ',' << r.integrator << ','
        << (r.fixed_step ? "" : csv_number(r.tolerance)) << ',' << (r.fixed_step ? csv_number(r.dt) : "")
        << ',' << (r.ok ? "ok" : "failed") << ',' << (r.ok ? csv_number(r.cpu_median * 1e3) : "") << ','
        << (r.ok ? csv_number(r.cpu_min * 1e3) : "") << ',' << (r.ok ? csv_number(r.cpu_max * 1e3) : "")
        << ',' << r.repeats << ',' << r.rhs_calls << ',' << r.steps << ',' << r.rejected << ','
        << (r.ok ? csv_number(r.error.end) : "") << ',' << (r.ok ? csv_number(r.error.history) : "")
        << ',' << csv_text(r.error.end_quantity) << ',' << csv_text(r.error.history_quantity) << ','
        << (r.front_end ? 1 : 0) << ',' << (r.front_history ? 1 : 0) << ',' << csv_text(r.failure)
        << '\n';
  }
  return out.str();
}

// ---- Scaling ----

std::string chain_scene_text(int n) {
  if (n < 1) throw InputError("chainN: N must be at least 1, got " + std::to_string(n));
  // The same text as scripts/make_chain.py N (docs/scenarios.md Scene 3).
  std::ostringstream y;
  y << "name: chain" << n << "\n"
    << "description: " << n << " identical slender links joined end to end by spherical joints (chainN).\n"
    << "source: crossdyn's own scaling scene, docs/scenarios.md Scene 3 (chainN).\n"
    << "bodies:\n  - {name: link1, mass: 10, inertia: &I [0.1, 3.4, 3.4]}\n";
  for (int k = 2; k <= n; ++k) y << "  - {name: link" << k << ", mass: 10, inertia: *I}\n";
  y << "joints:\n"
    << "  - {name: joint1, type: free, child: link1, initial: {angular_velocity: [0.3, 0.2, 0.5]}}\n";
  for (int k = 2; k <= n; ++k)
    y << "  - {name: joint" << k << ", type: spherical, parent: link" << k - 1 << ", child: link" << k
      << ", "
      << (k == 2 ? "parent_point: &P [1, 0, 0], child_point: &C [-1, 0, 0], "
                   "initial: &W {angular_velocity: [0.1, -0.2, 0.3]}"
                 : "parent_point: *P, child_point: *C, initial: *W")
      << "}\n";
  y << "run: {duration: 10.0, output_step: 0.1, integrator: rkf78, rtol: 1e-10, atol: 1e-10}\n";
  return y.str();
}

double fit_exponent(const std::vector<double>& x, const std::vector<double>& y) {
  std::vector<std::pair<double, double>> p;
  for (std::size_t i = 0; i < std::min(x.size(), y.size()); ++i)
    if (x[i] > 0 && y[i] > 0 && std::isfinite(x[i]) && std::isfinite(y[i]))
      p.emplace_back(std::log(x[i]), std::log(y[i]));
  std::sort(p.begin(), p.end());
  p.erase(p.begin(), p.begin() + static_cast<std::ptrdiff_t>(p.size() / 2));  // the upper half
  if (p.size() < 2) return kNaN;
  double mx = 0, my = 0;
  for (const auto& [a, b] : p) {
    mx += a;
    my += b;
  }
  mx /= static_cast<double>(p.size());
  my /= static_cast<double>(p.size());
  double sxy = 0, sxx = 0;
  for (const auto& [a, b] : p) {
    sxy += (a - mx) * (b - my);
    sxx += (a - mx) * (a - mx);
  }
  return sxx > 0 ? sxy / sxx : kNaN;
}

std::vector<int> scaling_links(int max_links) {
  std::vector<int> n;
  for (int a = 2; a <= max_links; a *= 2) {
    n.push_back(a);
    if (a + a / 2 <= max_links && a >= 2) n.push_back(a + a / 2);
  }
  if (n.empty() || n.back() != max_links) n.push_back(max_links);
  std::sort(n.begin(), n.end());
  n.erase(std::unique(n.begin(), n.end()), n.end());
  return n;
}

ScalingStudy scaling_study(const ScalingOptions& o) {
  if (o.max_links < 2 || o.max_links > 1024)
    throw InputError("--max-links: must be from 2 to 1024, got " + std::to_string(o.max_links));
  ScalingStudy s;
  s.links = scaling_links(o.max_links);
  s.budget = o.budget;
  const std::vector<std::string> engines = o.engines.empty() ? engine_names() : o.engines;
  for (const std::string& e : engines) {
    ScalingLine line;
    line.engine = e;
    s.lines.push_back(line);
  }
  Progress progress{o.progress};
  if (o.progress) o.progress->start("scaling", 0);
  for (int n : s.links) {
    const System system = read_scene_text(chain_scene_text(n), "chain" + std::to_string(n) + " (generated)");
    for (ScalingLine& line : s.lines) {
      progress.show("scaling: " + line.engine + " on chain" + std::to_string(n), true);
      ScalingPoint p;
      p.links = n;
      std::unique_ptr<Engine> engine;
      try {
        engine = make_engine(line.engine, system, {});
      } catch (const InputError& e) {
        p.ok = false;
        p.note = e.what();
        line.points.push_back(p);
        continue;
      }
      std::vector<double> x(static_cast<std::size_t>(engine->state_size())), xdot(x.size());
      engine->pack(TreeState::initial(system), x.data());
      engine->rhs(0.0, x.data(), xdot.data());  // warm-up (first touches of the workspace)
      // Calls per batch: at least 1 ms of CPU each.
      long per_batch = 1;
      for (;;) {
        cancel::poll();
        const double c0 = cpu_now();
        for (long k = 0; k < per_batch; ++k) engine->rhs(0.0, x.data(), xdot.data());
        if (cpu_now() - c0 >= 1e-3 || per_batch >= (1L << 24)) break;
        per_batch *= 2;
      }
      std::vector<double> per_call;
      double spent = 0;
      while (static_cast<int>(per_call.size()) < o.min_batches || spent < o.budget) {
        cancel::poll();
        const double c0 = cpu_now();
        for (long k = 0; k < per_batch; ++k) engine->rhs(0.0, x.data(), xdot.data());
        const double c = cpu_now() - c0;
        spent += c;
        per_call.push_back(c / static_cast<double>(per_batch));
        p.calls += per_batch;
      }
      p.seconds_per_call = median(per_call);
      const SolveConditioning c = solve_conditioning(*engine, 0.0, x.data());
      p.condition = c.condition;
      p.system_size = c.size;
      if (!c.what.empty()) line.system = c.what;
      line.points.push_back(p);
    }
    std::vector<std::string> names;
    for (const ScalingLine& line : s.lines) names.push_back(line.engine);
    const std::vector<double> dev = acceleration_deviation(system, names);
    for (std::size_t e = 0; e < s.lines.size(); ++e) s.lines[e].points.back().accel_deviation = dev[e];
  }
  for (ScalingLine& line : s.lines) {
    std::vector<double> x, y, xc, yc;
    for (const ScalingPoint& p : line.points) {
      if (p.ok) {
        x.push_back(p.links);
        y.push_back(p.seconds_per_call);
      }
      if (std::isfinite(p.condition)) {
        xc.push_back(p.links);
        yc.push_back(p.condition);
      }
    }
    line.exponent = fit_exponent(x, y);
    line.condition_exponent = fit_exponent(xc, yc);
  }
  if (o.progress) o.progress->clear();
  return s;
}

std::string format_scaling(const ScalingStudy& s) {
  std::ostringstream out;
  out << wrap100("right-hand-side cost on chainN (docs/scenarios.md Scene 3) at its initial state: "
                 "median CPU per call, us (batches of >= 1 ms, >= " + fmt_g(s.budget, 3) +
                 " s per point); exponent: least-squares slope of log cost against log N over the "
                 "upper half of N")
      << "\n";
  std::vector<std::vector<std::string>> rows{{"N"}};
  for (const ScalingLine& l : s.lines) rows[0].push_back(l.engine);
  for (std::size_t k = 0; k < s.links.size(); ++k) {
    std::vector<std::string> r{std::to_string(s.links[k])};
    for (const ScalingLine& l : s.lines)
      r.push_back(k < l.points.size() && l.points[k].ok ? fmt_g(l.points[k].seconds_per_call * 1e6, 4)
                                                         : "-");
    rows.push_back(r);
  }
  std::vector<std::string> e{"exponent"};
  for (const ScalingLine& l : s.lines) e.push_back(std::isfinite(l.exponent) ? fmt_g(l.exponent, 3) : "-");
  rows.push_back(e);
  out << text_table(rows);
  for (const ScalingLine& l : s.lines)
    for (const ScalingPoint& p : l.points)
      if (!p.ok) out << wrap100("note: " + l.engine + " on chain" + std::to_string(p.links) + ": " + p.note);
  // The conditioning of each engine's linear solve (harness/conditioning.hpp).
  out << "\n"
      << wrap100("conditioning on chainN at its initial state: kappa = sigma_max / sigma_min of the "
                 "system each engine solves for its accelerations (a solve may lose up to "
                 "log10(kappa) digits), and dev = the largest difference of its accelerations "
                 "from those of the closest other engine, relative to the largest of that kind "
                 "(the digits it lost where the others agree); exponent: slope of log kappa "
                 "against log N over the upper half of N")
      << "\n";
  std::vector<std::vector<std::string>> c{{"N"}};
  for (const ScalingLine& l : s.lines) {
    c[0].push_back(l.engine + " kappa");
    c[0].push_back("dev");
  }
  for (std::size_t k = 0; k < s.links.size(); ++k) {
    std::vector<std::string> r{std::to_string(s.links[k])};
    for (const ScalingLine& l : s.lines) {
      const ScalingPoint* p = k < l.points.size() ? &l.points[k] : nullptr;
      r.push_back(p && std::isfinite(p->condition) ? fmt_g(p->condition, 3) : "-");
      r.push_back(p && std::isfinite(p->accel_deviation) ? fmt_g(p->accel_deviation, 2) : "-");
    }
    c.push_back(r);
  }
  std::vector<std::string> ce{"exponent"};
  for (const ScalingLine& l : s.lines) {
    ce.push_back(std::isfinite(l.condition_exponent) ? fmt_g(l.condition_exponent, 3) : "-");
    ce.push_back("");
  }
  c.push_back(ce);
  out << text_table(c);
  for (const ScalingLine& l : s.lines)
    if (!l.system.empty()) out << wrap100(l.engine + " solves: " + l.system);
  return out.str();
}

std::string scaling_csv(const ScalingStudy& s) {
  std::ostringstream out;
  out << "engine,links,us_per_call,calls,exponent,condition,system_size,accel_deviation,"
         "condition_exponent\n";
  for (const ScalingLine& l : s.lines)
    for (const ScalingPoint& p : l.points)
      out << l.engine << ',' << p.links << ',' << (p.ok ? csv_number(p.seconds_per_call * 1e6) : "")
          << ',' << p.calls << ',' << csv_number(l.exponent) << ',' << csv_number(p.condition)
          << ',' << p.system_size << ',' << csv_number(p.accel_deviation) << ','
          << csv_number(l.condition_exponent) << '\n';
  return out.str();
}

const std::string& study_timing_text() {
  static const std::string t =
      "CPU time (clock_gettime CLOCK_THREAD_CPUTIME_ID: the run's own thread) of the integration only: one simulate() "
      "call from the initial state to the end, every step and right-hand side, the engine's "
      "after-step projection, and at each output time the engine's output row with its pinned "
      "values copied to memory set aside beforehand. Not timed: making the engine (before), the "
      "error (after); no CSV or row store is written. Median of the repeats, run interleaved "
      "(every configuration once, then again), in one process.";
  return t;
}

const std::string& study_error_text() {
  static const std::string t =
      "error = max over the scene's compared quantities q of |x_q - ref_q| / S_q, where S_q is the "
      "size of q's kind of motion in the reference (body w: max |w_body|; joint rates: the largest "
      "joint rate; modal: the body's largest modal value; H, E: max |H|, |E|); attitudes (the "
      "rotation angle between the two) and joint angles in rad, relative to how far the body or "
      "joint turned in the reference, at least 1 rad (a fast rotor's angle is judged by its "
      "travel, a pointing hub's absolutely). End-state error: at the last output time; history "
      "error: the largest over every output time.";
  return t;
}

}  // namespace crossdyn::harness
