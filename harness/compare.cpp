// Comparing engines on one scene (see compare.hpp for the quantities, the pass rule and the
// tolerance lookup).
#include "harness/compare.hpp"
#include "harness/engines.hpp"
#include "harness/numbers.hpp"

#include "analytic/torque_free.hpp"
#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/output_layout.hpp"
#include "core/progress.hpp"
#include "core/rotation.hpp"

#include <algorithm>
#include <new>
#include <array>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <map>
#include <numbers>
#include <set>
#include <sstream>

namespace crossdyn::harness {

namespace {


// One compared quantity of a scene: a scalar column, or an attitude (four quaternion columns).
struct Quantity {
  std::string name;        // "main.wx", "main.attitude"
  std::string group;       // "w", "attitude", ...
  std::string vector_key;  // "main.w" for main.wx; "" when none
  std::vector<std::string> columns;
  bool attitude = false;
  // A vector's component is scaled by the vector: max_t |(x, y, z)| of these columns of b, not
  // max_t |b| of its own column (H's components: a torque-free body's H along y, 200 kg m^2/s,
  // with 1 along x, would hold Hx to 1e-8 of 1 where its attitude is held to 1e-8 rad).
  std::vector<std::string> scale_columns = {};
};

// The quantities every engine must output for this scene, in table order: the pinned columns of
// the output layout (core/output_layout.hpp), a body's four quaternion columns as one attitude.
std::vector<Quantity> pinned_quantities(const System& s) {
  const OutputLayout layout(s);
  auto xyz = [](const std::string& prefix) {
    return std::vector<std::string>{prefix + "x", prefix + "y", prefix + "z"};
  };
  std::vector<Quantity> q;
  // Does the column's joint have more than one coordinate column of this kind?
  auto multi = [&layout](const Column& c) {
    int n = 0;
    for (const Column& d : layout.columns()) n += d.kind == c.kind && d.joint == c.joint;
    return n > 1;
  };
  for (const Column& c : layout.columns()) {
    const std::string body = c.body >= 0 ? s.bodies[static_cast<std::size_t>(c.body)].name : "";
    const std::string joint = c.joint >= 0 ? s.joints[static_cast<std::size_t>(c.joint)].name : "";
    switch (c.kind) {
      case ColumnKind::BodyW: q.push_back({c.name, "w", body + ".w", {c.name}, false}); break;
      case ColumnKind::BodyQ:
        if (c.component == 0)
          q.push_back({body + ".attitude", "attitude", "",
                       {body + ".qw", body + ".qx", body + ".qy", body + ".qz"}, true});
        break;
      // Joint coordinates by their unit: angles ("angle") and lengths ("position"); a joint with
      // more than one coordinate (a universal joint) also answers to "<joint>.angle" and
      // "<joint>.rate" for all of them.
      case ColumnKind::JointCoordinate:
        q.push_back({c.name, c.unit == "m" ? "position" : "angle",
                     multi(c) ? joint + (c.unit == "m" ? ".position" : ".angle") : "", {c.name}, false});
        break;
      case ColumnKind::JointRate:
        q.push_back({c.name, "rate", multi(c) ? joint + ".rate" : "", {c.name}, false});
        break;
      case ColumnKind::JointTorque: q.push_back({c.name, "torque", "", {c.name}, false}); break;
      case ColumnKind::SphericalW: q.push_back({c.name, "rate", joint + ".w", {c.name}, false}); break;
      case ColumnKind::Modal:
      case ColumnKind::ModalRate: q.push_back({c.name, "modal", "", {c.name}, false}); break;
      case ColumnKind::MomentumH: q.push_back({"H", "H", "", {"H"}, false}); break;
      case ColumnKind::EnergyE: q.push_back({"E", "E", "", {"E"}, false}); break;
      // Issue 26's columns: positions with the joints' (m), the momentum vector and the external
      // moment with H, the power with E, the joints' forces and moments as loads.
      case ColumnKind::BodyPosition:
        q.push_back({c.name, "position", body + ".position", {c.name}, false, xyz(body + ".")});
        break;
      case ColumnKind::SystemCM: q.push_back({c.name, "position", "CM", {c.name}, false, xyz("CM")}); break;
      case ColumnKind::MomentumVector: q.push_back({c.name, "H", "", {c.name}, false, xyz("H")}); break;
      case ColumnKind::ExternalMoment: q.push_back({c.name, "H", "M", {c.name}, false, xyz("M")}); break;
      case ColumnKind::Power: q.push_back({"P", "E", "", {"P"}, false}); break;
      case ColumnKind::JointForce:
        q.push_back({c.name, "load", joint + ".F", {c.name}, false, xyz(joint + ".F")});
        break;
      case ColumnKind::JointMoment:
        q.push_back({c.name, "load", joint + ".M", {c.name}, false, xyz(joint + ".M")});
        break;
      // Issue 28: the Jacobi integral with E; roll, pitch and yaw relative to the orbit frame are
      // q_NB seen from the orbit frame (RowWriter::body), compared as <body>.attitude already (and
      // an angle that wraps at +-pi would not compare as a number).
      case ColumnKind::Jacobi: q.push_back({"J", "E", "", {"J"}, false}); break;
      case ColumnKind::LvlhAngle:
      case ColumnKind::LvlhRate:
      case ColumnKind::Time:
      case ColumnKind::Extra: break;
    }
  }
  return q;
}

// Keys looked up for a quantity, most specific first (compare.hpp).
std::vector<std::string> lookup_keys(const Quantity& q) {
  std::vector<std::string> k{q.name};
  if (!q.vector_key.empty()) k.push_back(q.vector_key);
  if (q.group != q.name) k.push_back(q.group);
  return k;
}

struct Lookup {
  const System& s;
  std::set<std::string>* used;

  std::pair<std::string, Tolerance> tolerance(const std::vector<std::string>& keys,
                                              const Tolerance& fallback) const {
    for (const std::string& key : keys)
      for (const auto& [name, tol] : s.compare.tolerances)
        if (name == key) {
          used->insert(key);
          return {key, tol};
        }
    return {"default", fallback};
  }
  const std::string* exclusion(const std::vector<std::string>& keys) const {
    for (const std::string& key : keys)
      for (const auto& [name, reason] : s.compare.excluded)
        if (name == key) {
          used->insert(key);
          return &reason;
        }
    return nullptr;
  }
};

int column_index(const RunResult& r, const std::string& name) {
  const auto it = std::find(r.columns.begin(), r.columns.end(), name);
  return it == r.columns.end() ? -1 : static_cast<int>(it - r.columns.begin());
}

// Fills bound, normalised, status from error and scale (NaN errors fail).
void finish(Check& c) {
  c.bound = c.tolerance.atol + c.tolerance.rtol * c.scale + c.allowance;
  if (c.error == 0) c.normalised = 0;
  else if (c.bound > 0) c.normalised = c.error / c.bound;
  else c.normalised = std::numeric_limits<double>::infinity();
  if (!(c.error <= c.bound)) c.status = CheckStatus::Fail;
  if (std::isnan(c.error)) c.normalised = kNaN;
}

// The streaming comparison. Every check that needs the rows is an Accumulator; compare_runs reads
// the runs' rows in lockstep (row k of every run at once) and feeds each accumulator, so memory
// does not grow with the number of rows. Pass 1 finds the largest error, its time and the scale;
// pass 2 (only for checks that failed) finds the first time the error exceeded the bound, which
// needs the bound and therefore the whole of pass 1.
// The integral from the first output time of a rate sampled at the output times (a balance's W,
// issue 26), its pieces separated by the scene's breakpoints (System::breakpoints(): a motor or
// torque switching between two output times, where the rate jumps). Within a piece each interval
// is integrated by the polynomial through the piece's last (up to) three samples: the quadratic
// through the interval and the sample before it (the piece's first interval, once its third sample
// arrives, by the quadratic of its first three), third order in the output step. Across a
// breakpoint tb in (t_prev, t]: [t_prev, tb] by the left piece's polynomial carried to tb, [tb, t]
// by the right piece's, provisional (its value at t) until the right piece has two and then three
// samples, then corrected. estimate() sums what each rule differs from the next lower one
// (quadratic against trapezoid, each correction): an estimate of the error of W, which the balance
// check adds to its bound.
class PiecewiseQuadrature {
 public:
  void reset(std::size_t components, const std::vector<double>* breakpoints) {
    n_ = components;
    breaks_ = breakpoints;
    next_break_ = 0;
    piece_.clear();
    pending_ = false;
    W_ = {};
    estimate_ = 0;
  }
  const std::array<double, 3>& integral() const { return W_; }
  double estimate() const { return estimate_; }

