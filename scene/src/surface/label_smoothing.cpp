// Steps 3 to 5 of label surfaces: constrained windowed-sinc smoothing (see label_smoothing.h).

#include "label_smoothing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "elapsed.h"
#include "label_field.h"

namespace bisturi {

// In a triangle the corner after v names one neighbour; around a closed manifold vertex these
// are all of them, once each. At an open border one is missing, which only weights the average.
Neighbours neighbours_of(const PolygonMesh& mesh) {
  Neighbours nb;
  const std::size_t n = mesh.positions.size();
  nb.offsets.assign(n + 1, 0);
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    for (const std::uint32_t v : mesh.face(f))
      ++nb.offsets[v + 1];
  }
  for (std::size_t v = 0; v < n; ++v)
    nb.offsets[v + 1] += nb.offsets[v];
  nb.adjacency.resize(nb.offsets[n]);
  nb.before.resize(nb.offsets[n]);
  std::vector<std::uint32_t> fill(nb.offsets.begin(), nb.offsets.end() - 1);
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const auto face = mesh.face(f);
    for (std::size_t c = 0; c < face.size(); ++c) {
      nb.before[fill[face[c]]] = face[(c + face.size() - 1) % face.size()];
      nb.adjacency[fill[face[c]]++] = face[(c + 1) % face.size()];
    }
  }
  return nb;
}

Neighbours neighbours_of(const Dlfl& mesh) {
  Neighbours nb;
  const std::size_t n = mesh.vertex_capacity();
  nb.offsets.reserve(n + 1);
  nb.offsets.push_back(0);
  nb.adjacency.reserve(6 * n);
  for (std::uint32_t v = 0; v < n; ++v) {
    const VertexId x(v);
    if (mesh.alive(x)) {
      for (RotationId r = mesh.first_rotation(x); r.valid(); r = mesh.next_rotation(r)) {
        const CornerId start = mesh.rotation_corner(r);
        CornerId c = start;
        do {
          if (!mesh.is_point_sphere(c)) {
            nb.adjacency.push_back(mesh.vertex(mesh.next(c)).idx);
            nb.before.push_back(mesh.vertex(mesh.prev(c)).idx);
          }
          c = mesh.rot_next(c);
        } while (c != start);
      }
    }
    nb.offsets.push_back(static_cast<std::uint32_t>(nb.adjacency.size()));
  }
  return nb;
}

namespace {

using Vec3 = Dlfl::Vec3;
using Clock = std::chrono::steady_clock;

using surface::seconds_since;

/// The windowed-sinc low-pass filter of Taubin, Zhang and Golub ("Optimal surface smoothing as
/// filter design", 1996) as weights a_i of the Chebyshev terms T_i(1 - k/2), k a frequency of the
/// umbrella Laplacian (0..2): a sinc cut at angle theta + sigma, Hamming-windowed. A filter of
/// low order cannot be as sharp as a small pass band asks, so the cut is moved out by sigma
/// until the gain at the pass band is 1, as the paper does: the shape's own low frequencies then
/// pass unchanged (no shrinkage) and the staircase's high ones do not.
std::vector<double> sinc_weights(std::size_t order, double pass_band) {
  constexpr double kPi = 3.14159265358979323846;
  const double theta = std::acos(1.0 - 0.5 * pass_band);
  std::vector<double> a(order + 1);
  const auto make = [&](double cut) {
    for (std::size_t i = 0; i <= order; ++i) {
      const double d = static_cast<double>(i);
      const double window = 0.54 + 0.46 * std::cos(d * kPi / static_cast<double>(order + 1));
      a[i] = window * (i == 0 ? cut / kPi : 2.0 * std::sin(d * cut) / (d * kPi));
    }
  };
  const auto gain_at_pass_band = [&] {
    double f = 0.0;
    for (std::size_t i = 0; i <= order; ++i)
      f += a[i] * std::cos(static_cast<double>(i) * theta);
    return f;
  };
  // The smallest such sigma: above it the gain at theta ripples about 1 and a larger root would
  // let far more through. Bracketed by steps, then bisected.
  double lo = 0.0, hi = 0.0;
  for (make(theta); gain_at_pass_band() < 1.0 && hi < kPi / 2.0 - theta; make(theta + hi)) {
    lo = hi;
    hi += 0.01;
  }
  for (int it = 0; it < 40; ++it) {
    const double mid = 0.5 * (lo + hi);
    make(theta + mid);
    (gain_at_pass_band() < 1.0 ? lo : hi) = mid;
  }
  make(theta + hi);
  return a;
}

/// Whether a point lies within kBandMargin of a cell (in cells, along each axis) whose corners
/// are neither all inside nor all outside: the band of cells the label's true boundary passes
/// through, where marching cubes put its vertices. The margin lets the filter's surface round
/// the band's corners instead of creasing at them. Outside the grid counts as outside the band.
class BandTest {
 public:
  static constexpr double kBandMargin = 0.25;
  explicit BandTest(const Grid<float>& field) : f_(field) {}
  bool operator()(const Vec3& world) const {
    const Vec3 at = f_.geometry.world_to_index(world);
    if (mixed(at)) return true;
    for (int o = 0; o < 8; ++o)
      if (mixed(at + kBandMargin * Vec3((o & 1) ? 1 : -1, (o & 2) ? 1 : -1, (o & 4) ? 1 : -1)))
        return true;
    return false;
  }

