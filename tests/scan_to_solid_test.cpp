// The whole scan-to-solid pipeline, stage by stage as `bisturi segment` and
// `bisturi extract` run it: an analytic phantom written to a file and read back, segmented into
// objects, each object extracted as its own solid, then decimated, smoothed and subdivided, with
// the topology and the size of every solid checked against the phantom's.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>

#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/errors.h"
#include "bisturi/scene/lod/decimate.h"
#include "bisturi/scene/lod/smooth.h"
#include "bisturi/scene/lod/subdivision.h"
#include "bisturi/scene/polygon_export.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"
#include "bisturi/scene/volume/segmentation.h"
#include "bisturi/scene/volume/volume_io.h"

namespace bisturi {
namespace {

constexpr double kPi = std::numbers::pi;

/// Enclosed volume of the unlabelled faces (divergence theorem, fan triangulation).
double enclosed_volume(const Dlfl& mesh) {
  const ExportedPolygons e = export_polygons(mesh);
  double v = 0.0;
  for (std::size_t f = 0; f < e.polygons.face_count(); ++f) {
    const auto face = e.polygons.face(f);
    const glm::dvec3 a = e.polygons.positions[face[0]];
    for (std::size_t k = 1; k + 1 < face.size(); ++k) {
      v += glm::dot(a,
                    glm::cross(e.polygons.positions[face[k]], e.polygons.positions[face[k + 1]])) /
           6.0;
    }
  }
  return v;
}

IsoSurfaceOptions at_iso(float iso) {
  IsoSurfaceOptions o;
  o.iso = iso;
  return o;
}

lod::DecimateOptions to_faces(std::size_t faces) {
  lod::DecimateOptions o;
  o.target_faces = faces;
  return o;
}

std::filesystem::path temp_file(const std::string& name) {
  return std::filesystem::temp_directory_path() /
         ("bisturi_scan_to_solid_" + std::to_string(::getpid()) + "_" + name);
}

TEST(Phantoms, NamesRoundTripAndBadInputIsRefused) {
  for (const std::string& name : phantom_shape_names()) {
    EXPECT_EQ(to_string(phantom_shape_from_string(name)), name);
  }
  EXPECT_THROW((void)phantom_shape_from_string("cube"), InputError);
  PhantomOptions bad;
  bad.dims = {1, 10, 10};
  EXPECT_THROW((void)make_phantom(bad), InputError);
  bad.dims = {10, 10, 10};
  bad.spacing = glm::dvec3(0.5, 0.0, 0.5);
  EXPECT_THROW((void)make_phantom(bad), InputError);
}

TEST(ScanToSolid, TwoSpheresThroughAFileBecomeTwoSolids) {
  // Two spheres of radius 8 mm whose surfaces are 2 mm apart, at 0.5 mm voxels.
  PhantomOptions phantom;
  phantom.shape = PhantomShape::TwoSpheres;
  phantom.dims = {80, 44, 44};
  phantom.a = 8.0;
  phantom.b = 2.0;
  const Volume original = make_phantom(phantom);
  const auto file = temp_file("two_spheres.nrrd");
  write_nrrd(file, original, NrrdEncoding::Gzip);
  const Volume volume = read_volume(file);
  std::filesystem::remove(file);
  ASSERT_EQ(volume.values.size(), original.values.size());

  // Segment: inside is distance > 0; 6-connected components give one object per sphere.
  const Components objects = label_components(threshold(volume, 1e-6f, 1e9f), Connectivity::Six);
  ASSERT_EQ(objects.labels.label_count, 2u);

  const double sphere_volume = 4.0 / 3.0 * kPi * 8.0 * 8.0 * 8.0;
  for (std::uint32_t label = 1; label <= 2; ++label) {
    Dlfl solid = extract_isosurface(label_indicator(objects.labels, label), at_iso(0.5f));
    ASSERT_TRUE(validate(solid).ok());
    const MeshStatistics stats = mesh_statistics(solid);
    ASSERT_EQ(stats.parts.size(), 1u) << "label " << label;
    EXPECT_EQ(stats.parts[0].genus, 0);
    EXPECT_EQ(stats.parts[0].rings, 0u);
    // A voxel mask surface (iso 0.5 between inside and outside samples) encloses about the
    // voxelised volume: within 5% of the sphere's before smoothing.
    EXPECT_NEAR(enclosed_volume(solid), sphere_volume, 0.05 * sphere_volume);

    // Level of detail: decimate to a quarter, smooth, subdivide; topology stays.
    const std::size_t faces = lod::polygon_face_count(solid);
    const lod::DecimateStats d = lod::decimate(solid, to_faces(faces / 4));
    EXPECT_TRUE(d.reached_target);
    solid.compact();
    lod::SmoothOptions smoothing;
    smoothing.iterations = 10;
    lod::smooth_taubin(solid, smoothing);
    ASSERT_TRUE(validate(solid).ok());
    const MeshStatistics after = mesh_statistics(solid);
    ASSERT_EQ(after.parts.size(), 1u);
    EXPECT_EQ(after.parts[0].genus, 0);
    EXPECT_NEAR(enclosed_volume(solid), sphere_volume, 0.06 * sphere_volume);
    lod::SubdivisionOptions one_level;
    one_level.levels = 1;
    const lod::SubdivisionLevels levels(solid, one_level);
    const Dlfl fine = levels.build_level(1);
    ASSERT_TRUE(validate(fine).ok());
    EXPECT_EQ(mesh_statistics(fine).parts.size(), 1u);
    EXPECT_EQ(levels.face_count(1), 4 * lod::polygon_face_count(solid));
  }
}

TEST(ScanToSolid, TorusIsoSurfaceKeepsGenusOneThroughDecimation) {
  PhantomOptions phantom;
  phantom.shape = PhantomShape::Torus;
  phantom.dims = {64, 64, 32};
  phantom.a = 9.0;
  phantom.b = 4.0;
  const Volume volume = make_phantom(phantom);
  Dlfl solid = extract_isosurface(volume, at_iso(0.0f));
  const double exact = 2.0 * kPi * kPi * 9.0 * 4.0 * 4.0;
  EXPECT_NEAR(enclosed_volume(solid), exact, 0.01 * exact);
  lod::decimate(solid, to_faces(lod::polygon_face_count(solid) / 10));
  solid.compact();
  ASSERT_TRUE(validate(solid).ok());
  const MeshStatistics stats = mesh_statistics(solid);
  ASSERT_EQ(stats.parts.size(), 1u);
  EXPECT_EQ(stats.parts[0].genus, 1);
  EXPECT_NEAR(enclosed_volume(solid), exact, 0.03 * exact);
}

TEST(ScanToSolid, GyroidIsOneOpenPartOfHighGenus) {
  PhantomOptions phantom;
  phantom.shape = PhantomShape::Gyroid;
  phantom.dims = {48, 48, 48};
  phantom.a = 8.0;
  const Volume volume = make_phantom(phantom);
  const Dlfl solid = extract_isosurface(volume, at_iso(0.0f));
  ASSERT_TRUE(validate(solid).ok());
  const MeshStatistics stats = mesh_statistics(solid);
  EXPECT_EQ(stats.non_manifold_vertices, 0u);
  EXPECT_EQ(stats.non_manifold_edges, 0u);
  std::size_t open_parts = 0;
  for (const PartTopology& p : stats.parts)
    open_parts += p.rings > 0 ? 1 : 0;
  EXPECT_EQ(open_parts, stats.parts.size());  // the gyroid fills the box: every part is cut
}

}  // namespace
}  // namespace bisturi
