// The output layout (core/output_layout.hpp): the pinned columns' names, order, kinds and units,
// and the row writer's conventions.
#include <catch2/catch.hpp>

#include "core/output_layout.hpp"

#include <cmath>

using namespace crossdyn;

namespace {

// A base with a revolute child, a spherical grandchild, a fixed great-grandchild, and a flexible
// body with two modes.
System example() {
  System s;
  for (const char* n : {"hub", "arm", "ball", "tip", "beam"}) {
    Body b;
    b.name = n;
    b.mass = 1;
    b.I_BBo_B = Eigen::Matrix3d::Identity();
    s.bodies.push_back(b);
  }
  s.bodies[4].flex = FlexBody{};
  s.bodies[4].flex->mode_names = {"q1", "q2"};
  auto joint = [&s](const char* n, JointType t, int parent, int child) {
    Joint j;
    j.name = n;
    j.type = t;
    j.parent = parent;
    j.child = child;
    s.joints.push_back(j);
  };
  joint("base", JointType::Free, -1, 0);
  joint("hinge", JointType::Revolute, 0, 1);
  joint("ballj", JointType::Spherical, 1, 2);
  joint("weld", JointType::Fixed, 2, 3);
  joint("beamj", JointType::Revolute, 0, 4);
  return s;
}

}  // namespace

TEST_CASE("the pinned columns: t, bodies (w then q), joints, modes, H, E, then positions, loads, power") {
  const System s = example();
  OutputLayout layout(s);
  std::vector<std::string> expected{"t"};
  for (const char* b : {"hub", "arm", "ball", "tip", "beam"})
    for (const char* c : {".wx", ".wy", ".wz", ".qw", ".qx", ".qy", ".qz"}) expected.push_back(std::string(b) + c);
  for (const char* c : {"hinge.angle", "hinge.rate", "ballj.wx", "ballj.wy", "ballj.wz", "beamj.angle",
                        "beamj.rate", "beam.q1", "beam.q2", "beam.q1_rate", "beam.q2_rate", "H", "E"})
    expected.push_back(c);
  // Issue 26: positions, CM, momentum vector, every joint's loads but the free one's, P, M.
  for (const char* b : {"hub", "arm", "ball", "tip", "beam"})
    for (const char* c : {".x", ".y", ".z"}) expected.push_back(std::string(b) + c);
  for (const char* c : {"CMx", "CMy", "CMz", "Hx", "Hy", "Hz"}) expected.push_back(c);
  for (const char* j : {"hinge", "ballj", "weld", "beamj"})
    for (const char* c : {".Fx", ".Fy", ".Fz", ".Mx", ".My", ".Mz"}) expected.push_back(std::string(j) + c);
  for (const char* c : {"P", "Mx", "My", "Mz"}) expected.push_back(c);
  CHECK(layout.names() == expected);
  CHECK(pinned_columns(s) == expected);
  CHECK(layout.pinned_size() == expected.size());

  const int extra = layout.add_extra("engine.thing", "J");
  CHECK(extra == static_cast<int>(expected.size()));
  CHECK(layout.pinned_size() == expected.size());
  CHECK(layout.columns().back().kind == ColumnKind::Extra);

  // Kinds, owners and units of a few columns.
  const auto& c = layout.columns();
  CHECK(c[static_cast<std::size_t>(layout.body_w(1)) + 1].kind == ColumnKind::BodyW);
  CHECK(c[static_cast<std::size_t>(layout.body_w(1)) + 1].body == 1);
  CHECK(c[static_cast<std::size_t>(layout.body_w(1)) + 1].unit == "rad/s");
  CHECK(c[static_cast<std::size_t>(layout.body_q(2))].name == "ball.qw");
  CHECK(c[static_cast<std::size_t>(layout.joint_first(1))].kind == ColumnKind::JointCoordinate);
  CHECK(c[static_cast<std::size_t>(layout.joint_first(2)) + 2].name == "ballj.wz");
  CHECK(c[static_cast<std::size_t>(layout.joint_first(2)) + 2].joint == 2);
  CHECK(layout.joint_first(3) == -1);  // a fixed joint has no columns
  CHECK(layout.modal_first(0) == -1);
  CHECK(c[static_cast<std::size_t>(layout.modal_first(4)) + 3].name == "beam.q2_rate");
  CHECK(c[static_cast<std::size_t>(layout.modal_first(4)) + 3].kind == ColumnKind::ModalRate);
  CHECK(c[static_cast<std::size_t>(layout.modal_first(4)) + 3].component == 1);
  CHECK(c[static_cast<std::size_t>(layout.H())].name == "H");
  CHECK(c[static_cast<std::size_t>(layout.E())].unit == "J");
  CHECK(layout.joint_load(0) == -1);  // the free joint carries no load
  CHECK(c[static_cast<std::size_t>(layout.joint_load(3)) + 4].name == "weld.My");
  CHECK(c[static_cast<std::size_t>(layout.joint_load(3)) + 4].kind == ColumnKind::JointMoment);
  CHECK(c[static_cast<std::size_t>(layout.joint_load(3)) + 4].unit == "N m");
  CHECK(c[static_cast<std::size_t>(layout.joint_load(3)) + 4].joint == 3);
  CHECK(c[static_cast<std::size_t>(layout.body_position(2)) + 2].name == "ball.z");
  CHECK(c[static_cast<std::size_t>(layout.P())].unit == "W");
}

