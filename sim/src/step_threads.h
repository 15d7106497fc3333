#pragma once
// A fixed team of threads for the parallel passes of one soft-tissue step
// (IntegratorOptions::threads). run(job) calls job(t) once for every part t < size() and returns
// when all are done: the calling thread does part 0, then every thread of the team, the caller
// included, claims the parts left. Helpers wait for the next job spinning for a short while (a
// step's passes come microseconds apart), then sleeping on an atomic wait. What a part computes
// depends on t alone, not on the thread that runs it, so a pass that combines its parts' partial
// sums in part order gives the same bits run after run; and when a helper is not scheduled
// (more runnable threads than cores), the caller does its parts instead of waiting for it.

#include <atomic>
#include <cstdint>
#include <functional>
#include <thread>
#include <vector>

namespace bisturi::sim {

/// The most members a team has (passes keep their partial sums in arrays of this size).
constexpr unsigned kMaxThreads = 64;

class StepThreads {
 public:
  /// Pauses a helper spins for the next job before it sleeps: about 50-100 us.
  static constexpr unsigned kDefaultSpins = 20000;

  explicit StepThreads(unsigned threads);
  /// The same with each helper calling `on_start` first (on its own thread: a scheduling
  /// policy, say) and spinning `spins` pauses for the next job before it sleeps (a helper that
  /// may share a core with the caller should spin little).
  StepThreads(unsigned threads, unsigned spins, const std::function<void()>& on_start);
  /// A sequential team: no threads; run(job) calls job(0), ..., job(parts - 1) in turn on the
  /// calling thread and `after_part` after each (the multirate far field suspends its fiber
  /// there when its slice of the step is used up). Its parts run one at a time, so they may
  /// share arrays (sequential()).
  StepThreads(unsigned parts, std::function<void()> after_part);
  ~StepThreads();
  StepThreads(const StepThreads&) = delete;
  StepThreads& operator=(const StepThreads&) = delete;

  [[nodiscard]] unsigned size() const { return parts_; }
  [[nodiscard]] bool sequential() const { return static_cast<bool>(after_part_); }
  void run(const std::function<void(unsigned)>& job);
  /// A sequential team's hook between two pieces of work that are not parts (nothing for a
  /// team of threads).
  void checkpoint() const {
    if (after_part_) after_part_();
  }

 private:
  void work();
  /// Claims and runs parts of the current job until none is left.
  void run_claimed_parts();

  unsigned parts_ = 1;
  std::function<void()> after_part_;  ///< set for a sequential team
  std::vector<std::thread> workers_;
  const std::function<void(unsigned)>* job_ = nullptr;
  /// The job's generation (high 32 bits) and the next part to claim (low 32): a claim is a
  /// compare-and-swap on both, so a helper that wakes late cannot claim a part of a newer job
  /// under an older job's pointer.
  std::atomic<std::uint64_t> claim_{0};
  std::atomic<unsigned> unfinished_{0};  ///< parts claimed or not, not done yet
  std::atomic<bool> stop_{false};
  unsigned spins_ = kDefaultSpins;
};

/// [begin, end) of part t of n items split into `parts` nearly equal runs, each starting at a
/// multiple of `align`.
struct Range {
  std::size_t begin = 0, end = 0;
};
inline Range part_of(std::size_t n, unsigned parts, unsigned t, std::size_t align = 1) {
  const auto cut = [&](unsigned k) {
    const std::size_t at = n * k / parts;
    return k == parts ? n : std::min(n, (at + align - 1) / align * align);
  };
  return {cut(t), cut(t + 1)};
}

/// Calls part(begin, end, t) for every member t of the team on its run of n items (each run
/// starting at a multiple of `align`), or part(0, n, 0) on the calling thread when there is no
/// team.
template <class Part>
void run_parts(StepThreads* team, std::size_t n, const Part& part, std::size_t align = 1) {
  if (team == nullptr) {
    part(std::size_t{0}, n, 0u);
    return;
  }
  const unsigned members = team->size();
  auto job = [&](unsigned t) {
    const Range r = part_of(n, members, t, align);
    part(r.begin, r.end, t);
  };
  team->run([&job](unsigned t) { job(t); });
}

}  // namespace bisturi::sim
