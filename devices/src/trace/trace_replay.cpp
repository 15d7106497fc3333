#include "bisturi/devices/trace/trace_replay.h"

#include <string_view>

#include <deque>
#include <memory>
#include <stdexcept>
#include <utility>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/trace/guarded_haptic.h"
#include "bisturi/devices/trace/recording_transport.h"
#include "bisturi/devices/trace/replay_transport.h"

namespace bisturi::devices {

namespace {

struct Output {
  std::uint64_t record_index = 0;
  std::uint64_t output_index = 0;
  std::int64_t time_ns = 0;
  Bytes bytes;
};

struct Slot {
  ReplayDeviceStats stats;
  std::unique_ptr<Device> device;
  std::shared_ptr<ReplayLink> link;  // of the device's current transport
  std::unique_ptr<ForceGuard> guard;
  std::unique_ptr<GuardedHaptic> haptic;
  std::deque<Output> expected;  // recorded, not matched yet
  std::deque<Output> actual;    // written during replay, not matched yet
  bool open_pending = false;    // the driver opens at the device's first report
};

class Replayer {
 public:
  Replayer(TraceReader& reader, const TraceReplayOptions& options)
      : reader_(reader),
        registry_(options.registry != nullptr ? *options.registry : builtin_),
        guard_config_(options.guard ? *options.guard
                                    : force_guard_config_from_json(reader.header().config)),
        clock_(Nanoseconds{reader.header().start_time_ns}) {
    if (options.registry == nullptr) register_builtin_drivers(builtin_);
  }

  TraceReplayResult run() {
    bool first = true;
    for (;;) {
      std::optional<TraceRecord> record;
      try {
        record = reader_.next();
      } catch (const TraceCorruptError& e) {
        result_.trace_error = e;
        break;
      }
      if (!record) break;
      if (first) result_.first_time_ns = record->time_ns;
      first = false;
      result_.last_time_ns = record->time_ns;
      handle(*record);
      ++index_;
    }
    result_.records = index_;
    result_.closed_by_writer = reader_.closed_by_writer();
    const bool complete = reader_.session_ended() && !result_.trace_error;
    if (!reader_.devices().empty()) slot(0);  // devices without records are reported too
    for (std::uint16_t d = 0; d < slots_.size(); ++d) {
      Slot& slot = slots_[d];
      // The session closed its devices (zero forces) before it closed the trace.
      close(d);
      while (!slot.expected.empty()) {
        Output e = std::move(slot.expected.front());
        slot.expected.pop_front();
        mismatch(d, e.record_index, e.output_index, e.time_ns, std::move(e.bytes), std::nullopt,
                 "missing: the driver did not write this report");
      }
      if (complete) {
        while (!slot.actual.empty()) {
          Output a = std::move(slot.actual.front());
          slot.actual.pop_front();
          mismatch(d, a.record_index, a.output_index, a.time_ns, std::nullopt, std::move(a.bytes),
                   "unexpected: the recording has no such report");
        }
      } else {
        result_.unverified_outputs += slot.actual.size();
      }
      result_.devices.push_back(slot.stats);
    }
    return std::move(result_);
  }

 private:
  std::string where(const TraceRecord& r) const {
    return reader_.name() + ": record " + std::to_string(index_) + " (" + to_string(r.type) +
           ", device " + std::to_string(r.device) + ", t = " + std::to_string(r.time_ns) + " ns)";
  }

  Slot& slot(std::uint16_t d) {
    while (slots_.size() < reader_.devices().size()) {
      Slot s;
      s.stats.device = reader_.devices()[slots_.size()];
      slots_.push_back(std::move(s));
    }
    return slots_.at(d);
  }

  void connect(std::uint16_t d) {
    Slot& s = slot(d);
    // The previous driver closes as the session's did when it dropped it (zero forces, if its
    // transport still takes them).
    close(d);
    ++s.stats.connects;
    s.link.reset();
    s.device = open_replayed(registry_, to_device_descriptor(s.stats.device), clock_, s.link);
    s.open_pending = s.device == nullptr;
    if (s.device) guard_device(s);
  }

  /// Opens the driver again on the link (fed with the report it waited for).
  void open_with_link(Slot& s) {
    s.device = open_replayed(registry_, to_device_descriptor(s.stats.device), clock_, s.link);
    s.open_pending = s.device == nullptr;
    if (s.device) guard_device(s);
  }

  void guard_device(Slot& s) {
    if (HapticDevice* haptic = as_haptic(s.device.get())) {
      if (s.guard) {
        s.guard->rearm();
      } else {
        s.guard =
            std::make_unique<ForceGuard>(haptic->capabilities().force_channels, guard_config_);
      }
      s.haptic = std::make_unique<GuardedHaptic>(*haptic, *s.guard, clock_);
    }
  }

