#pragma once
// What the tissue thread hands the render thread after each step: the solids' positions and
// (shared, read-only) topologies, the instruments' poses and the events to show.

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/device.h"
#include "bisturi/runtime/session/session_sim.h"
#include "bisturi/runtime/session/triple_buffer.h"
#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/sim/volume/hex_lattice.h"

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
  /// A volume body's lattice (a new one after its refined box moved or a cut separated it; null for
  /// a membrane) and its nodes now (metres): what a finer drawn surface follows (drawn_surface.h).
  std::shared_ptr<const sim::HexLattice> lattice;
  std::vector<glm::dvec3> nodes_m;
};

/// What the tissue thread hands the render thread after each step (the head pose comes straight
/// from the haptic thread, see HeadPose below).
/// One hand's instrument as drawn: its tip, where its blade reaches, what it does.
struct InstrumentState {
  glm::dvec3 tip_mm{0.0};
  glm::dvec3 blade_to_mm{0.0};
  bool grasping = false;
  bool cutting = false;
};

struct Snapshot {
  std::uint64_t tick = 0;
  std::vector<SolidState> solids;
  std::vector<InstrumentState> instruments;  ///< one per hand
  std::vector<glm::dvec3> blood_mm;          ///< the blood's particles (sim/blood.h)
  std::uint64_t blood_behind = 0;            ///< blood steps queued on its thread, not yet made
  std::vector<Incision> incisions;           ///< the cuts made so far (SessionSim::incisions)
  std::uint64_t event_count = 0;
  std::array<EventStamp, 16> recent{};  ///< the last events, by index % size
};

/// A volume body's lattice and nodes into `state` (nothing for a membrane).
void copy_volume(const sim::SimWorld& world, std::uint32_t body, SolidState& state);

/// The solids as they are before the first step.
Snapshot initial_snapshot(SessionSim& sim);

/// The tissue thread's side of the hand-off: after each step, the solids' positions (a new
/// topology only after a cut), the instruments and the events, published for the renderer.
class SnapshotPublisher {
 public:
  /// `event_times` gets each event's device sample time (read by the render thread below the
  /// published count); its capacity bounds how many are kept.
  SnapshotPublisher(SessionSim& sim, const Snapshot& initial, TripleBuffer<Snapshot>& snapshots,
                    std::vector<devices::Nanoseconds>& event_times);
  /// After a step: `out` its output, `state` the haptic state it ran on.
  /// `states`: the hands' device states the step ran on (the first's sample time stamps events).
  void publish(const TickOutput& out, std::span<const devices::HapticState> states);
  /// Events the simulation has made so far (any thread).
  [[nodiscard]] std::size_t events() const { return event_count_.load(std::memory_order_relaxed); }

 private:
  SessionSim& sim_;
  TripleBuffer<Snapshot>& snapshots_;
  std::vector<devices::Nanoseconds>& event_times_;
  std::vector<std::shared_ptr<const Topology>> topology_;
  std::vector<std::shared_ptr<const sim::HexLattice>> lattice_;
  std::vector<std::uint64_t> lattice_versions_;
  std::uint64_t published_events_ = 0;
  std::array<EventStamp, 16> recent_{};
  std::atomic<std::size_t> event_count_{0};
};

}  // namespace bisturi::runtime
