#pragma once
// Names of HID usages for people: "Generic Desktop:X (0x0001:0x0030)".

#include <cstdint>
#include <string>

namespace bisturi::cli {

/// "0x0030" (digits hexadecimal digits, upper case).
std::string hex(std::uint32_t value, int digits);
/// The usage's page and, for the usages this program knows, its name, with the numeric code.
std::string usage_name(std::uint32_t usage);

}  // namespace bisturi::cli
