// The persistent settings store (firmware/core settings_store.h, docs/params.md): records survive a power cycle,
// a corrupted or torn record is never applied and leaves the older one in force, saves alternate the two slots,
// and a record of an older layout is migrated by a newer firmware.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <map>

#include <zlib.h>

#include "phalanx/apps/glove5.h"
#include "phalanx/apps/pantograph.h"
#include "phalanx/apps/sea_finger.h"
#include "phalanx/fw/core.h"
#include "phalanx/fw/settings_store.h"
#include "phalanx/host/session.h"
#include "phalanx/sim/board.h"
#include "phalanx/sim/sim_flash.h"

using namespace phalanx;
using fw::SettingsLoad;
using fw::SettingsSave;

namespace {

constexpr uint16_t kA = 0x0100, kB = 0x0101, kOld = 0x0102, kNew = 0x0103, kBRenamed = 0x0111;
// Version 1 persists A, B and Old; version 2 renames B to 0x0111, drops Old and adds New.
constexpr uint16_t kV1Ids[] = {kA, kB, kOld};
constexpr uint16_t kV2Ids[] = {kA, kBRenamed, kNew};
constexpr fw::SettingsRename kV2Renames[] = {{kB, kBRenamed}};
constexpr fw::SettingsLayout kHistory[] = {{1, kV1Ids, 3, nullptr, 0}, {2, kV2Ids, 3, kV2Renames, 1}};

/// An app with a few bounded parameters (0 ≤ value ≤ limit), defaults 0; knows the ids of both layout versions.
class ParamApp : public fw::DeviceApp {
 public:
  explicit ParamApp(protocol::DeviceType type = protocol::DeviceType::kSeaFinger) {
    layout_ = protocol::kSeaFingerLayout;
    layout_.type = type;
    for (uint16_t id : {kA, kB, kOld, kNew, kBRenamed}) values[id] = 0.0f;
  }
  const protocol::DeviceLayout& layout() const override { return layout_; }
  void init(hal::Board&) override {}
  uint16_t sense(float) override { return 0; }
  uint16_t control(const protocol::Command&, float) override { return 0; }
  void safe() override {}
  void fillSamples(int16_t*) const override {}
  protocol::ParamStatus getParam(uint16_t id, float& v) const override {
    const auto it = values.find(id);
    if (it == values.end()) return protocol::ParamStatus::kUnknownParam;
    v = it->second;
    return protocol::ParamStatus::kOk;
  }
  protocol::ParamStatus setParam(uint16_t id, float v) override {
    if (values.count(id) == 0) return protocol::ParamStatus::kUnknownParam;
    if (!(v >= 0.0f && v <= limit)) return protocol::ParamStatus::kOutOfRange;
    values[id] = v;
    return protocol::ParamStatus::kOk;
  }
  fw::SettingsHistory settingsHistory() const override { return {kHistory, 2}; }
  std::map<uint16_t, float> values;
  float limit = 100.0f;

