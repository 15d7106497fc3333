// Private: writes HID report descriptor items (shortest encoding) for the simulated twins.
#pragma once

#include <cstdint>

#include "bisturi/devices/transport.h"

namespace bisturi::devices::detail {

class DescriptorWriter {
 public:
  // type: 0 main, 1 global, 2 local. Signed values use the shortest two's-complement size.
  DescriptorWriter& item(std::uint8_t type, std::uint8_t tag, std::int64_t value, bool is_signed) {
    std::uint8_t size = 4;
    if (is_signed) {
      if (value >= -128 && value <= 127)
        size = 1;
      else if (value >= -32768 && value <= 32767)
        size = 2;
    } else {
      if (value >= 0 && value <= 0xFF)
        size = 1;
      else if (value >= 0 && value <= 0xFFFF)
        size = 2;
    }
    const std::uint8_t code = size == 4 ? 3 : size;
    bytes_.push_back(static_cast<std::uint8_t>(tag << 4 | type << 2 | code));
    const auto raw = static_cast<std::uint32_t>(value);
    for (std::uint8_t i = 0; i < size; ++i)
      bytes_.push_back(static_cast<std::uint8_t>(raw >> (8 * i)));
    return *this;
  }
  DescriptorWriter& usage_page(std::uint16_t page) { return item(1, 0, page, false); }
  DescriptorWriter& usage(std::uint16_t id) { return item(2, 0, id, false); }
  DescriptorWriter& usage_range(std::uint16_t lo, std::uint16_t hi) {
    item(2, 1, lo, false);
    return item(2, 2, hi, false);
  }
  DescriptorWriter& logical(std::int64_t lo, std::int64_t hi) {
    item(1, 1, lo, true);
    return item(1, 2, hi, lo < 0);
  }
  DescriptorWriter& physical(std::int64_t lo, std::int64_t hi) {
    item(1, 3, lo, true);
    return item(1, 4, hi, lo < 0);
  }
  DescriptorWriter& unit(std::uint32_t code, std::int8_t exponent) {
    item(1, 6, code, false);
    return item(1, 5, static_cast<std::uint8_t>(exponent) & 0x0F, false);
  }
  DescriptorWriter& report(std::uint8_t id) { return item(1, 8, id, false); }
  DescriptorWriter& size_count(std::uint32_t size, std::uint32_t count) {
    item(1, 7, size, false);
    return item(1, 9, count, false);
  }
  DescriptorWriter& input(std::uint8_t flags) { return item(0, 8, flags, false); }
  DescriptorWriter& output(std::uint8_t flags) { return item(0, 9, flags, false); }
  DescriptorWriter& collection(std::uint8_t type) { return item(0, 10, type, false); }
  DescriptorWriter& end_collection() {
    bytes_.push_back(0xC0);
    return *this;
  }
  Bytes take() { return std::move(bytes_); }

 private:
  Bytes bytes_;
};

inline void put_le(Bytes& out, std::size_t at, std::uint32_t value, int bytes) {
  for (int i = 0; i < bytes; ++i)
    out[at + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(value >> (8 * i));
}

}  // namespace bisturi::devices::detail
