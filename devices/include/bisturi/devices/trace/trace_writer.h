#pragma once
// Writes a device trace. Records are gathered into a chunk in memory; a chunk is sealed (its
// checksum computed) when it reaches a record count, a size or an age, and handed to the
// writer's own thread, which writes it to the file: a record costs its caller one short lock
// and a copy, never a system call, so a haptic tick that records waits on no disk. A process
// that is killed loses the chunk being filled and those sealed but not yet written (a few
// milliseconds' worth).

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <thread>
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
  /// When every buffer of the ring waits for the disk: true, a record waits for the writing
  /// thread (tools, tests: nothing is lost); false, the recording stops instead (a haptic
  /// session: its tick never waits on the disk).
  bool wait_when_full = true;
};

/// Totals of what a writer has sealed into its file.
struct TraceWriterStats {
  std::uint64_t chunks = 0;
  std::uint64_t records = 0;
  std::uint64_t bytes = 0;  ///< file size, header included
};

/// Writes one trace file. All methods may be called from several threads (a mutex serialises
/// them); a caller pays one short lock and a copy into the chunk per record. Sealed chunks wait
/// in a fixed ring of buffers (allocated up front) for the writing thread, which looks for them
/// every couple of milliseconds (a record never wakes it: that would be a system call). A disk
/// slower than the recording fills the ring: the record then waits, or with
/// TraceWriterOptions::wait_when_full off the recording stops (failure() says so) and the caller
/// goes on.
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
  /// The time the latest report from `device` was recorded at (nanoseconds; -1 before any, and
  /// for devices past the first kTimedDevices): what a replay's driver stamps that report with,
  /// so what the force guard must hear live too.
  [[nodiscard]] std::int64_t last_report_in_ns(std::uint16_t device) const;
  void report_out(std::uint16_t device, std::int64_t time_ns, std::span<const std::uint8_t> bytes);
  /// The force commanded for `device` (N per actuator) before the force guard.
  void force_command(std::uint16_t device, std::int64_t time_ns, std::span<const double> force_N);
  void connect(std::uint16_t device, std::int64_t time_ns);
  void disconnect(std::uint16_t device, std::int64_t time_ns);
  void note(std::int64_t time_ns, std::string_view text);
  /// Any record. Throws TraceError for an unknown device index, a record too large for a chunk
  /// or after close(). After a failed write (on the writing thread) or a full ring, records are
  /// dropped without a throw (failed() turns true, failure() says why), so a session can go on
  /// without its recording.
  void append(TraceRecordType type, std::uint16_t device, std::int64_t time_ns,
              std::span<const std::uint8_t> payload);

  /// Seals the open chunk if its first record is older than max_chunk_age_ns at `now_ns`; lets a
  /// quiet session still bound what a kill would lose.
  void poll(std::int64_t now_ns);
  /// Seals the open chunk now (if it holds any record) and waits until every sealed chunk is in
  /// the file.
  void flush();
  /// Seals the open chunk, writes the end-of-trace chunk, stops the writing thread and closes
  /// the file. Idempotent. Throws TraceError when a write failed (also an earlier one).
  /// `session_ended`: the trace ends where the recorded session ended (false for a cut, whose
  /// replay cannot know what the drivers wrote after it).
  void close(bool session_ended = true);

  const std::filesystem::path& path() const { return path_; }
  std::size_t device_count() const;
  TraceWriterStats stats() const;
  /// Why writing stopped (a failed write or fdatasync, a full ring); empty while the trace is
  /// being written.
  std::string failure() const;
  /// Fault injection (`bisturi run --inject`): the next write fails as `why` says, or the
  /// writing thread stalls for `stall` before its next write, as a full or a slow disk would.
  void fail_next_write(std::string why);
  void stall_next_write(std::chrono::milliseconds stall);
  /// Whether writing stopped: lock-free, for a haptic tick to ask.
  [[nodiscard]] bool failed() const noexcept { return failed_.load(std::memory_order_acquire); }

  /// Buffers of the ring: the open chunk and those sealed waiting for the writing thread.
  /// 32: at a session's 100 ms chunks the disk may stall for 3 s before the recording stops
  /// (buffers are reserved at their full size, but the system commits only the pages written).
  static constexpr std::size_t kBuffers = 32;

 private:
  static constexpr std::size_t kTimedDevices = 16;
  std::array<std::atomic<std::int64_t>, kTimedDevices> last_report_in_ns_{};
  void seal_locked(std::uint32_t flags);
  /// Writes all of `bytes` (the writing thread, or the constructor before it starts), adding
  /// what went to `written`; the error when the file refused them, else empty.
  std::string write_all(std::span<const std::uint8_t> bytes, std::uint64_t& written) const;
  void append_locked(TraceRecordType type, std::uint16_t device, std::int64_t time_ns,
                     std::span<const std::uint8_t> payload);
  void fail_locked(std::string why);
  /// The writing thread: writes sealed chunks in order until stopping_ and none is left.
  void write_loop();
  /// Waits (lock held) until the writing thread has taken and written every sealed chunk.
  void drain_locked(std::unique_lock<std::mutex>& lock);

  std::filesystem::path path_;
  TraceWriterOptions options_;
  mutable std::mutex mutex_;
  std::condition_variable written_;  ///< the writing thread finished a chunk
  std::condition_variable wake_;     ///< for the writing thread: flush or close wants it now
  int fd_ = -1;
  bool closed_ = false;
  bool stopping_ = false;
  std::size_t devices_ = 0;
  std::array<std::vector<std::uint8_t>, kBuffers> buffers_;
  std::size_t open_ = 0;                        ///< the buffer being filled
  std::array<std::size_t, kBuffers> sealed_{};  ///< ring of sealed buffers, oldest first
  std::size_t sealed_head_ = 0, sealed_count_ = 0;
  std::array<std::size_t, kBuffers> free_{};  ///< buffers neither open nor sealed
  std::size_t free_count_ = 0;
  bool writing_ = false;  ///< the writing thread holds a buffer out of the ring
  std::uint32_t chunk_records_ = 0;
  std::int64_t chunk_first_time_ns_ = 0;
  TraceWriterStats stats_;
  std::uint64_t total_records_ = 0;  // appended, sealed or not
  std::string failure_;
  std::atomic<bool> failed_{false};
  std::string injected_failure_;  ///< fail_next_write's reason, until the write
  std::chrono::milliseconds injected_stall_{0};
  std::thread thread_;
};

}  // namespace bisturi::devices
