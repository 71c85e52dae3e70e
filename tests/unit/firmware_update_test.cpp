// Firmware update on the device side (docs/firmware-update.md): fw::FirmwareUpdate and the boot choice on a
// simulated flash with the real parts' rules (RamFlash), power cut after every programmed byte of an update.
#include <gtest/gtest.h>

#include <vector>

#include "../support/test_image.h"
#include "phalanx/fw/core.h"
#include "phalanx/fw/crc32.h"
#include "phalanx/fw/firmware_update.h"
#include "phalanx/host/session.h"
#include "phalanx/protocol/can.h"
#include "phalanx/sim/board.h"
#include "phalanx/sim/sim_flash.h"

using namespace phalanx;
using protocol::MsgId;
using protocol::UpdateResult;

namespace {

constexpr uint32_t kOld = 0xA0A0A0A1u, kNew = 0xB0B0B0B2u;
constexpr uint8_t kGlove = static_cast<uint8_t>(protocol::DeviceType::kGlove5);

/// 2 KiB pages: slot 0 pages 0-29, boot records 30-31, slot 1 pages 32-61 (60 KiB slots).
fw::UpdateLayout layout() {
  fw::UpdateLayout l;
  l.slot_first_page[0] = 0;
  l.slot_first_page[1] = 32;
  l.slot_pages = 30;
  l.record_first_page = 30;
  l.board = static_cast<uint8_t>(image::BoardId::kStm32g474);
  l.device_type = kGlove;
  return l;
}

/// Writes `img` into `slot` and a boot record naming it (as `phalanx flash` then a first boot would leave it).
void provision(hal::FlashPages& flash, uint8_t slot, const std::vector<uint8_t>& img) {
  std::vector<uint8_t> b = img;
  b.resize((b.size() + 7) / 8 * 8, 0xFF);
  const fw::UpdateLayout l = layout();
  for (size_t at = 0; at < b.size(); at += 2048) {
    const size_t page = l.slot_first_page[slot] + at / 2048;
    ASSERT_TRUE(flash.erase(page));
    ASSERT_TRUE(flash.program(page, 0, &b[at], std::min<size_t>(2048, b.size() - at)));
  }
  fw::BootRecord rec;
  rec.slot = slot;
  ASSERT_TRUE(fw::writeBootRecord(flash, l, rec));
}

protocol::UpdateBegin beginFor(const std::vector<uint8_t>& img) { return image::updateBeginFor(test::infoOf(img)); }

protocol::UpdateData chunk(const std::vector<uint8_t>& img, uint32_t at) {
  protocol::UpdateData d;
  d.offset = at;
  d.length = static_cast<uint8_t>(std::min<size_t>(protocol::kUpdateChunkBytes, img.size() - at));
  std::memcpy(d.data, &img[at], d.length);
  return d;
}

/// The whole update, chunk after chunk; the result of the first request that is not kOk (kCommitted at the end).
UpdateResult runUpdate(fw::FirmwareUpdate& u, const std::vector<uint8_t>& img) {
  const protocol::UpdateBegin b = beginFor(img);
  protocol::UpdateStatus s = u.begin(b, 0);
  if (s.result != UpdateResult::kOk) return s.result;
  for (uint32_t at = s.next_offset; at < img.size(); at += protocol::kUpdateChunkBytes) {
    s = u.data(chunk(img, at));
    if (s.result != UpdateResult::kOk) return s.result;
  }
  protocol::UpdateCommit c;
  c.image_crc32 = b.image_crc32;
  c.build_id = b.build_id;
  return u.commit(c).result;
}

class FirmwareUpdateTest : public ::testing::Test {
 protected:
  void SetUp() override { provision(flash, 0, old_img); }
  sim::RamFlash flash{64, 2048};
  std::vector<uint8_t> old_img = test::makeImage(kOld), new_img = test::makeImage(kNew, kGlove,
                                                                                  image::BoardId::kStm32g474, 30001);
};

}  // namespace

