// The tissue's volume (sim/volume/): the graded lattice under a closed surface, the embedded
// surface, the hexahedron's stiffness (rigid motions free, a uniform strain's exact stress), the
// polar rotation, and the static indentation: force growing with depth and exactly linear in the
// modulus.

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/matrix.hpp>

#include "bisturi/sim/volume/elastic_volume.h"
#include "bisturi/sim/volume/embedding.h"
#include "bisturi/sim/volume/hex_lattice.h"
#include "volume/hex_element.h"

namespace bisturi::sim {
namespace {

struct Surface {
  std::vector<glm::dvec3> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

/// A UV sphere of radius r about c, outward triangles.
Surface uv_sphere(double r, const glm::dvec3& c, int rings = 40, int segments = 80) {
  Surface s;
  s.vertices.push_back(c + glm::dvec3(0, 0, -r));
  for (int i = 1; i < rings; ++i) {
    const double theta = std::numbers::pi * i / rings - std::numbers::pi / 2;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2 * std::numbers::pi * j / segments;
      s.vertices.push_back(c + r * glm::dvec3(std::cos(theta) * std::cos(phi),
                                              std::cos(theta) * std::sin(phi), std::sin(theta)));
    }
  }
  s.vertices.push_back(c + glm::dvec3(0, 0, r));
  const auto ring = [&](int i, int j) {
    return static_cast<std::uint32_t>(1 + (i - 1) * segments + (j % segments));
  };
  for (int j = 0; j < segments; ++j)
    s.triangles.push_back({0, ring(1, j + 1), ring(1, j)});
  for (int i = 1; i + 1 < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      s.triangles.push_back({ring(i, j), ring(i, j + 1), ring(i + 1, j + 1)});
      s.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i + 1, j)});
    }
  }
  const auto top = static_cast<std::uint32_t>(s.vertices.size() - 1);
  for (int j = 0; j < segments; ++j)
    s.triangles.push_back({top, ring(rings - 1, j), ring(rings - 1, j + 1)});
  return s;
}

/// An axis-aligned box [lo, hi] with n x n vertices a face (outward triangles).
Surface box(const glm::dvec3& lo, const glm::dvec3& hi, int n = 8) {
  Surface s;
  for (int axis = 0; axis < 3; ++axis) {
    for (int end = 0; end < 2; ++end) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const auto base = static_cast<std::uint32_t>(s.vertices.size());
      for (int a = 0; a <= n; ++a) {
        for (int b = 0; b <= n; ++b) {
          glm::dvec3 p;
          p[axis] = end ? hi[axis] : lo[axis];
          p[u] = lo[u] + (hi[u] - lo[u]) * a / n;
          p[v] = lo[v] + (hi[v] - lo[v]) * b / n;
          s.vertices.push_back(p);
        }
      }
      const auto at = [&](int a, int b) {
        return base + static_cast<std::uint32_t>(a * (n + 1) + b);
      };
      for (int a = 0; a < n; ++a) {
        for (int b = 0; b < n; ++b) {
          if (end) {
            s.triangles.push_back({at(a, b), at(a + 1, b), at(a + 1, b + 1)});
            s.triangles.push_back({at(a, b), at(a + 1, b + 1), at(a, b + 1)});
          } else {
            s.triangles.push_back({at(a, b), at(a + 1, b + 1), at(a + 1, b)});
            s.triangles.push_back({at(a, b), at(a, b + 1), at(a + 1, b + 1)});
          }
        }
      }
    }
  }
  return s;
}

