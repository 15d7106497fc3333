// The blood on a thread of its own (see blood_worker.h).
#include "blood_worker.h"

#include "free_core.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>

#include "bisturi/sim/units.h"

namespace bisturi::runtime {

BloodWorker::BloodWorker(const sim::BloodOptions& options, const sim::SimWorld& world)
    : blood_(options) {
  for (std::uint32_t b = 0; b < world.body_count(); ++b) {
    bodies_.push_back(world.body(b));
    topology_.push_back(world.body(b).mesh().topology_version());
  }
  for (const sim::SoftBody& body : bodies_)
    bvhs_.emplace_back(device_, body);
  for (std::size_t b = 0; b < bodies_.size(); ++b)
    surfaces_.push_back({&bodies_[b], &bvhs_[b]});
  for (Step& step : ring_) {
    step.positions.resize(bodies_.size());
    step.replaced.resize(bodies_.size());
  }
}

BloodWorker::~BloodWorker() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void BloodWorker::queue(double dt_s, std::span<const BloodEmission> emissions,
                        const sim::SimWorld& world) {
  if (!thread_.joinable()) thread_ = std::thread([this] { run(); });
  Step* step = nullptr;
  {
    // Only when the blood is kMostQueued steps behind does the tissue wait for it.
    std::unique_lock<std::mutex> lock(mutex_);
    const std::uint64_t behind = queued_ - done_;
    most_behind_ = std::max(most_behind_, behind);
    if (behind >= kMostQueued) {
      const auto begin = std::chrono::steady_clock::now();
      changed_.wait(lock, [&] { return queued_ - done_ < kMostQueued; });
      ++tissue_waits_;
      tissue_waited_ms_ +=
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - begin)
              .count();
    }
    step = &ring_[queued_ % kMostQueued];
  }
  // The slot is the tissue thread's until it is published: filled without the lock, into the
  // capacity it kept from the last time round.
  step->dt_s = dt_s;
  step->emissions.assign(emissions.begin(), emissions.end());
  for (std::uint32_t b = 0; b < world.body_count(); ++b) {
    const sim::SoftBody& body = world.body(b);
    step->replaced[b].reset();
    if (body.mesh().topology_version() != topology_[b]) {
      // A cut: the worker takes the whole body (allocating, as the cut did).
      topology_[b] = body.mesh().topology_version();
      step->replaced[b] = std::make_unique<sim::SoftBody>(body);
    }
    step->positions[b].assign(body.positions().begin(), body.positions().end());
  }
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    ++queued_;
    behind_.store(queued_ - done_, std::memory_order_relaxed);
  }
  changed_.notify_all();
}

const sim::Blood& BloodWorker::settled() {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [&] { return done_ == queued_; });
  return blood_;
}

void BloodWorker::newest_positions_mm(std::vector<glm::dvec3>& out) const {
  const std::lock_guard<std::mutex> lock(mutex_);
  out.assign(newest_mm_.begin(), newest_mm_.end());
}

void BloodWorker::run() {
  // Below the session's other threads: the blood takes what the haptic loop, the tissue and the
  // renderer leave of the cores (nice 10 while it is not stepping, SCHED_IDLE while it is).
  (void)setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 10);
  std::vector<glm::dvec3> newest;
  for (;;) {
    Step* step = nullptr;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait(lock, [&] { return stopping_ || done_ < queued_; });
      if (done_ == queued_) return;  // stopping, nothing left
      step = &ring_[done_ % kMostQueued];
    }
    if (stall_flag_ != nullptr && stall_flag_->exchange(false))
      std::this_thread::sleep_for(stall_for_);
    const auto begin = std::chrono::steady_clock::now();
    run_only_on_a_free_core(true);
    take(*step);
    run_only_on_a_free_core(false);
    step_ms_.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - begin)
            .count());
    most_particles_ = std::max<std::uint64_t>(most_particles_, blood_.positions().size());
    newest.resize(blood_.positions().size());
    for (std::size_t i = 0; i < newest.size(); ++i)
      newest[i] = sim::sim_to_scene(blood_.positions()[i]);
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      newest_mm_.swap(newest);
      ++done_;
      behind_.store(queued_ - done_, std::memory_order_relaxed);
    }
    changed_.notify_all();
  }
}

void BloodWorker::take(Step& step) {
  bool rebuilt = false;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    if (step.replaced[b]) {
      bodies_[b] = std::move(*step.replaced[b]);
      step.replaced[b].reset();
      bvhs_[b] = sim::SurfaceBvh(device_, bodies_[b]);
      rebuilt = true;
      continue;
    }
    bodies_[b].positions().assign(step.positions[b].begin(), step.positions[b].end());
    bvhs_[b].update(bodies_[b]);
  }
  if (rebuilt)
    for (std::size_t b = 0; b < bodies_.size(); ++b)
      surfaces_[b] = {&bodies_[b], &bvhs_[b]};
  for (const BloodEmission& e : step.emissions)
    (void)blood_.emit(e.sources, e.flow_m3_s, e.speed_m_s, step.dt_s);
  blood_.step(step.dt_s, surfaces_);
}

}  // namespace bisturi::runtime