  void add(double t, const std::array<double, 3>& f) {
    if (piece_.empty()) {
      piece_.push_back({t, f});
      skip_breaks_to(t);
      count_ = 1;
      return;
    }
    const double t_prev = piece_.back().t;
    double b_first = 0, b_last = 0;
    bool jump = false;
    while (breaks_ && next_break_ < breaks_->size() && (*breaks_)[next_break_] <= t) {
      const double b = (*breaks_)[next_break_++];
      if (b <= t_prev) continue;
      if (!jump) b_first = b;
      b_last = b;
      jump = true;
    }
    if (jump) {
      // The left piece to the first breakpoint (its polynomial against the one of one degree less).
      for (std::size_t i = 0; i < n_; ++i) {
        const double left = integrate(piece_, i, t_prev, b_first, piece_.size());
        W_[i] += left;
        if (piece_.size() >= 2)
          estimate_ += std::abs(left - integrate(piece_, i, t_prev, b_first, piece_.size() - 1));
        // Between two breakpoints in one interval nothing is sampled: its size is the estimate.
        W_[i] += f[i] * (b_last - b_first);
        estimate_ += (std::abs(f[i]) + std::abs(piece_.back().f[i])) * (b_last - b_first);
        provisional_[i] = f[i] * (t - b_last);  // the right piece, until it has more samples
        W_[i] += provisional_[i];
      }
      pending_ = true;
      tb_ = b_last;
      piece_.assign(1, {t, f});
      count_ = 1;
      return;
    }
    piece_.push_back({t, f});
    if (piece_.size() > 3) piece_.erase(piece_.begin());
    ++count_;
    const std::size_t m = piece_.size();
    const double a = m >= 3 ? piece_[1].t - piece_[0].t : 0;
    for (std::size_t i = 0; i < n_; ++i) {
      const double trapezoid = (t - t_prev) / 2 * (piece_[m - 2].f[i] + f[i]);
      if (m == 2) {
        W_[i] += trapezoid;
        first_trapezoid_[i] = trapezoid;
      } else {
        const double q = integrate(piece_, i, t_prev, t, 3);
        W_[i] += q;
        estimate_ += std::abs(q - trapezoid);
        if (count_ == 3) {  // the piece's first interval, by its first three samples
          const double first = integrate(piece_, i, piece_[0].t, piece_[0].t + a, 3);
          W_[i] += first - first_trapezoid_[i];
          estimate_ += std::abs(first - first_trapezoid_[i]);
        }
      }
      if (pending_ && count_ <= 3) {  // the right piece of the last breakpoint, corrected
        const double better = integrate(piece_, i, tb_, piece_[count_ == 3 ? 0 : m - 2].t, std::min<std::size_t>(m, 3));
        W_[i] += better - provisional_[i];
        estimate_ += std::abs(better - provisional_[i]);
        provisional_[i] = better;
      }
    }
    if (count_ >= 3) pending_ = false;
  }

 private:
  struct Sample {
    double t;
    std::array<double, 3> f;
  };
  // The integral over [u, v] of component i of the polynomial through the first `degree + 1`
  // (1 to 3) of the last samples of p (Newton's form about p's first sample used).
  static double integrate(const std::vector<Sample>& p, std::size_t i, double u, double v, std::size_t points) {
    const std::size_t first = p.size() - points;
    const Sample& s0 = p[first];
    const double U = u - s0.t, V = v - s0.t;
    double r = s0.f[i] * (V - U);
    if (points >= 2) {
      const Sample& s1 = p[first + 1];
      const double h1 = s1.t - s0.t;
      const double d1 = (s1.f[i] - s0.f[i]) / h1;
      r += d1 * (V * V - U * U) / 2;
      if (points >= 3) {
        const Sample& s2 = p[first + 2];
        const double d12 = (s2.f[i] - s1.f[i]) / (s2.t - s1.t);
        const double d2 = (d12 - d1) / (s2.t - s0.t);
        r += d2 * ((V * V * V - U * U * U) / 3 - h1 * (V * V - U * U) / 2);
      }
    }
    return r;
  }
  void skip_breaks_to(double t) {
    while (breaks_ && next_break_ < breaks_->size() && (*breaks_)[next_break_] <= t) ++next_break_;
  }

  std::size_t n_ = 1;
  const std::vector<double>* breaks_ = nullptr;
  std::size_t next_break_ = 0;
  std::vector<Sample> piece_;  // the current piece's last (up to) three samples
  int count_ = 0;              // samples in the current piece so far
  bool pending_ = false;       // the right piece of breakpoint tb_ is still provisional
  double tb_ = 0;
  std::array<double, 3> W_{}, provisional_{}, first_trapezoid_{};
  double estimate_ = 0;
};

struct Accumulator {
  enum class Kind { Pair, Drift, Time, Balance, Rate };
  Kind kind = Kind::Pair;
  Check* check = nullptr;
  std::size_t a = 0, b = 0;   // runs (indices into the lockstep rows); b unused for Drift
  std::vector<int> ca, cb;    // the quantity's columns in a and b
  std::vector<int> cs;        // Pair: the columns of b whose norm is the scale (else cb[0]'s)
  int ta = -1, tb = -1;       // time column of a (and b for Time)
  bool attitude = false;
  std::size_t n = 0;          // rows compared: min of the two runs' rows
  double tol = 0;             // Time: allowed difference of output times
  double x0 = 0;              // Drift: the value at row 0
  bool stopped = false;       // a NaN error was found: error and time stay as they are
  bool found = false;         // pass 2: first_exceeded is set
  // Balance: X (ca: E, or Hx Hy Hz) against the integral W of its rate (cb, in run a: P, or Mx
  // My Mz) from the first output time, X(t) - X(0) - W(t); W by PiecewiseQuadrature over the
  // scene's breakpoints, whose error estimate is added to the check's bound.
  std::array<double, 3> X0{};
  double rate_integral = 0, t_last = 0;
  // Rate: the largest estimated error of the differences, and the rows without them.
  double difference_error = 0;
  std::size_t unevaluated = 0;
  const std::vector<double>* breakpoints = nullptr;
  PiecewiseQuadrature quadrature;

  // Error at one row (pass 1 also widens the scale).
  double error(const double* A, const double* B, std::size_t k, bool widen_scale) {
    switch (kind) {
      case Kind::Pair: {
        if (attitude) {
          const Eigen::Quaterniond qa(A[ca[0]], A[ca[1]], A[ca[2]], A[ca[3]]);
          const Eigen::Quaterniond qb(B[cb[0]], B[cb[1]], B[cb[2]], B[cb[3]]);
          return rot::angle_between(qa.normalized(), qb.normalized());
        }
        const double va = A[ca[0]], vb = B[cb[0]];
        if (widen_scale) {
          double v = std::abs(vb);
          if (!cs.empty()) {
            double n2 = 0;
            for (int c : cs) n2 += B[c] * B[c];
            v = std::sqrt(n2);
          }
          check->scale = std::max(check->scale, v);
        }
        if (!std::isfinite(va) || !std::isfinite(vb)) return kNaN;
        return std::abs(va - vb);
      }
      case Kind::Drift:
        if (k == 0) {
          x0 = A[ca[0]];
          if (widen_scale) check->scale = std::abs(x0);
        }
        return std::abs(A[ca[0]] - x0);
      case Kind::Time:
        return std::abs(A[ta] - B[tb]);
      case Kind::Balance:
        return balance_error(A, k, widen_scale);
      case Kind::Rate: {
        // ca: dX/dt (1 or 3 columns), cb: the engine's rate (P, or M), cs: the differences' errors.
        double e2 = 0, d2 = 0, r2 = 0, err2 = 0;
        for (std::size_t i = 0; i < ca.size(); ++i) {
          const double d = A[ca[i]], r = A[cb[i]];
          if (std::isnan(d)) {  // the engine could not be evaluated beside this row
            if (widen_scale) ++unevaluated;
            return 0;
          }
          e2 += (d - r) * (d - r);
          d2 += d * d;
          r2 += r * r;
          err2 += A[cs[i]] * A[cs[i]];
        }
        if (widen_scale) {
          check->scale = std::max({check->scale, std::sqrt(d2), std::sqrt(r2)});
          difference_error = std::max(difference_error, std::sqrt(err2));
        }
        return std::sqrt(e2);
      }
    }
    return kNaN;
  }

