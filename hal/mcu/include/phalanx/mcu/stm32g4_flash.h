#pragma once
/// STM32G474 embedded flash: unlock, page erase and double-word programming of the main memory, following RM0440
/// rev 8 §3 (Embedded flash memory): §3.3.5 unlock (FLASH_KEYR), §3.3.6 page erase, §3.3.7 standard programming
/// and its programming errors, §3.7.5–§3.7.6 FLASH_SR / FLASH_CR bit descriptions, §3.7.8 FLASH_OPTR.DBANK. The
/// part: 512 KiB (STM32G474xE) in its default dual-bank mode (DBANK = 1): two banks of 128 pages of 2 KiB, bank 1
/// at 0x0800'0000, bank 2 at 0x0804'0000 (§3.3.1). Single-bank mode (4 KiB pages) is refused, not driven.
///
/// Written against a register bus `Bus` so the same sequence drives the peripheral (volatile accesses,
/// hal/mcu/stm32g474/flash_pages.h) and a host model (tests/unit/mcu_stm32g4_flash_test.cpp):
///   uint32_t read32(uint32_t address);                 // FLASH register at an absolute address
///   void write32(uint32_t address, uint32_t value);    // FLASH register
///   void writeFlash32(uint32_t address, uint32_t v);   // one 32-bit store into the flash memory
///   uint8_t readFlash8(uint32_t address);              // one byte of the flash memory (memory-mapped read)
/// No heap, no exceptions, every wait bounded. Never run on silicon (docs/firmware-mcu.md "Internal flash driver").
#include <cstddef>
#include <cstdint>

