// The host's parameter names and settings backups (host/include/phalanx/host/params.h, docs/params.md).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>
#include <unistd.h>

#include "phalanx/apps/glove5.h"
#include "phalanx/apps/pantograph.h"
#include "phalanx/apps/sea_finger.h"
#include "phalanx/host/params.h"

using namespace phalanx;
using host::params::Access;

namespace {

const protocol::DeviceType kTypes[] = {protocol::DeviceType::kGlove5, protocol::DeviceType::kSeaFinger,
                                       protocol::DeviceType::kPantograph};

fw::SettingsHistory historyOf(protocol::DeviceType t) {
  switch (t) {
    case protocol::DeviceType::kGlove5: return fw::settingsHistoryOf(apps::glove5_param::kSettingsLayouts);
    case protocol::DeviceType::kSeaFinger: return fw::settingsHistoryOf(apps::sea_param::kSettingsLayouts);
    default: return fw::settingsHistoryOf(apps::pantograph_param::kSettingsLayouts);
  }
}

std::set<uint16_t> firmwarePersisted(protocol::DeviceType t, uint16_t version) {
  const fw::SettingsLayout& l = historyOf(t).layouts[version - 1];
  return std::set<uint16_t>(l.ids, l.ids + l.id_count);
}

std::string writeTemp(const std::string& text) {
  static int n = 0;
  const std::string path = "/tmp/phalanx_params_test_" + std::to_string(getpid()) + "_" + std::to_string(n++) + ".yaml";
  std::ofstream(path) << text;
  return path;
}

TEST(ParamNames, EveryParameterTheFirmwarePersistsHasOneSettableNameAndNoOtherIsSaved) {
  for (const protocol::DeviceType t : kTypes) {
    const char* device = protocol::layoutFor(t)->name;
    for (uint16_t version = 1; version <= historyOf(t).count; ++version) {
      std::set<std::string> names;
      std::set<uint16_t> ids, saved;
      for (const auto& p : host::params::known(t, version)) {
        EXPECT_TRUE(names.insert(p.name).second) << "duplicate name " << p.name;
        EXPECT_TRUE(ids.insert(p.id).second) << "duplicate id " << p.id;
        if (!p.persisted) continue;
        saved.insert(p.id);
        EXPECT_EQ(p.access, Access::kSettable) << p.name << ": a saved parameter is settable";
      }
      EXPECT_EQ(saved, firmwarePersisted(t, version)) << device << " layout " << version;
    }
  }
}

TEST(ParamNames, TheSettingsAFirmwareKeepsFollowItsLayoutVersion) {
  std::string err;
  const auto v1 = host::params::known(protocol::DeviceType::kGlove5, 1);
  const auto newest = host::params::known(protocol::DeviceType::kGlove5);
  EXPECT_FALSE(host::params::lookup(v1, "feed_forward_scale", err)->persisted);
  EXPECT_TRUE(host::params::lookup(newest, "feed_forward_scale", err)->persisted);
  EXPECT_TRUE(host::params::lookup(v1, "force_kp", err)->persisted);
  // A backup taken on the newer firmware is refused by the older one, naming what it would not keep.
  const std::string path = writeTemp("device_type: glove5\nparams:\n  force_kp: 1\n  feed_forward_scale: 1\n");
  host::params::Backup b;
  err = host::params::readBackup(path, protocol::DeviceType::kGlove5, b, 1);
  EXPECT_NE(err.find("feed_forward_scale is not a setting the device keeps (settings layout 1)"), std::string::npos) << err;
  EXPECT_EQ(host::params::readBackup(path, protocol::DeviceType::kGlove5, b, 2), "");
  std::remove(path.c_str());
}

TEST(ParamNames, AParameterIsFoundByNameDecimalOrHexIdAndAnUnknownOneIsNamed) {
  const auto table = host::params::known(protocol::DeviceType::kGlove5);
  std::string err;
  for (const std::string key : {"force_ki", "257", "0x0101", "0x101"}) {
    const auto* p = host::params::lookup(table, key, err);
    ASSERT_NE(p, nullptr) << key;
    EXPECT_EQ(p->id, apps::glove5_param::kForceKi) << key;
  }
  EXPECT_EQ(host::params::lookup(table, "force_kq", err), nullptr);
  EXPECT_NE(err.find("unknown parameter 'force_kq'"), std::string::npos) << err;
  EXPECT_EQ(host::params::lookup(table, "0x0999", err), nullptr);
  EXPECT_EQ(host::params::lookup(table, "", err), nullptr);
}

TEST(ParamBackup, ABackupReadsBackExactlyAsWritten) {
  host::params::Backup b;
  b.device_type = "sea_finger";
  b.build_id = "0badf00d";
  // f32 values whose shortest decimal needs all 9 digits.
  b.values["kp_mcp"] = std::nextafter(0.1f, 1.0f);
  b.values["controller"] = 1.0f;
  b.values["kd_pip"] = 1.0e-7f;
  const std::string path = writeTemp(host::params::toYaml(b));
  host::params::Backup back;
  ASSERT_EQ(host::params::readBackup(path, protocol::DeviceType::kSeaFinger, back), "");
  EXPECT_EQ(back.device_type, "sea_finger");
  EXPECT_EQ(back.build_id, "0badf00d");
  EXPECT_EQ(back.values, b.values);
  EXPECT_TRUE(host::params::diff(back.values, b.values).empty());
  std::remove(path.c_str());
}

TEST(ParamBackup, ABadBackupIsRefusedNamingWhatIsWrongAndNothingIsReturned) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"device_type: glove5\nparams:\n  force_kp: 1\n", "device_type is glove5, the device is a pantograph"},
      {"params:\n  torque_limit_j0_Nm: 1\n", "device_type missing"},
      {"device_type: pantograph\n", "params missing"},
      {"device_type: pantograph\nparams:\n  torque_limit_j6_Nm: 1\n", "unknown parameter 'torque_limit_j6_Nm'"},
      {"device_type: pantograph\nparams:\n  geometry_fingerprint: 1\n", "geometry_fingerprint is not a setting"},
      {"device_type: pantograph\nparams:\n  torque_limit_j0_Nm: -.inf\n", "not a finite f32 value"},
      {"device_type: pantograph\nparams:\n  torque_limit_j0_Nm: 1e39\n", "not a finite f32 value"},
      {"device_type: pantograph\nparams:\n  torque_limit_j0_Nm: [1]\n", "not a number"},
      {"device_type: pantograph\nparams:\n  0x0100: 1\n", "unknown parameter '0x0100'"},
      {"- a list\n", "not a parameter backup"},
      {"device_type: pantograph\nparams: {torque_limit_j0_Nm: 1\n", "yaml"},
  };
  for (const auto& [text, expect] : cases) {
    const std::string path = writeTemp(text);
    host::params::Backup b;
    b.device_type = "untouched";
    const std::string err = host::params::readBackup(path, protocol::DeviceType::kPantograph, b);
    EXPECT_NE(err.find(path), std::string::npos) << "the file is named: " << err;
    EXPECT_NE(err.find(expect), std::string::npos) << text << " → " << err;
    EXPECT_EQ(b.device_type, "untouched") << text;
    std::remove(path.c_str());
  }
}

TEST(ParamBackup, DiffListsChangedMissingAndExtraSettings) {
  const std::map<std::string, float> device{{"a", 1.0f}, {"b", 2.0f}, {"c", 3.0f}};
  const std::map<std::string, float> file{{"a", 1.0f}, {"b", 2.5f}, {"d", 4.0f}};
  const auto d = host::params::diff(device, file);
  ASSERT_EQ(d.size(), 3u);
  EXPECT_EQ(d[0].name, "b");
  EXPECT_EQ(d[0].file_value, 2.5f);
  EXPECT_EQ(d[1].name, "c");
  EXPECT_FALSE(d[1].in_file);
  EXPECT_EQ(d[2].name, "d");
  EXPECT_FALSE(d[2].on_device);
}

}  // namespace
