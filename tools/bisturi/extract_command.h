#pragma once
// `bisturi extract VOLUME (--iso VALUE | --label N) [--decimate RATIO] [--smooth N] --out MESH`:
// the scan-to-solid pipeline of the command line. Reads a volume (NRRD, NIfTI, DICOM folder),
// extracts the isosurface (or the surface of one label of a label map) straight into a DLFL,
// optionally decimates and smooths it, writes the mesh (world millimetres, LPS) and prints a
// summary: faces, parts, genus and time per stage.

#include <optional>
#include <string>

namespace CLI {
class App;
}

namespace bisturi::cli {

struct ExtractOptions {
  std::string input;
  std::string output;
  std::optional<double> iso;
  std::optional<long long> label;
  double decimate = 1.0;  ///< fraction of the faces to keep, (0, 1]
  int smooth = 0;         ///< Taubin iterations
  bool json = false;
};

/// Adds the `extract` command; `run` is set when it is the one parsed.
void add_extract_command(CLI::App& app, ExtractOptions& options,
                         int (*&run)(const ExtractOptions&));

int run_extract(const ExtractOptions& options);

}  // namespace bisturi::cli
