// libFuzzer target: arbitrary bytes as a sequence of firmware update requests (docs/firmware-update.md), power
// cuts, resets (the boot stage, trial boot included) and confirms, against a board whose slot 0 holds a valid
// image. Whatever arrives: no crash or out-of-bounds access, the slot the board runs from is never written, and
// after every request and every cut the boot stage finds a valid image (the running one, or one that verified at
// a commit).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "phalanx/fw/crc32.h"
#include "phalanx/fw/firmware_update.h"
#include "phalanx/protocol/codec.h"
#include "phalanx/sim/sim_flash.h"

using namespace phalanx;

namespace {

constexpr size_t kPages = 10, kPageSize = 512;  // slot 0 pages 0-3, records 4-5, slot 1 pages 6-9

fw::UpdateLayout layout() {
  fw::UpdateLayout l;
  l.slot_first_page[1] = 6;
  l.slot_pages = 4;
  l.record_first_page = 4;
  l.board = 1;
  l.device_type = 1;
  return l;
}

/// A valid 1 KiB image in slot 0 and a record naming it.
void provision(sim::RamFlash& f) {
  std::vector<uint8_t> img(1024);
  for (size_t i = 0; i < img.size(); ++i) img[i] = static_cast<uint8_t>(i * 31u + 7u);
  const uint32_t words[] = {image::kImageInfoMagic, 1u | (32u << 16), 1u | (1u << 8), 0x1234u, 0x08000000u, 1024u, 0u, 0u};
  std::memcpy(&img[image::kImageInfoOffset], words, sizeof words);
  const uint32_t crc = fw::crc32(img.data(), img.size());
  std::memcpy(&img[image::kImageInfoOffset + 24], &crc, 4);
  for (size_t p = 0; p < 2; ++p) {
    f.erase(p);
    f.program(p, 0, &img[p * kPageSize], kPageSize);
  }
  fw::BootRecord rec;
  fw::writeBootRecord(f, layout(), rec);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  sim::RamFlash flash(kPages, kPageSize);
  provision(flash);
  fw::BootChoice boot = fw::chooseBoot(flash, layout());
  if (!boot.valid) std::abort();
  auto* u = new fw::FirmwareUpdate(flash, layout(), boot);
  std::vector<uint8_t> running(kPages * kPageSize);
  auto snapshot = [&]() {
    const size_t first = layout().slot_first_page[boot.slot];
    std::memcpy(running.data(), &flash.bytes()[first * kPageSize], layout().slot_pages * kPageSize);
  };
  snapshot();
  // Each request: 1 byte kind, then its payload's bytes (as many as the kind takes).
  size_t at = 0;
  while (at < size) {
    const uint8_t kind = data[at++] % 6;
    uint8_t payload[protocol::kMaxPayload] = {};
    const size_t want = kind == 0 ? protocol::UpdateBegin::kWireSize
                        : kind == 1 ? protocol::UpdateData::kWireSize
                        : kind == 2 ? protocol::UpdateCommit::kWireSize
                                    : 2;
    const size_t n = size - at < want ? size - at : want;
    std::memcpy(payload, data + at, n);
    at += n;
    if (kind == 0) {
      protocol::UpdateBegin m;
      if (protocol::decodePayload(payload, want, m)) u->begin(m, 0);
    } else if (kind == 1) {
      protocol::UpdateData m;
      if (protocol::decodePayload(payload, want, m)) u->data(m);
    } else if (kind == 2) {
      protocol::UpdateCommit m;
      if (protocol::decodePayload(payload, want, m)) u->commit(m);
    } else if (kind == 3) {
      flash.cutPowerAfter(static_cast<size_t>(payload[0] | payload[1] << 8));
    } else if (kind == 5) {
      u->confirm();  // the running image confirms itself (trial boot)
    }
    if (kind == 4 || u->rebootRequested()) {  // a reset (asked for, or after a commit): the boot stage chooses again
      flash.restorePower();
      boot = fw::bootStage(flash, layout());
      if (!boot.valid) std::abort();
      delete u;
      u = new fw::FirmwareUpdate(flash, layout(), boot);
      snapshot();
      continue;
    }
    // The running slot untouched; the board would boot a valid image if reset now.
    const size_t first = layout().slot_first_page[boot.slot];
    if (std::memcmp(running.data(), &flash.bytes()[first * kPageSize], layout().slot_pages * kPageSize) != 0) std::abort();
    if (!fw::chooseBoot(flash, layout()).valid) std::abort();
  }
  delete u;
  return 0;
}
