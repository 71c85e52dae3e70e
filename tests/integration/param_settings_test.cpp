// Persistent device settings end to end (issue #24 item 5, docs/params.md): `phalanx param` against firmware-sim
// with a settings flash file. Every phalanx param run starts a new firmware-sim process on the same file, so each
// command below is a power cycle of the board. Saved on the firmware of settings layout 1, kept across power cycles
// and across the update to the firmware of layout 2; backed up to YAML and restored from it; bad backups and
// values refused with exit 2 and nothing written.
#include <gtest/gtest.h>

#include <climits>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "process.h"

using phalanx::test::binPath;
using phalanx::test::Process;

namespace {

struct Outcome {
  int rc = INT_MIN;
  std::string out, err;
};

class ParamSettings : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/phalanx-param-XXXXXX";
    ASSERT_NE(mkdtemp(tmpl), nullptr);
    dir_ = tmpl;
    flash_ = dir_ + "/glove5.settings";
  }
  void TearDown() override { std::system(("rm -rf " + dir_).c_str()); }

  /// phalanx param <args> on sim:glove5 with the settings file; layout: the firmware's settings layout (0 newest).
  Outcome param(std::vector<std::string> args, unsigned layout = 0) {
    std::vector<std::string> argv{binPath("phalanx"), "param"};
    argv.insert(argv.end(), args.begin(), args.end());
    argv.insert(argv.end(), {"--device", "sim:glove5", "--firmware-sim", binPath("firmware-sim")});
    if (with_store_) argv.insert(argv.end(), {"--sim-settings", flash_, "--sim-settings-layout", std::to_string(layout)});
    Process p(argv);
    Outcome o;
    o.rc = p.wait(30000);
    o.out = p.stdoutText();
    o.err = p.stderrText();
    return o;
  }
  /// The value `param get` prints for name ("name = value").
  double get(const std::string& name, unsigned layout = 0) {
    const Outcome o = param({"get", name}, layout);
    EXPECT_EQ(o.rc, 0) << o.err;
    const std::string prefix = name + " = ";
    const auto at = o.out.find(prefix);
    if (at == std::string::npos) {
      ADD_FAILURE() << "no value in: " << o.out;
      return -1.0;
    }
    return std::atof(o.out.c_str() + at + prefix.size());
  }
  std::string flashBytes() const {
    std::ifstream f(flash_, std::ios::binary);
    std::ostringstream s;
    s << f.rdbuf();
    return s.str();
  }
  std::string write(const std::string& name, const std::string& text) const {
    const std::string path = dir_ + "/" + name;
    std::ofstream(path) << text;
    return path;
  }

  std::string dir_, flash_;
  bool with_store_ = true;  ///< false: firmware-sim without --settings (a board that keeps none)
};

TEST_F(ParamSettings, SavedPowerCycledAndUpdatedToAFirmwareWithANewLayoutKept) {
  // The firmware before the update (layout 1: the force PID gains).
  Outcome o = param({"set", "force_kp", "0.75", "--save"}, 1);
  ASSERT_EQ(o.rc, 0) << o.out << o.err;
  EXPECT_NE(o.out.find("saved: settings record 1"), std::string::npos) << o.out;
  EXPECT_EQ(param({"set", "force_ki", "12.5", "--save"}, 1).rc, 0);
  EXPECT_EQ(get("force_kp", 1), 0.75) << "kept across a power cycle";
  o = param({"set", "feed_forward_scale", "1.5", "--save"}, 1);
  EXPECT_EQ(o.rc, 2);
  EXPECT_NE(o.err.find("feed_forward_scale is not a setting this firmware keeps (settings layout 1)"), std::string::npos)
      << o.err;

  // Updated: layout 2 adds the feed-forward scale. The gains are kept, the new setting has its default.
  EXPECT_EQ(get("force_kp"), 0.75);
  EXPECT_EQ(get("force_ki"), 12.5);
  EXPECT_EQ(get("feed_forward_scale"), 1.0);
  EXPECT_EQ(get("settings_load"), 2.0) << "2: migrated from an older layout";
  EXPECT_EQ(get("settings_layout"), 2.0);

  // Saved by the new firmware: a layout-2 record, loaded as such.
  ASSERT_EQ(param({"set", "feed_forward_scale", "1.5", "--save"}).rc, 0);
  EXPECT_EQ(get("feed_forward_scale"), 1.5);
  EXPECT_EQ(get("force_kp"), 0.75);
  EXPECT_EQ(get("settings_load"), 1.0) << "1: loaded, this firmware's layout";
}

TEST_F(ParamSettings, ABackupRestoresTheSettingsAndDiffShowsWhatDiffers) {
  ASSERT_EQ(param({"set", "force_kp", "0.75", "--save"}).rc, 0);
  const std::string backup = dir_ + "/backup.yaml";
  Outcome o = param({"list", "--yaml", backup});
  ASSERT_EQ(o.rc, 0) << o.err;
  EXPECT_NE(o.out.find("force_kp"), std::string::npos);
  EXPECT_EQ(param({"diff", backup}).rc, 0) << "no difference right after the backup";

  ASSERT_EQ(param({"set", "force_kp", "1.25", "--save"}).rc, 0);
  o = param({"diff", backup});
  EXPECT_EQ(o.rc, 1);
  EXPECT_NE(o.out.find("force_kp: device 1.25, file 0.75"), std::string::npos) << o.out;

  o = param({"load", backup});
  ASSERT_EQ(o.rc, 0) << o.err;
  EXPECT_NE(o.out.find("restored 4 settings"), std::string::npos) << o.out;
  EXPECT_EQ(get("force_kp"), 0.75) << "restored and saved: kept across a power cycle";
  EXPECT_EQ(param({"diff", backup}).rc, 0);
}