  double balance_error(const double* A, std::size_t k, bool widen_scale) {
    const std::size_t n = ca.size();
    const double t = A[ta];
    std::array<double, 3> f{};
    double rate_norm = 0;
    for (std::size_t i = 0; i < n; ++i) {
      f[i] = A[cb[i]];
      rate_norm += f[i] * f[i];
    }
    if (k == 0) {
      for (std::size_t i = 0; i < n; ++i) X0[i] = A[ca[i]];
      quadrature.reset(n, breakpoints);
      rate_integral = 0;
    } else {
      rate_integral += (t - t_last) * std::sqrt(rate_norm);
    }
    t_last = t;
    quadrature.add(t, f);
    double e2 = 0, x2 = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double d = A[ca[i]] - X0[i] - quadrature.integral()[i];
      e2 += d * d;
      x2 += A[ca[i]] * A[ca[i]];
    }
    if (widen_scale) check->scale = std::max({check->scale, std::sqrt(x2), rate_integral});
    return std::sqrt(e2);
  }

  void pass1(const double* A, const double* B, std::size_t k) {
    Check& c = *check;
    const double e = error(A, B, k, true);
    if (kind == Kind::Time) {
      if (!(e <= tol) && (std::isnan(e) || e > c.error)) {
        c.error = e;
        c.time = A[ta];
      }
      return;
    }
    if (stopped) return;
    if (std::isnan(e) || e > c.error) {
      c.error = e;
      c.time = ta >= 0 ? A[ta] : kNaN;
      if (std::isnan(e)) stopped = true;
    }
  }

  void pass2(const double* A, const double* B, std::size_t k) {
    if (found) return;
    if (!(error(A, B, k, false) <= check->bound)) {
      check->first_exceeded = ta >= 0 ? A[ta] : kNaN;
      found = true;
    }
  }
};

// Feeds rows 0 .. n-1 of every run to the accumulators, in lockstep; `second` selects pass 2.
void feed(const std::vector<const EngineRun*>& runs, std::vector<Accumulator*>& accs, bool second) {
  if (accs.empty()) return;
  std::vector<RowReader> readers;
  for (const EngineRun* r : runs) readers.push_back(r->result.reader());
  std::size_t needed = 0;
  for (const Accumulator* acc : accs) needed = std::max(needed, acc->n);
  std::vector<const double*> row(runs.size(), nullptr);
  for (std::size_t k = 0; k < needed; ++k) {
    if ((k & 1023) == 0) cancel::poll();
    for (std::size_t i = 0; i < runs.size(); ++i) row[i] = k < readers[i].rows() ? readers[i].next() : nullptr;
    bool pending = false;
    for (Accumulator* acc : accs) {
      if (k >= acc->n) continue;
      const bool one_run = acc->kind == Accumulator::Kind::Drift || acc->kind == Accumulator::Kind::Balance ||
                           acc->kind == Accumulator::Kind::Rate;
      const double* B = one_run ? nullptr : row[acc->b];
      if (second) {
        acc->pass2(row[acc->a], B, k);
        pending = pending || !acc->found;
      } else {
        acc->pass1(row[acc->a], B, k);
      }
    }
    if (second && !pending) break;
  }
}

// Pairwise check of one quantity: a = runs[ia] against the reference b = runs[ib]. Returns the
// check, and in `acc` what pass 1 needs, unless the check is settled without the rows (excluded,
// a column missing).
Check pair_check(const Quantity& q, const EngineRun& A, const EngineRun& B, const Lookup& look,
                 const Tolerance& fallback, std::optional<Accumulator>& acc) {
  Check c;
  c.quantity = q.name;
  c.group = q.group;
  c.a = A.label;
  c.b = B.label;
  const std::vector<std::string> keys = lookup_keys(q);
  std::tie(c.tolerance_key, c.tolerance) = look.tolerance(keys, fallback);
  if (const std::string* reason = look.exclusion(keys)) {
    c.status = CheckStatus::Excluded;
    c.note = *reason;
    return c;
  }
  std::vector<int> ca, cb;
  for (const std::string& col : q.columns) {
    ca.push_back(column_index(A.result, col));
    cb.push_back(column_index(B.result, col));
    for (const auto& [run, idx] : {std::pair{&A, ca.back()}, std::pair{&B, cb.back()}})
      if (idx < 0 && c.note.empty()) c.note = "column '" + col + "' missing from " + run->label + "'s output";
  }
  if (!c.note.empty()) {
    c.status = CheckStatus::Fail;
    c.error = c.normalised = kNaN;
    return c;
  }
  c.scale = q.attitude ? 1.0 : 0.0;
  c.error = 0;
  acc.emplace();
  acc->kind = Accumulator::Kind::Pair;
  acc->ca = std::move(ca);
  acc->cb = std::move(cb);
  for (const std::string& col : q.scale_columns) {
    const int i = column_index(B.result, col);
    if (i >= 0) acc->cs.push_back(i);
  }
  if (acc->cs.size() != q.scale_columns.size()) acc->cs.clear();
  acc->ta = column_index(A.result, "t");
  acc->attitude = q.attitude;
  acc->n = std::min(A.result.rows(), B.result.rows());
  return c;
}

// Drift of H or E of one engine from its initial value (a quantity the scene conserves).
Check drift_check(const std::string& x, const EngineRun& R, const Lookup& look,
                  std::optional<Accumulator>& acc) {
  Check c;
  c.quantity = x + ".drift";
  c.group = c.quantity;
  c.a = R.label;
  const Tolerance fallback{kDefaultDriftTolerance, kDefaultDriftTolerance};
  std::tie(c.tolerance_key, c.tolerance) = look.tolerance({c.quantity, "drift"}, fallback);
  if (const std::string* reason = look.exclusion({c.quantity, "drift"})) {
    c.status = CheckStatus::Excluded;
    c.note = *reason;
    return c;
  }
  const int ix = column_index(R.result, x), it = column_index(R.result, "t");
  if (ix < 0 || R.result.rows() == 0) {
    c.status = CheckStatus::Fail;
    c.error = c.normalised = kNaN;
    c.note = "column '" + x + "' missing from " + R.label + "'s output";
    return c;
  }
  acc.emplace();
  acc->kind = Accumulator::Kind::Drift;
  acc->ca = {ix};
  acc->ta = it;
  acc->n = R.result.rows();
  return c;
}

// The columns of E or H in one engine's run that its balance and rate checks read: the quantity
// (E; H as the vector Hx Hy Hz), the rate the engine reports for it (P; M as Mx My Mz) and, in
// compare's runs, its derivative along the motion (core/integrate.hpp, rate_column_names(): dE_dt,
// then dHx_dt dHy_dt dHz_dt).
struct BalancedColumns {
  std::vector<std::string> x, rate, derivative;
};
BalancedColumns balanced_columns(const std::string& x) {
  const auto& d = rate_column_names();
  if (x == "E") return {{"E"}, {"P"}, {d[0]}};
  return {{"Hx", "Hy", "Hz"}, {"Mx", "My", "Mz"}, {d[1], d[2], d[3]}};
}

// Balance of H or E of one engine that does not conserve it (issue 26): X(t) - X(0) against the
// integral of its rate from the engine's own loads (E: P; H: the external moment M), |X(t) - X(0) -
// W(t)| <= atol + rtol * max(max_t |X|, integral of |rate|) + the quadrature's estimate.
Check balance_check(const std::string& x, const EngineRun& R, const Lookup& look,
                    const std::string& not_conserved, std::optional<Accumulator>& acc) {
  Check c;
  c.quantity = x + ".balance";
  c.group = c.quantity;
  c.a = R.label;
  const Tolerance fallback{kDefaultDriftTolerance, kDefaultDriftTolerance};
  std::tie(c.tolerance_key, c.tolerance) = look.tolerance({c.quantity, "balance"}, fallback);
  if (const std::string* reason = look.exclusion({c.quantity, "balance"})) {
    c.status = CheckStatus::Excluded;
    c.note = *reason;
    return c;
  }
  const bool energy = x == "E";
  const BalancedColumns names = balanced_columns(x);
  const std::vector<std::string>& xs = names.x;
  const std::vector<std::string>& rates = names.rate;
  std::vector<int> ca, cb;
  for (std::size_t i = 0; i < xs.size(); ++i) {
    ca.push_back(column_index(R.result, xs[i]));
    cb.push_back(column_index(R.result, rates[i]));
    for (const auto& [name, idx] : {std::pair{&xs[i], ca.back()}, std::pair{&rates[i], cb.back()}})
      if (idx < 0 && c.note.empty()) c.note = "column '" + *name + "' missing from " + R.label + "'s output";
  }
  const int it = column_index(R.result, "t");
  if (!c.note.empty() || it < 0 || R.result.rows() == 0) {
    c.status = CheckStatus::Fail;
    c.error = c.normalised = kNaN;
    if (c.note.empty()) c.note = R.label + "'s output has no rows";
    return c;
  }
  c.note = "not conserved (" + not_conserved.substr(not_conserved.rfind("has ") == std::string::npos
                                                        ? 0
                                                        : not_conserved.rfind("has ") + 4) +
           "): " + x + "(t) - " + x + "(0) against the integral of " + (energy ? "P" : "M");
  acc.emplace();
  acc->kind = Accumulator::Kind::Balance;
  acc->ca = std::move(ca);
  acc->cb = std::move(cb);
  acc->ta = it;
  acc->n = R.result.rows();
  return c;
}

// The rate of H or E of one engine against its own P or M, row by row (issue 26): dX/dt from the
// runner's differences along the engine's motion (IntegratorSettings::rate_columns). Settled
// without rows (nothing to check) when the run has no rate columns.
std::optional<Check> rate_check(const std::string& x, const EngineRun& R, const Lookup& look,
                                std::optional<Accumulator>& acc) {
  const bool energy = x == "E";
  const BalancedColumns names = balanced_columns(x);
  const std::vector<std::string>& d = names.derivative;
  const std::vector<std::string>& r = names.rate;
  std::vector<int> ca, cb, cs;
  for (std::size_t i = 0; i < d.size(); ++i) {
    ca.push_back(column_index(R.result, d[i]));
    cb.push_back(column_index(R.result, r[i]));
    cs.push_back(column_index(R.result, d[i] + ".err"));
  }
  const int it = column_index(R.result, "t");
  const auto missing = [](const std::vector<int>& v) { return std::find(v.begin(), v.end(), -1) != v.end(); };
  if (missing(ca) || missing(cs) || it < 0 || R.result.rows() == 0) return std::nullopt;
  Check c;
  c.quantity = x + ".rate";
  c.group = x + ".balance";
  c.a = R.label;
  const Tolerance fallback{kDefaultDriftTolerance, kDefaultRateTolerance};
  std::tie(c.tolerance_key, c.tolerance) = look.tolerance({c.quantity, "balance"}, fallback);
  if (const std::string* reason = look.exclusion({c.quantity, "balance"})) {
    c.status = CheckStatus::Excluded;
    c.note = *reason;
    return c;
  }
  if (missing(cb)) {
    c.status = CheckStatus::Fail;
    c.error = c.normalised = kNaN;
    c.note = "column '" + r[0] + "' missing from " + R.label + "'s output";
    return c;
  }
  c.note = std::string("d") + x + "/dt along the engine's own motion against its " +
           (energy ? "power P" : "external moment M");
  acc.emplace();
  acc->kind = Accumulator::Kind::Rate;
  acc->ca = std::move(ca);
  acc->cb = std::move(cb);
  acc->cs = std::move(cs);
  acc->ta = it;
  acc->n = R.result.rows();
  return c;
}

// Output times of two runs agree (row by row, to 1e-9 of the output step)? The check is kept
// only when they do not (finish_time_check).
Check time_check(const EngineRun& A, const EngineRun& B, double tol, std::optional<Accumulator>& acc) {
  const int ta = column_index(A.result, "t"), tb = column_index(B.result, "t");
  Check c;
  c.quantity = c.group = "t";
  c.a = A.label;
  c.b = B.label;
  c.tolerance = Tolerance{tol, 0};
  c.tolerance_key = "output times";
  if (ta < 0 || tb < 0) {
    c.status = CheckStatus::Fail;
    c.error = c.normalised = kNaN;
    c.note = "column 't' missing";
    return c;
  }
  acc.emplace();
  acc->kind = Accumulator::Kind::Time;
  acc->ta = ta;
  acc->tb = tb;
  acc->tol = tol;
  acc->n = std::min(A.result.rows(), B.result.rows());
  return c;
}

// After pass 1: false when the output times agree (the check is dropped).
bool finish_time_check(Check& c, const EngineRun& A, const EngineRun& B, bool streamed) {
  if (!streamed) return true;  // settled without rows (a 't' column missing)
  if (A.result.rows() != B.result.rows()) {
    c.note = A.label + " has " + std::to_string(A.result.rows()) + " rows, " + B.label + " " +
             std::to_string(B.result.rows());
    c.error = std::max(c.error, std::numeric_limits<double>::infinity());
  }
  if (c.error == 0) return false;
  finish(c);
  if (c.note.empty()) c.note = "the two runs were sampled at different output times";
  return true;
}

// Dampers on joints (joints[].damper) and a flexible body's modal damping (its matrix D) both
// dissipate energy; the reason names which one the scene has.
bool has_joint_dampers(const System& s) {
  for (const Joint& j : s.joints)
    if (j.has_damper()) return true;
  return false;
}
bool has_modal_damping(const System& s) {
  for (const Body& b : s.bodies)
    if (b.flex && b.flex->D.size() > 0 && b.flex->D.cwiseAbs().maxCoeff() > 0) return true;
  return false;
}
bool has_motors(const System& s) {
  for (const Joint& j : s.joints)
    if (j.has_motor()) return true;
  return false;
}
bool has_external_torques(const System& s) {
  for (const Body& b : s.bodies)
    if (!b.torque.empty()) return true;
  return false;
}

}  // namespace

