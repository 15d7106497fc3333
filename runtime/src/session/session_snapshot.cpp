// A solid's topology for the render thread (see session_snapshot.h).

#include "session_snapshot.h"

#include <algorithm>

#include "bisturi/scene/polygon_export.h"
#include "bisturi/sim/units.h"
#include "bisturi/sim/volume/volume_body.h"
#include "bisturi/sim/world.h"

namespace bisturi::runtime {

std::shared_ptr<const Topology> make_topology(const Dlfl& mesh) {
  auto t = std::make_shared<Topology>();
  t->version = mesh.topology_version();
  ExportedPolygons e = export_polygons(mesh);
  t->polygons = std::move(e.polygons);
  t->slot_of_position.reserve(e.vertex_of_position.size());
  for (VertexId v : e.vertex_of_position)
    t->slot_of_position.push_back(v.idx);
  return t;
}

void copy_volume(const sim::SimWorld& world, std::uint32_t body, SolidState& state) {
  const sim::VolumeBody* volume = world.volume(body);
  if (volume == nullptr) return;
  const std::span<const glm::dvec3> x = volume->volume().positions();
  state.nodes_m.assign(x.begin(), x.end());
}

Snapshot initial_snapshot(SessionSim& sim) {
  Snapshot initial;
  initial.solids.resize(sim.body_count());
  initial.instruments.resize(sim.hand_count());
  for (std::size_t b = 0; b < sim.body_count(); ++b) {
    const sim::SoftBody& body = sim.world().body(static_cast<std::uint32_t>(b));
    initial.solids[b].positions_mm.resize(body.positions().size());
    initial.solids[b].topology = make_topology(body.mesh());
    for (std::size_t i = 0; i < body.positions().size(); ++i)
      initial.solids[b].positions_mm[i] = sim::sim_to_scene(body.positions()[i]);
    if (const sim::VolumeBody* volume = sim.world().volume(static_cast<std::uint32_t>(b)))
      initial.solids[b].lattice =
          std::make_shared<const sim::HexLattice>(volume->volume().lattice());
    copy_volume(sim.world(), static_cast<std::uint32_t>(b), initial.solids[b]);
  }
  return initial;
}

SnapshotPublisher::SnapshotPublisher(SessionSim& sim, const Snapshot& initial,
                                     TripleBuffer<Snapshot>& snapshots,
                                     std::vector<devices::Nanoseconds>& event_times)
    : sim_(sim), snapshots_(snapshots), event_times_(event_times) {
  for (std::size_t b = 0; b < initial.solids.size(); ++b) {
    topology_.push_back(initial.solids[b].topology);
    lattice_.push_back(initial.solids[b].lattice);
    const sim::VolumeBody* volume = sim.world().volume(static_cast<std::uint32_t>(b));
    lattice_versions_.push_back(volume != nullptr ? volume->lattice_version() : 0);
  }
}

void SnapshotPublisher::publish(const TickOutput& out,
                                std::span<const devices::HapticState> states) {
  const devices::HapticState& state = states.front();
  Snapshot& s = snapshots_.back();
  s.tick = sim_.ticks();
  for (std::size_t b = 0; b < sim_.body_count(); ++b) {
    const sim::SoftBody& body = sim_.world().body(static_cast<std::uint32_t>(b));
    SolidState& st = s.solids[b];
    if (out.topology_changed && body.mesh().topology_version() != topology_[b]->version)
      topology_[b] = make_topology(body.mesh());
    st.topology = topology_[b];
    const auto& x = body.positions();
    st.positions_mm.resize(x.size());
    for (std::size_t i = 0; i < x.size(); ++i)
      st.positions_mm[i] = sim::sim_to_scene(x[i]);
    if (const sim::VolumeBody* volume = sim_.world().volume(static_cast<std::uint32_t>(b))) {
      if (volume->lattice_version() != lattice_versions_[b]) {
        // The refined box moved or a cut separated cells (between steps, on this thread; it
        // allocated already).
        lattice_versions_[b] = volume->lattice_version();
        lattice_[b] = std::make_shared<const sim::HexLattice>(volume->volume().lattice());
      }
      st.lattice = lattice_[b];
      copy_volume(sim_.world(), static_cast<std::uint32_t>(b), st);
    }
  }
  if (s.incisions.size() != sim_.incisions().size()) s.incisions = sim_.incisions();
  sim_.newest_blood_mm(s.blood_mm);  // the blood's thread's newest step: never waits for one
  s.blood_behind = sim_.blood_behind();
  s.instruments.resize(sim_.hand_count());
  for (std::size_t h = 0; h < sim_.hand_count(); ++h)
    s.instruments[h] = {sim_.tip_mm(h), sim_.blade_to_mm(h), sim_.grasping(h), sim_.cutting(h)};
  for (; published_events_ < sim_.events().size(); ++published_events_) {
    if (event_times_.size() < event_times_.capacity()) event_times_.push_back(state.sample_time);
    recent_[published_events_ % recent_.size()] = {published_events_, state.sample_time};
  }
  s.event_count = std::min<std::uint64_t>(published_events_, event_times_.size());
  s.recent = recent_;
  snapshots_.publish();
  event_count_.store(sim_.events().size(), std::memory_order_relaxed);
}

}  // namespace bisturi::runtime
