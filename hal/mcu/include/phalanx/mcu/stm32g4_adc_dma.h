#pragma once
/// ADC sequence registers and DMA circular-buffer bookkeeping for the STM32G4 (RM0440 §21 ADC, §12 DMA).
/// Pure functions and small state machines, tested on the host.
#include <cstddef>
#include <cstdint>

namespace phalanx::mcu::stm32g4 {

/// Regular sequence of up to 16 conversions (ADC_SQR1..4): SQR1 holds L = n−1 in [3:0] and SQ1..SQ4 at bits
/// 6, 12, 18, 24; SQR2 SQ5..SQ9, SQR3 SQ10..SQ14 and SQR4 SQ15..SQ16 at bits 0, 6, 12, 18, 24 (5 bits each).
struct AdcSequence {
  bool ok = false;
  uint32_t sqr[4] = {};
};
constexpr AdcSequence adcSequence(const uint8_t* channels, size_t n) {
  AdcSequence s{};
  if (n == 0 || n > 16) return s;
  s.sqr[0] = static_cast<uint32_t>(n - 1u);
  for (size_t i = 0; i < n; ++i) {
    if (channels[i] > 18u) return s;
    const size_t rank = i + 1u;  // SQ1 is rank 1
    if (rank <= 4u) s.sqr[0] |= static_cast<uint32_t>(channels[i]) << (6u * rank);
    else if (rank <= 9u) s.sqr[1] |= static_cast<uint32_t>(channels[i]) << (6u * (rank - 5u));
    else if (rank <= 14u) s.sqr[2] |= static_cast<uint32_t>(channels[i]) << (6u * (rank - 10u));
    else s.sqr[3] |= static_cast<uint32_t>(channels[i]) << (6u * (rank - 15u));
  }
  s.ok = true;
  return s;
}

/// Sample-time field: SMPR1 covers channels 0..9, SMPR2 10..18, 3 bits per channel. Returns {register index, shift}.
struct SmprField {
  uint8_t reg = 0;    ///< 0: SMPR1, 1: SMPR2
  uint8_t shift = 0;
};
constexpr SmprField smprField(uint8_t channel) {
  return channel < 10u ? SmprField{0, static_cast<uint8_t>(3u * channel)}
                       : SmprField{1, static_cast<uint8_t>(3u * (channel - 10u))};
}

/// ADC_CFGR2 for regular-channel oversampling (RM0440 §21.4.30, §21.7.4): ROVSE (bit 0), OVSR [4:2] = log2(ratio) − 1,
/// OVSS [8:5] = log2(ratio), so the sum of `ratio` conversions is shifted back to a 12-bit average. `ratio` 1: off
/// (0); anything but a power of two in 2..256 is refused (returns 0xFFFFFFFF).
inline constexpr uint32_t kAdcCfgr2Invalid = 0xFFFFFFFFu;
constexpr uint32_t adcCfgr2Oversampling(uint32_t ratio) {
  if (ratio == 1u) return 0u;
  uint32_t log2 = 0;
  while (log2 < 9u && (1u << log2) < ratio) ++log2;
  if (log2 < 1u || log2 > 8u || (1u << log2) != ratio) return kAdcCfgr2Invalid;
  return 1u | ((log2 - 1u) << 2) | (log2 << 5);
}

/// Where a circular DMA transfer is: the channel's CNDTR counts down from len to 1 and reloads, so the index
/// the DMA writes next is len − CNDTR (CNDTR = len right after a reload ⇒ index 0).
constexpr size_t dmaWriteIndex(size_t len, uint32_t cndtr) {
  return (cndtr == 0u || cndtr > len) ? 0u : len - cndtr;
}

/// Consumer side of a byte stream that a DMA channel writes into a circular buffer (UART RX): each poll()
/// reports the bytes written since the last poll as at most two contiguous spans. The caller must poll at
/// least once per buffer length of traffic (a 256-byte buffer at 2 Mbaud: every 1.28 ms); an overrun is not
/// detectable from CNDTR alone, so the half/full-transfer interrupts bound it in the board code.
class DmaRxTracker {
 public:
  explicit constexpr DmaRxTracker(size_t len) : len_(len) {}
  struct Spans {
    size_t first_begin = 0, first_len = 0;
    size_t second_len = 0;  ///< second span always starts at index 0
    size_t total() const { return first_len + second_len; }
  };
  Spans poll(uint32_t cndtr) {
    const size_t w = dmaWriteIndex(len_, cndtr);
    Spans s{};
    s.first_begin = read_;
    if (w >= read_) {
      s.first_len = w - read_;
    } else {
      s.first_len = len_ - read_;
      s.second_len = w;
    }
    read_ = w;
    return s;
  }
  size_t readIndex() const { return read_; }

 private:
  size_t len_;
  size_t read_ = 0;
};

/// ADC scans written by circular DMA into a double buffer of 2·n samples: the half-transfer interrupt means the
/// first n are complete, the transfer-complete interrupt the second n. Returns the offset of the newest complete
/// scan for a DMA write index (the half the DMA is not writing now).
constexpr size_t stableScanOffset(size_t n, size_t write_index) { return write_index < n ? n : 0u; }

}  // namespace phalanx::mcu::stm32g4
