#include "phalanx/fw/settings_store.h"

#include <cmath>
#include <cstring>

#include "phalanx/fw/crc32.h"

namespace phalanx::fw {

namespace {
void put16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
}
void put32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}
uint16_t get16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
uint32_t get32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) | (static_cast<uint32_t>(p[2]) << 16) |
         (static_cast<uint32_t>(p[3]) << 24);
}
size_t recordBytes(uint16_t count) { return kSettingsHeaderBytes + 8u * count + 4u; }

/// The id `id` of layout version `from` carries in version `to` (renames applied step by step).
uint16_t migrateId(const SettingsHistory& h, uint16_t from, uint16_t to, uint16_t id) {
  for (uint16_t v = static_cast<uint16_t>(from + 1); v <= to; ++v) {
    const SettingsLayout& l = h.layouts[v - 1];
    for (uint8_t r = 0; r < l.rename_count; ++r) {
      if (l.renames[r].from_id == id) {
        id = l.renames[r].to_id;
        break;
      }
    }
  }
  return id;
}

bool historyValid(const SettingsHistory& h) {
  if (h.layouts == nullptr || h.count == 0) return false;
  for (uint8_t i = 0; i < h.count; ++i) {
    if (h.layouts[i].version != i + 1 || h.layouts[i].id_count > kMaxSettings) return false;
  }
  return true;
}

bool sameValues(const SettingsRecord& a, const SettingsRecord& b) {
  if (a.device_type != b.device_type || a.layout_version != b.layout_version || a.count != b.count) return false;
  for (uint16_t i = 0; i < a.count; ++i) {
    if (a.id[i] != b.id[i] || std::memcmp(&a.value[i], &b.value[i], sizeof(float)) != 0) return false;
  }
  return true;
}
}  // namespace

const char* settingsLoadName(SettingsLoad r) {
  switch (r) {
    case SettingsLoad::kNothingStored: return "nothing-stored";
    case SettingsLoad::kLoaded: return "loaded";
    case SettingsLoad::kMigrated: return "migrated";
    case SettingsLoad::kNewerLayout: return "newer-layout";
    case SettingsLoad::kOtherDevice: return "other-device";
    case SettingsLoad::kNoLayout: return "no-layout";
  }
  return "?";
}

uint32_t settingsCrc32(const uint8_t* data, size_t n) { return crc32(data, n); }

size_t encodeSettingsRecord(const SettingsRecord& rec, uint8_t* out) {
  const uint16_t count = rec.count <= kMaxSettings ? rec.count : static_cast<uint16_t>(kMaxSettings);
  put32(out, kSettingsMagic);
  out[4] = kSettingsFormat;
  out[5] = rec.device_type;
  put16(out + 6, rec.layout_version);
  put32(out + 8, rec.sequence);
  put16(out + 12, count);
  put16(out + 14, 0);
  for (uint16_t i = 0; i < count; ++i) {
    uint8_t* p = out + kSettingsHeaderBytes + 8u * i;
    uint32_t bits = 0;
    std::memcpy(&bits, &rec.value[i], sizeof bits);
    put16(p, rec.id[i]);
    put16(p + 2, 0);
    put32(p + 4, bits);
  }
  const size_t body = kSettingsHeaderBytes + 8u * count;
  put32(out + body, settingsCrc32(out, body));
  return body + 4u;
}

bool decodeSettingsRecord(const uint8_t* in, size_t n, SettingsRecord& rec) {
  if (n < kSettingsHeaderBytes + 4u || get32(in) != kSettingsMagic || in[4] != kSettingsFormat) return false;
  const uint16_t count = get16(in + 12);
  if (count > kMaxSettings || n < recordBytes(count)) return false;
  const size_t body = kSettingsHeaderBytes + 8u * count;
  if (get32(in + body) != settingsCrc32(in, body)) return false;
  // Reserved fields are written as zero: a record with anything there is not one this firmware wrote (nor reads).
  if (get16(in + 14) != 0) return false;
  for (uint16_t i = 0; i < count; ++i) {
    if (get16(in + kSettingsHeaderBytes + 8u * i + 2u) != 0) return false;
  }
  rec.device_type = in[5];
  rec.layout_version = get16(in + 6);
  rec.sequence = get32(in + 8);
  rec.count = count;
  for (uint16_t i = 0; i < count; ++i) {
    const uint8_t* p = in + kSettingsHeaderBytes + 8u * i;
    const uint32_t bits = get32(p + 4);
    rec.id[i] = get16(p);
    std::memcpy(&rec.value[i], &bits, sizeof bits);
  }
  return true;
}

