// The caps of a label's surface over its last slices (see label_caps.h).

#include "label_caps.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <optional>
#include <vector>

namespace bisturi {

namespace {

/// A region's radius (its largest in-slice distance) in its last slice and in the two slices
/// before it, over the same samples (0 where there is no such slice). Where the label ends over
/// the region, also its area (in samples) in those slices: the area of the region in the last
/// slice and of the inside samples joined to it in the slices before.
struct Radii {
  float last = -1.0F, before = 0.0F, before2 = 0.0F;
  /// No sample of the region is inside in the slice beyond it: the label ends over it.
  bool ends = true;
  float area_last = 0.0F, area_before = 0.0F, area_before2 = 0.0F;
};

/// The 4-connected inside regions of one slice, flooded as they are asked for, with their radii
/// (and areas, where the label ends over them) in it and in the two slices before it (away from
/// the slice beyond).
class SliceRegions {
 public:
  explicit SliceRegions(const Grid<float>& field)
      : field_(field),
        nx_(field.geometry.dims[0]),
        ny_(field.geometry.dims[1]),
        nz_(field.geometry.dims[2]),
        radii_(static_cast<std::size_t>(nx_ * ny_)),
        stamp_(static_cast<std::size_t>(nx_ * ny_), -1),
        joined_stamp_(static_cast<std::size_t>(nx_ * ny_), 0) {}

  /// Looks at slice k, the slice beyond it k + step.
  void look_at(std::int64_t k, std::int64_t step) {
    k_ = k;
    step_ = step;
    ++generation_;
  }

  /// The radii of the region holding sample (i, j) of the slice, which must be inside.
  const Radii& at(std::int64_t i, std::int64_t j) {
    const std::int64_t seed = j * nx_ + i;
    if (stamp_[static_cast<std::size_t>(seed)] != generation_) flood(seed);
    return radii_[static_cast<std::size_t>(seed)];
  }

 private:
  [[nodiscard]] const float* slice(std::int64_t k) const {
    return k >= 0 && k < nz_ ? &field_.values[field_.geometry.linear_index(0, 0, k)] : nullptr;
  }

  /// The 4-neighbours of sample s in the slice (-1 past its edge).
  [[nodiscard]] std::array<std::int64_t, 4> neighbours(std::int64_t s) const {
    const std::int64_t x = s % nx_, y = s / nx_;
    return {x > 0 ? s - 1 : -1, x + 1 < nx_ ? s + 1 : -1, y > 0 ? s - nx_ : -1,
            y + 1 < ny_ ? s + nx_ : -1};
  }

  void flood(std::int64_t seed) {
    const float* here = slice(k_);
    const float* beyond = slice(k_ + step_);
    const float* inner = slice(k_ - step_);
    const float* inner2 = slice(k_ - 2 * step_);
    stack_.assign(1, seed);
    members_.clear();
    stamp_[static_cast<std::size_t>(seed)] = generation_;
    Radii most{0.0F, 0.0F, 0.0F, true};
    while (!stack_.empty()) {
      const std::int64_t s = stack_.back();
      stack_.pop_back();
      members_.push_back(s);
      most.last = std::max(most.last, here[s]);
      if (inner != nullptr) most.before = std::max(most.before, inner[s]);
      if (inner2 != nullptr) most.before2 = std::max(most.before2, inner2[s]);
      if (beyond != nullptr && beyond[s] > 0.0F) most.ends = false;
      for (const std::int64_t n : neighbours(s)) {
        if (n < 0 || here[n] <= 0.0F || stamp_[static_cast<std::size_t>(n)] == generation_)
          continue;
        stamp_[static_cast<std::size_t>(n)] = generation_;
        stack_.push_back(n);
      }
    }
    if (most.ends) {
      most.area_last = static_cast<float>(members_.size());
      most.area_before = static_cast<float>(join(inner, members_, joined_));
      most.area_before2 = static_cast<float>(join(inner2, joined_, joined2_));
    }
    for (const std::int64_t m : members_)
      radii_[static_cast<std::size_t>(m)] = most;
  }

