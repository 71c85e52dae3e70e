// The STM32G474 internal-flash driver (hal/mcu/include/phalanx/mcu/stm32g4_flash.h, stm32g4_flash_pages.h),
// checked on the host against a model of the FLASH peripheral and its memory array (the port cannot run here).
// The model is written from RM0440 rev 8 §3 on its own, not from the driver: it keeps the register file
// (KEYR, SR, CR, OPTR, ACR) and 512 KiB of cells and enforces the manual's rules — FLASH_CR locked after reset,
// a wrong key sequence locks it until the next reset (with a bus error), CR writes ignored while locked, PGSERR
// for a store without PG, for PG and PER together and for an operation started with an error flag of an earlier
// one still set, PGAERR for the two words of a double word not at the same double-word address in order, SIZERR
// for a byte or half-word store, PROGERR for programming a double word not erased (unless the data is all zero),
// WRPERR in a write-protected page, BSY for a number of SR reads, and a page erase of 2 KiB in the bank BKER
// selects. Where the manual is silent the model's choice is marked "model:".
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "../../hal/mcu/include/phalanx/mcu/stm32g4_flash.h"
#include "../../hal/mcu/include/phalanx/mcu/stm32g4_flash_pages.h"
#include "../../hal/mcu/stm32g474/flash_pages.h"  // compiled here for the host too (never called)
#include "phalanx/fw/app.h"
#include "phalanx/fw/settings_store.h"
#include "phalanx/protocol/devices.h"

using namespace phalanx;
using mcu::stm32g4::FlashResult;
using mcu::stm32g4::Stm32g4Flash;
using mcu::stm32g4::Stm32g4FlashPages;

namespace {

// The model's own constants, written out from RM0440 (not taken from the driver's header).
constexpr uint32_t kFlashRegs = 0x40022000u;
constexpr uint32_t kAcr = kFlashRegs + 0x00, kKeyr = kFlashRegs + 0x08, kSr = kFlashRegs + 0x10;
constexpr uint32_t kCr = kFlashRegs + 0x14, kOptr = kFlashRegs + 0x20;
constexpr uint32_t kEop = 1u << 0, kOperr = 1u << 1, kProgerr = 1u << 3, kWrperr = 1u << 4, kPgaerr = 1u << 5;
constexpr uint32_t kSizerr = 1u << 6, kPgserr = 1u << 7, kMisserr = 1u << 8, kFasterr = 1u << 9;
constexpr uint32_t kRderr = 1u << 14, kOptverr = 1u << 15, kBsy = 1u << 16;
constexpr uint32_t kClearable = 0xC3FBu;  // SR bits 0,1,3..9,14,15
constexpr uint32_t kPg = 1u << 0, kPer = 1u << 1, kBker = 1u << 11, kStrt = 1u << 16, kEopie = 1u << 24;
constexpr uint32_t kOptlock = 1u << 30, kLock = 1u << 31;
constexpr uint32_t kDbank = 1u << 22;
constexpr uint32_t kIcen = 1u << 9, kDcen = 1u << 10, kIcrst = 1u << 11, kDcrst = 1u << 12;
constexpr uint32_t kMem = 0x08000000u, kMemBytes = 512u * 1024u, kBank2 = 0x08040000u, kPage = 2048u;

class FlashModel {
 public:
  FlashModel() : mem_(kMemBytes, 0xFF) { reset(); }

  /// System reset: registers to their reset values (CR = LOCK | OPTLOCK, §3.7.6), the lock latch released;
  /// the cells keep their contents.
  void reset() {
    cr_ = kLock | kOptlock;
    sr_ = 0;
    acr_ = 0x600u;  // ICEN | DCEN at reset (§3.7.1)
    key_step_ = 0;
    latched_ = false;
    busy_ = 0;
    op_ = Op::kNone;
    half_pending_ = false;
  }

  // ---- The bus the driver is written against ----
  uint32_t read32(uint32_t a) {
    ++reads_;
    if (a == kSr) {
      ++sr_reads_;
      if (busy_ > 0 && !stuck_) {
        if (--busy_ == 0) complete();
      }
      return sr_ | (busy_ > 0 ? kBsy : 0u);
    }
    if (a == kCr) return cr_;
    if (a == kOptr) return optr_;
    if (a == kAcr) return acr_;
    return 0;  // KEYR reads as zero
  }
  void write32(uint32_t a, uint32_t v) {
    if (a == kKeyr) return key(v);
    if (a == kSr) {
      sr_ &= ~(v & kClearable);  // write 1 to clear; BSY is read-only
      return;
    }
    if (a == kCr) return writeCr(v);
    if (a == kAcr) {
      if ((v & kDcrst) && (v & kDcen)) ++cache_reset_while_on_;
      if ((v & kIcrst) && (v & kIcen)) ++cache_reset_while_on_;
      if (v & kDcrst) ++dcache_resets_;
      if (v & kIcrst) ++icache_resets_;
      acr_ = v;
      return;
    }
    // OPTR and the rest: OPTLOCK is never cleared here, writes ignored.
  }
  void writeFlash32(uint32_t a, uint32_t v) { store(a, v, 4); }
  uint8_t readFlash8(uint32_t a) { return mem_.at(a - kMem); }

  /// A store of `bytes` (1, 2 or 4) into the flash memory.
  void store(uint32_t a, uint32_t v, int bytes) {
    ++flash_stores_;
    if (a < kMem || a - kMem >= kMemBytes) {
      ++bus_errors_;
      return;
    }
    if (!(cr_ & kPg) || (cr_ & kPer)) {  // a store without PG, or with PG and PER both set
      sr_ |= kPgserr;
      half_pending_ = false;
      return;
    }
    if (bytes != 4) {  // only word stores build a double word
      sr_ |= kSizerr;
      half_pending_ = false;
      return;
    }
    if (!half_pending_) {
      if (a % 8u != 0) {  // the first word must open a double word
        sr_ |= kPgaerr;
        return;
      }
      half_pending_ = true;
      half_addr_ = a;
      half_value_ = v;
      return;
    }
    half_pending_ = false;
    if (a != half_addr_ + 4u) {  // the second word elsewhere: not one double word
      sr_ |= kPgaerr;
      return;
    }
    if (sr_ & (kProgerr | kSizerr | kPgaerr | kWrperr | kMisserr | kFasterr | kPgserr)) {
      sr_ |= kPgserr;  // an error flag of an earlier operation still set
      return;
    }
    if (protected_pages_.count((half_addr_ - kMem) / kPage)) {
      sr_ |= kWrperr;
      return;
    }
    ++programs_;
    start(Op::kProgram);
    op_addr_ = half_addr_;
    op_lo_ = half_value_;
    op_hi_ = v;
  }