const SettingsLayout* SettingsStore::builtLayout(const DeviceApp& app) const {
  const SettingsHistory h = app.settingsHistory();
  if (!historyValid(h)) return nullptr;
  if (built_version_ == 0) return &h.layouts[h.count - 1];
  return built_version_ <= h.count ? &h.layouts[built_version_ - 1] : nullptr;
}

uint16_t SettingsStore::layoutVersion(const DeviceApp& app) const {
  const SettingsLayout* l = builtLayout(app);
  return l != nullptr ? l->version : 0;
}

bool SettingsStore::readSlot(size_t slot, SettingsRecord& rec) {
  const size_t page = first_page_ + slot;
  if (page >= flash_.pageCount() || flash_.pageSize() < kSettingsSlotBytes) return false;
  if (!flash_.read(page, 0, buf_, kSettingsHeaderBytes)) return false;
  const uint16_t count = get16(buf_ + 12);
  if (get32(buf_) != kSettingsMagic || count > kMaxSettings) return false;
  if (!flash_.read(page, 0, buf_, recordBytes(count))) return false;
  return decodeSettingsRecord(buf_, recordBytes(count), rec);
}

int SettingsStore::readNewest(SettingsRecord& rec) {
  int newest = -1;
  newest_seq_ = 0;
  for (size_t slot = 0; slot < 2; ++slot) {
    SettingsRecord r;
    if (!readSlot(slot, r)) continue;
    if (newest < 0 || r.sequence > rec.sequence) {
      rec = r;
      newest = static_cast<int>(slot);
      newest_seq_ = r.sequence;
    }
  }
  return newest;
}

SettingsReport SettingsStore::load(DeviceApp& app) {
  SettingsReport rep;
  SettingsRecord rec;
  const int slot = readNewest(rec);
  const SettingsLayout* cur = builtLayout(app);
  if (cur == nullptr) {
    rep.result = SettingsLoad::kNoLayout;
  } else if (slot < 0 || rec.layout_version == 0) {
    rep.result = SettingsLoad::kNothingStored;
  } else {
    rep.record_version = rec.layout_version;
    rep.sequence = rec.sequence;
    if (rec.device_type != static_cast<uint8_t>(app.layout().type)) {
      rep.result = SettingsLoad::kOtherDevice;
    } else if (rec.layout_version > cur->version) {
      rep.result = SettingsLoad::kNewerLayout;
    } else {
      rep.result = rec.layout_version == cur->version ? SettingsLoad::kLoaded : SettingsLoad::kMigrated;
      const SettingsHistory h = app.settingsHistory();
      bool used[kMaxSettings] = {};
      // In the layout's order (a mode before the gains that depend on it); a value is applied once at most.
      for (uint8_t k = 0; k < cur->id_count; ++k) {
        for (uint16_t i = 0; i < rec.count; ++i) {
          if (used[i] || migrateId(h, rec.layout_version, cur->version, rec.id[i]) != cur->ids[k]) continue;
          used[i] = true;
          const bool ok = std::isfinite(rec.value[i]) && app.setParam(cur->ids[k], rec.value[i]) == protocol::ParamStatus::kOk;
          ++(ok ? rep.applied : rep.refused);
          break;
        }
      }
      for (uint16_t i = 0; i < rec.count; ++i) {
        if (!used[i]) ++rep.dropped;
      }
    }
  }
  last_load_ = rep;
  return rep;
}

