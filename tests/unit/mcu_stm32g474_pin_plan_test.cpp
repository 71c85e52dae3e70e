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

// ---- Analog channel plan: the datasheet table, the checker, the images ----------------------------------------

namespace {
using g474::AnalogInput;
using g474::AnalogPlanError;
using g474::Pin;

/// The datasheet table itself: no (ADC, channel) twice, ADC numbers 1..5, channels 1..18, and pins shared between
/// ADCs only where DS12288 shares them (checked per pin by counting).
std::set<std::pair<char, int>> pinsOfAdc(int adc) {
  std::set<std::pair<char, int>> pins;
  for (const auto& d : g474::kDeviceAdcInputs) {
    if (d.adc == adc) pins.insert({d.pin.port, d.pin.n});
  }
  return pins;
}

/// Independent checker for the plan: std::set over pins, pairs and a pin→(ADC, channel) map from the table.
bool planValidBySets(const AnalogInput* plan, size_t n, const g474::Pin* taken, size_t n_taken) {
  std::set<std::pair<char, int>> pins, taken_set;
  std::set<std::pair<int, int>> pairs;
  for (size_t t = 0; t < n_taken; ++t) taken_set.insert({taken[t].port, taken[t].n});
  int ranks[6] = {};
  for (size_t i = 0; i < n; ++i) {
    bool exists = false;
    for (const auto& d : g474::kDeviceAdcInputs) {
      exists = exists || (d.adc == plan[i].adc && d.channel == plan[i].channel && d.pin.port == plan[i].pin.port &&
                          d.pin.n == plan[i].pin.n);
    }
    if (!exists) return false;
    if (!pins.insert({plan[i].pin.port, plan[i].pin.n}).second) return false;
    if (!pairs.insert({plan[i].adc, plan[i].channel}).second) return false;
    if (taken_set.count({plan[i].pin.port, plan[i].pin.n}) != 0) return false;
    if (++ranks[plan[i].adc] > 16) return false;
  }
  return true;
}
}  // namespace

TEST(McuStm32g474PinPlan, DatasheetAdcTableIsConsistent) {
  std::set<std::pair<int, int>> pairs;
  for (const auto& d : g474::kDeviceAdcInputs) {
    EXPECT_TRUE(pairs.insert({d.adc, d.channel}).second) << int{d.adc} << "/" << int{d.channel};
    EXPECT_GE(d.adc, 1);
    EXPECT_LE(d.adc, 5);
    EXPECT_GE(d.channel, 1);
    EXPECT_LE(d.channel, 18);
    EXPECT_EQ(d.pin.af, g474::kGpioIn);
  }
  // GPIO-connected inputs per ADC (DS12288): ADC1 14, ADC2 16, ADC3 15, ADC4 16, ADC5 13.
  EXPECT_EQ(pinsOfAdc(1).size(), 14u);
  EXPECT_EQ(pinsOfAdc(2).size(), 16u);
  EXPECT_EQ(pinsOfAdc(3).size(), 15u);
  EXPECT_EQ(pinsOfAdc(4).size(), 16u);
  EXPECT_EQ(pinsOfAdc(5).size(), 13u);
  // ADC12_INx: same channel number on ADC1 and ADC2 for the shared pins.
  for (int ch : {1, 2, 6, 7, 8, 9, 14}) {
    ASSERT_NE(g474::deviceAdcInput(1, static_cast<uint8_t>(ch)), nullptr) << ch;
    ASSERT_NE(g474::deviceAdcInput(2, static_cast<uint8_t>(ch)), nullptr) << ch;
    EXPECT_TRUE(g474::samePin(g474::deviceAdcInput(1, static_cast<uint8_t>(ch))->pin,
                              g474::deviceAdcInput(2, static_cast<uint8_t>(ch))->pin))
        << ch;
  }
  // ADC345_INx (6–11, 14–16) and ADC45_IN12/13.
  for (int ch : {6, 7, 8, 9, 10, 11, 14, 15, 16}) {
    for (int adc : {3, 4, 5}) {
      ASSERT_NE(g474::deviceAdcInput(static_cast<uint8_t>(adc), static_cast<uint8_t>(ch)), nullptr);
    }
    EXPECT_TRUE(g474::samePin(g474::deviceAdcInput(3, static_cast<uint8_t>(ch))->pin,
                              g474::deviceAdcInput(5, static_cast<uint8_t>(ch))->pin));
  }
  EXPECT_EQ(g474::deviceAdcInput(3, 12)->pin.port, 'B');  // ADC3_IN12 is PB0, not ADC45_IN12's PD8
  EXPECT_TRUE(g474::samePin(g474::deviceAdcInput(4, 12)->pin, {'D', 8, 0}));
  EXPECT_EQ(g474::deviceAdcInput(3, 13), nullptr);   // internal
  EXPECT_EQ(g474::deviceAdcInput(1, 13), nullptr);   // OPAMP1
  EXPECT_EQ(g474::deviceAdcInput(5, 3), nullptr);    // internal
  EXPECT_EQ(g474::deviceAdcInput(6, 1), nullptr);
}

