#include "bisturi/devices/hid_descriptor.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace bisturi::devices::hid {

namespace {

// Limits that keep a hostile descriptor from asking for absurd allocations.
constexpr std::uint32_t kMaxReportBits = 8 * 4096;
constexpr std::uint32_t kMaxFieldBits = 32;
constexpr std::size_t kMaxFields = 4096;
constexpr std::size_t kMaxCollections = 1024;
// Linux's limits (include/linux/hid.h): HID_MAX_USAGES usages per main item, and a Push stack
// of HID_GLOBAL_STACK_SIZE.
constexpr std::size_t kMaxUsages = 12288;
constexpr std::size_t kMaxStackDepth = 4;
constexpr std::size_t kMaxReports = 256 * 3;

struct Globals {
  std::uint16_t usage_page = 0;
  std::int32_t logical_min = 0;
  std::uint32_t logical_max_raw = 0;
  std::uint8_t logical_max_size = 0;
  std::int32_t physical_min = 0;
  std::uint32_t physical_max_raw = 0;
  std::uint8_t physical_max_size = 0;
  bool physical_set = false;
  std::int8_t unit_exponent = 0;
  std::uint32_t unit = 0;
  std::uint32_t report_size = 0;
  bool report_size_set = false;
  std::uint32_t report_count = 0;
  std::uint8_t report_id = 0;
};

struct Locals {
  std::vector<std::uint32_t> usages;
  bool have_min = false, have_max = false;
  std::uint32_t usage_min = 0, usage_max = 0;
  bool min_extended = false, max_extended = false;
  // Delimiters: alternative usage sets; as Linux does, only the first set is read.
  int delimiter_depth = 0;
  int delimiter_branch = 0;
  [[nodiscard]] bool alternative() const { return delimiter_branch > 1; }
};

std::int32_t sign_extend(std::uint32_t value, std::uint8_t size) {
  switch (size) {
    case 1:
      return static_cast<std::int8_t>(value);
    case 2:
      return static_cast<std::int16_t>(value);
    default:
      return static_cast<std::int32_t>(value);
  }
}

// A maximum is signed when the minimum is negative, unsigned otherwise (HID 1.11 6.2.2.7).
std::int64_t interpret_max(std::int32_t min, std::uint32_t raw, std::uint8_t size) {
  if (min < 0) return sign_extend(raw, size);
  return raw;
}

// The item's name as the HID specification (6.2.2.4-6.2.2.8) gives it.
std::string item_name(std::uint8_t type, std::uint8_t tag) {
  static const char* const kMain[16] = {
      nullptr, nullptr,  nullptr,      nullptr,   nullptr,          nullptr, nullptr, nullptr,
      "Input", "Output", "Collection", "Feature", "End Collection", nullptr, nullptr, nullptr};
  static const char* const kGlobal[16] = {"Usage Page",
                                          "Logical Minimum",
                                          "Logical Maximum",
                                          "Physical Minimum",
                                          "Physical Maximum",
                                          "Unit Exponent",
                                          "Unit",
                                          "Report Size",
                                          "Report ID",
                                          "Report Count",
                                          "Push",
                                          "Pop",
                                          nullptr,
                                          nullptr,
                                          nullptr,
                                          nullptr};
  static const char* const kLocal[16] = {"Usage",
                                         "Usage Minimum",
                                         "Usage Maximum",
                                         "Designator Index",
                                         "Designator Minimum",
                                         "Designator Maximum",
                                         nullptr,
                                         "String Index",
                                         "String Minimum",
                                         "String Maximum",
                                         "Delimiter",
                                         nullptr,
                                         nullptr,
                                         nullptr,
                                         nullptr,
                                         nullptr};
  const char* const* table = type == 0 ? kMain : type == 1 ? kGlobal : type == 2 ? kLocal : nullptr;
  if (table && table[tag]) return table[tag];
  static const char* const kTypes[4] = {"main", "global", "local", "reserved"};
  return std::string(kTypes[type & 3]) + " item tag " + std::to_string(tag);
}

class Parser {
 public:
  Parser(std::span<const std::uint8_t> bytes, const std::string& device)
      : bytes_(bytes), device_(device) {}