 private:
  protocol::DeviceLayout layout_;
};

/// Two slots of 512 bytes, as firmware-sim's settings file.
sim::RamFlash twoSlots() { return sim::RamFlash(2, 512); }

/// A power cycle: a fresh app (defaults) and a fresh store over the same flash, loaded.
fw::SettingsReport powerCycle(sim::RamFlash& flash, ParamApp& app, uint16_t built = 0) {
  app = ParamApp();
  fw::SettingsStore store(flash, 0, built);
  return store.load(app);
}

/// Index (0 or 1) of the slot holding the record with this sequence, -1 if none.
int slotOf(sim::RamFlash& flash, uint32_t seq) {
  for (int s = 0; s < 2; ++s) {
    fw::SettingsRecord r;
    if (fw::decodeSettingsRecord(&flash.bytes()[static_cast<size_t>(s) * 512], 512, r) && r.sequence == seq) return s;
  }
  return -1;
}

TEST(SimFlash, ProgramsAlignedDoubleWordsOnceBetweenErasesAndOnlyClearsBits) {
  sim::RamFlash flash(2, 64);
  const uint8_t a[8] = {0x0F, 0xF0, 0, 1, 2, 3, 4, 5};
  EXPECT_FALSE(flash.program(0, 4, a, 8)) << "misaligned offset";
  EXPECT_FALSE(flash.program(0, 0, a, 4)) << "part of a double word";
  EXPECT_FALSE(flash.program(0, 64, a, 8)) << "beyond the page";
  ASSERT_TRUE(flash.program(0, 8, a, 8));
  EXPECT_FALSE(flash.program(0, 8, a, 8)) << "a double word programmed twice without an erase";
  uint8_t back[8];
  ASSERT_TRUE(flash.read(0, 8, back, 8));
  EXPECT_EQ(std::memcmp(back, a, 8), 0);
  ASSERT_TRUE(flash.erase(0));
  ASSERT_TRUE(flash.read(0, 8, back, 8));
  EXPECT_EQ(back[2], 0xFF);
  ASSERT_TRUE(flash.program(0, 8, a, 8)) << "programmable again after the erase";
  EXPECT_EQ(flash.erases(0), 1u);
  EXPECT_EQ(flash.erases(1), 0u);
}

TEST(SettingsRecord, TheCrcIsZlibsCrc32) {
  const char* check = "123456789";
  EXPECT_EQ(fw::settingsCrc32(reinterpret_cast<const uint8_t*>(check), 9), 0xCBF43926u);
  uint8_t b[fw::kSettingsRecordMaxBytes];
  fw::SettingsRecord r;
  r.count = 2;
  r.id[0] = 7;
  r.value[1] = 1.5f;
  const size_t n = fw::encodeSettingsRecord(r, b);
  uint32_t stored = 0;
  std::memcpy(&stored, b + n - 4, 4);
  EXPECT_EQ(stored, static_cast<uint32_t>(crc32(0L, b, static_cast<uInt>(n - 4))));
}

// Found by the settings fuzz target (4.5 M executions, 2026-12-07): a record whose reserved fields were not zero,
// with its CRC recomputed over them, was decoded and its reserved bytes silently dropped. It is refused now: the
// firmware writes them as zero, so such a record is not one it wrote.
TEST(SettingsRecord, ARecordWithNonZeroReservedFieldsIsRefusedEvenWithAValidCrc) {
  fw::SettingsRecord r;
  r.count = 2;
  r.id[0] = 0x100;
  r.id[1] = 0x101;
  r.value[0] = 1.5f;
  uint8_t b[fw::kSettingsRecordMaxBytes];
  const size_t n = fw::encodeSettingsRecord(r, b);
  fw::SettingsRecord back;
  ASSERT_TRUE(fw::decodeSettingsRecord(b, n, back));
  for (const size_t at : {size_t{14}, fw::kSettingsHeaderBytes + 2, fw::kSettingsHeaderBytes + 8 + 3}) {
    uint8_t c[fw::kSettingsRecordMaxBytes];
    std::memcpy(c, b, n);
    c[at] = 0x2E;
    const uint32_t crc = fw::settingsCrc32(c, n - 4);
    std::memcpy(c + n - 4, &crc, 4);  // little-endian, as the record stores it
    EXPECT_FALSE(fw::decodeSettingsRecord(c, n, back)) << "reserved byte " << at;
  }
}

TEST(SettingsStore, SavedValuesAreAppliedAfterAPowerCycle) {
  sim::RamFlash flash = twoSlots();
  ParamApp app;
  app.values[kA] = 12.5f;
  app.values[kBRenamed] = 3.25f;
  app.values[kNew] = 99.0f;
  fw::SettingsStore store(flash);
  ASSERT_EQ(store.save(app), SettingsSave::kSaved);
  EXPECT_EQ(store.newestSequence(), 1u);

  const fw::SettingsReport r = powerCycle(flash, app);
  EXPECT_EQ(r.result, SettingsLoad::kLoaded);
  EXPECT_EQ(r.applied, 3);
  EXPECT_EQ(r.refused + r.dropped, 0);
  EXPECT_EQ(app.values[kA], 12.5f);
  EXPECT_EQ(app.values[kBRenamed], 3.25f);
  EXPECT_EQ(app.values[kNew], 99.0f);
}

TEST(SettingsStore, AnErasedFlashLoadsNothingAndKeepsTheDefaults) {
  sim::RamFlash flash = twoSlots();
  ParamApp app;
  const fw::SettingsReport r = powerCycle(flash, app);
  EXPECT_EQ(r.result, SettingsLoad::kNothingStored);
  EXPECT_EQ(app.values[kA], 0.0f);
}

TEST(SettingsStore, SavesAlternateTheSlotsAndTheNewestWins) {
  sim::RamFlash flash = twoSlots();
  ParamApp app;
  fw::SettingsStore store(flash);
  for (int i = 1; i <= 6; ++i) {
    app.values[kA] = static_cast<float>(i);
    ASSERT_EQ(store.save(app), SettingsSave::kSaved);
    EXPECT_EQ(slotOf(flash, static_cast<uint32_t>(i)), (i - 1) % 2) << "save " << i;
    EXPECT_EQ(slotOf(flash, static_cast<uint32_t>(i - 1)), i == 1 ? -1 : i % 2) << "the previous record stays";
  }
  EXPECT_EQ(flash.erases(0), 3u);
  EXPECT_EQ(flash.erases(1), 3u);
  powerCycle(flash, app);
  EXPECT_EQ(app.values[kA], 6.0f);
}

TEST(SettingsStore, ASaveOfUnchangedValuesWritesNothing) {
  sim::RamFlash flash = twoSlots();
  ParamApp app;
  app.values[kA] = 4.0f;
  fw::SettingsStore store(flash);
  ASSERT_EQ(store.save(app), SettingsSave::kSaved);
  EXPECT_EQ(store.save(app), SettingsSave::kUnchanged);
  EXPECT_EQ(flash.erases(0) + flash.erases(1), 1u);
  EXPECT_EQ(store.newestSequence(), 1u);
}

TEST(SettingsStore, ACorruptedRecordIsNeverAppliedAndTheOlderOneIs) {
  sim::RamFlash flash = twoSlots();
  ParamApp app;
  fw::SettingsStore store(flash);
  app.values[kA] = 1.0f;
  ASSERT_EQ(store.save(app), SettingsSave::kSaved);
  app.values[kA] = 2.0f;
  ASSERT_EQ(store.save(app), SettingsSave::kSaved);
  const int newest = slotOf(flash, 2);
  ASSERT_GE(newest, 0);
  // Every single-bit flip anywhere in the newest record: the older record is what loads.
  const size_t record_len = fw::kSettingsHeaderBytes + 8 * 3 + 4;
  for (size_t byte = 0; byte < record_len; ++byte) {
    for (int bit = 0; bit < 8; ++bit) {
      sim::RamFlash copy = flash;
      copy.bytes()[static_cast<size_t>(newest) * 512 + byte] ^= static_cast<uint8_t>(1u << bit);
      const fw::SettingsReport r = powerCycle(copy, app);
      ASSERT_EQ(r.sequence, 1u) << "byte " << byte << " bit " << bit;
      ASSERT_EQ(app.values[kA], 1.0f);
    }
  }
  // Both corrupted: nothing applied.
  flash.bytes()[20] ^= 0x01;
  flash.bytes()[512 + 20] ^= 0x01;
  EXPECT_EQ(powerCycle(flash, app).result, SettingsLoad::kNothingStored);
  EXPECT_EQ(app.values[kA], 0.0f);
}

TEST(SettingsStore, APowerLossAtAnyPointOfASaveKeepsTheOlderRecord) {
  // Every cut before the record's last byte (a cut in the 0xFF padding after it leaves the new record whole).
  const size_t record_len = fw::kSettingsHeaderBytes + 8 * 3 + 4;
  for (size_t cut = 0; cut < record_len; ++cut) {
    sim::RamFlash flash = twoSlots();
    ParamApp app;
    fw::SettingsStore store(flash);
    app.values[kA] = 1.0f;
    ASSERT_EQ(store.save(app), SettingsSave::kSaved);
    app.values[kA] = 2.0f;
    flash.cutPowerAfter(cut);
    ASSERT_EQ(store.save(app), SettingsSave::kWriteFailed) << "cut after " << cut << " bytes";
    flash.restorePower();
    const fw::SettingsReport r = powerCycle(flash, app);
    ASSERT_EQ(r.result, SettingsLoad::kLoaded) << "cut after " << cut << " bytes";
    ASSERT_EQ(app.values[kA], 1.0f) << "cut after " << cut << " bytes";
  }
}

TEST(SettingsStore, ARecordOfAnOlderLayoutIsMigratedByTheNewerFirmware) {
  sim::RamFlash flash = twoSlots();
  ParamApp app;
  app.values[kA] = 5.0f;
  app.values[kB] = 6.0f;
  app.values[kOld] = 7.0f;
  fw::SettingsStore v1(flash, 0, 1);  // the firmware before the update
  ASSERT_EQ(v1.layoutVersion(app), 1);
  ASSERT_EQ(v1.save(app), SettingsSave::kSaved);

  const fw::SettingsReport r = powerCycle(flash, app);  // updated: the newest layout (2)
  EXPECT_EQ(r.result, SettingsLoad::kMigrated);
  EXPECT_EQ(r.record_version, 1);
  EXPECT_EQ(r.applied, 2);
  EXPECT_EQ(r.dropped, 1) << "Old is no longer persisted";
  EXPECT_EQ(app.values[kA], 5.0f);
  EXPECT_EQ(app.values[kBRenamed], 6.0f) << "B renamed: its value follows";
  EXPECT_EQ(app.values[kNew], 0.0f) << "new in version 2: the default";
  EXPECT_EQ(app.values[kOld], 0.0f);

  // The next save writes the new layout, which loads as such.
  fw::SettingsStore v2(flash);
  app.values[kNew] = 8.0f;
  ASSERT_EQ(v2.save(app), SettingsSave::kSaved);
  const fw::SettingsReport again = powerCycle(flash, app);
  EXPECT_EQ(again.result, SettingsLoad::kLoaded);
  EXPECT_EQ(again.record_version, 2);
  EXPECT_EQ(app.values[kBRenamed], 6.0f);
  EXPECT_EQ(app.values[kNew], 8.0f);
}

TEST(SettingsStore, ARecordOfANewerLayoutIsNotAppliedByAnOlderFirmware) {
  sim::RamFlash flash = twoSlots();
  ParamApp app;
  app.values[kA] = 5.0f;
  fw::SettingsStore v2(flash);
  ASSERT_EQ(v2.save(app), SettingsSave::kSaved);
  const fw::SettingsReport r = powerCycle(flash, app, 1);
  EXPECT_EQ(r.result, SettingsLoad::kNewerLayout);
  EXPECT_EQ(r.applied, 0);
  EXPECT_EQ(app.values[kA], 0.0f);
}

TEST(SettingsStore, ARecordOfAnotherDeviceTypeIsNotApplied) {
  sim::RamFlash flash = twoSlots();
  ParamApp glove(protocol::DeviceType::kGlove5);
  glove.values[kA] = 5.0f;
  fw::SettingsStore store(flash);
  ASSERT_EQ(store.save(glove), SettingsSave::kSaved);
  ParamApp app;
  const fw::SettingsReport r = powerCycle(flash, app);
  EXPECT_EQ(r.result, SettingsLoad::kOtherDevice);
  EXPECT_EQ(app.values[kA], 0.0f);
}

TEST(SettingsStore, AValueTheAppNowRefusesIsSkippedAndCountedTheOthersApply) {
  sim::RamFlash flash = twoSlots();
  ParamApp app;
  app.values[kA] = 50.0f;
  app.values[kNew] = 5.0f;
  fw::SettingsStore store(flash);
  ASSERT_EQ(store.save(app), SettingsSave::kSaved);
  app = ParamApp();
  app.limit = 10.0f;  // a firmware whose range for these values is narrower
  fw::SettingsStore after(flash);
  const fw::SettingsReport r = after.load(app);
  EXPECT_EQ(r.refused, 1);
  EXPECT_EQ(r.applied, 2);
  EXPECT_EQ(app.values[kA], 0.0f) << "refused: the default stays";
  EXPECT_EQ(app.values[kNew], 5.0f);
}

TEST(SettingsStore, EveryAppsPersistedParametersAreSettableWithTheirOwnValues) {
  apps::Glove5App glove(apps::glove5DefaultCalibration(), apps::glove5DefaultConfig());
  apps::SeaFingerApp sea(apps::seaFingerDefaultCalibration(), apps::seaFingerDefaultConfig());
  apps::PantographApp pen;
  for (fw::DeviceApp* app : std::initializer_list<fw::DeviceApp*>{&glove, &sea, &pen}) {
    const fw::SettingsHistory h = app->settingsHistory();
    ASSERT_GT(h.count, 0) << app->layout().name;
    for (uint8_t v = 0; v < h.count; ++v) {
      const fw::SettingsLayout& l = h.layouts[v];
      EXPECT_EQ(l.version, v + 1) << app->layout().name;
      ASSERT_LE(l.id_count, fw::kMaxSettings);
      for (uint8_t k = 0; k < l.id_count; ++k) {
        float value = NAN;
        ASSERT_EQ(app->getParam(l.ids[k], value), protocol::ParamStatus::kOk) << app->layout().name << " " << l.ids[k];
        EXPECT_EQ(app->setParam(l.ids[k], value), protocol::ParamStatus::kOk) << app->layout().name << " " << l.ids[k];
      }
    }
    // And a whole save and load through the store round-trips.
    sim::RamFlash flash = twoSlots();
    fw::SettingsStore store(flash);
    ASSERT_EQ(store.save(*app), SettingsSave::kSaved) << app->layout().name;
    const fw::SettingsReport r = store.load(*app);
    EXPECT_EQ(r.result, SettingsLoad::kLoaded);
    EXPECT_EQ(r.applied, h.layouts[h.count - 1].id_count) << app->layout().name;
  }
}

TEST(SettingsStore, TheSeaFingerKeepsItsControllerAndThatControllersGains) {
  // The gains are those of the active controller: the controller must be applied before them at load.
  apps::SeaFingerApp before(apps::seaFingerDefaultCalibration(), apps::seaFingerDefaultConfig());
  ASSERT_EQ(before.setParam(apps::sea_param::kController, 1.0f), protocol::ParamStatus::kOk);  // paper baseline
  ASSERT_EQ(before.setParam(apps::sea_param::kKp + 1, 0.625f), protocol::ParamStatus::kOk);
  sim::RamFlash flash = twoSlots();
  fw::SettingsStore store(flash);
  ASSERT_EQ(store.save(before), SettingsSave::kSaved);

  apps::SeaFingerApp after(apps::seaFingerDefaultCalibration(), apps::seaFingerDefaultConfig());
  float ours_kp = 0.0f;
  ASSERT_EQ(after.getParam(apps::sea_param::kKp + 1, ours_kp), protocol::ParamStatus::kOk);
  ASSERT_NE(ours_kp, 0.625f);
  fw::SettingsStore reload(flash);
  EXPECT_EQ(reload.load(after).applied, 9);
  float v = 0.0f;
  after.getParam(apps::sea_param::kController, v);
  EXPECT_EQ(v, 1.0f);
  after.getParam(apps::sea_param::kKp + 1, v);
  EXPECT_EQ(v, 0.625f) << "the paper controller's K_p";
  ASSERT_EQ(after.setParam(apps::sea_param::kController, 0.0f), protocol::ParamStatus::kOk);
  after.getParam(apps::sea_param::kKp + 1, v);
  EXPECT_EQ(v, ours_kp) << "the other controller's gains untouched";
}

// --- Through the firmware core (core_param::kSettingsSave) ------------------------------------------------------

struct CoreRig {
  explicit CoreRig(hal::FlashPages& flash, ParamApp& app_)
      : app(app_), store(flash), board(2, 4, 0, pipe.end(0)), core(board.board(), app, config()), host(pipe.end(1)) {}
  fw::CoreConfig config() {
    fw::CoreConfig c;
    c.settings = &store;
    return c;
  }
  void tick() {
    board.clock().advanceUs(1000);
    core.tick();
    host.poll(board.clock().nowUs() * 1000);
  }
  protocol::ParamValue set(uint16_t id, float v) {
    host.sendParamSet(id, v);
    tick();
    return host.lastParam();
  }
  ParamApp& app;
  fw::SettingsStore store;
  sim::BytePipe pipe;
  sim::SimBoard board;
  fw::FirmwareCore core;
  host::HostSession host;
};

TEST(SettingsThroughTheCore, TheSaveParameterPersistsAndIsRefusedWhileOutputsAreActive) {
  sim::RamFlash flash = twoSlots();
  ParamApp app;
  {
    CoreRig rig(flash, app);
    rig.host.sendHello(1, protocol::DeviceType::kAny);
    rig.tick();
    ASSERT_EQ(rig.host.handshake(), host::HandshakeResult::kOk);
    EXPECT_EQ(rig.set(kA, 9.0f).status, protocol::ParamStatus::kOk);
    protocol::Command c;
    c.mode = protocol::Mode::kSetpoint;
    c.channel_count = protocol::kSeaFingerLayout.setpoint_count;
    c.timeout_ms = 50;
    rig.host.sendCommand(c, rig.board.clock().nowUs() * 1000);
    rig.tick();
    ASSERT_TRUE(rig.core.outputsActive());
    EXPECT_EQ(rig.set(protocol::core_param::kSettingsSave, 1.0f).status, protocol::ParamStatus::kBusy);
    EXPECT_EQ(flash.erases(0) + flash.erases(1), 0u) << "nothing written while the outputs are driven";
    c.mode = protocol::Mode::kSafe;
    rig.host.sendCommand(c, rig.board.clock().nowUs() * 1000);
    rig.tick();
    ASSERT_FALSE(rig.core.outputsActive());
    EXPECT_EQ(rig.set(protocol::core_param::kSettingsSave, 2.0f).status, protocol::ParamStatus::kOutOfRange);
    const protocol::ParamValue saved = rig.set(protocol::core_param::kSettingsSave, 1.0f);
    EXPECT_EQ(saved.status, protocol::ParamStatus::kOk);
    EXPECT_EQ(saved.value, 1.0f) << "the answer carries the new record's sequence";
  }
  app = ParamApp();
  CoreRig after(flash, app);  // power cycle: the core loads the store at construction
  EXPECT_EQ(app.values[kA], 9.0f);
  after.host.sendParamGet(protocol::core_param::kSettingsLoad);
  after.tick();
  EXPECT_EQ(after.host.lastParam().value, static_cast<float>(SettingsLoad::kLoaded));
}

TEST(SettingsThroughTheCore, FirmwareWithoutAStoreDoesNotKnowTheSettingsParameters) {
  sim::BytePipe pipe;
  ParamApp app;
  sim::SimBoard board(2, 4, 0, pipe.end(0));
  fw::FirmwareCore core(board.board(), app, fw::CoreConfig{});
  host::HostSession host(pipe.end(1));
  host.sendParamSet(protocol::core_param::kSettingsSave, 1.0f);
  board.clock().advanceUs(1000);
  core.tick();
  host.poll(board.clock().nowUs() * 1000);
  ASSERT_TRUE(host.lastParamValid());
  EXPECT_EQ(host.lastParam().status, protocol::ParamStatus::kUnknownParam);
}

/// RamFlash seen through the begin/poll path as an MCU's flash behaves: a begun erase or program takes effect
/// after `busy_polls` polls that report busy (erase()/program() stay immediate).
class SlowFlash : public hal::FlashPages {
 public:
  SlowFlash(sim::RamFlash& ram, int busy_polls) : ram_(ram), busy_polls_(busy_polls) {}
  size_t pageCount() const override { return ram_.pageCount(); }
  size_t pageSize() const override { return ram_.pageSize(); }
  bool read(size_t page, size_t offset, uint8_t* data, size_t n) override {
    if (pending_) ++reads_while_busy;
    return ram_.read(page, offset, data, n);
  }
  bool erase(size_t page) override { return ram_.erase(page); }
  bool program(size_t page, size_t offset, const uint8_t* data, size_t n) override {
    return ram_.program(page, offset, data, n);
  }
  hal::FlashOp beginErase(size_t page) override { return begin(true, page, 0, nullptr); }
  hal::FlashOp beginProgram(size_t page, size_t offset, const uint8_t* unit) override {
    return begin(false, page, offset, unit);
  }
  hal::FlashOp poll() override {
    ++polls;
    if (!pending_) return hal::FlashOp::kDone;
    if (left_ > 0) {
      --left_;
      return hal::FlashOp::kBusy;
    }
    pending_ = false;
    const bool ok = erase_ ? ram_.erase(page_) : ram_.program(page_, offset_, unit_, hal::kFlashProgramUnit);
    return ok ? hal::FlashOp::kDone : hal::FlashOp::kFailed;
  }
  int polls = 0;
  int reads_while_busy = 0;
  int begun = 0;

