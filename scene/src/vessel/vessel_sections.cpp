#include "bisturi/scene/vessel/vessel_sections.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <glm/geometric.hpp>

#include "bisturi/scene/errors.h"

namespace bisturi {

namespace {

/// Two unit vectors spanning the plane normal to n.
void plane_basis(const glm::dvec3& n, glm::dvec3& u, glm::dvec3& v) {
  const glm::dvec3 a = std::abs(n.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  u = glm::normalize(glm::cross(n, a));
  v = glm::cross(n, u);
}

struct LoopCentroid {
  glm::dvec3 centroid{0.0};
  double area = 0.0;
};

/// The area centroid of the closed loop of `cut` that winds around `p` (the smallest if several).
std::optional<LoopCentroid> loop_around(const PlaneCut& cut, const glm::dvec3& p) {
  glm::dvec3 u, v;
  plane_basis(cut.plane.normal, u, v);
  std::optional<LoopCentroid> best;
  for (const CutLoop& loop : cut.loops) {
    if (!loop.closed) continue;
    const auto& pts = loop.surface_points.empty() ? loop.points : loop.surface_points;
    if (pts.size() < 3) continue;
    int winding = 0;
    double area2 = 0.0;
    glm::dvec2 c(0.0);
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const glm::dvec3 a3 = pts[i] - p, b3 = pts[(i + 1) % pts.size()] - p;
      const glm::dvec2 a(glm::dot(a3, u), glm::dot(a3, v)), b(glm::dot(b3, u), glm::dot(b3, v));
      const double cr = a.x * b.y - b.x * a.y;
      area2 += cr;
      c += (a + b) * cr;
      if (a.y <= 0.0) {
        if (b.y > 0.0 && cr > 0.0) ++winding;
      } else if (b.y <= 0.0 && cr < 0.0) {
        --winding;
      }
    }
    if (winding == 0 || area2 == 0.0) continue;
    c /= 3.0 * area2;
    const double area = 0.5 * std::abs(area2);
    if (!best || area < best->area) best = LoopCentroid{p + c.x * u + c.y * v, area};
  }
  return best;
}

void recompute_distances(Centreline& c) {
  for (CentrelineBranch& b : c.branches) {
    double d =
        b.parent < 0 ? 0.0 : c.branches[static_cast<std::size_t>(b.parent)].distance_mm.back();
    b.distance_mm.assign(b.points.size(), d);
    for (std::size_t k = 1; k < b.points.size(); ++k) {
      d += glm::distance(b.points[k - 1], b.points[k]);
      b.distance_mm[k] = d;
    }
  }
}

glm::dvec3 point_at(const CentrelineBranch& b, double d, double* radius = nullptr) {
  const auto& ds = b.distance_mm;
  if (d <= ds.front()) {
    if (radius) *radius = b.radius_mm.front();
    return b.points.front();
  }
  if (d >= ds.back()) {
    if (radius) *radius = b.radius_mm.back();
    return b.points.back();
  }
  const std::size_t k =
      static_cast<std::size_t>(std::upper_bound(ds.begin(), ds.end(), d) - ds.begin()) - 1;
  const double span = ds[k + 1] - ds[k];
  const double t = span > 0.0 ? (d - ds[k]) / span : 0.0;
  if (radius) *radius = (1.0 - t) * b.radius_mm[k] + t * b.radius_mm[k + 1];
  return (1.0 - t) * b.points[k] + t * b.points[k + 1];
}

double median_radius(const CentrelineBranch& b) {
  std::vector<double> r = b.radius_mm;
  if (r.empty()) return 0.0;
  std::nth_element(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2), r.end());
  return r[r.size() / 2];
}

}  // namespace