  // ---- Test controls and observations ----
  void setBusySteps(uint32_t n) { busy_steps_ = n; }  ///< SR reads that show BSY per operation (≥ 1)
  /// SR reads that show BSY for a page erase (0: as any operation). A tick-stepped caller reads SR once per
  /// tick, so this is the erase's length in ticks: 22 ms typical at 1 kHz (DS12288), against 82 µs for a double word.
  void setEraseBusySteps(uint32_t n) { erase_busy_steps_ = n; }
  /// Power lost (then reset()): an operation in flight leaves its cells torn. model: an erase has set the page's
  /// first half to 0xFF and left the rest; a double word has its low word programmed and its high word not.
  void powerCut() {
    if (busy_ > 0 && op_ == Op::kErase) {
      const uint32_t base = ((op_page_ >= 128) ? kBank2 : kMem) + (op_page_ % 128u) * kPage;
      std::memset(&mem_[base - kMem], 0xFF, kPage / 2);
      ++torn_;
    } else if (busy_ > 0 && op_ == Op::kProgram) {
      for (int i = 0; i < 4; ++i) mem_[op_addr_ - kMem + i] &= static_cast<uint8_t>(op_lo_ >> (8 * i));
      ++torn_;
    }
    reset();
  }
  int tornOperations() const { return torn_; }
  bool operationRunning() const { return busy_ > 0; }
  void setStuck(bool s) { stuck_ = s; }               ///< BSY never clears
  void setDualBank(bool d) { optr_ = d ? (optr_ | kDbank) : (optr_ & ~kDbank); }
  void protectPage(uint32_t global_page) { protected_pages_.insert(global_page); }
  void setSr(uint32_t bits) { sr_ |= bits; }
  uint32_t cr() const { return cr_; }
  uint32_t sr() const { return sr_; }
  uint32_t acr() const { return acr_; }
  bool locked() const { return (cr_ & kLock) != 0; }
  std::vector<uint8_t>& mem() { return mem_; }
  uint8_t at(uint32_t a) const { return mem_.at(a - kMem); }
  int busErrors() const { return bus_errors_; }
  int crWritesIgnored() const { return cr_ignored_; }
  int pgAndPerTogether() const { return pg_and_per_; }
  int programs() const { return programs_; }
  int erases() const { return erases_; }
  int flashStores() const { return flash_stores_; }
  long srReads() const { return sr_reads_; }
  int dcacheResets() const { return dcache_resets_; }
  int icacheResets() const { return icache_resets_; }
  int cacheResetWhileOn() const { return cache_reset_while_on_; }

 private:
  enum class Op { kNone, kProgram, kErase };

  /// §3.3.5: KEY1 then KEY2 clears LOCK; any other value, or the keys in the other order, locks FLASH_CR until
  /// the next reset and raises a bus error. model: a key written while already unlocked is a wrong sequence too.
  void key(uint32_t v) {
    if (latched_) {
      ++bus_errors_;
      return;
    }
    if (!(cr_ & kLock)) return latch();
    if (key_step_ == 0) {
      if (v == 0x45670123u) {
        key_step_ = 1;
      } else {
        latch();
      }
      return;
    }
    key_step_ = 0;
    if (v == 0xCDEF89ABu) {
      cr_ &= ~kLock;
    } else {
      latch();
    }
  }
  void latch() {
    latched_ = true;
    cr_ |= kLock;
    ++bus_errors_;
  }

  void writeCr(uint32_t v) {
    if (cr_ & kLock) {  // §3.7.6: FLASH_CR cannot be written while locked
      ++cr_ignored_;
      return;
    }
    if ((v & kPg) && (v & kPer)) ++pg_and_per_;
    // model: clearing PG with half a double word stored abandons it as a sequence error.
    if (half_pending_ && !(v & kPg)) {
      half_pending_ = false;
      sr_ |= kPgserr;
    }
    const bool strt = (v & kStrt) && !(cr_ & kStrt);
    cr_ = (v & ~kStrt) | (cr_ & kStrt);  // STRT is set by software, cleared by hardware at the end (§3.7.6)
    if (!strt) return;
    if (!(cr_ & kPer) || (cr_ & kPg)) {  // STRT with no erase selected, or with PG as well
      sr_ |= kPgserr;
      return;
    }
    if (sr_ & (kProgerr | kSizerr | kPgaerr | kWrperr | kMisserr | kFasterr | kPgserr)) {
      sr_ |= kPgserr;
      return;
    }
    const uint32_t pnb = (cr_ >> 3) & 0x7Fu;
    op_page_ = ((cr_ & kBker) ? 128u : 0u) + pnb;
    if (protected_pages_.count(op_page_)) {
      sr_ |= kWrperr;
      return;
    }
    ++erases_;
    cr_ |= kStrt;
    start(Op::kErase);
  }

  void start(Op op) {
    op_ = op;
    busy_ = op == Op::kErase && erase_busy_steps_ > 0 ? erase_busy_steps_ : busy_steps_;
  }
  void complete() {
    if (op_ == Op::kErase) {
      const uint32_t base = ((op_page_ >= 128) ? kBank2 : kMem) + (op_page_ % 128u) * kPage;
      std::memset(&mem_[base - kMem], 0xFF, kPage);
      cr_ &= ~kStrt;
    } else if (op_ == Op::kProgram) {
      uint8_t* cell = &mem_[op_addr_ - kMem];
      bool erased = true;
      for (int i = 0; i < 8; ++i) erased = erased && cell[i] == 0xFF;
      if (!erased && (op_lo_ | op_hi_) != 0) {
        sr_ |= kProgerr;  // §3.7.5 PROGERR: not 0xFFFF'FFFF before programming, data not all zero
      } else {
        for (int i = 0; i < 4; ++i) {
          cell[i] = static_cast<uint8_t>(op_lo_ >> (8 * i));
          cell[4 + i] = static_cast<uint8_t>(op_hi_ >> (8 * i));
        }
      }
    }
    if (!(sr_ & kProgerr) && (cr_ & kEopie)) sr_ |= kEop;  // EOP only with EOPIE (§3.7.5)
    op_ = Op::kNone;
  }

