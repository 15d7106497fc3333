#pragma once
// What the soft-tissue benchmarks (sim_bench.cpp, volume_bench.cpp) share: the phantom sphere
// they press, percentiles of step times, and the haptic force's dependence on the step length.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"
#include "bisturi/sim/world.h"

namespace bisturi::bench {

struct Shape {
  PolygonMesh polygons;  // a Dlfl does not copy: each body is built from these
  double centre_mm = 0.0;
  double radius_mm = 0.0;
};

/// A sphere of radius_mm (1 mm voxels, 3 voxels of margin), cached per radius.
inline const Shape& sphere(double radius_mm) {
  static std::map<double, Shape> cache;
  auto it = cache.find(radius_mm);
  if (it != cache.end()) return it->second;
  PhantomOptions o;
  o.shape = PhantomShape::Sphere;
  const auto dims = static_cast<std::int64_t>(2.0 * radius_mm + 6.0);
  o.dims = {dims, dims, dims};
  o.spacing = glm::dvec3(1.0);
  o.a = radius_mm;
  Shape s;
  s.polygons = extract_isosurface_mesh(make_phantom(o));
  s.centre_mm = double(dims - 1) / 2.0;
  s.radius_mm = radius_mm;
  std::fprintf(stderr, "sphere r=%.0f mm: %zu vertices\n", radius_mm, s.polygons.positions.size());
  return cache.emplace(radius_mm, std::move(s)).first->second;
}

inline double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(q * double(v.size() - 1) + 0.5);
  return v[std::min(i, v.size() - 1)];
}

/// The body's vertices below z_m anchored (the benches hold a sphere's lower third).
inline void anchor_below(sim::SoftBody& body, double z_m) {
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    const VertexId v(i);
    if (body.mesh().alive(v) && body.position(v).z < z_m) body.set_anchored(v, true);
  }
}

/// The bench probe's tip at t_ms milliseconds: a 2 Hz sine from 1 mm above the sphere's rest top to
/// 2 mm below it, lowered by lower_m.
inline glm::dvec3 probe_tip(const Shape& shape, double t_ms, double lower_m = 0.0) {
  const double c = shape.centre_mm * 1e-3;
  const double r = shape.radius_mm * 1e-3;
  const double depth = 0.0015 * (1.0 - std::cos(2.0 * 3.141592653589793 * 2.0 * t_ms * 1e-3));
  return {c, c, c + r + 0.001 - depth - lower_m};
}

/// How the haptic force depends on the step length: `milliseconds` of the tip at tip(ms) in
/// worlds made by make_world(dt) for dt = 1 ms / k, k = 1, 2, 4, 8, 16 (the device held over a
/// millisecond's steps). Counters per k: the RMS force (force_k_mN), the RMS difference from the
/// k = 16 run against that run's RMS force (diff_k), and the contact changes per second (flips_k).
inline void force_convergence(benchmark::State& state,
                              const std::function<std::unique_ptr<sim::SimWorld>(double)>& make_world,
                              const std::function<glm::dvec3(int)>& tip, int milliseconds) {
  constexpr int kRuns = 5;
  for (auto _ : state) {
    std::vector<std::unique_ptr<sim::SimWorld>> worlds;
    for (int k = 0; k < kRuns; ++k)
      worlds.push_back(make_world(1e-3 / double(1 << k)));
    double force2[kRuns] = {}, diff2[kRuns] = {};
    int flips[kRuns] = {};
    bool contact[kRuns] = {};
    for (int s = 0; s < milliseconds; ++s) {
      const glm::dvec3 at = tip(s);
      glm::dvec3 f[kRuns];
      for (int k = 0; k < kRuns; ++k) {
        sim::HapticOutput out;
        for (int j = 0; j < (1 << k); ++j) {
          out = worlds[std::size_t(k)]->step(at);
          flips[k] += out.contact != contact[k] ? 1 : 0;
          contact[k] = out.contact;
        }
        f[k] = out.force_N;
        force2[k] += glm::dot(f[k], f[k]);
      }
      for (int k = 0; k < kRuns; ++k)
        diff2[k] += glm::dot(f[k] - f[kRuns - 1], f[k] - f[kRuns - 1]);
    }
    const double seconds = milliseconds * 1e-3;
    for (int k = 0; k < kRuns; ++k) {
      const std::string n = std::to_string(1 << k);
      state.counters["force_" + n + "_mN"] = 1e3 * std::sqrt(force2[k] / milliseconds);
      state.counters["diff_" + n] = std::sqrt(diff2[k] / std::max(force2[kRuns - 1], 1e-300));
      state.counters["flips_" + n] = flips[k] / seconds;
    }
  }
}

}  // namespace bisturi::bench
