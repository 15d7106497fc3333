#pragma once
// What `bisturi trace inspect` and `bisturi trace cut` do, as library functions: a summary of a
// trace (read to its end or its first bad chunk), and a cut that writes part of a trace as a new,
// valid trace.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "bisturi/devices/trace/trace_format.h"
#include "bisturi/devices/trace/trace_reader.h"
#include "bisturi/devices/trace/trace_writer.h"

namespace bisturi::devices {

struct TraceDeviceSummary {
  TraceDevice device;
  std::uint64_t reports_in = 0;
  std::uint64_t reports_out = 0;
  std::uint64_t bytes_in = 0;
  std::uint64_t bytes_out = 0;
  std::uint64_t force_commands = 0;
  std::uint64_t connects = 0;
  std::uint64_t disconnects = 0;
};

struct TraceSummary {
  std::string file;
  TraceHeader header;
  std::vector<TraceDeviceSummary> devices;  ///< header devices, then added ones
  std::uint64_t chunks = 0;                 ///< good chunks (the end-of-trace chunk included)
  std::uint64_t records = 0;
  std::uint64_t reports_in = 0;
  std::uint64_t reports_out = 0;
  std::uint64_t force_commands = 0;
  std::uint64_t notes = 0;
  std::uint64_t skipped_records = 0;  ///< of types unknown to this reader
  std::optional<std::int64_t> first_time_ns;
  std::optional<std::int64_t> last_time_ns;
  std::uint64_t good_bytes = 0;  ///< the header and the good chunks
  bool closed_by_writer = false;
  bool session_ended = false;  ///< not a cut, not killed
  std::optional<TraceCorruptError> first_bad_chunk;

  double duration_s() const {
    return first_time_ns ? static_cast<double>(*last_time_ns - *first_time_ns) * 1e-9 : 0.0;
  }
};

/// Reads `reader` to its end (or its first bad chunk, which is returned, not thrown).
TraceSummary summarize_trace(TraceReader& reader);

struct TraceCutOptions {
  /// Keep records with time >= start + from_s and <= start + to_s, where start is the time of the
  /// trace's first record.
  std::optional<double> from_s;
  std::optional<double> to_s;
  /// Keep records of chunks from_chunk..to_chunk (inclusive).
  std::optional<std::uint64_t> from_chunk;
  std::optional<std::uint64_t> to_chunk;
  TraceWriterOptions writer;
};

struct TraceCutResult {
  std::uint64_t records_read = 0;
  std::uint64_t records_written = 0;
  std::uint64_t chunks_written = 0;  ///< the end-of-trace chunk included
  /// The input's bad chunk, if it had one: the cut holds what came before it.
  std::optional<TraceCorruptError> input_error;
};

/// Writes the records of `reader` that fall in the window to a new trace at `out`, with the same
/// header. Every kDeviceAdded record is kept (device indices stay valid); a device that was
/// connected when the window opens gets a kConnect at the window's first record; a note records
/// the cut. A trace cut from its start replays like the original up to the cut's end; one cut later
/// starts its drivers and force guards afresh, so its replay compares outputs from that state.
/// A damaged input yields a valid trace of what came before its bad chunk. Throws TraceError when
/// `out` cannot be written or is the input.
TraceCutResult cut_trace(TraceReader& reader, const std::filesystem::path& out,
                         const TraceCutOptions& options);

}  // namespace bisturi::devices
