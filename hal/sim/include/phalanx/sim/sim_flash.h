#pragma once
/// Simulated flash (hal::FlashPages): RamFlash for unit tests, with a power cut after a given number of programmed
/// bytes (a torn write), erase counters, and the real parts' rules enforced (aligned double words, each programmed
/// once between erases); FileFlash for firmware-sim (--settings PATH), the pages kept in
/// one file so that a restart of the process is a power cycle of the board.
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "phalanx/hal/flash.h"

namespace phalanx::sim {

class RamFlash : public hal::FlashPages {
 public:
  RamFlash(size_t page_count, size_t page_size);
  size_t pageCount() const override { return page_count_; }
  size_t pageSize() const override { return page_size_; }
  bool read(size_t page, size_t offset, uint8_t* data, size_t n) override;
  bool erase(size_t page) override;
  bool program(size_t page, size_t offset, const uint8_t* data, size_t n) override;

  /// Power cut: after `bytes` more bytes are programmed every write fails (the byte in flight is lost too), until
  /// restorePower(). Erases then fail as well.
  void cutPowerAfter(size_t bytes) {
    cut_armed_ = true;
    bytes_left_ = bytes;
  }
  void restorePower() { cut_armed_ = false; }
  /// The cut has happened: the budget of cutPowerAfter() is spent.
  bool powerLost() const { return cut_armed_ && bytes_left_ == 0; }
  uint32_t erases(size_t page) const { return erase_count_[page]; }
  /// Contents as a file holds them: units with any byte programmed (≠ 0xFF) count as programmed.
  void loadImage(const uint8_t* data, size_t n);
  std::vector<uint8_t>& bytes() { return mem_; }

 private:
  bool inRange(size_t page, size_t offset, size_t n) const;
  size_t page_count_, page_size_;
  std::vector<uint8_t> mem_;
  std::vector<uint32_t> erase_count_;
  std::vector<bool> unit_written_;  ///< per kFlashProgramUnit: programmed since its page's erase
  bool cut_armed_ = false;
  size_t bytes_left_ = 0;
};

/// Pages backed by a file of page_count × page_size bytes (created erased when absent): firmware-sim's --settings
/// and --flash. Every erase and program is
/// written through to the file at once (fflush), as flash keeps data once programmed.
class FileFlash : public hal::FlashPages {
 public:
  FileFlash(size_t page_count, size_t page_size) : ram_(page_count, page_size) {}
  ~FileFlash() override;
  /// "" or the problem (cannot create, wrong size: not a settings file of this geometry).
  std::string open(const std::string& path);
  size_t pageCount() const override { return ram_.pageCount(); }
  size_t pageSize() const override { return ram_.pageSize(); }
  bool read(size_t page, size_t offset, uint8_t* data, size_t n) override { return ram_.read(page, offset, data, n); }
  bool erase(size_t page) override;
  bool program(size_t page, size_t offset, const uint8_t* data, size_t n) override;
  /// As RamFlash's: firmware-sim's --flash-power-cut-after (the process then ends as a board losing power would).
  void cutPowerAfter(size_t bytes) { ram_.cutPowerAfter(bytes); }
  bool powerLost() const { return ram_.powerLost(); }

 private:
  bool writeThrough(size_t page);
  RamFlash ram_;
  std::FILE* f_ = nullptr;
};

}  // namespace phalanx::sim
