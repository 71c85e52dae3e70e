#pragma once
/// The image-info block every MCU firmware image carries (docs/firmware-mcu.md "Flashing"): what the image is
/// (device app, board, build id) and how to check it (its size and CRC-32), at a fixed offset from the start of the
/// image so that `phalanx flash` can check an image file before anything is written to a board.
/// The firmware defines the block (firmware/mcu/src/image_info.cpp, section .image_info, placed by
/// firmware/boards/phalanx-sections.ld at kImageInfoOffset); the size and the CRC are filled in after the link by
/// firmware/mcu/cmake/image_info.py, which writes the .bin/.hex the ELF now contains. Freestanding (no heap, no OS).
#include <cstddef>
#include <cstdint>

#include "phalanx/protocol/messages.h"

namespace phalanx::image {

constexpr uint32_t kImageInfoMagic = 0x49584850u;  ///< "PHXI" read as little-endian bytes
constexpr uint16_t kImageInfoLayoutVersion = 1;    ///< bump when a field moves or changes meaning
/// Offset of the block from the image's first byte (its load address). The vector table comes first (the core
/// reads it at reset) and must fit below: 472 bytes on the STM32G474 (16 + 102 entries), 192 on the emulated boards.
constexpr uint32_t kImageInfoOffset = 0x200;

/// Board the image was linked for. Explicit values: they are stored in images.
enum class BoardId : uint8_t {
  kUnknown = 0,
  kStm32g474 = 1,  ///< the project's motor board (STM32G474, 512 KiB flash at 0x0800_0000)
  kMps2An386 = 2,  ///< QEMU mps2-an386 (code in ZBT SSRAM1, 4 MiB at 0)
  kAst1030 = 3,    ///< QEMU ast1030-evb (code in the first 512 KiB of its SRAM at 0)
};

/// All fields little-endian (every supported core is); 32 bytes.
struct ImageInfo {
  uint32_t magic = kImageInfoMagic;
  uint16_t layout_version = kImageInfoLayoutVersion;
  uint16_t info_size = 32;      ///< sizeof(ImageInfo) for this layout version
  uint8_t device_type = 0;      ///< protocol::DeviceType of the image's device app
  uint8_t board = 0;            ///< BoardId
  uint16_t reserved0 = 0;
  uint32_t build_id = 0;        ///< the HelloAck's firmware_build_id (git hash the firmware was built from)
  uint32_t load_address = 0;    ///< where the image's first byte goes: the part's flash (code memory) origin
  uint32_t image_size = 0;      ///< bytes of the image file from load_address (filled after the link)
  uint32_t image_crc32 = 0;     ///< CRC-32 (IEEE 802.3, zlib's) of those bytes with this field read as 0 (after link)
  uint32_t reserved1 = 0;
};
static_assert(sizeof(ImageInfo) == 32, "image-info layout 1 is 32 bytes");
static_assert(offsetof(ImageInfo, device_type) == 8 && offsetof(ImageInfo, build_id) == 12 &&
                  offsetof(ImageInfo, load_address) == 16 && offsetof(ImageInfo, image_size) == 20 &&
                  offsetof(ImageInfo, image_crc32) == 24,
              "image-info field offsets are part of the stored layout");

/// A board's code memory: where images go and how much there is.
struct BoardPart {
  BoardId id;
  const char* name;          ///< the board's name in the build (PHALANX_MCU_BOARD) and in `phalanx flash --board`
  uint32_t flash_origin;     ///< first byte of the code memory (the image's load address)
  uint32_t flash_size;       ///< bytes of it
};

constexpr BoardPart kBoardParts[] = {
    {BoardId::kStm32g474, "stm32g474", 0x08000000u, 512u * 1024u},  // RM0440 §2.2, DS12288 (xE parts)
    {BoardId::kMps2An386, "mps2_an386", 0x00000000u, 4u * 1024u * 1024u},
    {BoardId::kAst1030, "ast1030", 0x00000000u, 512u * 1024u},  // firmware/boards/ast1030/ast1030.ld FLASH
};

/// The part of a board id, or nullptr.
constexpr const BoardPart* boardPart(BoardId id) {
  for (const BoardPart& p : kBoardParts) {
    if (p.id == id) return &p;
  }
  return nullptr;
}

/// The UpdateBegin that announces an image with this block (docs/firmware-update.md).
constexpr protocol::UpdateBegin updateBeginFor(const ImageInfo& info) {
  protocol::UpdateBegin b{};
  b.image_size = info.image_size;
  b.image_crc32 = info.image_crc32;
  b.build_id = info.build_id;
  b.device_type = info.device_type;
  b.board = info.board;
  return b;
}

}  // namespace phalanx::image
