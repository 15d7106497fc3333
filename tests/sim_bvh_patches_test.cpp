// The two-level surface BVH (sim/src/collision.cpp with bvh_patches.*): a body of several
// patches answers closest-point, nearby-triangle and ray queries exactly as a brute-force pass
// over every triangle does, before and after a cut, and a cut rebuilds only some patches; a
// refit commits only the patches whose vertices moved and answers as a BVH built anew does, and
// with a refit tolerance the patches that wait keep the answers exact.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vector_relational.hpp>

#include "bisturi/sim/collision.h"
#include "bisturi/sim/world.h"
#include "sim_test_shapes.h"

namespace bisturi::sim {
namespace {

constexpr double kCentre = 0.0275;  // sphere(56, ...) is centred at 27.5 mm
constexpr double kRadius = 0.025;

struct Nearest {
  double distance = std::numeric_limits<double>::infinity();
  std::uint32_t triangle = 0;
};

/// The distance from p to every triangle of the body, in triangle order.
std::vector<double> brute_distances(const SoftBody& body, const glm::dvec3& p) {
  const auto& idx = body.triangles().indices;
  const auto& x = body.positions();
  std::vector<double> out;
  for (std::size_t i = 0; i < idx.size(); i += 3) {
    glm::dvec3 bc;
    const glm::dvec3 q = closest_point_on_triangle(p, x[idx[i]], x[idx[i + 1]], x[idx[i + 2]], bc);
    out.push_back(glm::length(q - p));
  }
  return out;
}

/// The closest triangle to p over every triangle of the body (the lowest index on a tie, as the
/// BVH's query breaks ties).
Nearest brute_closest(const SoftBody& body, const glm::dvec3& p) {
  Nearest best;
  const std::vector<double> d = brute_distances(body, p);
  for (std::uint32_t t = 0; t < d.size(); ++t)
    if (d[t] < best.distance) best = {d[t], t};
  return best;
}

std::vector<std::uint32_t> brute_near(const SoftBody& body, const glm::dvec3& p, double r) {
  std::vector<std::uint32_t> out;
  const std::vector<double> d = brute_distances(body, p);
  for (std::uint32_t t = 0; t < d.size(); ++t)
    if (d[t] <= r) out.push_back(t);
  return out;
}

/// Distance along the segment to its first triangle hit (Moller-Trumbore), infinity for none.
double brute_ray(const SoftBody& body, const glm::dvec3& from, const glm::dvec3& to) {
  const auto& idx = body.triangles().indices;
  const auto& x = body.positions();
  const glm::dvec3 dir = glm::normalize(to - from);
  const double len = glm::length(to - from);
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < idx.size(); i += 3) {
    const glm::dvec3 a = x[idx[i]], e1 = x[idx[i + 1]] - a, e2 = x[idx[i + 2]] - a;
    const glm::dvec3 pv = glm::cross(dir, e2);
    const double det = glm::dot(e1, pv);
    if (std::abs(det) < 1e-30) continue;
    const glm::dvec3 tv = from - a;
    const double u = glm::dot(tv, pv) / det;
    const glm::dvec3 qv = glm::cross(tv, e1);
    const double v = glm::dot(dir, qv) / det;
    const double s = glm::dot(e2, qv) / det;
    if (u < 0.0 || v < 0.0 || u + v > 1.0 || s < 0.0 || s > len) continue;
    best = std::min(best, s);
  }
  return best;
}

/// Query points in a shell around the sphere's surface, and rays from outside towards points
/// inside, all from a fixed seed.
void expect_queries_match(const SoftBody& body, const SurfaceBvh& bvh, std::uint32_t seed,
                          const glm::dvec3& focus, double spread, int queries = 150,
                          bool rays = true) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int i = 0; i < queries; ++i) {
    const glm::dvec3 p = focus + spread * glm::dvec3(unit(rng), unit(rng), unit(rng));
    const Nearest want = brute_closest(body, p);
    const SurfacePoint got = bvh.closest_point(body, p);
    ASSERT_TRUE(got.found);
    EXPECT_EQ(got.triangle, want.triangle) << "query " << i;
    EXPECT_EQ(got.distance_m, want.distance) << "query " << i;
    EXPECT_EQ(bvh.triangles_near(body, p, 0.002), brute_near(body, p, 0.002)) << "query " << i;
    if (!rays) continue;
    const glm::dvec3 from = p + glm::dvec3(0.0, 0.0, 0.08);
    const double hit = brute_ray(body, from, p);
    const SurfacePoint ray = bvh.ray(body, from, p);
    EXPECT_EQ(ray.found, std::isfinite(hit)) << "ray " << i;
    if (ray.found && std::isfinite(hit)) {
      // Embree intersects in float: the hit agrees to float precision over the 8 cm segment.
      EXPECT_NEAR(ray.distance_m, hit, 1e-6) << "ray " << i;
    }
  }
}

