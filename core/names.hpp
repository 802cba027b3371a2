// Names that select behaviour (integrator, constraint stabilisation) as enums, each with ONE table
// mapping its names to its values. Names are parsed once, where they enter (the scene reader, the
// command line), and the code dispatches on the enum. Every list of the names (the scene schema's
// words, the CLI's help and error text, messages, the output) is made from the table.
//
//   Names<E>::noun              what one value is called in messages ("integrator")
//   Names<E>::table             {name, value} in documentation order
//   name_of(e)                  "rk4"
//   parse_name<E>("rk4")        optional<E>
//   known_names<E>()            "rk4, dopri5, dop853, rkf78, bulirsch-stoer, cvode-adams, cvode-bdf"
//   all_names<E>()              {"rk4", "dopri5", ...}
//   unknown_name_message<E>(s)  "unknown integrator 'rk45' (did you mean 'rk4'?); known: rk4, dopri5,
//                               dop853, rkf78, bulirsch-stoer, cvode-adams, cvode-bdf"
//   kNameWords<E>               "rk4|dopri5|...|cvode-bdf" (compile time: the scene schema)
//
// Choice<E> holds a value of E that may also be given by its name: settings structs use it so that
// `settings.method = "rk4"` (tests, tools) parses through the table (an unknown name throws
// InputError with unknown_name_message) while the code switches on value().
#pragma once

#include "core/errors.hpp"

#include <array>
#include <cstddef>
#include <optional>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

namespace crossdyn {

// Integration methods (core/integrate.hpp describes each).
enum class Integrator { Rk4, Dopri5, Dop853, Rkf78, BulirschStoer, CvodeAdams, CvodeBdf };

// Newton-Euler constraint stabilisation (formulations/newton_euler/newton_euler.hpp).
enum class ConstraintStabilization { Projection, Baumgarte, None };

template <class E>
struct NamedValue {
  std::string_view name;
  E value;
};

template <class E>
struct Names;  // specialised once per enum, below

template <>
struct Names<Integrator> {
  static constexpr std::string_view noun = "integrator";
  static constexpr std::array<NamedValue<Integrator>, 7> table{{
      {"rk4", Integrator::Rk4},
      {"dopri5", Integrator::Dopri5},
      {"dop853", Integrator::Dop853},
      {"rkf78", Integrator::Rkf78},
      {"bulirsch-stoer", Integrator::BulirschStoer},
      {"cvode-adams", Integrator::CvodeAdams},
      {"cvode-bdf", Integrator::CvodeBdf},
  }};
};

template <>
struct Names<ConstraintStabilization> {
  static constexpr std::string_view noun = "stabilization";
  static constexpr std::array<NamedValue<ConstraintStabilization>, 3> table{{
      {"projection", ConstraintStabilization::Projection},
      {"baumgarte", ConstraintStabilization::Baumgarte},
      {"none", ConstraintStabilization::None},
  }};
};

template <class E>
constexpr std::string_view name_of(E e) {
  for (const auto& n : Names<E>::table)
    if (n.value == e) return n.name;
  return "?";
}

template <class E>
constexpr std::optional<E> parse_name(std::string_view s) {
  for (const auto& n : Names<E>::table)
    if (n.name == s) return n.value;
  return std::nullopt;
}

template <class E>
std::vector<std::string> all_names() {
  std::vector<std::string> out;
  for (const auto& n : Names<E>::table) out.emplace_back(n.name);
  return out;
}

// The names joined by `separator`: "rk4, dopri5, dop853, rkf78, bulirsch-stoer, cvode-adams, cvode-bdf".
template <class E>
std::string known_names(std::string_view separator = ", ") {
  std::string out;
  for (const auto& n : Names<E>::table) {
    if (!out.empty()) out += separator;
    out += n.name;
  }
  return out;
}

// "unknown <noun> 's' (did you mean 'x'?); known: a, b, c" (core/names.cpp).
std::string unknown_name_text(std::string_view noun, std::string_view s,
                              const std::vector<std::string>& known);

template <class E>
std::string unknown_name_message(std::string_view s) {
  return unknown_name_text(Names<E>::noun, s, all_names<E>());
}

namespace detail {
// The names joined by '|' at compile time, NUL-terminated.
template <class E>
constexpr std::size_t joined_size() {
  std::size_t n = 0;
  for (const auto& v : Names<E>::table) n += v.name.size() + 1;  // name and '|' (last: NUL)
  return n;
}
template <class E>
constexpr std::array<char, joined_size<E>()> joined_names() {
  std::array<char, joined_size<E>()> out{};
  std::size_t i = 0;
  for (const auto& v : Names<E>::table) {
    if (i > 0) out[i++] = '|';
    for (char c : v.name) out[i++] = c;
  }
  return out;
}
template <class E>
inline constexpr auto kJoinedNames = joined_names<E>();
}  // namespace detail

// "rk4|dopri5|dop853|rkf78|bulirsch-stoer|cvode-adams|cvode-bdf": the form of the scene schema's word lists.
template <class E>
inline constexpr std::string_view kNameWords{detail::kJoinedNames<E>.data(),
                                             detail::joined_size<E>() - 1};

template <class E>
class Choice {
 public:
  constexpr Choice(E e) : value_(e) {}
  Choice(std::string_view name) : value_(parse_or_throw(name)) {}
  Choice(const char* name) : Choice(std::string_view(name)) {}
  Choice(const std::string& name) : Choice(std::string_view(name)) {}

  constexpr E value() const { return value_; }
  constexpr std::string_view name() const { return name_of(value_); }
  std::string str() const { return std::string(name()); }
  friend constexpr bool operator==(Choice a, Choice b) = default;
  friend std::ostream& operator<<(std::ostream& os, Choice c) { return os << c.name(); }

 private:
  static E parse_or_throw(std::string_view name) {
    if (const auto e = parse_name<E>(name)) return *e;
    throw InputError(unknown_name_message<E>(name));
  }
  E value_;
};

}  // namespace crossdyn
