// Vendor-specific USB devices through libusb interrupt transfers.
#include <libusb.h>

#include <algorithm>
#include <cstdio>
#include <deque>

#include "bisturi/devices/host_transports.h"
#include "bisturi/devices/usb_async.h"

namespace bisturi::devices {

struct UsbSource::Context {
  libusb_context* ctx = nullptr;
};

namespace {

using Endpoints = UsbEndpoints;

/// The device's active configuration as choose_usb_endpoints reads it.
std::vector<UsbAltSetting> alt_settings(libusb_device* device) {
  std::vector<UsbAltSetting> out;
  libusb_config_descriptor* config = nullptr;
  if (libusb_get_active_config_descriptor(device, &config) != 0 || !config) return out;
  for (int i = 0; i < config->bNumInterfaces; ++i) {
    const libusb_interface& interface = config->interface[i];
    for (int a = 0; a < interface.num_altsetting; ++a) {
      const libusb_interface_descriptor& alt = interface.altsetting[a];
      UsbAltSetting s;
      s.interface_number = alt.bInterfaceNumber;
      s.interface_class = alt.bInterfaceClass;
      for (int k = 0; k < alt.bNumEndpoints; ++k) {
        const libusb_endpoint_descriptor& ep = alt.endpoint[k];
        s.endpoints.push_back({ep.bEndpointAddress, ep.bmAttributes, ep.wMaxPacketSize});
      }
      out.push_back(std::move(s));
    }
  }
  libusb_free_config_descriptor(config);
  return out;
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

UsbTransferStatus status_of(libusb_transfer_status status) {
  switch (status) {
    case LIBUSB_TRANSFER_COMPLETED:
      return UsbTransferStatus::Completed;
    case LIBUSB_TRANSFER_TIMED_OUT:
      return UsbTransferStatus::TimedOut;
    case LIBUSB_TRANSFER_CANCELLED:
      return UsbTransferStatus::Cancelled;
    case LIBUSB_TRANSFER_STALL:
      return UsbTransferStatus::Stall;
    case LIBUSB_TRANSFER_NO_DEVICE:
      return UsbTransferStatus::NoDevice;
    case LIBUSB_TRANSFER_OVERFLOW:
      return UsbTransferStatus::Overflow;
    case LIBUSB_TRANSFER_ERROR:
      break;
  }
  return UsbTransferStatus::Error;
}

// libusb's asynchronous API under AsyncUsbTransport. Each opened device has a libusb context of
// its own, so its completions run only on the thread that polls it (libusb runs callbacks inside
// libusb_handle_events* on whichever thread handles the context's events).
class LibusbIo final : public UsbIo {
 public:
  LibusbIo(libusb_context* context, libusb_device_handle* handle, Endpoints endpoints)
      : context_(context), handle_(handle), endpoints_(endpoints) {}
  ~LibusbIo() override {
    // AsyncUsbTransport waited for the cancellations; a transfer still in flight (a bus that did
    // not answer within its close timeout) is leaked rather than freed under libusb's feet.
    bool in_flight = false;
    for (auto* list : {&in_, &out_}) {
      for (Slot& slot : *list) {
        if (slot.busy)
          in_flight = true;
        else
          libusb_free_transfer(slot.transfer);
      }
    }
    libusb_release_interface(handle_, endpoints_.interface);
    libusb_close(handle_);
    if (!in_flight) libusb_exit(context_);
  }

  void set_listener(UsbIoListener* listener) override { listener_ = listener; }

  std::string submit_in(std::size_t slot, std::span<std::uint8_t> buffer) override {
    // No timeout: an IN transfer waits on the bus (not on us) until the device sends.
    return submit(in_, slot, endpoints_.in, buffer.data(), buffer.size(), 0);
  }

  std::string submit_out(std::size_t slot, std::span<const std::uint8_t> packet) override {
    // libusb takes a non-const buffer for both directions; it only reads an OUT buffer.
    return submit(out_, slot, endpoints_.out, const_cast<std::uint8_t*>(packet.data()),
                  packet.size(), 100);
  }

  void cancel_all() override {
    for (auto* list : {&in_, &out_}) {
      for (Slot& slot : *list)
        if (slot.busy) libusb_cancel_transfer(slot.transfer);
    }
  }

  void handle_events(std::chrono::microseconds timeout) override {
    // A zero timeval: handle what is pending and return at once (libusb's non-blocking mode).
    timeval tv{};
    tv.tv_sec = static_cast<decltype(tv.tv_sec)>(timeout.count() / 1000000);
    tv.tv_usec = static_cast<decltype(tv.tv_usec)>(timeout.count() % 1000000);
    libusb_handle_events_timeout_completed(context_, &tv, nullptr);
  }

 private:
  struct Slot {
    LibusbIo* io = nullptr;
    std::size_t index = 0;
    bool in = true;
    bool busy = false;
    libusb_transfer* transfer = nullptr;
  };

  std::string submit(std::deque<Slot>& list, std::size_t index, std::uint8_t endpoint,
                     std::uint8_t* data, std::size_t length, unsigned timeout_ms) {
    while (list.size() <= index) {
      Slot slot;
      slot.io = this;
      slot.index = list.size();
      slot.in = &list == &in_;
      slot.transfer = libusb_alloc_transfer(0);
      if (!slot.transfer) return "out of memory for a transfer";
      list.push_back(slot);
    }
    // A deque keeps earlier slots in place as it grows: their user_data pointers stay valid.
    Slot& slot = list[index];
    libusb_fill_interrupt_transfer(slot.transfer, handle_, endpoint, data, static_cast<int>(length),
                                   &LibusbIo::completed, &slot, timeout_ms);
    const int rc = libusb_submit_transfer(slot.transfer);
    if (rc != 0) return libusb_error_name(rc);
    slot.busy = true;
    return {};
  }

  static void LIBUSB_CALL completed(libusb_transfer* transfer) {
    auto* slot = static_cast<Slot*>(transfer->user_data);
    slot->busy = false;
    UsbIoListener* listener = slot->io->listener_;
    if (!listener) return;
    const UsbTransferStatus status = status_of(transfer->status);
    if (slot->in) {
      listener->in_done(slot->index, status, static_cast<std::size_t>(transfer->actual_length));
    } else {
      listener->out_done(slot->index, status);
    }
  }

  libusb_context* context_;
  libusb_device_handle* handle_;
  Endpoints endpoints_;
  UsbIoListener* listener_ = nullptr;
  std::deque<Slot> in_, out_;
};

}  // namespace

UsbEndpoints choose_usb_endpoints(const std::vector<UsbAltSetting>& settings,
                                  const UsbInterface& declared) {
  for (const UsbAltSetting& alt : settings) {
    if (declared.number >= 0 ? alt.interface_number != declared.number
                             : alt.interface_class != LIBUSB_CLASS_VENDOR_SPEC)
      continue;
    UsbEndpoints e;
    for (const UsbAltSetting::Endpoint& ep : alt.endpoints) {
      if ((ep.attributes & 0x03) != LIBUSB_TRANSFER_TYPE_INTERRUPT) continue;
      if (ep.address & LIBUSB_ENDPOINT_IN) {
        if (declared.in_endpoint != 0 && ep.address != declared.in_endpoint) continue;
        if (e.in != 0) continue;  // the first that fits
        e.in = ep.address;
        e.in_size = ep.max_packet_size;
      } else {
        if (declared.out_endpoint != 0 && ep.address != declared.out_endpoint) continue;
        if (e.out == 0) e.out = ep.address;
      }
    }
    if (e.in && e.out) {
      e.interface = alt.interface_number;
      return e;
    }
  }
  return {};
}

UsbSource::UsbSource(std::vector<UsbId> wanted, UsbInterface interface)
    : wanted_(std::move(wanted)), interface_(interface), context_(std::make_unique<Context>()) {
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
    if (choose_usb_endpoints(alt_settings(device), interface_).interface < 0) continue;
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
  // A context per opened device: its transfers complete only on the thread that polls it.
  libusb_context* context = nullptr;
  int rc = libusb_init(&context);
  if (rc != 0) throw DeviceError(describe(wanted) + ": libusb: " + libusb_error_name(rc));
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(context, &list);
  if (n < 0) {
    libusb_exit(context);
    throw DeviceError(describe(wanted) + ": libusb: " + libusb_error_name(static_cast<int>(n)));
  }
  libusb_device_handle* handle = nullptr;
  Endpoints endpoints;
  std::string failure = "not found";
  for (ssize_t i = 0; i < n; ++i) {
    libusb_device* device = list[i];
    if (usb_path(device) != wanted.path) continue;
    endpoints = choose_usb_endpoints(alt_settings(device), interface_);
    rc = endpoints.interface < 0 ? LIBUSB_ERROR_NOT_FOUND : libusb_open(device, &handle);
    if (rc == 0) {
      libusb_set_auto_detach_kernel_driver(handle, 1);
      rc = libusb_claim_interface(handle, endpoints.interface);
      if (rc != 0) {
        libusb_close(handle);
        handle = nullptr;
      }
    }
    if (rc != 0) failure = libusb_error_name(rc);
    break;
  }
  libusb_free_device_list(list, 1);
  if (!handle) {
    libusb_exit(context);
    throw DeviceError(describe(wanted) + ": cannot open: " + failure);
  }
  AsyncUsbOptions options;
  options.in_packet_size = std::max<std::uint16_t>(endpoints.in_size, 1);
  return std::make_unique<AsyncUsbTransport>(std::make_unique<LibusbIo>(context, handle, endpoints),
                                             wanted, options);
}

std::vector<UsbId> usb_ids(const Registry& registry) {
  std::vector<UsbId> ids;
  for (const auto& driver : registry.drivers()) {
    ids.insert(ids.end(), driver.usb_ids.begin(), driver.usb_ids.end());
  }
  return ids;
}

}  // namespace bisturi::devices
