#pragma once
// A liquid drawn as a surface round its particles, not as drops: the isosurface of the particles'
// colour field (Müller, Charypar and Gross, "Particle-based fluid simulation for interactive
// applications", 2003, section 7), sum_j W(|x - x_j|) with the kernel W(r) = (1 - r^2/R^2)^3
// for r < R, sampled on a grid round each group of particles whose kernels overlap and extracted
// by marching cubes. A particle
// alone is a bead; particles at their rest spacing merge into one sheet, so a pool reads as a
// pool and a stream as a stream. Built again each frame from the particles' centres.

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/volume/volume.h"

namespace bisturi::render {

struct LiquidSurfaceOptions {
  /// The kernel's reach (mm): 1.5 times the blood's rest spacing, so neighbours merge.
  double kernel_radius_mm = 3.6;
  /// Colour-field value at the surface: a lone particle's bead has the radius where the kernel
  /// falls to it (about 1.3 mm with the defaults, the drawn drops' size).
  float iso = 0.65f;
  /// The grid's spacing (mm). Grows when the particles spread so far that the grid would pass
  /// max_samples.
  double cell_mm = 1.2;
  /// Past this many particles the spacing grows as the square root of the count's ratio to it,
  /// up to max_cell_mm: a pool's faces then stay about as many as this many particles give,
  /// where each face costs the renderer (on the CPU the session shares, with lavapipe) more than
  /// the finer surface is worth. 0: cell_mm whatever the count.
  std::size_t fine_particles = 600;
  double max_cell_mm = 3.0;
  std::size_t max_samples = std::size_t{1} << 21;
};

class LiquidSurface {
 public:
  explicit LiquidSurface(const LiquidSurfaceOptions& options = {});
  /// The surface round `centres_mm` (world millimetres): closed parts, facing out. No faces
  /// without particles.
  const Dlfl& update(std::span<const glm::dvec3> centres_mm);
  [[nodiscard]] const Dlfl& mesh() const { return mesh_; }
  /// The coarsest grid spacing the last update used (mm), and its parts' particle groups.
  [[nodiscard]] double cell_mm() const { return cell_mm_; }
  [[nodiscard]] std::size_t groups() const { return clusters_.size(); }

 private:
  /// Groups the particles whose kernels overlap (clusters_).
  void cluster(std::span<const glm::dvec3> centres_mm);
  /// One group's surface, on a grid round it, into combined_.
  void add_part(std::span<const glm::dvec3> centres_mm);

  LiquidSurfaceOptions options_;
  Grid<float> field_;  ///< kept between parts and frames: its storage is reused
  std::vector<std::uint32_t> parent_;
  /// cluster's scratch: the particles by cube (key, index), where each cube's run begins, and
  /// the cubes' keys in order.
  std::vector<std::pair<std::uint64_t, std::uint32_t>> by_cube_;
  std::vector<std::uint32_t> cube_begin_;
  std::vector<std::uint64_t> cube_keys_;
  std::vector<std::vector<glm::dvec3>> clusters_;
  PolygonMesh combined_;
  Dlfl mesh_;
  double cell_mm_ = 0.0;
  double base_cell_mm_ = 0.0;  ///< this update's spacing before max_samples grows it
};

}  // namespace bisturi::render
