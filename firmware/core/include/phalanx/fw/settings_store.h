#pragma once
/// Persistent device settings (docs/params.md): the app's settable device parameters kept in flash across power
/// cycles and firmware updates. A record is
///   magic u32 "PXST" | format u8 | device_type u8 | layout_version u16 | sequence u32 | count u16 | reserved u16 |
///   count × (id u16 | reserved u16 | value f32) | CRC-32 (IEEE, zlib's) of everything before it
/// little-endian, padded with 0xFF to whole flash program units and programmed in one pass after the page's erase
/// (each double word once, as ECC flash requires), written alternately into two flash pages (slots): a save goes
/// to the slot that does not hold the newest valid record, so a power loss mid-write leaves that one intact; the newest valid record (highest
/// sequence, CRC good) wins at load. A save that would write what the newest record already holds writes nothing.
/// A save runs as steps (beginSave, then stepSave once per control tick): erase started, polled until it ends, one
/// program unit started per step and polled, then the read-back check — so that a flash whose page erase outlasts
/// the tick and the watchdog (the STM32G474's: 22 ms typical) never makes a step wait. On a flash that completes
/// at once (hal/sim) the whole save is one step; save() runs the steps back to back.
/// No heap, no exceptions, loops bounded by kMaxSettings, the two slots and the record's program units.
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
  kInProgress = 5,   ///< beginSave/stepSave: the save is under way, call stepSave() again (next tick)
  kBusy = 6,         ///< beginSave: a save is already under way, or the flash still busy (nothing new started)
};

/// Steps one flash operation may stay busy before the save gives up (kWriteFailed): at 1 kHz, 200 ms, 8× the
/// STM32G474's longest page erase (DS12288 t_ERASE max 24.5 ms).
constexpr uint32_t kSettingsBusyStepBound = 200;

class SettingsStore {
 public:
  /// Slots are pages first_page and first_page + 1 (each at least kSettingsSlotBytes). built_version: the
  /// layout version this firmware writes, one of the app's history; 0 = its newest. (firmware-sim lets a test pick
  /// an older one to play the firmware before an update.)
  /// busy_step_bound: stepSave() calls one flash operation may report busy before the save fails.
  explicit SettingsStore(hal::FlashPages& flash, size_t first_page = 0, uint16_t built_version = 0,
                         uint32_t busy_step_bound = kSettingsBusyStepBound)
      : flash_(flash), first_page_(first_page), built_version_(built_version), busy_bound_(busy_step_bound) {}

  /// Read the newest valid record and apply it through app.setParam, migrating an older layout. Call once at init,
  /// outputs off.
  SettingsReport load(DeviceApp& app);
  /// Write the app's current values of its persisted ids as a new record: beginSave and stepSave until it ends
  /// (waits for the flash: for hal/sim's flashes and tests; the MCU boards use the steps).
  SettingsSave save(const DeviceApp& app);
  /// Starts a save of the app's current values (taken now: later changes are not in this record). kInProgress:
  /// call stepSave() once per tick until it returns something else; any other result is final (nothing to
  /// write, refused, or kBusy when a save is already under way). Reads the slots: no flash operation runs.
  SettingsSave beginSave(const DeviceApp& app);
  /// One bounded step of the save under way: polls the flash once, starts the next operation when the last one
  /// ended. kInProgress until the save ends, then its result (kSaved or kWriteFailed) once; kInProgress never
  /// when no save is under way (then kUnchanged).
  SettingsSave stepSave();
  bool saving() const { return phase_ != Phase::kIdle; }

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
  enum class Phase : uint8_t { kIdle, kErase, kProgram };
  /// After the last operation ended: starts the next unit's programming, or runs the read-back check once every
  /// unit is programmed (kSaved / kWriteFailed then).
  SettingsSave advanceOnce();
  SettingsSave endSave(SettingsSave r);

  hal::FlashPages& flash_;
  size_t first_page_;
  uint16_t built_version_;
  uint32_t busy_bound_;
  Phase phase_ = Phase::kIdle;
  bool op_pending_ = false;    ///< an operation was begun and has not yet been seen to end
  uint32_t busy_steps_ = 0;    ///< steps the pending operation has reported busy
  size_t target_page_ = 0;
  size_t write_len_ = 0;       ///< bytes of buf_ to program (whole units)
  size_t next_unit_ = 0;       ///< offset of the next unit to program
  uint32_t pending_seq_ = 0;   ///< the sequence of the record being written
  uint32_t newest_seq_ = 0;
  SettingsReport last_load_;
  uint8_t buf_[kSettingsSlotBytes] = {};
  uint8_t check_[kSettingsSlotBytes] = {};
};

}  // namespace phalanx::fw
