#include "bisturi/runtime/render/solid_levels.h"

#include <algorithm>
#include <cmath>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/lod/decimate.h"
#include "bisturi/scene/lod/subdivision.h"
#include "bisturi/scene/polygon_export.h"
#include "bisturi/scene/polygon_import.h"

namespace bisturi::render {

namespace {

/// Area-weighted vertex normals and the interleaved vertex array of a level.
/// Interleaved positions and normals; a normal's length is its vertex's ambient occlusion (the
/// shader normalises it and reads the length: 1 open, less where the field hides the sky).
/// An interior vertex's normal is 2 + its occlusion long (the shader draws it in the interior
/// colour).
void write_vertices(const std::vector<glm::vec3>& positions,
                    const std::vector<std::uint32_t>& indices, const std::vector<float>& occlusion,
                    const std::vector<std::uint8_t>& interior, std::vector<float>& out) {
  std::vector<glm::vec3> normals(positions.size(), glm::vec3(0.0f));
  for (std::size_t t = 0; t + 2 < indices.size(); t += 3) {
    const std::uint32_t a = indices[t], b = indices[t + 1], c = indices[t + 2];
    const glm::vec3 n = glm::cross(positions[b] - positions[a], positions[c] - positions[a]);
    normals[a] += n;
    normals[b] += n;
    normals[c] += n;
  }
  out.resize(positions.size() * 6);
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const float length = glm::length(normals[i]);
    const float open = (occlusion.empty() ? 1.0f : occlusion[i]) +
                       (!interior.empty() && interior[i] ? 2.0f : 0.0f);
    const glm::vec3 n = open * (length > 0.0f ? normals[i] / length : glm::vec3(0.0f, 0.0f, 1.0f));
    float* v = out.data() + 6 * i;
    v[0] = positions[i].x;
    v[1] = positions[i].y;
    v[2] = positions[i].z;
    v[3] = n.x;
    v[4] = n.y;
    v[5] = n.z;
  }
}

}  // namespace

std::vector<std::uint32_t> triangulate(const PolygonMesh& polygons) {
  std::vector<std::uint32_t> out;
  out.reserve(polygons.indices.size() * 3 / 2);
  for (std::size_t f = 0; f < polygons.face_count(); ++f) {
    const auto face = polygons.face(f);
    for (std::size_t k = 2; k < face.size(); ++k) {
      out.push_back(face[0]);
      out.push_back(face[k - 1]);
      out.push_back(face[k]);
    }
  }
  return out;
}

SolidLevels::SolidLevels(const Dlfl& mesh, const LevelOptions& options) : options_(options) {
  topology_version_ = mesh.topology_version();
  copy_positions(mesh);
  build_source(mesh);
  build_derived(mesh);
}

SolidLevels::~SolidLevels() = default;
SolidLevels::SolidLevels(SolidLevels&&) noexcept = default;
SolidLevels& SolidLevels::operator=(SolidLevels&&) noexcept = default;

void SolidLevels::copy_positions(const Dlfl& mesh) {
  const auto& p = mesh.positions();
  positions_.resize(p.size());
  for (std::size_t i = 0; i < p.size(); ++i)
    positions_[i] = glm::vec3(p[i]);
  ++revision_;
}

void SolidLevels::build_source(const Dlfl& mesh) {
  ExportedPolygons exported = export_polygons(mesh);
  SolidLevel level;
  level.kind = LevelKind::Source;
  level.vertex_count = exported.vertex_of_position.size();
  level.source_vertex.resize(level.vertex_count);
  for (std::size_t i = 0; i < level.vertex_count; ++i)
    level.source_vertex[i] = exported.vertex_of_position[i].idx;
  if (mesh.face_properties().has(kInteriorFaces)) split_interior(mesh, exported, level);
  std::vector<glm::vec3> local(level.vertex_count);
  for (std::size_t i = 0; i < level.vertex_count; ++i)
    local[i] = positions_[level.source_vertex[i]];
  level.indices = triangulate(exported.polygons);
  level.tree = build_chunk_tree(local, level.indices, options_.chunk_triangles);
  level.index_generation = next_generation_++;
  levels_.clear();
  levels_.push_back(std::move(level));
  source_level_ = 0;
  subdivision_.reset();
  bounds_ = Aabb{};
  for (const glm::vec3& p : local)
    bounds_.extend(glm::dvec3(p));
}

