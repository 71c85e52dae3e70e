// phalanxd's unplug / re-plug state machine (host LinkRecovery) against a real firmware core and host session,
// over an in-memory cable that can be pulled: while unplugged nothing crosses and reopening fails. Checks: the
// loss is reported and no command is sent while offline; the device goes safe by its own command timeout;
// reopen is tried once per period; after re-plug a new handshake, the start-up parameters again, the
// command-timeout fault cleared, then control resumes with new commands only; a different device or a refused
// parameter ends the session; a loss during the handshake goes back to reconnecting.
// (The real links: tests/vm/usb_test.sh, usb-replug and acm-replug.)
#include <gtest/gtest.h>

#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "phalanx/apps/glove5.h"
#include "phalanx/fw/core.h"
#include "phalanx/fw_sim/sim_device.h"
#include "phalanx/host/link_recovery.h"
#include "phalanx/host/session.h"
#include "phalanx/protocol/codec.h"
#include "phalanx/protocol/messages.h"
#include "phalanx/sim/board.h"

using namespace phalanx;
using host::LinkRecovery;
using protocol::DeviceType;

namespace {

struct Msg {
  uint8_t id;
  std::vector<uint8_t> payload;
};

// Two PacketLink ends joined by a cable; pulled, it carries nothing.
struct Cable {
  bool plugged = true;
  bool wrong_port = false;              ///< the host end is open on another tty: nothing crosses either way
  bool next_reopen_wrong_port = false;  ///< the next reopen by name lands on another tty (it took the freed name)
  struct End final : hal::PacketLink {
    Cable* cable = nullptr;
    std::deque<Msg> rx;
    End* peer = nullptr;
    uint64_t sent = 0;
    bool send(uint8_t id, const uint8_t* p, size_t n) override {
      if (!cable->plugged) return false;
      if (cable->wrong_port) return true;  // written, to a port where no device listens
      peer->rx.push_back(Msg{id, std::vector<uint8_t>(p, p + n)});
      ++sent;
      return true;
    }
    bool receive(uint8_t& id, uint8_t* p, size_t& n) override {
      if (rx.empty()) return false;
      id = rx.front().id;
      n = rx.front().payload.size();
      std::copy(rx.front().payload.begin(), rx.front().payload.end(), p);
      rx.pop_front();
      return true;
    }
    hal::PacketRxStats rxStats() const override { return {}; }
  } host, dev;
  Cable() {
    host.cable = dev.cable = this;
    host.peer = &dev;
    dev.peer = &host;
  }
  void pull() {
    plugged = false;
    host.rx.clear();  // what was on the wire is gone
    dev.rx.clear();
  }
};

// The host side of the cable as the daemon sees it: lost until reopened after a re-plug.
struct CableLink final : host::RecoveryLink {
  Cable& cable;
  bool open = true;
  int reopen_calls = 0;
  int drops = 0;
  explicit CableLink(Cable& c) : cable(c) {}
  bool lost() override { return !open || !cable.plugged; }
  void drop() override {
    ++drops;
    open = false;
    cable.wrong_port = false;
  }
  std::string reopen() override {
    ++reopen_calls;
    if (!cable.plugged) return "no device";
    open = true;
    cable.wrong_port = cable.next_reopen_wrong_port;
    cable.next_reopen_wrong_port = false;
    return {};
  }
  void flush() override {}
  std::string describe() override { return open && cable.plugged ? "cable" : "cable pulled"; }
};

// One simulated device on the device end of the cable.
struct Device {
  std::unique_ptr<fw_sim::SimDevice> dev;
  sim::BytePipe unused;
  std::unique_ptr<sim::SimBoard> board;
  std::unique_ptr<fw::FirmwareCore> core;
  Device(const char* name, Cable& cable) {
    std::string err;
    dev = fw_sim::makeSimDevice(name, fw_sim::SimDeviceOptions{}, err);
    EXPECT_TRUE(dev) << err;
    board = std::make_unique<sim::SimBoard>(dev->pwmCount(), dev->adcCount(), dev->encoderCount(), unused.end(0));
    board->board().packets = &cable.dev;
    core = std::make_unique<fw::FirmwareCore>(board->board(), dev->app(), fw::CoreConfig{});
  }
  void tick() {
    for (int i = 0; i < 10; ++i) dev->plant().step(1e-4, board->io());
    board->clock().advanceUs(1000);
    core->tick();
  }
};

struct Rig {
  Cable cable;
  CableLink link{cable};
  std::unique_ptr<Device> device = std::make_unique<Device>("glove5", cable);
  host::HostSession session{cable.host};
  std::vector<std::string> log;
  uint32_t next_id = 100;
  uint64_t now_ns = 0;
  std::unique_ptr<LinkRecovery> rec;
  int commands_sent = 0;

