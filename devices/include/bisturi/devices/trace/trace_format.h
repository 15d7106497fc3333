#pragma once
// The bisturi device trace: what crossed the transports (reports in and out, with monotonic
// timestamps), the force commands that produced the output reports, connect and disconnect events,
// and the session's configuration. The byte layout is documented in docs/devices/trace-format.md;
// this header holds its in-memory side: the header, the records and the errors a reader reports.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace bisturi::devices {

/// Format version written by TraceWriter. A reader accepts any minor version of its major version
/// (unknown record types and trailing fields are skipped) and rejects other major versions.
inline constexpr std::uint16_t kTraceVersionMajor = 1;
inline constexpr std::uint16_t kTraceVersionMinor = 0;

/// A chunk's payload may not exceed this (a writer's chunks are far smaller; a reader refuses
/// larger lengths instead of allocating them).
inline constexpr std::uint32_t kTraceMaxChunkPayload = 64u << 20;

/// What a recorded device was, as the trace stores it: enough to rebuild its driver through the
/// registry and to tell a person which device it was.
struct TraceDevice {
  std::string kind;  ///< "hid", "usb", "virtual", ... (the transport kind, as text)
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::string serial;
  std::string product;
  std::string path;
  std::string driver;                           ///< registry name of the driver that was opened
  std::vector<std::uint8_t> report_descriptor;  ///< HID report descriptor bytes (empty if none)

  bool operator==(const TraceDevice&) const = default;
};

/// The trace header: written once, before the first chunk.
struct TraceHeader {
  std::uint16_t version_major = kTraceVersionMajor;
  std::uint16_t version_minor = kTraceVersionMinor;
  std::int64_t start_time_ns = 0;       ///< the recording clock's time when the trace was opened
  std::int64_t wall_clock_unix_ns = 0;  ///< wall-clock time at open (information only)
  std::string producer;                 ///< program and version that wrote the trace
  std::string config;                   ///< session configuration (opaque; JSON text by convention)
  std::vector<TraceDevice> devices;     ///< devices known at open; more may be added by records

  bool operator==(const TraceHeader&) const = default;
};

enum class TraceRecordType : std::uint8_t {
  kReportIn = 1,      ///< bytes a device sent (a transport read)
  kReportOut = 2,     ///< bytes sent to a device (a transport write)
  kForceCommand = 3,  ///< the force (N per actuator) commanded before the force guard
  kConnect = 4,       ///< the device was (re)connected
  kDisconnect = 5,    ///< the device was lost
  kDeviceAdded = 6,   ///< a device that was not in the header; payload: its description
  kNote = 7,          ///< free UTF-8 text (an annotation)
};

/// Name of a record type ("report_in", "force", ...); "unknown" for others.
const char* to_string(TraceRecordType type);

/// One record. `payload` holds the report bytes for reports, the forces as little-endian float64
/// for force commands (see forces_N()), the text for notes and the encoded description for
/// kDeviceAdded; it is empty for connect and disconnect.
struct TraceRecord {
  TraceRecordType type = TraceRecordType::kNote;
  std::uint16_t device = 0;
  std::int64_t time_ns = 0;
  std::vector<std::uint8_t> payload;

  /// The forces of a kForceCommand record, in newtons per actuator.
  std::vector<double> forces_N() const;
  bool operator==(const TraceRecord&) const = default;
};

/// Base of every error about a trace file. The message starts with the file's name.
class TraceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A bad or truncated part of a trace: the header or one chunk. Everything before it was valid and
/// has been delivered.
class TraceCorruptError : public TraceError {
 public:
  /// `chunk` is empty for a bad file header. `offset` is the byte offset of the chunk (or of the
  /// header) in the file.
  TraceCorruptError(std::string file, std::optional<std::uint64_t> chunk, std::uint64_t offset,
                    const std::string& reason);

  const std::string& file() const { return file_; }
  const std::optional<std::uint64_t>& chunk() const { return chunk_; }
  std::uint64_t offset() const { return offset_; }
  const std::string& reason() const { return reason_; }
  /// True when the trace simply ends inside this chunk (or header), as opposed to bad contents.
  bool truncated() const { return truncated_; }
  void set_truncated(bool truncated) { truncated_ = truncated; }

 private:
  std::string file_;
  std::optional<std::uint64_t> chunk_;
  std::uint64_t offset_ = 0;
  std::string reason_;
  bool truncated_ = false;
};

/// Encodes a force command's payload (little-endian float64 per actuator).
std::vector<std::uint8_t> encode_forces(std::span<const double> forces_N);
/// Encodes and decodes a device description as kDeviceAdded records and the header store it.
std::vector<std::uint8_t> encode_device(const TraceDevice& device);
/// Throws TraceError (with `what` in its message) when `bytes` is not a valid description.
TraceDevice decode_device(std::span<const std::uint8_t> bytes, const std::string& what);

}  // namespace bisturi::devices
