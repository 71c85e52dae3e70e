#pragma once
/// A contiguous range of the STM32G474's flash pages as hal::FlashPages (the settings store's and the firmware
/// update's view of flash), over the register sequences of stm32g4_flash.h. Pages are numbered over both banks
/// in dual-bank mode (0..127 bank 1, 128..255 bank 2, 2 KiB each, contiguous from 0x0800'0000), so a range may
/// straddle the banks. Every erase or program unlocks FLASH_CR and locks it again before returning, failed or not;
/// a begun one (beginErase/beginProgram) keeps it unlocked until the poll() that sees it end, or the begin that fails.
#include <cstddef>
#include <cstdint>

#include "phalanx/hal/flash.h"
#include "stm32g4_flash.h"

namespace phalanx::mcu::stm32g4 {

static_assert(hal::kFlashProgramUnit == 8, "the G4 programs 64-bit double words");

template <class Bus>
class Stm32g4FlashPages final : public hal::FlashPages {
 public:
  /// Pages first_page .. first_page + count - 1 (global numbering). A range reaching past page 255 is cut
  /// at the end of the memory (pageCount() tells what is left).
  Stm32g4FlashPages(Bus& bus, uint32_t first_page, uint32_t count, uint32_t busy_wait_bound = flash::kBusyWaitBound)
      : bus_(bus),
        flash_(bus, busy_wait_bound),
        first_(first_page < flash::kPageCount ? first_page : flash::kPageCount),
        count_(count < flash::kPageCount - first_ ? count : flash::kPageCount - first_) {}

  size_t pageCount() const override { return count_; }
  size_t pageSize() const override { return flash::kPageBytes; }

  /// Memory-mapped reads (no register access: reading needs no unlock). Refused while a begun operation still
  /// runs: a read of the bank being written stalls the CPU until the operation ends (RM0440 §3.3.1), for an
  /// erase longer than the board's watchdog allows. (One that has ended is left for its owner's poll().)
  bool read(size_t page, size_t offset, uint8_t* data, size_t n) override {
    if (!inRange(page, offset, n) || (pending_ != Pending::kNone && flash_.busy())) return false;
    const uint32_t a = address(page, offset);
    for (size_t i = 0; i < n; ++i) data[i] = bus_.readFlash8(a + static_cast<uint32_t>(i));
    return true;
  }

  bool erase(size_t page) override {
    if (!settled()) return fail(FlashResult::kBusy);
    if (page >= count_) return fail(FlashResult::kBadArgument);
    const uint32_t global = first_ + static_cast<uint32_t>(page);
    FlashResult r = flash_.unlock();
    if (r == FlashResult::kSuccess) r = flash_.erasePage(flash::bankOf(global), flash::pageInBank(global));
    flash_.lock();
    return done(r);
  }

  /// Refuses (programs nothing) when any double word of the span is not erased — a second program of one double
  /// word between erases is what FlashPages forbids; the hardware would allow it for all-zero data only (PROGERR
  /// otherwise). A failure mid-span leaves the double words before it programmed, as FlashPages allows.
  bool program(size_t page, size_t offset, const uint8_t* data, size_t n) override {
    if (!settled()) return fail(FlashResult::kBusy);
    if (!inRange(page, offset, n) || offset % hal::kFlashProgramUnit != 0 || n % hal::kFlashProgramUnit != 0) {
      return fail(FlashResult::kBadArgument);
    }
    const uint32_t a = address(page, offset);
    for (size_t i = 0; i < n; ++i) {
      if (bus_.readFlash8(a + static_cast<uint32_t>(i)) != 0xFFu) return fail(FlashResult::kProgramError);
    }
    FlashResult r = flash_.unlock();
    for (size_t i = 0; i < n && r == FlashResult::kSuccess; i += hal::kFlashProgramUnit) {
      r = flash_.programDoubleWord(a + static_cast<uint32_t>(i), le32(data + i), le32(data + i + 4));
    }
    flash_.lock();
    return done(r);
  }