TEST_CASE("the row writer puts values where the layout says, with qw >= 0, and NaN where none") {
  const System s = example();
  const OutputLayout layout(s);
  std::vector<double> row(layout.size());
  RowWriter out(layout, row.data());
  out.time(1.5);
  // q and -q: the writer keeps the one with a non-negative scalar part.
  const Eigen::Quaterniond q(-0.5, 0.5, -0.5, 0.5);
  out.body(1, Eigen::Vector3d(1, 2, 3), q);
  out.revolute(1, 0.25, -0.5);
  out.spherical(2, Eigen::Vector3d(7, 8, 9));
  out.modal(4, Eigen::Vector2d(0.1, 0.2), Eigen::Vector2d(-0.1, -0.2));
  out.momentum(Eigen::Vector3d(0, 3, 4));
  out.energy(12);
  out.body_position(2, Eigen::Vector3d(-1, -2, -3));
  out.system_cm(Eigen::Vector3d(0.5, 0.25, 0.125));
  out.joint_load(3, Eigen::Vector3d(21, 22, 23), Eigen::Vector3d(24, 25, 26));
  out.power(-7);
  out.external_moment(Eigen::Vector3d(31, 32, 33));
  auto at = [&](const std::string& name) {
    const auto& n = layout.names();
    return row[static_cast<std::size_t>(std::find(n.begin(), n.end(), name) - n.begin())];
  };
  CHECK(at("t") == 1.5);
  CHECK(at("arm.wy") == 2);
  CHECK(at("arm.qw") == 0.5);
  CHECK(at("arm.qx") == -0.5);
  CHECK(at("arm.qz") == -0.5);
  CHECK(at("hinge.angle") == 0.25);
  CHECK(at("hinge.rate") == -0.5);
  CHECK(at("ballj.wz") == 9);
  CHECK(at("beam.q2") == 0.2);
  CHECK(at("beam.q1_rate") == -0.1);
  CHECK(at("H") == 5);
  CHECK(at("Hy") == 3);
  CHECK(at("E") == 12);
  CHECK(at("ball.z") == -3);
  CHECK(at("CMy") == 0.25);
  CHECK(at("weld.Fx") == 21);
  CHECK(at("weld.Mz") == 26);
  CHECK(at("P") == -7);
  CHECK(at("My") == 32);
  CHECK(std::isnan(at("hinge.Fx")));
  // Values nobody wrote stay NaN, so an engine that forgets one fails its run loudly.
  CHECK(std::isnan(at("hub.wx")));
  CHECK(std::isnan(at("beamj.angle")));
}