TEST(FirmwareUpdateCrc, Crc32IsZlibs) {
  const std::vector<uint8_t> img = test::makeImage(7);
  std::vector<uint8_t> zeroed = img;
  std::memset(&zeroed[image::kImageInfoOffset + 24], 0, 4);
  uint32_t s = fw::kCrc32Init;
  s = fw::crc32Update(s, zeroed.data(), 1000);  // in two parts: the incremental form is the same CRC
  s = fw::crc32Update(s, zeroed.data() + 1000, zeroed.size() - 1000);
  EXPECT_EQ(fw::crc32Final(s), host::flash::imageCrc(img));
  const uint8_t check[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  EXPECT_EQ(fw::crc32(check, sizeof check), 0xCBF43926u);  // the CRC-32 check value
}

TEST_F(FirmwareUpdateTest, TheProvisionedImageBootsAndAnUpdateGoesToTheOtherSlotAndBootsAfterTheCommit) {
  const fw::BootChoice before = fw::chooseBoot(flash, layout());
  ASSERT_TRUE(before.valid);
  EXPECT_EQ(before.slot, 0);
  EXPECT_EQ(before.build_id, kOld);
  fw::FirmwareUpdate u(flash, layout(), before);
  EXPECT_EQ(u.targetSlot(), 1);
  EXPECT_EQ(runUpdate(u, new_img), UpdateResult::kCommitted);
  EXPECT_TRUE(u.rebootRequested());
  const fw::BootChoice after = fw::chooseBoot(flash, layout());
  EXPECT_TRUE(after.valid);
  EXPECT_EQ(after.slot, 1);
  EXPECT_EQ(after.build_id, kNew);
  EXPECT_FALSE(after.fell_back);
  // The next update goes back into slot 0 (the old image is overwritten only now).
  fw::FirmwareUpdate u2(flash, layout(), after);
  EXPECT_EQ(u2.targetSlot(), 0);
  EXPECT_EQ(runUpdate(u2, old_img), UpdateResult::kCommitted);
  EXPECT_EQ(fw::chooseBoot(flash, layout()).build_id, kOld);
}

TEST_F(FirmwareUpdateTest, APowerCutAfterAnyProgrammedByteLeavesABootableImageAndTheRetryCompletes) {
  // Bytes the whole update programs: the image padded to whole units, then one 32-byte boot record.
  const size_t total = (new_img.size() + 7) / 8 * 8 + fw::kBootRecordBytes;
  const std::vector<uint8_t> before = flash.bytes();
  size_t cuts = 0, booted_new = 0;
  for (size_t cut = 0; cut <= total; cut += (cut < total - 64 ? 61 : 1)) {  // every byte of the record's write
    sim::RamFlash f(64, 2048);
    f.loadImage(before.data(), before.size());
    fw::FirmwareUpdate u(f, layout(), fw::chooseBoot(f, layout()));
    f.cutPowerAfter(cut);
    const UpdateResult r = runUpdate(u, new_img);
    f.restorePower();  // the board powered again: reset, the boot stage chooses
    const fw::BootChoice c = fw::chooseBoot(f, layout());
    ASSERT_TRUE(c.valid) << "cut after " << cut << " bytes";
    ASSERT_TRUE(c.build_id == kOld || c.build_id == kNew) << cut;
    EXPECT_EQ(c.build_id == kNew, r == UpdateResult::kCommitted) << "cut after " << cut << " bytes, result "
                                                                   << static_cast<int>(r);
    booted_new += c.build_id == kNew;
    ++cuts;
    if (c.build_id == kOld) {  // the retry after the reset completes
      fw::FirmwareUpdate retry(f, layout(), c);
      ASSERT_EQ(runUpdate(retry, new_img), UpdateResult::kCommitted) << cut;
      ASSERT_EQ(fw::chooseBoot(f, layout()).build_id, kNew) << cut;
    }
  }
  EXPECT_GT(cuts, 400u);
  EXPECT_EQ(booted_new, 1u);  // only a budget that covers the whole update, record included, commits
}

// Trial boot: the committed image boots once on trial; confirmed, it stays; reset unconfirmed, the board goes back
// to the previous image (confirmed) and stays there.
TEST_F(FirmwareUpdateTest, TheNewImageBootsOnTrialAndAResetWithoutItsConfirmGoesBackToThePreviousImage) {
  fw::FirmwareUpdate u(flash, layout(), fw::bootStage(flash, layout()));
  ASSERT_EQ(runUpdate(u, new_img), UpdateResult::kCommitted);
  const fw::BootChoice trial = fw::bootStage(flash, layout());  // the reset after the commit
  EXPECT_EQ(trial.build_id, kNew);
  EXPECT_TRUE(trial.trial);
  fw::FirmwareUpdate on_trial(flash, layout(), trial);
  EXPECT_TRUE(on_trial.onTrial());
  // No second update over the image a failed trial goes back to.
  EXPECT_EQ(on_trial.begin(beginFor(old_img), 0).result, UpdateResult::kUnconfirmed);
  // The new image hung: reset without a confirm.
  const fw::BootChoice back = fw::bootStage(flash, layout());
  EXPECT_EQ(back.build_id, kOld);
  EXPECT_EQ(back.slot, 0);
  EXPECT_TRUE(back.trial_failed);
  EXPECT_FALSE(back.trial);
  const fw::BootChoice again = fw::bootStage(flash, layout());  // and stays there, confirmed
  EXPECT_EQ(again.build_id, kOld);
  EXPECT_FALSE(again.trial || again.trial_failed);
}

TEST_F(FirmwareUpdateTest, AConfirmedImageStaysAcrossResets) {
  fw::FirmwareUpdate u(flash, layout(), fw::bootStage(flash, layout()));
  ASSERT_EQ(runUpdate(u, new_img), UpdateResult::kCommitted);
  fw::FirmwareUpdate running(flash, layout(), fw::bootStage(flash, layout()));
  ASSERT_TRUE(running.onTrial());
  EXPECT_TRUE(running.confirm());
  EXPECT_FALSE(running.onTrial());
  EXPECT_TRUE(running.confirm());  // nothing left to do
  for (int reset = 0; reset < 3; ++reset) {
    const fw::BootChoice c = fw::bootStage(flash, layout());
    EXPECT_EQ(c.build_id, kNew) << reset;
    EXPECT_FALSE(c.trial || c.trial_failed) << reset;
  }
  // The image the update replaced was booted before trial boot existed (provision's record, state 0): confirmed.
  fw::BootRecord rec;
  ASSERT_GE(fw::readNewestBootRecord(flash, layout(), rec), 0);
  EXPECT_EQ(rec.state, fw::BootState::kConfirmed);
}

// A power cut after every programmed byte of each record the trial writes: the boot stage's "trial booted", the
// confirm, the way back. The board always boots kOld or kNew, and the trial's outcome is never reversed: a cut
// before the confirm's record is whole leaves it unconfirmed (the next reset goes back), after it confirmed.
TEST_F(FirmwareUpdateTest, APowerCutWhileATrialRecordIsWrittenNeverLosesABootableImage) {
  {
    fw::FirmwareUpdate u(flash, layout(), fw::bootStage(flash, layout()));
    ASSERT_EQ(runUpdate(u, new_img), UpdateResult::kCommitted);
  }
  const std::vector<uint8_t> committed = flash.bytes();
  for (size_t cut = 0; cut <= fw::kBootRecordBytes; ++cut) {
    // The reset after the commit, cut while the boot stage records the trial.
    sim::RamFlash f(64, 2048);
    f.loadImage(committed.data(), committed.size());
    f.cutPowerAfter(cut);
    fw::bootStage(f, layout());
    f.restorePower();
    const fw::BootChoice c = fw::bootStage(f, layout());
    ASSERT_TRUE(c.valid) << cut;
    if (cut < fw::kBootRecordBytes) {  // the record never became whole: the trial starts now
      EXPECT_TRUE(c.trial && c.build_id == kNew) << cut;
    } else {  // it did, and the image was not confirmed: back
      EXPECT_TRUE(c.trial_failed && c.build_id == kOld) << cut;
    }
  }
  for (size_t cut = 0; cut <= fw::kBootRecordBytes; ++cut) {
    // The new image runs on trial and confirms; the power goes while the confirm's record is written.
    sim::RamFlash f(64, 2048);
    f.loadImage(committed.data(), committed.size());
    fw::FirmwareUpdate running(f, layout(), fw::bootStage(f, layout()));
    ASSERT_TRUE(running.onTrial());
    f.cutPowerAfter(cut);
    const bool confirmed = running.confirm();
    f.restorePower();
    const fw::BootChoice c = fw::bootStage(f, layout());
    ASSERT_TRUE(c.valid) << cut;
    EXPECT_EQ(confirmed, cut >= fw::kBootRecordBytes) << cut;
    EXPECT_EQ(c.build_id, confirmed ? kNew : kOld) << cut;
  }
  {
    sim::RamFlash f(64, 2048);
    f.loadImage(committed.data(), committed.size());
    ASSERT_TRUE(fw::bootStage(f, layout()).trial);  // the trial ran and was not confirmed
    const std::vector<uint8_t> trial_used = f.bytes();
    for (size_t cut = 0; cut <= fw::kBootRecordBytes; ++cut) {
      // The reset that goes back, cut while it writes the old image's confirmed record: the next one goes back too.
      sim::RamFlash g(64, 2048);
      g.loadImage(trial_used.data(), trial_used.size());
      g.cutPowerAfter(cut);
      EXPECT_EQ(fw::bootStage(g, layout()).build_id, kOld) << cut;
      g.restorePower();
      const fw::BootChoice c = fw::bootStage(g, layout());
      EXPECT_EQ(c.build_id, kOld) << cut;
      EXPECT_EQ(c.trial_failed, cut < fw::kBootRecordBytes) << cut;  // taken again only when not yet recorded
    }
  }
}

TEST_F(FirmwareUpdateTest, ABeginOfTheSameImageResumesAndAnotherImageStartsAgain) {
  fw::FirmwareUpdate u(flash, layout(), fw::chooseBoot(flash, layout()));
  const protocol::UpdateBegin b = beginFor(new_img);
  EXPECT_EQ(u.begin(b, 0).next_offset, 0u);
  for (uint32_t at = 0; at < 480; at += 48) ASSERT_EQ(u.data(chunk(new_img, at)).result, UpdateResult::kOk);
  EXPECT_EQ(u.begin(b, 0).next_offset, 480u);  // the link was lost and the host came back: resume
  // A repeated chunk is acknowledged without programming; one beyond the next is out of order.
  EXPECT_EQ(u.data(chunk(new_img, 432)).result, UpdateResult::kOk);
  const protocol::UpdateStatus gap = u.data(chunk(new_img, 528));
  EXPECT_EQ(gap.result, UpdateResult::kOutOfOrder);
  EXPECT_EQ(gap.next_offset, 480u);
  protocol::UpdateBegin other = beginFor(old_img);
  EXPECT_EQ(u.begin(other, 0).next_offset, 0u);
  EXPECT_TRUE(u.inProgress());
}

TEST_F(FirmwareUpdateTest, BeginsThatDoNotSuitTheBoardAreRefusedNamingTheField) {
  fw::FirmwareUpdate u(flash, layout(), fw::chooseBoot(flash, layout()));
  auto field = [&](protocol::UpdateBegin b, uint32_t session = 0) {
    const protocol::UpdateStatus s = u.begin(b, session);
    EXPECT_EQ(s.result, UpdateResult::kBadImage);
    return static_cast<protocol::UpdateImageField>(s.detail);
  };
  protocol::UpdateBegin b = beginFor(new_img);
  b.device_type = static_cast<uint8_t>(protocol::DeviceType::kPantograph);
  EXPECT_EQ(field(b), protocol::UpdateImageField::kDeviceType);
  b = beginFor(new_img);
  b.board = static_cast<uint8_t>(image::BoardId::kMps2An386);
  EXPECT_EQ(field(b), protocol::UpdateImageField::kBoard);
  b = beginFor(new_img);
  b.image_size = 30 * 2048 + 1;
  EXPECT_EQ(field(b), protocol::UpdateImageField::kSize);
  b.image_size = 100;
  EXPECT_EQ(field(b), protocol::UpdateImageField::kSize);
  b = beginFor(new_img);
  b.build_id = 0;
  EXPECT_EQ(field(b), protocol::UpdateImageField::kBuildId);
  b = beginFor(new_img);
  b.reserved = 1;
  EXPECT_EQ(field(b), protocol::UpdateImageField::kReserved);
  b = beginFor(new_img);
  b.session_id = 5;
  EXPECT_EQ(field(b, 6), protocol::UpdateImageField::kSession);
  EXPECT_FALSE(u.inProgress());
  EXPECT_EQ(u.data(chunk(new_img, 0)).result, UpdateResult::kNotStarted);
}

TEST_F(FirmwareUpdateTest, ChunksThatBreakTheRulesAreRefusedAndProgramNothing) {
  fw::FirmwareUpdate u(flash, layout(), fw::chooseBoot(flash, layout()));
  ASSERT_EQ(u.begin(beginFor(new_img), 0).result, UpdateResult::kOk);
  protocol::UpdateData d = chunk(new_img, 0);
  d.length = 20;  // not a whole number of units, and not the last chunk
  EXPECT_EQ(u.data(d).result, UpdateResult::kBadChunk);
  d = chunk(new_img, 0);
  d.length = 0;
  EXPECT_EQ(u.data(d).result, UpdateResult::kBadChunk);
  d = chunk(new_img, 0);
  d.length = 40;
  d.data[45] = 1;  // bytes past the length must be 0
  EXPECT_EQ(u.data(d).result, UpdateResult::kBadChunk);
  d = chunk(new_img, 0);
  d.reserved[1] = 1;
  EXPECT_EQ(u.data(d).result, UpdateResult::kBadChunk);
  d = chunk(new_img, 29999 - 47);  // runs past the image
  d.offset = 29976;
  d.length = 48;
  EXPECT_EQ(u.data(d).result, UpdateResult::kBadChunk);
  EXPECT_EQ(u.begin(beginFor(new_img), 0).next_offset, 0u);
  EXPECT_EQ(flash.erases(32), 0u);  // the target slot was not even erased
}

TEST_F(FirmwareUpdateTest, AnImageThatDoesNotVerifyIsNotCommittedAndTheOldOneKeepsBooting) {
  std::vector<uint8_t> bad = new_img;
  bad[5000] ^= 0x10;  // corrupted on the way: the CRC in Begin is the image's, the bytes are not
  fw::FirmwareUpdate u(flash, layout(), fw::chooseBoot(flash, layout()));
  ASSERT_EQ(u.begin(beginFor(new_img), 0).result, UpdateResult::kOk);
  for (uint32_t at = 0; at < bad.size(); at += 48) ASSERT_EQ(u.data(chunk(bad, at)).result, UpdateResult::kOk);
  protocol::UpdateCommit c;
  c.image_crc32 = beginFor(new_img).image_crc32;
  c.build_id = kNew;
  EXPECT_EQ(u.commit(c).result, UpdateResult::kVerifyFailed);
  EXPECT_FALSE(u.inProgress());
  EXPECT_FALSE(u.rebootRequested());
  EXPECT_EQ(fw::chooseBoot(flash, layout()).build_id, kOld);
  // A commit before every byte arrived, or for another image, is refused too.
  fw::FirmwareUpdate u2(flash, layout(), fw::chooseBoot(flash, layout()));
  ASSERT_EQ(u2.begin(beginFor(new_img), 0).result, UpdateResult::kOk);
  EXPECT_EQ(u2.commit(c).result, UpdateResult::kNotStarted);
}

TEST_F(FirmwareUpdateTest, ARecordNamingASlotThatNoLongerVerifiesFallsBackToTheOtherSlot) {
  fw::FirmwareUpdate u(flash, layout(), fw::chooseBoot(flash, layout()));
  ASSERT_EQ(runUpdate(u, new_img), UpdateResult::kCommitted);
  // Slot 1's flash decays (a page erased by a fault): the record still names it.
  ASSERT_TRUE(flash.erase(32 + 3));
  const fw::BootChoice c = fw::chooseBoot(flash, layout());
  EXPECT_TRUE(c.valid);
  EXPECT_EQ(c.slot, 0);
  EXPECT_EQ(c.build_id, kOld);
  EXPECT_TRUE(c.fell_back);
  // Both slots bad: nothing to boot.
  ASSERT_TRUE(flash.erase(0));
  EXPECT_FALSE(fw::chooseBoot(flash, layout()).valid);
}

TEST(FirmwareUpdateRecord, ARecordWithNonZeroReservedBytesIsRefusedEvenWithAValidCrc) {
  fw::BootRecord rec;
  rec.slot = 1;
  rec.sequence = 7;
  rec.build_id = 0x1234;
  uint8_t buf[fw::kBootRecordBytes];
  fw::encodeBootRecord(rec, buf);
  fw::BootRecord out;
  ASSERT_TRUE(fw::decodeBootRecord(buf, out));
  EXPECT_EQ(out.sequence, 7u);
  for (const size_t at : {size_t{7}, size_t{24}, size_t{27}}) {
    uint8_t bad[fw::kBootRecordBytes];
    std::copy(buf, buf + sizeof buf, bad);
    bad[at] = 1;
    const uint32_t crc = fw::crc32(bad, 28);  // re-signed: only the reserved field is wrong
    for (size_t i = 0; i < 4; ++i) bad[28 + i] = static_cast<uint8_t>(crc >> (8 * i));
    EXPECT_FALSE(fw::decodeBootRecord(bad, out)) << "reserved byte " << at;
  }
}

TEST(FirmwareUpdateCan, UpdateMessagesTravelOnCanFdAndAreRefusedOnClassicCan) {
  protocol::can::Mapper host(protocol::can::Flavor::kFd, protocol::can::Role::kHost, 5);
  protocol::can::Mapper dev(protocol::can::Flavor::kFd, protocol::can::Role::kDevice, 5);
  protocol::UpdateData d;
  d.offset = 96;
  d.length = 48;
  for (uint8_t i = 0; i < 48; ++i) d.data[i] = static_cast<uint8_t>(i * 7);
  uint8_t payload[protocol::kMaxPayload];
  protocol::encodePayload(d, payload);
  protocol::can::CanFrame frames[4];
  protocol::can::EncodeStatus st;
  ASSERT_EQ(host.encode(static_cast<uint8_t>(MsgId::kUpdateData), payload, d.kWireSize, frames, st), 1u);
  EXPECT_EQ(frames[0].len, 64);
  uint8_t id = 0, out[protocol::kMaxPayload];
  size_t len = 0;
  ASSERT_TRUE(dev.decode(frames[0], id, out, len));
  EXPECT_EQ(id, static_cast<uint8_t>(MsgId::kUpdateData));
  protocol::UpdateData back;
  ASSERT_TRUE(protocol::decodePayload(out, len, back));
  EXPECT_EQ(back.offset, 96u);
  EXPECT_EQ(std::memcmp(back.data, d.data, 48), 0);
  protocol::can::Mapper classic(protocol::can::Flavor::kClassic, protocol::can::Role::kHost, 5);
  EXPECT_EQ(classic.encode(static_cast<uint8_t>(MsgId::kUpdateData), payload, d.kWireSize, frames, st), 0u);
  EXPECT_EQ(st, protocol::can::EncodeStatus::kNotRepresentable);
}