  ReportDescriptor run() {
    std::size_t pos = 0;
    while (pos < bytes_.size()) {
      item_offset_ = pos;
      const std::uint8_t prefix = bytes_[pos];
      if (prefix == 0xFE) {  // long item: skipped (none are defined)
        if (pos + 3 > bytes_.size()) fail("truncated long item");
        const std::size_t size = bytes_[pos + 1];
        if (pos + 3 + size > bytes_.size()) fail("long item runs past the end");
        pos += 3 + size;
        continue;
      }
      static constexpr std::uint8_t kSizes[4] = {0, 1, 2, 4};
      const std::uint8_t size = kSizes[prefix & 0x03];
      const std::uint8_t type = (prefix >> 2) & 0x03;
      const std::uint8_t tag = prefix >> 4;
      item_name_ = item_name(type, tag);
      if (pos + 1 + size > bytes_.size()) {
        fail("item needs " + std::to_string(size) + " data bytes, " +
             std::to_string(bytes_.size() - pos - 1) + " left");
      }
      std::uint32_t data = 0;
      for (std::uint8_t i = 0; i < size; ++i)
        data |= std::uint32_t{bytes_[pos + 1 + i]} << (8 * i);
      pos += 1 + size;
      switch (type) {
        case 0:
          main_item(tag, data, size);
          break;
        case 1:
          global_item(tag, data, size);
          break;
        case 2:
          local_item(tag, data, size);
          break;
        default:
          fail("reserved item type 3");
      }
    }
    item_offset_ = bytes_.size();
    item_name_ = "end of descriptor";
    if (!open_.empty()) fail(std::to_string(open_.size()) + " collection(s) not closed");
    if (l_.delimiter_depth != 0) fail("a delimiter still open");
    // Linux takes a descriptor that describes no report (a vendor interface, a collection kept
    // for a later firmware): there is simply nothing to read or write.
    if (out_.fields.empty() && out_.wide_fields.empty())
      warn("no input, output or feature fields: the device describes no report to read or write");
    return std::move(out_);
  }

 private:
  [[noreturn]] void fail(const std::string& reason) const {
    throw ProtocolError(device_, item_offset_,
                        item_name_.empty() ? reason : item_name_ + ": " + reason);
  }
  void warn(const std::string& reason) {
    out_.warnings.push_back("byte " + std::to_string(item_offset_) + ": " + item_name_ + ": " +
                            reason);
  }

  std::uint32_t extend_usage(std::uint32_t data, std::uint8_t size) const {
    return size == 4 ? data : usage(g_.usage_page, static_cast<std::uint16_t>(data));
  }

  void global_item(std::uint8_t tag, std::uint32_t data, std::uint8_t size) {
    switch (tag) {
      case 0:
        if (data > 0xFFFF) fail("usage page above 0xFFFF");
        g_.usage_page = static_cast<std::uint16_t>(data);
        break;
      case 1:
        g_.logical_min = sign_extend(data, size);
        break;
      case 2:
        g_.logical_max_raw = data;
        g_.logical_max_size = size;
        break;
      case 3:
        g_.physical_min = sign_extend(data, size);
        g_.physical_set = true;
        break;
      case 4:
        g_.physical_max_raw = data;
        g_.physical_max_size = size;
        g_.physical_set = true;
        break;
      case 5: {
        const std::uint32_t nibble = data & 0x0F;
        g_.unit_exponent = static_cast<std::int8_t>(nibble >= 8 ? static_cast<int>(nibble) - 16
                                                                : static_cast<int>(nibble));
        break;
      }
      case 6:
        g_.unit = data;
        break;
      case 7:
        if (data > kMaxReportBits) fail("report size " + std::to_string(data));
        // Shipping firmware declares zero-size fields: they take no bits.
        if (data == 0) warn("report size 0: the main items that follow take no bits");
        g_.report_size = data;
        g_.report_size_set = true;
        break;
      case 8:
        if (data == 0 || data > 0xFF) fail("report id " + std::to_string(data) + " (1-255)");
        if (!out_.fields.empty() && !out_.uses_report_ids) {
          // Linux reads it: the fields before stay report 0, without an ID byte.
          warn("report id " + std::to_string(data) +
               " after main items that had none: those stay report 0, without an ID byte");
        }
        out_.uses_report_ids = true;
        g_.report_id = static_cast<std::uint8_t>(data);
        break;
      case 9:
        if (data > kMaxReportBits) fail("report count " + std::to_string(data));
        g_.report_count = data;
        break;
      case 10:
        if (stack_.size() >= kMaxStackDepth)
          fail("push: global stack deeper than 4 (Linux's limit)");
        stack_.push_back(g_);
        break;
      case 11:
        if (stack_.empty()) fail("pop without push");
        g_ = stack_.back();
        stack_.pop_back();
        break;
      default:
        fail("reserved global item tag " + std::to_string(tag));
    }
  }