  explicit Rig(std::vector<std::pair<uint16_t, float>> params = {}) {
    session.sendHello(next_id++, DeviceType::kGlove5);
    device->tick();
    now_ns += 1000000;
    session.poll(now_ns);
    EXPECT_EQ(session.handshake(), host::HandshakeResult::kOk);
    rec = std::make_unique<LinkRecovery>(
        link, session, DeviceType::kGlove5, std::move(params), host::LinkRecoveryOptions{},
        [this]() { return next_id++; }, [this](const std::string& m) { log.push_back(m); }, 0);
  }
  // One 1 kHz cycle as in phalanxd's loop: poll, recovery step, a command only when the step says control.
  LinkRecovery::Step cycle() {
    now_ns += 1000000;
    session.poll(now_ns);
    const LinkRecovery::Step st = rec->step(now_ns);
    if (st == LinkRecovery::Step::kControl) {
      protocol::Command c;
      c.mode = protocol::Mode::kSetpoint;
      c.channel_count = 5;
      c.timeout_ms = 20;
      for (int i = 0; i < 5; ++i) c.gain_scale_permille[i] = 1000;
      EXPECT_TRUE(session.sendCommand(c, now_ns));
      ++commands_sent;
    }
    device->tick();
    return st;
  }
  // One cycle connected, then the cable pulled for `cycles` cycles (the device goes safe by its command timeout).
  void pulledFor(int cycles) {
    cycle();
    cable.pull();
    for (int i = 0; i < cycles; ++i) cycle();
  }
  bool logged(const std::string& what) const {
    for (const auto& l : log) {
      if (l.find(what) != std::string::npos) return true;
    }
    return false;
  }
};

}  // namespace

