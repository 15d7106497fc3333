#pragma once
// Option checks that say what a number must be ("must be positive") instead of CLI11's
// PositiveNumber, which prints the range it checks against, up to the largest double.

#include <CLI/CLI.hpp>

#include <string>

namespace bisturi::cli {

/// A number strictly above zero.
inline const CLI::Validator kPositive(
    [](std::string& text) -> std::string {
      double value = 0.0;
      if (!CLI::detail::lexical_cast(text, value)) return "'" + text + "' is not a number";
      return value > 0.0 ? std::string() : "must be positive (got " + text + ")";
    },
    "POSITIVE");

/// A number at or above zero.
inline const CLI::Validator kNonNegative(
    [](std::string& text) -> std::string {
      double value = 0.0;
      if (!CLI::detail::lexical_cast(text, value)) return "'" + text + "' is not a number";
      return value >= 0.0 ? std::string() : "must be zero or more (got " + text + ")";
    },
    "NONNEGATIVE");

}  // namespace bisturi::cli
