#pragma once
// Argument errors of `phalanxd` and `phalanx` (every subcommand): one exit code (2, README "Exit codes"), one
// message naming the option, the nearest option for a mistyped one, and no empty value taken as "not given".
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

namespace phalanx::host::cli {

inline constexpr int kExitBadArguments = 2;

/// CLI::Range with a message that says what was expected: "--rate-hz: expected an integer in [100, 4000], got
/// 'abc'". Integer bounds also refuse a fraction.
template <class T>
CLI::Validator inRange(T lo, T hi) {
  std::ostringstream bounds;
  bounds << "[" << lo << ", " << hi << "]";
  const std::string expected = std::string("expected ") + (std::is_integral_v<T> ? "an integer" : "a number") + " in " +
                               bounds.str();
  return CLI::Validator(
      [lo, hi, expected](std::string& in) {
        T v{};
        if (!CLI::detail::lexical_cast(in, v) || !(v >= lo && v <= hi)) return expected + ", got '" + in + "'";
        return std::string();
      },
      bounds.str());
}

/// A length in seconds that is 0 (meaning zero_means) or at least min_s: a bench stepped at 1 kHz runs
/// seconds × 1000 steps, so a shorter positive length would run none and report empty metrics as a result.
inline CLI::Validator zeroOrAtLeast(double min_s, const std::string& zero_means) {
  std::ostringstream os;
  os << "expected 0 (" << zero_means << ") or at least " << min_s << " s";
  const std::string expected = os.str();
  return CLI::Validator(
      [min_s, expected](std::string& in) {
        double v = 0.0;
        if (CLI::detail::lexical_cast(in, v) && (v == 0.0 || v >= min_s)) return std::string();
        return expected + ", got '" + in + "'";
      },
      "");
}

/// Every option and positional of app and of its subcommands that takes a value refuses an empty one
/// ("--api: must not be empty"): for a path or an address an empty value would otherwise read as "not given" and
/// silently change what runs (`phalanxd --api ""` ran a motor session). Call after every option is added.
inline void refuseEmptyValues(CLI::App& app) {
  const CLI::Validator non_empty(
      [](std::string& in) { return in.empty() ? std::string("must not be empty") : std::string(); }, "");
  for (CLI::Option* opt : app.get_options([](CLI::Option*) { return true; })) {
    if (opt->get_items_expected_max() > 0) opt->transform(non_empty);  // first: before a file-exists check
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) refuseEmptyValues(*sub);
}

/// Help shows each option's default ("--rate-hz UINT=1000"), except where the stored value only marks "not given"
/// (-1: the daemon's or the plant's own default; [] an empty list), which the option's description explains.
/// Call after every option is added.
inline void hideUnsetDefaults(CLI::App& app) {
  for (CLI::Option* opt : app.get_options([](CLI::Option*) { return true; })) {
    const std::string d = opt->get_default_str();
    if (d == "-1" || d == "[]") opt->default_str("");
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) hideUnsetDefaults(*sub);
}

/// Optimal-string-alignment edit distance (a swap of two neighbours counts once: --secnods → --seconds is 1).
inline std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  }
  return d[a.size()][b.size()];
}

/// The name nearest to word: the closest by edit distance if within a third of word's length (at least 1), else
/// the only name that word begins (--rate → --rate-hz); "" when none is close enough to be a likely typo.
inline std::string nearestName(const std::string& word, const std::vector<std::string>& names) {
  std::string best;
  std::size_t best_d = std::string::npos;
  for (const std::string& n : names) {
    const std::size_t dist = editDistance(word, n);
    if (dist < best_d) best_d = dist, best = n;
  }
  const std::size_t allowed = std::max<std::size_t>(1, word.size() / 3);
  if (!best.empty() && best_d <= allowed) return best;
  std::vector<std::string> extending;
  for (const std::string& n : names) {
    if (word.size() >= 3 && n.size() > word.size() && n.compare(0, word.size(), word) == 0) extending.push_back(n);
  }
  return extending.size() == 1 ? extending.front() : std::string();
}

