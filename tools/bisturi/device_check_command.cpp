// `bisturi device check DRIVER`: a driver against its twin as a session would use it.

#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "bisturi/devices/registry.h"
#include "bisturi/runtime/session/device_check.h"
#include "device_command.h"

namespace bisturi::cli {

namespace {

std::array<double, 3> three(const std::vector<double>& v) {
  return {v.at(0), v.at(1), v.at(2)};
}

nlohmann::json to_json(const runtime::DeviceCheckResult& r) {
  nlohmann::json channels = nlohmann::json::array();
  for (const runtime::DeviceCheckChannel& c : r.channels)
    channels.push_back({{"role", c.role},
                        {"components", c.components},
                        {"per_axis", c.per_axis},
                        {"unitless", c.unitless},
                        {"limit_N", c.limit_N},
                        {"rate_limit_N_per_s", c.rate_limit_N_per_s},
                        {"peak_command_N", c.peak_command_N},
                        {"peak_output_N", c.peak_output_N}});
  nlohmann::json events = nlohmann::json::array();
  for (const runtime::SessionEvent& e : r.events)
    events.push_back({{"kind", runtime::to_string(e.kind)},
                      {"time_s", static_cast<double>(e.tick) / r.haptic_hz},
                      {"body", e.body},
                      {"detail", e.detail}});
  nlohmann::json samples = nlohmann::json::array();
  for (const runtime::DeviceCheckSample& s : r.samples)
    samples.push_back({{"time_s", s.time_s},
                       {"tip_mm", {s.tip_mm.x, s.tip_mm.y, s.tip_mm.z}},
                       {"contact", s.contact},
                       {"command_N", s.command_N},
                       {"output_N", s.output_N}});
  return {{"driver", r.driver},
          {"summary", r.summary},
          {"device", r.device},
          {"seconds", r.seconds},
          {"haptic_hz", r.haptic_hz},
          {"ticks", r.ticks},
          {"channels", channels},
          {"buttons", r.buttons},
          {"clamped_forces", r.clamped},
          {"rate_limited_forces", r.rate_limited},
          {"guard_latches", r.guard_latches},
          {"malformed_reports", r.malformed_reports},
          {"silent_ticks", r.silent_ticks},
          {"untracked_ticks", r.untracked_ticks},
          {"events", events},
          {"samples", samples},
          {"warnings", r.warnings},
          {"passed", r.warnings.empty()}};
}

void print(const runtime::DeviceCheckResult& r) {
  std::printf("%s: %s\n  twin: %s\n  %.1f s of the default procedure at %.0f Hz, %llu ticks\n",
              r.driver.c_str(), r.summary.c_str(), r.device.c_str(), r.seconds, r.haptic_hz,
              static_cast<unsigned long long>(r.ticks));
  for (std::size_t i = 0; i < r.channels.size(); ++i) {
    const runtime::DeviceCheckChannel& c = r.channels[i];
    std::printf(
        "  channel %zu (%s, %u component%s): limit %.3g %s%s, rate limit %.3g/s; peak "
        "command %.3f, sent %.3f\n",
        i, c.role.c_str(), c.components, c.components == 1 ? "" : "s", c.limit_N,
        c.unitless ? "(fraction)" : "N", c.per_axis ? " per axis" : "", c.rate_limit_N_per_s,
        c.peak_command_N, c.peak_output_N);
  }
  std::string buttons;
  for (std::size_t i = 0; i < r.buttons.size(); ++i)
    buttons += (i > 0 ? ", " : "") + std::to_string(i) + " " + r.buttons[i];
  std::printf("  buttons: %s\n", buttons.empty() ? "none (button 0 cuts)" : buttons.c_str());
  std::printf("  guard: %llu clamped, %llu rate-limited, %llu latches; %llu malformed reports\n",
              static_cast<unsigned long long>(r.clamped),
              static_cast<unsigned long long>(r.rate_limited),
              static_cast<unsigned long long>(r.guard_latches),
              static_cast<unsigned long long>(r.malformed_reports));
  for (const runtime::SessionEvent& e : r.events)
    std::printf("  %6.3f s %s%s%s\n", static_cast<double>(e.tick) / r.haptic_hz,
                runtime::to_string(e.kind), e.detail.empty() ? "" : ": ", e.detail.c_str());
  std::printf("  %8s %26s  %s\n", "time s", "tip (scene mm)", "command -> sent (N)");
  for (const runtime::DeviceCheckSample& s : r.samples) {
    std::string forces;
    for (std::size_t k = 0; k < s.command_N.size(); ++k) {
      char text[48];
      std::snprintf(text, sizeof text, "%s%.3f->%.3f", k > 0 ? " " : "", s.command_N[k],
                    k < s.output_N.size() ? s.output_N[k] : 0.0);
      forces += text;
    }
    std::printf("  %8.3f (%7.2f %7.2f %7.2f) %s %s\n", s.time_s, s.tip_mm.x, s.tip_mm.y, s.tip_mm.z,
                s.contact ? "contact" : "       ", forces.c_str());
  }
  for (const std::string& w : r.warnings)
    std::printf("warning: %s\n", w.c_str());
  std::printf("%s\n", r.warnings.empty() ? "check: ok" : "check: see the warnings");
}

}  // namespace

void add_device_check_command(CLI::App& device, DeviceOptions& options,
                              int (*&run)(const DeviceOptions&)) {
  CLI::App* check = device.add_subcommand(
      "check",
      "run a driver against its simulated twin through the force guard and the haptic loop, "
      "following the default procedure on the default organ in virtual time, and show what a "
      "session would see: poses in the scene, commands and what the guard let through per "
      "channel, limits hit, rate limiting, events (exit 1: a warning, 2: it could not run)");
  check->add_option("DRIVER", options.input, "a registered driver with a twin (device list)")
      ->required();
  check->add_option("--seconds", options.seconds, "length of the procedure (virtual time)")
      ->check(CLI::Range(0.2, 600.0))
      ->capture_default_str();
  check->add_option("--max-force-N", options.max_force_N, "the scene's cap on the force")
      ->check(CLI::Range(0.01, 1000.0))
      ->capture_default_str();
  check
      ->add_option("--rotation-deg", options.rotation_deg,
                   "device_to_scene_rotation_deg: the device frame's rotation about x, y, z")
      ->expected(3);
  check
      ->add_option("--translation-mm", options.translation_mm,
                   "device_to_scene_translation_mm: the device frame's origin in the scene")
      ->expected(3);
  check->add_flag("--json", options.json, "write one JSON object on stdout");
  check->callback([&run] { run = run_device_check; });
}

int run_device_check(const DeviceOptions& options) {
  runtime::DeviceCheckOptions check;
  check.driver = options.input;
  check.seconds = options.seconds;
  check.max_force_N = options.max_force_N;
  check.rotation_deg = three(options.rotation_deg);
  check.translation_mm = three(options.translation_mm);
  runtime::DeviceCheckResult r;
  try {
    if (!options.json)
      std::fprintf(stderr, "checking %s against its twin (%.1f s, virtual time)...\n",
                   check.driver.c_str(), check.seconds);
    r = runtime::check_device(check, devices::builtin_registry());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bisturi device check: %s\n", e.what());
    return 2;
  }
  if (options.json)
    std::cout << to_json(r).dump(2) << "\n";
  else
    print(r);
  return r.warnings.empty() ? 0 : 1;
}

}  // namespace bisturi::cli
