// A soft body stepped by its volume (volume_body.h) inside a SimWorld, as a session steps it:
// the probe's force grows strictly with depth and is of the order a solid gives (Hertz), the
// organ settles under gravity on its anchors, grasped vertices follow their targets, a cut keeps
// every vertex embedded, and two runs are bit-identical.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/sim/tissue.h"
#include "bisturi/sim/world.h"
#include "sim_test_shapes.h"

namespace bisturi::sim {
namespace {

constexpr double kRadius_m = 0.015;
const glm::dvec3 kCentre_m(0.0195, 0.0195, 0.0195);  // sphere(40, 15 mm)

/// The sphere with its lowest 3 mm anchored.
SoftBody anchored_sphere() {
  SoftBody body(testing::sphere(40, kRadius_m * 1e3), Material{});
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    const VertexId v(i);
    if (body.mesh().alive(v) && body.position(v).z < kCentre_m.z - kRadius_m + 0.003)
      body.set_anchored(v, true);
  }
  return body;
}

/// A liver-like volume of 3 mm cells.
VolumeOptions liver_cells() {
  VolumeOptions volume;
  volume.cell_m = 0.003;
  volume.material = tissue_preset("liver").material;
  return volume;
}

/// The anchored sphere stepped by a liver-like volume of 3 mm cells; exact_solve: each step's
/// solve to a residual of 1e-9 (not the session's 1e-3).
SimWorld volume_world(bool gravity, bool exact_solve = false) {
  WorldOptions options;
  if (!gravity) options.integrator.gravity_m_s2 = glm::dvec3(0.0);
  SimWorld world(options);
  world.add_body(anchored_sphere());
  VolumeOptions volume = liver_cells();
  if (exact_solve) {
    volume.cg_tolerance = 1e-9;
    volume.max_cg = 2000;
  }
  world.set_volume(0, volume);
  world.prepare();
  return world;
}

/// The probe's force (N, along +z) with the tip held `depth` below the top for `steps`: the mean
/// over the last third (what is left of the tissue's ringing averages out).
double press(SimWorld& world, double depth_m, int steps) {
  const double probe = world.options().haptic.probe_radius_m;
  const glm::dvec3 tip = kCentre_m + glm::dvec3(0.0, 0.0, kRadius_m + probe - depth_m);
  double sum = 0.0;
  int counted = 0;
  for (int s = 0; s < steps; ++s) {
    const HapticOutput out = world.step(tip);
    if (3 * s < 2 * steps) continue;
    sum += out.force_N.z;
    ++counted;
  }
  return sum / counted;
}

TEST(SimVolumeBody, ProbeForceGrowsStrictlyWithDepthAtASolidsOrder) {
  SimWorld world = volume_world(false);
  // A probe a few surface edges wide: its contact patch holds several vertices at every depth.
  world.options().haptic.probe_radius_m = 0.003;
  ASSERT_NE(world.volume(0), nullptr);
  EXPECT_EQ(world.volume(0)->embedded_vertices(), world.body(0).mesh().num_vertices());
  EXPECT_GT(world.volume(0)->volume().held_count(), 0u);
  std::vector<double> forces;
  // From above the surface down to 4 mm, slowly (a quarter millimetre per 150 ms).
  for (int k = -2; k <= 16; ++k) {
    const double f = press(world, 2.5e-4 * k, 150);
    if (k > 0) forces.push_back(f);
  }
  for (std::size_t i = 1; i < forces.size(); ++i)
    EXPECT_GT(forces[i], forces[i - 1]) << "at " << 0.25 * double(i + 1) << " mm";
  // Hertz for the probe on the 15 mm sphere at the tip's depth less the coupling's
  // stretch: the same order (the contact patch is sampled by 1-2 mm surface edges and 3 mm
  // cells, which stiffen it), where the spring membrane gave about 1 %.
  const double force = forces.back();
  const double coupling = world.options().haptic.coupling_N_per_m;
  const double depth = 0.004 - force / coupling;
  const double probe = world.options().haptic.probe_radius_m;
  const ElasticMaterial liver = tissue_preset("liver").material;
  const double e_star =
      liver.youngs_modulus_kPa * 1e3 / (1.0 - liver.poisson_ratio * liver.poisson_ratio);
  const double r_eff = 1.0 / (1.0 / probe + 1.0 / kRadius_m);
  const double hertz = 4.0 / 3.0 * e_star * std::sqrt(r_eff) * std::pow(depth, 1.5);
  EXPECT_GT(force, 0.5 * hertz) << "hertz " << hertz;
  EXPECT_LT(force, 4.0 * hertz) << "hertz " << hertz;
  EXPECT_TRUE(world.take_events().empty());
}

TEST(SimVolumeBody, TheComplianceUnderTheProbeGivesTheNextStepsForce) {
  // At 500 Hz, as the liver scene steps: the haptic tick between two steps adds the tip's
  // motion times the coupling in series with this compliance; the step that follows, with the
  // tip moved on, must land on that force, so the hand feels no jump when it comes. Two worlds
  // with the same history, one with the tip held and one with it moved on: the difference of
  // their next forces is the response to the motion alone (the tissue's own ringing cancels).
  // Their steps are solved exactly: at the session's tolerance a solve's error is of the order
  // of the response to 20 um.
  const double further_m = 2e-5;
  for (const double depth_m : {0.001, 0.002, 0.003}) {
    std::array<SimWorld, 2> worlds{volume_world(false, true), volume_world(false, true)};
    for (SimWorld& world : worlds) {
      world.options().integrator.dt_s = 0.002;
      world.options().haptic.probe_radius_m = 0.003;
    }
    const double coupling = worlds[0].options().haptic.coupling_N_per_m;
    const double probe = worlds[0].options().haptic.probe_radius_m;
    const glm::dvec3 tip = kCentre_m + glm::dvec3(0.0, 0.0, kRadius_m + probe - depth_m);
    std::array<HapticOutput, 2> held;
    for (int s = 0; s < 100; ++s)
      for (std::size_t w = 0; w < 2; ++w)
        held[w] = worlds[w].step(tip);
    ASSERT_TRUE(held[0].contact);
    EXPECT_GT(held[0].compliance_m_per_N, 0.0);
    const double stiffness = 1.0 / (1.0 / coupling + held[0].compliance_m_per_N);
    const HapticOutput ob = worlds[1].step(tip - glm::dvec3(0.0, 0.0, further_m));
    const HapticOutput oa = worlds[0].step(tip);
    const double change = ob.force_N.z - oa.force_N.z;
    EXPECT_NEAR(change, stiffness * further_m, 0.05 * stiffness * further_m)
        << "at " << depth_m * 1e3 << " mm: the tissue gives " << held[0].compliance_m_per_N
        << " m/N; the coupling alone would predict " << coupling * further_m << " N";
  }
}

TEST(SimVolumeBody, ARefinedBoxFollowsTheProbeWithoutAJump) {
  // 3 mm cells split in 8 within 8 mm of the contact, following it: the probe presses the top
  // 2 mm deep, then slides 12 mm along the surface. The box moves with it (its centre within a
  // cell of the contact), and no move jolts the surface or the force beyond what a step does.
  WorldOptions options;
  options.integrator.gravity_m_s2 = glm::dvec3(0.0);
  options.haptic.probe_radius_m = 0.003;
  SimWorld world(options);
  world.add_body(anchored_sphere());
  VolumeOptions volume = liver_cells();
  volume.refine_factor = 2;
  volume.refine_centre_m = kCentre_m + glm::dvec3(0.0, 0.0, kRadius_m);
  volume.refine_half_width_m = 0.008;
  volume.refine_follows = true;
  world.set_volume(0, volume);
  world.prepare();
  const double probe = options.haptic.probe_radius_m;
  // The tip 2 mm deep at polar angle a (radians) from the top, in the x-z plane.
  const auto tip = [&](double a) {
    return kCentre_m + (kRadius_m + probe - 0.002) * glm::dvec3(std::sin(a), 0.0, std::cos(a));
  };
  HapticOutput out;
  for (int s = 0; s < 300; ++s)
    out = world.step(tip(0.0));
  const VolumeBody& v = *world.volume(0);
  EXPECT_EQ(v.refocus_count(), 0u);
  const double slide = 0.012 / kRadius_m;  // 12 mm of arc
  const int steps = 600;
  double largest_force_change = 0.0, largest_move_change = 0.0, largest_force = 0.0;
  std::vector<glm::dvec3> before(world.body(0).positions().begin(),
                                 world.body(0).positions().end());
  double last_move = 0.0;
  for (int s = 1; s <= steps; ++s) {
    const std::uint64_t moved = v.refocus_count();
    const HapticOutput next = world.step(tip(slide * s / steps));
    double move = 0.0;
    const auto& x = world.body(0).positions();
    for (std::size_t i = 0; i < before.size(); ++i)
      move = std::max(move, glm::length(x[i] - before[i]));
    before.assign(x.begin(), x.end());
    largest_force = std::max(largest_force, glm::length(next.force_N));
    if (v.refocus_count() != moved) {
      largest_force_change =
          std::max(largest_force_change, glm::length(next.force_N - out.force_N));
      largest_move_change = std::max(largest_move_change, move - last_move);
    }
    last_move = move;
    out = next;
  }
  // It moves when the contact is half its half width (4 mm) from its centre: twice in 12 mm.
  EXPECT_GE(v.refocus_count(), 2u);
  const glm::dvec3 under_tip =
      kCentre_m + kRadius_m * glm::dvec3(std::sin(slide), 0.0, std::cos(slide));
  const glm::dvec3 off = glm::abs(v.options().refine_centre_m - under_tip);
  EXPECT_LT(std::max({off.x, off.y, off.z}), 0.004 + 0.002) << "the box stayed behind";
  EXPECT_LT(largest_force_change, 0.1 * largest_force) << "of " << largest_force << " N";
  EXPECT_LT(largest_move_change, 1e-4) << "a surface vertex jumped (m)";
  const HexLattice& lattice = v.volume().lattice();
  ASSERT_FALSE(lattice.hanging.empty());
  for (const HangingNode& h : lattice.hanging) {
    glm::dvec3 at(0.0);
    for (std::uint32_t k = 0; k < h.masters_count; ++k)
      at += h.weights[k] * v.volume().positions()[h.masters[k]];
    EXPECT_LT(glm::length(at - v.volume().positions()[h.node]), 1e-12);
  }
}

TEST(SimVolumeBody, SettlesUnderGravityOnItsAnchors) {
  SimWorld world = volume_world(true);
  const SoftBody& body = world.body(0);
  const glm::dvec3 top_rest = kCentre_m + glm::dvec3(0.0, 0.0, kRadius_m);
  for (int s = 0; s < 1500; ++s)
    world.step({1.0, 1.0, 1.0});  // the probe far away
  EXPECT_TRUE(world.take_events().empty());
  double top_sag = 0.0, fastest = 0.0;
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    const VertexId v(i);
    if (!body.mesh().alive(v)) continue;
    fastest = std::max(fastest, glm::length(body.velocity(v)));
    if (glm::length(body.rest_position(v) - top_rest) < 0.002)
      top_sag = std::max(top_sag, body.rest_position(v).z - body.position(v).z);
    if (body.anchored(v)) {
      EXPECT_LT(glm::length(body.position(v) - body.rest_position(v)), 1e-9);
    }
  }
  // A 30 mm liver sphere sags by its weight: rho g H^2 / E is about 2 mm; it has stopped.
  EXPECT_GT(top_sag, 2e-4);
  EXPECT_LT(top_sag, 8e-3);
  EXPECT_LT(fastest, 2e-3);
}

