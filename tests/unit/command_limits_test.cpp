// The session's one limits stage: device limits, then the patient's, on any command.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "phalanx/host/command_limits.h"

using namespace phalanx;
using host::CommandLimits;

namespace {

const protocol::DeviceLayout& glove() { return *protocol::layoutFor(protocol::DeviceType::kGlove5); }

protocol::Command setpointCommand(float v) {
  protocol::Command c;
  c.mode = protocol::Mode::kSetpoint;
  for (auto& s : c.setpoint) s = v;
  for (auto& g : c.gain_scale_permille) g = 1000;
  return c;
}

/// A patient stage that holds every channel to |x| <= 1 and records that it ran.
struct OneNewton : host::PatientLimitStage {
  int calls = 0;
  uint32_t limit(const host::TelemetryFrame&, protocol::Command& cmd) override {
    ++calls;
    uint32_t bits = 0;
    for (uint8_t i = 0; i < cmd.channel_count; ++i) {
      if (std::fabs(cmd.setpoint[i]) > 1.0f) {
        cmd.setpoint[i] = std::copysign(1.0f, cmd.setpoint[i]);
        bits |= 1u << i;
      }
    }
    return bits;
  }
};

}  // namespace

TEST(CommandLimits, SaturatesToTheDeviceLimitAndCountsIt) {
  CommandLimits limits(glove());
  protocol::Command c = setpointCommand(-3.0f * glove().setpoint_limit);
  EXPECT_EQ(limits.apply({}, c), CommandLimits::Verdict::kLimited);
  for (uint8_t i = 0; i < glove().setpoint_count; ++i) EXPECT_FLOAT_EQ(c.setpoint[i], -glove().setpoint_limit);
  EXPECT_EQ(limits.counters().device_limited, 1u);
  protocol::Command ok = setpointCommand(0.5f);
  EXPECT_EQ(limits.apply({}, ok), CommandLimits::Verdict::kPassed);
  EXPECT_EQ(limits.counters().device_limited, 1u);
}

TEST(CommandLimits, RefusesNonFiniteValuesAndUndefinedModesWithTheSafeCommand) {
  CommandLimits limits(glove());
  protocol::Command c = setpointCommand(1.0f);
  c.setpoint[2] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(limits.apply({}, c), CommandLimits::Verdict::kRefused);
  EXPECT_EQ(c.mode, protocol::Mode::kSafe);
  for (float s : c.setpoint) EXPECT_EQ(s, 0.0f);
  protocol::Command m = setpointCommand(0.0f);
  m.mode = static_cast<protocol::Mode>(protocol::kModeCount);
  EXPECT_EQ(limits.apply({}, m), CommandLimits::Verdict::kRefused);
  protocol::Command inf = setpointCommand(std::numeric_limits<float>::infinity());
  EXPECT_EQ(limits.apply({}, inf), CommandLimits::Verdict::kRefused);
  EXPECT_EQ(limits.counters().refused, 3u);
}

TEST(CommandLimits, UnusedChannelsCarryNothingAndGainsStayWithinTheProtocol) {
  CommandLimits limits(glove());
  protocol::Command c = setpointCommand(0.5f);
  c.gain_scale_permille[0] = 3000;
  limits.apply({}, c);
  EXPECT_EQ(c.gain_scale_permille[0], 2000);
  EXPECT_EQ(c.channel_count, glove().setpoint_count);
  for (uint8_t i = glove().setpoint_count; i < protocol::kMaxSetpoints; ++i) {
    EXPECT_EQ(c.setpoint[i], 0.0f);
    EXPECT_EQ(c.gain_scale_permille[i], 1000);
  }
}

TEST(CommandLimits, ThePatientsLimitsComeAfterTheDevicesOnEveryCommand) {
  CommandLimits limits(glove());
  OneNewton patient;
  limits.setPatientStage(&patient);
  protocol::Command c = setpointCommand(6.0f);
  EXPECT_EQ(limits.apply({}, c), CommandLimits::Verdict::kLimited);
  for (uint8_t i = 0; i < glove().setpoint_count; ++i) EXPECT_FLOAT_EQ(c.setpoint[i], 1.0f);
  EXPECT_EQ(limits.counters().patient_limited, 1u);
  // A refused command never reaches the patient stage (it is already the safe command).
  protocol::Command bad = setpointCommand(std::numeric_limits<float>::quiet_NaN());
  limits.apply({}, bad);
  EXPECT_EQ(patient.calls, 1);
}
