#include "bisturi/scene/measure/section_measures.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <limits>
#include <numbers>

#include <glm/geometric.hpp>

#include "bisturi/scene/errors.h"

namespace bisturi {
namespace {

using Vec3 = glm::dvec3;
using Complex = std::complex<double>;
constexpr double kPi = std::numbers::pi;
/// A harmonic is signal when its power exceeds this many times the noise floor.
constexpr double kFloorFactor = 4.0;

/// An orthonormal frame of the plane: world = origin + x u + y v.
struct Frame {
  Vec3 origin, u, v, n;
  explicit Frame(const Plane& plane) : origin(plane.point), n(glm::normalize(plane.normal)) {
    const Vec3 helper = std::abs(n.x) < 0.6 ? Vec3(1, 0, 0) : Vec3(0, 1, 0);
    u = glm::normalize(glm::cross(n, helper));
    v = glm::cross(n, u);
  }
  [[nodiscard]] Complex to_plane(const Vec3& p) const {
    const Vec3 d = p - origin;
    return {glm::dot(d, u), glm::dot(d, v)};
  }
  [[nodiscard]] Vec3 to_world(Complex z) const { return origin + z.real() * u + z.imag() * v; }
};

double cross2(Complex a, Complex b) {
  return a.real() * b.imag() - a.imag() * b.real();
}

/// Convex hull (counter-clockwise, no collinear points), Andrew's monotone chain.
std::vector<Complex> convex_hull(std::vector<Complex> pts) {
  std::sort(pts.begin(), pts.end(), [](Complex a, Complex b) {
    return a.real() < b.real() || (a.real() == b.real() && a.imag() < b.imag());
  });
  pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
  if (pts.size() < 3) return pts;
  std::vector<Complex> h(2 * pts.size());
  std::size_t k = 0;
  for (const Complex p : pts) {
    while (k >= 2 && cross2(h[k - 1] - h[k - 2], p - h[k - 2]) <= 0.0)
      --k;
    h[k++] = p;
  }
  for (std::size_t i = pts.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross2(h[k - 1] - h[k - 2], pts[i] - h[k - 2]) <= 0.0)
      --k;
    h[k++] = pts[i];
  }
  h.resize(k - 1);
  return h;
}

/// Minimum width and diameter of a point set (rotating calipers on its hull).
std::pair<double, double> calipers(const std::vector<Complex>& pts) {
  const std::vector<Complex> h = convex_hull(pts);
  const std::size_t n = h.size();
  if (n == 0) return {0.0, 0.0};
  if (n < 3) return {0.0, n == 2 ? std::abs(h[1] - h[0]) : 0.0};
  double width = std::numeric_limits<double>::infinity(), diameter = 0.0;
  std::size_t j = 1;
  for (std::size_t i = 0; i < n; ++i) {
    const Complex a = h[i], b = h[(i + 1) % n];
    const Complex e = b - a;
    const double len = std::abs(e);
    auto height = [&](std::size_t q) { return cross2(e, h[q % n] - a); };
    while (height(j + 1) > height(j))
      j = (j + 1) % n;
    width = std::min(width, height(j) / len);
    diameter = std::max({diameter, std::abs(h[j] - a), std::abs(h[j] - b)});
  }
  return {width, diameter};
}

/// Shoelace area (signed) and area centroid of a closed polygon.
std::pair<double, Complex> polygon_area_centroid(const std::vector<Complex>& z) {
  double a2 = 0.0;
  Complex c(0.0);
  const Complex o = z.empty() ? Complex(0.0) : z[0];  // relative to a vertex: no cancellation
  for (std::size_t i = 0; i < z.size(); ++i) {
    const Complex p = z[i] - o, q = z[(i + 1) % z.size()] - o;
    const double w = cross2(p, q);
    a2 += w;
    c += w * (p + q);
  }
  if (a2 == 0.0) {
    Complex mean(0.0);
    for (const Complex p : z)
      mean += p;
    return {0.0, z.empty() ? mean : mean / double(z.size())};
  }
  return {0.5 * a2, o + c / (3.0 * a2)};
}

/// Length and arc-length mean distance from c of a polyline (closed: with the closing segment).
std::pair<double, double> polyline_length_mean_distance(const std::vector<Complex>& z, bool closed,
                                                        Complex c) {
  double length = 0.0, weighted = 0.0;
  const std::size_t segments = closed ? z.size() : z.size() - 1;
  for (std::size_t i = 0; i < segments; ++i) {
    const Complex a = z[i], b = z[(i + 1) % z.size()];
    const double l = std::abs(b - a);
    length += l;
    // Simpson's rule on the segment (|p - c| is smooth along it away from c).
    weighted += l / 6.0 * (std::abs(a - c) + 4.0 * std::abs(0.5 * (a + b) - c) + std::abs(b - c));
  }
  return {length, length > 0.0 ? weighted / length : 0.0};
}

void polygon_measures(const std::vector<Complex>& z, bool closed, LoopMeasures& m,
                      Complex& centroid) {
  const auto [area, c] = polygon_area_centroid(z);
  centroid = c;
  m.area = std::abs(area);
  const auto [length, mean] = polyline_length_mean_distance(z, closed, c);
  m.perimeter = length;
  m.mean_diameter = 2.0 * mean;
  const auto [w, d] = calipers(z);
  m.min_caliper = w;
  m.max_caliper = d;
  m.harmonics = 0;
}

/// Solves the Hermitian positive definite system A x = b (row-major, n x n) by Cholesky.
bool solve_hpd(std::vector<Complex>& a, std::vector<Complex>& b, std::size_t n) {
  for (std::size_t j = 0; j < n; ++j) {
    double d = a[j * n + j].real();
    for (std::size_t k = 0; k < j; ++k)
      d -= std::norm(a[j * n + k]);
    if (!(d > 0.0)) return false;
    d = std::sqrt(d);
    a[j * n + j] = d;
    for (std::size_t i = j + 1; i < n; ++i) {
      Complex s = a[i * n + j];
      for (std::size_t k = 0; k < j; ++k)
        s -= a[i * n + k] * std::conj(a[j * n + k]);
      a[i * n + j] = s / d;
    }
  }
  for (std::size_t i = 0; i < n; ++i) {  // L y = b
    Complex s = b[i];
    for (std::size_t k = 0; k < i; ++k)
      s -= a[i * n + k] * b[k];
    b[i] = s / a[i * n + i].real();
  }
  for (std::size_t i = n; i-- > 0;) {  // L^H x = y
    Complex s = b[i];
    for (std::size_t k = i + 1; k < n; ++k)
      s -= std::conj(a[k * n + i]) * b[k];
    b[i] = s / a[i * n + i].real();
  }
  return true;
}

/// The smooth-curve measures of a closed loop (see the header); false when the fit fails.
bool smooth_measures(const std::vector<Complex>& z, double edge_length, double cutoff,
                     bool adaptive, LoopMeasures& m, Complex& centroid) {
  const std::size_t n = z.size();
  std::vector<double> s(n + 1, 0.0);
  for (std::size_t i = 0; i < n; ++i)
    s[i + 1] = s[i] + std::abs(z[(i + 1) % n] - z[i]);
  const double length = s[n];
  if (!(length > 0.0)) return false;
  if (!(edge_length > 0.0)) edge_length = 2.0 * length / double(n);
  const double k_wanted = std::floor(length / (cutoff * edge_length));
  const std::size_t k_max = std::min<std::size_t>(200, (n - 1) / 2);
  if (k_wanted < 2.0 || k_max < 2) return false;
  const std::size_t K = std::min<std::size_t>(k_max, static_cast<std::size_t>(k_wanted));
  const std::size_t dim = 2 * K + 1;

  // Weighted least squares: G c = b, G(j, k) = h(k - j), h(m) = sum w_i e^{i m u_i}.
  std::vector<Complex> h(2 * K + 1, Complex(0.0));
  std::vector<Complex> rhs(dim, Complex(0.0));
  for (std::size_t i = 0; i < n; ++i) {
    const double w =
        0.5 * ((s[i + 1] - s[i]) + (i == 0 ? s[n] - s[n - 1] : s[i] - s[i - 1])) / length;
    const double u = 2.0 * kPi * s[i] / length;
    const Complex step = std::polar(1.0, u);
    Complex e(1.0);
    for (std::size_t mm = 0; mm <= 2 * K; ++mm) {
      h[mm] += w * e;
      e *= step;
    }
    // rhs_j = sum w z e^{-i j u}, j = -K..K.
    const Complex wz = w * z[i];
    Complex ep(1.0), en(1.0);
    const Complex back = std::conj(step);
    rhs[K] += wz;
    for (std::size_t j = 1; j <= K; ++j) {
      ep *= back;  // e^{-i j u}
      en *= step;  // e^{+i j u}
      rhs[K + j] += wz * ep;
      rhs[K - j] += wz * en;
    }
  }
  std::vector<Complex> g(dim * dim);
  for (std::size_t r = 0; r < dim; ++r) {
    for (std::size_t c = 0; c < dim; ++c) {
      const auto d = static_cast<std::ptrdiff_t>(c) - static_cast<std::ptrdiff_t>(r);
      g[r * dim + c] =
          d >= 0 ? h[static_cast<std::size_t>(d)] : std::conj(h[static_cast<std::size_t>(-d)]);
    }
    g[r * dim + r] += 1e-12;
  }
  if (!solve_hpd(g, rhs, dim)) return false;
  std::vector<Complex>& coef = rhs;  // c_k at index K + k
  std::size_t kept = K;
  if (adaptive && K >= 8) {
    // Noise floor: the median power of the upper half of the band; keep harmonics up to the
    // last one clearly above it.
    std::vector<double> power(K + 1, 0.0);
    for (std::size_t k = 1; k <= K; ++k)
      power[k] = std::norm(coef[K + k]) + std::norm(coef[K - k]);
    std::vector<double> upper(power.begin() + static_cast<std::ptrdiff_t>(K / 2 + 1), power.end());
    const auto mid = upper.begin() + static_cast<std::ptrdiff_t>(upper.size() / 2);
    std::nth_element(upper.begin(), mid, upper.end());
    const double floor = *mid;
    kept = 2;
    for (std::size_t k = K; k > 2; --k) {
      if (power[k] > kFloorFactor * floor) {
        kept = k;
        break;
      }
    }
    for (std::size_t k = kept + 1; k <= K; ++k)
      coef[K + k] = coef[K - k] = Complex(0.0);
  }

  double area = 0.0;
  for (std::size_t idx = 0; idx < dim; ++idx) {
    const double k = double(idx) - double(K);
    area += kPi * k * std::norm(coef[idx]);
  }
  const std::size_t samples = std::max<std::size_t>(512, 16 * K);
  std::vector<Complex> pts(samples);
  std::vector<double> speed(samples);
  for (std::size_t q = 0; q < samples; ++q) {
    const double u = 2.0 * kPi * double(q) / double(samples);
    const Complex step = std::polar(1.0, u);
    Complex e = std::polar(1.0, -double(K) * u);
    Complex p(0.0), dp(0.0);
    for (std::size_t idx = 0; idx < dim; ++idx) {
      const double k = double(idx) - double(K);
      p += coef[idx] * e;
      dp += Complex(0.0, k) * coef[idx] * e;
      e *= step;
    }
    pts[q] = p;
    speed[q] = std::abs(dp);
  }
  double perimeter = 0.0;
  for (const double v : speed)
    perimeter += v;
  perimeter *= 2.0 * kPi / double(samples);
  centroid = polygon_area_centroid(pts).second;
  double weighted = 0.0, total = 0.0;
  for (std::size_t q = 0; q < samples; ++q) {
    weighted += std::abs(pts[q] - centroid) * speed[q];
    total += speed[q];
  }
  m.area = std::abs(area);
  m.perimeter = perimeter;
  m.mean_diameter = total > 0.0 ? 2.0 * weighted / total : 0.0;
  const auto [w, d] = calipers(pts);
  m.min_caliper = w;
  m.max_caliper = d;
  m.harmonics = kept;
  return true;
}

}  // namespace

