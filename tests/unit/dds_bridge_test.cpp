// The DDS bridge's parts that need no network: the `dds` configuration section, the model state it publishes
// (the client channel's device-model stage, put into the ROS shapes; checked against the device models in both
// directions), and the loop's hand-over ring (drops counted).
#include <gtest/gtest.h>

#include <cmath>

#include "phalanx/host/config.h"
#include "phalanx/host/dds/dds_bridge.h"
#include "phalanx/host/client/device_model.h"
#include "phalanx/host/dds/model_view.h"

using namespace phalanx;
using phalanx::host::loadConfigText;
using phalanx::host::RunOptions;

TEST(DdsConfig, OffByDefaultAndEveryKeyApplies) {
  RunOptions o;
  EXPECT_FALSE(o.dds.enabled);
  const std::string err = loadConfigText(
      "dds:\n  domain_id: 42\n  interface: eth1\n  namespace: lab/glove_a\n  state_rate_hz: 250\n"
      "  diagnostics_rate_hz: 2\n  state_reliability: reliable\n  state_depth: 5\n  diagnostics_depth: 20\n"
      "  queue_slots: 1024\n  topics: {joint_states: true, poses: false, wrenches: true, diagnostics: false}\n",
      "t.yaml", o);
  ASSERT_EQ(err, "");
  EXPECT_TRUE(o.dds.enabled);  // a section without `enabled` is meant to be used
  EXPECT_EQ(o.dds.domain_id, 42u);
  EXPECT_EQ(o.dds.interface, "eth1");
  EXPECT_EQ(o.dds.ns, "lab/glove_a");
  EXPECT_EQ(o.dds.state_rate_hz, 250.0);
  EXPECT_EQ(o.dds.diagnostics_rate_hz, 2.0);
  EXPECT_EQ(o.dds.state_reliability, "reliable");
  EXPECT_EQ(o.dds.state_depth, 5u);
  EXPECT_EQ(o.dds.diagnostics_depth, 20u);
  EXPECT_EQ(o.dds.queue_slots, 1024u);
  EXPECT_TRUE(o.dds.joint_states);
  EXPECT_FALSE(o.dds.poses);
  EXPECT_FALSE(o.dds.diagnostics);
  EXPECT_FALSE(o.dds.commands);  // commands stay off unless enabled
}

TEST(DdsConfig, CommandsAreOffUnlessEnabledAndValidated) {
  RunOptions o;
  ASSERT_EQ(loadConfigText("dds:\n  commands: {deadline_ms: 100}\n", "t.yaml", o), "");
  EXPECT_FALSE(o.dds.commands);
  EXPECT_TRUE(o.dds.announce);  // rt/phalanx/devices unless turned off
  ASSERT_EQ(loadConfigText("dds:\n  topics: {announce: false}\n", "t.yaml", o), "");
  EXPECT_FALSE(o.dds.announce);
  ASSERT_EQ(loadConfigText("dds:\n  commands: {enabled: true, deadline_ms: 100, fallback: transparent, depth: 8}\n",
                           "t.yaml", o),
            "");
  EXPECT_TRUE(o.dds.commands);
  EXPECT_EQ(o.dds.command_deadline_ms, 100u);
  EXPECT_EQ(o.dds.command_fallback, "transparent");
  EXPECT_EQ(o.dds.command_depth, 8u);
  const auto err = [](const std::string& text) {
    RunOptions r;
    std::string e = loadConfigText(text, "t.yaml", r);
    if (e.empty()) e = host::dds::validateDdsOptions(r.dds, 1000);
    return e;
  };
  EXPECT_NE(err("dds: {commands: {enabled: true, deadline_ms: 1}}\n").find("dds.commands.deadline_ms: must be in [2, 1000]"),
            std::string::npos);
  EXPECT_NE(err("dds: {commands: {enabled: true, fallback: hold}}\n").find("dds.commands.fallback"), std::string::npos);
  EXPECT_NE(err("dds: {commands: {enabled: true, depth: 0}}\n").find("dds.commands.depth"), std::string::npos);
  EXPECT_NE(err("dds: {commands: {enabled: yes please}}\n").find("dds.commands.enabled: expected a boolean"),
            std::string::npos);
  EXPECT_NE(err("dds: {commands: {rate: 5}}\n").find("dds.commands.rate: unknown key"), std::string::npos);
}

