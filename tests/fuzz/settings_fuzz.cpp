// libFuzzer target: arbitrary bytes as the two settings slots of a board's flash (firmware/core settings_store.h).
// Whatever the flash holds, the load must not crash or read out of bounds and applies only values the app takes;
// a save after it must then succeed and load back exactly. A decoded record re-encodes to the bytes it came from.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "phalanx/fw/settings_store.h"
#include "phalanx/sim/sim_flash.h"

using namespace phalanx;

namespace {

constexpr uint16_t kV1[] = {0x100, 0x101, 0x102};
constexpr uint16_t kV2[] = {0x100, 0x111, 0x103};
constexpr fw::SettingsRename kRenames[] = {{0x101, 0x111}};
constexpr fw::SettingsLayout kHistory[] = {{1, kV1, 3, nullptr, 0}, {2, kV2, 3, kRenames, 1}};

/// Five bounded parameters (0 ≤ v ≤ 100), defaults 0.
class App : public fw::DeviceApp {
 public:
  const protocol::DeviceLayout& layout() const override { return protocol::kSeaFingerLayout; }
  void init(hal::Board&) override {}
  uint16_t sense(float) override { return 0; }
  uint16_t control(const protocol::Command&, float) override { return 0; }
  void safe() override {}
  void fillSamples(int16_t*) const override {}
  protocol::ParamStatus getParam(uint16_t id, float& v) const override {
    const int i = index(id);
    if (i < 0) return protocol::ParamStatus::kUnknownParam;
    v = value[i];
    return protocol::ParamStatus::kOk;
  }
  protocol::ParamStatus setParam(uint16_t id, float v) override {
    const int i = index(id);
    if (i < 0) return protocol::ParamStatus::kUnknownParam;
    if (!(v >= 0.0f && v <= 100.0f)) return protocol::ParamStatus::kOutOfRange;
    value[i] = v;
    return protocol::ParamStatus::kOk;
  }
  fw::SettingsHistory settingsHistory() const override { return fw::settingsHistoryOf(kHistory); }
  static int index(uint16_t id) {
    const uint16_t ids[] = {0x100, 0x101, 0x102, 0x103, 0x111};
    for (int i = 0; i < 5; ++i) {
      if (ids[i] == id) return i;
    }
    return -1;
  }
  float value[5] = {};
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  fw::SettingsRecord rec;
  if (fw::decodeSettingsRecord(data, size, rec)) {
    uint8_t again[fw::kSettingsRecordMaxBytes];
    const size_t n = fw::encodeSettingsRecord(rec, again);
    if (n > size || std::memcmp(again, data, n) != 0) std::abort();
  }
  if (size == 0) return 0;
  const uint16_t built = static_cast<uint16_t>(data[0] % 3);  // 0 newest, 1, 2
  sim::RamFlash flash(2, 512);
  flash.loadImage(data + 1, size - 1);
  App app;
  fw::SettingsStore store(flash, 0, built);
  const fw::SettingsReport r = store.load(app);
  if (r.applied + r.refused + r.dropped > fw::kMaxSettings) std::abort();
  for (float v : app.value) {
    if (!(v >= 0.0f && v <= 100.0f)) std::abort();
  }
  const fw::SettingsSave s = store.save(app);
  if (s != fw::SettingsSave::kSaved && s != fw::SettingsSave::kUnchanged) std::abort();
  App back;
  fw::SettingsStore reload(flash, 0, built);
  if (reload.load(back).result != fw::SettingsLoad::kLoaded) std::abort();
  for (uint16_t i = 0; i < 3; ++i) {
    const uint16_t id = kHistory[store.layoutVersion(app) - 1].ids[i];
    if (back.value[App::index(id)] != app.value[App::index(id)]) std::abort();
  }
  return 0;
}