void judge_check(Check& c) {
  c.status = CheckStatus::Pass;
  finish(c);
}

const char* to_string(CheckStatus s) {
  switch (s) {
    case CheckStatus::Pass: return "PASS";
    case CheckStatus::Fail: return "FAIL";
    case CheckStatus::Excluded: return "EXCLUDED";
    case CheckStatus::Skipped: return "SKIPPED";
  }
  return "?";
}

bool SceneComparison::passed() const { return count(CheckStatus::Fail) == 0; }

int SceneComparison::count(CheckStatus s) const {
  return static_cast<int>(std::count_if(checks.begin(), checks.end(),
                                        [s](const Check& c) { return c.status == s; }));
}

namespace {
// The non-conservative loads of a scene ("" when none): what changes E (and, on an orbit, J).
std::string nonconservative_loads(const System& s) {
  std::vector<std::string> why;
  if (has_joint_dampers(s)) why.push_back("joint dampers");
  if (has_modal_damping(s)) why.push_back("modal damping");
  if (has_motors(s)) why.push_back("motors");
  if (has_external_torques(s)) why.push_back("external torques");
  if (std::any_of(s.joints.begin(), s.joints.end(), [](const Joint& j) { return j.prescribed.has_value(); }))
    why.push_back("prescribed joints");
  if (why.empty()) return "";
  std::string r = "scene has ";
  for (std::size_t i = 0; i < why.size(); ++i)
    r += (i == 0 ? "" : i + 1 == why.size() ? " and " : ", ") + why[i];
  return r;
}
}  // namespace

// On an orbit the gravity-gradient potential turns with the orbit frame, so E changes even without
// such loads (docs/environment.md): the Jacobi integral J is conserved instead.
std::string energy_not_conserved_reason(const System& s) {
  const std::string loads = nonconservative_loads(s);
  if (!s.environment.orbit()) return loads;
  const std::string orbit = "the gravity-gradient potential turns with the orbit (J is checked instead)";
  return loads.empty() ? orbit : loads + "; " + orbit;
}

std::string jacobi_not_conserved_reason(const System& s) { return nonconservative_loads(s); }

std::string momentum_not_conserved_reason(const System& s) {
  if (has_external_torques(s)) return "scene has external torques";
  if (!s.joints.empty() && !s.base_is_free()) return "scene has a prescribed base";
  if (s.environment.orbit()) return "the gravity gradient's moments";
  return "";
}

std::vector<double> output_times(const IntegratorSettings& settings) {
  // Same rule as the integrator plumbing (core/integrate.hpp): k * step, plus the duration.
  std::vector<double> t;
  const auto n = static_cast<long>(std::floor(settings.duration / settings.output_step * (1 + 1e-12)));
  for (long k = 0; k <= n; ++k) t.push_back(static_cast<double>(k) * settings.output_step);
  if (settings.duration - t.back() > 1e-9 * settings.output_step) t.push_back(settings.duration);
  return t;
}

