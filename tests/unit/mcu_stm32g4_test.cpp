// Register arithmetic of the STM32G474 port, checked on the host (the port itself cannot run here).
// Values are checked against RM0440's formulas evaluated independently in the test, not against the port's code.
#include <gtest/gtest.h>

#include <cmath>

#include "../../hal/mcu/include/phalanx/mcu/stm32g4_adc_dma.h"
#include "../../hal/mcu/include/phalanx/mcu/stm32g4_clock.h"
#include "../../hal/mcu/include/phalanx/mcu/stm32g4_fdcan.h"
#include "../../hal/mcu/include/phalanx/mcu/stm32g4_iwdg.h"
#include "../../hal/mcu/include/phalanx/mcu/stm32g4_timer.h"
#include "../../hal/mcu/include/phalanx/mcu/stm32g4_uart.h"

using namespace phalanx::mcu::stm32g4;

TEST(McuStm32g4Clock, PllReaches170MHzFromCommonCrystalsWithinEveryRange) {
  for (uint32_t hse : {8000000u, 12000000u, 16000000u, 24000000u, 25000000u}) {
    const PllConfig p = pllFor(hse, 170000000u);
    ASSERT_TRUE(p.ok) << hse;
    const double in = static_cast<double>(hse) / p.m;
    EXPECT_GE(in, 2.66e6);
    EXPECT_LE(in, 16e6);
    EXPECT_GE(in * p.n, 96e6);
    EXPECT_LE(in * p.n, 344e6);
    EXPECT_EQ(in * p.n / p.r, 170e6) << hse;
    EXPECT_TRUE(p.r == 2 || p.r == 4 || p.r == 6 || p.r == 8);
  }
}

TEST(McuStm32g4Clock, The24MHzBoardSettingIsM6N85R2AndEncodesIntoPllcfgr) {
  const PllConfig p = pllFor(24000000u, 170000000u);
  EXPECT_EQ(p.m, 6u);
  EXPECT_EQ(p.n, 85u);
  EXPECT_EQ(p.r, 2u);
  // PLLSRC=HSE(3) | PLLM=5<<4 | PLLN=85<<8 | PLLREN<<24 | PLLR=0<<25
  EXPECT_EQ(pllcfgrHse(p), 0x3u | (5u << 4) | (85u << 8) | (1u << 24));
}

TEST(McuStm32g4Clock, UnreachableFrequenciesAreRefused) {
  EXPECT_FALSE(pllFor(24000000u, 171000000u).ok);  // beyond the maximum
  EXPECT_FALSE(pllFor(7000000u, 169999999u).ok);   // no exact M, N, R
}

TEST(McuStm32g4Clock, FlashWaitStatesFollowTable9) {
  EXPECT_EQ(flashWaitStates(170000000u, true), 4);
  EXPECT_EQ(flashWaitStates(136000000u, true), 3);
  EXPECT_EQ(flashWaitStates(136000001u, true), 4);
  EXPECT_EQ(flashWaitStates(34000000u, true), 0);
  EXPECT_EQ(flashWaitStates(150000000u, false), 4);
  EXPECT_EQ(flashWaitStates(170000000u, false), -1) << "170 MHz needs boost mode";
  EXPECT_TRUE(needsBoost(170000000u));
  EXPECT_FALSE(needsBoost(150000000u));
}

TEST(McuStm32g4Clock, SysTickReloadForTheOneKilohertzTick) {
  EXPECT_EQ(systickReload(170000000u, 1000u), 169999u);
  EXPECT_EQ(systickReload(25000000u, 1000u), 24999u);
  EXPECT_EQ(systickReload(170000000u, 7u), 0u) << "not an integer number of clocks";
}

TEST(McuStm32g4Timer, CenterAligned20kHzAt170MHzUsesArr4250) {
  const PwmTiming t = centerAlignedPwm(170000000u, 20000u);
  ASSERT_TRUE(t.ok);
  EXPECT_EQ(t.psc, 0u);
  EXPECT_EQ(t.arr, 4250u);
  EXPECT_EQ(t.actual_hz, 20000u);
}

TEST(McuStm32g4Timer, LowPwmFrequenciesUseThePrescalerToFitSixteenBits) {
  const PwmTiming t = centerAlignedPwm(170000000u, 1000u);
  ASSERT_TRUE(t.ok);
  EXPECT_LE(t.arr, 0xFFFFu);
  const double f = 170e6 / ((t.psc + 1.0) * 2.0 * t.arr);
  EXPECT_NEAR(f, 1000.0, 1.0);
}

