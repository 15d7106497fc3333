// Report descriptors of shipping devices (tests/data/hid, sources in its README) parse, with the
// report sizes computed by hand from the HID specification; the quirks of real firmware (Report
// Size 0, fields wider than 32 bits) parse with a warning; none of them is taken for a glove.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "bisturi/devices/hid_descriptor.h"
#include "bisturi/devices/hid_drivers.h"

namespace hid = bisturi::devices::hid;

namespace {

std::vector<std::uint8_t> load(const std::string& name) {
  std::ifstream in(std::string(BISTURI_HID_DATA) + "/" + name, std::ios::binary);
  EXPECT_TRUE(in) << name;
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

struct Expected {
  hid::ReportType type;
  std::uint8_t id;
  std::uint32_t bits;
  std::size_t bytes;
};

void expect_reports(const std::string& file, std::size_t descriptor_bytes, std::size_t reports,
                    const std::vector<Expected>& expected) {
  const auto bytes = load(file);
  ASSERT_EQ(bytes.size(), descriptor_bytes) << file;
  const hid::ReportDescriptor d = hid::parse_report_descriptor(bytes, file);
  EXPECT_EQ(d.reports.size(), reports) << file;
  for (const Expected& e : expected) {
    const hid::ReportInfo* r = d.find_report(e.type, e.id);
    ASSERT_NE(r, nullptr) << file << ": " << hid::to_string(e.type) << " report " << int{e.id};
    EXPECT_EQ(r->bits, e.bits) << file << ": " << hid::to_string(e.type) << " " << int{e.id};
    EXPECT_EQ(r->bytes(), e.bytes) << file << ": " << hid::to_string(e.type) << " " << int{e.id};
  }
  const auto fit = bisturi::devices::assess_generic_hid(bytes);
  EXPECT_FALSE(fit.glove) << file;
  EXPECT_NE(fit.glove_why.find("not VR Controls:Glove"), std::string::npos) << fit.glove_why;
}

constexpr auto kIn = hid::ReportType::Input;
constexpr auto kOut = hid::ReportType::Output;
constexpr auto kFeature = hid::ReportType::Feature;

}  // namespace

TEST(HidDescriptorFiles, BootMouseAndKeyboardFromTheSpecification) {
  expect_reports("hid_boot_mouse.bin", 50, 1, {{kIn, 0, 24, 3}});
  expect_reports("hid_boot_keyboard.bin", 63, 2, {{kIn, 0, 64, 8}, {kOut, 0, 8, 1}});
}

TEST(HidDescriptorFiles, SonySixaxis) {
  expect_reports("sony_sixaxis_ds3_usb.bin", 148, 4,
                 {{kIn, 1, 384, 49},
                  {kFeature, 2, 384, 49},
                  {kFeature, 0xEE, 384, 49},
                  {kFeature, 0xEF, 384, 49}});
}

TEST(HidDescriptorFiles, SonyDualShock4) {
  expect_reports("sony_dualshock4_v2_usb.bin", 507, 50,
                 {{kIn, 1, 504, 64},
                  {kOut, 5, 248, 32},
                  {kFeature, 2, 288, 37},
                  {kFeature, 4, 288, 37},
                  {kFeature, 0x12, 120, 16},
                  {kFeature, 0xA3, 384, 49},
                  {kFeature, 0xF0, 504, 64}});
}

TEST(HidDescriptorFiles, WideAndZeroSizeFieldsParseWithWarnings) {
  const auto bytes = load("constructed_wide_and_zero_size.bin");
  const hid::ReportDescriptor d = hid::parse_report_descriptor(bytes, "sensor");
  ASSERT_EQ(d.reports.size(), 1u);
  EXPECT_EQ(d.reports[0].bits, 112u);
  EXPECT_EQ(d.reports[0].bytes(), 15u);
  ASSERT_EQ(d.warnings.size(), 2u);
  ASSERT_EQ(d.wide_fields.size(), 1u);
  EXPECT_EQ(d.wide_fields[0].bit_size, 64u);
  ASSERT_EQ(d.fields.size(), 1u);  // the acceleration, after the 64-bit timestamp
  EXPECT_EQ(d.fields[0].bit_offset, 64u);
}

TEST(HidDescriptorFiles, ATruncatedShippingDescriptorNamesTheByteAndTheItem) {
  auto bytes = load("sony_dualshock4_v2_usb.bin");
  bytes.resize(20);  // inside Logical Maximum (0x26 0xFF 0x00) at byte 18
  try {
    (void)hid::parse_report_descriptor(bytes, "ds4");
    ADD_FAILURE() << "a truncated descriptor parsed";
  } catch (const bisturi::devices::ProtocolError& e) {
    EXPECT_EQ(e.offset(), 18u);
    EXPECT_NE(std::string(e.what()).find("Logical Maximum"), std::string::npos) << e.what();
  }
}

namespace {

struct CorpusEntry {
  std::string name;
  std::vector<std::uint8_t> bytes;
  std::vector<std::pair<std::string, std::uint32_t>> bits;  // "input 1" -> bits with the id byte
};

std::vector<CorpusEntry> load_corpus(const std::string& file) {
  std::ifstream in(std::string(BISTURI_HID_DATA) + "/" + file);
  EXPECT_TRUE(in) << file;
  std::vector<CorpusEntry> out;
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("name: ", 0) == 0) {
      out.push_back({line.substr(6), {}, {}});
    } else if (line.rfind("rdesc: ", 0) == 0 && !out.empty()) {
      std::istringstream hex(line.substr(7));
      unsigned byte = 0;
      while (hex >> std::hex >> byte)
        out.back().bytes.push_back(static_cast<std::uint8_t>(byte));
    } else if (line.rfind("bits: ", 0) == 0 && !out.empty()) {
      std::istringstream list(line.substr(6));
      std::string type, id_bits;
      unsigned id = 0, bits = 0;
      char comma = 0;
      while (list >> type >> id >> bits) {
        out.back().bits.emplace_back(type + " " + std::to_string(id), bits);
        list >> comma;
      }
    }
  }
  return out;
}

