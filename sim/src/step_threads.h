#pragma once
// A fixed team of threads for the parallel passes of one soft-tissue step
// (IntegratorOptions::threads). run(job) calls job(t) for every member t, member 0 on the calling
// thread, and returns when all are done. Members wait for the next job spinning for a short
// while (a step's passes come microseconds apart), then sleeping on an atomic wait. Which member
// does which part is fixed by t alone, so a pass that combines its members' partial sums in
// member order gives the same bits run after run.

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
  explicit StepThreads(unsigned threads);
  ~StepThreads();
  StepThreads(const StepThreads&) = delete;
  StepThreads& operator=(const StepThreads&) = delete;

  [[nodiscard]] unsigned size() const { return static_cast<unsigned>(workers_.size()) + 1; }
  void run(const std::function<void(unsigned)>& job);

 private:
  void work(unsigned member);

  std::vector<std::thread> workers_;
  const std::function<void(unsigned)>* job_ = nullptr;
  std::atomic<std::uint32_t> generation_{0};
  std::atomic<unsigned> pending_{0};
  std::atomic<bool> stop_{false};
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
