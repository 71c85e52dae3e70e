#pragma once
/// Non-volatile storage as the MCUs' internal flash behaves: fixed-size pages, an erase sets a whole page to 0xFF,
/// a program can only clear bits (1 → 0) of erased bytes, in units of kFlashProgramUnit bytes (the STM32G4 programs
/// 64-bit double words, each once between erases: its ECC forbids a second write). The settings store (firmware/core settings_store.h) is
/// written against this; hal/sim holds a RAM one for tests and a file-backed one for firmware-sim (a restart of
/// firmware-sim is then a power cycle). Not on the tick's hot path: a virtual interface.
#include <cstddef>
#include <cstdint>

namespace phalanx::hal {

constexpr size_t kFlashProgramUnit = 8;

class FlashPages {
 public:
  virtual ~FlashPages() = default;
  virtual size_t pageCount() const = 0;
  virtual size_t pageSize() const = 0;
  /// false: page/offset/n out of range or the medium failed.
  virtual bool read(size_t page, size_t offset, uint8_t* data, size_t n) = 0;
  virtual bool erase(size_t page) = 0;
  /// Writes data into erased units of the page; offset and n are multiples of kFlashProgramUnit. false: out of
  /// range, misaligned, a unit already programmed since its erase, or the medium failed (then the page may hold
  /// part of the data: a power loss mid-write looks the same).
  virtual bool program(size_t page, size_t offset, const uint8_t* data, size_t n) = 0;
};

}  // namespace phalanx::hal
