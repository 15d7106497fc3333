#pragma once
// Files embedded in the program at build time, so that the default scene needs no file on disk:
// config/data/liver.nrrd as "data/liver.nrrd" (its name relative to config/, as
// config/liver.toml names it).

#include <cstddef>
#include <optional>
#include <span>
#include <string_view>

namespace bisturi::runtime {

/// The bytes of the embedded file of that name; nothing for other names.
std::optional<std::span<const std::byte>> embedded_file(std::string_view name);

}  // namespace bisturi::runtime
