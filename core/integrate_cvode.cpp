// The SUNDIALS CVODE methods (see integrate.hpp for the contract, integrate_runner.hpp for the
// Runner they share with the Odeint methods):
//   cvode-adams  variable-order (1-12) variable-step Adams-Moulton, fixed-point (functional)
//                corrector iteration: nonstiff problems
//   cvode-bdf    variable-order (1-5) variable-step BDF, Newton iteration with a dense linear
//                solver and CVODE's difference-quotient Jacobian: stiff problems
// Both are described in Hindmarsh et al., "SUNDIALS: Suite of nonlinear and differential/algebraic
// equation solvers" (ACM TOMS 31(3), 2005), Sec. 3, and the CVODE User Documentation (v6.4.1),
// Ch. 2 (the methods; the local error test in the weighted RMS norm with weights
// 1 / (rtol |y_i| + atol); dense output: CVodeGetDky interpolates the Nordsieck history of the
// last step) and Ch. 4 (CVodeSetStopTime, CVodeGetDky, recoverable right-hand-side errors).
//
// How the run is driven: CVode in CV_ONE_STEP mode, one internal step a call, so that every
// accepted step passes through Runner::guard() (cancellation, step limit) and Runner::accepted()
// (the after_step() hook). Output times inside the last step come from CVodeGetDky; the next load
// breakpoint (or the duration) is CVODE's stop time (CVodeSetStopTime), so no step straddles it,
// and the history is restarted there (CVodeReInit: a multistep history must not span a jump in
// the right-hand side). When after_step() changes the state by more than the error CVODE accepts
// in one step the history is restarted likewise; a smaller change is not applied (see below:
// each restart sets the method back to order 1). An engine that projects onto constraints
// (Engine::projects(): newton-euler) is projected inside BDF's steps instead (cvode_project), so
// its after_step() finds nothing to change.
//
// Right-hand-side failures: a non-finite or diverged derivative in a trial evaluation returns
// CVODE's "recoverable" status (> 0), on which CVODE retries with a step 4 times shorter
// (User Documentation Ch. 4, the CVRhsFn return values); any other exception (the engine's
// RunFailure, a bad derivative at the accepted state, cancellation) is kept, CVODE is stopped
// with an unrecoverable status (< 0), and the exception is rethrown here: no C++ exception
// crosses the C library.
#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/integrate_runner.hpp"

#include <cvode/cvode.h>
#include <cvode/cvode_proj.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>
#include <sunnonlinsol/sunnonlinsol_fixedpoint.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <string>
#include <vector>

namespace crossdyn::integrate_detail {

namespace {

// CVODE gives up a step after this many error-test or convergence failures in a row (defaults 7
// and 10). Set high so that a step shrinks down to the minimum step first, which is how the Odeint
// methods fail too (a step-size underflow).
constexpr int kMaxFailuresPerStep = 200;

// The SUNDIALS objects of one run, freed in the order of CVODE's examples.
struct CvodeObjects {
  SUNContext context = nullptr;
  void* mem = nullptr;
  N_Vector y = nullptr;
  N_Vector y_out = nullptr;
  SUNMatrix jacobian = nullptr;
  SUNLinearSolver linear = nullptr;
  SUNNonlinearSolver nonlinear = nullptr;
  CvodeObjects() = default;
  CvodeObjects(const CvodeObjects&) = delete;
  CvodeObjects& operator=(const CvodeObjects&) = delete;
  ~CvodeObjects() {
    if (mem) CVodeFree(&mem);
    if (linear) SUNLinSolFree(linear);
    if (jacobian) SUNMatDestroy(jacobian);
    if (nonlinear) SUNNonlinSolFree(nonlinear);
    if (y_out) N_VDestroy(y_out);
    if (y) N_VDestroy(y);
    if (context) SUNContext_Free(&context);
  }
};

// What the C callbacks need, and what they leave for the driver.
struct Callbacks {
  const OdeSystem* system = nullptr;
  std::exception_ptr error;                // to rethrow after CVode returns
  std::optional<TrialRejected> blow_up;    // the last recoverable failure
  std::string message;                     // CVODE's last error or warning text
  Engine* engine = nullptr;                // the projection's (cvode_project)
  std::vector<double> projected;           // its scratch state
};

int cvode_rhs(sunrealtype t, N_Vector y, N_Vector ydot, void* user) {
  auto& cb = *static_cast<Callbacks*>(user);
  try {
    cb.system->eval(N_VGetArrayPointer(y), N_VGetArrayPointer(ydot),
                    static_cast<std::size_t>(N_VGetLength(y)), t);
    return 0;
  } catch (TrialRejected& r) {
    cb.blow_up = std::move(r);
    return 1;  // recoverable: CVODE retries with a shorter step
  } catch (...) {
    cb.error = std::current_exception();
    return -1;  // unrecoverable: CVode returns, the exception is rethrown
  }
}

// CVODE's projection (CVODE User Documentation v6.4.1, Sec. 2.8, "Projection methods", and
// CVodeSetProjFn): after the corrector has converged and before the error test, CVODE asks for the
// correction that takes the step's solution onto the constraint manifold, and applies it to the
// solution and its history alike, so a projecting engine (newton-euler) costs no restart. The
// error estimate is not projected (CVodeSetProjErrEst off): it is tested as computed.
int cvode_project(sunrealtype t, N_Vector ycur, N_Vector corr, sunrealtype /*eps_proj*/,
                  N_Vector /*err*/, void* user) {
  auto& cb = *static_cast<Callbacks*>(user);
  try {
    const double* y = N_VGetArrayPointer(ycur);
    const auto n = static_cast<std::size_t>(N_VGetLength(ycur));
    cb.projected.assign(y, y + n);
    cb.engine->project_state(t, cb.projected.data());
    double* c = N_VGetArrayPointer(corr);
    for (std::size_t i = 0; i < n; ++i) c[i] = cb.projected[i] - y[i];
    return 0;
  } catch (...) {
    cb.error = std::current_exception();
    return -1;  // unrecoverable: CVode returns, the exception is rethrown
  }
}

void cvode_message(int /*code*/, const char* module, const char* function, char* msg, void* user) {
  auto& cb = *static_cast<Callbacks*>(user);
  cb.message = std::string(module ? module : "CVODE") + "/" + (function ? function : "") + ": " +
               (msg ? msg : "");
}

}  // namespace

// CVODE's norm of a change from y to x: sqrt(mean(((x_i - y_i) / (rtol |y_i| + atol))^2)).
double Runner::weighted_rms_change(const double* y, const State& x) const {
  double sum = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double e = (x[i] - y[i]) / (s_.rtol * std::abs(y[i]) + s_.atol);
    sum += e * e;
  }
  return x.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(x.size()));
}

