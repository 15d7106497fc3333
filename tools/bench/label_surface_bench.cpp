// Label-map surfaces against the true shape: analytic solids (sphere, tilted ellipsoid, tilted
// torus, two ellipsoids one empty slice apart) voxelised by sample centre at anisotropic spacing
// (0.6 x 0.6 x 1.3 mm, a CT series, and 1 x 1 x 3 mm, a thick-slice one), their surfaces extracted
// by
//   mc          marching cubes on the 0/1 indicator (what `bisturi extract --label` gave),
//   mc+taubin10 the same with 10 unconstrained Taubin iterations (`--smooth 10`),
//   shape-interp extract_label_surface_mesh without smoothing (shape-based interpolation only),
//   constrained  extract_label_surface_mesh (shape-based interpolation, then constrained
//                windowed-sinc smoothing; label_surface.h),
//   vtk         vtkDiscreteFlyingEdges3D + vtkWindowedSincPolyDataFilter with 3D Slicer's
//               defaults (with BISTURI_BENCH_VTK),
// and measured in one run: RMS and maximum distance of the vertices to the true surface (mm),
// RMS and maximum angle between face normals and the true normal (degrees, area-weighted RMS),
// and the median wall time of `--repeats` runs (one thread each). A plain program: the figures
// are a table, not a loop. `--json FILE` writes them too.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include "bisturi/scene/lod/smooth.h"
#include "bisturi/scene/polygon_export.h"
#include "bisturi/scene/volume/label_surface.h"
#include "bisturi/scene/volume/marching_cubes.h"

#ifdef BISTURI_BENCH_VTK
#include "label_vtk.h"
#endif

namespace {

using bisturi::Grid;
using bisturi::PolygonMesh;
using glm::dvec3;

constexpr float kLabel = 255.0F;

/// A solid: signed distance (negative inside), closest-point normal, and a bounding radius.
struct Shape {
  std::string name;
  double bound = 0.0;
  std::function<double(const dvec3&)> distance;
  std::function<dvec3(const dvec3&)> normal;  ///< outward unit normal at the closest point
};

const dvec3 kCentre(0.37, -0.21, 0.53);  // off the grid's symmetry

glm::dmat3 rotation(double ax_deg, double az_deg) {
  const glm::dmat4 r = glm::rotate(glm::rotate(glm::dmat4(1.0), glm::radians(az_deg), {0, 0, 1}),
                                   glm::radians(ax_deg), {1, 0, 0});
  return glm::dmat3(r);
}

Shape sphere(double r) {
  return {"sphere r" + std::to_string(int(r)), r,
          [r](const dvec3& p) { return glm::length(p - kCentre) - r; },
          [](const dvec3& p) { return glm::normalize(p - kCentre); }};
}

// Closest point on an ellipsoid (semi-axes a, local frame): the root t of
// sum (a_i q_i / (t + a_i^2))^2 = 1 above -min a_i^2, by bisection (Eberly's method).
dvec3 ellipsoid_closest(const dvec3& a, const dvec3& q) {
  const dvec3 s = glm::abs(q);
  const double amin = std::min({a.x, a.y, a.z});
  double lo = -amin * amin + 1e-12, hi = glm::length(a * s) + 1.0;
  const auto f = [&](double t) {
    const dvec3 u = a * s / (dvec3(t) + a * a);
    return glm::dot(u, u) - 1.0;
  };
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (f(mid) > 0.0 ? lo : hi) = mid;
  }
  const double t = 0.5 * (lo + hi);
  const dvec3 c = a * a * s / (dvec3(t) + a * a);
  return glm::sign(q) * c;
}

Shape ellipsoid(dvec3 a) {
  const glm::dmat3 r = rotation(30.0, 20.0);
  const glm::dmat3 rt = glm::transpose(r);
  const auto inside = [a](const dvec3& q) { return glm::dot(q / a, q / a) < 1.0; };
  return {"ellipsoid 25x15x10", std::max({a.x, a.y, a.z}),
          [=](const dvec3& p) {
            const dvec3 q = rt * (p - kCentre);
            const double d = glm::length(q - ellipsoid_closest(a, q));
            return inside(q) ? -d : d;
          },
          [=](const dvec3& p) {
            const dvec3 c = ellipsoid_closest(a, rt * (p - kCentre));
            return glm::normalize(r * (c / (a * a)));
          }};
}

