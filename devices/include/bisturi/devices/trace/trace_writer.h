#pragma once
// Writes a device trace. Records are gathered into a chunk in memory; a chunk is sealed (its
// checksum computed) and handed to the operating system in one write when it reaches a record
// count, a size or an age, so a process that is killed loses at most the chunk it was filling.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "bisturi/devices/trace/trace_format.h"

namespace bisturi::devices {

struct TraceWriterOptions {
  /// A chunk is sealed once it holds this many records...
  std::size_t max_chunk_records = 4096;
  /// ...or this many payload bytes...
  std::size_t max_chunk_bytes = 256 * 1024;
  /// ...or when a record (or poll()) comes this long after the chunk's first record.
  std::int64_t max_chunk_age_ns = 100'000'000;
  /// Also fdatasync() each sealed chunk (survives power loss, not only a killed process). Costly.
  bool sync_each_chunk = false;
};

/// Totals of what a writer has sealed into its file.
struct TraceWriterStats {
  std::uint64_t chunks = 0;
  std::uint64_t records = 0;
  std::uint64_t bytes = 0;  ///< file size, header included
};

/// Writes one trace file. All methods may be called from several threads (a mutex serialises
/// them); the haptic thread pays one uncontended lock and a copy into the chunk per record, and a
/// write() system call per sealed chunk.
class TraceWriter {
 public:
  /// Creates (truncates) `path` and writes the header at once, so even an empty trace is valid.
  /// Throws TraceError when the file cannot be created or written.
  TraceWriter(const std::filesystem::path& path, TraceHeader header,
              TraceWriterOptions options = {});
  /// Closes the trace as close() does; errors are swallowed (call close() to see them).
  ~TraceWriter();
  TraceWriter(const TraceWriter&) = delete;
  TraceWriter& operator=(const TraceWriter&) = delete;

  /// Adds a device that was not in the header (hot-plug); returns its device index.
  std::uint16_t add_device(std::int64_t time_ns, const TraceDevice& device);

  void report_in(std::uint16_t device, std::int64_t time_ns, std::span<const std::uint8_t> bytes);
  void report_out(std::uint16_t device, std::int64_t time_ns, std::span<const std::uint8_t> bytes);
  /// The force commanded for `device` (N per actuator) before the force guard.
  void force_command(std::uint16_t device, std::int64_t time_ns, std::span<const double> force_N);
  void connect(std::uint16_t device, std::int64_t time_ns);
  void disconnect(std::uint16_t device, std::int64_t time_ns);
  void note(std::int64_t time_ns, std::string_view text);
  /// Any record. Throws TraceError for an unknown device index or after close(), and when a
  /// write to the file fails; after such a failure the trace is closed and every later record is
  /// dropped without a throw (failure() says why), so a session can go on without its recording.
  void append(TraceRecordType type, std::uint16_t device, std::int64_t time_ns,
              std::span<const std::uint8_t> payload);

  /// Seals the open chunk if its first record is older than max_chunk_age_ns at `now_ns`; lets a
  /// quiet session still bound what a kill would lose.
  void poll(std::int64_t now_ns);
  /// Seals the open chunk now (if it holds any record).
  void flush();
  /// Seals the open chunk, writes the end-of-trace chunk and closes the file. Idempotent.
  /// `session_ended`: the trace ends where the recorded session ended (false for a cut, whose
  /// replay cannot know what the drivers wrote after it).
  void close(bool session_ended = true);

  const std::filesystem::path& path() const { return path_; }
  std::size_t device_count() const;
  TraceWriterStats stats() const;
  /// Why writing stopped (a failed write or fdatasync); empty while the trace is being written.
  std::string failure() const;

 private:
  void seal_locked(std::uint32_t flags);
  void write_all_locked(std::span<const std::uint8_t> bytes);
  void append_locked(TraceRecordType type, std::uint16_t device, std::int64_t time_ns,
                     std::span<const std::uint8_t> payload);

  std::filesystem::path path_;
  TraceWriterOptions options_;
  mutable std::mutex mutex_;
  int fd_ = -1;
  std::size_t devices_ = 0;
  std::vector<std::uint8_t> chunk_;  // chunk header placeholder, then the records
  std::uint32_t chunk_records_ = 0;
  std::int64_t chunk_first_time_ns_ = 0;
  TraceWriterStats stats_;
  std::uint64_t total_records_ = 0;  // appended, sealed or not
  std::string failure_;
};

}  // namespace bisturi::devices