/// Blade points along a 2 cm arc of the meridian y = centre, over the top of the sphere.
std::vector<glm::dvec3> top_meridian_arc() {
  std::vector<glm::dvec3> points;
  const double half_angle = 0.01 / kRadius;
  for (int i = 0; i <= 8; ++i) {
    const double a = -half_angle + 2.0 * half_angle * i / 8.0;
    points.emplace_back(kCentre + kRadius * std::sin(a), kCentre, kCentre + kRadius * std::cos(a));
  }
  return points;
}

/// A world with the 25 mm sphere and no gravity (the cuts' tests).
SimWorld weightless_sphere_world() {
  WorldOptions options;
  options.integrator.gravity_m_s2 = glm::dvec3(0.0);
  SimWorld world(options);
  world.add_body(SoftBody(testing::sphere(56, 25.0), Material{}));
  return world;
}

TEST(SimBvhPatches, ATriangleWithoutAreaHasAClosestPointOnItsSides) {
  // A tissue pressed flat or cut can leave a triangle whose corners lie on one line, or two of
  // them on one point; the region tests divided by zero there, and the blood's collisions took
  // the NaN for a surface point.
  const glm::dvec3 a(0.0, 0.0, 0.0), b(1.0, 0.0, 0.0), c(3.0, 0.0, 0.0), p(2.0, 1.0, 0.5);
  for (const auto& [x, y, z] :
       {std::array{a, b, c}, std::array{a, a, c}, std::array{c, b, c}, std::array{a, a, a}}) {
    glm::dvec3 bc;
    const glm::dvec3 q = closest_point_on_triangle(p, x, y, z, bc);
    const auto finite = [](const glm::dvec3& v) {
      return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
    };
    ASSERT_TRUE(finite(q) && finite(bc));
    EXPECT_NEAR(glm::length(bc.x * x + bc.y * y + bc.z * z - q), 0.0, 1e-12);
    EXPECT_NEAR(bc.x + bc.y + bc.z, 1.0, 1e-12);
    const bool a_point = x == y && y == z;
    EXPECT_NEAR(q.x, a_point ? 0.0 : 2.0, 1e-12);  // the foot of p on the line, or the point
    EXPECT_NEAR(q.y, 0.0, 1e-12);
  }
}

TEST(SimBvhPatches, QueriesMatchBruteForceOnEveryPatch) {
  CollisionDevice device(1);
  const SoftBody body(testing::sphere(56, 25.0), Material{});
  SurfaceBvh bvh(device, body);
  ASSERT_GE(bvh.patch_count(), 4u) << "the sphere should span several patches";
  expect_queries_match(body, bvh, 7, glm::dvec3(kCentre), kRadius * 1.2);
}

TEST(SimBvhPatches, ACutRebuildsSomePatchesAndQueriesStillMatch) {
  SimWorld world = weightless_sphere_world();
  const std::size_t patches = world.bvh(0).patch_count();
  const std::uint64_t rebuilds = world.bvh(0).rebuilds();
  const CutResult cut = world.cut(0, top_meridian_arc());
  ASSERT_GT(cut.path.size(), 2u);
  const SurfaceBvh& bvh = world.bvh(0);
  EXPECT_EQ(bvh.rebuilds(), rebuilds + 1);
  EXPECT_EQ(bvh.patch_count(), patches);
  EXPECT_GT(bvh.last_rebuilt_patches(), 0u);
  EXPECT_LT(bvh.last_rebuilt_patches(), patches);
  // The changed patches kept their BVHs: the cut's new triangles are in the loose patch.
  EXPECT_GT(bvh.loose_triangles(), 0u);
  // Around the incision (the new faces and the split ones) and over the whole body.
  const glm::dvec3 top(kCentre, kCentre, kCentre + kRadius);
  expect_queries_match(world.body(0), bvh, 11, top, 0.012);
  expect_queries_match(world.body(0), bvh, 13, glm::dvec3(kCentre), kRadius * 1.2);
  // Steps refit the kept and the rebuilt patches alike.
  for (int s = 0; s < 5; ++s)
    world.step(top + glm::dvec3(0.0, 0.0, 0.01));
  expect_queries_match(world.body(0), bvh, 17, top, 0.012);
}

