#pragma once
/// USART baud-rate divisor (RM0440 §37.5.7): with 16× oversampling BRR = USARTDIV = f_ck / baud (≥ 16);
/// with 8× oversampling USARTDIV = 2·f_ck / baud, BRR[15:4] = USARTDIV[15:4], BRR[3] = 0,
/// BRR[2:0] = USARTDIV[3:0] >> 1. Pure arithmetic, tested on the host.
#include <cstdint>

namespace phalanx::mcu::stm32g4 {

struct UartDivisor {
  bool ok = false;
  bool over8 = false;      ///< CR1.OVER8
  uint16_t brr = 0;
  uint32_t actual_baud = 0;
  int32_t error_ppm = 0;   ///< (actual − wanted) / wanted
};

constexpr UartDivisor uartDivisor(uint32_t ck_hz, uint32_t baud) {
  UartDivisor d{};
  if (baud == 0) return d;
  const uint32_t div16 = static_cast<uint32_t>((static_cast<uint64_t>(ck_hz) + baud / 2u) / baud);
  uint32_t usartdiv = 0;
  if (div16 >= 16u && div16 <= 0xFFFFu) {
    d.brr = static_cast<uint16_t>(div16);
    usartdiv = div16;
    d.actual_baud = static_cast<uint32_t>(static_cast<uint64_t>(ck_hz) / div16);
  } else {
    const uint32_t div8 = static_cast<uint32_t>((2u * static_cast<uint64_t>(ck_hz) + baud / 2u) / baud);
    if (div8 < 16u || div8 > 0xFFFFu) return d;
    d.over8 = true;
    d.brr = static_cast<uint16_t>((div8 & 0xFFF0u) | ((div8 & 0xFu) >> 1));
    usartdiv = div8;
    d.actual_baud = static_cast<uint32_t>(2u * static_cast<uint64_t>(ck_hz) / div8);
  }
  d.ok = usartdiv != 0;
  d.error_ppm = static_cast<int32_t>((static_cast<int64_t>(d.actual_baud) - baud) * 1000000 / baud);
  return d;
}

/// Bytes per second a UART link carries at a baud rate (8N1: 10 bit times per byte).
constexpr uint32_t uartBytesPerSecond(uint32_t baud) { return baud / 10u; }

}  // namespace phalanx::mcu::stm32g4
