#pragma once
// A lock-free single-producer / single-consumer hand-off of the newest value (the seed's figure
// 33 as threads: the haptic thread publishes, the render thread takes the newest snapshot).
// Three slots: the producer writes the back slot and swaps it with the middle one; the consumer
// swaps the middle one with its front slot when a new value is there. Neither ever waits, the
// consumer never sees a half-written value, and values the consumer was too slow to take are
// simply replaced (the renderer wants the newest state, not every state).

#include <array>
#include <atomic>
#include <cstdint>
#include <utility>

namespace bisturi::runtime {

template <class T>
class TripleBuffer {
 public:
  TripleBuffer() = default;
  explicit TripleBuffer(const T& initial) : slots_{initial, initial, initial} {}

  /// Producer side: the slot to fill (only the producer touches it until publish()).
  T& back() { return slots_[back_]; }

  /// Producer side: makes back() the newest value; back() then refers to a free slot.
  void publish() {
    const std::uint8_t fresh = static_cast<std::uint8_t>(back_ | kFreshBit);
    back_ =
        static_cast<std::uint8_t>(middle_.exchange(fresh, std::memory_order_acq_rel) & kIndexMask);
  }

  /// Consumer side: takes the newest published value if there is one since the last take.
  /// Returns true when front() changed.
  bool take() {
    if ((middle_.load(std::memory_order_relaxed) & kFreshBit) == 0) return false;
    front_ =
        static_cast<std::uint8_t>(middle_.exchange(front_, std::memory_order_acq_rel) & kIndexMask);
    return true;
  }

  /// Consumer side: the value taken last (the initial value before the first take).
  const T& front() const { return slots_[front_]; }

 private:
  static constexpr std::uint8_t kFreshBit = 0x4;
  static constexpr std::uint8_t kIndexMask = 0x3;

  std::array<T, 3> slots_{};
  std::uint8_t back_ = 0;                // producer only
  std::atomic<std::uint8_t> middle_{1};  // shared: index | fresh bit
  std::uint8_t front_ = 2;               // consumer only
};

}  // namespace bisturi::runtime
