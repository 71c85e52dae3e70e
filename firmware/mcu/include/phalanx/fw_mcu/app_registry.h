#pragma once
/// The device app an MCU image carries. firmware/mcu/CMakeLists.txt builds one image per (board, app) and defines
/// PHALANX_MCU_APP_<NAME>; adding an app is one entry here plus its name in PHALANX_MCU_APPS there.
#include <cstdint>
#include <new>
#include <utility>

#include "phalanx/fw/app.h"

namespace phalanx::fw_mcu {

/// Storage for one statically allocated object constructed at init (no heap: placement into a member array).
template <class T>
class StaticObject {
 public:
  template <class... Args>
  T& emplace(Args&&... args) {
    ptr_ = new (static_cast<void*>(storage_)) T(std::forward<Args>(args)...);
    return *ptr_;
  }
  T& get() { return *ptr_; }
  bool constructed() const { return ptr_ != nullptr; }

 private:
  alignas(T) unsigned char storage_[sizeof(T)];
  T* ptr_ = nullptr;
};

}  // namespace phalanx::fw_mcu

#if defined(PHALANX_MCU_APP_GLOVE5)
#include "phalanx/apps/glove5.h"
#include "phalanx/glove/board.h"
namespace phalanx::fw_mcu {
using AppType = apps::Glove5App;
constexpr const char* kAppName = "glove5";
constexpr uint8_t kAppPwmCount = glove::board::kPwmChannelCount;
constexpr uint8_t kAppAdcCount = glove::board::kAdcChannelCount;
constexpr uint8_t kAppEncoderCount = 0;
inline AppType& constructApp(StaticObject<AppType>& s) {
  return s.emplace(apps::glove5DefaultCalibration(), apps::glove5DefaultConfig());
}
}  // namespace phalanx::fw_mcu
#elif defined(PHALANX_MCU_APP_SEA_FINGER)
#include "phalanx/apps/sea_finger.h"
#include "phalanx/sea/board.h"
namespace phalanx::fw_mcu {
using AppType = apps::SeaFingerApp;
constexpr const char* kAppName = "sea_finger";
constexpr uint8_t kAppPwmCount = sea::board::kPwmChannelCount;
constexpr uint8_t kAppAdcCount = sea::board::kAdcChannelCount;
constexpr uint8_t kAppEncoderCount = sea::board::kEncoderChannelCount;
inline AppType& constructApp(StaticObject<AppType>& s) {
  return s.emplace(apps::seaFingerDefaultCalibration(), apps::seaFingerDefaultConfig());
}
}  // namespace phalanx::fw_mcu
#elif defined(PHALANX_MCU_APP_PANTOGRAPH)
#include "phalanx/apps/pantograph.h"
#include "phalanx/pen/board.h"
namespace phalanx::fw_mcu {
using AppType = apps::PantographApp;
constexpr const char* kAppName = "pantograph";
constexpr uint8_t kAppPwmCount = pen::board::kPwmChannelCount;
constexpr uint8_t kAppAdcCount = pen::board::kAdcChannelCount;
constexpr uint8_t kAppEncoderCount = pen::board::kEncoderChannelCount;
inline AppType& constructApp(StaticObject<AppType>& s) { return s.emplace(apps::pantographDefaultConfig()); }
}  // namespace phalanx::fw_mcu
#else
#error "no device app selected: define PHALANX_MCU_APP_<NAME> (see firmware/mcu/CMakeLists.txt)"
#endif
