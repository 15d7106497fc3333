#include "pipeline_stages.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

#include "bisturi/runtime/session/plots.h"
#include "bisturi/scene/volume/segmentation.h"

namespace bisturi::cli {

namespace {

std::string point_text(const std::array<double, 3>& p) {
  return "(" + std::to_string(p[0]) + ", " + std::to_string(p[1]) + ", " + std::to_string(p[2]) +
         ")";
}

/// Grows the mask by `r` voxels along each axis (a box), in three separable passes.
Grid<std::uint8_t> dilate(const Grid<std::uint8_t>& in, int r) {
  Grid<std::uint8_t> a = in, b = in;
  const auto& d = in.geometry.dims;
  const std::int64_t stride[3] = {1, d[0], d[0] * d[1]};
  for (int axis = 0; axis < 3; ++axis) {
    b = a;
    for (std::int64_t k = 0; k < d[2]; ++k)
      for (std::int64_t j = 0; j < d[1]; ++j)
        for (std::int64_t i = 0; i < d[0]; ++i) {
          const std::int64_t c[3] = {i, j, k};
          if (a.at(i, j, k) == 0) continue;
          const std::int64_t base = static_cast<std::int64_t>(in.geometry.linear_index(i, j, k));
          for (int o = -r; o <= r; ++o) {
            const std::int64_t p = c[axis] + o;
            if (p < 0 || p >= d[static_cast<std::size_t>(axis)]) continue;
            b.values[static_cast<std::size_t>(base + o * stride[axis])] = 1;
          }
        }
    a = b;
  }
  return a;
}

}  // namespace

VesselMask segment_vessel(const Volume& volume, const PipelinePlan& plan) {
  VesselMask out;
  const Connectivity connectivity =
      plan.connectivity == 26 ? Connectivity::TwentySix : Connectivity::Six;
  Grid<std::uint8_t> in_range;
  if (plan.method == "label") {
    in_range.geometry = volume.geometry;
    in_range.values.resize(volume.values.size());
    const auto wanted = static_cast<float>(plan.label);
    for (std::size_t i = 0; i < volume.values.size(); ++i)
      in_range.values[i] = volume.values[i] == wanted ? 1 : 0;
  } else {
    const auto r = plan.threshold_range();
    in_range = threshold(volume, static_cast<float>(r[0]), static_cast<float>(r[1]));
  }
  if (plan.seed_mm) {
    const glm::dvec3 ijk = volume.geometry.world_to_index(
        glm::dvec3((*plan.seed_mm)[0], (*plan.seed_mm)[1], (*plan.seed_mm)[2]));
    const std::array<std::int64_t, 3> seed{std::llround(ijk.x), std::llround(ijk.y),
                                           std::llround(ijk.z)};
    if (!volume.geometry.contains(seed[0], seed[1], seed[2])) {
      throw std::runtime_error("segmentation: seed_mm " + point_text(*plan.seed_mm) +
                               " is outside the volume");
    }
    if (in_range.at(seed[0], seed[1], seed[2]) == 0) {
      throw std::runtime_error(
          "segmentation: the voxel at seed_mm " + point_text(*plan.seed_mm) + " has the value " +
          std::to_string(volume.at(seed[0], seed[1], seed[2])) + ", outside the plan's range");
    }
    const Components c = label_components(in_range, connectivity);
    const std::uint32_t label = c.labels.at(seed[0], seed[1], seed[2]);
    out.objects_in_range = c.stats.size();
    out.mask.geometry = volume.geometry;
    out.mask.values.resize(volume.values.size());
    for (std::size_t i = 0; i < volume.values.size(); ++i)
      out.mask.values[i] = c.labels.values[i] == label ? 1 : 0;
    out.voxels = static_cast<std::size_t>(c.stats[label - 1].voxel_count);
    out.how = "seed";
    return out;
  }
  const Components c = label_components(in_range, connectivity);
  if (c.stats.empty()) {
    throw std::runtime_error(plan.method == "label"
                                 ? "segmentation: label " + std::to_string(plan.label) +
                                       " is not in the volume"
                                 : "segmentation: no voxel has a value in the plan's range");
  }
  const auto largest = std::max_element(c.stats.begin(), c.stats.end(),
                                        [](const ComponentStats& a, const ComponentStats& b) {
                                          return a.voxel_count < b.voxel_count;
                                        });
  out.objects_in_range = c.stats.size();
  out.mask.geometry = volume.geometry;
  out.mask.values.resize(volume.values.size());
  for (std::size_t i = 0; i < volume.values.size(); ++i)
    out.mask.values[i] = c.labels.values[i] == largest->label ? 1 : 0;
  out.voxels = static_cast<std::size_t>(largest->voxel_count);
  out.how = plan.method == "label" ? "label (largest object)" : "largest object";
  return out;
}

SurfaceField surface_field(const Volume& volume, const VesselMask& vessel,
                           const PipelinePlan& plan) {
  // Only the vessel's box (and 4 voxels around it) is extracted: a CT's field of view is mostly
  // something else, and marching cubes would visit every cell of it.
  const VolumeGeometry& g = volume.geometry;
  std::array<std::int64_t, 3> lo{g.dims[0], g.dims[1], g.dims[2]}, hi{-1, -1, -1};
  std::size_t n = 0;
  for (std::int64_t k = 0; k < g.dims[2]; ++k)
    for (std::int64_t j = 0; j < g.dims[1]; ++j)
      for (std::int64_t i = 0; i < g.dims[0]; ++i, ++n) {
        if (vessel.mask.values[n] == 0) continue;
        lo = {std::min(lo[0], i), std::min(lo[1], j), std::min(lo[2], k)};
        hi = {std::max(hi[0], i), std::max(hi[1], j), std::max(hi[2], k)};
      }
  if (hi[0] < 0) throw std::runtime_error("segmentation: the vessel has no voxel");
  Grid<std::uint8_t> mask;
  Grid<float> values;
  mask.geometry = g;
  for (std::size_t a = 0; a < 3; ++a) {
    lo[a] = std::max<std::int64_t>(0, lo[a] - 4);
    hi[a] = std::min<std::int64_t>(g.dims[a] - 1, hi[a] + 4);
    mask.geometry.dims[a] = hi[a] - lo[a] + 1;
  }
  mask.geometry.origin = g.index_to_world(glm::dvec3(lo[0], lo[1], lo[2]));
  values.geometry = mask.geometry;
  mask.values.resize(mask.geometry.voxel_count());
  values.values.resize(mask.geometry.voxel_count());
  n = 0;
  for (std::int64_t k = lo[2]; k <= hi[2]; ++k)
    for (std::int64_t j = lo[1]; j <= hi[1]; ++j)
      for (std::int64_t i = lo[0]; i <= hi[0]; ++i, ++n) {
        mask.values[n] = vessel.mask.at(i, j, k);
        values.values[n] = volume.at(i, j, k);
      }

  SurfaceField s;
  s.field.geometry = mask.geometry;
  s.field.values.resize(mask.values.size());
  if (plan.method == "label") {
    for (std::size_t i = 0; i < mask.values.size(); ++i)
      s.field.values[i] = mask.values[i] != 0 ? 1.0f : 0.0f;
    s.iso.iso = 0.5f;
    s.iso.placement = VertexPlacement::Linear;  // an indicator is a step: nothing to fit
    return s;
  }
  const auto low = static_cast<float>(plan.threshold_range()[0]);
  // Near the vessel the scan itself (its blurred wall places the surface within a voxel);
  // three voxels out (past the four samples cubic placement reads) nothing else.
  const Grid<std::uint8_t> near = dilate(mask, 3);
  float floor_value = low - 1.0f;
  for (const float v : values.values)
    if (std::isfinite(v)) floor_value = std::min(floor_value, v);
  for (std::size_t i = 0; i < values.values.size(); ++i)
    s.field.values[i] =
        near.values[i] != 0 && std::isfinite(values.values[i]) ? values.values[i] : floor_value;
  // Inside is value > iso; the range includes its low end, so the surface sits just below it.
  s.iso.iso = std::nextafter(low, -std::numeric_limits<float>::infinity());
  s.iso.placement = VertexPlacement::Cubic;
  return s;
}

void write_profile_png(const std::filesystem::path& file, const std::string& title,
                       const std::vector<VesselSection>& sections, std::size_t branches,
                       double step_mm) {
  // Sections lie at multiples of the step on every branch: one shared x axis.
  std::map<long long, std::size_t> slot;
  for (const VesselSection& s : sections)
    slot.emplace(std::llround(s.distance_mm / step_mm), 0);
  std::vector<double> x;
  for (auto& [k, i] : slot) {
    i = x.size();
    x.push_back(static_cast<double>(k) * step_mm);
  }
  static const double colours[][3] = {{0.10, 0.30, 0.80}, {0.80, 0.20, 0.10}, {0.10, 0.60, 0.20},
                                      {0.60, 0.20, 0.70}, {0.90, 0.60, 0.00}, {0.30, 0.30, 0.30}};
  std::vector<runtime::Series> series(branches);
  for (std::size_t b = 0; b < branches; ++b) {
    series[b].label = "branch " + std::to_string(b);
    series[b].y.assign(x.size(), std::numeric_limits<double>::quiet_NaN());
    series[b].r = colours[b % 6][0];
    series[b].g = colours[b % 6][1];
    series[b].b = colours[b % 6][2];
  }
  for (const VesselSection& s : sections) {
    if (s.branch < 0 || static_cast<std::size_t>(s.branch) >= branches) continue;
    series[static_cast<std::size_t>(s.branch)].y[slot[std::llround(s.distance_mm / step_mm)]] =
        s.measures.mean_diameter;
  }
  runtime::write_series_png(file, title, "distance along the centreline (mm)", "mean diameter (mm)",
                            x, series, std::numeric_limits<double>::quiet_NaN());
}

}  // namespace bisturi::cli
