#pragma once
// The x y z of one vertex line in the text formats (OBJ `v`, OFF vertex lines).

#include <cstdint>

#include "bisturi/scene/dlfl.h"
#include "parse_errors.h"
#include "text_scanner.h"

namespace bisturi::mesh_io {

/// Reads three finite coordinates from the current line of `text`; anything after them is left
/// unread. Errors name vertex `v` and the scanner's line.
Dlfl::Vec3 read_coordinates(TextScanner& text, const ErrorSite& err, std::uint64_t v);

}  // namespace bisturi::mesh_io