TEST(McuStm32g4Timer, DutyMapsToCcrWithSignIgnoredClampedAndNanSafe) {
  EXPECT_EQ(dutyToCcr(0.5f, 4250), 2125u);
  EXPECT_EQ(dutyToCcr(-0.5f, 4250), 2125u);
  EXPECT_EQ(dutyToCcr(2.0f, 4250), 4250u);
  EXPECT_EQ(dutyToCcr(0.95f, 4250, 0.9f), 3825u);
  EXPECT_EQ(dutyToCcr(std::nanf(""), 4250), 0u);
  EXPECT_EQ(dutyToCcr(0.0f, 4250), 0u);
}

namespace {
// RM0440 §28.6.20 decode of DTG[7:0] in t_DTS units.
uint32_t decodeDtg(uint8_t dtg) {
  if ((dtg & 0x80u) == 0) return dtg;
  if ((dtg & 0xC0u) == 0x80u) return (64u + (dtg & 0x3Fu)) * 2u;
  if ((dtg & 0xE0u) == 0xC0u) return (32u + (dtg & 0x1Fu)) * 8u;
  return (32u + (dtg & 0x1Fu)) * 16u;
}
}  // namespace

TEST(McuStm32g4Timer, DeadTimeIsNeverShorterThanAskedAndDecodesToWhatItClaims) {
  for (uint32_t ticks = 0; ticks <= 1008; ++ticks) {
    const DeadTime d = deadTimeDtg(ticks);
    ASSERT_EQ(decodeDtg(d.dtg), d.ticks) << ticks;
    ASSERT_GE(d.ticks, ticks);
  }
  EXPECT_EQ(nsToTicks(500, 170000000u), 85u);
  EXPECT_EQ(deadTimeDtg(85).dtg, 85u);
}

TEST(McuStm32g4Timer, EncoderExtenderFollowsSixteenBitWrapsBothWays) {
  EncoderExtender e;
  e.update(65530);
  EXPECT_EQ(e.update(4), 10);      // forward through 65535 → 0
  EXPECT_EQ(e.update(65520), -10); // backward through 0
  int32_t expected = -10;
  uint16_t raw = 65520;
  for (int i = 0; i < 10000; ++i) {
    raw = static_cast<uint16_t>(raw + 1000);
    expected += 1000;
    ASSERT_EQ(e.update(raw), expected);
  }
}

TEST(McuStm32g4Uart, TwoMegabaudAt170MHzIsExact) {
  const UartDivisor d = uartDivisor(170000000u, 2000000u);
  ASSERT_TRUE(d.ok);
  EXPECT_FALSE(d.over8);
  EXPECT_EQ(d.brr, 85u);
  EXPECT_EQ(d.error_ppm, 0);
  EXPECT_GE(uartBytesPerSecond(2000000u), 70u * 1000u) << "one 70-byte telemetry frame per 1 kHz tick fits";
}

TEST(McuStm32g4Uart, ClassicRatesStayWithinTwoPercentAndHighRatesSwitchToOver8) {
  for (uint32_t baud : {9600u, 115200u, 921600u, 3000000u}) {
    const UartDivisor d = uartDivisor(170000000u, baud);
    ASSERT_TRUE(d.ok) << baud;
    EXPECT_LT(std::abs(d.error_ppm), 20000) << baud;
  }
  const UartDivisor fast = uartDivisor(170000000u, 12500000u);
  ASSERT_TRUE(fast.ok);
  EXPECT_TRUE(fast.over8);
  // USARTDIV = round(2·170e6/12.5e6) = 27 = 0x1B → BRR = 0x10 | (0xB >> 1) = 0x15
  EXPECT_EQ(fast.brr, 0x15u);
}

TEST(McuStm32g4Fdcan, OneMegabitNominalAndFiveMegabitDataAt170MHz) {
  const CanBitTiming n = canBitTiming(170000000u, 1000000u, 800u, kNominalLimits);
  ASSERT_TRUE(n.ok);
  EXPECT_EQ(170000000u / (n.brp * n.tq_per_bit), 1000000u);
  EXPECT_EQ(n.tq_per_bit, 1u + n.tseg1 + n.tseg2);
  EXPECT_NEAR(n.sample_point_permille, 800u, 10u);
  EXPECT_EQ(nbtp(n), ((n.sjw - 1u) << 25) | ((n.brp - 1u) << 16) | ((n.tseg1 - 1u) << 8) | (n.tseg2 - 1u));

  const CanBitTiming d = canBitTiming(170000000u, 5000000u, 750u, kDataLimits);
  ASSERT_TRUE(d.ok);
  EXPECT_EQ(170000000u / (d.brp * d.tq_per_bit), 5000000u);
  EXPECT_LE(d.tseg1, 32u);
  EXPECT_LE(d.tseg2, 16u);
  EXPECT_NEAR(d.sample_point_permille, 750u, 30u);
  EXPECT_EQ(dbtp(d, true) >> 23 & 1u, 1u);
}

TEST(McuStm32g4Fdcan, ImpossibleDataRateIsRefused) {
  EXPECT_FALSE(canBitTiming(170000000u, 7000000u, 750u, kDataLimits).ok);
}

