#pragma once
/// The simulated plant the emulated board links in for each device app (the same plant classes firmware-sim
/// runs on Linux), chosen with the app (PHALANX_MCU_APP_<NAME>).
#include <cstdint>

#include "phalanx/fw_mcu/app_registry.h"

namespace phalanx::mcu::qemu {
/// True if the len characters at s spell name exactly.
inline bool spells(const char* s, int len, const char* name) {
  int i = 0;
  for (; i < len && name[i] != 0; ++i) {
    if (name[i] != s[i]) return false;
  }
  return i == len && name[i] == 0;
}
/// An instrument reading in micro-units (µN, µN·m), clamped to the int32 the instrument line carries.
inline int32_t microUnits(double si) {
  const double v = si * 1e6;
  return static_cast<int32_t>(v < -2e9 ? -2e9 : (v > 2e9 ? 2e9 : v));
}
}  // namespace phalanx::mcu::qemu

#if defined(PHALANX_MCU_APP_GLOVE5)
#include "phalanx/sim/glove_plant.h"
#if PHALANX_GLOVE_PLANT_F32
#include "glove_plant_f32.h"
#endif
namespace phalanx::mcu::qemu {
struct PlantOptions {
  uint32_t seed = 1;
  uint8_t scenario = 2;  ///< sim::HandScenario (kGrasp, as firmware-sim's default)
  bool noise = true;
  uint32_t substep_us = 0;  ///< plant integration step (0: the plant's default, 100 µs)
};
#if PHALANX_GLOVE_PLANT_F32
/// The glove plant in single precision (glove_plant_f32.h: the same source as sim::GlovePlant,
/// compiled with float, so that it keeps real time on the emulated core). Same interface as the double plant.
class GlovePlantF32 {
 public:
  explicit GlovePlantF32(const phx_glove_f32::Options& o) : plant_(phx_glove_f32::construct(storage_, o)) {}
  void step(double dt_s, sim::SimIo& io) {
    for (int i = 0; i < phx_glove_f32::kPwm; ++i) io_.pwm_duty[i] = io.pwm_duty[static_cast<size_t>(i)];
    io_.pwm_enabled = io.pwm_enabled;
    io_.drive_enable = io.drive_enable;
    io_.estop_pressed = io.estop_pressed;
    phx_glove_f32::step(plant_, static_cast<float>(dt_s), io_);
    for (int i = 0; i < phx_glove_f32::kAdc; ++i) io.adc[static_cast<size_t>(i)] = io_.adc[i];
  }
  double padForce_N(int finger) const { return static_cast<double>(phx_glove_f32::padForce_N(plant_, finger)); }

 private:
  static_assert(phx_glove_f32::kPwm == sim::kMaxPwm && phx_glove_f32::kAdc == sim::kMaxAdc, "SimIo sizes");
  alignas(phx_glove_f32::kPlantAlign) unsigned char storage_[phx_glove_f32::kPlantBytes];
  void* plant_;
  phx_glove_f32::Io io_{};
};
using PlantType = GlovePlantF32;
inline phx_glove_f32::Options plantConfig(const PlantOptions& o) {
  phx_glove_f32::Options c;
  c.seed = o.seed;
  c.noise = o.noise;
  c.scenario = o.scenario;
  c.substep_us = o.substep_us;
  return c;
}
#else
using PlantType = sim::GlovePlant;
inline sim::GlovePlantConfig plantConfig(const PlantOptions& o) {
  sim::GlovePlantConfig c;
  c.seed = o.seed;
  c.noise = o.noise;
  c.scenario = static_cast<sim::HandScenario>(o.scenario);
  if (o.substep_us != 0) c.params.max_substep_s = static_cast<double>(o.substep_us) * 1e-6;
  return c;
}
#endif
/// "still" | "close-open" | "grasp" | "random" → scenario number, or −1.
inline int scenarioNumber(const char* s, int len) {
  auto is = [&](const char* name) { return spells(s, len, name); };
  if (is("still")) return static_cast<int>(sim::HandScenario::kStill);
  if (is("close-open")) return static_cast<int>(sim::HandScenario::kCloseOpen);
  if (is("grasp")) return static_cast<int>(sim::HandScenario::kGrasp);
  if (is("random")) return static_cast<int>(sim::HandScenario::kRandom);
  return -1;
}
/// The simulated instrument (option instrument=1): a fingertip force sensor on the index finger, its true pad
/// force, as firmware-sim's glove5 serves it by default (`pad_force_index_N`), in µN.
constexpr const char* kInstrumentSignal = "pad_force_index_uN";
inline int32_t instrumentMicro(const PlantType& p) { return microUnits(p.padForce_N(1)); }
}  // namespace phalanx::mcu::qemu