TEST_F(ParamSettings, BadBackupsAndValuesAreRefusedNamingTheProblemAndNothingIsWritten) {
  ASSERT_EQ(param({"set", "force_kp", "0.75", "--save"}).rc, 0);
  const std::string before = flashBytes();
  ASSERT_FALSE(before.empty());
  struct Case {
    std::string yaml, expect;
  };
  const std::vector<Case> cases = {
      {"device_type: sea_finger\nparams:\n  force_kp: 1\n", "device_type is sea_finger, the device is a glove5"},
      {"device_type: glove5\nparams:\n  force_kq: 1\n", "unknown parameter 'force_kq'"},
      {"device_type: glove5\nparams:\n  force_kp: .nan\n", "force_kp: not a finite f32 value"},
      {"device_type: glove5\nparams:\n  force_kp: 1\n  force_ki: .inf\n", "force_ki: not a finite f32 value"},
      {"device_type: glove5\nparams:\n  tare: 1\n", "tare is not a setting the device keeps"},
      {"device_type: glove5\nparams:\n  force_kp: fast\n", "force_kp: not a number"},
      {"device: glove5\n", "unknown key 'device'"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    const std::string path = write("bad" + std::to_string(i) + ".yaml", cases[i].yaml);
    const Outcome o = param({"load", path});
    EXPECT_EQ(o.rc, 2) << cases[i].yaml;
    EXPECT_NE(o.err.find(cases[i].expect), std::string::npos) << cases[i].yaml << " → " << o.err;
  }
  // A value the firmware refuses (force_kp ≤ 10) after one it takes: rolled back, nothing saved.
  const std::string refused = write("refused.yaml", "device_type: glove5\nparams:\n  force_kp: 3\n  force_ki: 5000\n");
  Outcome o = param({"load", refused});
  EXPECT_EQ(o.rc, 4);
  EXPECT_NE(o.err.find("force_ki = 5000"), std::string::npos) << o.err;
  EXPECT_NE(o.err.find("out of range"), std::string::npos) << o.err;

  EXPECT_EQ(param({"set", "force_kp", "nan"}).rc, 2);
  EXPECT_EQ(param({"set", "force_kp", "inf", "--save"}).rc, 2);
  EXPECT_EQ(param({"set", "force_kq", "1", "--save"}).rc, 2);
  EXPECT_EQ(param({"set", "geometry_fingerprint_index", "1", "--save"}).rc, 2);
  EXPECT_EQ(flashBytes(), before) << "no refused input wrote the flash";
  EXPECT_EQ(get("force_kp"), 0.75);
}

TEST_F(ParamSettings, ADaemonSessionRunsTheSimulatedBoardOnItsKeptSettings) {
  // Saved with phalanx param; then phalanxd and phalanx run start their firmware-sim on the same file (a power
  // cycle): the board reports what it loaded, the session does not write the flash, and the value is still kept.
  ASSERT_EQ(param({"set", "force_kp", "0.75", "--save"}).rc, 0);
  const std::string before = flashBytes();
  for (const std::vector<std::string>& prog : {std::vector<std::string>{binPath("phalanxd")},
                                              std::vector<std::string>{binPath("phalanx"), "run"}}) {
    std::vector<std::string> argv = prog;
    argv.insert(argv.end(), {"--device", "sim:glove5", "--firmware-sim", binPath("firmware-sim"), "--seconds", "0.5",
                             "--no-realtime", "--sim-settings", flash_});
    Process p(argv);
    ASSERT_EQ(p.wait(30000), 0) << p.stderrText();
    EXPECT_NE(p.stderrText().find("settings layout v2: loaded (record v2"), std::string::npos) << p.stderrText();
    EXPECT_EQ(flashBytes(), before) << "a session does not write the settings";
  }
  EXPECT_EQ(get("force_kp"), 0.75);

  // Refused before anything is opened, naming the option.
  for (const std::vector<std::string>& bad :
       {std::vector<std::string>{"--device", "serial:/dev/null", "--sim-settings", flash_},
        std::vector<std::string>{"--device", "sim:glove5", "--sim-settings-layout", "1"}}) {
    std::vector<std::string> argv{binPath("phalanxd"), "--seconds", "0.5", "--no-realtime"};
    argv.insert(argv.end(), bad.begin(), bad.end());
    Process p(argv);
    EXPECT_EQ(p.wait(10000), 2) << bad[1];
    EXPECT_NE(p.stderrText().find("--sim-settings"), std::string::npos) << p.stderrText();
  }
}

TEST_F(ParamSettings, ABoardWithoutASettingsStoreRefusesASaveBeforeSettingAnything) {
  with_store_ = false;
  Outcome o = param({"set", "force_kp", "0.5", "--save"});
  EXPECT_EQ(o.rc, 4);
  EXPECT_NE(o.err.find("this firmware keeps no settings"), std::string::npos) << o.err;
  EXPECT_EQ(o.out.find("force_kp ="), std::string::npos) << "refused before the set: " << o.out;
  o = param({"list"});
  EXPECT_EQ(o.rc, 0);
  EXPECT_NE(o.out.find("settings_sequence            0x0010  ro        - (unknown to this firmware)"), std::string::npos)
      << o.out;
}

}  // namespace
