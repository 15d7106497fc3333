#include "bisturi/devices/usb_async.h"

#include <algorithm>
#include <cstring>

#include "bisturi/devices/virtual_transport.h"

namespace bisturi::devices {

const char* to_string(UsbTransferStatus status) {
  switch (status) {
    case UsbTransferStatus::Completed:
      return "completed";
    case UsbTransferStatus::Error:
      return "transfer error";
    case UsbTransferStatus::TimedOut:
      return "timed out";
    case UsbTransferStatus::Cancelled:
      return "cancelled";
    case UsbTransferStatus::Stall:
      return "endpoint stalled";
    case UsbTransferStatus::NoDevice:
      return "no device";
    case UsbTransferStatus::Overflow:
      return "overflow";
  }
  return "unknown";
}

UsbIoListener::~UsbIoListener() = default;
UsbIo::~UsbIo() = default;

AsyncUsbTransport::AsyncUsbTransport(std::unique_ptr<UsbIo> io, DeviceDescriptor descriptor,
                                     AsyncUsbOptions options)
    : io_(std::move(io)), descriptor_(std::move(descriptor)), options_(options) {
  options_.in_transfers = std::max<std::size_t>(options_.in_transfers, 1);
  options_.out_transfers = std::max<std::size_t>(options_.out_transfers, 1);
  options_.in_packet_size = std::max<std::size_t>(options_.in_packet_size, 1);
  options_.queue_capacity = std::max<std::size_t>(options_.queue_capacity, 1);
  in_buffers_.assign(options_.in_transfers, Bytes(options_.in_packet_size));
  in_busy_.assign(options_.in_transfers, 0);
  out_buffers_.assign(options_.out_transfers, Bytes{});
  out_busy_.assign(options_.out_transfers, 0);
  io_->set_listener(this);
  for (std::size_t slot = 0; slot < in_buffers_.size() && failure_.empty(); ++slot)
    submit_in(slot);
  if (!failure_.empty()) {
    io_->cancel_all();
    io_->handle_events(std::chrono::microseconds(0));
    io_->set_listener(nullptr);
    throw DeviceError(describe(descriptor_) + ": cannot start reading: " + failure_);
  }
}

AsyncUsbTransport::~AsyncUsbTransport() {
  closing_ = true;
  const auto wait_until = [&](auto done) {
    const auto deadline = std::chrono::steady_clock::now() + options_.close_timeout;
    while (!done() && std::chrono::steady_clock::now() < deadline)
      events(std::chrono::milliseconds(1));
  };
  wait_until([&] { return !failure_.empty() || (!have_waiting_ && !any_busy(out_busy_)); });
  io_->cancel_all();
  wait_until([&] { return !any_busy(in_busy_) && !any_busy(out_busy_); });
  io_->set_listener(nullptr);
}

bool AsyncUsbTransport::any_busy(const std::vector<char>& busy) const {
  return std::any_of(busy.begin(), busy.end(), [](char b) { return b != 0; });
}

void AsyncUsbTransport::events(std::chrono::microseconds timeout) {
  if (timeout.count() > 0) ++stats_.blocking_waits;
  io_->handle_events(timeout);
}

std::optional<Bytes> AsyncUsbTransport::read(std::chrono::microseconds timeout) {
  events(std::chrono::microseconds(0));
  throw_if_failed();
  if (received_.empty() && timeout.count() > 0) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::microseconds>(
          deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) break;
      events(left);
      throw_if_failed();
      if (!received_.empty()) break;
    }
  }
  if (received_.empty()) return std::nullopt;
  Bytes packet = std::move(received_.front());
  received_.pop_front();
  return packet;
}

void AsyncUsbTransport::write(std::span<const std::uint8_t> report) {
  throw_if_failed();
  auto free_slot = [&] { return std::find(out_busy_.begin(), out_busy_.end(), 0); };
  auto slot = free_slot();
  if (slot == out_busy_.end()) {
    events(std::chrono::microseconds(0));  // collect finished OUT transfers, never wait
    throw_if_failed();
    slot = free_slot();
  }
  if (slot == out_busy_.end()) {
    if (have_waiting_) ++stats_.out_coalesced;
    waiting_.assign(report.begin(), report.end());
    have_waiting_ = true;
    return;
  }
  if (have_waiting_) {  // older than this packet: superseded
    ++stats_.out_coalesced;
    have_waiting_ = false;
  }
  const auto index = static_cast<std::size_t>(slot - out_busy_.begin());
  out_buffers_[index].assign(report.begin(), report.end());
  submit_out(index);
  throw_if_failed();
}

void AsyncUsbTransport::submit_in(std::size_t slot) {
  const std::string refused = io_->submit_in(slot, in_buffers_[slot]);
  if (!refused.empty()) {
    fail(refused);
    return;
  }
  in_busy_[slot] = 1;
}

