#pragma once
// Numbers in text mesh files, parsed with std::from_chars (no locale, no allocation).

#include <cstdint>
#include <optional>
#include <string_view>

namespace bisturi::mesh_io {

/// The whole token as a double (a leading '+' is accepted). Too large a magnitude gives +-inf
/// and too small one its rounded value, as strtod does; the caller decides about non-finite.
std::optional<double> parse_double(std::string_view token);

/// The whole token as an integer (a leading '+' is accepted); nullopt when it is not one or
/// does not fit in 64 bits.
std::optional<std::int64_t> parse_int(std::string_view token);

}  // namespace bisturi::mesh_io
