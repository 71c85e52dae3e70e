#pragma once
/// Board pin plan of the project's STM32G474 motor board: every digital pin the drivers claim, with its
/// alternate function (AF) number from the STM32G474 datasheet's alternate-function table (DS12288, Table 13), and
/// every analog input with its ADC and channel, checked against the datasheet's ADC input table below.
/// This is the project's reading of the datasheet, not checked against a schematic or on silicon
/// (docs/firmware-mcu.md). Pure data plus a constexpr conflict check, compiled into the image (static_assert in
/// board.cpp) and unit-tested on the host (tests/unit/mcu_stm32g4_encoder_test.cpp).
#include <cstddef>
#include <cstdint>

namespace phalanx::mcu::g474 {

struct Pin {
  char port = 0;     ///< 'A'..'G'
  uint8_t n = 0;     ///< 0..15
  uint8_t af = 0;    ///< alternate function, or kGpioOut / kGpioIn
};
constexpr uint8_t kGpioOut = 0xF0, kGpioIn = 0xF1;

/// PWM channel i (BridgePwm): 0..3 TIM1 CH1..CH4, 4..7 TIM8 CH1..CH4.
constexpr Pin kPwmPins[8] = {{'A', 8, 6},  {'A', 9, 6},  {'A', 10, 6}, {'A', 11, 11},
                             {'C', 6, 4},  {'C', 7, 4},  {'C', 8, 4},  {'C', 9, 4}};
/// Direction (PH) line of PWM channel i: PD0..PD7. (PE2/PE3 carry TIM20's encoder inputs.)
constexpr char kDirectionPort = 'D';
constexpr Pin kDirectionPins[8] = {{'D', 0, kGpioOut}, {'D', 1, kGpioOut}, {'D', 2, kGpioOut}, {'D', 3, kGpioOut},
                                   {'D', 4, kGpioOut}, {'D', 5, kGpioOut}, {'D', 6, kGpioOut}, {'D', 7, kGpioOut}};

/// Encoder channel i (TimerEncoders), inputs A and B. The counting unit of each channel is in board.cpp
/// (kEncoderUnits): TIM2, TIM3, TIM4, TIM5, TIM20 in encoder mode 3, then LPTIM1 in encoder mode. TIM1 and TIM8
/// are the PWM timers; TIM15/16/17 have no encoder interface, so LPTIM1 is the sixth counter.
constexpr size_t kMaxEncoders = 6;
constexpr Pin kEncoderPins[kMaxEncoders][2] = {
    {{'A', 15, 1}, {'B', 3, 1}},   // TIM2_CH1/CH2 (PA15/PB3: JTDI/JTDO, free with SWD-only debug)
    {{'A', 6, 2}, {'A', 7, 2}},    // TIM3_CH1/CH2
    {{'D', 12, 2}, {'D', 13, 2}},  // TIM4_CH1/CH2
    {{'A', 0, 2}, {'A', 1, 2}},    // TIM5_CH1/CH2
    {{'E', 2, 6}, {'E', 3, 6}},    // TIM20_CH1/CH2
    {{'C', 0, 1}, {'C', 2, 1}},    // LPTIM1_IN1/IN2
};

constexpr Pin kUsartPins[2] = {{'B', 6, 7}, {'B', 7, 7}};   // USART1 TX/RX
constexpr Pin kFdcanPins[2] = {{'B', 8, 9}, {'B', 9, 9}};   // FDCAN1 RX/TX
constexpr Pin kDriveEnablePin = {'B', 12, kGpioOut};
constexpr Pin kEstopPin = {'C', 13, kGpioIn};
constexpr Pin kHsePins[2] = {{'F', 0, kGpioIn}, {'F', 1, kGpioIn}};  // 24 MHz crystal (OSC_IN/OSC_OUT)
constexpr Pin kSwdPins[2] = {{'A', 13, 0}, {'A', 14, 0}};         // SWDIO/SWCLK (debug, reset state)

/// One regular input channel of ADC1..ADC5 that is bonded to a GPIO pin: ADC `adc`, input ADCx_IN`channel`.
struct AdcPinChannel {
  uint8_t adc = 0;      ///< 1..5
  uint8_t channel = 0;  ///< ADCx_INchannel
  Pin pin{};
};
/// Every GPIO-connected regular input of the STM32G474's five ADCs (DS12288 Table 13 "STM32G474xx pin
/// definitions", additional functions ADC12_INx / ADC1_INx / ADC2_INx / ADC3_INx / ADC345_INx / ADC45_INx,
/// with RM0440 §21.4.x "ADC connectivity"). Several pins are shared: ADC12_IN1/2/6–9/14 (PA0, PA1, PC0–PC3, PB11)
/// reach ADC1 and ADC2 through the same channel number; ADC345_IN6–11/14–16 (PE8, PD10–PD14, PE10–PE12) reach
/// ADC3, ADC4 and ADC5 (ADC45_IN12/13, PD8/PD9: ADC4 and ADC5); and PB0, PB1, PB12, PB14, PB15 reach ADC1/ADC2
/// under one number and ADC3/ADC4 under another. Channels without a pin (internal: OPAMP outputs, temperature
/// sensor, V_BAT/3, V_REFINT, DAC) are not listed. Port D and E pins 7–15 exist on the 100-pin and larger
/// packages only; the board already needs such a package (PD0–PD7 direction lines, TIM4/TIM20 encoder pins).
constexpr AdcPinChannel kDeviceAdcInputs[] = {
    // ADC1
    {1, 1, {'A', 0, kGpioIn}}, {1, 2, {'A', 1, kGpioIn}}, {1, 3, {'A', 2, kGpioIn}}, {1, 4, {'A', 3, kGpioIn}},
    {1, 5, {'B', 14, kGpioIn}}, {1, 6, {'C', 0, kGpioIn}}, {1, 7, {'C', 1, kGpioIn}}, {1, 8, {'C', 2, kGpioIn}},
    {1, 9, {'C', 3, kGpioIn}}, {1, 10, {'F', 0, kGpioIn}}, {1, 11, {'B', 12, kGpioIn}}, {1, 12, {'B', 1, kGpioIn}},
    {1, 14, {'B', 11, kGpioIn}}, {1, 15, {'B', 0, kGpioIn}},
    // ADC2
    {2, 1, {'A', 0, kGpioIn}}, {2, 2, {'A', 1, kGpioIn}}, {2, 3, {'A', 6, kGpioIn}}, {2, 4, {'A', 7, kGpioIn}},
    {2, 5, {'C', 4, kGpioIn}}, {2, 6, {'C', 0, kGpioIn}}, {2, 7, {'C', 1, kGpioIn}}, {2, 8, {'C', 2, kGpioIn}},
    {2, 9, {'C', 3, kGpioIn}}, {2, 10, {'F', 1, kGpioIn}}, {2, 11, {'C', 5, kGpioIn}}, {2, 12, {'B', 2, kGpioIn}},
    {2, 13, {'A', 5, kGpioIn}}, {2, 14, {'B', 11, kGpioIn}}, {2, 15, {'B', 15, kGpioIn}}, {2, 17, {'A', 4, kGpioIn}},
    // ADC3
    {3, 1, {'B', 1, kGpioIn}}, {3, 2, {'E', 9, kGpioIn}}, {3, 3, {'E', 13, kGpioIn}}, {3, 4, {'E', 7, kGpioIn}},
    {3, 5, {'B', 13, kGpioIn}}, {3, 6, {'E', 8, kGpioIn}}, {3, 7, {'D', 10, kGpioIn}}, {3, 8, {'D', 11, kGpioIn}},
    {3, 9, {'D', 12, kGpioIn}}, {3, 10, {'D', 13, kGpioIn}}, {3, 11, {'D', 14, kGpioIn}}, {3, 12, {'B', 0, kGpioIn}},
    {3, 14, {'E', 10, kGpioIn}}, {3, 15, {'E', 11, kGpioIn}}, {3, 16, {'E', 12, kGpioIn}},
    // ADC4
    {4, 1, {'E', 14, kGpioIn}}, {4, 2, {'E', 15, kGpioIn}}, {4, 3, {'B', 12, kGpioIn}}, {4, 4, {'B', 14, kGpioIn}},
    {4, 5, {'B', 15, kGpioIn}}, {4, 6, {'E', 8, kGpioIn}}, {4, 7, {'D', 10, kGpioIn}}, {4, 8, {'D', 11, kGpioIn}},
    {4, 9, {'D', 12, kGpioIn}}, {4, 10, {'D', 13, kGpioIn}}, {4, 11, {'D', 14, kGpioIn}}, {4, 12, {'D', 8, kGpioIn}},
    {4, 13, {'D', 9, kGpioIn}}, {4, 14, {'E', 10, kGpioIn}}, {4, 15, {'E', 11, kGpioIn}}, {4, 16, {'E', 12, kGpioIn}},
    // ADC5
    {5, 1, {'A', 8, kGpioIn}}, {5, 2, {'A', 9, kGpioIn}}, {5, 6, {'E', 8, kGpioIn}}, {5, 7, {'D', 10, kGpioIn}},
    {5, 8, {'D', 11, kGpioIn}}, {5, 9, {'D', 12, kGpioIn}}, {5, 10, {'D', 13, kGpioIn}}, {5, 11, {'D', 14, kGpioIn}},
    {5, 12, {'D', 8, kGpioIn}}, {5, 13, {'D', 9, kGpioIn}}, {5, 14, {'E', 10, kGpioIn}}, {5, 15, {'E', 11, kGpioIn}},
    {5, 16, {'E', 12, kGpioIn}},
};
constexpr size_t kDeviceAdcInputCount = sizeof(kDeviceAdcInputs) / sizeof(kDeviceAdcInputs[0]);

/// The ADCs of the STM32G474 and the DMA channel that empties each one's regular data register. ADC1/ADC2 share
/// the common block ADC12_COMMON (0x5000_0300, clock RCC_AHB2ENR.ADC12EN), ADC3/ADC4/ADC5 the block ADC345_COMMON
/// (0x5000_0700, ADC345EN); all five sit on AHB2 (RM0440 §2.2.2 memory map). DMAMUX request inputs: RM0440
/// Table 91 (ADC1 5, ADC2 36, ADC3 37, ADC4 38, ADC5 39). DMA1 channels 3/4 are the USART1 RX/TX (below).
struct AdcUnit {
  uint32_t base = 0;
  uint32_t common = 0;         ///< ADC12_COMMON or ADC345_COMMON
  uint8_t dma1_channel = 0;    ///< DMA1 channel 1..8 (DMAMUX channel = this − 1)
  uint8_t dmamux_request = 0;
};
constexpr size_t kAdcCount = 5;
constexpr uint32_t kAdc12CommonBase = 0x50000300u, kAdc345CommonBase = 0x50000700u;
constexpr AdcUnit kAdcUnits[kAdcCount] = {
    {0x50000000u, kAdc12CommonBase, 1, 5},  {0x50000100u, kAdc12CommonBase, 2, 36},
    {0x50000400u, kAdc345CommonBase, 5, 37}, {0x50000500u, kAdc345CommonBase, 6, 38},
    {0x50000600u, kAdc345CommonBase, 7, 39},
};
constexpr uint8_t kUsartRxDmaChannel = 3, kUsartTxDmaChannel = 4;
constexpr uint8_t kDmareqUsart1RxPlan = 24, kDmareqUsart1TxPlan = 25;  ///< RM0440 Table 91
constexpr size_t kMaxRanksPerAdc = 16;  ///< ADC_SQR1.L: up to 16 regular conversions

/// DMA bookkeeping of the board: every DMA1 channel (1..8) serves one peripheral, and no DMAMUX request is routed
/// to two channels (an ADC's and the USART's requests included).
constexpr bool dmaPlanDistinct() {
  uint8_t ch[kAdcCount + 2] = {}, req[kAdcCount + 2] = {};
  for (size_t a = 0; a < kAdcCount; ++a) {
    ch[a] = kAdcUnits[a].dma1_channel;
    req[a] = kAdcUnits[a].dmamux_request;
  }
  ch[kAdcCount] = kUsartRxDmaChannel;
  ch[kAdcCount + 1] = kUsartTxDmaChannel;
  req[kAdcCount] = kDmareqUsart1RxPlan;
  req[kAdcCount + 1] = kDmareqUsart1TxPlan;
  for (size_t i = 0; i < kAdcCount + 2; ++i) {
    if (ch[i] < 1u || ch[i] > 8u || req[i] == 0u) return false;
    for (size_t j = 0; j < i; ++j) {
      if (ch[i] == ch[j] || req[i] == req[j]) return false;
    }
  }
  return true;
}

/// Analog input i of an image (AdcScan channel i = the app's ADC channel i): converted by ADC `adc`, regular input
/// `channel`, on `pin`. Every entry is on a pin that nothing else on the board claims (no PWM, direction, encoder,
/// link, CAN, drive-enable, e-stop, crystal or debug pin), so any prefix of the table fits any image;
/// checkAnalogPlan() proves it (static_assert in main.cpp, tests/unit/mcu_stm32g474_pin_plan_test.cpp).
/// Images take the first n entries: sea_finger 9, pantograph 6, glove5 all 25 (15 Hall, 5 strain gauges, 5 motor
/// current-sense amplifiers: glove/board.h channel map). Entries 0–13 are on ADC1/ADC2 (alternating, so both
/// convert in parallel); 14–24 on ADC3/ADC4/ADC5 (round robin), on port E/D/B pins of those ADCs that the board
/// leaves free (PD12/PD13, also ADC345 inputs, are TIM4's encoder pins and stay digital).
struct AnalogInput {
  uint8_t adc = 0;      ///< 1..5
  uint8_t channel = 0;  ///< ADCx_INchannel
  Pin pin{};
};
constexpr size_t kAnalogInputCount = 25;
constexpr AnalogInput kAnalogInputs[kAnalogInputCount] = {
    // ADC1 / ADC2 (unchanged from the first version of the port: sea_finger and pantograph use these only).
    {1, 3, {'A', 2, kGpioIn}}, {2, 13, {'A', 5, kGpioIn}}, {1, 4, {'A', 3, kGpioIn}}, {2, 17, {'A', 4, kGpioIn}},
    {1, 5, {'B', 14, kGpioIn}}, {2, 5, {'C', 4, kGpioIn}}, {1, 12, {'B', 1, kGpioIn}}, {2, 11, {'C', 5, kGpioIn}},
    {1, 15, {'B', 0, kGpioIn}}, {2, 12, {'B', 2, kGpioIn}}, {1, 7, {'C', 1, kGpioIn}}, {2, 15, {'B', 15, kGpioIn}},
    {1, 9, {'C', 3, kGpioIn}}, {1, 14, {'B', 11, kGpioIn}},
    // ADC3 / ADC4 / ADC5. glove5: 14 = little-finger α3 Hall, 15–19 the strain gauges, 20–24 the current sense.
    {3, 4, {'E', 7, kGpioIn}}, {4, 1, {'E', 14, kGpioIn}}, {5, 6, {'E', 8, kGpioIn}},
    {3, 2, {'E', 9, kGpioIn}}, {4, 2, {'E', 15, kGpioIn}}, {5, 14, {'E', 10, kGpioIn}},
    {3, 3, {'E', 13, kGpioIn}}, {4, 12, {'D', 8, kGpioIn}}, {5, 15, {'E', 11, kGpioIn}},
    {3, 5, {'B', 13, kGpioIn}}, {4, 13, {'D', 9, kGpioIn}},
};

/// The datasheet entry of (adc, channel), or nullptr if that ADC has no such GPIO-connected input.
constexpr const AdcPinChannel* deviceAdcInput(uint8_t adc, uint8_t channel) {
  for (const AdcPinChannel& d : kDeviceAdcInputs) {
    if (d.adc == adc && d.channel == channel) return &d;
  }
  return nullptr;
}

/// What is wrong with an analog channel plan (first problem found, in this order per entry).
enum class AnalogPlanError : uint8_t {
  kOk = 0,
  kNoSuchInput,      ///< (adc, channel) is not a GPIO-connected input of the STM32G474
  kWrongPin,         ///< the pair exists but is bonded to another pin than the plan says
  kPinTwice,         ///< two logical channels on the same pin (e.g. ADC12_IN1 on ADC1 and ADC2: one PA0)
  kPairTwice,        ///< two logical channels on the same (ADC, channel)
  kPinTaken,         ///< the pin is claimed by another function of the image (PWM, encoder, link, …)
  kTooManyRanks,     ///< an ADC would need more than 16 regular conversions
};
struct AnalogPlanCheck {
  AnalogPlanError error = AnalogPlanError::kOk;
  size_t index = 0;  ///< the offending logical channel
  constexpr bool ok() const { return error == AnalogPlanError::kOk; }
};
constexpr bool samePin(const Pin& a, const Pin& b) { return a.port == b.port && a.n == b.n; }
/// Checks logical channels plan[0..n) against the datasheet table and against `taken` (the image's other pins).
constexpr AnalogPlanCheck checkAnalogPlan(const AnalogInput* plan, size_t n, const Pin* taken, size_t n_taken) {
  size_t ranks[kAdcCount] = {};
  for (size_t i = 0; i < n; ++i) {
    const AnalogInput& in = plan[i];
    const AdcPinChannel* d = deviceAdcInput(in.adc, in.channel);
    if (d == nullptr) return {AnalogPlanError::kNoSuchInput, i};
    if (!samePin(d->pin, in.pin)) return {AnalogPlanError::kWrongPin, i};
    for (size_t j = 0; j < i; ++j) {
      if (samePin(plan[j].pin, in.pin)) return {AnalogPlanError::kPinTwice, i};
      if (plan[j].adc == in.adc && plan[j].channel == in.channel) return {AnalogPlanError::kPairTwice, i};
    }
    for (size_t t = 0; t < n_taken; ++t) {
      if (samePin(taken[t], in.pin)) return {AnalogPlanError::kPinTaken, i};
    }
    if (++ranks[in.adc - 1u] > kMaxRanksPerAdc) return {AnalogPlanError::kTooManyRanks, i};
  }
  return {};
}

/// How the first n analog inputs split over the five ADCs: each ADC's regular sequence (in rank order) and, per
/// input, its ADC and rank. ok = false if n is out of range, an entry names no ADC 1..5, or an ADC would need
/// more than 16 ranks.
struct AnalogSplit {
  bool ok = false;
  uint8_t seq[kAdcCount][kMaxRanksPerAdc] = {};  ///< channel numbers by rank, per ADC (index 0 = ADC1)
  size_t len[kAdcCount] = {};
  uint8_t adc_index[kAnalogInputCount] = {};  ///< 0..4 = ADC1..ADC5
  uint8_t rank[kAnalogInputCount] = {};
};
constexpr AnalogSplit splitAnalogInputs(const AnalogInput* plan, size_t n) {
  AnalogSplit s{};
  if (n > kAnalogInputCount) return s;
  for (size_t i = 0; i < n; ++i) {
    if (plan[i].adc < 1u || plan[i].adc > kAdcCount) return s;
    const size_t a = plan[i].adc - 1u;
    if (s.len[a] == kMaxRanksPerAdc) return s;
    s.adc_index[i] = static_cast<uint8_t>(a);
    s.rank[i] = static_cast<uint8_t>(s.len[a]);
    s.seq[a][s.len[a]++] = plan[i].channel;
  }
  s.ok = true;
  return s;
}
constexpr AnalogSplit splitAnalogInputs(size_t n) { return splitAnalogInputs(kAnalogInputs, n); }

/// Index of the first pin in `pins` that repeats an earlier one (same port and number), or n if none.
constexpr size_t firstRepeatedPin(const Pin* pins, size_t n) {
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = 0; j < i; ++j) {
      if (pins[i].port == pins[j].port && pins[i].n == pins[j].n) return i;
    }
  }
  return n;
}

