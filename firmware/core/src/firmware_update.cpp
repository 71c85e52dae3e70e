#include "phalanx/fw/firmware_update.h"

#include <cstring>

#include "phalanx/fw/crc32.h"

namespace phalanx::fw {

using protocol::MsgId;
using protocol::UpdateImageField;
using protocol::UpdateResult;
using protocol::UpdateStatus;

namespace {

void put32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}
uint32_t get32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 | static_cast<uint32_t>(p[2]) << 16 |
         static_cast<uint32_t>(p[3]) << 24;
}

/// Reads bytes [at, at + n) of a slot, n ≤ the chunk buffer; false when the flash read fails.
bool readSlotBytes(hal::FlashPages& flash, const UpdateLayout& layout, uint8_t slot, uint32_t at, uint8_t* out,
                   size_t n) {
  const size_t page_size = flash.pageSize();
  while (n > 0) {
    const size_t page = at / page_size, offset = at % page_size;
    const size_t take = n < page_size - offset ? n : page_size - offset;
    if (page >= layout.slot_pages || !flash.read(layout.slot_first_page[slot] + page, offset, out, take)) return false;
    at += static_cast<uint32_t>(take);
    out += take;
    n -= take;
  }
  return true;
}

image::ImageInfo decodeInfo(const uint8_t* b) {
  image::ImageInfo i;
  i.magic = get32(b);
  i.layout_version = static_cast<uint16_t>(b[4] | b[5] << 8);
  i.info_size = static_cast<uint16_t>(b[6] | b[7] << 8);
  i.device_type = b[8];
  i.board = b[9];
  i.build_id = get32(b + 12);
  i.load_address = get32(b + 16);
  i.image_size = get32(b + 20);
  i.image_crc32 = get32(b + 24);
  return i;
}

constexpr size_t kCrcField = image::kImageInfoOffset + offsetof(image::ImageInfo, image_crc32);

}  // namespace

void encodeBootRecord(const BootRecord& rec, uint8_t* out) {
  put32(out, kBootRecordMagic);
  out[4] = kBootRecordFormat;
  out[5] = rec.slot;
  out[6] = static_cast<uint8_t>(rec.state);
  out[7] = 0;
  put32(out + 8, rec.sequence);
  put32(out + 12, rec.image_size);
  put32(out + 16, rec.image_crc32);
  put32(out + 20, rec.build_id);
  put32(out + 24, 0);
  put32(out + 28, crc32(out, 28));
}

bool decodeBootRecord(const uint8_t* in, BootRecord& rec) {
  // The reserved byte 7 and word 24 are written as zero: a record with anything else there, even under a valid
  // CRC, is not one this firmware wrote (as the settings record's reserved fields, found by fuzzing).
  if (get32(in) != kBootRecordMagic || in[4] != kBootRecordFormat || in[5] > 1 ||
      in[6] > static_cast<uint8_t>(BootState::kTrialBooted) || in[7] != 0 || get32(in + 24) != 0 ||
      get32(in + 28) != crc32(in, 28)) {
    return false;
  }
  rec.slot = in[5];
  rec.state = static_cast<BootState>(in[6]);
  rec.sequence = get32(in + 8);
  rec.image_size = get32(in + 12);
  rec.image_crc32 = get32(in + 16);
  rec.build_id = get32(in + 20);
  return true;
}