TEST(GradedAxis, EndsExactFinestAtTheCentreGrowingAway) {
  const std::vector<double> x = graded_axis(-0.02, 0.03, 0.01, 0.001, 0.003, 1.3, 0.006);
  ASSERT_GE(x.size(), 10u);
  EXPECT_DOUBLE_EQ(x.front(), -0.02);
  EXPECT_DOUBLE_EQ(x.back(), 0.03);
  double finest = 1.0, coarsest = 0.0;
  for (std::size_t i = 0; i + 1 < x.size(); ++i) {
    const double h = x[i + 1] - x[i];
    ASSERT_GT(h, 0.0);
    finest = std::min(finest, h);
    coarsest = std::max(coarsest, h);
    // Near the centre the cells are the finest ones (up to the side's rescale).
    if (std::abs(0.5 * (x[i] + x[i + 1]) - 0.01) < 0.003) {
      EXPECT_LT(h, 0.0012);
    }
  }
  EXPECT_GT(coarsest, 4.0 * finest);
  EXPECT_LT(coarsest, 0.0075);
}

TEST(HexLattice, FillsASphereWithItsVolumeAndEmbedsEveryVertex) {
  const Surface s = uv_sphere(0.01, glm::dvec3(0.001, -0.002, 0.003));
  LatticeOptions o;
  o.finest_m = 0.001;
  o.coarsest_m = 0.003;
  o.focus_m = glm::dvec3(0.001, -0.002, 0.013);
  o.fine_half_width_m = 0.003;
  const HexLattice lattice = build_hex_lattice(s.vertices, s.triangles, o);
  double volume = 0.0;
  for (std::size_t c = 0; c < lattice.cells.size(); ++c) {
    const auto& ijk = lattice.cell_ijk[c];
    double v = lattice.fill[c];
    for (int a = 0; a < 3; ++a)
      v *= lattice.axis[static_cast<std::size_t>(a)][ijk[static_cast<std::size_t>(a)] + 1] -
           lattice.axis[static_cast<std::size_t>(a)][ijk[static_cast<std::size_t>(a)]];
    volume += v;
  }
  const double exact = 4.0 / 3.0 * std::numbers::pi * 1e-6;  // the UV sphere is 0.3 % smaller
  EXPECT_NEAR(volume / exact, 1.0, 0.03);
  const std::vector<EmbeddedPoint> points = embed_points(lattice, s.vertices);
  for (std::size_t p = 0; p < points.size(); ++p) {
    double sum = 0.0;
    for (double w : points[p].weights) {
      EXPECT_GE(w, 0.0);
      sum += w;
    }
    EXPECT_NEAR(sum, 1.0, 1e-12);
    EXPECT_LT(glm::length(embedded_position(lattice, lattice.rest, points[p]) - s.vertices[p]),
              1e-12)
        << "vertex " << p;
  }
}

TEST(HexElement, RigidMotionsAreFreeAndAUniformStrainGivesItsExactStress) {
  const glm::dvec3 h(0.002, 0.001, 0.0015);
  const double mu = 1500.0, lambda = 12000.0;
  HexStiffness k;
  box_stiffness(h, mu, lambda, 1.0, k);
  std::array<glm::dvec3, 8> corner;
  for (int c = 0; c < 8; ++c)
    corner[static_cast<std::size_t>(c)] =
        glm::dvec3((c & 1) * h.x, ((c >> 1) & 1) * h.y, ((c >> 2) & 1) * h.z);
  const auto force = [&](const std::array<glm::dvec3, 8>& u, std::size_t i) {
    glm::dvec3 f(0.0);
    for (std::size_t j = 0; j < 8; ++j)
      f += k[i][j] * u[j];
    return f;
  };
  // Symmetric.
  for (std::size_t i = 0; i < 8; ++i)
    for (std::size_t j = 0; j < 8; ++j)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
          EXPECT_NEAR(k[i][j][b][a], k[j][i][a][b], 1e-12);
  // A translation and an infinitesimal rotation cost nothing.
  std::array<glm::dvec3, 8> t, w;
  for (std::size_t i = 0; i < 8; ++i) {
    t[i] = glm::dvec3(1e-4, -2e-4, 3e-4);
    w[i] = glm::cross(glm::dvec3(0.3, -0.2, 0.5), corner[i]);
  }
  for (std::size_t i = 0; i < 8; ++i) {
    EXPECT_LT(glm::length(force(t, i)), 1e-12);
    EXPECT_LT(glm::length(force(w, i)), 1e-12);
  }
  // Uniaxial strain e along z: the top face carries (lambda + 2 mu) e over its area.
  const double e = 0.01;
  std::array<glm::dvec3, 8> u;
  for (std::size_t i = 0; i < 8; ++i)
    u[i] = glm::dvec3(0.0, 0.0, e * corner[i].z);
  double top = 0.0;
  for (std::size_t i = 4; i < 8; ++i)
    top += force(u, i).z;
  EXPECT_NEAR(top, (lambda + 2.0 * mu) * e * h.x * h.y, 1e-9 * top);
}

