#pragma once
// Builds the DLFL of a consistently oriented polygon mesh whose edges and vertices are manifold
// (closed, or open with boundary loops), with the DLFL operators only.
//
// Method: the target rotation system is read off the polygons (half-edges, with every boundary
// loop closed by a hole face). With join_vertices, it is built with the operators: vertices are
// created as point spheres, a spanning forest of edges joins them (merges), then every other edge
// is inserted next to its predecessor in the target rotation of each end; when every rotation
// matches the target, every face does too; hole faces are labelled as boundary. Without joins,
// the same final structure is written in one linear pass (the bulk assembler of the import,
// tested against the operator path), about ten times faster on large meshes.
//
// Inputs that are not oriented manifolds (an edge used twice in one direction, an edge in three
// faces, two fans at one vertex) are refused with an InputError naming the faces or vertex; the
// general construction (procedures 3-6 of the seed) handles those.

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "bisturi/scene/dlfl.h"

namespace bisturi {

/// Polygons as one index array with offsets (face i is indices[offsets[i] .. offsets[i+1])).
struct PolygonMesh {
  BigVector<Dlfl::Vec3> positions;
  BigVector<std::uint32_t> indices;
  BigVector<std::uint32_t> offsets{0};

  void add_face(std::initializer_list<std::uint32_t> face);
  void add_face(std::span<const std::uint32_t> face);
  [[nodiscard]] std::size_t face_count() const { return offsets.size() - 1; }
  [[nodiscard]] std::span<const std::uint32_t> face(std::size_t i) const {
    return {indices.data() + offsets[i], offsets[i + 1] - offsets[i]};
  }
};

struct BuildOptions {
  /// Input vertex i becomes a new rotation of existing vertex join_vertices[i] when that handle is
  /// valid (shared vertices of non-manifold junctions); empty means all vertices are new.
  std::vector<VertexId> join_vertices;
  /// Called with (done, total) edge insertions, about every 1% of the work.
  std::function<void(std::size_t, std::size_t)> progress;
};

/// Appends the mesh to `dlfl` and returns the vertex handle of every input vertex. Throws
/// InputError (and leaves `dlfl` unchanged) when the input is not an oriented manifold.
std::vector<VertexId> append_oriented_manifold(Dlfl& dlfl, const PolygonMesh& mesh,
                                               const BuildOptions& options = {});

/// A new Dlfl holding the mesh.
Dlfl build_oriented_manifold(const PolygonMesh& mesh, const BuildOptions& options = {});

}  // namespace bisturi
