#pragma once
/// The G474 board's internal flash as hal::FlashPages: the register bus of stm32g4_flash.h on the real
/// peripheral (volatile accesses through regs.h's reg()) and the page range the board sets aside. Not used by any
/// image yet (the settings store and the firmware update will take it); never run on silicon.
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

using FlashPages = stm32g4::Stm32g4FlashPages<MmioFlashBus>;

}  // namespace phalanx::mcu::g474
