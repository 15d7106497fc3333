// import_polygons(): the pipeline of procedures 3-6. Each stage lives in construction/.

#include "bisturi/scene/polygon_import.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "bisturi/scene/errors.h"
#include "construction/edge_groups.h"
#include "construction/import_paths.h"
#include "construction/import_report.h"
#include "construction/manifold_writer.h"
#include "construction/orient.h"
#include "construction/prefault.h"
#include "construction/rotation_system.h"
#include "construction/weld.h"

namespace bisturi {

std::string_view to_string(DropReason reason) {
  switch (reason) {
    case DropReason::TooFewDistinctVertices:
      return "fewer than three distinct vertices";
    case DropReason::RepeatedConsecutiveVertex:
      return "a vertex repeated on consecutive corners";
    case DropReason::ZeroArea:
      return "zero area";
  }
  return "unknown";
}

namespace {

using construction::kNone;

void check_input(const PolygonMesh& in) {
  for (std::size_t v = 0; v < in.positions.size(); ++v) {
    const auto& p = in.positions[v];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      throw InputError("vertex " + std::to_string(v) + " has a non-finite coordinate");
    }
  }
  if (in.offsets.empty() || in.offsets.front() != 0 || in.offsets.back() != in.indices.size()) {
    throw InputError("polygon offsets do not cover the index array");
  }
  for (std::size_t f = 0; f + 1 < in.offsets.size(); ++f) {
    if (in.offsets[f + 1] < in.offsets[f]) {
      throw InputError("face " + std::to_string(f) + ": offsets decrease");
    }
    for (std::uint32_t k = in.offsets[f]; k < in.offsets[f + 1]; ++k) {
      if (in.indices[k] >= in.positions.size()) {
        throw InputError("face " + std::to_string(f) + ": vertex index " +
                         std::to_string(in.indices[k]) + " is out of range (" +
                         std::to_string(in.positions.size()) + " vertices)");
      }
    }
  }
}

/// Why a face cannot be kept, if it cannot.
std::optional<DropReason> degenerate(std::span<const std::uint32_t> face,
                                     std::span<const Dlfl::Vec3> positions) {
  const std::size_t n = face.size();
  std::size_t distinct = 0;
  for (std::size_t i = 0; i < n && distinct < 3; ++i) {
    if (std::find(face.begin(), face.begin() + static_cast<std::ptrdiff_t>(i), face[i]) ==
        face.begin() + static_cast<std::ptrdiff_t>(i)) {
      ++distinct;
    }
  }
  if (distinct < 3) return DropReason::TooFewDistinctVertices;
  for (std::size_t i = 0; i < n; ++i) {
    if (face[i] == face[i + 1 == n ? 0 : i + 1]) return DropReason::RepeatedConsecutiveVertex;
  }
  // Twice the vector area (Newell), against the squared perimeter: exact zero for collinear
  // corners up to rounding.
  Dlfl::Vec3 normal(0.0);
  double squared_sides = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const Dlfl::Vec3& p = positions[face[i]];
    const Dlfl::Vec3& q = positions[face[i + 1 == n ? 0 : i + 1]];
    normal.x += (p.y - q.y) * (p.z + q.z);
    normal.y += (p.z - q.z) * (p.x + q.x);
    normal.z += (p.x - q.x) * (p.y + q.y);
    const Dlfl::Vec3 d = q - p;
    squared_sides += d.x * d.x + d.y * d.y + d.z * d.z;
  }
  const double area2_squared = normal.x * normal.x + normal.y * normal.y + normal.z * normal.z;
  // Most faces pass without square roots: perimeter^2 <= n * (sum of squared sides), so an area
  // above the bound (a factor 4 over it for rounding) is above the exact test's too. Only at
  // normal magnitudes, where rounding errors stay relative; the rest takes the exact test.
  const double bound = static_cast<double>(n) * squared_sides;
  if (bound > 1e-140 && bound < 1e140 && area2_squared > 4e-24 * bound * bound) {
    return std::nullopt;
  }
  double perimeter = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const Dlfl::Vec3 d = positions[face[i + 1 == n ? 0 : i + 1]] - positions[face[i]];
    perimeter += std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
  }
  const double area2 = std::sqrt(area2_squared);
  if (!(area2 > 1e-12 * perimeter * perimeter)) return DropReason::ZeroArea;
  return std::nullopt;
}

}  // namespace

