#include "device_command.h"

#include <CLI/CLI.hpp>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bisturi/devices/hid_descriptor.h"
#include "bisturi/devices/hid_drivers.h"
#include "bisturi/devices/host_transports.h"
#include "bisturi/devices/registry.h"
#include "hid_names.h"

namespace bisturi::cli {

namespace {

namespace hid = devices::hid;

constexpr int kExitMalformed = 2;

std::vector<std::uint8_t> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot be opened");
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

nlohmann::json field_json(const hid::Field& f) {
  nlohmann::json usages = nlohmann::json::array();
  for (std::uint32_t u : f.usages)
    usages.push_back(usage_name(u));
  return {{"bit_offset", f.bit_offset},
          {"bit_size", f.bit_size},
          {"count", f.count},
          {"variable", f.is_variable()},
          {"relative", f.is_relative()},
          {"logical_min", f.logical_min},
          {"logical_max", f.logical_max},
          {"physical_min", f.physical_min},
          {"physical_max", f.physical_max},
          {"unit", hex(f.unit.code, 4)},
          {"unit_exponent", f.unit.exponent},
          {"usages", usages}};
}

std::string field_line(const hid::Field& f) {
  std::string line = "bits " + std::to_string(f.bit_offset) + "+" + std::to_string(f.count) + "x" +
                     std::to_string(f.bit_size) + (f.is_variable() ? " var" : " array") + " [" +
                     std::to_string(f.logical_min) + ".." + std::to_string(f.logical_max) + "]";
  if (f.unit.code != 0)
    line += " unit " + hex(f.unit.code, 4) + " exp " + std::to_string(f.unit.exponent);
  line += ":";
  const std::size_t shown = std::min<std::size_t>(f.usages.size(), 4);
  for (std::size_t i = 0; i < shown; ++i)
    line += (i ? ", " : " ") + usage_name(f.usages[i]);
  if (f.usages.size() > shown) line += ", ... (" + std::to_string(f.usages.size()) + " usages)";
  if (f.usages.empty()) line += " (no usage)";
  return line;
}

std::string claimed_by(const devices::Registry& registry, const devices::DeviceDescriptor& d) {
  const devices::DriverInfo* driver = registry.find(d);
  return driver ? driver->name : std::string();
}

}  // namespace

void add_device_command(CLI::App& app, DeviceOptions& options, int (*&run)(const DeviceOptions&)) {
  CLI::App* device = app.add_subcommand(
      "device", "what is connected and which driver claims it; HID report descriptors explained");
  device->require_subcommand(1);

  CLI::App* list = device->add_subcommand(
      "list",
      "list the HID (hidapi) and vendor-specific USB (libusb) devices connected now and "
      "the driver that claims each (an empty list when none is connected)");
  list->add_flag("--json", options.json, "write one JSON object on stdout");
  list->callback([&run] { run = run_device_list; });

  CLI::App* describe = device->add_subcommand(
      "describe",
      "explain a HID report descriptor (raw bytes, e.g. a copy of "
      "/sys/class/hidraw/hidrawN/device/report_descriptor): reports with their sizes, fields, "
      "usages, and whether the generic glove or tracker driver can use it (exit 2: malformed)");
  describe->add_option("DESCRIPTOR", options.input, "report descriptor file (.bin)")
      ->required()
      ->check(CLI::ExistingFile);
  describe->add_flag("--json", options.json, "write one JSON object on stdout");
  describe->callback([&run] { run = run_device_describe; });
  add_device_check_command(*device, options, run);

  CLI::App* udev = device->add_subcommand(
      "udev-rules",
      "print udev rules that let the logged-in user (and the plugdev group) open the devices "
      "the registered drivers claim, without root: save as /etc/udev/rules.d/70-bisturi.rules, "
      "then run `udevadm control --reload && udevadm trigger`");
  udev->callback([&run] { run = run_device_udev_rules; });
}

namespace {

/// A driver as `device list` shows it: what it opens, where, the USB ids it claims, whether it
/// has a twin (scenes can simulate it), the roles of its force channels (empty: by shape) and
/// what its buttons do, by bit (by default button 0 cuts).
nlohmann::json driver_json(const devices::DriverInfo& d) {
  nlohmann::json ids = nlohmann::json::array();
  for (const devices::UsbId& id : d.usb_ids)
    ids.push_back(hex(id.vendor_id, 4) + ":" + hex(id.product_id, 4));
  nlohmann::json channels = nlohmann::json::array();
  for (const devices::ChannelRole& r : d.layout.channels) {
    std::string role = devices::to_string(r.use);
    if (r.use == devices::ChannelUse::Finger) role += " " + std::to_string(r.finger);
    channels.push_back(role);
  }
  nlohmann::json buttons = nlohmann::json::array();
  if (d.device_class != devices::DeviceClass::HeadTracker) {
    for (const devices::ButtonUse use :
         d.layout.buttons.empty() ? std::vector<devices::ButtonUse>{devices::ButtonUse::Cut}
                                  : d.layout.buttons)
      buttons.push_back(devices::to_string(use));
  }
  return {{"name", d.name},
          {"bus", devices::to_string(d.bus)},
          {"buttons", buttons},
          {"class", devices::to_string(d.device_class)},
          {"summary", d.summary},
          {"usb_ids", ids},
          {"twin", static_cast<bool>(d.make_twin)},
          {"channels", channels}};
}

}  // namespace

int run_device_udev_rules(const DeviceOptions&) {
  // Raw USB devices are opened through /dev/bus/usb (libusb), HID ones through /dev/hidraw*
  // (hidapi's hidraw backend); both are root's alone unless a rule says otherwise. uaccess gives
  // the user at the seat access (systemd-logind), plugdev covers remote and headless users.
  const devices::Registry registry = devices::builtin_registry();
  std::cout << "# udev rules for bisturi's drivers (generated by `bisturi device udev-rules` from\n"
               "# its driver registry). Save as /etc/udev/rules.d/70-bisturi.rules, then run\n"
               "#   udevadm control --reload && udevadm trigger\n"
               "# and plug the device in again.\n";
  for (const devices::DriverInfo& d : registry.drivers()) {
    if (d.bus == devices::TransportKind::Virtual) continue;
    std::cout << "\n# " << d.name << ": " << d.summary << "\n";
    if (d.usb_ids.empty()) {
      // sysfs gives the ids in lower-case hex, and udev compares them as text.
      std::cout
          << "# claims devices by their report descriptor: uncomment with your device's "
             "vendor and product id\n# (lower-case hex without 0x, as udev reads them from sysfs)\n"
          << (d.bus == devices::TransportKind::Usb
                  ? "# SUBSYSTEM==\"usb\", ATTR{idVendor}==\"vvvv\", ATTR{idProduct}==\"pppp\""
                  : "# KERNEL==\"hidraw*\", SUBSYSTEM==\"hidraw\", "
                    "ATTRS{idVendor}==\"vvvv\", ATTRS{idProduct}==\"pppp\"")
          << ", MODE=\"0660\", GROUP=\"plugdev\", TAG+=\"uaccess\"\n";
      continue;
    }
    for (const devices::UsbId& id : d.usb_ids) {
      char vendor[8], product[8];
      std::snprintf(vendor, sizeof vendor, "%04x", id.vendor_id);
      std::snprintf(product, sizeof product, "%04x", id.product_id);
      if (d.bus == devices::TransportKind::Usb) {
        std::cout << "SUBSYSTEM==\"usb\", ATTR{idVendor}==\"" << vendor << "\", ATTR{idProduct}==\""
                  << product << "\", MODE=\"0660\", GROUP=\"plugdev\", TAG+=\"uaccess\"\n";
      } else {
        std::cout << "KERNEL==\"hidraw*\", SUBSYSTEM==\"hidraw\", ATTRS{idVendor}==\"" << vendor
                  << "\", ATTRS{idProduct}==\"" << product
                  << "\", MODE=\"0660\", GROUP=\"plugdev\", TAG+=\"uaccess\"\n";
      }
    }
  }
  return 0;
}

int run_device_list(const DeviceOptions& options) {
  const devices::Registry registry = devices::builtin_registry();
  nlohmann::json listed = nlohmann::json::array();
  nlohmann::json problems = nlohmann::json::array();
  const auto scan = [&](const char* bus, auto make_source) {
    try {
      auto source = make_source();
      for (const devices::DeviceDescriptor& d : source->enumerate()) {
        const std::string driver = claimed_by(registry, d);
        listed.push_back(
            {{"bus", bus},
             {"vendor_id", hex(d.vendor_id, 4)},
             {"product_id", hex(d.product_id, 4)},
             {"product", d.product},
             {"serial", d.serial},
             {"path", d.path},
             {"report_descriptor_bytes", d.report_descriptor.size()},
             {"driver", driver.empty() ? nlohmann::json(nullptr) : nlohmann::json(driver)}});
      }
    } catch (const std::exception& e) {
      problems.push_back(std::string(bus) + ": " + e.what());
    }
  };
  scan("hid", [] { return std::make_unique<devices::HidSource>(); });
  scan("usb", [] { return std::make_unique<devices::UsbSource>(); });
  if (options.json) {
    nlohmann::json drivers = nlohmann::json::array();
    for (const devices::DriverInfo& d : registry.drivers())
      drivers.push_back(driver_json(d));
    std::cout
        << nlohmann::json{{"devices", listed}, {"problems", problems}, {"drivers", drivers}}.dump(2)
        << "\n";
    return 0;
  }
  if (listed.empty()) std::cout << "no HID or vendor-specific USB device connected\n";
  for (const auto& d : listed) {
    std::cout << d["bus"].get<std::string>() << " " << d["vendor_id"].get<std::string>() << ":"
              << d["product_id"].get<std::string>() << " " << d["product"].get<std::string>()
              << " (serial " << d["serial"].get<std::string>() << ", "
              << d["path"].get<std::string>() << "): "
              << (d["driver"].is_null() ? std::string("no driver claims it")
                                        : "driver " + d["driver"].get<std::string>())
              << "\n";
  }
  for (const auto& p : problems)
    std::cout << "could not list " << p.get<std::string>() << "\n";
  std::cout << "drivers:\n";
  for (const devices::DriverInfo& d : registry.drivers()) {
    const nlohmann::json j = driver_json(d);
    std::cout << "  " << d.name << " (" << j["bus"].get<std::string>() << ", "
              << j["class"].get<std::string>() << (d.make_twin ? ", simulated twin" : "")
              << "): " << d.summary;
    if (!j["usb_ids"].empty()) {
      std::cout << "; claims";
      for (const auto& id : j["usb_ids"])
        std::cout << " " << id.get<std::string>();
    }
    std::cout << "; force channels: ";
    if (d.device_class == devices::DeviceClass::HeadTracker)
      std::cout << "none";
    else if (j["channels"].empty())
      std::cout << "by their shape (3 axes a vector, 1 a finger)";
    for (std::size_t i = 0; i < j["channels"].size(); ++i)
      std::cout << (i > 0 ? ", " : "") << j["channels"][i].get<std::string>();
    for (std::size_t i = 0; i < j["buttons"].size(); ++i)
      std::cout << (i == 0 ? "; buttons: " : ", ") << i << " "
                << j["buttons"][i].get<std::string>();
    std::cout << "\n";
  }
  return 0;
}

int run_device_describe(const DeviceOptions& options) {
  const std::vector<std::uint8_t> bytes = read_bytes(options.input);
  hid::ReportDescriptor d;
  devices::GenericHidFit fit;
  try {
    d = hid::parse_report_descriptor(bytes, options.input);
    fit = devices::assess_generic_hid(bytes);
  } catch (const devices::ProtocolError& e) {
    if (options.json) {
      std::cout << nlohmann::json{{"file", options.input},
                                  {"error", {{"offset", e.offset()}, {"reason", e.reason()}}}}
                       .dump(2)
                << "\n";
    }
    std::cerr << "bisturi: error: malformed report descriptor: " << e.what() << "\n";
    return kExitMalformed;
  }
  nlohmann::json reports = nlohmann::json::array();
  for (const hid::ReportInfo& r : d.reports) {
    nlohmann::json fields = nlohmann::json::array();
    for (const hid::Field& f : d.fields)
      if (f.type == r.type && f.report_id == r.id) fields.push_back(field_json(f));
    reports.push_back({{"type", hid::to_string(r.type)},
                       {"id", r.id},
                       {"bits", r.bits},
                       {"bytes", r.bytes()},
                       {"fields", fields}});
  }
  nlohmann::json collections = nlohmann::json::array();
  for (const hid::Collection& c : d.collections)
    collections.push_back({{"type", c.type}, {"usage", usage_name(c.usage)}, {"parent", c.parent}});
  const auto verdict = [](bool ok, const std::string& why) {
    return nlohmann::json{{"usable", ok},
                          {"why_not", ok ? nlohmann::json(nullptr) : nlohmann::json(why)}};
  };
  if (options.json) {
    std::cout << nlohmann::json{{"file", options.input},
                                {"bytes", bytes.size()},
                                {"uses_report_ids", d.uses_report_ids},
                                {"application", usage_name(d.application_usage())},
                                {"reports", reports},
                                {"collections", collections},
                                {"warnings", d.warnings},
                                {"generic_drivers",
                                 {{"hid-glove", verdict(fit.glove, fit.glove_why)},
                                  {"hid-tracker", verdict(fit.tracker, fit.tracker_why)},
                                  {"found", fit.found}}}}
                     .dump(2)
              << "\n";
    return 0;
  }
  std::cout << options.input << ": " << bytes.size() << " bytes, application "
            << usage_name(d.application_usage()) << ", "
            << (d.uses_report_ids ? "report ids" : "no report ids") << "\n";
  for (const auto& r : reports) {
    std::cout << "  " << r["type"].get<std::string>() << " report " << r["id"].get<int>() << ": "
              << r["bits"].get<std::uint32_t>() << " bits, " << r["bytes"].get<std::size_t>()
              << " bytes on the wire\n";
    for (const hid::Field& f : d.fields)
      if (hid::to_string(f.type) == r["type"].get<std::string>() && f.report_id == r["id"])
        std::cout << "    " << field_line(f) << "\n";
  }
  for (const std::string& w : d.warnings)
    std::cout << "  warning: " << w << "\n";
  std::cout << "  hid-glove: "
            << (fit.glove ? std::string("can use it") : "cannot use it: " + fit.glove_why) << "\n";
  std::cout << "  hid-tracker: "
            << (fit.tracker ? std::string("can use it") : "cannot use it: " + fit.tracker_why)
            << "\n";
  if (!fit.found.empty()) {
    std::cout << "  the generic drivers would read:";
    for (std::size_t i = 0; i < fit.found.size(); ++i)
      std::cout << (i ? ", " : " ") << fit.found[i];
    std::cout << "\n";
  }
  return 0;
}

}  // namespace bisturi::cli
