#include "core/units.hpp"

#include <array>
#include <numbers>

namespace crossdyn::units {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;  // rad per degree

// Every unit the reader knows. Factors are exact definitions: 1 deg = pi/180 rad,
// 1 rpm = 2 pi rad / 60 s, 1 min = 60 s, 1 mN = 1e-3 N. Per degree is per pi/180 rad:
// 1 N m/deg = 180/pi N m/rad. The first unit of a dimension is its SI unit.
constexpr double kPerDeg = 180.0 / std::numbers::pi;  // (per degree) / (per radian)
constexpr std::array<Unit, 52> kUnits{{
    {"rad", Dimension::Angle, 1.0},
    {"deg", Dimension::Angle, kDeg},
    {"rad/s", Dimension::AngularRate, 1.0},
    {"deg/s", Dimension::AngularRate, kDeg},
    {"rpm", Dimension::AngularRate, 2.0 * std::numbers::pi / 60.0},
    {"m", Dimension::Length, 1.0},
    {"mm", Dimension::Length, 1e-3},
    {"cm", Dimension::Length, 1e-2},
    {"km", Dimension::Length, 1e3},
    {"kg", Dimension::Mass, 1.0},
    {"g", Dimension::Mass, 1e-3},
    {"s", Dimension::Time, 1.0},
    {"ms", Dimension::Time, 1e-3},
    {"min", Dimension::Time, 60.0},
    {"kg m^2", Dimension::Inertia, 1.0},
    {"N m", Dimension::Torque, 1.0},
    {"mN m", Dimension::Torque, 1e-3},
    {"N m/rad", Dimension::Stiffness, 1.0},
    {"N m/deg", Dimension::Stiffness, kPerDeg},
    {"mN m/rad", Dimension::Stiffness, 1e-3},
    {"mN m/deg", Dimension::Stiffness, 1e-3 * kPerDeg},
    {"N m s/rad", Dimension::Damping, 1.0},
    {"N m s/deg", Dimension::Damping, kPerDeg},
    {"mN m s/rad", Dimension::Damping, 1e-3},
    {"mN m s/deg", Dimension::Damping, 1e-3 * kPerDeg},
    {"m/s", Dimension::Velocity, 1.0},
    {"cm/s", Dimension::Velocity, 1e-2},
    {"mm/s", Dimension::Velocity, 1e-3},
    {"rad/s^2", Dimension::AngularAcceleration, 1.0},
    {"deg/s^2", Dimension::AngularAcceleration, kDeg},
    {"N", Dimension::Force, 1.0},
    {"mN", Dimension::Force, 1e-3},
    {"kN", Dimension::Force, 1e3},
    {"N/m", Dimension::LinearStiffness, 1.0},
    {"N/mm", Dimension::LinearStiffness, 1e3},
    {"kN/m", Dimension::LinearStiffness, 1e3},
    {"N s/m", Dimension::LinearDamping, 1.0},
    {"Ns/m", Dimension::LinearDamping, 1.0},
    {"m/s^2", Dimension::Acceleration, 1.0},
    {"g0", Dimension::Acceleration, 9.80665},  // standard gravity (CGPM 1901), exact
    {"m^3/s^2", Dimension::GravitationalParameter, 1.0},
    {"km^3/s^2", Dimension::GravitationalParameter, 1e9},
    // Accepted alternative spellings (same factors).
    {"Nm", Dimension::Torque, 1.0},
    {"mNm", Dimension::Torque, 1e-3},
    {"Nm/rad", Dimension::Stiffness, 1.0},
    {"Nm/deg", Dimension::Stiffness, kPerDeg},
    {"mNm/rad", Dimension::Stiffness, 1e-3},
    {"mNm/deg", Dimension::Stiffness, 1e-3 * kPerDeg},
    {"Nms/rad", Dimension::Damping, 1.0},
    {"Nms/deg", Dimension::Damping, kPerDeg},
    {"degrees", Dimension::Angle, kDeg},
    {"radians", Dimension::Angle, 1.0},
}};

}  // namespace

std::string normalise_unit(std::string_view text) {
  std::string spaced;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '*' || c == '\t') {
      spaced += ' ';
    } else if (static_cast<unsigned char>(c) == 0xC2 && i + 1 < text.size() &&
               static_cast<unsigned char>(text[i + 1]) == 0xB7) {  // U+00B7 middle dot
      spaced += ' ';
      ++i;
    } else {
      spaced += c;
    }
  }
  std::string out;
  for (std::size_t i = 0; i < spaced.size(); ++i) {
    const char c = spaced[i];
    if (c == ' ') {
      // Keep one space, and none at the ends or next to '/'.
      if (out.empty() || out.back() == ' ' || out.back() == '/') continue;
      out += ' ';
    } else {
      if (c == '/' && !out.empty() && out.back() == ' ') out.pop_back();
      out += c;
    }
  }
  if (!out.empty() && out.back() == ' ') out.pop_back();
  return out;
}

std::optional<Unit> find_unit(std::string_view text) {
  const std::string n = normalise_unit(text);
  for (const Unit& u : kUnits)
    if (u.name == n) return u;
  return std::nullopt;
}

std::string dimension_name(Dimension d) {
  switch (d) {
    case Dimension::None:
      return "a pure number";
    case Dimension::Angle:
      return "an angle";
    case Dimension::AngularRate:
      return "an angular rate";
    case Dimension::Length:
      return "a length";
    case Dimension::Mass:
      return "a mass";
    case Dimension::Time:
      return "a time";
    case Dimension::Inertia:
      return "a moment of inertia";
    case Dimension::Torque:
      return "a torque";
    case Dimension::Stiffness:
      return "a rotational stiffness";
    case Dimension::Damping:
      return "a rotational damping";
    case Dimension::Velocity:
      return "a velocity";
    case Dimension::AngularAcceleration:
      return "an angular acceleration";
    case Dimension::Force:
      return "a force";
    case Dimension::LinearStiffness:
      return "a linear stiffness";
    case Dimension::LinearDamping:
      return "a linear damping";
    case Dimension::Acceleration:
      return "an acceleration";
    case Dimension::GravitationalParameter:
      return "a gravitational parameter";
  }
  return "?";
}

std::vector<std::string> unit_names(Dimension d) {
  std::vector<std::string> names;
  for (const Unit& u : kUnits)
    if (u.dimension == d) names.emplace_back(u.name);
  return names;
}

std::string units_of(Dimension d) {
  if (d == Dimension::None) return "no unit";
  std::string s;
  for (const std::string& n : unit_names(d)) s += (s.empty() ? "" : ", ") + n;
  return s;
}

}  // namespace crossdyn::units
