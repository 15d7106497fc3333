// Solids of a scene, built at start-up (see scene_builder.h).

#include "bisturi/runtime/session/scene_builder.h"

#include <chrono>
#include <cstdint>
#include <iostream>
#include <string>

#include "bisturi/scene/io/mesh_file.h"
#include "bisturi/scene/lod/decimate.h"
#include "bisturi/scene/lod/smooth.h"
#include "bisturi/scene/polygon_import.h"
#include "bisturi/scene/volume/label_surface.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"
#include "bisturi/scene/volume/volume_io.h"
#include "embedded_data.h"

namespace bisturi::runtime {

namespace {
/// The thinnest face a decimated solid's surface may get (lod::DecimateOptions): about five
/// times as long as wide.
constexpr double kSimulatedTriangleQuality = 0.3;
}  // namespace

Dlfl build_solid(const SolidDescription& solid, const std::string& scene_name,
                 const BuildProgress& progress) {
  const std::string where = scene_name + ": solid '" + solid.name + "'";
  const auto report = [&](std::string_view stage) {
    return [&progress, &solid, stage](std::size_t done, std::size_t total) {
      if (progress) progress(solid.name, stage, done, total);
    };
  };
  Dlfl mesh;
  if (solid.source == SolidDescription::Source::Mesh) {
    ReadOptions read;
    read.progress = report("read");
    const MeshFile file = read_mesh(solid.path, read);
    for (const std::string& w : file.warnings)
      std::cerr << "bisturi: warning: " << where << ": " << w << "\n";
    ImportOptions import;
    import.progress = [&](std::string_view stage, std::size_t done, std::size_t total) {
      if (progress) progress(solid.name, stage, done, total);
  };
  mesh = import_polygons(file.polygons, file.has_vertex_list, import).mesh;
}
else {
  Volume volume;
  if (solid.source == SolidDescription::Source::Phantom) {
    PhantomOptions p;
    p.shape = phantom_shape_from_string(solid.phantom);
    p.dims = solid.dims;
    p.spacing = glm::dvec3(solid.spacing_mm);
    p.a = solid.a_mm;
    p.b = solid.b_mm;
    volume = make_phantom(p);
  } else if (solid.embedded) {
    const auto bytes = embedded_file(solid.path.generic_string());
    if (!bytes) throw SceneFileError(where + ": no embedded file " + solid.path.string());
    volume = read_nrrd_from_memory(*bytes, solid.path.string() + " (embedded)");
  } else {
    volume = read_volume(solid.path);
  }
  IsoSurfaceOptions iso;
  iso.progress = report("surface");
  iso.build_progress = report("build");
  if (solid.label) {
    const auto wanted = static_cast<float>(*solid.label);
    if (label_voxel_count(volume, wanted) == 0)
      throw SceneFileError(where + ": label " + std::to_string(*solid.label) +
                           " is not in the volume");
    // Smooth, not terraced: constrained windowed-sinc smoothing (label_surface.h).
    LabelSurfaceOptions label;
    label.progress = iso.progress;
    label.build_progress = iso.build_progress;
    label.smooth_progress = report("smooth label");
    if (solid.downsample != std::array<int, 3>{1, 1, 1}) {
      const Grid<float> coarse = downsample_label(volume, wanted, solid.downsample);
      mesh = extract_label_surface(coarse, wanted, label);
    } else {
      mesh = extract_label_surface(volume, wanted, label);
    }
  } else {
    iso.iso = static_cast<float>(solid.iso);
    mesh = extract_isosurface(volume, iso);
  }
}
if (mesh.num_faces() == 0) throw SceneFileError(where + ": the source gives no surface");
if (solid.decimate < 1.0) {
  lod::DecimateOptions d;
  d.target_faces =
      static_cast<std::size_t>(static_cast<double>(lod::polygon_face_count(mesh)) * solid.decimate);
  d.progress = report("decimate");
  // A simulated surface bends only where it has vertices: no slivers (lod/decimate.h).
  d.min_triangle_quality = kSimulatedTriangleQuality;
  lod::decimate(mesh, d);
}
if (solid.smooth > 0) {
  lod::SmoothOptions s;
  s.iterations = static_cast<std::size_t>(solid.smooth);
  s.progress = report("smooth");
  lod::smooth_taubin(mesh, s);
}
mesh.compact();
const glm::dvec3 offset(solid.offset_mm[0], solid.offset_mm[1], solid.offset_mm[2]);
for (std::size_t v = 0; v < mesh.vertex_capacity(); ++v)
  mesh.positions()[v] += offset;
return mesh;
}  // namespace bisturi::runtime

std::optional<Dlfl> build_drawn_surface(const SolidDescription& solid,
                                        const std::string& scene_name,
                                        const BuildProgress& progress) {
  if (!solid.drawn) return std::nullopt;
  SolidDescription drawn = solid;
  drawn.downsample = solid.drawn->downsample;
  drawn.decimate = solid.drawn->decimate;
  drawn.smooth = solid.drawn->smooth;
  return build_solid(drawn, scene_name, progress);
}

std::vector<BuiltSolid> build_solids(const SceneDescription& scene, const BuildProgress& progress) {
  const std::string name = scene.file.empty() ? "default scene" : scene.file.string();
  std::vector<BuiltSolid> out;
  out.reserve(scene.solids.size());
  for (const SolidDescription& s : scene.solids) {
    const auto start = std::chrono::steady_clock::now();
    BuiltSolid b;
    b.description = &s;
    b.scene = &scene;
    b.mesh = build_solid(s, name, progress);
    b.build_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    out.push_back(std::move(b));
  }
  return out;
}

}  // namespace bisturi::runtime