void AsyncUsbTransport::submit_out(std::size_t slot) {
  const std::string refused = io_->submit_out(slot, out_buffers_[slot]);
  if (!refused.empty()) {
    ++stats_.out_failed;
    fail(refused);
    return;
  }
  out_busy_[slot] = 1;
  ++stats_.out_submitted;
}

void AsyncUsbTransport::in_done(std::size_t slot, UsbTransferStatus status, std::size_t length) {
  if (slot >= in_busy_.size()) return;
  in_busy_[slot] = 0;
  switch (status) {
    case UsbTransferStatus::Completed:
      if (length > 0) {
        if (received_.size() >= options_.queue_capacity) {
          received_.pop_front();
          ++stats_.in_dropped;
        }
        const Bytes& buffer = in_buffers_[slot];
        received_.emplace_back(
            buffer.begin(),
            buffer.begin() + static_cast<std::ptrdiff_t>(std::min(length, buffer.size())));
        ++stats_.in_packets;
      }
      break;
    case UsbTransferStatus::TimedOut:  // IN transfers have no timeout; a bus that sets one
      break;                           // simply gets the slot back
    case UsbTransferStatus::Cancelled:
      return;  // closing: leave it idle
    default:
      fail(std::string("IN transfer: ") + to_string(status));
      return;
  }
  if (!closing_ && failure_.empty()) submit_in(slot);
}

void AsyncUsbTransport::out_done(std::size_t slot, UsbTransferStatus status) {
  if (slot >= out_busy_.size()) return;
  out_busy_[slot] = 0;
  if (status == UsbTransferStatus::NoDevice || status == UsbTransferStatus::Stall ||
      status == UsbTransferStatus::Error) {
    ++stats_.out_failed;
    fail(std::string("OUT transfer: ") + to_string(status));
    return;
  }
  if (status != UsbTransferStatus::Completed)
    ++stats_.out_failed;  // timed out: the next
                          // packet supersedes it
  if (have_waiting_ && failure_.empty()) {
    out_buffers_[slot] = std::move(waiting_);
    waiting_.clear();
    have_waiting_ = false;
    submit_out(slot);
  }
}

void AsyncUsbTransport::fail(const std::string& reason) {
  if (failure_.empty()) failure_ = reason;
}

void AsyncUsbTransport::throw_if_failed() const {
  if (!failure_.empty()) throw DeviceDisconnected(describe(descriptor_) + ": " + failure_);
}

// ---- VirtualUsbIo -------------------------------------------------------------------------------

VirtualUsbIo::VirtualUsbIo(std::unique_ptr<VirtualTransport> host_side)
    : link_(std::move(host_side)) {}

VirtualUsbIo::~VirtualUsbIo() = default;

std::string VirtualUsbIo::submit_in(std::size_t slot, std::span<std::uint8_t> buffer) {
  if (!link_->connected()) return "no device";
  in_.push_back(Pending{slot, buffer});
  return {};
}

std::string VirtualUsbIo::submit_out(std::size_t slot, std::span<const std::uint8_t> packet) {
  try {
    link_->write(packet);
  } catch (const DeviceDisconnected&) {
    return "no device";
  }
  out_done_.emplace_back(slot, UsbTransferStatus::Completed);
  return {};
}

void VirtualUsbIo::cancel_all() {
  cancelled_ = true;
}

void VirtualUsbIo::handle_events(std::chrono::microseconds timeout) {
  if (timeout.count() > 0) ++blocking_waits_;
  bool delivered = false;
  while (!out_done_.empty()) {
    const auto [slot, status] = out_done_.front();
    out_done_.pop_front();
    if (listener_) listener_->out_done(slot, status);
    delivered = true;
  }
  auto complete_all = [&](UsbTransferStatus status) {
    std::deque<Pending> ended;
    ended.swap(in_);
    for (const Pending& p : ended)
      if (listener_) listener_->in_done(p.slot, status, 0);
  };
  if (cancelled_) {
    complete_all(UsbTransferStatus::Cancelled);
    return;
  }
  // Each submitted IN transfer takes the next packet the device sent; a resubmitted one (from
  // the listener) joins the back of the line, as on a real endpoint.
  // A device that keeps sending while we copy must not keep us here: at most kMaxPerPass.
  constexpr int kMaxPerPass = 1024;
  for (int n = 0; n < kMaxPerPass && !in_.empty(); ++n) {
    std::optional<Bytes> packet;
    try {
      packet = link_->read(delivered ? std::chrono::microseconds(0) : timeout);
    } catch (const DeviceDisconnected&) {
      complete_all(UsbTransferStatus::NoDevice);
      return;
    }
    if (!packet) return;
    delivered = true;
    const Pending p = in_.front();
    in_.pop_front();
    const std::size_t length = std::min(packet->size(), p.buffer.size());
    std::memcpy(p.buffer.data(), packet->data(), length);
    if (listener_) {
      listener_->in_done(p.slot,
                         packet->size() > p.buffer.size() ? UsbTransferStatus::Overflow
                                                          : UsbTransferStatus::Completed,
                         length);
    }
  }
}

}  // namespace bisturi::devices
