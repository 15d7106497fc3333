// Raw USB interrupt endpoints without blocking the haptic tick: IN transfers are kept submitted
// (the bus fills them while the loop does other work), OUT transfers are submitted and left to
// complete, and completions are collected with a zero-timeout event pass. The logic lives here;
// the bus below it is a UsbIo: libusb's asynchronous API for real hardware (usb_transport.cpp),
// or VirtualUsbIo, an in-process bus that completes transfers the way libusb does (on the thread
// that handles events, never on its own), for tests and benchmarks on machines without USB.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "bisturi/devices/transport.h"

namespace bisturi::devices {

class VirtualTransport;

// How a transfer ended (libusb_transfer_status, one to one).
enum class UsbTransferStatus : std::uint8_t {
  Completed,
  Error,
  TimedOut,
  Cancelled,
  Stall,
  NoDevice,
  Overflow
};
const char* to_string(UsbTransferStatus status);

// Receives completions. Called only from inside UsbIo::handle_events.
class UsbIoListener {
 public:
  virtual ~UsbIoListener();
  virtual void in_done(std::size_t slot, UsbTransferStatus status, std::size_t length) = 0;
  virtual void out_done(std::size_t slot, UsbTransferStatus status) = 0;
};

// The asynchronous bus: submissions never wait; completions are delivered to the listener inside
// handle_events, which waits only when given a non-zero timeout.
class UsbIo {
 public:
  virtual ~UsbIo();
  virtual void set_listener(UsbIoListener* listener) = 0;
  // Starts IN transfer `slot` into `buffer` (kept alive by the caller until it completes).
  // Returns "" or the reason it was refused (the device is gone, ...).
  virtual std::string submit_in(std::size_t slot, std::span<std::uint8_t> buffer) = 0;
  // Starts OUT transfer `slot` with `packet` (kept alive by the caller until it completes).
  virtual std::string submit_out(std::size_t slot, std::span<const std::uint8_t> packet) = 0;
  // Asks every submitted transfer to end (each completes, Cancelled or otherwise, later).
  virtual void cancel_all() = 0;
  // Delivers completions that are ready; waits up to `timeout` for one when there are none.
  virtual void handle_events(std::chrono::microseconds timeout) = 0;
};

struct AsyncUsbOptions {
  std::size_t in_transfers = 4;      // IN transfers kept submitted
  std::size_t in_packet_size = 64;   // bytes per IN transfer (the endpoint's wMaxPacketSize)
  std::size_t out_transfers = 4;     // OUT transfers that may be in flight at once
  std::size_t queue_capacity = 256;  // IN packets held for read() before the oldest is dropped
  std::chrono::milliseconds close_timeout{100};  // flush OUT, then cancel IN, when destroyed
};

// Counters a benchmark or a report reads.
struct AsyncUsbStats {
  std::uint64_t in_packets = 0;     // IN transfers completed with data
  std::uint64_t in_dropped = 0;     // packets dropped because read() fell behind
  std::uint64_t out_submitted = 0;  // OUT transfers started
  std::uint64_t out_coalesced = 0;  // OUT reports replaced by a newer one while all slots were busy
  std::uint64_t out_failed = 0;     // OUT transfers that timed out or were refused
  std::uint64_t blocking_waits = 0;  // handle_events calls with a non-zero timeout
};

class AsyncUsbTransport final : public Transport, private UsbIoListener {
 public:
  // Submits the IN transfers at once. Throws DeviceError when the bus refuses the first one.
  AsyncUsbTransport(std::unique_ptr<UsbIo> io, DeviceDescriptor descriptor,
                    AsyncUsbOptions options = {});
  // Lets waiting OUT transfers finish (a closing driver's zero force goes out), then cancels the
  // IN transfers; each wait is bounded by options.close_timeout.
  ~AsyncUsbTransport() override;

  const DeviceDescriptor& descriptor() const override { return descriptor_; }
  // One event pass without waiting, then the oldest packet received. With a zero timeout it
  // never waits; otherwise it waits up to `timeout` for a packet. DeviceDisconnected once a
  // transfer ended with NoDevice, Error, Stall or Overflow.
  std::optional<Bytes> read(std::chrono::microseconds timeout) override;
  // Submits the packet and returns. When every OUT transfer is still in flight the packet waits
  // and goes out when one completes; a newer packet replaces a waiting one (a force packet
  // carries the whole command: an older one is worth nothing once a newer exists).
  void write(std::span<const std::uint8_t> report) override;

  const AsyncUsbStats& stats() const { return stats_; }

 private:
  void in_done(std::size_t slot, UsbTransferStatus status, std::size_t length) override;
  void out_done(std::size_t slot, UsbTransferStatus status) override;
  void events(std::chrono::microseconds timeout);
  void submit_in(std::size_t slot);
  void submit_out(std::size_t slot);
  void fail(const std::string& reason);
  void throw_if_failed() const;
  bool any_busy(const std::vector<char>& busy) const;

  std::unique_ptr<UsbIo> io_;
  DeviceDescriptor descriptor_;
  AsyncUsbOptions options_;
  std::vector<Bytes> in_buffers_, out_buffers_;
  std::vector<char> in_busy_, out_busy_;
  std::deque<Bytes> received_;
  Bytes waiting_;  // the newest OUT packet while every slot is busy
  bool have_waiting_ = false;
  bool closing_ = false;
  std::string failure_;
  AsyncUsbStats stats_;
};

// An in-process bus for AsyncUsbTransport: IN transfers complete with the packets the device side
// of a virtual link writes, OUT transfers deliver their packet to it, and all completions happen
// inside handle_events, on the caller's thread, as with libusb. A disconnect of the link completes
// every transfer with NoDevice. handle_events waits (up to its timeout) only on the link.
class VirtualUsbIo final : public UsbIo {
 public:
  explicit VirtualUsbIo(std::unique_ptr<VirtualTransport> host_side);
  ~VirtualUsbIo() override;
  void set_listener(UsbIoListener* listener) override { listener_ = listener; }
  std::string submit_in(std::size_t slot, std::span<std::uint8_t> buffer) override;
  std::string submit_out(std::size_t slot, std::span<const std::uint8_t> packet) override;
  void cancel_all() override;
  void handle_events(std::chrono::microseconds timeout) override;

  // handle_events calls that were given a non-zero timeout.
  std::uint64_t blocking_waits() const { return blocking_waits_; }

 private:
  struct Pending {
    std::size_t slot;
    std::span<std::uint8_t> buffer;
  };
  std::unique_ptr<VirtualTransport> link_;
  UsbIoListener* listener_ = nullptr;
  std::deque<Pending> in_;
  std::deque<std::pair<std::size_t, UsbTransferStatus>> out_done_;
  bool cancelled_ = false;
  std::uint64_t blocking_waits_ = 0;
};

}  // namespace bisturi::devices