RunResult analytic_run(const System& system, const std::vector<double>& times) {
  if (!analytic::is_torque_free(system))
    throw InputError(system.file + ": the torque-free analytic reference needs a single free rigid "
                     "body without loads");
  const Body& body = system.bodies[0];
  const TreeState s0 = TreeState::initial(system);
  const analytic::TorqueFreeBody reference(body.I_BBo_B, s0.w_NB_B, s0.q_NB);
  // Translational kinetic energy is constant; zero when the scene zeroes the linear momentum.
  const double E_translation =
      system.zero_linear_momentum ? 0.0 : 0.5 * body.mass * s0.v_NBo_N.squaredNorm();
  RunResult r;
  r.engine = "analytic";
  r.columns = pinned_columns(system);
  RowStore rows(r.columns.size());
  for (double t : times) {
    if ((rows.rows() & 1023) == 0) cancel::poll();
    const analytic::TorqueFreeState x = reference.at(t);
    const Eigen::Quaterniond q = rot::canonical(x.q_NB);
    const Eigen::Vector3d H_B = body.I_BBo_B * x.w_NB_B;
    const Eigen::Vector3d H_N = x.q_NB * H_B;
    // The CM moves uniformly: p_NoBo_N(t) = p_NoBo_N(0) + v t (v zero when the scene zeroes the
    // linear momentum); no loads, so P and M are zero.
    const Eigen::Vector3d v = system.zero_linear_momentum ? Eigen::Vector3d::Zero() : s0.v_NBo_N;
    const Eigen::Vector3d p = s0.p_NoBo_N + v * t;
    const double row[] = {t, x.w_NB_B.x(), x.w_NB_B.y(), x.w_NB_B.z(), q.w(), q.x(), q.y(), q.z(),
                          H_B.norm(), 0.5 * x.w_NB_B.dot(H_B) + E_translation,
                          p.x(), p.y(), p.z(), p.x(), p.y(), p.z(), H_N.x(), H_N.y(), H_N.z(),
                          0, 0, 0, 0};
    if (r.columns.size() != std::size(row))
      throw std::logic_error("analytic_run: the pinned columns of a single body changed");
    rows.append(row);
  }
  r.store(rows.finish());
  return r;
}

namespace {

// The closest approach of each universal joint's boresight to its outer axis in a run, as notes
// for those within kKeyholeNoteRad (see compare_runs).
constexpr double kKeyholeNoteRad = 10 * std::numbers::pi / 180;
std::vector<std::string> keyhole_notes(const System& system, const RunResult& run) {
  std::vector<std::string> notes;
  for (const Joint& J : system.joints) {
    if (J.type != JointType::Universal) continue;
    const int a2 = run.column(J.name + ".angle2");
    const int t = run.column("t");
    if (a2 < 0 || t < 0) continue;
    const double sin_alpha = J.axis_P.normalized().cross(J.axis2_P.normalized()).norm();
    double closest = std::numbers::pi / 2, at = 0, angle2 = 0;
    run.for_each_row([&](const double* row) {
      const double c = std::acos(std::min(1.0, std::abs(std::sin(row[a2])) * sin_alpha));
      if (c < closest) {
        closest = c;
        at = row[t];
        angle2 = row[a2];
      }
    });
    if (closest > kKeyholeNoteRad) continue;
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "%s: the gimbal's boresight (axis x axis2, the direction both axes leave free) came "
                  "within %.3g deg of its outer axis at t = %.6g s (angle2 %.4g deg): near there the "
                  "outer axis no longer turns it (a two-axis gimbal's keyhole); the dynamics have no "
                  "singularity there",
                  J.name.c_str(), closest * 180 / std::numbers::pi, at, angle2 * 180 / std::numbers::pi);
    notes.emplace_back(buf);
  }
  return notes;
}

}  // namespace

namespace {
const std::string kLoadsNote =
    "joint loads differ while the motions agree: loads follow the accelerations, in which a stiff "
    "mode or spring multiplies an integration error by its stiffness; run compare at a tighter "
    "--rtol and --atol: a difference that falls with them is integration, one that stays is "
    "physics (then set the scene's `load` tolerance if the difference is below what matters)";
}  // namespace