 private:
  hal::FlashOp begin(bool erase, size_t page, size_t offset, const uint8_t* unit) {
    if (pending_) return hal::FlashOp::kFailed;
    ++begun;
    erase_ = erase;
    page_ = page;
    offset_ = offset;
    if (unit != nullptr) std::memcpy(unit_, unit, sizeof unit_);
    left_ = busy_polls_;
    pending_ = true;
    return hal::FlashOp::kBusy;
  }
  sim::RamFlash& ram_;
  int busy_polls_;
  bool pending_ = false, erase_ = false;
  int left_ = 0;
  size_t page_ = 0, offset_ = 0;
  uint8_t unit_[hal::kFlashProgramUnit] = {};
};

TEST(SettingsStore, ASteppedSaveOnASlowFlashTakesOneOperationPerStepAndNeverReadsWhileBusy) {
  sim::RamFlash ram = twoSlots();
  SlowFlash slow(ram, 5);
  ParamApp app;
  fw::SettingsStore store(slow);
  app.values[kA] = 4.0f;
  ASSERT_EQ(store.beginSave(app), SettingsSave::kInProgress);
  EXPECT_TRUE(store.saving());
  EXPECT_EQ(store.beginSave(app), SettingsSave::kBusy) << "one save at a time";
  app.values[kA] = 6.0f;  // after the request: not in this record
  int steps = 0;
  SettingsSave r = SettingsSave::kInProgress;
  while (r == SettingsSave::kInProgress && steps < 1000) {
    const int polls = slow.polls;
    r = store.stepSave();
    ++steps;
    ASSERT_LE(slow.polls - polls, 1) << "one poll per step";
  }
  ASSERT_EQ(r, SettingsSave::kSaved);
  const int units = static_cast<int>((fw::kSettingsHeaderBytes + 8 * 3 + 4 + 7) / 8);
  EXPECT_EQ(slow.begun, 1 + units);
  EXPECT_EQ(steps, 6 * (1 + units)) << "each operation: 5 busy polls and the one that sees it end";
  EXPECT_EQ(slow.reads_while_busy, 0) << "an MCU stalls reading the bank it writes";
  EXPECT_EQ(powerCycle(ram, app).sequence, 1u);
  EXPECT_EQ(app.values[kA], 4.0f) << "the values as they were when the save was requested";
}

TEST(SettingsThroughTheCore, OnASlowFlashTheSaveIsAnsweredWhenItEndsAndCommandsAreRefusedUntilThen) {
  sim::RamFlash ram = twoSlots();
  SlowFlash slow(ram, 20);
  ParamApp app;
  {
    CoreRig rig(slow, app);
    rig.host.sendHello(1, protocol::DeviceType::kAny);
    rig.tick();
    ASSERT_EQ(rig.host.handshake(), host::HandshakeResult::kOk);
    ASSERT_EQ(rig.set(kA, 9.0f).status, protocol::ParamStatus::kOk);
    rig.host.sendParamSet(protocol::core_param::kSettingsSave, 1.0f);
    rig.tick();
    EXPECT_EQ(rig.host.lastParam().param_id, kA) << "no answer yet: the erase runs";
    // Meanwhile: a command is refused (reason 11) and drives nothing; reads and RAM writes are answered; a
    // second save is busy.
    protocol::Command c;
    c.mode = protocol::Mode::kSetpoint;
    c.channel_count = protocol::kSeaFingerLayout.setpoint_count;
    c.timeout_ms = 50;
    rig.host.sendCommand(c, rig.board.clock().nowUs() * 1000);
    rig.tick();
    EXPECT_FALSE(rig.core.outputsActive());
    EXPECT_EQ(rig.host.lastEvent().code, protocol::EventCode::kCommandRejected);
    EXPECT_EQ(rig.host.lastEvent().detail, static_cast<uint8_t>(protocol::RejectReason::kSaveInProgress));
    rig.host.sendParamGet(protocol::core_param::kSettingsSave);
    rig.tick();
    EXPECT_EQ(rig.host.lastParam().param_id, protocol::core_param::kSettingsSave);
    EXPECT_EQ(rig.host.lastParam().value, 0.0f) << "the newest record stored: none yet";
    EXPECT_EQ(rig.set(protocol::core_param::kSettingsSave, 1.0f).status, protocol::ParamStatus::kBusy);
    EXPECT_EQ(rig.set(kA, 5.0f).status, protocol::ParamStatus::kOk) << "RAM only: the save has its values";
    int ticks = 0;
    while (!(rig.host.lastParam().param_id == protocol::core_param::kSettingsSave &&
             rig.host.lastParam().status == protocol::ParamStatus::kOk && rig.host.lastParam().value == 1.0f)) {
      ASSERT_LT(++ticks, 1000);
      rig.tick();
      ASSERT_FALSE(rig.core.outputsActive());
    }
    EXPECT_GT(ticks, 20) << "answered when the save ended, many ticks later";
    rig.host.sendCommand(c, rig.board.clock().nowUs() * 1000);
    rig.tick();
    EXPECT_TRUE(rig.core.outputsActive()) << "commands apply again";
  }
  app = ParamApp();
  CoreRig after(ram, app);
  EXPECT_EQ(app.values[kA], 9.0f);
}

TEST(SettingsThroughTheCore, OnAFlashThatCompletesAtOnceTheSaveIsAnsweredInLineAndACommandBehindItApplies) {
  sim::RamFlash flash = twoSlots();
  ParamApp app;
  CoreRig rig(flash, app);
  rig.host.sendHello(1, protocol::DeviceType::kAny);
  rig.tick();
  ASSERT_EQ(rig.host.handshake(), host::HandshakeResult::kOk);
  ASSERT_EQ(rig.set(kA, 2.0f).status, protocol::ParamStatus::kOk);
  rig.host.sendParamSet(protocol::core_param::kSettingsSave, 1.0f);
  protocol::Command c;
  c.mode = protocol::Mode::kSetpoint;
  c.channel_count = protocol::kSeaFingerLayout.setpoint_count;
  c.timeout_ms = 50;
  rig.host.sendCommand(c, rig.board.clock().nowUs() * 1000);
  rig.tick();  // both in one tick: the save ended before the command was handled
  EXPECT_EQ(rig.host.lastParam().param_id, protocol::core_param::kSettingsSave);
  EXPECT_EQ(rig.host.lastParam().status, protocol::ParamStatus::kOk);
  EXPECT_EQ(rig.host.lastParam().value, 1.0f);
  EXPECT_TRUE(rig.core.outputsActive());
  EXPECT_EQ(rig.core.counters().commands_rejected, 0u);
}

TEST(SettingsThroughTheCore, ASaveWhoseFlashFailsIsAnsweredFailedAndTheOlderRecordStays) {
  sim::RamFlash ram = twoSlots();
  ParamApp app;
  {
    CoreRig rig(ram, app);
    rig.host.sendHello(1, protocol::DeviceType::kAny);
    rig.tick();
    ASSERT_EQ(rig.host.handshake(), host::HandshakeResult::kOk);
    ASSERT_EQ(rig.set(kA, 3.0f).status, protocol::ParamStatus::kOk);
    ASSERT_EQ(rig.set(protocol::core_param::kSettingsSave, 1.0f).status, protocol::ParamStatus::kOk);
    ASSERT_EQ(rig.set(kA, 4.0f).status, protocol::ParamStatus::kOk);
    ram.cutPowerAfter(10);
    EXPECT_EQ(rig.set(protocol::core_param::kSettingsSave, 1.0f).status, protocol::ParamStatus::kFailed);
    ram.restorePower();
  }
  EXPECT_EQ(powerCycle(ram, app).sequence, 1u);
  EXPECT_EQ(app.values[kA], 3.0f);
}

}  // namespace