void SolidLevels::split_interior(const Dlfl& mesh, ExportedPolygons& exported, SolidLevel& level) {
  const auto& marked = mesh.face_properties().get<std::uint8_t>(kInteriorFaces);
  // The interior faces' corners move onto copies of their vertices: a wall and the outside
  // meeting at a lip each keep their own normal and colour there.
  std::vector<std::uint32_t> copy(level.vertex_count, UINT32_MAX);
  PolygonMesh& polygons = exported.polygons;
  for (std::size_t f = 0; f < polygons.face_count(); ++f) {
    if (!marked[exported.face_of_polygon[f]]) continue;
    for (std::uint32_t k = polygons.offsets[f]; k < polygons.offsets[f + 1]; ++k) {
      std::uint32_t& v = polygons.indices[k];
      if (copy[v] == UINT32_MAX) {
        copy[v] = static_cast<std::uint32_t>(level.source_vertex.size());
        level.source_vertex.push_back(level.source_vertex[v]);
      }
      v = copy[v];
    }
  }
  level.interior.assign(level.source_vertex.size(), 0);
  for (std::size_t i = level.vertex_count; i < level.source_vertex.size(); ++i)
    level.interior[i] = 1;
  level.vertex_count = level.source_vertex.size();
}

void SolidLevels::build_derived(const Dlfl& mesh) {
  if (!options_.derived_levels) return;
  SolidLevel source = std::move(levels_[source_level_]);
  levels_.clear();
  subdivision_.reset();
  source.error_mm = 0.0;
  const std::size_t faces = lod::polygon_face_count(mesh);

  // A finer level for coarse solids: one uniform subdivision step.
  if (options_.subdivide_below_faces > 0 && faces > 0 && faces <= options_.subdivide_below_faces) {
    try {
      lod::SubdivisionOptions so;
      so.levels = 1;
      auto subdivision = std::make_unique<lod::SubdivisionLevels>(mesh, so);
      const PolygonMesh fine = subdivision->level_mesh(1);
      SolidLevel level;
      level.kind = LevelKind::Subdivided;
      level.vertex_count = fine.positions.size();
      level.indices = triangulate(fine);
      std::vector<glm::vec3> local(level.vertex_count);
      for (std::size_t i = 0; i < level.vertex_count; ++i)
        local[i] = glm::vec3(fine.positions[i]);
      level.tree = build_chunk_tree(local, level.indices, options_.chunk_triangles);
      level.index_generation = next_generation_++;
      // The control points move to their vertex points in the first step (OpenSubdiv numbers the
      // children of vertices first): how far the control mesh is from the smoother surface.
      const auto control = subdivision->positions(0);
      const auto refined = subdivision->positions(1);
      double error = 0.0;
      for (std::size_t i = 0; i < control.size() && i < refined.size(); ++i) {
        error = std::max(error, glm::length(refined[i] - control[i]));
      }
      source.error_mm = error;
      levels_.push_back(std::move(level));
      subdivision_ = std::move(subdivision);
    } catch (const SceneError&) {
      // OpenSubdiv refused this control mesh: no finer level.
    }
  }
  source_level_ = levels_.size();
  const double base_error = source.error_mm;
  levels_.push_back(std::move(source));

  // Coarser levels: QEM decimation of a copy, each from the previous one. The copy keeps the
  // handles of surviving vertices, so each level vertex names its vertex in the solid.
  if (options_.max_decimated_levels <= 0 || options_.decimation_ratio <= 0.0 ||
      options_.decimation_ratio >= 1.0) {
    return;
  }
  // A working copy through the general import (the Dlfl is not copyable); copy_to_source maps
  // the copy's vertex indices back to the solid's.
  const ExportedPolygons exported_source = export_polygons(mesh);
  ImportResult imported = import_polygons(exported_source.polygons, true);
  Dlfl& copy = imported.mesh;
  std::vector<std::uint32_t> copy_to_source(copy.vertex_capacity(), kInvalidIndex);
  for (std::size_t i = 0; i < imported.vertex_of_input.size(); ++i) {
    const VertexId v = imported.vertex_of_input[i];
    if (v.valid()) copy_to_source[v.idx] = exported_source.vertex_of_position[i].idx;
  }
  double error = base_error;
  std::size_t current = faces;
  for (int l = 0; l < options_.max_decimated_levels; ++l) {
    const auto target = static_cast<std::size_t>(
        std::llround(static_cast<double>(current) * options_.decimation_ratio));
    if (target < options_.min_faces) break;
    lod::DecimateOptions d;
    d.target_faces = target;
    const lod::DecimateStats stats = lod::decimate(copy, d);
    if (stats.collapses == 0 || stats.final_faces >= current) break;
    error += stats.max_error;
    current = stats.final_faces;
    const ExportedPolygons exported = export_polygons(copy);
    SolidLevel level;
    level.kind = LevelKind::Decimated;
    level.error_mm = error;
    level.vertex_count = exported.vertex_of_position.size();
    level.source_vertex.resize(level.vertex_count);
    level.offset.resize(level.vertex_count);
    std::vector<glm::vec3> local(level.vertex_count);
    for (std::size_t i = 0; i < level.vertex_count; ++i) {
      const std::uint32_t v = copy_to_source[exported.vertex_of_position[i].idx];
      level.source_vertex[i] = v;
      local[i] = glm::vec3(exported.polygons.positions[i]);
      level.offset[i] = local[i] - positions_[v];
    }
    level.indices = triangulate(exported.polygons);
    level.tree = build_chunk_tree(local, level.indices, options_.chunk_triangles);
    level.index_generation = next_generation_++;
    levels_.push_back(std::move(level));
  }
}

