#pragma once
// The DLFL (doubly linked face list) with the two extensions of the seed text (section 4):
// labelled boundary faces (open 2-manifolds) and vertex rotation lists (non-manifold meshes).
//
// Storage, all typed integer handles into arrays (no pointers):
// - Face: a circular doubly linked list of corners (next/prev live in the corner).
// - Corner: one occurrence of a vertex in a face. The corner c starts the side c -> next(c); the
//   edge of that side is stored in the corner. A face of one corner is a point sphere (no edge).
// - Edge: a list of corner pairs (a, b), a starting the side v1 -> v2 and b the side v2 -> v1. A
//   manifold edge has one pair; a non-manifold edge has one pair per rotation it lives in.
// - Vertex: a list of rotations. A rotation is the cyclic list of the vertex's corners that one
//   2-manifold sheet sees; it is walked through the edges (rot_next(c) is the partner of the side
//   that enters c), so it needs no links of its own and cannot disagree with the faces.
//
// Operators validate their arguments first and throw TopologyError without touching anything when
// they would break an invariant. Deleted elements go to free lists and are reused; compact()
// renumbers everything densely. Attribute arrays registered in the property registries follow
// creation, reuse and renumbering.

#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/scene/big_vector.h"
#include "bisturi/scene/handles.h"
#include "bisturi/scene/property.h"

namespace bisturi {

/// Which face keeps the label when insert_edge splits a labelled face (procedure 1): Forward is
/// f1' (the face that keeps the corners' predecessor and successor in the direction of insertion,
/// the one holding c2), Backward is f1'' (the one holding c1).
enum class LabelSide : std::uint8_t { Forward, Backward };

struct InsertEdgeOptions {
  LabelSide label_side = LabelSide::Forward;
  /// Refuse to merge two labelled faces whose geometric orientations (Newell normals) are
  /// opposite (seed figure 39). Faces with a vanishing normal are not judged.
  bool check_label_orientation = true;
};

struct InsertEdgeResult {
  EdgeId edge;
  CornerId side12;               ///< corner at v1 that starts the new side v1 -> v2
  CornerId side21;               ///< corner at v2 that starts the new side v2 -> v1
  bool split = false;            ///< true: c1 and c2 were cofacial and their face was split
  FaceId face_forward;           ///< face holding side12 (f1' of procedure 1, or the merged face)
  FaceId face_backward;          ///< face holding side21 (f1'' of procedure 1, or the merged face)
  bool joined_existing = false;  ///< the pair joined an edge that already lives in another rotation
};

struct DeleteEdgeResult {
  bool split = false;  ///< true: both sides were in one face, which split in two
  FaceId face_a;       ///< face now holding what followed side a (the surviving/merged face)
  FaceId face_b;       ///< after a split, the other face; else equal to face_a
};

struct AddRotationResult {
  RotationId rotation;
  CornerId corner;  ///< the corner of the new point sphere
  FaceId face;      ///< the new point-sphere face
};

struct CornerPair {
  CornerId a;  ///< starts side v1 -> v2
  CornerId b;  ///< starts side v2 -> v1
};

namespace construction {
class BulkAssembler;
class RawArrays;
}  // namespace construction

class Dlfl {
 public:
  using Vec3 = glm::dvec3;

  Dlfl() = default;

  // ---- The four operators of the seed, with the boundary and non-manifold extensions ----

  /// CreateVertex: a new vertex with one rotation holding one corner in a new point-sphere face.
  VertexId create_vertex(const Vec3& position = Vec3(0.0));
  /// DeleteVertex: only for a vertex with one rotation whose single corner is alone in its face.
  void delete_vertex(VertexId v);
  /// InsertEdge(c1, c2): cofacial corners split their face, others merge their two faces
  /// (corners repeat so both sides of the new edge exist). Labels follow procedure 1. When the
  /// two ends are already joined by an edge in another rotation, the new pair joins that edge.
  InsertEdgeResult insert_edge(CornerId c1, CornerId c2, const InsertEdgeOptions& options = {});
  /// DeleteEdge(e) for every pair of e (one for a manifold edge). Labels follow procedure 2.
  DeleteEdgeResult delete_edge(EdgeId e);
  /// DeleteEdge of the one pair that `side` belongs to: the exact inverse of insert_edge.
  DeleteEdgeResult delete_edge_pair(CornerId side);

