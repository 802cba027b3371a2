// The crossdyn program as a function (see cli.hpp).
#include "harness/cli.hpp"

#include <CLI/CLI.hpp>

#include "core/cancel.hpp"
#include "core/errors.hpp"
#include "core/output.hpp"
#include "harness/commands.hpp"
#include "harness/locations.hpp"

#include <algorithm>
#include <charconv>
#include <limits>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <new>
#include <string_view>

namespace crossdyn {

namespace {

// Optimal string alignment distance: insertions, deletions, substitutions and transpositions of
// adjacent characters ("lsit" for "list") each cost one.
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1,
                          d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

// "run, compare, verify, list, draw, converge, study": the registered commands, in order.
std::string command_list(const CLI::App& app) {
  std::string out;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
    out += (out.empty() ? "" : ", ") + sub->get_name();
  return out;
}

// Every spelling of the options of `app` ("--engines", "-o"), and its subcommands' names.
std::vector<std::string> known_words(const CLI::App& app, bool options) {
  std::vector<std::string> out;
  if (options) {
    for (const CLI::Option* opt : app.get_options()) {
      for (const std::string& n : opt->get_lnames()) out.push_back("--" + n);
      for (const std::string& n : opt->get_snames()) out.push_back("-" + n);
    }
  } else {
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
      out.push_back(sub->get_name());
  }
  return out;
}

// The message for arguments CLI11 did not expect: which one, and what was probably meant.
std::string unexpected_arguments(CLI::App& app, const CLI::ExtrasError& e) {
  const std::vector<CLI::App*> used = app.get_subcommands();
  CLI::App& where = used.empty() ? app : *used.front();
  const std::string cmd = used.empty() ? "" : where.get_name() + ": ";
  std::vector<std::string> extras = app.remaining(true);
  for (const std::string& arg : extras) {
    if (arg.size() > 1 && arg[0] == '-') {
      const std::string name = arg.substr(0, arg.find('='));
      const std::string hint = closest_match(name, known_words(where, true));
      return cmd + "unknown option '" + name + "'" +
             (hint.empty() ? "" : " (did you mean '" + hint + "'?)");
    }
  }
  if (used.empty() && !extras.empty()) {
    const std::string hint = closest_match(extras.front(), known_words(app, false));
    return "unknown command '" + extras.front() + "'" +
           (hint.empty() ? " (commands: " + command_list(app) + ")"
                         : " (did you mean '" + hint + "'?)");
  }
  return cmd + e.what();
}

}  // namespace

std::string closest_match(const std::string& word, const std::vector<std::string>& known) {
  if (word.size() < 4) return "";  // "-x": any one-letter option would be "close"
  std::string best;
  std::size_t best_d = std::string::npos;
  for (const std::string& k : known) {
    std::size_t d = edit_distance(word, k);
    // "--engine" for "--engines", "--out" for "--output": a prefix counts as close.
    if (word.size() >= 3 && k.compare(0, word.size(), word) == 0) d = std::min<std::size_t>(d, 1);
    if (d < best_d) {
      best_d = d;
      best = k;
    }
  }
  const std::size_t limit = std::max<std::size_t>(1, std::min<std::size_t>(3, word.size() / 3));
  return best_d <= limit ? best : "";
}

int interrupted_status(std::ostream& err, const std::string& what) {
  cancel::acknowledge_interrupt();  // the watchdog's forced exit stays silent
  err << "crossdyn: interrupted" << (what.empty() ? "" : " (" + what + ")") << '\n';
  return kExitInterrupted;
}

int exit_status_for(const std::exception_ptr& e, std::ostream& err) {
  try {
    std::rethrow_exception(e);
  } catch (const cancel::Cancelled& x) {
    if (x.reason() == cancel::Reason::Interrupt) return interrupted_status(err, "");
    err << "crossdyn: run failed: " << x.what() << '\n';
    return kExitRunFailed;
  } catch (const InputError& x) {
    // An interrupted system call or child process can surface as an input error: 130 wins.
    if (cancel::interrupted()) return interrupted_status(err, "");
    err << "crossdyn: error: " << x.what() << '\n';
    return kExitBadInput;
  } catch (const OutputError& x) {
    if (x.broken_pipe() && x.target() == "standard output")
      return kExitBrokenPipe;  // the reader of our stdout is gone: stop quietly
    err << "crossdyn: error: " << x.what() << '\n';
    return kExitRunFailed;
  } catch (const RunFailure& x) {
    if (x.reason() == "interrupted" || cancel::interrupted()) {
      if (x.engine().empty() || x.engine() == "output" || x.engine() == "report")
        return interrupted_status(err, "");
      char t[64];
      std::snprintf(t, sizeof t, "%.9g", x.time());
      return interrupted_status(err, "engine " + x.engine() + " at t = " + t + " s");
    }
    err << "crossdyn: run failed: " << x.what() << '\n';
    return kExitRunFailed;
  } catch (const std::filesystem::filesystem_error& x) {
    err << "crossdyn: error: " << x.code().message();
    if (!x.path1().empty()) err << ": '" << x.path1().string() << "'";
    if (!x.path2().empty()) err << ", '" << x.path2().string() << "'";
    err << '\n';
    return kExitBadInput;
  } catch (const std::bad_alloc&) {
    err << "crossdyn: error: out of memory\n";
    return kExitRunFailed;
  } catch (const std::exception& x) {
    err << "crossdyn: internal error: " << x.what() << '\n';
    return kExitRunFailed;
  } catch (...) {
    err << "crossdyn: internal error: unknown exception\n";
    return kExitRunFailed;
  }
}

int crossdyn_main(int argc, char** argv) {
  // A closed pipe on an output is a write error (EPIPE) crossdyn reports, not a silent death.
  std::signal(SIGPIPE, SIG_IGN);
  CheckedStdout checked_stdout;
  int exit_code = kExitOk;
  try {
    CLI::App app{
        "crossdyn: can I trust this simulation? Runs one multibody spacecraft scene through three\n"
        "independently written dynamics engines (Kane, Lagrange with quasi-coordinates,\n"
        "Newton-Euler) and shows where they agree.\n\n"
        "Exit status: 0 success, 1 a comparison failed, 2 bad input, 3 a run or a write failed,\n"
        "130 interrupted, 141 standard output closed by its reader."};
    app.require_subcommand(1);
    app.set_version_flag("--version", "crossdyn " + harness::version());
    // Start-up: CLI11 builds every option of every command it is given (about a third of the
    // instructions of `crossdyn --version`). When the first argument names a command, only that
    // command is registered (its parsing, help and messages are the same); otherwise all are, for
    // the top-level help and the "unknown command" hints.
    struct Command {
      const char* name;
      void (*add)(CLI::App&, int&);
    };
    static constexpr Command kCommands[] = {
        {"run", add_run_command},   {"compare", add_compare_command}, {"verify", add_verify_command},
        {"merge", add_merge_command},
        {"list", add_list_command}, {"draw", add_draw_command},       {"converge", add_converge_command},
        {"study", add_study_command}, {"stability", add_stability_command},
        {"linearize", add_linearize_command}};
    const Command* named = nullptr;
    for (const Command& c : kCommands)
      if (argc > 1 && std::string_view(argv[1]) == c.name) named = &c;
    for (const Command& c : kCommands)
      if (!named || named == &c) c.add(app, exit_code);
    for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; }))
      for (CLI::Option* option : sub->get_options())
        if (option->nonpositional() && option->get_type_size() != 0) {  // not a flag
          if (option->get_type_name() == "INT" || option->get_type_name() == "UINT") whole_number_option(option);
          non_empty_option(option);
        }
    try {
      app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
      app.exit(e, std::cout, std::cerr);
      exit_code = kExitOk;
    } catch (const CLI::CallForAllHelp& e) {
      app.exit(e, std::cout, std::cerr);
      exit_code = kExitOk;
    } catch (const CLI::CallForVersion& e) {
      app.exit(e, std::cout, std::cerr);
      exit_code = kExitOk;
    } catch (const CLI::ExtrasError& e) {
      std::cerr << "crossdyn: error: " << unexpected_arguments(app, e)
                << "\nRun with --help for the options.\n";
      exit_code = kExitBadInput;
    } catch (const CLI::ParseError& e) {
      std::string message = e.what();
      // CLI11's "Could not convert: --duration = abc": a sentence about the value instead.
      const std::string kConvert = "Could not convert: ";
      if (message.rfind(kConvert, 0) == 0 && message.find(" = ") != std::string::npos) {
        const std::size_t eq = message.find(" = ");
        message = message.substr(kConvert.size(), eq - kConvert.size()) + ": '" +
                  message.substr(eq + 3) + "' is not a number this option takes";
      }
      if (app.get_subcommands().empty()) {  // no command recognised
        const std::vector<std::string> rest = app.remaining(true);
        if (rest.empty()) message = "no command given (commands: " + command_list(app) + ")";
        else if (rest.front().size() > 1 && rest.front()[0] == '-') {
          const std::string name = rest.front().substr(0, rest.front().find('='));
          const std::string hint = closest_match(name, known_words(app, true));
          message = "unknown option '" + name + "'" +
                    (hint.empty() ? " (a command comes first: " + command_list(app) + ")"
                                  : " (did you mean '" + hint + "'?)");
        } else {
          const std::string hint = closest_match(rest.front(), known_words(app, false));
          message = "unknown command '" + rest.front() + "'" +
                    (hint.empty() ? " (commands: " + command_list(app) + ")"
                                  : " (did you mean '" + hint + "'?)");
        }
      }
      std::cerr << "crossdyn: error: " << message << "\nRun with --help for the options.\n";
      exit_code = kExitBadInput;
    }
    check_written(std::cout);
    // Ctrl-C during a command that finished anyway (between its last poll and its return): 130.
    if (cancel::interrupted()) exit_code = interrupted_status(std::cerr, "");
  } catch (...) {
    exit_code = exit_status_for(std::current_exception(), std::cerr);
  }
  return exit_code;
}