bool verifySlot(hal::FlashPages& flash, const UpdateLayout& layout, uint8_t slot, image::ImageInfo* info_out) {
  if (slot > 1) return false;
  uint8_t buf[64];
  if (!readSlotBytes(flash, layout, slot, image::kImageInfoOffset, buf, sizeof(image::ImageInfo))) return false;
  const image::ImageInfo info = decodeInfo(buf);
  const size_t slot_bytes = layout.slot_pages * flash.pageSize();
  if (info.magic != image::kImageInfoMagic || info.layout_version != image::kImageInfoLayoutVersion ||
      info.board != layout.board || info.device_type != layout.device_type || info.build_id == 0 ||
      info.image_size < image::kImageInfoOffset + sizeof(image::ImageInfo) || info.image_size > slot_bytes) {
    return false;
  }
  // CRC over the image with its CRC field read as zero, a buffer at a time (bounded by the slot's size).
  uint32_t crc = kCrc32Init;
  for (uint32_t at = 0; at < info.image_size;) {
    const uint32_t left = info.image_size - at;
    const size_t n = left < sizeof buf ? left : sizeof buf;
    if (!readSlotBytes(flash, layout, slot, at, buf, n)) return false;
    for (size_t i = 0; i < n; ++i) {
      if (at + i >= kCrcField && at + i < kCrcField + 4) buf[i] = 0;
    }
    crc = crc32Update(crc, buf, n);
    at += static_cast<uint32_t>(n);
  }
  if (crc32Final(crc) != info.image_crc32) return false;
  if (info_out != nullptr) *info_out = info;
  return true;
}

int readNewestBootRecord(hal::FlashPages& flash, const UpdateLayout& layout, BootRecord& rec) {
  int newest = -1;
  for (int copy = 0; copy < 2; ++copy) {
    uint8_t buf[kBootRecordBytes];
    BootRecord r;
    if (!flash.read(layout.record_first_page + static_cast<size_t>(copy), 0, buf, sizeof buf) ||
        !decodeBootRecord(buf, r)) {
      continue;
    }
    if (newest < 0 || r.sequence > rec.sequence) {
      rec = r;
      newest = copy;
    }
  }
  return newest;
}

namespace {
/// Booting the verified image `info` in `slot`.
BootChoice bootOf(uint8_t slot, const image::ImageInfo& info) {
  BootChoice c;
  c.valid = true;
  c.slot = slot;
  c.build_id = info.build_id;
  c.image_size = info.image_size;
  c.image_crc32 = info.image_crc32;
  return c;
}
}  // namespace

BootChoice chooseBoot(hal::FlashPages& flash, const UpdateLayout& layout) {
  BootChoice c;
  BootRecord rec;
  const bool have_record = readNewestBootRecord(flash, layout, rec) >= 0;
  const uint8_t first = have_record ? rec.slot : 0;
  c.record_sequence = have_record ? rec.sequence : 0;
  for (uint8_t k = 0; k < 2; ++k) {
    const auto slot = static_cast<uint8_t>(k == 0 ? first : 1u - first);
    image::ImageInfo info;
    if (!verifySlot(flash, layout, slot, &info)) continue;
    c = bootOf(slot, info);
    c.record_sequence = have_record ? rec.sequence : 0;
    c.fell_back = have_record && slot != rec.slot;
    return c;
  }
  return c;
}

namespace {
BootRecord recordFor(const BootChoice& c, BootState state) {
  BootRecord r;
  r.slot = c.slot;
  r.state = state;
  r.image_size = c.image_size;
  r.image_crc32 = c.image_crc32;
  r.build_id = c.build_id;
  return r;
}
}  // namespace

BootChoice bootStage(hal::FlashPages& flash, const UpdateLayout& layout) {
  BootChoice c = chooseBoot(flash, layout);
  BootRecord rec;
  if (!c.valid || c.fell_back || readNewestBootRecord(flash, layout, rec) < 0) return c;
  if (rec.state == BootState::kTrial) {
    // Booting the trial: say so first. A board that cannot record it boots the image it can go back to.
    if (writeBootRecord(flash, layout, recordFor(c, BootState::kTrialBooted))) {
      c.trial = true;
      return c;
    }
    rec.state = BootState::kTrialBooted;  // as if the trial had been used up
  }
  if (rec.state == BootState::kTrialBooted) {
    // The trial image ran, and the board reset without its confirm: back to the other slot's image, confirmed.
    image::ImageInfo info;
    const auto other = static_cast<uint8_t>(1u - c.slot);
    if (verifySlot(flash, layout, other, &info)) {
      BootChoice back = bootOf(other, info);
      back.trial_failed = true;
      if (writeBootRecord(flash, layout, recordFor(back, BootState::kConfirmed))) {
        back.record_sequence = rec.sequence + 1u;
      } else {
        back.record_sequence = rec.sequence;  // the next reset decides the same again
      }
      return back;
    }
    c.trial = true;  // nothing to go back to: the trial image runs (still unconfirmed)
  }
  return c;
}

