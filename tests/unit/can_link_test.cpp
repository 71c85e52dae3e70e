// The SocketCAN transport's I/O path (hal/linux CanLink) over a seqpacket socketpair standing in for the CAN
// socket: messages cross whole, a full kernel queue never blocks the sender, the user-space queue is bounded
// and replaces stale commands, error frames drive the bus state, and a firmware core and a host session talk
// through it. (The real kernel path runs in the VM lane: tests/vm/can_session_test.sh.)
#include <gtest/gtest.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstring>

#include "phalanx/fw/core.h"
#include "phalanx/fw_sim/sim_device.h"
#include "phalanx/host/session.h"
#include "phalanx/sim/board.h"
#include "phalanx/linux/can_link.h"
#include "phalanx/protocol/codec.h"

using namespace phalanx;
using namespace phalanx::protocol;
using linux_hal::CanBusState;
using linux_hal::CanLink;

namespace {

struct Pair {
  CanLink host, dev;
  int fds[2] = {-1, -1};
  explicit Pair(can::Flavor flavor, int sndbuf = 0) {
    EXPECT_EQ(socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0, fds), 0);
    if (sndbuf > 0) {
      setsockopt(fds[0], SOL_SOCKET, SO_SNDBUF, &sndbuf, sizeof sndbuf);
      setsockopt(fds[1], SOL_SOCKET, SO_RCVBUF, &sndbuf, sizeof sndbuf);
    }
    CanLink::Options o;
    o.node = 3;
    o.flavor = flavor;
    o.role = can::Role::kHost;
    host.adopt(fds[0], o);
    o.role = can::Role::kDevice;
    dev.adopt(fds[1], o);
  }
};

Command command(uint16_t seq) {
  Command c;
  c.seq = seq;
  c.timeout_ms = 20;
  c.mode = Mode::kSetpoint;
  c.channel_count = 2;
  c.setpoint[0] = 0.25f;
  c.setpoint[1] = -0.5f;
  c.gain_scale_permille[0] = c.gain_scale_permille[1] = 1000;
  return c;
}

bool sendCommand(CanLink& l, uint16_t seq) {
  uint8_t p[Command::kWireSize];
  encodePayload(command(seq), p);
  return l.send(static_cast<uint8_t>(MsgId::kCommand), p, sizeof p);
}

void injectError(int fd, uint32_t err_bits) {
  can_frame f{};
  f.can_id = CAN_ERR_FLAG | err_bits;
  f.len = CAN_ERR_DLC;
  ASSERT_EQ(write(fd, &f, CAN_MTU), static_cast<ssize_t>(CAN_MTU));
}

}  // namespace

TEST(CanLink, MessagesCrossWholeInBothFlavours) {
  for (auto flavor : {can::Flavor::kFd, can::Flavor::kFdCompact, can::Flavor::kClassic}) {
    Pair p(flavor);
    p.host.setDevice(DeviceType::kSeaFinger, 1000);
    p.dev.setDevice(DeviceType::kSeaFinger, 1000);
    ASSERT_TRUE(sendCommand(p.host, 77));
    uint8_t id;
    uint8_t payload[64];
    size_t len;
    ASSERT_TRUE(p.dev.receive(id, payload, len));
    Command c;
    ASSERT_TRUE(decodePayload(payload, len, c));
    EXPECT_EQ(c.seq, 77);
    EXPECT_FLOAT_EQ(c.setpoint[0], 0.25f);
    EXPECT_FALSE(p.dev.receive(id, payload, len));
  }
}

TEST(CanLink, AFullKernelQueueNeverBlocksAndTheUserQueueIsBounded) {
  Pair p(can::Flavor::kFd, 4096);
  // Nobody reads the device end: the socket fills, writes defer, then the bounded queue refuses.
  uint64_t refused = 0;
  ParamGet g;
  uint8_t pl[ParamGet::kWireSize];
  for (int i = 0; i < 2000; ++i) {
    g.param_id = static_cast<uint16_t>(i);
    encodePayload(g, pl);
    if (!p.host.send(static_cast<uint8_t>(MsgId::kParamGet), pl, sizeof pl)) ++refused;
  }
  EXPECT_GT(p.host.stats().tx_would_block, 0u);
  EXPECT_GT(refused, 0u);
  EXPECT_EQ(refused, p.host.stats().tx_dropped_full);
  EXPECT_EQ(p.host.queued(), CanLink::kTxQueueFrames);
}

