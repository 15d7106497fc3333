// Vendor-specific USB devices through libusb interrupt transfers.
#include <libusb.h>

#include <algorithm>
#include <cstdio>

#include "bisturi/devices/host_transports.h"

namespace bisturi::devices {

struct UsbSource::Context {
  libusb_context* ctx = nullptr;
};

namespace {

struct Endpoints {
  int interface = -1;
  std::uint8_t in = 0, out = 0;
  std::uint16_t in_size = 64;
};

// The first vendor-specific interface with interrupt IN and OUT endpoints.
Endpoints find_endpoints(libusb_device* device) {
  Endpoints found;
  libusb_config_descriptor* config = nullptr;
  if (libusb_get_active_config_descriptor(device, &config) != 0 || !config) return found;
  for (int i = 0; i < config->bNumInterfaces && found.interface < 0; ++i) {
    const libusb_interface& interface = config->interface[i];
    for (int a = 0; a < interface.num_altsetting && found.interface < 0; ++a) {
      const libusb_interface_descriptor& alt = interface.altsetting[a];
      if (alt.bInterfaceClass != LIBUSB_CLASS_VENDOR_SPEC) continue;
      Endpoints e;
      for (int k = 0; k < alt.bNumEndpoints; ++k) {
        const libusb_endpoint_descriptor& ep = alt.endpoint[k];
        if ((ep.bmAttributes & 0x03) != LIBUSB_TRANSFER_TYPE_INTERRUPT) continue;
        if (ep.bEndpointAddress & LIBUSB_ENDPOINT_IN) {
          e.in = ep.bEndpointAddress;
          e.in_size = ep.wMaxPacketSize;
        } else {
          e.out = ep.bEndpointAddress;
        }
      }
      if (e.in && e.out) {
        e.interface = alt.bInterfaceNumber;
        found = e;
      }
    }
  }
  libusb_free_config_descriptor(config);
  return found;
}

std::string usb_path(libusb_device* device) {
  std::uint8_t ports[8];
  const int n = libusb_get_port_numbers(device, ports, 8);
  std::string path = "usb:" + std::to_string(libusb_get_bus_number(device)) + "-";
  for (int i = 0; i < n; ++i) {
    if (i) path += ".";
    path += std::to_string(ports[i]);
  }
  return path;
}

std::string string_descriptor(libusb_device_handle* handle, std::uint8_t index) {
  if (!handle || index == 0) return {};
  unsigned char text[256];
  const int n = libusb_get_string_descriptor_ascii(handle, index, text, sizeof text);
  return n > 0 ? std::string(reinterpret_cast<char*>(text), static_cast<std::size_t>(n)) : "";
}

class UsbTransport final : public Transport {
 public:
  UsbTransport(libusb_device_handle* handle, Endpoints endpoints, DeviceDescriptor descriptor)
      : handle_(handle), endpoints_(endpoints), descriptor_(std::move(descriptor)) {}
  ~UsbTransport() override {
    libusb_release_interface(handle_, endpoints_.interface);
    libusb_close(handle_);
  }
  const DeviceDescriptor& descriptor() const override { return descriptor_; }

  std::optional<Bytes> read(std::chrono::microseconds timeout) override {
    Bytes buffer(std::max<std::uint16_t>(endpoints_.in_size, 64));
    int transferred = 0;
    const auto ms = static_cast<unsigned>(std::max<long long>(1, (timeout.count() + 999) / 1000));
    const int rc = libusb_interrupt_transfer(handle_, endpoints_.in, buffer.data(),
                                             static_cast<int>(buffer.size()), &transferred, ms);
    if (rc == LIBUSB_ERROR_TIMEOUT && transferred == 0) return std::nullopt;
    check(rc);
    buffer.resize(static_cast<std::size_t>(transferred));
    return buffer;
  }

  void write(std::span<const std::uint8_t> report) override {
    Bytes copy(report.begin(), report.end());
    int transferred = 0;
    check(libusb_interrupt_transfer(handle_, endpoints_.out, copy.data(),
                                    static_cast<int>(copy.size()), &transferred, 100));
  }