/// Rays straight down into the incision of a cut along the sphere's top meridian (y = centre),
/// opened by `gap` metres: each must find what a brute-force pass finds, never a dead triangle
/// of a kept patch spanning the opening.
void expect_rays_into_gap_match(const SoftBody& body, const SurfaceBvh& bvh, double gap) {
  for (int i = 0; i < 40; ++i) {
    const double x = kCentre - 0.008 + 0.016 * i / 39.0;
    const double y = kCentre + gap * (0.25 + 0.5 * (i % 5) / 4.0);
    const glm::dvec3 from(x, y, kCentre + 0.08), to(x, y, kCentre);
    const double hit = brute_ray(body, from, to);
    const SurfacePoint ray = bvh.ray(body, from, to);
    ASSERT_EQ(ray.found, std::isfinite(hit)) << "ray " << i;
    if (ray.found) {
      EXPECT_NEAR(ray.distance_m, hit, 1e-6) << "ray " << i;
    }
  }
}

TEST(SimBvhPatches, RaysPassThroughTheDeadTrianglesOfAnOpenedIncision) {
  // The far lip is moved away from the near one, in either direction (one of them opens the
  // incision; the dead triangles of the kept patches still span it).
  for (const double gap : {0.0015, -0.0015}) {
    SimWorld world = weightless_sphere_world();
    const CutResult cut = world.cut(0, top_meridian_arc());
    ASSERT_GT(cut.new_vertices.size(), 2u);
    ASSERT_GT(world.bvh(0).loose_triangles(), 0u) << "the cut should keep stale patches";
    SoftBody& body = world.body(0);
    for (const VertexId v : cut.new_vertices)
      body.set_position(v, body.position(v) + glm::dvec3(0.0, gap, 0.0));
    world.prepare_body(0);  // refits the BVH
    expect_rays_into_gap_match(body, world.bvh(0), gap);
  }
}

/// Blade points along a 1 cm arc of the sphere's parallel at latitude lat, centred on longitude
/// lon (radians).
std::vector<glm::dvec3> parallel_arc(double lat, double lon) {
  std::vector<glm::dvec3> points;
  const double half = 0.005 / (kRadius * std::cos(lat));
  for (int i = 0; i <= 8; ++i) {
    const double l = lon - half + 2.0 * half * i / 8.0;
    points.push_back(glm::dvec3(kCentre) + kRadius * glm::dvec3(std::cos(lat) * std::cos(l),
                                                                std::cos(lat) * std::sin(l),
                                                                std::sin(lat)));
  }
  return points;
}

/// Cuts twelve short incisions over the sphere (two parallels, six longitudes each) with the
/// given rebuild limits, checking the queries around each; returns the loose patch's size after
/// each cut.
std::vector<std::size_t> cut_around(const PatchRebuildLimits& limits) {
  WorldOptions options;
  options.integrator.gravity_m_s2 = glm::dvec3(0.0);
  options.bvh_rebuild = limits;
  SimWorld world(options);
  world.add_body(SoftBody(testing::sphere(56, 25.0), Material{}));
  const double kPi = std::acos(-1.0);
  std::vector<std::size_t> loose;
  for (const double lat : {-0.4, 0.4}) {
    for (int k = 0; k < 6; ++k) {
      const std::vector<glm::dvec3> points = parallel_arc(lat, k * kPi / 3.0 + lat);
      const CutResult cut = world.cut(0, points);
      EXPECT_GT(cut.path.size(), 2u) << "cut " << loose.size();
      loose.push_back(world.bvh(0).loose_triangles());
      // Around the incision, where the dead triangles lie under the new ones.
      expect_queries_match(world.body(0), world.bvh(0), 100 + static_cast<std::uint32_t>(k),
                           points[4], 0.006, 40);
    }
  }
  expect_queries_match(world.body(0), world.bvh(0), 7, glm::dvec3(kCentre), kRadius * 1.2);
  return loose;
}

/// True when the loose patch grew and then shrank: the patches it served were rebuilt.
bool grew_then_shrank(const std::vector<std::size_t>& loose) {
  for (std::size_t i = 1; i < loose.size(); ++i)
    if (loose[i - 1] > 0 && loose[i] < loose[i - 1]) return true;
  return false;
}

TEST(SimBvhPatches, AFullLoosePatchRebuildsTheStalePatches) {
  const std::vector<std::size_t> loose = cut_around({.loose_triangles = 150, .stale_share = 1.0});
  EXPECT_TRUE(grew_then_shrank(loose))
      << "largest " << *std::max_element(loose.begin(), loose.end());
  EXPECT_LE(*std::max_element(loose.begin(), loose.end()), 150u);
}

