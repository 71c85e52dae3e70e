#include <gtest/gtest.h>

#include <cmath>
#include <tuple>
#include <vector>

#include "phalanx/fw/core.h"
#include "phalanx/host/session.h"
#include "phalanx/sim/board.h"
#include "phalanx/sim/sim_flash.h"
#include "../support/test_image.h"

using namespace phalanx;
using protocol::Mode;

namespace {

// A two-channel test app: duty = setpoint / 10; reports a sensor fault on demand.
class TestApp : public fw::DeviceApp {
 public:
  TestApp() = default;
  explicit TestApp(const protocol::DeviceLayout& layout) : layout_(layout) {}
  const protocol::DeviceLayout& layout() const override { return layout_; }
  void init(hal::Board& board) override { board_ = &board; }
  uint16_t sense(float) override { return inject_sensor_fault; }
  uint16_t control(const protocol::Command& cmd, float) override {
    ++control_calls;
    for (uint8_t i = 0; i < 2; ++i) board_->pwm->setDuty(i, cmd.setpoint[i] / 10.0f);
    return 0;
  }
  void safe() override { ++safe_calls; }
  void fillSamples(int16_t* s) const override { s[0] = 123; }
  protocol::ParamStatus setParam(uint16_t id, float value) override {
    if (id != kAppParam) return protocol::ParamStatus::kUnknownParam;
    app_param = value;
    return protocol::ParamStatus::kOk;
  }
  static constexpr uint16_t kAppParam = 0x0100;
  float app_param = 0.0f;
  uint16_t inject_sensor_fault = 0;
  int control_calls = 0;
  int safe_calls = 0;

 private:
  // By default a two-channel app that identifies as the SEA finger (its real layout, so the host accepts the
  // handshake).
  protocol::DeviceLayout layout_ = protocol::kSeaFingerLayout;
  hal::Board* board_ = nullptr;
};

class CoreTest : public ::testing::Test {
 protected:
  // A build id above 2^24, which a float cannot hold exactly.
  static constexpr uint32_t kBuildId = 3713657881u;
  CoreTest() : board(2, 4, 0, pipe.end(0)), core(board.board(), app, fw::CoreConfig{1000, kBuildId, 4 * 69}), host(pipe.end(1)) {}

  // One 1 ms tick of the firmware, then let the host read.
  void tick() {
    board.clock().advanceUs(1000);
    core.tick();
    host.poll(board.clock().nowUs() * 1000);
  }
  void openSession() {
    host.sendHello(11, protocol::DeviceType::kAny);
    tick();
    ASSERT_EQ(host.handshake(), host::HandshakeResult::kOk);
  }
  protocol::Command command(float sp0, uint16_t timeout_ms = 10) {
    protocol::Command c;
    c.mode = Mode::kSetpoint;
    c.channel_count = 2;
    c.timeout_ms = timeout_ms;
    c.setpoint[0] = sp0;
    c.setpoint[1] = -sp0;
    return c;
  }
  void send(protocol::Command c) { host.sendCommand(c, board.clock().nowUs() * 1000); }
  /// Write a message to the device as it is, bypassing the host session (its own seq, any field values).
  template <class Msg>
  void sendRaw(const Msg& m) {
    uint8_t f[protocol::kMaxEncodedFrame];
    pipe.end(1).write(f, protocol::encodeFrame(m, f));
  }
  /// Write a frame with this ID and payload bytes (a valid CRC and length; any field values).
  void sendRawPayload(protocol::MsgId id, const uint8_t* payload, size_t len) {
    uint8_t f[protocol::kMaxEncodedFrame];
    pipe.end(1).write(f, protocol::encodeFrameRaw(static_cast<uint8_t>(id), payload, len, f));
  }
  protocol::Command commandWithSeq(uint16_t seq, float sp0, uint16_t timeout_ms = 10) {
    protocol::Command c = command(sp0, timeout_ms);
    c.seq = seq;
    return c;
  }
  /// Ask for a parameter and return the answer (status and value).
  protocol::ParamValue paramGet(uint16_t id) {
    host.sendParamGet(id);
    tick();
    EXPECT_TRUE(host.lastParamValid()) << "no answer to ParamGet " << id;
    return host.lastParam();
  }

  sim::BytePipe pipe;
  TestApp app;
  sim::SimBoard board;
  fw::FirmwareCore core;
  host::HostSession host;
};

}  // namespace

TEST_F(CoreTest, OutputsStaySafeUntilTheFirstValidCommand) {
  openSession();
  for (int i = 0; i < 5; ++i) tick();
  EXPECT_FALSE(board.io().pwm_enabled);
  EXPECT_EQ(app.control_calls, 0);
  send(command(0.5f));
  tick();
  EXPECT_TRUE(board.io().pwm_enabled);
  EXPECT_NEAR(board.io().pwm_duty[0], 0.05f, 1e-6f);
}

TEST_F(CoreTest, HandshakeReportsIdentityAndLayout) {
  openSession();
  EXPECT_EQ(host.deviceInfo().firmware_build_id, kBuildId);
  EXPECT_EQ(host.deviceInfo().tick_rate_hz, 1000);
  EXPECT_EQ(host.deviceInfo().setpoint_count, 2);
}

