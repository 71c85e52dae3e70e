#pragma once
// A firmware image for the update tests: random bytes with a valid image-info block (common/include/phalanx/
// image_info.h), its CRC computed by the host's zlib-based flash::imageCrc, as the MCU build's image_info.py does.
// The bytes are not ARM code: what the update path checks and moves is the image's identity and integrity.
#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

#include "phalanx/host/flash.h"
#include "phalanx/image_info.h"

namespace phalanx::test {

inline std::vector<uint8_t> makeImage(uint32_t build_id, uint8_t device_type = 1,
                                      image::BoardId board = image::BoardId::kStm32g474, uint32_t size = 42001) {
  std::mt19937 rng(build_id);
  std::vector<uint8_t> b(size);
  for (uint8_t& x : b) x = static_cast<uint8_t>(rng());
  image::ImageInfo info;
  info.device_type = device_type;
  info.board = static_cast<uint8_t>(board);
  info.build_id = build_id;
  info.load_address = image::boardPart(board)->flash_origin;
  info.image_size = size;
  info.image_crc32 = 0;
  std::memcpy(&b[image::kImageInfoOffset], &info, sizeof info);  // little-endian host, as the targets
  info.image_crc32 = host::flash::imageCrc(b);
  std::memcpy(&b[image::kImageInfoOffset], &info, sizeof info);
  return b;
}

/// The image-info block of an image made by makeImage (or any image on a little-endian host).
inline image::ImageInfo infoOf(const std::vector<uint8_t>& img) {
  image::ImageInfo info;
  std::memcpy(&info, &img[image::kImageInfoOffset], sizeof info);
  return info;
}

}  // namespace phalanx::test
