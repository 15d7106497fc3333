#pragma once
// The outputs of the marching-cubes extractor (marching_cubes.cpp): MeshSink collects an indexed
// triangle mesh in one pass; the direct DLFL build runs CountSink (vertex positions and the
// counts that size the arrays) and then DlflSink (every record written once). The extractor
// calls vertex() for each crossed edge and triangles() for each mixed cell.

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/scene/big_vector.h"
#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/errors.h"
#include "bisturi/scene/oriented_builder.h"
#include "cell_topology.h"
#include "construction/raw_arrays.h"
#include "cube_cases.h"

namespace bisturi::surface {

constexpr std::uint32_t kNoVertex = std::numeric_limits<std::uint32_t>::max();

/// Vertex ids of the 12 cube edges, then of the entry's extra (centroid) vertices.
using CellIds = std::array<std::uint32_t, 12 + 6>;

/// Output of the single-pass extraction: an indexed triangle mesh.
class MeshSink {
 public:
  static constexpr bool kPlaces = true;  // computes vertex positions
  static constexpr bool kStats = true;   // counts cells for ExtractionStats

  MeshSink(PolygonMesh& mesh, bool flip) : mesh_(mesh), flip_(flip) {}

  std::uint32_t vertex(const glm::dvec3& world) {
    const std::size_t n = mesh_.positions.size();
    if (n >= kNoVertex) throw InputError("extract_isosurface: more than 2^32 - 1 vertices");
    mesh_.positions.push_back(world);
    return static_cast<std::uint32_t>(n);
  }
  [[nodiscard]] const glm::dvec3& position(std::uint32_t v) const { return mesh_.positions[v]; }

  void triangles(const surface::CubeCases& cases, const surface::CaseEntry& entry,
                 const CellIds& ids, std::int64_t /*i*/, std::int64_t /*j*/, std::int64_t /*k*/) {
    const std::uint8_t* codes = cases.triangle_codes.data() + 3 * std::size_t{entry.first_triangle};
    auto& indices = mesh_.indices;
    auto& offsets = mesh_.offsets;
    if (indices.size() + 3 * std::size_t{entry.triangle_count} > kNoVertex) {
      throw InputError("extract_isosurface: more than 2^32 - 1 indices");
    }
    for (std::uint32_t t = 0; t < entry.triangle_count; ++t, codes += 3) {
      const std::uint32_t a = ids[codes[0]], b = ids[codes[1]], c = ids[codes[2]];
      if (flip_) {
        indices.insert(indices.end(), {a, c, b});
      } else {
        indices.insert(indices.end(), {a, b, c});
      }
      offsets.push_back(static_cast<std::uint32_t>(indices.size()));
    }
  }

 private:
  PolygonMesh& mesh_;
  bool flip_;
};

/// First pass of the DLFL build: the vertex positions (in their final order) and the counts that
/// size the arrays. It reads the volume, so the second pass need not (but for the decider).
class CountSink {
 public:
  static constexpr bool kPlaces = true;
  static constexpr bool kStats = true;

  CountSink(const surface::CubeCases& cases, std::int64_t ncx, std::int64_t ncy, std::int64_t ncz)
      : cases_(cases), topo_(cell_topology()), last_{ncx - 1, ncy - 1, ncz - 1} {}

  std::uint32_t vertex(const glm::dvec3& world) {
    const std::size_t n = positions_.size();
    if (n >= kNoVertex) throw InputError("extract_isosurface: more than 2^32 - 1 vertices");
    positions_.push_back(world);
    return static_cast<std::uint32_t>(n);
  }
  [[nodiscard]] const glm::dvec3& position(std::uint32_t v) const { return positions_[v]; }

  void triangles(const surface::CubeCases& /*cases*/, const surface::CaseEntry& entry,
                 const CellIds& /*ids*/, std::int64_t i, std::int64_t j, std::int64_t k) {
    triangles_ += entry.triangle_count;
    const std::array<std::int64_t, 3> cell{i, j, k};
    if (cell[0] != 0 && cell[1] != 0 && cell[2] != 0 && cell[0] != last_[0] &&
        cell[1] != last_[1] && cell[2] != last_[2]) {
      return;
    }
    // Sides on the outer faces of the volume (lower faces at index 0, upper at the last) get
    // hole twins.
    const unsigned fs = topo_.face_sides[static_cast<std::size_t>(&entry - cases_.entries.data())];
    for (std::size_t a = 0; a < 3; ++a) {
      if (cell[a] == 0) border_sides_ += (fs >> (4 * a)) & 3;
      if (cell[a] == last_[a]) border_sides_ += (fs >> (4 * a + 2)) & 3;
    }
  }

