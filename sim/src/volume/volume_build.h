#pragma once
// What VolumeBody's construction, refocus and cuts share: the volume built under a surface, and
// a lattice's motion read at a point (volume_body.h).

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/sim/soft_body.h"
#include "bisturi/sim/volume/elastic_volume.h"
#include "bisturi/sim/volume/hex_lattice.h"
#include "bisturi/sim/volume/volume_body.h"

namespace bisturi::sim {

/// Where the lattice's motion takes `p` (positions or velocities of its nodes in `field`): in
/// its kept cell, or, outside every kept cell (a corner of a coarse cell in the air, where the
/// fine cells were not kept), extrapolated from the nearest kept cell within two positions.
/// False when there is none.
bool motion_at(const HexLattice& lattice, std::span<const glm::dvec3> field, const glm::dvec3& p,
               glm::dvec3& out);

/// The volume under `body`: one level of cells of options.cell_m, or, with `refine` boxes and a
/// factor above 1, two, the cells meeting a box split into factor^3 (`shares`, may be null: the
/// fine grid's inside shares from an earlier build, build_two_level_lattice).
ElasticVolume build_volume(const SoftBody& body, const VolumeOptions& options,
                           const std::vector<TwoLevelOptions::Box>& refine, std::uint32_t factor,
                           const FineShares* shares = nullptr);

/// The fine grid's inside shares a cut's split builds on (VolumeOptions::cut_refine_factor), at
/// the body's rest; empty when its cuts split nothing.
FineShares cut_fine_shares(const SoftBody& body, const VolumeOptions& options);

/// The volume under `body` with options' refined cube (if any) split finer.
ElasticVolume build_volume(const SoftBody& body, const VolumeOptions& options);

}  // namespace bisturi::sim
