// The machine's own floor for a fixed-rate loop: a thread that does nothing but wake at every
// period (the haptic thread's sleep-then-spin, SCHED_FIFO when allowed) and counts how late it
// started. A session cannot miss fewer deadlines than this loop misses on the same machine at the
// same time, so `bisturi run`'s missed_by_late_wakeup is read against it. `--spin-us auto` spins
// as the session does by default (wakeup_spin.h): as long as the wakeups have lately come late.
//
//   timer_bench [--seconds S] [--hz RATE] [--spin-us US|auto] [--json]

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "bisturi/devices/clock.h"
#include "session/wakeup_spin.h"

namespace {

struct Options {
  double seconds = 10.0;
  double hz = 1000.0;
  double spin_us = 200.0;
  bool adaptive_spin = false;  ///< --spin-us auto: at most spin_us, as the wakeups need
  bool json = false;
};

void usage() {
  std::puts(
      "timer_bench: how late a fixed-rate thread that does no work is woken on this machine\n"
      "  --seconds S   how long to run (default 10)\n"
      "  --hz RATE     loop rate (default 1000)\n"
      "  --spin-us US  sleep until this long before each deadline, then spin (default 200);\n"
      "                auto: as long as the wakeups have lately come late, 20 to 200 us (the\n"
      "                99th percentile of the last 512 plus 10 us), as bisturi run does\n"
      "  --json        one JSON object on stdout");
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&]() -> double {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "timer_bench: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      char* end = nullptr;
      const double v = std::strtod(argv[++i], &end);
      if (end == argv[i] || *end != '\0' || !(v > 0.0)) {
        std::fprintf(stderr, "timer_bench: %s: '%s' is not a positive number\n", a.c_str(),
                     argv[i]);
        std::exit(2);
      }
      return v;
    };
    if (a == "--help" || a == "-h") {
      usage();
      std::exit(0);
    } else if (a == "--seconds") {
      o.seconds = value();
    } else if (a == "--hz") {
      o.hz = value();
    } else if (a == "--spin-us") {
      if (i + 1 < argc && std::strcmp(argv[i + 1], "auto") == 0) {
        o.adaptive_spin = true;
        ++i;
      } else {
        o.spin_us = value();
      }
    } else if (a == "--json") {
      o.json = true;
    } else {
      std::fprintf(stderr, "timer_bench: unknown option '%s' (see --help)\n", a.c_str());
      std::exit(2);
    }
  }
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  const Options o = parse(argc, argv);
  sched_param p{};
  p.sched_priority = std::max(1, sched_get_priority_max(SCHED_FIFO) / 2);  // as the session
  const bool realtime = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p) == 0;

  bisturi::devices::SteadyClock clock;
  const auto period = std::chrono::nanoseconds(static_cast<long long>(1e9 / o.hz));
  const auto fixed_spin = std::chrono::nanoseconds(static_cast<long long>(o.spin_us * 1e3));
  bisturi::runtime::WakeupSpin adaptive(
      bisturi::runtime::WakeupSpin::Limits{.ceiling = fixed_spin});
  double spin_sum_us = 0.0;
  const auto ticks = static_cast<std::size_t>(o.seconds * o.hz);
  std::vector<double> late_ms;
  late_ms.reserve(ticks);
  auto next = clock.now() + period;
  for (std::size_t i = 0; i < ticks; ++i) {
    const auto spin = o.adaptive_spin ? adaptive.spin() : fixed_spin;
    spin_sum_us += static_cast<double>(spin.count()) * 1e-3;
    if (const auto late = bisturi::runtime::sleep_then_spin(clock, next, spin))
      adaptive.woke(*late);
    late_ms.push_back(std::chrono::duration<double, std::milli>(clock.now() - next).count());
    next += period;
    if (clock.now() > next) {  // a whole period behind: skip, as the session does
      const auto behind = (clock.now() - next) / period;
      next += period * behind;
    }
    if (!o.json && i % static_cast<std::size_t>(o.hz) == 0)
      std::fprintf(stderr, "\rtimer_bench %.0f/%.0f s", static_cast<double>(i) / o.hz, o.seconds);
  }
  if (!o.json) std::fprintf(stderr, "\n");
  const double period_ms = 1e3 / o.hz;
  const double spin_mean_us = ticks > 0 ? spin_sum_us / static_cast<double>(ticks) : 0.0;
  const auto missed = static_cast<std::size_t>(
      std::count_if(late_ms.begin(), late_ms.end(), [&](double l) { return l > period_ms; }));
  std::vector<double> sorted = late_ms;
  std::sort(sorted.begin(), sorted.end());
  const auto at = [&](double q) {
    return sorted.empty() ? 0.0 : sorted[static_cast<std::size_t>(q * double(sorted.size() - 1))];
  };
  if (o.json) {
    std::printf(
        "{\"ticks\": %zu, \"realtime_priority\": %s, \"missed_deadlines\": %zu, "
        "\"late_ms\": {\"p50\": %.6f, \"p99\": %.6f, \"max\": %.6f}, \"spin_us_mean\": %.3f}\n",
        late_ms.size(), realtime ? "true" : "false", missed, at(0.5), at(0.99), at(1.0),
        spin_mean_us);
  } else {
    std::printf(
        "%zu ticks at %.0f Hz (%s): %zu started more than a period late; lateness p50 %.4f ms, "
        "p99 %.4f ms, max %.3f ms; spin %.1f us on average\n",
        late_ms.size(), o.hz, realtime ? "SCHED_FIFO" : "normal priority", missed, at(0.5),
        at(0.99), at(1.0), spin_mean_us);
  }
  return 0;
}
