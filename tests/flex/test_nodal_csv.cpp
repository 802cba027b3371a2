// Nodal data files (core/flex/nodal_csv.hpp): the round trip beam generator => CSV writer =>
// reader, the example file of scenarios/data/, and one case per class of bad input, each message
// checked for its file:line:column, the column it names and what is wrong.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <string>

#include "core/errors.hpp"
#include "core/flex/beam.hpp"
#include "core/flex/nodal_csv.hpp"
#include "tests/support/paths.hpp"

using namespace crossdyn;
using namespace crossdyn::flex;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;

namespace {

BeamSpec spec(int axis, BeamBoundary boundary) {
  BeamSpec s;
  s.length = 5;
  s.axis = axis;
  s.mass_per_length = 4;
  s.section = {0.05, 0.05, 0.05};
  s.section[static_cast<std::size_t>(axis)] = 0;
  for (int d = 0; d < 3; ++d)
    if (d != axis) s.bending[static_cast<std::size_t>(d)] = BeamPlane{2, 100.0 + 50 * d};
  s.boundary = boundary;
  s.slices = 12;
  s.damping.kind = BeamDamping::Kind::Ratio;
  s.damping.ratios = {0.01};
  return s;
}

// The message of reading the two texts ("(no error)" when they are read).
std::string error_of(const std::string& nodes, const std::string& modes,
                     const std::string& modes_label = "m.csv") {
  try {
    read_nodal_csv_text(nodes, "n.csv", modes, modes_label);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

// A valid pair: five nodes in the x-z plane, one mode (a translation-free, rotation-free bending shape).
const std::string kHeader = "name,mass,x,y,z,q1.ux,q1.uy,q1.uz,q1.rx,q1.ry,q1.rz\n";
const std::string kRows =
    "a,1,0,0,-1,1,0,0,0,1,0\n"
    "b,2,0,0,0,-1,0,0,0,0,0\n"
    "c,1,0,0,1,1,0,0,0,-1,0\n"
    "d,1,1,0,0,0,0,0,0,0,0\n"
    "e,1,-1,0,0,0,0,0,0,0,0\n";
const std::string kModes = "mode,frequency_hz,damping_ratio\nq1,2,0.01\n";

}  // namespace

TEST_CASE("nodal CSV round trip: beam generator => writer => reader gives the same body, bit for bit but the CM shift") {
  for (int axis = 0; axis < 3; ++axis)
    for (BeamBoundary b : {BeamBoundary::FreeFree, BeamBoundary::ClampedBottom}) {
      INFO("axis " << axis << ", boundary " << static_cast<int>(b));
      const FlexModel beam = make_beam(spec(axis, b), "beam");
      const NodalCsv csv = write_nodal_csv(beam.flex);
      const FlexModel back = read_nodal_csv_text(csv.nodes, "n.csv", csv.modes, "m.csv");
      const FlexBody& f = beam.flex;
      const FlexBody& g = back.flex;
      CHECK(g.mode_names == f.mode_names);
      CHECK(g.K == f.K);
      CHECK(g.D == f.D);
      REQUIRE(g.nodes.size() == f.nodes.size());
      for (std::size_t i = 0; i < f.nodes.size(); ++i) {
        INFO("node " << f.nodes[i].name);
        CHECK(g.nodes[i].name == f.nodes[i].name);
        CHECK(g.nodes[i].mass == f.nodes[i].mass);
        // positions: shifted by the nodes' CM as the file gives it, which is the generator's
        // rounding (|p_RoBo_R| ~ 2e-17 m), so the same to an ulp of the largest coordinate
        CHECK(g.nodes[i].p_BoNi_B == f.nodes[i].p_BoNi_B - back.p_RoBo_R);
        CHECK(g.nodes[i].J_Ni_B == f.nodes[i].J_Ni_B);
        CHECK(g.nodes[i].Phi_B == f.nodes[i].Phi_B);
        CHECK(g.nodes[i].Psi_B == f.nodes[i].Psi_B);
      }
      CHECK(back.mass == beam.mass);
      CHECK(back.I_BBo_B == beam.I_BBo_B);
      CHECK(back.p_RoBo_R.norm() <= 1e-16);
    }
}

TEST_CASE("the example panel files read, shifted to their CM, and match the beam generator's panel") {
  const std::string dir = test::source_dir() + "/scenarios/data/";
  const FlexModel panel = read_nodal_csv(dir + "panel_nodes.csv", dir + "panel_modes.csv");
  CHECK(panel.flex.mode_names == std::vector<std::string>{"m1", "m2", "m3"});
  CHECK(panel.flex.nodes.size() == 12);
  CHECK(panel.mass == 20);
  CHECK(std::abs(panel.p_RoBo_R.y() - 2.5) < 1e-15);  // the root frame's origin is 2.5 m inboard
  CHECK(panel.flex.nodes.front().name == "root");
  CHECK(std::abs(panel.flex.nodes.front().p_BoNi_B.y() + 2.5) < 1e-15);
  // f_1 of a cantilever 5 m, 4 kg/m, EI from the frequency: the K the reader builds gives it back.
  const double M1 = [&] {
    double m = 0;
    for (const FlexNode& n : panel.flex.nodes) m += n.mass * n.Phi_B.col(0).squaredNorm();
    return m;
  }();
  const double f1 = std::sqrt(panel.flex.K(0, 0) / M1) / (2 * std::numbers::pi);
  CHECK(std::abs(f1 - 0.5005135940402592) < 1e-15);
  CHECK(panel.flex.D(0, 0) == Approx(2 * 0.005 * 2 * std::numbers::pi * 0.5005135940402592 * M1)
                                  .epsilon(1e-14));
}

TEST_CASE("nodal CSV: a valid small file reads, K from frequencies, D from damping ratios") {
  REQUIRE(error_of(kHeader + kRows, kModes) == "(no error)");
  const FlexModel m = read_nodal_csv_text(kHeader + kRows, "n.csv", kModes, "m.csv");
  CHECK(m.mass == 6);
  CHECK(m.flex.K(0, 0) == Approx(std::pow(4 * std::numbers::pi, 2) * 4).epsilon(1e-15));
  // comments, blank lines, CRLF and spaces around fields are accepted
  CHECK(error_of("# c\n\n" + kHeader + " a , 1 ,0,0,-1,1,0,0,0,1,0\r\nb,2,0,0,0,-1,0,0,0,0,0\n"
                 "c,1,0,0,1,1,0,0,0,-1,0\nd,1,1,0,0,0,0,0,0,0,0\ne,1,-1,0,0,0,0,0,0,0,0\n",
                 kModes) == "(no error)");
}

TEST_CASE("nodal CSV bad input: the file's structure") {
  CHECK(error_of("# only a comment\n", kModes) ==
        "n.csv: no header line (the file is empty or all comments)");
  CHECK(error_of(kHeader, kModes) == "n.csv: no nodes (the file has a header but no rows)");
  CHECK_THAT(error_of("name,mass,x,y,z,q1.ux,q1.uy,q1.uz,q1.rx,q1.ry,q1.rz,colour\n" + kRows, kModes),
             StartsWith("n.csv:1:53: unknown column 'colour'"));
  CHECK(error_of("name,x,y,z\na,0,0,0\n", "") == "n.csv:1:11: missing column 'mass'");
  CHECK_THAT(error_of("name,mass,x,y,z,x\na,1,0,0,0,0\n", ""),
             StartsWith("n.csv:1:17: duplicate column 'x' (first at column 11)"));
  CHECK_THAT(error_of("name,mass,x,y,z,Jxx\na,1,0,0,0,0\n", ""),
             StartsWith("n.csv:1:17: column 'Jxx' without 'Jyz': give all six J columns"));
  CHECK_THAT(error_of("name,mass,x,y,z,q1.ux,q1.uy,q1.uz,q1.rx,q1.ry\na,1,0,0,0,0,0,0,0,0\n", kModes),
             StartsWith("n.csv:1:46: mode 'q1' has no column 'q1.rz'"));
  CHECK_THAT(error_of("name,mass,x,y,z,q1.ux,q1.uy,q1.uz,q1.rx,q1.ry,q1.vz\n" + kRows, kModes),
             StartsWith("n.csv:1:47: column 'q1.vz': unknown component 'vz' of mode 'q1'"));
  CHECK_THAT(error_of("name,mass,x,y,z,,q1.ux\n", kModes),
             StartsWith("n.csv:1:17: empty column name in the header"));
}

TEST_CASE("nodal CSV bad input: rows and values") {
  const std::string h = kHeader;
  CHECK(error_of(h + "a,1,0,0,-1,1,0,0,0,1\n", kModes) ==
        "n.csv:2:21: this row has 10 fields, the header 11: column 'q1.rz' is missing");
  CHECK(error_of(h + "a,1,0,0,-1,1,0,0,0,1,0,7\n", kModes) ==
        "n.csv:2:24: this row has 12 fields, the header 11: extra field '7'");
  CHECK(error_of(h + "a,1,,0,-1,1,0,0,0,1,0\n", kModes) == "n.csv:2:5: column 'x': empty value");
  CHECK(error_of(h + "a,1,0,0,-1,1,0,0,0,one,0\n", kModes) ==
        "n.csv:2:20: column 'q1.ry': expected a number, found 'one'");
  CHECK(error_of(h + "a,1,0,0,-1,inf,0,0,0,1,0\n", kModes) ==
        "n.csv:2:12: column 'q1.ux': non-finite or out-of-range number 'inf'");
  CHECK(error_of(h + "a,1,0,0,-1,1e400,0,0,0,1,0\n", kModes) ==
        "n.csv:2:12: column 'q1.ux': non-finite or out-of-range number '1e400'");
  CHECK_THAT(error_of(h + "a,1,0,0,1e13,1,0,0,0,1,0\n", kModes),
             StartsWith("n.csv:2:9: column 'z': absurd value 1e+13"));
  CHECK(error_of(h + "a,-1,0,0,-1,1,0,0,0,1,0\n", kModes) ==
        "n.csv:2:3: column 'mass': negative mass -1 kg (a node's mass is >= 0)");
  CHECK_THAT(error_of(h + "a,0,0,0,-1,1,0,0,0,1,0\n", kModes),
             Contains("n.csv: the nodes' total mass is zero"));
  CHECK(error_of(h + "a,1,0,0,-1,1,0,0,0,1,0\na,1,0,0,1,1,0,0,0,1,0\n", kModes) ==
        "n.csv:3:1: column 'name': duplicate node name 'a' (first on line 2)");
  CHECK_THAT(error_of(h + "1a,1,0,0,-1,1,0,0,0,1,0\n", kModes), StartsWith("n.csv:2:1: column 'name': "));
  CHECK_THAT(error_of(h + "\"a\",1,0,0,-1,1,0,0,0,1,0\n", kModes),
             StartsWith("n.csv:2:1: quoted fields are not supported"));
  CHECK_THAT(error_of(h + "a,1,0,0,-1,1,0\x01,0,0,1,0\n", kModes),
             StartsWith("n.csv:2:15: control character 1"));
  CHECK_THAT(error_of(h + "\xc3\xa9,1,0,0,-1,1,0,0,0,1,0\n", kModes),
             StartsWith("n.csv:2:1: non-ASCII character"));
  // a node inertia that no body has (Jxx + Jyy < Jzz)
  CHECK_THAT(error_of("name,mass,x,y,z,Jxx,Jyy,Jzz,Jxy,Jxz,Jyz\na,1,0,0,0,1,1,3,0,0,0\n", ""),
             StartsWith("n.csv:2:11: columns Jxx ... Jyz of node 'a': "));
}

TEST_CASE("nodal CSV bad input: the modes file and K, D") {
  const std::string n = kHeader + kRows;
  CHECK(error_of(n, "", "") == "n.csv: the file has 1 modes but no modes file gives their stiffness");
  CHECK(error_of(n, "mode,frequency_hz\nq2,2\n") ==
        "m.csv:2:1: column 'mode': 'q2' but the nodes file's mode 1 is 'q1' (one row per mode, in "
        "the nodes file's order)");
  CHECK(error_of(n, "mode,frequency_hz\n") ==
        "m.csv: 0 rows for the nodes file's 1 modes: mode 'q1' has no row");
  CHECK(error_of(n, "mode,frequency_hz\nq1,2\nq1,3\n") ==
        "m.csv:3:1: more rows than the nodes file's 1 modes");
  CHECK(error_of(n, "mode,frequency_hz\nq1,-2\n") ==
        "m.csv:2:4: column 'frequency_hz': negative frequency -2 Hz");
  CHECK(error_of(n, "mode,frequency_hz,damping_ratio\nq1,2,-0.1\n") ==
        "m.csv:2:6: column 'damping_ratio': negative damping ratio -0.1");
  CHECK(error_of(n, "mode\nq1\n") ==
        "m.csv:1:5: no stiffness: give the column frequency_hz or the columns K.<mode>");
  CHECK_THAT(error_of(n, "mode,frequency_hz,K.q1\nq1,2,3\n"),
             StartsWith("m.csv:1:6: column 'frequency_hz' and K.<mode> columns"));
  CHECK_THAT(error_of(n, "mode,K.q9\nq1,2\n"),
             StartsWith("m.csv:1:6: column 'K.q9': 'q9' is not a mode of the nodes file"));
  CHECK_THAT(error_of(n, "mode,K.q1,damping_ratio\nq1,2,0.1\n"),
             StartsWith("m.csv:1:11: column 'damping_ratio' goes with 'frequency_hz'"));
  CHECK_THAT(error_of(n, "mode,period\nq1,2\n"), StartsWith("m.csv:1:6: unknown column 'period'"));
  // K not positive semi-definite, K not symmetric (two modes)
  CHECK_THAT(error_of(n, "mode,K.q1\nq1,-5\n"), StartsWith("m.csv: K "));
  const std::string two =
      "name,mass,x,y,z,p.ux,p.uy,p.uz,p.rx,p.ry,p.rz,q.ux,q.uy,q.uz,q.rx,q.ry,q.rz\n"
      "a,1,0,0,-1,1,0,0,0,1,0,0,1,0,-1,0,0\n"
      "b,2,0,0,0,-1,0,0,0,0,0,0,-1,0,0,0,0\n"
      "c,1,0,0,1,1,0,0,0,-1,0,0,1,0,1,0,0\n"
      "d,1,1,0,0,0,0,0,0,0,0,0,0,0,0,0,0\n"
      "e,1,-1,0,0,0,0,0,0,0,0,0,0,0,0,0,0\n";
  CHECK(error_of(two, "mode,K.p,K.q\np,4,1\nq,2,4\n") ==
        "m.csv:3:3: column 'K.p': K(q, p) = 2 differs from K(p, q) = 1 (line 2): K must be "
        "symmetric");
  CHECK(error_of(two, "mode,K.p,K.q\np,4,1\nq,1,4\n") == "(no error)");
}

TEST_CASE("nodal CSV bad input: size limits against hostile files") {
  // bytes
  const std::string huge(kMaxNodalFileBytes + 1, '#');
  CHECK(error_of(huge, kModes) == "n.csv: the file is larger than 64 MiB");
  // modes (so columns): one mode more than kMaxModes
  std::string header = "name,mass,x,y,z";
  for (int m = 0; m <= kMaxModes; ++m)
    for (const char* c : {"ux", "uy", "uz", "rx", "ry", "rz"})
      header += ",m" + std::to_string(m) + "." + c;
  CHECK_THAT(error_of(header + "\n", ""),
             StartsWith("n.csv:1:") && Contains("more than 1000 modes (column 'm1000.ux')"));
  // rows: one more than kMaxNodes
  std::string rows = "name,mass,x,y,z\n";
  rows.reserve(rows.size() + 12 * (kMaxNodes + 1));
  for (std::size_t i = 0; i <= kMaxNodes; ++i) rows += "n,1,0,0,0\n";
  CHECK(error_of(rows, "", "") ==
        "n.csv:" + std::to_string(kMaxNodes + 2) + ":1: more than " + std::to_string(kMaxNodes) +
            " rows");
}

TEST_CASE("nodal CSV files: missing files are named") {
  CHECK_THROWS_WITH(read_nodal_csv("/nonexistent/n.csv", ""), "/nonexistent/n.csv: no such file");
}

// Every nodal_csv_fuzzer regression input (fuzz/nodal_regressions/: the nodes text, a line "%%",
// the modes text) is read or refused with InputError; one it reads survives the writer and the
// reader again, so the body a user's files give is one crossdyn can write back.
TEST_CASE("class: a nodal file the reader accepts reads back from what the writer writes (fuzz regressions)") {
  const std::filesystem::path dir = std::filesystem::path(test::source_dir()) / "fuzz" / "nodal_regressions";
  REQUIRE(std::filesystem::exists(dir));
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    std::ifstream in(e.path(), std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::size_t sep = text.find("\n%%\n");
    const std::string nodes = sep == std::string::npos ? text : text.substr(0, sep + 1);
    const std::string modes = sep == std::string::npos ? std::string() : text.substr(sep + 4);
    INFO(e.path().string());
    ++files;
    try {
      const FlexModel m = read_nodal_csv_text(nodes, "n.csv", modes, modes.empty() ? "" : "m.csv");
      const NodalCsv w = write_nodal_csv(m.flex);
      CHECK_NOTHROW(read_nodal_csv_text(w.nodes, "n.csv", w.modes, w.modes.empty() ? "" : "m.csv"));
    } catch (const InputError& err) {
      const std::string what = err.what();
      CHECK((what.rfind("n.csv", 0) == 0 || what.rfind("m.csv", 0) == 0));
    }
  }
  CHECK(files >= 1);
  // The finding itself: 8.7 Hz on a mode shape of 1e11 gave K = 3.6e27, refused at its frequency.
  std::ifstream in(dir / "stiffness-from-frequency-above-1e18.txt", std::ios::binary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t sep = text.find("\n%%\n");
  REQUIRE(sep != std::string::npos);
  try {
    (void)read_nodal_csv_text(text.substr(0, sep + 1), "n.csv", text.substr(sep + 4), "m.csv");
    FAIL("accepted");
  } catch (const InputError& err) {
    CHECK_THAT(err.what(), Catch::Contains("column 'frequency_hz'") && Catch::Contains("above 1e18"));
  }
}