SettingsSave SettingsStore::beginSave(const DeviceApp& app) {
  if (saving()) return SettingsSave::kBusy;
  // An operation a failed save gave up on may still run: reading the slots now would stall an MCU on the bank
  // being written (for up to an erase: longer than its watchdog allows).
  if (flash_.poll() == hal::FlashOp::kBusy) return SettingsSave::kBusy;
  const SettingsLayout* cur = builtLayout(app);
  if (cur == nullptr) return SettingsSave::kNoLayout;
  SettingsRecord rec;
  rec.device_type = static_cast<uint8_t>(app.layout().type);
  rec.layout_version = cur->version;
  rec.count = cur->id_count;
  for (uint8_t k = 0; k < cur->id_count; ++k) {
    rec.id[k] = cur->ids[k];
    if (app.getParam(cur->ids[k], rec.value[k]) != protocol::ParamStatus::kOk) return SettingsSave::kReadFailed;
  }
  SettingsRecord newest;
  const int slot = readNewest(newest);
  if (slot >= 0 && sameValues(rec, newest)) return SettingsSave::kUnchanged;
  rec.sequence = slot >= 0 ? newest.sequence + 1u : 1u;
  const size_t target = slot == 0 ? 1u : 0u;
  target_page_ = first_page_ + target;
  if (target_page_ >= flash_.pageCount() || flash_.pageSize() < kSettingsSlotBytes) return SettingsSave::kWriteFailed;
  // One pass, each unit once (ECC flash); a write cut anywhere leaves a record whose CRC fails.
  const size_t len = encodeSettingsRecord(rec, buf_);
  write_len_ = (len + hal::kFlashProgramUnit - 1) / hal::kFlashProgramUnit * hal::kFlashProgramUnit;
  for (size_t i = len; i < write_len_; ++i) buf_[i] = 0xFF;
  pending_seq_ = rec.sequence;
  next_unit_ = 0;
  busy_steps_ = 0;
  phase_ = Phase::kErase;
  const hal::FlashOp op = flash_.beginErase(target_page_);
  if (op == hal::FlashOp::kFailed) return endSave(SettingsSave::kWriteFailed);
  op_pending_ = op == hal::FlashOp::kBusy;
  return SettingsSave::kInProgress;
}

SettingsSave SettingsStore::stepSave() {
  if (!saving()) return SettingsSave::kUnchanged;
  if (op_pending_) {
    const hal::FlashOp op = flash_.poll();
    if (op == hal::FlashOp::kBusy) {
      return ++busy_steps_ < busy_bound_ ? SettingsSave::kInProgress : endSave(SettingsSave::kWriteFailed);
    }
    op_pending_ = false;
    if (op == hal::FlashOp::kFailed) return endSave(SettingsSave::kWriteFailed);
  }
  // Operations that end at once (hal/sim) follow each other within this step; one that runs on (kBusy) ends it.
  // At most one erase, the record's units and the check: bounded by kSettingsSlotBytes.
  for (size_t i = 0; i < kSettingsSlotBytes / hal::kFlashProgramUnit + 2; ++i) {
    const SettingsSave r = advanceOnce();
    if (r != SettingsSave::kInProgress || op_pending_) return r;
  }
  return SettingsSave::kInProgress;
}

SettingsSave SettingsStore::advanceOnce() {
  busy_steps_ = 0;
  if (phase_ == Phase::kErase) phase_ = Phase::kProgram;
  if (phase_ == Phase::kProgram && next_unit_ < write_len_) {
    const hal::FlashOp op = flash_.beginProgram(target_page_, next_unit_, buf_ + next_unit_);
    next_unit_ += hal::kFlashProgramUnit;
    if (op == hal::FlashOp::kFailed) return endSave(SettingsSave::kWriteFailed);
    op_pending_ = op == hal::FlashOp::kBusy;
    return SettingsSave::kInProgress;
  }
  // Every unit programmed and ended: the read-back check (no operation runs, the page may be read).
  if (!flash_.read(target_page_, 0, check_, write_len_) || std::memcmp(buf_, check_, write_len_) != 0) {
    return endSave(SettingsSave::kWriteFailed);
  }
  newest_seq_ = pending_seq_;
  return endSave(SettingsSave::kSaved);
}

SettingsSave SettingsStore::endSave(SettingsSave r) {
  phase_ = Phase::kIdle;
  op_pending_ = false;
  return r;
}

SettingsSave SettingsStore::save(const DeviceApp& app) {
  SettingsSave r = beginSave(app);
  // Each step either moves the save on by one operation or counts one busy poll of it: bounded.
  const size_t max_steps = (kSettingsSlotBytes / hal::kFlashProgramUnit + 2) * (static_cast<size_t>(busy_bound_) + 1);
  for (size_t i = 0; r == SettingsSave::kInProgress && i < max_steps; ++i) r = stepSave();
  return r == SettingsSave::kInProgress ? endSave(SettingsSave::kWriteFailed) : r;
}

}  // namespace phalanx::fw