TEST(DdsConfig, RefusesWhatIsWrongNamingTheKey) {
  const auto err = [](const std::string& yaml) {
    RunOptions o;
    const std::string e = loadConfigText(yaml, "t.yaml", o);
    EXPECT_FALSE(o.dds.enabled) << "a refused file changed the options";
    return e;
  };
  EXPECT_NE(err("dds: {domian_id: 3}\n").find("dds.domian_id: unknown key"), std::string::npos);
  EXPECT_NE(err("dds: {topics: {joints: true}}\n").find("dds.topics.joints: unknown key"), std::string::npos);
  EXPECT_NE(err("dds:\n  domain_id: 1\n  domain_id: 2\n").find("domain_id"), std::string::npos);  // duplicate
  EXPECT_NE(err("dds: {domain_id: 233}\n").find("dds.domain_id: must be in [0, 232]"), std::string::npos);
  EXPECT_NE(err("dds: {domain_id: -1}\n").find("dds.domain_id"), std::string::npos);
  EXPECT_NE(err("dds: {state_rate_hz: 1001}\n").find("dds.state_rate_hz: must be in [1, rate_hz = 1000]"),
            std::string::npos);
  EXPECT_NE(err("dds: {state_rate_hz: .nan}\n").find("dds.state_rate_hz"), std::string::npos);
  EXPECT_NE(err("dds: {diagnostics_rate_hz: 0}\n").find("dds.diagnostics_rate_hz"), std::string::npos);
  EXPECT_NE(err("dds: {state_reliability: sometimes}\n").find("dds.state_reliability"), std::string::npos);
  EXPECT_NE(err("dds: {state_depth: 0}\n").find("dds.state_depth"), std::string::npos);
  EXPECT_NE(err("dds: {queue_slots: 8}\n").find("dds.queue_slots"), std::string::npos);
  EXPECT_NE(err("dds: {namespace: /abs}\n").find("dds.namespace"), std::string::npos);
  EXPECT_NE(err("dds: {namespace: 'a b'}\n").find("dds.namespace"), std::string::npos);
  EXPECT_NE(err("dds: {interface: 'eth0\"/><x'}\n").find("dds.interface"), std::string::npos);
  EXPECT_NE(err("dds: {enabled: maybe}\n").find("dds.enabled: expected a boolean"), std::string::npos);
  EXPECT_NE(err("dds: {topics: {joint_states: false, poses: false, wrenches: false, diagnostics: false}}\n")
                .find("dds.topics: every topic is off"),
            std::string::npos);
  EXPECT_NE(err("dds: [1]\n").find("dds: expected a mapping"), std::string::npos);
}

TEST(DdsConfig, ShippedConfigParses) {
  RunOptions o;
  EXPECT_EQ(host::loadConfigFile(std::string(PHALANX_SOURCE_DIR) + "/config/phalanxd.yaml", o), "");
  EXPECT_FALSE(o.dds.enabled);  // off in the shipped file
}

namespace {
std::array<glove::Model<double>, 5> defaultGlove() { return host::client::ModelGeometry::defaultGlove(); }

/// What the bridge publishes for one telemetry frame: its own device-model stage, then the view.
host::dds::ModelState viewOf(const protocol::DeviceLayout& layout, const host::TelemetryFrame& tel) {
  host::client::DeviceModelStage stage(layout, host::client::ModelGeometry{});
  stage.observe(tel);
  host::dds::ModelState s;
  host::dds::modelView(layout, stage, tel, s);
  return s;
}
}  // namespace

TEST(ModelState, GloveFlexionAndFingertipFromTheMechanismAngles) {
  const auto glove_models = defaultGlove();
  host::TelemetryFrame tel;
  tel.sample_count = 25;
  std::array<glove::Vec3<double>, 5> theta{};
  for (std::size_t f = 0; f < 5; ++f) {
    theta[f] = {-0.3 - 0.05 * static_cast<double>(f), -0.6, -0.2};
    glove::Vec3<double> alpha{};
    ASSERT_TRUE(glove::isUsable(glove::alphaFromTheta(glove_models[f], theta[f], alpha)));
    for (std::size_t j = 0; j < 3; ++j) tel.value[3 * f + j] = static_cast<float>(alpha[j]);
    tel.value[15 + f] = 1.5f + static_cast<float>(f);
  }
  const host::dds::ModelState s = viewOf(protocol::kGlove5Layout, tel);
  ASSERT_EQ(s.joint_count, 30);
  ASSERT_EQ(s.body_count, 5);
  for (std::size_t f = 0; f < 5; ++f) {
    for (std::size_t j = 0; j < 3; ++j) {
      EXPECT_NEAR(s.position[3 * f + j], -theta[f][j], 2e-4) << "finger " << f << " joint " << j;  // float α
      EXPECT_EQ(s.position[15 + 3 * f + j], static_cast<double>(tel.value[3 * f + j]));
    }
    const glove::Vec3<double> u = glove::tipPoseFromTheta(glove_models[f].finger, theta[f]);
    EXPECT_NEAR(s.pose[f].position[0], u[0], 1e-5);
    EXPECT_NEAR(s.pose[f].position[1], u[1], 1e-5);
    EXPECT_NEAR(2.0 * std::atan2(s.pose[f].orientation[2], s.pose[f].orientation[3]), u[2], 1e-5);
    EXPECT_EQ(s.wrench[f].force[1], 1.5 + static_cast<double>(f));
    EXPECT_TRUE(s.body_valid[f]);
  }
  const host::dds::ModelNames n = host::dds::modelNames(protocol::DeviceType::kGlove5);
  EXPECT_STREQ(n.joints[3], "index_mcp");
  EXPECT_STREQ(n.joints[29], "little_mech3");
}

