#pragma once
/// Flash pages kept in a file on the host through ARM semihosting: the emulated boards' settings flash. The pages
/// live in RAM; the file is read once when opened and every erase and program is written through, so a restart
/// of QEMU with the same file is a power cycle that keeps them. The medium's rules are the STM32G4's
/// (hal/flash.h): erased bytes read 0xFF, a program only into units erased since, each unit once.
/// No heap; bounded loops; for the emulated boards only (semihosting traps on silicon without a debugger).
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "phalanx/hal/flash.h"
#include "phalanx/mcu/semihosting.h"

namespace phalanx::mcu {

template <size_t kPages, size_t kPageBytes>
class SemihostFlashPages final : public hal::FlashPages {
  static_assert(kPageBytes % hal::kFlashProgramUnit == 0, "whole program units per page");
  static constexpr size_t kUnits = kPages * kPageBytes / hal::kFlashProgramUnit;

 public:
  /// Opens the host file `path` (created erased when absent or shorter than the pages). false: semihosting
  /// could not open or write it; the pages then stay erased and every write fails (the store reports it).
  bool open(const char* path) {
    std::memset(bytes_, 0xFF, sizeof bytes_);
    std::memset(programmed_, 0, sizeof programmed_);
    const uint32_t len = static_cast<uint32_t>(std::strlen(path));
    const uint32_t read_write[3] = {reinterpret_cast<uint32_t>(path), 3u /* "r+b" */, len};
    handle_ = semihost(kSysOpen, read_write);
    if (handle_ >= 0) {
      const uint32_t rd[3] = {static_cast<uint32_t>(handle_), reinterpret_cast<uint32_t>(bytes_), sizeof bytes_};
      if (semihost(kSysRead, rd) == 0) {
        markProgrammed();
        return true;
      }
      std::memset(bytes_, 0xFF, sizeof bytes_);  // a short file: start erased, as a blank part
    } else {
      const uint32_t create[3] = {reinterpret_cast<uint32_t>(path), 7u /* "w+b" */, len};
      handle_ = semihost(kSysOpen, create);
      if (handle_ < 0) return false;
    }
    return writeThrough(0, sizeof bytes_);
  }
  bool isOpen() const { return handle_ >= 0; }

  size_t pageCount() const override { return kPages; }
  size_t pageSize() const override { return kPageBytes; }

  bool read(size_t page, size_t offset, uint8_t* data, size_t n) override {
    if (!inRange(page, offset, n)) return false;
    std::memcpy(data, bytes_ + page * kPageBytes + offset, n);
    return true;
  }

  bool erase(size_t page) override {
    if (handle_ < 0 || page >= kPages) return false;
    std::memset(bytes_ + page * kPageBytes, 0xFF, kPageBytes);
    const size_t first = page * kPageBytes / hal::kFlashProgramUnit;
    for (size_t u = first; u < first + kPageBytes / hal::kFlashProgramUnit; ++u) setProgrammed(u, false);
    return writeThrough(page * kPageBytes, kPageBytes);
  }

  bool program(size_t page, size_t offset, const uint8_t* data, size_t n) override {
    if (handle_ < 0 || !inRange(page, offset, n) || offset % hal::kFlashProgramUnit != 0 || n % hal::kFlashProgramUnit != 0) {
      return false;
    }
    const size_t at = page * kPageBytes + offset;
    for (size_t u = at / hal::kFlashProgramUnit; u < (at + n) / hal::kFlashProgramUnit; ++u) {
      if (isProgrammed(u)) return false;
    }
    for (size_t i = 0; i < n; ++i) bytes_[at + i] = static_cast<uint8_t>(bytes_[at + i] & data[i]);
    for (size_t u = at / hal::kFlashProgramUnit; u < (at + n) / hal::kFlashProgramUnit; ++u) setProgrammed(u, true);
    return writeThrough(at, n);
  }

 private:
  bool inRange(size_t page, size_t offset, size_t n) const {
    return page < kPages && offset <= kPageBytes && n <= kPageBytes - offset;
  }
  bool isProgrammed(size_t unit) const { return (programmed_[unit / 8] >> (unit % 8)) & 1u; }
  void setProgrammed(size_t unit, bool on) {
    const auto bit = static_cast<uint8_t>(1u << (unit % 8));
    programmed_[unit / 8] = static_cast<uint8_t>(on ? programmed_[unit / 8] | bit : programmed_[unit / 8] & ~bit);
  }
  /// A unit read back from the file is programmed unless it is still erased (all 0xFF).
  void markProgrammed() {
    for (size_t u = 0; u < kUnits; ++u) {
      bool erased = true;
      for (size_t i = 0; i < hal::kFlashProgramUnit; ++i) erased = erased && bytes_[u * hal::kFlashProgramUnit + i] == 0xFF;
      setProgrammed(u, !erased);
    }
  }
  bool writeThrough(size_t at, size_t n) {
    const uint32_t seek[2] = {static_cast<uint32_t>(handle_), static_cast<uint32_t>(at)};
    if (semihost(kSysSeek, seek) != 0) return false;
    const uint32_t wr[3] = {static_cast<uint32_t>(handle_), reinterpret_cast<uint32_t>(bytes_ + at), static_cast<uint32_t>(n)};
    return semihost(kSysWrite, wr) == 0;
  }

  uint8_t bytes_[kPages * kPageBytes];
  uint8_t programmed_[(kUnits + 7) / 8];
  int32_t handle_ = -1;
};

}  // namespace phalanx::mcu