TEST(SimBvhPatches, APatchWithManyDeadTrianglesIsRebuilt) {
  const std::vector<std::size_t> loose =
      cut_around({.loose_triangles = 1000000, .stale_share = 0.02});
  EXPECT_TRUE(grew_then_shrank(loose))
      << "largest " << *std::max_element(loose.begin(), loose.end());
}

/// Moves every live vertex within `radius` of `centre` by `shift`; returns how many moved.
std::size_t move_region(SoftBody& body, const glm::dvec3& centre, double radius,
                        const glm::dvec3& shift) {
  std::size_t moved = 0;
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    const VertexId v(i);
    if (!body.mesh().alive(v) || glm::length(body.position(v) - centre) > radius) continue;
    body.set_position(v, body.position(v) + shift);
    ++moved;
  }
  return moved;
}

/// Closest points around focus from `bvh` (refitted) and from a BVH built anew on the same
/// body: the same triangle and the same point.
void expect_same_as_fresh(const SoftBody& body, const SurfaceBvh& bvh, std::uint32_t seed,
                          const glm::dvec3& focus, double spread) {
  CollisionDevice device(1);
  const SurfaceBvh fresh(device, body);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    const glm::dvec3 p = focus + spread * glm::dvec3(unit(rng), unit(rng), unit(rng));
    const SurfacePoint want = fresh.closest_point(body, p);
    const SurfacePoint got = bvh.closest_point(body, p);
    ASSERT_TRUE(want.found && got.found) << "query " << i;
    EXPECT_EQ(got.triangle, want.triangle) << "query " << i;
    EXPECT_EQ(got.point_m, want.point_m) << "query " << i;
  }
}

const glm::dvec3 kTop(kCentre, kCentre, kCentre + kRadius);
// Far enough sideways that the old bounds of the moved region are farther from a query at its
// new place than the unmoved surface is: a region left unrefitted gives other answers.
const glm::dvec3 kSideways(0.006, 0.0, 0.0);

TEST(SimBvhPatches, MovingOneRegionRefitsOnlyItsPatches) {
  CollisionDevice device(1);
  SoftBody body(testing::sphere(56, 25.0), Material{});
  SurfaceBvh bvh(device, body);
  ASSERT_EQ(bvh.loose_triangles(), 0u);
  const std::size_t filled = bvh.patch_count() - 1;  // the loose patch is empty
  ASSERT_GE(filled, 4u);
  ASSERT_GT(move_region(body, kTop, 0.004, kSideways), 10u);
  bvh.update(body);
  EXPECT_GT(bvh.last_refitted_patches(), 0u);
  EXPECT_LT(bvh.last_refitted_patches(), filled);
  expect_same_as_fresh(body, bvh, 21, kTop + kSideways, 0.006);
  expect_queries_match(body, bvh, 23, kTop + kSideways, 0.006, 60);
}

// With a refit tolerance, moved patches wait until their drift passes it; the point queries stay
// exact meanwhile (a 6 mm move leaves the old bounds where a query at the new place would not
// look without the drift added to its radius), and a ray refits the waiting patches first.
TEST(SimBvhPatches, WaitingRefitsKeepTheQueriesExact) {
  CollisionDevice device(1);
  SoftBody body(testing::sphere(56, 25.0), Material{});
  SurfaceBvh bvh(device, body);
  bvh.set_refit_tolerance(0.02);
  ASSERT_GT(move_region(body, kTop, 0.004, kSideways), 10u);
  bvh.update(body);
  EXPECT_EQ(bvh.last_refitted_patches(), 0u);  // 6 mm: under 20 mm
  expect_queries_match(body, bvh, 51, kTop + kSideways, 0.006, 60, false);
  const auto [lo, hi] = bvh.bounds();  // grown by the drift: it holds the moved region
  for (const glm::dvec3& x : body.positions()) {
    ASSERT_TRUE(glm::all(glm::lessThanEqual(lo, x)) && glm::all(glm::lessThanEqual(x, hi)));
  }
  move_region(body, kTop + kSideways, 0.004, -0.5 * kSideways);
  bvh.update(body);
  EXPECT_EQ(bvh.last_refitted_patches(), 0u);  // 6 + 3 mm drift, at most 15.6 mm
  expect_queries_match(body, bvh, 53, kTop + 0.5 * kSideways, 0.006, 60, false);
  move_region(body, kTop + 0.5 * kSideways, 0.004, kSideways);
  bvh.update(body);
  EXPECT_GT(bvh.last_refitted_patches(), 0u);  // past 20 mm
  move_region(body, kTop + 1.5 * kSideways, 0.004, -kSideways);
  bvh.update(body);
  EXPECT_EQ(bvh.last_refitted_patches(), 0u);
  expect_queries_match(body, bvh, 55, kTop + 0.5 * kSideways, 0.006, 60, true);
  expect_same_as_fresh(body, bvh, 57, kTop + 0.5 * kSideways, 0.006);
}

