#pragma once
// Work that runs only on a core the session's other threads leave free: the blood's steps and
// its liquid surface (blood_worker.cpp, liquid_worker.cpp).

#include <pthread.h>
#include <sched.h>

namespace bisturi::runtime {

/// The calling thread's policy: SCHED_IDLE while `only_when_free` (it runs only on a core no
/// other thread of the session wants, and any of them that wakes takes the core at once), the
/// ordinary policy otherwise, as before it takes a lock another thread waits on (so that thread
/// never waits for an idle core).
inline void run_only_on_a_free_core(bool only_when_free) {
  sched_param p{};
  p.sched_priority = 0;
  (void)pthread_setschedparam(pthread_self(), only_when_free ? SCHED_IDLE : SCHED_OTHER, &p);
}

}  // namespace bisturi::runtime
