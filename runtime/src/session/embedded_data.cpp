// The embedded data files (see embedded_data.h); the bytes come from runtime/CMakeLists.txt.

#include "embedded_data.h"

#include "embedded_liver.h"

namespace bisturi::runtime {

std::optional<std::span<const std::byte>> embedded_file(std::string_view name) {
  if (name == "data/liver.nrrd") {
    return std::span<const std::byte>(reinterpret_cast<const std::byte*>(kEmbeddedLiverNrrd),
                                      sizeof kEmbeddedLiverNrrd);
  }
  return std::nullopt;
}

}  // namespace bisturi::runtime