 private:
  [[nodiscard]] bool mixed(const Vec3& ijk) const {
    const auto& d = f_.geometry.dims;
    const Vec3 c = glm::floor(ijk);
    if (c.x < 0 || c.y < 0 || c.z < 0 || c.x >= static_cast<double>(d[0] - 1) ||
        c.y >= static_cast<double>(d[1] - 1) || c.z >= static_cast<double>(d[2] - 1))
      return false;
    const auto i = static_cast<std::int64_t>(c.x), j = static_cast<std::int64_t>(c.y),
               k = static_cast<std::int64_t>(c.z);
    float lo = 1.0F, hi = 0.0F;
    for (int corner = 0; corner < 8; ++corner) {
      const float v = f_.at(i + (corner & 1), j + ((corner >> 1) & 1), k + (corner >> 2));
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    return lo != hi;
  }

  const Grid<float>& f_;
};

/// Each vertex's unit normal: the sum of its faces' area vectors, normalised (0 where they
/// cancel).
void vertex_normals(std::span<const Vec3> pos, const Neighbours& nb, std::vector<Vec3>& normal) {
  for (std::size_t v = 0; v < pos.size(); ++v) {
    Vec3 sum(0.0);
    for (std::uint32_t k = nb.offsets[v]; k < nb.offsets[v + 1]; ++k)
      sum += glm::cross(pos[nb.adjacency[k]] - pos[v], pos[nb.before[k]] - pos[v]);
    const double length = glm::length(sum);
    normal[v] = length > 0.0 ? sum / length : Vec3(0.0);
  }
}

/// Sun, Rosin, Martin and Langbein, "Fast and effective feature-preserving mesh denoising"
/// (2007), section 3.2: each vertex moves along its faces' smooth normals by the mean of its
/// distances to their planes, so each face comes to lie across its smooth normal. The smooth
/// normal of a face is here the mean of its corners' normals (each the sum of its faces' area
/// vectors). `keep(p, v)` is where vertex v may go when it would go to p.
template <class Keep>
void fit_to_smooth_normals(std::span<Vec3> pos, const Neighbours& nb, std::size_t sweeps,
                           Keep&& keep) {
  const std::size_t n = pos.size();
  std::vector<Vec3> normal(n), moved(n);
  for (std::size_t sweep = 0; sweep < sweeps; ++sweep) {
    vertex_normals(pos, nb, normal);
    for (std::size_t v = 0; v < n; ++v) {
      const std::uint32_t b = nb.offsets[v], e = nb.offsets[v + 1];
      Vec3 move(0.0);
      for (std::uint32_t k = b; k < e; ++k) {
        const std::uint32_t x = nb.adjacency[k], y = nb.before[k];
        const Vec3 smooth = normal[v] + normal[x] + normal[y];
        const double length = glm::length(smooth);
        if (length == 0.0) continue;
        const Vec3 unit = smooth / length;
        move += glm::dot(unit, (pos[x] + pos[y] - 2.0 * pos[v]) / 3.0) * unit;
      }
      moved[v] = b == e ? pos[v] : pos[v] + move / static_cast<double>(e - b);
    }
    for (std::size_t v = 0; v < n; ++v)
      pos[v] = keep(moved[v], v);
  }
}

/// Tangential relaxation, as in isotropic remeshing (Botsch and Kobbelt, "A remeshing approach
/// to multiresolution modeling", 2004): each vertex moves to the centroid of its faces' centres,
/// weighted by their areas, less the part of that move along its normal. The shape stays (to
/// second order in the move) while the thin triangles that the caps and the band leave where a
/// thin part ends in a slice even out, and their normals, mostly their corners' small errors,
/// with them. Where the surface is too coarse for a tangent plane to stand for it (`coarse`,
/// too_coarse_shares) the vertices move less, none where it is wholly so. `keep(p, v)` is where
/// vertex v may go when it would go to p.
template <class Keep>
void relax_along_surface(std::span<Vec3> pos, const Neighbours& nb, std::size_t sweeps,
                         const std::vector<double>& coarse, Keep&& keep) {
  const std::size_t n = pos.size();
  std::vector<Vec3> normal(n), moved(n);
  for (std::size_t sweep = 0; sweep < sweeps; ++sweep) {
    vertex_normals(pos, nb, normal);
    for (std::size_t v = 0; v < n; ++v) {
      Vec3 centre(0.0);
      double area = 0.0;
      for (std::uint32_t k = nb.offsets[v]; k < nb.offsets[v + 1]; ++k) {
        const Vec3 x = pos[nb.adjacency[k]], y = pos[nb.before[k]];
        const double a = glm::length(glm::cross(x - pos[v], y - pos[v]));
        centre += a * (pos[v] + x + y) / 3.0;
        area += a;
      }
      const Vec3 move = area > 0.0 ? centre / area - pos[v] : Vec3(0.0);
      moved[v] = pos[v] + (1.0 - coarse[v]) * (move - glm::dot(move, normal[v]) * normal[v]);
    }
    for (std::size_t v = 0; v < n; ++v)
      pos[v] = keep(moved[v], v);
  }
}

/// Each vertex's value averaged with its neighbours', `sweeps` times.
void average_over_neighbours(std::vector<double>& value, const Neighbours& nb, int sweeps) {
  std::vector<double> averaged(value.size());
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    for (std::size_t v = 0; v < value.size(); ++v) {
      const std::uint32_t b = nb.offsets[v], e = nb.offsets[v + 1];
      double sum = value[v];
      for (std::uint32_t k = b; k < e; ++k)
        sum += value[nb.adjacency[k]];
      averaged[v] = sum / static_cast<double>(1 + e - b);
    }
    value.swap(averaged);
  }
}

/// How sharply the surface bends at each vertex against its sampling: the largest turn of its
/// normal to a neighbour per millimetre, times its mean edge length, averaged over its
/// neighbourhood.
std::vector<double> bends(std::span<const Vec3> pos, const Neighbours& nb) {
  constexpr int kAveragingSweeps = 5;
  const std::size_t n = pos.size();
  std::vector<Vec3> normal(n);
  vertex_normals(pos, nb, normal);
  std::vector<double> bend(n, 0.0);
  for (std::size_t v = 0; v < n; ++v) {
    const std::uint32_t b = nb.offsets[v], e = nb.offsets[v + 1];
    double sharpest = 0.0, edges = 0.0;
    for (std::uint32_t k = b; k < e; ++k) {
      const std::uint32_t x = nb.adjacency[k];
      const double d = glm::length(pos[x] - pos[v]);
      edges += d;
      if (d > 0.0) sharpest = std::max(sharpest, glm::length(normal[x] - normal[v]) / d);
    }
    bend[v] = b == e ? 0.0 : sharpest * edges / static_cast<double>(e - b);
  }
  average_over_neighbours(bend, nb, kAveragingSweeps);
  return bend;
}

/// Each vertex's share of the filtered residual added back (LabelSurfaceOptions::twicing_share),
/// by its bend: `flat` up to twicing_bend_flat, `sharp` from twicing_bend_sharp on.
std::vector<double> twicing_shares(const std::vector<double>& bend, const LabelSurfaceOptions& o,
                                   double flat, double sharp) {
  const std::size_t n = bend.size();
  std::vector<double> share(n);
  for (std::size_t v = 0; v < n; ++v) {
    const double t = std::clamp(
        (bend[v] - o.twicing_bend_flat) / (o.twicing_bend_sharp - o.twicing_bend_flat), 0.0, 1.0);
    share[v] = flat + t * (sharp - flat);
  }
  return share;
}

/// Whether the slices (across k) lie further apart than the samples within them, by a fifth or
/// more against the finer of the two: there a solid only a few slices high keeps its rim
/// (LabelSurfaceOptions::sharp_rounds).
bool thick_slices(const VolumeGeometry& g) {
  return g.spacing.z > kThicker * std::min(g.spacing.x, g.spacing.y);
}

/// Where the surface turns by about a radian or more from one vertex to the next (a tube two or
/// three samples across: a vessel at 3 mm samples), its samples are too few for a low-pass to
/// tell the shape from the staircase, and the filter draws it in towards its axis (a capsule 3
/// mm in radius at 3 x 3 x 3 mm lay 2.3 mm off RMS, as VTK's does); twicing brings nothing back,
/// since the residual is as sharp. Each vertex's share of too coarse: 1 from a bend of 2, none
/// under 1, averaged over the neighbourhood so the surface does not crease where it changes.
std::vector<double> too_coarse_shares(const std::vector<double>& bend, const Neighbours& nb) {
  constexpr double kFilteredUpTo = 1.0, kKeptFrom = 2.0;
  constexpr int kSpreadSweeps = 3;
  std::vector<double> share(bend.size());
  for (std::size_t v = 0; v < bend.size(); ++v)
    share[v] = std::clamp((bend[v] - kFilteredUpTo) / (kKeptFrom - kFilteredUpTo), 0.0, 1.0);
  average_over_neighbours(share, nb, kSpreadSweeps);
  return share;
}

/// Where too coarse, the vertices go back towards their places from steps 1 and 2 by that share.
template <typename Keep>
void keep_where_too_coarse(std::span<Vec3> pos, std::span<const Vec3> home,
                           const std::vector<double>& coarse, const Keep& kept_in_band) {
  for (std::size_t v = 0; v < coarse.size(); ++v)
    if (coarse[v] > 0.0) pos[v] = kept_in_band(pos[v] + coarse[v] * (home[v] - pos[v]), v);
}

}  // namespace