LoopMeasures measure_loop(const CutLoop& loop, const Plane& plane, const MeasureOptions& options) {
  LoopMeasures m;
  const Frame frame(plane);
  m.normal = frame.n;
  m.closed = loop.closed;
  m.faces_touched = loop.faces_touched;
  m.points = loop.points.size();
  if (loop.points.empty()) return m;

  std::vector<Complex> raw(loop.points.size());
  for (std::size_t i = 0; i < raw.size(); ++i)
    raw[i] = frame.to_plane(loop.points[i]);
  {
    const auto [a, c] = polygon_area_centroid(raw);
    (void)c;
    m.polygon_area = std::abs(a);
    m.polygon_perimeter = polyline_length_mean_distance(raw, loop.closed, c).first;
  }
  const bool surface =
      options.use_surface_points && loop.surface_points.size() == loop.points.size();
  std::vector<Complex> z = raw;
  if (surface) {
    for (std::size_t i = 0; i < z.size(); ++i)
      z[i] = frame.to_plane(loop.surface_points[i]);
  }
  Complex centroid(0.0);
  const double cutoff = options.cutoff_spacings > 0.0 ? options.cutoff_spacings : 4.0;
  if (!(loop.closed && options.smooth && z.size() >= 8 &&
        smooth_measures(z, loop.edge_length, cutoff, options.adaptive_cutoff, m, centroid))) {
    polygon_measures(z, loop.closed, m, centroid);
  }
  m.centroid = frame.to_world(centroid);
  m.equivalent_diameter = 2.0 * std::sqrt(m.area / kPi);
  return m;
}