/// Two ellipsoids (semi-axes a, turned 20 deg about z) stacked along the slice axis with one
/// empty slice between them: the slice of the grid `voxelise` makes at `spacing` nearest z = 0
/// lies in a gap of 1.2 slices, the slices either side of it inside one ellipsoid each.
Shape two_ellipsoids(dvec3 a, const dvec3& spacing) {
  const glm::dmat3 r = rotation(0.0, 20.0);
  const glm::dmat3 rt = glm::transpose(r);
  const double gap = 0.6 * spacing.z;
  const double bound = std::max({a.x, a.y, gap + 2.0 * a.z});
  const double half = bound + 3.0 * std::max({spacing.x, spacing.y, spacing.z});
  const double z0 = -half + std::round(half / spacing.z) * spacing.z;
  const dvec3 ca(kCentre.x, kCentre.y, z0 - gap - a.z), cb(kCentre.x, kCentre.y, z0 + gap + a.z);
  const auto signed_distance = [=](const dvec3& p, const dvec3& c) {
    const dvec3 q = rt * (p - c);
    const double d = glm::length(q - ellipsoid_closest(a, q));
    return glm::dot(q / a, q / a) < 1.0 ? -d : d;
  };
  return {"two ellipsoids 16x11x6", bound,
          [=](const dvec3& p) { return std::min(signed_distance(p, ca), signed_distance(p, cb)); },
          [=](const dvec3& p) {
            const dvec3 c = signed_distance(p, ca) < signed_distance(p, cb) ? ca : cb;
            const dvec3 q = ellipsoid_closest(a, rt * (p - c));
            return glm::normalize(r * (q / (a * a)));
          }};
}

Shape torus(double big, double small) {
  const glm::dmat3 r = rotation(25.0, 10.0);
  const glm::dmat3 rt = glm::transpose(r);
  const auto ring = [big](const dvec3& q) {
    const double rho = std::hypot(q.x, q.y);
    return dvec3(q.x / rho * big, q.y / rho * big, 0.0);
  };
  return {"torus 16/6", big + small,
          [=](const dvec3& p) {
            const dvec3 q = rt * (p - kCentre);
            return glm::length(q - ring(q)) - small;
          },
          [=](const dvec3& p) {
            const dvec3 q = rt * (p - kCentre);
            return glm::normalize(r * (q - ring(q)));
          }};
}

/// A vessel lying across the slices: a capsule (radius r, its axis 2 half_length long) turned
/// 30 deg within the slices and tilted `tilt_deg` out of them.
Shape lying_vessel(double r, double half_length, double tilt_deg) {
  const glm::dmat3 turn = rotation(0.0, 30.0);
  const dvec3 axis = turn * glm::normalize(dvec3(1.0, 0.0, std::tan(glm::radians(tilt_deg))));
  const auto closest_on_axis = [=](const dvec3& p) {
    const double t = std::clamp(glm::dot(p - kCentre, axis), -half_length, half_length);
    return kCentre + t * axis;
  };
  char name[48];
  std::snprintf(name, sizeof name, tilt_deg == 8.0 ? "vessel r%g lying" : "vessel r%g tilt %g", r,
                tilt_deg);
  return {name, half_length + r,
          [=](const dvec3& p) { return glm::length(p - closest_on_axis(p)) - r; },
          [=](const dvec3& p) { return glm::normalize(p - closest_on_axis(p)); }};
}

Grid<float> voxelise(const Shape& s, const dvec3& spacing) {
  Grid<float> g;
  const double half = s.bound + 3.0 * std::max({spacing.x, spacing.y, spacing.z});
  for (int a = 0; a < 3; ++a)
    g.geometry.dims[a] = static_cast<std::int64_t>(std::ceil(2.0 * half / spacing[a])) + 1;
  g.geometry.spacing = spacing;
  g.geometry.origin = dvec3(-half);
  g.values.resize(g.geometry.voxel_count());
  for (std::int64_t k = 0; k < g.geometry.dims[2]; ++k)
    for (std::int64_t j = 0; j < g.geometry.dims[1]; ++j)
      for (std::int64_t i = 0; i < g.geometry.dims[0]; ++i) {
        const dvec3 p = g.geometry.index_to_world(dvec3(i, j, k));
        g.at(i, j, k) = s.distance(p) < 0.0 ? kLabel : 0.0F;
      }
  return g;
}

struct Errors {
  double rms_mm = 0, max_mm = 0, normal_rms_deg = 0, normal_max_deg = 0;
  std::size_t triangles = 0;
};

/// --list-far: vertices further than this from the true surface are listed (negative: none).
double list_far_mm = -1.0;

