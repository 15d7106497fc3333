// A liquid's surface round its particles (see liquid_surface.h).

#include "bisturi/runtime/render/liquid_surface.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/gtc/type_precision.hpp>

#include <glm/common.hpp>

#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/volume/marching_cubes.h"

namespace bisturi::render {

LiquidSurface::LiquidSurface(const LiquidSurfaceOptions& options) : options_(options) {}

namespace {

/// Union-find root of i (with path halving).
std::uint32_t root(std::vector<std::uint32_t>& parent, std::uint32_t i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

}  // namespace

void LiquidSurface::cluster(std::span<const glm::dvec3> centres_mm) {
  // Particles whose kernels overlap (closer than twice the reach) share a grid; a spray of drops
  // far apart gets a small grid each instead of one grid over the whole field. The particles go
  // into cubes whose diagonal is under that distance, so those of one cube are linked without a
  // test; two cubes are linked by the first pair found close enough, and not searched at all
  // once they are in one group (a pool is one group after a pass over its cubes).
  const double link = 2.0 * options_.kernel_radius_mm;
  const double side = 0.999 * link / std::sqrt(3.0);
  const auto n = static_cast<std::uint32_t>(centres_mm.size());
  parent_.resize(n);
  for (std::uint32_t i = 0; i < n; ++i)
    parent_[i] = i;
  const auto cube_of = [side](const glm::dvec3& p) { return glm::i64vec3(glm::floor(p / side)); };
  const auto key_of = [](const glm::i64vec3& c) {
    constexpr std::int64_t kBias = 1 << 20;
    const auto u = [](std::int64_t v) { return static_cast<std::uint64_t>(v + kBias) & 0x1FFFFFu; };
    return u(c.x) << 42 | u(c.y) << 21 | u(c.z);
  };
  by_cube_.resize(n);
  for (std::uint32_t i = 0; i < n; ++i)
    by_cube_[i] = {key_of(cube_of(centres_mm[i])), i};
  std::sort(by_cube_.begin(), by_cube_.end());
  cube_begin_.clear();
  cube_keys_.clear();
  for (std::uint32_t a = 0; a < n; ++a) {
    if (a > 0 && by_cube_[a].first == by_cube_[a - 1].first) {
      parent_[root(parent_, by_cube_[a].second)] =
          root(parent_, by_cube_[cube_begin_.back()].second);
      continue;
    }
    cube_begin_.push_back(a);
    cube_keys_.push_back(by_cube_[a].first);
  }
  cube_begin_.push_back(n);
  // The cubes a cube's particles may reach: two cubes on along each axis at most. Cubes are in
  // key order (x, then y, then z), so the cubes of one column (dx, dy) round a cube follow one
  // another, and each column's start only moves on from cube to cube: a cursor per column walks
  // the keys once. Each pair of cubes is looked at from the earlier one.
  const std::size_t cubes = cube_keys_.size();
  std::array<std::size_t, 25> cursor{};
  for (std::size_t c = 0; c < cubes; ++c) {
    const std::uint32_t first = by_cube_[cube_begin_[c]].second;
    const glm::i64vec3 here = cube_of(centres_mm[first]);
    for (std::int64_t column = 0; column < 25; ++column) {
      const glm::i64vec3 low = here + glm::i64vec3(column % 5 - 2, column / 5 - 2, -2);
      const std::uint64_t from = key_of(low), to = key_of(low + glm::i64vec3(0, 0, 4));
      std::size_t& o = cursor[static_cast<std::size_t>(column)];
      while (o < cubes && cube_keys_[o] < from)
        ++o;
      for (std::size_t q = std::max(o, c + 1); q < cubes && cube_keys_[q] <= to; ++q) {
        const std::uint32_t other = by_cube_[cube_begin_[q]].second;
        const glm::i64vec3 d = cube_of(centres_mm[other]) - here;
        const glm::dvec3 gap(glm::max(glm::abs(d) - std::int64_t{1}, glm::i64vec3(0)));
        if (side * glm::length(gap) >= link) continue;
        if (root(parent_, first) == root(parent_, other)) continue;
        bool linked = false;
        for (std::uint32_t a = cube_begin_[c]; a < cube_begin_[c + 1] && !linked; ++a) {
          const glm::dvec3& p = centres_mm[by_cube_[a].second];
          for (std::uint32_t b = cube_begin_[q]; b < cube_begin_[q + 1] && !linked; ++b)
            linked = glm::length(p - centres_mm[by_cube_[b].second]) < link;
        }
        if (linked) parent_[root(parent_, first)] = root(parent_, other);
      }
    }
  }
  clusters_.clear();
  std::vector<std::int64_t> slot(n, -1);
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t r = root(parent_, i);
    if (slot[r] < 0) {
      slot[r] = static_cast<std::int64_t>(clusters_.size());
      clusters_.emplace_back();
    }
    clusters_[static_cast<std::size_t>(slot[r])].push_back(centres_mm[i]);
  }
}

const Dlfl& LiquidSurface::update(std::span<const glm::dvec3> centres_mm) {
  combined_ = PolygonMesh{};
  base_cell_mm_ = options_.cell_mm;
  if (options_.fine_particles > 0 && centres_mm.size() > options_.fine_particles)
    base_cell_mm_ =
        std::min(std::max(options_.max_cell_mm, options_.cell_mm),
                 options_.cell_mm * std::sqrt(static_cast<double>(centres_mm.size()) /
                                              static_cast<double>(options_.fine_particles)));
  cell_mm_ = base_cell_mm_;
  cluster(centres_mm);
  for (const std::vector<glm::dvec3>& c : clusters_)
    add_part(c);
  mesh_ = build_oriented_manifold(combined_);
  return mesh_;
}

void LiquidSurface::add_part(std::span<const glm::dvec3> centres_mm) {
  const double reach = options_.kernel_radius_mm;
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-lo);
  for (const glm::dvec3& c : centres_mm) {
    lo = glm::min(lo, c);
    hi = glm::max(hi, c);
  }
  // A margin of the kernel's reach and a cell more: the field is below iso on the grid's border,
  // so every part is closed.
  double cell = base_cell_mm_;
  glm::dvec3 extent = hi - lo + 2.0 * (reach + cell);
  const auto samples_at = [&](double h) {
    double n = 1.0;
    for (int a = 0; a < 3; ++a)
      n *= std::ceil(extent[a] / h) + 1.0;
    return n;
  };
  while (samples_at(cell) > static_cast<double>(options_.max_samples)) {
    cell *= 1.25;
    extent = hi - lo + 2.0 * (reach + cell);
  }
  cell_mm_ = std::max(cell_mm_, cell);
  VolumeGeometry& g = field_.geometry;
  for (int a = 0; a < 3; ++a)
    g.dims[static_cast<std::size_t>(a)] =
        static_cast<std::int64_t>(std::ceil(extent[a] / cell)) + 1;
  g.spacing = glm::dvec3(cell);
  g.origin = lo - (reach + cell);
  g.direction = glm::dmat3(1.0);
  field_.values.assign(g.voxel_count(), 0.0f);

