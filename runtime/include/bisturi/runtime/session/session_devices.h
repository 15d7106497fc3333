#pragma once
// The session's devices: the haptic device that drives the instruments and the head tracker, each
// either a simulated twin behind a virtual transport (the twin the driver registered, driven by
// the scene's script) or real hardware found by driver name, vendor/product id and serial on the
// bus the driver registered (hidapi for HID, libusb for raw USB). Nothing here knows a driver by
// name: a new driver plugs in through its DriverInfo alone. Both go through the same registry and
// drivers, and through the trace writer when the session records.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/device.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/devices/trace/trace_writer.h"
#include "bisturi/runtime/session/procedure.h"
#include "bisturi/runtime/session/scene_description.h"

namespace bisturi::runtime {

/// Which scene devices the session uses: the haptic device every instrument names (or the first
/// haptic device when no instrument names one) and the first head tracker. Throws SceneFileError
/// when a role is missing or the instruments name different haptic devices (the session has one
/// hand: every instrument follows the same device).
struct DeviceChoice {
  const DeviceDescription* haptic = nullptr;
  const DeviceDescription* head = nullptr;
};
DeviceChoice choose_session_devices(const SceneDescription& scene);

/// Finds a real device for `description` among what `source` lists: the registry's driver for it
/// must be the named one (or the one claiming its vendor/product id), and vendor id, product id
/// and serial must match where given. Throws devices::DeviceError naming the scene device, what
/// was looked for and what is connected.
devices::DeviceDescriptor find_real_device(const DeviceDescription& description,
                                           const devices::Registry& registry,
                                           const std::vector<devices::DeviceDescriptor>& listed);

/// Where a device fed from inside the process comes from (a driver on the virtual bus that is not
/// simulated, like the headset controller the render thread feeds): the transport for `driver`,
/// or nullptr when this process has none for it.
using InProcessTransports =
    std::function<std::unique_ptr<devices::Transport>(const devices::DriverInfo& driver)>;

class SessionDevices {
 public:
  /// Opens both devices (recording them into `writer` when it is not null). `procedure` scripts
  /// the simulated twins. Throws SceneFileError for a simulated driver without a twin or real
  /// hardware for a driver without a bus, and devices::DeviceError when real hardware is not
  /// connected or cannot be opened. `in_process` serves drivers on the virtual bus that are not
  /// simulated.
  SessionDevices(const SceneDescription& scene, const Procedure& procedure,
                 const devices::Registry& registry, devices::Clock& clock,
                 devices::TraceWriter* writer, InProcessTransports in_process = {});
  ~SessionDevices();
  SessionDevices(const SessionDevices&) = delete;
  SessionDevices& operator=(const SessionDevices&) = delete;

  /// The twins send the reports due at session time t (hardware sends on its own: no-op there).
  void step_twins(devices::Nanoseconds t);

  [[nodiscard]] devices::HapticDevice& haptic() const { return *haptic_; }
  [[nodiscard]] devices::Tracker& head() const { return *head_; }
  [[nodiscard]] const DeviceDescription& haptic_description() const { return *choice_.haptic; }
  /// What the session sends on each of the haptic device's force channels (its driver's layout,
  /// in capabilities().force_channels order).
  [[nodiscard]] const std::vector<devices::ChannelRole>& haptic_channels() const {
    return haptic_roles_;
  }
  /// What each of the haptic device's buttons does (its driver's layout).
  [[nodiscard]] const std::vector<devices::ButtonUse>& haptic_buttons() const {
    return haptic_buttons_;
  }
  /// The haptic device's index in the trace (0 when not recording).
  [[nodiscard]] std::uint16_t haptic_trace_index() const { return haptic_index_; }
  /// "glove: hid-glove (simulated)", "head: hid-tracker (GloveCo Tracker (1234:5678, ...))".
  [[nodiscard]] std::vector<std::string> summary() const;
  /// Closes both drivers (zero forces first).
  void close();
  /// Breaks a simulated haptic device's link as an unplug would (an injected fault): false for
  /// hardware, which only a hand can unplug.
  bool unplug_haptic();
  /// Makes a simulated haptic device hold off the host's next write for `duration` (an injected
  /// fault): false for hardware.
  bool stall_haptic_io(devices::Nanoseconds duration);
  /// Whether the haptic device's writes return within a bound (Transport::write_is_bounded).
  [[nodiscard]] bool haptic_write_bounded() const { return haptic_write_bounded_; }

 private:
  std::unique_ptr<devices::Device> open_one(const DeviceDescription& d,
                                            const devices::DeviceScript& script,
                                            const devices::Registry& registry,
                                            devices::Clock& clock, devices::TraceWriter* writer,
                                            std::uint16_t* trace_index, bool* write_bounded);

  DeviceChoice choice_;
  double haptic_hz_;
  InProcessTransports in_process_;
  std::vector<std::unique_ptr<devices::SimulatedDevice>> twins_;
  std::unique_ptr<devices::Device> haptic_device_, head_device_;
  devices::HapticDevice* haptic_ = nullptr;
  devices::Tracker* head_ = nullptr;
  bool haptic_write_bounded_ = true;
  std::uint16_t haptic_index_ = 0;
  std::vector<devices::ChannelRole> haptic_roles_;
  std::vector<devices::ButtonUse> haptic_buttons_;
  std::vector<std::string> summary_;
};

}  // namespace bisturi::runtime