  // ---- Boundary extension (section 4.2) ----
  void set_bounding(FaceId f, bool bounding);
  [[nodiscard]] bool is_bounding(FaceId f) const;

  // ---- Non-manifold extension (section 4.3) ----
  /// AddRotation(v): a new rotation on v with a new point-sphere face.
  AddRotationResult add_rotation(VertexId v);
  /// CleanRotations(v): removes point-sphere rotations, keeping the first if all are.
  void clean_rotations(VertexId v);

  // ---- Element access (handles must be alive; checked in debug builds) ----
  [[nodiscard]] VertexId vertex(CornerId c) const { return corners_[c.idx].vertex; }
  [[nodiscard]] FaceId face(CornerId c) const { return corners_[c.idx].face; }
  [[nodiscard]] CornerId next(CornerId c) const { return corners_[c.idx].next; }
  [[nodiscard]] CornerId prev(CornerId c) const { return corners_[c.idx].prev; }
  /// The edge of the side that starts at c (invalid for a point-sphere corner).
  [[nodiscard]] EdgeId edge(CornerId c) const { return corners_[c.idx].edge; }
  /// The corner that starts the opposite side of c's side (invalid for a point sphere).
  [[nodiscard]] CornerId partner(CornerId c) const {
    const EdgeId e = corners_[c.idx].edge;
    if (!e.valid()) return CornerId{};
    const CornerPair& p = edges_[e.idx];  // the primary pair: every manifold edge's only one
    if (p.a == c) return p.b;
    if (p.b == c) return p.a;
    const CornerPair q = pair_of(c);
    return q.a == c ? q.b : q.a;
  }
  /// The next corner of c's rotation: the partner of the side that enters c.
  [[nodiscard]] CornerId rot_next(CornerId c) const {
    const CornerId entering = corners_[c.idx].prev;
    return entering == c ? c : partner(entering);  // a point sphere is its own rotation
  }
  [[nodiscard]] bool is_point_sphere(CornerId c) const { return corners_[c.idx].next == c; }

  [[nodiscard]] CornerId first_corner(FaceId f) const { return faces_[f.idx].first; }
  [[nodiscard]] RotationId first_rotation(VertexId v) const { return vertices_[v.idx].first; }
  [[nodiscard]] RotationId next_rotation(RotationId r) const;
  /// A corner of rotation r; the others follow by rot_next.
  [[nodiscard]] CornerId rotation_corner(RotationId r) const { return rotations_[r.idx].corner; }
  [[nodiscard]] VertexId rotation_vertex(RotationId r) const { return vertex(rotation_corner(r)); }
  /// The rotation of v that holds corner c (walks c's rotation: O(valence)).
  [[nodiscard]] RotationId rotation_of(CornerId c) const;
  /// The pairs of e, primary pair first.
  [[nodiscard]] std::vector<CornerPair> edge_pairs(EdgeId e) const;
  [[nodiscard]] std::size_t edge_pair_count(EdgeId e) const;
  [[nodiscard]] CornerPair primary_pair(EdgeId e) const { return edges_[e.idx]; }
  /// The pair of e that contains corner c (throws if none).
  [[nodiscard]] CornerPair pair_of(CornerId c) const;

  const Vec3& position(VertexId v) const { return positions_[v.idx]; }
  void set_position(VertexId v, const Vec3& p) { positions_[v.idx] = p; }
  BigVector<Vec3>& positions() { return positions_; }
  const BigVector<Vec3>& positions() const { return positions_; }

  // ---- Liveness and sizes ----
  [[nodiscard]] bool alive(VertexId v) const;
  [[nodiscard]] bool alive(CornerId c) const;
  [[nodiscard]] bool alive(FaceId f) const;
  [[nodiscard]] bool alive(EdgeId e) const;
  [[nodiscard]] bool alive(RotationId r) const;

