// Where the triangle sides of the cube cases find their twins (see cell_topology.h).

#include "cell_topology.h"

#include <algorithm>
#include <stdexcept>

#include "cube_cases.h"

namespace bisturi::surface {

namespace {

CellTopology build_topology(const surface::CubeCases& cases) {
  CellTopology topo;
  topo.face_sides.assign(cases.entries.size(), 0);
  for (auto& c : topo.side_class)
    c.assign(cases.triangle_codes.size(), 0);
  std::vector<std::array<std::uint8_t, 2>> sides;
  for (std::size_t e = 0; e < cases.entries.size(); ++e) {
    const surface::CaseEntry& entry = cases.entries[e];
    const std::size_t base = 3 * std::size_t{entry.first_triangle};
    const std::size_t n = 3 * std::size_t{entry.triangle_count};
    if (n + CellTopology::kInterior > 256) throw std::logic_error("cube cases: entry too large");
    for (int flip = 0; flip < 2; ++flip) {
      sides.clear();
      for (std::size_t t = base; t < base + n; t += 3) {
        const std::uint8_t* c = cases.triangle_codes.data() + t;
        const std::array<std::uint8_t, 3> v =
            flip != 0 ? std::array{c[0], c[2], c[1]} : std::array{c[0], c[1], c[2]};
        for (std::size_t k = 0; k < 3; ++k)
          sides.push_back({v[k], v[(k + 1) % 3]});
      }
      for (std::size_t s = 0; s < n; ++s) {
        const auto [a, b] = sides[s];
        std::size_t twin = n;
        for (std::size_t r = 0; r < n && twin == n; ++r) {
          if (sides[r][0] == b && sides[r][1] == a) twin = r;
        }
        std::uint8_t cls = 0;
        if (twin < n) {
          cls = static_cast<std::uint8_t>(CellTopology::kInterior + twin);
        } else {
          std::size_t face = 6;
          for (std::size_t f = 0; f < 6 && a < 12 && b < 12; ++f) {
            const auto& fe = cases.faces[f].edges;
            if (std::find(fe.begin(), fe.end(), a) != fe.end() &&
                std::find(fe.begin(), fe.end(), b) != fe.end()) {
              face = f;
            }
          }
          if (face == 6) throw std::logic_error("cube cases: an open side off the cube faces");
          cls = static_cast<std::uint8_t>(face);
          if (flip == 0)
            topo.face_sides[e] =
                static_cast<std::uint16_t>(topo.face_sides[e] + (1u << (2 * face)));
        }
        topo.side_class[static_cast<std::size_t>(flip)][base + s] = cls;
      }
    }
  }
  return topo;
}

}  // namespace

const CellTopology& cell_topology() {
  static const CellTopology topo = build_topology(surface::cube_cases());
  return topo;
}

}  // namespace bisturi::surface