SceneComparison compare_runs(const System& system, std::vector<EngineRun> runs) {
  SceneComparison out;
  out.scene = system.name;
  out.file = system.file;
  out.runs = std::move(runs);
  std::set<std::string> used;
  const Lookup look{system, &used};
  const Tolerance fallback = system.compare.default_tolerance;

  // Runs: one check each (pass, failure with time and reason, or skipped).
  std::vector<const EngineRun*> ok;
  for (const EngineRun& r : out.runs) {
    if (r.engine == "analytic") {
      ok.push_back(&r);
      continue;
    }
    Check c;
    c.quantity = c.group = "run";
    c.a = r.label;
    c.tolerance_key = "-";
    c.note = r.note;
    if (r.state == EngineRun::State::NotBuilt) {
      c.status = CheckStatus::Skipped;
    } else if (r.state == EngineRun::State::Failed || r.result.failure) {
      c.status = CheckStatus::Fail;
      c.error = c.normalised = std::numeric_limits<double>::infinity();
      if (r.result.failure) {
        c.time = r.result.failure->time();
        if (c.note.empty()) c.note = r.result.failure->what();
      }
      out.notes.push_back(r.label + " left out of the comparison: " + c.note);
    } else {
      ok.push_back(&r);
    }
    out.checks.push_back(c);
  }
  for (const EngineRun& r : out.runs)
    if (r.state == EngineRun::State::NotBuilt) out.notes.push_back(r.label + " skipped: " + r.note);

  // Pairs (a, b) with b the reference: the earlier run.
  std::vector<std::pair<const EngineRun*, const EngineRun*>> pairs;
  for (std::size_t j = 0; j < ok.size(); ++j)
    for (std::size_t i = 0; i < j; ++i) pairs.emplace_back(ok[j], ok[i]);
  if (ok.size() < 2)
    out.notes.push_back(ok.empty() ? "no run finished: nothing to compare"
                                   : "only " + ok[0]->label + " finished: no pairwise comparison");

  // Every check is made first (in table order), with an accumulator when it needs the rows; then
  // the rows are read once in lockstep (pass 1), and again for the checks that failed (pass 2).
  auto index_of = [&ok](const EngineRun* r) {
    return static_cast<std::size_t>(std::find(ok.begin(), ok.end(), r) - ok.begin());
  };
  std::vector<Check> time_checks, checks;
  std::vector<std::optional<Accumulator>> time_accs, accs;
  const double t_tol = 1e-9 * std::max(1.0, system.run.output_step);
  for (const auto& [A, B] : pairs) {
    time_accs.emplace_back();
    time_checks.push_back(time_check(*A, *B, t_tol, time_accs.back()));
    if (time_accs.back()) {
      time_accs.back()->a = index_of(A);
      time_accs.back()->b = index_of(B);
    }
  }

  // Pinned quantities, then extra columns the scene's tolerances name.
  std::vector<Quantity> quantities = pinned_quantities(system);
  std::set<std::string> known_keys{"drift",     "H.drift", "E.drift", "J.drift", "balance",
                                   "H.balance", "E.balance", "H.rate", "E.rate"};
  for (const Quantity& q : quantities)
    for (const std::string& k : lookup_keys(q)) known_keys.insert(k);
  for (const auto& [key, tol] : system.compare.tolerances) {
    if (known_keys.count(key)) continue;
    bool in_all = !ok.empty();
    bool in_any = false;
    for (const EngineRun* r : ok) {
      const bool has = column_index(r->result, key) >= 0;
      in_all = in_all && has;
      in_any = in_any || has;
    }
    if (in_any) {
      quantities.push_back({key, "extra", "", {key}, false});
      known_keys.insert(key);
      if (!in_all) out.notes.push_back("extra column '" + key + "' is not written by every engine");
    }
  }
  for (const Quantity& q : quantities)
    for (const auto& [A, B] : pairs) {
      accs.emplace_back();
      checks.push_back(pair_check(q, *A, *B, look, fallback, accs.back()));
      if (accs.back()) {
        accs.back()->a = index_of(A);
        accs.back()->b = index_of(B);
      }
    }

  // Drift of each engine (not of the analytic solution): each conserved quantity with the reason
  // the scene does not conserve it ("" when it does).
  const std::string no_E = energy_not_conserved_reason(system);
  const std::string no_H = momentum_not_conserved_reason(system);
  const std::string no_J = jacobi_not_conserved_reason(system);
  const std::vector<double> breakpoints = system.breakpoints();  // where a balance's rate may jump
  const struct {
    const char* quantity;
    const std::string& not_conserved;
  } drifts[] = {{"H", no_H}, {"E", no_E}, {"J", no_J}};
  // A quantity the scene does not conserve is balanced instead (issue 26): its change against the
  // integral of the rate the engine reports from its own loads. On an orbit (issue 28) E has no
  // balance (its rate has the potential's turning, which P leaves out) and J is conserved or not
  // checked; without an orbit there is no J.
  const bool orbit = system.environment.orbit();
  for (const auto& d : drifts)
    for (const EngineRun* r : ok)
      if (r->engine != "analytic") {
        const std::string q = d.quantity;
        if (q == "J" && !orbit) continue;
        if ((q == "E" && orbit) || (q == "J" && !d.not_conserved.empty())) {
          Check c;
          c.quantity = q + ".drift";
          c.group = c.quantity;
          c.a = r->label;
          c.status = CheckStatus::Skipped;
          c.note = q == "E" ? "on an orbit E changes as the gravity-gradient potential turns with the "
                              "orbit frame; the Jacobi integral J is checked instead"
                            : "J is not conserved: " + d.not_conserved + " (no balance for J)";
          checks.push_back(std::move(c));
          accs.emplace_back();
          continue;
        }
        accs.emplace_back();
        checks.push_back(d.not_conserved.empty()
                             ? drift_check(d.quantity, *r, look, accs.back())
                             : balance_check(d.quantity, *r, look, d.not_conserved, accs.back()));
        if (accs.back()) {
          accs.back()->a = index_of(r);
          accs.back()->breakpoints = &breakpoints;
        }
        std::optional<Accumulator> rate;
        if (q == "J") continue;  // J has no rate column of its own
        if (std::optional<Check> k = rate_check(d.quantity, *r, look, rate)) {
          checks.push_back(std::move(*k));
          accs.push_back(std::move(rate));
          if (accs.back()) accs.back()->a = index_of(r);
        }
      }

  // Pass 1: largest errors, their times, the scales.
  std::vector<Accumulator*> live;
  for (std::size_t i = 0; i < time_accs.size(); ++i)
    if (time_accs[i]) {
      time_accs[i]->check = &time_checks[i];
      live.push_back(&*time_accs[i]);
    }
  for (std::size_t i = 0; i < accs.size(); ++i)
    if (accs[i]) {
      accs[i]->check = &checks[i];
      live.push_back(&*accs[i]);
    }
  feed(ok, live, false);
  // Pass 2: where each failed check first exceeded its bound.
  std::vector<Accumulator*> failed;
  for (std::size_t i = 0; i < accs.size(); ++i)
    if (accs[i]) {
      // A balance's bound has room for its quadrature on the output times (Accumulator).
      if (accs[i]->kind == Accumulator::Kind::Rate) {
        checks[i].allowance = accs[i]->difference_error;
        if (accs[i]->difference_error > 0)
          checks[i].note += "; the differences' estimated error " + sci(accs[i]->difference_error, 2) +
                            " in the bound";
        if (accs[i]->unevaluated)
          checks[i].note += "; " + std::to_string(accs[i]->unevaluated) +
                            " rows without a rate (the engine could not be evaluated beside them)";
      }
      if (accs[i]->kind == Accumulator::Kind::Balance && accs[i]->quadrature.estimate() > 0) {
        checks[i].allowance = accs[i]->quadrature.estimate();
        checks[i].note += "; quadrature of the output times: estimated error " +
                          sci(accs[i]->quadrature.estimate(), 2) + " in the bound";
      }
      finish(checks[i]);
      if (checks[i].status == CheckStatus::Fail) failed.push_back(&*accs[i]);
    }
  feed(ok, failed, true);

  for (std::size_t i = 0; i < pairs.size(); ++i)
    if (finish_time_check(time_checks[i], *pairs[i].first, *pairs[i].second, time_accs[i].has_value()))
      out.checks.push_back(time_checks[i]);
  out.checks.insert(out.checks.end(), checks.begin(), checks.end());

  // A universal joint's keyhole (a finding, not a failure): its boresight b, the direction both
  // axes leave free (axis x axis2 at zero angles, turned by angle2 about axis2), makes with the
  // outer axis the angle acos(|sin(angle2)| sin(alpha)), alpha the angle between the axes. At zero
  // the outer axis no longer turns the boresight: a pointing loop needs unbounded outer rates
  // there, the two-axis gimbal's lock. The dynamics have no singularity (the rates always span
  // the joint's motion), so the engines run through it; the note says how close the run came.
  if (!ok.empty())
    for (const std::string& note : keyhole_notes(system, ok.front()->result)) out.notes.push_back(note);

  // Joint loads follow the accelerations: where a stiff mode or a stiff spring carries them, an
  // integration error d_eta in the state shows in them as K d_eta (hub_nodal_panel's clamp: 3e-6
  // N m at rtol 1e-10, 3e-8 at 1e-12). When loads fail and the motions agree, say how to tell
  // integration from physics.
  const auto failed_in = [&out](std::initializer_list<const char*> groups) {
    return std::any_of(out.checks.begin(), out.checks.end(), [&groups](const Check& k) {
      return k.status == CheckStatus::Fail &&
             std::any_of(groups.begin(), groups.end(), [&k](const char* g) { return k.group == g; });
    });
  };
  if (failed_in({"load"}) && !failed_in({"run", "t", "w", "attitude", "rate", "angle", "position", "modal"}))
    out.notes.push_back(kLoadsNote);

  // Scene keys that match nothing are almost always typos: say so.
  for (const auto& [key, tol] : system.compare.tolerances)
    if (!known_keys.count(key) && !used.count(key))
      out.notes.push_back("tolerance '" + key + "' matches no compared quantity or column");
  for (const auto& [key, reason] : system.compare.excluded)
    if (!known_keys.count(key) && !used.count(key))
      out.notes.push_back("exclusion '" + key + "' matches no compared quantity");
  return out;
}

bool diagnosable(const SceneComparison& c) {
  bool failed = false;
  for (const Check& k : c.checks) {
    if (k.group == "run" && k.status != CheckStatus::Pass) return false;  // a run that did not finish
    failed = failed || k.status == CheckStatus::Fail;
  }
  return failed;
}

void diagnose(SceneComparison& c, const SceneComparison& t, double rtol, double atol) {
  if (!diagnosable(c)) return;
  const std::string at = "tolerances 100 times tighter (--rtol " + sci(rtol, 2) + " --atol " + sci(atol, 2) + ")";
  const auto describe = [](const Check& k) { return k.quantity + (k.b.empty() ? " (" + k.a + ")" : " (" + k.a + " vs " + k.b + ")"); };
  // Each failed check and the same check there: did its difference fall at least 10-fold?
  const Check* worst = nullptr;       // the largest failure that fell
  const Check* worst_again = nullptr;
  const Check* stays = nullptr;       // the largest that did not (or could not be compared)
  const Check* stays_again = nullptr;
  int n_stay = 0;
  bool loads = false;
  for (const Check& k : c.checks) {
    if (k.status != CheckStatus::Fail) continue;
    loads = loads || k.group == "load";
    const Check* again = nullptr;
    for (const Check& x : t.checks)
      if (x.quantity == k.quantity && x.a == k.a && x.b == k.b) again = &x;
    const bool fell = again && again->status != CheckStatus::Skipped && again->error <= 0.1 * k.error;
    const auto larger = [](const Check* best, const Check& x) {
      return !best || std::isnan(x.normalised) || x.normalised > best->normalised;
    };
    if (fell && larger(worst, k)) {
      worst = &k;
      worst_again = again;
    }
    if (!fell) {
      ++n_stay;
      if (larger(stays, k)) {
        stays = &k;
        stays_again = again;
      }
    }
  }
  std::string note;
  if (stays) {
    note = at + ": " + describe(*stays) + " " +
           (stays_again && stays_again->status != CheckStatus::Skipped
                ? "is " + sci(stays_again->error, 2) + ", was " + sci(stays->error, 2) +
                      ": it does not fall with the tolerances, so it is not integration error; the engines "
                      "disagree there"
                : std::string("could not be compared there")) +
           (n_stay > 1 ? " (and " + std::to_string(n_stay - 1) + " more failed checks that do not fall)" : "");
  } else {
    note = at + ": every failed check's difference falls at least 10-fold, the largest, " + describe(*worst) +
           ", from " + sci(worst->error, 2) + " to " + sci(worst_again->error, 2) + " (" +
           sci(worst->normalised, 2) + " -> " + sci(worst_again->normalised, 2) +
           " of its bound): integration error, not physics" +
           (loads ? "; joint loads follow the accelerations, in which a stiff mode or spring multiplies the "
                    "state's integration error by its stiffness"
                  : "") +
           ". " +
           (t.passed() ? "Every check passes there: set the scene's run.rtol and run.atol to those values"
                       : "Some still fail there: tighten the scene's run.rtol and run.atol further") +
           ", or the tolerance of what fails if the difference is below what matters";
  }
  // Measured, it replaces the advice to measure.
  c.notes.erase(std::remove(c.notes.begin(), c.notes.end(), kLoadsNote), c.notes.end());
  c.notes.push_back(note);
}