  /// Live element counts.
  [[nodiscard]] std::size_t num_vertices() const {
    return vertices_.size() - free_vertices_.size();
  }
  [[nodiscard]] std::size_t num_corners() const { return corners_.size() - free_corners_.size(); }
  [[nodiscard]] std::size_t num_faces() const { return faces_.size() - free_faces_.size(); }
  [[nodiscard]] std::size_t num_edges() const { return edges_.size() - free_edges_.size(); }
  [[nodiscard]] std::size_t num_rotations() const {
    return rotations_.size() - free_rotations_.size();
  }
  /// Array sizes (live and deleted slots): the range of valid handle indices.
  [[nodiscard]] std::size_t vertex_capacity() const { return vertices_.size(); }
  [[nodiscard]] std::size_t corner_capacity() const { return corners_.size(); }
  [[nodiscard]] std::size_t face_capacity() const { return faces_.size(); }
  [[nodiscard]] std::size_t edge_capacity() const { return edges_.size(); }
  [[nodiscard]] std::size_t rotation_capacity() const { return rotations_.size(); }

  /// Increases on every topological change; caches (BVH, index buffers, springs) compare it.
  [[nodiscard]] std::uint64_t topology_version() const { return topology_version_; }

  /// Renumbers every element densely (drops deleted slots and free lists); attribute arrays
  /// follow. Invalidates every handle held outside.
  void compact();
  /// Reserves array space for about n vertices, c corners, f faces and e edges (attribute arrays
  /// included).
  void reserve(std::size_t n, std::size_t c, std::size_t f, std::size_t e);
  /// Returns the memory of free lists that are empty (a bulk build leaves them so).
  void release_empty_free_lists();
  /// Bytes held by the structure's arrays (capacity, not size), attributes excluded.
  [[nodiscard]] std::size_t memory_bytes() const;

  // ---- Attribute arrays that algorithms add by name ----
  PropertyRegistry<VertexTag>& vertex_properties() { return vertex_props_; }
  PropertyRegistry<CornerTag>& corner_properties() { return corner_props_; }
  PropertyRegistry<FaceTag>& face_properties() { return face_props_; }
  const PropertyRegistry<FaceTag>& face_properties() const { return face_props_; }
  PropertyRegistry<EdgeTag>& edge_properties() { return edge_props_; }

  // ---- Raw views for validate() and compact(); not for general use ----
  struct CornerRecord {
    VertexId vertex;
    FaceId face;
    CornerId next;
    CornerId prev;
    EdgeId edge;
  };
  struct FaceRecord {
    CornerId first;
  };
  struct VertexRecord {
    RotationId first;
  };
  struct RotationRecord {
    CornerId corner;  ///< the rotation's other corners follow by rot_next
  };
  const BigVector<CornerRecord>& corner_records() const { return corners_; }
  const BigVector<FaceRecord>& face_records() const { return faces_; }
  const BigVector<CornerPair>& edge_records() const { return edges_; }
  const BigVector<VertexRecord>& vertex_records() const { return vertices_; }
  const BigVector<RotationRecord>& rotation_records() const { return rotations_; }
  const BigVector<std::uint8_t>& bounding_labels() const { return bounding_; }
  /// Extra pairs of non-manifold edges, keyed by edge index (the primary pair is in the edge).
  const std::vector<std::pair<std::uint32_t, std::vector<CornerPair>>>& extra_pair_lists() const {
    return extra_pairs_;
  }
  /// Rotation list links (rotation -> next rotation of the same vertex), sorted by rotation; only
  /// vertices with several rotations have any.
  const std::vector<std::pair<std::uint32_t, std::uint32_t>>& rotation_links() const {
    return rotation_links_;
  }
  const std::vector<std::uint32_t>& free_list(VertexTag) const { return free_vertices_; }
  const std::vector<std::uint32_t>& free_list(CornerTag) const { return free_corners_; }
  const std::vector<std::uint32_t>& free_list(FaceTag) const { return free_faces_; }
  const std::vector<std::uint32_t>& free_list(EdgeTag) const { return free_edges_; }
  const std::vector<std::uint32_t>& free_list(RotationTag) const { return free_rotations_; }

