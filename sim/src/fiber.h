#pragma once
// A fiber: a function run on a stack of its own, on the calling thread, that can stop part-way
// (Fiber::suspend, called from inside it) and be resumed later where it stopped. The multirate
// far field's solve runs in one, a slice per step, so it shares the step's core without a
// second thread and the step's time stays bounded (integrator_far_field.cpp). Built on
// ucontext; the stack has a guard page below it.

#include <cstddef>
#include <exception>
#include <functional>

#include <ucontext.h>

namespace bisturi::sim {

class Fiber {
 public:
  explicit Fiber(std::size_t stack_bytes = std::size_t{1} << 20);
  /// A fiber destroyed part-way is first resumed to its end (its stack holds live objects).
  ~Fiber();
  Fiber(const Fiber&) = delete;
  Fiber& operator=(const Fiber&) = delete;

  /// Sets the function the next resume() starts; the fiber must not be part-way.
  void start(std::function<void()> body);
  /// Runs the function until it suspends or returns; true when it has returned (then an
  /// exception it let out is thrown here).
  bool resume();
  /// Started and not yet returned.
  [[nodiscard]] bool part_way() const { return started_ && !finished_; }
  /// From inside a fiber's function: back to the resume() that ran it.
  static void suspend();
  /// The fiber whose function is running on this thread, or nullptr.
  static Fiber* current();

 private:
  static void entry();

  std::size_t stack_bytes_ = 0;
  char* mapping_ = nullptr;  ///< guard page + stack
  std::size_t mapping_bytes_ = 0;
  ucontext_t context_{};  ///< the function's
  ucontext_t caller_{};   ///< the resume()'s
  std::function<void()> body_;
  std::exception_ptr error_;
  bool started_ = false, finished_ = true;
  Fiber* outer_ = nullptr;  ///< the fiber current when resume() was called
  // AddressSanitizer's view of the stacks (unused without it).
  void* fake_stack_ = nullptr;
  const void* caller_bottom_ = nullptr;
  std::size_t caller_size_ = 0;
};

}  // namespace bisturi::sim
