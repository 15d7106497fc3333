#pragma once
// Error messages of the mesh readers: "file: line 12: face 3: reason" or "file: byte 96: ...".

#include <concepts>
#include <cstddef>
#include <string>
#include <string_view>

namespace bisturi::mesh_io {

namespace detail {
inline void append(std::string& s, std::string_view v) {
  s += v;
}
inline void append(std::string& s, const char* v) {
  s += v;
}
inline void append(std::string& s, const std::string& v) {
  s += v;
}
void append(std::string& s, double v);
template <std::integral T>
requires(!std::same_as<T, char> && !std::same_as<T, bool>) void append(std::string& s, T v) {
  s += std::to_string(v);
}
}  // namespace detail

/// Concatenates strings and numbers (for messages; not for hot paths).
template <class... Parts>
std::string cat(const Parts&... parts) {
  std::string s;
  (detail::append(s, parts), ...);
  return s;
}

/// A token from the file, quoted for a message: at most 32 characters, bytes that are not
/// printable written as \xNN.
std::string quoted(std::string_view token);

/// Throws InputError whose message starts with the file name and the place.
class ErrorSite {
 public:
  explicit ErrorSite(const std::string& file) : file_(file) {}

  [[noreturn]] void at_line(std::size_t line, std::string_view what) const;
  [[noreturn]] void at_byte(std::size_t byte, std::string_view what) const;
  [[noreturn]] void whole(std::string_view what) const;
  const std::string& file() const { return file_; }

 private:
  const std::string& file_;
};

}  // namespace bisturi::mesh_io
