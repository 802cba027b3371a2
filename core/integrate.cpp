// Integrator plumbing with Boost.Odeint (see integrate.hpp for the contract).
//
// Steppers, used as Odeint's examples use them (docs/style.md item 11): a system object that
// holds the engine, the stepper chosen explicitly, and right-hand-side calls counted here.
//   rk4             runge_kutta4                                       (Hairer et al. I, Table 1.2)
//   dopri5          dense_output of controlled runge_kutta_dopri5      (Dormand & Prince 1980)
//   rkf78           controlled runge_kutta_fehlberg78                  (Fehlberg 1968, NASA TR R-287)
//   bulirsch-stoer  bulirsch_stoer                                      (Hairer et al. I, Sec. II.9)
#include "core/integrate.hpp"

#include "core/cancel.hpp"
#include "core/errors.hpp"

#include <boost/numeric/odeint.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

// Integrator plumbing with Boost.Odeint (see integrate.hpp for the contract; the SUNDIALS CVODE
// methods are in integrate_cvode.cpp, the Runner they share in integrate_runner.hpp).
//
// Steppers, used as Odeint's examples use them (docs/style.md item 11): a system object that
// holds the engine, the stepper chosen explicitly, and right-hand-side calls counted here.
//   rk4             runge_kutta4                                       (Hairer et al. I, Table 1.2)
//   dopri5          dense_output of controlled runge_kutta_dopri5      (Dormand & Prince 1980;
//                   continuous extension: Hairer et al. I, Sec. II.6)
//   dop853          Dormand-Prince 8(5,3) with its order-7 continuous  (Hairer et al. I, Sec. II.10;
//                   extension: core/dop853.cpp (Odeint has none)        dop853.f)
//   rkf78           controlled runge_kutta_fehlberg78                  (Fehlberg 1968, NASA TR R-287)
//   bulirsch-stoer  bulirsch_stoer_dense_out, interpolation error      (Hairer et al. I, Sec. II.9,
//                   controlled                                          "Dense output for the GBS method")
#include "core/integrate.hpp"

#include "core/cancel.hpp"
#include "core/dop853.hpp"
#include "core/errors.hpp"
#include "core/integrate_runner.hpp"

#include <boost/numeric/odeint.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <type_traits>

