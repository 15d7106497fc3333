// libFuzzer: the HID report descriptor parser, then every report it lays out, zeroed and encoded.
#include <cstdint>
#include <span>

#include "bisturi/devices/hid_descriptor.h"
#include "bisturi/devices/hid_report.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace hid = bisturi::devices::hid;
  try {
    hid::ReportCodec codec(hid::parse_report_descriptor(std::span(data, size), "fuzz"), "fuzz");
    for (const auto& report : codec.descriptor().reports) {
      auto bytes = codec.make_report(report.type, report.id);
      for (const auto& field : codec.descriptor().fields) {
        if (field.type != report.type || field.report_id != report.id) continue;
        for (std::uint32_t e = 0; e < field.count; ++e) {
          codec.set_si(bytes, field, e, 0.5);
          (void)codec.si(bytes, field, e);
        }
      }
      (void)codec.decode(report.type, bytes);
    }
  } catch (const bisturi::devices::ProtocolError&) {
  }
  return 0;
}