TEST(SimVolumeBody, GraspedVerticesFollowTheirTargets) {
  SimWorld world = volume_world(false);
  SoftBody& body = world.body(0);
  const glm::dvec3 top = kCentre_m + glm::dvec3(0.0, 0.0, kRadius_m);
  const glm::dvec3 lift(0.0, 0.0, 0.003);
  std::vector<VertexId> held;
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    const VertexId v(i);
    if (body.mesh().alive(v) && glm::length(body.position(v) - top) < 0.002) held.push_back(v);
  }
  ASSERT_GE(held.size(), 3u);
  for (int s = 0; s < 800; ++s) {
    const double share = std::min(1.0, s / 300.0);
    for (const VertexId v : held)
      body.set_kinematic_target(v, body.rest_position(v) + share * lift);
    world.step({1.0, 1.0, 1.0});
  }
  for (const VertexId v : held)
    EXPECT_LT(glm::length(body.position(v) - (body.rest_position(v) + lift)), 5e-4);
  EXPECT_TRUE(world.take_events().empty());
}

TEST(SimVolumeBody, ACutKeepsEveryVertexEmbeddedAndTheRunsAreIdentical) {
  std::uint64_t hashes[2];
  for (std::uint64_t& hash : hashes) {
    SimWorld world = volume_world(true);
    const double z = kCentre_m.z + std::sqrt(kRadius_m * kRadius_m - 0.005 * 0.005);
    const std::vector<glm::dvec3> blade{kCentre_m * glm::dvec3(1, 1, 0) + glm::dvec3(-0.005, 0, z),
                                        kCentre_m * glm::dvec3(1, 1, 0) + glm::dvec3(0.005, 0, z)};
    for (int s = 0; s < 100; ++s)
      world.step({1.0, 1.0, 1.0});
    const CutResult cut = world.cut(0, blade);
    ASSERT_FALSE(cut.new_vertices.empty());
    ASSERT_TRUE(validate(world.body(0).mesh()).ok());
    EXPECT_EQ(world.volume(0)->embedded_vertices(), world.body(0).mesh().num_vertices());
    for (int s = 0; s < 200; ++s)
      world.step(kCentre_m + glm::dvec3(0.0, 0.0, kRadius_m - 0.001));
    EXPECT_TRUE(world.take_events().empty());
    hash = world.body(0).state_hash();
  }
  EXPECT_EQ(hashes[0], hashes[1]);
}