namespace crossdyn {

namespace odeint = boost::numeric::odeint;

namespace integrate_detail {

std::string fmt(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

void OdeSystem::eval(const double* x, double* dxdt, std::size_t n, double t_stage) const {
  ++stats->rhs_calls;
  const double t = t_stage >= interval_end
                       ? std::nextafter(interval_end, -std::numeric_limits<double>::infinity())
                       : t_stage;
  engine->rhs(t, x, dxdt);
  // One branch-free pass finds a bad value (a NaN fails every comparison), then the first is named.
  bool bad = false;
  for (std::size_t i = 0; i < n; ++i) bad |= !(std::abs(dxdt[i]) <= kDiverged);
  if (!bad) return;
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isfinite(dxdt[i]) || std::abs(dxdt[i]) > kDiverged) {
      std::string quantity = "d/dt " + engine->state_label(static_cast<int>(i));
      std::string reason = std::isfinite(dxdt[i]) ? "derivative diverged (" + fmt(dxdt[i]) + ")"
                                                  : "non-finite derivative";
      const bool at_start = t_stage == start_t && start_x != nullptr &&
                            start_x->size() == n && std::equal(x, x + n, start_x->begin());
      if (trial_steps && !at_start) throw TrialRejected{std::move(quantity), std::move(reason)};
      throw RunFailure(engine->name(), t, quantity, reason);
    }
}

namespace {

void check_state(const Engine& engine, double t, const State& x) {
  for (std::size_t i = 0; i < x.size(); ++i)
    if (!std::isfinite(x[i]) || std::abs(x[i]) > kDiverged)
      throw RunFailure(engine.name(), t, engine.state_label(static_cast<int>(i)),
                       std::isfinite(x[i]) ? "state diverged (" + fmt(x[i]) + ")"
                                           : "non-finite state");
}

// Output times k * output_step, k = 0..n, plus the duration when it is not a multiple.
std::vector<double> output_times(double duration, double step) {
  std::vector<double> t;
  const auto n = static_cast<long>(std::floor(duration / step * (1 + 1e-12)));
  for (long k = 0; k <= n; ++k) t.push_back(static_cast<double>(k) * step);
  if (duration - t.back() > 1e-9 * step) t.push_back(duration);
  return t;
}

}  // namespace

Runner::Runner(Engine& engine, const System& system, const IntegratorSettings& s, RunResult& result,
               const RowCallback& on_row, const StepCallback& on_step, RowStore* rows)
    : engine_(engine), s_(s), result_(result), on_row_(on_row), on_step_(on_step), rows_(rows),
      sys_{&engine, &result.stats}, outputs_(output_times(s.duration, s.output_step)),
      breaks_(system.breakpoints()), row_(engine.columns().size()),
      engine_width_(engine.columns().size()) {
  if (s.rate_columns) {
    row_.resize(engine_width_ + rate_column_names().size());
    xdot_.resize(static_cast<std::size_t>(engine.state_size()));
    xs_.resize(xdot_.size());
    side_.resize(engine_width_);
  }
  sys_.trial_steps = s.method != Integrator::Rk4;
  sys_.start_x = &start_x_;
}

void Runner::run(State& x) {
  check_state(engine_, 0.0, x);
  emit(0.0, x.data());
  if (on_step_) on_step_(0.0, result_.stats);
  if (x.empty()) {
    // Every motion prescribed (no state: a rigid scene whose joints are all prescribed, or a
    // converge model that keeps no modes of such a scene): nothing to integrate, whatever the
    // method; the rows are the prescribed motion at the output times. (dop853's error norm and
    // CVODE's matrices need at least one state.)
    for (std::size_t k = 1; k < outputs_.size(); ++k) {
      guard(outputs_[k - 1], x);
      emit(outputs_[k], x.data());
    }
    return;
  }
  switch (s_.method.value()) {
    case Integrator::Rk4: fixed_rk4(x); break;
    case Integrator::Dopri5: {
      auto stepper = odeint::make_dense_output(s_.atol, s_.rtol, odeint::runge_kutta_dopri5<State>());
      dense(stepper, x, 6, 5);  // a rejected trial step of dopri5 costs 6 new stages (FSAL)
      break;
    }
    case Integrator::Dop853: {
      // Its rejected trial steps are inside do_step(): each is counted here and passes the checks
      // every trial step passes (cancellation, the step limit, step-size underflow).
      Dop853 stepper(s_.atol, s_.rtol);
      stepper.set_reject_hook([this](double t, double next_dt) {
        blow_up_.reset();
        ++result_.stats.rejected;
        limits(t);
        underflow(t, next_dt);
      });
      dense(stepper, x, 0, 8);
      break;
    }
    case Integrator::Rkf78: {
      auto stepper = odeint::make_controlled(s_.atol, s_.rtol, odeint::runge_kutta_fehlberg78<State>());
      controlled(stepper, x);
      break;
    }
    case Integrator::BulirschStoer: {
      // Arguments: eps_abs, eps_rel, factor_x, factor_dxdt (Odeint's defaults, as make_controlled
      // uses), no largest step, and control_interpolation = true: the interpolation error enters
      // the step-size control, so that the values between steps keep the tolerance too.
      odeint::bulirsch_stoer_dense_out<State> stepper(s_.atol, s_.rtol, 1.0, 1.0, 0.0, true);
      dense(stepper, x, 0, 8);  // its rejected trial steps are internal: only blow-ups are counted
      break;
    }
    case Integrator::CvodeAdams:
    case Integrator::CvodeBdf: cvode(x); break;
  }
}

void Runner::emit(double t, const double* x) {
  hold(t, x);
  release();
}

void Runner::hold(double t, const double* x) {
  engine_.output_row(t, x, row_.data());
  for (std::size_t i = 0; i < engine_width_; ++i)
    if (!std::isfinite(row_[i]))
      throw RunFailure(engine_.name(), t, engine_.columns()[i], "non-finite output");
  if (s_.rate_columns) rates(t, x);
  held_.insert(held_.end(), row_.begin(), row_.end());
}

// IntegratorSettings::rate_columns: d/dt of E, Hx, Hy, Hz along (1, xdot) at (t, x) by the
// sixth-order central difference, and each one's error estimate (core/integrate.hpp). Not the hot
// path: 1 right-hand side and 6 output rows per output time.
void Runner::rates(double t, const double* x) {
  const std::size_t n = xdot_.size();
  const OutputLayout& layout = engine_.layout();
  const int cols[4] = {layout.E(), layout.H_vector(), layout.H_vector() + 1, layout.H_vector() + 2};
  double* out = row_.data() + engine_width_;
  try {
    engine_.rhs(t, x, xdot_.data());
    const double h = kRateStep * s_.output_step;
    // A load or a prescribed profile changes formula at a breakpoint: E and H are not smooth
    // across it (a prescribed joint's profile enters them through t). Within 4h of one, the
    // differences stay on one side of it: forward from a breakpoint at or just before t (the
    // state and the loads at t are already the new ones), backward from one just after.
    int side = 0;  // 0 central, +1 forward, -1 backward
    for (double b : breaks_)
      if (std::abs(b - t) < 4 * h) side = b <= t ? 1 : -1;
    const double central[6] = {-3, -2, -1, 1, 2, 3};
    const double one_sided[4] = {1, 2, 3, 4};
    const int m = side == 0 ? 6 : 4;
    double f[6][4];  // f[k][quantity] at t + steps[k] h
    for (int k = 0; k < m; ++k) {
      const double step = (side == 0 ? central[k] : side * one_sided[k]) * h;
      for (std::size_t i = 0; i < n; ++i) xs_[i] = x[i] + step * xdot_[i];
      engine_.output_row(t + step, xs_.data(), side_.data());
      for (int q = 0; q < 4; ++q) f[k][q] = side_[static_cast<std::size_t>(cols[q])];
    }
    for (int q = 0; q < 4; ++q) {
      const double f0 = row_[static_cast<std::size_t>(cols[q])];
      double D = 0, D_low = 0, weights = 0;
      if (side == 0) {
        // Central differences of orders 6 and 4 (Fornberg 1988, Table 1: 3/4, -3/20, 1/60 and
        // 2/3, -1/12 at +-h, +-2h, +-3h).
        const double d1 = f[3][q] - f[2][q], d2 = f[4][q] - f[1][q], d3 = f[5][q] - f[0][q];
        D = (45 * d1 - 9 * d2 + d3) / (60 * h);
        D_low = (8 * d1 - d2) / (12 * h);
        weights = 110.0 / 60;
      } else {
        // One-sided differences of orders 4 and 3 (Fornberg 1988, Table 3: -25/12, 4, -3, 4/3,
        // -1/4 and -11/6, 3, -3/2, 1/3), h signed by the side.
        const double hs = side * h;
        D = (-25 * f0 + 48 * f[0][q] - 36 * f[1][q] + 16 * f[2][q] - 3 * f[3][q]) / (12 * hs);
        D_low = (-11 * f0 + 18 * f[0][q] - 9 * f[1][q] + 2 * f[2][q]) / (6 * hs);
        weights = 128.0 / 12;
      }
      // D's error: at most |D - D_low| where truncation dominates; where rounding does, the
      // weights times kRateUlps ulps of the largest value, over h.
      double fmax = std::abs(f0);
      for (int k = 0; k < m; ++k) fmax = std::max(fmax, std::abs(f[k][q]));
      out[q] = D;
      out[4 + q] = std::abs(D - D_low) + kRateUlps * std::numeric_limits<double>::epsilon() * fmax * weights / h;
    }
  } catch (const RunFailure&) {
    for (int q = 0; q < 8; ++q) out[q] = std::numeric_limits<double>::quiet_NaN();
  }
}

void Runner::release() {
  const std::size_t n = row_.size();
  for (std::size_t r = 0; n > 0 && r < held_.size() / n; ++r) {
    const double* row = held_.data() + r * n;
    if (rows_) {
      try {
        rows_->append(row);
      } catch (const RowStorageError& e) {
        throw RunFailure(engine_.name(), row[0], "", e.what());
      }
    }
    if (on_row_) on_row_(row);
  }
  held_.clear();
}

void Runner::guard(double t, const State& x) {
  last_t_ = t;
  sys_.interval_end = next_break(t);
  sys_.start_t = t;
  start_x_ = x;
  limits(t);
}

void Runner::limits(double t) {
  cancel::poll();
  if (result_.stats.steps + result_.stats.rejected >= s_.max_steps)
    throw RunFailure(engine_.name(), t, "",
                     "step limit reached (" + std::to_string(s_.max_steps) + " steps)");
  if (s_.give_up_factor > 0) predict_cost(t);
}

void Runner::predict_cost(double t) {
  // At each tenth of the step limit from the second on: the last tenth's pace (steps per
  // simulated second) extrapolated to the duration, against give_up_factor x the steps left.
  const double used = static_cast<double>(result_.stats.steps + result_.stats.rejected);
  const double M = static_cast<double>(s_.max_steps);
  if (used < pace_.next) return;
  if (pace_.started) {
    const double spent = used - pace_.used, covered = t - pace_.t;
    const double need = covered > 0 ? spent / covered * (s_.duration - t)
                                    : std::numeric_limits<double>::infinity();
    const double left = M - used;
    if (need > s_.give_up_factor * left)
      throw RunFailure(engine_.name(), t, "",
                       "step limit: stopped early after " + fmt(used) + " of " + fmt(M) +
                           " steps (accepted and rejected): at its pace over the last " +
                           fmt(spent) + " steps it needs about " + fmt(need) +
                           " steps more to reach t = " + fmt(s_.duration) + " s, more than " +
                           fmt(s_.give_up_factor) + " x the " + fmt(left) + " steps left");
  }
  pace_.started = true;
  pace_.used = used;
  pace_.t = t;
  pace_.next = used + M / 10;
}

void Runner::underflow(double t, double dt) const {
  if (dt < s_.min_step) underflow_failure(t, dt, "below");
}

void Runner::underflow_failure(double t, double dt, const char* relation) const {
  const std::string what = "step-size underflow (step " + fmt(dt) + " s " + relation + " " +
                           fmt(s_.min_step) + " s)";
  if (blow_up_)
    throw RunFailure(engine_.name(), t, blow_up_->quantity,
                     blow_up_->reason + " in every trial step down to the minimum step; " + what);
  throw RunFailure(engine_.name(), t, "", what);
}

// The first trial step of an adaptive method: the user's (a scene's run.dt or --dt), else an
// estimate from the derivatives at the start, the algorithm of Hairer, Norsett and Wanner I,
// Sec. II.4 ("Starting Step Size") as their codes dopri5.f and dop853.f implement it (HINIT):
// with the weights sk_i = atol + rtol |x_i| and the norms ||v|| = sqrt(sum_i (v_i / sk_i)^2),
//   d0 = ||x||, d1 = ||f0||, h0 = 0.01 d0 / d1 (1e-6 s when d0 or d1 is below 1e-5);
//   one explicit Euler step: f1 = f(h0, x + h0 f0), d2 = ||f1 - f0|| / h0;
//   h1 = (0.01 / max(d1, d2))^(1/order) (max(1e-6, 1e-3 h0) when that maximum is below 1e-15);
//   h = min(100 h0, h1, h_max).
// It costs two right-hand sides (f0 is handed to the stepper when it can take it). Without it a
// fixed 1 ms first trial needs several steps to grow to the tolerance's step: kane + dop853 on
// spear1_case1 at 1e-10 took 405 right-hand sides from 1 ms, 381 from 0.05 s.
double Runner::first_step(const State& x, double h_max, int order, State& f0) {
  if (s_.first_step > 0) return std::min(s_.first_step, h_max);
  guard(0.0, x);  // f0 is the derivative at the start: a bad one ends the run (RunFailure)
  const std::size_t n = x.size();
  f0.resize(n);
  sys_(x, f0, 0.0);
  double d0 = 0, d1 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double sk = s_.atol + s_.rtol * std::abs(x[i]);
    d0 += (x[i] / sk) * (x[i] / sk);
    d1 += (f0[i] / sk) * (f0[i] / sk);
  }
  double h0 = (d0 <= 1e-10 || d1 <= 1e-10) ? 1e-6 : 0.01 * std::sqrt(d0 / d1);
  h0 = std::min(h0, h_max);
  State x1(n), f1(n);
  for (std::size_t i = 0; i < n; ++i) x1[i] = x[i] + h0 * f0[i];
  try {
    sys_(x1, f1, h0);
  } catch (TrialRejected&) {  // the Euler step's derivative blew up: start below it
    return std::max(1e-3 * h0, std::min(s_.min_step * 10, h_max));
  }
  double d2 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double sk = s_.atol + s_.rtol * std::abs(x[i]);
    d2 += ((f1[i] - f0[i]) / sk) * ((f1[i] - f0[i]) / sk);
  }
  d2 = std::sqrt(d2) / h0;
  const double d12 = std::max(d2, std::sqrt(d1));
  const double h1 = d12 <= 1e-15 ? std::max(1e-6, 1e-3 * h0) : std::pow(0.01 / d12, 1.0 / order);
  return std::min({100 * h0, h1, h_max});
}

