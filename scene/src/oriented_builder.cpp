#include "bisturi/scene/oriented_builder.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "bisturi/scene/errors.h"
#include "construction/rotation_system.h"

namespace bisturi {

void PolygonMesh::add_face(std::initializer_list<std::uint32_t> face) {
  add_face(std::span<const std::uint32_t>(face.begin(), face.size()));
}

void PolygonMesh::add_face(std::span<const std::uint32_t> face) {
  indices.insert(indices.end(), face.begin(), face.end());
  offsets.push_back(static_cast<std::uint32_t>(indices.size()));
}

namespace {

using construction::kNone;
using construction::RotationSystem;

void check_input(const PolygonMesh& mesh) {
  const std::size_t nv = mesh.positions.size();
  for (std::size_t v = 0; v < nv; ++v) {
    const auto& p = mesh.positions[v];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      throw InputError("vertex " + std::to_string(v) + " has a non-finite coordinate");
    }
  }
  if (mesh.offsets.empty() || mesh.offsets.back() != mesh.indices.size()) {
    throw InputError("polygon offsets do not cover the index array");
  }
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const auto face = mesh.face(f);
    if (face.size() < 3) {
      throw InputError("face " + std::to_string(f) + " has " + std::to_string(face.size()) +
                       " vertices (at least 3 needed)");
    }
    for (std::size_t k = 0; k < face.size(); ++k) {
      if (face[k] >= nv) {
        throw InputError("face " + std::to_string(f) + ": vertex index " + std::to_string(face[k]) +
                         " is out of range (" + std::to_string(nv) + " vertices)");
      }
      if (face[k] == face[(k + 1) % face.size()]) {
        throw InputError("face " + std::to_string(f) + " repeats vertex " +
                         std::to_string(face[k]) + " on consecutive corners");
      }
    }
  }
}

std::uint32_t face_of(const PolygonMesh& mesh, std::uint32_t half_edge) {
  const auto it = std::upper_bound(mesh.offsets.begin(), mesh.offsets.end(), half_edge);
  return static_cast<std::uint32_t>(it - mesh.offsets.begin() - 1);
}

/// Twins by walking each vertex's outgoing half-edges; the same directed edge twice means
/// inconsistent orientation or a non-manifold edge, which this builder refuses.
RotationSystem read_target(const PolygonMesh& mesh) {
  const std::size_t nv = mesh.positions.size();
  RotationSystem rs;
  construction::read_polygon_half_edges(mesh.indices, mesh.offsets, rs);
  const std::size_t nh = rs.from.size();
  std::vector<std::uint32_t> out_offsets(nv + 1, 0);
  for (std::uint32_t u : rs.from)
    ++out_offsets[u + 1];
  for (std::size_t v = 0; v < nv; ++v)
    out_offsets[v + 1] += out_offsets[v];
  std::vector<std::uint32_t> out(nh);
  {
    std::vector<std::uint32_t> fill(out_offsets.begin(), out_offsets.end() - 1);
    for (std::uint32_t h = 0; h < nh; ++h)
      out[fill[rs.from[h]]++] = h;
  }
  for (std::size_t u = 0; u < nv; ++u) {
    auto first = out.begin() + out_offsets[u];
    auto last = out.begin() + out_offsets[u + 1];
    std::sort(first, last, [&](std::uint32_t a, std::uint32_t b) { return rs.to[a] < rs.to[b]; });
    for (auto it = first; it + 1 < last; ++it) {
      if (rs.to[*it] == rs.to[*(it + 1)]) {
        throw InputError("edge " + std::to_string(u) + "-" + std::to_string(rs.to[*it]) +
                         " runs the same way in faces " + std::to_string(face_of(mesh, *it)) +
                         " and " + std::to_string(face_of(mesh, *(it + 1))) +
                         ": the faces are inconsistently oriented or the edge is non-manifold");
      }
    }
  }
  for (std::uint32_t h = 0; h < nh; ++h) {
    const std::uint32_t w = rs.to[h];
    for (std::uint32_t k = out_offsets[w]; k < out_offsets[w + 1]; ++k) {
      if (rs.to[out[k]] == rs.from[h]) {
        rs.twin[h] = out[k];
        break;
      }
    }
  }
  construction::close_boundaries(rs);
  // One fan per vertex: two fans meet only at a non-manifold (e.g. bow-tie) vertex.
  std::vector<char> has_fan(nv, 0);
  for (std::uint32_t vertex : rs.fan_vertex) {
    if (has_fan[vertex]++) {
      throw InputError("vertex " + std::to_string(vertex) +
                       " is non-manifold: its faces form more than one fan (e.g. a bow-tie)");
    }
  }
  return rs;
}

}  // namespace

std::vector<VertexId> append_oriented_manifold(Dlfl& dlfl, const PolygonMesh& mesh,
                                               const BuildOptions& options) {
  check_input(mesh);
  const std::size_t nv = mesh.positions.size();
  if (!options.join_vertices.empty()) {
    if (options.join_vertices.size() != nv) {
      throw InputError("join_vertices has " + std::to_string(options.join_vertices.size()) +
                       " entries for " + std::to_string(nv) + " vertices");
    }
    for (std::size_t i = 0; i < nv; ++i) {
      const VertexId v = options.join_vertices[i];
      if (v.valid() && !dlfl.alive(v)) {
        throw InputError("join_vertices[" + std::to_string(i) + "] names " + to_string(v) +
                         ", which is not a live vertex of the mesh");
      }
    }
  }
  const RotationSystem rs = read_target(mesh);
  construction::InsertOptions insert_options;
  insert_options.join_vertices = options.join_vertices;
  insert_options.progress = options.progress;
  // Without joins the final structure is written in one pass: the same DLFL the operators reach
  // one insertion at a time (the import tests check the two paths agree), at a fraction of the
  // cost. Joining existing vertices needs the operators, which find the edges already there.
  if (options.join_vertices.empty()) {
    return construction::assemble_rotation_system(dlfl, rs, mesh.positions, insert_options);
  }
  return construction::insert_rotation_system(dlfl, rs, mesh.positions, insert_options);
}

Dlfl build_oriented_manifold(const PolygonMesh& mesh, const BuildOptions& options) {
  Dlfl dlfl;
  append_oriented_manifold(dlfl, mesh, options);
  return dlfl;
}

}  // namespace bisturi