namespace phalanx::mcu::stm32g4 {

namespace flash {
constexpr uint32_t kBase = 0x40022000u;  ///< FLASH registers (RM0440 Table 4)
// Register offsets (§3.7).
constexpr uint32_t kAcr = 0x00, kKeyr = 0x08, kSr = 0x10, kCr = 0x14, kOptr = 0x20;
// Unlock keys, written to FLASH_KEYR in this order (§3.3.5).
constexpr uint32_t kKey1 = 0x45670123u, kKey2 = 0xCDEF89ABu;
// FLASH_ACR caches (§3.7.1): a cache reset needs the cache disabled.
constexpr uint32_t kAcrIcen = 1u << 9, kAcrDcen = 1u << 10, kAcrIcrst = 1u << 11, kAcrDcrst = 1u << 12;
// FLASH_SR (§3.7.5). Every flag but BSY is cleared by writing 1.
constexpr uint32_t kSrEop = 1u << 0, kSrOperr = 1u << 1, kSrProgerr = 1u << 3, kSrWrperr = 1u << 4;
constexpr uint32_t kSrPgaerr = 1u << 5, kSrSizerr = 1u << 6, kSrPgserr = 1u << 7, kSrMisserr = 1u << 8;
constexpr uint32_t kSrFasterr = 1u << 9, kSrRderr = 1u << 14, kSrOptverr = 1u << 15, kSrBsy = 1u << 16;
constexpr uint32_t kSrErrors = kSrOperr | kSrProgerr | kSrWrperr | kSrPgaerr | kSrSizerr | kSrPgserr | kSrMisserr |
                               kSrFasterr | kSrRderr | kSrOptverr;
// FLASH_CR (§3.7.6).
constexpr uint32_t kCrPg = 1u << 0, kCrPer = 1u << 1, kCrMer1 = 1u << 2, kCrPnbShift = 3, kCrPnbMask = 0x7Fu << 3;
constexpr uint32_t kCrBker = 1u << 11, kCrMer2 = 1u << 15, kCrStrt = 1u << 16, kCrOptstrt = 1u << 17;
constexpr uint32_t kCrFstpg = 1u << 18, kCrEopie = 1u << 24, kCrErrie = 1u << 25, kCrOblLaunch = 1u << 27;
constexpr uint32_t kCrOptlock = 1u << 30, kCrLock = 1u << 31;
// FLASH_OPTR (§3.7.8): DBANK = 1 is dual-bank mode, the factory setting of the 512 KiB parts.
constexpr uint32_t kOptrDbank = 1u << 22;

// Main memory of the 512 KiB part in dual-bank mode (§3.3.1).
constexpr uint32_t kMemoryBase = 0x08000000u;
constexpr uint32_t kBank2Base = 0x08040000u;
constexpr uint32_t kMemoryBytes = 512u * 1024u;
constexpr uint32_t kPagesPerBank = 128;
constexpr uint32_t kPageBytes = 2048;  ///< dual-bank mode; 4 KiB in single-bank mode (not supported here)
constexpr uint32_t kPageCount = 2 * kPagesPerBank;
static_assert(kBank2Base - kMemoryBase == kPagesPerBank * kPageBytes, "bank 2 follows bank 1");
static_assert(kPageCount * kPageBytes == kMemoryBytes, "512 KiB");

/// Address of page `page` counted over both banks (0..255: bank 1 pages 0..127, then bank 2).
constexpr uint32_t pageAddress(uint32_t page) { return kMemoryBase + page * kPageBytes; }
/// Bank (1 or 2) and page within it of a global page number (FLASH_CR.BKER and PNB).
constexpr uint32_t bankOf(uint32_t page) { return page < kPagesPerBank ? 1u : 2u; }
constexpr uint32_t pageInBank(uint32_t page) { return page % kPagesPerBank; }

/// SR reads before a wait for BSY gives up. A page erase is tens of ms (DS12288 tERASE, not checked here); a
/// polling loop of SR reads takes at least a few cycles per read at 170 MHz, so 4 M reads last well beyond it.
/// (While the CPU fetches from the bank being written it stalls instead of polling: that does not use the bound.)
constexpr uint32_t kBusyWaitBound = 4000000u;
}  // namespace flash

/// Result of a flash operation. Errors the peripheral reports are 16 and up, one per FLASH_SR flag; the driver's
/// own refusals are below 16.
enum class FlashResult : uint8_t {
  kSuccess = 0,
  kBadArgument = 1,     ///< address/page outside the main memory, or misaligned: nothing written
  kLocked = 2,          ///< FLASH_CR still locked after the key sequence (a wrong sequence locks it until reset)
  kBusyTimeout = 3,     ///< BSY still set after kBusyWaitBound reads (before or during the operation)
  kSingleBank = 4,      ///< FLASH_OPTR.DBANK = 0: page geometry differs (4 KiB), refused
  kBusy = 5,            ///< begin*(): BSY already set (an operation still running): nothing started
  kProgramError = 16,   ///< PROGERR: the double word was not erased (and the data not all zero)
  kWriteProtected = 17, ///< WRPERR: page in a write-protected (WRP/PCROP/securable) area
  kAlignmentError = 18, ///< PGAERR: the two words not in one double word, or the double word incomplete
  kSizeError = 19,      ///< SIZERR: a byte or half-word store during programming
  kSequenceError = 20,  ///< PGSERR: a store without PG, PG and PER together, or a flag of an earlier error left set
  kOperationError = 21, ///< OPERR
  kFastError = 22,      ///< MISSERR or FASTERR (fast programming; not used by this driver)
  kReadError = 23,      ///< RDERR (PCROP read)
  kOptionError = 24,    ///< OPTVERR
};

/// The error a FLASH_SR value reports (kSuccess when none). Several flags at once: the most specific one, in the
/// order write protection, sequence, alignment, size, program, operation, the rest.
constexpr FlashResult flashErrorOf(uint32_t sr) {
  using namespace flash;
  if (sr & kSrWrperr) return FlashResult::kWriteProtected;
  if (sr & kSrPgserr) return FlashResult::kSequenceError;
  if (sr & kSrPgaerr) return FlashResult::kAlignmentError;
  if (sr & kSrSizerr) return FlashResult::kSizeError;
  if (sr & kSrProgerr) return FlashResult::kProgramError;
  if (sr & kSrOperr) return FlashResult::kOperationError;
  if (sr & (kSrMisserr | kSrFasterr)) return FlashResult::kFastError;
  if (sr & kSrRderr) return FlashResult::kReadError;
  if (sr & kSrOptverr) return FlashResult::kOptionError;
  return FlashResult::kSuccess;
}

/// "success", "bad-argument", …, "option-error" ("?" otherwise).
constexpr const char* flashResultName(FlashResult r) {
  switch (r) {
    case FlashResult::kSuccess: return "success";
    case FlashResult::kBadArgument: return "bad-argument";
    case FlashResult::kLocked: return "locked";
    case FlashResult::kBusyTimeout: return "busy-timeout";
    case FlashResult::kSingleBank: return "single-bank";
    case FlashResult::kBusy: return "busy";
    case FlashResult::kProgramError: return "program-error";
    case FlashResult::kWriteProtected: return "write-protected";
    case FlashResult::kAlignmentError: return "alignment-error";
    case FlashResult::kSizeError: return "size-error";
    case FlashResult::kSequenceError: return "sequence-error";
    case FlashResult::kOperationError: return "operation-error";
    case FlashResult::kFastError: return "fast-error";
    case FlashResult::kReadError: return "read-error";
    case FlashResult::kOptionError: return "option-error";
  }
  return "?";
}

/// The FLASH peripheral's sequences. Each operation expects FLASH_CR unlocked (unlock()); the adapter
/// (stm32g4_flash_pages.h) unlocks and re-locks around every one. Interrupts: the sequences do not disable them;
/// an ISR that touches FLASH_CR mid-sequence would break it (none does in this firmware).
template <class Bus>
class Stm32g4Flash {
 public:
  explicit Stm32g4Flash(Bus& bus, uint32_t busy_wait_bound = flash::kBusyWaitBound)
      : bus_(bus), bound_(busy_wait_bound) {}