TEST(PolarRotation, RecoversTheRotationOfAStretchedRotatedGradient) {
  const glm::dmat3 r =
      glm::dmat3(glm::rotate(glm::dmat4(1.0), 0.7, glm::normalize(glm::dvec3(1, 2, -1))));
  const glm::dmat3 stretch(1.2, 0.1, 0.0, 0.1, 0.9, 0.05, 0.0, 0.05, 1.1);
  const glm::dmat3 got = polar_rotation(r * stretch);
  for (int c = 0; c < 3; ++c)
    for (int row = 0; row < 3; ++row)
      EXPECT_NEAR(got[c][row], r[c][row], 1e-10);
}

/// A 20 mm cube of tissue on a rigid plane, pressed at its top centre by a 5 mm probe.
struct PressedBlock {
  explicit PressedBlock(double youngs_kPa, ElasticLaw law = ElasticLaw::NeoHookean) {
    const Surface s = box(glm::dvec3(0.0), glm::dvec3(0.02), 24);
    LatticeOptions o;
    o.finest_m = 0.001;
    o.coarsest_m = 0.004;
    o.focus_m = glm::dvec3(0.01, 0.01, 0.02);
    o.fine_half_width_m = 0.004;
    ElasticMaterial m;
    m.youngs_modulus_kPa = youngs_kPa;
    m.poisson_ratio = 0.45;
    volume.emplace(build_hex_lattice(s.vertices, s.triangles, o), m, law);
    points = embed_points(volume->lattice(), s.vertices);
    for (std::uint32_t i = 0; i < volume->positions().size(); ++i)
      if (volume->lattice().rest[i].z <= 0.0) volume->hold(i);
  }
  PressResult press(double depth_m) {
    PressOptions po;
    po.penetration_tolerance_m = 1e-3 * depth_m;
    return volume->press_sphere(points, glm::dvec3(0.01, 0.01, 0.02 + 0.005 - depth_m), 0.005, po);
  }
  std::optional<ElasticVolume> volume;
  std::vector<EmbeddedPoint> points;
};

TEST(TwoLevelLattice, FillsASphereHangsItsFineNodesOnTheCoarseAndEmbedsEveryVertex) {
  const Surface s = uv_sphere(0.01, glm::dvec3(0.001, -0.002, 0.003));
  // 3 mm cells, split in 27 within 4 mm of the top.
  const glm::dvec3 top(0.001, -0.002, 0.013);
  const HexLattice lattice = build_two_level_lattice(
      s.vertices, s.triangles, {0.003, 3, {{top - glm::dvec3(0.004), top + glm::dvec3(0.004)}}});
  std::size_t fine = 0, coarse = 0;
  double volume = 0.0;
  for (std::size_t c = 0; c < lattice.cells.size(); ++c) {
    (lattice.span(c) == 1 ? fine : coarse) += 1;
    const glm::dvec3 h = lattice.cell_sides(c);
    volume += lattice.fill[c] * h.x * h.y * h.z;
  }
  EXPECT_GT(fine, 100u);
  EXPECT_GT(coarse, 50u);
  const double exact = 4.0 / 3.0 * std::numbers::pi * 1e-6;
  EXPECT_NEAR(volume / exact, 1.0, 0.03);
  ASSERT_FALSE(lattice.hanging.empty());
  std::vector<std::uint8_t> hangs(lattice.rest.size(), 0);
  for (const HangingNode& h : lattice.hanging)
    hangs[h.node] = 1;
  for (const HangingNode& h : lattice.hanging) {
    EXPECT_TRUE(h.masters_count == 2 || h.masters_count == 4) << h.node;
    glm::dvec3 at(0.0);
    double sum = 0.0;
    for (std::uint32_t m = 0; m < h.masters_count; ++m) {
      EXPECT_FALSE(hangs[h.masters[m]]) << "a master hangs itself";
      at += h.weights[m] * lattice.rest[h.masters[m]];
      sum += h.weights[m];
    }
    EXPECT_NEAR(sum, 1.0, 1e-12);
    EXPECT_LT(glm::length(at - lattice.rest[h.node]), 1e-12) << "node " << h.node;
  }
  const std::vector<EmbeddedPoint> points = embed_points(lattice, s.vertices);
  for (std::size_t p = 0; p < points.size(); ++p)
    EXPECT_LT(glm::length(embedded_position(lattice, lattice.rest, points[p]) - s.vertices[p]),
              1e-12)
        << "vertex " << p;
}

