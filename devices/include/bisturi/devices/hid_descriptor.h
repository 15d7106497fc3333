// HID report descriptors (HID 1.11, section 6.2.2): items, global and local state, usage pages,
// report ids, report sizes and counts, bit fields, logical/physical ranges, units and unit
// exponents, collections. Malformed descriptors give a ProtocolError, never a crash.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "bisturi/devices/transport.h"

namespace bisturi::devices::hid {

// Usage pages this library interprets.
inline constexpr std::uint16_t kPageGenericDesktop = 0x01;
inline constexpr std::uint16_t kPageVrControls = 0x03;
inline constexpr std::uint16_t kPageButton = 0x09;
inline constexpr std::uint16_t kPageHaptics = 0x0E;
inline constexpr std::uint16_t kPagePid = 0x0F;  // Physical Interface Device (force feedback)
inline constexpr std::uint16_t kPageSensors = 0x20;

// An extended usage: page in the high 16 bits, id in the low 16.
constexpr std::uint32_t usage(std::uint16_t page, std::uint16_t id) {
  return (std::uint32_t{page} << 16) | id;
}
inline constexpr std::uint32_t kUsageX = usage(kPageGenericDesktop, 0x30);
inline constexpr std::uint32_t kUsageY = usage(kPageGenericDesktop, 0x31);
inline constexpr std::uint32_t kUsageZ = usage(kPageGenericDesktop, 0x32);
inline constexpr std::uint32_t kUsageRx = usage(kPageGenericDesktop, 0x33);
inline constexpr std::uint32_t kUsageRy = usage(kPageGenericDesktop, 0x34);
inline constexpr std::uint32_t kUsageRz = usage(kPageGenericDesktop, 0x35);
inline constexpr std::uint32_t kUsageFlexor = usage(kPageVrControls, 0x03);
inline constexpr std::uint32_t kUsageGlove = usage(kPageVrControls, 0x04);
inline constexpr std::uint32_t kUsageHeadTracker = usage(kPageVrControls, 0x05);
inline constexpr std::uint32_t kUsageHeadMountedDisplay = usage(kPageVrControls, 0x06);
inline constexpr std::uint32_t kUsageHandTracker = usage(kPageVrControls, 0x07);
inline constexpr std::uint32_t kUsageHapticIntensity = usage(kPageHaptics, 0x23);
inline constexpr std::uint32_t kUsagePidSetConstantForce = usage(kPagePid, 0x73);
inline constexpr std::uint32_t kUsagePidMagnitude = usage(kPagePid, 0x70);
inline constexpr std::uint32_t kUsagePidEffectBlockIndex = usage(kPagePid, 0x22);
inline constexpr std::uint32_t kUsageOrientationQuaternion = usage(kPageSensors, 0x0483);

enum class ReportType : std::uint8_t { Input, Output, Feature };
const char* to_string(ReportType type);

// A HID unit (the Unit item's nibbles) with its exponent.
struct Unit {
  std::uint32_t code = 0;
  std::int8_t exponent = 0;

  enum class Quantity : std::uint8_t { None, Length, Rotation, Force, Time, Other };
  Quantity quantity() const;
  // Factor from the field's physical units to SI (metres, radians, newtons, seconds): includes
  // 10^exponent and the unit system (cm, inch, degree, dyne...). 1 for no unit.
  double to_si() const;
};

enum class CollectionType : std::uint8_t {
  Physical = 0,
  Application = 1,
  Logical = 2,
  Report = 3,
  NamedArray = 4,
  UsageSwitch = 5,
  UsageModifier = 6
};

struct Collection {
  std::uint8_t type = 0;    // CollectionType, or a vendor value (0x80-0xFF)
  std::uint32_t usage = 0;  // extended usage
  int parent = -1;          // index in ReportDescriptor::collections, -1 at top level
};

// One main item (Input, Output, Feature): count elements of size bits each.
struct Field {
  ReportType type = ReportType::Input;
  std::uint8_t report_id = 0;    // 0 when the descriptor uses no report ids
  std::uint32_t bit_offset = 0;  // from the start of the report data (after the id byte)
  std::uint32_t bit_size = 0;
  std::uint32_t count = 0;
  std::uint32_t flags = 0;  // the main item's data bits
  // Variable fields: usages[i] for element i (the last one repeats). Array fields: the usages an
  // element's value selects (value - logical_min indexes this list).
  std::vector<std::uint32_t> usages;
  std::int32_t logical_min = 0, logical_max = 0;
  std::int32_t physical_min = 0, physical_max = 0;  // equal to logical when the item gave none
  Unit unit;
  int collection = -1;  // innermost enclosing collection

  bool is_constant() const { return flags & 0x01; }
  bool is_variable() const { return flags & 0x02; }
  bool is_relative() const { return flags & 0x04; }
  bool is_signed() const { return logical_min < 0; }
  std::uint32_t usage_of(std::uint32_t element) const;
  // Logical value -> SI value (physical range, unit, exponent).
  double to_si(std::int32_t logical) const;
  // SI value -> nearest logical value, clamped to the logical range.
  std::int32_t from_si(double si) const;
};

struct ReportInfo {
  ReportType type = ReportType::Input;
  std::uint8_t id = 0;
  std::uint32_t bits = 0;     // data bits (without the id byte)
  std::size_t bytes() const;  // on the wire, with the id byte when the descriptor uses ids
  bool with_id = false;
};

// A data field wider than 32 bits: counted in its report's size, its values not read.
struct WideField {
  ReportType type = ReportType::Input;
  std::uint8_t report_id = 0;
  std::uint32_t bit_offset = 0;
  std::uint32_t bit_size = 0;
  std::uint32_t count = 0;
  std::uint32_t usage = 0;  // the first usage given, 0 when none
};

struct ReportDescriptor {
  std::vector<Field> fields;
  std::vector<Collection> collections;
  std::vector<ReportInfo> reports;
  std::vector<WideField> wide_fields;
  bool uses_report_ids = false;
  // What real firmware does that the specification frowns on, accepted: "byte N: item: what".
  std::vector<std::string> warnings;

  const ReportInfo* find_report(ReportType type, std::uint8_t id) const;
  // The top-level application collection's usage (the first one), 0 when none.
  std::uint32_t application_usage() const;
  // Whether collection `index` or one of its parents has this usage.
  bool within(int collection, std::uint32_t usage) const;
};

// Parses a report descriptor. `device` names the device in error messages. Throws ProtocolError
// (device, byte offset of the offending item, "Item Name: reason") on a malformed descriptor.
// Report Size 0 and fields wider than 32 bits occur in shipping firmware: they parse, with a
// warning (zero-size items take no bits; wide fields count in their report's size, unread).
ReportDescriptor parse_report_descriptor(std::span<const std::uint8_t> bytes,
                                         const std::string& device = "HID descriptor");

}  // namespace bisturi::devices::hid
