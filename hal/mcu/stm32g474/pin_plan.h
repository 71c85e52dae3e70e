#pragma once
/// Board pin plan of the project's STM32G474 motor board: every digital pin the drivers claim, with its
/// alternate function (AF) number from the STM32G474 datasheet's alternate-function table (DS12288, Table 13).
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

/// Analog input i of an image (AdcScan channel i): converted by ADC1 or ADC2, regular channel `channel`
/// (ADC12_INx pin table, DS12288 Table 13). Ordered so that the first kAnalogInputsFree entries use pins that
/// nothing else on the board claims even with all six encoders fitted; entries up to kAnalogInputsWithOwnPin use
/// encoder pins (free in images with fewer encoders: the image check below decides); the rest have no pin of
/// their own on ADC1/ADC2 (they repeat a pin of an earlier entry): an image needing them (glove5, 25 channels)
/// needs ADC3–ADC5, which this port does not drive yet (docs/firmware-mcu.md).
struct AnalogInput {
  uint8_t adc = 0;      ///< 1 or 2
  uint8_t channel = 0;  ///< ADCx_INchannel
  Pin pin{};
};
constexpr size_t kAnalogInputCount = 25;
constexpr size_t kAnalogInputsFree = 14;
constexpr size_t kAnalogInputsWithOwnPin = 20;
constexpr AnalogInput kAnalogInputs[kAnalogInputCount] = {
    // Pins of their own, whatever the image (alternating ADCs so both convert in parallel).
    {1, 3, {'A', 2, kGpioIn}}, {2, 13, {'A', 5, kGpioIn}}, {1, 4, {'A', 3, kGpioIn}}, {2, 17, {'A', 4, kGpioIn}},
    {1, 5, {'B', 14, kGpioIn}}, {2, 5, {'C', 4, kGpioIn}}, {1, 12, {'B', 1, kGpioIn}}, {2, 11, {'C', 5, kGpioIn}},
    {1, 15, {'B', 0, kGpioIn}}, {2, 12, {'B', 2, kGpioIn}}, {1, 7, {'C', 1, kGpioIn}}, {2, 15, {'B', 15, kGpioIn}},
    {1, 9, {'C', 3, kGpioIn}}, {1, 14, {'B', 11, kGpioIn}},
    // Encoder pins: TIM5 (encoder 3), TIM3 (encoder 1), LPTIM1 (encoder 5).
    {1, 1, {'A', 0, kGpioIn}}, {1, 2, {'A', 1, kGpioIn}}, {2, 3, {'A', 6, kGpioIn}}, {2, 4, {'A', 7, kGpioIn}},
    {1, 6, {'C', 0, kGpioIn}}, {1, 8, {'C', 2, kGpioIn}},
    // No pin of their own on ADC1/ADC2 (ADC12 channels 1, 2, 6, 7, 8 repeat PA0, PA1, PC0, PC1, PC2 on ADC2).
    {2, 1, {'A', 0, kGpioIn}}, {2, 2, {'A', 1, kGpioIn}}, {2, 6, {'C', 0, kGpioIn}}, {2, 7, {'C', 1, kGpioIn}},
    {2, 8, {'C', 2, kGpioIn}},
};

/// How the first n analog inputs split over the two ADCs: each ADC's regular sequence (in rank order) and,
/// per input, its ADC and rank. ok = false if n is out of range or an ADC would need more than 16 ranks.
struct AnalogSplit {
  bool ok = false;
  uint8_t seq[2][16] = {};  ///< ADC1, ADC2 channel numbers by rank
  size_t len[2] = {0, 0};
  uint8_t adc_index[kAnalogInputCount] = {};  ///< 0: ADC1, 1: ADC2
  uint8_t rank[kAnalogInputCount] = {};
};
constexpr AnalogSplit splitAnalogInputs(size_t n) {
  AnalogSplit s{};
  if (n > kAnalogInputCount) return s;
  for (size_t i = 0; i < n; ++i) {
    const size_t a = kAnalogInputs[i].adc == 1 ? 0u : 1u;
    if (s.len[a] == 16) return s;
    s.adc_index[i] = static_cast<uint8_t>(a);
    s.rank[i] = static_cast<uint8_t>(s.len[a]);
    s.seq[a][s.len[a]++] = kAnalogInputs[i].channel;
  }
  s.ok = true;
  return s;
}

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
/// inputs (at most kAnalogInputsWithOwnPin of them: beyond, pins repeat by construction, see kAnalogInputs), the
/// link, CAN, drive enable, e-stop, crystal and debug pins. No repeat in the result = no pin conflict.
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
  for (size_t i = 0; i < analog && i < kAnalogInputsWithOwnPin; ++i) add(kAnalogInputs[i].pin);
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

}  // namespace phalanx::mcu::g474
