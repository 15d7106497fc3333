#include "import_report.h"

#include <algorithm>
#include <numeric>

namespace bisturi::construction {

namespace {

class UnionFind {
 public:
  explicit UnionFind(std::size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0u); }
  std::uint32_t find(std::uint32_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  void join(std::uint32_t a, std::uint32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  ScratchVector<std::uint32_t> parent_;
};

/// The face's corners from its smallest vertex, in the direction whose second vertex is
/// smaller, so that a face and its reverse (from any start) read alike.
void canonical_cycle(std::span<const std::uint32_t> face, ScratchVector<std::uint32_t>& out) {
  const std::size_t n = face.size();
  const auto m =
      static_cast<std::size_t>(std::min_element(face.begin(), face.end()) - face.begin());
  const bool forward = face[(m + 1) % n] <= face[(m + n - 1) % n];
  out.clear();
  for (std::size_t i = 0; i < n; ++i)
    out.push_back(face[forward ? (m + i) % n : (m + n - i) % n]);
}

/// Faces with the same vertex cycle as an earlier face. Two such faces share every edge, so the
/// candidates for a face are the earlier faces on the edge group of its first side: no hashing.
std::size_t count_duplicate_faces(const KeptFaces& kept, const EdgeGroups& groups) {
  std::size_t duplicates = 0;
  ScratchVector<std::uint32_t> mine, theirs;
  const std::size_t nf = kept.offsets.size() - 1;
  for (std::uint32_t f = 0; f < nf; ++f) {
    const std::uint32_t b = kept.offsets[f];
    const auto face = kept.from.subspan(b, kept.offsets[f + 1] - b);
    bool computed = false;
    for (std::uint32_t side : groups.of(groups.group_of[b])) {
      const std::uint32_t g = kept.face_of[side];
      if (g >= f || kept.offsets[g + 1] - kept.offsets[g] != face.size()) continue;
      // Cheap reject first: a duplicate holds every vertex of the face.
      const auto other = kept.from.subspan(kept.offsets[g], face.size());
      if (face.size() <= 16 && !std::all_of(face.begin(), face.end(), [&](std::uint32_t v) {
            return std::find(other.begin(), other.end(), v) != other.end();
          })) {
        continue;
      }
      if (!computed) canonical_cycle(face, mine);
      computed = true;
      canonical_cycle(kept.from.subspan(kept.offsets[g], face.size()), theirs);
      if (mine == theirs) {
        ++duplicates;
        break;
      }
    }
  }
  return duplicates;
}

}  // namespace

void fill_report(const KeptFaces& kept, const EdgeGroups& groups, const Orientation& orientation,
                 ImportReport& report) {
  const std::size_t nh = kept.from.size();
  const std::size_t nf = kept.offsets.size() - 1;
  const std::size_t nv = kept.vertex_count;
  auto next = [&](std::uint32_t h) {
    return h + 1 == kept.offsets[kept.face_of[h] + 1] ? kept.offsets[kept.face_of[h]] : h + 1;
  };

  // Fans: corners (a half-edge stands for the corner at its tail) joined across every edge in
  // exactly two faces, seams included (the definition is combinatorial, not oriented).
  UnionFind fans(nh);
  for (std::uint32_t g = 0; g < groups.count(); ++g) {
    if (groups.size(g) != 2) continue;
    const std::uint32_t h = groups.of(g)[0];
    const std::uint32_t k = groups.of(g)[1];
    if (kept.from[h] == kept.from[k]) {
      fans.join(h, k);
      fans.join(next(h), next(k));
    } else {
      fans.join(h, next(k));
      fans.join(next(h), k);
    }
  }
  ScratchVector<std::uint32_t> fan_count(nv, 0);
  for (std::uint32_t h = 0; h < nh; ++h) {
    if (fans.find(h) == h) ++fan_count[kept.from[h]];
  }
  ScratchVector<char> nonmanifold(nv, 0);
  for (std::size_t v = 0; v < nv; ++v)
    nonmanifold[v] = fan_count[v] > 1 ? 1 : 0;
  report.nonmanifold_edges = 0;
  for (std::uint32_t g = 0; g < groups.count(); ++g) {
    if (groups.size(g) < 3) continue;
    ++report.nonmanifold_edges;
    const std::uint32_t h = groups.of(g)[0];
    nonmanifold[kept.from[h]] = 1;
    nonmanifold[kept.to[h]] = 1;
  }
  report.nonmanifold_vertices =
      static_cast<std::size_t>(std::count(nonmanifold.begin(), nonmanifold.end(), 1));
  report.vertices = static_cast<std::size_t>(
      std::count_if(fan_count.begin(), fan_count.end(), [](std::uint32_t c) { return c > 0; }));
  report.isolated_vertices = nv - report.vertices;
  report.edges = groups.count();
  report.faces = nf;
  report.duplicate_faces = count_duplicate_faces(kept, groups);

  // Parts, one at a time, with stamps instead of clearing per-part arrays.
  ScratchVector<std::uint32_t> part_offsets(orientation.part_count + 1, 0);
  for (std::uint32_t f = 0; f < nf; ++f)
    ++part_offsets[orientation.part_of_face[f] + 1];
  for (std::size_t p = 0; p < orientation.part_count; ++p)
    part_offsets[p + 1] += part_offsets[p];
  ScratchVector<std::uint32_t> faces_by_part(nf);
  {
    ScratchVector<std::uint32_t> fill(part_offsets.begin(), part_offsets.end() - 1);
    for (std::uint32_t f = 0; f < nf; ++f)
      faces_by_part[fill[orientation.part_of_face[f]]++] = f;
  }
  ScratchVector<std::uint32_t> vertex_stamp(nv, 0), group_stamp(groups.count(), 0);
  ScratchVector<std::uint32_t> sides_in_part(groups.count(), 0);
  ScratchVector<std::uint32_t> fan_stamp(nh, 0), fan_first_boundary(nh, 0);
  UnionFind loops(nh);
  report.parts.clear();
  for (std::uint32_t p = 0; p < orientation.part_count; ++p) {
    const std::uint32_t stamp = p + 1;
    ImportPart part;
    part.orientable = orientation.part_orientable[p] != 0;
    const auto faces =
        std::span(faces_by_part).subspan(part_offsets[p], part_offsets[p + 1] - part_offsets[p]);
    part.faces = faces.size();
    for (std::uint32_t f : faces) {
      for (std::uint32_t h = kept.offsets[f]; h < kept.offsets[f + 1]; ++h) {
        if (vertex_stamp[kept.from[h]] != stamp) {
          vertex_stamp[kept.from[h]] = stamp;
          ++part.vertices;
        }
        const std::uint32_t g = groups.group_of[h];
        if (group_stamp[g] != stamp) {
          group_stamp[g] = stamp;
          sides_in_part[g] = 0;
          ++part.edges;
        }
        ++sides_in_part[g];
      }
    }
    // Boundary sides: edges in only one face of the part. Loops join them at shared fans.
    std::size_t boundary_sides = 0;
    std::size_t merged = 0;
    auto attach = [&](std::uint32_t corner, std::uint32_t side) {
      const std::uint32_t fan = fans.find(corner);
      if (fan_stamp[fan] != stamp) {
        fan_stamp[fan] = stamp;
        fan_first_boundary[fan] = side;
      } else if (loops.find(fan_first_boundary[fan]) != loops.find(side)) {
        loops.join(fan_first_boundary[fan], side);
        ++merged;
      }
    };
    for (std::uint32_t f : faces) {
      for (std::uint32_t h = kept.offsets[f]; h < kept.offsets[f + 1]; ++h) {
        if (sides_in_part[groups.group_of[h]] != 1) continue;
        ++boundary_sides;
        attach(h, h);
        attach(next(h), h);
      }
    }
    part.closed = boundary_sides == 0;
    part.boundary_loops = boundary_sides - merged;
    part.euler = static_cast<std::int64_t>(part.vertices) - static_cast<std::int64_t>(part.edges) +
                 static_cast<std::int64_t>(part.faces);
    if (part.orientable) {
      part.genus = (2 - part.euler - static_cast<std::int64_t>(part.boundary_loops)) / 2;
    }
    report.parts.push_back(part);
  }
}

}  // namespace bisturi::construction