std::optional<ImportResult> construction::import_polygons_via(const PolygonMesh& in,
                                                              bool has_vertex_list,
                                                              const ImportOptions& options,
                                                              construction::ImportPath path) {
  check_input(in);
  ImportResult result;
  ImportReport& report = result.report;
  report.input_vertices = in.positions.size();
  report.input_faces = in.face_count();
  auto progress = [&](std::string_view stage, std::size_t done, std::size_t total) {
    if (options.progress) options.progress(stage, done, total);
  };

  // Procedure 3: one vertex per place where asked (always for soups).
  construction::WeldResult welded;
  const bool weld = !has_vertex_list || options.weld || options.weld_tolerance > 0.0;
  if (weld) {
    progress("weld", 0, in.positions.size());
    welded = options.weld_tolerance > 0.0
                 ? construction::weld_within(in.positions, options.weld_tolerance)
                 : construction::weld_exact(in.positions);
  }
  // Without welding the input positions and indices serve as they are (no copy).
  const std::span<const Dlfl::Vec3> input_positions(in.positions);
  const std::span<const std::uint32_t> welded_index(welded.welded_index);
  auto vertex_at = [&](std::uint32_t input_vertex) {
    return weld ? welded_index[input_vertex] : input_vertex;
  };
  const std::size_t vertex_count = weld ? welded.positions.size() : in.positions.size();
  report.welded_vertices = in.positions.size() - vertex_count;

  // Degenerate faces are dropped and listed; the rest keep their corners. Found first, so that
  // the common input (nothing dropped) needs no copy of its polygons.
  {
    const std::span<const Dlfl::Vec3> positions =
        weld ? std::span<const Dlfl::Vec3>(welded.positions) : input_positions;
    std::vector<std::uint32_t> face;
    for (std::uint32_t f = 0; f < in.face_count(); ++f) {
      face.clear();
      for (std::uint32_t i : in.face(f))
        face.push_back(vertex_at(i));
      if (const auto reason = degenerate(face, positions)) report.dropped.push_back({f, *reason});
    }
  }
  const bool all_kept = report.dropped.empty();
  ScratchVector<std::uint32_t> kept_offsets, kept_from, kept_input_face;
  if (!all_kept) {
    kept_offsets.reserve(in.face_count() - report.dropped.size() + 1);
    kept_offsets.push_back(0);
    kept_from.reserve(in.indices.size());
    kept_input_face.reserve(in.face_count() - report.dropped.size());
    std::size_t next_dropped = 0;
    for (std::uint32_t f = 0; f < in.face_count(); ++f) {
      if (next_dropped < report.dropped.size() && report.dropped[next_dropped].face == f) {
        ++next_dropped;
        continue;
      }
      for (std::uint32_t i : in.face(f))
        kept_from.push_back(vertex_at(i));
      kept_offsets.push_back(static_cast<std::uint32_t>(kept_from.size()));
      kept_input_face.push_back(f);
    }
  }
  const std::span<const std::uint32_t> offsets =
      all_kept ? std::span<const std::uint32_t>(in.offsets) : std::span(kept_offsets);
  const std::size_t nf = offsets.size() - 1;
  auto input_face = [&](std::uint32_t f) { return all_kept ? f : kept_input_face[f]; };

  // The fast path: consistently oriented manifold surfaces (closed or with boundary) written
  // straight into the DLFL. It gives up on anything else (the general path below then builds the
  // same mesh).
  const bool tried_fast = path != construction::ImportPath::kGeneral && !options.use_operators;
  if (path == construction::ImportPath::kFast && !tried_fast) return std::nullopt;
  if (tried_fast) {
    progress("orient", 0, nf);
    BigVector<Dlfl::Vec3> dlfl_positions;
    if (weld) {
      dlfl_positions = std::move(welded.positions);
    } else {
      dlfl_positions.reserve(
          construction::whole_huge_pages(in.positions.size(), sizeof(Dlfl::Vec3)));
      construction::prefault(dlfl_positions.data(), in.positions.size() * sizeof(Dlfl::Vec3));
      dlfl_positions.assign(in.positions.begin(), in.positions.end());
    }
    bool written = false;
    const std::span<const std::uint32_t> indices(in.indices);
    if (!all_kept) {
      written = construction::write_manifold(
          result.mesh, [&](std::uint32_t h) { return kept_from[h]; }, offsets, dlfl_positions,
          report);
    } else if (weld) {
      written = construction::write_manifold(
          result.mesh, [&](std::uint32_t h) { return welded_index[indices[h]]; }, offsets,
          dlfl_positions, report);
    } else {
      written = construction::write_manifold(
          result.mesh, [&](std::uint32_t h) { return indices[h]; }, offsets, dlfl_positions,
          report);
    }
    if (written) {
      if (options.progress)
        options.progress("insert", in.indices.size() / 2, in.indices.size() / 2);
      const std::uint32_t spheres = static_cast<std::uint32_t>(report.isolated_vertices);
      construction::reserve_mapped(result.vertex_of_input, in.positions.size());
      construction::reserve_mapped(result.face_of_input, in.face_count());
      construction::reserve_mapped(result.flipped, in.face_count());
      result.vertex_of_input.resize(in.positions.size());
      for (std::uint32_t v = 0; v < in.positions.size(); ++v)
        result.vertex_of_input[v] = VertexId(vertex_at(v));
      result.flipped.assign(in.face_count(), 0);
      if (all_kept) {
        result.face_of_input.resize(in.face_count());
        for (std::uint32_t f = 0; f < nf; ++f)
          result.face_of_input[f] = FaceId(spheres + f);
      } else {
        result.face_of_input.assign(in.face_count(), FaceId{});
        for (std::uint32_t f = 0; f < nf; ++f)
          result.face_of_input[kept_input_face[f]] = FaceId(spheres + f);
      }
      return result;
    }
    if (path == construction::ImportPath::kFast) return std::nullopt;
    if (weld) welded.positions = std::move(dlfl_positions);
  }

  // The general path works on copies of the kept polygons.
  ScratchVector<std::uint32_t> from;
  if (all_kept) {
    from.resize(in.indices.size());
    for (std::size_t h = 0; h < in.indices.size(); ++h)
      from[h] = vertex_at(in.indices[h]);
  } else {
    from = std::move(kept_from);
  }
  const std::span<const Dlfl::Vec3> positions =
      weld ? std::span<const Dlfl::Vec3>(welded.positions) : input_positions;
  const std::size_t nh = from.size();
  ScratchVector<std::uint32_t> to(nh), face_of(nh);
  for (std::uint32_t f = 0; f < nf; ++f) {
    for (std::uint32_t h = offsets[f]; h < offsets[f + 1]; ++h) {
      to[h] = from[h + 1 == offsets[f + 1] ? offsets[f] : h + 1];
      face_of[h] = f;
    }
  }

  // Procedure 4: orientation, parts, seams; procedure 5: fans and the report.
  if (!tried_fast) progress("orient", 0, nf);
  const construction::EdgeGroups groups = construction::group_edges(from, to, positions.size());
  const construction::Orientation orientation =
      construction::orient_faces(offsets, from, face_of, groups);
  construction::fill_report({offsets, from, to, face_of, positions.size()}, groups, orientation,
                            report);
  report.flipped_faces =
      static_cast<std::size_t>(std::count(orientation.flip.begin(), orientation.flip.end(), 1));
  report.seam_edges = orientation.seam_count;

  // The oriented polygons: a flipped face lists its corners backwards. Side h (local i of a
  // face of n corners) runs backwards as the side starting at local (n - 2 - i) mod n.
  construction::RotationSystem rs;
  ScratchVector<std::uint32_t> oriented(nh), position_of(nh);
  for (std::uint32_t f = 0; f < nf; ++f) {
    const std::uint32_t b = offsets[f];
    const std::uint32_t n = offsets[f + 1] - b;
    for (std::uint32_t i = 0; i < n; ++i) {
      if (orientation.flip[f]) {
        oriented[b + i] = from[b + n - 1 - i];
        position_of[b + i] = b + (2 * n - 2 - i) % n;
      } else {
        oriented[b + i] = from[b + i];
        position_of[b + i] = b + i;
      }
    }
  }
  construction::read_polygon_half_edges(oriented, offsets, rs);
  // Twins across edges in exactly two faces that are not seams; every other side is boundary.
  for (std::uint32_t g = 0; g < groups.count(); ++g) {
    if (groups.size(g) != 2 || orientation.seam[g]) continue;
    const std::uint32_t a = position_of[groups.of(g)[0]];
    const std::uint32_t b = position_of[groups.of(g)[1]];
    rs.twin[a] = b;
    rs.twin[b] = a;
  }
  construction::close_boundaries(rs);

  // Procedure 6: insertion with the operators.
  construction::InsertOptions insert_options;
  if (options.progress) {
    insert_options.progress = [&](std::size_t done, std::size_t total) {
      options.progress("insert", done, total);
    };
  }
  ScratchVector<CornerId> corner_of;
  const std::vector<VertexId> vertices =
      options.use_operators ? construction::insert_rotation_system(result.mesh, rs, positions,
                                                                   insert_options, &corner_of)
                            : construction::assemble_rotation_system(result.mesh, rs, positions,
                                                                     insert_options, &corner_of);

  result.vertex_of_input.resize(in.positions.size());
  for (std::uint32_t v = 0; v < in.positions.size(); ++v) {
    result.vertex_of_input[v] = vertices[vertex_at(v)];
  }
  result.face_of_input.assign(in.face_count(), FaceId{});
  result.flipped.assign(in.face_count(), 0);
  for (std::uint32_t f = 0; f < nf; ++f) {
    result.face_of_input[input_face(f)] = result.mesh.face(corner_of[offsets[f]]);
    result.flipped[input_face(f)] = orientation.flip[f];
  }
  return result;
}

ImportResult import_polygons(const PolygonMesh& in, bool has_vertex_list,
                             const ImportOptions& options) {
  return *construction::import_polygons_via(in, has_vertex_list, options,
                                            construction::ImportPath::kAuto);
}

}  // namespace bisturi