SceneComparison compare_scene(const System& system, const CompareOptions& options) {
  IntegratorSettings settings = IntegratorSettings::from(system.run);
  if (options.integrator) settings.method = *options.integrator;
  if (options.rtol) settings.rtol = *options.rtol;
  if (options.atol) settings.atol = *options.atol;
  if (options.dt) settings.dt = settings.first_step = *options.dt;
  if (options.max_steps) settings.max_steps = *options.max_steps;
  settings.rate_columns = options.rates;

  std::vector<EngineSpec> specs = options.engines;
  if (specs.empty())
    for (const std::string& name : engine_names()) specs.push_back({name, name, {}});

  ProgressLine progress(options.progress);
  std::vector<EngineRun> runs;
  for (const EngineSpec& spec : specs) {
    cancel::poll();
    EngineRun run;
    run.label = spec.label;
    run.engine = spec.engine;
    progress.start(system.name + " " + spec.label, settings.duration);
    progress.phase("setting up the engine");
    // The time limit covers the engine's set-up and its run; an interrupt ends everything.
    std::optional<cancel::Deadline> deadline;
    if (options.timeout) deadline.emplace(*options.timeout);
    std::unique_ptr<Engine> engine;
    try {
      engine = make_engine(spec.engine, system, spec.options);
    } catch (const InputError& e) {
      const std::string what = e.what();
      if (what.find("not built yet") == std::string::npos) throw;
      run.state = EngineRun::State::NotBuilt;
      run.note = what;
      runs.push_back(std::move(run));
      continue;
    } catch (const cancel::Cancelled& c) {
      if (c.reason() == cancel::Reason::Interrupt) throw;
      run.result.failure = RunFailure(spec.label, 0.0, "", std::string(c.what()) + " while setting up the engine");
    }
    if (engine) {
      try {
        run.result = simulate(*engine, system, TreeState::initial(system), settings, {},
                              [&progress](double t, const RunStats& s) { progress.update(t, s.steps); });
      } catch (const InputError&) {
        throw;
      } catch (const RunFailure& f) {
        run.result.failure = f;
      } catch (const cancel::Cancelled& c) {  // from pack() or output_row() outside simulate's care
        if (c.reason() == cancel::Reason::Interrupt) throw;
        run.result.failure = RunFailure(spec.label, 0.0, "", c.what());
      } catch (const std::bad_alloc&) {
        throw;  // out of memory is the command's error (exit 3), not an engine's failure
      } catch (const std::exception& e) {
        run.result.failure = RunFailure(spec.label, 0.0, "", std::string("unexpected error: ") + e.what());
      }
      engine.reset();  // a large engine's memory goes back before the next one is built
    }
    deadline.reset();
    progress.clear();
    run.result.engine = spec.label;
    if (run.result.failure) {
      if (cancel::interrupted()) throw cancel::Cancelled(cancel::Reason::Interrupt, 0);
      run.state = EngineRun::State::Failed;
      run.note = run.result.failure->what();
    }
    runs.push_back(std::move(run));
  }

  if (options.analytic && system.analytic == "torque-free") {
    // Sample at the engines' output times (identical by construction), else the nominal ones.
    std::vector<double> times = output_times(settings);
    for (const EngineRun& r : runs)
      if (r.state == EngineRun::State::Ok && column_index(r.result, "t") == 0 &&
          r.result.rows() == times.size()) {
        RowReader reader = r.result.reader();
        for (std::size_t k = 0; k < times.size(); ++k) times[k] = reader.next()[0];
        break;
      }
    EngineRun a;
    a.label = a.engine = "analytic";
    a.result = analytic_run(system, times);
    runs.insert(runs.begin(), std::move(a));
  }
  SceneComparison c = compare_runs(system, std::move(runs));
  c.settings = settings;

  // A comparison that failed with every engine's run complete: measure whether the differences are
  // integration error (they fall with the tolerances) or physics (they stay), instead of only
  // saying how to.
  if (options.diagnose && diagnosable(c) && settings.method.value() != Integrator::Rk4) {
    CompareOptions tight = options;
    tight.diagnose = false;
    tight.rtol = settings.rtol / 100;
    tight.atol = settings.atol / 100;
    tight.integrator = settings.method;
    diagnose(c, compare_scene(system, tight), *tight.rtol, *tight.atol);
  }
  return c;
}

std::string sci(double v, int digits) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  if (v == 0) return "0";
  char b[64];
  std::snprintf(b, sizeof b, "%.*e", std::max(0, digits - 1), v);
  return b;
}

std::string text_table(const std::vector<std::vector<std::string>>& rows) {
  std::vector<std::size_t> width;
  for (const auto& r : rows)
    for (std::size_t i = 0; i < r.size(); ++i) {
      if (width.size() <= i) width.push_back(0);
      width[i] = std::max(width[i], r[i].size());
    }
  std::ostringstream out;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    std::string line;
    for (std::size_t i = 0; i < rows[k].size(); ++i) {
      line += rows[k][i];
      if (i + 1 < rows[k].size()) line += std::string(width[i] - rows[k][i].size() + 2, ' ');
    }
    out << line << '\n';
    if (k == 0) {
      std::size_t total = 0;
      for (std::size_t i = 0; i < width.size(); ++i) total += width[i] + (i + 1 < width.size() ? 2 : 0);
      out << std::string(total, '-') << '\n';
    }
  }
  return out.str();
}

namespace {

// ---- compare's text output (format_comparison): at most kTextWidth characters a line ----
constexpr std::size_t kTextWidth = 100;

// `text` wrapped at kTextWidth, every line starting with `indent` (the first with `first`).
std::string wrap(const std::string& text, const std::string& first, const std::string& indent) {
  std::string out, line = first;
  std::size_t pos = 0;
  bool line_empty = true;
  while (pos < text.size()) {
    while (pos < text.size() && text[pos] == ' ') ++pos;
    std::size_t end = text.find(' ', pos);
    if (end == std::string::npos) end = text.size();
    std::string word = text.substr(pos, end - pos);
    pos = end;
    if (word.empty()) continue;
    if (!line_empty && line.size() + 1 + word.size() > kTextWidth) {
      out += line + "\n";
      line = indent;
      line_empty = true;
    }
    while (line.size() + (line_empty ? 0 : 1) + word.size() > kTextWidth) {  // a very long word
      const std::size_t room = kTextWidth - line.size() - (line_empty ? 0 : 1);
      line += (line_empty ? "" : " ") + word.substr(0, room);
      word = word.substr(room);
      out += line + "\n";
      line = indent;
      line_empty = true;
    }
    line += (line_empty ? "" : " ") + word;
    line_empty = false;
  }
  if (!line_empty) out += line + "\n";
  return out;
}

// A table that fits kTextWidth: columns in `shrinkable` give up width (widest first, down to 8
// characters), their cut cells ending in '~'. Row 0 is the header, underlined.
std::string fitted_table(std::vector<std::vector<std::string>> rows,
                         const std::vector<std::size_t>& shrinkable) {
  std::vector<std::size_t> width;
  for (const auto& r : rows)
    for (std::size_t i = 0; i < r.size(); ++i) {
      if (width.size() <= i) width.push_back(0);
      width[i] = std::max(width[i], r[i].size());
    }
  auto total = [&width] {
    std::size_t t = 0;
    for (std::size_t w : width) t += w;
    return t + 2 * (width.empty() ? 0 : width.size() - 1);
  };
  while (total() > kTextWidth) {
    std::size_t widest = width.size();
    for (std::size_t i : shrinkable)
      if (i < width.size() && width[i] > 8 && (widest == width.size() || width[i] > width[widest]))
        widest = i;
    if (widest == width.size()) break;
    --width[widest];
  }
  for (auto& r : rows)
    for (std::size_t i = 0; i < r.size(); ++i)
      if (r[i].size() > width[i]) r[i] = r[i].substr(0, width[i] - 1) + "~";
  std::string out;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    std::string line;
    for (std::size_t i = 0; i < rows[k].size(); ++i) {
      line += rows[k][i];
      if (i + 1 < rows[k].size()) line += std::string(width[i] - rows[k][i].size() + 2, ' ');
    }
    out += line + "\n";
    if (k == 0) out += std::string(std::min(total(), kTextWidth), '-') + "\n";
  }
  return out;
}