  // Each particle adds its kernel to the samples within its reach.
  const double inv_r2 = 1.0 / (reach * reach);
  const auto span = static_cast<std::int64_t>(std::ceil(reach / cell));
  for (const glm::dvec3& c : centres_mm) {
    const glm::dvec3 at = (c - g.origin) / cell;
    const std::int64_t ci = std::llround(at.x), cj = std::llround(at.y), ck = std::llround(at.z);
    for (std::int64_t k = std::max<std::int64_t>(ck - span, 0);
         k <= std::min(ck + span, g.dims[2] - 1); ++k) {
      const double dz = g.origin.z + static_cast<double>(k) * cell - c.z;
      for (std::int64_t j = std::max<std::int64_t>(cj - span, 0);
           j <= std::min(cj + span, g.dims[1] - 1); ++j) {
        const double dy = g.origin.y + static_cast<double>(j) * cell - c.y;
        const double dyz = dy * dy + dz * dz;
        if (dyz >= reach * reach) continue;
        float* row = &field_.values[g.linear_index(0, j, k)];
        for (std::int64_t i = std::max<std::int64_t>(ci - span, 0);
             i <= std::min(ci + span, g.dims[0] - 1); ++i) {
          const double dx = g.origin.x + static_cast<double>(i) * cell - c.x;
          const double q = 1.0 - (dx * dx + dyz) * inv_r2;
          if (q > 0.0) row[i] += static_cast<float>(q * q * q);
        }
      }
    }
  }
  IsoSurfaceOptions iso;
  iso.iso = options_.iso;
  const PolygonMesh part = extract_isosurface_mesh(field_, iso);
  const auto base = static_cast<std::uint32_t>(combined_.positions.size());
  combined_.positions.insert(combined_.positions.end(), part.positions.begin(),
                             part.positions.end());
  for (std::size_t f = 0; f < part.face_count(); ++f) {
    const std::span<const std::uint32_t> face = part.face(f);
    combined_.add_face({face[0] + base, face[1] + base, face[2] + base});
  }
}

}  // namespace bisturi::render