void whole_number_option(CLI::Option* option) {
  option->transform(CLI::Validator(
      [](std::string& text) -> std::string {
        // CLI11 reads integers with strtoll base 0 ("010" is 8, "0x10" 16) and saturates on
        // overflow (99999999999999999999 became 9223372036854775807): decimal digits only, and a
        // value an int holds, checked on the text.
        const char* b = text.data();
        const char* e = text.data() + text.size();
        if (b != e && *b == '+') ++b;
        long long v = 0;
        const auto r = std::from_chars(b, e, v, 10);
        if (b == e || r.ptr != e || (r.ec != std::errc() && r.ec != std::errc::result_out_of_range))
          return "'" + text + "' is not a whole number";
        if (r.ec == std::errc::result_out_of_range || v > std::numeric_limits<int>::max() ||
            v < std::numeric_limits<int>::min())
          return "'" + text + "' is too large (at most " + std::to_string(std::numeric_limits<int>::max()) + ")";
        text = std::to_string(v);  // "010" is ten, not CLI11's octal eight
        return "";
      },
      ""));
}

void non_empty_option(CLI::Option* option) {
  option->check(CLI::Validator(
      [](std::string& text) -> std::string {
        return text.empty() ? "an empty value (leave the option out for its default)" : "";
      },
      ""));
}

CLI::Option* list_option(CLI::Option* option) {
  option->check(CLI::Validator(
      [](std::string& text) -> std::string {
        if (text.empty())
          return "the list is empty (leave the option out for its default)";
        std::vector<std::string> items;
        std::size_t start = 0;
        while (true) {
          const std::size_t comma = text.find(',', start);
          const std::string item = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
          if (item.empty()) return "an empty item in '" + text + "' (a comma too many)";
          if (std::find(items.begin(), items.end(), item) != items.end())
            return "'" + item + "' is listed twice in '" + text + "'";
          items.push_back(item);
          if (comma == std::string::npos) break;
          start = comma + 1;
        }
        return "";
      },
      ""));
  return option;
}

}  // namespace crossdyn
