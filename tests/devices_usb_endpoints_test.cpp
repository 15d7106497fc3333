// Which interface and endpoints of a raw USB device a driver talks to (choose_usb_endpoints):
// the driver's declared ones, or the first vendor-specific interface with interrupt IN and OUT.

#include <gtest/gtest.h>

#include <vector>

#include "bisturi/devices/host_transports.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/vendor_arm.h"

namespace bisturi::devices {
namespace {

constexpr std::uint8_t kInterrupt = 3, kBulk = 2, kVendor = 0xff, kHid = 3;

/// A composite device: a HID interface, a vendor-specific one with bulk endpoints only, then two
/// vendor-specific ones with interrupt endpoints.
std::vector<UsbAltSetting> composite() {
  return {{0, kHid, {{0x83, kInterrupt, 8}}},
          {1, kVendor, {{0x84, kBulk, 512}, {0x04, kBulk, 512}}},
          {2, kVendor, {{0x81, kInterrupt, 64}, {0x01, kInterrupt, 64}}},
          {3, kVendor, {{0x82, kInterrupt, 32}, {0x02, kInterrupt, 32}, {0x85, kInterrupt, 16}}}};
}

TEST(UsbEndpoints, WithoutADeclarationTheFirstVendorInterruptInterfaceIsUsed) {
  const UsbEndpoints e = choose_usb_endpoints(composite());
  EXPECT_EQ(e.interface, 2);
  EXPECT_EQ(e.in, 0x81);
  EXPECT_EQ(e.out, 0x01);
  EXPECT_EQ(e.in_size, 64);
}

TEST(UsbEndpoints, ADriverNamesItsInterfaceAndEndpoints) {
  const UsbEndpoints by_number = choose_usb_endpoints(composite(), {3, 0, 0});
  EXPECT_EQ(by_number.interface, 3);
  EXPECT_EQ(by_number.in, 0x82) << "the first interrupt IN of the interface";
  EXPECT_EQ(by_number.in_size, 32);
  const UsbEndpoints by_address = choose_usb_endpoints(composite(), {3, 0x85, 0x02});
  EXPECT_EQ(by_address.interface, 3);
  EXPECT_EQ(by_address.in, 0x85);
  EXPECT_EQ(by_address.in_size, 16);
  EXPECT_EQ(by_address.out, 0x02);
}

TEST(UsbEndpoints, AnInterfaceWithoutWhatTheDriverNeedsIsNotUsed) {
  EXPECT_EQ(choose_usb_endpoints(composite(), {0, 0, 0}).interface, -1) << "IN only";
  EXPECT_EQ(choose_usb_endpoints(composite(), {1, 0, 0}).interface, -1) << "bulk only";
  EXPECT_EQ(choose_usb_endpoints(composite(), {3, 0x81, 0}).interface, -1) << "no IN 0x81 there";
  EXPECT_EQ(choose_usb_endpoints(composite(), {7, 0, 0}).interface, -1) << "no interface 7";
  EXPECT_EQ(
      choose_usb_endpoints({{0, kHid, {{0x81, kInterrupt, 8}, {0x01, kInterrupt, 8}}}}).interface,
      -1)
      << "a HID interface is hidraw's, not a vendor driver's";
}

TEST(UsbEndpoints, TheVendorArmDeclaresItsEndpoints) {
  const Registry registry = builtin_registry();
  const DriverInfo* arm = registry.find_by_name("vendor-arm");
  ASSERT_NE(arm, nullptr);
  EXPECT_EQ(arm->usb_interface,
            (UsbInterface{0, arm_protocol::kEndpointIn, arm_protocol::kEndpointOut}));
  const UsbEndpoints e = choose_usb_endpoints(
      {{0, kVendor, {{0x81, kInterrupt, 32}, {0x01, kInterrupt, 32}}}}, arm->usb_interface);
  EXPECT_EQ(e.interface, 0);
  EXPECT_EQ(e.in_size, 32);
}

}  // namespace
}  // namespace bisturi::devices
