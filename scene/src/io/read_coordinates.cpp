#include "read_coordinates.h"

#include <cmath>

#include "numbers.h"

namespace bisturi::mesh_io {

Dlfl::Vec3 read_coordinates(TextScanner& text, const ErrorSite& err, std::uint64_t v) {
  Dlfl::Vec3 p;
  for (int k = 0; k < 3; ++k) {
    const std::string_view t = text.token();
    if (t.empty()) {
      err.at_line(text.line_number(), cat("vertex ", v, ": expected 3 coordinates, found ", k));
    }
    const auto value = parse_double(t);
    if (!value) err.at_line(text.line_number(), cat("vertex ", v, ": bad coordinate ", quoted(t)));
    if (!std::isfinite(*value)) {
      err.at_line(text.line_number(),
                  cat("vertex ", v, ": coordinate ", quoted(t), " is not finite"));
    }
    p[k] = *value;
  }
  return p;
}

}  // namespace bisturi::mesh_io