TEST(McuStm32g474PinPlan, TheBoardAnalogPlanIsValidOnEveryPinTheBoardUses) {
  const g474::AnalogPlanCheck c = g474::checkBoardAnalogPlan();
  EXPECT_TRUE(c.ok()) << static_cast<int>(c.error) << " at " << c.index;
  const g474::PinList board = g474::boardPins();
  EXPECT_TRUE(planValidBySets(g474::kAnalogInputs, g474::kAnalogInputCount, board.pins, board.n));
  // With all six encoders and eight PWM channels every prefix stays conflict-free (no more encoder-pin inputs).
  for (size_t n = 0; n <= g474::kAnalogInputCount; ++n) {
    EXPECT_TRUE(g474::imagePinsDistinct(8, 6, n)) << n;
    EXPECT_TRUE(distinctBySet(8, 6, n)) << n;
    EXPECT_TRUE(g474::checkImageAnalogPlan(8, 6, n).ok()) << n;
  }
  EXPECT_FALSE(g474::checkImageAnalogPlan(0, 0, g474::kAnalogInputCount + 1).ok());
}

TEST(McuStm32g474PinPlan, EachDeviceImageHasAValidAnalogPlanIncludingTheGloveCurrentSense) {
  namespace gb = phalanx::glove::board;
  namespace sb = phalanx::sea::board;
  namespace pb = phalanx::pen::board;
  EXPECT_TRUE(g474::checkImageAnalogPlan(gb::kPwmChannelCount, 0, gb::kAdcChannelCount).ok());
  EXPECT_TRUE(g474::checkImageAnalogPlan(sb::kPwmChannelCount, sb::kEncoderChannelCount, sb::kAdcChannelCount).ok());
  EXPECT_TRUE(g474::checkImageAnalogPlan(pb::kPwmChannelCount, pb::kEncoderChannelCount, pb::kAdcChannelCount).ok());
  // The glove's 15 Hall + 5 strain + 5 current channels: 25 distinct pins, 25 distinct (ADC, channel) pairs, and
  // the five current-sense channels (the ones the old plan put on ADC1's pins) each on a pin of its own that no
  // other glove channel, ADC1 input of the plan or board function uses.
  static_assert(gb::kAdcChannelCount == 25 && gb::kAdcFirstCurrent == 20, "glove channel map");
  std::set<std::pair<char, int>> glove_pins;
  for (int i = 0; i < gb::kAdcChannelCount; ++i) {
    glove_pins.insert({g474::kAnalogInputs[i].pin.port, g474::kAnalogInputs[i].pin.n});
  }
  EXPECT_EQ(glove_pins.size(), 25u);
  for (int f = 0; f < gb::kFingerCount; ++f) {
    const AnalogInput& in = g474::kAnalogInputs[gb::currentAdcChannel(f)];
    EXPECT_GE(in.adc, 3) << f;  // ADC3..ADC5
    const auto* d = g474::deviceAdcInput(in.adc, in.channel);
    ASSERT_NE(d, nullptr) << f;
    EXPECT_TRUE(g474::samePin(d->pin, in.pin)) << f;
    for (const auto& other : g474::kDeviceAdcInputs) {  // not a pin that ADC1 converts in this plan
      if (other.adc != 1 || !g474::samePin(other.pin, in.pin)) continue;
      for (int j = 0; j < gb::kAdcChannelCount; ++j) {
        EXPECT_FALSE(g474::kAnalogInputs[j].adc == 1 && g474::kAnalogInputs[j].channel == other.channel) << f;
      }
    }
  }
}

