// Reading and writing HID reports laid out by a parsed report descriptor: bit fields of any size
// and alignment, signed and unsigned, converted to SI through the physical range and unit.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "bisturi/devices/hid_descriptor.h"
#include "bisturi/devices/transport.h"

namespace bisturi::devices::hid {

// Raw bit access (little-endian bit order, as HID). Bits beyond the span read as zero; writes
// beyond it are ignored.
std::uint32_t read_bits(std::span<const std::uint8_t> data, std::uint32_t bit_offset,
                        std::uint32_t bit_size);
void write_bits(std::span<std::uint8_t> data, std::uint32_t bit_offset, std::uint32_t bit_size,
                std::uint32_t value);

struct FieldValue {
  std::uint32_t field = 0;  // index in ReportDescriptor::fields
  std::uint32_t element = 0;
  std::uint32_t usage = 0;  // extended usage (for arrays: the selected usage, 0 when none)
  std::int32_t logical = 0;
  double si = 0;  // Field::to_si(logical)
};

class ReportCodec {
 public:
  ReportCodec(ReportDescriptor descriptor, std::string device);
  const ReportDescriptor& descriptor() const { return descriptor_; }
  const std::string& device() const { return device_; }

  // Checks a report received on the wire (id byte first when the descriptor uses ids): a known
  // report of that type and enough bytes. Returns it; throws ProtocolError otherwise.
  const ReportInfo& check(ReportType type, std::span<const std::uint8_t> report) const;
  // Element `element` of field `field`, from a report that passed check(): its logical value
  // (sign-extended for signed fields).
  std::int32_t logical(std::span<const std::uint8_t> report, const Field& field,
                       std::uint32_t element) const;
  double si(std::span<const std::uint8_t> report, const Field& field, std::uint32_t element) const {
    return field.to_si(logical(report, field, element));
  }
  // Every non-constant element of a report (inspection, fuzzing).
  std::vector<FieldValue> decode(ReportType type, std::span<const std::uint8_t> report) const;

  // A zeroed report of that type and id, with the id byte set. ProtocolError when unknown.
  Bytes make_report(ReportType type, std::uint8_t id) const;
  void set_logical(std::span<std::uint8_t> report, const Field& field, std::uint32_t element,
                   std::int32_t value) const;
  void set_si(std::span<std::uint8_t> report, const Field& field, std::uint32_t element,
              double value) const {
    set_logical(report, field, element, field.from_si(value));
  }

 private:
  std::uint32_t data_offset_bits() const { return descriptor_.uses_report_ids ? 8u : 0u; }
  ReportDescriptor descriptor_;
  std::string device_;
};

}  // namespace bisturi::devices::hid