/// The widest gap between an opened path vertex and its copy (metres), with the part of it
/// along y (the blade's sheet is the plane y = centre).
struct Gap {
  double width_m = 0.0;
  double across_m = 0.0;
};
Gap widest_gap(const SoftBody& body, const CutResult& cut) {
  Gap gap;
  const std::size_t opened = cut.new_vertices.size();
  for (std::size_t k = 0; k < opened; ++k) {
    // An incision inside the surface opens every path vertex but its two ends, in order.
    const glm::dvec3 d = body.position(cut.new_vertices[k]) - body.position(cut.path[k + 1]);
    if (glm::length(d) <= gap.width_m) continue;
    gap.width_m = glm::length(d);
    gap.across_m = std::abs(d.y);
  }
  return gap;
}

/// The anchored sphere (no gravity) with a resting tension, cut `depth_m` deep across its top
/// along x by a blade standing in the plane y = centre, its cells split `refine`^3 along the
/// blade's sheet first.
struct Wound {
  SimWorld world;
  CutResult cut;
  std::size_t separated = 0;
};
Wound cut_sphere(double tension_Pa, double depth_m = 0.006, std::uint32_t refine = 1) {
  WorldOptions options;
  options.integrator.gravity_m_s2 = glm::dvec3(0.0);
  Wound w{SimWorld(options), {}, 0};
  w.world.add_body(anchored_sphere());
  VolumeOptions volume = liver_cells();
  volume.resting_tension_Pa = tension_Pa;
  volume.cut_refine_factor = refine;
  w.world.set_volume(0, volume);
  w.world.prepare();
  std::vector<glm::dvec3> entry, tip;
  for (int k = 0; k <= 16; ++k) {
    const double x = -0.008 + 0.001 * k;
    const double z = std::sqrt(kRadius_m * kRadius_m - x * x);
    entry.push_back(kCentre_m + glm::dvec3(x, 0.0, z));
    tip.push_back(kCentre_m + glm::dvec3(x, 0.0, z - depth_m));
  }
  w.cut = w.world.cut(0, entry, {}, tip);
  w.separated = w.world.separated_faces(0);
  return w;
}

