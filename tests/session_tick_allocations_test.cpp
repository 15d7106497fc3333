// No allocation in the haptic tick: the global allocation functions of this test program count
// the calls made on a thread while it is marked, and a live-shaped session's ticks (the tissue on
// its own thread, the arm and head tracker through their real drivers and twins) are marked
// through its degraded paths: contact, late steps, a hung tissue fading the force, a device gone
// silent, the display held. The tissue thread's haptic proxy keeps its contact patch in buffers
// of its own, so it allocates nothing in contact either.

#include <gtest/gtest.h>

#include <execinfo.h>

#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <string>
#include <thread>

#include "bisturi/sim/collision.h"
#include "bisturi/sim/haptic.h"
#include "haptic_rig.h"
#include "sim_test_shapes.h"

namespace {

thread_local bool g_counting = false;
thread_local bool g_counting_ticks = false;  ///< inside a counted tick (g_counting: and not a twin)
std::atomic<std::uint64_t> g_allocations{0};
/// Where the counted allocations came from (distinct return addresses), for the failure message.
std::array<void*, 64> g_sites{};
std::atomic<std::size_t> g_site_count{0};

void* counted(std::size_t n, std::size_t align) {
  if (g_counting) {
    g_allocations.fetch_add(1, std::memory_order_relaxed);
    void* site = __builtin_return_address(0);
    const std::size_t seen = std::min(g_site_count.load(std::memory_order_relaxed), g_sites.size());
    bool known = false;
    for (std::size_t i = 0; i < seen; ++i)
      known = known || g_sites[i] == site;
    if (!known) {
      const std::size_t i = g_site_count.fetch_add(1, std::memory_order_relaxed);
      if (i < g_sites.size()) g_sites[i] = site;
    }
  }
  void* p = align > alignof(std::max_align_t)
                ? std::aligned_alloc(align, (n + align - 1) / align * align)
                : std::malloc(n == 0 ? 1 : n);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}

}  // namespace

void* operator new(std::size_t n) {
  return counted(n, 0);
}
void* operator new[](std::size_t n) {
  return counted(n, 0);
}
void* operator new(std::size_t n, std::align_val_t a) {
  return counted(n, std::size_t(a));
}
void* operator new[](std::size_t n, std::align_val_t a) {
  return counted(n, std::size_t(a));
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return counted(n, 0);
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return counted(n, 0);
  } catch (...) {
    return nullptr;
  }
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete[](void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete(void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept {
  std::free(p);
}

namespace bisturi::runtime {
namespace {

using testing::arm_scene;
using testing::pressing_arm;
using testing::Rig;

std::string sites() {
  const std::size_t n = std::min(g_site_count.load(), g_sites.size());
  std::string out;
  char** names = backtrace_symbols(g_sites.data(), static_cast<int>(n));
  for (std::size_t i = 0; i < n && names != nullptr; ++i)
    out += std::string("\n  ") + names[i];
  std::free(names);
  return out;
}

/// Ticks `ticks` milliseconds of the rig, each followed (`paced`) by a wait for the tissue
/// thread to finish what it was handed, or not (the virtual clock then runs far ahead of the
/// tissue: late ticks); with `count`, this thread's allocations in the ticks are counted and
/// returned.
std::uint64_t paced_ticks(Rig& rig, int ticks, bool count = true, bool paced = true) {
  const std::uint64_t before = g_allocations.load();
  for (int i = 0; i < ticks; ++i) {
    rig.clock.advance(std::chrono::milliseconds(1));
    g_counting = g_counting_ticks = count;
    (void)rig.loop->tick(rig.clock.now());
    g_counting = g_counting_ticks = false;
    while (paced && rig.tissue->done() < rig.tissue->pushed())
      std::this_thread::yield();
  }
  return g_allocations.load() - before;
}

TEST(HapticTick, AllocatesNothingOnItsPaths) {
  Rig rig(arm_scene("[0.0, 0.0, 0.0]"), pressing_arm(DeviceFrame{}), /*threaded=*/true);
  // The twins stand in for the hardware: their own step is not the tick's (what they write
  // reaches the drivers through the virtual transport, which is).
  rig.twins_running = [](bool running) { g_counting = !running && g_counting_ticks; };
  // Until contact (the first ticks size what they keep: not counted).
  (void)paced_ticks(rig, 1000, false);
  ASSERT_GT(glm::length(rig.applied()), 0.0) << "pressing";
  EXPECT_EQ(paced_ticks(rig, 400), 0u) << "in contact" << sites();
  EXPECT_EQ(paced_ticks(rig, 100, true, false), 0u) << "late steps" << sites();
  EXPECT_GT(rig.loop->counters().late_ticks, 0u) << "the tissue thread lags the virtual clock";
  rig.hangable->hung = true;
  EXPECT_EQ(paced_ticks(rig, 200), 0u) << "a hung tissue" << sites();
  EXPECT_GT(rig.loop->counters().stale_ticks, 100u);
  rig.hangable->hung = false;
  rig.arm_muted = true;
  EXPECT_EQ(paced_ticks(rig, 300), 0u) << "a silent arm" << sites();
  EXPECT_GT(rig.loop->counters().hands[0].silent_ticks, 100u);
  rig.arm_muted = false;
  EXPECT_EQ(paced_ticks(rig, 200), 0u) << "back" << sites();
}

TEST(HapticProxy, AProbeInContactAllocatesNothingAfterItsFirstTouch) {
  // The tissue thread's proxy: the contact patch's triangles, vertices and weights go into
  // buffers the proxy keeps, so a probe moving over and into a tube allocates nothing once its
  // first contacts have sized them.
  sim::SoftBody tube(build_oriented_manifold(tube_mesh(6.0, 60.0, 16, 4)),
                     sim::testing::firm_material());
  const sim::CollisionDevice device;
  const sim::SurfaceBvh bvh(device, tube);
  sim::HapticOptions options;
  options.probe_radius_m = 0.0015;
  sim::HapticProxy proxy(options);
  const sim::TouchTarget target{&tube, &bvh};
  const auto press = [&](int step) {  // along the tube's side, 0.2 to 0.8 mm deep
    const double depth = 0.0002 + 0.0006 * (0.5 + 0.5 * std::sin(0.1 * step));
    return glm::dvec3(0.006 + 0.0015 - depth, 0.0, 0.020 + 0.00005 * step);
  };
  (void)proxy.update(glm::dvec3(0.010, 0.0, 0.020), {&target, 1}, 0.001);
  // Each step clears the forces the last one left on the tissue, as the world's step does.
  for (int step = 0; step < 50; ++step) {
    tube.clear_forces();
    ASSERT_TRUE(proxy.update(press(step), {&target, 1}, 0.001).contact) << "step " << step;
  }
  const std::uint64_t before = g_allocations.load();
  g_counting = true;
  bool contact = true;
  for (int step = 0; step < 50; ++step) {
    tube.clear_forces();
    contact = proxy.update(press(step), {&target, 1}, 0.001).contact && contact;
  }
  g_counting = false;
  EXPECT_TRUE(contact);
  EXPECT_EQ(g_allocations.load() - before, 0u) << sites();
}

}  // namespace
}  // namespace bisturi::runtime