  bool locked() { return (cr() & flash::kCrLock) != 0; }
  bool dualBank() { return (bus_.read32(flash::kBase + flash::kOptr) & flash::kOptrDbank) != 0; }

  /// §3.3.5: KEY1 then KEY2 into FLASH_KEYR. Writes no key when already unlocked (a second key sequence is a
  /// wrong sequence: it would lock FLASH_CR until reset and raise a bus error).
  FlashResult unlock() {
    if (!locked()) return FlashResult::kSuccess;
    bus_.write32(flash::kBase + flash::kKeyr, flash::kKey1);
    bus_.write32(flash::kBase + flash::kKeyr, flash::kKey2);
    return locked() ? FlashResult::kLocked : FlashResult::kSuccess;
  }

  /// Sets FLASH_CR.LOCK (and clears PG/PER in the same write, so nothing is left armed).
  void lock() { setCr((cr() & ~(flash::kCrPg | flash::kCrPer | flash::kCrStrt)) | flash::kCrLock); }

  /// §3.3.6 page erase: BSY clear, error flags cleared, PER + PNB + BKER, then STRT, wait for BSY, PER cleared.
  /// bank 1 or 2, page 0..127 within it. The caches are reset afterwards (they may hold the page's old contents).
  FlashResult erasePage(uint32_t bank, uint32_t page) {
    FlashResult r = checkErase(bank, page);
    if (r != FlashResult::kSuccess) return r;
    if (!waitNotBusy()) return FlashResult::kBusyTimeout;
    startErase(bank, page);
    r = waitNotBusy() ? takeResult() : FlashResult::kBusyTimeout;
    endErase();
    return r;
  }

  /// §3.3.7 standard programming of one double word at a double-word aligned address of the main memory: BSY
  /// clear, error flags cleared, PG set, the low word stored at address then the high word at address + 4 (the
  /// second store starts the programming), wait for BSY, PG cleared. lo is the word at the lower address.
  FlashResult programDoubleWord(uint32_t address, uint32_t lo, uint32_t hi) {
    FlashResult r = checkProgram(address);
    if (r != FlashResult::kSuccess) return r;
    if (!waitNotBusy()) return FlashResult::kBusyTimeout;
    startProgram(address, lo, hi);
    r = waitNotBusy() ? takeResult() : FlashResult::kBusyTimeout;
    endProgram();
    return r;
  }

  // The same two operations without the wait, for a caller that polls once per control tick (a page erase,
  // ~22 ms typical by DS12288, outlasts the board's 5 ms watchdog). begin*() checks, starts the operation and
  // returns; busy() reads FLASH_SR once; once it is false, finishErase()/finishProgram() decode the result and
  // disarm PER/PG. Meanwhile nothing else may touch FLASH_CR, and the code must not read the bank being written:
  // a read of that bank stalls until the operation ends (RM0440 §3.3.1: read-while-write holds between the two
  // banks only), which for an erase is several watchdog periods.

  /// As erasePage up to STRT. kBusy when FLASH_SR.BSY is already set (nothing started).
  FlashResult beginErasePage(uint32_t bank, uint32_t page) {
    const FlashResult r = checkErase(bank, page);
    if (r != FlashResult::kSuccess) return r;
    if (busy()) return FlashResult::kBusy;
    startErase(bank, page);
    return FlashResult::kSuccess;
  }
  /// As programDoubleWord up to the second store. kBusy when BSY is already set (nothing stored).
  FlashResult beginProgramDoubleWord(uint32_t address, uint32_t lo, uint32_t hi) {
    const FlashResult r = checkProgram(address);
    if (r != FlashResult::kSuccess) return r;
    if (busy()) return FlashResult::kBusy;
    startProgram(address, lo, hi);
    return FlashResult::kSuccess;
  }
  /// FLASH_SR.BSY now (one register read; lastStatus() keeps the value read).
  bool busy() {
    last_sr_ = bus_.read32(flash::kBase + flash::kSr);
    return (last_sr_ & flash::kSrBsy) != 0;
  }
  /// After busy() returned false: the erase's result; PER, PNB, BKER cleared and the caches reset.
  FlashResult finishErase() {
    const FlashResult r = takeResult();
    endErase();
    return r;
  }
  /// After busy() returned false: the double word's result; PG cleared.
  FlashResult finishProgram() {
    const FlashResult r = takeResult();
    endProgram();
    return r;
  }