/// Checks that every vertex embedded in a cell the cut parted lies in a cell of its own side:
/// the lips on the side their faces are on, the others on the side of the blade's sheet they
/// lie on (the floor lies on the sheet: both walls' own). An `earlier` cut's lips keep their
/// sides too. Returns how many were checked.
std::size_t expect_each_vertex_on_its_side(const Wound& w, const CutResult* earlier = nullptr) {
  const SoftBody& body = w.world.body(0);
  const VolumeBody& volume = *w.world.volume(0);
  const HexLattice& lattice = volume.volume().lattice();
  std::vector<std::int8_t> lips = lip_sides(body, w.cut, lattice);
  std::vector<VertexId> floor = w.cut.floor_vertices;
  if (earlier != nullptr) {
    const std::vector<std::int8_t> earlier_lips = lip_sides(body, *earlier, lattice);
    for (std::size_t i = 0; i < lips.size(); ++i)
      if (lips[i] == 0) lips[i] = earlier_lips[i];
    floor.insert(floor.end(), earlier->floor_vertices.begin(), earlier->floor_vertices.end());
  }
  std::size_t beside = 0;
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    if (!body.mesh().alive(VertexId(i))) continue;
    const EmbeddedPoint* e = volume.embedding(VertexId(i));
    EXPECT_NE(e, nullptr) << "vertex " << i;
    if (e == nullptr || lattice.separated[e->cell] == 0 ||
        std::find(floor.begin(), floor.end(), VertexId(i)) != floor.end())
      continue;
    ++beside;
    const int side = lips[i] != 0 ? lips[i] : sheet_side(lattice, body.rest_position(VertexId(i)));
    EXPECT_EQ(sheet_side(lattice, lattice.cell_centre(e->cell)), side) << "vertex " << i;
  }
  return beside;
}

