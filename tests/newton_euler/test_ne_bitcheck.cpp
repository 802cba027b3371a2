// A hidden check that the run's double path is unchanged bit for bit by the exact tangent's
// templating (issue 27): an FNV-1a hash of pack, rhs, accelerations, output_row and
// project_state over random states of rigid, flexible (linear and stiffened), prescribed-base and
// gravity/orbit scenes. Run it before and after a change (`[.bitcheck]`) and compare the printed
// hashes (not asserted: the figure only means something against its own earlier value).
#include "core/scene/scene.hpp"
#include "formulations/newton_euler/newton_euler.hpp"
#include "tests/newton_euler/ne_prescribed_scenes.hpp"
#include "tests/newton_euler/ne_systems.hpp"

#include <catch2/catch.hpp>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <random>
#include <vector>

namespace {

using namespace crossdyn;
using namespace crossdyn::test::ne;

struct Fnv {
  std::uint64_t h = 1469598103934665603ull;
  void add(const double* p, std::size_t n) {
    const auto* c = reinterpret_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n * sizeof(double); ++i) h = (h ^ c[i]) * 1099511628211ull;
  }
  void add(const std::vector<double>& v) { add(v.data(), v.size()); }
  void add(const Eigen::Vector3d& v) { add(v.data(), 3); }
};

}  // namespace

TEST_CASE("newton-euler: bit-for-bit hash of the run's double path", "[.bitcheck]") {
  std::vector<std::pair<std::string, System>> systems;
  systems.emplace_back("chain3", chain(3));
  systems.emplace_back("mixed_tree", mixed_tree());
  systems.emplace_back("flexible_tree", flexible_tree());
  systems.emplace_back("flexible_chain3", flexible_chain(3));
  {
    System s = flexible_tree();
    s.environment.kind = Environment::Kind::Uniform;
    s.environment.g_N = Eigen::Vector3d(0.3, -9.81, 1.2);
    s.zero_linear_momentum = false;
    systems.emplace_back("flexible_tree_gravity", s);
  }
  {
    System s = flexible_tree();
    Environment& e = s.environment;
    e.kind = Environment::Kind::Orbit;
    e.mu = 3.986004418e14;
    e.body_radius = 6.378e6;
    e.radius = 7.0e6;
    e.inclination = 0.9;
    e.raan = 0.4;
    e.latitude0 = 0.3;
    systems.emplace_back("flexible_tree_orbit", s);
  }
  systems.emplace_back("scan_platform", read_scene_text(scan_platform_text(), "scan"));
  systems.emplace_back("spinup_beam", read_scene_text(spinup_beam_text(false), "spinup"));
  systems.emplace_back("spinup_beam_stiff", read_scene_text(spinup_beam_text(true), "spinup_s"));
  systems.emplace_back("free_spinning_beam", read_scene_text(free_spinning_beam_text(), "fsb"));
  systems.emplace_back("beam_tip_prescribed", read_scene_text(beam_with_tip_text(true), "bt1"));
  systems.emplace_back("beam_tip_free", read_scene_text(beam_with_tip_text(false), "bt0"));
  Fnv all;
  for (const auto& [name, sys] : systems) {
    for (const ConstraintStabilization st :
         {ConstraintStabilization::Projection, ConstraintStabilization::Baumgarte}) {
      EngineOptions o;
      o.stabilization = st;
      std::unique_ptr<Engine> e = make_newton_euler_engine(sys, o);
      std::mt19937 rng(99);
      Fnv h;
      for (int k = 0; k < 5; ++k) {
        TreeState s = random_state(sys, rng);
        for (std::size_t j = 0; j < sys.joints.size(); ++j)
          if (sys.joints[j].prescribed || (j == 0 && !sys.base_is_free())) s.joints[j] = TreeState::initial(sys).joints[j];
        deform(sys, s, rng, 0.05, 0.3);
        const double t = 0.37 * k;
        std::vector<double> x(static_cast<std::size_t>(e->state_size())), xd(x.size());
        e->pack(s, x.data());
        h.add(x);
        e->rhs(t, x.data(), xd.data());
        h.add(xd);
        TreeAccel a;
        e->accelerations(t, x.data(), a);
        for (const auto& v : a.wdot_NB_B) h.add(v);
        for (const auto& v : a.a_NBo_N) h.add(v);
        h.add(a.angle_ddot);
        h.add(a.angle2_ddot);
        for (const auto& v : a.wdot_PC_C) h.add(v);
        for (const auto& v : a.eta_ddot) h.add(v.data(), static_cast<std::size_t>(v.size()));
        std::vector<double> row(static_cast<std::size_t>(e->layout().size()));
        e->output_row(t, x.data(), row.data());
        h.add(row);
        for (double& v : x) v *= 1.0 + 1e-7;  // off the manifold: the projection works
        e->project_state(t, x.data());
        h.add(x);
      }
      std::printf("bitcheck %-24s %d %016llx\n", name.c_str(), static_cast<int>(st),
                  static_cast<unsigned long long>(h.h));
      all.add(reinterpret_cast<const double*>(&h.h), 1);
    }
  }
  std::printf("bitcheck ALL %016llx\n", static_cast<unsigned long long>(all.h));
}