  /// Floods the inside samples of `slice` (may be null) joined to `seeds` (4-connected, starting
  /// from the seeds inside there) into `joined` (not `seeds`); returns how many.
  std::size_t join(const float* slice, const std::vector<std::int64_t>& seeds,
                   std::vector<std::int64_t>& joined) {
    joined.clear();
    if (slice == nullptr) return 0;
    ++join_generation_;
    stack_.clear();
    for (const std::int64_t s : seeds) {
      if (slice[s] <= 0.0F || joined_stamp_[static_cast<std::size_t>(s)] == join_generation_)
        continue;
      joined_stamp_[static_cast<std::size_t>(s)] = join_generation_;
      stack_.push_back(s);
    }
    while (!stack_.empty()) {
      const std::int64_t s = stack_.back();
      stack_.pop_back();
      joined.push_back(s);
      for (const std::int64_t n : neighbours(s)) {
        if (n < 0 || slice[n] <= 0.0F ||
            joined_stamp_[static_cast<std::size_t>(n)] == join_generation_)
          continue;
        joined_stamp_[static_cast<std::size_t>(n)] = join_generation_;
        stack_.push_back(n);
      }
    }
    return joined.size();
  }

  const Grid<float>& field_;
  std::int64_t nx_, ny_, nz_;
  std::int64_t k_ = 0, step_ = 1, generation_ = -1;
  std::vector<Radii> radii_;
  std::vector<std::int64_t> stamp_;         ///< the look a sample's radii were found in
  std::vector<std::int64_t> joined_stamp_;  ///< the join that reached a sample last
  std::int64_t join_generation_ = 0;
  std::vector<std::int64_t> stack_, members_, joined_, joined2_;
};

/// A region's size in its last three slices, as squares of a width: its radius squared, or its
/// area (both change as alpha D - beta D^2 over depth D under an ellipsoid's or a ball's end).
struct SquaredSizes {
  double last = 0.0, before = 0.0, before2 = 0.0;
  /// The solid is these two slices high: nothing lies beyond the one before the last either.
  bool two_slices_high = false;
  /// The sizes are squared radii (mm^2), which go as 2 R D - D^2 over depth D under a round
  /// section's top: two slices place it.
  bool radii = false;
};

/// How far past the last slice (in slice spacings) the end lies above a sample at `u` (its
/// distance from its region's middle over the region's radius, 0 to 1). The region's squared
/// size over depth D below the end is fitted as an ellipsoid's, alpha D - beta D^2, through the
/// last three slices (exact for the end of an ellipsoid or a ball; beta 0 is a paraboloid), also
/// where the middle one is the widest (a solid three slices high, whose far end is near). A solid
/// only two slices high has its two ends share the spacing beyond them; a tube's local radii
/// through only two slices place its top as a round section's. Otherwise, or where the
/// fit puts the end a spacing or more away, it is a paraboloid through both outlines; where the
/// region does not narrow towards the end (a flat end), a paraboloid half a spacing high, where
/// such an end lies on average. The sample lies on the outline of the section whose size is u
/// times the last one's.
double cap_height(double u, const SquaredSizes& s, double dz) {
  const double s1 = s.last, s2 = s.before, s3 = s.before2;
  const double own = u * u * s1;  // the squared size of the section through the sample
  const auto height = [&](double alpha, double beta, double depth) {
    // The depth below the end where the squared size is own: beta D^2 - alpha D + own = 0.
    const double disc = alpha * alpha - 4.0 * beta * own;
    const double d = std::abs(beta) < 1e-12 * alpha * alpha / std::max(s1, 1e-30)
                         ? own / alpha
                         : (alpha - std::sqrt(std::max(disc, 0.0))) / (2.0 * beta);
    return (depth - d) / dz;
  };
  if (s.two_slices_high && s2 > 0.0) {
    // Both ends of a solid two slices high lie between them and the slices beyond, as far as a
    // solid of twice the spacing, its size D (2 dz - D) at depth D under the end, puts them:
    // the last slice at depth h where h (2 dz - h) / ((dz + h) (dz - h)) = s1 / s2.
    const double ratio = s1 / s2;
    double lo = 0.0, hi = dz;
    for (int it = 0; it < 40; ++it) {
      const double h = 0.5 * (lo + hi);
      (h * (2.0 * dz - h) < ratio * (dz + h) * (dz - h) ? lo : hi) = h;
    }
    const double h = 0.5 * (lo + hi);
    const double d = dz - std::sqrt(std::max(dz * dz - u * u * h * (2.0 * dz - h), 0.0));
    return (h - d) / dz;
  }
  if (s.radii && s2 > 0.0 && s3 == 0.0) {
    // A round section (a tube lying along the slices, two slices high) through both outlines:
    // its centre c below the last slice, where s1 = R^2 - c^2 and s2 = R^2 - (dz - c)^2.
    const double c = (dz * dz - s1 + s2) / (2.0 * dz);
    const double radius = std::sqrt(s1 + c * c);
    if (radius - c < dz) return (std::sqrt(std::max(radius * radius - own, 0.0)) - c) / dz;
  }
  if (s2 > s1 && s3 > 0.0) {
    const double d1 = s2 - s1, d2 = s3 - s2;
    const double beta = (d1 - d2) / (2.0 * dz * dz);
    const double a = (d1 + beta * dz * dz) / dz;  // alpha - 2 beta h
    // beta h^2 + a h - s1 = 0 for the last slice's depth h.
    const bool linear = std::abs(beta) * s1 < 1e-12 * a * a;
    const double h =
        linear ? s1 / a : (-a + std::sqrt(std::max(a * a + 4.0 * beta * s1, 0.0))) / (2.0 * beta);
    if (a > 0.0 && h > 0.0 && h < dz) {
      return height(a + 2.0 * beta * h, beta, h);
    }
  }
  if (s2 > s1) {
    // A paraboloid (r^2 = 2 R D) through both outlines: its end s1 / (s2 - s1) spacings past
    // the last slice, at most 0.7 (a paraboloid's end lies further than a flatter end's).
    return std::clamp(s1 / (s2 - s1), 0.1, 0.7) * (1.0 - u * u);
  }
  return 0.5 * (1.0 - u * u);
}

/// A region's radius squared in its last three slices.
SquaredSizes squared_radii(const Radii& r) {
  return {.last = double(r.last) * r.last,
          .before = double(r.before) * r.before,
          .before2 = double(r.before2) * r.before2,
          .radii = true};
}

/// A region's area in its last three slices.
SquaredSizes areas(const Radii& r) {
  return {.last = r.area_last,
          .before = r.area_before,
          .before2 = r.area_before2,
          .two_slices_high = r.area_before > 0.0F && r.area_before2 == 0.0F};
}

/// A sample whose local radius is under this share of its region's is on a part of the region
/// narrower than its middle (a band, an arm, the thin end of a crescent), which may end by
/// itself: a ridge or a saddle. On a round region the two differ by the ray's sampling error.
constexpr float kNarrowerThanItsRegion = 0.9F;

/// The radius of the widest disc of slice k's region that holds sample (i, j), near it: from the
/// sample straight away from its nearest outline point (up the distance's gradient) to where the
/// distance stops growing, the region's local middle (the centre line of a band, the centre of a
/// round region). Unlike the region's largest distance, it is the width that ends here: at a
/// saddle or along a ridge the region may be far wider elsewhere in the slice. The ray stops
/// once the radius passes `enough`.
float local_radius(const Grid<float>& field, std::int64_t i, std::int64_t j, std::int64_t k,
                   double enough = std::numeric_limits<double>::infinity()) {
  const VolumeGeometry& g = field.geometry;
  const std::int64_t nx = g.dims[0], ny = g.dims[1];
  const auto value = [&](std::int64_t x, std::int64_t y) {
    return field.at(std::clamp<std::int64_t>(x, 0, nx - 1), std::clamp<std::int64_t>(y, 0, ny - 1),
                    k);
  };
  const float here = field.at(i, j, k);
  const double hx = g.spacing.x, hy = g.spacing.y;
  // The gradient in mm: central differences.
  const double gx = (value(i + 1, j) - value(i - 1, j)) / (2.0 * hx);
  const double gy = (value(i, j + 1) - value(i, j - 1)) / (2.0 * hy);
  const double length = std::hypot(gx, gy);
  if (length < 0.25) return here;  // on the middle already
  // Bilinear in the slice, in index units.
  const auto sample = [&](double x, double y) {
    const double fx = std::floor(x), fy = std::floor(y);
    const auto x0 = static_cast<std::int64_t>(fx), y0 = static_cast<std::int64_t>(fy);
    const double u = x - fx, w = y - fy;
    return (1.0 - w) * ((1.0 - u) * value(x0, y0) + u * value(x0 + 1, y0)) +
           w * ((1.0 - u) * value(x0, y0 + 1) + u * value(x0 + 1, y0 + 1));
  };
  const double step = 0.5 * std::min(hx, hy);
  const double dx = gx / length * step / hx, dy = gy / length * step / hy;
  double best = here, x = static_cast<double>(i), y = static_cast<double>(j);
  for (std::int64_t s = 0; s < 4 * (nx + ny); ++s) {
    x += dx;
    y += dy;
    if (x < 0.0 || y < 0.0 || x > static_cast<double>(nx - 1) || y > static_cast<double>(ny - 1))
      break;
    const double d = sample(x, y);
    best = std::max(best, d);
    if (d < best - step || best > enough) break;  // past the middle, or as wide as asked
  }
  return static_cast<float>(best);
}

/// Where a part of a region narrower than its middle (a ridge, a saddle, a crescent's arm) tops
/// out over sample (i, j) of slice `last`, its local radius, else 0: the part ends here under a
/// cap as wide as it is here, not as the region's widest part (the top of a ring's tube, a tube
/// lying along the slices). It ends here where the whole region does (`ends`), or where no
/// outline of the slice beyond reaches over the sample's local middle (that outline is
/// `-outside` from the sample). Only parts wider than a slice spacing: a narrower one's radii
/// over three slices say little of its shape.
float narrow_part_end_radius(const Grid<float>& field, std::int64_t i, std::int64_t j,
                             std::int64_t last, const Radii& region, double inside,
                             double outside) {
  const double dz = field.geometry.spacing.z;
  const double narrower = kNarrowerThanItsRegion * region.last;
  // The local radius is at least `inside`: these rule most samples out without the ray.
  if (narrower <= dz || (!region.ends && inside - outside <= dz)) return 0.0F;
  const double enough = region.ends ? narrower : std::min(narrower, inside - outside);
  const float local = local_radius(field, i, j, last, enough);
  const bool ends_here =
      local > dz && local < narrower && (region.ends || local - inside + outside <= 0.0);
  return ends_here ? local : 0.0F;
}

/// The local radii at (i, j) in slice `last` (known) and the two before it (away from `step`).
Radii local_radii(const Grid<float>& field, std::int64_t i, std::int64_t j, std::int64_t last,
                  float radius_in_last, std::int64_t step) {
  Radii r;
  r.last = radius_in_last;
  const std::int64_t nz = field.geometry.dims[2];
  const auto at = [&](std::int64_t k) {
    return k >= 0 && k < nz && field.at(i, j, k) > 0.0F ? local_radius(field, i, j, k) : 0.0F;
  };
  r.before = at(last - step);
  r.before2 = r.before > 0.0F ? at(last - 2 * step) : 0.0F;
  return r;
}

/// How far a sample `inside` deep in its region lies from the region's middle towards its
/// outline, as a share of the way (0 to 1): it lies on the outline of the region shrunk by that
/// share about its middle, the region taken as an ellipse whose minor radius is the region's
/// radius and whose half-width at the sample is the sample's local radius `local`. A point y off
/// the long axis, where the half-width is w, lies on the ellipse shrunk by u where
/// u^2 = 1 - (w^2 - y^2) / radius^2, and y = w - inside. Exact for a round region (local =
/// radius: u = 1 - inside / radius) and across a band (a tube's section: the same); along an
/// ellipse's long axis, where the radius alone puts a sample nearer the middle than it is, it
/// moves the sample out (halfway along a section twice as long as wide: u 0.5, not 0.18).
double section_share(double inside, double local, double radius) {
  const double w = std::clamp(local, inside, radius);
  return std::sqrt(std::max(1.0 - (2.0 * w * inside - inside * inside) / (radius * radius), 0.0));
}

/// A region whose area is more than this many times its widest disc's is long (a band, a tube
/// lying along the slice) rather than round.
constexpr double kLongerThanRound = 2.0;

/// Over sample (i, j) of slice `last` of a region that goes on into the slice beyond only
/// further along (a tube lying across the slices, rising into it elsewhere, whose top runs along
/// the last slice), or of a long region that ends there (the tube's higher end): how far past
/// the slice (in spacings) the top lies: from the round section through the sample's local
/// widths in the last slice and the one before, where the tube is only those two slices high,
/// or about the last slice, where the tube is only that slice high; where it is higher and
/// `higher` is set, as a narrow part's end, its local widths fitted over the last three slices
/// (the top of a ring's tube, three or more slices high, running along the last slice: at 1.4 mm
/// samples linear interpolation left it 0.4 mm low). None where the slice beyond's outline
/// reaches over the sample's local middle, or the tube is higher and `higher` is not set.
/// `local` is the sample's local radius in the last slice.
std::optional<double> tube_top_height(const Grid<float>& field, std::int64_t i, std::int64_t j,
                                      std::int64_t last, float local, double inside, double outside,
                                      std::int64_t step, bool higher) {
  if (!(local > 0.0F) || local - inside + outside > 0.0) return std::nullopt;
  const Radii r = local_radii(field, i, j, last, local, step);
  const double dz = field.geometry.spacing.z;
  const double u = std::max(local - inside, 0.0) / local;
  if (!(r.before > 0.0F)) {
    // Only the last slice holds the tube here: nothing says where its section's middle lies,
    // and a slice through it on average passes its middle, so the section is round about the
    // slice, its radius the local width.
    const double top = local * std::sqrt(std::max(1.0 - u * u, 0.0));
    return top > 0.0 && top < dz ? std::optional<double>(top / dz) : std::nullopt;
  }
  if (r.before2 > 0.0F && !higher) return std::nullopt;
  return cap_height(u, squared_radii(r), dz);
}

}  // namespace

void place_vertices_across_slices(std::span<Dlfl::Vec3> positions, const Grid<float>& field,
                                  AcrossSlices which) {
  const bool ends_only = which == AcrossSlices::EndsFurtherOut;
  const VolumeGeometry& g = field.geometry;
  const std::int64_t nz = g.dims[2];
  if (nz < 2 || positions.empty()) return;
  // The vertices on k-edges, by the slice their edge starts at. Those the caps moved along another
  // axis keep a thousandth of a spacing from the samples; vertices on edges of this axis are
  // on the samples' lines.
  std::vector<std::vector<std::size_t>> on_edge(static_cast<std::size_t>(nz));
  for (std::size_t v = 0; v < positions.size(); ++v) {
    const glm::dvec3 c = g.world_to_index(positions[v]);
    if (std::abs(c.x - std::round(c.x)) > 1e-4 || std::abs(c.y - std::round(c.y)) > 1e-4) continue;
    const auto k = static_cast<std::int64_t>(std::floor(c.z));
    if (k < 0 || k + 1 >= nz) continue;
    on_edge[static_cast<std::size_t>(k)].push_back(v);
  }
  // Edges up from slice k and down from slice k + 1: the regions of each, looking the way the
  // edges go.
  SliceRegions up(field), down(field);
  for (std::int64_t k = 0; k + 1 < nz; ++k) {
    if (on_edge[static_cast<std::size_t>(k)].empty()) continue;
    up.look_at(k, 1);
    down.look_at(k + 1, -1);
    for (const std::size_t v : on_edge[static_cast<std::size_t>(k)]) {
      glm::dvec3 c = g.world_to_index(positions[v]);
      const std::int64_t i = std::llround(c.x), j = std::llround(c.y);
      // The edge runs from the region's last slice (`last`) out of the label.
      const float below = field.at(i, j, k), above = field.at(i, j, k + 1);
      const bool rising = below > 0.0F && above <= 0.0F;
      if (!rising && !(above > 0.0F && below <= 0.0F)) continue;
      const std::int64_t last = rising ? k : k + 1, outward = rising ? 1 : -1;
      const Radii& r = rising ? up.at(i, j) : down.at(i, j);
      if (r.last <= 0.0F) continue;
      const double inside = rising ? below : above, outside = rising ? above : below;
      const double rho = std::max(static_cast<double>(r.last) - inside, 0.0);
      double t = 0.0;
      if (const float local =
              ends_only ? 0.0F : narrow_part_end_radius(field, i, j, last, r, inside, outside);
          local > 0.0F) {
        t = cap_height(std::max(local - inside, 0.0) / local,
                       squared_radii(local_radii(field, i, j, last, local, outward)), g.spacing.z);
      } else if (r.ends) {
        // A long region's areas follow its length, not how its section narrows (the top of a
        // tube lying along the last slice): its local widths place the end where they can.
        const float width_here = local_radius(field, i, j, last);
        std::optional<double> top;
        if (r.area_last * g.spacing.x * g.spacing.y >
            kLongerThanRound * std::numbers::pi * r.last * r.last)
          top = tube_top_height(field, i, j, last, width_here, inside, outside, outward, false);
        if (top) {
          t = *top;
        } else {
          // The sections of most ends shrink alike towards the end (an ellipsoid's); the sample
          // lies on the one through it. A tip's regions along a finely sampled axis are a few
          // samples across, too few for a local width to say more than the radius.
          const double u = ends_only ? rho / r.last : section_share(inside, width_here, r.last);
          t = cap_height(u, areas(r), g.spacing.z);
        }
      } else {
        if (ends_only) continue;  // the field holds distances only about the ends
        // The region goes on narrowing into the slice beyond: its width there at the sample's
        // place is rho + outside. The square of a width, not the width, changes evenly from
        // slice to slice over a rounded end (r^2 = 2 R D under a sphere's top), so the outline
        // passes the sample where the squared width is rho^2. On a wide region that is where
        // the distances interpolated linearly put it.
        const double wide = r.last, narrow = rho + outside;
        if (narrow > 0.0) {
          if (!(narrow < wide)) continue;
          t = (wide * wide - rho * rho) / (wide * wide - narrow * narrow);
        } else if (const std::optional<double> top =
                       tube_top_height(field, i, j, last, local_radius(field, i, j, last), inside,
                                       outside, outward, true)) {
          t = *top;
        } else {
          continue;
        }
      }
      if (ends_only) t = std::max(t, std::abs(c.z - static_cast<double>(last)));
      // Kept strictly inside the edge, as marching cubes keeps its vertices.
      t = std::clamp(t, 1e-3, 1.0 - 1e-3);
      c.z = static_cast<double>(last) + (rising ? t : -t);
      c.x = static_cast<double>(i);
      c.y = static_cast<double>(j);
      positions[v] = g.index_to_world(c);
    }
  }
}

}  // namespace bisturi