  BigVector<Dlfl::Vec3>& positions() { return positions_; }
  [[nodiscard]] std::size_t triangle_count() const { return triangles_; }
  [[nodiscard]] std::size_t border_sides() const { return border_sides_; }

 private:
  const surface::CubeCases& cases_;
  const CellTopology& topo_;
  std::array<std::int64_t, 3> last_;
  BigVector<Dlfl::Vec3> positions_;
  std::size_t triangles_ = 0, border_sides_ = 0;
};

/// Second pass of the DLFL build: the records of a Dlfl sized exactly by the counting pass.
/// Triangle t is face t with corners 3t, 3t+1, 3t+2; vertex v has rotation v. A triangle side
/// finds its twin in its own cell (table) or in the slot its neighbour across the cube face left
/// (cells run in x, then y, then z order, so lower faces are read, upper faces written). Sides
/// on the volume's border get a hole twin at the end; hole loops become labelled faces.
class DlflSink {
 public:
  static constexpr bool kPlaces = false;  // the first pass placed every vertex
  static constexpr bool kStats = false;

  /// The sides on one cube face (at most two segments: an ambiguous face), 8 bytes so that a
  /// plane of them stays in cache.
  struct Slot {
    std::array<std::uint32_t, 2> side;
  };
  struct Border {
    std::uint32_t side, from, to;
  };

  DlflSink(construction::RawArrays::View out, bool flip, std::int64_t ncx, std::int64_t ncy,
           std::int64_t ncz)
      : out_(out),
        flip_(flip),
        topo_(cell_topology()),
        last_{ncx - 1, ncy - 1, ncz - 1},
        ncx_(ncx) {
    xslot_.resize(static_cast<std::size_t>(ncx));
    yslot_.resize(static_cast<std::size_t>(ncx));
    zslot_.resize(static_cast<std::size_t>(ncx * ncy));
  }

  std::uint32_t vertex() {
    const std::uint32_t v = vertex_++;
    out_.vertices[v].first = RotationId(v);
    return v;
  }

  void triangles(const surface::CubeCases& cases, const surface::CaseEntry& entry,
                 const CellIds& ids, std::int64_t i, std::int64_t j, std::int64_t k) {
    const std::size_t first = 3 * std::size_t{entry.first_triangle};
    const std::uint8_t* codes = cases.triangle_codes.data() + first;
    const std::uint8_t* cls = topo_.side_class[flip_ ? 1 : 0].data() + first;
    const unsigned face_sides =
        topo_.face_sides[static_cast<std::size_t>(&entry - cases.entries.data())];
    const std::array<std::int64_t, 3> cell{i, j, k};
    const std::size_t zs = static_cast<std::size_t>(j * ncx_ + i);
    // The y and z slots are shared by the lower and the upper face: the lower ones are read from
    // copies, so the upper ones can be written in place.
    const std::array<Slot, 2> lower_yz{yslot_[static_cast<std::size_t>(i)], zslot_[zs]};
    const std::array<const Slot*, 3> lower{
        i > 0 ? &xslot_[static_cast<std::size_t>(i - 1)] : nullptr, &lower_yz[0], &lower_yz[1]};
    const std::array<Slot*, 3> upper{&xslot_[static_cast<std::size_t>(i)],
                                     &yslot_[static_cast<std::size_t>(i)], &zslot_[zs]};
    std::array<std::uint32_t, 3> upper_count{};
    const std::uint32_t h0 = 3 * tri_;
    for (std::uint32_t t = 0; t < entry.triangle_count; ++t, codes += 3, cls += 3) {
      const std::uint32_t face = tri_ + t;
      const std::uint32_t c0 = h0 + 3 * t;
      const std::array<std::uint32_t, 3> v{ids[codes[0]], ids[codes[flip_ ? 2 : 1]],
                                           ids[codes[flip_ ? 1 : 2]]};
      for (std::uint32_t s = 0; s < 3; ++s) {
        const std::uint32_t h = c0 + s;
        const std::uint32_t from = v[s], to = v[s == 2 ? 0 : s + 1];
        const std::uint8_t c = cls[s];
        EdgeId e;
        if (c >= CellTopology::kInterior) {
          const std::uint32_t twin = h0 + (c - CellTopology::kInterior);
          if (twin < h) e = pair(twin, h);
        } else {
          const std::size_t axis = c >> 1;
          const bool up = (c & 1) != 0;
          if (cell[axis] == (up ? last_[axis] : 0)) {
            border_.push_back({h, from, to});
          } else if (up) {
            upper[axis]->side[upper_count[axis]++] = h;
          } else {
            const Slot& l = *lower[axis];
            std::uint32_t twin = l.side[0];
            // Two segments on the face: the twin is the one that ends where h starts.
            if (((face_sides >> (4 * axis)) & 3) == 2 && end_vertex(twin) != from) twin = l.side[1];
            e = pair(twin, h);
          }
        }
        out_.corners[h] = {VertexId(from), FaceId(face), CornerId(s == 2 ? c0 : h + 1),
                           CornerId(s == 0 ? c0 + 2 : h - 1), e};
        out_.rotations[from].corner = CornerId(h);
      }
      out_.faces[face].first = CornerId(c0);
    }
    tri_ += entry.triangle_count;
  }