bool writeBootRecord(hal::FlashPages& flash, const UpdateLayout& layout, BootRecord rec) {
  BootRecord newest;
  const int at = readNewestBootRecord(flash, layout, newest);
  rec.sequence = at < 0 ? 1u : newest.sequence + 1u;
  const size_t page = layout.record_first_page + static_cast<size_t>(at == 0 ? 1 : 0);
  uint8_t buf[kBootRecordBytes], check[kBootRecordBytes];
  encodeBootRecord(rec, buf);
  return flash.erase(page) && flash.program(page, 0, buf, sizeof buf) && flash.read(page, 0, check, sizeof check) &&
         std::memcmp(buf, check, sizeof buf) == 0;
}

bool FirmwareUpdate::confirm() {
  if (!running_.trial) return true;
  if (!writeBootRecord(flash_, layout_, recordFor(running_, BootState::kConfirmed))) return false;
  running_.trial = false;
  return true;
}

UpdateStatus FirmwareUpdate::status(MsgId answers, UpdateResult r, uint8_t detail) const {
  UpdateStatus s;
  s.answers = answers;
  s.result = r;
  s.detail = detail;
  s.slot = targetSlot();
  s.next_offset = state_ == State::kIdle ? 0u : received_;
  s.value = running_.build_id;
  return s;
}

UpdateStatus FirmwareUpdate::fail(MsgId answers, UpdateResult r) {
  state_ = State::kIdle;
  received_ = 0;
  pages_erased_ = 0;
  return status(answers, r);
}

UpdateStatus FirmwareUpdate::begin(const protocol::UpdateBegin& m, uint32_t open_session_id) {
  auto bad = [&](UpdateImageField f) { return status(MsgId::kUpdateBegin, UpdateResult::kBadImage, static_cast<uint8_t>(f)); };
  if (state_ == State::kCommitted) return status(MsgId::kUpdateBegin, UpdateResult::kCommitted);
  // The other slot holds the image a failed trial goes back to: not overwritten before this one is confirmed.
  if (running_.trial) return status(MsgId::kUpdateBegin, UpdateResult::kUnconfirmed);
  if (m.reserved != 0) return bad(UpdateImageField::kReserved);
  if (m.session_id != 0 && m.session_id != open_session_id) return bad(UpdateImageField::kSession);
  if (m.device_type != layout_.device_type) return bad(UpdateImageField::kDeviceType);
  if (m.board != layout_.board) return bad(UpdateImageField::kBoard);
  if (m.image_size < image::kImageInfoOffset + sizeof(image::ImageInfo) || m.image_size > slotBytes()) {
    return bad(UpdateImageField::kSize);
  }
  if (m.build_id == 0) return bad(UpdateImageField::kBuildId);
  const bool same = state_ == State::kReceiving && m.image_size == image_.image_size &&
                    m.image_crc32 == image_.image_crc32 && m.build_id == image_.build_id;
  if (!same) {  // a new update: from the first byte (pages are erased as the chunks reach them)
    image_ = m;
    received_ = 0;
    pages_erased_ = 0;
    state_ = State::kReceiving;
  }
  return status(MsgId::kUpdateBegin, UpdateResult::kOk);
}

bool FirmwareUpdate::erasePagesThrough(uint32_t last) {
  const size_t page_size = flash_.pageSize();
  const size_t need = last / page_size + 1;
  while (pages_erased_ < need && pages_erased_ < layout_.slot_pages) {
    if (!flash_.erase(layout_.slot_first_page[targetSlot()] + pages_erased_)) return false;
    ++pages_erased_;
  }
  return pages_erased_ >= need;
}