TEST(CanLink, ANewCommandReplacesAQueuedStaleOne) {
  Pair p(can::Flavor::kFd, 4096);
  int sent = 0;
  while (sendCommand(p.host, static_cast<uint16_t>(sent)) && p.host.stats().tx_would_block == 0) ++sent;
  ASSERT_GT(p.host.queued(), 0u);
  for (uint16_t s = 1000; s < 1010; ++s) EXPECT_TRUE(sendCommand(p.host, s));
  EXPECT_EQ(p.host.queued(), 1u);  // only the newest command waits
  EXPECT_GE(p.host.stats().tx_superseded, 10u);
  // Drain the receiver: the last command that arrives is the newest one.
  uint8_t id;
  uint8_t payload[64];
  size_t len;
  uint16_t last = 0;
  for (int round = 0; round < 100 && last != 1009; ++round) {
    while (p.dev.receive(id, payload, len)) last = static_cast<uint16_t>(payload[0] | (payload[1] << 8));
    p.host.flush();
  }
  EXPECT_EQ(last, 1009);
}

TEST(CanLink, BusOffStopsSendingUntilTheControllerRestarts) {
  Pair p(can::Flavor::kFd);
  uint8_t id;
  uint8_t payload[64];
  size_t len;
  injectError(p.fds[1], CAN_ERR_BUSOFF);
  EXPECT_FALSE(p.host.receive(id, payload, len));
  EXPECT_EQ(p.host.state(), CanBusState::kBusOff);
  EXPECT_EQ(p.host.stats().bus_off_events, 1u);
  EXPECT_FALSE(sendCommand(p.host, 1));
  EXPECT_EQ(p.host.stats().tx_dropped_bus_off, 1u);
  // A frame still arriving (queued before the bus went off) does not end bus-off; only the restart does.
  ParamValue v;
  uint8_t vp[ParamValue::kWireSize];
  encodePayload(v, vp);
  ASSERT_TRUE(p.dev.send(static_cast<uint8_t>(MsgId::kParamValue), vp, sizeof vp));
  EXPECT_TRUE(p.host.receive(id, payload, len));
  EXPECT_EQ(p.host.state(), CanBusState::kBusOff);
  injectError(p.fds[1], CAN_ERR_RESTARTED);
  EXPECT_FALSE(p.host.receive(id, payload, len));
  EXPECT_EQ(p.host.state(), CanBusState::kActive);
  EXPECT_TRUE(sendCommand(p.host, 2));
  ASSERT_TRUE(p.dev.receive(id, payload, len));
}

TEST(CanLink, ControllerErrorStatesAreFollowed) {
  Pair p(can::Flavor::kClassic);
  uint8_t id;
  uint8_t payload[64];
  size_t len;
  can_frame f{};
  f.can_id = CAN_ERR_FLAG | CAN_ERR_CRTL;
  f.len = CAN_ERR_DLC;
  f.data[1] = CAN_ERR_CRTL_TX_PASSIVE;
  ASSERT_EQ(write(p.fds[1], &f, CAN_MTU), static_cast<ssize_t>(CAN_MTU));
  p.host.receive(id, payload, len);
  EXPECT_EQ(p.host.state(), CanBusState::kPassive);
  f.data[1] = CAN_ERR_CRTL_ACTIVE;
  ASSERT_EQ(write(p.fds[1], &f, CAN_MTU), static_cast<ssize_t>(CAN_MTU));
  p.host.receive(id, payload, len);
  EXPECT_EQ(p.host.state(), CanBusState::kActive);
}

TEST(CanLink, ForeignFramesAreCountedAndDoNotStopTheGoodOnes) {
  Pair p(can::Flavor::kFd);
  canfd_frame junk{};
  junk.can_id = (0x1Fu << 6) | 3u;  // unknown function for our node
  junk.len = 8;
  ASSERT_EQ(write(p.fds[0], &junk, CANFD_MTU), static_cast<ssize_t>(CANFD_MTU));
  ASSERT_TRUE(sendCommand(p.host, 5));
  uint8_t id;
  uint8_t payload[64];
  size_t len;
  ASSERT_TRUE(p.dev.receive(id, payload, len));
  EXPECT_EQ(p.dev.rxStats().bad_id, 1u);
}

