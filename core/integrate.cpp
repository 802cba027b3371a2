// Integrator plumbing with Boost.Odeint (see integrate.hpp for the contract).
//
// Steppers, used as Odeint's examples use them (../shared/STYLE.md item 11): a system object that
// holds the engine, the stepper chosen explicitly, and right-hand-side calls counted here.
//   rk4             runge_kutta4                                       (Hairer et al. I, Table 1.2)
//   dopri5          dense_output of controlled runge_kutta_dopri5      (Dormand & Prince 1980)
//   rkf78           controlled runge_kutta_fehlberg78                  (Fehlberg 1968, NASA TR R-287)
//   bulirsch-stoer  bulirsch_stoer                                      (Hairer et al. I, Sec. II.9)
#include "core/integrate.hpp"

#include "core/errors.hpp"

#include <boost/numeric/odeint.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

namespace crossdyn {

namespace odeint = boost::numeric::odeint;
using State = std::vector<double>;

namespace {

std::atomic<bool> g_interrupt{false};

// Largest magnitude we accept in a state or derivative before calling the run diverged.
constexpr double kDiverged = 1e100;

std::string fmt(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

// The Odeint system: (x, t) => dxdt through the engine, counted and checked.
// Loads are right-continuous (value(t) switches at t = breakpoint), but a step that ends on a
// breakpoint must see the load of the interval it integrates: stage times at or past the end of the
// current load interval are evaluated just before it.
struct OdeSystem {
  Engine* engine;
  RunStats* stats;
  double interval_end = std::numeric_limits<double>::infinity();
  void operator()(const State& x, State& dxdt, double t_stage) const {
    ++stats->rhs_calls;
    const double t = t_stage >= interval_end
                         ? std::nextafter(interval_end, -std::numeric_limits<double>::infinity())
                         : t_stage;
    engine->rhs(t, x.data(), dxdt.data());
    for (std::size_t i = 0; i < dxdt.size(); ++i)
      if (!std::isfinite(dxdt[i]) || std::abs(dxdt[i]) > kDiverged)
        throw RunFailure(engine->name(), t, "d/dt " + engine->state_label(static_cast<int>(i)),
                         std::isfinite(dxdt[i]) ? "derivative diverged (" + fmt(dxdt[i]) + ")"
                                                : "non-finite derivative");
  }
};

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

class Runner {
 public:
  Runner(Engine& engine, const System& system, const IntegratorSettings& s, RunResult& result,
         const RowCallback& on_row)
      : engine_(engine), s_(s), result_(result), on_row_(on_row),
        sys_{&engine, &result.stats}, outputs_(output_times(s.duration, s.output_step)),
        breaks_(system.breakpoints()), row_(engine.columns().size()) {}

  void run(State& x) {
    check_state(engine_, 0.0, x);
    emit(0.0, x);
    if (s_.method == "rk4") fixed_rk4(x);
    else if (s_.method == "dopri5") dense_dopri5(x);
    else if (s_.method == "rkf78") {
      auto stepper = odeint::make_controlled(s_.atol, s_.rtol, odeint::runge_kutta_fehlberg78<State>());
      controlled(stepper, x);
    } else {
      odeint::bulirsch_stoer<State> stepper(s_.atol, s_.rtol);
      controlled(stepper, x);
    }
  }

 private:
  void emit(double t, const State& x) {
    engine_.output_row(t, x.data(), row_.data());
    for (std::size_t i = 0; i < row_.size(); ++i)
      if (!std::isfinite(row_[i]))
        throw RunFailure(engine_.name(), t, engine_.columns()[i], "non-finite output");
    if (s_.keep_rows) result_.data.insert(result_.data.end(), row_.begin(), row_.end());
    if (on_row_) on_row_(row_.data());
  }

  // Called before every step attempt: interrupt and step limit.
  void guard(double t) {
    last_t_ = t;
    sys_.interval_end = next_break(t);
    if (g_interrupt.load(std::memory_order_relaxed))
      throw RunFailure(engine_.name(), t, "", "interrupted");
    if (result_.stats.steps + result_.stats.rejected >= s_.max_steps)
      throw RunFailure(engine_.name(), t, "",
                       "step limit reached (" + std::to_string(s_.max_steps) + " steps)");
  }

  // The next time a step must land on: the target output time or an earlier load breakpoint.
  double next_stop(double t, double target) const { return std::min(next_break(t), target); }

  // The first load breakpoint after t (infinity if none). Within 1e-12 relative of t counts as
  // reached, so that rounding never asks for a vanishing step.
  double next_break(double t) const {
    for (double b : breaks_)
      if (b > t + 1e-12 * std::max(1.0, std::abs(t))) return b;
    return std::numeric_limits<double>::infinity();
  }

  // After an accepted step: state check, then the engine's projection or re-charting.
  bool accepted(double t, State& x) {
    ++result_.stats.steps;
    check_state(engine_, t, x);
    if (engine_.after_step(t, x.data())) {
      ++result_.stats.restarts;
      check_state(engine_, t, x);
      return true;
    }
    return false;
  }

  void fixed_rk4(State& x) {
    odeint::runge_kutta4<State> stepper;
    double t = 0;
    for (std::size_t k = 1; k < outputs_.size(); ++k) {
      while (t < outputs_[k]) {
        guard(t);
        const double stop = next_stop(t, outputs_[k]);
        const bool last = stop - t <= s_.dt * (1 + 1e-9);
        const double h = last ? stop - t : s_.dt;
        stepper.do_step(sys_, x, t, h);
        t = last ? stop : t + h;
        accepted(t, x);
      }
      emit(outputs_[k], x);
    }
  }

  template <class Stepper>
  void controlled(Stepper& stepper, State& x) {
    double t = 0, dt = s_.dt;
    for (std::size_t k = 1; k < outputs_.size(); ++k) {
      while (t < outputs_[k]) {
        guard(t);
        const double stop = next_stop(t, outputs_[k]);
        const bool clipped = dt >= stop - t;
        double h = clipped ? stop - t : dt;
        const double t_before = t;
        if (stepper.try_step(sys_, x, t, h) == odeint::success) {
          // A clipped step's suggestion reflects the short step; keep the longer accepted one.
          dt = clipped ? std::max(dt, h) : h;
          if (clipped) t = stop;  // land exactly, free of rounding
          if (accepted(t, x)) {
            if constexpr (requires { stepper.reset(); }) stepper.reset();  // Bulirsch-Stoer state
          }
        } else {
          ++result_.stats.rejected;
          dt = h;
          if (dt < s_.min_step)
            throw RunFailure(engine_.name(), t_before, "",
                             "step-size underflow (step " + fmt(dt) + " s below " +
                                 fmt(s_.min_step) + " s)");
        }
      }
      emit(outputs_[k], x);
    }
  }

  void dense_dopri5(State& x) {
    auto stepper = odeint::make_dense_output(s_.atol, s_.rtol, odeint::runge_kutta_dopri5<State>());
    stepper.initialize(x, 0.0, s_.dt);
    std::size_t k = 1;
    State xo(x.size());
    while (k < outputs_.size()) {
      const double t = stepper.current_time();
      guard(t);
      // Do not straddle a load breakpoint: restart with a step that ends on it.
      const double stop = next_break(t);
      if (stop < outputs_.back() && t + stepper.current_time_step() > stop)
        stepper.initialize(stepper.current_state(), t, stop - t);
      const long rhs_before = result_.stats.rhs_calls;
      const auto [t0, t1] = stepper.do_step(sys_);
      (void)t0;
      // Each rejected trial step of dopri5 costs 6 new stages (FSAL reuses the seventh).
      result_.stats.rejected += std::max(0L, (result_.stats.rhs_calls - rhs_before) / 6 - 1);
      if (stepper.current_time_step() < s_.min_step)
        throw RunFailure(engine_.name(), t1, "",
                         "step-size underflow (step " + fmt(stepper.current_time_step()) + " s)");
      while (k < outputs_.size() && outputs_[k] <= t1 * (1 + 1e-14)) {
        stepper.calc_state(outputs_[k], xo);
        emit(outputs_[k], xo);
        ++k;
      }
      State xn = stepper.current_state();
      if (accepted(t1, xn)) stepper.initialize(xn, t1, stepper.current_time_step());
    }
    x = stepper.current_state();
  }

  double last_t_ = 0;

 public:
  double last_time() const { return last_t_; }

 private:
  Engine& engine_;
  const IntegratorSettings& s_;
  RunResult& result_;
  const RowCallback& on_row_;
  OdeSystem sys_;
  std::vector<double> outputs_;
  std::vector<double> breaks_;
  std::vector<double> row_;
};

}  // namespace

IntegratorSettings IntegratorSettings::from(const RunSpec& run) {
  IntegratorSettings s;
  s.method = run.integrator;
  s.rtol = run.rtol;
  s.atol = run.atol;
  s.dt = run.dt;
  s.duration = run.duration;
  s.output_step = run.output_step;
  return s;
}

// integrator_names() is defined in core/run_limits.cpp, with the other limits on run settings.

int RunResult::column(const std::string& name) const {
  const auto it = std::find(columns.begin(), columns.end(), name);
  return it == columns.end() ? -1 : static_cast<int>(it - columns.begin());
}

void request_interrupt() { g_interrupt.store(true, std::memory_order_relaxed); }
bool interrupt_requested() { return g_interrupt.load(std::memory_order_relaxed); }
void clear_interrupt() { g_interrupt.store(false, std::memory_order_relaxed); }

RunResult simulate(Engine& engine, const System& system, const TreeState& initial,
                   const IntegratorSettings& s, const RowCallback& on_row) {
  const auto names = integrator_names();
  if (std::find(names.begin(), names.end(), s.method) == names.end())
    throw InputError("unknown integrator '" + s.method +
                     "' (known: rk4, dopri5, rkf78, bulirsch-stoer)");
  auto positive = [](double v, const char* what) {
    if (!(v > 0) || !std::isfinite(v))
      throw InputError(std::string(what) + " must be a positive number, got " + fmt(v));
  };
  positive(s.duration, "duration");
  positive(s.output_step, "output step");
  positive(s.dt, "step dt");
  if (s.method != "rk4") {
    positive(s.rtol, "rtol");
    positive(s.atol, "atol");
  }

  RunResult result;
  result.engine = engine.name();
  result.columns = engine.columns();
  State x(static_cast<std::size_t>(engine.state_size()));
  const auto start = std::chrono::steady_clock::now();
  Runner runner(engine, system, s, result, on_row);
  try {
    engine.pack(initial, x.data());
    runner.run(x);
  } catch (const RunFailure& f) {
    result.failure = f;
  } catch (const odeint::odeint_error& e) {  // step adjustment or no progress inside Odeint
    result.failure = RunFailure(engine.name(), runner.last_time(), "",
                                std::string("integrator gave up: ") + e.what());
  }
  result.stats.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace crossdyn
