// `crossdyn linearize` (harness/linearize.hpp; issue 27): every engine's linear model about an
// equilibrium or a steady spin, eigenvalues against closed forms and between engines, a wrong
// gyroscopic sign caught, points that are not equilibria refused, and the outputs.
#include <catch2/catch.hpp>

#include <unistd.h>

#include <Eigen/Eigenvalues>
#include <nlohmann/json.hpp>

#include <cmath>
#include <complex>
#include <limits>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/errors.hpp"
#include "core/output_layout.hpp"
#include "core/flex/beam.hpp"
#include "core/scene/scene.hpp"
#include "harness/engines.hpp"
#include "harness/linearize.hpp"
#include "tests/harness/run_program.hpp"
#include "tests/support/paths.hpp"

using namespace crossdyn;
using namespace crossdyn::harness;
using cd = std::complex<double>;

namespace {

// The default beam (100 slices, its mass at Gauss-Legendre points: issue 27 item 5) against the
// continuum beam's frequencies: exact to rounding (it was 3e-9 with the mass at the slice centres).
constexpr double kBeamTolerance = 1e-10;

LinearizeOptions every_engine() {
  LinearizeOptions o;
  for (const std::string& e : engine_names()) o.engines.push_back({e, e, {}});
  return o;
}

// The engine's eigenvalue nearest to `expected`, and its distance.
double nearest(const EngineLinearModel& m, cd expected) {
  double best = INFINITY;
  for (const cd& l : m.eigenvalues) best = std::min(best, std::abs(l - expected));
  return best;
}

std::string failed_checks(const LinearizeResult& r) {
  std::string s;
  for (const LinearCheck& c : r.checks)
    if (!c.passed) s += c.kind + " " + c.what + " " + c.engine_a + " vs " + c.engine_b + "; ";
  for (const EngineLinearModel& m : r.engines)
    if (!m.failure.empty()) s += m.label + ": " + m.failure + "; ";
  return s;
}

int count(const LinearizeResult& r, const std::string& kind) {
  int n = 0;
  for (const LinearCheck& c : r.checks) n += c.kind == kind;
  return n;
}

std::string slurp(const std::string& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST_CASE("linearize: a torque-free body's steady spin about each principal axis gives Euler's eigenvalues to 1e-10 in every engine") {
  // diag(100, 200, 300) kg m^2; lambda^2 = Omega^2 (I_j - I_k)(I_k - I_i) / (I_i I_j) about axis k.
  // Spin 2 rad/s: minor (x) +-i 2 sqrt(1/3), intermediate (y) +-2 sqrt(1/3) real, major (z) +-2i.
  // The body is also turned (principal axes not the body axes) so that the principal-axis
  // search is exercised.
  const double Om = 2.0;
  struct Case {
    int axis;
    cd expected;
  };
  const Case cases[] = {{0, cd(0, Om * std::sqrt(1.0 / 3.0))}, {1, cd(Om * std::sqrt(1.0 / 3.0), 0)}, {2, cd(0, Om)}};
  for (const bool turned : {false, true}) {
    for (const Case& c : cases) {
      INFO("axis " << c.axis << (turned ? " (principal axes turned in the body)" : ""));
      System s = read_scene(test::scene_path("torque_free_asymmetric"));
      s.analytic.clear();
      Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
      if (turned) R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
      s.bodies[0].I_BBo_B = R * Eigen::Vector3d(100, 200, 300).asDiagonal() * R.transpose();
      s.joints[0].w_NB_B0 = Om * R.col(c.axis);
      const LinearizeResult r = linearize(s, every_engine());
      CHECK(failed_checks(r) == "");
      CHECK(r.equilibrium);
      CHECK(count(r, "analytic") == 3);
      for (const EngineLinearModel& m : r.engines) {
        INFO(m.label);
        CHECK(nearest(m, c.expected) <= 1e-10 * Om);
        CHECK(nearest(m, -c.expected) <= 1e-10 * Om);
        CHECK(m.zeros == 1);  // the spin's own magnitude
      }
      // The intermediate axis is a finding in every engine, the others are not.
      int unstable = 0;
      for (const std::string& f : r.findings) unstable += f.find("unstable") != std::string::npos;
      CHECK(unstable == (c.axis == 1 ? 3 : 0));
    }
  }
}

TEST_CASE("linearize: hub_two_panels_spin's engines agree to 1e-8 and find the intermediate-axis instability") {
  const System s = read_scene(test::scene_path("hub_two_panels_spin"));
  LinearizeOptions o = every_engine();
  o.point = OperatingPoint::Neutral;
  const LinearizeResult r = linearize(s, o);
  CHECK(failed_checks(r) == "");
  CHECK(count(r, "eigenvalue") == 2 * 4);  // 4 modes, two engine pairs
  for (const EngineLinearModel& m : r.engines) {
    INFO(m.label);
    REQUIRE(m.modes.size() == 4);
    CHECK(m.modes[2].frequency == Approx(1.423672).epsilon(1e-6));
    CHECK(m.modes[3].frequency == Approx(2.236786).epsilon(1e-6));
    CHECK(m.modes[1].lambda.real() == Approx(0.0218069).epsilon(1e-5));  // the unstable one
  }
  for (const LinearCheck& c : r.checks)
    if (c.kind == "eigenvalue") CHECK(c.error <= 1e-8 * std::abs(c.a));
  CHECK(r.findings.size() == 3);
}

TEST_CASE("linearize: a wrong gyroscopic sign in one engine (test double) is caught at a steady spin") {
  const System s = read_scene(test::scene_path("hub_two_panels_spin"));
  LinearizeOptions o = every_engine();
  o.point = OperatingPoint::Neutral;
  LinearEngineChoice wrong{"kane*gyro", "kane", {}};
  wrong.options.test_gyroscopic_sign = -1;
  o.engines.push_back(wrong);
  const LinearizeResult r = linearize(s, o);
  int failed_wrong = 0, failed_right = 0;
  for (const LinearCheck& c : r.checks)
    if (!c.passed) (c.engine_b == "kane*gyro" ? failed_wrong : failed_right)++;
  CHECK(failed_right == 0);
  CHECK(failed_wrong >= 2);  // the hinge modes move by 1.3e-3 relative; the instability disappears
  CHECK_FALSE(r.passed());
  // The test double changes nothing when nothing spins (the sign multiplies w x I w).
  System rest = s;
  rest.joints[0].w_NB_B0.setZero();
  CHECK(failed_checks(linearize(rest, o)) == "");
}

TEST_CASE("linearize: a spinning cantilever with and without geometric stiffening matches its modal Lagrangian and the linear model's runaway is an unstable mode") {
  // spinup_beam(_linear): a clamped beam on a hub whose spin is prescribed; at t = 20 s it turns
  // at 10 rad/s, at t = 0 it is at rest (the cantilever's own frequencies).
  const double ok = std::sqrt(14000.0 / (1.2 * 1e4));  // sqrt(EI / (rho A L^4))
  for (const char* scene : {"spinup_beam", "spinup_beam_linear"}) {
    for (const double t : {0.0, 20.0}) {
      INFO(scene << " at t = " << t);
      const System s = read_scene(test::scene_path(scene));
      LinearizeOptions o = every_engine();
      o.time = t;
      const LinearizeResult r = linearize(s, o);
      CHECK(failed_checks(r) == "");
      CHECK(count(r, "analytic") >= 3 * 3);  // three modes (a real pair counts twice), every engine
      // Without stiffening: K_eff = K - Omega^2 M, so lambda_k^2 = Omega^2 - omega_k^2 with the
      // continuum's clamped-free omega_k (the generator's modal mass is diagonal to rounding).
      if (std::string(scene) == "spinup_beam_linear") {
        const double Om = t > 15 ? 10.0 : 0.0;
        const double w1 = std::pow(flex::clamped_root(1), 2) * ok;
        const cd expected = std::sqrt(cd(Om * Om - w1 * w1, 0));
        for (const EngineLinearModel& m : r.engines) CHECK(nearest(m, expected) <= kBeamTolerance * std::abs(expected));
        int unstable = 0;
        for (const std::string& f : r.findings) unstable += f.find("unstable mode beam.qy1") != std::string::npos;
        CHECK(unstable == (Om > w1 ? 3 : 0));
      } else {
        CHECK(r.findings.empty());
      }
    }
  }
}

TEST_CASE("linearize: every committed scene at an equilibrium or steady spin: the three engines' eigenvalues agree to 1e-8") {
  struct Point {
    const char* scene;
    OperatingPoint point;
    double t;
  };
  const Point points[] = {{"spear1_case1", OperatingPoint::Neutral, 0},
                          {"chain5", OperatingPoint::Spin, 0},
                          {"dual_spin", OperatingPoint::Spin, 0},
                          {"spear1_case2", OperatingPoint::Neutral, 0},
                          {"spear1_case1_spherical", OperatingPoint::Neutral, 0},
                          {"pointing_flex", OperatingPoint::Neutral, 10},
                          {"hub_two_panels_spin", OperatingPoint::Neutral, 0},
                          {"spinup_beam", OperatingPoint::Initial, 20}};
  for (const Point& p : points) {
    INFO(p.scene);
    const System s = read_scene(test::scene_path(p.scene));
    LinearizeOptions o = every_engine();
    o.point = p.point;
    o.time = p.t;
    const LinearizeResult r = linearize(s, o);
    CHECK(failed_checks(r) == "");
    CHECK(count(r, "eigenvalue") > 0);
    for (const LinearCheck& c : r.checks)
      if (c.kind == "eigenvalue") {
        INFO(c.what << " " << c.engine_a << " vs " << c.engine_b);
        CHECK(c.error <= 1e-8 * std::abs(c.a));
        // A bound the check can fail: the finite differences' allowance is each eigenvalue's own (a
        // freely turning joint's defective zero once made every bound infinite: pointing_flex, chain5).
        CHECK(c.bound < 1e-6 * std::abs(c.a));
      }
  }
}

TEST_CASE("linearize: a state that is not an equilibrium is refused with its residual and --jacobian-only compares nothing") {
  // A tumbling body, a spring away from its neutral angle, a motor that is on.
  struct Case {
    const char* scene;
    OperatingPoint point;
    double t;
    const char* says;
  };
  const Case cases[] = {{"torque_free_asymmetric", OperatingPoint::Initial, 0, "body.w"},
                        {"hub_two_panels", OperatingPoint::Initial, 0, "not an equilibrium"},
                        {"pointing_flex", OperatingPoint::Neutral, 0, "joint1.motor = 1"},
                        {"spinup_beam", OperatingPoint::Initial, 5, "not an equilibrium"}};
  for (const Case& c : cases) {
    INFO(c.scene);
    const System s = read_scene(test::scene_path(c.scene));
    LinearizeOptions o = every_engine();
    o.point = c.point;
    o.time = c.t;
    try {
      linearize(s, o);
      FAIL("not refused");
    } catch (const InputError& e) {
      CHECK_THAT(e.what(), Catch::Contains(c.says) && Catch::Contains("allowed 1e-09"));
    }
    o.jacobian_only = true;
    const LinearizeResult r = linearize(s, o);
    CHECK_FALSE(r.equilibrium);
    // Nothing compared between engines: only each engine's exact matrices against their own
    // differences.
    for (const LinearCheck& k : r.checks) {
      INFO(k.what);
      CHECK(k.kind == "jacobian");
      CHECK(k.engine_b == k.engine_a + " differences");
      CHECK(k.passed);
    }
    for (const EngineLinearModel& m : r.engines) {
      CHECK(m.A.rows() == static_cast<Eigen::Index>(r.states.size()));
      CHECK(m.own_A.rows() == static_cast<Eigen::Index>(m.own_states.size()));
      CHECK(m.own_A.rows() > 0);
    }
  }
}

TEST_CASE("linearize: bad input on the command line is refused with exit 2 and nothing written") {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("crossdyn-linearize-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string json = (dir / "out.json").string();
  std::ofstream(dir / "file.txt") << "x";
  const std::pair<std::string, std::string> cases[] = {
      {"pointing_flex --time 10 --operating-point neutral --inputs joint9.motor", "'joint9.motor' is not an input"},
      {"pointing_flex --time 10 --operating-point neutral --outputs beam.nope", "'beam.nope' is not an output column"},
      {"pointing_flex --time 10 --operating-point neutral --outputs t", "'t' is not an output column"},
      {"pointing_flex --time 10 --operating-point neutral --inputs joint1.motor,joint1.motor", "listed twice"},
      {"pointing_flex --operating-point sideways", "not one of initial, neutral, equilibrium, spin"},
      {"pointing_flex --time -1", "--time"},
      {"pointing_flex --rtol 0", "--rtol"},
      {"pointing_flex --engines kane,foo", "unknown engine 'foo'"},
      {"pointing_flex --time 10 --operating-point neutral --csv '" + (dir / "file.txt").string() + "'", "a folder is needed"},
      {"torque_free_asymmetric", "is not an equilibrium"},
      {"no_such_scene", "no_such_scene"}};
  for (const auto& [args, says] : cases) {
    INFO(args);
    const test::ProgramResult p = test::run_crossdyn("linearize " + args + " --json '" + json + "'");
    CHECK(p.status == 2);
    CHECK_THAT(p.output, Catch::Contains(says));
    CHECK_FALSE(fs::exists(json));
  }
  fs::remove_all(dir);
}

TEST_CASE("linearize: A B C D and the eigenvalues as JSON and CSV with every state named and transfer functions compared") {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("crossdyn-linearize-out-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string json = (dir / "lin.json").string(), csv = (dir / "csv").string();
  const test::ProgramResult p = test::run_crossdyn(
      "linearize pointing_flex --time 10 --operating-point neutral --outputs joint1.angle,beam.wy,beam.qx1 --json '" +
      json + "' --csv '" + csv + "'");
  INFO(p.output);
  REQUIRE(p.status == 0);
  CHECK_THAT(p.output, Catch::Contains("PASS transfer joint1.angle <- joint1.motor"));
  const nlohmann::json j = nlohmann::json::parse(slurp(json));
  const std::size_t n = j["states"].size(), m = j["inputs"].size(), q = j["outputs"].size();
  CHECK(n == 15);
  CHECK(m == 2);
  CHECK(q == 3);
  CHECK(j["engines"].size() == 3);
  for (const auto& e : j["engines"]) {
    CHECK(e["A"].size() == n);
    CHECK(e["A"][0].size() == n);
    CHECK(e["B"].size() == n);
    CHECK(e["B"][0].size() == m);
    CHECK(e["C"].size() == q);
    CHECK(e["D"].size() == q);
    CHECK(e["eigenvalues"].size() == n);
    CHECK(e["own_coordinates"]["states"].size() == e["own_coordinates"]["A"].size());
  }
  CHECK(j["passed"] == true);
  // B: a motor torque on joint1 accelerates joint1 (and not the configuration rows).
  const auto& B = j["engines"][0]["B"];
  CHECK(B[0][0].get<double>() == 0.0);
  // The CSV files: a header row of names, then the matrix; states.csv lists the order.
  for (const std::string engine : {"kane", "lagrange", "newton-euler"})
    for (const std::string what : {"A", "B", "C", "D", "eigenvalues", "own_A"})
      CHECK(fs::exists(fs::path(csv) / (engine + "." + what + ".csv")));
  std::ifstream a(fs::path(csv) / "kane.A.csv");
  std::string header;
  std::getline(a, header);
  CHECK(header.rfind("joint1.angle,joint2.angle,", 0) == 0);
  int rows = 0;
  for (std::string line; std::getline(a, line);) ++rows;
  CHECK(rows == 15);
  CHECK(slurp((fs::path(csv) / "states.csv").string()).rfind("index,name\n1,joint1.angle\n", 0) == 0);
  fs::remove_all(dir);
}

TEST_CASE("linearize: a root locus over a scene parameter finds where the linear spinning beam diverges") {
  // spinup_beam_linear at full spin: the first mode's lambda^2 = Omega^2 - omega_1^2 (omega_1 =
  // 3.7977 rad/s): stable at 3.7 rad/s, growing at 3.9; spinup_beam (stiffened) never.
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("crossdyn-locus-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const test::ProgramResult p = test::run_crossdyn(
      "linearize spinup_beam_linear --time 20 --vary spin.prescribed_rate --values 3.7,3.9,10 --json '" +
      (dir / "l.json").string() + "' --csv '" + (dir / "csv").string() + "'");
  INFO(p.output);
  REQUIRE(p.status == 0);
  const nlohmann::json j = nlohmann::json::parse(slurp((dir / "l.json").string()));
  REQUIRE(j["points"].size() == 3);
  const bool growing[] = {false, true, true};
  for (std::size_t k = 0; k < 3; ++k) {
    const auto& lin = j["points"][k]["linearization"];
    CHECK(lin["passed"] == true);
    bool unstable = false;
    for (const auto& f : lin["findings"]) unstable = unstable || f.get<std::string>().find("unstable mode beam.qy1") != std::string::npos;
    CHECK(unstable == growing[k]);
  }
  CHECK(slurp((dir / "csv" / "root_locus.csv").string()).rfind("value,engine,re,im,frequency,damping_ratio\n3.7,kane,", 0) == 0);
  const test::ProgramResult q = test::run_crossdyn("linearize spinup_beam --time 20 --vary spin.prescribed_rate --values 3.7,3.9,10");
  CHECK(q.status == 0);
  CHECK(q.output.find("unstable") == std::string::npos);
  // A value whose point is not an equilibrium is listed as refused; bad sweeps are refused.
  const test::ProgramResult r = test::run_crossdyn("linearize hub_two_panels_spin --operating-point neutral --vary base.wx --values 0,0.05");
  CHECK(r.status == 0);
  CHECK_THAT(r.output, Catch::Contains("refused: ") && Catch::Contains("not an equilibrium"));
  CHECK(test::run_crossdyn("linearize spinup_beam --vary spin.prescribed_rate").status == 2);
  CHECK(test::run_crossdyn("linearize spinup_beam --vary spin.nothing --values 1").status == 2);
  CHECK(test::run_crossdyn("linearize spinup_beam --vary spin.prescribed_rate --values 1,x").status == 2);
  fs::remove_all(dir);
}

TEST_CASE("linearize: the report draws the eigenvalues and every mode and a root locus with --vary") {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("crossdyn-linrep-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const test::ProgramResult p =
      test::run_crossdyn("linearize hub_two_panels_spin --operating-point neutral --report '" + (dir / "one").string() + "'");
  INFO(p.output);
  REQUIRE(p.status == 0);
  for (const char* f : {"index.html", "eigenvalues.png", "differences.png", "mode-1.png", "mode-3.png", "mode-4.png", "linearize.json"})
    CHECK(fs::exists(dir / "one" / f));
  const std::string html = slurp((dir / "one" / "index.html").string());
  CHECK_THAT(html, Catch::Contains("hinge1.angle + hinge2.angle") && Catch::Contains("(grows)") &&
                       Catch::Contains("unstable mode hub.w"));
  const test::ProgramResult q = test::run_crossdyn("linearize spinup_beam_linear --time 20 --vary spin.prescribed_rate --values 1,3.9,10 --report '" +
                                                   (dir / "locus").string() + "'");
  INFO(q.output);
  REQUIRE(q.status == 0);
  CHECK(fs::exists(dir / "locus" / "root-locus.png"));
  CHECK_THAT(slurp((dir / "locus" / "index.html").string()), Catch::Contains("Root locus against spin.prescribed_rate"));
  // A folder that is not a linearize report is refused before the work, and left alone.
  fs::create_directories(dir / "mine");
  std::ofstream(dir / "mine" / "notes.txt") << "mine";
  const test::ProgramResult r = test::run_crossdyn("linearize hub_two_panels_spin --operating-point neutral --report '" + (dir / "mine").string() + "'");
  CHECK(r.status == 2);
  CHECK(fs::exists(dir / "mine" / "notes.txt"));
  CHECK_FALSE(fs::exists(dir / "mine" / "index.html"));
  fs::remove_all(dir);
}

TEST_CASE("linearize: a free-free beam alone at rest vibrates at the continuum beam's frequencies in every engine") {
  // The beam generator's free-free modes (10 m, 50 kg/m, EI 1e4 and 2e4 N m^2): omega_k =
  // lambda_k^2 sqrt(EI / (rho A L^4)), lambda_k the roots of cos cosh = 1 (Blevins 1979). The
  // check against the condensed modal Lagrangian (rigid motions removed) is in the result; the
  // closed form here.
  const System s = read_scene_text(R"(name: free_beam
description: a free-free beam alone at rest
bodies:
  - name: beam
    flexible:
      beam:
        length: 10 m
        axis: z
        mass_per_length: 50
        section: [0.1 m, 0.1 m, 0]
        bending:
          x: {modes: 3, EI: 10000}
          y: {modes: 2, EI: 20000}
        boundary: free-free
joints:
  - name: base
    type: free
    child: beam
run: {duration: 10 s, output_step: 0.1 s}
)", "free_beam.yaml");
  const LinearizeResult r = linearize(s, every_engine());
  CHECK(failed_checks(r) == "");
  CHECK(count(r, "analytic") == 3 * 5);
  for (const EngineLinearModel& m : r.engines) {
    INFO(m.label);
    CHECK(m.zeros == 3);  // the rigid rotation rates
    for (int k = 1; k <= 3; ++k) {
      const double w = std::pow(flex::free_free_root(k), 2) * std::sqrt(1e4 / (50.0 * 1e4));
      CHECK(nearest(m, cd(0, w)) <= kBeamTolerance * w);
    }
    for (int k = 1; k <= 2; ++k) {
      const double w = std::pow(flex::free_free_root(k), 2) * std::sqrt(2e4 / (50.0 * 1e4));
      CHECK(nearest(m, cd(0, w)) <= kBeamTolerance * w);
    }
  }
}

TEST_CASE("linearize: --operating-point equilibrium solves for a spring against a motor and spin turns the spin onto a principal axis") {
  System s = read_scene(test::scene_path("hub_two_panels_spin"));
  s.joints[1].motor_revolute.times = {0.0};
  s.joints[1].motor_revolute.values = {Eigen::Matrix<double, 1, 1>(10.0)};  // N m against 500 N m/rad
  for (const double spin : {0.0, 0.1}) {
    INFO("spin " << spin);
    s.joints[0].w_NB_B0 = Eigen::Vector3d(0, 0, spin);
    LinearizeOptions o = every_engine();
    o.point = OperatingPoint::Neutral;
    CHECK_THROWS_AS(linearize(s, o), InputError);  // the motor is on: not an equilibrium
    o.point = OperatingPoint::Equilibrium;
    if (spin != 0.0) {
      // Deflecting one panel turns the principal axes: the spin about z is no longer steady.
      CHECK_THROWS_WITH(linearize(s, o), Catch::Contains("try --operating-point spin"));
      o.point = OperatingPoint::Spin;
    }
    const LinearizeResult r = linearize(s, o);
    CHECK(failed_checks(r) == "");
    CHECK_THAT(r.how, Catch::Contains("solved for an equilibrium with kane's equations"));
    if (spin != 0.0) CHECK(std::abs(r.op.w_NB_B.x()) + std::abs(r.op.w_NB_B.y()) > 1e-9);  // the axis tilted
    // At rest the spring balances the motor exactly: 10 / 500 rad; spinning, the centrifugal
    // pull on the panel changes it a little.
    if (spin == 0.0) CHECK(r.z0(0) == Approx(0.02).epsilon(1e-10));
    if (spin != 0.0) CHECK(std::abs(r.z0(0) - 0.02) > 1e-6);
    if (spin == 0.0) CHECK(std::abs(r.z0(1)) < 1e-12);  // spinning about a tilted axis, panel2 deflects too
    for (const EngineLinearModel& m : r.engines) CHECK(m.relative_residual <= 1e-9);
  }
  // spin: hub_two_panels starts with a transverse rate (0.01, 0, 0.1) and deflected panels; its
  // spin turned onto the principal axis z keeps |I w0|.
  const System h = read_scene(test::scene_path("hub_two_panels"));
  LinearizeOptions o = every_engine();
  o.point = OperatingPoint::Spin;
  const LinearizeResult r = linearize(h, o);
  CHECK(failed_checks(r) == "");
  CHECK(r.op.w_NB_B.x() == Approx(0).margin(1e-12));
  CHECK(r.op.w_NB_B.y() == Approx(0).margin(1e-12));
  CHECK(r.op.w_NB_B.z() > 0.1);  // |I w0| kept: a bit faster about z than 0.1
  CHECK_THAT(r.how, Catch::Contains("intermediate principal axis"));
}

TEST_CASE("linearize: a gyrostat (dual_spin) keeps its wheel spinning and nutates at the closed form's frequency") {
  // The wheel's angle is cyclic (axisymmetric, CM on its axis, no spring): it is left out of z
  // and its rate kept, so the spin with the wheel at 1000 rpm is a relative equilibrium.
  for (const double rpm : {1000.0, 0.0, -300.0}) {
    INFO("wheel " << rpm << " rpm");
    System s = read_scene(test::scene_path("dual_spin"));
    s.joints[1].rate0 = rpm * 2 * M_PI / 60;
    LinearizeOptions o = every_engine();
    o.point = OperatingPoint::Spin;
    const LinearizeResult r = linearize(s, o);
    CHECK(failed_checks(r) == "");
    CHECK(std::find(r.states.begin(), r.states.end(), "bearing.angle") == r.states.end());
    CHECK(std::find(r.states.begin(), r.states.end(), "bearing.rate") != r.states.end());
    CHECK(r.op.joints[1].rate == Approx(rpm * 2 * M_PI / 60));
    CHECK(count(r, "analytic") == 3);
    for (const EngineLinearModel& m : r.engines) CHECK(m.zeros == 2);  // the spin and the wheel rate
  }
  // A wheel that is not axisymmetric keeps its angle in z, and its spin is no equilibrium: spin
  // (like neutral) stops it; the scene's own spinning state is refused.
  System lopsided = read_scene(test::scene_path("dual_spin"));
  lopsided.bodies[1].I_BBo_B(0, 0) = 0.6;
  LinearizeOptions o = every_engine();
  o.point = OperatingPoint::Spin;
  const LinearizeResult r = linearize(lopsided, o);
  CHECK(failed_checks(r) == "");
  CHECK(std::find(r.states.begin(), r.states.end(), "bearing.angle") != r.states.end());
  CHECK(r.op.joints[1].rate == 0);
  lopsided.joints[0].w_NB_B0 = Eigen::Vector3d(0, 0, 0.05);
  o.point = OperatingPoint::Initial;
  CHECK_THROWS_WITH(linearize(lopsided, o), Catch::Contains("bearing.angle = 104.7"));
}

TEST_CASE("linearize: spin solves the joints and the spin together when a wheel tilts the steady axis") {
  // A bus with a sprung mast (the centrifugal pull deflects it), a sprung spherical head and a
  // reaction wheel at 2000 rpm: the steady spin satisfies w x (I w + h) = 0, not along a principal
  // axis. (Alternating the principal axis with the joints' solve stopped at a relative residual of
  // 7e-10, just inside the 1e-9 allowed; the spin is now solved with the joints.)
  const System s = read_scene_text(R"(# A new user's scene, written from docs/writing-a-scene.md and docs/commands/linearize.md: a
# spinning bus with a sprung telescoping mast (prismatic) carrying a sensor head on a sprung
# spherical mount, and a reaction wheel.
name: mast_probe
description: >
  A 600 kg bus spinning at 0.3 rad/s about z, a 20 kg mast sliding along +x on a spring, a 5 kg
  sensor head on a sprung spherical joint at the mast's tip, a 10 kg reaction wheel about z.
bodies:
  - name: bus
    mass: 600 kg
    inertia: [300, 320, 450]
  - name: mast
    mass: 20 kg
    inertia: [0.1, 2, 2]
  - name: head
    mass: 5 kg
    inertia: [0.05, 0.05, 0.05]
  - name: wheel
    mass: 10 kg
    inertia: [0.2, 0.2, 0.4]
joints:
  - name: base
    type: free
    child: bus
    initial: {angular_velocity: [0, 0, 0.3]}
  - name: slide
    type: prismatic
    parent: bus
    child: mast
    parent_point: [1 m, 0, 0]
    child_point: [-1 m, 0, 0]
    axis: [1, 0, 0]
    spring: {stiffness: 2000 N/m, neutral_position: 0 m}
    damper: {damping: 20 N s/m}
  - name: mount
    type: spherical
    parent: mast
    child: head
    parent_point: [1 m, 0, 0]
    child_point: [-0.1 m, 0, 0]
    spring: {stiffness: 30}
  - name: rw
    type: revolute
    parent: bus
    child: wheel
    parent_point: [0, 0, -0.5 m]
    child_point: [0, 0, 0]
    axis: [0, 0, 1]
    initial: {angle: 0 deg, rate: 2000 rpm}
run:
  duration: 20 s
  output_step: 0.1 s
)", "mast_probe.yaml");
  LinearizeOptions o = every_engine();
  o.point = OperatingPoint::Spin;
  const LinearizeResult r = linearize(s, o);
  CHECK(failed_checks(r) == "");
  CHECK_THAT(r.how, Catch::Contains("and the spin solved"));
  for (const EngineLinearModel& m : r.engines) CHECK(m.relative_residual < 1e-14);
  CHECK(std::abs(r.op.w_NB_B.x()) > 1e-5);  // tilted off z by the wheel and the deflected mast
  CHECK(r.z0(0) > 1e-4);                    // the mast pulled out by the spin
}

// Issue 28: uniform gravity. A pendulum on a held base hangs in equilibrium at -90 deg (gravity
// along -y, the bob at +x at angle 0) and swings at sqrt(m g L / (I + m L^2)), in every engine; on
// an orbit linearize refuses (the attitude relative to the orbit frame is not in z).
TEST_CASE("linearize: iftomm_pendulum hangs at -90 deg and swings at sqrt(m g L / I_pivot) in every "
          "engine") {
  const System s = read_scene(test::scene_path("iftomm_pendulum"));
  LinearizeOptions o = every_engine();
  o.point = OperatingPoint::Equilibrium;
  // Released horizontal, the start is a stationary point of the residual's norm (no first-order
  // change of the gravity torque): the solve restarts either side and keeps the equilibrium of
  // least energy, the hanging one (not the inverted one at +90 deg).
  const LinearizeResult r = linearize(s, o);
  INFO(failed_checks(r) << r.how);
  CHECK(r.how.find("least energy") != std::string::npos);
  CHECK(r.passed());
  REQUIRE(r.op.joints.size() == 2);
  CHECK(std::abs(r.op.joints[1].angle + std::acos(-1.0) / 2) < 1e-9);
  const double m = s.bodies[1].mass, L = 1.0, g = 9.81;
  const double I_pivot = s.bodies[1].I_BBo_B(2, 2) + m * L * L;
  const double w = std::sqrt(m * g * L / I_pivot);
  for (const EngineLinearModel& e : r.engines) {
    INFO(e.label);
    // newton-euler's accelerations carry its constraint solve's rounding times m L^2 / I = 1e6
    // (the near point mass of the benchmark): 5e-10 measured; kane and lagrange 1e-13.
    CHECK(nearest(e, cd(0, w)) <= (e.label == "newton-euler" ? 2e-9 : 1e-10) * w);
  }
}

// Issue 28 on an orbit: the base's attitude relative to the orbit frame and its rate relative to
// it are in z; a lone rigid body turning with the orbit frame has Wie's (2008, Sec. 6.4.2) pitch
// and roll-yaw libration eigenvalues, and the three engines agree.
TEST_CASE("linearize: gg_libration's pitch and roll-yaw librations match the closed forms to 1e-10 in "
          "every engine, and spin is refused on an orbit") {
  const System s = read_scene(test::scene_path("gg_libration"));
  LinearizeOptions o = every_engine();
  o.point = OperatingPoint::Equilibrium;
  const LinearizeResult r = linearize(s, o);
  INFO(failed_checks(r));
  CHECK(r.passed());
  CHECK(count(r, "analytic") == 9);  // 3 frequencies x 3 engines
  const double n = s.environment.mean_motion();
  const Eigen::Matrix3d& I = s.bodies[0].I_BBo_B;
  const double pitch = n * std::sqrt(3 * (I(0, 0) - I(2, 2)) / I(1, 1));
  for (const EngineLinearModel& e : r.engines) CHECK(nearest(e, cd(0, pitch)) <= 1e-10 * pitch);
  // No rigid-body zeros: on an orbit the attitude is not ignorable.
  for (const EngineLinearModel& e : r.engines)
    for (const cd& l : e.eigenvalues) CHECK(std::abs(l) > 0.5 * n);
  o.point = OperatingPoint::Spin;
  CHECK_THROWS_AS(linearize(s, o), InputError);
}

// A stiff spring beside the gravity gradient (n^2 ~ 1e-6 against 20 N m/rad): the equilibrium solve
// damps each coordinate against its own stiffness (Marquardt's scaling); damped against the trace
// it stopped after 40 steps with the attitude still off (residual 2e-8, just inside the bound).
TEST_CASE("linearize: on an orbit a stiff appendage does not stall the attitude's equilibrium solve") {
  const System s = read_scene_text(R"(
name: gg_gimbal_sat
environment:
  central_body: {mu: 398600.4418 km^3/s^2, radius: 6378.137 km}
  orbit: {altitude: 550 km, inclination: 45 deg, raan: 120 deg, argument_of_latitude: 10 deg}
bodies:
  - {name: sat, mass: 200 kg, inertia: [90, 110, 40]}
  - {name: antenna, mass: 15 kg, inertia: [2, 2, 1]}
joints:
  - name: base
    type: free
    child: sat
    initial: {frame: lvlh, attitude: {axis: [1, 0, 0], angle: 1 deg}}
  - {name: mount, type: spherical, parent: sat, child: antenna, parent_point: [0, 0, 0.8],
     child_point: [0, 0, -0.4], spring: {stiffness: 20 N m/rad}}
run: {duration: 10, output_step: 1}
)",
                                   "gg_gimbal_sat.yaml");
  LinearizeOptions o = every_engine();
  o.point = OperatingPoint::Equilibrium;
  const LinearizeResult r = linearize(s, o);
  INFO(r.how << failed_checks(r));
  CHECK(r.passed());
  for (const EngineLinearModel& e : r.engines) CHECK(e.relative_residual < 1e-15);
}

// Each engine linearises its own equations exactly (Engine::accelerations_tangent, output_row_tangent,
// rhs_tangent: its own automatic differentiation or complex step), the finite differences are their
// cross-check (three "jacobian" checks per engine), and the exactness shows: on an orbit the libration eigenvalues equal Wie's closed forms to
// a few units of rounding, where the differences' Jacobian carried 5e-13 of |lambda|.
TEST_CASE("linearize: every engine's A, C and own Jacobian are its own exact tangents, within their finite differences' error, on rigid, spherical, prescribed, flexible, gravity and orbit scenes") {
  struct Point {
    const char* scene;
    OperatingPoint point;
    double t = 0;
  };
  const Point points[] = {{"gg_libration", OperatingPoint::Equilibrium},
                          {"boom_on_orbit", OperatingPoint::Equilibrium},
                          {"pointing_flex", OperatingPoint::Neutral, 10},
                          {"hub_nodal_panel", OperatingPoint::Spin},
                          {"spinup_beam_linear", OperatingPoint::Spin},
                          {"iftomm_pendulum", OperatingPoint::Equilibrium},
                          {"spear1_case1_spherical", OperatingPoint::Spin},
                          {"chain5", OperatingPoint::Spin},
                          {"dual_spin", OperatingPoint::Spin},
                          {"hub_two_panels_spin", OperatingPoint::Neutral},
                          // At rest under gravity: |H| = 0, where it has no derivative (every
                          // engine's C must stay finite there: kane's was 0/0).
                          {"tests/harness/scenes/hanging_gimbal.yaml", OperatingPoint::Equilibrium},
                          {"tests/harness/scenes/telescope_gimbal.yaml", OperatingPoint::Spin}};
  for (const Point& p : points) {
    INFO(p.scene);
    const std::string name = p.scene;
    const System s = read_scene(name.ends_with(".yaml") ? test::source_dir() + "/" + name : test::scene_path(name));
    LinearizeOptions o = every_engine();
    o.point = p.point;
    o.time = p.t;
    // Every pinned output column (joint loads, momentum, energy, positions; on an orbit the
    // attitude relative to the orbit frame and the Jacobi integral): C exact too.
    o.outputs = pinned_columns(s);
    o.outputs.erase(o.outputs.begin());  // t
    const LinearizeResult r = linearize(s, o);
    CHECK(failed_checks(r) == "");
    // A, C and the engine's own Jacobian: three cross-checks per engine.
    CHECK(count(r, "jacobian") == 3 * static_cast<int>(r.engines.size()));
    for (const EngineLinearModel& m : r.engines) {
      INFO(m.label);
      for (const MatrixMethod* how : {&m.a_method, &m.c_method, &m.own_method}) {
        CHECK(how->exact);
        CHECK(how->worst.exact == how->worst.exact);  // not NaN
        CHECK(how->fd_difference <= 100 * how->fd_error + 1e-9 * (how == &m.a_method   ? m.A
                                                                  : how == &m.c_method ? m.C
                                                                                       : m.own_A)
                                                                         .cwiseAbs()
                                                                         .maxCoeff());
      }
      CHECK(m.A.allFinite());
      CHECK(m.C.allFinite());
      CHECK(m.own_A.allFinite());
      // The cross-check can fail: its bound is the differences' own error estimate (x 100), which
      // is far below |A|.
      CHECK(m.a_method.fd_error < 1e-9 * m.A.lpNorm<Eigen::Infinity>());
    }
    if (std::string(p.scene) == "gg_libration")
      for (const LinearCheck& c : r.checks)
        if (c.kind == "analytic") {
          INFO(c.what << " " << c.engine_a);
          CHECK(c.error <= 1e-13 * std::abs(c.b));
        }
  }
}

namespace {
// A test double: a real engine whose exact tangents are wrong in one place (A: joint 1's acceleration
// by one part in 1e6; C: one output column's derivative along joint 1's coordinate and rate by 1e-4,
// 6e-8 of C's largest entry (d|H|/d hub.wz = 1567 on hub_two_panels_spin); own A: the last
// state's rate along the first state by 1e-4), every other call passed
// through. Each cross-check must catch its own.
class WrongTangent final : public Engine {
 public:
  enum class Which { A, C, Own, CNaN };
  WrongTangent(std::unique_ptr<Engine> inner, Which which) : inner_(std::move(inner)), which_(which) {}
  const char* name() const override { return inner_->name(); }
  int state_size() const override { return inner_->state_size(); }
  std::string state_label(int i) const override { return inner_->state_label(i); }
  void pack(const TreeState& s, double* x) override { inner_->pack(s, x); }
  void rhs(double t, const double* x, double* xdot) override { inner_->rhs(t, x, xdot); }
  void accelerations(double t, const double* x, TreeAccel& a) override { inner_->accelerations(t, x, a); }
  const OutputLayout& layout() const override { return inner_->layout(); }
  void output_row(double t, const double* x, double* row) override { inner_->output_row(t, x, row); }
  bool accelerations_tangent(double t, const TreeState& s, const TreeTangent& ds, TreeAccel& a, TreeAccel& da) override {
    const bool ok = inner_->accelerations_tangent(t, s, ds, a, da);
    if (ok && which_ == Which::A) da.angle_ddot[1] *= 1 + 1e-6;
    return ok;
  }
  bool output_row_tangent(double t, const TreeState& s, const TreeTangent& ds, double* row, double* drow) override {
    const bool ok = inner_->output_row_tangent(t, s, ds, row, drow);
    // Along joint 1's coordinate and rate only: a whole row scaled would keep a zero transfer
    // function zero.
    if (ok && which_ == Which::C) drow[column_] += c_offset_ * (ds.joints[1].angle + ds.joints[1].rate);
    if (ok && which_ == Which::CNaN) drow[column_] = std::numeric_limits<double>::quiet_NaN();
    return ok;
  }
  bool rhs_tangent(double t, const double* x, const double* dx, double* xdot, double* dxdot) override {
    const bool ok = inner_->rhs_tangent(t, x, dx, xdot, dxdot);
    if (ok && which_ == Which::Own) dxdot[state_size() - 1] += 1e-4 * dx[0];
    return ok;
  }
  std::size_t column_ = 0;
  double c_offset_ = 1e-4;

 private:
  std::unique_ptr<Engine> inner_;
  Which which_;
};
}  // namespace

// The cross-checks can fail: an engine whose A, C or own Jacobian is off by 1e-6 in one entry
// (far below what would move an eigenvalue visibly) fails its own "jacobian" check, which names
// the entry; the other engines and the other matrices pass.
TEST_CASE("linearize: a wrong exact tangent (A, C or the engine's own Jacobian) fails its cross-check against its differences, naming the entry") {
  const System s = read_scene(test::scene_path("hub_two_panels_spin"));
  const std::vector<std::string> columns = pinned_columns(s);
  const auto H = static_cast<std::size_t>(std::find(columns.begin(), columns.end(), "H") - columns.begin());
  REQUIRE(H < columns.size());
  struct Case {
    WrongTangent::Which which;
    const char* says;
  };
  const Case cases[] = {{WrongTangent::Which::A, "A exact vs its finite differences, entry d/dt hinge1.rate"},
                        {WrongTangent::Which::C, "C exact vs its finite differences, entry d H"},
                        {WrongTangent::Which::Own, "own-coordinate A exact vs its finite differences"}};
  for (const std::string& engine : engine_names())
    for (const Case& c : cases) {
      INFO(engine << ": " << c.says);
      LinearizeOptions o = every_engine();
      o.point = OperatingPoint::Neutral;
      o.outputs = {"H", "E", "hinge1.Mx"};
      LinearEngineChoice wrong(engine + "*wrong", engine);
      wrong.factory = [&, which = c.which](const System& sys, const EngineOptions& opt) -> std::unique_ptr<Engine> {
        auto w = std::make_unique<WrongTangent>(make_engine(engine, sys, opt), which);
        w->column_ = H;
        return w;
      };
      o.engines.push_back(wrong);
      const LinearizeResult r = linearize(s, o);
      // Exactly one failed cross-check, the wrong engine's, at the wrong entry. A wrong A moves
      // the eigenvalues too (by ~1e-6 relative: the eigenvalue checks fail as well); a wrong C or
      // own Jacobian moves nothing else.
      int jacobian_failed = 0, other_failed = 0;
      for (const LinearCheck& k : r.checks) {
        if (k.passed) continue;
        if (k.kind != "jacobian") {
          ++other_failed;
          CHECK(c.which == WrongTangent::Which::A);
          CHECK((k.engine_a == engine + "*wrong" || k.engine_b == engine + "*wrong"));
          continue;
        }
        ++jacobian_failed;
        CHECK(k.engine_a == engine + "*wrong");
        CHECK_THAT(k.what, Catch::Contains(c.says));
      }
      CHECK(jacobian_failed == 1);
      CHECK_FALSE(r.passed());
    }
  // A tangent with a NaN (an engine's 0/0) is not adopted: C stays the differences', finite, and
  // says so; nothing fails.
  for (const std::string& engine : engine_names()) {
    INFO(engine);
    LinearizeOptions o;
    o.point = OperatingPoint::Neutral;
    o.outputs = {"H", "E", "hinge1.Mx"};
    LinearEngineChoice nan(engine + "*nan", engine);
    nan.factory = [&](const System& sys, const EngineOptions& opt) -> std::unique_ptr<Engine> {
      auto w = std::make_unique<WrongTangent>(make_engine(engine, sys, opt), WrongTangent::Which::CNaN);
      w->column_ = H;
      return w;
    };
    o.engines = {nan};
    const LinearizeResult r = linearize(s, o);
    REQUIRE(r.engines.size() == 1);
    CHECK_FALSE(r.engines[0].c_method.exact);
    CHECK(r.engines[0].a_method.exact);
    CHECK(r.engines[0].C.allFinite());
    CHECK(r.passed());
    CHECK_THAT(format_linearization(r), Catch::Contains("C by finite differences"));
  }
}

// A user's scene (docs/writing-a-scene.md): a slowly turning bus, a sprung telescoping mast (a
// prismatic joint) and a sprung two-axis gimbal with a motor. |H| cannot move under an internal
// motor (C_H A = 0 and C_H B = 0), so its transfer functions are zero: a cancellation of terms of
// about |C_H| |X| ~ 1, which failed against a bound of 1e-14 of the largest |G| (2.1e-12 vs
// 3.3e-15). The bound now carries each engine's rounding and its matrices' errors per pair
// (transfer_allowance); it stays far below what a wrong entry of C_H moves (tests/harness/scenes/
// telescope_gimbal.yaml).
TEST_CASE("linearize: a transfer function that a conservation law makes zero passes at rounding, and a wrong output row still fails it") {
  const System s = crossdyn::read_scene(crossdyn::test::source_dir() + "/tests/harness/scenes/telescope_gimbal.yaml");
  LinearizeOptions o = every_engine();
  o.point = OperatingPoint::Spin;
  o.outputs = {"slider.Fx", "gimbal.angle1", "H"};
  const LinearizeResult r = linearize(s, o);
  INFO(failed_checks(r));
  CHECK(r.passed());
  int zero_pairs = 0;
  for (const LinearCheck& c : r.checks)
    if (c.kind == "transfer" && c.what.starts_with("H <- ")) {
      INFO(c.what << ": " << c.engine_a << " " << c.a << " vs " << c.engine_b << " " << c.b << ", bound " << c.bound);
      CHECK(std::abs(c.a) < 1e-10);
      CHECK(c.bound < 1e-7);
      ++zero_pairs;
    }
  CHECK(zero_pairs == 2 * (static_cast<int>(r.engines.size()) - 1));

  // kane's C row of H off by 1e-4 along the slider's position and rate (a few 1e-6 of the row's
  // largest entry): |H| <- gimbal.motor1 is then no longer zero, and fails.
  const std::vector<std::string> columns = pinned_columns(s);
  const auto H = static_cast<std::size_t>(std::find(columns.begin(), columns.end(), "H") - columns.begin());
  LinearizeOptions w = o;
  w.engines.at(0).factory = [H](const System& sys, const EngineOptions& opt) -> std::unique_ptr<Engine> {
    auto e = std::make_unique<WrongTangent>(make_engine("kane", sys, opt), WrongTangent::Which::C);
    e->column_ = H;
    return e;
  };
  const LinearizeResult bad = linearize(s, w);
  int transfer_failed = 0;
  for (const LinearCheck& c : bad.checks)
    if (c.kind == "transfer" && !c.passed) {
      CHECK(c.what.starts_with("H <- gimbal.motor"));
      ++transfer_failed;
    }
  CHECK(transfer_failed >= 1);
}