  std::vector<uint8_t> mem_;
  uint32_t cr_ = 0, sr_ = 0, acr_ = 0, optr_ = 0xF0000000u | kDbank;
  int key_step_ = 0;
  bool latched_ = false;
  uint32_t busy_ = 0, busy_steps_ = 3, erase_busy_steps_ = 0;
  int torn_ = 0;
  bool stuck_ = false;
  Op op_ = Op::kNone;
  uint32_t op_addr_ = 0, op_lo_ = 0, op_hi_ = 0, op_page_ = 0;
  bool half_pending_ = false;
  uint32_t half_addr_ = 0, half_value_ = 0;
  std::set<uint32_t> protected_pages_;
  long reads_ = 0, sr_reads_ = 0;
  int bus_errors_ = 0, cr_ignored_ = 0, pg_and_per_ = 0, programs_ = 0, erases_ = 0, flash_stores_ = 0;
  int dcache_resets_ = 0, icache_resets_ = 0, cache_reset_while_on_ = 0;
};

using Driver = Stm32g4Flash<FlashModel>;
using Pages = Stm32g4FlashPages<FlashModel>;

/// Fills a range of the cells with a non-erased pattern (as a previous image would leave them).
void dirty(FlashModel& m, uint32_t from, uint32_t bytes) { std::memset(&m.mem()[from - kMem], 0x5A, bytes); }

// ---- The model's own rules (so that a driver passing against it means something) ----

TEST(McuStm32g4FlashModel, ControlRegisterIsLockedAfterResetAndIgnoresWritesUntilUnlocked) {
  FlashModel m;
  EXPECT_TRUE(m.locked());
  m.write32(kCr, kPg);
  EXPECT_EQ(m.cr() & kPg, 0u);
  EXPECT_EQ(m.crWritesIgnored(), 1);
  m.write32(kKeyr, 0x45670123u);
  m.write32(kKeyr, 0xCDEF89ABu);
  EXPECT_FALSE(m.locked());
}

TEST(McuStm32g4FlashModel, KeysInTheWrongOrderLockUntilResetWithABusError) {
  FlashModel m;
  m.write32(kKeyr, 0xCDEF89ABu);
  m.write32(kKeyr, 0x45670123u);
  EXPECT_TRUE(m.locked());
  EXPECT_GE(m.busErrors(), 1);
  m.write32(kKeyr, 0x45670123u);  // even the right sequence now
  m.write32(kKeyr, 0xCDEF89ABu);
  EXPECT_TRUE(m.locked());
  m.reset();
  m.write32(kKeyr, 0x45670123u);
  m.write32(kKeyr, 0xCDEF89ABu);
  EXPECT_FALSE(m.locked());
}

TEST(McuStm32g4FlashModel, StoresOutOfSequenceSetTheManualsErrorFlags) {
  FlashModel m;
  m.write32(kKeyr, 0x45670123u);
  m.write32(kKeyr, 0xCDEF89ABu);
  m.writeFlash32(kBank2, 0);  // PG not set
  EXPECT_TRUE(m.sr() & kPgserr);
  m.write32(kSr, kPgserr);
  m.write32(kCr, kPg | kPer);  // both
  m.writeFlash32(kBank2, 0);
  EXPECT_TRUE(m.sr() & kPgserr);
  m.write32(kSr, 0xFFFFFFFFu);
  m.write32(kCr, kPg);
  m.store(kBank2, 0, 2);  // half-word
  EXPECT_TRUE(m.sr() & kSizerr);
  m.write32(kSr, 0xFFFFFFFFu);
  m.writeFlash32(kBank2 + 4, 0);  // first word in the upper half
  EXPECT_TRUE(m.sr() & kPgaerr);
  m.write32(kSr, 0xFFFFFFFFu);
  m.writeFlash32(kBank2, 0);
  m.writeFlash32(kBank2 + 12, 0);  // second word of another double word
  EXPECT_TRUE(m.sr() & kPgaerr);
  EXPECT_EQ(m.programs(), 0);
  // A correct pair with an earlier error flag still set: PGSERR, nothing programmed.
  m.writeFlash32(kBank2, 1);
  m.writeFlash32(kBank2 + 4, 2);
  EXPECT_TRUE(m.sr() & kPgserr);
  EXPECT_EQ(m.programs(), 0);
  EXPECT_EQ(m.at(kBank2), 0xFF);
}

// ---- The driver's sequences ----

TEST(McuStm32g4Flash, AnErasedPageProgrammedReadsBackWithTheLowWordFirst) {
  FlashModel m;
  Driver d(m);
  const uint32_t page_addr = kBank2 + 5 * kPage;
  dirty(m, page_addr - kPage, 3 * kPage);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  ASSERT_EQ(d.erasePage(2, 5), FlashResult::kSuccess);
  for (uint32_t i = 0; i < kPage; ++i) ASSERT_EQ(m.at(page_addr + i), 0xFF) << i;
  EXPECT_EQ(m.at(page_addr - 1), 0x5A) << "the page before is kept";
  EXPECT_EQ(m.at(page_addr + kPage), 0x5A) << "the page after is kept";
  ASSERT_EQ(d.programDoubleWord(page_addr + 16, 0x44332211u, 0x88776655u), FlashResult::kSuccess);
  for (uint32_t i = 0; i < 8; ++i) EXPECT_EQ(m.at(page_addr + 16 + i), 0x11 * (i + 1)) << i;
  EXPECT_EQ(m.at(page_addr + 24), 0xFF);
  EXPECT_EQ(m.cr() & (kPg | kPer | kBker | kStrt), 0u) << "nothing left armed";
  EXPECT_EQ(m.pgAndPerTogether(), 0);
  d.lock();
  EXPECT_TRUE(m.locked());
}

TEST(McuStm32g4Flash, EraseSelectsTheBankWithBker) {
  FlashModel m;
  Driver d(m);
  dirty(m, kMem, kMemBytes);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  ASSERT_EQ(d.erasePage(1, 127), FlashResult::kSuccess);
  EXPECT_EQ(m.at(kMem + 127 * kPage), 0xFF);
  EXPECT_EQ(m.at(kBank2 + 127 * kPage), 0x5A);
  ASSERT_EQ(d.erasePage(2, 0), FlashResult::kSuccess);
  EXPECT_EQ(m.at(kBank2), 0xFF);
  EXPECT_EQ(m.at(kBank2 + kPage - 1), 0xFF);
  EXPECT_EQ(m.at(kMem), 0x5A);
  EXPECT_EQ(m.at(kBank2 + kPage), 0x5A);
}

TEST(McuStm32g4Flash, ProgrammingAProgrammedDoubleWordIsAProgramErrorAndChangesNothing) {
  FlashModel m;
  Driver d(m);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  ASSERT_EQ(d.programDoubleWord(kBank2, 0xFFFF0000u, 0xFFFFFFFFu), FlashResult::kSuccess);
  EXPECT_EQ(d.programDoubleWord(kBank2, 0x0000FFFFu, 0u), FlashResult::kProgramError);
  EXPECT_TRUE(d.lastStatus() & kProgerr);
  EXPECT_EQ(m.at(kBank2), 0x00);
  EXPECT_EQ(m.at(kBank2 + 2), 0xFF);
  // The flag was cleared, so the next operation is not refused for it; all-zero data is the manual's exception.
  EXPECT_EQ(d.programDoubleWord(kBank2, 0u, 0u), FlashResult::kSuccess);
  EXPECT_EQ(d.programDoubleWord(kBank2 + 8, 1u, 2u), FlashResult::kSuccess);
}

TEST(McuStm32g4Flash, AStaleErrorFlagIsClearedBeforeTheOperation) {
  FlashModel m;
  Driver d(m);
  m.setSr(kPgaerr | kSizerr | kProgerr | kEop);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  EXPECT_EQ(d.programDoubleWord(kBank2 + 64, 7u, 8u), FlashResult::kSuccess);
  EXPECT_EQ(m.at(kBank2 + 64), 7);
  m.setSr(kPgserr);
  EXPECT_EQ(d.erasePage(2, 0), FlashResult::kSuccess);
  EXPECT_EQ(m.at(kBank2 + 64), 0xFF);
  EXPECT_EQ(m.sr() & kClearable, 0u) << "flags cleared after the operation too";
}

TEST(McuStm32g4Flash, ArgumentsOutsideTheMemoryOrMisalignedAreRefusedWithoutABusAccessToTheCells) {
  FlashModel m;
  Driver d(m);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  EXPECT_EQ(d.programDoubleWord(kBank2 + 4, 1, 2), FlashResult::kBadArgument);
  EXPECT_EQ(d.programDoubleWord(kBank2 + 1, 1, 2), FlashResult::kBadArgument);
  EXPECT_EQ(d.programDoubleWord(kMem - 8, 1, 2), FlashResult::kBadArgument);
  EXPECT_EQ(d.programDoubleWord(kMem + kMemBytes, 1, 2), FlashResult::kBadArgument);
  EXPECT_EQ(d.erasePage(0, 0), FlashResult::kBadArgument);
  EXPECT_EQ(d.erasePage(3, 0), FlashResult::kBadArgument);
  EXPECT_EQ(d.erasePage(1, 128), FlashResult::kBadArgument);
  EXPECT_EQ(m.flashStores(), 0);
  EXPECT_EQ(m.erases(), 0);
  EXPECT_EQ(d.programDoubleWord(kMem + kMemBytes - 8, 1, 2), FlashResult::kSuccess) << "the last double word";
}

TEST(McuStm32g4Flash, WhileLockedNothingIsWrittenAndLockedIsReported) {
  FlashModel m;
  Driver d(m);
  EXPECT_EQ(d.programDoubleWord(kBank2, 1, 2), FlashResult::kLocked);
  EXPECT_EQ(d.erasePage(2, 0), FlashResult::kLocked);
  EXPECT_EQ(m.flashStores(), 0);
  EXPECT_EQ(m.crWritesIgnored(), 0) << "the driver did not even try";
}

TEST(McuStm32g4Flash, AWrongKeySequenceIsReportedAsLockedUntilReset) {
  FlashModel m;
  Driver d(m);
  m.write32(kKeyr, 0x12345678u);  // someone else's wrong key
  EXPECT_EQ(d.unlock(), FlashResult::kLocked);
  EXPECT_EQ(d.programDoubleWord(kBank2, 1, 2), FlashResult::kLocked);
  m.reset();
  EXPECT_EQ(d.unlock(), FlashResult::kSuccess);
}

TEST(McuStm32g4Flash, UnlockingTwiceWritesNoSecondKeySequence) {
  FlashModel m;
  Driver d(m);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  EXPECT_EQ(d.unlock(), FlashResult::kSuccess);
  EXPECT_FALSE(m.locked());
  EXPECT_EQ(m.busErrors(), 0);
}

TEST(McuStm32g4Flash, WriteProtectedPagesReportWrperr) {
  FlashModel m;
  m.protectPage(200);
  Driver d(m);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  EXPECT_EQ(d.erasePage(2, 72), FlashResult::kWriteProtected);
  EXPECT_EQ(d.programDoubleWord(kMem + 200 * kPage, 1, 2), FlashResult::kWriteProtected);
  EXPECT_EQ(d.erasePage(2, 73), FlashResult::kSuccess) << "the flag does not outlive its operation";
}

TEST(McuStm32g4Flash, BusyForManyReadsIsWaitedOut) {
  FlashModel m;
  m.setBusySteps(5000);
  Driver d(m);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  EXPECT_EQ(d.erasePage(2, 1), FlashResult::kSuccess);
  EXPECT_EQ(d.programDoubleWord(kBank2 + kPage, 9, 10), FlashResult::kSuccess);
  EXPECT_EQ(m.at(kBank2 + kPage), 9);
}

TEST(McuStm32g4Flash, ABusyFlagThatNeverClearsIsATimeoutAfterTheBound) {
  FlashModel m;
  Driver d(m, 100);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  m.setStuck(true);
  EXPECT_EQ(d.programDoubleWord(kBank2, 1, 2), FlashResult::kBusyTimeout) << "started, never ends";
  EXPECT_EQ(m.programs(), 1);
  EXPECT_EQ(m.cr() & kPg, 0u);
  const long before = m.srReads();
  EXPECT_EQ(d.erasePage(2, 0), FlashResult::kBusyTimeout) << "BSY of the operation before";
  EXPECT_EQ(m.srReads() - before, 100);
  EXPECT_EQ(m.erases(), 0) << "nothing started while busy";
  EXPECT_EQ(d.programDoubleWord(kBank2 + 8, 1, 2), FlashResult::kBusyTimeout);
  EXPECT_EQ(m.programs(), 1);
}

TEST(McuStm32g4Flash, ATimeoutDuringTheOperationIsReportedAndPgIsCleared) {
  FlashModel m;
  m.setBusySteps(1000);
  Driver d(m, 10);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  EXPECT_EQ(d.programDoubleWord(kBank2, 1, 2), FlashResult::kBusyTimeout);
  EXPECT_EQ(m.cr() & kPg, 0u);
}

TEST(McuStm32g4Flash, SingleBankModeIsRefused) {
  FlashModel m;
  m.setDualBank(false);
  Driver d(m);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  EXPECT_EQ(d.erasePage(1, 0), FlashResult::kSingleBank);
  EXPECT_EQ(d.programDoubleWord(kMem, 1, 2), FlashResult::kSingleBank);
  EXPECT_EQ(m.erases() + m.flashStores(), 0);
}

TEST(McuStm32g4Flash, EraseResetsTheEnabledCachesWhileDisabledAndRestoresThem) {
  FlashModel m;
  Driver d(m);
  const uint32_t acr = m.acr();
  ASSERT_EQ(acr & (kIcen | kDcen), kIcen | kDcen);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  ASSERT_EQ(d.erasePage(2, 3), FlashResult::kSuccess);
  EXPECT_EQ(m.dcacheResets(), 1);
  EXPECT_EQ(m.icacheResets(), 1);
  EXPECT_EQ(m.cacheResetWhileOn(), 0);
  EXPECT_EQ(m.acr(), acr);
}

TEST(McuStm32g4Flash, EverySrErrorFlagDecodesToItsResult) {
  using mcu::stm32g4::flashErrorOf;
  using mcu::stm32g4::flashResultName;
  const std::map<uint32_t, FlashResult> expect = {
      {kOperr, FlashResult::kOperationError}, {kProgerr, FlashResult::kProgramError},
      {kWrperr, FlashResult::kWriteProtected}, {kPgaerr, FlashResult::kAlignmentError},
      {kSizerr, FlashResult::kSizeError},      {kPgserr, FlashResult::kSequenceError},
      {kMisserr, FlashResult::kFastError},     {kFasterr, FlashResult::kFastError},
      {kRderr, FlashResult::kReadError},       {kOptverr, FlashResult::kOptionError}};
  for (const auto& [bit, r] : expect) EXPECT_EQ(flashErrorOf(bit), r) << bit;
  EXPECT_EQ(flashErrorOf(0), FlashResult::kSuccess);
  EXPECT_EQ(flashErrorOf(kEop | kBsy), FlashResult::kSuccess);
  EXPECT_EQ(flashErrorOf(kPgaerr | kPgserr), FlashResult::kSequenceError);
  std::set<std::string> names;
  for (int v = 0; v < 32; ++v) {
    const std::string n = flashResultName(static_cast<FlashResult>(v));
    if (n != "?") {
      EXPECT_TRUE(names.insert(n).second) << n;
    }
  }
  EXPECT_EQ(names.size(), 15u);
}

// ---- The FlashPages adapter ----

TEST(McuStm32g4FlashPages, GeometryAndAddressesAcrossTheBankBoundary) {
  FlashModel m;
  dirty(m, kMem, kMemBytes);
  Pages p(m, 127, 2);
  EXPECT_EQ(p.pageCount(), 2u);
  EXPECT_EQ(p.pageSize(), 2048u);
  ASSERT_TRUE(p.erase(0));
  EXPECT_EQ(m.at(kMem + 127 * kPage), 0xFF);
  EXPECT_EQ(m.at(kBank2), 0x5A);
  ASSERT_TRUE(p.erase(1));
  EXPECT_EQ(m.at(kBank2), 0xFF);
  EXPECT_EQ(m.at(kBank2 + kPage), 0x5A);
  EXPECT_FALSE(p.erase(2));
  EXPECT_EQ(Pages(m, 250, 10).pageCount(), 6u) << "cut at the end of the memory";
  EXPECT_EQ(Pages(m, 300, 1).pageCount(), 0u);
}

TEST(McuStm32g4FlashPages, ProgramReadsBackAndTheLockIsRestoredAfterEveryOperation) {
  FlashModel m;
  Pages p(m, 254, 2);
  uint8_t data[24];
  for (size_t i = 0; i < sizeof data; ++i) data[i] = static_cast<uint8_t>(3 * i + 1);
  ASSERT_TRUE(p.erase(1));
  EXPECT_TRUE(m.locked());
  ASSERT_TRUE(p.program(1, 2040 - 16, data, 24));
  EXPECT_TRUE(m.locked());
  uint8_t back[24] = {};
  ASSERT_TRUE(p.read(1, 2040 - 16, back, 24));
  EXPECT_EQ(std::memcmp(back, data, 24), 0);
  EXPECT_EQ(m.at(kBank2 + 127 * kPage + 2024), 1) << "page 1 of the range is global page 255";
  // Failures re-lock too.
  EXPECT_FALSE(p.program(1, 2040 - 16, data, 8));
  EXPECT_TRUE(m.locked());
  m.setStuck(true);
  m.setBusySteps(5);
  Pages slow(m, 254, 2, 50);
  EXPECT_FALSE(slow.erase(0));  // starts, then BSY never clears
  EXPECT_EQ(slow.lastResult(), FlashResult::kBusyTimeout);
  EXPECT_TRUE(m.locked());
}

TEST(McuStm32g4FlashPages, MisalignedOrOutOfRangeRequestsAreRefusedBeforeTheHardware) {
  FlashModel m;
  Pages p(m, 254, 2);
  const uint8_t data[16] = {};
  EXPECT_FALSE(p.program(0, 4, data, 8));
  EXPECT_FALSE(p.program(0, 0, data, 12));
  EXPECT_FALSE(p.program(0, 2048 - 8, data, 16));
  EXPECT_FALSE(p.program(2, 0, data, 8));
  uint8_t out[8];
  EXPECT_FALSE(p.read(0, 2044, out, 8));
  EXPECT_FALSE(p.read(2, 0, out, 1));
  EXPECT_TRUE(p.read(0, 2047, out, 1));
  EXPECT_EQ(p.lastResult(), FlashResult::kBadArgument);
  EXPECT_EQ(m.flashStores(), 0);
  EXPECT_TRUE(p.program(0, 0, data, 0)) << "nothing to write";
}

TEST(McuStm32g4FlashPages, AnyProgrammedDoubleWordInTheSpanRefusesTheWholeSpan) {
  FlashModel m;
  Pages p(m, 254, 2);
  ASSERT_TRUE(p.erase(0));
  const uint8_t one[8] = {1, 2, 3, 4, 5, 6, 7, 8};
  ASSERT_TRUE(p.program(0, 8, one, 8));
  const int stores = m.flashStores();
  uint8_t zeros[24] = {};
  EXPECT_FALSE(p.program(0, 0, zeros, 24)) << "even all-zero data, which the hardware would take";
  EXPECT_EQ(p.lastResult(), FlashResult::kProgramError);
  EXPECT_EQ(m.flashStores(), stores);
  EXPECT_EQ(m.at(kBank2 + 126 * kPage), 0xFF);
  ASSERT_TRUE(p.erase(0));
  EXPECT_TRUE(p.program(0, 0, zeros, 24));
}

/// An app with three bounded parameters, persisted in one layout version.
constexpr uint16_t kIds[] = {0x0100, 0x0101, 0x0102};
constexpr fw::SettingsLayout kHistory[] = {{1, kIds, 3, nullptr, 0}};
class ThreeParamApp : public fw::DeviceApp {
 public:
  const protocol::DeviceLayout& layout() const override { return protocol::kSeaFingerLayout; }
  void init(hal::Board&) override {}
  uint16_t sense(float) override { return 0; }
  uint16_t control(const protocol::Command&, float) override { return 0; }
  void safe() override {}
  void fillSamples(int16_t*) const override {}
  protocol::ParamStatus getParam(uint16_t id, float& v) const override {
    if (id < 0x0100 || id > 0x0102) return protocol::ParamStatus::kUnknownParam;
    v = values[id - 0x0100];
    return protocol::ParamStatus::kOk;
  }
  protocol::ParamStatus setParam(uint16_t id, float v) override {
    if (id < 0x0100 || id > 0x0102) return protocol::ParamStatus::kUnknownParam;
    values[id - 0x0100] = v;
    return protocol::ParamStatus::kOk;
  }
  fw::SettingsHistory settingsHistory() const override { return {kHistory, 1}; }
  float values[3] = {0.0f, 0.0f, 0.0f};
};

TEST(McuStm32g4FlashPages, TheSettingsStoreSurvivesAResetOnTheBoardsPages) {
  FlashModel m;
  dirty(m, kMem + mcu::g474::kSettingsFirstPage * kPage, 2 * kPage);  // not erased from the factory
  {
    Pages p(m, mcu::g474::kSettingsFirstPage, mcu::g474::kSettingsPages);
    ThreeParamApp app;
    fw::SettingsStore store(p);
    EXPECT_EQ(store.load(app).result, fw::SettingsLoad::kNothingStored);
    app.values[0] = 1.5f;
    app.values[1] = -2.25f;
    app.values[2] = 1e6f;
    ASSERT_EQ(store.save(app), fw::SettingsSave::kSaved);
    app.values[1] = 4.0f;
    ASSERT_EQ(store.save(app), fw::SettingsSave::kSaved);  // the other slot
    EXPECT_EQ(store.save(app), fw::SettingsSave::kUnchanged);
    EXPECT_EQ(store.newestSequence(), 2u);
  }
  EXPECT_TRUE(m.locked());
  m.reset();
  Pages p(m, mcu::g474::kSettingsFirstPage, mcu::g474::kSettingsPages);
  ThreeParamApp app;
  fw::SettingsStore store(p);
  const fw::SettingsReport r = store.load(app);
  EXPECT_EQ(r.result, fw::SettingsLoad::kLoaded);
  EXPECT_EQ(r.sequence, 2u);
  EXPECT_EQ(app.values[0], 1.5f);
  EXPECT_EQ(app.values[1], 4.0f);
  EXPECT_EQ(app.values[2], 1e6f);
  EXPECT_EQ(m.busErrors(), 0);
  EXPECT_EQ(m.pgAndPerTogether(), 0);
  EXPECT_GE(m.erases(), 2);
}

// ---- Operations begun and polled (the tick-stepped path: a page erase outlasts the board's 5 ms watchdog) ----

TEST(McuStm32g4Flash, ABegunEraseReturnsAtOnceAndIsFinishedOnceBsyClears) {
  FlashModel m;
  m.setBusySteps(50);
  Driver d(m);
  const uint32_t page_addr = kBank2 + 126 * kPage;
  dirty(m, page_addr, kPage);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  const long before = m.srReads();
  ASSERT_EQ(d.beginErasePage(2, 126), FlashResult::kSuccess);
  EXPECT_EQ(m.srReads() - before, 1) << "one SR read (BSY clear before the start), no wait";
  EXPECT_TRUE(m.operationRunning());
  EXPECT_EQ(m.cr() & (kPer | kBker), kPer | kBker) << "armed while it runs";
  int polls = 0;
  while (d.busy()) ASSERT_LT(++polls, 100);
  EXPECT_EQ(polls, 49);
  EXPECT_EQ(d.finishErase(), FlashResult::kSuccess);
  for (uint32_t i = 0; i < kPage; ++i) ASSERT_EQ(m.at(page_addr + i), 0xFF) << i;
  EXPECT_EQ(m.cr() & (kPer | kBker | kStrt), 0u);
  EXPECT_EQ(m.icacheResets(), 1) << "caches reset after the erase, as the blocking one";
  EXPECT_EQ(m.cacheResetWhileOn(), 0);
}

TEST(McuStm32g4Flash, ABegunDoubleWordIsProgrammedAndItsErrorReportedByFinish) {
  FlashModel m;
  m.setBusySteps(4);
  Driver d(m);
  ASSERT_EQ(d.unlock(), FlashResult::kSuccess);
  ASSERT_EQ(d.beginProgramDoubleWord(kBank2 + 16, 0x04030201u, 0x08070605u), FlashResult::kSuccess);
  EXPECT_TRUE(m.cr() & kPg);
  EXPECT_EQ(d.beginProgramDoubleWord(kBank2 + 24, 1, 2), FlashResult::kBusy) << "BSY set: nothing stored";
  EXPECT_EQ(d.beginErasePage(2, 0), FlashResult::kBusy);
  EXPECT_EQ(m.programs(), 1);
  EXPECT_EQ(m.erases(), 0);
  while (d.busy()) {
  }
  EXPECT_EQ(d.finishProgram(), FlashResult::kSuccess);
  EXPECT_EQ(m.cr() & kPg, 0u);
  for (uint32_t i = 0; i < 8; ++i) EXPECT_EQ(m.at(kBank2 + 16 + i), i + 1) << i;
  ASSERT_EQ(d.beginProgramDoubleWord(kBank2 + 16, 0x10u, 0u), FlashResult::kSuccess);
  while (d.busy()) {
  }
  EXPECT_EQ(d.finishProgram(), FlashResult::kProgramError) << "not erased";
  EXPECT_EQ(m.sr() & kClearable, 0u) << "flags cleared for the next operation";
  EXPECT_EQ(d.beginProgramDoubleWord(kBank2 + 4, 1, 2), FlashResult::kBadArgument);
  d.lock();
  EXPECT_EQ(d.beginErasePage(2, 0), FlashResult::kLocked);
}

TEST(McuStm32g4FlashPages, ABegunOperationIsPolledToItsEndOneSrReadEachAndRelocks) {
  FlashModel m;
  m.setBusySteps(1000);
  dirty(m, kBank2 + 126 * kPage, 2 * kPage);
  Pages p(m, 254, 2, 10);  // the blocking wait's bound (10 reads) does not apply to a begun operation
  EXPECT_EQ(p.poll(), hal::FlashOp::kDone) << "nothing pending";
  ASSERT_EQ(p.beginErase(0), hal::FlashOp::kBusy);
  EXPECT_FALSE(m.locked()) << "FLASH_CR stays unlocked while the erase runs";
  EXPECT_TRUE(p.operationPending());
  EXPECT_EQ(p.beginErase(1), hal::FlashOp::kFailed) << "one operation at a time";
  EXPECT_EQ(p.lastResult(), FlashResult::kBusy);
  EXPECT_FALSE(p.erase(1));
  const uint8_t unit[8] = {1, 2, 3, 4, 5, 6, 7, 8};
  EXPECT_FALSE(p.program(1, 0, unit, 8));
  EXPECT_EQ(m.erases(), 1);
  EXPECT_EQ(m.flashStores(), 0);
  uint8_t byte = 0;
  EXPECT_FALSE(p.read(1, 0, &byte, 1)) << "no read while the erase runs (it would stall the CPU)";
  int busy = 0;
  for (;;) {
    const long before = m.srReads();
    const hal::FlashOp op = p.poll();
    ASSERT_EQ(m.srReads() - before, 1);
    if (op != hal::FlashOp::kBusy) {
      EXPECT_EQ(op, hal::FlashOp::kDone);
      break;
    }
    ASSERT_LT(++busy, 2000);
  }
  EXPECT_GT(busy, 900) << "the polls before (and the read's), not counted against the blocking bound";
  EXPECT_TRUE(m.locked());
  EXPECT_FALSE(p.operationPending());
  EXPECT_EQ(m.at(kBank2 + 126 * kPage), 0xFF);
  EXPECT_EQ(m.at(kBank2 + 127 * kPage), 0x5A) << "only page 0 of the range";
  m.setBusySteps(3);
  ASSERT_EQ(p.beginProgram(0, 8, unit), hal::FlashOp::kBusy);
  while (p.poll() == hal::FlashOp::kBusy) {
  }
  uint8_t back[8] = {};
  ASSERT_TRUE(p.read(0, 8, back, 8));
  EXPECT_EQ(std::memcmp(back, unit, 8), 0);
  const int stores = m.flashStores();
  EXPECT_EQ(p.beginProgram(0, 8, unit), hal::FlashOp::kFailed) << "programmed already";
  EXPECT_EQ(p.lastResult(), FlashResult::kProgramError);
  EXPECT_EQ(p.beginProgram(0, 4, unit), hal::FlashOp::kFailed);
  EXPECT_EQ(p.beginProgram(0, 2048, unit), hal::FlashOp::kFailed);
  EXPECT_EQ(p.beginErase(2), hal::FlashOp::kFailed);
  EXPECT_EQ(m.flashStores(), stores);
  EXPECT_TRUE(m.locked());
}

TEST(McuStm32g4FlashPages, AnOperationGivenUpOnDoesNotBlockTheNextOnceItHasEnded) {
  FlashModel m;
  m.setBusySteps(5);
  Pages p(m, 254, 2);
  ASSERT_EQ(p.beginErase(0), hal::FlashOp::kBusy);  // and never polled by its caller
  EXPECT_EQ(p.beginErase(1), hal::FlashOp::kFailed) << "first poll: still busy";
  for (int i = 0; i < 5; ++i) m.read32(kSr);  // time passes
  EXPECT_EQ(p.beginErase(1), hal::FlashOp::kBusy) << "the first one has ended: the next starts";
  while (p.poll() == hal::FlashOp::kBusy) {
  }
  EXPECT_EQ(m.erases(), 2);
  EXPECT_TRUE(m.locked());
}

// ---- The settings store's stepped save on the board's pages ----

/// What a stepped save did: its result, the steps it took, the most SR reads in one step.
struct SteppedSave {
  fw::SettingsSave result = fw::SettingsSave::kInProgress;
  int steps = 0;
  long max_sr_reads_per_step = 0;
};

SteppedSave stepToEnd(FlashModel& m, fw::SettingsStore& store, const fw::DeviceApp& app, int max_steps) {
  SteppedSave s;
  s.result = store.beginSave(app);
  while (s.result == fw::SettingsSave::kInProgress && s.steps < max_steps) {
    const long before = m.srReads();
    s.result = store.stepSave();
    ++s.steps;
    s.max_sr_reads_per_step = std::max(s.max_sr_reads_per_step, m.srReads() - before);
  }
  return s;
}

/// A fresh board after a reset: a new adapter, store and app over the model's cells; load's report.
fw::SettingsReport reboot(FlashModel& m, ThreeParamApp& app) {
  m.reset();
  Pages p(m, mcu::g474::kSettingsFirstPage, mcu::g474::kSettingsPages);
  app = ThreeParamApp();
  fw::SettingsStore store(p);
  return store.load(app);
}

TEST(McuStm32g4SettingsSave, ASaveRunsOverManyTicksWithNoStepWaitingForTheFlash) {
  FlashModel m;
  m.setEraseBusySteps(22);  // 22 ms at one poll per 1 ms tick
  m.setBusySteps(2);
  dirty(m, kMem + mcu::g474::kSettingsFirstPage * kPage, 2 * kPage);
  Pages p(m, mcu::g474::kSettingsFirstPage, mcu::g474::kSettingsPages);
  ThreeParamApp app;
  fw::SettingsStore store(p);
  store.load(app);
  app.values[0] = 0.5f;
  app.values[1] = 7.0f;
  app.values[2] = -3.0f;
  const SteppedSave s = stepToEnd(m, store, app, 1000);
  ASSERT_EQ(s.result, fw::SettingsSave::kSaved);
  EXPECT_LE(s.max_sr_reads_per_step, 2) << "a step polls; it never spins on BSY";
  // 48 bytes = 6 double words, 2 polls each, after the 22 of the erase.
  EXPECT_GE(s.steps, 22 + 6);
  EXPECT_LE(s.steps, 22 + 6 * 2 + 2);
  EXPECT_FALSE(store.saving());
  EXPECT_EQ(store.newestSequence(), 1u);
  EXPECT_TRUE(m.locked());
  EXPECT_EQ(m.pgAndPerTogether(), 0);
  EXPECT_EQ(m.busErrors(), 0);
  EXPECT_EQ(store.stepSave(), fw::SettingsSave::kUnchanged) << "no save under way";
  const fw::SettingsReport r = reboot(m, app);
  EXPECT_EQ(r.result, fw::SettingsLoad::kLoaded);
  EXPECT_EQ(app.values[0], 0.5f);
  EXPECT_EQ(app.values[1], 7.0f);
  EXPECT_EQ(app.values[2], -3.0f);
}

TEST(McuStm32g4SettingsSave, ABusyFlagSetForThousandsOfPollsIsWaitedOutOneStepAtATime) {
  FlashModel m;
  m.setEraseBusySteps(5000);
  m.setBusySteps(300);
  Pages p(m, mcu::g474::kSettingsFirstPage, mcu::g474::kSettingsPages);
  ThreeParamApp app;
  fw::SettingsStore store(p, 0, 0, 6000);
  app.values[0] = 2.0f;
  const SteppedSave s = stepToEnd(m, store, app, 10000);
  ASSERT_EQ(s.result, fw::SettingsSave::kSaved);
  EXPECT_LE(s.max_sr_reads_per_step, 2);
  EXPECT_GE(s.steps, 5000 + 6 * 300);
  EXPECT_EQ(reboot(m, app).result, fw::SettingsLoad::kLoaded);
  EXPECT_EQ(app.values[0], 2.0f);
}

TEST(McuStm32g4SettingsSave, AFlashThatStaysBusyFailsTheSaveAfterItsBoundAndTheOlderRecordStays) {
  FlashModel m;
  Pages p(m, mcu::g474::kSettingsFirstPage, mcu::g474::kSettingsPages);
  ThreeParamApp app;
  fw::SettingsStore store(p);
  app.values[0] = 1.0f;
  ASSERT_EQ(store.save(app), fw::SettingsSave::kSaved);
  app.values[0] = 9.0f;
  m.setStuck(true);
  const SteppedSave s = stepToEnd(m, store, app, 1000);
  EXPECT_EQ(s.result, fw::SettingsSave::kWriteFailed);
  EXPECT_EQ(s.steps, static_cast<int>(fw::kSettingsBusyStepBound));
  EXPECT_FALSE(store.saving());
  EXPECT_EQ(store.beginSave(app), fw::SettingsSave::kBusy) << "still busy: refused, nothing read or started";
  EXPECT_EQ(m.erases(), 2);
  m.setStuck(false);
  EXPECT_EQ(reboot(m, app).sequence, 1u);
  EXPECT_EQ(app.values[0], 1.0f);
}

TEST(McuStm32g4SettingsSave, APowerCutAtEveryStepLeavesTheOlderOrTheNewRecordNeverNone) {
  int cuts_in_flight = 0;
  int full_steps = -1;
  int new_before_end = 0;
  for (int cut = 0; full_steps < 0 || cut <= full_steps; ++cut) {
    FlashModel m;
    m.setEraseBusySteps(22);
    m.setBusySteps(2);
    ThreeParamApp app;
    {
      Pages p(m, mcu::g474::kSettingsFirstPage, mcu::g474::kSettingsPages);
      fw::SettingsStore store(p);
      // Records 1 and 2 in both slots: the save below erases the one holding record 1.
      app.values[0] = 1.0f;
      ASSERT_EQ(store.save(app), fw::SettingsSave::kSaved);
      app.values[0] = 2.0f;
      ASSERT_EQ(store.save(app), fw::SettingsSave::kSaved);
      app.values[0] = 3.0f;
      fw::SettingsSave r = store.beginSave(app);
      ASSERT_EQ(r, fw::SettingsSave::kInProgress);
      int steps = 0;
      for (; steps < cut && r == fw::SettingsSave::kInProgress; ++steps) r = store.stepSave();
      if (r == fw::SettingsSave::kSaved && full_steps < 0) full_steps = steps;
      if (m.operationRunning()) ++cuts_in_flight;
      m.powerCut();
    }
    const fw::SettingsReport rep = reboot(m, app);
    ASSERT_EQ(rep.result, fw::SettingsLoad::kLoaded) << "cut after " << cut << " steps";
    // The new record is in force once the save ended, and may be once its last double word (holding the CRC's
    // low word: the high word is 0xFF padding) is in flight; before that never.
    const bool finished = full_steps >= 0 && cut >= full_steps;
    if (finished) {
      ASSERT_EQ(rep.sequence, 3u) << "cut after " << cut << " steps";
    }
    ASSERT_TRUE(rep.sequence == 2u || rep.sequence == 3u) << "cut after " << cut << " steps";
    ASSERT_EQ(app.values[0], static_cast<float>(rep.sequence)) << "the record's own values, cut after " << cut;
    if (!finished && rep.sequence == 3u) ++new_before_end;
  }
  EXPECT_LE(new_before_end, 2) << "only while the last double word was in flight";
  EXPECT_GE(full_steps, 22 + 6);
  EXPECT_GE(cuts_in_flight, full_steps - 1) << "nearly every cut tore an erase or a double word in flight";
}

TEST(McuStm32g474Board, TheSettingsPagesLieInBank2BeyondTheUpdateSlotsAndOnlyTheirEccErrorsAreSurvived) {
  using mcu::g474::isSettingsEccError;
  EXPECT_EQ(mcu::g474::kSettingsFirstPage, 254u);
  EXPECT_EQ(mcu::stm32g4::flash::pageAddress(mcu::g474::kSettingsFirstPage), 0x0807F000u);
  const uint32_t eccd = 1u << 31, bk2 = 1u << 21, sysf = 1u << 22;
  EXPECT_TRUE(isSettingsEccError(eccd | bk2 | 0x3F008u));
  EXPECT_FALSE(isSettingsEccError(eccd)) << "bank 1: the image itself";
  EXPECT_FALSE(isSettingsEccError(eccd | bk2 | sysf)) << "system memory";
  EXPECT_FALSE(isSettingsEccError(bk2 | (1u << 30))) << "a corrected single error raises no NMI";
}

}  // namespace