Errors measure(const Shape& s, const std::vector<dvec3>& pts,
               const std::vector<std::uint32_t>& tris) {
  Errors e;
  double sum2 = 0;
  for (const dvec3& p : pts) {
    const double d = s.distance(p);
    sum2 += d * d;
    e.max_mm = std::max(e.max_mm, std::abs(d));
    if (list_far_mm >= 0.0 && std::abs(d) > list_far_mm) {
      const dvec3 n = s.normal(p);
      std::fprintf(stderr,
                   "  far %.3f at (%.2f %.2f %.2f) from the centre, normal (%.2f %.2f %.2f)\n", d,
                   p.x - kCentre.x, p.y - kCentre.y, p.z - kCentre.z, n.x, n.y, n.z);
    }
  }
  e.rms_mm = std::sqrt(sum2 / static_cast<double>(pts.size()));
  double area = 0, angle2 = 0;
  dvec3 worst_face(0.0);
  for (std::size_t t = 0; t + 2 < tris.size(); t += 3) {
    const dvec3 a = pts[tris[t]], b = pts[tris[t + 1]], c = pts[tris[t + 2]];
    const dvec3 n = glm::cross(b - a, c - a);
    const double len = glm::length(n);
    if (len == 0.0) continue;
    const double cosine = std::clamp(glm::dot(n / len, s.normal((a + b + c) / 3.0)), -1.0, 1.0);
    const double deg = glm::degrees(std::acos(cosine));
    angle2 += 0.5 * len * deg * deg;
    area += 0.5 * len;
    if (deg > e.normal_max_deg) worst_face = (a + b + c) / 3.0;
    e.normal_max_deg = std::max(e.normal_max_deg, deg);
  }
  e.normal_rms_deg = std::sqrt(angle2 / area);
  if (list_far_mm >= 0.0 && area > 0.0) {
    const dvec3 at = worst_face - kCentre, n = s.normal(worst_face);
    std::fprintf(stderr, "  worst normal %.1f deg at (%.2f %.2f %.2f), normal (%.2f %.2f %.2f)\n",
                 e.normal_max_deg, at.x, at.y, at.z, n.x, n.y, n.z);
  }
  e.triangles = tris.size() / 3;
  return e;
}

void from_mesh(const PolygonMesh& m, std::vector<dvec3>& pts, std::vector<std::uint32_t>& tris) {
  pts.assign(m.positions.begin(), m.positions.end());
  tris.clear();
  for (std::size_t f = 0; f < m.face_count(); ++f)
    for (const std::uint32_t v : m.face(f))
      tris.push_back(v);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct Row {
  std::string shape, spacing, method;
  Errors e;
  double ms = 0;
};

}  // namespace