TEST(ModelState, GloveNaNIsNaNNotAPose) {
  host::TelemetryFrame tel;
  tel.value.fill(0.1f);
  tel.value[0] = std::nanf("");
  const host::dds::ModelState s = viewOf(protocol::kGlove5Layout, tel);
  EXPECT_TRUE(std::isnan(s.position[0]));
  EXPECT_FALSE(s.body_valid[0]);
  EXPECT_TRUE(std::isnan(s.pose[0].position[0]));
}

TEST(ModelState, PenPoseAndWrenchFromJointsAndMeasuredTorques) {
  const pen::Model<double> m = pen::defaultModel<double>();
  pen::PenPose<double> pose;
  pose.centre_m = {0.01, -0.005, 0.2};
  pose.theta_x_rad = 0.2;
  pose.theta_z_rad = -0.3;
  pen::JointVec<double> q{};
  ASSERT_EQ(pen::computeInverse(m, pose, q), pen::Status::kOk);
  pen::Data<double> d;
  ASSERT_TRUE(pen::isUsable(pen::computeForward(m, q, d)));
  // End forces the motors would apply: τ = Jᵀ f per pantograph.
  const pen::Vec3<double> fb{0.5, -0.2, 1.0}, ft{-0.1, 0.3, 0.4};
  const pen::Vec3<double> tb = pen::mulTransposed(d.pantograph[0].J, fb), tt = pen::mulTransposed(d.pantograph[1].J, ft);
  host::TelemetryFrame tel;
  for (std::size_t i = 0; i < 6; ++i) tel.value[i] = static_cast<float>(q[i] - m.q_home_rad[i]);
  for (std::size_t i = 0; i < 3; ++i) {
    tel.value[6 + i] = static_cast<float>(tb[i]);
    tel.value[9 + i] = static_cast<float>(tt[i]);
  }
  const host::dds::ModelState s = viewOf(protocol::kPantographLayout, tel);
  ASSERT_TRUE(s.body_valid[0]);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_NEAR(s.pose[0].position[i], pose.centre_m[i], 1e-5);
  // Orientation: R·y_B is the pen axis.
  const auto& o = s.pose[0].orientation;  // x y z w
  const double ax[3] = {2 * (o[0] * o[1] - o[3] * o[2]), 1 - 2 * (o[0] * o[0] + o[2] * o[2]), 2 * (o[1] * o[2] + o[3] * o[0])};
  const pen::Vec3<double> a = pen::penAxis(pose.theta_x_rad, pose.theta_z_rad);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_NEAR(ax[i], a[i], 1e-5);
  const pen::Vec3<double> diff{ft[0] - fb[0], ft[1] - fb[1], ft[2] - fb[2]};
  const pen::Vec3<double> mom = pen::cross(a, diff);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(s.wrench[0].force[i], fb[i] + ft[i], 1e-4);
    EXPECT_NEAR(s.wrench[0].torque[i], pen::penLength(m) / 2 * mom[i], 1e-5);
    EXPECT_EQ(s.effort[i], static_cast<double>(tel.value[6 + i]));
  }
}

TEST(DdsLoopPort, HandsOverAtTheStateRateAndCountsDropsWhenFull) {
  host::dds::DdsOptions o;
  o.enabled = true;
  o.state_rate_hz = 100.0;
  o.diagnostics_rate_hz = 1.0;
  o.queue_slots = 16;
  host::dds::LoopPort port(o, 1000);
  EXPECT_EQ(port.stateDecimation(), 10u);
  host::TelemetryFrame tel;
  for (uint64_t cycle = 1; cycle <= 1000; ++cycle) {
    tel.host_rx_ns = cycle * 1000000;  // fresh every cycle
    port.offer(tel, cycle * 1000000, cycle, 0, 1.0, 2.0);
  }
  // 100 state samples (one of them with the first diagnostics) were due; 16 fit, the rest were dropped.
  EXPECT_EQ(port.offered(), 100u);
  EXPECT_EQ(port.droppedFull(), 84u);
  host::dds::LoopSample s;
  int taken = 0;
  while (port.take(s, 0)) ++taken;
  EXPECT_EQ(taken, 16);
  // Drained: a fresh sample at cycle 2000 is due for both; the same telemetry again (a stale cycle) hands over
  // nothing; a fault change hands over diagnostics at once.
  tel.host_rx_ns = 2000000000ull;
  port.offer(tel, 0, 2000, 0, 0.0, 0.0);
  ASSERT_TRUE(port.take(s, 0));
  EXPECT_EQ(s.what, host::dds::kState | host::dds::kDiagnostics);
  port.offer(tel, 0, 2010, 0, 0.0, 0.0);
  EXPECT_FALSE(port.take(s, 0));
  tel.fault_bits = 4;
  port.offer(tel, 0, 2011, 0, 0.0, 0.0);
  ASSERT_TRUE(port.take(s, 0));
  EXPECT_EQ(s.what, host::dds::kDiagnostics);
  EXPECT_EQ(s.tel.fault_bits, 4);
}
