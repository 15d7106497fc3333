// The raw-USB path without blocking the tick: AsyncUsbTransport (IN transfers kept submitted, OUT
// transfers submitted and left to complete, completions collected by zero-timeout event passes)
// on an in-process bus, with the vendor arm's real driver on its twin. Waiting is asserted by
// counting the event passes that were allowed to wait, never by timing.
#include <gtest/gtest.h>

#include <deque>

#include "bisturi/devices/simulated.h"
#include "bisturi/devices/usb_async.h"
#include "bisturi/devices/vendor_arm.h"
#include "bisturi/devices/virtual_transport.h"

namespace bd = bisturi::devices;
using namespace std::chrono_literals;

namespace {

// The arm's twin behind VirtualUsbIo: what UsbSource::open gives for real hardware, with an
// in-process bus instead of libusb.
struct ArmOnUsb {
  bd::SimulatedArm twin{bd::DeviceScript{}};
  bd::VirtualUsbIo* bus = nullptr;
  std::unique_ptr<bd::AsyncUsbTransport> transport;

  ArmOnUsb() {
    auto pair = bd::make_virtual_pair(twin.descriptor());
    twin.attach(std::move(pair.device));
    auto io = std::make_unique<bd::VirtualUsbIo>(std::move(pair.host));
    bus = io.get();
    bd::AsyncUsbOptions options;
    options.in_packet_size = bd::arm_protocol::kPacketSize;
    transport = std::make_unique<bd::AsyncUsbTransport>(std::move(io), twin.descriptor(), options);
  }
};

// A transport that records the timeout of every read it is asked for.
class CountingTransport final : public bd::Transport {
 public:
  explicit CountingTransport(std::unique_ptr<bd::Transport> inner) : inner_(std::move(inner)) {}
  const bd::DeviceDescriptor& descriptor() const override { return inner_->descriptor(); }
  std::optional<bd::Bytes> read(std::chrono::microseconds timeout) override {
    if (timeout.count() > 0) ++*waits;
    return inner_->read(timeout);
  }
  void write(std::span<const std::uint8_t> report) override { inner_->write(report); }
  std::shared_ptr<int> waits = std::make_shared<int>(0);

 private:
  std::unique_ptr<bd::Transport> inner_;
};

// A bus whose OUT transfers finish only when the test says so (a device that is slow to accept).
class HeldOutBus final : public bd::UsbIo {
 public:
  void set_listener(bd::UsbIoListener* listener) override { listener_ = listener; }
  std::string submit_in(std::size_t, std::span<std::uint8_t>) override { return {}; }
  std::string submit_out(std::size_t slot, std::span<const std::uint8_t> packet) override {
    sent.emplace_back(packet.begin(), packet.end());
    held.push_back(slot);
    return {};
  }
  void cancel_all() override {}
  void handle_events(std::chrono::microseconds timeout) override {
    if (timeout.count() > 0) ++waits;
    while (release > 0 && !held.empty()) {
      const std::size_t slot = held.front();
      held.pop_front();
      --release;
      listener_->out_done(slot, bd::UsbTransferStatus::Completed);
    }
  }
  std::vector<bd::Bytes> sent;
  std::deque<std::size_t> held;
  int release = 0;
  int waits = 0;

 private:
  bd::UsbIoListener* listener_ = nullptr;
};

}  // namespace

TEST(DevicesUsbAsync, AZeroTimeoutReadOnAnEmptyEndpointNeverWaits) {
  ArmOnUsb usb;
  for (int i = 0; i < 100; ++i)
    EXPECT_FALSE(usb.transport->read(0us).has_value());
  EXPECT_EQ(usb.bus->blocking_waits(), 0u);
  EXPECT_EQ(usb.transport->stats().blocking_waits, 0u);
  // A packet the twin sent is there on the next zero-timeout read, still without a wait.
  usb.twin.step(1ms);
  const auto packet = usb.transport->read(0us);
  ASSERT_TRUE(packet.has_value());
  EXPECT_EQ(packet->size(), bd::arm_protocol::kPacketSize);
  EXPECT_EQ(usb.bus->blocking_waits(), 0u);
}

