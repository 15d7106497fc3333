#pragma once
// Recording side of traces: a Transport decorator that writes every report crossing it into a
// TraceWriter with the clock's timestamp, and the conversions between a transport's
// DeviceDescriptor and the trace's description of a device.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/trace/trace_format.h"
#include "bisturi/devices/trace/trace_writer.h"
#include "bisturi/devices/transport.h"

namespace bisturi::devices {

TraceDevice to_trace_device(const DeviceDescriptor& descriptor);
/// Throws TraceError on a transport kind this library does not know.
DeviceDescriptor to_device_descriptor(const TraceDevice& device);

/// Wraps any Transport and records what crosses it as device `index` of `writer`:
///  - construction records kConnect (a replay opens the device's driver there);
///  - read(): each report returned is recorded as kReportIn at clock.now() after the read;
///    an empty read lets the writer seal an old chunk (TraceWriter::poll);
///  - write(): the report is recorded as kReportOut at clock.now() before it is forwarded (what
///    the driver sent, which replay compares), unless the device is already known to be lost;
///  - the first DeviceDisconnected from the wrapped transport records kDisconnect and is rethrown.
/// Write failures of the trace itself (a full disk) propagate as TraceError.
class RecordingTransport final : public Transport {
 public:
  /// `writer` and `clock` are observed and must outlive the transport.
  RecordingTransport(std::unique_ptr<Transport> inner, TraceWriter& writer, std::uint16_t index,
                     Clock& clock);

  const DeviceDescriptor& descriptor() const override { return inner_->descriptor(); }
  std::optional<Bytes> read(std::chrono::microseconds timeout) override;
  bool read_into(Bytes& report, std::chrono::microseconds timeout) override;
  void write(std::span<const std::uint8_t> report) override;
  /// Forwarded and not recorded (recording may wait on the writer): the haptic loop records the
  /// zero it sends once the stalled write returns.
  bool write_preempting(std::span<const std::uint8_t> report) noexcept override {
    return inner_->write_preempting(report);
  }
  bool write_is_bounded() const override { return inner_->write_is_bounded(); }

  std::uint16_t index() const { return index_; }
  bool disconnected() const { return disconnected_.load(); }

 private:
  void lost();

  std::unique_ptr<Transport> inner_;
  TraceWriter* writer_;
  std::uint16_t index_;
  Clock* clock_;
  std::atomic<bool> disconnected_{false};
};

}  // namespace bisturi::devices
