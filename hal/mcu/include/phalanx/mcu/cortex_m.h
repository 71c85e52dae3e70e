#pragma once
/// Cortex-M4 core registers used by both MCU boards (ARMv7-M Architecture Reference Manual, DDI 0403E: B3.2
/// System Control Space, B3.3 SysTick, B3.4 NVIC; FPU: Cortex-M4 TRM §7). Only what the boards use, defined here
/// instead of CMSIS. Target-only (raw addresses): not included by host code.
#include <cstdint>

namespace phalanx::mcu::cm4 {

inline volatile uint32_t& reg(uint32_t address) { return *reinterpret_cast<volatile uint32_t*>(address); }
inline volatile uint8_t& reg8(uint32_t address) { return *reinterpret_cast<volatile uint8_t*>(address); }

// SysTick (B3.3.2)
constexpr uint32_t kSysTickCsr = 0xE000E010u;   ///< ENABLE [0], TICKINT [1], CLKSOURCE [2] (1 = core clock), COUNTFLAG [16]
constexpr uint32_t kSysTickRvr = 0xE000E014u;   ///< 24-bit reload
constexpr uint32_t kSysTickCvr = 0xE000E018u;   ///< current value (counts down; any write clears it)
// System control block (B3.2.2)
constexpr uint32_t kScbIcsr = 0xE000ED04u;      ///< PENDSTSET [26]
constexpr uint32_t kScbVtor = 0xE000ED08u;
constexpr uint32_t kScbAircr = 0xE000ED0Cu;     ///< VECTKEY 0x05FA [31:16], SYSRESETREQ [2]
constexpr uint32_t kScbShpr3 = 0xE000ED20u;     ///< PRI_15 SysTick [31:24], PRI_14 PendSV [23:16]
constexpr uint32_t kScbCfsr = 0xE000ED28u;
constexpr uint32_t kScbHfsr = 0xE000ED2Cu;
constexpr uint32_t kScbCpacr = 0xE000ED88u;     ///< CP10/CP11 full access = 0xF << 20
// NVIC (B3.4.3)
constexpr uint32_t kNvicIser = 0xE000E100u;
constexpr uint32_t kNvicIcer = 0xE000E180u;
constexpr uint32_t kNvicIpr = 0xE000E400u;      ///< one byte per IRQ; the M4 implements the top bits

constexpr uint32_t kIcsrPendStSet = 1u << 26;

inline void enableIrq(uint32_t irq) { reg(kNvicIser + 4u * (irq / 32u)) = 1u << (irq % 32u); }
inline void disableIrq(uint32_t irq) { reg(kNvicIcer + 4u * (irq / 32u)) = 1u << (irq % 32u); }
inline void setIrqPriority(uint32_t irq, uint8_t priority) { reg8(kNvicIpr + irq) = priority; }
inline void setSysTickPriority(uint8_t priority) {
  reg(kScbShpr3) = (reg(kScbShpr3) & 0x00FFFFFFu) | (static_cast<uint32_t>(priority) << 24);
}

/// SysTick on the core clock with its interrupt, period reload + 1 clocks.
inline void startSysTick(uint32_t reload) {
  reg(kSysTickCsr) = 0;
  reg(kSysTickRvr) = reload & 0x00FFFFFFu;
  reg(kSysTickCvr) = 0;
  reg(kSysTickCsr) = 0x7u;
}
inline uint32_t sysTickValue() { return reg(kSysTickCvr); }
inline bool sysTickPending() { return (reg(kScbIcsr) & kIcsrPendStSet) != 0; }

inline void disableInterrupts() { __asm volatile("cpsid i" ::: "memory"); }
inline void enableInterrupts() { __asm volatile("cpsie i" ::: "memory"); }
inline void waitForInterrupt() { __asm volatile("dsb\n wfi" ::: "memory"); }

/// C/C++ run-time start after the reset handler enabled the FPU: copy .data, zero .bss, run constructors.
/// Symbols come from each board's linker script.
extern "C" uint32_t __data_load__, __data_start__, __data_end__, __bss_start__, __bss_end__;
extern "C" uint32_t __stack_bottom__, __stack_top__;
constexpr uint32_t kStackPaint = 0xA5A5A5A5u;
extern "C" void (*__init_array_start[])();
extern "C" void (*__init_array_end[])();
inline void runtimeInit() {
  const uint32_t* src = &__data_load__;
  for (uint32_t* dst = &__data_start__; dst < &__data_end__;) *dst++ = *src++;
  for (uint32_t* dst = &__bss_start__; dst < &__bss_end__;) *dst++ = 0;
  // Paint the unused stack so stackHighWater() can tell how deep it has ever been (stop 64 bytes below the
  // current frame).
  uint32_t* sp = nullptr;
  __asm volatile("mov %0, sp" : "=r"(sp));
  for (uint32_t* p = &__stack_bottom__; p < sp - 16; ++p) *p = kStackPaint;
  for (auto* fn = __init_array_start; fn < __init_array_end; ++fn) (*fn)();
}

/// Bytes of stack ever used (from the top down to the deepest overwritten paint word).
inline uint32_t stackHighWater() {
  const uint32_t* p = &__stack_bottom__;
  while (p < &__stack_top__ && *p == kStackPaint) ++p;
  return static_cast<uint32_t>(reinterpret_cast<uintptr_t>(&__stack_top__) - reinterpret_cast<uintptr_t>(p));
}

}  // namespace phalanx::mcu::cm4

/// The reset handler both boards use: enable CP10/CP11 (the FPU) before any floating-point instruction can run,
/// then continue in C++ at phalanx_reset_continue (the board's). Written in assembly so the compiler cannot
/// schedule an FPU instruction (e.g. a VPUSH in a prologue) ahead of the CPACR write.
#define PHALANX_CM4_RESET_HANDLER()                                                                   \
  extern "C" [[noreturn]] void phalanx_reset_continue();                                             \
  extern "C" __attribute__((naked, noreturn)) void Reset_Handler() {                                 \
    __asm volatile(                                                                                   \
        "ldr r0, =0xE000ED88\n"                                                                       \
        "ldr r1, [r0]\n"                                                                              \
        "orr r1, r1, #0x00F00000\n"                                                                   \
        "str r1, [r0]\n"                                                                              \
        "dsb\n"                                                                                       \
        "isb\n"                                                                                       \
        "b phalanx_reset_continue\n");                                                                \
  }
