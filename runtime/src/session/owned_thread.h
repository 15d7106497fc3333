#pragma once
// A session thread with an owner that always joins it. run_session joins its threads in order
// when the session ends; when an exception unwinds it first (a thread that cannot start, the
// watching loop running out of memory), the owner runs the thread's stop action (which for the
// haptic thread zeros the device) and joins, instead of std::thread's std::terminate with the
// last force still on the hand.

#include <functional>
#include <thread>
#include <utility>

namespace bisturi::runtime {

class OwnedThread {
 public:
  /// Starts `body`; `stop` must make it return soon (set its flags, zero the device). Throws
  /// std::system_error when the thread cannot start.
  template <class Body>
  OwnedThread(Body&& body, std::function<void()> stop)
      : stop_(std::move(stop)), thread_(std::forward<Body>(body)) {}
  OwnedThread(const OwnedThread&) = delete;
  OwnedThread& operator=(const OwnedThread&) = delete;
  ~OwnedThread() {
    if (!thread_.joinable()) return;
    if (stop_) stop_();
    thread_.join();
  }
  /// The ordinary end: waits for the thread (which was told to stop some other way).
  void join() {
    if (thread_.joinable()) thread_.join();
  }

 private:
  std::function<void()> stop_;
  std::thread thread_;
};

}  // namespace bisturi::runtime