TEST_F(CoreTest, AHelloAfterAFrameAPreviousHostLeftUnfinishedIsAnswered) {
  // A previous host process wrote the first half of a command and went away (killed, or its close discarded the
  // rest): the device holds that fragment when the next host's Hello arrives.
  uint8_t f[protocol::kMaxEncodedFrame];
  const size_t n = protocol::encodeFrame(command(0.5f), f);
  pipe.end(1).write(f, n / 2);
  tick();
  openSession();
  EXPECT_EQ(host.deviceInfo().firmware_build_id, kBuildId);
  EXPECT_EQ(core.rxErrors(), 1u) << "the fragment is one damaged frame, the delimiter before the Hello none";
}

TEST_F(CoreTest, ARepeatedHelloOfTheOpenSessionIsAnsweredWithoutRestartingIt) {
  // The daemon says Hello again every 500 ms while it has no answer; one may arrive after the session has started.
  openSession();
  send(command(0.5f));
  tick();
  ASSERT_TRUE(board.io().pwm_enabled);
  host.sendHello(11, protocol::DeviceType::kAny);  // the same session id
  tick();
  EXPECT_EQ(host.handshake(), host::HandshakeResult::kOk);
  EXPECT_TRUE(board.io().pwm_enabled) << "the open session's repeated Hello must not drive the outputs safe";
  EXPECT_EQ(app.safe_calls, 0);
  send(command(0.5f));  // the command sequence goes on (not restarted: a stale sequence would be rejected)
  tick();
  EXPECT_TRUE(board.io().pwm_enabled);
  // Another session id is a new session: safe until its first command.
  host.sendHello(12, protocol::DeviceType::kAny);
  tick();
  EXPECT_FALSE(board.io().pwm_enabled);
}

TEST_F(CoreTest, HandshakeRefusesTheWrongDeviceType) {
  host.sendHello(1, protocol::DeviceType::kGlove5);
  tick();
  EXPECT_EQ(host.handshake(), host::HandshakeResult::kDeviceMismatch);
  EXPECT_NE(host.handshakeError().find("device type mismatch"), std::string::npos);
  EXPECT_FALSE(core.sessionOpen());
}

TEST_F(CoreTest, HandshakeRefusesAnotherProtocolVersion) {
  protocol::Hello h;
  h.protocol_version = protocol::kProtocolVersion + 1;
  uint8_t f[protocol::kMaxEncodedFrame];
  pipe.end(1).write(f, protocol::encodeFrame(h, f));
  tick();
  EXPECT_FALSE(core.sessionOpen());
}

TEST_F(CoreTest, MissingCommandsDriveOutputsSafeWithinTwoTicksOfTheTimeoutAndLatch) {
  openSession();
  send(command(0.5f, 10));
  tick();
  ASSERT_TRUE(board.io().pwm_enabled);
  const uint64_t deadline = core.commandDeadlineUs();
  int ticks_after_deadline = -1;
  for (int i = 0; i < 50; ++i) {
    tick();
    if (!board.io().pwm_enabled) {
      ticks_after_deadline = static_cast<int>((board.clock().nowUs() - deadline + 999) / 1000);
      break;
    }
  }
  ASSERT_GE(ticks_after_deadline, 0) << "outputs never went safe";
  EXPECT_LE(ticks_after_deadline, 2);
  EXPECT_TRUE(core.faultBits() & protocol::fault::kCommandTimeout);
  EXPECT_TRUE(host.latest().fault_bits & protocol::fault::kCommandTimeout);
  // Latched: a new command does not move the motors until the fault is cleared explicitly.
  send(command(0.5f));
  tick();
  EXPECT_FALSE(board.io().pwm_enabled);
  host.sendClearFaults();
  tick();
  EXPECT_EQ(core.faultBits(), 0);
  EXPECT_FALSE(board.io().pwm_enabled) << "clearing must not resume the old command";
  send(command(0.5f));
  tick();
  EXPECT_TRUE(board.io().pwm_enabled);
}

TEST_F(CoreTest, InvalidCommandsAreRejectedAndNeverMoveAMotor) {
  openSession();
  auto nan_cmd = command(0.0f);
  nan_cmd.setpoint[1] = NAN;
  auto inf_cmd = command(0.0f);
  inf_cmd.setpoint[0] = INFINITY;
  auto big = command(1.5f);  // limit 1.0
  auto wrong_count = command(0.1f);
  wrong_count.channel_count = 3;
  auto zero_timeout = command(0.1f, 0);
  auto long_timeout = command(0.1f, 5000);
  auto flags = command(0.1f);
  flags.flags = 1;
  auto gain = command(0.1f);
  gain.gain_scale_permille[0] = 5000;
  for (auto c : {nan_cmd, inf_cmd, big, wrong_count, zero_timeout, long_timeout, flags, gain}) {
    send(c);
    tick();
    EXPECT_FALSE(board.io().pwm_enabled);
  }
  EXPECT_EQ(core.counters().commands_rejected, 8u);
  EXPECT_EQ(app.control_calls, 0);
  EXPECT_EQ(host.lastEvent().code, protocol::EventCode::kCommandRejected);
}

TEST_F(CoreTest, CommandsBeforeAHandshakeAreRejected) {
  send(command(0.5f));
  tick();
  EXPECT_FALSE(board.io().pwm_enabled);
  EXPECT_EQ(core.counters().commands_rejected, 1u);
}

TEST_F(CoreTest, EstopLatchesAndCannotBeClearedWhileHeld) {
  openSession();
  send(command(0.5f));
  tick();
  ASSERT_TRUE(board.io().pwm_enabled);
  board.io().estop_pressed = true;
  send(command(0.5f));
  tick();
  EXPECT_FALSE(board.io().pwm_enabled);
  EXPECT_FALSE(board.io().drive_enable);
  host.sendClearFaults();
  tick();
  EXPECT_EQ(host.lastEvent().code, protocol::EventCode::kClearRefused);
  EXPECT_TRUE(core.faultBits() & protocol::fault::kEstop);
  board.io().estop_pressed = false;
  host.sendClearFaults();
  tick();
  EXPECT_EQ(core.faultBits(), 0);
}