TEST(LinkRecovery, UnplugGoesSafeReconnectsAndResumesWithNewCommandsOnly) {
  Rig r({{apps::glove5_param::kForceKp, 1.0f}});
  for (int i = 0; i < 50; ++i) ASSERT_EQ(r.cycle(), LinkRecovery::Step::kControl);
  EXPECT_TRUE(r.device->core->outputsActive());
  EXPECT_EQ(r.device->core->faultBits(), 0u);
  const uint32_t applied_before = r.device->core->counters().commands_applied;

  r.cable.pull();
  const int sent_before = r.commands_sent;
  for (int i = 0; i < 500; ++i) ASSERT_EQ(r.cycle(), LinkRecovery::Step::kOffline) << "cycle " << i;
  EXPECT_EQ(r.commands_sent, sent_before);  // nothing is sent while the link is down
  EXPECT_TRUE(r.logged("link lost at t="));
  EXPECT_EQ(r.link.drops, 1);
  EXPECT_EQ(r.rec->phase(), LinkRecovery::Phase::kDown);
  // Reopen at once, then every 100 ms: 500 ms offline → 5 or 6 attempts.
  EXPECT_GE(r.link.reopen_calls, 5);
  EXPECT_LE(r.link.reopen_calls, 6);
  // The device went safe by itself (command timeout), the commands it applied were those sent before the pull.
  EXPECT_FALSE(r.device->core->outputsActive());
  EXPECT_NE(r.device->core->faultBits() & protocol::fault::kCommandTimeout, 0u);
  EXPECT_EQ(r.device->core->counters().commands_applied, applied_before);

  r.cable.plugged = true;
  int offline_after_plug = 0;
  while (r.cycle() == LinkRecovery::Step::kOffline) {
    ASSERT_LT(++offline_after_plug, 300) << "control never resumed";
  }
  EXPECT_LE(offline_after_plug, 100 + 10);  // the next reopen (≤ 100 ms), handshake, parameter, first telemetry
  EXPECT_TRUE(r.logged("link back at t="));
  EXPECT_TRUE(r.logged("clearing faults latched during the outage: command-timeout"));
  EXPECT_NE(r.rec->stats().faults_after_reconnect & protocol::fault::kCommandTimeout, 0u);  // reported in faults_seen
  EXPECT_TRUE(r.logged("control resumed at t="));
  EXPECT_EQ(r.rec->phase(), LinkRecovery::Phase::kUp);
  EXPECT_EQ(r.rec->stats().outages, 1u);
  EXPECT_EQ(r.rec->stats().reconnects, 1u);
  EXPECT_GT(r.rec->stats().max_s, 0.5);
  EXPECT_LT(r.rec->stats().max_s, 0.62);
  EXPECT_EQ(r.rec->stats().cycles_offline, 500u + offline_after_plug);  // the resuming cycle sends no command yet
  for (int i = 0; i < 20; ++i) ASSERT_EQ(r.cycle(), LinkRecovery::Step::kControl);
  EXPECT_EQ(r.device->core->faultBits(), 0u);
  EXPECT_TRUE(r.device->core->outputsActive());
  EXPECT_EQ(r.session.handshake(), host::HandshakeResult::kOk);
  EXPECT_EQ(r.session.stats().telemetry_lost, 0u);  // the outage is not loss inside a session
}

TEST(LinkRecovery, LossDuringTheHandshakeGoesBackToReconnecting) {
  Rig r;
  r.pulledFor(150);
  r.cable.plugged = true;
  // Plug and pull again before the device can answer the new Hello.
  while (r.rec->phase() == LinkRecovery::Phase::kDown) {
    ASSERT_LT(r.now_ns, 2000000000ull);
    r.now_ns += 1000000;
    r.session.poll(r.now_ns);
    r.rec->step(r.now_ns);
  }
  EXPECT_EQ(r.rec->phase(), LinkRecovery::Phase::kHandshake);
  r.cable.pull();
  EXPECT_EQ(r.cycle(), LinkRecovery::Step::kOffline);
  EXPECT_EQ(r.rec->phase(), LinkRecovery::Phase::kDown);
  EXPECT_TRUE(r.logged("lost again before control resumed"));
  r.cable.plugged = true;
  int n = 0;
  while (r.cycle() != LinkRecovery::Step::kControl) ASSERT_LT(++n, 300);
  EXPECT_EQ(r.rec->stats().outages, 1u);  // one outage, resumed once
  EXPECT_EQ(r.rec->stats().reconnects, 1u);
}

TEST(LinkRecovery, AReopenedPortThatNeverAnswersIsClosedAndOpenedAgain) {
  // The soak's link_replug once reopened the device's name while another tty held the freed pty number: the
  // daemon said Hello to a port where no device listened, for the rest of the session.
  Rig r;
  r.pulledFor(50);
  r.cable.next_reopen_wrong_port = true;
  r.cable.plugged = true;
  int n = 0;
  while (r.cycle() != LinkRecovery::Step::kControl) ASSERT_LT(++n, 3000) << "stuck on the wrong port";
  EXPECT_GT(n, 2000) << "the first port was given the whole handshake timeout";
  EXPECT_TRUE(r.logged("no answer to the handshake within 2.0 s on the reopened link")) << r.log.back();
  EXPECT_EQ(r.link.drops, 2);  // the unplug, then the silent port
  EXPECT_EQ(r.rec->stats().outages, 1u);
  EXPECT_EQ(r.rec->stats().reconnects, 1u);
}