std::vector<LoopMeasures> measure_cut(const PlaneCut& cut, const MeasureOptions& options) {
  std::vector<LoopMeasures> out;
  out.reserve(cut.loops.size());
  for (const CutLoop& loop : cut.loops)
    out.push_back(measure_loop(loop, cut.plane, options));
  return out;
}

namespace {

/// Winding number of the closed polygon z around p (non-zero: p is inside).
int winding(const std::vector<Complex>& z, Complex p) {
  int w = 0;
  for (std::size_t i = 0; i < z.size(); ++i) {
    const Complex a = z[i] - p, b = z[(i + 1) % z.size()] - p;
    if (a.imag() <= 0.0) {
      if (b.imag() > 0.0 && cross2(a, b) > 0.0) ++w;
    } else if (b.imag() <= 0.0 && cross2(a, b) < 0.0) {
      --w;
    }
  }
  return w;
}

struct Candidate {
  double area = std::numeric_limits<double>::infinity();
  std::size_t loop = 0;
  bool found = false;
};

/// The loop around the point (smallest containing one; else the closest closed loop).
Candidate loop_around(const PlaneCut& cut, const Vec3& point) {
  const Frame frame(cut.plane);
  const Complex p = frame.to_plane(point);
  Candidate inside, closest;
  double closest_distance = std::numeric_limits<double>::infinity();
  for (std::size_t l = 0; l < cut.loops.size(); ++l) {
    const CutLoop& loop = cut.loops[l];
    if (!loop.closed) continue;
    const std::vector<Vec3>& src =
        loop.surface_points.size() == loop.points.size() ? loop.surface_points : loop.points;
    std::vector<Complex> z(src.size());
    for (std::size_t i = 0; i < z.size(); ++i)
      z[i] = frame.to_plane(src[i]);
    const auto [signed_area, c] = polygon_area_centroid(z);
    const double area = std::abs(signed_area);
    if (winding(z, p) != 0) {
      if (area < inside.area) inside = {area, l, true};
    } else if (std::abs(c - p) < closest_distance) {
      closest_distance = std::abs(c - p);
      closest = {area, l, true};
    }
  }
  return inside.found ? inside : closest;
}

}  // namespace