std::string who(const Check& k) { return k.b.empty() ? k.a : k.a + " vs " + k.b; }

}  // namespace

// Layout (every line at most 100 characters): the verdict, the settings, the runs, the pass rule,
// then one table of checks with the failures first (worst error/bound first), then the passes in
// table order, then what was excluded or skipped and why, the tolerances used, and the notes.
std::string format_comparison(const SceneComparison& c, bool failures_only) {
  std::string out;
  const int failed = c.count(CheckStatus::Fail);
  out += wrap("scene " + c.scene + (c.file.empty() ? "" : " (" + c.file + ")") + ": " +
                  (failed ? "FAIL, " + std::to_string(failed) + " of " +
                                std::to_string(c.checks.size()) + " checks failed"
                          : "PASS, " + std::to_string(c.count(CheckStatus::Pass)) +
                                " checks passed"),
              "", "  ");
  out += wrap("integrator " + c.settings.method.str() + ", rtol " + fmt_g(c.settings.rtol, 6) + ", atol " +
                  fmt_g(c.settings.atol, 6) + "; output every " + fmt_g(c.settings.output_step, 6) +
                  " s to " + fmt_g(c.settings.duration, 6) + " s",
              "", "  ");
  out += "\n";

  std::vector<std::vector<std::string>> runs{{"run", "status", "rows", "rhs calls", "steps", "wall (s)"}};
  std::string run_notes;
  for (const EngineRun& r : c.runs) {
    const char* st = r.state == EngineRun::State::Ok ? "ok"
                     : r.state == EngineRun::State::Failed ? "FAILED" : "skipped";
    const bool ran = r.state != EngineRun::State::NotBuilt && r.engine != "analytic";
    runs.push_back({r.label, st, std::to_string(r.result.rows()),
                    ran ? std::to_string(r.result.stats.rhs_calls) : "-",
                    ran ? std::to_string(r.result.stats.steps) : "-",
                    ran ? fmt_g(r.result.stats.wall_seconds, 3) : "-"});
    const std::string note = r.engine == "analytic" ? "closed-form torque-free solution" : r.note;
    if (!note.empty()) run_notes += wrap(note, "  " + r.label + ": ", "    ");
  }
  out += fitted_table(runs, {0}) + run_notes + "\n";

  out += "pass rule: pair   max_t |a - b| <= bound = atol + rtol * max_t |b|  (b: the reference,\n"
         "                  named second); attitude error = rotation angle between the attitudes\n"
         "                  (rad), with max|b| = 1\n"
         "           drift  max_t |X(t) - X(0)| <= atol + rtol * |X(0)|\n"
         "         balance  max_t |X(t) - X(0) - integral of P (E) or M (H)| <= atol + rtol * scale + Q\n"
         "                  (scale: max(max_t |X|, integral of |rate|); Q: the quadrature's estimated error)\n\n";

  // Checks: failures (worst first), then passes in table order; exclusions and skips listed apart.
  std::vector<const Check*> fails, passes, others;
  for (const Check& k : c.checks)
    (k.status == CheckStatus::Fail ? fails : k.status == CheckStatus::Pass ? passes : others)
        .push_back(&k);
  std::stable_sort(fails.begin(), fails.end(), [](const Check* x, const Check* y) {
    const double a = std::isnan(x->normalised) ? std::numeric_limits<double>::infinity() : x->normalised;
    const double b = std::isnan(y->normalised) ? std::numeric_limits<double>::infinity() : y->normalised;
    return a > b;
  });
  std::vector<std::vector<std::string>> rows{
      {"quantity", "a vs b", "max error", "at t (s)", "1st over", "err/bound", "result"}};
  auto add = [&rows](const Check& k) {
    const bool run = k.group == "run";
    rows.push_back({k.quantity, who(k), run ? "-" : sci(k.error),
                    !run || k.status == CheckStatus::Fail ? fmt_g(k.time, 6) : "-",
                    k.first_exceeded ? fmt_g(*k.first_exceeded, 6) : "-", run ? "-" : sci(k.normalised),
                    to_string(k.status)});
  };
  for (const Check* k : fails) add(*k);
  if (!failures_only)
    for (const Check* k : passes) add(*k);
  if (rows.size() > 1) out += fitted_table(rows, {0, 1});
  else out += "(no failed checks)\n";

  // What the failures say beyond their numbers (a missing column, a failed run, nothing compared).
  std::string fail_notes;
  for (const Check* k : fails)
    if (!k->note.empty()) fail_notes += wrap(k->note, "  " + k->quantity + ", " + who(*k) + ": ", "    ");
  if (!fail_notes.empty()) out += "\nfailed checks, why:\n" + fail_notes;

  // Excluded and skipped, one line per quantity and reason.
  if (!failures_only && !others.empty()) {
    std::vector<std::pair<std::string, std::vector<std::string>>> groups;  // "EXCLUDED E: reason"
    for (const Check* k : others) {
      const std::string key = std::string(to_string(k->status)) + " " + k->quantity + ": " + k->note;
      auto it = std::find_if(groups.begin(), groups.end(), [&key](const auto& g) { return g.first == key; });
      if (it == groups.end()) it = groups.insert(groups.end(), {key, {}});
      it->second.push_back(who(*k));
    }
    out += "\nexcluded or skipped:\n";
    for (const auto& [key, pairs] : groups) {
      const auto colon = key.find(": ");
      std::string line = key.substr(0, colon) + " (" + std::to_string(pairs.size()) +
                         (pairs.size() == 1 ? " check" : " checks") + ")" + key.substr(colon);
      out += wrap(line, "  ", "    ");
    }
  }

  // The tolerances used: per tolerance key, which quantities and the numbers.
  if (!failures_only) {
    std::vector<std::pair<std::string, std::set<std::string>>> keys;
    std::map<std::string, Tolerance> tol;
    for (const Check& k : c.checks) {
      if (k.tolerance_key == "-" || k.status == CheckStatus::Excluded) continue;
      const bool drift = k.group.ends_with(".drift"), balance = k.group.ends_with(".balance");
      const std::string key = (drift || balance) && k.tolerance_key == "default"
                                  ? (drift ? "drift default" : "balance default")
                                  : k.tolerance_key;
      auto it = std::find_if(keys.begin(), keys.end(), [&key](const auto& x) { return x.first == key; });
      if (it == keys.end()) it = keys.insert(keys.end(), {key, {}});
      it->second.insert(k.quantity);
      tol[key] = k.tolerance;
    }
    if (!keys.empty()) {
      out += "\ntolerances (atol, rtol) and the quantities they apply to:\n";
      for (const auto& [key, quantities] : keys) {
        std::string list;
        std::size_t n = 0;
        for (const std::string& q : quantities) {
          if (++n > 8) {
            list += ", ... (" + std::to_string(quantities.size()) + " quantities)";
            break;
          }
          list += (list.empty() ? "" : ", ") + q;
        }
        const std::string name =
            key == "default" || key == "drift default" || key == "balance default" ? key : "'" + key + "'";
        out += wrap(name + ": " + sci(tol[key].atol, 2) + ", " + sci(tol[key].rtol, 2) + " for " + list,
                    "  ", "    ");
      }
    }
  }
  if (!c.notes.empty()) {
    out += "\nnotes:\n";
    for (const std::string& n : c.notes) out += wrap(n, "  - ", "    ");
  }
  return out;
}

}  // namespace crossdyn::harness
