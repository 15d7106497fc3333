#pragma once
// Read-only queries on a Dlfl: valences, neighbourhoods, boundary loops, parts and their
// topology (Euler characteristic with the ring term, genus). Free functions: they keep no state.

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "bisturi/scene/dlfl.h"

namespace bisturi {

/// Number of corners of f (1 for a point sphere).
std::size_t face_valence(const Dlfl& mesh, FaceId f);
/// Number of edge sides that leave v, over all its rotations (0 for a lone point sphere).
std::size_t vertex_valence(const Dlfl& mesh, VertexId v);
/// Number of rotations of v (more than one: a non-manifold junction).
std::size_t rotation_count(const Dlfl& mesh, VertexId v);

std::vector<CornerId> face_corners(const Dlfl& mesh, FaceId f);
std::vector<VertexId> face_vertices(const Dlfl& mesh, FaceId f);
/// The corners of rotation r in rotation order.
std::vector<CornerId> rotation_corners(const Dlfl& mesh, RotationId r);
/// The faces around v, one list per rotation, in rotation order.
std::vector<std::vector<FaceId>> faces_around_vertex(const Dlfl& mesh, VertexId v);
/// The two faces of every pair of e (four or more for a non-manifold edge).
std::vector<FaceId> edge_faces(const Dlfl& mesh, EdgeId e);
/// The two vertices e joins.
std::pair<VertexId, VertexId> edge_vertices(const Dlfl& mesh, EdgeId e);

/// Every labelled face that has sides: each is one boundary loop (a ring).
std::vector<FaceId> boundary_loops(const Dlfl& mesh);
std::vector<EdgeId> non_manifold_edges(const Dlfl& mesh);
std::vector<VertexId> non_manifold_vertices(const Dlfl& mesh);

/// A 2-manifold part: the faces reachable from one another across edge sides. Parts meet only
/// at non-manifold vertices (separate rotations) and non-manifold edges (separate pairs).
struct Part {
  std::vector<FaceId> faces;
};
std::vector<Part> connected_parts(const Dlfl& mesh);

/// Euler-Poincare terms of one part. V counts rotations (a junction vertex counts once in each
/// part it joins), E counts edge pairs, F counts unlabelled faces and R labelled faces (rings).
struct PartTopology {
  std::size_t vertices = 0;
  std::size_t edges = 0;
  std::size_t faces = 0;
  std::size_t rings = 0;
  /// V - E + F: the Euler characteristic of the part as a surface with boundary.
  std::int64_t euler_characteristic = 0;
  /// (2 - (V - E + F + R)) / 2: every DLFL part is orientable, so this is its genus.
  std::int64_t genus = 0;
};
PartTopology part_topology(const Dlfl& mesh, const Part& part);

/// Whole-mesh figures for reports and the demo.
struct MeshStatistics {
  std::size_t vertices = 0, corners = 0, faces = 0, edges = 0, rotations = 0;
  std::size_t bounding_faces = 0, point_spheres = 0;
  std::size_t non_manifold_vertices = 0, non_manifold_edges = 0;
  std::vector<PartTopology> parts;
};
MeshStatistics mesh_statistics(const Dlfl& mesh);

}  // namespace bisturi