double Runner::next_stop(double t, double target) const { return std::min(next_break(t), target); }

double Runner::next_break(double t) const {
  for (double b : breaks_)
    if (b > t + 1e-12 * std::max(1.0, std::abs(t))) return b;
  return std::numeric_limits<double>::infinity();
}

bool Runner::accepted(double t, State& x) {
  ++result_.stats.steps;
  check_state(engine_, t, x);
  bool changed = false;
  if (engine_.after_step(t, x.data())) {
    ++result_.stats.restarts;
    check_state(engine_, t, x);
    changed = true;
  }
  if (on_step_) on_step_(t, result_.stats);
  return changed;
}

void Runner::fixed_rk4(State& x) {
  odeint::runge_kutta4<State> stepper;
  double t = 0;
  for (std::size_t k = 1; k < outputs_.size(); ++k) {
    while (t < outputs_[k]) {
      guard(t, x);
      const double stop = next_stop(t, outputs_[k]);
      const bool last = stop - t <= s_.dt * (1 + 1e-9);
      const double h = last ? stop - t : s_.dt;
      stepper.do_step(sys_, x, t, h);
      t = last ? stop : t + h;
      accepted(t, x);
    }
    emit(outputs_[k], x.data());
  }
}

// rkf78 has no continuous extension in Odeint (nor an accepted one of its order in the
// literature that Odeint implements): its steps land on every output time, so it takes at least
// one step per output interval (docs/integrators.md).
template <class Stepper>
void Runner::controlled(Stepper& stepper, State& x) {
  State f0;
  double t = 0, dt = first_step(x, next_stop(0.0, outputs_.back()), 8, f0);
  for (std::size_t k = 1; k < outputs_.size(); ++k) {
    while (t < outputs_[k]) {
      guard(t, x);
      const double stop = next_stop(t, outputs_[k]);
      const bool clipped = dt >= stop - t;
      double h = clipped ? stop - t : dt;
      const double t_before = t, attempted = h;
      odeint::controlled_step_result result = odeint::fail;
      bool blew_up = false;
      try {
        result = stepper.try_step(sys_, x, t, h);  // x, t unchanged unless it succeeds
      } catch (TrialRejected& blow_up) {
        blow_up_ = std::move(blow_up);
        blew_up = true;
        h = attempted * kBlowUpShrink;
        t = t_before;
      }
      if (result == odeint::success) {
        blow_up_.reset();
        // A clipped step's suggestion reflects the short step; keep the longer accepted one.
        dt = clipped ? std::max(dt, h) : h;
        if (clipped) t = stop;  // land exactly, free of rounding
        accepted(t, x);
      } else {
        if (!blew_up) blow_up_.reset();
        ++result_.stats.rejected;
        dt = h;
        underflow(t_before, dt);
      }
    }
    emit(outputs_[k], x.data());
  }
}

