// ClientPort, the client channel's loop side, driven cycle by cycle with synthetic telemetry: model-level state
// (glove, SEA finger, pen) from the host's device models, model-level commands converted before the limits stage,
// the compliant fallback in missed cycles, refusals, the deadline, and no allocation per cycle. The client's side
// is the shared-memory block itself (what libphalanx writes), attached the way the socket thread attaches one.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <string>

#include "../support/counting_allocator.h"  // g_allocations
#include "phalanx/glove/kinematics.h"
#include "phalanx/host/client/client_port.h"
#include "phalanx/host/pen/force_split.h"
#include "phalanx/host/sea/sea_finger_controller.h"
#include "phalanx/pen/kinematics.h"
#include "phalanx/sea/kinematics.h"

namespace wire = phalanx::client_wire;
namespace hc = phalanx::host::client;
using phalanx::host::TelemetryFrame;
using phalanx::protocol::Command;

namespace {

constexpr uint64_t kPeriodNs = 1000000;  // 1 kHz

struct Rig {
  explicit Rig(const phalanx::protocol::DeviceLayout& layout, uint16_t deadline_ms = 20)
      : server(options(), hc::DeviceIdentity{&layout, 1000, 0}), port(server, layout, 1000, nullptr) {
    const std::string err = server.start();
    EXPECT_EQ(err, "");
    auto& a = server.attachment();
    a.deadline_ms.store(deadline_ms);
    a.fallback.store(0);
    a.generation.store(7);  // what the socket thread does after a successful negotiation
  }
  static hc::ClientOptions options() {
    hc::ClientOptions o;
    o.socket_path = "/tmp/phalanx_cpt_" + std::to_string(getpid()) + "_" + std::to_string(++counter) + "/c.sock";
    return o;
  }
  /// The client writes a command (as libphalanx does).
  void send(wire::CommandPayload p) {
    p.generation = 7;
    p.command_seq = ++seq;
    wire::seqlockWrite(server.channel().command.seq, server.channel().command.payload, p);
  }
  /// One daemon cycle: the client port's command (if it commands), then the state it publishes.
  bool cycle(TelemetryFrame& tel, Command& cmd) {
    tel.device_time_us += 1000;
    ++tel.seq;
    now += kPeriodNs;
    cmd = Command{};
    const bool commands = port.overrideCommand(tel, cmd, now);
    port.publish(tel, cmd, now, ++cycles);
    return commands;
  }
  wire::StatePayload state() { return server.channel().state.payload; }