  void handle(const TraceRecord& r) {
    if (r.type == TraceRecordType::kNote) {
      // The session's haptic loop latched its guard before the zero that follows these notes
      // (runtime/src/session/haptic_loop.h): latch here too, so the zero goes out as it did.
      const std::string_view text(reinterpret_cast<const char*>(r.payload.data()),
                                  r.payload.size());
      for (Slot& s : slots_) {
        if (!s.guard) continue;
        if (text == "haptic_stop") s.guard->device_disconnected();
        if (text == "watchdog_zero") s.guard->deadline_missed();
      }
      return;
    }
    Slot& s = slot(r.device);
    clock_.set(Nanoseconds{r.time_ns});
    // A device recorded without a kConnect (a trace cut after it connected) opens at its first
    // record.
    if (r.type != TraceRecordType::kConnect && r.type != TraceRecordType::kDeviceAdded &&
        !s.device && !s.open_pending) {
      connect(r.device);
    }
    switch (r.type) {
      case TraceRecordType::kConnect:
        connect(r.device);
        break;
      case TraceRecordType::kReportIn:
        ++s.stats.reports_in;
        s.link->push_input(Nanoseconds{r.time_ns}, r.payload);
        if (s.open_pending) {
          open_with_link(s);
          break;
        }
        try {
          if (s.haptic) {
            s.haptic->poll(std::chrono::microseconds(0));
          } else {
            s.device->poll(std::chrono::microseconds(0));
          }
        } catch (const ProtocolError&) {
          ++s.stats.malformed_reports;
        } catch (const DeviceDisconnected&) {
          // Lost in the recording too: the session went on.
        }
        break;
      case TraceRecordType::kForceCommand: {
        ++s.stats.force_commands;
        if (!s.haptic) {
          throw TraceError(where(r) + ": a force command for a device that takes no forces");
        }
        const std::vector<double> forces = r.forces_N();
        try {
          s.haptic->send(forces);
        } catch (const DeviceDisconnected&) {
          // As in the session: the guard has latched, the session goes on.
        } catch (const std::invalid_argument& e) {
          throw TraceError(where(r) + ": " + e.what());
        }
        break;
      }
      case TraceRecordType::kDisconnect:
        ++s.stats.disconnects;
        if (s.link) s.link->disconnect();
        if (s.guard) s.guard->device_disconnected();
        break;
      case TraceRecordType::kReportOut:
        ++s.stats.reports_out_recorded;
        s.expected.push_back(
            Output{index_, s.stats.reports_out_recorded - 1, r.time_ns, r.payload});
        break;
      case TraceRecordType::kDeviceAdded:
      case TraceRecordType::kNote:
        break;
    }
    collect(r.device);
  }

  void close(std::uint16_t d) {
    Slot& s = slots_.at(d);
    s.haptic.reset();
    if (s.device) s.device->close();
    collect(d);
    s.device.reset();
  }

  // Takes what the device's driver wrote and matches it, in order, with the recorded outputs.
  void collect(std::uint16_t d) {
    Slot& s = slots_.at(d);
    if (s.link) {
      for (CapturedReport& c : s.link->take_written()) {
        s.actual.push_back(
            Output{index_, s.stats.reports_out_replayed, c.time.count(), std::move(c.bytes)});
        ++s.stats.reports_out_replayed;
      }
    }
    while (!s.expected.empty() && !s.actual.empty()) {
      Output e = std::move(s.expected.front());
      Output a = std::move(s.actual.front());
      s.expected.pop_front();
      s.actual.pop_front();
      if (e.bytes == a.bytes) {
        ++s.stats.reports_out_matched;
      } else {
        mismatch(d, e.record_index, e.output_index, e.time_ns, std::move(e.bytes),
                 std::move(a.bytes), "bytes differ");
      }
    }
  }

  void mismatch(std::uint16_t d, std::uint64_t record, std::uint64_t output, std::int64_t time,
                std::optional<Bytes> expected, std::optional<Bytes> actual, const char* reason) {
    ++result_.mismatches;
    if (result_.mismatch) return;
    result_.mismatch =
        ReplayMismatch{d, record, output, time, std::move(expected), std::move(actual), reason};
  }

  TraceReader& reader_;
  Registry builtin_;
  const Registry& registry_;
  ForceGuardConfig guard_config_;
  VirtualClock clock_;
  std::vector<Slot> slots_;
  std::uint64_t index_ = 0;
  TraceReplayResult result_;
};

}  // namespace

std::unique_ptr<Device> open_replayed(const Registry& registry, const DeviceDescriptor& device,
                                      VirtualClock& clock, std::shared_ptr<ReplayLink>& link) {
  auto transport = link ? std::make_unique<ReplayTransport>(device, clock, link)
                        : std::make_unique<ReplayTransport>(device, clock);
  link = transport->link();
  const Nanoseconds now = clock.now();
  try {
    return registry.open(std::move(transport), clock);
  } catch (const DeviceError&) {
    if (link->pending() > 0) throw;  // it had its first report: a real refusal
    (void)link->take_written();
    clock.set(now);
    return nullptr;
  }
}

TraceReplayResult replay_trace(TraceReader& reader, const TraceReplayOptions& options) {
  Replayer replayer(reader, options);
  return replayer.run();
}

}  // namespace bisturi::devices