TEST(SimVolumeBody, AWoundOpensUnderTheTissuesTensionAndWidensOverASecond) {
  {
    // At rest the surroundings hold the tension: the uncut sphere does not move.
    WorldOptions options;
    options.integrator.gravity_m_s2 = glm::dvec3(0.0);
    SimWorld world(options);
    world.add_body(anchored_sphere());
    VolumeOptions volume = liver_cells();
    volume.resting_tension_Pa = 300.0;
    world.set_volume(0, volume);
    world.prepare();
    for (int s = 0; s < 200; ++s)
      world.step({1.0, 1.0, 1.0});
    double moved = 0.0;
    const SoftBody& body = world.body(0);
    for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i)
      if (body.mesh().alive(VertexId(i)))
        moved = std::max(moved,
                         glm::length(body.position(VertexId(i)) - body.rest_position(VertexId(i))));
    EXPECT_LT(moved, 1e-6);
  }
  Wound tense = cut_sphere(300.0);
  ASSERT_GT(tense.separated, 0u);
  ASSERT_FALSE(tense.cut.new_vertices.empty());
  ASSERT_EQ(tense.cut.path.size(), tense.cut.new_vertices.size() + 2);
  ASSERT_TRUE(validate(tense.world.body(0).mesh()).ok());
  // The wound's walls close it: a floor vertex under each opened pair, the solid closed again,
  // two wall faces a pair but the first (one at each end spans both walls).
  EXPECT_EQ(tense.cut.floor_vertices.size(), tense.cut.new_vertices.size());
  EXPECT_TRUE(tense.world.body(0).closed());
  {
    Dlfl mesh = tense.world.body(0).mesh();
    const auto& interior = mesh.face_properties().get<std::uint8_t>(kInteriorFaces);
    std::size_t walls = 0;
    for (std::uint32_t f = 0; f < mesh.face_capacity(); ++f)
      walls += mesh.alive(FaceId(f)) && interior[FaceId(f)] != 0;
    EXPECT_EQ(walls, 2 * tense.cut.floor_vertices.size());
  }
  EXPECT_GT(expect_each_vertex_on_its_side(tense), tense.cut.path.size());
  const glm::dvec3 away{1.0, 1.0, 1.0};
  EXPECT_LT(widest_gap(tense.world.body(0), tense.cut).width_m, 1e-6);  // closed at the cut
  for (int s = 0; s < 100; ++s)
    tense.world.step(away);
  const Gap early = widest_gap(tense.world.body(0), tense.cut);
  for (int s = 0; s < 900; ++s)
    tense.world.step(away);
  const Gap late = widest_gap(tense.world.body(0), tense.cut);
  EXPECT_TRUE(tense.world.take_events().empty());
  // It opens as the walls let go of the tension (0.3 s): a quarter of the way at 0.1 s.
  EXPECT_GT(early.width_m, 2e-4);
  EXPECT_GT(late.width_m, 2.0 * early.width_m);
  EXPECT_GT(late.across_m, 0.8 * late.width_m);  // the lips part across the blade's sheet
  std::printf("wound: %zu faces separated, gap %.3f mm at 0.1 s, %.3f mm at 1 s\n", tense.separated,
              early.width_m * 1e3, late.width_m * 1e3);

  // Without a tension the lips part no more than the solve's error.
  Wound slack = cut_sphere(0.0);
  for (int s = 0; s < 200; ++s)
    slack.world.step(away);
  EXPECT_LT(widest_gap(slack.world.body(0), slack.cut).width_m, 1e-5);
}

/// How deep under the sphere's surface (metres) the deepest corner of a face a cut parted lies,
/// and how far from the blade's plane y = centre the farthest such face lies.
struct Parted {
  double deepest_m = 0.0;
  double widest_m = 0.0;
};
Parted parted_faces(const HexLattice& lattice) {
  Parted out;
  for (std::size_t c = 0; c < lattice.cells.size(); ++c) {
    if (lattice.separated.empty() || lattice.separated[c] == 0) continue;
    for (std::uint32_t bit = 0; bit < 6; ++bit) {
      if (!((lattice.separated[c] >> bit) & 1u)) continue;
      const int a = static_cast<int>(bit / 2), b = (a + 1) % 3, c2 = (a + 2) % 3;
      const glm::dvec3 half = 0.5 * lattice.cell_sides(c);
      glm::dvec3 face = lattice.cell_centre(c);
      face[a] += (bit & 1u) ? half[a] : -half[a];
      out.widest_m = std::max(out.widest_m, std::abs(face.y - kCentre_m.y));
      for (int corner = 0; corner < 4; ++corner) {
        glm::dvec3 p = face;
        p[b] += (corner & 1) ? half[b] : -half[b];
        p[c2] += (corner & 2) ? half[c2] : -half[c2];
        out.deepest_m = std::max(out.deepest_m, kRadius_m - glm::length(p - kCentre_m));
      }
    }
  }
  return out;
}

