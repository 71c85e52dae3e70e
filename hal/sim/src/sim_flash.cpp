#include "phalanx/sim/sim_flash.h"

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace phalanx::sim {

RamFlash::RamFlash(size_t page_count, size_t page_size)
    : page_count_(page_count),
      page_size_(page_size),
      mem_(page_count * page_size, 0xFF),
      erase_count_(page_count, 0),
      unit_written_(page_count * page_size / hal::kFlashProgramUnit, false) {}

bool RamFlash::inRange(size_t page, size_t offset, size_t n) const {
  return page < page_count_ && offset <= page_size_ && n <= page_size_ - offset;
}

void RamFlash::loadImage(const uint8_t* data, size_t n) {
  const size_t len = n < mem_.size() ? n : mem_.size();
  std::memcpy(mem_.data(), data, len);
  for (size_t u = 0; u < unit_written_.size(); ++u) {
    bool erased = true;
    for (size_t i = 0; i < hal::kFlashProgramUnit; ++i) erased = erased && mem_[u * hal::kFlashProgramUnit + i] == 0xFF;
    unit_written_[u] = !erased;
  }
}

bool RamFlash::read(size_t page, size_t offset, uint8_t* data, size_t n) {
  if (!inRange(page, offset, n)) return false;
  std::memcpy(data, &mem_[page * page_size_ + offset], n);
  return true;
}

bool RamFlash::erase(size_t page) {
  if (page >= page_count_) return false;
  if (cut_armed_ && bytes_left_ == 0) return false;
  std::memset(&mem_[page * page_size_], 0xFF, page_size_);
  const size_t units = page_size_ / hal::kFlashProgramUnit;
  for (size_t u = 0; u < units; ++u) unit_written_[page * units + u] = false;
  ++erase_count_[page];
  return true;
}

bool RamFlash::program(size_t page, size_t offset, const uint8_t* data, size_t n) {
  if (!inRange(page, offset, n) || offset % hal::kFlashProgramUnit != 0 || n % hal::kFlashProgramUnit != 0) return false;
  const size_t first_unit = (page * page_size_ + offset) / hal::kFlashProgramUnit;
  for (size_t u = 0; u < n / hal::kFlashProgramUnit; ++u) {
    if (unit_written_[first_unit + u]) return false;
  }
  uint8_t* dst = &mem_[page * page_size_ + offset];
  for (size_t i = 0; i < n; ++i) {
    if (i % hal::kFlashProgramUnit == 0) unit_written_[first_unit + i / hal::kFlashProgramUnit] = true;
    if (cut_armed_) {
      if (bytes_left_ == 0) return false;
      --bytes_left_;
    }
    dst[i] = static_cast<uint8_t>(dst[i] & data[i]);
  }
  return true;
}

FileFlash::~FileFlash() {
  if (f_ != nullptr) std::fclose(f_);
}

std::string FileFlash::open(const std::string& path) {
  const size_t total = ram_.pageCount() * ram_.pageSize();
  f_ = std::fopen(path.c_str(), "r+b");
  if (f_ == nullptr && errno == ENOENT) {
    f_ = std::fopen(path.c_str(), "w+b");
    if (f_ == nullptr) return path + ": " + std::strerror(errno);
    for (size_t p = 0; p < ram_.pageCount(); ++p) {
      if (!writeThrough(p)) return path + ": cannot write the erased pages";
    }
    return {};
  }
  if (f_ == nullptr) return path + ": " + std::strerror(errno);
  std::vector<uint8_t> buf(total + 1);
  const size_t n = std::fread(buf.data(), 1, buf.size(), f_);
  if (n != total) {
    return path + ": " + std::to_string(n) + " bytes, this flash file holds " + std::to_string(total) +
           " (not a flash file of this board's geometry?)";
  }
  ram_.loadImage(buf.data(), total);
  return {};
}

bool FileFlash::writeThrough(size_t page) {
  if (f_ == nullptr) return false;
  const size_t size = ram_.pageSize();
  if (std::fseek(f_, static_cast<long>(page * size), SEEK_SET) != 0) return false;
  if (std::fwrite(&ram_.bytes()[page * size], 1, size, f_) != size) return false;
  return std::fflush(f_) == 0;
}

bool FileFlash::erase(size_t page) { return ram_.erase(page) && writeThrough(page); }

bool FileFlash::program(size_t page, size_t offset, const uint8_t* data, size_t n) {
  // Written through even when the program failed part-way: what a torn write left is what the flash holds.
  const bool programmed = ram_.program(page, offset, data, n);
  return writeThrough(page) && programmed;
}

}  // namespace phalanx::sim
