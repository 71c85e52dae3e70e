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

/// Index of the first pin in `pins` that repeats an earlier one (same port and number), or n if none.
constexpr size_t firstRepeatedPin(const Pin* pins, size_t n) {
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = 0; j < i; ++j) {
      if (pins[i].port == pins[j].port && pins[i].n == pins[j].n) return i;
    }
  }
  return n;
}

/// Every pin the board claims, for the largest image (8 PWM + 8 direction lines, 6 encoders).
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

}  // namespace phalanx::mcu::g474
