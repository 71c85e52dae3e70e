// The glove plant (hal/sim/src/glove_plant.cpp, unmodified) compiled in single precision for the emulated boards:
// see glove_plant_f32.h for why. Mechanics of this translation unit:
//  - plant_no_throw.h is included first (as for every plant on the emulated board): it reads every standard header
//    the plant uses with the real keywords, then turns `throw` into a fault call;
//  - only then `double` becomes `float` and the project namespace `phalanx` becomes `phalanx_f32`, so the plant,
//    the glove model headers (templates on the scalar type) and SimIo are compiled afresh in their own namespace:
//    no symbol of this file can be merged with a double-precision one of another translation unit (ODR), and
//    the standard library, already parsed, keeps its own types;
//  - the build adds -fsingle-precision-constant for this file (unsuffixed literals are float), so no arithmetic
//    is promoted back to double (-Wdouble-promotion stays an error).
#include "plant_no_throw.h"
#include "glove_plant_f32.h"

#include <new>

// NOLINTBEGIN: redefining a keyword and the namespace is deliberate and confined to this translation unit.
#define phalanx phalanx_f32
#define double float
// Two int → double conversions become int → float: substep counts and indices (≤ 10^4), exact in float.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wconversion"
#include "../../../hal/sim/src/glove_plant.cpp"
#pragma GCC diagnostic pop
#undef double
#undef phalanx
// NOLINTEND


namespace phx_glove_f32 {

namespace sim32 = ::phalanx_f32::sim;
static_assert(sizeof(sim32::GlovePlant) <= kPlantBytes && alignof(sim32::GlovePlant) <= kPlantAlign,
              "glove_plant_f32.h: kPlantBytes too small for the single-precision GlovePlant");
static_assert(sizeof(void*) != 4 || sizeof(sim32::GlovePlant) + 256 > kPlantBytes,
              "glove_plant_f32.h: kPlantBytes wastes RAM on the MCU");
static_assert(sim32::kMaxPwm == kPwm && sim32::kMaxAdc == kAdc, "SimIo sizes");
static_assert(sizeof(float) == 4 && sizeof(sim32::GlovePlantParams{}.max_substep_s) == 4, "single precision");

void* construct(void* storage, const Options& o) {
  sim32::GlovePlantConfig c;
  c.seed = o.seed;
  c.noise = o.noise;
  c.calibration_errors = o.calibration_errors;
  c.scenario = static_cast<sim32::HandScenario>(o.scenario);
  if (o.substep_us != 0) c.params.max_substep_s = static_cast<float>(o.substep_us) * 1e-6f;
  return new (storage) sim32::GlovePlant(c);
}

void step(void* plant, float dt_s, Io& io) {
  sim32::SimIo s;
  for (int i = 0; i < kPwm; ++i) s.pwm_duty[static_cast<size_t>(i)] = io.pwm_duty[i];
  s.pwm_enabled = io.pwm_enabled;
  s.drive_enable = io.drive_enable;
  s.estop_pressed = io.estop_pressed;
  for (int i = 0; i < kAdc; ++i) s.adc[static_cast<size_t>(i)] = io.adc[i];
  static_cast<sim32::GlovePlant*>(plant)->step(dt_s, s);
  for (int i = 0; i < kAdc; ++i) io.adc[i] = s.adc[static_cast<size_t>(i)];
}

float padForce_N(const void* plant, int finger) { return static_cast<const sim32::GlovePlant*>(plant)->padForce_N(finger); }

}  // namespace phx_glove_f32
