// DOP853: the explicit Runge-Kutta method of order 8 of Dormand and Prince, with the error
// estimator "5 and 3" and a continuous extension of order 7 (dense output).
//   Hairer, Norsett and Wanner, Solving Ordinary Differential Equations I (2nd ed., Springer 1993),
//   Sec. II.10 (the method, its error estimator and step-size control, Table 10.x "DOP853") and
//   Sec. II.6 (continuous Runge-Kutta methods, dense output); the coefficients are those of the
//   authors' Fortran code dop853.f (version of 2004, unige.ch/~hairer), which the book describes.
//
// Part of the integrator plumbing (core/integrate.cpp drives it like the Odeint dense-output
// steppers: initialize, do_step, calc_state). Why it is here: Odeint has no method of order > 5
// with dense output, and rkf78 (order 8) must land on every output time; SUNDIALS' ARKode offers
// order-8 tables only with Hermite interpolation of degree <= 5. DOP853's own continuous extension
// keeps order 7 between steps, so an order-8 method can step over the output times.
//
// Costs: 12 right-hand sides per accepted step (the last is the next step's first, FSAL), 11 per
// rejected one, and 3 more in a step that holds an output time (the extension's stages, computed
// once on the first calc_state() of the step).
#pragma once

#include <cstddef>
#include <functional>
#include <utility>
#include <vector>

namespace crossdyn::integrate_detail {

class Dop853 {
 public:
  using State = std::vector<double>;
  // The right-hand side, called as f(x, dxdt, t) (the Odeint convention of OdeSystem).
  struct Rhs {
    const void* object = nullptr;
    void (*call)(const void* object, const State& x, State& dxdt, double t) = nullptr;
    void operator()(const State& x, State& dxdt, double t) const { call(object, x, dxdt, t); }
  };
  // Called after each rejected trial step with its start time and the next trial step (the
  // caller counts it, polls cancellation and checks the step limit and step-size underflow by
  // throwing).
  using RejectHook = std::function<void(double t, double next_dt)>;

  Dop853(double atol, double rtol) : atol_(atol), rtol_(rtol) {}
  void set_reject_hook(RejectHook hook) { on_reject_ = std::move(hook); }

  // Starts (or restarts) from (x, t) with first trial step dt. The first stage is f(t, x): given
  // as `f_x` when the caller has it (the starting-step estimate computes it), else recomputed.
  void initialize(const State& x, double t, double dt, const State* f_x = nullptr);

  // One accepted step (trial steps rejected by the error test are retried shorter, the hook told
  // of each). Returns (t_old, t_new). A stage that throws leaves the stepper at its last accepted
  // state. f must stay alive until the next do_step() (calc_state() evaluates it).
  template <class F>
  std::pair<double, double> do_step(const F& f) {
    return step(Rhs{&f, [](const void* o, const State& x, State& dxdt, double t) {
                      (*static_cast<const F*>(o))(x, dxdt, t);
                    }});
  }

  // The continuous extension of order 7 at t in [t_old, t_new] of the last step.
  void calc_state(double t, State& x);

  double current_time() const { return t_; }
  double current_time_step() const { return dt_; }
  const State& current_state() const { return x_; }

 private:
  std::pair<double, double> step(Rhs f);
  // x_out = x + h * sum_j a[j] k_[j] over the nonzero a[j], j < stages.
  void combine(const double* a, int stages, double h, const State& x, State& x_out) const;
  // out = base + sum_j c[j] k_[j] over the nonzero c[j], j < stages (base null: 0).
  void sum_stages(const double* c, int stages, const double* base, double* out) const;
  void prepare_dense();  // the extension's stages 14-16 and its 7 coefficient vectors

  double atol_, rtol_;
  RejectHook on_reject_;
  Rhs f_{};
  double t_ = 0, dt_ = 0;         // current time; next trial step
  double t_old_ = 0, h_old_ = 0;  // the last accepted step
  bool have_k1_ = false;          // k_[0] = f(t_, x_) is known
  bool fsal_pending_ = false;     // a step was taken: f(t_, x_) is in k_[12] (FSAL), the step's
                                  // stages are kept for its continuous extension
  bool dense_ready_ = false;      // the last step's extension is computed
  bool last_rejected_ = false;
  double facold_ = 1e-4;          // max(err, 1e-4) of the last accepted step (PI control)
  State x_, x_old_, x_trial_, x_stage_;
  State est5_, est3_;             // the error estimators' sums (step())
  std::vector<State> k_;          // 16 stages (12 of the step, k_[12] = f at the new point, 3 extra)
  std::vector<State> r_;          // the extension's 7 coefficient vectors
};

}  // namespace crossdyn::integrate_detail
