// Units accepted in scene files and their factors to SI (docs/scene-format.md "Units").
//
// A scene quantity is a number in SI, or a string "<number> <unit>" ("10 deg/s", "300 kg"), or for
// vectors {value: [...], unit: ...}. find_unit() looks a unit up after normalising its spelling:
// '*' and U+00B7 (middle dot) are read as spaces, runs of spaces collapse, and spaces around '/'
// are dropped, so "kg*m^2", "kg m^2" and "kg  m^2" are one unit, as are "N*m/rad" and "N m / rad".
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace crossdyn::units {

// Physical dimension a scene key expects. None: a pure number (tolerances, quaternion components).
enum class Dimension {
  None,
  Angle,        // rad
  AngularRate,  // rad/s
  Length,       // m
  Mass,         // kg
  Time,         // s
  Inertia,      // kg m^2
  Torque,       // N m
  Stiffness,    // N m/rad
  Damping,      // N m s/rad
  Velocity,     // m/s
  AngularAcceleration,  // rad/s^2 (no key takes one yet: known so that a wrong use is named)
  Force,            // N (a prismatic joint's motor)
  LinearStiffness,  // N/m (a prismatic joint's spring)
  LinearDamping,    // N s/m (a prismatic joint's damper)
  Acceleration,     // m/s^2 (uniform gravity)
  GravitationalParameter,  // m^3/s^2 (a central body's mu = G M)
};

// Every dimension with a unit, in the order the documentation lists them.
inline constexpr Dimension kDimensions[] = {
    Dimension::Angle,   Dimension::AngularRate, Dimension::Length,  Dimension::Mass,
    Dimension::Time,    Dimension::Inertia,     Dimension::Torque,  Dimension::Stiffness,
    Dimension::Damping, Dimension::Velocity,    Dimension::AngularAcceleration,
    Dimension::Force,   Dimension::LinearStiffness, Dimension::LinearDamping,
    Dimension::Acceleration, Dimension::GravitationalParameter,
};

struct Unit {
  std::string_view name;  // canonical spelling
  Dimension dimension;
  double to_si;  // value_SI = value * to_si
};

// The unit spelled `text` (after normalisation), or nothing when it is not known.
std::optional<Unit> find_unit(std::string_view text);

// "an angle", "an angular rate", ... for messages.
std::string dimension_name(Dimension d);

// The accepted units of a dimension, for messages: "rad, deg".
std::string units_of(Dimension d);

// The same as a list.
std::vector<std::string> unit_names(Dimension d);

// Normalised spelling used by find_unit (exposed for tests).
std::string normalise_unit(std::string_view text);

}  // namespace crossdyn::units
