// HID devices through hidapi (hidraw backend).
#include <hidapi/hidapi.h>

#include <algorithm>
#include <atomic>
#include <fstream>
#include <iterator>
#include <mutex>

#include "bisturi/devices/hid_descriptor.h"
#include "bisturi/devices/host_transports.h"

namespace bisturi::devices {

namespace {

std::mutex init_mutex;
int init_count = 0;

void hid_acquire() {
  std::lock_guard lock(init_mutex);
  if (init_count == 0 && hid_init() != 0) throw DeviceError("hidapi: hid_init failed");
  ++init_count;
}

void hid_release() {
  std::lock_guard lock(init_mutex);
  if (--init_count == 0) hid_exit();
}

std::string narrow(const wchar_t* text) {
  std::string out;
  if (!text) return out;
  for (; *text; ++text)
    out.push_back(*text < 0x80 ? static_cast<char>(*text) : '?');
  return out;
}

// /dev/hidrawN -> /sys/class/hidraw/hidrawN/device/report_descriptor
Bytes read_report_descriptor(const std::string& path) {
  const auto slash = path.rfind('/');
  const std::string node = slash == std::string::npos ? path : path.substr(slash + 1);
  std::ifstream in("/sys/class/hidraw/" + node + "/device/report_descriptor", std::ios::binary);
  if (!in) return {};
  return Bytes(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

class HidTransport final : public Transport {
 public:
  HidTransport(hid_device* handle, DeviceDescriptor descriptor)
      : handle_(handle), descriptor_(std::move(descriptor)) {
    try {
      prepend_zero_ = !hid::parse_report_descriptor(descriptor_.report_descriptor).uses_report_ids;
    } catch (const ProtocolError&) {
      prepend_zero_ = true;
    }
    // Non-blocking: a zero-timeout read is hid_read, which returns at once when nothing waits.
    hid_set_nonblocking(handle_, 1);
    std::size_t largest = 64;
    try {
      for (const auto& report : hid::parse_report_descriptor(descriptor_.report_descriptor).reports)
        largest = std::max(largest, report.bytes());
    } catch (const ProtocolError&) {
      largest = 4096;
    }
    buffer_.resize(largest + 1);
  }
  ~HidTransport() override {
    hid_close(handle_);
    hid_release();
  }
  const DeviceDescriptor& descriptor() const override { return descriptor_; }

  std::optional<Bytes> read(std::chrono::microseconds timeout) override {
    // hidapi counts in milliseconds: a positive timeout below 1 ms waits 1 ms, zero never waits.
    const int n = timeout.count() <= 0
                      ? hid_read(handle_, buffer_.data(), buffer_.size())
                      : hid_read_timeout(handle_, buffer_.data(), buffer_.size(),
                                         static_cast<int>((timeout.count() + 999) / 1000));
    if (n < 0) {
      throw DeviceDisconnected(describe(descriptor_) + ": " + narrow(hid_error(handle_)));
    }
    if (n == 0) return std::nullopt;
    return Bytes(buffer_.begin(), buffer_.begin() + n);
  }

  void write(std::span<const std::uint8_t> report) override {
    int n;
    if (prepend_zero_) {
      scratch_.assign(1, 0);
      scratch_.insert(scratch_.end(), report.begin(), report.end());
      n = hid_write(handle_, scratch_.data(), scratch_.size());
    } else {
      n = hid_write(handle_, report.data(), report.size());
    }
    if (n < 0) {
      throw DeviceDisconnected(describe(descriptor_) + ": " + narrow(hid_error(handle_)));
    }
  }

  // hid_write blocks until the kernel takes the report, for as long as the device holds off.
  bool write_is_bounded() const override { return false; }

 private:
  hid_device* handle_;
  DeviceDescriptor descriptor_;
  bool prepend_zero_ = false;
  Bytes scratch_;
  Bytes buffer_;  // the largest input report the descriptor declares, plus one
};

}  // namespace

HidSource::HidSource(std::uint16_t vendor_id, std::uint16_t product_id)
    : vendor_id_(vendor_id), product_id_(product_id) {
  hid_acquire();
}

HidSource::~HidSource() {
  hid_release();
}

std::vector<DeviceDescriptor> HidSource::enumerate() {
  std::vector<DeviceDescriptor> out;
  hid_device_info* list = hid_enumerate(vendor_id_, product_id_);
  for (hid_device_info* info = list; info; info = info->next) {
    DeviceDescriptor d;
    d.kind = TransportKind::Hid;
    d.vendor_id = info->vendor_id;
    d.product_id = info->product_id;
    d.serial = narrow(info->serial_number);
    d.product = narrow(info->product_string);
    d.path = info->path ? info->path : "";
    d.report_descriptor = read_report_descriptor(d.path);
    out.push_back(std::move(d));
  }
  hid_free_enumeration(list);
  return out;
}

std::unique_ptr<Transport> HidSource::open(const DeviceDescriptor& device) {
  hid_acquire();
  hid_device* handle = hid_open_path(device.path.c_str());
  if (!handle) {
    hid_release();
    throw DeviceError(describe(device) + ": cannot open (gone, or no permission)");
  }
  DeviceDescriptor d = device;
  if (d.report_descriptor.empty()) d.report_descriptor = read_report_descriptor(d.path);
  return std::make_unique<HidTransport>(handle, std::move(d));
}

}  // namespace bisturi::devices