 private:
  // Builds a whole rotation system in one pass (the fast path of mesh construction); it writes
  // the arrays directly and is checked against the operator path in the tests.
  friend class construction::BulkAssembler;
  // Marching cubes writes the records of its triangles directly (twins from the cell tables).
  friend class construction::RawArrays;

  // Element allocation (reuses free slots) and release.
  VertexId new_vertex();
  CornerId new_corner(VertexId v);
  FaceId new_face(CornerId first);
  EdgeId new_edge(CornerPair pair);
  RotationId new_rotation(CornerId corner);
  void free_corner(CornerId c);
  void free_face(FaceId f);
  void free_edge(EdgeId e);
  void free_rotation(VertexId v, RotationId r);

  // Argument checks that throw TopologyError naming the operator and the element.
  void require(VertexId v, const char* op) const;
  void require(CornerId c, const char* op) const;
  void require(FaceId f, const char* op) const;
  void require(EdgeId e, const char* op) const;

  /// Sets face f on every corner of the cycle starting at c.
  void assign_face(CornerId start, FaceId f);
  /// After a splice left face f as two cycles (through a and through b): the shorter cycle gets a
  /// new face. Returns the faces of (a's cycle, b's cycle). Costs the shorter cycle's length.
  std::pair<FaceId, FaceId> split_face(FaceId f, CornerId a, CornerId b);
  /// After a splice joined two faces: renames the run [from, until) to `kept`, frees `gone`.
  void absorb_face(FaceId kept, FaceId gone, CornerId from, CornerId until);
  /// Walks the cycles of a and b in lockstep; returns true when a's cycle is the shorter one.
  bool first_cycle_is_shorter(CornerId a, CornerId b) const;
  /// An edge joining v1 and v2 in a rotation other than those of c1 (at v1) and c2 (at v2).
  EdgeId find_edge_in_other_rotations(CornerId c1, CornerId c2) const;
  /// Makes sure rotation records of v never name `gone` (about to be freed) as their corner.
  void move_rotation_anchor(CornerId gone, CornerId replacement);
  void set_next_rotation(RotationId r, RotationId next);
  /// The last rotation of v's list.
  RotationId last_rotation(VertexId v) const;
  std::vector<CornerPair>* extra_pairs_of(EdgeId e);
  const std::vector<CornerPair>* extra_pairs_of(EdgeId e) const;
  void remove_pair(EdgeId e, CornerId side);
  Vec3 newell_normal(FaceId f) const;
  DeleteEdgeResult delete_pair(EdgeId e, CornerPair pair);

  BigVector<CornerRecord> corners_;
  BigVector<FaceRecord> faces_;
  BigVector<CornerPair> edges_;  // primary pair; a.valid() == false marks a deleted edge
  BigVector<VertexRecord> vertices_;
  BigVector<RotationRecord> rotations_;
  BigVector<Vec3> positions_;
  BigVector<std::uint8_t> bounding_;  // per face: 1 = labelled boundary face (a ring)
  // Non-manifold edges are rare: their extra pairs live in a small side list, sorted by edge.
  std::vector<std::pair<std::uint32_t, std::vector<CornerPair>>> extra_pairs_;
  // Next-rotation links are rare too (non-manifold junctions), so rotations store only a corner.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> rotation_links_;

  std::vector<std::uint32_t> free_vertices_, free_corners_, free_faces_, free_edges_,
      free_rotations_;
  std::uint64_t topology_version_ = 0;

  PropertyRegistry<VertexTag> vertex_props_;
  PropertyRegistry<CornerTag> corner_props_;
  PropertyRegistry<FaceTag> face_props_;
  PropertyRegistry<EdgeTag> edge_props_;
};

}  // namespace bisturi
