#pragma once
// Typed integer handles for DLFL elements. A handle is an index into the element arrays of one
// Dlfl; it carries no pointer, so arrays can grow and be compacted freely.

#include <compare>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>

namespace bisturi {

inline constexpr std::uint32_t kInvalidIndex = std::numeric_limits<std::uint32_t>::max();

template <class Tag>
struct Handle {
  std::uint32_t idx = kInvalidIndex;

  constexpr Handle() = default;
  constexpr explicit Handle(std::uint32_t i) : idx(i) {}

  [[nodiscard]] constexpr bool valid() const { return idx != kInvalidIndex; }
  constexpr auto operator<=>(const Handle&) const = default;
};

struct VertexTag {
  static constexpr char kPrefix = 'v';
};
struct CornerTag {
  static constexpr char kPrefix = 'c';
};
struct FaceTag {
  static constexpr char kPrefix = 'f';
};
struct EdgeTag {
  static constexpr char kPrefix = 'e';
};
struct RotationTag {
  static constexpr char kPrefix = 'r';
};

using VertexId = Handle<VertexTag>;
using CornerId = Handle<CornerTag>;
using FaceId = Handle<FaceTag>;
using EdgeId = Handle<EdgeTag>;
using RotationId = Handle<RotationTag>;

/// "v12", "c7", "f3" (or "v<invalid>"): how handles are named in error messages.
template <class Tag>
std::string to_string(Handle<Tag> h) {
  std::string s(1, Tag::kPrefix);
  s += h.valid() ? std::to_string(h.idx) : std::string("<invalid>");
  return s;
}

}  // namespace bisturi

template <class Tag>
struct std::hash<bisturi::Handle<Tag>> {
  std::size_t operator()(bisturi::Handle<Tag> h) const noexcept {
    return std::hash<std::uint32_t>{}(h.idx);
  }
};
