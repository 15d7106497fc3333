// Private: binds the inputs and outputs a generic HID driver understands to fields of a parsed
// report descriptor, so a report is handled by reading only the bound elements.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "bisturi/devices/device.h"
#include "bisturi/devices/hid_report.h"

namespace bisturi::devices::detail {

struct Binding {
  std::uint32_t field = 0;
  std::uint32_t element = 0;
};

struct InputReportMap {
  std::uint8_t id = 0;
  int position[3] = {-1, -1, -1};        // index into bindings
  int quaternion[4] = {-1, -1, -1, -1};  // x y z w
  int euler[3] = {-1, -1, -1};
  std::vector<std::pair<std::size_t, Binding>> joints;     // joint index, binding
  std::vector<std::pair<std::uint32_t, Binding>> buttons;  // button index, binding (variable)
  std::vector<std::uint32_t> button_arrays;                // array fields on the Button page
  std::vector<Binding> bindings;
};

struct ForceOutput {
  std::uint8_t report_id = 0;
  std::vector<std::pair<std::size_t, Binding>> channels;  // channel index, binding
  std::vector<Binding> effect_block_index;                // set to 1
};

class HidMapping {
 public:
  // Throws ProtocolError (naming the device) when the descriptor is malformed.
  HidMapping(const DeviceDescriptor& device, double max_force_rate_N_per_s);

  const hid::ReportCodec& codec() const { return codec_; }
  const Capabilities& capabilities() const { return capabilities_; }
  std::uint32_t application_usage() const { return application_; }
  bool has_pose() const { return has_position_ || has_orientation_; }

  // Updates pose / joints / buttons from one input report (only those it carries). Returns false
  // for an input report with nothing bound. Throws ProtocolError on a malformed report.
  bool apply(std::span<const std::uint8_t> report, Pose* pose, std::vector<double>* joints_rad,
             std::uint64_t* buttons) const;
  // Output reports carrying these forces (one per report id with force fields).
  void encode_forces(std::span<const double> forces_N, std::vector<Bytes>& reports) const;

 private:
  hid::ReportCodec codec_;
  Capabilities capabilities_;
  std::uint32_t application_ = 0;
  bool has_position_ = false, has_orientation_ = false;
  std::vector<InputReportMap> inputs_;
  std::vector<ForceOutput> outputs_;
};

}  // namespace bisturi::devices::detail
