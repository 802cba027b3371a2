// Flexible (modal) bodies in the Newton-Euler engine, integrated with crossdyn::simulate and at
// single states: the rigid limit, a free vibration in closed form, conservation of H and E with
// joints at nodes, damping and motor power balances, projection with modal coordinates.
#include "formulations/newton_euler/newton_euler.hpp"

#include "core/integrate.hpp"
#include "core/rotation.hpp"
#include "tests/newton_euler/ne_systems.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

using namespace crossdyn;
using namespace crossdyn::test::ne;
using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;
using Eigen::VectorXd;

namespace {

RunResult run(const System& s, const TreeState& ts, double duration, double tol,
              const EngineOptions& o = {}, double output_step = 0) {
  auto e = make_newton_euler_engine(s, o);
  IntegratorSettings st;
  st.method = "rkf78";
  st.rtol = st.atol = tol;
  st.duration = duration;
  st.output_step = output_step > 0 ? output_step : duration / 100;
  st.dt = 1e-3;
  RunResult r = simulate(*e, s, ts, st);
  if (r.failure) FAIL(r.failure->what());
  REQUIRE(r.rows() > 1);
  return r;
}

std::vector<double> series(const RunResult& r, const std::string& c) {
  const int i = r.column(c);
  REQUIRE(i >= 0);
  std::vector<double> v;
  for (std::size_t k = 0; k < r.rows(); ++k) v.push_back(r.at(k, static_cast<std::size_t>(i)));
  return v;
}

double max_abs_change(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m = std::max(m, std::abs(x - v.front()));
  return m;
}

double max_of(const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); }

// The flexible tree from a deformed, spinning state: eta up to 0.1 m and rates up to 0.3 m/s.
TreeState deformed_tree_state(const System& s, unsigned seed) {
  std::mt19937 rng(seed);
  TreeState ts = TreeState::initial(s);
  deform(s, ts, rng, 0.1, 0.3);
  return ts;
}

}  // namespace

// H with no external torque, E with no dampers or motors (springs and modal stiffness are
// conservative, E includes their potential): rkf78 at 1e-12 over 10 s with large deformation
// (eta up to 0.1 m on a 4 m beam, slopes up to 0.15 rad), base rotation, and every joint type at
// nodes of flexible parents and children. Measured: see the INFO line.
TEST_CASE("newton-euler flex: H and E are conserved with joints at nodes of flexible bodies",
          "[newton_euler][flexible][simulation]") {
  const System s = flexible_tree();
  const TreeState ts = deformed_tree_state(s, 1);
  for (const char* stab : {"projection", "baumgarte", "none"}) {
    EngineOptions o;
    o.stabilization = stab;
    const RunResult r = run(s, ts, 10, 1e-12, o);
    const auto H = series(r, "H"), E = series(r, "E");
    const auto q = series(r, "beam.qx1"), angle = series(r, "hinge.angle");
    INFO(stab << ": H drift " << max_abs_change(H) / H.front() << ", E drift "
              << max_abs_change(E) / E.front() << ", constraint.pos " << max_of(series(r, "constraint.pos")));
    CHECK(max_abs_change(q) > 0.02);      // the beam does deform
    CHECK(max_abs_change(angle) > 0.5);   // and the payload does turn
    CHECK(max_abs_change(H) <= 1e-10 * H.front());
    CHECK(max_abs_change(E) <= 1e-10 * E.front());
  }
}

