// The name tables of core/names.hpp: every name parses to its value and back, the lists made from
// a table (schema words, known names) say the same names in the same order, and an unknown name is
// refused with the message the command line and the settings structs give.
#include <catch2/catch.hpp>

#include "core/engine.hpp"
#include "core/integrate.hpp"
#include "core/names.hpp"
#include "core/run_limits.hpp"

#include <set>

using namespace crossdyn;

namespace {

// Each name once, each value once, and name_of(parse_name(n)) == n.
template <class E>
void check_table() {
  std::set<std::string_view> names;
  std::set<E> values;
  for (const auto& [name, value] : Names<E>::table) {
    INFO(name);
    CHECK(names.insert(name).second);
    CHECK(values.insert(value).second);
    REQUIRE(parse_name<E>(name).has_value());
    CHECK(*parse_name<E>(name) == value);
    CHECK(name_of(value) == name);
    CHECK(Choice<E>(name).value() == value);
    CHECK(Choice<E>(value).name() == name);
  }
}

}  // namespace

TEST_CASE("names: each table maps names to values one to one") {
  check_table<Integrator>();
  check_table<ConstraintStabilization>();
  CHECK(Names<Integrator>::table.size() == 7);
  CHECK(Names<ConstraintStabilization>::table.size() == 3);
  CHECK_FALSE(parse_name<Integrator>("RK4"));  // names are exact: no case folding
  CHECK_FALSE(parse_name<Integrator>(""));
}

TEST_CASE("names: the lists made from a table") {
  CHECK(kNameWords<Integrator> == "rk4|dopri5|dop853|rkf78|bulirsch-stoer|cvode-adams|cvode-bdf");
  CHECK(kNameWords<ConstraintStabilization> == "projection|baumgarte|none");
  CHECK(known_names<Integrator>() == "rk4, dopri5, dop853, rkf78, bulirsch-stoer, cvode-adams, cvode-bdf");
  CHECK(integrator_names() == std::vector<std::string>{"rk4", "dopri5", "dop853", "rkf78",
                                                       "bulirsch-stoer", "cvode-adams", "cvode-bdf"});
  CHECK(all_names<ConstraintStabilization>() ==
        std::vector<std::string>{"projection", "baumgarte", "none"});
  // The defaults, by value.
  CHECK(IntegratorSettings{}.method == Integrator::Rkf78);
  CHECK(RunSpec{}.integrator == Integrator::Rkf78);
  CHECK(EngineOptions{}.stabilization == ConstraintStabilization::Projection);
}

TEST_CASE("names: an unknown name is refused, with the close one suggested") {
  CHECK(unknown_name_message<Integrator>("rk45") ==
        "unknown integrator 'rk45' (did you mean 'rk4'?); known: rk4, dopri5, dop853, rkf78, bulirsch-stoer, "
        "cvode-adams, cvode-bdf");
  CHECK(unknown_name_message<Integrator>("euler") ==
        "unknown integrator 'euler'; known: rk4, dopri5, dop853, rkf78, bulirsch-stoer, cvode-adams, "
        "cvode-bdf");
  CHECK(unknown_name_message<ConstraintStabilization>("baumgart") ==
        "unknown stabilization 'baumgart' (did you mean 'baumgarte'?); known: projection, "
        "baumgarte, none");
  CHECK(run_limits::integrator_problem("dopri5").empty());
  CHECK(run_limits::integrator_problem("Dopri5") == unknown_name_message<Integrator>("Dopri5"));

  IntegratorSettings s;
  CHECK_THROWS_WITH(s.method = "rkf45", unknown_name_message<Integrator>("rkf45"));
  CHECK(s.method == Integrator::Rkf78);  // unchanged by the refused name
  s.method = "bulirsch-stoer";
  CHECK(s.method == Integrator::BulirschStoer);
  CHECK(s.method.str() == "bulirsch-stoer");
  s.method = "cvode-bdf";
  CHECK(s.method == Integrator::CvodeBdf);
  EngineOptions o;
  CHECK_THROWS_AS(o.stabilization = std::string("projections"), InputError);
  // A control character in a name is not echoed raw into the message.
  CHECK(unknown_name_message<Integrator>(std::string("r\x1bk4")).find('\x1b') == std::string::npos);
}
