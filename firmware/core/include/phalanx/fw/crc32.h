#pragma once
/// CRC-32 (IEEE 802.3, reflected poly 0xEDB88320, init and final xor 0xFFFFFFFF: zlib's crc32), incrementally:
///   uint32_t s = kCrc32Init; s = crc32Update(s, a, na); s = crc32Update(s, b, nb); crc = crc32Final(s);
/// A 16-entry table, two lookups per byte: 64 bytes of flash. Freestanding.
#include <cstddef>
#include <cstdint>

namespace phalanx::fw {

constexpr uint32_t kCrc32Init = 0xFFFFFFFFu;
uint32_t crc32Update(uint32_t state, const uint8_t* data, size_t n);
constexpr uint32_t crc32Final(uint32_t state) { return ~state; }
inline uint32_t crc32(const uint8_t* data, size_t n) { return crc32Final(crc32Update(kCrc32Init, data, n)); }

}  // namespace phalanx::fw