TEST(McuStm32g474PinPlan, TheCheckerRejectsEachKindOfBadPlan) {
  const g474::PinList board = g474::boardPins();
  auto check = [&](const AnalogInput* plan, size_t n) {
    const g474::AnalogPlanCheck c = g474::checkAnalogPlan(plan, n, board.pins, board.n);
    EXPECT_EQ(c.ok(), planValidBySets(plan, n, board.pins, board.n));  // both checkers agree
    return c;
  };
  // The old plan's last entry: ADC2_IN8 on PC2, a pin ADC1_IN8 (and LPTIM1) also has.
  const AnalogInput old_current[2] = {{1, 8, {'C', 2, g474::kGpioIn}}, {2, 8, {'C', 2, g474::kGpioIn}}};
  // ADC12_IN1: PA0 through ADC1 and through ADC2 is one pin twice (PA0 is also TIM5's input: taken on the board).
  const AnalogInput adc12_shared[2] = {{1, 1, {'A', 0, g474::kGpioIn}}, {2, 1, {'A', 0, g474::kGpioIn}}};
  EXPECT_EQ(g474::checkAnalogPlan(adc12_shared, 2, nullptr, 0).error, AnalogPlanError::kPinTwice);
  EXPECT_EQ(check(adc12_shared, 2).error, AnalogPlanError::kPinTaken);
  {
    // PC2 is LPTIM1's input on the board: taken.
    const g474::AnalogPlanCheck c = check(old_current, 2);
    EXPECT_EQ(c.error, AnalogPlanError::kPinTaken);
    EXPECT_EQ(c.index, 0u);
    // Without the board's pins: the second entry repeats the pin.
    const g474::AnalogPlanCheck c2 = g474::checkAnalogPlan(old_current, 2, nullptr, 0);
    EXPECT_EQ(c2.error, AnalogPlanError::kPinTwice);
    EXPECT_EQ(c2.index, 1u);
  }
  {
    const AnalogInput same_pair[2] = {{3, 4, {'E', 7, g474::kGpioIn}}, {3, 4, {'E', 7, g474::kGpioIn}}};
    EXPECT_EQ(g474::checkAnalogPlan(same_pair, 2, nullptr, 0).error, AnalogPlanError::kPinTwice);
    // ADC3_IN6 and ADC4_IN6 are one pin (PE8): the same pin twice, through two ADCs.
    const AnalogInput shared345[2] = {{3, 6, {'E', 8, g474::kGpioIn}}, {4, 6, {'E', 8, g474::kGpioIn}}};
    EXPECT_EQ(check(shared345, 2).error, AnalogPlanError::kPinTwice);
  }
  {
    const AnalogInput no_such[1] = {{5, 3, {'A', 2, g474::kGpioIn}}};  // ADC5_IN3 has no pin
    EXPECT_EQ(check(no_such, 1).error, AnalogPlanError::kNoSuchInput);
    const AnalogInput no_adc6[1] = {{6, 1, {'A', 2, g474::kGpioIn}}};
    EXPECT_EQ(check(no_adc6, 1).error, AnalogPlanError::kNoSuchInput);
    const AnalogInput wrong_pin[1] = {{3, 1, {'B', 0, g474::kGpioIn}}};  // ADC3_IN1 is PB1
    EXPECT_EQ(check(wrong_pin, 1).error, AnalogPlanError::kWrongPin);
  }
  {
    // Pins of other functions: PWM (ADC5_IN1 = PA8 = TIM1_CH1), encoder (ADC345_IN9 = PD12 = TIM4_CH1),
    // drive enable (ADC1_IN11 = PB12), crystal (ADC1_IN10 = PF0), encoder TIM3 (ADC2_IN3 = PA6).
    const AnalogInput taken[5] = {{5, 1, {'A', 8, g474::kGpioIn}},
                                  {4, 9, {'D', 12, g474::kGpioIn}},
                                  {1, 11, {'B', 12, g474::kGpioIn}},
                                  {1, 10, {'F', 0, g474::kGpioIn}},
                                  {2, 3, {'A', 6, g474::kGpioIn}}};
    for (const AnalogInput& in : taken) {
      EXPECT_EQ(check(&in, 1).error, AnalogPlanError::kPinTaken) << int{in.adc} << "/" << int{in.channel};
    }
    // PA6 is free in an image without encoders (the glove's), taken in the SEA image (TIM3 = encoder 1).
    const g474::ImagePins glove = g474::imagePins(5, 0, 0), sea = g474::imagePins(2, 2, 0);
    const AnalogInput pa6{2, 3, {'A', 6, g474::kGpioIn}};
    EXPECT_TRUE(g474::checkAnalogPlan(&pa6, 1, glove.pins, glove.n).ok());
    EXPECT_EQ(g474::checkAnalogPlan(&pa6, 1, sea.pins, sea.n).error, AnalogPlanError::kPinTaken);
  }
  {
    // Sixteen conversions on one ADC is the most a sequence holds and the most any ADC has inputs for (ADC4: 16), so
    // a seventeenth entry on one ADC always repeats a pin or pair first; splitAnalogInputs refuses it on its own.
    AnalogInput many[17] = {};
    size_t n = 0;
    for (const auto& d : g474::kDeviceAdcInputs) {
      if (d.adc == 4 && n < 16) many[n++] = {d.adc, d.channel, d.pin};
    }
    ASSERT_EQ(n, 16u);
    EXPECT_TRUE(g474::checkAnalogPlan(many, 16, nullptr, 0).ok());
    EXPECT_TRUE(g474::splitAnalogInputs(many, 16).ok);
    many[16] = many[0];
    EXPECT_FALSE(g474::checkAnalogPlan(many, 17, nullptr, 0).ok());
    EXPECT_FALSE(g474::splitAnalogInputs(many, 17).ok);
  }
  // Mutating any one entry of the real plan onto another entry's pin or pair is caught.
  for (size_t i = 1; i < g474::kAnalogInputCount; ++i) {
    AnalogInput plan[g474::kAnalogInputCount];
    for (size_t k = 0; k < g474::kAnalogInputCount; ++k) plan[k] = g474::kAnalogInputs[k];
    plan[i] = plan[i - 1];
    EXPECT_FALSE(check(plan, g474::kAnalogInputCount).ok()) << i;
    plan[i] = g474::kAnalogInputs[i];
    plan[i].channel = static_cast<uint8_t>(plan[i].channel + 1);  // now a different (or no) input on the old pin
    EXPECT_FALSE(check(plan, g474::kAnalogInputCount).ok()) << i;
  }
}