TEST(SimVolumeBody, AShallowCutPartsTheTissueAsDeepAsTheBladeWentOnceItsCellsAreSplit) {
  // 1.2 mm deep in 3 mm cells: the faces parted are the cells' own, down to 3 mm under the
  // surface. With the cells along the blade's sheet split into 1 mm ones first, the tissue
  // parts down to the blade's depth and less than a fine cell more (1.8 mm), and opens under
  // the tension.
  constexpr double kDepth_m = 0.0012;
  const glm::dvec3 away{1.0, 1.0, 1.0};
  const Wound coarse = cut_sphere(300.0, kDepth_m);
  const Parted coarse_parted = parted_faces(coarse.world.volume(0)->volume().lattice());

  Wound fine = cut_sphere(300.0, kDepth_m, 3);
  ASSERT_FALSE(fine.cut.new_vertices.empty());
  EXPECT_GT(fine.separated, coarse.separated);
  ASSERT_TRUE(validate(fine.world.body(0).mesh()).ok());
  EXPECT_TRUE(fine.world.body(0).closed());
  const VolumeBody& volume = *fine.world.volume(0);
  const HexLattice& lattice = volume.volume().lattice();
  EXPECT_FALSE(lattice.cell_span.empty());  // two levels now
  EXPECT_EQ(volume.embedded_vertices(), fine.world.body(0).mesh().num_vertices());
  const Parted fine_parted = parted_faces(lattice);
  std::printf("shallow cut: %zu faces parted down to %.2f mm (%zu down to %.2f mm unsplit)\n",
              fine.separated, fine_parted.deepest_m * 1e3, coarse.separated,
              coarse_parted.deepest_m * 1e3);
  EXPECT_LT(fine_parted.deepest_m, kDepth_m + 0.001);
  EXPECT_GT(coarse_parted.deepest_m, kDepth_m + 0.0015);
  EXPECT_LT(fine_parted.widest_m, 0.001);  // the faces next to the blade's plane
  // Each vertex in a parted cell lies in a cell of its own side, as in the one-level lattice.
  EXPECT_GT(expect_each_vertex_on_its_side(fine), fine.cut.path.size());
  EXPECT_LT(widest_gap(fine.world.body(0), fine.cut).width_m, 1e-6);  // closed at the cut
  for (int s = 0; s < 1000; ++s)
    fine.world.step(away);
  EXPECT_TRUE(fine.world.take_events().empty());
  const Gap open = widest_gap(fine.world.body(0), fine.cut);
  std::printf("  it opened %.3f mm in 1 s\n", open.width_m * 1e3);
  EXPECT_GT(open.width_m, 1e-4);
  EXPECT_GT(open.across_m, 0.8 * open.width_m);
}

/// After a cut: the surface valid and closed, every vertex embedded in the volume.
void expect_whole(const SimWorld& world) {
  ASSERT_TRUE(validate(world.body(0).mesh()).ok());
  EXPECT_TRUE(world.body(0).closed());
  EXPECT_EQ(world.volume(0)->embedded_vertices(), world.body(0).mesh().num_vertices());
}

/// A cut over the top of the sphere: blade points at (x, y) = from + k step for k = 0..steps,
/// on the surface, the tips `depth_m` straight down.
CutResult cut_over_the_top(SimWorld& world, glm::dvec2 from, glm::dvec2 step, int steps,
                           double depth_m) {
  std::vector<glm::dvec3> entry, tip;
  for (int k = 0; k <= steps; ++k) {
    const glm::dvec2 xy = from + double(k) * step;
    const double z = std::sqrt(kRadius_m * kRadius_m - xy.x * xy.x - xy.y * xy.y);
    entry.push_back(kCentre_m + glm::dvec3(xy, z));
    tip.push_back(kCentre_m + glm::dvec3(xy, z - depth_m));
  }
  return world.cut(0, entry, {}, tip);
}