  void local_item(std::uint8_t tag, std::uint32_t data, std::uint8_t size) {
    switch (tag) {
      case 0:
        if (l_.alternative()) break;
        if (l_.usages.size() >= kMaxUsages) fail("too many usages");
        l_.usages.push_back(extend_usage(data, size));
        break;
      case 1:
        if (l_.alternative()) break;
        l_.have_min = true;
        l_.usage_min = data;
        l_.min_extended = size == 4;
        break;
      case 2:
        if (l_.alternative()) break;
        l_.have_max = true;
        l_.usage_max = data;
        l_.max_extended = size == 4;
        break;
      case 3:
      case 4:
      case 5:
      case 7:
      case 8:
      case 9:  // designators, strings: not used
        break;
      case 10:  // delimiter: alternative usage sets; the first is kept
        if (data != 0) {
          if (l_.delimiter_depth != 0) fail("a delimiter opened inside an open delimiter");
          ++l_.delimiter_depth;
          ++l_.delimiter_branch;
        } else {
          if (l_.delimiter_depth < 1) fail("a delimiter closed that was not open");
          --l_.delimiter_depth;
        }
        break;
      default:
        fail("reserved local item tag " + std::to_string(tag));
    }
  }

  void main_item(std::uint8_t tag, std::uint32_t data, std::uint8_t size) {
    (void)size;
    switch (tag) {
      case 8:
        add_field(ReportType::Input, data);
        break;
      case 9:
        add_field(ReportType::Output, data);
        break;
      case 11:
        add_field(ReportType::Feature, data);
        break;
      case 10: {
        if (out_.collections.size() >= kMaxCollections) fail("too many collections");
        if (open_.size() >= kMaxCollections) fail("collections nested too deep");
        Collection collection;
        collection.type = static_cast<std::uint8_t>(data & 0xFF);
        collection.usage = l_.usages.empty() ? 0 : l_.usages.front();
        if (l_.usages.empty() && l_.have_min) {
          collection.usage = l_.min_extended
                                 ? l_.usage_min
                                 : usage(g_.usage_page, static_cast<std::uint16_t>(l_.usage_min));
        }
        collection.parent = open_.empty() ? -1 : open_.back();
        out_.collections.push_back(collection);
        open_.push_back(static_cast<int>(out_.collections.size() - 1));
        break;
      }
      case 12:
        if (open_.empty()) fail("end collection without a collection");
        open_.pop_back();
        break;
      default:
        fail("reserved main item tag " + std::to_string(tag));
    }
    l_ = Locals{};
  }

