#include "trace_devices.h"

#include <map>
#include <utility>

#include "bisturi/devices/trace/recording_transport.h"
#include "bisturi/devices/trace/replay_transport.h"
#include "bisturi/devices/trace/trace_reader.h"

namespace bisturi::cli {

namespace {

using Inputs = std::vector<std::pair<std::int64_t, std::vector<std::uint8_t>>>;

void open_driver(DecodedDevice& d, const devices::Registry& registry, const Inputs& inputs) {
  if (!d.trace.report_descriptor.empty()) {
    try {
      d.codec.emplace(
          devices::hid::parse_report_descriptor(d.trace.report_descriptor, d.trace.product),
          d.trace.product);
    } catch (const devices::ProtocolError&) {
    }
  }
  auto transport =
      std::make_unique<devices::ReplayTransport>(devices::to_device_descriptor(d.trace), d.clock);
  for (const auto& [t, bytes] : inputs)
    transport->push_input(devices::Nanoseconds(t), bytes);
  if (!inputs.empty()) d.clock.set(devices::Nanoseconds(inputs.front().first));
  try {
    d.driver = registry.open(std::move(transport), d.clock);
  } catch (const std::exception& e) {
    d.driver_error = e.what();
  }
}

}  // namespace

std::vector<std::unique_ptr<DecodedDevice>> decode_trace_devices(
    const std::string& path, const devices::Registry& registry) {
  std::vector<devices::TraceDevice> trace_devices;
  std::map<std::uint16_t, Inputs> inputs;
  {
    devices::TraceReader reader(path);
    try {
      while (auto r = reader.next()) {
        if (r->type == devices::TraceRecordType::kReportIn)
          inputs[r->device].emplace_back(r->time_ns, r->payload);
      }
    } catch (const devices::TraceCorruptError&) {
    }
    trace_devices = reader.devices();
  }
  std::vector<std::unique_ptr<DecodedDevice>> decoded;
  for (std::size_t i = 0; i < trace_devices.size(); ++i) {
    auto d = std::make_unique<DecodedDevice>();
    d->trace = trace_devices[i];
    open_driver(*d, registry, inputs[static_cast<std::uint16_t>(i)]);
    decoded.push_back(std::move(d));
  }
  return decoded;
}

}  // namespace bisturi::cli
