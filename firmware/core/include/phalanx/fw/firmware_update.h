#pragma once
/// Firmware update over the device's own link (docs/firmware-update.md), and the boot choice it relies on.
///
/// The board's code flash holds two image slots and a boot record kept in two pages. An update is written into the
/// slot the board did not boot from; the slot it runs from is never erased or programmed. Only when the received
/// image has verified (its image-info block says it is this board's and this device's, its CRC-32 matches) is a
/// new boot record written — into the record page that does not hold the newest record, so a power loss mid-write
/// leaves the previous record intact. At reset the boot stage (chooseBoot) takes the slot the newest valid record
/// names if that slot's image verifies, otherwise the other slot if its image does. A power loss or a link loss at
/// any point therefore leaves a board that boots a valid image: the old one until the record is written, the new
/// one after.
///
/// Trial boot (bootStage). The commit's record puts the new image on trial. The boot stage boots it once, writing a
/// record that says so first; the running image confirms itself when told to (core_param::kUpdateTrial, which
/// `phalanx update` sets once the board answers with the new build). A reset before the confirm — the image hung,
/// crashed or never answered, the watchdog or the power took the board down — finds the trial used up, and the boot
/// stage goes back to the other slot's image, confirmed. Every decision is taken again from the records at the next
/// reset, so a power loss while a record is written repeats it.
///
/// A boot record is
///   magic u32 "PXBT" | format u8 | slot u8 | state u8 | reserved u8 | sequence u32 | image_size u32 |
///   image_crc32 u32 | build_id u32 | reserved u32 | CRC-32 of everything before it
/// little-endian, 32 bytes (whole flash program units), the CRC last: a write torn anywhere leaves no valid record.
///
/// No heap, no exceptions; every loop is bounded by the slot's size, the two slots or the two record pages.
#include <cstddef>
#include <cstdint>

#include "phalanx/hal/flash.h"
#include "phalanx/image_info.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::fw {

constexpr uint32_t kBootRecordMagic = 0x54425850u;  ///< "PXBT" read as little-endian bytes
constexpr uint8_t kBootRecordFormat = 1;
constexpr size_t kBootRecordBytes = 32;

/// Where the slots and the boot records are, in pages of one hal::FlashPages, and what images the board takes.
struct UpdateLayout {
  size_t slot_first_page[2] = {0, 0};
  size_t slot_pages = 0;          ///< pages per slot (an image is at most slot_pages × page size bytes)
  size_t record_first_page = 0;   ///< two pages: the boot record's two copies
  uint8_t board = 0;              ///< image::BoardId this board accepts
  uint8_t device_type = 0;        ///< protocol::DeviceType of this firmware's app
};

/// A record's trial state. 0 is what records had before trial boot existed (the byte was reserved as zero).
enum class BootState : uint8_t {
  kConfirmed = 0,    ///< boot this slot
  kTrial = 1,        ///< written by the commit: boot this slot once, on trial
  kTrialBooted = 2,  ///< written by the boot stage as it boots the trial: found at the next reset, the trial failed
};

struct BootRecord {
  uint32_t sequence = 0;
  uint8_t slot = 0;
  BootState state = BootState::kConfirmed;
  uint32_t image_size = 0;
  uint32_t image_crc32 = 0;
  uint32_t build_id = 0;
};
void encodeBootRecord(const BootRecord& rec, uint8_t* out);  ///< kBootRecordBytes bytes
bool decodeBootRecord(const uint8_t* in, BootRecord& rec);   ///< false: magic, format, slot, state, reserved or CRC wrong

/// What the boot stage chose.
struct BootChoice {
  bool valid = false;          ///< a slot holds a valid image (false: nothing to boot)
  uint8_t slot = 0;
  uint32_t build_id = 0;       ///< of the image booted
  uint32_t image_size = 0;
  uint32_t record_sequence = 0;  ///< the newest valid boot record's (0: none)
  bool fell_back = false;      ///< the record named a slot whose image did not verify; the other slot boots
  uint32_t image_crc32 = 0;    ///< of the image booted
  bool trial = false;          ///< (bootStage) the image runs on trial: confirm it, or the next reset goes back
  bool trial_failed = false;   ///< (bootStage) the last trial ended in a reset unconfirmed: the previous image boots
};