TEST_F(CoreTest, ASensorFaultGoesSafeInTheSameTick) {
  openSession();
  send(command(0.5f));
  tick();
  ASSERT_TRUE(board.io().pwm_enabled);
  app.inject_sensor_fault = protocol::fault::kSensorStuck;
  send(command(0.5f));
  tick();
  EXPECT_FALSE(board.io().pwm_enabled);
  EXPECT_GE(app.safe_calls, 1);
  EXPECT_TRUE(host.latest().fault_bits & protocol::fault::kSensorStuck);
}

TEST_F(CoreTest, LostCommandsAreCountedFromSequenceGaps) {
  openSession();
  auto c = command(0.1f);
  host.sendCommand(c, 0);
  tick();
  host.sendCommand(c, 0);  // seq 2, then skip 3 and 4
  tick();
  c.seq = 0;
  protocol::Command skip = command(0.1f);
  host.sendCommand(skip, 0);  // 3 (consumed by the host but dropped below)
  pipe.end(0).read(nullptr, 0);
  tick();
  EXPECT_EQ(core.counters().cmd_lost, 0u);
  // Forge a gap: the next command the device sees jumps by 5.
  protocol::Command jump = command(0.1f);
  jump.seq = static_cast<uint16_t>(core.counters().commands_applied + 6);
  uint8_t f[protocol::kMaxEncodedFrame];
  pipe.end(1).write(f, protocol::encodeFrame(jump, f));
  tick();
  EXPECT_EQ(core.counters().cmd_lost, 5u);
}

TEST_F(CoreTest, TelemetryThatArrivesLateIsDroppedNeitherLostNorAClockWrap) {
  // Seen over CAN-FD in the VM lane: a frame older than the newest received. Before, its older device time was
  // taken for a 32-bit wrap (the device clock jumped 71 minutes) and it replaced the newest state.
  openSession();
  tick();
  const host::TelemetryFrame first = host.latest();
  auto deviceSends = [&](uint16_t dseq) {
    protocol::Telemetry t;
    t.seq = static_cast<uint16_t>(first.seq + dseq);
    t.time_us = static_cast<uint32_t>(first.device_time_us + 1000u * dseq);
    uint8_t f[protocol::kMaxEncodedFrame];
    pipe.end(0).write(f, protocol::encodeFrame(t, f));
  };
  for (int d : {1, 3, 2, 4}) deviceSends(static_cast<uint16_t>(d));
  host.poll(board.clock().nowUs() * 1000);
  EXPECT_EQ(host.stats().telemetry_lost, 0u);
  EXPECT_EQ(host.stats().telemetry_late, 1u);
  EXPECT_EQ(host.latest().seq, static_cast<uint16_t>(first.seq + 4));
  EXPECT_EQ(host.latest().device_time_us, first.device_time_us + 4000u) << "no wrap";
}

TEST_F(CoreTest, TelemetryEchoesTheCommandAndCountsNoLossOnAQuietLink) {
  openSession();
  for (int i = 0; i < 500; ++i) {
    send(command(0.2f, 20));
    tick();
  }
  EXPECT_EQ(host.stats().telemetry_lost, 0u);
  EXPECT_EQ(host.stats().device_cmd_lost, 0u);
  EXPECT_EQ(host.latest().cmd_seq_echo, 500);
  EXPECT_EQ(host.latest().mode, Mode::kSetpoint);
  EXPECT_EQ(host.roundTripUs().count(), 500u);
}

TEST_F(CoreTest, ReadOnlyParametersRefuseWrites) {
  openSession();
  host.sendParamGet(0x0001);
  tick();
  ASSERT_TRUE(host.lastParamValid());
  EXPECT_EQ(host.lastParam().value, 1000.0f);
  protocol::ParamSet s;
  s.param_id = 0x0001;
  s.value = 5.0f;
  uint8_t f[protocol::kMaxEncodedFrame];
  pipe.end(1).write(f, protocol::encodeFrame(s, f));
  tick();
  EXPECT_EQ(host.lastParam().status, protocol::ParamStatus::kReadOnly);
}

// --- Command sequence (docs/protocol.md, "Command sequence") ---------------------------------------------------

TEST_F(CoreTest, AReplayedCommandIsDiscardedCountedAndDoesNotFeedTheWatchdog) {
  openSession();
  sendRaw(commandWithSeq(10, 0.5f, 10));
  tick();
  ASSERT_TRUE(board.io().pwm_enabled);
  const uint64_t rx_before = host.stats().device_rx_errors;
  bool replay_applied = false;
  for (int i = 0; i < 200; ++i) {
    sendRaw(commandWithSeq(10, 0.9f, 10));  // the same seq, another setpoint: must never reach the motors
    tick();
    replay_applied = replay_applied || std::fabs(board.io().pwm_duty[0] - 0.09f) < 1e-6f;
  }
  EXPECT_FALSE(replay_applied);
  EXPECT_EQ(core.counters().commands_applied, 1u);
  EXPECT_EQ(core.counters().cmd_stale, 200u);
  EXPECT_EQ(core.counters().cmd_lost, 0u);
  EXPECT_EQ(host.stats().device_rx_errors - rx_before, 200u) << "each stale command is a rejected frame";
  // Replays are not fresh commands: the watchdog expired 10 ms after the only applied one.
  EXPECT_TRUE(core.faultBits() & protocol::fault::kCommandTimeout);
  EXPECT_EQ(host.lastEvent().code, protocol::EventCode::kCommandRejected);
  EXPECT_EQ(host.lastEvent().detail, static_cast<uint8_t>(protocol::RejectReason::kStaleSequence));
  EXPECT_EQ(host.lastEvent().value, 10.0f);
}

