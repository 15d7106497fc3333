#include "bisturi/devices/trace/guarded_haptic.h"

#include <nlohmann/json.hpp>
#include <utility>

#include "bisturi/devices/trace/recording_transport.h"

namespace bisturi::devices {

RecordedDevice open_recorded(const Registry& registry, std::unique_ptr<Transport> transport,
                             TraceWriter& writer, Clock& clock,
                             std::optional<std::uint16_t> index) {
  if (!transport) throw std::invalid_argument("open_recorded: no transport");
  if (!index) {
    // The description names the driver, so a replay opens the same one.
    TraceDevice device = to_trace_device(transport->descriptor());
    if (device.driver.empty()) {
      const DriverInfo* driver = registry.find(transport->descriptor());
      if (driver == nullptr) {
        throw DeviceError(describe(transport->descriptor()) + ": no driver for this device");
      }
      device.driver = driver->name;
    }
    index = writer.add_device(clock.now().count(), device);
  }
  auto recording =
      std::make_unique<RecordingTransport>(std::move(transport), writer, *index, clock);
  RecordedDevice result;
  result.index = *index;
  result.device = registry.open(std::move(recording), clock);
  return result;
}

std::string force_guard_config_json(const ForceGuardConfig& config) {
  const nlohmann::json j = {{"force_guard",
                             {{"period_ns", config.period.count()},
                              {"deadline_margin_ns", config.deadline_margin.count()},
                              {"device_silence_timeout_ns", config.device_silence_timeout.count()},
                              {"engage_threshold_N", config.engage_threshold_N},
                              {"ramp_in_ns", config.ramp_in.count()},
                              {"watchdog_auto_rearm", config.watchdog_auto_rearm}}}};
  return j.dump();
}

ForceGuardConfig force_guard_config_from_json(std::string_view config,
                                              const ForceGuardConfig& fallback) {
  const nlohmann::json j = nlohmann::json::parse(config, nullptr, false);
  if (j.is_discarded() || !j.is_object() || !j.contains("force_guard")) return fallback;
  const nlohmann::json& g = j["force_guard"];
  ForceGuardConfig out = fallback;
  try {
    const auto ns = [&g](const char* key, Nanoseconds& field) {
      if (g.contains(key)) field = Nanoseconds{g.at(key).get<Nanoseconds::rep>()};
    };
    ns("period_ns", out.period);
    ns("deadline_margin_ns", out.deadline_margin);
    ns("device_silence_timeout_ns", out.device_silence_timeout);
    ns("ramp_in_ns", out.ramp_in);
    if (g.contains("engage_threshold_N")) {
      out.engage_threshold_N = g.at("engage_threshold_N").get<double>();
    }
    if (g.contains("watchdog_auto_rearm")) {
      out.watchdog_auto_rearm = g.at("watchdog_auto_rearm").get<bool>();
    }
  } catch (const nlohmann::json::exception& e) {
    throw TraceError(std::string("trace configuration: force_guard: ") + e.what());
  }
  return out;
}

GuardedHaptic::GuardedHaptic(HapticDevice& device, ForceGuard& guard, Clock& clock,
                             TraceWriter* writer, std::uint16_t index)
    : device_(&device),
      guard_(&guard),
      clock_(&clock),
      writer_(writer),
      index_(index),
      output_(guard.force_components(), 0.0) {
  device.prepare_preempting_zero();
}

std::size_t GuardedHaptic::poll(std::chrono::microseconds timeout) {
  // The guard hears of every report handled, also when a later one in the same poll is malformed
  // (replay polls report by report and must come to the same last answer).
  const std::uint64_t before = device_->state().reports;
  const auto answered = [&] {
    if (device_->state().reports == before) return;
    // Recording, the guard hears the time the report was recorded at, as a replay's does (its
    // driver stamps the report with that time): the driver's own stamp comes a little later,
    // and a silence watchdog at its limit would decide the other way.
    Nanoseconds at = device_->state().sample_time;
    if (writer_ != nullptr) {
      const std::int64_t recorded = writer_->last_report_in_ns(index_);
      if (recorded >= 0) at = Nanoseconds(recorded);
    }
    guard_->device_answered(at);
  };
  std::size_t handled = 0;
  try {
    handled = device_->poll(timeout);
  } catch (const DeviceDisconnected&) {
    answered();
    guard_->device_disconnected();
    throw;
  } catch (...) {
    answered();
    throw;
  }
  answered();
  return handled;
}

GuardStep GuardedHaptic::send(std::span<const double> command_N) {
  const Nanoseconds now = clock_->now();
  const GuardStep step = guard_->step(command_N, now, output_);
  // The device first, the trace after: a recording that stalls or fails never delays or
  // swallows a force (a zero above all). The record keeps the command's own time.
  try {
    device_->send_forces(output_);
  } catch (const DeviceDisconnected&) {
    guard_->device_disconnected();
    record(now, command_N);
    throw;
  }
  record(now, command_N);
  return step;
}

void GuardedHaptic::record(Nanoseconds time, std::span<const double> command_N) {
  if (writer_ == nullptr) return;
  try {
    writer_->force_command(index_, time.count(), command_N);
  } catch (const TraceError&) {
    // Only a closed trace throws here (a failed write stops the recording quietly): the force
    // went out, and the recording's end is the writer's to report.
  }
}

}  // namespace bisturi::devices