TEST(TwoLevelLattice, SharesTakenOnceBuildTheSameLatticeForAnyBoxesAndOthersAreNotUsed) {
  const Surface s = uv_sphere(0.01, glm::dvec3(0.001, -0.002, 0.003));
  const glm::dvec3 top(0.001, -0.002, 0.013), side(0.011, -0.002, 0.003);
  const glm::dvec3 half(0.004);
  const TwoLevelOptions none{0.003, 3, {}};
  const FineShares shares = two_level_fine_shares(s.vertices, s.triangles, none);
  ASSERT_EQ(shares.share.size(), shares.dims[0] * shares.dims[1] * shares.dims[2]);
  for (const std::vector<TwoLevelOptions::Box>& boxes :
       {std::vector<TwoLevelOptions::Box>{{top - half, top + half}},
        std::vector<TwoLevelOptions::Box>{{top - half, top + half}, {side - half, side + half}}}) {
    const TwoLevelOptions options{0.003, 3, boxes};
    const HexLattice fresh = build_two_level_lattice(s.vertices, s.triangles, options);
    const HexLattice reused =
        build_two_level_lattice(s.vertices, s.triangles, options, {}, &shares);
    EXPECT_EQ(reused.cells, fresh.cells);
    EXPECT_EQ(reused.fill, fresh.fill);
    EXPECT_EQ(reused.rest, fresh.rest);
  }
  // Shares of another grid (a larger solid's box) are not this one's: they are computed again.
  const Surface larger = uv_sphere(0.012, glm::dvec3(0.001, -0.002, 0.003));
  const FineShares other = two_level_fine_shares(larger.vertices, larger.triangles, none);
  const TwoLevelOptions options{0.003, 3, {{top - half, top + half}}};
  EXPECT_EQ(build_two_level_lattice(s.vertices, s.triangles, options, {}, &other).fill,
            build_two_level_lattice(s.vertices, s.triangles, options).fill);
}