TEST_F(CoreTest, OlderCommandsAreDiscardedAcrossTheSequenceWrap) {
  openSession();
  sendRaw(commandWithSeq(0xFFFE, 0.1f));
  tick();
  sendRaw(commandWithSeq(0xFFFF, 0.2f));
  tick();
  sendRaw(commandWithSeq(0x0001, 0.3f));  // newer across the wrap; 0x0000 never arrived
  tick();
  EXPECT_EQ(core.counters().commands_applied, 3u);
  EXPECT_EQ(core.counters().cmd_lost, 1u);
  sendRaw(commandWithSeq(0xFFFF, 0.4f));  // older across the wrap
  tick();
  sendRaw(commandWithSeq(0x8001, 0.5f));  // exactly half the range ahead counts as older
  tick();
  EXPECT_EQ(core.counters().commands_applied, 3u);
  EXPECT_EQ(core.counters().cmd_stale, 2u);
  EXPECT_NEAR(board.io().pwm_duty[0], 0.03f, 1e-6f);
  EXPECT_EQ(host.latest().cmd_seq_echo, 0x0001);
  sendRaw(commandWithSeq(0x8000, 0.6f));  // 0x7FFF ahead: newer, 0x7FFE missing
  tick();
  EXPECT_EQ(core.counters().commands_applied, 4u);
  EXPECT_EQ(core.counters().cmd_lost, 1u + 0x7FFEu);
  EXPECT_EQ(host.latest().cmd_seq_echo, 0x8000);
}

TEST_F(CoreTest, CmdLostCountsMissingCommandsNotGaps) {
  openSession();
  sendRaw(commandWithSeq(1, 0.1f));
  tick();
  sendRaw(commandWithSeq(5, 0.1f));  // one gap of three missing commands
  tick();
  tick();
  EXPECT_EQ(core.counters().cmd_lost, 3u);
  EXPECT_EQ(host.stats().device_cmd_lost, 3u);
}

TEST_F(CoreTest, ARejectedCommandWasReceivedNotLost) {
  openSession();
  sendRaw(commandWithSeq(1, 0.1f));
  tick();
  protocol::Command bad = commandWithSeq(2, 0.1f);
  bad.setpoint[1] = NAN;
  sendRaw(bad);
  tick();
  sendRaw(commandWithSeq(3, 0.1f));
  tick();
  EXPECT_EQ(core.counters().commands_rejected, 1u);
  EXPECT_EQ(core.counters().cmd_lost, 0u);
  EXPECT_EQ(host.latest().cmd_seq_echo, 3);
}

TEST_F(CoreTest, AHelloResetsTheExpectedSequence) {
  openSession();
  sendRaw(commandWithSeq(500, 0.1f));
  tick();
  host.sendHello(12, protocol::DeviceType::kAny);
  tick();
  ASSERT_EQ(host.handshake(), host::HandshakeResult::kOk);
  EXPECT_FALSE(board.io().pwm_enabled) << "a new session starts safe";
  sendRaw(commandWithSeq(3, 0.2f));  // a new session may restart its sequence anywhere
  tick();
  EXPECT_TRUE(board.io().pwm_enabled);
  EXPECT_EQ(core.counters().commands_applied, 2u);
  EXPECT_EQ(core.counters().cmd_stale, 0u);
  EXPECT_EQ(core.counters().cmd_lost, 0u);
}

TEST_F(CoreTest, WithoutAHelloARestartedSequenceIsStale) {
  openSession();
  sendRaw(commandWithSeq(500, 0.1f));
  tick();
  sendRaw(commandWithSeq(3, 0.2f));
  tick();
  EXPECT_EQ(core.counters().commands_applied, 1u);
  EXPECT_EQ(core.counters().cmd_stale, 1u);
  EXPECT_NEAR(board.io().pwm_duty[0], 0.01f, 1e-6f);
}

TEST_F(CoreTest, TheHostSessionsSequenceKeepsWorkingAcrossANewHandshake) {
  openSession();
  for (int i = 0; i < 20; ++i) {
    send(command(0.1f));
    tick();
  }
  host.sendHello(12, protocol::DeviceType::kAny);  // a reconnect: new session, the host's seq goes on
  tick();
  ASSERT_EQ(host.handshake(), host::HandshakeResult::kOk);
  for (int i = 0; i < 20; ++i) {
    send(command(0.1f));
    tick();
  }
  EXPECT_EQ(core.counters().commands_applied, 40u);
  EXPECT_EQ(core.counters().cmd_stale, 0u);
  EXPECT_EQ(core.counters().cmd_lost, 0u);
  EXPECT_TRUE(board.io().pwm_enabled);
}

// --- Rejections are answered and counted ------------------------------------------------------------------------

TEST_F(CoreTest, ACommandBeforeAnyHelloIsAnsweredWithNoSession) {
  send(command(0.5f));
  tick();
  EXPECT_FALSE(board.io().pwm_enabled);
  ASSERT_EQ(host.stats().events, 1u);
  EXPECT_EQ(host.lastEvent().code, protocol::EventCode::kCommandRejected);
  EXPECT_EQ(host.lastEvent().detail, static_cast<uint8_t>(protocol::RejectReason::kNoSession));
}

