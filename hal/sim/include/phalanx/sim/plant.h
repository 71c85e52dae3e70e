#pragma once
/// Simulated hardware: the I/O image that a simulated board exposes to firmware, and the plant interface that
/// turns actuator outputs into sensor readings on a virtual clock.
#include <array>
#include <cstdint>

namespace phalanx::sim {

constexpr int kMaxPwm = 8;
constexpr int kMaxAdc = 32;
constexpr int kMaxEncoders = 8;

/// What the firmware writes (PWM, enable) and reads (ADC counts, encoder counts, e-stop) on a simulated board.
struct SimIo {
  std::array<float, kMaxPwm> pwm_duty{};         ///< [-1, 1] per H-bridge, written by firmware
  bool pwm_enabled = false;                      ///< false: bridges high-impedance (safe state)
  bool drive_enable = false;                     ///< drive-enable GPIO output
  std::array<int32_t, kMaxAdc> adc{};            ///< raw counts, written by the plant
  std::array<int32_t, kMaxEncoders> encoder{};   ///< accumulated counts, written by the plant
  bool estop_pressed = false;                    ///< e-stop input
};

/// A physical model of one device plus its user. step() advances physics by dt_s using io's actuator outputs
/// and writes io's sensor inputs. Deterministic for a given seed.
class Plant {
 public:
  virtual ~Plant() = default;
  virtual void step(double dt_s, SimIo& io) = 0;
  /// `steps` consecutive steps of dt_s with io's actuator outputs unchanged in between, as that many step()
  /// calls would do them; io's sensor readings are those of the last step. A plant may override it to skip
  /// the sensor readings nothing can see (the lockstep rig and firmware-sim read them once per tick).
  virtual void advance(double dt_s, unsigned steps, SimIo& io) {
    for (unsigned i = 0; i < steps; ++i) step(dt_s, io);
  }
};

}  // namespace phalanx::sim
