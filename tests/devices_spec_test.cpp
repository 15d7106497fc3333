// What the drivers state about the hardware (DeviceSpec, with units), and the checks on the
// checks: the vendor arm's CRC against values computed outside this code base.
#include <gtest/gtest.h>

#include <array>
#include <string>

#include "bisturi/devices/hid_drivers.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/devices/vendor_arm.h"
#include "bisturi/devices/virtual_transport.h"

namespace bd = bisturi::devices;
namespace ap = bisturi::devices::arm_protocol;
using namespace std::chrono_literals;

namespace {

template <typename Twin>
std::unique_ptr<bd::Device> open_on(Twin& twin, bd::Clock& clock) {
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  return bd::builtin_registry().open(std::move(pair.host), clock);
}

std::vector<std::uint8_t> ascii(const std::string& text) {
  return {text.begin(), text.end()};
}

}  // namespace

// Expected values from Python's binascii.crc_hqx(data, 0xFFFF) (CRC-CCITT, polynomial 0x1021,
// not reflected, no final xor: CRC-16/CCITT-FALSE), an implementation independent of ours; the
// first is the catalogue's check value for the parameter set (Greg Cook's CRC catalogue).
TEST(VendorArmCrc, KnownAnswers) {
  EXPECT_EQ(ap::crc16(ascii("123456789")), 0x29B1);
  EXPECT_EQ(ap::crc16({}), 0xFFFF);  // the initial value, nothing fed
  EXPECT_EQ(ap::crc16(ascii("A")), 0xB915);
  const std::array<std::uint8_t, 30> zeros{};
  EXPECT_EQ(ap::crc16(zeros), 0x2A45);
  // A GET_INFO packet as the driver sends it: type 0x11, then 29 zeros; CRC low byte first.
  ap::Packet get_info{};
  get_info[0] = ap::kGetInfo;
  ap::seal(get_info);
  EXPECT_EQ(get_info[30], 0xAA);
  EXPECT_EQ(get_info[31], 0xB2);
}

TEST(DeviceSpec, TheArmStatesItsDatasheetFromTheInfoPacket) {
  bd::SimulatedArm twin{bd::DeviceScript{}};
  bd::VirtualClock clock;
  auto device = open_on(twin, clock);
  const bd::DeviceSpec& spec = device->capabilities().spec;
  EXPECT_DOUBLE_EQ(spec.max_stiffness_N_per_m, 2000.0);
  EXPECT_NEAR(spec.workspace_min_m.x, -0.080, 1e-12);
  EXPECT_NEAR(spec.workspace_min_m.y, -0.060, 1e-12);
  EXPECT_NEAR(spec.workspace_min_m.z, -0.050, 1e-12);
  EXPECT_NEAR(spec.workspace_max_m.x, 0.080, 1e-12);
  EXPECT_NEAR(spec.workspace_max_m.y, 0.060, 1e-12);
  EXPECT_NEAR(spec.workspace_max_m.z, 0.070, 1e-12);
}

TEST(DeviceSpec, AnArmThatDoesNotSayGivesZerosAndABadBoxIsRefused) {
  bd::SimulatedArm twin{bd::DeviceScript{}};
  bd::VirtualClock clock;
  auto device = open_on(twin, clock);
  // An info packet from older firmware: bytes 7-20 are zero.
  ap::Packet info{};
  info[0] = ap::kInfo;
  info[1] = ap::kVersion;
  info[2] = 0x20;  // 800 cN
  info[3] = 0x03;
  info[4] = 100;  // 100 N/s
  ap::seal(info);
  device->handle_report(info);
  EXPECT_EQ(device->capabilities().spec.max_stiffness_N_per_m, 0.0);
  EXPECT_EQ(device->capabilities().spec.workspace_max_m, bd::Vec3{});
  // y minimum +10 mm above a y maximum of -10 mm.
  info[11] = 10;
  info[17] = 0xF6;
  info[18] = 0xFF;
  ap::seal(info);
  try {
    device->handle_report(info);
    ADD_FAILURE() << "an inverted workspace was accepted";
  } catch (const bd::ProtocolError& e) {
    EXPECT_EQ(e.offset(), 11u);
  }
}

TEST(DeviceSpec, HidDevicesStateTheBoxTheirPositionFieldsReport) {
  bd::VirtualClock clock;
  bd::SimulatedGlove glove{bd::DeviceScript{}};
  auto g = open_on(glove, clock);
  // The glove's X/Y/Z: logical -32767..32767 over physical -100..100 cm.
  EXPECT_NEAR(g->capabilities().spec.workspace_min_m.x, -1.0, 1e-12);
  EXPECT_NEAR(g->capabilities().spec.workspace_max_m.z, 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(g->capabilities().spec.max_stiffness_N_per_m,
                   bd::HidGloveOptions{}.max_stiffness_N_per_m);
  bd::SimulatedHeadTracker head{bd::DeviceScript{}};
  auto h = open_on(head, clock);
  EXPECT_EQ(h->capabilities().spec.max_stiffness_N_per_m, 0.0);  // renders no force
  EXPECT_GT(h->capabilities().spec.workspace_max_m.y, 1.0);      // reaches head height
  EXPECT_LT(h->capabilities().spec.workspace_min_m.y, -1.0);
}
