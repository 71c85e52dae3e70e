// The parts of the USB transport that need no USB device: the `usb:VID:PID[:SERIAL]` parser and the OUT queue
// that holds messages back while every OUT transfer is in flight (a newer command supersedes a waiting one, other
// messages keep their order, the queue is bounded, an unplug empties it). The libusb path itself runs against the
// kernel's USB stack in the VM lane (tests/vm/usb_test.sh).
#include <gtest/gtest.h>

#include <string>

#include "phalanx/linux/usb_link.h"
#include "phalanx/linux/usb_out_queue.h"
#include "phalanx/protocol/messages.h"

using phalanx::linux_hal::parseUsbDevice;
using phalanx::linux_hal::UsbLink;
using phalanx::linux_hal::UsbOutQueue;
using phalanx::protocol::MsgId;

namespace {

constexpr uint8_t kCmd = static_cast<uint8_t>(MsgId::kCommand);
constexpr uint8_t kHello = static_cast<uint8_t>(MsgId::kHello);
constexpr uint8_t kParam = static_cast<uint8_t>(MsgId::kParamSet);

UsbOutQueue::Push push(UsbOutQueue& q, uint8_t id, uint8_t tag) {
  const uint8_t body[3] = {id, tag, static_cast<uint8_t>(~tag)};
  return q.push(id, body, sizeof body);
}

// (msg id, tag) of every waiting message, front first; pops them.
std::string drain(UsbOutQueue& q) {
  std::string s;
  while (!q.empty()) {
    const auto& b = q.front();
    EXPECT_EQ(b.len, 3u);
    EXPECT_EQ(b.data[0], b.msg_id);
    EXPECT_EQ(b.data[2], static_cast<uint8_t>(~b.data[1]));
    s += (b.msg_id == kCmd ? "C" : b.msg_id == kHello ? "H" : "P") + std::to_string(b.data[1]) + " ";
    q.pop();
  }
  return s;
}

}  // namespace

TEST(ParseUsbDevice, AcceptsVidPidAndSerial) {
  UsbLink::Options o;
  EXPECT_EQ(parseUsbDevice("usb:1209:0001", o), "");
  EXPECT_EQ(o.vid, 0x1209);
  EXPECT_EQ(o.pid, 0x0001);
  EXPECT_EQ(o.serial, "");
  EXPECT_EQ(parseUsbDevice("usb:cafe:BEEF:phalanx-vm-1", o), "");
  EXPECT_EQ(o.vid, 0xCAFE);
  EXPECT_EQ(o.pid, 0xBEEF);
  EXPECT_EQ(o.serial, "phalanx-vm-1");
  // A serial may itself contain ':' (everything after the PID is the serial).
  EXPECT_EQ(parseUsbDevice("usb:1209:0001:a:b", o), "");
  EXPECT_EQ(o.serial, "a:b");
}

TEST(ParseUsbDevice, RefusesMalformedSpecsNamingThePart) {
  UsbLink::Options o;
  EXPECT_EQ(parseUsbDevice("serial:/dev/ttyACM0", o), "not a USB device");
  EXPECT_NE(parseUsbDevice("usb:", o).find("expected usb:VID:PID"), std::string::npos);
  EXPECT_NE(parseUsbDevice("usb:1209", o).find("expected usb:VID:PID"), std::string::npos);
  EXPECT_NE(parseUsbDevice("usb:12:0001", o).find("vendor id '12' is not four hexadecimal digits"), std::string::npos);
  EXPECT_NE(parseUsbDevice("usb:12g9:0001", o).find("vendor id '12g9'"), std::string::npos);
  EXPECT_NE(parseUsbDevice("usb:1209:00001", o).find("product id '00001'"), std::string::npos);
  EXPECT_NE(parseUsbDevice("usb:1209:", o).find("product id ''"), std::string::npos);
  EXPECT_NE(parseUsbDevice("usb:1209:-001", o).find("product id '-001'"), std::string::npos);
  EXPECT_NE(parseUsbDevice("usb:+209:0001", o).find("vendor id '+209'"), std::string::npos);
  EXPECT_NE(parseUsbDevice("usb:1209:0001:", o).find("empty or too long serial"), std::string::npos);
  EXPECT_NE(parseUsbDevice("usb:1209:0001:" + std::string(127, 'x'), o).find("too long serial"), std::string::npos);
  EXPECT_EQ(parseUsbDevice("usb:1209:0001:" + std::string(126, 'x'), o), "");
}

