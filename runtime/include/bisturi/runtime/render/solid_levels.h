#pragma once
// The renderable levels of detail of one solid, on the CPU side.
//
// Levels, finest first: an optional subdivided level (Loop or Catmull-Clark, one step, for coarse
// solids), the solid itself (its DLFL polygons, triangulated), then decimated copies (QEM, each a
// fraction of the previous). Every level carries its geometric error in millimetres against the
// finest level, which the renderer projects to pixels to pick one.
//
// Deformation: a decimated level keeps a subset of the solid's vertices (handles survive the
// decimation of a copy), so its positions follow the solid's every frame; the QEM placement is
// kept as a per-vertex offset from the rest position. The subdivided level is re-interpolated from
// the control positions (OpenSubdiv refines its topology once). Normals are area-weighted sums of
// the level's face normals, recomputed only for a level that is drawn after positions changed.
//
// Topology changes (cuts): the solid's own level is rebuilt (new indices, new chunks) as soon as
// its topology version moves; the derived levels are dropped until rebuild_derived_levels() is
// called (decimation costs about a second per 100k faces, too much for one frame).

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/runtime/render/chunk_tree.h"
#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/oriented_builder.h"

namespace bisturi {
struct ExportedPolygons;
}  // namespace bisturi

namespace bisturi::lod {
class SubdivisionLevels;
}

namespace bisturi::render {

struct LevelOptions {
  /// Each decimated level keeps this fraction of the previous level's faces.
  double decimation_ratio = 0.25;
  /// No decimated level below this many faces.
  std::size_t min_faces = 256;
  /// At most this many decimated levels.
  int max_decimated_levels = 4;
  /// Solids with at most this many faces also get a subdivided level (0: never).
  std::size_t subdivide_below_faces = 4096;
  /// Triangles per culling chunk.
  std::uint32_t chunk_triangles = 2048;
  /// Build the derived levels at all (false: the solid's own level only).
  bool derived_levels = true;
};

enum class LevelKind : std::uint8_t { Subdivided, Source, Decimated };

struct SolidLevel {
  LevelKind kind = LevelKind::Source;
  double error_mm = 0.0;  ///< geometric error against the finest level
  std::size_t vertex_count = 0;
  std::vector<std::uint32_t> source_vertex;  ///< Source/Decimated: DLFL vertex index per vertex
  /// Source: per vertex, 1 where it belongs to faces marked kInteriorFaces (their own copy of
  /// each corner vertex, drawn in the interior colour); empty: none.
  std::vector<std::uint8_t> interior;
  std::vector<glm::vec3> offset;       ///< Decimated: QEM position minus rest position
  std::vector<std::uint32_t> indices;  ///< triangles, in chunk order
  ChunkTree tree;
  std::uint64_t index_generation = 0;  ///< changes whenever `indices` do
  /// Interleaved position (3 floats) and normal (3 floats) per vertex, as of `vertex_revision`.
  std::vector<float> vertices;
  std::uint64_t vertex_revision = 0;

  [[nodiscard]] std::size_t triangle_count() const { return indices.size() / 3; }
};

class SolidLevels {
 public:
  SolidLevels(const Dlfl& mesh, const LevelOptions& options = {});
  ~SolidLevels();
  SolidLevels(SolidLevels&&) noexcept;
  SolidLevels& operator=(SolidLevels&&) noexcept;

  /// New positions of the same solid; a changed topology version rebuilds the solid's own level
  /// and drops the derived ones.
  void update(const Dlfl& mesh);
  /// Another mesh for the solid, whatever its topology version (a mesh built anew each frame
  /// starts its own count): its own level rebuilt, the derived ones dropped.
  void replace(const Dlfl& mesh);
  /// The same solid after a cut (its vertices keep their indices; some were added): its own
  /// level is rebuilt and the decimated ones are kept, following the vertices they kept. A
  /// cut's slit is below their error at the distances they are drawn from, and decimating the
  /// solid again would take a frame many times over.
  void recut(const Dlfl& mesh);
  /// Each vertex's ambient occlusion (1: open sky; by the mesh's vertex index, as positions;
  /// empty: none), drawn on the solid's own and decimated levels. Vertices a cut adds later
  /// are open.
  void set_occlusion(std::vector<float> by_vertex);
  /// Builds the decimated and subdivided levels again from the current mesh.
  void rebuild_derived_levels(const Dlfl& mesh);

  [[nodiscard]] std::size_t level_count() const { return levels_.size(); }
  [[nodiscard]] const SolidLevel& level(std::size_t i) const { return levels_[i]; }
  /// The index of the solid's own level (0, or 1 after a subdivided level).
  [[nodiscard]] std::size_t source_level() const { return source_level_; }
  /// Brings a level's vertices (and its chunk boxes) up to the newest positions; returns it.
  const SolidLevel& refresh(std::size_t i);
  /// The bounds of the solid at the newest positions.
  [[nodiscard]] const Aabb& bounds() const { return bounds_; }
  [[nodiscard]] std::uint64_t topology_version() const { return topology_version_; }
  [[nodiscard]] std::uint64_t revision() const { return revision_; }

 private:
  void build_source(const Dlfl& mesh);
  /// The faces marked kInteriorFaces onto copies of their vertices (SolidLevel::interior).
  void split_interior(const Dlfl& mesh, ExportedPolygons& exported, SolidLevel& level);
  void build_derived(const Dlfl& mesh);
  void copy_positions(const Dlfl& mesh);

  LevelOptions options_;
  std::vector<SolidLevel> levels_;
  std::size_t source_level_ = 0;
  std::vector<glm::vec3> positions_;  ///< the solid's positions by vertex index (float)
  std::vector<float> occlusion_;      ///< by vertex index; empty: none
  std::unique_ptr<lod::SubdivisionLevels> subdivision_;
  Aabb bounds_;
  std::uint64_t topology_version_ = 0;
  std::uint64_t revision_ = 1;
  std::uint64_t next_generation_ = 1;
};

/// Triangles of a polygon list (fans), skipping faces with fewer than three corners.
std::vector<std::uint32_t> triangulate(const PolygonMesh& polygons);

}  // namespace bisturi::render
