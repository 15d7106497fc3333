#pragma once
// Replays a recorded trace through the same drivers and force guard in virtual time and compares
// the output reports the drivers write with the recorded ones, byte for byte.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/trace/trace_format.h"
#include "bisturi/devices/trace/trace_reader.h"
#include "bisturi/devices/transport.h"

namespace bisturi::devices {

struct TraceReplayOptions {
  /// Where the drivers come from (observed); nullptr: the built-in drivers.
  const Registry* registry = nullptr;
  /// The guard's settings; unset: those in the trace's configuration ("force_guard"), else the
  /// defaults.
  std::optional<ForceGuardConfig> guard;
};

/// The first output report that differs from the recording.
struct ReplayMismatch {
  std::uint16_t device = 0;
  /// Index in the trace (counting every record from 0) of the recorded output report; for an
  /// output the driver wrote beyond the recording, the record being replayed when it wrote it.
  std::uint64_t record_index = 0;
  /// Which of the device's output reports (0 = its first).
  std::uint64_t output_index = 0;
  std::int64_t time_ns = 0;       ///< recorded time (or the replay's, if none)
  std::optional<Bytes> expected;  ///< nullopt: the recording has no such report
  std::optional<Bytes> actual;    ///< nullopt: the driver did not write it
  std::string reason;             ///< "bytes differ", "missing", "unexpected"
};

struct ReplayDeviceStats {
  TraceDevice device;
  std::uint64_t reports_in = 0;
  std::uint64_t reports_out_recorded = 0;
  std::uint64_t reports_out_replayed = 0;  ///< written by the driver during replay
  std::uint64_t reports_out_matched = 0;
  std::uint64_t force_commands = 0;
  std::uint64_t malformed_reports = 0;  ///< ProtocolError from the driver (as in the session)
  std::uint64_t connects = 0;
  std::uint64_t disconnects = 0;
};

struct TraceReplayResult {
  /// True when every output report matched and the trace was read to its end without error.
  bool passed() const { return !mismatch && !trace_error; }

  std::uint64_t records = 0;  ///< records replayed
  std::int64_t first_time_ns = 0;
  std::int64_t last_time_ns = 0;
  std::vector<ReplayDeviceStats> devices;
  std::uint64_t mismatches = 0;  ///< output reports that differ, are missing or unexpected
  std::optional<ReplayMismatch> mismatch;  ///< the first
  /// Outputs the drivers wrote beyond the recording of a trace that does not end where its session
  /// ended (its writer was killed, it is a cut, or it ends with a bad chunk): the recording may
  /// have lost them, so they are not mismatches.
  std::uint64_t unverified_outputs = 0;
  /// The bad chunk that ended the replay early; everything before it was replayed.
  std::optional<TraceCorruptError> trace_error;
  bool closed_by_writer = false;
};

/// Replays `reader` from its current position to its end or to its first bad chunk:
///  - kConnect: a ReplayTransport carrying the device's description; its driver opened through
///    the registry (by the recorded driver name) on a VirtualClock; for a haptic device a
///    ForceGuard over its force channels, or guard.rearm() when it reconnects;
///  - kReportIn: the clock moves to the record's time, the report is queued and the device polled
///    (GuardedHaptic::poll); a ProtocolError is counted and the replay goes on;
///  - kForceCommand: the clock moves to its time and the command goes through GuardedHaptic::send;
///  - kDisconnect: the transport is lost and the guard latched;
///  - kReportOut: compared, in order per device, with what the driver wrote;
///  - at the end every driver is closed (its zero-force reports are compared too: a session
///    closes its devices before it closes the trace). Outputs beyond the recording count as
///    mismatches only in a trace its writer closed (see unverified_outputs).
/// Throws DeviceError when a recorded device's driver cannot be opened, TraceError on records that
/// do not fit the devices (a force command of the wrong length, a report for a device never
/// connected). A bad chunk does not throw: it ends the replay and is returned in trace_error.
TraceReplayResult replay_trace(TraceReader& reader, const TraceReplayOptions& options = {});

class ReplayLink;
/// Opens the driver `registry` picks for a replayed `device` on a ReplayTransport over `link`
/// (a new link when it is null; `link` then holds it). Returns nullptr when the driver waits for
/// the device's first report while it opens (the vendor arm's info packet): what the attempt
/// wrote is dropped and its wait on `clock` undone; call again once the recording's first report
/// for the device is pushed into `link`. Throws what the driver throws otherwise.
std::unique_ptr<Device> open_replayed(const Registry& registry, const DeviceDescriptor& device,
                                      VirtualClock& clock, std::shared_ptr<ReplayLink>& link);

}  // namespace bisturi::devices