TEST_F(CoreTest, AHelloWithAnUndefinedDeviceTypeOrReservedByteIsRejectedAndCounted) {
  openSession();
  send(command(0.5f, 50));
  tick();
  ASSERT_TRUE(board.io().pwm_enabled);
  const uint64_t rx_before = host.stats().device_rx_errors;
  protocol::Hello good;
  good.session_id = 99;
  uint8_t p[protocol::Hello::kWireSize];
  protocol::encodePayload(good, p);
  p[2] = 9;  // expected_device: undefined
  sendRawPayload(protocol::MsgId::kHello, p, sizeof p);
  tick();
  protocol::Hello reserved = good;
  reserved.reserved = 7;
  sendRaw(reserved);
  tick();
  EXPECT_EQ(host.stats().device_rx_errors - rx_before, 2u);
  EXPECT_EQ(core.counters().frames_invalid, 2u);
  EXPECT_TRUE(board.io().pwm_enabled) << "a rejected Hello must not open a new session (which starts safe)";
}

TEST_F(CoreTest, AParamSetWithAReservedFieldSetIsRejectedCountedAndNotApplied) {
  openSession();
  tick();
  const uint64_t rx_before = host.stats().device_rx_errors;
  protocol::ParamSet set;
  set.param_id = TestApp::kAppParam;
  set.reserved = 1;
  set.value = 2.0f;
  sendRaw(set);
  tick();
  EXPECT_EQ(app.app_param, 0.0f);
  EXPECT_FALSE(host.lastParamValid()) << "a rejected frame is not answered";
  EXPECT_EQ(host.stats().device_rx_errors - rx_before, 1u);
  set.reserved = 0;
  sendRaw(set);
  tick();
  EXPECT_EQ(app.app_param, 2.0f);
}

TEST_F(CoreTest, DeviceToHostMessagesSentToTheDeviceAreRejectedAndCounted) {
  openSession();
  tick();
  const uint64_t rx_before = host.stats().device_rx_errors;
  sendRaw(protocol::Telemetry{});
  sendRaw(protocol::HelloAck{});
  sendRaw(protocol::Event{});
  sendRaw(protocol::ParamValue{});
  tick();
  tick();
  EXPECT_EQ(host.stats().device_rx_errors - rx_before, 4u);
  EXPECT_EQ(core.counters().frames_wrong_direction, 4u);
}

TEST_F(CoreTest, UpdateRequestsToABoardWithoutAnUpdaterAreAnsweredNoUpdater) {
  protocol::UpdateBegin b;
  b.image_size = 4096;
  b.build_id = 1;
  host.sendUpdate(b);
  tick();
  protocol::UpdateStatus st;
  ASSERT_TRUE(host.popUpdateStatus(st));
  EXPECT_EQ(st.answers, protocol::MsgId::kUpdateBegin);
  EXPECT_EQ(st.result, protocol::UpdateResult::kNoUpdater);
}

namespace {
/// A board with an updater for the update tests: slots of 4 pages of 2 KiB (slot 0 pages 0-3, slot 1 pages 8-11),
/// the boot records in pages 4-5, empty flash; the two-channel test app; a host session on its link.
struct UpdaterBoard {
  UpdaterBoard() : update(flash, layout, fw::chooseBoot(flash, layout)), board(2, 4, 0, pipe.end(0)),
                   core(board.board(), app, config()), host(pipe.end(1)) {}
  static fw::UpdateLayout makeLayout() {
    fw::UpdateLayout l;
    l.slot_first_page[1] = 8;
    l.slot_pages = 4;
    l.record_first_page = 4;
    l.board = static_cast<uint8_t>(image::BoardId::kStm32g474);
    l.device_type = static_cast<uint8_t>(protocol::kSeaFingerLayout.type);
    return l;
  }
  fw::CoreConfig config() {
    fw::CoreConfig cfg{1000, 3713657881u, 4 * 69};
    cfg.update = &update;
    return cfg;
  }
  /// One 1 ms tick of the firmware, then the host reads.
  void step() {
    board.clock().advanceUs(1000);
    core.tick();
    host.poll(board.clock().nowUs() * 1000);
  }
  auto parts() { return std::tie(update, app, board, core, host); }

  sim::RamFlash flash{12, 2048};
  fw::UpdateLayout layout = makeLayout();
  fw::FirmwareUpdate update;
  sim::BytePipe pipe;
  TestApp app;
  sim::SimBoard board;
  fw::FirmwareCore core;
  host::HostSession host;
};
}  // namespace

