#pragma once
// Ambient occlusion between the parts of the operating field, computed once at rest: how much
// of the sky each vertex sees past the other solids and the drape (rays in a cosine-weighted
// hemisphere about its normal, each hit within the reach counting by how near it is). The
// renderer dims the ambient light and part of the lamp's there (StereoRenderer::set_occlusion):
// the drape darkens under and around the organ, the organ's underside over the drape, a vessel
// where it stands against the organ. A solid does not occlude itself here (its drawn surface may
// lie millimetres off the simulated one the rays hit). The tissue moves little from rest, so the
// shading is kept as it is.

#include <cstdint>
#include <vector>

#include "bisturi/scene/dlfl.h"
#include "bisturi/sim/world.h"

namespace bisturi::runtime {

/// The drape lies this far under the lowest solid (the blood's tray, session_sim.cpp, too).
constexpr double kDrapeBelow_mm = 2.0;

struct OcclusionOptions {
  double reach_mm = 40.0;  ///< hits further away hide nothing
  int rays = 32;
  /// The share of the sky hidden at most (an open-sided field keeps some light everywhere).
  double strength = 0.75;
  /// The overhead lamp (straight down) is this wide, its half angle (degrees): where the solids
  /// hide part of it, the drape lies in their soft shadow.
  double lamp_half_angle_deg = 20.0;
  /// How dark the full shadow is (the share of the light it takes).
  double shadow_strength = 0.6;
};

/// Each vertex of `receiver` (world mm; by vertex index, dead ones 1) open to the sky: 1 where
/// nothing hides it, less where the world's bodies other than `own_body` (-1: none of them is
/// its own) or the drape (the plane z = drape_z_mm, hiding what lies below its top side) do.
std::vector<float> field_occlusion(const Dlfl& receiver, const sim::SimWorld& world,
                                   std::int32_t own_body, double drape_z_mm,
                                   const OcclusionOptions& options = {});

/// The field's drape and ambient occlusion, computed at rest before the session's threads start.
struct FieldShading {
  Dlfl drape;  ///< the sheet under the solids (render::drape_sheet)
  double drape_z_mm = 0.0;
  std::vector<float> drape_open;  ///< by drape vertex
  /// Per solid: by the drawn surface's vertex when it has one (`drawn[b]`), else by body slot.
  std::vector<std::vector<float>> solid_open;
  double build_ms = 0.0;
};

/// Each vertex of `receiver` (world mm) in the lamp's light: 1 where no body hides any of the
/// overhead lamp's disc, less in the soft shadow of one (the share of the disc's rays hidden).
std::vector<float> lamp_light(const Dlfl& receiver, const sim::SimWorld& world,
                              const OcclusionOptions& options = {});

/// The drape `below_mm` under the solids' box (as at rest in `world`), open to the sky and lit by
/// the lamp where the solids leave it (its soft shadow), and every part's occlusion.
/// `drawn[b]` (may be null): solid b's drawn mesh, shaded in place of its body's.
FieldShading shade_field(const sim::SimWorld& world, const std::vector<const Dlfl*>& drawn,
                         double below_mm, const OcclusionOptions& options = {});

}  // namespace bisturi::runtime
