#include "bisturi/devices/hid_report.h"

namespace bisturi::devices::hid {

std::uint32_t read_bits(std::span<const std::uint8_t> data, std::uint32_t bit_offset,
                        std::uint32_t bit_size) {
  std::uint64_t value = 0;
  const std::size_t first = bit_offset / 8;
  const std::uint32_t shift = bit_offset % 8;
  const std::size_t bytes = (shift + bit_size + 7) / 8;  // at most 5 for 32 bits
  for (std::size_t i = 0; i < bytes; ++i) {
    const std::size_t at = first + i;
    if (at < data.size()) value |= std::uint64_t{data[at]} << (8 * i);
  }
  value >>= shift;
  if (bit_size < 32) value &= (std::uint64_t{1} << bit_size) - 1;
  return static_cast<std::uint32_t>(value);
}

void write_bits(std::span<std::uint8_t> data, std::uint32_t bit_offset, std::uint32_t bit_size,
                std::uint32_t value) {
  for (std::uint32_t i = 0; i < bit_size; ++i) {
    const std::uint32_t bit = bit_offset + i;
    const std::size_t at = bit / 8;
    if (at >= data.size()) return;
    const auto mask = static_cast<std::uint8_t>(1u << (bit % 8));
    if ((value >> i) & 1u) {
      data[at] = static_cast<std::uint8_t>(data[at] | mask);
    } else {
      data[at] = static_cast<std::uint8_t>(data[at] & ~mask);
    }
  }
}

ReportCodec::ReportCodec(ReportDescriptor descriptor, std::string device)
    : descriptor_(std::move(descriptor)), device_(std::move(device)) {}

const ReportInfo& ReportCodec::check(ReportType type, std::span<const std::uint8_t> report) const {
  if (report.empty())
    throw ProtocolError(device_, 0, std::string("empty ") + to_string(type) + " report");
  const std::uint8_t id = descriptor_.uses_report_ids ? report[0] : 0;
  const ReportInfo* info = descriptor_.find_report(type, id);
  if (!info) {
    throw ProtocolError(
        device_, 0, std::string("unknown ") + to_string(type) + " report id " + std::to_string(id));
  }
  if (report.size() < info->bytes()) {
    throw ProtocolError(device_, report.size(),
                        std::string(to_string(type)) + " report " + std::to_string(id) + ": " +
                            std::to_string(report.size()) + " bytes, the descriptor needs " +
                            std::to_string(info->bytes()));
  }
  return *info;
}

std::int32_t ReportCodec::logical(std::span<const std::uint8_t> report, const Field& field,
                                  std::uint32_t element) const {
  const std::uint32_t raw = read_bits(
      report, data_offset_bits() + field.bit_offset + element * field.bit_size, field.bit_size);
  if (field.is_signed() && field.bit_size < 32) {
    const std::uint32_t sign = 1u << (field.bit_size - 1);
    if (raw & sign)
      return static_cast<std::int32_t>(static_cast<std::int64_t>(raw) -
                                       (std::int64_t{1} << field.bit_size));
  }
  return static_cast<std::int32_t>(raw);
}

std::vector<FieldValue> ReportCodec::decode(ReportType type,
                                            std::span<const std::uint8_t> report) const {
  const ReportInfo& info = check(type, report);
  std::vector<FieldValue> values;
  for (std::uint32_t f = 0; f < descriptor_.fields.size(); ++f) {
    const Field& field = descriptor_.fields[f];
    if (field.type != type || field.report_id != info.id) continue;
    for (std::uint32_t e = 0; e < field.count; ++e) {
      FieldValue value;
      value.field = f;
      value.element = e;
      value.logical = logical(report, field, e);
      value.si = field.to_si(value.logical);
      if (field.is_variable()) {
        value.usage = field.usage_of(e);
      } else {
        const std::int64_t index = std::int64_t{value.logical} - field.logical_min;
        value.usage = index >= 0 && static_cast<std::uint64_t>(index) < field.usages.size()
                          ? field.usages[static_cast<std::size_t>(index)]
                          : 0;
      }
      values.push_back(value);
    }
  }
  return values;
}

Bytes ReportCodec::make_report(ReportType type, std::uint8_t id) const {
  const ReportInfo* info = descriptor_.find_report(type, id);
  if (!info) {
    throw ProtocolError(device_, 0,
                        std::string("no ") + to_string(type) + " report " + std::to_string(id));
  }
  Bytes report(info->bytes(), 0);
  if (info->with_id) report[0] = id;
  return report;
}

void ReportCodec::set_logical(std::span<std::uint8_t> report, const Field& field,
                              std::uint32_t element, std::int32_t value) const {
  if (value < field.logical_min) value = field.logical_min;
  if (value > field.logical_max) value = field.logical_max;
  write_bits(report, data_offset_bits() + field.bit_offset + element * field.bit_size,
             field.bit_size, static_cast<std::uint32_t>(value));
}

}  // namespace bisturi::devices::hid