TEST_F(CoreTest, AnUpdateBeginsOnlyWithTheOutputsOffAndThenNoCommandDrivesThem) {
  UpdaterBoard u;
  auto [update, a, b, c, h] = u.parts();
  const fw::UpdateLayout& l = u.layout;
  auto step = [&]() { u.step(); };
  h.sendHello(3, protocol::DeviceType::kAny);
  step();
  ASSERT_EQ(h.handshake(), host::HandshakeResult::kOk);
  protocol::Command cmd = command(0.5f, 50);
  h.sendCommand(cmd, 0);
  step();
  ASSERT_TRUE(c.outputsActive());
  protocol::UpdateBegin begin;
  begin.image_size = 4096;
  begin.build_id = 9;
  begin.device_type = l.device_type;
  begin.board = l.board;
  h.sendUpdate(begin);
  step();
  protocol::UpdateStatus st;
  ASSERT_TRUE(h.popUpdateStatus(st));
  EXPECT_EQ(st.result, protocol::UpdateResult::kBusy);  // in motion: refused, nothing changed
  EXPECT_TRUE(c.outputsActive());
  EXPECT_FALSE(update.inProgress());
  protocol::Command safe = command(0.0f, 50);
  safe.mode = Mode::kSafe;
  h.sendCommand(safe, 0);
  step();
  ASSERT_FALSE(c.outputsActive());
  h.sendUpdate(begin);
  step();
  ASSERT_TRUE(h.popUpdateStatus(st));
  EXPECT_EQ(st.result, protocol::UpdateResult::kOk);
  EXPECT_TRUE(update.inProgress());
  const int controls = a.control_calls;
  protocol::Command again = command(0.5f, 50);
  h.sendCommand(again, 0);
  step();
  step();
  EXPECT_FALSE(c.outputsActive());
  EXPECT_EQ(a.control_calls, controls);
  EXPECT_FALSE(b.io().pwm_enabled);
  EXPECT_EQ(h.lastEvent().detail, static_cast<uint8_t>(protocol::RejectReason::kUpdateInProgress));
}

// core_param::kUpdateTrial (docs/firmware-update.md "Trial boot"): read 0 when the running image is confirmed; a
// confirm is 1 only, never while the outputs are driven; unknown to a board without an updater.
TEST_F(CoreTest, TheUpdateTrialParameterConfirmsOnlyWithTheOutputsOff) {
  UpdaterBoard u;
  auto [update, a, b, c, h] = u.parts();
  auto step = [&]() { u.step(); };
  const uint16_t id = protocol::core_param::kUpdateTrial;
  auto answer = [&](bool set, float value) {
    if (set) {
      h.sendParamSet(id, value);
    } else {
      h.sendParamGet(id);
    }
    step();
    EXPECT_TRUE(h.lastParamValid());
    return h.lastParam();
  };
  EXPECT_EQ(answer(false, 0).status, protocol::ParamStatus::kOk);
  EXPECT_EQ(answer(false, 0).value, 0.0f);
  h.sendHello(3, protocol::DeviceType::kAny);
  step();
  protocol::Command cmd = command(0.5f, 50);
  h.sendCommand(cmd, 0);
  step();
  ASSERT_TRUE(c.outputsActive());
  EXPECT_EQ(answer(true, 1.0f).status, protocol::ParamStatus::kBusy);
  EXPECT_EQ(answer(true, 2.0f).status, protocol::ParamStatus::kOutOfRange);
  protocol::Command safe = command(0.0f, 50);
  safe.mode = Mode::kSafe;
  h.sendCommand(safe, 0);
  step();
  ASSERT_FALSE(c.outputsActive());
  EXPECT_EQ(answer(true, 1.0f).status, protocol::ParamStatus::kOk);  // confirmed already: nothing to write
  EXPECT_FALSE(update.onTrial());
}

TEST_F(CoreTest, ABoardWithoutAnUpdaterDoesNotKnowTheUpdateTrialParameter) {
  host.sendParamGet(protocol::core_param::kUpdateTrial);
  tick();
  ASSERT_TRUE(host.lastParamValid());
  EXPECT_EQ(host.lastParam().status, protocol::ParamStatus::kUnknownParam);
}

TEST_F(CoreTest, NothingReceivedAfterACommittedUpdateIsHandledBeforeTheReset) {
  // A board with an updater and an image of 5000 bytes streamed into slot 1; the commit and a Hello arrive in the
  // same tick: the board resets after the commit, so the Hello must wait for the new image (the host's handshake
  // after an update must reach the new firmware, not the old one).
  UpdaterBoard u;
  auto [update, a, b, c, h] = u.parts();
  const fw::UpdateLayout& l = u.layout;
  auto step = [&]() { u.step(); };
  const std::vector<uint8_t> img = test::makeImage(0x51515151u, l.device_type, image::BoardId::kStm32g474, 5000);
  const image::ImageInfo info = test::infoOf(img);
  h.sendUpdate(image::updateBeginFor(info));
  step();
  for (uint32_t at = 0; at < img.size(); at += protocol::kUpdateChunkBytes) {
    protocol::UpdateData d;
    d.offset = at;
    d.length = static_cast<uint8_t>(std::min<size_t>(protocol::kUpdateChunkBytes, img.size() - at));
    std::memcpy(d.data, &img[at], d.length);
    h.sendUpdate(d);
    step();
  }
  protocol::UpdateCommit commit;
  commit.image_crc32 = info.image_crc32;
  commit.build_id = info.build_id;
  h.sendUpdate(commit);
  h.sendHello(77, protocol::DeviceType::kAny);
  step();
  protocol::UpdateStatus st, last;
  while (h.popUpdateStatus(st)) last = st;
  EXPECT_EQ(last.answers, protocol::MsgId::kUpdateCommit);
  EXPECT_EQ(last.result, protocol::UpdateResult::kCommitted);
  EXPECT_TRUE(update.rebootRequested());
  EXPECT_EQ(h.handshake(), host::HandshakeResult::kPending);  // the old firmware did not answer the Hello
  EXPECT_FALSE(c.sessionOpen());
}