  static inline int counter = 0;
  hc::Server server;
  hc::ClientPort port;
  uint32_t seq = 0;
  uint64_t now = 1000000000ull, cycles = 0;
};

TelemetryFrame gloveTelemetry(double pip_flex) {
  TelemetryFrame tel;
  tel.mode = phalanx::protocol::Mode::kSetpoint;
  for (size_t f = 0; f < 5; ++f) {
    const auto m = phalanx::glove::defaultModel<double>(static_cast<phalanx::glove::FingerId>(f));
    phalanx::glove::Data<double> d;
    phalanx::glove::computeFromTheta(m, {-0.4, -pip_flex, -0.3}, d);
    for (size_t j = 0; j < 3; ++j) tel.value[3 * f + j] = static_cast<float>(d.alpha_rad[j]);
    tel.value[15 + f] = 0.5f;
  }
  return tel;
}

TEST(ClientPort, GloveStateIsTheKinematicsAndAFingertipForceIsItsPadNormalComponent) {
  Rig rig(phalanx::protocol::kGlove5Layout);
  TelemetryFrame tel = gloveTelemetry(0.6);
  Command cmd;
  EXPECT_FALSE(rig.cycle(tel, cmd)) << "no command yet: the built-in controller's stands";
  const wire::StatePayload s = rig.state();
  const auto model = phalanx::glove::defaultModel<double>(phalanx::glove::FingerId::kIndex);
  phalanx::glove::Data<double> d;
  phalanx::glove::computeFromAlpha(model, {tel.value[3], tel.value[4], tel.value[5]}, d);
  ASSERT_EQ(s.glove.valid[1], 1);
  EXPECT_NEAR(s.glove.joint_rad[1][1], -0.6, 1e-5);
  EXPECT_NEAR(s.glove.fingertip[1][0], d.O_u_tip[0], 1e-6);
  EXPECT_NEAR(s.glove.fingertip[1][2], d.O_u_tip[2], 1e-6);
  EXPECT_FLOAT_EQ(s.glove.pad_force_N[1], 0.5f);

  wire::CommandPayload p;
  p.kind = wire::CommandKind::kGloveFingertipForce;
  p.model[2] = 1.0f;  // index: 1 N along x, 2 N along y
  p.model[3] = 2.0f;
  rig.send(p);
  ASSERT_TRUE(rig.cycle(tel, cmd));
  const auto n = phalanx::glove::padNormal(d.O_u_tip[2]);
  EXPECT_NEAR(cmd.setpoint[1], 1.0 * n[0] + 2.0 * n[1], 1e-5);
  EXPECT_EQ(cmd.setpoint[0], 0.0f);
  EXPECT_EQ(rig.state().rendered, static_cast<uint8_t>(wire::Rendered::kCommand));
}

TEST(ClientPort, AMissedCycleRendersTheFallbackSpringAtTheNewState) {
  Rig rig(phalanx::protocol::kGlove5Layout, 50);
  TelemetryFrame tel = gloveTelemetry(0.6);
  Command cmd;
  rig.cycle(tel, cmd);
  const wire::StatePayload s0 = rig.state();
  wire::CommandPayload p;
  p.kind = wire::CommandKind::kGloveFingertipForce;
  p.fallback.kind = wire::FallbackKind::kSpring;
  p.fallback.element[1] = {{s0.glove.fingertip[1][0], s0.glove.fingertip[1][1] + 0.01f, 0.0f}, 200.0f, 0.0f};
  rig.send(p);
  ASSERT_TRUE(rig.cycle(tel, cmd));
  EXPECT_EQ(cmd.setpoint[1], 0.0f) << "the fresh command (0 N) is what is sent";
  // No new command: the spring, 200 N/m · 10 mm along +y, at the current pose.
  ASSERT_TRUE(rig.cycle(tel, cmd));
  const double phi = s0.glove.fingertip[1][2];
  EXPECT_NEAR(cmd.setpoint[1], 200.0 * 0.01 * std::cos(phi), 2e-4);
  EXPECT_EQ(rig.state().rendered, static_cast<uint8_t>(wire::Rendered::kFallbackSpring));
  EXPECT_EQ(rig.state().fallback_cycles, 1u);
  // The finger moves (more flexion): the spring follows the new fingertip position.
  TelemetryFrame moved = gloveTelemetry(0.8);
  moved.device_time_us = tel.device_time_us;
  moved.seq = tel.seq;
  ASSERT_TRUE(rig.cycle(moved, cmd));
  const wire::StatePayload s2 = rig.state();
  const double fx = 200.0 * static_cast<double>(s0.glove.fingertip[1][0] - s2.glove.fingertip[1][0]);
  const double fy = 200.0 * static_cast<double>(s0.glove.fingertip[1][1] + 0.01f - s2.glove.fingertip[1][1]);
  const auto n = phalanx::glove::padNormal<double>(s2.glove.fingertip[1][2]);
  EXPECT_NEAR(cmd.setpoint[1], fx * n[0] + fy * n[1], 2e-4);
  // Past the deadline: force off (safe), cause client-timeout.
  for (int i = 0; i < 60; ++i) rig.cycle(moved, cmd);
  EXPECT_EQ(cmd.mode, phalanx::protocol::Mode::kSafe);
  EXPECT_EQ(rig.state().force_off_cause, wire::ForceOffCause::kClientTimeout);
}

TEST(ClientPort, NonFiniteOrWrongModelCommandsAreRefusedAndCounted) {
  Rig rig(phalanx::protocol::kGlove5Layout);
  TelemetryFrame tel = gloveTelemetry(0.6);
  Command cmd;
  rig.cycle(tel, cmd);
  wire::CommandPayload p;
  p.kind = wire::CommandKind::kGloveFingertipForce;
  p.model[0] = NAN;
  rig.send(p);
  rig.cycle(tel, cmd);
  EXPECT_EQ(cmd.mode, phalanx::protocol::Mode::kSafe);
  EXPECT_EQ(rig.state().refused_invalid, 1u);
  p.model[0] = 0.0f;
  p.kind = wire::CommandKind::kPenWrench;  // not this device's
  rig.send(p);
  rig.cycle(tel, cmd);
  EXPECT_EQ(rig.state().refused_invalid, 2u);
  p.kind = wire::CommandKind::kGloveFingertipForce;
  p.fallback.kind = wire::FallbackKind::kSpring;
  p.fallback.element[2].stiffness = -5.0f;  // a negative spring pushes away: refused
  rig.send(p);
  rig.cycle(tel, cmd);
  EXPECT_EQ(rig.state().refused_invalid, 3u);
  p.fallback.element[2].stiffness = 5.0f;
  p.fallback.element[2].target[0] = INFINITY;
  rig.send(p);
  rig.cycle(tel, cmd);
  EXPECT_EQ(rig.state().refused_invalid, 4u);
  for (float s : cmd.setpoint) EXPECT_EQ(s, 0.0f);
}

TelemetryFrame seaTelemetry() {
  namespace ps = phalanx::sea;
  const auto m = ps::defaultModel<double>();
  ps::Data<double> d;
  EXPECT_EQ(ps::computeFromFinger(m, ps::FingerAngles<double>{-0.5, -0.6, -0.3, 0.0}, d), ps::Status::kOk);
  TelemetryFrame tel;
  tel.mode = phalanx::protocol::Mode::kSetpoint;
  for (size_t i = 0; i < ps::kNumSensors; ++i) tel.value[phalanx::host::sea::kSampleSensor0 + i] = static_cast<float>(d.sensors_rad[i]);
  tel.value[phalanx::host::sea::kSampleSeaTorque0] = 0.1f;
  tel.value[phalanx::host::sea::kSampleSeaTorque0 + 1] = -0.05f;
  return tel;
}

TEST(ClientPort, SeaFingerTorquesGoThroughJnTransposeAndSaturateTogether) {
  namespace ps = phalanx::sea;
  Rig rig(phalanx::protocol::kSeaFingerLayout);
  TelemetryFrame tel = seaTelemetry();
  Command cmd;
  rig.cycle(tel, cmd);
  const wire::StatePayload s = rig.state();
  ASSERT_EQ(s.sea.valid, 1);
  EXPECT_NEAR(s.sea.flexion_rad[0], 0.5, 1e-5);
  EXPECT_NEAR(s.sea.flexion_rad[1], 0.6, 1e-5);
  // The measured finger torque is J_n^{-T} τ_j (001 eq 9) at this pose.
  ps::Data<double> d;
  ps::computeFromFinger(ps::defaultModel<double>(), ps::FingerAngles<double>{-0.5, -0.6, -0.3, 0.0}, d);
  ASSERT_TRUE(d.J_valid);
  ps::Vec2<double> tf{};
  ASSERT_EQ(ps::fingerTorqueFromExoTorque(d.J_n, ps::Vec2<double>{0.1, -0.05}, 1e-6, tf), ps::Status::kOk);
  EXPECT_NEAR(s.sea.finger_torque_Nm[0], tf[0], 1e-4);
  EXPECT_NEAR(s.sea.finger_torque_Nm[1], tf[1], 1e-4);

  wire::CommandPayload p;
  p.kind = wire::CommandKind::kSeaFingerTorque;
  p.model[0] = 0.1f;
  p.model[1] = 0.05f;
  rig.send(p);
  rig.cycle(tel, cmd);
  const auto tj = ps::exoTorqueFromFingerTorque(d.J_n, ps::Vec2<double>{0.1, 0.05});  // eq 6/11
  EXPECT_NEAR(cmd.setpoint[0], tj[0], 1e-4);
  EXPECT_NEAR(cmd.setpoint[1], tj[1], 1e-4);
  EXPECT_EQ(rig.state().model_saturated, 0u);
  // 3 N·m asked: scaled down together to |τ_j| ≤ 0.5 N·m, direction kept, counted.
  p.model[0] = 3.0f;
  p.model[1] = 1.5f;
  rig.send(p);
  rig.cycle(tel, cmd);
  EXPECT_LE(std::fmax(std::fabs(cmd.setpoint[0]), std::fabs(cmd.setpoint[1])), 0.5f + 1e-6f);
  EXPECT_NEAR(cmd.setpoint[0] / cmd.setpoint[1], tj[0] / tj[1], 1e-3);
  EXPECT_EQ(rig.state().model_saturated, 1u);
  EXPECT_LT(rig.state().model_scale, 1.0f);
}

TEST(ClientPort, APenWrenchGoesThroughTheForceSplitAndTheMeasuredWrenchIsItsStatics) {
  namespace pp = phalanx::pen;
  Rig rig(phalanx::protocol::kPantographLayout);
  TelemetryFrame tel;  // home: all joints at their home angles
  tel.mode = phalanx::protocol::Mode::kSetpoint;
  Command cmd;
  rig.cycle(tel, cmd);
  ASSERT_EQ(rig.state().pen.valid, 1);
  pp::Model<double> m;
  ASSERT_EQ(pp::makeModel(pp::defaultGeometry<double>(), m), pp::Status::kOk);
  pp::Data<double> kin;
  ASSERT_TRUE(pp::isUsable(pp::computeForward(m, m.q_home_rad, kin)));
  EXPECT_NEAR(rig.state().pen.centre_m[2], kin.B_p_centre[2], 1e-6);

  wire::CommandPayload p;
  p.kind = wire::CommandKind::kPenWrench;
  p.model[1] = 2.0f;   // 2 N up
  p.model[3] = 0.05f;  // 0.05 N·m about x
  rig.send(p);
  rig.cycle(tel, cmd);
  phalanx::host::pen::PenForceSplitter split;
  phalanx::host::pen::SplitResult r;
  split.split(kin, phalanx::host::pen::PenWrench{{0.0, 2.0, 0.0}, {0.05, 0.0, 0.0}}, r);
  for (size_t i = 0; i < 6; ++i) EXPECT_NEAR(cmd.setpoint[i], r.tau_Nm[i], 1e-5) << "joint " << i;
  // Those torques measured back: the state's wrench is the commanded one.
  for (size_t i = 0; i < 6; ++i) tel.value[6 + i] = cmd.setpoint[i];
  rig.cycle(tel, cmd);
  const wire::StatePayload s = rig.state();
  EXPECT_NEAR(s.pen.force_N[1], 2.0, 1e-4);
  EXPECT_NEAR(s.pen.force_N[0], 0.0, 1e-4);
  EXPECT_NEAR(s.pen.torque_Nm[0], 0.05, 1e-4);
  // 100 N asked: the split scales it to the torque limits (direction kept), counted; never above 2.1 N·m.
  p.model[1] = 100.0f;
  p.model[3] = 0.0f;
  rig.send(p);
  rig.cycle(tel, cmd);
  for (size_t i = 0; i < 6; ++i) EXPECT_LE(std::fabs(cmd.setpoint[i]), 2.1f);
  EXPECT_EQ(rig.state().model_saturated, 1u);
  EXPECT_LT(rig.state().model_scale, 1.0f);
}

TEST(ClientPort, CyclesDoNotAllocate) {
  for (const auto* layout : {&phalanx::protocol::kGlove5Layout, &phalanx::protocol::kSeaFingerLayout,
                             &phalanx::protocol::kPantographLayout}) {
    Rig rig(*layout);
    TelemetryFrame tel = layout == &phalanx::protocol::kGlove5Layout    ? gloveTelemetry(0.6)
                         : layout == &phalanx::protocol::kSeaFingerLayout ? seaTelemetry()
                                                                          : TelemetryFrame{};
    Command cmd;
    rig.cycle(tel, cmd);
    wire::CommandPayload p;
    p.kind = layout == &phalanx::protocol::kGlove5Layout    ? wire::CommandKind::kGloveFingertipForce
             : layout == &phalanx::protocol::kSeaFingerLayout ? wire::CommandKind::kSeaFingerTorque
                                                              : wire::CommandKind::kPenWrench;
    p.model[0] = 0.1f;
    p.fallback.kind = wire::FallbackKind::kSpring;
    p.fallback.element[0].stiffness = 100.0f;
    const long before = g_allocations.load();
    for (int i = 0; i < 200; ++i) {
      if (i % 3 == 0) rig.send(p);  // fresh commands and missed cycles (the fallback spring)
      rig.cycle(tel, cmd);
    }
    EXPECT_EQ(g_allocations.load() - before, 0) << layout->name;
    EXPECT_GT(rig.state().fallback_cycles, 100u);
  }
}

}  // namespace

