#pragma once
/// Persistent device settings (docs/params.md): the app's settable device parameters kept in flash across power
/// cycles and firmware updates. A record is
///   magic u32 "PXST" | format u8 | device_type u8 | layout_version u16 | sequence u32 | count u16 | reserved u16 |
///   count × (id u16 | reserved u16 | value f32) | CRC-32 (IEEE, zlib's) of everything before it
/// little-endian, padded with 0xFF to whole flash program units and programmed in one pass after the page's erase
/// (each double word once, as ECC flash requires), written alternately into two flash pages (slots): a save goes
/// to the slot that does not hold the newest valid record, so a power loss mid-write leaves that one intact; the newest valid record (highest
/// sequence, CRC good) wins at load. A save that would write what the newest record already holds writes nothing.
/// No heap, no exceptions, loops bounded by kMaxSettings and the two slots.
#include <cstddef>
#include <cstdint>

#include "phalanx/fw/app.h"
#include "phalanx/hal/flash.h"

namespace phalanx::fw {

constexpr size_t kMaxSettings = 32;
constexpr uint32_t kSettingsMagic = 0x54535850u;  ///< "PXST" read as little-endian bytes
constexpr uint8_t kSettingsFormat = 1;            ///< the record's own byte layout (above)
constexpr size_t kSettingsHeaderBytes = 16;
constexpr size_t kSettingsRecordMaxBytes = kSettingsHeaderBytes + 8 * kMaxSettings + 4;
/// A record as programmed: padded with 0xFF to whole flash program units (hal::kFlashProgramUnit).
constexpr size_t kSettingsSlotBytes =
    (kSettingsRecordMaxBytes + hal::kFlashProgramUnit - 1) / hal::kFlashProgramUnit * hal::kFlashProgramUnit;

/// One record, decoded.
struct SettingsRecord {
  uint8_t device_type = 0;
  uint16_t layout_version = 0;
  uint32_t sequence = 0;
  uint16_t count = 0;
  uint16_t id[kMaxSettings] = {};
  float value[kMaxSettings] = {};
};

/// Bytes of rec into out (kSettingsRecordMaxBytes at least); returns the record's length.
size_t encodeSettingsRecord(const SettingsRecord& rec, uint8_t* out);
/// false when the bytes are not a valid record (magic, format, count, CRC).
bool decodeSettingsRecord(const uint8_t* in, size_t n, SettingsRecord& rec);
uint32_t settingsCrc32(const uint8_t* data, size_t n);

/// What load() found (core parameter core_param::kSettingsLoad reports it as a number).
enum class SettingsLoad : uint8_t {
  kNothingStored = 0,  ///< no valid record in either slot (new board, or both slots corrupted)
  kLoaded = 1,         ///< a record of this firmware's layout version
  kMigrated = 2,       ///< a record of an older layout version, migrated (renamed ids mapped, new ids at defaults)
  kNewerLayout = 3,    ///< written by a newer firmware (a downgrade): nothing applied, defaults kept
  kOtherDevice = 4,    ///< written by another device type's firmware: nothing applied
  kNoLayout = 5,       ///< the app persists nothing (or its layout history is malformed)
};

/// "nothing-stored", "loaded", "migrated", "newer-layout", "other-device", "no-layout" ("?" otherwise).
const char* settingsLoadName(SettingsLoad r);

struct SettingsReport {
  SettingsLoad result = SettingsLoad::kNothingStored;
  uint16_t record_version = 0;  ///< layout version of the record found (0: none)
  uint32_t sequence = 0;        ///< its sequence number
  uint8_t applied = 0;          ///< values the app took
  uint8_t refused = 0;          ///< values the app refused (out of range now, non-finite): the default stays
  uint8_t dropped = 0;          ///< values of ids this layout no longer persists
};

enum class SettingsSave : uint8_t {
  kSaved = 0,
  kUnchanged = 1,    ///< the newest record already holds these values: nothing written (wear)
  kNoLayout = 2,     ///< the app persists nothing
  kReadFailed = 3,   ///< the app did not answer one of its own persisted ids
  kWriteFailed = 4,  ///< erase, program or the read-back check failed: the other slot still holds the previous record
};

class SettingsStore {
 public:
  /// Slots are pages first_page and first_page + 1 (each at least kSettingsSlotBytes). built_version: the
  /// layout version this firmware writes, one of the app's history; 0 = its newest. (firmware-sim lets a test pick
  /// an older one to play the firmware before an update.)
  explicit SettingsStore(hal::FlashPages& flash, size_t first_page = 0, uint16_t built_version = 0)
      : flash_(flash), first_page_(first_page), built_version_(built_version) {}

  /// Read the newest valid record and apply it through app.setParam, migrating an older layout. Call once at init,
  /// outputs off.
  SettingsReport load(DeviceApp& app);
  /// Write the app's current values of its persisted ids as a new record.
  SettingsSave save(const DeviceApp& app);

  const SettingsReport& lastLoad() const { return last_load_; }
  /// Sequence of the newest valid record in flash (0: none).
  uint32_t newestSequence() const { return newest_seq_; }
  /// The layout version this firmware writes (0: the app persists nothing).
  uint16_t layoutVersion(const DeviceApp& app) const;

 private:
  const SettingsLayout* builtLayout(const DeviceApp& app) const;
  /// The newest valid record into rec; its slot index, or -1 when neither slot holds one.
  int readNewest(SettingsRecord& rec);
  bool readSlot(size_t slot, SettingsRecord& rec);
  bool writeSlot(size_t slot, const SettingsRecord& rec);

  hal::FlashPages& flash_;
  size_t first_page_;
  uint16_t built_version_;
  uint32_t newest_seq_ = 0;
  SettingsReport last_load_;
  uint8_t buf_[kSettingsSlotBytes] = {};
  uint8_t check_[kSettingsSlotBytes] = {};
};

}  // namespace phalanx::fw