namespace {
/// A packet transport that delivers whatever the test queues, lengths included (a transport is expected to check
/// lengths; the core must still never act on a payload that does not decode).
class ScriptedPackets : public hal::PacketLink {
 public:
  void queue(protocol::MsgId id, const uint8_t* payload, size_t len) {
    Msg m;
    m.id = static_cast<uint8_t>(id);
    m.len = len;
    for (size_t i = 0; i < len; ++i) m.payload[i] = payload[i];
    rx_.push_back(m);
  }
  bool send(uint8_t msg_id, const uint8_t* payload, size_t len) override {
    Msg m;
    m.id = msg_id;
    m.len = len;
    for (size_t i = 0; i < len; ++i) m.payload[i] = payload[i];
    tx.push_back(m);
    return true;
  }
  bool receive(uint8_t& msg_id, uint8_t* payload, size_t& len) override {
    if (rx_.empty()) return false;
    const Msg m = rx_.front();
    rx_.erase(rx_.begin());
    msg_id = m.id;
    len = m.len;
    for (size_t i = 0; i < m.len; ++i) payload[i] = m.payload[i];
    return true;
  }
  hal::PacketRxStats rxStats() const override { return {}; }
  struct Msg {
    uint8_t id = 0;
    size_t len = 0;
    uint8_t payload[protocol::kMaxPayload] = {};
  };
  std::vector<Msg> tx;

 private:
  std::vector<Msg> rx_;
};
}  // namespace

TEST(CorePackets, PayloadsThatFailToDecodeAreRejectedCountedAndNotAnswered) {
  sim::BytePipe pipe;
  TestApp app;
  sim::SimBoard board(2, 4, 0, pipe.end(0));
  ScriptedPackets packets;
  board.board().packets = &packets;
  fw::FirmwareCore core(board.board(), app, fw::CoreConfig{});
  uint8_t p[protocol::kMaxPayload] = {};
  protocol::Hello hello;
  hello.session_id = 5;
  protocol::encodePayload(hello, p);
  packets.queue(protocol::MsgId::kHello, p, protocol::Hello::kWireSize);
  board.clock().advanceUs(1000);
  core.tick();
  ASSERT_TRUE(core.sessionOpen());
  packets.tx.clear();
  uint8_t clear[4] = {5, 0, 0, 0};
  packets.queue(protocol::MsgId::kClearFaults, clear, 3);
  packets.queue(protocol::MsgId::kParamGet, p, 1);
  packets.queue(protocol::MsgId::kParamSet, p, 7);
  board.clock().advanceUs(1000);
  core.tick();
  EXPECT_EQ(core.counters().frames_invalid, 3u);
  ASSERT_FALSE(packets.tx.empty());
  for (const auto& m : packets.tx) {
    EXPECT_EQ(m.id, static_cast<uint8_t>(protocol::MsgId::kTelemetry)) << "only telemetry goes out, no answer";
  }
  protocol::Telemetry t;
  ASSERT_TRUE(protocol::decodePayload(packets.tx.back().payload, packets.tx.back().len, t));
  EXPECT_EQ(t.rx_errors, 3);
}

// --- Lock ----------------------------------------------------------------------------------------------------

TEST_F(CoreTest, LockOnABackDrivableDeviceIsTheSafeState) {
  openSession();
  protocol::Command lock = command(0.0f, 50);
  lock.mode = Mode::kLock;
  send(lock);
  tick();
  EXPECT_FALSE(board.io().pwm_enabled);
  EXPECT_EQ(app.control_calls, 0);
  EXPECT_EQ(host.latest().mode, Mode::kSafe);
  EXPECT_EQ(host.latest().state_flags & protocol::state::kOutputsActive, 0);
  EXPECT_EQ(host.latest().cmd_seq_echo, 1) << "the lock command was applied (as safe)";
  host.sendParamSet(TestApp::kAppParam, 3.0f);
  tick();
  ASSERT_TRUE(host.lastParamValid());
  EXPECT_EQ(host.lastParam().status, protocol::ParamStatus::kOk) << "outputs are off: parameters may be set";
  EXPECT_EQ(app.app_param, 3.0f);
}

TEST(CoreLock, LockOnASelfLockingDeviceIsAnActiveMode) {
  sim::BytePipe pipe;
  TestApp app(protocol::kGlove5Layout);
  sim::SimBoard board(5, 4, 0, pipe.end(0));
  fw::FirmwareCore core(board.board(), app, fw::CoreConfig{});
  host::HostSession host(pipe.end(1));
  auto tick = [&]() {
    board.clock().advanceUs(1000);
    core.tick();
    host.poll(board.clock().nowUs() * 1000);
  };
  host.sendHello(1, protocol::DeviceType::kGlove5);
  tick();
  ASSERT_EQ(host.handshake(), host::HandshakeResult::kOk);
  protocol::Command lock;
  lock.mode = Mode::kLock;
  lock.channel_count = 5;
  lock.timeout_ms = 50;
  host.sendCommand(lock, 0);
  tick();
  EXPECT_TRUE(board.io().pwm_enabled);
  EXPECT_EQ(app.control_calls, 1) << "the app holds its mechanism; the core keeps supervising";
  EXPECT_EQ(host.latest().mode, Mode::kLock);
  EXPECT_NE(host.latest().state_flags & protocol::state::kOutputsActive, 0);
}

// --- Fields that must be zero --------------------------------------------------------------------------------