  /// FLASH_SR as read at the end of the last erase or program (for diagnostics).
  uint32_t lastStatus() const { return last_sr_; }

 private:
  uint32_t cr() { return bus_.read32(flash::kBase + flash::kCr); }
  void setCr(uint32_t v) { bus_.write32(flash::kBase + flash::kCr, v); }
  /// Error flags and EOP are write-1-to-clear (§3.7.5): a flag left from an earlier operation would make the
  /// next one fail with PGSERR (FLASH_SR.PGSERR, §3.7.5).
  void clearFlags() { bus_.write32(flash::kBase + flash::kSr, flash::kSrErrors | flash::kSrEop); }
  bool waitNotBusy() {
    for (uint32_t i = 0; i < bound_; ++i) {
      last_sr_ = bus_.read32(flash::kBase + flash::kSr);
      if ((last_sr_ & flash::kSrBsy) == 0) return true;
    }
    return false;
  }
  FlashResult checkErase(uint32_t bank, uint32_t page) {
    if ((bank != 1 && bank != 2) || page >= flash::kPagesPerBank) return FlashResult::kBadArgument;
    return checkMode();
  }
  FlashResult checkProgram(uint32_t address) {
    using namespace flash;
    if (address % 8u != 0 || address < kMemoryBase || address - kMemoryBase >= kMemoryBytes) {
      return FlashResult::kBadArgument;
    }
    return checkMode();
  }
  FlashResult checkMode() {
    if (!dualBank()) return FlashResult::kSingleBank;
    return locked() ? FlashResult::kLocked : FlashResult::kSuccess;
  }
  /// With BSY clear: flags cleared, PER + PNB + BKER, then STRT (§3.3.6).
  void startErase(uint32_t bank, uint32_t page) {
    using namespace flash;
    clearFlags();
    uint32_t c = cr() & ~(kCrPg | kCrPer | kCrMer1 | kCrMer2 | kCrPnbMask | kCrBker | kCrStrt | kCrFstpg);
    c |= kCrPer | (page << kCrPnbShift) | (bank == 2 ? kCrBker : 0u);
    setCr(c);
    setCr(c | kCrStrt);
  }
  /// With BSY clear: flags cleared, PG, then the two word stores (§3.3.7).
  void startProgram(uint32_t address, uint32_t lo, uint32_t hi) {
    using namespace flash;
    clearFlags();
    const uint32_t c = cr() & ~(kCrPer | kCrMer1 | kCrMer2 | kCrStrt | kCrFstpg);
    setCr(c | kCrPg);
    bus_.writeFlash32(address, lo);
    bus_.writeFlash32(address + 4u, hi);
  }
  void endErase() {
    setCr(cr() & ~(flash::kCrPer | flash::kCrPnbMask | flash::kCrBker));
    resetCaches();
  }
  void endProgram() { setCr(cr() & ~flash::kCrPg); }
  /// Decodes the SR read that saw BSY clear. EOP is set only with EOPIE (§3.7.5), which this driver leaves off:
  /// success is BSY clear with no error flag. The flags are cleared for the next operation.
  FlashResult takeResult() {
    const FlashResult r = flashErrorOf(last_sr_);
    clearFlags();
    return r;
  }
  /// §3.3.4 (ART): a cache is reset only while disabled; reset whichever is on, then turn it back on.
  void resetCaches() {
    using namespace flash;
    const uint32_t acr = bus_.read32(kBase + kAcr);
    const uint32_t on = acr & (kAcrIcen | kAcrDcen);
    if (on == 0) return;
    const uint32_t rst = ((on & kAcrIcen) ? kAcrIcrst : 0u) | ((on & kAcrDcen) ? kAcrDcrst : 0u);
    bus_.write32(kBase + kAcr, acr & ~on);
    bus_.write32(kBase + kAcr, (acr & ~on) | rst);
    bus_.write32(kBase + kAcr, acr & ~on);
    bus_.write32(kBase + kAcr, acr);
  }

  Bus& bus_;
  uint32_t bound_;
  uint32_t last_sr_ = 0;
};

}  // namespace phalanx::mcu::stm32g4