TEST(UsbOutQueue, NewerCommandSupersedesWaitingOneOthersKeepOrder) {
  UsbOutQueue q;
  EXPECT_EQ(push(q, kCmd, 1), UsbOutQueue::Push::kQueued);
  EXPECT_EQ(push(q, kParam, 2), UsbOutQueue::Push::kQueued);
  EXPECT_EQ(push(q, kCmd, 3), UsbOutQueue::Push::kSuperseded);  // command 1 removed, 3 goes to the back
  EXPECT_EQ(push(q, kHello, 4), UsbOutQueue::Push::kQueued);
  EXPECT_EQ(push(q, kCmd, 5), UsbOutQueue::Push::kSuperseded);
  EXPECT_EQ(q.superseded(), 2u);
  EXPECT_EQ(drain(q), "P2 H4 C5 ");
}

TEST(UsbOutQueue, AStallNeverRefusesTheNewestCommand) {
  UsbOutQueue q;
  for (uint8_t i = 0; i < 200; ++i) EXPECT_NE(push(q, kCmd, i), UsbOutQueue::Push::kFull);
  EXPECT_EQ(q.size(), 1u);
  EXPECT_EQ(q.superseded(), 199u);
  EXPECT_EQ(drain(q), "C199 ");
}

TEST(UsbOutQueue, BoundedForMessagesThatCannotBeSuperseded) {
  UsbOutQueue q;
  for (uint8_t i = 0; i < UsbOutQueue::kCapacity; ++i) EXPECT_EQ(push(q, kParam, i), UsbOutQueue::Push::kQueued);
  EXPECT_EQ(push(q, kParam, 99), UsbOutQueue::Push::kFull);
  EXPECT_EQ(push(q, kCmd, 100), UsbOutQueue::Push::kFull);  // no older command to replace: refused, counted by UsbLink
  q.pop();
  EXPECT_EQ(push(q, kCmd, 101), UsbOutQueue::Push::kQueued);
  EXPECT_EQ(push(q, kCmd, 102), UsbOutQueue::Push::kSuperseded);  // room made by the superseded one
  EXPECT_EQ(drain(q), "P1 P2 P3 P4 P5 P6 P7 C102 ");
}

TEST(UsbOutQueue, WrapsAroundAndClearDiscardsEverything) {
  UsbOutQueue q;
  for (uint8_t round = 0; round < 5; ++round) {  // the head moves around the ring
    EXPECT_EQ(push(q, kParam, round), UsbOutQueue::Push::kQueued);
    EXPECT_EQ(push(q, kHello, static_cast<uint8_t>(round + 50)), UsbOutQueue::Push::kQueued);
    q.pop();
  }
  EXPECT_EQ(push(q, kCmd, 7), UsbOutQueue::Push::kQueued);
  EXPECT_EQ(push(q, kCmd, 8), UsbOutQueue::Push::kSuperseded);
  EXPECT_EQ(q.superseded(), 1u);
  EXPECT_EQ(drain(q), "H52 P3 H53 P4 H54 C8 ");
  EXPECT_EQ(push(q, kParam, 1), UsbOutQueue::Push::kQueued);
  EXPECT_EQ(push(q, kCmd, 2), UsbOutQueue::Push::kQueued);
  EXPECT_EQ(q.clear(), 2u);
  EXPECT_TRUE(q.empty());
  EXPECT_EQ(push(q, kHello, 9), UsbOutQueue::Push::kQueued);
  EXPECT_EQ(drain(q), "H9 ");
}

TEST(UsbOutQueue, RefusesABodyLongerThanAProtocolBody) {
  UsbOutQueue q;
  uint8_t big[phalanx::protocol::kMaxFrameBody + 1] = {};
  EXPECT_EQ(q.push(kCmd, big, sizeof big), UsbOutQueue::Push::kTooLong);
  EXPECT_EQ(q.push(kCmd, big, sizeof big - 1), UsbOutQueue::Push::kQueued);
}

TEST(UsbLink, SendWithoutADeviceIsRefusedAndCounted) {
  UsbLink link;
  const uint8_t payload[4] = {};
  EXPECT_FALSE(link.send(kCmd, payload, sizeof payload));
  EXPECT_EQ(link.stats().tx_dropped_offline, 1u);
  EXPECT_FALSE(link.connected());
  EXPECT_EQ(link.reconnect(), "USB link was never opened");
}
