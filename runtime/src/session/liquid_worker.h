#pragma once
// The blood's liquid surface (render/liquid_surface.h) built on a thread of its own, only on a
// core the session's other threads leave free (SCHED_IDLE while it builds, as the blood steps:
// blood_worker.cpp), so the render thread hands it the newest particles and draws the newest
// surface built. Built on the render thread, it took the display 3 ms every other frame at 5000
// particles on two cores. Particles offered while a build runs wait for the next one; only the
// newest are built.

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/runtime/render/liquid_surface.h"
#include "bisturi/scene/dlfl.h"

namespace bisturi::runtime {

class LiquidWorker {
 public:
  explicit LiquidWorker(const render::LiquidSurfaceOptions& options = {});
  ~LiquidWorker();
  LiquidWorker(const LiquidWorker&) = delete;
  LiquidWorker& operator=(const LiquidWorker&) = delete;

  /// The particles now (world mm): the next build uses them, unless newer ones come first. The
  /// same particles as the last offered (none, at first) start no build. With every_other (the
  /// blood's thread behind), only every second new set is built: the surface and the blood
  /// share the core the session leaves free, and the blood, behind, needs it more.
  void offer(const std::vector<glm::dvec3>& centres_mm, bool every_other = false);
  /// The newest surface built (null before the first) and its number, which grows by one a
  /// build: a caller holding that number has it already.
  [[nodiscard]] std::shared_ptr<const Dlfl> newest(std::uint64_t& number) const;
  /// Waits until the particles offered last are built (tests, and a session's last frame).
  void settle();

 private:
  void run();

  render::LiquidSurface liquid_;  ///< the worker thread's
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<glm::dvec3> offered_;  ///< the newest set offered, built or passed over (mutex_)
  bool passed_over_ = false;         ///< offered_ was passed over (every_other)
  bool pending_ = false;             ///< offered_ not built yet
  bool building_ = false;
  bool stopping_ = false;
  std::shared_ptr<const Dlfl> newest_;
  std::uint64_t number_ = 0;
  std::thread thread_;
};

}  // namespace bisturi::runtime
