// Error types and the exit codes they map to (docs/outputs.md "Exit status").
//   InputError  bad input (scene file, command line): exit 2. The message names the file, the
//               line and column where known, the key, and what is wrong.
//   RunFailure  a run that cannot go on (non-finite state, step-size underflow, step limit,
//               singular coordinates, interrupted): exit 3 from `run`; `verify` records it.
#pragma once

#include <stdexcept>
#include <string>

namespace crossdyn {

enum ExitCode : int { kExitOk = 0, kExitCheckFailed = 1, kExitBadInput = 2, kExitRunFailed = 3 };

class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
};

class RunFailure : public std::runtime_error {
 public:
  RunFailure(std::string engine, double t, std::string quantity, std::string reason)
      : std::runtime_error(format(engine, t, quantity, reason)),
        engine_(std::move(engine)), t_(t), quantity_(std::move(quantity)),
        reason_(std::move(reason)) {}
  const std::string& engine() const { return engine_; }
  double time() const { return t_; }
  const std::string& quantity() const { return quantity_; }
  const std::string& reason() const { return reason_; }

 private:
  static std::string format(const std::string& engine, double t, const std::string& quantity,
                            const std::string& reason);
  std::string engine_;
  double t_;
  std::string quantity_;
  std::string reason_;
};

}  // namespace crossdyn