void smooth_in_band(std::span<Vec3> pos, const Neighbours& nb, const Grid<float>& field,
                    const LabelSurfaceOptions& o, LabelSurfaceStats& stats) {
  const auto start = Clock::now();
  const std::size_t n = pos.size();
  const std::vector<Vec3> home(pos.begin(), pos.end());
  const std::vector<double> a = sinc_weights(o.iterations, o.pass_band);
  // x_{i+1} = 2 (I - K/2) x_i - x_{i-1} = x_i + avg(x_i) - x_{i-1}, with x_1 = (x_0 + avg(x_0))/2.
  std::vector<Vec3> prev(n), cur(n), next(n);
  const auto average = [&](const std::vector<Vec3>& x, std::size_t v) {
    const std::uint32_t b = nb.offsets[v], e = nb.offsets[v + 1];
    if (b == e) return x[v];
    Vec3 sum(0.0);
    for (std::uint32_t k = b; k < e; ++k)
      sum += x[nb.adjacency[k]];
    return sum / static_cast<double>(e - b);
  };
  const BandTest in_band(field);
  std::size_t clamped = 0;
  std::vector<Vec3> input(n);
  // out = F(input), F the filter: sum of a_i x_i.
  const auto filter = [&](std::vector<Vec3>& out) {
    std::copy(input.begin(), input.end(), prev.begin());
    for (std::size_t v = 0; v < n; ++v) {
      cur[v] = 0.5 * (prev[v] + average(prev, v));
      out[v] = a[0] * prev[v] + a[1] * cur[v];
    }
    for (std::size_t i = 2; i <= o.iterations; ++i) {
      for (std::size_t v = 0; v < n; ++v) {
        next[v] = cur[v] + average(cur, v) - prev[v];
        out[v] += a[i] * next[v];
      }
      std::swap(prev, cur);
      std::swap(cur, next);
    }
  };
  std::vector<Vec3> smoothed(n), back(n);
  std::vector<double> bend, share;  // per vertex, set after the first round
  std::vector<std::uint8_t> held(n, 0);
  constexpr int kSpreadSweeps = 4;
  // From `from` (in the band) towards `to`: as far as the band goes.
  const auto towards_in_band = [&](const Vec3& from, const Vec3& to) {
    double lo = 0.0, hi = 1.0;
    for (int it = 0; it < 12; ++it) {
      const double mid = 0.5 * (lo + hi);
      (in_band(from + mid * (to - from)) ? lo : hi) = mid;
    }
    return from + lo * (to - from);
  };
  // Where vertex v may go when it would go to p: there if in the band, else as far towards it
  // from its marching-cubes position as the band goes.
  const auto kept_in_band = [&](const Vec3& p, std::size_t v) {
    return in_band(p) ? p : towards_in_band(home[v], p);
  };
  const bool thick = thick_slices(field.geometry);
  const std::size_t rounds = o.rounds + (o.rounds > 0 && thick ? o.sharp_rounds : 0);
  for (std::size_t round = 0; round < rounds; ++round) {
    // Round 0 filters the positions; each later one filters what is left between them and the
    // marching-cubes ones and adds a share w of it back (Tukey's twicing, gain (1 + w)F - wF^2
    // after two), which flattens the pass band, so curved parts shrink less while the staircase
    // stays filtered. The sharp rounds after those add back only where the surface bends sharply.
    for (std::size_t v = 0; v < n; ++v)
      input[v] = round == 0 ? Vec3(home[v]) : home[v] - pos[v];
    filter(smoothed);
    if (round == 0) {
      std::copy(smoothed.begin(), smoothed.end(), pos.begin());
    } else {
      if (share.empty()) {
        bend = bends(pos, nb);
        share = twicing_shares(bend, o, o.twicing_share_flat, o.twicing_share);
      }
      if (round == o.rounds) share = twicing_shares(bend, o, 0.0, o.twicing_share);
      for (std::size_t v = 0; v < n; ++v)
        pos[v] += share[v] * smoothed[v];
    }
    // Back into the band the voxels allow: along the way from its marching-cubes position (a
    // point of the band), as far as the band goes.
    clamped = 0;
    std::fill(held.begin(), held.end(), 0);
    for (std::size_t v = 0; v < n; ++v) {
      back[v] = Vec3(0.0);
      if (in_band(pos[v])) continue;
      ++clamped;
      held[v] = 1;
      back[v] = towards_in_band(home[v], pos[v]) - pos[v];
    }
    // The held vertices' way back spreads to their neighbours, fading (each free vertex takes
    // its neighbours' mean a few times): the surface bends back into the band instead of
    // creasing round each held vertex.
    if (clamped > 0) {
      std::vector<Vec3> spread(back);
      for (int sweep = 0; sweep < kSpreadSweeps; ++sweep) {
        for (std::size_t v = 0; v < n; ++v)
          if (!held[v]) spread[v] = average(back, v);
        back.swap(spread);
      }
      for (std::size_t v = 0; v < n; ++v)
        pos[v] = kept_in_band(pos[v] + back[v], v);
    }
    if (o.smooth_progress) o.smooth_progress(round + 1, rounds);
  }
  std::vector<double> coarse(n, 0.0);
  if (!bend.empty()) {
    coarse = too_coarse_shares(bend, nb);
    keep_where_too_coarse(pos, home, coarse, kept_in_band);
  }
  relax_along_surface(pos, nb, o.tangential_sweeps, coarse, kept_in_band);
  fit_to_smooth_normals(pos, nb, thick ? o.normal_fit_sweeps_thick : o.normal_fit_sweeps,
                        kept_in_band);
  stats.clamped_last = clamped;
  stats.smooth_seconds = seconds_since(start);
}

}  // namespace bisturi