TEST(DevicesUsbAsync, TheArmDriverPollsAndSendsWithoutWaiting) {
  ArmOnUsb usb;
  bd::VirtualClock clock;
  auto arm = bd::open_vendor_arm(std::move(usb.transport), clock);  // waits for info: set-up
  const auto waits_at_open = usb.bus->blocking_waits();
  for (int tick = 1; tick <= 200; ++tick) {
    clock.set(std::chrono::milliseconds(tick));
    if (tick % 2 == 0) usb.twin.step(clock.now());  // a report every other tick
    EXPECT_EQ(arm->poll(0us), tick % 2 == 0 ? 1u : 0u) << "tick " << tick;
    const double force[3] = {0.5, -0.25, 1.0};
    arm->send_forces(force);
  }
  EXPECT_EQ(usb.bus->blocking_waits(), waits_at_open) << "a tick waited on the bus";
  EXPECT_EQ(arm->state().reports, 100u);
  const bd::Vec3 applied = usb.twin.applied_force_N();
  EXPECT_NEAR(applied.x, 0.5, 1e-3);
  EXPECT_NEAR(applied.y, -0.25, 1e-3);
  EXPECT_NEAR(applied.z, 1.0, 1e-3);
  EXPECT_EQ(usb.twin.bad_packets(), 0u);
  // Closing sends zero and lets it out before the transfers are cancelled.
  arm->close();
  EXPECT_EQ(usb.twin.applied_force_N(), bd::Vec3{});
}

TEST(DevicesUsbAsync, PollTransportWaitsOnlyWhenAskedTo) {
  bd::SimulatedArm twin{bd::DeviceScript{}};
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  auto counting = std::make_unique<CountingTransport>(std::move(pair.host));
  const std::shared_ptr<int> waits = counting->waits;
  bd::VirtualClock clock;
  auto arm = bd::open_vendor_arm(std::move(counting), clock);
  *waits = 0;
  EXPECT_EQ(arm->poll(0us), 0u);  // empty
  for (int i = 1; i <= 5; ++i)
    twin.step(std::chrono::milliseconds(i));
  EXPECT_EQ(arm->poll(0us), 5u);  // all that waits, none waited for
  EXPECT_EQ(*waits, 0);
  EXPECT_EQ(arm->poll(-5us), 0u);  // a negative timeout is zero
  EXPECT_EQ(*waits, 0);
  twin.step(10ms);
  EXPECT_EQ(arm->poll(2ms), 1u);  // asked to wait: only the first read may
  EXPECT_EQ(*waits, 1);
}

TEST(DevicesUsbAsync, WritesNeverWaitAndTheNewestPacketWins) {
  auto bus_owner = std::make_unique<HeldOutBus>();
  HeldOutBus* bus = bus_owner.get();
  bd::AsyncUsbOptions options;
  options.out_transfers = 2;
  options.close_timeout = 1ms;
  bd::AsyncUsbTransport usb(std::move(bus_owner), bd::DeviceDescriptor{}, options);
  const std::uint8_t a[1] = {1}, b[1] = {2}, c[1] = {3}, d[1] = {4};
  usb.write(a);
  usb.write(b);  // both slots in flight now
  usb.write(c);  // waits
  usb.write(d);  // replaces c
  EXPECT_EQ(bus->sent.size(), 2u);
  EXPECT_EQ(usb.stats().out_coalesced, 1u);
  bus->release = 1;  // one slot frees: the waiting packet (d) goes out
  EXPECT_FALSE(usb.read(0us).has_value());
  ASSERT_EQ(bus->sent.size(), 3u);
  EXPECT_EQ(bus->sent[2], bd::Bytes{4});
  EXPECT_EQ(bus->waits, 0);
}

TEST(DevicesUsbAsync, AnUnplugEndsTheTransfersAndThePollSaysSo) {
  ArmOnUsb usb;
  bd::VirtualClock clock;
  auto arm = bd::open_vendor_arm(std::move(usb.transport), clock);
  usb.twin.step(1ms);
  EXPECT_EQ(arm->poll(0us), 1u);
  usb.twin.disconnect();
  EXPECT_THROW(arm->poll(0us), bd::DeviceDisconnected);
  EXPECT_FALSE(arm->is_open());
}

TEST(DevicesUsbAsync, TransferStatusesHaveNames) {
  EXPECT_STREQ(bd::to_string(bd::UsbTransferStatus::NoDevice), "no device");
  EXPECT_STREQ(bd::to_string(bd::UsbTransferStatus::Stall), "endpoint stalled");
}
