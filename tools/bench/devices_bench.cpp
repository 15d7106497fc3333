// Devices: report parse + dispatch cost per report; the haptic tick's device work (poll(0) and a
// force send) on the virtual transport and on the asynchronous USB transport over the in-process
// bus (the libusb path's own logic, without hardware); and the end-to-end latency from an input
// report arriving on the virtual transport to the force report leaving it, at 1 kHz.
//   build/bin/devices_bench
#include <benchmark/benchmark.h>

#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/hid_drivers.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/devices/usb_async.h"
#include "bisturi/devices/vendor_arm.h"
#include "bisturi/devices/virtual_transport.h"

namespace bd = bisturi::devices;
using namespace std::chrono_literals;

namespace {

bd::DeviceScript moving_hand() {
  bd::DeviceScript script;
  for (int i = 0; i <= 10; ++i) {
    bd::MotionKey k;
    k.t = std::chrono::milliseconds(100 * i);
    k.pose.position_m = {0.01 * i, 0.02, -0.005 * i};
    k.joints_rad.assign(15, 0.1 * i);
    script.motion.push_back(k);
  }
  return script;
}

template <typename Twin, typename Open>
void parse_dispatch(benchmark::State& state, Twin& twin, Open open) {
  bd::VirtualClock clock;
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  auto device = open(std::move(pair.host), clock);
  std::vector<bd::Bytes> reports;
  for (int i = 0; i < 64; ++i) {
    twin.step(std::chrono::milliseconds(16 * i));
    while (auto r = device->poll(0us))
      (void)r;
  }
  // Collect raw reports straight from a second link.
  auto probe = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(probe.device));
  for (int i = 0; i < 64; ++i) {
    twin.step(std::chrono::milliseconds(2000 + 16 * i));
    if (auto r = probe.host->read(0us)) reports.push_back(*r);
  }
  std::size_t i = 0;
  for (auto _ : state) {
    device->handle_report(reports[i++ & 63]);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(std::to_string(reports[0].size()) + "-byte reports");
}

void BM_GloveReportParseDispatch(benchmark::State& state) {
  bd::SimulatedGlove twin(moving_hand());
  parse_dispatch(state, twin, [](std::unique_ptr<bd::Transport> t, bd::Clock& c) {
    return bd::open_hid_glove(std::move(t), c);
  });
}
BENCHMARK(BM_GloveReportParseDispatch);

void BM_TrackerReportParseDispatch(benchmark::State& state) {
  bd::SimulatedHeadTracker twin(moving_hand());
  parse_dispatch(state, twin, [](std::unique_ptr<bd::Transport> t, bd::Clock& c) {
    return bd::open_hid_tracker(std::move(t), c);
  });
}
BENCHMARK(BM_TrackerReportParseDispatch);

void BM_ArmPacketParseDispatch(benchmark::State& state) {
  bd::SimulatedArm twin(moving_hand());
  parse_dispatch(state, twin, [](std::unique_ptr<bd::Transport> t, bd::Clock& c) {
    return bd::open_vendor_arm(std::move(t), c);
  });
}
BENCHMARK(BM_ArmPacketParseDispatch);

void BM_GloveForceEncodeGuard(benchmark::State& state) {
  bd::SimulatedGlove twin(moving_hand());
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  auto glove = bd::open_hid_glove(std::move(pair.host));
  bd::ForceGuard guard(glove->capabilities().force_channels);
  std::vector<double> command(glove->capabilities().force_components(), 0.0), out(command.size());
  std::int64_t t = 0;
  for (auto _ : state) {
    t += 1000000;
    guard.device_answered(bd::Nanoseconds(t));
    guard.step(command, bd::Nanoseconds(t), out);
    glove->send_forces(out);
    command[0] = 1.0;
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_GloveForceEncodeGuard);

// The arm's transport for the tick benchmarks: the virtual link itself (Arg 0), or the
// asynchronous USB transport over the in-process bus (Arg 1).
std::unique_ptr<bd::Transport> arm_transport(bd::SimulatedArm& twin, bool usb) {
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  if (!usb) return std::move(pair.host);
  bd::AsyncUsbOptions options;
  options.in_packet_size = bd::arm_protocol::kPacketSize;
  return std::make_unique<bd::AsyncUsbTransport>(
      std::make_unique<bd::VirtualUsbIo>(std::move(pair.host)), twin.descriptor(), options);
}

const char* transport_label(const benchmark::State& state) {
  return state.range(0) ? "async usb over the in-process bus" : "virtual transport";
}

// poll(0) with nothing waiting: what every tick between two device reports pays.
void BM_ArmTickPollEmpty(benchmark::State& state) {
  bd::SimulatedArm twin(moving_hand());
  bd::VirtualClock clock;
  auto arm = bd::open_vendor_arm(arm_transport(twin, state.range(0) != 0), clock);
  for (auto _ : state)
    benchmark::DoNotOptimize(arm->poll(0us));
  state.SetLabel(transport_label(state));
}
BENCHMARK(BM_ArmTickPollEmpty)->Arg(0)->Arg(1);

// One device report sent by the twin and taken by poll(0), as at 1 kHz (the twin's encoding is in
// the figure, for both transports alike).
void BM_ArmTickPollOneReport(benchmark::State& state) {
  bd::SimulatedArm twin(moving_hand());
  bd::VirtualClock clock;
  auto arm = bd::open_vendor_arm(arm_transport(twin, state.range(0) != 0), clock);
  std::int64_t t = 0;
  for (auto _ : state) {
    t += 1000000;
    twin.step(bd::Nanoseconds(t));
    benchmark::DoNotOptimize(arm->poll(0us));
  }
  state.SetLabel(transport_label(state));
}
BENCHMARK(BM_ArmTickPollOneReport)->Arg(0)->Arg(1);

// One force packet encoded and sent, then the next tick's empty poll (on USB its event pass is what
// returns the OUT slot); the twin decodes the packet when it lands, for both alike.
void BM_ArmTickSend(benchmark::State& state) {
  bd::SimulatedArm twin(moving_hand());
  bd::VirtualClock clock;
  auto arm = bd::open_vendor_arm(arm_transport(twin, state.range(0) != 0), clock);
  double force[3] = {0.5, -0.25, 1.0};
  for (auto _ : state) {
    force[0] = -force[0];
    arm->send_forces(force);
    benchmark::DoNotOptimize(arm->poll(0us));
  }
  state.SetLabel(transport_label(state));
}
BENCHMARK(BM_ArmTickSend)->Arg(0)->Arg(1);

// A device thread steps the twin at 1 kHz (SteadyClock); the haptic thread blocks in poll, reads
// the pose, computes a spring force, guards it and sends it. Latency: from just before the twin
// writes its input report to the force report having left the host (the twin has received it).
template <typename Twin, typename Open>
void end_to_end(benchmark::State& state, Twin& twin, Open open) {
  bd::SteadyClock& clock = static_cast<bd::SteadyClock&>(bd::steady_clock());
  std::vector<double> latencies_us;
  for (auto _ : state) {
    auto pair = bd::make_virtual_pair(twin.descriptor());
    twin.attach(std::move(pair.device));
    auto device = open(std::move(pair.host), clock);
    auto* haptic = bd::as_haptic(device.get());
    bd::ForceGuardConfig config;
    config.deadline_margin = 1000ms;  // measure, do not latch on scheduler noise
    bd::ForceGuard guard(haptic->capabilities().force_channels, config);
    std::vector<double> command(guard.force_components(), 0.0), out(command.size());
    std::atomic<std::int64_t> sent_ns{0};
    std::atomic<bool> stop{false};
    const int reports = static_cast<int>(state.range(0));
    std::thread device_thread([&] {
      auto next = clock.now();
      for (int i = 0; i < reports && !stop; ++i) {
        next += 1ms;
        clock.sleep_until(next);
        sent_ns = clock.now().count();
        twin.step(next);
      }
    });
    latencies_us.clear();
    while (static_cast<int>(latencies_us.size()) < reports) {
      if (device->poll(200ms) == 0) break;
      const auto& pose = haptic->state().end_effector_poses[0].position_m;
      for (std::size_t i = 0; i < command.size(); ++i)
        command[i] = -50.0 * pose.x * 0.01;
      guard.device_answered(clock.now());
      guard.step(command, clock.now(), out);
      haptic->send_forces(out);
      latencies_us.push_back(static_cast<double>(clock.now().count() - sent_ns.load()) / 1000.0);
    }
    stop = true;
    device_thread.join();
  }
  std::sort(latencies_us.begin(), latencies_us.end());
  if (!latencies_us.empty()) {
    state.counters["p50_us"] = latencies_us[latencies_us.size() / 2];
    state.counters["p99_us"] = latencies_us[latencies_us.size() * 99 / 100];
    state.counters["max_us"] = latencies_us.back();
    state.counters["reports"] = static_cast<double>(latencies_us.size());
  }
}

void BM_GloveEndToEnd1kHz(benchmark::State& state) {
  bd::SimulatedGlove twin(moving_hand());
  end_to_end(state, twin, [](std::unique_ptr<bd::Transport> t, bd::Clock& c) {
    return bd::open_hid_glove(std::move(t), c);
  });
}
BENCHMARK(BM_GloveEndToEnd1kHz)->Arg(2000)->Iterations(1)->Unit(benchmark::kMillisecond);

void BM_ArmEndToEnd1kHz(benchmark::State& state) {
  bd::SimulatedArm twin(moving_hand());
  end_to_end(state, twin, [](std::unique_ptr<bd::Transport> t, bd::Clock& c) {
    return bd::open_vendor_arm(std::move(t), c);
  });
}
BENCHMARK(BM_ArmEndToEnd1kHz)->Arg(2000)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