// An in-process source (the DDS bridge's commands, docs/dds.md §"Commands"): the same checks, one commander at a
// time, its commands through the same path, and a timeout recorded with its source.
TEST(ClientPort, AnInProcessSourceIsAClientWithTheSameRulesAndItsTimeoutIsRecordedAsIts) {
  hc::ClientOptions o;  // no socket: the shared memory only
  hc::Server server(o, hc::DeviceIdentity{&phalanx::protocol::kGlove5Layout, 1000, 0});
  ASSERT_EQ(server.start(), "");
  hc::ClientPort port(server, phalanx::protocol::kGlove5Layout, 1000, nullptr);
  std::string why;
  EXPECT_EQ(server.attachInProcess(1, wire::Fallback::kSafe, hc::CommandSource::kDds, why), 0u);  // < 2 periods
  EXPECT_NE(why.find("deadline_ms 1"), std::string::npos) << why;
  const uint32_t g = server.attachInProcess(20, wire::Fallback::kSafe, hc::CommandSource::kDds, why);
  ASSERT_NE(g, 0u) << why;
  EXPECT_EQ(server.attachInProcess(20, wire::Fallback::kSafe, hc::CommandSource::kDds, why), 0u);
  EXPECT_EQ(why, "another client holds this device");
  EXPECT_EQ(server.counters().refused_busy.load(), 1u);
  TelemetryFrame tel = gloveTelemetry(0.6);
  uint64_t now = 1000000000ull;
  Command cmd;
  wire::CommandPayload p;
  p.generation = g;
  p.command_seq = 1;
  p.setpoint[1] = 12.0f;  // beyond the glove's 10 N: the limits stage (after this port) saturates it
  server.writeInProcess(p);
  for (int c = 0; c < 40; ++c) {
    tel.device_time_us += 1000;
    ++tel.seq;
    now += kPeriodNs;
    cmd = Command{};
    const bool commands = port.overrideCommand(tel, cmd, now);
    EXPECT_TRUE(commands);
    if (c == 0) {
      EXPECT_EQ(cmd.setpoint[1], 12.0f);  // the source's command, before the limits stage
    }
    port.publish(tel, cmd, now, static_cast<uint64_t>(c));
  }
  EXPECT_EQ(cmd.mode, phalanx::protocol::Mode::kSafe);  // 20 ms without a new command: forced off
  const nlohmann::json j = port.summaryJson(0);
  ASSERT_EQ(j["force_off_records"].size(), 1u) << j.dump();
  EXPECT_EQ(j["force_off_records"][0]["cause"], "client-timeout");
  EXPECT_EQ(j["force_off_records"][0]["source"], "dds");
  EXPECT_EQ(j["dds_attachments"], 1);
  server.goneInProcess(g);  // its writer went away: another source may attach once the loop let go
  tel.device_time_us += 1000;
  port.overrideCommand(tel, cmd, now + kPeriodNs);
  port.publish(tel, cmd, now + kPeriodNs, 41);
  EXPECT_NE(server.attachInProcess(20, wire::Fallback::kSafe, hc::CommandSource::kDds, why), 0u) << why;
}
