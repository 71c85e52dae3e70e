// Patient profiles: validation (each problem refused with the key named), resolution to limits, and the limit
// law itself.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "phalanx/host/therapy/glove_device.h"
#include "phalanx/host/therapy/profile.h"

using namespace phalanx::host::therapy;

namespace {

const char* kValid = R"(version: 1
patient: p-17
device: glove5
size: S
handedness: right
kinematics:
  index: {p1_mm: 45, p2_mm: 26, p3_mm: 18}
rom_deg:
  index_mcp: [0, 70]
limits:
  effort_max: {default: 4, thumb: 2.5}
  range_deg:
    index_mcp: [-10, 60]
)";

std::string load(const std::string& text, Profile& p) { return loadProfileText(text, "p.yaml", p); }

/// The valid profile with one line replaced.
std::string with(const std::string& from, const std::string& to) {
  std::string s = kValid;
  const auto at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

}  // namespace

TEST(Profile, AValidProfileResolvesToLimitsOnTopOfTheDevice) {
  Profile p;
  ASSERT_EQ(load(kValid, p), "");
  EXPECT_EQ(p.patient, "p-17");
  EXPECT_EQ(p.handedness, "right");
  EXPECT_EQ(p.limits.channel_count, 5u);
  EXPECT_DOUBLE_EQ(p.limits.effort_max[0], 2.5);
  EXPECT_DOUBLE_EQ(p.limits.effort_max[1], 4.0);
  EXPECT_NEAR(p.limits.flexion_max_rad[3], 60.0 * M_PI / 180.0, 1e-12);  // index_mcp
  EXPECT_NEAR(p.limits.flexion_min_rad[3], -10.0 * M_PI / 180.0, 1e-12);
  // Joints the profile does not restrict keep the device's own range (000 Table 2: PIP flexion 0..120°).
  EXPECT_NEAR(p.limits.flexion_max_rad[4], 120.0 * M_PI / 180.0, 1e-9);
  ASSERT_EQ(p.rom_rad.size(), 1u);
  EXPECT_EQ(p.rom_rad[0].first, "index_mcp");
}

TEST(Profile, EveryInvalidProfileIsRefusedNamingWhatWasWrong) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {with("version: 1", "version: 2"), "version"},
      {with("patient: p-17", "patient: John Smith"), "patient"},
      {with("patient: p-17", "patient: ../../etc"), "patient"},
      {with("device: glove5", "device: toaster"), "device"},
      {with("size: S", "size: XXL"), "size"},
      {with("handedness: right", "handedness: both"), "handedness"},
      {with("p1_mm: 45", "p1_mm: 450"), "kinematics.index.p1_mm"},
      {with("index: {p1_mm", "pinky: {p1_mm"), "kinematics.pinky"},
      {with("index_mcp: [0, 70]", "index_mcp: [70, 0]"), "rom_deg.index_mcp"},
      {with("index_mcp: [0, 70]", "index_knee: [0, 70]"), "rom_deg.index_knee"},
      {with("default: 4", "default: 11"), "limits.effort_max.default"},
      {with("default: 4", "default: 0"), "limits.effort_max.default"},
      {with("default: 4", "default: .nan"), "limits.effort_max.default"},
      {with("thumb: 2.5", "thumb: -1"), "limits.effort_max.thumb"},
      {with("thumb: 2.5", "toe: 1"), "limits.effort_max.toe"},
      {with("default: 4, thumb: 2.5", "thumb: 2.5"), "limits.effort_max.index"},
      {with("index_mcp: [-10, 60]", "index_mcp: [-10, 100]"), "limits.range_deg.index_mcp"},
      {with("index_mcp: [-10, 60]", "index_mcp: [-40, 60]"), "limits.range_deg.index_mcp"},
      {with("index_mcp: [-10, 60]", "index_mcp: [10]"), "limits.range_deg.index_mcp"},
      {with("size: S", "size: S\nfavourite_colour: blue"), "favourite_colour"},
      {with("limits:\n", "nolimits:\n"), "nolimits"},
      {"version: 1\npatient: a\ndevice: glove5\n", "limits"},
      {"version: 1\npatient: a\ndevice: glove5\nlimits: [1, 2\n", "YAML syntax"},
      {"", "empty"},
  };
  for (const auto& [text, key] : cases) {
    Profile p;
    p.patient = "unchanged";
    const std::string err = load(text, p);
    EXPECT_NE(err.find(key), std::string::npos) << "expected an error naming '" << key << "', got: " << err;
    EXPECT_EQ(err.rfind("p.yaml: ", 0), 0u) << err;
    EXPECT_EQ(p.patient, "unchanged") << "a refused profile must not change the output";
  }
}

TEST(Profile, ARepeatedKeyIsRefusedInsteadOfTheLastOneWinning) {
  Profile p;
  const std::string err = load(with("effort_max: {default: 4, thumb: 2.5}", "effort_max: {default: 2, index: 1, index: 9}"), p);
  EXPECT_NE(err.find("p.yaml: limits.effort_max.index: duplicate key"), std::string::npos) << err;
  const std::string top = load(with("size: S\n", "size: S\nsize: L\n"), p);
  EXPECT_NE(top.find("p.yaml: size: duplicate key"), std::string::npos) << top;
}