  void add_field(ReportType type, std::uint32_t flags) {
    if (!g_.report_size_set) {
      // The global state starts at zero: Linux reads such an item as zero-size fields.
      warn("before any report size: its fields take no bits");
      g_.report_size_set = true;
    }
    const std::uint64_t bits = std::uint64_t{g_.report_size} * g_.report_count;
    ReportInfo* report = nullptr;
    for (auto& info : out_.reports) {
      if (info.type == type && info.id == g_.report_id) report = &info;
    }
    if (!report) {
      if (out_.reports.size() >= kMaxReports) fail("too many reports");
      out_.reports.push_back(ReportInfo{type, g_.report_id, 0, out_.uses_report_ids});
      report = &out_.reports.back();
    }
    if (report->bits + bits > kMaxReportBits) {
      fail(std::string(to_string(type)) + " report " + std::to_string(g_.report_id) +
           " longer than 4096 bytes");
    }
    const std::uint32_t offset = report->bits;
    report->bits += static_cast<std::uint32_t>(bits);
    const bool constant = flags & 0x01;
    if (g_.report_count == 0 || g_.report_size == 0) return;
    if (constant) return;  // padding: counted in the report length, no field
    if (g_.report_size > kMaxFieldBits) {
      // Counted in the report's length (so the report's size stays right), but not read.
      warn(std::to_string(g_.report_count) + " field(s) of " + std::to_string(g_.report_size) +
           " bits at bit " + std::to_string(offset) + " of " + to_string(type) + " report " +
           std::to_string(g_.report_id) + ": wider than 32 bits, not read");
      out_.wide_fields.push_back(WideField{type, g_.report_id, offset, g_.report_size,
                                           g_.report_count,
                                           l_.usages.empty() ? 0 : l_.usages.front()});
      return;
    }
    if (out_.fields.size() >= kMaxFields) fail("too many fields");

    Field field;
    field.type = type;
    field.report_id = g_.report_id;
    field.bit_offset = offset;
    field.bit_size = g_.report_size;
    field.count = g_.report_count;
    field.flags = flags;
    field.logical_min = g_.logical_min;
    const std::int64_t logical_max =
        interpret_max(g_.logical_min, g_.logical_max_raw, g_.logical_max_size);
    if (logical_max < g_.logical_min) {
      fail("logical maximum " + std::to_string(logical_max) + " below minimum " +
           std::to_string(g_.logical_min));
    }
    if (logical_max > INT32_MAX) {
      // An unsigned 32-bit range (0..0xFFFFFFFF), which Linux takes: values read up to 2^31-1.
      warn("logical maximum " + std::to_string(logical_max) +
           " above 2^31-1: read as 2^31-1, larger values saturate");
    }
    field.logical_max = static_cast<std::int32_t>(std::min<std::int64_t>(logical_max, INT32_MAX));
    const std::int64_t physical_max =
        interpret_max(g_.physical_min, g_.physical_max_raw, g_.physical_max_size);
    if (!g_.physical_set || (g_.physical_min == 0 && physical_max == 0)) {
      field.physical_min = field.logical_min;
      field.physical_max = field.logical_max;
    } else {
      if (physical_max > INT32_MAX)
        warn("physical maximum " + std::to_string(physical_max) + " above 2^31-1: read as 2^31-1");
      field.physical_min = g_.physical_min;
      field.physical_max =
          static_cast<std::int32_t>(std::min<std::int64_t>(physical_max, INT32_MAX));
    }
    field.unit = Unit{g_.unit, g_.unit_exponent};
    field.collection = open_.empty() ? -1 : open_.back();

    field.usages = l_.usages;
    if (l_.have_min || l_.have_max) {
      if (!(l_.have_min && l_.have_max)) fail("usage minimum without maximum");
      std::uint32_t lo = l_.min_extended
                             ? l_.usage_min
                             : usage(g_.usage_page, static_cast<std::uint16_t>(l_.usage_min));
      std::uint32_t hi = l_.max_extended
                             ? l_.usage_max
                             : usage(g_.usage_page, static_cast<std::uint16_t>(l_.usage_max));
      if (hi < lo) fail("usage maximum below minimum");
      std::uint64_t span = std::uint64_t{hi} - lo + 1;
      if (field.usages.size() >= kMaxUsages)
        fail("no usage left for its range (Linux keeps 12288)");
      if (field.usages.size() + span > kMaxUsages) {
        // As Linux does ("ignoring exceeding usage max"): the range is cut where the item's
        // usages reach its limit.
        const std::uint64_t kept = kMaxUsages - field.usages.size();
        warn("usage range of " + std::to_string(span) + " usages: the first " +
             std::to_string(kept) + " kept (Linux keeps 12288 per main item)");
        span = kept;
        hi = static_cast<std::uint32_t>(lo + span - 1);
      }
      for (std::uint64_t u = lo; u <= hi; ++u)
        field.usages.push_back(static_cast<std::uint32_t>(u));
    }
    out_.fields.push_back(std::move(field));
  }

  std::span<const std::uint8_t> bytes_;
  const std::string& device_;
  std::size_t item_offset_ = 0;
  std::string item_name_;
  Globals g_;
  Locals l_;
  std::vector<Globals> stack_;
  std::vector<int> open_;
  ReportDescriptor out_;
};

// Nibble i (0: system, 1: length, 2: mass, 3: time, ...) as a signed power.
int unit_power(std::uint32_t code, int nibble) {
  const int value = static_cast<int>((code >> (4 * nibble)) & 0x0F);
  return value >= 8 ? value - 16 : value;
}

}  // namespace

