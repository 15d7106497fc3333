#pragma once
// The blood on a thread of its own (sim/blood.h), so that bleeding costs the tissue thread, and
// through it the haptic force, nothing but a copy of the surfaces' positions. Every blood step,
// the tissue thread queues what the step needs: its length, each opening's sources and flow,
// and where the bodies' surfaces are at that step (a body whose topology changed goes whole).
// The worker steps the blood on its own copies of the bodies, in the order the steps were
// queued, so the blood is the same whatever the timing: a replay bleeds the same, bit for bit.
// The blood does not act on the tissue (one way), so the tissue never waits for it; the tissue
// thread waits only when kMostQueued steps are queued (the blood more than that behind).

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <thread>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/sim/blood.h"
#include "bisturi/sim/collision.h"
#include "bisturi/sim/world.h"

namespace bisturi::runtime {

/// What leaves one opening in a blood step.
struct BloodEmission {
  std::vector<sim::BloodSource> sources;
  double flow_m3_s = 0.0;
  double speed_m_s = 0.0;
};

class BloodWorker {
 public:
  /// How far the blood may fall behind the tissue (0.36 s at 90 Hz) before the tissue waits.
  static constexpr std::size_t kMostQueued = 32;

  /// The blood with `options`, running on `world`'s bodies as they are now. The thread starts
  /// with the first step queued.
  BloodWorker(const sim::BloodOptions& options, const sim::SimWorld& world);
  ~BloodWorker();
  BloodWorker(const BloodWorker&) = delete;
  BloodWorker& operator=(const BloodWorker&) = delete;

  /// Queues a step of dt_s (tissue thread): `emissions` first, then the particles move against
  /// `world`'s bodies as they are now.
  void queue(double dt_s, std::span<const BloodEmission> emissions, const sim::SimWorld& world);
  /// Waits until every queued step is done, and gives the blood then.
  const sim::Blood& settled();
  /// The particles after the newest step done, in millimetres (any thread; never waits on a
  /// step).
  void newest_positions_mm(std::vector<glm::dvec3>& out) const;
  /// Wall time of each step done (ms, on the worker's thread), and the most particles after
  /// a step; settle() first for all of them.
  [[nodiscard]] const std::vector<double>& step_ms() const { return step_ms_; }
  [[nodiscard]] std::uint64_t most_particles() const { return most_particles_; }
  /// The most steps that were queued and not done when one more came; how often and how long
  /// (ms) the tissue thread waited for room (the tissue thread's figures).
  [[nodiscard]] std::uint64_t most_behind() const { return most_behind_; }
  [[nodiscard]] std::uint64_t tissue_waits() const { return tissue_waits_; }
  [[nodiscard]] double tissue_waited_ms() const { return tissue_waited_ms_; }
  /// Once `flag` is set (by another thread), the next step stops for `how_long` first, and clears
  /// it (an injected fault: fault_injection.h).
  void stall_when(std::atomic<bool>* flag, std::chrono::milliseconds how_long) {
    stall_flag_ = flag;
    stall_for_ = how_long;
  }
  /// Steps queued and not done now (any thread; never waits).
  [[nodiscard]] std::uint64_t behind() const { return behind_.load(std::memory_order_relaxed); }

 private:
  struct Step {
    double dt_s = 0.0;
    std::vector<BloodEmission> emissions;
    std::vector<std::vector<glm::dvec3>> positions;        ///< per body
    std::vector<std::unique_ptr<sim::SoftBody>> replaced;  ///< per body: a new topology, or null
  };
  void run();
  void take(Step& step);

  sim::Blood blood_;
  sim::CollisionDevice device_;
  std::vector<sim::SoftBody> bodies_;  ///< the worker's copies
  std::vector<sim::SurfaceBvh> bvhs_;
  std::vector<sim::BloodSurface> surfaces_;
  std::vector<std::uint64_t> topology_;  ///< per body: the version the worker has (tissue side)

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<Step> ring_{kMostQueued};
  std::uint64_t queued_ = 0, done_ = 0;      ///< steps queued and taken, under mutex_
  std::atomic<std::uint64_t> behind_{0};     ///< queued_ - done_, for readers without the lock
  std::atomic<bool>* stall_flag_ = nullptr;  ///< set before the thread starts
  std::chrono::milliseconds stall_for_{0};
  bool stopping_ = false;
  std::vector<glm::dvec3> newest_mm_;  ///< under mutex_
  std::vector<double> step_ms_;
  std::uint64_t most_particles_ = 0;
  std::uint64_t most_behind_ = 0, tissue_waits_ = 0;  ///< the tissue thread's
  double tissue_waited_ms_ = 0.0;
  std::thread thread_;
};

}  // namespace bisturi::runtime
