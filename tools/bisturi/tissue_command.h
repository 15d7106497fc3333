#pragma once
// `bisturi tissue indent --shape sphere|block --size-mm S --material NAME|--youngs-kPa E
// --poisson NU --probe-radius-mm R --depth-mm D [--vertices N] [--dt-s T] [--json]`: a
// quasi-static indentation of a simulated solid by a rigid spherical probe pressed along -z at
// its top centre, printed as a force-depth curve beside the continuum reference (Hertz contact).
// Sphere: radius S on a rigid plane (its bottom cap held), Hertz at the probe and at the plane
// in series; block: a cube of side S on a rigid plane (its bottom face held), Hertz on a half
// space. The material is calibrated from the modulus (sim::calibrate_surface); docs/sim/tissue.md
// says what the surface model reaches.

#include <string>

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
  int points = 10;         ///< depths sampled, evenly up to depth_mm
  int settle_steps = 400;  ///< steps held at each depth
  bool json = false;
};

/// Adds the `tissue` command (sub-command `indent`); `run` is set when it is the one parsed.
void add_tissue_command(CLI::App& app, TissueIndentOptions& options,
                        int (*&run)(const TissueIndentOptions&));

int run_tissue_indent(const TissueIndentOptions& options);

}  // namespace bisturi::cli