 private:
  void check(int rc) const {
    if (rc == 0 || rc == LIBUSB_ERROR_TIMEOUT) return;
    const std::string message = describe(descriptor_) + ": " + libusb_error_name(rc);
    if (rc == LIBUSB_ERROR_NO_DEVICE || rc == LIBUSB_ERROR_IO || rc == LIBUSB_ERROR_PIPE) {
      throw DeviceDisconnected(message);
    }
    throw DeviceError(message);
  }

  libusb_device_handle* handle_;
  Endpoints endpoints_;
  DeviceDescriptor descriptor_;
};

}  // namespace

UsbSource::UsbSource(std::vector<UsbId> wanted)
    : wanted_(std::move(wanted)), context_(std::make_unique<Context>()) {
  const int rc = libusb_init(&context_->ctx);
  if (rc != 0) throw DeviceError(std::string("libusb: ") + libusb_error_name(rc));
}

UsbSource::~UsbSource() {
  libusb_exit(context_->ctx);
}

std::vector<DeviceDescriptor> UsbSource::enumerate() {
  std::vector<DeviceDescriptor> out;
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(context_->ctx, &list);
  if (n < 0) throw DeviceError(std::string("libusb: ") + libusb_error_name(static_cast<int>(n)));
  for (ssize_t i = 0; i < n; ++i) {
    libusb_device* device = list[i];
    libusb_device_descriptor dd;
    if (libusb_get_device_descriptor(device, &dd) != 0) continue;
    const UsbId id{dd.idVendor, dd.idProduct};
    if (!wanted_.empty() && std::find(wanted_.begin(), wanted_.end(), id) == wanted_.end()) {
      continue;
    }
    if (find_endpoints(device).interface < 0) continue;
    DeviceDescriptor d;
    d.kind = TransportKind::Usb;
    d.vendor_id = dd.idVendor;
    d.product_id = dd.idProduct;
    d.path = usb_path(device);
    libusb_device_handle* handle = nullptr;
    if (libusb_open(device, &handle) == 0) {
      d.serial = string_descriptor(handle, dd.iSerialNumber);
      d.product = string_descriptor(handle, dd.iProduct);
      libusb_close(handle);
    }
    out.push_back(std::move(d));
  }
  libusb_free_device_list(list, 1);
  return out;
}

std::unique_ptr<Transport> UsbSource::open(const DeviceDescriptor& wanted) {
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(context_->ctx, &list);
  if (n < 0) throw DeviceError(std::string("libusb: ") + libusb_error_name(static_cast<int>(n)));
  std::unique_ptr<Transport> transport;
  std::string failure = "not found";
  for (ssize_t i = 0; i < n && !transport; ++i) {
    libusb_device* device = list[i];
    if (usb_path(device) != wanted.path) continue;
    const Endpoints endpoints = find_endpoints(device);
    libusb_device_handle* handle = nullptr;
    int rc = endpoints.interface < 0 ? LIBUSB_ERROR_NOT_FOUND : libusb_open(device, &handle);
    if (rc == 0) {
      libusb_set_auto_detach_kernel_driver(handle, 1);
      rc = libusb_claim_interface(handle, endpoints.interface);
      if (rc != 0) libusb_close(handle);
    }
    if (rc != 0) {
      failure = libusb_error_name(rc);
      break;
    }
    transport = std::make_unique<UsbTransport>(handle, endpoints, wanted);
  }
  libusb_free_device_list(list, 1);
  if (!transport) throw DeviceError(describe(wanted) + ": cannot open: " + failure);
  return transport;
}

std::vector<UsbId> usb_ids(const Registry& registry) {
  std::vector<UsbId> ids;
  for (const auto& driver : registry.drivers()) {
    ids.insert(ids.end(), driver.usb_ids.begin(), driver.usb_ids.end());
  }
  return ids;
}

}  // namespace bisturi::devices