TEST(SimVolumeBody, ASecondCutAfterTheSplitPartsTheFineCellsItMeetsAndKeepsEveryVertex) {
  // The first cut split the cells along it; a second, 1 mm beside it and longer, parts the fine
  // cells it meets (and the coarse ones past the split): the surface stays closed and valid,
  // every vertex embedded, and the steps after it run clean.
  Wound w = cut_sphere(300.0, 0.004, 3);
  ASSERT_GT(w.separated, 0u);
  const CutResult second = cut_over_the_top(w.world, {-0.010, 0.001}, {0.001, 0.0}, 20, 0.004);
  ASSERT_FALSE(second.new_vertices.empty());
  EXPECT_GT(w.world.separated_faces(0), w.separated);
  ASSERT_NO_FATAL_FAILURE(expect_whole(w.world));
  for (int s = 0; s < 300; ++s)
    w.world.step({1.0, 1.0, 1.0});
  EXPECT_TRUE(w.world.take_events().empty());
  EXPECT_GT(widest_gap(w.world.body(0), second).width_m, 1e-5);
}

/// A second cut, `depth_m` deep down the sphere's side (+x), 8 mm and more from cut_sphere's.
CutResult cut_down_the_side(SimWorld& world, double depth_m = 0.005) {
  std::vector<glm::dvec3> entry, tip;
  for (int k = 0; k <= 12; ++k) {
    const double z = -0.007 + 0.001 * k;
    const double x = std::sqrt(kRadius_m * kRadius_m - z * z);
    entry.push_back(kCentre_m + glm::dvec3(x, 0.0, z));
    tip.push_back(kCentre_m + glm::dvec3(x - depth_m, 0.0, z));
  }
  return world.cut(0, entry, {}, tip);
}

TEST(SimVolumeBody, ASecondCutFarFromTheFirstSplitsItsOwnCellsAndOpens) {
  // The first cut split the cells along it; a second down the sphere's side, 8 mm and more from
  // it, splits the coarse cells along its own sheet (the lattice built again, the first wound
  // separated again) and parts them: the surface stays closed and valid, every vertex stays
  // embedded on its side, and the wound opens.
  Wound w = cut_sphere(300.0, 0.004, 3);
  ASSERT_GT(w.separated, 0u);
  const std::size_t first_parted = w.separated;
  const CutResult first = w.cut;
  const auto begin = std::chrono::steady_clock::now();
  w.cut = cut_down_the_side(w.world);  // the wound measured below is the second cut's
  const double cut_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - begin).count();
  ASSERT_FALSE(w.cut.new_vertices.empty());
  const std::size_t parted = w.world.separated_faces(0) - first_parted;
  EXPECT_GT(parted, 0u);
  ASSERT_NO_FATAL_FAILURE(expect_whole(w.world));
  EXPECT_GT(expect_each_vertex_on_its_side(w, &first), w.cut.path.size());
  // Closed at the cut, but for the first wound's strain: the cells on either side of the new
  // one were already moving, and each lip follows its own.
  EXPECT_LT(widest_gap(w.world.body(0), w.cut).width_m, 5e-5);
  for (int s = 0; s < 1000; ++s)
    w.world.step({1.0, 1.0, 1.0});
  EXPECT_TRUE(w.world.take_events().empty());
  const Gap open = widest_gap(w.world.body(0), w.cut);
  std::printf(
      "second cut far away: %zu faces parted (the cut took %.1f ms), it opened %.3f mm in "
      "1 s\n",
      parted, cut_ms, open.width_m * 1e3);
  EXPECT_GT(open.width_m, 5e-4);
  EXPECT_GT(open.across_m, 0.8 * open.width_m);
}

TEST(SimVolumeBody, ASecondCutLeavesTheFirstWoundOpen) {
  // Every cut embeds the surface again in the separated lattice. The first wound's lips lie on
  // its sheet at rest, where their positions cannot tell the sides apart: each keeps the side
  // it was given, and the first wound stays as open as it was.
  Wound w = cut_sphere(300.0, 0.004, 3);
  for (int s = 0; s < 500; ++s)
    w.world.step({1.0, 1.0, 1.0});
  const CutResult first = w.cut;
  const double open_before = widest_gap(w.world.body(0), first).width_m;
  ASSERT_GT(open_before, 5e-4);
  const std::size_t first_parted = w.world.separated_faces(0);
  (void)cut_down_the_side(w.world);
  ASSERT_GT(w.world.separated_faces(0), first_parted);
  const double open_after = widest_gap(w.world.body(0), first).width_m;
  EXPECT_NEAR(open_after, open_before, 0.05 * open_before);
  for (int s = 0; s < 300; ++s)
    w.world.step({1.0, 1.0, 1.0});
  EXPECT_TRUE(w.world.take_events().empty());
  EXPECT_GT(widest_gap(w.world.body(0), first).width_m, 0.9 * open_before);
  std::printf("first wound %.3f mm before the second cut, %.3f mm just after\n", open_before * 1e3,
              open_after * 1e3);
}