// A dense-output stepper (dopri5, dop853, Bulirsch-Stoer) takes the steps its tolerance allows and
// interpolates the output times in between; only load breakpoints and the duration end a step.
// `stages_per_rejection`: right-hand sides a rejected trial step costs, to count the rejections
// hidden inside do_step() (0: not counted).
template <class Stepper>
void Runner::dense(Stepper& stepper, State& x, int stages_per_rejection, int order) {
  State f0;
  const double h = first_step(x, next_stop(0.0, outputs_.back()), order, f0);
  if constexpr (std::is_same_v<Stepper, Dop853>)
    stepper.initialize(x, 0.0, h, f0.empty() ? nullptr : &f0);
  else
    stepper.initialize(x, 0.0, h);
  std::size_t k = 1;
  State xo(x.size());
  const double end = outputs_.back();
  while (k < outputs_.size()) {
    const double t = stepper.current_time();
    guard(t, stepper.current_state());
    // Do not straddle a load breakpoint or the duration: restart with a step that ends on it.
    const double stop = s_.land_on_outputs ? std::min(next_stop(t, end), outputs_[k])
                                           : next_stop(t, end);
    if (t + stepper.current_time_step() > stop)
      stepper.initialize(State(stepper.current_state()), t, stop - t);
    const long rhs_before = result_.stats.rhs_calls;
    std::pair<double, double> step;
    try {
      step = stepper.do_step(sys_);  // the current state is unchanged unless it succeeds
    } catch (TrialRejected& blow_up) {
      blow_up_ = std::move(blow_up);
      ++result_.stats.rejected;
      const double h = stepper.current_time_step() * kBlowUpShrink;
      underflow(t, h);
      stepper.initialize(State(stepper.current_state()), t, h);
      continue;
    }
    double t1 = step.second;
    blow_up_.reset();
    if (stages_per_rejection > 0)
      result_.stats.rejected +=
          std::max(0L, (result_.stats.rhs_calls - rhs_before) / stages_per_rejection - 1);
    if (stepper.current_time_step() < s_.min_step)
      throw RunFailure(engine_.name(), t1, "",
                       "step-size underflow (step " + fmt(stepper.current_time_step()) + " s)");
    // A step meant to end on a breakpoint or the duration ends there, free of rounding.
    const bool landed = std::abs(t1 - stop) <= 1e-12 * std::max(1.0, std::abs(stop));
    // The rows inside the step are computed now, in the coordinates the step was taken in (an
    // engine may re-chart in after_step()), and written once after_step() has accepted the step:
    // a step it refuses (a singularity crossed inside it) leaves no row past its start.
    while (k < outputs_.size() && (outputs_[k] <= t1 || (landed && outputs_[k] <= stop))) {
      if (outputs_[k] >= t1) {
        hold(outputs_[k], stepper.current_state().data());
      } else {
        try {
          stepper.calc_state(outputs_[k], xo);  // dop853 evaluates its extension's stages here
        } catch (TrialRejected& bad) {
          throw RunFailure(engine_.name(), outputs_[k], bad.quantity,
                           bad.reason + " in a stage of the dense output");
        }
        hold(outputs_[k], xo.data());
      }
      ++k;
    }
    if (landed) t1 = stop;
    State xn = stepper.current_state();
    const bool changed = accepted(t1, xn);
    release();
    if (changed || landed) stepper.initialize(xn, t1, stepper.current_time_step());
  }
  x = stepper.current_state();
}

}  // namespace integrate_detail

