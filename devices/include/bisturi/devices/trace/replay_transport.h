#pragma once
// Replay side of traces: a Transport that hands a driver recorded input reports in virtual time
// and captures what the driver writes, for comparison with the recorded output reports.

#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/transport.h"

namespace bisturi::devices {

/// An output report a driver wrote to a ReplayTransport.
struct CapturedReport {
  Nanoseconds time{0};  ///< the clock's time at the write
  Bytes bytes;
};

/// The feeding end of a ReplayTransport, shared with it: it outlives the transport, so what a
/// driver wrote while closing (zero forces) can still be taken after the driver released it.
/// Thread-safe.
class ReplayLink {
 public:
  /// Queues an input report recorded at `time`.
  void push_input(Nanoseconds time, std::span<const std::uint8_t> report);
  /// Input reports queued and not yet read.
  std::size_t pending() const;
  /// The device is lost from now on (queued inputs are dropped, as an unplug loses them).
  void disconnect();
  bool connected() const;
  /// The reports written since the last call, oldest first.
  std::vector<CapturedReport> take_written();

 private:
  friend class ReplayTransport;
  struct Input {
    Nanoseconds time;
    Bytes bytes;
  };
  mutable std::mutex mutex_;
  std::deque<Input> inputs_;
  std::vector<CapturedReport> written_;
  bool connected_ = true;
};

/// A Transport fed from a trace:
///  - read(timeout) returns the oldest queued input whose time has come (time <= clock.now()); if
///    the next one is due within `timeout`, the clock sleeps until it (a VirtualClock jumps there),
///    otherwise the clock sleeps for the timeout and read returns nullopt (a zero timeout never
///    moves the clock);
///  - write() captures the report with clock.now() while connected;
///  - after disconnect(), reads and writes throw DeviceDisconnected, as a live transport does.
/// The mirror of RecordingTransport.
class ReplayTransport final : public Transport {
 public:
  /// `clock` is observed and must outlive the transport.
  ReplayTransport(DeviceDescriptor descriptor, Clock& clock);
  /// On an existing link (a driver opened again on what was already fed to it).
  ReplayTransport(DeviceDescriptor descriptor, Clock& clock, std::shared_ptr<ReplayLink> link);

  const DeviceDescriptor& descriptor() const override { return descriptor_; }
  std::optional<Bytes> read(std::chrono::microseconds timeout) override;
  void write(std::span<const std::uint8_t> report) override;

  /// The feeding end (keep it to feed and inspect the transport after handing it to a driver).
  const std::shared_ptr<ReplayLink>& link() const { return link_; }
  void push_input(Nanoseconds time, std::span<const std::uint8_t> report) {
    link_->push_input(time, report);
  }
  void disconnect() { link_->disconnect(); }
  std::vector<CapturedReport> take_written() { return link_->take_written(); }

 private:
  DeviceDescriptor descriptor_;
  Clock* clock_;
  std::shared_ptr<ReplayLink> link_;
};

}  // namespace bisturi::devices