TEST(McuStm32g474PinPlan, AnalogInputsSplitIntoSixteenRankSequencesWithConsistentRanks) {
  for (size_t n = 0; n <= g474::kAnalogInputCount; ++n) {
    const g474::AnalogSplit s = g474::splitAnalogInputs(n);
    ASSERT_TRUE(s.ok) << n;
    size_t total = 0;
    for (size_t a = 0; a < g474::kAdcCount; ++a) total += s.len[a];
    EXPECT_EQ(total, n);
    for (size_t i = 0; i < n; ++i) {
      const size_t a = s.adc_index[i];
      EXPECT_EQ(a + 1, g474::kAnalogInputs[i].adc);
      ASSERT_LT(s.rank[i], s.len[a]);
      EXPECT_EQ(s.seq[a][s.rank[i]], g474::kAnalogInputs[i].channel);
    }
    for (size_t a = 0; a < g474::kAdcCount; ++a) {
      if (s.len[a] == 0) continue;
      const phalanx::mcu::stm32g4::AdcSequence q = phalanx::mcu::stm32g4::adcSequence(s.seq[a], s.len[a]);
      EXPECT_TRUE(q.ok) << n;
      EXPECT_EQ(q.sqr[0] & 0xFu, s.len[a] - 1);  // L = length − 1
    }
  }
  // The glove uses all five ADCs; the SEA and pen images only ADC1/ADC2 (ADC3..5 stay off).
  const g474::AnalogSplit glove = g474::splitAnalogInputs(25);
  for (size_t a = 0; a < g474::kAdcCount; ++a) EXPECT_GT(glove.len[a], 0u) << a;
  const g474::AnalogSplit sea = g474::splitAnalogInputs(9);
  EXPECT_EQ(sea.len[2] + sea.len[3] + sea.len[4], 0u);
  EXPECT_FALSE(g474::splitAnalogInputs(g474::kAnalogInputCount + 1).ok);
  const AnalogInput bad_adc[1] = {{0, 1, {'A', 0, g474::kGpioIn}}};
  EXPECT_FALSE(g474::splitAnalogInputs(bad_adc, 1).ok);
  // Each (ADC, channel) pair is converted once.
  std::set<std::pair<int, int>> pairs;
  for (const auto& in : g474::kAnalogInputs) EXPECT_TRUE(pairs.insert({in.adc, in.channel}).second);
}