IntegratorSettings IntegratorSettings::from(const RunSpec& run) {
  IntegratorSettings s;
  s.method = run.integrator;
  s.rtol = run.rtol;
  s.atol = run.atol;
  s.dt = run.dt;
  s.first_step = run.dt_given ? run.dt : 0.0;
  s.duration = run.duration;
  s.output_step = run.output_step;
  return s;
}

// integrator_names() is defined in core/run_limits.cpp, with the other limits on run settings.

int RunResult::column(const std::string& name) const {
  const auto it = std::find(columns.begin(), columns.end(), name);
  return it == columns.end() ? -1 : static_cast<int>(it - columns.begin());
}

std::size_t RunResult::rows() const {
  if (spill) return spill->rows();
  return columns.empty() ? 0 : data.size() / columns.size();
}

double RunResult::at(std::size_t row, std::size_t col) const {
  if (!spill) return data[row * columns.size() + col];
  std::vector<double> buffer(columns.size());
  spill->read(row, 1, buffer.data());
  return buffer[col];
}

void RunResult::for_each_row(const std::function<void(const double* row)>& f) const {
  RowReader r = reader();
  while (const double* row = r.next()) f(row);
}

void RunResult::store(RowStore::Rows rows) {
  data = std::move(rows.data);
  spill = std::move(rows.file);
  reservation = std::move(rows.reservation);
}