/// Every report of every descriptor the same size as the independent parser gives it, and no
/// report here that it does not have; the reports compared.
std::size_t expect_the_same_reports(const std::vector<CorpusEntry>& corpus) {
  std::size_t reports = 0;
  for (const CorpusEntry& e : corpus) {
    hid::ReportDescriptor d;
    try {
      d = hid::parse_report_descriptor(e.bytes, e.name);
    } catch (const std::exception& error) {
      ADD_FAILURE() << e.name << ": refused: " << error.what();
      continue;
    }
    std::vector<std::pair<std::string, std::uint32_t>> ours;
    for (const hid::ReportInfo& r : d.reports) {
      const std::string type = r.type == kIn ? "input" : r.type == kOut ? "output" : "feature";
      ours.emplace_back(type + " " + std::to_string(r.id), r.bits + (r.with_id ? 8u : 0u));
    }
    std::sort(ours.begin(), ours.end());
    std::vector<std::pair<std::string, std::uint32_t>> theirs = e.bits;
    std::sort(theirs.begin(), theirs.end());
    EXPECT_EQ(ours, theirs) << e.name;
    reports += ours.size();
  }
  return reports;
}

}  // namespace

TEST(HidDescriptorFiles, ShippingMultitouchDescriptorsMatchAnIndependentParser) {
  // 82 descriptors dumped from shipping touch screens and touchpads (hid-tools' test data), with
  // the report sizes hid-tools' own parser computes.
  const std::vector<CorpusEntry> corpus = load_corpus("hid_tools_multitouch.txt");
  ASSERT_EQ(corpus.size(), 82u);
  RecordProperty("reports", static_cast<int>(expect_the_same_reports(corpus)));
}

TEST(HidDescriptorFiles, TheKernelSelftestsDescriptorsMatchAnIndependentParser) {
  // 36 from the Linux kernel's HID selftests: pen tablets and laptop pen digitisers, keyboards,
  // mice, gamepads, and the kernel's constructed cases (a collection stack 21 deep that hid-core
  // must grow), again against hid-tools' parser.
  const std::vector<CorpusEntry> corpus = load_corpus("hid_tools_kernel_tests.txt");
  ASSERT_EQ(corpus.size(), 36u);
  RecordProperty("reports", static_cast<int>(expect_the_same_reports(corpus)));
}
