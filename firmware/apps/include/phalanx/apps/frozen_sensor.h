#pragma once
/// `sensor-stuck` for an analog sensor read every tick (the glove's Hall channels, the SEA finger's joint
/// sensors): its raw count stayed identical for `stuck_ticks` ticks while related sensors of the same limb moved
/// at least `motion_counts` in total (sum of their |change| per tick) over that time. A live analog sensor's noise
/// (a few counts) changes its count every few ticks; a frozen ADC channel or a held DMA buffer does not. The
/// related sensors' motion keeps a still limb from tripping it, also on a noise-free simulated plant.
#include <cstdint>

namespace phalanx::apps {

struct FrozenSensorLimits {
  uint16_t stuck_ticks = 250;  ///< unchanged raw count this long …
  int32_t motion_counts = 40;  ///< … while the related sensors' raw counts changed this much in total
};

class FrozenSensor {
 public:
  /// One tick. `unchanged`: the raw count equals the previous tick's (false on the first tick);
  /// `related_motion`: Σ|change| of the related sensors' raw counts this tick. True while frozen.
  bool update(bool unchanged, int32_t related_motion, const FrozenSensorLimits& limits) {
    if (!unchanged) {
      ticks_ = 0;
      motion_ = 0;
      return false;
    }
    if (ticks_ < 0xFFFF) ++ticks_;
    if (motion_ < limits.motion_counts) motion_ += related_motion;  // bounded: only "reached" matters
    return ticks_ >= limits.stuck_ticks && motion_ >= limits.motion_counts;
  }

 private:
  uint16_t ticks_ = 0;
  int32_t motion_ = 0;
};

}  // namespace phalanx::apps
