#pragma once
// Shared pieces of the volume readers and writers: sample types and their conversion to float,
// size checks, geometry from world step vectors, zlib inflate with a cap, gzip deflate.

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>

#include <glm/glm.hpp>

#include "../io/parse_errors.h"
#include "bisturi/scene/volume/volume_io.h"

namespace bisturi::volume_io {

using mesh_io::cat;
using mesh_io::ErrorSite;
inline std::string quote(std::string_view s) {
  return mesh_io::quoted(s);
}

enum class SampleType {
  Int8,
  UInt8,
  Int16,
  UInt16,
  Int32,
  UInt32,
  Int64,
  UInt64,
  Float32,
  Float64
};

std::size_t sample_size(SampleType type);
/// "int8" .. "uint64", "float32", "float64".
const char* type_name(SampleType type);

/// The number of samples dims[0] * dims[1] * dims[2] and its size in bytes of `type`; InputError
/// (via `site`) when a size is below 1 or a product overflows.
struct SampleCount {
  std::size_t samples = 0;
  std::size_t bytes = 0;
};
SampleCount checked_count(const std::array<std::int64_t, 3>& dims, SampleType type,
                          const ErrorSite& site);

/// Stored value -> float: out[n] = float(slope * v + intercept) when `rescale`, float(v) otherwise.
struct Rescale {
  bool apply = false;
  double slope = 1.0;
  double intercept = 0.0;
};

/// Converts `count` samples of `type` at `src` (byte order `big_endian`) into `dst`, calling
/// `progress(done_bytes, total_bytes)` about every 16 MiB (the totals are offset by `done_before`
/// and `total`).
void convert_samples(const std::byte* src, std::size_t count, SampleType type, bool big_endian,
                     const Rescale& rescale, float* dst,
                     const std::function<void(std::size_t, std::size_t)>& progress = {},
                     std::size_t done_before = 0, std::size_t total = 0);

/// Geometry from the world step of each index axis (columns of `steps`, millimetres) and the
/// world origin: spacing = column lengths, direction = unit columns. InputError when a step is
/// zero, not finite, or the axes are not orthogonal within 1e-3 (a sheared grid); nearly
/// orthogonal axes are straightened (Gram-Schmidt, +i kept).
void set_geometry_from_steps(VolumeGeometry& geometry, const glm::dmat3& steps,
                             const glm::dvec3& origin, const ErrorSite& site);

/// Straightens three nearly orthogonal unit directions (InputError when they are not).
glm::dmat3 orthonormalized(const glm::dmat3& direction, const ErrorSite& site);

/// Streaming inflate of zlib or gzip data (concatenated gzip members too).
class Inflater {
 public:
  Inflater(std::span<const std::byte> input, const ErrorSite& site);
  ~Inflater();
  Inflater(const Inflater&) = delete;
  Inflater& operator=(const Inflater&) = delete;

  /// Fills `out` with the next out.size() bytes; returns fewer only at the end of the data.
  /// InputError on corrupt data.
  std::size_t read(std::span<std::byte> out);
  /// Compressed bytes consumed so far.
  std::size_t consumed() const;

 private:
  void refill();

  struct State;
  State* state_;
  const ErrorSite& site_;
  std::size_t remaining_ = 0;
  bool ended_ = false;
};

/// The most bytes a deflate stream of `compressed` bytes can hold (zlib's ratio is below 1032:1).
std::size_t max_inflated_size(std::size_t compressed);

/// gzip-compressed copy of `data` (writers).
std::string gzip_compress(std::string_view data, const std::string& file_for_errors);

bool ends_with_icase(std::string_view s, std::string_view suffix);

}  // namespace bisturi::volume_io
