// Label surfaces: the steps wired together, and the slices read across the thickest axis (see
// label_surface.h).

#include "bisturi/scene/volume/label_surface.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "bisturi/scene/errors.h"
#include "elapsed.h"
#include "label_caps.h"
#include "label_field.h"
#include "label_smoothing.h"

namespace bisturi {

namespace {

using Vec3 = Dlfl::Vec3;
using Clock = std::chrono::steady_clock;

using surface::seconds_since;

void check_options(const LabelSurfaceOptions& o) {
  if (o.iterations == 1 || !(o.pass_band > 0.0 && o.pass_band < 2.0)) {
    throw InputError("label surface: need iterations 0 or >= 2 and a pass band in (0, 2) (got " +
                     std::to_string(o.iterations) + ", " + std::to_string(o.pass_band) + ")");
  }
  if (!(o.twicing_share >= 0.0 && o.twicing_share <= 2.0 && o.twicing_share_flat >= 0.0 &&
        o.twicing_share_flat <= 2.0)) {
    throw InputError("label surface: need twicing shares in [0, 2] (got " +
                     std::to_string(o.twicing_share_flat) + " and " +
                     std::to_string(o.twicing_share) + ")");
  }
  if (!(o.twicing_bend_flat >= 0.0 && o.twicing_bend_sharp > o.twicing_bend_flat)) {
    throw InputError("label surface: need twicing bends 0 <= flat < sharp (got " +
                     std::to_string(o.twicing_bend_flat) + " and " +
                     std::to_string(o.twicing_bend_sharp) + ")");
  }
}

IsoSurfaceOptions iso_options(const LabelSurfaceOptions& o) {
  IsoSurfaceOptions iso;
  iso.iso = 0.0F;
  iso.placement = VertexPlacement::Linear;
  iso.progress = o.progress;
  iso.build_progress = o.build_progress;
  return iso;
}

}  // namespace

Grid<float> downsample_label(const Grid<float>& labels, float label,
                             const std::array<int, 3>& factors) {
  if (factors[0] < 1 || factors[1] < 1 || factors[2] < 1 || label == 0.0F) {
    throw InputError("downsample_label: factors must be at least 1 and the label not 0");
  }
  const VolumeGeometry& g = labels.geometry;
  Grid<float> out;
  VolumeGeometry& c = out.geometry;
  c.direction = g.direction;
  glm::dvec3 shift(0.0);
  for (int a = 0; a < 3; ++a) {
    c.dims[a] = (g.dims[a] + factors[a] - 1) / factors[a] + 2;  // and a background border
    c.spacing[a] = g.spacing[a] * factors[a];
    shift[a] = 0.5 * g.spacing[a] * (factors[a] - 1) - c.spacing[a];
  }
  c.origin = g.origin + g.direction * shift;
  out.values.resize(c.voxel_count());
  std::vector<std::uint32_t> inside(c.voxel_count(), 0), total(c.voxel_count(), 0);
  for (std::int64_t k = 0; k < g.dims[2]; ++k) {
    for (std::int64_t j = 0; j < g.dims[1]; ++j) {
      const float* row = labels.values.data() + g.linear_index(0, j, k);
      const std::size_t base = c.linear_index(1, 1 + j / factors[1], 1 + k / factors[2]);
      for (std::int64_t i = 0; i < g.dims[0]; ++i) {
        const std::size_t b = base + static_cast<std::size_t>(i / factors[0]);
        inside[b] += row[i] == label ? 1U : 0U;
        ++total[b];
      }
    }
  }
  for (std::size_t b = 0; b < inside.size(); ++b)
    out.values[b] = inside[b] > 0 && 2 * inside[b] >= total[b] ? label : 0.0F;
  return out;
}

std::size_t label_voxel_count(const Grid<float>& labels, float label) {
  return static_cast<std::size_t>(
      std::count(labels.values.data(), labels.values.data() + labels.values.size(), label));
}

namespace {

/// The label's smooth indicator field and the band of cells its boundary crosses (both
/// extractions start here).
struct LabelIndicator {
  Grid<float> field;
  Grid<float> band;
  /// The map read with its thickest axis as k (slices_across_k), where that is not k already;
  /// empty where it is.
  Grid<float> turned;
  [[nodiscard]] const Grid<float>& sliced(const Grid<float>& labels) const {
    return turned.values.empty() ? labels : turned;
  }
};

/// `labels` read with index axis `axis` and k swapped (every sample keeps its world position):
/// its geometry into `turned`, and each sample as `value` makes it into `out`.
template <typename T, typename Value>
void swap_with_k(const Grid<float>& labels, int axis, VolumeGeometry& turned, T* out,
                 const Value& value) {
  const VolumeGeometry& g = labels.geometry;
  std::array<int, 3> from{0, 1, 2};  // the axis of `labels` each axis of `turned` is
  std::swap(from[static_cast<std::size_t>(axis)], from[2]);
  VolumeGeometry& t = turned;
  t.origin = g.origin;
  for (int a = 0; a < 3; ++a) {
    const int f = from[static_cast<std::size_t>(a)];
    t.dims[static_cast<std::size_t>(a)] = g.dims[static_cast<std::size_t>(f)];
    t.spacing[a] = g.spacing[f];
    t.direction[a] = g.direction[f];
  }
  std::array<std::int64_t, 3> at{};  // the sample of `labels` for (i, j, k) of `turned`
  for (std::int64_t k = 0; k < t.dims[2]; ++k)
    for (std::int64_t j = 0; j < t.dims[1]; ++j)
      for (std::int64_t i = 0; i < t.dims[0]; ++i) {
        at[static_cast<std::size_t>(from[0])] = i;
        at[static_cast<std::size_t>(from[1])] = j;
        at[static_cast<std::size_t>(from[2])] = k;
        out[t.linear_index(i, j, k)] = value(labels.values[g.linear_index(at[0], at[1], at[2])]);
      }
}

/// The steps above take the slices across k: shape-based interpolation runs between them and
/// the caps go over the last ones. A map whose samples are furthest apart along i or j (a
/// sagittal or coronal series), by a fifth more than along k, is read with that axis and k
/// swapped: its index axes and their spacings and world directions trade places, so every
/// sample keeps its world position (and marching cubes' winding follows the direction's
/// handedness). Nearly isotropic maps stay as they are (their repeated slices, if any, lie
/// across k). `turned` holds the copy; the map itself is returned when it is not turned.
const Grid<float>& slices_across_k(const Grid<float>& labels, Grid<float>& turned) {
  const VolumeGeometry& g = labels.geometry;
  int thick = 2;
  for (int a = 0; a < 2; ++a)
    if (g.spacing[a] > kThicker * g.spacing[2] && g.spacing[a] > g.spacing[thick]) thick = a;
  if (thick == 2) return labels;
  turned.values.resize(labels.values.size());
  swap_with_k(labels, thick, turned.geometry, turned.values.data(), [](float v) { return v; });
  return turned;
}

/// At about even sampling a shape's tips along i and j (not only its ends across the slices) are
/// the ends of regions of slices across those axes, and bulge past the midpoints marching cubes
/// puts their vertices at: smoothed, an ellipsoid at 1.3 mm samples lay 0.47 mm inside at the
/// tips of its long axis (VTK's surface 0.43), and lies 0.37 mm off with their caps. Slices
/// across an axis whose samples lie about as far apart as the slices' (within a fifth) give
/// those tips their caps, where the caps lie further out.
void place_ends_across_other_axes(std::span<Vec3> positions, const Grid<float>& sliced,
                                  float label) {
  for (int a = 0; a < 2; ++a) {
    if (kThicker * sliced.geometry.spacing[a] < sliced.geometry.spacing[2]) continue;
    VolumeGeometry across;
    std::vector<std::uint8_t> mask(sliced.values.size());
    swap_with_k(sliced, a, across, mask.data(),
                [label](float v) -> std::uint8_t { return v == label ? 1 : 0; });
    const std::vector<std::uint8_t> wanted = slices_around_ends(mask, across);
    place_vertices_across_slices(positions, signed_slice_distances(mask, across, &wanted),
                                 AcrossSlices::EndsFurtherOut);
  }
}

LabelIndicator label_indicator(const Grid<float>& labels, float label,
                               const LabelSurfaceOptions& options, LabelSurfaceStats& s) {
  check_options(options);
  const auto t = Clock::now();
  LabelIndicator out;
  out.field = label_field(slices_across_k(labels, out.turned), label, s.label_voxels, out.band);
  s.indicator_seconds = seconds_since(t);
  return out;
}

}  // namespace

PolygonMesh extract_label_surface_mesh(const Grid<float>& labels, float label,
                                       const LabelSurfaceOptions& options,
                                       LabelSurfaceStats* stats) {
  LabelSurfaceStats local;
  LabelSurfaceStats& s = stats ? *stats : local;
  const LabelIndicator in = label_indicator(labels, label, options, s);
  const Grid<float>& band = in.band;
  PolygonMesh mesh = extract_isosurface_mesh(in.field, iso_options(options), &s.extraction);
  place_vertices_across_slices({mesh.positions.data(), mesh.positions.size()}, in.field);
  place_ends_across_other_axes({mesh.positions.data(), mesh.positions.size()}, in.sliced(labels),
                               label);
  if (options.iterations > 0 && options.rounds > 0 && !mesh.positions.empty()) {
    smooth_in_band({mesh.positions.data(), mesh.positions.size()}, neighbours_of(mesh), band,
                   options, s);
  }
  return mesh;
}

Dlfl extract_label_surface(const Grid<float>& labels, float label,
                           const LabelSurfaceOptions& options, LabelSurfaceStats* stats) {
  LabelSurfaceStats local;
  LabelSurfaceStats& s = stats ? *stats : local;
  const LabelIndicator in = label_indicator(labels, label, options, s);
  const Grid<float>& band = in.band;
  Dlfl mesh = extract_isosurface(in.field, iso_options(options), &s.extraction);
  place_vertices_across_slices({mesh.positions().data(), mesh.vertex_capacity()}, in.field);
  place_ends_across_other_axes({mesh.positions().data(), mesh.vertex_capacity()}, in.sliced(labels),
                               label);
  if (options.iterations > 0 && options.rounds > 0 && mesh.vertex_capacity() > 0) {
    auto& pos = mesh.positions();
    smooth_in_band({pos.data(), mesh.vertex_capacity()}, neighbours_of(mesh), band, options, s);
  }
  return mesh;
}

}  // namespace bisturi