TEST(LinkRecovery, ADifferentDeviceAfterReplugEndsTheSession) {
  Rig r;
  r.pulledFor(50);
  r.device = std::make_unique<Device>("pantograph", r.cable);  // another board on the same port
  r.cable.plugged = true;
  LinkRecovery::Step st = LinkRecovery::Step::kOffline;
  for (int i = 0; i < 300 && st == LinkRecovery::Step::kOffline; ++i) st = r.cycle();
  EXPECT_EQ(st, LinkRecovery::Step::kFailed);
  // Hello asks for a glove5: the pantograph refuses the handshake, or (had it answered) the type check would.
  EXPECT_NE(r.rec->error().find("after reconnect"), std::string::npos) << r.rec->error();
  EXPECT_EQ(r.rec->stats().reconnects, 0u);
}

TEST(LinkRecovery, ARefusedStartupParameterEndsTheSession) {
  Rig r({{0x7777, 1.0f}});  // no such parameter
  r.pulledFor(50);
  r.cable.plugged = true;
  LinkRecovery::Step st = LinkRecovery::Step::kOffline;
  for (int i = 0; i < 300 && st == LinkRecovery::Step::kOffline; ++i) st = r.cycle();
  EXPECT_EQ(st, LinkRecovery::Step::kFailed);
  EXPECT_EQ(r.rec->error(), "after reconnect: device refused start-up parameter 30583");
}

// A byte stream reopened after an unplug: the frame the unplug cut and the tail of one the device was sending when
// the port reopened are dropped without being counted as rejected; the next whole frame decodes.
TEST(LinkRecovery, ReopenedByteStreamDropsTheCutFrameWithoutCountingIt) {
  protocol::Command c;
  c.channel_count = 5;
  uint8_t a[protocol::kMaxEncodedFrame];
  const size_t n = protocol::encodeFrame(c, a);
  ASSERT_GT(n, 10u);
  protocol::StreamDecoder d;
  for (size_t i = 0; i < n / 2; ++i) EXPECT_FALSE(d.push(a[i]));  // cut here by the unplug
  d.resync();
  for (size_t i = n / 3; i < n; ++i) EXPECT_FALSE(d.push(a[i]));  // the reopened port starts mid-frame
  bool got = false;
  for (size_t i = 0; i < n; ++i) got = d.push(a[i]);
  EXPECT_TRUE(got);
  EXPECT_EQ(d.stats().total_rejected(), 0u);
  // Without resync the same bytes are one rejected frame.
  protocol::StreamDecoder e;
  for (size_t i = 0; i < n / 2; ++i) e.push(a[i]);
  for (size_t i = n / 3; i < n; ++i) e.push(a[i]);
  EXPECT_EQ(e.stats().total_rejected(), 1u);
}

// A reopened port that starts at a frame boundary (a new pseudo-terminal, a re-enumerated CDC-ACM port): its first
// frame is whole and taken — it is typically the device's answer to the new handshake. (Dropping it unjudged, as
// the decoder once did, cost every reconnect a 2 s handshake retry: the soak's link_replug episodes.)
TEST(LinkRecovery, ReopenedByteStreamTakesAWholeFirstFrame) {
  protocol::HelloAck ack;
  ack.session_id = 0xCF35B4E3u;
  uint8_t a[protocol::kMaxEncodedFrame];
  const size_t n = protocol::encodeFrame(ack, a);
  protocol::StreamDecoder d;
  for (size_t i = 0; i < n / 2; ++i) EXPECT_FALSE(d.push(a[i]));  // the frame the unplug cut
  d.resync();
  bool got = false;
  for (size_t i = 0; i < n; ++i) got = d.push(a[i]);
  ASSERT_TRUE(got);
  EXPECT_EQ(d.frame().id, static_cast<uint8_t>(protocol::MsgId::kHelloAck));
  EXPECT_EQ(d.stats().total_rejected(), 0u);
  EXPECT_EQ(d.stats().frames_ok, 1u);
}