namespace detail {

/// app and its parsed subcommands, outermost first (the command line's path: phalanx → bench → glove-grasp).
inline std::vector<const CLI::App*> parsedChain(const CLI::App& app) {
  std::vector<const CLI::App*> chain{&app};
  for (;;) {
    const CLI::App* next = nullptr;
    for (const CLI::App* sub : chain.back()->get_subcommands([](const CLI::App* s) { return s->count() > 0; })) {
      next = sub;
    }
    if (next == nullptr) return chain;
    chain.push_back(next);
  }
}

inline std::vector<std::string> optionNames(const CLI::App& app) {
  std::vector<std::string> names;
  for (const CLI::Option* opt : app.get_options()) {
    for (const std::string& l : opt->get_lnames()) names.push_back("--" + l);
    for (const std::string& s : opt->get_snames()) names.push_back("-" + s);
  }
  return names;
}

inline std::vector<std::string> subcommandNames(const CLI::App& app) {
  std::vector<std::string> names;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App* s) { return !s->get_name().empty(); })) {
    names.push_back(sub->get_name());
  }
  return names;
}

inline std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const std::string& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

inline std::string didYouMean(const std::string& suggestion) {
  return suggestion.empty() ? std::string() : "; did you mean " + suggestion + "?";
}

/// "unknown option --secnds; did you mean --seconds?" for what a (sub)command could not place; "" if nothing.
inline std::string leftoverMessage(const std::vector<const CLI::App*>& chain) {
  for (const CLI::App* app : chain) {
    const std::vector<std::string> rest = app->remaining(false);
    if (rest.empty()) continue;
    for (const std::string& arg : rest) {
      if (arg.size() < 2 || arg[0] != '-') continue;
      const std::string name = arg.substr(0, arg.find('='));
      return "unknown option " + name + didYouMean(nearestName(name, optionNames(*app)));
    }
    const std::vector<std::string> subs = subcommandNames(*app);
    if (!subs.empty() && app == chain.back()) {
      return "unknown command '" + rest.front() + "'" + didYouMean(nearestName(rest.front(), subs)) + " (commands: " +
             joined(subs) + ")";
    }
    return "unexpected argument '" + rest.front() + "'";
  }
  return {};
}

inline std::string typeWord(const std::string& type_name) {
  if (type_name.rfind("UINT", 0) == 0) return "a non-negative integer";
  if (type_name.rfind("INT", 0) == 0) return "an integer";
  if (type_name.rfind("FLOAT", 0) == 0) return "a number";
  return "a valid value";
}

/// CLI11's "Could not convert: --seed = abc" as "--seed: expected a non-negative integer, got 'abc'".
inline std::string conversionMessage(const std::vector<const CLI::App*>& chain, const std::string& what) {
  const std::string prefix = "Could not convert: ";
  const auto eq = what.find(" = ");
  if (what.rfind(prefix, 0) != 0 || eq == std::string::npos) return what;
  const std::string name = what.substr(prefix.size(), eq - prefix.size());
  const std::string value = what.substr(eq + 3);
  for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
    for (const CLI::Option* opt : (*it)->get_options()) {
      if (opt->get_name() == name) return name + ": expected " + typeWord(opt->get_type_name()) + ", got '" + value + "'";
    }
  }
  return name + ": cannot use '" + value + "'";
}

}  // namespace detail

/// The one line an argument error is reported with (without the program's name).
inline std::string parseErrorMessage(const CLI::App& app, const CLI::ParseError& e) {
  const std::vector<const CLI::App*> chain = detail::parsedChain(app);
  const std::string what = e.what();
  const bool placement = e.get_exit_code() == static_cast<int>(CLI::ExitCodes::ExtrasError) ||
                         e.get_exit_code() == static_cast<int>(CLI::ExitCodes::RequiredError);
  if (placement) {
    // An unknown option or command is the cause of a "required" error that follows from it (phalanx rnu).
    if (std::string m = detail::leftoverMessage(chain); !m.empty()) return m;
  }
  if (what == "A subcommand is required") {
    return "a command is required (" + detail::joined(detail::subcommandNames(*chain.back())) + ")";
  }
  if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::ConversionError)) return detail::conversionMessage(chain, what);
  return what;
}

/// Parses argv into app. --help (and its kin) print and set rc 0; an argument error prints
/// "<prog>: error: <message>" and sets rc 2. Returns whether the caller should go on.
inline bool parseArgs(CLI::App& app, int argc, char** argv, const char* prog, int& rc) {
  try {
    app.parse(argc, argv);
    return true;
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) {
      rc = app.exit(e);
      return false;
    }
    std::fprintf(stderr, "%s: error: %s\nRun with --help for more information.\n", prog,
                 parseErrorMessage(app, e).c_str());
    rc = kExitBadArguments;
    return false;
  }
}

}  // namespace phalanx::host::cli