TEST(SimVolumeBody, AShallowSecondCutSplitsItsOwnCellsAndTheFirstWoundStaysOpen) {
  // Two cuts 1.2 mm deep in 3 mm cells, the second down the side, far from the first: each
  // splits the cells along it, so both part the tissue as deep as the blade went (a fine cell
  // more at most), where the second cut alone in coarse cells would part them 3 mm deep. The
  // lattice built again for the second keeps the first wound: separated again along its sheet,
  // each node moving on its own side and letting go of what it had still to let go of, it goes
  // on as the same wound with no second cut does.
  constexpr double kDepth_m = 0.0012;
  Wound w = cut_sphere(300.0, kDepth_m, 3);
  Wound alone = cut_sphere(300.0, kDepth_m, 3);
  const auto step_both = [&](int steps) {
    for (int s = 0; s < steps; ++s) {
      w.world.step({1.0, 1.0, 1.0});
      alone.world.step({1.0, 1.0, 1.0});
    }
  };
  step_both(500);
  const double open_before = widest_gap(w.world.body(0), w.cut).width_m;
  ASSERT_GT(open_before, 1e-4);
  const std::size_t first_parted = w.world.separated_faces(0);
  const CutResult second = cut_down_the_side(w.world, kDepth_m);
  ASSERT_FALSE(second.new_vertices.empty());
  EXPECT_GT(w.world.separated_faces(0), first_parted);
  ASSERT_NO_FATAL_FAILURE(expect_whole(w.world));
  const Parted parted = parted_faces(w.world.volume(0)->volume().lattice());
  EXPECT_LT(parted.deepest_m, kDepth_m + 0.001);
  const double open_after = widest_gap(w.world.body(0), w.cut).width_m;
  EXPECT_NEAR(open_after, open_before, 0.01 * open_before);
  step_both(1000);
  EXPECT_TRUE(w.world.take_events().empty());
  const Gap opened = widest_gap(w.world.body(0), second);
  EXPECT_GT(opened.width_m, 1e-4);
  const double first_later = widest_gap(w.world.body(0), w.cut).width_m;
  const double alone_later = widest_gap(alone.world.body(0), alone.cut).width_m;
  EXPECT_NEAR(first_later, alone_later, 0.005 * alone_later);
  std::printf(
      "shallow second cut: parted down to %.2f mm, opened %.3f mm in 1 s; the first "
      "wound %.3f mm before it, %.3f mm just after, %.4f mm 1 s later (%.4f mm with no "
      "second cut)\n",
      parted.deepest_m * 1e3, opened.width_m * 1e3, open_before * 1e3, open_after * 1e3,
      first_later * 1e3, alone_later * 1e3);
}

TEST(SimVolumeBody, ACutAcrossAnEarlierWoundKeepsBothSurfacesWhole) {
  // A second cut at right angles across the first wound, 3 mm deep: the surface stays closed and
  // valid, every vertex embedded, the lattice parts along the new sheet, the steps run clean and
  // the first wound stays open (the tissue across it now let go, a little less than before).
  Wound w = cut_sphere(300.0, 0.004, 3);
  for (int s = 0; s < 300; ++s)
    w.world.step({1.0, 1.0, 1.0});
  const double first_before = widest_gap(w.world.body(0), w.cut).width_m;
  const std::size_t first_parted = w.world.separated_faces(0);
  const CutResult across = cut_over_the_top(w.world, {0.002, -0.006}, {0.0, 0.001}, 12, 0.003);
  ASSERT_FALSE(across.new_vertices.empty());
  EXPECT_GT(w.world.separated_faces(0), first_parted);
  ASSERT_NO_FATAL_FAILURE(expect_whole(w.world));
  for (int s = 0; s < 500; ++s)
    w.world.step({1.0, 1.0, 1.0});
  EXPECT_TRUE(w.world.take_events().empty());
  const double first_after = widest_gap(w.world.body(0), w.cut).width_m;
  EXPECT_GT(first_after, 0.8 * first_before);
  std::printf(
      "a cut across the wound: %zu faces parted; the first wound %.3f mm before it, %.3f "
      "mm half a second later\n",
      w.world.separated_faces(0) - first_parted, first_before * 1e3, first_after * 1e3);
}

}  // namespace
}  // namespace bisturi::sim