/// Every fixed-function pin the board claims, for the largest image (8 PWM + 8 direction lines, 6 encoders).
constexpr size_t kBoardPinCount = 8 + 8 + 2 * kMaxEncoders + 2 + 2 + 1 + 1 + 2 + 2;
struct PinList {
  Pin pins[kBoardPinCount] = {};
  size_t n = 0;
  constexpr void add(const Pin& p) { pins[n++] = p; }
};
constexpr PinList boardPins() {
  PinList l{};
  for (const Pin& p : kPwmPins) l.add(p);
  for (const Pin& p : kDirectionPins) l.add(p);
  for (const auto& e : kEncoderPins) {
    l.add(e[0]);
    l.add(e[1]);
  }
  for (const Pin& p : kUsartPins) l.add(p);
  for (const Pin& p : kFdcanPins) l.add(p);
  l.add(kDriveEnablePin);
  l.add(kEstopPin);
  for (const Pin& p : kHsePins) l.add(p);
  for (const Pin& p : kSwdPins) l.add(p);
  return l;
}

/// The pins one image claims: its PWM channels and their direction lines, its encoders, the first `analog` analog
/// inputs, the link, CAN, drive enable, e-stop, crystal and debug pins. No repeat in the result = no pin conflict.
struct ImagePins {
  Pin pins[kBoardPinCount + kAnalogInputCount] = {};
  size_t n = 0;
};
constexpr ImagePins imagePins(size_t pwm, size_t encoders, size_t analog) {
  ImagePins l{};
  auto add = [&l](const Pin& p) { l.pins[l.n++] = p; };
  for (size_t i = 0; i < pwm && i < 8; ++i) {
    add(kPwmPins[i]);
    add(kDirectionPins[i]);
  }
  for (size_t i = 0; i < encoders && i < kMaxEncoders; ++i) {
    add(kEncoderPins[i][0]);
    add(kEncoderPins[i][1]);
  }
  for (size_t i = 0; i < analog && i < kAnalogInputCount; ++i) add(kAnalogInputs[i].pin);
  for (const Pin& p : kUsartPins) add(p);
  for (const Pin& p : kFdcanPins) add(p);
  add(kDriveEnablePin);
  add(kEstopPin);
  for (const Pin& p : kHsePins) add(p);
  for (const Pin& p : kSwdPins) add(p);
  return l;
}
constexpr bool imagePinsDistinct(size_t pwm, size_t encoders, size_t analog) {
  const ImagePins l = imagePins(pwm, encoders, analog);
  return firstRepeatedPin(l.pins, l.n) == l.n;
}

/// An image's analog channel plan (its first `analog` inputs) checked against the datasheet and against every
/// other pin the image claims (imagePins without the analog inputs).
constexpr AnalogPlanCheck checkImageAnalogPlan(size_t pwm, size_t encoders, size_t analog) {
  if (analog > kAnalogInputCount) return {AnalogPlanError::kNoSuchInput, kAnalogInputCount};
  const ImagePins others = imagePins(pwm, encoders, 0);
  return checkAnalogPlan(kAnalogInputs, analog, others.pins, others.n);
}
/// The whole table against every pin the board claims for its largest image (8 PWM, 6 encoders).
constexpr AnalogPlanCheck checkBoardAnalogPlan() {
  const PinList board = boardPins();
  return checkAnalogPlan(kAnalogInputs, kAnalogInputCount, board.pins, board.n);
}

}  // namespace phalanx::mcu::g474
