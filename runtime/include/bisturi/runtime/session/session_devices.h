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

/// Which scene devices the session uses: its hands, the haptic devices the instruments name (all
/// the scene's haptic devices when no instrument names one), in the scene's order, and the first
/// head tracker. Every hand drives its own probe, grasper and scalpel. Throws SceneFileError when
/// a role is missing or an instrument names a device that is not a haptic device of the scene.
struct DeviceChoice {
  std::vector<const DeviceDescription*> hands;
  const DeviceDescription* haptic = nullptr;  ///< the first hand's
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
  /// Opens the hands' devices, then the head tracker (recording them into `writer` when it is not
  /// null, in that order). `procedure` scripts the simulated twins. Throws SceneFileError for a
  /// simulated driver without a twin or real hardware for a driver without a bus, and
  /// devices::DeviceError when real hardware is not connected or cannot be opened. `in_process`
  /// serves drivers on the virtual bus that are not simulated.
  SessionDevices(const SceneDescription& scene, const Procedure& procedure,
                 const devices::Registry& registry, devices::Clock& clock,
                 devices::TraceWriter* writer, InProcessTransports in_process = {});
  ~SessionDevices();
  SessionDevices(const SessionDevices&) = delete;
  SessionDevices& operator=(const SessionDevices&) = delete;

  /// The twins send the reports due at session time t (hardware sends on its own: no-op there).
  void step_twins(devices::Nanoseconds t);

  [[nodiscard]] std::size_t hand_count() const { return hands_.size(); }
  /// A hand's haptic device (the first: the session's first hand).
  [[nodiscard]] devices::HapticDevice& haptic(std::size_t hand = 0) const {
    return *hands_[hand].haptic;
  }
  [[nodiscard]] devices::Tracker& head() const { return *head_; }
  [[nodiscard]] const DeviceDescription& haptic_description(std::size_t hand = 0) const {
    return *choice_.hands[hand];
  }
  /// What the session sends on each of a hand's device's force channels (its driver's layout,
  /// in capabilities().force_channels order).
  [[nodiscard]] const std::vector<devices::ChannelRole>& haptic_channels(
      std::size_t hand = 0) const {
    return hands_[hand].roles;
  }
  /// What each of a hand's device's buttons does (its driver's layout).
  [[nodiscard]] const std::vector<devices::ButtonUse>& haptic_buttons(std::size_t hand = 0) const {
    return hands_[hand].buttons;
  }
  /// A hand's device's index in the trace (0 when not recording).
  [[nodiscard]] std::uint16_t haptic_trace_index(std::size_t hand = 0) const {
    return hands_[hand].trace_index;
  }
  /// "glove: hid-glove (simulated)", "head: hid-tracker (GloveCo Tracker (1234:5678, ...))".
  [[nodiscard]] std::vector<std::string> summary() const;
  /// Closes every driver (zero forces first).
  void close();
  /// Breaks the first hand's simulated device's link as an unplug would (an injected fault):
  /// false for hardware, which only a hand can unplug.
  bool unplug_haptic();
  /// Makes the first hand's simulated device hold off the host's next write for `duration` (an
  /// injected fault): false for hardware.
  bool stall_haptic_io(devices::Nanoseconds duration);
  /// Whether a hand's device's writes return within a bound (Transport::write_is_bounded).
  [[nodiscard]] bool haptic_write_bounded(std::size_t hand = 0) const {
    return hands_[hand].write_bounded;
  }

 private:
  std::unique_ptr<devices::Device> open_one(const DeviceDescription& d,
                                            const devices::DeviceScript& script,
                                            const devices::Registry& registry,
                                            devices::Clock& clock, devices::TraceWriter* writer,
                                            std::uint16_t* trace_index, bool* write_bounded);

  /// One hand's device, opened.
  struct Hand {
    std::unique_ptr<devices::Device> device;
    devices::HapticDevice* haptic = nullptr;
    devices::SimulatedDevice* twin = nullptr;  ///< null: hardware or fed in process
    bool write_bounded = true;
    std::uint16_t trace_index = 0;
    std::vector<devices::ChannelRole> roles;
    std::vector<devices::ButtonUse> buttons;
  };

  DeviceChoice choice_;
  double haptic_hz_;
  InProcessTransports in_process_;
  std::vector<std::unique_ptr<devices::SimulatedDevice>> twins_;
  std::vector<Hand> hands_;
  std::unique_ptr<devices::Device> head_device_;
  devices::Tracker* head_ = nullptr;
  std::vector<std::string> summary_;
};

}  // namespace bisturi::runtime