/// The image in `slot` verifies: image-info block (magic, layout), this board and device, a size that fits the
/// slot and holds the block, a non-zero build id, and the CRC-32 over image_size bytes with the CRC field read as
/// zero (as the build computes it). Its block into *info when given.
bool verifySlot(hal::FlashPages& flash, const UpdateLayout& layout, uint8_t slot, image::ImageInfo* info = nullptr);

/// The newest valid boot record (highest sequence, CRC good) and which record page holds it (-1: none).
int readNewestBootRecord(hal::FlashPages& flash, const UpdateLayout& layout, BootRecord& rec);

/// The slot the newest record names if its image verifies, else the other slot's (no writes; trial state aside).
BootChoice chooseBoot(hal::FlashPages& flash, const UpdateLayout& layout);

/// At reset: chooseBoot, then the trial rules (file comment), writing the record they need before booting.
BootChoice bootStage(hal::FlashPages& flash, const UpdateLayout& layout);

/// Writes `rec` (its sequence replaced by one past the newest) into the record page that does not hold the newest
/// record, and reads it back. false: the erase, the program or the read-back failed (the newest record is intact).
bool writeBootRecord(hal::FlashPages& flash, const UpdateLayout& layout, BootRecord rec);

/// The device's side of an update: each request's answer. The core calls it from the tick with the outputs off.
class FirmwareUpdate {
 public:
  /// running: what the boot stage chose at this reset (the update goes into the other slot).
  FirmwareUpdate(hal::FlashPages& flash, const UpdateLayout& layout, const BootChoice& running)
      : flash_(flash), layout_(layout), running_(running) {}

  /// Begin or, when an update of the same image (size, CRC, build id) is already being received since this reset,
  /// resume it: next_offset says where. session_id: 0 or the open session's (open_session_id; 0 when none).
  protocol::UpdateStatus begin(const protocol::UpdateBegin& m, uint32_t open_session_id);
  protocol::UpdateStatus data(const protocol::UpdateData& m);
  /// Verify the received image and write the boot record; kCommitted → rebootRequested().
  protocol::UpdateStatus commit(const protocol::UpdateCommit& m);

  /// An update is being received (begun, not failed, not committed): the core keeps the outputs off.
  bool inProgress() const { return state_ == State::kReceiving; }
  /// The new image is marked to boot: the board resets now (the MCU through its reset; firmware-sim restarts).
  bool rebootRequested() const { return state_ == State::kCommitted; }
  /// The running image is on trial (bootStage) and not yet confirmed.
  bool onTrial() const { return running_.trial; }
  /// Confirms the running image (a record naming its slot, confirmed). false: the record could not be written
  /// (still on trial). Nothing to do when it is not on trial.
  bool confirm();
  const BootChoice& running() const { return running_; }
  uint8_t targetSlot() const { return static_cast<uint8_t>(running_.valid ? 1u - running_.slot : 0u); }
  size_t slotBytes() const { return layout_.slot_pages * flash_.pageSize(); }

 private:
  enum class State : uint8_t { kIdle, kReceiving, kCommitted };
  protocol::UpdateStatus status(protocol::MsgId answers, protocol::UpdateResult r, uint8_t detail = 0) const;
  /// Fails the update: the next one must begin again (the running image is untouched).
  protocol::UpdateStatus fail(protocol::MsgId answers, protocol::UpdateResult r);
  /// Erase the pages of the target slot up to the one holding image byte `last` (each once per update).
  bool erasePagesThrough(uint32_t last);

  hal::FlashPages& flash_;
  UpdateLayout layout_;
  BootChoice running_;
  State state_ = State::kIdle;
  protocol::UpdateBegin image_{};
  uint32_t received_ = 0;     ///< image bytes programmed, from 0
  size_t pages_erased_ = 0;   ///< target slot pages erased in this update, from its first
};

}  // namespace phalanx::fw