void Runner::cvode(State& x) {
  const bool bdf = s_.method == Integrator::CvodeBdf;
  const auto n = static_cast<sunindextype>(x.size());
  CvodeObjects cv;
  Callbacks cb;
  cb.system = &sys_;
  // A failing SUNDIALS set-up call is a bug here or an allocation failure: say which.
  auto ok = [&](int flag, const char* call) {
    if (flag < 0)
      throw RunFailure(engine_.name(), last_t_, "",
                       std::string("CVODE set-up failed in ") + call + " (" + std::to_string(flag) +
                           (cb.message.empty() ? "" : ": " + cb.message) + ")");
  };
  auto made = [&](const void* p, const char* call) {
    if (p == nullptr) ok(-1, call);
  };
  ok(SUNContext_Create(nullptr, &cv.context), "SUNContext_Create");
  cv.y = N_VNew_Serial(n, cv.context);
  made(cv.y, "N_VNew_Serial");
  cv.y_out = N_VNew_Serial(n, cv.context);
  made(cv.y_out, "N_VNew_Serial");
  std::copy(x.begin(), x.end(), N_VGetArrayPointer(cv.y));
  cv.mem = CVodeCreate(bdf ? CV_BDF : CV_ADAMS, cv.context);
  made(cv.mem, "CVodeCreate");
  ok(CVodeSetErrHandlerFn(cv.mem, cvode_message, &cb), "CVodeSetErrHandlerFn");
  ok(CVodeInit(cv.mem, cvode_rhs, 0.0, cv.y), "CVodeInit");
  ok(CVodeSetUserData(cv.mem, &cb), "CVodeSetUserData");
  ok(CVodeSStolerances(cv.mem, s_.rtol, s_.atol), "CVodeSStolerances");
  // The user's first trial step (a scene's run.dt or --dt), else 0: CVODE's own estimate.
  ok(CVodeSetInitStep(cv.mem, std::min(s_.first_step, s_.duration)), "CVodeSetInitStep");
  ok(CVodeSetMinStep(cv.mem, s_.min_step), "CVodeSetMinStep");
  ok(CVodeSetMaxErrTestFails(cv.mem, kMaxFailuresPerStep), "CVodeSetMaxErrTestFails");
  ok(CVodeSetMaxConvFails(cv.mem, kMaxFailuresPerStep), "CVodeSetMaxConvFails");
  ok(CVodeSetMaxHnilWarns(cv.mem, -1), "CVodeSetMaxHnilWarns");  // no "t + h = t" warnings
  if (bdf) {
    cv.jacobian = SUNDenseMatrix(n, n, cv.context);
    made(cv.jacobian, "SUNDenseMatrix");
    cv.linear = SUNLinSol_Dense(cv.y, cv.jacobian, cv.context);
    made(cv.linear, "SUNLinSol_Dense");
    ok(CVodeSetLinearSolver(cv.mem, cv.linear, cv.jacobian), "CVodeSetLinearSolver");
    // No Jacobian function: CVODE's difference-quotient Jacobian (n right-hand sides each).
    // An engine that projects onto its constraints (newton-euler) does it inside the step
    // (cvode_project): done after the step instead, its change exceeded CVODE's error test at
    // every step at tight tolerances, and each restart to order 1 made newton-euler + cvode-bdf
    // crawl (chain5, 2 s, rtol 1e-9: 29,364 steps, 29,345 restarts, 3.9 s; issue 24).
    if (engine_.projects()) {
      cb.engine = &engine_;
      ok(CVodeSetProjFn(cv.mem, cvode_project), "CVodeSetProjFn");
      ok(CVodeSetProjErrEst(cv.mem, SUNFALSE), "CVodeSetProjErrEst");
    }
  } else {
    cv.nonlinear = SUNNonlinSol_FixedPoint(cv.y, 0, cv.context);
    made(cv.nonlinear, "SUNNonlinSol_FixedPoint");
    ok(CVodeSetNonlinearSolver(cv.mem, cv.nonlinear), "CVodeSetNonlinearSolver");
  }

  const double end = outputs_.back();
  double t = 0;
  double stop = next_stop(t, end);
  ok(CVodeSetStopTime(cv.mem, stop), "CVodeSetStopTime");
  long rejected_before = result_.stats.rejected;  // CVODE's counters restart with the history
  std::size_t k = 1;
  State xo(x.size());
  while (k < outputs_.size()) {
    guard(t, x);
    cb.blow_up.reset();
    cb.message.clear();
    sunrealtype t_reached = t;
    const int flag = CVode(cv.mem, stop, cv.y, &t_reached, CV_ONE_STEP);
    long error_test_failures = 0, convergence_failures = 0;
    CVodeGetNumErrTestFails(cv.mem, &error_test_failures);
    CVodeGetNumNonlinSolvConvFails(cv.mem, &convergence_failures);
    result_.stats.rejected = rejected_before + error_test_failures + convergence_failures;
    if (flag < 0) {
      if (cb.error) std::rethrow_exception(cb.error);
      sunrealtype h = 0;
      CVodeGetCurrentStep(cv.mem, &h);
      blow_up_ = cb.blow_up;
      const bool at_minimum = std::abs(h) <= s_.min_step * (1 + 1e-6);
      if (at_minimum && (flag == CV_ERR_FAILURE || flag == CV_CONV_FAILURE ||
                         flag == CV_REPTD_RHSFUNC_ERR || flag == CV_UNREC_RHSFUNC_ERR))
        underflow_failure(t, h, "at");
      throw RunFailure(engine_.name(), t, blow_up_ ? blow_up_->quantity : "",
                       "integrator gave up: CVODE status " + std::to_string(flag) +
                           (cb.message.empty() ? "" : " (" + cb.message + ")"));
    }
    const double t1 = t_reached;
    const double* y = N_VGetArrayPointer(cv.y);
    // The output times this step passed: interpolated (the step's own end: as returned).
    // Held until after_step() accepts the step (see Runner::dense).
    while (k < outputs_.size() && outputs_[k] <= t1) {
      if (outputs_[k] == t1) {
        hold(t1, y);
      } else {
        ok(CVodeGetDky(cv.mem, outputs_[k], 0, cv.y_out), "CVodeGetDky");
        hold(outputs_[k], N_VGetArrayPointer(cv.y_out));
      }
      ++k;
    }
    x.assign(y, y + n);
    t = t1;
    blow_up_.reset();
    const bool changed = accepted(t, x);
    release();
    const bool at_stop = flag == CV_TSTOP_RETURN;
    if (k >= outputs_.size()) break;
    // A change smaller than the error CVODE accepts in one step (weighted RMS norm <= 1, the norm
    // of its error test) is not worth a restart to order 1: the history continues from CVODE's
    // own state. Otherwise an engine that renormalises or projects at every step (kane at loose
    // tolerances, newton-euler) would restart CVODE at every step and crawl at order 1; the
    // engine sees the unchanged state again after the next step and changes it once it matters.
    bool restart = at_stop;
    if (changed) {
      if (weighted_rms_change(y, x) > 1.0)
        restart = true;
      else
        x.assign(y, y + n);
    }
    if (restart) {
      // Restart the history from (t, x): order 1, with CVODE's own estimate of the first step.
      std::copy(x.begin(), x.end(), N_VGetArrayPointer(cv.y));
      rejected_before = result_.stats.rejected;
      ok(CVodeReInit(cv.mem, t, cv.y), "CVodeReInit");
      ok(CVodeSetInitStep(cv.mem, 0.0), "CVodeSetInitStep");
    }
    if (at_stop) {
      stop = next_stop(t, end);
      ok(CVodeSetStopTime(cv.mem, stop), "CVodeSetStopTime");
    }
  }
}

}  // namespace crossdyn::integrate_detail
