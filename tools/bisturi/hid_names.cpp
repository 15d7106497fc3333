#include "hid_names.h"

#include <cstdio>

#include "bisturi/devices/hid_descriptor.h"

namespace bisturi::cli {

namespace {

namespace hid = devices::hid;

const char* page_name(std::uint32_t page) {
  switch (page) {
    case 0x01:
      return "Generic Desktop";
    case 0x02:
      return "Simulation Controls";
    case 0x03:
      return "VR Controls";
    case 0x05:
      return "Game Controls";
    case 0x06:
      return "Generic Device Controls";
    case 0x07:
      return "Keyboard/Keypad";
    case 0x08:
      return "LED";
    case 0x09:
      return "Button";
    case 0x0C:
      return "Consumer";
    case 0x0D:
      return "Digitizers";
    case 0x0E:
      return "Haptics";
    case 0x0F:
      return "PID";
    case 0x20:
      return "Sensors";
    default:
      return page >= 0xFF00 ? "Vendor" : nullptr;
  }
}

}  // namespace

std::string usage_name(std::uint32_t usage) {
  const std::uint32_t page = usage >> 16, id = usage & 0xFFFF;
  const std::string code = hex(page, 4) + ":" + hex(id, 4);
  std::string name;
  if (page == 0x01) {
    static const char* const kDesktop[] = {nullptr,    "Pointer",  "Mouse",    nullptr,
                                           "Joystick", "Game Pad", "Keyboard", "Keypad"};
    static const char* const kAxes[] = {"X",  "Y",      "Z",    "Rx",    "Ry",
                                        "Rz", "Slider", "Dial", "Wheel", "Hat switch"};
    if (id < 8 && kDesktop[id]) name = kDesktop[id];
    if (id >= 0x30 && id <= 0x39) name = kAxes[id - 0x30];
  } else if (page == 0x09) {
    name = "Button " + std::to_string(id);
  } else if (usage == hid::kUsageFlexor) {
    name = "Flexor";
  } else if (usage == hid::kUsageGlove) {
    name = "Glove";
  } else if (usage == hid::kUsageHeadTracker) {
    name = "Head Tracker";
  } else if (usage == hid::kUsageHeadMountedDisplay) {
    name = "Head Mounted Display";
  } else if (usage == hid::kUsagePidMagnitude) {
    name = "Magnitude";
  } else if (usage == hid::kUsageHapticIntensity) {
    name = "Intensity";
  } else if (usage == hid::kUsageOrientationQuaternion) {
    name = "Orientation Quaternion";
  }
  const char* p = page_name(page);
  std::string text = p ? std::string(p) : hex(page, 4);
  if (!name.empty()) text += ":" + name;
  return text + " (" + code + ")";
}

std::string hex(std::uint32_t value, int digits) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%0*X", digits, value);
  return text;
}

}  // namespace bisturi::cli
