#include "phalanx/fw/crc32.h"

namespace phalanx::fw {

namespace {
// CRC of each 4-bit value through four reflected steps of poly 0xEDB88320.
constexpr uint32_t kNibble[16] = {
    0x00000000u, 0x1DB71064u, 0x3B6E20C8u, 0x26D930ACu, 0x76DC4190u, 0x6B6B51F4u, 0x4DB26158u, 0x5005713Cu,
    0xEDB88320u, 0xF00F9344u, 0xD6D6A3E8u, 0xCB61B38Cu, 0x9B64C2B0u, 0x86D3D2D4u, 0xA00AE278u, 0xBDBDF21Cu,
};
}  // namespace

uint32_t crc32Update(uint32_t state, const uint8_t* data, size_t n) {
  for (size_t i = 0; i < n; ++i) {
    state ^= data[i];
    state = (state >> 4) ^ kNibble[state & 0x0Fu];
    state = (state >> 4) ^ kNibble[state & 0x0Fu];
  }
  return state;
}

}  // namespace phalanx::fw
