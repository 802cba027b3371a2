// The progress line (see progress.hpp).
#include "core/progress.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sys/ioctl.h>
#include <unistd.h>

namespace crossdyn {

namespace {

// "12 s", "3 min 05 s", "2 h 04 min".
std::string duration_text(double s) {
  char b[64];
  if (!std::isfinite(s) || s < 0) return "?";
  if (s < 60) std::snprintf(b, sizeof b, "%.0f s", s);
  else if (s < 3600) std::snprintf(b, sizeof b, "%d min %02d s", static_cast<int>(s / 60), static_cast<int>(s) % 60);
  else std::snprintf(b, sizeof b, "%d h %02d min", static_cast<int>(s / 3600), static_cast<int>(s / 60) % 60);
  return b;
}

void write_all(const std::string& s) {
  std::size_t done = 0;
  while (done < s.size()) {
    const ssize_t n = ::write(STDERR_FILENO, s.data() + done, s.size() - done);
    if (n <= 0) return;  // a display only: never an error
    done += static_cast<std::size_t>(n);
  }
}

}  // namespace

ProgressLine::ProgressLine(bool enabled) : enabled_(enabled && stderr_is_terminal()) {}

ProgressLine::~ProgressLine() { clear(); }

bool ProgressLine::stderr_is_terminal() { return ::isatty(STDERR_FILENO) == 1; }
bool ProgressLine::stdout_is_terminal() { return ::isatty(STDOUT_FILENO) == 1; }

std::string ProgressLine::format(const std::string& label, double t, double duration, long steps,
                                 double elapsed) {
  const double f = duration > 0 ? std::clamp(t / duration, 0.0, 1.0) : 0.0;
  char b[256];
  std::snprintf(b, sizeof b, "%s: %.1f%%  t = %.4g of %.4g s  %ld steps  %s elapsed",
                label.c_str(), 100 * f, t, duration, steps, duration_text(elapsed).c_str());
  std::string s = b;
  if (f > 0 && f < 1) s += ", about " + duration_text(elapsed * (1 - f) / f) + " left";
  return s;
}

void ProgressLine::start(std::string label, double duration) {
  label_ = std::move(label);
  duration_ = duration;
  start_ = std::chrono::steady_clock::now();
  last_draw_ = {};
}

void ProgressLine::phase(const std::string& what) {
  if (!enabled_) return;
  draw(label_ + ": " + what);
  phase_shown_ = true;  // the first update replaces it at once
}

void ProgressLine::update(double t, long steps) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (drawn_ && !phase_shown_ &&
      now - last_draw_ < std::chrono::duration<double>(1.0 / kRedrawsPerSecond))
    return;
  last_draw_ = now;
  phase_shown_ = false;
  draw(format(label_, t, duration_, steps, std::chrono::duration<double>(now - start_).count()));
}

void ProgressLine::draw(const std::string& text) {
  winsize w{};
  std::size_t width = 80;
  if (::ioctl(STDERR_FILENO, TIOCGWINSZ, &w) == 0 && w.ws_col > 1) width = w.ws_col;
  // One character short of the width, so the cursor never wraps to a new line.
  write_all("\r" + text.substr(0, width - 1) + "\033[K");
  drawn_ = true;
}

void ProgressLine::clear() {
  if (!enabled_ || !drawn_) return;
  write_all("\r\033[K");
  drawn_ = false;
}

}  // namespace crossdyn