  /// Starts the page's erase and returns (kBusy); poll() once per tick until it ends (22 ms typical, DS12288).
  hal::FlashOp beginErase(size_t page) override {
    if (!settled()) return failOp(FlashResult::kBusy);
    if (page >= count_) return failOp(FlashResult::kBadArgument);
    const uint32_t global = first_ + static_cast<uint32_t>(page);
    FlashResult r = flash_.unlock();
    if (r == FlashResult::kSuccess) r = flash_.beginErasePage(flash::bankOf(global), flash::pageInBank(global));
    return started(r, Pending::kErase);
  }

  /// Starts programming one double word (82 µs typical, DS12288); refused, as program(), when it is not erased.
  hal::FlashOp beginProgram(size_t page, size_t offset, const uint8_t* unit) override {
    if (!settled()) return failOp(FlashResult::kBusy);
    if (!inRange(page, offset, hal::kFlashProgramUnit) || offset % hal::kFlashProgramUnit != 0) {
      return failOp(FlashResult::kBadArgument);
    }
    const uint32_t a = address(page, offset);
    for (uint32_t i = 0; i < hal::kFlashProgramUnit; ++i) {
      if (bus_.readFlash8(a + i) != 0xFFu) return failOp(FlashResult::kProgramError);
    }
    FlashResult r = flash_.unlock();
    if (r == FlashResult::kSuccess) r = flash_.beginProgramDoubleWord(a, le32(unit), le32(unit + 4));
    return started(r, Pending::kProgram);
  }

  /// One FLASH_SR read: kBusy while BSY is set; then the operation's result, with PER/PG cleared and FLASH_CR
  /// locked again.
  hal::FlashOp poll() override {
    if (pending_ == Pending::kNone) return hal::FlashOp::kDone;
    if (flash_.busy()) return hal::FlashOp::kBusy;
    const FlashResult r = pending_ == Pending::kErase ? flash_.finishErase() : flash_.finishProgram();
    pending_ = Pending::kNone;
    flash_.lock();
    return done(r) ? hal::FlashOp::kDone : hal::FlashOp::kFailed;
  }
  /// An operation begun and not yet seen ended by poll().
  bool operationPending() const { return pending_ != Pending::kNone; }

  /// Why the last erase or program failed (kSuccess after one that did not).
  FlashResult lastResult() const { return last_; }
  /// FLASH_SR at the end of the last operation the peripheral ran.
  uint32_t lastStatus() const { return flash_.lastStatus(); }

 private:
  bool inRange(size_t page, size_t offset, size_t n) const {
    return page < count_ && offset <= flash::kPageBytes && n <= flash::kPageBytes - offset;
  }
  uint32_t address(size_t page, size_t offset) const {
    return flash::pageAddress(first_ + static_cast<uint32_t>(page)) + static_cast<uint32_t>(offset);
  }
  static uint32_t le32(const uint8_t* p) {
    return static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 | static_cast<uint32_t>(p[2]) << 16 |
           static_cast<uint32_t>(p[3]) << 24;
  }
  bool fail(FlashResult r) {
    last_ = r;
    return false;
  }
  bool done(FlashResult r) {
    last_ = r;
    return r == FlashResult::kSuccess;
  }

  enum class Pending : uint8_t { kNone, kErase, kProgram };
  /// No operation pending, or the one begun has ended since (one poll: a caller that gave up on an operation,
  /// as the settings store does after its busy bound, does not block the next one for good). false: still busy.
  bool settled() { return pending_ == Pending::kNone || poll() != hal::FlashOp::kBusy; }
  hal::FlashOp failOp(FlashResult r) {
    last_ = r;
    return hal::FlashOp::kFailed;
  }
  /// After a begin: pending when it started, else FLASH_CR locked again and the refusal kept.
  hal::FlashOp started(FlashResult r, Pending what) {
    last_ = r;
    if (r != FlashResult::kSuccess) {
      flash_.lock();
      return hal::FlashOp::kFailed;
    }
    pending_ = what;
    return hal::FlashOp::kBusy;
  }

  Bus& bus_;
  Stm32g4Flash<Bus> flash_;
  Pending pending_ = Pending::kNone;
  uint32_t first_;
  uint32_t count_;
  FlashResult last_ = FlashResult::kSuccess;
};

}  // namespace phalanx::mcu::stm32g4