TEST(CanLink, HostSessionHandshakesOverPackets) {
  Pair p(can::Flavor::kClassic);
  host::HostSession session(p.host);
  session.sendHello(0x1234, DeviceType::kAny);
  uint8_t id;
  uint8_t payload[64];
  size_t len;
  ASSERT_TRUE(p.dev.receive(id, payload, len));
  EXPECT_EQ(id, static_cast<uint8_t>(MsgId::kHello));
  HelloAck a;
  a.device_type = DeviceType::kPantograph;
  a.session_id = 0x1234;
  a.tick_rate_hz = 1000;
  a.setpoint_count = 6;
  a.sample_count = 12;
  uint8_t ap[HelloAck::kWireSize];
  encodePayload(a, ap);
  p.dev.setDevice(DeviceType::kPantograph, 1000);
  ASSERT_TRUE(p.dev.send(static_cast<uint8_t>(MsgId::kHelloAck), ap, sizeof ap));
  session.poll(1);
  ASSERT_EQ(session.handshake(), host::HandshakeResult::kOk);
  EXPECT_EQ(session.layout()->type, DeviceType::kPantograph);
}

// The firmware core and the host session run the same protocol over a packet link as over a byte stream: the
// handshake opens the session, commands drive the outputs, and a rejected frame shows up in telemetry rx_errors.
TEST(CanLink, FirmwareCoreAndHostSessionRunASessionOverClassicCan) {
  Pair p(can::Flavor::kClassic);
  std::string err;
  auto dev = fw_sim::makeSimDevice("glove5", fw_sim::SimDeviceOptions{}, err);
  ASSERT_TRUE(dev) << err;
  sim::BytePipe unused;
  sim::SimBoard board(dev->pwmCount(), dev->adcCount(), dev->encoderCount(), unused.end(0));
  board.board().packets = &p.dev;
  p.dev.setDevice(DeviceType::kGlove5, 1000);
  fw::CoreConfig cfg;
  fw::FirmwareCore core(board.board(), dev->app(), cfg);
  host::HostSession session(p.host);
  auto tick = [&]() {
    for (int i = 0; i < 10; ++i) dev->plant().step(1e-4, board.io());
    board.clock().advanceUs(1000);
    core.tick();
    session.poll(board.clock().nowUs() * 1000);
  };
  session.sendHello(99, DeviceType::kGlove5);
  tick();
  ASSERT_EQ(session.handshake(), host::HandshakeResult::kOk);
  Command c;
  c.mode = Mode::kSetpoint;
  c.channel_count = 5;
  c.timeout_ms = 20;
  for (int i = 0; i < 5; ++i) c.gain_scale_permille[i] = 1000;
  c.setpoint[1] = 1.0f;
  for (int k = 0; k < 20; ++k) {
    ASSERT_TRUE(session.sendCommand(c, board.clock().nowUs() * 1000));
    tick();
  }
  EXPECT_TRUE(core.outputsActive());
  EXPECT_EQ(core.counters().commands_applied, 20u);
  EXPECT_EQ(session.stats().telemetry_lost, 0u);
  EXPECT_GE(session.stats().telemetry_received, 19u);
  EXPECT_EQ(session.latest().cmd_seq_echo, c.seq);
  // A command part 1 with no part 0: rejected by the transport, counted by the device, seen by the host.
  can_frame junk{};
  junk.can_id = protocol::can::canId(protocol::can::Function::kCommandPart1Odd, 3);
  junk.len = 6;
  ASSERT_EQ(write(p.fds[0], &junk, CAN_MTU), static_cast<ssize_t>(CAN_MTU));
  ASSERT_TRUE(session.sendCommand(c, board.clock().nowUs() * 1000));
  tick();
  tick();
  EXPECT_EQ(p.dev.rxStats().sequence, 1u);
  EXPECT_EQ(session.stats().device_rx_errors, 1u);
  EXPECT_TRUE(core.outputsActive());
}