TEST(Profile, TheShippedDemoProfileIsValid) {
  Profile p;
  EXPECT_EQ(loadProfileFile(std::string(PHALANX_SOURCE_DIR) + "/config/profiles/demo-001.yaml", p), "");
  // Its example preset and plan (the format a user copies).
  ASSERT_EQ(p.presets.size(), 1u);
  ASSERT_EQ(p.plans.size(), 1u);
  EXPECT_EQ(p.plans[0].name, "first-visit");
  EXPECT_EQ(p.plans[0].step_count, 3u);
  EXPECT_DOUBLE_EQ(p.plans[0].total_s, 240.0);
}

TEST(PatientLimits, ClampEffortAndNeverPushAJointFurtherOutOfItsRange) {
  std::string err;
  auto dev = GloveTherapyDevice::make({}, err);
  ASSERT_TRUE(dev) << err;
  PatientLimits l = PatientLimits::deviceDefaults(*dev);
  l.effort_max.fill(2.0);
  l.flexion_max_rad[3] = 0.5;   // index_mcp
  l.flexion_min_rad[3] = 0.0;
  Observation obs{};
  for (size_t j = 0; j < 15; ++j) {
    obs.joint_valid[j] = true;
    obs.flexion_rad[j] = 0.2;
  }
  std::array<double, kMaxChannels> e{};
  e[0] = 5.0;
  e[1] = -1.0;
  e[2] = std::nan("");
  e[3] = -3.0;
  uint32_t bits = l.apply(obs, e);
  EXPECT_DOUBLE_EQ(e[0], 2.0);
  EXPECT_DOUBLE_EQ(e[1], -1.0);
  EXPECT_DOUBLE_EQ(e[2], 0.0) << "non-finite effort is zeroed";
  EXPECT_DOUBLE_EQ(e[3], -2.0);
  EXPECT_EQ(bits, 0b1101u);
  // index_mcp beyond its flexion limit: no more flexing effort on the index, extending effort still allowed.
  obs.flexion_rad[3] = 0.6;
  e = {};
  e[1] = -1.0;
  EXPECT_EQ(l.apply(obs, e), 0b10u);
  EXPECT_DOUBLE_EQ(e[1], 0.0);
  e[1] = 1.5;
  EXPECT_EQ(l.apply(obs, e), 0u);
  EXPECT_DOUBLE_EQ(e[1], 1.5);
  // Below its extension limit: no extending effort.
  obs.flexion_rad[3] = -0.1;
  e[1] = 1.5;
  l.apply(obs, e);
  EXPECT_DOUBLE_EQ(e[1], 0.0);
}

// The therapy session reads the glove's tare back after start-up like the grasp session, and warns the same way.
TEST(GloveTherapyDevice, ReadsTheTareBackAndWarnsOfRefusedFingers) {
  std::string error;
  const auto glove = GloveTherapyDevice::make({}, error);
  ASSERT_TRUE(glove) << error;
  ASSERT_EQ(glove->startupReadback(), std::vector<uint16_t>{phalanx::apps::glove5_param::kTare});
  EXPECT_EQ(glove->startupWarning(phalanx::apps::glove5_param::kTare, 0.0f), "") << "every finger re-zeroed";
  const std::string w = glove->startupWarning(phalanx::apps::glove5_param::kTare, -6.0f);  // index and middle
  EXPECT_NE(w.find("index, middle"), std::string::npos) << w;
  EXPECT_NE(w.find("refused"), std::string::npos) << w;
  EXPECT_EQ(glove->startupWarning(phalanx::apps::glove5_param::kForceKp, -6.0f), "") << "another parameter";
}

namespace {
std::string writeProfile(const std::string& dir, const std::string& file, const std::string& text) {
  const std::string path = dir + "/" + file;
  std::ofstream(path) << text;
  return path;
}
}  // namespace

// Issue: pid-mismatch.yaml holding `patient: someone-else` was accepted; the record was named after the file but
// held the other patient.
TEST(Profile, AFileWhosePatientIsNotItsNameIsRefusedNamingBoth) {
  char tmpl[] = "/tmp/phalanx-profiles-XXXXXX";
  ASSERT_NE(mkdtemp(tmpl), nullptr);
  const std::string dir = tmpl;
  Profile p;
  const std::string mismatch = writeProfile(dir, "pid-mismatch.yaml", with("patient: p-17", "patient: someone-else"));
  const std::string err = loadProfileFile(mismatch, p);
  EXPECT_NE(err.find("'someone-else'"), std::string::npos) << err;
  EXPECT_NE(err.find("'pid-mismatch.yaml'"), std::string::npos) << err;
  EXPECT_EQ(p.patient, "") << "a refused profile changes nothing";
  EXPECT_EQ(loadProfileFile(writeProfile(dir, "p-17.yaml", kValid), p), "");
  EXPECT_EQ(p.patient, "p-17");
  EXPECT_EQ(loadProfileFile(writeProfile(dir, "p-17.yml", kValid), p), "") << "any extension";
  std::system(("rm -rf " + dir).c_str());
}

TEST(Profile, AnythingButASmallRegularFileIsRefusedWithoutReadingIt) {
  Profile p;
  EXPECT_NE(loadProfileFile("/dev/zero", p).find("not a regular file"), std::string::npos);
  EXPECT_NE(loadProfileFile("/tmp", p).find("not a regular file"), std::string::npos);
  EXPECT_NE(loadProfileFile("/nonexistent/p.yaml", p).find("cannot read profile"), std::string::npos);
}

TEST(Profile, TheAnonymousIdIsReserved) {
  Profile p;
  EXPECT_NE(load(with("patient: p-17", "patient: anonymous"), p).find("reserved"), std::string::npos);
}