const char* to_string(ReportType type) {
  switch (type) {
    case ReportType::Input:
      return "input";
    case ReportType::Output:
      return "output";
    case ReportType::Feature:
      return "feature";
  }
  return "unknown";
}

Unit::Quantity Unit::quantity() const {
  if (code == 0) return Quantity::None;
  const int system = static_cast<int>(code & 0x0F);
  const int length = unit_power(code, 1), mass = unit_power(code, 2), time = unit_power(code, 3);
  const bool only_lmt = (code >> 16) == 0;
  if (!only_lmt || system == 0) return Quantity::Other;
  const bool rotation_system = system == 2 || system == 4;
  if (length == 1 && mass == 0 && time == 0) {
    return rotation_system ? Quantity::Rotation : Quantity::Length;
  }
  if (!rotation_system && length == 1 && mass == 1 && time == -2) return Quantity::Force;
  if (length == 0 && mass == 0 && time == 1) return Quantity::Time;
  return Quantity::Other;
}

double Unit::to_si() const {
  if (code == 0) return 1.0;
  const int system = static_cast<int>(code & 0x0F);
  double length = 1.0, mass = 1.0;
  switch (system) {
    case 1:  // SI linear: cm, g
      length = 0.01;
      mass = 0.001;
      break;
    case 2:  // SI rotation: rad, g
      mass = 0.001;
      break;
    case 3:  // English linear: inch, slug
      length = 0.0254;
      mass = 14.593903;
      break;
    case 4:  // English rotation: degree, slug
      length = std::numbers::pi / 180.0;
      mass = 14.593903;
      break;
    default:
      break;
  }
  return std::pow(length, unit_power(code, 1)) * std::pow(mass, unit_power(code, 2)) *
         std::pow(10.0, exponent);
}

std::uint32_t Field::usage_of(std::uint32_t element) const {
  if (usages.empty()) return 0;
  return usages[std::min<std::size_t>(element, usages.size() - 1)];
}

double Field::to_si(std::int32_t logical) const {
  double physical = logical;
  if (logical_max != logical_min && (physical_min != logical_min || physical_max != logical_max)) {
    physical = physical_min + (static_cast<double>(logical) - logical_min) *
                                  (static_cast<double>(physical_max) - physical_min) /
                                  (static_cast<double>(logical_max) - logical_min);
  }
  return physical * unit.to_si();
}

std::int32_t Field::from_si(double si) const {
  if (!std::isfinite(si)) return logical_min <= 0 && logical_max >= 0 ? 0 : logical_min;
  const double physical = si / unit.to_si();
  double logical = physical;
  if (physical_max != physical_min &&
      (physical_min != logical_min || physical_max != logical_max)) {
    logical = logical_min + (physical - physical_min) *
                                (static_cast<double>(logical_max) - logical_min) /
                                (static_cast<double>(physical_max) - physical_min);
  }
  logical = std::clamp(std::round(logical), static_cast<double>(logical_min),
                       static_cast<double>(logical_max));
  return static_cast<std::int32_t>(logical);
}

std::size_t ReportInfo::bytes() const {
  return (with_id ? 1u : 0u) + (bits + 7) / 8;
}

const ReportInfo* ReportDescriptor::find_report(ReportType type, std::uint8_t id) const {
  for (const auto& report : reports) {
    if (report.type == type && report.id == id) return &report;
  }
  return nullptr;
}

std::uint32_t ReportDescriptor::application_usage() const {
  for (const auto& collection : collections) {
    if (collection.parent < 0 && collection.type == 1) return collection.usage;
  }
  return 0;
}

bool ReportDescriptor::within(int collection, std::uint32_t wanted) const {
  for (int depth = 0; collection >= 0 && depth < 1024; ++depth) {
    const auto& c = collections[static_cast<std::size_t>(collection)];
    if (c.usage == wanted) return true;
    collection = c.parent;
  }
  return false;
}

ReportDescriptor parse_report_descriptor(std::span<const std::uint8_t> bytes,
                                         const std::string& device) {
  return Parser(bytes, device).run();
}

}  // namespace bisturi::devices::hid
