#pragma once
// Subdivision levels of detail from a coarse DLFL control mesh, with OpenSubdiv (kept out of this
// header). The topology is refined once, when the object is built; update() then re-interpolates
// the positions of every level from new control positions (a cheap pass per frame), so a
// deforming control mesh keeps its fine levels in step without refining again.
//
// The control mesh is the DLFL's polygons (export_polygons: unlabelled faces with three or more
// corners), so the holes of open meshes are boundaries, and non-manifold vertices and edges are
// passed to OpenSubdiv as they are. Boundary edges are interpolated as sharp creases.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/oriented_builder.h"

namespace bisturi::lod {

enum class SubdivisionScheme : std::uint8_t {
  Automatic,     ///< Loop when every control face is a triangle, Catmull-Clark otherwise
  Loop,          ///< triangles only (a control face with more corners is an InputError)
  CatmullClark,  ///< any polygons; every refined face is a quad
};

struct SubdivisionOptions {
  int levels = 2;  ///< uniform refinement levels, 0 to 8
  SubdivisionScheme scheme = SubdivisionScheme::Automatic;
  /// Boundary corners (boundary vertices in one face) stay on their control point; otherwise only
  /// the boundary edges are creased and corners are smoothed.
  bool sharp_boundary_corners = true;
};

class SubdivisionLevels {
 public:
  /// Refines the topology of `control` to options.levels and interpolates its current positions.
  /// Throws InputError for an empty control mesh, a level count out of range, non-triangles
  /// under the Loop scheme, or topology OpenSubdiv refuses (its message is included).
  explicit SubdivisionLevels(const Dlfl& control, const SubdivisionOptions& options = {});
  ~SubdivisionLevels();
  SubdivisionLevels(SubdivisionLevels&&) noexcept;
  SubdivisionLevels& operator=(SubdivisionLevels&&) noexcept;
  SubdivisionLevels(const SubdivisionLevels&) = delete;
  SubdivisionLevels& operator=(const SubdivisionLevels&) = delete;

  [[nodiscard]] int levels() const;
  /// The scheme in use (never Automatic).
  [[nodiscard]] SubdivisionScheme scheme() const;
  /// The DLFL vertex of each control point (control point i is level 0's vertex i).
  [[nodiscard]] const std::vector<VertexId>& control_vertices() const;
  [[nodiscard]] std::size_t vertex_count(int level) const;
  [[nodiscard]] std::size_t face_count(int level) const;

  /// Re-interpolates every level from the positions of the control vertices of `control`, which
  /// must be the mesh the levels were built from with only positions changed since (checked
  /// through its topology version; TopologyError otherwise).
  void update(const Dlfl& control);
  /// Re-interpolates every level from control_vertices().size() positions in control order.
  /// Throws InputError on a size mismatch.
  void update(std::span<const Dlfl::Vec3> control_positions);

  /// The current positions of a level (level 0: the control points).
  [[nodiscard]] std::span<const Dlfl::Vec3> positions(int level) const;
  /// A level as polygons with its current positions (faces in OpenSubdiv order, oriented as the
  /// control faces).
  [[nodiscard]] PolygonMesh level_mesh(int level) const;
  /// A level as a new DLFL (build_oriented_manifold; the general import for levels with
  /// non-manifold vertices or edges).
  [[nodiscard]] Dlfl build_level(int level) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bisturi::lod
