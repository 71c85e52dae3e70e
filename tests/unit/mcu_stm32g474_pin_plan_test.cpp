// The STM32G474 board pin plan (hal/mcu/stm32g474/pin_plan.h), checked on the host: no pin claimed twice by an
// image, and the analog inputs split over ADC1/ADC2 into valid sequences. The expected conflicts are derived here
// from the pin lists, not from the plan's own checker.
#include <gtest/gtest.h>

#include <set>
#include <utility>

#include "../../common/include/phalanx/glove/board.h"
#include "../../common/include/phalanx/pen/board.h"
#include "../../common/include/phalanx/sea/board.h"
#include "../../hal/mcu/include/phalanx/mcu/stm32g4_adc_dma.h"
#include "../../hal/mcu/stm32g474/pin_plan.h"

namespace g474 = phalanx::mcu::g474;

namespace {
/// Independent conflict check with a std::set over an image's pins.
bool distinctBySet(size_t pwm, size_t enc, size_t analog) {
  const g474::ImagePins l = g474::imagePins(pwm, enc, analog);
  std::set<std::pair<char, int>> seen;
  for (size_t i = 0; i < l.n; ++i) {
    if (!seen.insert({l.pins[i].port, l.pins[i].n}).second) return false;
  }
  return true;
}
}  // namespace

TEST(McuStm32g474PinPlan, NoPinIsClaimedTwiceAndTheCheckerFindsARepeat) {
  constexpr g474::PinList l = g474::boardPins();
  EXPECT_EQ(l.n, g474::kBoardPinCount);
  std::set<std::pair<char, int>> seen;
  for (size_t i = 0; i < l.n; ++i) {
    EXPECT_TRUE(seen.insert({l.pins[i].port, l.pins[i].n}).second) << l.pins[i].port << int{l.pins[i].n};
    EXPECT_GE(l.pins[i].port, 'A');
    EXPECT_LE(l.pins[i].port, 'G');
    EXPECT_LT(l.pins[i].n, 16);
  }
  EXPECT_EQ(g474::firstRepeatedPin(l.pins, l.n), l.n);

  g474::Pin clash[3] = {{'A', 0, 1}, {'E', 2, 6}, {'E', 2, 0}};  // e.g. a direction line on TIM20's input
  EXPECT_EQ(g474::firstRepeatedPin(clash, 3), 2u);
  g474::Pin other_port[2] = {{'A', 2, 0}, {'B', 2, 0}};
  EXPECT_EQ(g474::firstRepeatedPin(other_port, 2), 2u);
}

TEST(McuStm32g474PinPlan, SixEncodersEightPwmAndEightDirectionLinesFit) {
  EXPECT_EQ(g474::kMaxEncoders, 6u);
  EXPECT_EQ(sizeof(g474::kPwmPins) / sizeof(g474::kPwmPins[0]), 8u);
  for (const g474::Pin& p : g474::kDirectionPins) {
    EXPECT_EQ(p.port, g474::kDirectionPort);
    EXPECT_EQ(p.af, g474::kGpioOut);
  }
  for (const auto& e : g474::kEncoderPins) {
    EXPECT_LT(e[0].af, 16);  // both inputs in an alternate function, not GPIO
    EXPECT_LT(e[1].af, 16);
  }
}

TEST(McuStm32g474PinPlan, EachDeviceImageClaimsDistinctPins) {
  namespace gb = phalanx::glove::board;
  namespace sb = phalanx::sea::board;
  namespace pb = phalanx::pen::board;
  EXPECT_TRUE(g474::imagePinsDistinct(gb::kPwmChannelCount, 0, gb::kAdcChannelCount));
  EXPECT_TRUE(g474::imagePinsDistinct(sb::kPwmChannelCount, sb::kEncoderChannelCount, sb::kAdcChannelCount));
  EXPECT_TRUE(g474::imagePinsDistinct(pb::kPwmChannelCount, pb::kEncoderChannelCount, pb::kAdcChannelCount));
  EXPECT_TRUE(distinctBySet(gb::kPwmChannelCount, 0, gb::kAdcChannelCount));
  EXPECT_TRUE(distinctBySet(sb::kPwmChannelCount, sb::kEncoderChannelCount, sb::kAdcChannelCount));
  EXPECT_TRUE(distinctBySet(pb::kPwmChannelCount, pb::kEncoderChannelCount, pb::kAdcChannelCount));
}

TEST(McuStm32g474PinPlan, FreeAnalogInputsCoexistWithAllEncodersAndTheNextOneDoesNot) {
  for (size_t n = 0; n <= g474::kAnalogInputsWithOwnPin; ++n) {
    EXPECT_EQ(g474::imagePinsDistinct(8, 6, n), distinctBySet(8, 6, n)) << n;
    EXPECT_EQ(g474::imagePinsDistinct(8, 6, n), n <= g474::kAnalogInputsFree) << n;  // input 14 is PA0 = TIM5
    EXPECT_TRUE(g474::imagePinsDistinct(8, 0, n)) << n;  // without encoders all 20 have a pin of their own
  }
  EXPECT_FALSE(g474::imagePinsDistinct(2, 2, 17));  // input 16 is PA6 = TIM3 (encoder 1)
}

TEST(McuStm32g474PinPlan, AnalogInputsSplitIntoSixteenRankSequencesWithConsistentRanks) {
  for (size_t n = 0; n <= g474::kAnalogInputCount; ++n) {
    const g474::AnalogSplit s = g474::splitAnalogInputs(n);
    ASSERT_TRUE(s.ok) << n;
    EXPECT_EQ(s.len[0] + s.len[1], n);
    for (size_t i = 0; i < n; ++i) {
      const size_t a = s.adc_index[i];
      EXPECT_EQ(a + 1, g474::kAnalogInputs[i].adc);
      ASSERT_LT(s.rank[i], s.len[a]);
      EXPECT_EQ(s.seq[a][s.rank[i]], g474::kAnalogInputs[i].channel);
    }
    for (size_t a = 0; a < 2; ++a) {
      if (s.len[a] == 0) continue;
      const phalanx::mcu::stm32g4::AdcSequence q = phalanx::mcu::stm32g4::adcSequence(s.seq[a], s.len[a]);
      EXPECT_TRUE(q.ok) << n;
      EXPECT_EQ(q.sqr[0] & 0xFu, s.len[a] - 1);  // L = length − 1
    }
  }
  EXPECT_FALSE(g474::splitAnalogInputs(g474::kAnalogInputCount + 1).ok);
  // Each (ADC, channel) pair is converted once.
  std::set<std::pair<int, int>> pairs;
  for (const auto& in : g474::kAnalogInputs) EXPECT_TRUE(pairs.insert({in.adc, in.channel}).second);
}