int main(int argc, char** argv) {
  int repeats = 5;
  std::string json_path;
  bisturi::LabelSurfaceOptions constrained;  // the defaults unless given
  std::vector<std::pair<std::string, dvec3>> spacings;
  bool with_vessel = false;
  double vessel_radius = 3.0, vessel_tilt = 8.0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::printf(
          "label_surface_bench [--repeats N] [--iterations N] [--pass-band K] [--rounds N]\n"
          "                    [--sharp-rounds N] [--fit-sweeps-thick N]\n"
          "                    [--twicing-share W] [--twicing-shares FLAT,SHARP]\n"
          "                    [--twicing-bends FLAT,SHARP] [--fit-sweeps N] [--tangential-sweeps "
          "N]\n"
          "                    [--spacing X,Y,Z]...\n"
          "                    [--json FILE]\n"
          "                    [--list-far MM] [--vessel] [--vessel-radius MM]\n"
          "                    [--vessel-tilt DEG]\n"
          "  surfaces of voxelised analytic solids against the true shape: marching cubes,\n"
          "  constrained smoothing and (when built with VTK) 3D Slicer's VTK pipeline;\n"
          "  each --spacing (mm) replaces the default 0.6,0.6,1.3 and 1,1,3; --list-far writes\n"
          "  each vertex further than MM from the true surface to stderr, before its row,\n"
          "  and the face whose normal is furthest off;\n"
          "  --twicing-share W adds back one share W everywhere instead of the one the\n"
          "  surface's bend sets; --twicing-shares and --twicing-bends set the shares at\n"
          "  and the bends of a flat and a sharply bent surface; --sharp-rounds N sets the\n"
          "  rounds that add back only where it bends sharply (at thick slices);\n"
          "  --fit-sweeps-thick N the fit's sweeps there (--fit-sweeps: elsewhere);\n"
          "  --vessel adds a vessel (a\n"
          "  capsule 3 mm in radius, 36 mm long) lying across the slices, tilted 8 deg out of\n"
          "  them; --vessel-radius and --vessel-tilt change those (and imply --vessel)\n");
      return 0;
    }
    if (a == "--repeats" && i + 1 < argc) {
      repeats = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--iterations" && i + 1 < argc) {
      constrained.iterations = static_cast<std::size_t>(std::max(0, std::atoi(argv[++i])));
    } else if (a == "--pass-band" && i + 1 < argc) {
      constrained.pass_band = std::atof(argv[++i]);
    } else if (a == "--rounds" && i + 1 < argc) {
      constrained.rounds = static_cast<std::size_t>(std::max(0, std::atoi(argv[++i])));
    } else if (a == "--sharp-rounds" && i + 1 < argc) {
      constrained.sharp_rounds = static_cast<std::size_t>(std::max(0, std::atoi(argv[++i])));
    } else if (a == "--twicing-share" && i + 1 < argc) {
      constrained.twicing_share = constrained.twicing_share_flat = std::atof(argv[++i]);
    } else if ((a == "--twicing-shares" || a == "--twicing-bends") && i + 1 < argc) {
      double flat = 0.0, sharp = 0.0;
      char tail = 0;
      if (std::sscanf(argv[++i], "%lf,%lf%c", &flat, &sharp, &tail) != 2) {
        std::fprintf(stderr, "label_surface_bench: %s wants FLAT,SHARP, got '%s'\n", a.c_str(),
                     argv[i]);
        return 2;
      }
      (a == "--twicing-shares" ? constrained.twicing_share_flat : constrained.twicing_bend_flat) =
          flat;
      (a == "--twicing-shares" ? constrained.twicing_share : constrained.twicing_bend_sharp) =
          sharp;
    } else if (a == "--tangential-sweeps" && i + 1 < argc) {
      constrained.tangential_sweeps = static_cast<std::size_t>(std::max(0, std::atoi(argv[++i])));
    } else if (a == "--fit-sweeps" && i + 1 < argc) {
      constrained.normal_fit_sweeps = static_cast<std::size_t>(std::max(0, std::atoi(argv[++i])));
    } else if (a == "--fit-sweeps-thick" && i + 1 < argc) {
      constrained.normal_fit_sweeps_thick =
          static_cast<std::size_t>(std::max(0, std::atoi(argv[++i])));
    } else if (a == "--vessel") {
      with_vessel = true;
    } else if ((a == "--vessel-radius" || a == "--vessel-tilt") && i + 1 < argc) {
      const double value = std::atof(argv[++i]);
      const bool radius = a == "--vessel-radius";
      if (!(value > 0.0) || (!radius && value >= 90.0)) {
        std::fprintf(stderr, "label_surface_bench: %s wants %s, got '%s'\n", a.c_str(),
                     radius ? "a radius in mm above 0" : "an angle in degrees in (0, 90)", argv[i]);
        return 2;
      }
      (radius ? vessel_radius : vessel_tilt) = value;
      with_vessel = true;
    } else if (a == "--list-far" && i + 1 < argc) {
      list_far_mm = std::atof(argv[++i]);
    } else if (a == "--spacing" && i + 1 < argc) {
      const std::string text = argv[++i];
      dvec3 v(0.0);
      char tail = 0;
      if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &v.x, &v.y, &v.z, &tail) != 3 ||
          !(v.x > 0.0 && v.y > 0.0 && v.z > 0.0)) {
        std::fprintf(stderr, "label_surface_bench: --spacing wants X,Y,Z in mm, got '%s'\n",
                     text.c_str());
        return 2;
      }
      std::string name = text;
      std::replace(name.begin(), name.end(), ',', 'x');
      spacings.emplace_back(name, v);
    } else if (a == "--json" && i + 1 < argc) {
      json_path = argv[++i];
    } else {
      std::fprintf(stderr, "label_surface_bench: unknown argument '%s' (see --help)\n", argv[i]);
      return 2;
    }
  }
  if (spacings.empty()) spacings = {{"0.6x0.6x1.3", {0.6, 0.6, 1.3}}, {"1x1x3", {1.0, 1.0, 3.0}}};
  std::vector<Row> rows;
  std::printf("%-20s %-12s %-13s %9s %9s %9s %9s %9s %8s\n", "shape", "spacing", "method", "rms_mm",
              "max_mm", "n_rms_deg", "n_max_deg", "ms", "tris");
  for (const auto& [sname, spacing] : spacings) {
    std::vector<Shape> shapes = {sphere(20.0), ellipsoid({25.0, 15.0, 10.0}), torus(16.0, 6.0),
                                 two_ellipsoids({16.0, 11.0, 6.0}, spacing)};
    if (with_vessel) shapes.push_back(lying_vessel(vessel_radius, 15.0, vessel_tilt));
    for (const Shape& s : shapes) {
      const Grid<float> labels = voxelise(s, spacing);
      std::vector<dvec3> pts;
      std::vector<std::uint32_t> tris;
      const auto run = [&](const std::string& method, const auto& extract) {
        std::vector<double> ms;
        for (int r = 0; r < repeats; ++r)
          ms.push_back(extract());
        Row row{s.name, sname, method, measure(s, pts, tris), median(ms)};
        std::printf("%-20s %-12s %-13s %9.4f %9.4f %9.3f %9.3f %9.2f %8zu\n", row.shape.c_str(),
                    row.spacing.c_str(), row.method.c_str(), row.e.rms_mm, row.e.max_mm,
                    row.e.normal_rms_deg, row.e.normal_max_deg, row.ms, row.e.triangles);
        std::fflush(stdout);
        rows.push_back(row);
      };
      // Timed: the extraction into an indexed mesh (or VTK's polydata), not the copy out.
      const auto ours = [&](const bisturi::LabelSurfaceOptions& o) {
        return [&, o] {
          const auto t = std::chrono::steady_clock::now();
          const PolygonMesh m = bisturi::extract_label_surface_mesh(labels, kLabel, o);
          const double ms =
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t)
                  .count();
          from_mesh(m, pts, tris);
          return ms;
        };
      };
      // The previous extraction: marching cubes on the 0/1 indicator, vertices at edge midpoints.
      bisturi::Grid<float> indicator;
      indicator.geometry = labels.geometry;
      indicator.values.resize(labels.values.size());
      for (std::size_t i = 0; i < labels.values.size(); ++i)
        indicator.values[i] = labels.values[i] == kLabel ? 1.0F : 0.0F;
      bisturi::IsoSurfaceOptions half;
      half.iso = 0.5F;
      run("mc", [&] {
        const auto t = std::chrono::steady_clock::now();
        const PolygonMesh m = bisturi::extract_isosurface_mesh(indicator, half);
        const double ms =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
        from_mesh(m, pts, tris);
        return ms;
      });
      run("mc+taubin10", [&] {  // `--smooth 10`: the DLFL path, its build timed too
        const auto t = std::chrono::steady_clock::now();
        bisturi::Dlfl d = bisturi::extract_isosurface(indicator, half);
        bisturi::lod::SmoothOptions taubin;
        taubin.iterations = 10;
        bisturi::lod::smooth_taubin(d, taubin);
        const double ms =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
        from_mesh(bisturi::export_polygons(d).polygons, pts, tris);
        return ms;
      });
      bisturi::LabelSurfaceOptions interpolated_only;
      interpolated_only.iterations = 0;
      run("shape-interp", ours(interpolated_only));
      run("constrained", ours(constrained));
#ifdef BISTURI_BENCH_VTK
      run("vtk", [&] {
        const double sp[3] = {spacing.x, spacing.y, spacing.z};
        const double origin[3] = {labels.geometry.origin.x, labels.geometry.origin.y,
                                  labels.geometry.origin.z};
        const auto v = bisturi::bench::vtk_label_surface(
            labels.values.data(), labels.geometry.dims.data(), sp, origin, kLabel, 1);
        pts.resize(v.points.size() / 3);
        for (std::size_t i = 0; i < pts.size(); ++i)
          pts[i] = dvec3(v.points[3 * i], v.points[3 * i + 1], v.points[3 * i + 2]);
        tris.assign(v.triangles.begin(), v.triangles.end());
        return v.seconds * 1e3;
      });
#endif
    }
  }
  if (!json_path.empty()) {
    std::ofstream out(json_path);
    out << "[\n";
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const Row& r = rows[i];
      out << "  {\"shape\": \"" << r.shape << "\", \"spacing\": \"" << r.spacing
          << "\", \"method\": \"" << r.method << "\", \"rms_mm\": " << r.e.rms_mm
          << ", \"max_mm\": " << r.e.max_mm << ", \"normal_rms_deg\": " << r.e.normal_rms_deg
          << ", \"normal_max_deg\": " << r.e.normal_max_deg << ", \"ms\": " << r.ms
          << ", \"triangles\": " << r.e.triangles << "}" << (i + 1 < rows.size() ? "," : "")
          << "\n";
    }
    out << "]\n";
  }
  return 0;
}
