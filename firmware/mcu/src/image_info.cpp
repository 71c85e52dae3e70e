// The image-info block of this image (common/include/phalanx/image_info.h): compiled into every image with the
// image's app and board (PHALANX_MCU_APP_<NAME>, PHALANX_MCU_BOARD_ID, PHALANX_BUILD_ID from
// firmware/mcu/CMakeLists.txt) and placed at kImageInfoOffset by phalanx-sections.ld. Its image_size and image_crc32
// are filled in after the link (firmware/mcu/cmake/image_info.py, which also re-checks every field set here).
#include "phalanx/image_info.h"

#include "phalanx/protocol/messages.h"

namespace {
using phalanx::image::BoardId;
using phalanx::protocol::DeviceType;

#if defined(PHALANX_MCU_APP_GLOVE5)
constexpr DeviceType kDevice = DeviceType::kGlove5;
#elif defined(PHALANX_MCU_APP_SEA_FINGER)
constexpr DeviceType kDevice = DeviceType::kSeaFinger;
#elif defined(PHALANX_MCU_APP_PANTOGRAPH)
constexpr DeviceType kDevice = DeviceType::kPantograph;
#else
#error "no device app selected: define PHALANX_MCU_APP_<NAME> (see firmware/mcu/CMakeLists.txt)"
#endif

#if !defined(PHALANX_MCU_BOARD_ID) || !defined(PHALANX_BUILD_ID)
#error "PHALANX_MCU_BOARD_ID and PHALANX_BUILD_ID are set by firmware/mcu/CMakeLists.txt"
#endif
constexpr BoardId kBoard = static_cast<BoardId>(PHALANX_MCU_BOARD_ID);
// A board id that names no part fails here: boardPart() returns nullptr, which a constant expression cannot read.
static_assert(phalanx::image::boardPart(kBoard)->id == kBoard, "PHALANX_MCU_BOARD_ID names no board in image_info.h");

constexpr phalanx::image::ImageInfo makeInfo() {
  phalanx::image::ImageInfo info{};
  info.device_type = static_cast<uint8_t>(kDevice);
  info.board = static_cast<uint8_t>(kBoard);
  info.build_id = PHALANX_BUILD_ID;
  info.load_address = phalanx::image::boardPart(kBoard)->flash_origin;
  return info;
}
}  // namespace

extern "C" __attribute__((section(".image_info"), used)) const phalanx::image::ImageInfo phalanx_image_info = makeInfo();
