// Firmware update over the link end to end (issue #24 item 4, docs/firmware-update.md): `phalanx update` against
// firmware-sim with a code flash file (--flash), over the pseudo-terminal. The link cut (the host killed mid-
// transfer) and the power lost (firmware-sim ending at a seeded random byte of the update) at several points: the
// board always boots a valid image, and the update completes on retry. Refusals write nothing.
#include <gtest/gtest.h>

#include <climits>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "../support/test_image.h"
#include "process.h"

using phalanx::test::binPath;
using phalanx::test::Process;

namespace {

constexpr uint32_t kOld = 0x01d0000au, kNew = 0x0e000b0bu;

std::string hex(uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "%08x", v);
  return b;
}

class FirmwareUpdateLink : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/phalanx-update-XXXXXX";
    ASSERT_NE(mkdtemp(tmpl), nullptr);
    dir_ = tmpl;
    flash_ = dir_ + "/code.flash";
    old_ = write("old.bin", phalanx::test::makeImage(kOld));
    new_ = write("new.bin", phalanx::test::makeImage(kNew, 1, phalanx::image::BoardId::kStm32g474, 61003));
  }
  void TearDown() override {
    sim_.reset();
    std::system(("rm -rf " + dir_).c_str());
  }
  std::string write(const std::string& name, const std::vector<uint8_t>& bytes) const {
    const std::string path = dir_ + "/" + name;
    std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()),
                                                static_cast<std::streamsize>(bytes.size()));
    return path;
  }
  /// A power-up of the board: firmware-sim on the flash file (the old image provisioned when it is new). Returns
  /// the build id its boot stage chose ("" when it did not start).
  std::string powerUp(long long cut_after = -1) {
    sim_.reset();
    std::vector<std::string> argv{binPath("firmware-sim"), "--device", "glove5", "--flash", flash_,
                                  "--flash-provision", old_, "--seconds", "120"};
    if (cut_after >= 0) argv.insert(argv.end(), {"--flash-power-cut-after", std::to_string(cut_after)});
    sim_ = std::make_unique<Process>(argv);
    const std::string line = sim_->readStdoutLine(10000);
    if (line.rfind("PTY ", 0) != 0) return "";
    pty_ = line.substr(4);
    const std::string err = sim_->stderrText();
    const auto at = err.rfind("build ");
    return at == std::string::npos ? "" : err.substr(at + 6, 8);
  }
  struct Outcome {
    int rc = INT_MIN;
    std::string out, err;
  };
  Outcome update(const std::string& image, std::vector<std::string> extra = {}) {
    std::vector<std::string> argv{binPath("phalanx"), "update", image, "--device", "serial:" + pty_, "--timeout", "3",
                                  "--reconnects", "1"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    Process p(argv);
    Outcome o;
    o.rc = p.wait(60000);
    o.out = p.stdoutText();
    o.err = p.stderrText();
    return o;
  }
  std::string flashBytes() const {
    std::ifstream f(flash_, std::ios::binary);
    std::ostringstream s;
    s << f.rdbuf();
    return s.str();
  }

  std::string dir_, flash_, old_, new_, pty_;
  std::unique_ptr<Process> sim_;
};

}  // namespace

TEST_F(FirmwareUpdateLink, AnUpdateBootsTheNewImageAndARepeatIsNothingToDo) {
  ASSERT_EQ(powerUp(), hex(kOld));
  const Outcome o = update(new_);
  ASSERT_EQ(o.rc, 0) << o.err << "\nfirmware-sim:\n" << sim_->stderrText();
  EXPECT_NE(o.out.find("to build " + hex(kNew) + ", confirmed"), std::string::npos) << o.out;
  EXPECT_NE(sim_->stderrText().find("reset after the update, boot: slot 1 build " + hex(kNew)), std::string::npos);
  const Outcome again = update(new_);
  EXPECT_EQ(again.rc, 0);
  EXPECT_NE(again.out.find("already runs build " + hex(kNew)), std::string::npos) << again.out;
  // A power cycle keeps it.
  EXPECT_EQ(powerUp(), hex(kNew));
}

