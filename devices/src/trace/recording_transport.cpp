#include "bisturi/devices/trace/recording_transport.h"

#include <string>
#include <utility>

namespace bisturi::devices {

TraceDevice to_trace_device(const DeviceDescriptor& descriptor) {
  TraceDevice d;
  d.kind = to_string(descriptor.kind);
  d.vendor_id = descriptor.vendor_id;
  d.product_id = descriptor.product_id;
  d.serial = descriptor.serial;
  d.product = descriptor.product;
  d.path = descriptor.path;
  d.driver = descriptor.driver;
  d.report_descriptor = descriptor.report_descriptor;
  return d;
}

DeviceDescriptor to_device_descriptor(const TraceDevice& device) {
  DeviceDescriptor d;
  bool known = false;
  for (const TransportKind kind :
       {TransportKind::Hid, TransportKind::Usb, TransportKind::Virtual}) {
    if (device.kind == to_string(kind)) {
      d.kind = kind;
      known = true;
    }
  }
  if (!known) {
    throw TraceError("device " + device.product + ": unknown transport kind \"" + device.kind +
                     "\"");
  }
  d.vendor_id = device.vendor_id;
  d.product_id = device.product_id;
  d.serial = device.serial;
  d.product = device.product;
  d.path = device.path;
  d.driver = device.driver;
  d.report_descriptor = device.report_descriptor;
  return d;
}

RecordingTransport::RecordingTransport(std::unique_ptr<Transport> inner, TraceWriter& writer,
                                       std::uint16_t index, Clock& clock)
    : inner_(std::move(inner)), writer_(&writer), index_(index), clock_(&clock) {
  writer_->connect(index_, clock_->now().count());
}

void RecordingTransport::lost() {
  if (!disconnected_.exchange(true)) writer_->disconnect(index_, clock_->now().count());
}

std::optional<Bytes> RecordingTransport::read(std::chrono::microseconds timeout) {
  std::optional<Bytes> report;
  try {
    report = inner_->read(timeout);
  } catch (const DeviceDisconnected&) {
    lost();
    throw;
  }
  const std::int64_t now = clock_->now().count();
  if (report) {
    writer_->report_in(index_, now, *report);
  } else {
    writer_->poll(now);
  }
  return report;
}

bool RecordingTransport::read_into(Bytes& report, std::chrono::microseconds timeout) {
  bool got = false;
  try {
    got = inner_->read_into(report, timeout);
  } catch (const DeviceDisconnected&) {
    lost();
    throw;
  }
  const std::int64_t now = clock_->now().count();
  if (got) {
    writer_->report_in(index_, now, report);
  } else {
    writer_->poll(now);
  }
  return got;
}

void RecordingTransport::write(std::span<const std::uint8_t> report) {
  // The device first, the trace after (at the time the write began): a recording never delays
  // what goes to the device. A write that loses the device is recorded before its disconnect.
  const std::int64_t now = clock_->now().count();
  const bool known_lost = disconnected_.load();
  try {
    inner_->write(report);
  } catch (const DeviceDisconnected&) {
    if (!known_lost) writer_->report_out(index_, now, report);
    lost();
    throw;
  }
  if (!known_lost) writer_->report_out(index_, now, report);
}

}  // namespace bisturi::devices