TEST(TwoLevelLattice, PressedWhereItIsFineItGivesTheFineLatticesForce) {
  // PressedBlock's block and probe, 1 mm deep, on three lattices: uniform 2.5 mm cells (729),
  // uniform 1.25 mm (4913), and 2.5 mm split in 8 about the probe (1593). The split one's
  // force is the fine one's where the coarse one's is not, and its hanging nodes stay on the
  // coarse faces.
  const Surface s = box(glm::dvec3(0.0), glm::dvec3(0.02), 24);
  ElasticMaterial m;
  m.youngs_modulus_kPa = 4.0;
  m.poisson_ratio = 0.45;
  const glm::dvec3 probe(0.01, 0.01, 0.02);
  const auto press = [&](HexLattice lattice, std::vector<glm::dvec3>* nodes) {
    ElasticVolume volume(std::move(lattice), m);
    const std::vector<EmbeddedPoint> points = embed_points(volume.lattice(), s.vertices);
    for (std::uint32_t i = 0; i < volume.positions().size(); ++i)
      if (volume.lattice().rest[i].z <= 0.0) volume.hold(i);
    PressOptions po;
    po.penetration_tolerance_m = 1e-6;
    const PressResult r =
        volume.press_sphere(points, probe + glm::dvec3(0.0, 0.0, 0.005 - 0.001), 0.005, po);
    EXPECT_TRUE(r.converged) << "after " << r.newton_iterations << " Newton steps";
    if (nodes) nodes->assign(volume.positions().begin(), volume.positions().end());
    return r.probe_force_N.z;
  };
  const double coarse =
      press(build_two_level_lattice(s.vertices, s.triangles, {0.0025, 1, {}}), nullptr);
  const double fine =
      press(build_two_level_lattice(s.vertices, s.triangles, {0.00125, 1, {}}), nullptr);
  const HexLattice two = build_two_level_lattice(
      s.vertices, s.triangles,
      {0.0025,
       2,
       {{probe - glm::dvec3(0.006, 0.006, 0.006), probe + glm::dvec3(0.006, 0.006, 0.001)}}});
  const std::vector<HangingNode> hanging = two.hanging;
  std::vector<glm::dvec3> nodes;
  const double refined = press(two, &nodes);
  EXPECT_LT(std::abs(refined - fine), 0.1 * std::abs(coarse - fine))
      << "coarse " << coarse << " N, fine " << fine << " N, refined " << refined << " N";
  ASSERT_FALSE(hanging.empty());
  for (const HangingNode& h : hanging) {
    glm::dvec3 at(0.0);
    for (std::uint32_t k = 0; k < h.masters_count; ++k)
      at += h.weights[k] * nodes[h.masters[k]];
    EXPECT_LT(glm::length(at - nodes[h.node]), 1e-12) << "node " << h.node;
  }
}

TEST(ElasticVolume, ThePressingForceGrowsWithDepthAndIsLinearInTheModulus) {
  PressedBlock soft(4.0), stiff(8.0);
  EXPECT_GT(soft.volume->held_count(), 0u);
  double last = 0.0;
  for (double depth : {0.0005, 0.001, 0.002, 0.003}) {
    const PressResult a = soft.press(depth);
    const PressResult b = stiff.press(depth);
    ASSERT_TRUE(a.converged) << depth;
    ASSERT_TRUE(b.converged) << depth;
    EXPECT_GT(a.probe_force_N.z, last) << "the force grows with depth, at " << depth;
    last = a.probe_force_N.z;
    EXPECT_NEAR(b.probe_force_N.z / a.probe_force_N.z, 2.0, 0.01) << depth;
    EXPECT_LT(std::abs(a.probe_force_N.x), 1e-3 * a.probe_force_N.z) << "pressed straight down";
    EXPECT_LE(a.max_penetration_m, 1e-3 * depth + 1e-12);
    EXPECT_GT(a.contacts, 3u);
  }
}

TEST(ElasticVolume, NeoHookeanAgreesWithCorotatedAtSmallStrainAndStiffensInCompression) {
  PressedBlock hyper(4.0, ElasticLaw::NeoHookean), linear(4.0, ElasticLaw::Corotational);
  const PressResult a = hyper.press(0.0002), b = linear.press(0.0002);
  ASSERT_TRUE(a.converged);
  ASSERT_TRUE(b.converged);
  EXPECT_NEAR(a.probe_force_N.z / b.probe_force_N.z, 1.0, 0.03) << "the same law at 1 % strain";
  const PressResult c = hyper.press(0.004), d = linear.press(0.004);
  ASSERT_TRUE(c.converged);
  ASSERT_TRUE(d.converged);
  EXPECT_GT(c.probe_force_N.z, 1.15 * d.probe_force_N.z) << "neo-Hookean stiffens at 4 mm";
}

}  // namespace
}  // namespace bisturi::sim
