// Encoder register values of the STM32G474 port, checked on the host. Field positions are
// decoded here from RM0440's register descriptions (TIMx_CCMR1 input mode, LPTIM_CFGR), not from the port's code.
#include <gtest/gtest.h>

#include <vector>

#include "../../hal/mcu/include/phalanx/mcu/stm32g4_encoder.h"
#include "../../hal/mcu/include/phalanx/mcu/stm32g4_timer.h"

using namespace phalanx::mcu::stm32g4;

namespace {
uint32_t field(uint32_t v, int lo, int width) { return (v >> lo) & ((1u << width) - 1u); }
}  // namespace

TEST(McuStm32g4Encoder, TimerCcmr1MapsBothInputsToTheirOwnPinWithTheFilter) {
  const TimEncoderCcmr1 c = timEncoderCcmr1(8);
  ASSERT_TRUE(c.ok);
  EXPECT_EQ(field(c.value, 0, 2), 1u);   // CC1S = 01: IC1 ← TI1
  EXPECT_EQ(field(c.value, 2, 2), 0u);   // IC1PSC: every edge
  EXPECT_EQ(field(c.value, 4, 4), 3u);   // IC1F = 0011: f_CK_INT, N = 8
  EXPECT_EQ(field(c.value, 8, 2), 1u);   // CC2S = 01: IC2 ← TI2
  EXPECT_EQ(field(c.value, 10, 2), 0u);  // IC2PSC
  EXPECT_EQ(field(c.value, 12, 4), 3u);  // IC2F
  EXPECT_EQ(c.value >> 16, 0u);
  EXPECT_EQ(field(timEncoderCcmr1(2).value, 4, 4), 1u);
  EXPECT_EQ(field(timEncoderCcmr1(4).value, 12, 4), 2u);
  EXPECT_EQ(field(timEncoderCcmr1(1).value, 4, 4), 0u);
}

TEST(McuStm32g4Encoder, FilterLengthsWithoutAFullSpeedCodeAreRefused) {
  for (uint32_t n : {0u, 3u, 5u, 6u, 16u, 32u}) {
    EXPECT_FALSE(timEncoderCcmr1(n).ok) << n;
    EXPECT_FALSE(lptimEncoderCfgr(n).ok) << n;
  }
}

TEST(McuStm32g4Encoder, LptimCfgrSelectsEncoderModeOnBothEdgesWithInternalClockAndNoPrescaler) {
  const LptimEncoderCfgr c = lptimEncoderCfgr(8);
  ASSERT_TRUE(c.ok);
  EXPECT_EQ(field(c.value, 24, 1), 1u);  // ENC
  EXPECT_EQ(field(c.value, 0, 1), 0u);   // CKSEL = 0: internal clock (mandatory in encoder mode)
  EXPECT_EQ(field(c.value, 1, 2), 2u);   // CKPOL = 10: both edges, ×4 (Table 307)
  EXPECT_EQ(field(c.value, 3, 2), 3u);   // CKFLT = 11: 8 clock periods
  EXPECT_EQ(field(c.value, 9, 3), 0u);   // PRESC = /1 (mandatory)
  EXPECT_EQ(field(c.value, 17, 2), 0u);  // TRIGEN: software start
  EXPECT_EQ(field(c.value, 23, 1), 0u);  // COUNTMODE = 0 (the inputs drive the count in encoder mode)
  EXPECT_EQ(c.value & ~((1u << 24) | (3u << 1) | (3u << 3)), 0u);  // nothing else set
  EXPECT_EQ(field(lptimEncoderCfgr(2).value, 3, 2), 1u);
  EXPECT_EQ(field(lptimEncoderCfgr(4).value, 3, 2), 2u);
  EXPECT_EQ(field(lptimEncoderCfgr(1).value, 3, 2), 0u);
}

TEST(McuStm32g4Encoder, LptimCountIsTakenOnlyWhenTwoConsecutiveReadsAgree) {
  std::vector<uint32_t> seq{100, 101, 101, 7};
  size_t i = 0;
  int reads = 0;
  auto fake = [&] {
    ++reads;
    return seq[i < seq.size() - 1 ? i++ : i];
  };
  ConfirmedRead r = confirmedRead(fake);
  EXPECT_TRUE(r.ok);
  EXPECT_EQ(r.value, 101);
  EXPECT_EQ(reads, 3);

  // A counter that changes on every read is never confirmed, and the number of reads stays bounded.
  uint32_t moving = 65534;
  reads = 0;
  r = confirmedRead([&] {
    ++reads;
    return moving++;
  }, 4);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(reads, 4);
  EXPECT_EQ(r.value, 1);  // 16-bit: 65534, 65535, 0, 1
}

TEST(McuStm32g4Encoder, LptimSixteenBitCountExtendsAcrossWrapsLikeTheTimers) {
  // LPTIM1 with ARR = 0xFFFF wraps 0xFFFF ↔ 0 like a 16-bit timer: the same extender gives the running count.
  EncoderExtender e;
  uint16_t raw = 10;
  e.update(raw);
  int32_t expected = 0;
  for (int step : {-30, -4000, 25000, 31000, -32000, 7, -7}) {
    raw = static_cast<uint16_t>(raw + step);
    expected += step;
    const ConfirmedRead r = confirmedRead([raw] { return static_cast<uint32_t>(raw); });
    ASSERT_TRUE(r.ok);
    EXPECT_EQ(e.update(r.value), expected) << step;
  }
}
