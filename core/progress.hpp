// A one-line progress display for long runs, on stderr, redrawn in place ("\r", erase to the end
// of the line) at most kRedrawsPerSecond times a second:
//
//   chain100 kane: 42.0%  t = 4.2 of 10 s  1234 steps  12 s elapsed, about 17 s left
//
// Shown only when stderr is a terminal (isatty) and not switched off (--quiet); otherwise every
// call is a no-op, so output to files and pipes is byte-identical with or without it. The line is
// erased by clear() and by the destructor, so that messages printed afterwards start clean.
#pragma once

#include <chrono>
#include <string>

namespace crossdyn {

class ProgressLine {
 public:
  static constexpr double kRedrawsPerSecond = 4;

  // enabled: the caller's wish (false with --quiet); the line is shown only if stderr is also a
  // terminal.
  explicit ProgressLine(bool enabled);
  ~ProgressLine();
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;

  bool shown() const { return enabled_; }
  static bool stderr_is_terminal();
  static bool stdout_is_terminal();  // `run` writing rows to the terminal shows no progress line

  // A new run: the label ("chain100 kane") and its simulated duration; the clock starts now.
  void start(std::string label, double duration);
  // A phase without simulated time yet ("setting up"): drawn at once.
  void phase(const std::string& what);
  // Simulated time t of the run's duration after `steps` steps; drawn when due.
  void update(double t, long steps);
  // Erases the line (if drawn).
  void clear();

  // The text drawn for a run at t of duration after steps, elapsed seconds (for tests).
  static std::string format(const std::string& label, double t, double duration, long steps,
                            double elapsed);

 private:
  void draw(const std::string& text);
  bool enabled_;
  bool drawn_ = false;
  bool phase_shown_ = false;  // the line shows a phase ("setting up the engine"), not progress
  std::string label_;
  double duration_ = 0;
  std::chrono::steady_clock::time_point start_{}, last_draw_{};
};

}  // namespace crossdyn
