// Synthetic scenes and runs for testing the comparison logic without any engine.
#pragma once

#include "core/integrate.hpp"
#include "core/system.hpp"
#include "harness/compare.hpp"

#include <functional>
#include <string>
#include <vector>

namespace crossdyn::test {

// Two bodies: "base" (free) and "arm" on the revolute joint "hinge". Pinned columns:
// t, base.w*, base.q*, arm.w*, arm.q*, hinge.angle, hinge.rate, H, E.
inline System two_body_system() {
  System s;
  s.name = "synthetic";
  s.file = "synthetic.yaml";
  Body base;
  base.name = std::string("base");
  base.mass = 10;
  base.I_BBo_B = Eigen::Vector3d(1, 2, 3).asDiagonal();
  Body arm = base;
  arm.name = std::string("arm");
  s.bodies = {base, arm};
  Joint free;
  free.name = std::string("root");
  free.type = JointType::Free;
  free.child = 0;
  Joint hinge;
  hinge.name = std::string("hinge");
  hinge.type = JointType::Revolute;
  hinge.parent = 0;
  hinge.child = 1;
  s.joints = {free, hinge};
  s.run.duration = 1.0;
  s.run.output_step = 0.25;
  return s;
}

// A run at t = 0, 0.25, ..., 1 whose value in every column is value(column, row).
using ValueFn = std::function<double(const std::string& column, std::size_t row)>;

// The baseline value of a column: identity attitude, w = (1, 2, 3), angle = t, rate = 1,
// H = 10, E = 5.
inline double baseline(const std::string& column, std::size_t row) {
  const double t = 0.25 * static_cast<double>(row);
  auto ends = [&column](const char* s) {
    const std::string x(s);
    return column.size() >= x.size() && column.compare(column.size() - x.size(), x.size(), x) == 0;
  };
  if (column == "t") return t;
  if (ends(".qw")) return 1;
  if (ends(".qx") || ends(".qy") || ends(".qz")) return 0;
  if (ends(".wx")) return 1;
  if (ends(".wy")) return 2;
  if (ends(".wz")) return 3;
  if (ends(".angle")) return t;
  if (ends(".rate")) return 1;
  if (column == "H") return 10;
  if (column == "E") return 5;
  return 0;
}

inline RunResult make_run(const System& s, const ValueFn& value = baseline,
                          std::vector<std::string> extra_columns = {}) {
  RunResult r;
  r.columns = pinned_columns(s);
  r.columns.insert(r.columns.end(), extra_columns.begin(), extra_columns.end());
  for (std::size_t row = 0; row < 5; ++row)
    for (const std::string& c : r.columns) r.data.push_back(value(c, row));
  return r;
}

inline harness::EngineRun engine_run(const std::string& label, RunResult r) {
  harness::EngineRun e;
  e.label = label;
  e.engine = label;
  r.engine = label;
  e.result = std::move(r);
  return e;
}

// The checks of a comparison with this quantity (and pair a vs b when given).
inline std::vector<harness::Check> find_checks(const harness::SceneComparison& c,
                                               const std::string& quantity,
                                               const std::string& a = "",
                                               const std::string& b = "") {
  std::vector<harness::Check> out;
  for (const harness::Check& k : c.checks)
    if (k.quantity == quantity && (a.empty() || k.a == a) && (b.empty() || k.b == b))
      out.push_back(k);
  return out;
}

}  // namespace crossdyn::test
