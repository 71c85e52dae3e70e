#pragma once
/// STM32G474 registers this port uses, from RM0440 rev 8 (STM32G4 reference manual): base addresses from §2.2.2
/// (memory map, Table 4), offsets and bits from each peripheral's register chapter. Written out by hand instead of
/// the vendor CMSIS headers; only what the drivers touch.
///
/// Constants marked "board" are this project's pin/channel assignment for its G474 motor board (a design
/// decision, not the reference manual); they have not been checked against a schematic or on silicon.
#include <cstdint>

namespace phalanx::mcu::g474 {

inline volatile uint32_t& reg(uint32_t address) { return *reinterpret_cast<volatile uint32_t*>(address); }

// ---- Base addresses (RM0440 Table 4) ----
constexpr uint32_t kTim2 = 0x40000000u, kTim3 = 0x40000400u, kTim4 = 0x40000800u, kTim5 = 0x40000C00u;
constexpr uint32_t kIwdg = 0x40003000u;
constexpr uint32_t kFdcan1 = 0x40006400u;
constexpr uint32_t kLptim1 = 0x40007C00u;
constexpr uint32_t kPwr = 0x40007000u;
constexpr uint32_t kFdcanRam = 0x4000A400u;  ///< message RAM of FDCAN1 (0x350 bytes)
constexpr uint32_t kSyscfg = 0x40010000u;
constexpr uint32_t kExti = 0x40010400u;
constexpr uint32_t kTim1 = 0x40012C00u, kTim8 = 0x40013400u, kTim20 = 0x40015000u;
constexpr uint32_t kUsart1 = 0x40013800u;
constexpr uint32_t kDma1 = 0x40020000u;
constexpr uint32_t kDmamux = 0x40020800u;
constexpr uint32_t kRcc = 0x40021000u;
constexpr uint32_t kFlash = 0x40022000u;
constexpr uint32_t kGpioA = 0x48000000u;  ///< GPIOB = A + 0x400, … GPIOG = A + 0x1800
constexpr uint32_t kAdc1 = 0x50000000u, kAdc2 = 0x50000100u, kAdc12Common = 0x50000300u;
constexpr uint32_t kAdc3 = 0x50000400u, kAdc4 = 0x50000500u, kAdc5 = 0x50000600u, kAdc345Common = 0x50000700u;
constexpr uint32_t gpio(char port) { return kGpioA + 0x400u * static_cast<uint32_t>(port - 'A'); }

// ---- RCC (§7.4) ----
constexpr uint32_t kRccCr = 0x00, kRccCfgr = 0x08, kRccPllcfgr = 0x0C, kRccAhb1enr = 0x48, kRccAhb2enr = 0x4C;
constexpr uint32_t kRccApb1enr1 = 0x58, kRccApb2enr = 0x60, kRccCcipr = 0x88, kRccCsr = 0x94;
constexpr uint32_t kRccCrHseon = 1u << 16, kRccCrHserdy = 1u << 17, kRccCrPllon = 1u << 24, kRccCrPllrdy = 1u << 25;
constexpr uint32_t kRccCfgrSwPll = 0x3u, kRccCfgrSwsMask = 0x3u << 2, kRccCfgrSwsPll = 0x3u << 2;
constexpr uint32_t kRccCfgrHpreDiv2 = 0x8u << 4, kRccCfgrHpreMask = 0xFu << 4;
constexpr uint32_t kRccAhb1Dma1 = 1u << 0, kRccAhb1Dmamux = 1u << 2, kRccAhb1Flash = 1u << 8;
constexpr uint32_t kRccAhb2GpioAll = 0x7Fu, kRccAhb2Adc12 = 1u << 13, kRccAhb2Adc345 = 1u << 14;
constexpr uint32_t kRccApb1Tim2 = 1u << 0, kRccApb1Tim3 = 1u << 1, kRccApb1Tim4 = 1u << 2, kRccApb1Tim5 = 1u << 3;
constexpr uint32_t kRccApb1Fdcan = 1u << 25, kRccApb1Pwr = 1u << 28, kRccApb1Lptim1 = 1u << 31;
constexpr uint32_t kRccApb2Syscfg = 1u << 0, kRccApb2Tim1 = 1u << 11, kRccApb2Tim8 = 1u << 13, kRccApb2Usart1 = 1u << 14;
constexpr uint32_t kRccApb2Tim20 = 1u << 20;
constexpr uint32_t kRccCciprFdcanPclk = 0x2u << 24;  ///< FDCANSEL = PCLK1
constexpr uint32_t kRccCciprAdc12Sysclk = 0x2u << 28; ///< ADC12SEL = SYSCLK

// ---- PWR (§6.4): range 1 boost mode is R1MODE = 0 in PWR_CR5 ----
constexpr uint32_t kPwrCr5 = 0x80, kPwrCr5R1mode = 1u << 8;

// ---- FLASH_ACR (§3.7.1) ----
constexpr uint32_t kFlashAcr = 0x00, kFlashAcrPrften = 1u << 8, kFlashAcrIcen = 1u << 9, kFlashAcrDcen = 1u << 10;

// ---- GPIO (§9.4) ----
constexpr uint32_t kGpioModer = 0x00, kGpioPupdr = 0x0C, kGpioIdr = 0x10, kGpioBsrr = 0x18, kGpioAfrl = 0x20;
constexpr uint32_t kGpioOspeedr = 0x08;

// ---- Advanced/general timers (§28, §29) ----
constexpr uint32_t kTimCr1 = 0x00, kTimCr2 = 0x04, kTimSmcr = 0x08, kTimDier = 0x0C, kTimSr = 0x10, kTimEgr = 0x14;
constexpr uint32_t kTimCcmr1 = 0x18, kTimCcmr2 = 0x1C, kTimCcer = 0x20, kTimCnt = 0x24, kTimPsc = 0x28, kTimArr = 0x2C;
constexpr uint32_t kTimRcr = 0x30, kTimCcr1 = 0x34, kTimBdtr = 0x44;
constexpr uint32_t kTimCr1Cen = 1u << 0, kTimCr1Cms1 = 1u << 5, kTimCr1Arpe = 1u << 7;
constexpr uint32_t kTimCr2MmsUpdate = 0x2u << 4;
constexpr uint32_t kTimBdtrMoe = 1u << 15, kTimBdtrOssr = 1u << 11, kTimBdtrOssi = 1u << 10;
constexpr uint32_t kTimEgrUg = 1u << 0;
constexpr uint32_t kTimOcPwm1 = 0x6u;  ///< OCxM = 0110, PWM mode 1

// ---- LPTIM1 (§38.7): encoder mode values in phalanx/mcu/stm32g4_encoder.h ----
constexpr uint32_t kLptimIsr = 0x00, kLptimCfgr = 0x0C, kLptimCr = 0x10, kLptimArr = 0x18, kLptimCnt = 0x1C;

// ---- ADC (§21.7) ----
constexpr uint32_t kAdcIsr = 0x00, kAdcCr = 0x08, kAdcCfgr = 0x0C, kAdcCfgr2 = 0x10, kAdcSmpr1 = 0x14, kAdcSmpr2 = 0x18;
constexpr uint32_t kAdcSqr1 = 0x30, kAdcDr = 0x40, kAdcCommonCcr = 0x08;
constexpr uint32_t kAdcCrAden = 1u << 0, kAdcCrAdstart = 1u << 2, kAdcCrAdvregen = 1u << 28;
constexpr uint32_t kAdcCrDeeppwd = 1u << 29, kAdcCrAdcal = 1u << 31;
constexpr uint32_t kAdcIsrAdrdy = 1u << 0;
constexpr uint32_t kAdcCfgrDmaen = 1u << 0, kAdcCfgrDmacfg = 1u << 1, kAdcCfgrExtenRising = 0x1u << 10;
/// Regular trigger adc_ext_trg9 = TIM1_TRGO, the same EXTSEL on ADC1/2 (RM0440 Table 163) and ADC3/4/5 (Table 165).
constexpr uint32_t kAdcExtselTim1Trgo = 9u;

// ---- DMA1 + DMAMUX (§12, §13) ----
constexpr uint32_t dmaCcr(uint32_t ch) { return 0x08u + 0x14u * (ch - 1u); }  ///< ch 1..8
constexpr uint32_t dmaCndtr(uint32_t ch) { return 0x0Cu + 0x14u * (ch - 1u); }
constexpr uint32_t dmaCpar(uint32_t ch) { return 0x10u + 0x14u * (ch - 1u); }
constexpr uint32_t dmaCmar(uint32_t ch) { return 0x14u + 0x14u * (ch - 1u); }
constexpr uint32_t kDmaIfcr = 0x04;
constexpr uint32_t kDmaCcrEn = 1u << 0, kDmaCcrTcie = 1u << 1, kDmaCcrDir = 1u << 4, kDmaCcrCirc = 1u << 5;
constexpr uint32_t kDmaCcrMinc = 1u << 7, kDmaCcrPsize16 = 1u << 8, kDmaCcrMsize16 = 1u << 10;
constexpr uint32_t kDmaCcrPlHigh = 0x2u << 12;
constexpr uint32_t dmamuxCcr(uint32_t dma1_channel) { return 4u * (dma1_channel - 1u); }  ///< DMA1 ch1 → DMAMUX ch0
// DMAMUX request inputs (RM0440 Table 91).
constexpr uint32_t kDmareqAdc1 = 5, kDmareqAdc2 = 36, kDmareqUsart1Rx = 24, kDmareqUsart1Tx = 25;
constexpr uint32_t kDmareqAdc3 = 37, kDmareqAdc4 = 38, kDmareqAdc5 = 39;

// ---- USART (§37.8) ----
constexpr uint32_t kUsartCr1 = 0x00, kUsartCr3 = 0x08, kUsartBrr = 0x0C, kUsartIsr = 0x1C, kUsartIcr = 0x20;
constexpr uint32_t kUsartRdr = 0x24, kUsartTdr = 0x28;
constexpr uint32_t kUsartCr1Ue = 1u << 0, kUsartCr1Re = 1u << 2, kUsartCr1Te = 1u << 3, kUsartCr1Over8 = 1u << 15;
constexpr uint32_t kUsartCr3Dmar = 1u << 6, kUsartCr3Dmat = 1u << 7;
constexpr uint32_t kUsartIsrTc = 1u << 6, kUsartIcrAll = 0x0012'1B5Fu;

// ---- FDCAN (§44.4) ----
constexpr uint32_t kCanDbtp = 0x0C, kCanCccr = 0x18, kCanNbtp = 0x1C, kCanTdcr = 0x48, kCanIr = 0x50;
constexpr uint32_t kCanRxgfc = 0x80, kCanRxf0s = 0x90, kCanRxf0a = 0x94, kCanTxfqs = 0xC4, kCanTxbar = 0xCC;
constexpr uint32_t kCanCccrInit = 1u << 0, kCanCccrCce = 1u << 1, kCanCccrFdoe = 1u << 8, kCanCccrBrse = 1u << 9;
constexpr uint32_t kCanTxfqsTfqf = 1u << 21;
// Message RAM layout of one FDCAN instance (fixed in the G4, §44.3.3): element sizes 18 words for FIFOs/buffers.
constexpr uint32_t kCanRamRxFifo0 = 0x0B0, kCanRamTxBuffers = 0x278, kCanRamElementBytes = 72;

// ---- IWDG (§42.4) ----
constexpr uint32_t kIwdgKr = 0x00, kIwdgPr = 0x04, kIwdgRlr = 0x08, kIwdgSr = 0x0C;
constexpr uint32_t kIwdgStart = 0xCCCCu, kIwdgUnlock = 0x5555u, kIwdgRefresh = 0xAAAAu;

// ---- EXTI + SYSCFG (§15.5, §10.2) ----
constexpr uint32_t kExtiImr1 = 0x00, kExtiRtsr1 = 0x08, kExtiFtsr1 = 0x0C, kExtiPr1 = 0x14;
constexpr uint32_t syscfgExticr(uint32_t line) { return 0x08u + 4u * (line / 4u); }

// ---- Interrupt numbers (RM0440 Table 97) ----
constexpr uint32_t kIrqDma1Ch4 = 14;    ///< USART1 TX DMA complete
constexpr uint32_t kIrqExti15_10 = 40;  ///< e-stop on PC13
constexpr uint32_t kIrqCount = 102;

// ---- DWT cycle counter (ARMv7-M C1.8) — the tick is measured in CPU cycles on silicon ----
constexpr uint32_t kDemcr = 0xE000EDFCu, kDemcrTrcena = 1u << 24;
constexpr uint32_t kDwtCtrl = 0xE0001000u, kDwtCyccnt = 0xE0001004u;

}  // namespace phalanx::mcu::g474