  /// Hole twins for the border sides, linked into loops (each a labelled face). The hole of side
  /// a -> b runs b -> a and is followed by the hole of the border side that enters a.
  void close_holes(Dlfl& d) {
    const auto nb = static_cast<std::uint32_t>(border_.size());
    const std::uint32_t base = 3 * tri_;
    std::vector<std::uint32_t> entering(nb);
    for (std::uint32_t q = 0; q < nb; ++q)
      entering[q] = q;
    std::sort(entering.begin(), entering.end(),
              [&](std::uint32_t a, std::uint32_t b) { return border_[a].to < border_[b].to; });
    auto entering_side = [&](std::uint32_t v) {
      const auto it = std::lower_bound(
          entering.begin(), entering.end(), v,
          [&](std::uint32_t q, std::uint32_t value) { return border_[q].to < value; });
      if (it == entering.end() || border_[*it].to != v) {
        throw std::logic_error("marching cubes: a border loop does not close");
      }
      return *it;
    };
    for (std::uint32_t q = 0; q < nb; ++q) {
      const Border& b = border_[q];
      const std::uint32_t hole = base + q;
      const std::uint32_t next = base + entering_side(b.from);
      Dlfl::CornerRecord& c = out_.corners[hole];
      c.vertex = VertexId(b.to);
      c.next = CornerId(next);
      out_.corners[next].prev = CornerId(hole);
      c.edge = pair(b.side, hole);
    }
    for (std::uint32_t q = 0; q < nb; ++q) {
      const std::uint32_t hole = base + q;
      if (out_.corners[hole].face.valid()) continue;
      const FaceId f = construction::RawArrays::push_face(d, CornerId(hole), true);
      std::uint32_t x = hole;
      do {
        out_.corners[x].face = f;
        x = out_.corners[x].next.idx;
      } while (x != hole);
    }
  }

  [[nodiscard]] std::uint32_t vertex_count() const { return vertex_; }
  [[nodiscard]] std::uint32_t triangle_count() const { return tri_; }
  [[nodiscard]] std::uint32_t edge_count() const { return edge_; }
  [[nodiscard]] std::size_t border_sides() const { return border_.size(); }

 private:
  /// The vertex a written triangle side ends at.
  [[nodiscard]] std::uint32_t end_vertex(std::uint32_t side) const {
    return out_.corners[side % 3 == 2 ? side - 2 : side + 1].vertex.idx;
  }

  EdgeId pair(std::uint32_t first, std::uint32_t second) {
    const EdgeId e(edge_++);
    out_.edges[e.idx] = {CornerId(first), CornerId(second)};
    out_.corners[first].edge = e;
    return e;
  }

  construction::RawArrays::View out_;
  bool flip_;
  const CellTopology& topo_;
  std::array<std::int64_t, 3> last_;  ///< the last cell index along each axis
  std::int64_t ncx_;
  std::uint32_t vertex_ = 0, tri_ = 0, edge_ = 0;
  ScratchVector<Slot> xslot_, yslot_, zslot_;  // upper-face sides of the cells before
  std::vector<Border> border_;
};

}  // namespace bisturi::surface
