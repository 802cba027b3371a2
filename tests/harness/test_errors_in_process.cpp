// Every way a command can end maps to a message and an exit status, never an abort (issue 9,
// "Crashes"): the top-level mapping, verify recording one scene's exception and going on, and the
// "did you mean" matcher.
#include <catch2/catch.hpp>

#include "core/errors.hpp"
#include "core/output.hpp"
#include "harness/cli.hpp"
#include "harness/verify.hpp"
#include "tests/cli/cli_helpers.hpp"
#include "tests/harness/synthetic.hpp"

#include <cerrno>
#include <filesystem>
#include <new>
#include <sstream>
#include <stdexcept>

using namespace crossdyn;

namespace {

std::pair<int, std::string> mapped(const std::exception_ptr& e) {
  std::ostringstream err;
  const int status = exit_status_for(e, err);
  return {status, err.str()};
}

}  // namespace

TEST_CASE("errors: every exception maps to a message and an exit status, never an abort") {
  namespace fs = std::filesystem;
  struct Case {
    std::exception_ptr e;
    int status;
    std::string message;
  };
  const std::vector<Case> cases{
      {std::make_exception_ptr(InputError("x.yaml:1:1: bad")), 2, "crossdyn: error: x.yaml:1:1: bad\n"},
      {std::make_exception_ptr(OutputError("'o.csv'", ENOSPC)), 3,
       "crossdyn: error: cannot write 'o.csv': No space left on device\n"},
      {std::make_exception_ptr(OutputError("standard output", EPIPE)), kExitBrokenPipe, ""},
      {std::make_exception_ptr(OutputError("'fifo'", EPIPE)), 3, "crossdyn: error: cannot write 'fifo': Broken pipe\n"},
      {std::make_exception_ptr(RunFailure("kane", 1.5, "", "interrupted")), 130, "interrupted"},
      {std::make_exception_ptr(RunFailure("kane", 1.5, "x", "non-finite state")), 3,
       "crossdyn: run failed: engine kane failed at t = 1.5 s (x): non-finite state\n"},
      {std::make_exception_ptr(fs::filesystem_error("directory iterator", fs::path("scenes/a"),
                                                    std::make_error_code(std::errc::too_many_symbolic_link_levels))),
       2, "crossdyn: error: Too many levels of symbolic links: 'scenes/a'\n"},
      {std::make_exception_ptr(std::bad_alloc()), 3, "crossdyn: error: out of memory\n"},
      {std::make_exception_ptr(std::domain_error("elliptic modulus > 1")), 3,
       "crossdyn: internal error: elliptic modulus > 1\n"},
      {std::make_exception_ptr(42), 3, "crossdyn: internal error: unknown exception\n"}};
  for (const Case& c : cases) {
    const auto [status, message] = mapped(c.e);
    INFO(message);
    CHECK(status == c.status);
    if (c.status == 130) CHECK(message.find(c.message) != std::string::npos);
    else CHECK(message == c.message);
  }
}

TEST_CASE("verify: one scene's exception is recorded for that scene and every other scene runs") {
  test::Scratch s("verify_throws");
  const std::string a = s.write("a.yaml", test::kSmallScene);
  std::string other = test::kSmallScene;
  other.replace(other.find("name: small"), 11, "name: throws");
  const std::string b = s.write("b.yaml", other);
  other.replace(other.find("name: throws"), 12, "name: last");
  const std::string c = s.write("c.yaml", other);
  struct Thrown {
    std::function<void()> raise;
    std::string recorded;
  };
  const std::vector<Thrown> kinds{
      {[] { throw std::domain_error("the analytic reference failed"); }, "internal error: the analytic reference failed"},
      {[] { throw std::bad_alloc(); }, "error: out of memory"},
      {[] {
         throw std::filesystem::filesystem_error(
             "status", std::make_error_code(std::errc::permission_denied));
       },
       "internal error: "},
      {[] { throw 7; }, "internal error: unknown exception"}};
  for (const Thrown& k : kinds) {
    harness::VerifyOptions o;
    o.quiet = true;
    int compared = 0;
    o.compare_fn = [&](const System& system, const harness::CompareOptions&) {
      if (system.name == "throws") k.raise();
      ++compared;
      const std::vector<harness::EngineRun> runs{test::engine_run("kane", test::make_run(test::two_body_system())),
                                                 test::engine_run("lagrange", test::make_run(test::two_body_system()))};
      harness::SceneComparison cmp = harness::compare_runs(test::two_body_system(), runs);
      cmp.scene = system.name;
      return cmp;
    };
    const harness::VerifyResult r = harness::run_verify(o, {a, b, c});
    REQUIRE(r.scenes.size() == 3);
    CHECK(compared == 2);  // the scenes before and after the one that threw
    CHECK(r.scenes[0].comparison);
    CHECK(r.scenes[2].comparison);
    CHECK_FALSE(r.scenes[1].comparison);
    CHECK(r.scenes[1].internal_error);
    CHECK(r.scenes[1].input_error.rfind(k.recorded, 0) == 0);
    CHECK(r.exit_code() == kExitRunFailed);
    const std::string table = harness::format_verify_table(r);
    CHECK(table.find("ERROR") != std::string::npos);
    CHECK(table.find(k.recorded) != std::string::npos);
  }
}

TEST_CASE("did you mean: the closest option or command, or nothing when none is close") {
  const std::vector<std::string> options{"--engines", "--integrator", "--json", "--junit", "--output",
                                         "--output-step", "--help"};
  CHECK(closest_match("--engine", options) == "--engines");
  CHECK(closest_match("--intgrator", options) == "--integrator");
  CHECK(closest_match("--jsno", options) == "--json");
  CHECK(closest_match("--output_step", options) == "--output-step");
  CHECK(closest_match("--out", options) == "--output");
  CHECK(closest_match("--frobnicate", options).empty());
  CHECK(closest_match("-x", options).empty());
  CHECK(closest_match("lsit", {"run", "compare", "verify", "list"}) == "list");
  CHECK(closest_match("banana", {"run", "compare", "verify", "list"}).empty());
}
