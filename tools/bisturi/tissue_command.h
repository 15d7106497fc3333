#pragma once
// `bisturi tissue indent --shape sphere|block --size-mm S --material NAME|--youngs-kPa E
// --poisson NU --probe-radius-mm R --depth-mm D [--model volume|surface] [--cell-mm H]
// [--vertices N] [--dt-s T] [--json]`: a
// quasi-static indentation of a simulated solid by a rigid spherical probe pressed along -z at
// its top centre, printed as a force-depth curve beside the continuum reference (Hertz contact).
// Sphere: radius S on a rigid plane (its bottom cap held), Hertz at the probe and at the plane
// in series; block: a cube of side S on a rigid plane (its bottom face held), Hertz on a half
// space. The volume model (the default) solves static equilibrium of corotational hexahedra
// straight from E and nu (sim/volume/elastic_volume.h); the surface model steps the spring
// membrane calibrated from the modulus (sim::calibrate_surface). docs/sim/tissue.md compares both
// with CalculiX (tools/fem/indent_ccx.py).

#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace bisturi::cli {

struct TissueIndentOptions {
  std::string shape = "sphere";
  double size_mm = 20.0;
  std::string material;     ///< a preset name; empty: youngs_kPa
  double youngs_kPa = 0.0;  ///< 0: from the preset
  double poisson = -1.0;    ///< < 0: the preset's (0.45 without one)
  double probe_radius_mm = 5.0;
  double depth_mm = 2.0;
  std::size_t vertices = 2000;
  double dt_s = 1e-3;
  int points = 10;               ///< depths sampled, evenly up to depth_mm
  int settle_steps = 400;        ///< steps held at each depth
  std::string model = "volume";  ///< "volume" (hexahedral FEM) or "surface" (the spring membrane)
  double cell_mm = 0.0;          ///< volume: the finest cell, at the probe (0: from the probe)
  /// volume: "graded" (rectilinear, growing away from the probe) or "two-level" (cells four
  /// times the finest, split in 64 about the probe, hanging nodes between).
  std::string lattice = "graded";
  bool vertices_given = false;  ///< --vertices was given (the volume model's default is finer)
  bool json = false;
};

/// Adds the `tissue` command (sub-command `indent`); `run` is set when it is the one parsed.
void add_tissue_command(CLI::App& app, TissueIndentOptions& options,
                        int (*&run)(const TissueIndentOptions&));

int run_tissue_indent(const TissueIndentOptions& options);

/// A force-depth curve of `tissue indent`.
struct IndentCurve {
  std::vector<double> depth_mm, force_N, hertz_N;
  std::size_t vertices = 0;
  // Surface model.
  double structural_N_per_m = 0.0, bulk_modulus_Pa = 0.0;
  std::size_t rollbacks = 0;
  // Volume model.
  std::size_t cells = 0, nodes = 0, held_nodes = 0;
  double finest_cell_mm = 0.0, build_s = 0.0, solve_s = 0.0;
  long cg_iterations = 0;
  int newton_iterations = 0;
  bool converged = true;
};

/// The volume model's curve (tissue_indent_volume.cpp).
IndentCurve indent_volume(const TissueIndentOptions& options, double youngs_kPa, double poisson);

}  // namespace bisturi::cli
