#include "numbers.h"

#include <charconv>
#include <cstdlib>
#include <string>
#include <system_error>

namespace bisturi::mesh_io {
namespace {

// from_chars refuses '+', which some writers put before exponents' mantissas.
std::string_view drop_plus(std::string_view t) {
  if (t.size() > 1 && t[0] == '+' && t[1] != '-' && t[1] != '+') t.remove_prefix(1);
  return t;
}

}  // namespace

std::optional<double> parse_double(std::string_view token) {
  const std::string_view t = drop_plus(token);
  double value = 0.0;
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), value);
  if (end != t.data() + t.size()) return std::nullopt;
  if (ec == std::errc::result_out_of_range) {
    // from_chars reports overflow and underflow alike; strtod tells them apart (rare path).
    const std::string copy(t);
    return std::strtod(copy.c_str(), nullptr);
  }
  if (ec != std::errc()) return std::nullopt;
  return value;
}

std::optional<std::int64_t> parse_int(std::string_view token) {
  const std::string_view t = drop_plus(token);
  std::int64_t value = 0;
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), value);
  if (ec != std::errc() || end != t.data() + t.size()) return std::nullopt;
  return value;
}

}  // namespace bisturi::mesh_io