OrthogonalSection find_orthogonal_section(const CutIndex& index, const Vec3& point,
                                          const Vec3& direction, const OrthogonalOptions& options) {
  const double len = glm::length(direction);
  if (!(len > 0.0) || !std::isfinite(len)) {
    throw InputError("orthogonal section: the direction must be non-zero and finite");
  }
  const Vec3 d = direction / len;
  const Frame basis(Plane{point, d});
  OrthogonalSection result;
  CutOptions cut_options = options.cut;
  auto normal_of = [&](const std::array<double, 2>& x) {
    return glm::normalize(d + x[0] * basis.u + x[1] * basis.v);
  };
  auto objective = [&](const std::array<double, 2>& x) {
    ++result.evaluations;
    const PlaneCut cut = index.cut(Plane{point, normal_of(x)}, cut_options);
    const Candidate c = loop_around(cut, point);
    return c.found ? c.area : std::numeric_limits<double>::infinity();
  };

  // Nelder-Mead over the two tilts (reflection 1, expansion 2, contraction 1/2, shrink 1/2).
  using P = std::array<double, 2>;
  std::array<P, 3> x{P{0.0, 0.0}, P{options.initial_step, 0.0}, P{0.0, options.initial_step}};
  std::array<double, 3> f{};
  for (std::size_t i = 0; i < 3; ++i)
    f[i] = objective(x[i]);
  auto lerp = [](const P& a, const P& b, double t) {
    return P{a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])};
  };
  while (result.evaluations < options.max_evaluations) {
    std::array<std::size_t, 3> order{0, 1, 2};
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return f[a] < f[b]; });
    const std::size_t best = order[0], mid = order[1], worst = order[2];
    double size = 0.0;
    for (std::size_t i = 0; i < 3; ++i)
      size = std::max(size, std::hypot(x[i][0] - x[best][0], x[i][1] - x[best][1]));
    if (size < options.tolerance) break;
    const P centre = lerp(x[best], x[mid], 0.5);
    const P reflected = lerp(x[worst], centre, 2.0);
    const double fr = objective(reflected);
    if (fr < f[best]) {
      const P expanded = lerp(x[worst], centre, 3.0);
      const double fe = objective(expanded);
      if (fe < fr) {
        x[worst] = expanded, f[worst] = fe;
      } else {
        x[worst] = reflected, f[worst] = fr;
      }
    } else if (fr < f[mid]) {
      x[worst] = reflected, f[worst] = fr;
    } else {
      const bool outside = fr < f[worst];
      const P contracted = outside ? lerp(x[worst], centre, 1.5) : lerp(x[worst], centre, 0.5);
      const double fc = objective(contracted);
      if (fc < std::min(fr, f[worst])) {
        x[worst] = contracted, f[worst] = fc;
      } else {
        for (const std::size_t i : {mid, worst}) {
          x[i] = lerp(x[best], x[i], 0.5);
          f[i] = objective(x[i]);
        }
      }
    }
  }
  std::size_t best = 0;
  for (std::size_t i = 1; i < 3; ++i)
    if (f[i] < f[best]) best = i;

  result.plane = Plane{point, normal_of(x[best])};
  result.tilt_degrees =
      std::acos(std::clamp(glm::dot(result.plane.normal, d), -1.0, 1.0)) * 180.0 / kPi;
  PlaneCut cut = index.cut(result.plane, cut_options);
  const Candidate c = loop_around(cut, point);
  if (c.found) {
    result.found = true;
    result.loop = std::move(cut.loops[c.loop]);
    result.measures = measure_loop(result.loop, result.plane, options.measure);
  }
  return result;
}

}  // namespace bisturi
