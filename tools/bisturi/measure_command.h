#pragma once
// `bisturi measure MESH|VOLUME --plane PX PY PZ NX NY NZ [--plane ...] [--orthogonal]
// [--iso VALUE] [--json]`: cross-sections of a vessel surface by planes. A mesh file
// (.obj .ply .stl .off) is imported into the DLFL; a volume (NRRD, NIfTI, DICOM folder) is first
// extracted at the iso value (default 0) with cubic vertex placement. Each plane is cut through
// the DLFL and every loop measured: area centroid, area, perimeter, mean and equivalent
// diameters, minimum and maximum calipers, in millimetres of the world frame (LPS). With
// --orthogonal each plane's point and normal only start a search for the plane through the point
// with the smallest section of the loop around it.

#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace bisturi::cli {

struct MeasureCommandOptions {
  std::string input;
  std::vector<std::vector<double>> planes;  ///< each: px py pz nx ny nz
  bool orthogonal = false;
  double iso = 0.0;
  bool linear = false;   ///< linear vertex placement on volumes (classic marching cubes)
  bool polygon = false;  ///< measure the raw polygons (no surface points, no smooth curve)
  bool json = false;
};

/// Adds the `measure` command; `run` is set when it is the one parsed.
void add_measure_command(CLI::App& app, MeasureCommandOptions& options,
                         int (*&run)(const MeasureCommandOptions&));

int run_measure(const MeasureCommandOptions& options);

}  // namespace bisturi::cli