// Trial boot (docs/firmware-update.md): an image left unconfirmed is replaced by the previous one at the next
// power-up; one confirmed afterwards with `phalanx param set update_trial 1` stays.
TEST_F(FirmwareUpdateLink, AnImageLeftOnTrialGoesBackAtThePowerUpAndAConfirmedOneStays) {
  ASSERT_EQ(powerUp(), hex(kOld));
  const Outcome o = update(new_, {"--no-confirm"});
  ASSERT_EQ(o.rc, 0) << o.err;
  EXPECT_NE(o.out.find("to build " + hex(kNew) + ", on trial"), std::string::npos) << o.out;
  EXPECT_NE(sim_->stderrText().find("on trial: not yet confirmed"), std::string::npos) << sim_->stderrText();
  // No update over the image the trial would go back to.
  const Outcome refused = update(old_, {"--force"});
  EXPECT_EQ(refused.rc, 4);
  EXPECT_NE(refused.err.find("runs an image on trial, not yet confirmed"), std::string::npos) << refused.err;
  EXPECT_EQ(powerUp(), hex(kOld)) << "the unconfirmed image is left at the next power-up";
  EXPECT_NE(sim_->stderrText().find("back from a trial that was not confirmed"), std::string::npos);

  ASSERT_EQ(update(new_, {"--no-confirm"}).rc, 0);
  Process get({binPath("phalanx"), "param", "get", "update_trial", "--device", "serial:" + pty_});
  EXPECT_EQ(get.wait(20000), 0) << get.stderrText();
  EXPECT_NE(get.stdoutText().find("update_trial = 1\n"), std::string::npos) << get.stdoutText();
  Process set({binPath("phalanx"), "param", "set", "update_trial", "1", "--device", "serial:" + pty_});
  EXPECT_EQ(set.wait(20000), 0) << set.stderrText();
  EXPECT_EQ(powerUp(), hex(kNew)) << "confirmed, the new image stays";
}

TEST_F(FirmwareUpdateLink, PowerLostAtRandomPointsAlwaysLeavesABootableImageAndTheRetryCompletes) {
  ASSERT_EQ(powerUp(), hex(kOld));
  const long long total = (61003 + 7) / 8 * 8 + 32;  // the bytes an update programs: image, then the boot record
  std::mt19937 rng(24);
  std::vector<long long> cuts{0, total - 1, total - 32};  // before anything, in the record, just before it
  for (int i = 0; i < 4; ++i) cuts.push_back(std::uniform_int_distribution<long long>(1, total - 2)(rng));
  for (const long long cut : cuts) {
    SCOPED_TRACE("power lost after " + std::to_string(cut) + " bytes");
    ASSERT_EQ(powerUp(cut), hex(kOld));
    const Outcome o = update(new_);
    EXPECT_NE(o.rc, 0) << "an update whose power was cut cannot have succeeded";
    EXPECT_EQ(sim_->wait(10000), 75) << sim_->stderrText();  // the board lost power
    EXPECT_EQ(powerUp(), hex(kOld)) << "after the power loss the board boots its old, valid image";
  }
  const Outcome o = update(new_);
  ASSERT_EQ(o.rc, 0) << o.err;
  EXPECT_EQ(powerUp(), hex(kNew));
}

TEST_F(FirmwareUpdateLink, AHostKilledMidTransferIsResumedByTheNextUpdate) {
  ASSERT_EQ(powerUp(), hex(kOld));
  {
    // The link cut: `phalanx update` killed once the device has a third of the image (its progress line says so).
    Process p({binPath("phalanx"), "update", new_, "--device", "serial:" + pty_, "--window", "1"});
    for (int i = 0; i < 600 && p.stderrText().find("30%") == std::string::npos; ++i) usleep(10000);
    ASSERT_NE(p.stderrText().find("30%"), std::string::npos) << p.stderrText();
    p.signal(SIGKILL);
    p.wait(5000);
  }
  const Outcome o = update(new_);
  ASSERT_EQ(o.rc, 0) << o.err;
  EXPECT_NE(o.err.find("resuming at byte "), std::string::npos) << o.err;
  EXPECT_NE(o.out.find("to build " + hex(kNew)), std::string::npos);
}

TEST_F(FirmwareUpdateLink, ImagesForAnotherDeviceOrCorruptedAreRefusedBeforeAnythingIsWritten) {
  ASSERT_EQ(powerUp(), hex(kOld));
  const std::string before = flashBytes();
  const std::string pen = write("pen.bin", phalanx::test::makeImage(0x7e11, 3));
  Outcome o = update(pen);
  EXPECT_EQ(o.rc, 3) << o.err;
  EXPECT_NE(o.err.find("the image is for a pantograph"), std::string::npos) << o.err;
  std::vector<uint8_t> bad = phalanx::test::makeImage(kNew);
  bad[9000] ^= 1;
  o = update(write("bad.bin", bad));
  EXPECT_EQ(o.rc, 3);
  EXPECT_NE(o.err.find("CRC"), std::string::npos) << o.err;
  const std::string other_board = write("mps2.bin", phalanx::test::makeImage(kNew, 1, phalanx::image::BoardId::kMps2An386));
  o = update(other_board);
  EXPECT_EQ(o.rc, 3) << o.err;
  EXPECT_EQ(flashBytes(), before);
  EXPECT_EQ(powerUp(), hex(kOld));
}
