#pragma once
/// Non-volatile storage as the MCUs' internal flash behaves: fixed-size pages, an erase sets a whole page to 0xFF,
/// a program can only clear bits (1 → 0) of erased bytes, in units of kFlashProgramUnit bytes (the STM32G4 programs
/// 64-bit double words, each once between erases: its ECC forbids a second write). The settings store (firmware/core settings_store.h) is
/// written against this; hal/sim holds a RAM one for tests and a file-backed one for firmware-sim (a restart of
/// firmware-sim is then a power cycle). Not on the tick's hot path: a virtual interface.
///
/// Two ways to erase and program. erase()/program() return when the operation has ended: fine where it ends at
/// once (RAM, a file) or where the caller may wait. beginErase()/beginProgram() + poll() start one operation and
/// return, so that a 1 kHz tick can run a page erase that lasts tens of milliseconds on an MCU (the STM32G474's
/// 2 KiB page: 22 ms typical, DS12288) one poll per tick, with its watchdog refreshed in between. The defaults
/// below run the blocking call and report it finished, so a flash that completes at once needs nothing more.
#include <cstddef>
#include <cstdint>

namespace phalanx::hal {

constexpr size_t kFlashProgramUnit = 8;

/// State of a started (non-blocking) operation.
enum class FlashOp : uint8_t {
  kDone = 0,    ///< finished, successfully
  kBusy = 1,    ///< still running: poll() again later (nothing else may be started meanwhile)
  kFailed = 2,  ///< refused, or ended with an error (as erase()/program() returning false)
};

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

  /// Starts erasing `page`. kBusy: poll() until it is no longer kBusy; kDone/kFailed: it has already ended.
  virtual FlashOp beginErase(size_t page) { return erase(page) ? FlashOp::kDone : FlashOp::kFailed; }
  /// Starts programming one unit (kFlashProgramUnit bytes of `unit`) at `offset`, with program()'s rules.
  virtual FlashOp beginProgram(size_t page, size_t offset, const uint8_t* unit) {
    return program(page, offset, unit, kFlashProgramUnit) ? FlashOp::kDone : FlashOp::kFailed;
  }
  /// The operation begun last: kBusy while it runs, then how it ended. Never waits. Without one pending: kDone.
  virtual FlashOp poll() { return FlashOp::kDone; }
};

}  // namespace phalanx::hal
