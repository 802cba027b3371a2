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

namespace crossdyn {

namespace odeint = boost::numeric::odeint;
using State = std::vector<double>;

namespace {

// Largest magnitude we accept in a state or derivative before calling the run diverged.
constexpr double kDiverged = 1e100;

std::string fmt(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

// A stage of an adaptive trial step produced a non-finite or diverged derivative: the trial is
// rejected (integrate.hpp), not the run.
struct TrialRejected {
  std::string quantity, reason;  // "d/dt main.wx", "non-finite derivative"
};

// The Odeint system: (x, t) => dxdt through the engine, counted and checked.
// Loads are right-continuous (value(t) switches at t = breakpoint), but a step that ends on a
// breakpoint must see the load of the interval it integrates: stage times at or past the end of the
// current load interval are evaluated just before it.
// A bad derivative ends the run when the method has no trial steps (rk4) or when it is the
// derivative at the accepted state itself (no shorter step can avoid it); otherwise it rejects
// the trial step.
struct OdeSystem {
  Engine* engine;
  RunStats* stats;
  bool trial_steps = false;      // adaptive method
  double start_t = 0;            // the accepted state the current step starts from
  const State* start_x = nullptr;
  double interval_end = std::numeric_limits<double>::infinity();
  void operator()(const State& x, State& dxdt, double t_stage) const {
    ++stats->rhs_calls;
    const double t = t_stage >= interval_end
                         ? std::nextafter(interval_end, -std::numeric_limits<double>::infinity())
                         : t_stage;
    engine->rhs(t, x.data(), dxdt.data());
    for (std::size_t i = 0; i < dxdt.size(); ++i)
      if (!std::isfinite(dxdt[i]) || std::abs(dxdt[i]) > kDiverged) {
        std::string quantity = "d/dt " + engine->state_label(static_cast<int>(i));
        std::string reason = std::isfinite(dxdt[i]) ? "derivative diverged (" + fmt(dxdt[i]) + ")"
                                                    : "non-finite derivative";
        const bool at_start = t_stage == start_t && start_x != nullptr && x == *start_x;
        if (trial_steps && !at_start) throw TrialRejected{std::move(quantity), std::move(reason)};
        throw RunFailure(engine->name(), t, quantity, reason);
      }
  }
};

// A trial step that blew up is retried this much shorter.
constexpr double kBlowUpShrink = 0.25;

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
         const RowCallback& on_row, const StepCallback& on_step, RowStore* rows)
      : engine_(engine), s_(s), result_(result), on_row_(on_row), on_step_(on_step), rows_(rows),
        sys_{&engine, &result.stats}, outputs_(output_times(s.duration, s.output_step)),
        breaks_(system.breakpoints()), row_(engine.columns().size()) {
    sys_.trial_steps = s.method != Integrator::Rk4;
    sys_.start_x = &start_x_;
  }

  void run(State& x) {
    check_state(engine_, 0.0, x);
    emit(0.0, x);
    if (on_step_) on_step_(0.0, result_.stats);
    switch (s_.method.value()) {
      case Integrator::Rk4: fixed_rk4(x); break;
      case Integrator::Dopri5: dense_dopri5(x); break;
      case Integrator::Rkf78: {
        auto stepper = odeint::make_controlled(s_.atol, s_.rtol, odeint::runge_kutta_fehlberg78<State>());
        controlled(stepper, x);
        break;
      }
      case Integrator::BulirschStoer: {
        odeint::bulirsch_stoer<State> stepper(s_.atol, s_.rtol);
        controlled(stepper, x);
        break;
      }
    }
  }

 private:
  void emit(double t, const State& x) {
    engine_.output_row(t, x.data(), row_.data());
    for (std::size_t i = 0; i < row_.size(); ++i)
      if (!std::isfinite(row_[i]))
        throw RunFailure(engine_.name(), t, engine_.columns()[i], "non-finite output");
    if (rows_) {
      try {
        rows_->append(row_.data());
      } catch (const RowStorageError& e) {
        throw RunFailure(engine_.name(), t, "", e.what());
      }
    }
    if (on_row_) on_row_(row_.data());
  }

  // Called before every step attempt from the accepted state (t, x): cancellation, step limit.
  void guard(double t, const State& x) {
    last_t_ = t;
    sys_.interval_end = next_break(t);
    sys_.start_t = t;
    start_x_ = x;
    cancel::poll();
    if (result_.stats.steps + result_.stats.rejected >= s_.max_steps)
      throw RunFailure(engine_.name(), t, "",
                       "step limit reached (" + std::to_string(s_.max_steps) + " steps)");
  }

  // An adaptive step below min_step ends the run. When the last rejection was a blow-up, the
  // failure names its quantity and reason: no step, however short, got past it.
  void underflow(double t, double dt) const {
    if (dt >= s_.min_step) return;
    const std::string what = "step-size underflow (step " + fmt(dt) + " s below " + fmt(s_.min_step) + " s)";
    if (blow_up_)
      throw RunFailure(engine_.name(), t, blow_up_->quantity,
                       blow_up_->reason + " in every trial step down to the minimum step; " + what);
    throw RunFailure(engine_.name(), t, "", what);
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
    bool changed = false;
    if (engine_.after_step(t, x.data())) {
      ++result_.stats.restarts;
      check_state(engine_, t, x);
      changed = true;
    }
    if (on_step_) on_step_(t, result_.stats);
    return changed;
  }

  void fixed_rk4(State& x) {
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
      emit(outputs_[k], x);
    }
  }

  template <class Stepper>
  void controlled(Stepper& stepper, State& x) {
    double t = 0, dt = s_.dt;
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
          if constexpr (requires { stepper.reset(); }) stepper.reset();  // Bulirsch-Stoer tables
        }
        if (result == odeint::success) {
          blow_up_.reset();
          // A clipped step's suggestion reflects the short step; keep the longer accepted one.
          dt = clipped ? std::max(dt, h) : h;
          if (clipped) t = stop;  // land exactly, free of rounding
          if (accepted(t, x)) {
            if constexpr (requires { stepper.reset(); }) stepper.reset();  // Bulirsch-Stoer state
          }
        } else {
          if (!blew_up) blow_up_.reset();
          ++result_.stats.rejected;
          dt = h;
          underflow(t_before, dt);
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
      guard(t, stepper.current_state());
      // Do not straddle a load breakpoint: restart with a step that ends on it.
      const double stop = next_break(t);
      if (stop < outputs_.back() && t + stepper.current_time_step() > stop)
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
      const double t1 = step.second;
      blow_up_.reset();
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
  State start_x_;
  std::optional<TrialRejected> blow_up_;  // the last rejection, when it was a blow-up

 public:
  double last_time() const { return last_t_; }

 private:
  Engine& engine_;
  const IntegratorSettings& s_;
  RunResult& result_;
  const RowCallback& on_row_;
  const StepCallback& on_step_;
  RowStore* rows_;
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
      throw InputError(std::string(what) + " must be a positive number, got " + fmt(v));
  };
  positive(s.duration, "duration");
  positive(s.output_step, "output step");
  positive(s.dt, "step dt");
  if (s.method != Integrator::Rk4) {
    positive(s.rtol, "rtol");
    positive(s.atol, "atol");
  }

  RunResult result;
  result.engine = engine.name();
  result.columns = engine.columns();
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
