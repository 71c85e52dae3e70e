#pragma once
/// Quadrature-encoder register values for the STM32G4, pure functions tested on the host: the timers' encoder
/// interface (TIM1–TIM5, TIM8, TIM20; RM0440 §28.3.26 / §29.4.23) and the low-power timer's encoder mode
/// (LPTIM1, RM0440 §38.4.15). The 16-bit counts they produce are extended to 32 bits by EncoderExtender
/// (stm32g4_timer.h).
#include <cstdint>

namespace phalanx::mcu::stm32g4 {

/// Digital input filter, both kinds of timer: the input must be stable for this many kernel-clock samples before
/// an edge counts. 8 samples at 170 MHz = 47 ns: rejects ringing on a long encoder cable, and still passes edges
/// 4× faster than a 4000-count/turn encoder at 10 000 rev/s.
constexpr uint32_t kEncoderFilterSamples = 8;

/// TIMx_CCMR1 for encoder mode: CC1S = CC2S = 01 (IC1 ← TI1, IC2 ← TI2), IC1F = IC2F = the filter code for
/// `samples` consecutive samples at f_CK_INT (codes 0001 → 2, 0010 → 4, 0011 → 8 samples; RM0440 TIMx_CCMR1
/// IC1F). Other sample counts are refused (ok = false): the longer filters sample at divided clocks.
struct TimEncoderCcmr1 {
  bool ok = false;
  uint32_t value = 0;
};
constexpr TimEncoderCcmr1 timEncoderCcmr1(uint32_t samples) {
  uint32_t code = 0;
  if (samples == 1) code = 0;
  else if (samples == 2) code = 1;
  else if (samples == 4) code = 2;
  else if (samples == 8) code = 3;
  else return {};
  return {true, (1u << 0) | (code << 4) | (1u << 8) | (code << 12)};
}
/// TIMx_SMCR.SMS = 0011: encoder mode 3, the counter counts on every edge of TI1 and TI2 (×4 decoding).
constexpr uint32_t kTimSmcrEncoderX4 = 0x3u;

/// LPTIM_CFGR for encoder mode (RM0440 §38.4.15, §38.7.4): ENC (bit 24) = 1, CKSEL (bit 0) = 0 (internal clock,
/// mandatory in encoder mode), PRESC[11:9] = 000 (mandatory), CKPOL[2:1] = 10 (both edges of both inputs: ×4
/// decoding, Table 307), CKFLT[4:3] = the filter code for `samples` (00 → none, 01 → 2, 10 → 4, 11 → 8 clock
/// periods). Everything else 0: software trigger, continuous mode is started by CR.CNTSTRT.
struct LptimEncoderCfgr {
  bool ok = false;
  uint32_t value = 0;
};
constexpr LptimEncoderCfgr lptimEncoderCfgr(uint32_t samples) {
  uint32_t code = 0;
  if (samples == 1) code = 0;
  else if (samples == 2) code = 1;
  else if (samples == 4) code = 2;
  else if (samples == 8) code = 3;
  else return {};
  return {true, (1u << 24) | (0x2u << 1) | (code << 3)};
}
constexpr uint32_t kLptimCrEnable = 1u << 0, kLptimCrCntstrt = 1u << 2;
constexpr uint32_t kLptimIsrArrok = 1u << 4;

/// LPTIM_CNT may be read while the counter changes (RM0440 §38.7.8: "two consecutive read accesses must be
/// performed and compared"). Reads until two consecutive values agree, at most `max_reads` reads; returns the
/// last value and whether it was confirmed. `read` is any callable returning the 16-bit counter.
struct ConfirmedRead {
  bool ok = false;
  uint16_t value = 0;
};
template <class Read>
ConfirmedRead confirmedRead(Read&& read, int max_reads = 4) {
  uint16_t prev = static_cast<uint16_t>(read());
  for (int i = 1; i < max_reads; ++i) {
    const uint16_t v = static_cast<uint16_t>(read());
    if (v == prev) return {true, v};
    prev = v;
  }
  return {false, prev};
}

}  // namespace phalanx::mcu::stm32g4
