#pragma once
// `bisturi volume info FILE|DIR [--json]`: read a NRRD, NIfTI-1 or DICOM series (a folder) and
// report its grid (dimensions, spacing, origin, direction in the LPS millimetre world frame), its
// value range and the modality where the file says it. `bisturi volume phantom`: write an
// analytic phantom whose true surface is known (for demos, benchmarks and checks).

#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace bisturi::cli {

struct VolumeOptions {
  std::string input;
  std::string series_uid;
  bool json = false;
  // volume phantom
  std::string output;
  std::string shape = "sphere";
  std::vector<long long> dims{128, 128, 128};
  std::vector<double> spacing{0.5, 0.5, 0.5};
  double a = 0.0;
  double b = 0.0;
};

/// Adds the `volume` command with its `info` and `phantom` sub-commands; `run` is set to the action
/// the parsed command line asks for.
void add_volume_command(CLI::App& app, VolumeOptions& options, int (*&run)(const VolumeOptions&));

int run_volume_info(const VolumeOptions& options);
/// `bisturi volume phantom --shape S --dims X Y Z --spacing SX SY SZ --out FILE`: writes an
/// analytic phantom (signed distance in mm, surface at iso 0) as NRRD or NIfTI.
int run_volume_phantom(const VolumeOptions& options);

}  // namespace bisturi::cli
