#include <gtest/gtest.h>

#include <cmath>

#include "phalanx/fw/core.h"
#include "phalanx/host/session.h"
#include "phalanx/sim/board.h"

using namespace phalanx;
using protocol::Mode;

namespace {

// A two-channel test app: duty = setpoint / 10; reports a sensor fault on demand.
class TestApp : public fw::DeviceApp {
 public:
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
  uint16_t inject_sensor_fault = 0;
  int control_calls = 0;
  int safe_calls = 0;

 private:
  // A two-channel app that identifies as the SEA finger (its real layout, so the host accepts the handshake).
  protocol::DeviceLayout layout_ = protocol::kSeaFingerLayout;
  hal::Board* board_ = nullptr;
};

class CoreTest : public ::testing::Test {
 protected:
  CoreTest() : board(2, 4, 0, pipe.end(0)), core(board.board(), app, fw::CoreConfig{1000, 7, 4 * 69}), host(pipe.end(1)) {}

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
  EXPECT_EQ(host.deviceInfo().firmware_build_id, 7u);
  EXPECT_EQ(host.deviceInfo().tick_rate_hz, 1000);
  EXPECT_EQ(host.deviceInfo().setpoint_count, 2);
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