void request_interrupt() { cancel::request_interrupt(); }
bool interrupt_requested() { return cancel::interrupted(); }
void clear_interrupt() { cancel::detail::reset_interrupt_for_tests(); }

RunResult simulate(Engine& engine, const System& system, const TreeState& initial,
                   const IntegratorSettings& s, const RowCallback& on_row,
                   const StepCallback& on_step) {
  auto positive = [](double v, const char* what) {
    if (!(v > 0) || !std::isfinite(v))
      throw InputError(std::string(what) + " must be a positive number, got " + integrate_detail::fmt(v));
  };
  positive(s.duration, "duration");
  positive(s.output_step, "output step");
  positive(s.dt, "step dt");
  if (s.method != Integrator::Rk4) {
    positive(s.rtol, "rtol");
    positive(s.atol, "atol");
  }

  using integrate_detail::Runner;
  using integrate_detail::State;
  RunResult result;
  result.engine = engine.name();
  result.columns = engine.columns();
  if (s.rate_columns)
    result.columns.insert(result.columns.end(), rate_column_names().begin(), rate_column_names().end());
  State x(static_cast<std::size_t>(engine.state_size()));
  const auto start = std::chrono::steady_clock::now();
  std::optional<RowStore> rows;
  if (s.keep_rows) rows.emplace(result.columns.size());
  Runner runner(engine, system, s, result, on_row, on_step, rows ? &*rows : nullptr);
  try {
    engine.pack(initial, x.data());
    runner.run(x);
  } catch (const RunFailure& f) {
    result.failure = f;
  } catch (const cancel::Cancelled& c) {
    result.failure = RunFailure(engine.name(), runner.last_time(), "", c.what());
  } catch (const odeint::odeint_error& e) {  // step adjustment or no progress inside Odeint
    result.failure = RunFailure(engine.name(), runner.last_time(), "",
                                std::string("integrator gave up: ") + e.what());
  }
  if (rows) {
    try {
      result.store(rows->finish());
    } catch (const RowStorageError& e) {
      if (!result.failure) result.failure = RunFailure(engine.name(), runner.last_time(), "", e.what());
    }
  }
  result.stats.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace crossdyn