TEST(McuStm32g4Fdcan, DlcCoversEveryProtocolFrameAndRoundsUp) {
  for (uint32_t len = 0; len <= 64; ++len) {
    const uint8_t dlc = canFdDlc(len);
    EXPECT_GE(canFdBytes(dlc), len);
    if (dlc > 0) {
      EXPECT_LT(canFdBytes(static_cast<uint8_t>(dlc - 1)), len);
    }
  }
}

TEST(McuStm32g4Adc, SequenceRegistersHoldLengthAndRanks) {
  const uint8_t ch[11] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11};
  const AdcSequence s = adcSequence(ch, 11);
  ASSERT_TRUE(s.ok);
  EXPECT_EQ(s.sqr[0] & 0xFu, 10u);
  EXPECT_EQ((s.sqr[0] >> 6) & 0x1Fu, 1u);    // SQ1
  EXPECT_EQ((s.sqr[0] >> 24) & 0x1Fu, 4u);   // SQ4
  EXPECT_EQ(s.sqr[1] & 0x1Fu, 5u);           // SQ5
  EXPECT_EQ((s.sqr[1] >> 24) & 0x1Fu, 9u);   // SQ9
  EXPECT_EQ(s.sqr[2] & 0x1Fu, 10u);          // SQ10
  EXPECT_EQ((s.sqr[2] >> 6) & 0x1Fu, 11u);   // SQ11
  EXPECT_FALSE(adcSequence(ch, 0).ok);
  const uint8_t bad[1] = {19};
  EXPECT_FALSE(adcSequence(bad, 1).ok);
  EXPECT_EQ(smprField(9).reg, 0u);
  EXPECT_EQ(smprField(9).shift, 27u);
  EXPECT_EQ(smprField(12).reg, 1u);
  EXPECT_EQ(smprField(12).shift, 6u);
}

TEST(McuStm32g4Adc, OversamplingRatioFourAveragesBackToTwelveBits) {
  // RM0440 ADC_CFGR2: ROVSE bit 0, OVSR [4:2] = 001 (×4), OVSS [8:5] = 0010 (shift 2).
  EXPECT_EQ(adcCfgr2Oversampling(4), 0x1u | (0x1u << 2) | (0x2u << 5));
  EXPECT_EQ(adcCfgr2Oversampling(2), 0x1u | (0x0u << 2) | (0x1u << 5));
  EXPECT_EQ(adcCfgr2Oversampling(256), 0x1u | (0x7u << 2) | (0x8u << 5));
  EXPECT_EQ(adcCfgr2Oversampling(1), 0u);
  for (uint32_t bad : {0u, 3u, 6u, 512u, 1000u}) EXPECT_EQ(adcCfgr2Oversampling(bad), kAdcCfgr2Invalid) << bad;
}

TEST(McuStm32g4Dma, RxTrackerReportsNewBytesAcrossTheBufferEnd) {
  DmaRxTracker t(8);
  auto s = t.poll(8);  // nothing yet
  EXPECT_EQ(s.total(), 0u);
  s = t.poll(3);  // 5 bytes written: indices 0..4
  EXPECT_EQ(s.first_begin, 0u);
  EXPECT_EQ(s.first_len, 5u);
  EXPECT_EQ(s.second_len, 0u);
  s = t.poll(5);  // 6 more: 5,6,7 then 0,1,2
  EXPECT_EQ(s.first_begin, 5u);
  EXPECT_EQ(s.first_len, 3u);
  EXPECT_EQ(s.second_len, 3u);
  EXPECT_EQ(t.readIndex(), 3u);
  EXPECT_EQ(dmaWriteIndex(8, 8), 0u);
  EXPECT_EQ(stableScanOffset(25, 3), 25u);
  EXPECT_EQ(stableScanOffset(25, 30), 0u);
}

TEST(McuStm32g4Iwdg, TimeoutsUseTheFinestPrescalerAndNeverExceedTheRequest) {
  const IwdgConfig a = iwdgFor(10000u);
  ASSERT_TRUE(a.ok);
  EXPECT_EQ(a.pr, 0u);
  EXPECT_EQ(a.rlr, 79u);
  EXPECT_EQ(a.timeout_us, 10000u);
  const IwdgConfig b = iwdgFor(2000000u);
  ASSERT_TRUE(b.ok);
  EXPECT_EQ(b.pr, 2u);
  EXPECT_EQ(b.rlr, 3999u);
  for (uint32_t us = 200; us < 30000000u; us = us * 3 / 2) {
    const IwdgConfig c = iwdgFor(us);
    if (!c.ok) continue;
    EXPECT_LE(c.timeout_us, us);
    EXPECT_LE(c.rlr, 4095u);
  }
  EXPECT_FALSE(iwdgFor(50u).ok) << "shorter than one LSI/4 tick";
}
