#pragma once
// What the tissue thread hands the render thread after each step: the solids' positions and
// (shared, read-only) topologies, the instruments' poses and the events to show.

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/devices/clock.h"
#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/oriented_builder.h"

namespace bisturi::runtime {

/// An event as the render thread sees it: which one, and when its device report was read.
struct EventStamp {
  std::uint64_t index = 0;
  devices::Nanoseconds time{0};
};

/// A solid's faces as the render thread rebuilds its own DLFL from them (a Dlfl is not
/// copyable, and the haptic thread's one must not be read while it steps): made by the haptic
/// thread at start and after each topology change (a cut), shared read-only.
struct Topology {
  std::uint64_t version = 0;
  PolygonMesh polygons;
  std::vector<std::uint32_t> slot_of_position;  ///< body vertex slot of each polygon position
};

std::shared_ptr<const Topology> make_topology(const Dlfl& mesh);

/// What the haptic thread hands the render thread.
struct SolidState {
  std::vector<glm::dvec3> positions_mm;  ///< by body vertex slot
  std::shared_ptr<const Topology> topology;
};

/// What the tissue thread hands the render thread after each step (the head pose comes straight
/// from the haptic thread, see HeadPose below).
struct Snapshot {
  std::uint64_t tick = 0;
  std::vector<SolidState> solids;
  glm::dvec3 tip_mm{0.0};
  glm::dvec3 blade_to_mm{0.0};
  bool grasping = false;
  bool cutting = false;
  std::uint64_t event_count = 0;
  std::array<EventStamp, 16> recent{};  ///< the last events, by index % size
};

}  // namespace bisturi::runtime
