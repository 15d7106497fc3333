#pragma once
// Bytes as the trace tools print them: "0a ff 01".

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace bisturi::cli {

inline std::string hex_bytes(const std::vector<std::uint8_t>& bytes) {
  std::string out;
  char cell[4];
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    std::snprintf(cell, sizeof cell, "%02x", bytes[i]);
    if (i > 0) out += ' ';
    out += cell;
  }
  return out;
}

}  // namespace bisturi::cli