TEST(SimBvhPatches, AVertexOnAPatchBorderRefitsEveryPatchThatUsesIt) {
  CollisionDevice device(1);
  SoftBody body(testing::sphere(56, 25.0), Material{});
  SurfaceBvh bvh(device, body);
  // Each live vertex alone pulled 6 mm outwards until one refits two patches (it lies on a
  // border); the others go back.
  std::size_t most = 0;
  VertexId spike;
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity() && most < 2; ++i) {
    spike = VertexId(i);
    if (!body.mesh().alive(spike)) continue;
    const glm::dvec3 was = body.position(spike);
    body.set_position(spike, was + 0.006 * glm::normalize(was - glm::dvec3(kCentre)));
    bvh.update(body);
    most = std::max(most, bvh.last_refitted_patches());
    if (most >= 2) break;
    body.set_position(spike, was);
    bvh.update(body);
  }
  ASSERT_GE(most, 2u) << "no vertex refitted two patches";
  // The spike's triangles in each patch are where their BVHs say.
  expect_same_as_fresh(body, bvh, 43, body.position(spike), 0.004);
}

TEST(SimBvhPatches, MovingNothingRefitsNoPatch) {
  CollisionDevice device(1);
  SoftBody body(testing::sphere(56, 25.0), Material{});
  SurfaceBvh bvh(device, body);
  const std::uint64_t refits = bvh.refits();
  bvh.update(body);
  EXPECT_EQ(bvh.last_refitted_patches(), 0u);
  move_region(body, kTop, 0.004, kSideways);
  bvh.update(body);
  ASSERT_GT(bvh.last_refitted_patches(), 0u);
  bvh.update(body);  // the moved region stays where it went
  EXPECT_EQ(bvh.last_refitted_patches(), 0u);
  EXPECT_EQ(bvh.refits(), refits + 3);
  expect_same_as_fresh(body, bvh, 27, kTop + kSideways, 0.006);
}

TEST(SimBvhPatches, MovingEveryVertexRefitsEveryFilledPatch) {
  CollisionDevice device(1);
  SoftBody body(testing::sphere(56, 25.0), Material{});
  SurfaceBvh bvh(device, body);
  ASSERT_EQ(bvh.loose_triangles(), 0u);
  for (glm::dvec3& p : body.positions())
    p.z += 1e-6;  // a few float steps at 5 cm
  bvh.update(body);
  EXPECT_EQ(bvh.last_refitted_patches(), bvh.patch_count() - 1);
  expect_same_as_fresh(body, bvh, 29, glm::dvec3(kCentre), kRadius * 1.2);
}

TEST(SimBvhPatches, APartialRefitAfterACutAnswersAsAFreshBvh) {
  SimWorld world = weightless_sphere_world();
  const CutResult cut = world.cut(0, top_meridian_arc());
  ASSERT_GT(cut.new_vertices.size(), 2u);
  const SurfaceBvh& bvh = world.bvh(0);
  ASSERT_GT(bvh.loose_triangles(), 0u) << "the cut should fill the loose patch";
  // After the cut's rebuild every patch was committed, the loose one too.
  EXPECT_EQ(bvh.last_refitted_patches(), bvh.patch_count());
  // The incision and the region around it (the loose patch's triangles among them) move.
  SoftBody& body = world.body(0);
  ASSERT_GT(move_region(body, kTop, 0.004, kSideways), 10u);
  world.prepare_body(0);  // refits the BVH
  EXPECT_GT(bvh.last_refitted_patches(), 0u);
  EXPECT_LT(bvh.last_refitted_patches(), bvh.patch_count());
  expect_same_as_fresh(body, bvh, 31, kTop + kSideways, 0.006);
  expect_queries_match(body, bvh, 37, kTop + kSideways, 0.006, 60);
  expect_queries_match(body, bvh, 41, glm::dvec3(kCentre), kRadius * 1.2, 60);
}

}  // namespace
}  // namespace bisturi::sim
