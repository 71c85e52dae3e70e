#pragma once
// The glove plant in single precision, for the emulated boards' glove5 image (docs/firmware-mcu.md "The simulated
// plant on the emulated board"). hal/sim/src/glove_plant.cpp integrates in double, which the Cortex-M4F's FPU does
// not have: every operation is a libgcc call, and one millisecond of physics cost 3.7 M instructions, about 1/16
// of real time on the emulated core. glove_plant_f32.cpp compiles the same source, unmodified, with `double`
// read as `float` (and unsuffixed literals as float), in a namespace of its own so that nothing of it can mix with
// the double-precision declarations other translation units see. This header is the only way in: plain data and
// two functions, and it deliberately spells neither the project namespace nor `double` (both are macros inside
// glove_plant_f32.cpp).
#include <cstddef>
#include <cstdint>

namespace phx_glove_f32 {

/// The plant configuration the emulated board chooses (sim_devices.h PlantOptions).
struct Options {
  uint32_t seed = 1;
  uint8_t scenario = 2;     ///< sim::HandScenario
  bool noise = true;
  bool calibration_errors = true;  ///< per-sensor gain/offset/mounting errors (GlovePlantConfig)
  uint32_t substep_us = 0;  ///< 0: the plant's default (GlovePlantParams::max_substep_s, 100 µs)
};

/// The plant's view of the board: sim::SimIo's fields the glove plant reads and writes.
constexpr int kPwm = 8;
constexpr int kAdc = 32;
struct Io {
  float pwm_duty[kPwm] = {};
  bool pwm_enabled = false;
  bool drive_enable = false;
  bool estop_pressed = false;
  int32_t adc[kAdc] = {};
};

/// Storage for one plant (checked against the real size in glove_plant_f32.cpp): 6 080 B on the Cortex-M4; the
/// host build (tests) has 8-byte pointers and gets more room.
constexpr size_t kPlantBytes = sizeof(void*) == 4 ? 6144 : 10240;
constexpr size_t kPlantAlign = 8;

/// Constructs the single-precision GlovePlant in `storage` (kPlantBytes, kPlantAlign-aligned); returns it.
void* construct(void* storage, const Options& o);
/// One step of dt_s seconds: reads the actuator fields of io, writes its ADC counts.
void step(void* plant, float dt_s, Io& io);
/// The true pad force of finger 0..4 (N): the emulated board's instrument (sim_devices.h).
float padForce_N(const void* plant, int finger);

}  // namespace phx_glove_f32