TEST_F(CoreTest, CommandFieldsThatMustBeZeroOrBoundedAreCheckedOnEveryChannel) {
  openSession();
  auto reserved = command(0.1f);
  reserved.reserved = 1;
  auto unused_setpoint = command(0.1f);
  unused_setpoint.setpoint[2] = 0.5f;  // the device has two channels
  auto unused_gain = command(0.1f);
  unused_gain.gain_scale_permille[5] = 3000;
  auto unused_nan = command(0.1f);
  unused_nan.setpoint[7] = NAN;
  struct Expect {
    protocol::Command cmd;
    protocol::RejectReason reason;
    uint8_t channel;
  };
  const Expect cases[] = {{reserved, protocol::RejectReason::kReservedNotZero, 0xFF},
                          {unused_setpoint, protocol::RejectReason::kOutOfRange, 2},
                          {unused_gain, protocol::RejectReason::kOutOfRange, 5},
                          {unused_nan, protocol::RejectReason::kNonFinite, 7}};
  for (const Expect& e : cases) {
    send(e.cmd);
    tick();
    EXPECT_FALSE(board.io().pwm_enabled);
    EXPECT_EQ(host.lastEvent().code, protocol::EventCode::kCommandRejected);
    EXPECT_EQ(host.lastEvent().detail, static_cast<uint8_t>(e.reason));
    EXPECT_EQ(host.lastEvent().channel, e.channel);
  }
  EXPECT_EQ(core.counters().commands_rejected, 4u);
  EXPECT_EQ(app.control_calls, 0);
  // What every host sends: unused setpoints 0, every gain (used or not) at most 2000 permille.
  auto nominal = command(0.1f);
  for (auto& g : nominal.gain_scale_permille) g = 1000;
  send(nominal);
  tick();
  EXPECT_TRUE(board.io().pwm_enabled);
}

// --- ClearFaults -----------------------------------------------------------------------------------------------

namespace {
void recordEvent(void* ctx, const protocol::Event& e) { static_cast<std::vector<protocol::Event>*>(ctx)->push_back(e); }
}  // namespace

TEST_F(CoreTest, ClearFaultsWithNothingLatchedChangesNothing) {
  std::vector<protocol::Event> events;
  host.setEventCallback(recordEvent, &events);
  openSession();
  send(command(0.5f, 50));
  tick();
  ASSERT_TRUE(board.io().pwm_enabled);
  events.clear();
  const int calls = app.control_calls;
  host.sendClearFaults();
  tick();
  EXPECT_TRUE(board.io().pwm_enabled) << "the command in effect goes on";
  EXPECT_EQ(app.control_calls, calls + 1);
  EXPECT_TRUE(events.empty()) << "nothing was cleared: no event";
}

TEST_F(CoreTest, ClearFaultsIsRefusedWhileTheSensorConditionIsStillPresent) {
  std::vector<protocol::Event> events;
  host.setEventCallback(recordEvent, &events);
  openSession();
  send(command(0.5f, 50));
  tick();
  app.inject_sensor_fault = protocol::fault::kSensorSaturated;  // e.g. the glove's pad pressed to full scale
  tick();
  ASSERT_TRUE(core.faultBits() & protocol::fault::kSensorSaturated);
  events.clear();
  host.sendClearFaults();
  tick();
  ASSERT_EQ(events.size(), 1u) << "one answer: refused (not cleared, then latched again)";
  EXPECT_EQ(events[0].code, protocol::EventCode::kClearRefused);
  EXPECT_EQ(events[0].value, static_cast<float>(protocol::fault::kSensorSaturated));
  EXPECT_TRUE(core.faultBits() & protocol::fault::kSensorSaturated);
  app.inject_sensor_fault = 0;
  tick();
  events.clear();
  host.sendClearFaults();
  tick();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].code, protocol::EventCode::kFaultsCleared);
  EXPECT_EQ(events[0].value, static_cast<float>(protocol::fault::kSensorSaturated)) << "value = the bits cleared";
  EXPECT_EQ(core.faultBits(), 0);
}

// --- Core parameters ------------------------------------------------------------------------------------------

TEST_F(CoreTest, TheBuildIdReadsExactlyFromItsTwoHalves) {
  openSession();
  const protocol::ParamValue lo = paramGet(protocol::core_param::kBuildIdLow);
  const protocol::ParamValue hi = paramGet(protocol::core_param::kBuildIdHigh);
  ASSERT_EQ(lo.status, protocol::ParamStatus::kOk);
  ASSERT_EQ(hi.status, protocol::ParamStatus::kOk);
  const uint32_t id = static_cast<uint32_t>(hi.value) << 16 | static_cast<uint32_t>(lo.value);
  EXPECT_EQ(id, kBuildId);
  EXPECT_EQ(id, host.deviceInfo().firmware_build_id);
  protocol::ParamSet s;
  s.param_id = protocol::core_param::kBuildIdHigh;
  sendRaw(s);
  tick();
  EXPECT_EQ(host.lastParam().status, protocol::ParamStatus::kReadOnly);
}

TEST_F(CoreTest, TheDeviceVariantIsAReadOnlyCoreParameter) {
  openSession();
  const protocol::ParamValue v = paramGet(protocol::core_param::kDeviceVariant);
  EXPECT_EQ(v.status, protocol::ParamStatus::kOk);
  EXPECT_EQ(v.value, 0.0f);
}

TEST(CoreVariant, TheConfiguredVariantIsReported) {
  sim::BytePipe pipe;
  TestApp app;
  sim::SimBoard board(2, 4, 0, pipe.end(0));
  fw::CoreConfig cfg;
  cfg.device_variant = protocol::variant::kSeaTestRig;
  fw::FirmwareCore core(board.board(), app, cfg);
  host::HostSession host(pipe.end(1));
  host.sendParamGet(protocol::core_param::kDeviceVariant);
  board.clock().advanceUs(1000);
  core.tick();
  host.poll(0);
  ASSERT_TRUE(host.lastParamValid());
  EXPECT_EQ(host.lastParam().value, static_cast<float>(protocol::variant::kSeaTestRig));
}
