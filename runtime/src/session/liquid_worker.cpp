// The blood's liquid surface on a thread of its own (see liquid_worker.h).
#include "liquid_worker.h"

#include "free_core.h"

#include <algorithm>

namespace bisturi::runtime {

LiquidWorker::LiquidWorker(const render::LiquidSurfaceOptions& options)
    : liquid_(options), thread_([this] { run(); }) {}

LiquidWorker::~LiquidWorker() {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

void LiquidWorker::offer(const std::vector<glm::dvec3>& centres_mm, bool every_other) {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    const bool same = centres_mm.size() == offered_.size() &&
                      std::equal(centres_mm.begin(), centres_mm.end(), offered_.begin());
    // A set passed over is built once the blood is no longer behind, even if no newer comes.
    if (same && !(passed_over_ && !every_other)) return;
    if (!same) {
      offered_.assign(centres_mm.begin(), centres_mm.end());
      if (every_other && !passed_over_) {
        passed_over_ = true;
        return;
      }
    }
    passed_over_ = false;
    pending_ = true;
  }
  changed_.notify_all();
}

std::shared_ptr<const Dlfl> LiquidWorker::newest(std::uint64_t& number) const {
  const std::lock_guard<std::mutex> lock(mutex_);
  number = number_;
  return newest_;
}

void LiquidWorker::settle() {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [&] { return !pending_ && !building_; });
}

void LiquidWorker::run() {
  std::vector<glm::dvec3> centres;
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait(lock, [&] { return stopping_ || pending_; });
      if (stopping_) return;
      centres.assign(offered_.begin(), offered_.end());
      passed_over_ = false;  // a set passed over while a build waited is built now
      pending_ = false;
      building_ = true;
    }
    run_only_on_a_free_core(true);
    auto built = std::make_shared<const Dlfl>(liquid_.update(centres));
    run_only_on_a_free_core(false);  // before the lock the render thread waits on
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      newest_ = std::move(built);
      ++number_;
      building_ = false;
    }
    changed_.notify_all();
  }
}

}  // namespace bisturi::runtime
