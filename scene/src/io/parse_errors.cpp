#include "parse_errors.h"

#include <charconv>

#include "bisturi/scene/errors.h"

namespace bisturi::mesh_io {

void detail::append(std::string& s, double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  s.append(buf, r.ptr);
}

std::string quoted(std::string_view token) {
  constexpr std::size_t kMax = 32;
  constexpr char kHex[] = "0123456789abcdef";
  std::string s = "'";
  for (std::size_t i = 0; i < token.size() && i < kMax; ++i) {
    const auto c = static_cast<unsigned char>(token[i]);
    if (c >= 0x20 && c < 0x7f && c != '\\') {
      s += static_cast<char>(c);
    } else {
      s += "\\x";
      s += kHex[c >> 4];
      s += kHex[c & 15];
    }
  }
  if (token.size() > kMax) s += "...";
  return s + "'";
}

void ErrorSite::at_line(std::size_t line, std::string_view what) const {
  throw InputError(cat(file_, ": line ", line, ": ", what));
}

void ErrorSite::at_byte(std::size_t byte, std::string_view what) const {
  throw InputError(cat(file_, ": byte ", byte, ": ", what));
}

void ErrorSite::whole(std::string_view what) const {
  throw InputError(cat(file_, ": ", what));
}

}  // namespace bisturi::mesh_io