void SolidLevels::update(const Dlfl& mesh) {
  if (mesh.topology_version() != topology_version_) {
    replace(mesh);
    return;
  }
  copy_positions(mesh);
  if (subdivision_) subdivision_->update(mesh);
  bounds_ = Aabb{};
  for (const std::uint32_t v : levels_[source_level_].source_vertex) {
    bounds_.extend(glm::dvec3(positions_[v]));
  }
}

void SolidLevels::set_occlusion(std::vector<float> by_vertex) {
  occlusion_ = std::move(by_vertex);
  ++revision_;  // every level's vertices written again
}

void SolidLevels::replace(const Dlfl& mesh) {
  topology_version_ = mesh.topology_version();
  copy_positions(mesh);
  build_source(mesh);
}

void SolidLevels::recut(const Dlfl& mesh) {
  std::vector<SolidLevel> coarser;
  for (std::size_t i = source_level_ + 1; i < levels_.size(); ++i)
    coarser.push_back(std::move(levels_[i]));
  replace(mesh);
  for (SolidLevel& level : coarser)
    levels_.push_back(std::move(level));
}

void SolidLevels::rebuild_derived_levels(const Dlfl& mesh) {
  topology_version_ = mesh.topology_version();
  copy_positions(mesh);
  build_source(mesh);
  build_derived(mesh);
}

const SolidLevel& SolidLevels::refresh(std::size_t i) {
  SolidLevel& level = levels_[i];
  if (level.vertex_revision == revision_) return level;
  std::vector<glm::vec3> local(level.vertex_count);
  std::vector<float> open;
  if (!occlusion_.empty() && level.kind != LevelKind::Subdivided) {
    open.resize(level.vertex_count);
    for (std::size_t k = 0; k < level.vertex_count; ++k) {
      const std::uint32_t v = level.source_vertex[k];
      open[k] = v < occlusion_.size() ? occlusion_[v] : 1.0f;
    }
  }
  if (level.kind == LevelKind::Subdivided) {
    const auto fine = subdivision_->positions(1);
    for (std::size_t k = 0; k < level.vertex_count; ++k)
      local[k] = glm::vec3(fine[k]);
  } else {
    for (std::size_t k = 0; k < level.vertex_count; ++k)
      local[k] = positions_[level.source_vertex[k]];
    if (!level.offset.empty()) {
      for (std::size_t k = 0; k < level.vertex_count; ++k)
        local[k] += level.offset[k];
    }
  }
  write_vertices(local, level.indices, open, level.interior, level.vertices);
  level.tree.refit(local, level.indices);
  level.vertex_revision = revision_;
  return level;
}

}  // namespace bisturi::render
