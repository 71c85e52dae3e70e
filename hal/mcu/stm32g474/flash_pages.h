#pragma once
/// The G474 board's internal flash as hal::FlashPages: the register bus of stm32g4_flash.h on the real
/// peripheral (volatile accesses through regs.h's reg()) and the page range the board sets aside. The image's
/// settings store (firmware/boards/stm32g474/main.cpp) runs on it, one step per tick; the firmware update does not
/// yet. Never run on silicon.
#include <cstdint>

#include "phalanx/mcu/stm32g4_flash_pages.h"
#include "regs.h"

namespace phalanx::mcu::g474 {

/// Volatile accesses to the FLASH registers and the memory-mapped flash. The two stores of a double word must be
/// two separate 32-bit stores in this order (RM0440 §3.3.7): volatile keeps the compiler from merging them into
/// one 64-bit store (STRD) or reordering them.
struct MmioFlashBus {
  uint32_t read32(uint32_t address) { return reg(address); }
  void write32(uint32_t address, uint32_t value) { reg(address) = value; }
  void writeFlash32(uint32_t address, uint32_t value) { reg(address) = value; }
  uint8_t readFlash8(uint32_t address) { return *reinterpret_cast<const volatile uint8_t*>(address); }
};

/// Board choice: the last two pages of bank 2 (global pages 254 and 255, 0x0807'F000..0x0807'FFFF) for the
/// settings store's two slots, so that programming them never stalls instruction fetches from bank 1, where the
/// image lives (read-while-write between banks, RM0440 §3.3.1); the linker script must keep the image below.
constexpr uint32_t kSettingsFirstPage = stm32g4::flash::kPageCount - 2;
constexpr uint32_t kSettingsPages = 2;
// The firmware update's layout (docs/firmware-update.md, firmware-sim's CodeFlash): slot 0 pages 0-119 (the
// linker script's FLASH), boot record 120-121, slot 1 128-247. The settings pages lie beyond all of them, in bank 2.
constexpr uint32_t kUpdateSlot1LastPage = 247;
static_assert(kSettingsFirstPage > kUpdateSlot1LastPage && kSettingsFirstPage >= stm32g4::flash::kPagesPerBank,
              "the settings pages must be in bank 2, outside the firmware update's slots");

/// FLASH_ECCR (RM0440 §3.7.7; bit positions as the part's SVD): ECCD is set, and the NMI raised, when a read
/// meets a double-bit ECC error — what a page whose erase or programming a reset cut short may hold. BK_ECC names
/// the bank, SYSF_ECC system memory. ECCD and ECCC are cleared by writing 1.
namespace eccr {
constexpr uint32_t kAddress = stm32g4::flash::kBase + 0x18u;
constexpr uint32_t kBkEcc = 1u << 21, kSysfEcc = 1u << 22, kEccc = 1u << 30, kEccd = 1u << 31;
}  // namespace eccr

/// Whether an NMI with this FLASH_ECCR is a settings page read (the store's load or read-back) meeting a torn
/// double word. Decided by the bank alone: the image (bank 1) reads nothing of bank 2 but the settings pages.
/// Such a read returns garbage that fails the record's CRC, so the store falls back to the other slot.
constexpr bool isSettingsEccError(uint32_t eccr_value) {
  return (eccr_value & eccr::kEccd) != 0 && (eccr_value & eccr::kBkEcc) != 0 && (eccr_value & eccr::kSysfEcc) == 0;
}

/// From the NMI handler: true (ECCD cleared, the handler may return) when the NMI is a settings page's ECC error.
inline bool takeSettingsEccError() {
  const uint32_t v = reg(eccr::kAddress);
  if (!isSettingsEccError(v)) return false;
  reg(eccr::kAddress) = v;  // writes 1 to the flags that are set (ECCD, and ECCC if set); ECCCIE unchanged
  return true;
}

using FlashPages = stm32g4::Stm32g4FlashPages<MmioFlashBus>;

}  // namespace phalanx::mcu::g474