TEST(McuStm32g474PinPlan, AdcUnitsAndDmaBookkeeping) {
  EXPECT_TRUE(g474::dmaPlanDistinct());
  // ADC1/2 on the ADC12 common block, ADC3/4/5 on ADC345's; DMAMUX requests per RM0440 Table 91.
  const uint8_t req[5] = {5, 36, 37, 38, 39};
  std::set<int> channels = {g474::kUsartRxDmaChannel, g474::kUsartTxDmaChannel};
  for (size_t a = 0; a < g474::kAdcCount; ++a) {
    EXPECT_EQ(g474::kAdcUnits[a].common, a < 2 ? g474::kAdc12CommonBase : g474::kAdc345CommonBase);
    EXPECT_EQ(g474::kAdcUnits[a].dmamux_request, req[a]);
    EXPECT_TRUE(channels.insert(g474::kAdcUnits[a].dma1_channel).second) << a;
    EXPECT_EQ(g474::kAdcUnits[a].base & 0xFFu, 0u);
  }
  // A DMA double buffer per ADC (2·len samples): the reader takes the half the DMA is not writing, for every
  // sequence length the glove plan produces.
  const g474::AnalogSplit glove = g474::splitAnalogInputs(25);
  for (size_t a = 0; a < g474::kAdcCount; ++a) {
    const size_t len = glove.len[a];
    for (uint32_t cndtr = 1; cndtr <= 2 * len; ++cndtr) {
      const size_t w = phalanx::mcu::stm32g4::dmaWriteIndex(2 * len, cndtr);
      const size_t off = phalanx::mcu::stm32g4::stableScanOffset(len, w);
      EXPECT_TRUE(w < off || w >= off + len) << a << " " << cndtr;  // the half read is not being written
    }
  }
}
