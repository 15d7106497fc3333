#include "orient.h"

namespace bisturi::construction {

Orientation orient_faces(std::span<const std::uint32_t> offsets,
                         std::span<const std::uint32_t> from,
                         std::span<const std::uint32_t> face_of, const EdgeGroups& groups) {
  const std::size_t nf = offsets.size() - 1;
  constexpr char kUnseen = -1;
  Orientation o;
  o.flip.assign(nf, kUnseen);
  o.part_of_face.assign(nf, 0);
  o.seam.assign(groups.count(), 0);
  ScratchVector<std::uint32_t> stack;
  for (std::uint32_t start = 0; start < nf; ++start) {
    if (o.flip[start] != kUnseen) continue;
    const auto part = static_cast<std::uint32_t>(o.part_count++);
    o.part_orientable.push_back(1);
    o.flip[start] = 0;
    o.part_of_face[start] = part;
    stack.push_back(start);
    while (!stack.empty()) {
      const std::uint32_t f = stack.back();
      stack.pop_back();
      for (std::uint32_t h = offsets[f]; h < offsets[f + 1]; ++h) {
        const std::uint32_t g = groups.group_of[h];
        if (groups.size(g) != 2) continue;  // boundary or non-manifold: not crossed
        const auto sides = groups.of(g);
        const std::uint32_t k = sides[0] == h ? sides[1] : sides[0];
        const std::uint32_t other = face_of[k];
        // Consistent neighbours run the shared edge in opposite directions once flipped.
        const char same_direction = from[h] == from[k] ? 1 : 0;
        if (o.flip[other] == kUnseen) {
          o.flip[other] = static_cast<char>(same_direction ^ o.flip[f]);
          o.part_of_face[other] = part;
          stack.push_back(other);
        } else if ((same_direction ^ o.flip[f] ^ o.flip[other]) != 0 && !o.seam[g]) {
          o.seam[g] = 1;
          ++o.seam_count;
          o.part_orientable[part] = 0;
        }
      }
    }
  }
  return o;
}

}  // namespace bisturi::construction