#elif defined(PHALANX_MCU_APP_SEA_FINGER)
// The SEA rig (§7.1 of seeds/001: both exoskeleton joints clamped to load cells), firmware-sim's `sea_rig`.
#include "phalanx/sim/sea_plant.h"
namespace phalanx::mcu::qemu {
using PlantType = sim::SeaPlant;
struct PlantOptions {
  uint32_t seed = 1;
  uint8_t scenario = 0;  ///< sim::SeaVariant (kRig, the only variant)
  bool noise = true;
  uint32_t substep_us = 0;  ///< plant integration step (0: the plant's default, 100 µs)
};
inline sim::SeaPlantConfig plantConfig(const PlantOptions& o) {
  sim::SeaPlantConfig c;
  c.seed = o.seed;
  c.noise = o.noise;
  c.variant = static_cast<sim::SeaVariant>(o.scenario);
  if (o.substep_us != 0) c.params.max_substep_s = static_cast<double>(o.substep_us) * 1e-6;
  return c;
}
/// "rig" → variant number, or −1.
inline int scenarioNumber(const char* s, int len) {
  if (spells(s, len, "rig")) return static_cast<int>(sim::SeaVariant::kRig);
  return -1;
}
/// The simulated instrument (option instrument=1): the rig's load cell on SEA 0, its true joint torque, as
/// firmware-sim's sea_rig serves it (docs/bench-runner.md "Devices"), in µN·m.
constexpr const char* kInstrumentSignal = "joint_torque_uNm";
inline int32_t instrumentMicro(const PlantType& p) { return microUnits(p.truth(0).joint_torque_Nm); }
}  // namespace phalanx::mcu::qemu
#elif defined(PHALANX_MCU_APP_PANTOGRAPH)
// The pen and the hand holding it, as firmware-sim's `pantograph` (same scenario names: the hand holds the pen
// for still/grasp, moves it for random/close-open; "released" takes the hand off).
#include "phalanx/sim/pen_plant.h"
namespace phalanx::mcu::qemu {
using PlantType = sim::PenPlant;
struct PlantOptions {
  uint32_t seed = 1;
  uint8_t scenario = 1;  ///< sim::PenHandScenario (kHold, as firmware-sim's default "grasp")
  bool noise = true;
  uint32_t substep_us = 0;  ///< plant integration step (0: the plant's default, 100 µs)
};
inline sim::PenPlantConfig plantConfig(const PlantOptions& o) {
  sim::PenPlantConfig c;
  c.seed = o.seed;
  c.noise = o.noise;
  c.scenario = static_cast<sim::PenHandScenario>(o.scenario);
  if (o.substep_us != 0) c.params.max_substep_s = static_cast<double>(o.substep_us) * 1e-6;
  return c;
}
/// "still" | "grasp" (hold) | "close-open" | "random" (move) | "released" → scenario number, or −1.
inline int scenarioNumber(const char* s, int len) {
  if (spells(s, len, "still") || spells(s, len, "grasp")) return static_cast<int>(sim::PenHandScenario::kHold);
  if (spells(s, len, "random") || spells(s, len, "close-open")) return static_cast<int>(sim::PenHandScenario::kRandom);
  if (spells(s, len, "released")) return static_cast<int>(sim::PenHandScenario::kReleased);
  return -1;
}
/// The simulated instrument (option instrument=1): none on the pen board. Its plant cannot keep real time on the
/// emulated core (docs/firmware-mcu.md: about 1.9 M instructions per simulated ms), so a force it served would not
/// belong to the board's ticks.
constexpr const char* kInstrumentSignal = nullptr;
inline int32_t instrumentMicro(const PlantType&) { return 0; }
}  // namespace phalanx::mcu::qemu
#else
#error "no simulated plant for this device app on the emulated board (firmware/boards/qemu/sim_devices.h)"
#endif
