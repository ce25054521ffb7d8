// Checks for the programs' numeric command-line options, as CLI11 validators that say in words
// what is allowed ("must be > 0, not 0"; CLI11's own ranges print "Value 0 not in range 0.000000
// to 1797693…" with 300 digits). Every one refuses NaN and the infinities: they slip past any
// range check (every comparison with NaN is false) and no option means anything with them.
// Header-only, for the main()s, which link CLI11; a failed check is a bad option (exit 2).
#pragma once

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>
#include <thread>

namespace frontier::option_checks {

// The most --threads a program takes: four per hardware thread. More cannot run any faster, and
// every render or build thread costs memory and a slot in the thread pool (--threads 100000 took
// gigabytes before it was bounded).
inline int max_threads() { return 4 * static_cast<int>(std::max(1u, std::thread::hardware_concurrency())); }

namespace detail {

// The option's text as a number (decimal or hexadecimal, NaN and infinities included); nullopt
// when it is none, and CLI11's conversion then says so.
inline std::optional<double> number(const std::string& text) {
  if (text.empty()) return std::nullopt;
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size()) return std::nullopt;
  return value;  // out of range: ±inf, refused below
}

inline std::string shortest(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

// Finite numbers for which `ok` holds; else "must be WHAT, not TEXT".
template <class Ok>
CLI::Validator finite_where(Ok ok, const std::string& what, const std::string& name) {
  return CLI::Validator(
      [ok, what](std::string& text) -> std::string {
        const std::optional<double> value = number(text);
        if (!value) return {};
        if (!std::isfinite(*value)) return "must be a finite number" + (what.empty() ? "" : " " + what) + ", not " + text;
        if (!ok(*value)) return "must be " + what + ", not " + text;
        return {};
      },
      name, name);
}

}  // namespace detail

inline CLI::Validator finite() {
  return detail::finite_where([](double) { return true; }, "", "NUMBER");
}
inline CLI::Validator positive() {
  return detail::finite_where([](double v) { return v > 0.0; }, "> 0", "POSITIVE");
}
inline CLI::Validator non_negative() {
  return detail::finite_where([](double v) { return v >= 0.0; }, ">= 0", "NONNEGATIVE");
}
// lo <= value <= hi.
inline CLI::Validator between(double lo, double hi) {
  return detail::finite_where([lo, hi](double v) { return v >= lo && v <= hi; },
                              "between " + detail::shortest(lo) + " and " + detail::shortest(hi), "NUMBER");
}
// --threads: 0 (all cores) up to max_threads().
inline CLI::Validator thread_count() {
  const int most = max_threads();
  return detail::finite_where([most](double v) { return v >= 0.0 && v <= most; },
                              "0 (all cores) to " + std::to_string(most) + " (4 per hardware thread)", "THREADS");
}

}  // namespace frontier::option_checks