CentrelineSample sample_branch(const CentrelineBranch& branch, double distance_mm) {
  CentrelineSample s;
  if (branch.points.empty()) return s;
  const double d = std::clamp(distance_mm, branch.distance_mm.front(), branch.distance_mm.back());
  s.point = point_at(branch, d, &s.radius_mm);
  const double half = std::max(s.radius_mm, 1e-3);
  const double lo = std::max(branch.distance_mm.front(), d - half);
  const double hi = std::min(branch.distance_mm.back(), d + half);
  const glm::dvec3 t = point_at(branch, hi) - point_at(branch, lo);
  if (glm::length(t) > 0.0) s.tangent = glm::normalize(t);
  return s;
}

RecentreStats recentre_on_surface(const CutIndex& index, Centreline& centreline) {
  RecentreStats stats;
  CutOptions cut_options;
  for (CentrelineBranch& b : centreline.branches) {
    std::vector<glm::dvec3> moved = b.points;
    for (std::size_t k = 1; k + 1 < b.points.size(); ++k) {
      const CentrelineSample s = sample_branch(b, b.distance_mm[k]);
      const PlaneCut cut = index.cut({b.points[k], s.tangent}, cut_options);
      const std::optional<LoopCentroid> c = loop_around(cut, b.points[k]);
      const double move = c ? glm::distance(c->centroid, b.points[k]) : 0.0;
      // A centroid farther than a radius is a different section (a merged loop at a crotch).
      if (!c || move > b.radius_mm[k] + 1e-9) {
        ++stats.kept;
        continue;
      }
      moved[k] = c->centroid;
      ++stats.moved;
      stats.max_move_mm = std::max(stats.max_move_mm, move);
    }
    b.points = std::move(moved);
  }
  recompute_distances(centreline);
  return stats;
}

SectionsResult measure_sections(const CutIndex& index, const Centreline& centreline,
                                const SectionOptions& options) {
  if (!(options.step_mm > 0.0) || !std::isfinite(options.step_mm)) {
    throw InputError("sections: the step must be a positive number of mm");
  }
  SectionsResult out;
  for (const CentrelineBranch& b : centreline.branches) {
    if (b.points.size() < 2) continue;
    const double r = median_radius(b);
    const double lo = b.distance_mm.front() +
                      (b.parent < 0 ? options.end_margin_radii * r
                                    : options.junction_margin_radii * b.radius_mm.front());
    const double hi =
        b.distance_mm.back() - (b.ends_at_tip ? options.end_margin_radii * r
                                              : options.junction_margin_radii * b.radius_mm.back());
    for (auto k = static_cast<long long>(std::ceil(lo / options.step_mm - 1e-9));
         static_cast<double>(k) * options.step_mm <= hi + 1e-9; ++k) {
      const double d = static_cast<double>(k) * options.step_mm;
      const CentrelineSample s = sample_branch(b, d);
      VesselSection section;
      section.branch = b.id;
      section.distance_mm = d;
      if (options.orthogonal_search) {
        OrthogonalOptions o;
        o.measure = options.measure;
        const OrthogonalSection found = find_orthogonal_section(index, s.point, s.tangent, o);
        if (!found.found) {
          ++out.skipped_no_loop;
          continue;
        }
        section.measures = found.measures;
        section.normal = found.plane.normal;
        section.tilt_degrees = found.tilt_degrees;
        section.cuts = found.evaluations;
      } else {
        const PlaneCut cut = index.cut({s.point, s.tangent});
        const LoopMeasures* best = nullptr;
        std::vector<LoopMeasures> all = measure_cut(cut, options.measure);
        const std::optional<LoopCentroid> around = loop_around(cut, s.point);
        for (const LoopMeasures& m : all) {
          if (around && m.closed &&
              (!best || glm::distance(m.centroid, around->centroid) <
                            glm::distance(best->centroid, around->centroid)))
            best = &m;
        }
        if (!best) {
          ++out.skipped_no_loop;
          continue;
        }
        section.measures = *best;
        section.normal = cut.plane.normal;
        section.cuts = 1;
      }
      section.centre = section.measures.centroid;
      out.sections.push_back(section);
    }
  }
  return out;
}

}  // namespace bisturi
