// The three engines agree: at random states (accelerations) and over whole runs (time histories).
// Kane's engine is the reference of each pair only by convention; a disagreement means one of the
// two independently written engines is wrong.
#include <catch2/catch.hpp>

#include "core/rotation.hpp"
#include "tests/cross/common.hpp"

#include <cmath>

using namespace crossdyn;
using namespace crossdyn::test;

namespace {

// Largest component difference of a list of vectors, relative to the largest component (floor 1).
template <typename V>
double rel_diff(const std::vector<V>& a, const std::vector<V>& b) {
  double d = 0, m = 1.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    d = std::max(d, (a[i] - b[i]).cwiseAbs().maxCoeff());
    m = std::max(m, b[i].cwiseAbs().maxCoeff());
  }
  return d / m;
}
double rel_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0, m = 1.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    d = std::max(d, std::abs(a[i] - b[i]));
    m = std::max(m, std::abs(b[i]));
  }
  return d / m;
}

}  // namespace

TEST_CASE("at 100 random states every engine's accelerations agree with Kane's to 1e-10") {
  for (const std::string& scene : pinned_rigid_scenes()) {
    const System system = read_scene(scene_path(scene));
    auto kane = make_engine("kane", system);
    for (const std::string& other : {std::string("newton-euler"), std::string("lagrange")}) {
      auto engine = make_engine(other, system);
      std::mt19937 g(2026);
      double worst_w = 0, worst_a = 0, worst_joint = 0;
      for (int k = 0; k < 100; ++k) {
        const TreeState s = random_state(system, g);
        std::vector<double> xk(static_cast<std::size_t>(kane->state_size()));
        std::vector<double> xo(static_cast<std::size_t>(engine->state_size()));
        kane->pack(s, xk.data());
        engine->pack(s, xo.data());
        TreeAccel ak, ao;
        kane->accelerations(0.0, xk.data(), ak);
        engine->accelerations(0.0, xo.data(), ao);
        worst_w = std::max(worst_w, rel_diff(ao.wdot_NB_B, ak.wdot_NB_B));
        worst_a = std::max(worst_a, rel_diff(ao.a_NBo_N, ak.a_NBo_N));
        worst_joint = std::max({worst_joint, rel_diff(ao.angle_ddot, ak.angle_ddot),
                                rel_diff(ao.wdot_PC_C, ak.wdot_PC_C)});
      }
      INFO(scene << ": " << other << " vs kane, worst relative difference: body angular "
                 << worst_w << ", CM " << worst_a << ", joint " << worst_joint);
      CHECK(worst_w <= 1e-10);
      CHECK(worst_a <= 1e-10);
      CHECK(worst_joint <= 1e-10);
    }
  }
}

TEST_CASE("integrated at 1e-12, every pinned column agrees with Kane's engine to 1e-8 relative") {
  std::vector<std::string> scenes = pinned_rigid_scenes();
  scenes.push_back("gimbal_lock");  // Lagrange re-charts its Euler angles on the way
  for (const std::string& scene : scenes) {
    const System system = read_scene(scene_path(scene));
    const RunResult ref = run_engine("kane", system, "rkf78", 1e-12);
    REQUIRE_FALSE(ref.failure);
    const auto pinned = pinned_columns(system);
    // Angular velocities are held relative to the largest rate in the scene, angles to 1 rad.
    double w_scale = 0;
    for (std::size_t c = 0; c < pinned.size(); ++c)
      if (pinned[c].ends_with(".wx") || pinned[c].ends_with(".wy") || pinned[c].ends_with(".wz"))
        for (std::size_t i = 0; i < ref.rows(); ++i) w_scale = std::max(w_scale, std::abs(ref.at(i, c)));
    const std::vector<double> new_scale = new_column_scales(OutputLayout(system), ref);
    for (const std::string& other : {std::string("newton-euler"), std::string("lagrange")}) {
      const RunResult r = run_engine(other, system, "rkf78", 1e-12);
      REQUIRE_FALSE(r.failure);
      REQUIRE(r.rows() == ref.rows());
      for (std::size_t c = 0; c < pinned.size(); ++c) {
        const std::string& col = pinned[c];
        if (col.find(".q") != std::string::npos) continue;  // attitudes below, as rotation angles
        const int rc = r.column(col);
        REQUIRE(rc >= 0);
        double diff = 0, scale = 0;
        for (std::size_t i = 0; i < ref.rows(); ++i) {
          diff = std::max(diff, std::abs(r.at(i, static_cast<std::size_t>(rc)) - ref.at(i, c)));
          scale = std::max(scale, std::abs(ref.at(i, c)));
        }
        if (col.ends_with(".wx") || col.ends_with(".wy") || col.ends_with(".wz")) scale = w_scale;
        if (col.ends_with(".angle")) scale = std::max(scale, 1.0);
        if (new_scale[c] > 0) scale = new_scale[c];  // issue 26's columns: by what they belong to
        INFO(scene << ": " << other << " vs kane, " << col << " max difference " << diff
                   << " (scale " << scale << ")");
        CHECK(diff <= 1e-8 * scale);
      }
      for (const Body& b : system.bodies) {
        const int k0 = ref.column(b.name + ".qw"), o0 = r.column(b.name + ".qw");
        double worst = 0;
        for (std::size_t i = 0; i < ref.rows(); ++i) {
          auto q = [](const RunResult& x, std::size_t row, int c0) {
            const auto c = static_cast<std::size_t>(c0);
            return Eigen::Quaterniond(x.at(row, c), x.at(row, c + 1), x.at(row, c + 2), x.at(row, c + 3));
          };
          worst = std::max(worst, rot::angle_between(q(ref, i, k0), q(r, i, o0)));
        }
        INFO(scene << ": " << other << " vs kane, attitude of " << b.name << " differs by " << worst << " rad");
        CHECK(worst <= 1e-8);
      }
    }
  }
}