UpdateStatus FirmwareUpdate::data(const protocol::UpdateData& m) {
  if (state_ != State::kReceiving) return status(MsgId::kUpdateData, UpdateResult::kNotStarted);
  const uint32_t end = m.offset + m.length;
  const bool last = end == image_.image_size;
  bool padding_clear = m.reserved[0] == 0 && m.reserved[1] == 0 && m.reserved[2] == 0;
  for (size_t i = m.length; i < protocol::kUpdateChunkBytes && padding_clear; ++i) padding_clear = m.data[i] == 0;
  if (m.length == 0 || m.length > protocol::kUpdateChunkBytes || m.offset % hal::kFlashProgramUnit != 0 ||
      end > image_.image_size || end < m.offset || (!last && m.length % hal::kFlashProgramUnit != 0) || !padding_clear) {
    return status(MsgId::kUpdateData, UpdateResult::kBadChunk);
  }
  if (m.offset > received_) return status(MsgId::kUpdateData, UpdateResult::kOutOfOrder);
  if (end <= received_) return status(MsgId::kUpdateData, UpdateResult::kOk);  // a repeat: already programmed
  if (m.offset != received_) return status(MsgId::kUpdateData, UpdateResult::kBadChunk);  // overlaps: not a chunk we sent
  // Program whole units; the last chunk's tail unit is padded with the erased value.
  uint8_t buf[protocol::kUpdateChunkBytes];
  std::memset(buf, 0xFF, sizeof buf);
  std::memcpy(buf, m.data, m.length);
  const size_t n = (m.length + hal::kFlashProgramUnit - 1) / hal::kFlashProgramUnit * hal::kFlashProgramUnit;
  const size_t page_size = flash_.pageSize();
  if (!erasePagesThrough(static_cast<uint32_t>(m.offset + n - 1))) return fail(MsgId::kUpdateData, UpdateResult::kFlashError);
  // A chunk may straddle two pages (48-byte chunks, 2 KiB pages: it does not, but the layout does not promise it).
  for (size_t done = 0; done < n;) {
    const size_t at = m.offset + done, page = at / page_size, offset = at % page_size;
    const size_t take = n - done < page_size - offset ? n - done : page_size - offset;
    uint8_t check[protocol::kUpdateChunkBytes];
    const size_t fp = layout_.slot_first_page[targetSlot()] + page;
    if (!flash_.program(fp, offset, buf + done, take) || !flash_.read(fp, offset, check, take) ||
        std::memcmp(check, buf + done, take) != 0) {
      return fail(MsgId::kUpdateData, UpdateResult::kFlashError);
    }
    done += take;
  }
  received_ = end;
  return status(MsgId::kUpdateData, UpdateResult::kOk);
}

UpdateStatus FirmwareUpdate::commit(const protocol::UpdateCommit& m) {
  if (state_ == State::kCommitted) return status(MsgId::kUpdateCommit, UpdateResult::kCommitted);
  if (state_ != State::kReceiving || received_ != image_.image_size || m.image_crc32 != image_.image_crc32 ||
      m.build_id != image_.build_id) {
    return status(MsgId::kUpdateCommit, UpdateResult::kNotStarted);
  }
  image::ImageInfo info;
  if (!verifySlot(flash_, layout_, targetSlot(), &info) || info.image_size != image_.image_size ||
      info.image_crc32 != image_.image_crc32 || info.build_id != image_.build_id) {
    return fail(MsgId::kUpdateCommit, UpdateResult::kVerifyFailed);
  }
  BootRecord rec;
  rec.slot = targetSlot();
  rec.state = BootState::kTrial;
  rec.image_size = info.image_size;
  rec.image_crc32 = info.image_crc32;
  rec.build_id = info.build_id;
  if (!writeBootRecord(flash_, layout_, rec)) return fail(MsgId::kUpdateCommit, UpdateResult::kFlashError);
  state_ = State::kCommitted;
  UpdateStatus s = status(MsgId::kUpdateCommit, UpdateResult::kCommitted);
  s.value = info.build_id;
  return s;
}

}  // namespace phalanx::fw
