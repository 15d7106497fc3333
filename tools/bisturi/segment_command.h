#pragma once
// `bisturi segment VOLUME (--threshold LO HI | --window CENTRE WIDTH) [--seed I J K]
// [--connectivity 6|26] [--min-voxels N] --out LABELS.nrrd`, or `--split-merge TOLERANCE`:
// segments a volume into labelled objects and writes the label map (same geometry), which
// `bisturi extract LABELS.nrrd --label N` turns into a solid per object.

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace bisturi::cli {

struct SegmentOptions {
  std::string input;
  std::string output;
  std::vector<double> threshold;  ///< LO HI
  std::vector<double> window;     ///< CENTRE WIDTH
  std::vector<long long> seed;    ///< I J K: region growing from this voxel
  std::optional<double> split_merge_tolerance;
  long long min_region_voxels = 1;
  int connectivity = 6;
  long long min_voxels = 0;
  bool json = false;
};

void add_segment_command(CLI::App& app, SegmentOptions& options,
                         int (*&run)(const SegmentOptions&));

int run_segment(const SegmentOptions& options);

}  // namespace bisturi::cli
