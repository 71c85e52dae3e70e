#pragma once
/// FDCAN bit timing and DLC arithmetic (RM0440 §44 FDCAN; ISO 11898-1:2015). Pure functions, tested on the host.
/// Bit time = (1 + TSEG1 + TSEG2) time quanta of (BRP / f_kernel); sample point = (1 + TSEG1) / total.
/// Nominal (arbitration) phase: NBRP 1..512, NTSEG1 2..256, NTSEG2 2..128, NSJW 1..128 (FDCAN_NBTP).
/// Data phase: DBRP 1..32, DTSEG1 1..32, DTSEG2 1..16, DSJW 1..16 (FDCAN_DBTP).
#include <cstdint>

namespace phalanx::mcu::stm32g4 {

struct CanBitTiming {
  bool ok = false;
  uint32_t brp = 0, tseg1 = 0, tseg2 = 0, sjw = 0;
  uint32_t tq_per_bit = 0;
  uint32_t sample_point_permille = 0;
};

struct CanTimingLimits {
  uint32_t brp_max, tseg1_min, tseg1_max, tseg2_min, tseg2_max, sjw_max;
};
constexpr CanTimingLimits kNominalLimits{512, 2, 256, 2, 128, 128};
constexpr CanTimingLimits kDataLimits{32, 1, 32, 1, 16, 16};

/// Exact timing for a bit rate with the sample point closest to sample_point_permille, smallest prescaler first
/// (most time quanta per bit). SJW = min(TSEG2, limit).
constexpr CanBitTiming canBitTiming(uint32_t kernel_hz, uint32_t bitrate, uint32_t sample_point_permille,
                                    const CanTimingLimits& lim) {
  CanBitTiming t{};
  if (bitrate == 0) return t;
  for (uint32_t brp = 1; brp <= lim.brp_max; ++brp) {
    if (kernel_hz % (brp * bitrate) != 0) continue;
    const uint32_t tq = kernel_hz / (brp * bitrate);
    const uint32_t max_tq = 1u + lim.tseg1_max + lim.tseg2_max;
    const uint32_t min_tq = 1u + lim.tseg1_min + lim.tseg2_min;
    if (tq > max_tq) continue;
    if (tq < min_tq) return t;
    uint32_t tseg2 = (tq * (1000u - sample_point_permille) + 500u) / 1000u;
    if (tseg2 < lim.tseg2_min) tseg2 = lim.tseg2_min;
    if (tseg2 > lim.tseg2_max) tseg2 = lim.tseg2_max;
    const uint32_t tseg1 = tq - 1u - tseg2;
    if (tseg1 < lim.tseg1_min || tseg1 > lim.tseg1_max) continue;
    t.ok = true;
    t.brp = brp;
    t.tseg1 = tseg1;
    t.tseg2 = tseg2;
    t.sjw = tseg2 < lim.sjw_max ? tseg2 : lim.sjw_max;
    t.tq_per_bit = tq;
    t.sample_point_permille = (1u + tseg1) * 1000u / tq;
    return t;
  }
  return t;
}

/// FDCAN_NBTP: NSJW [31:25], NBRP [24:16], NTSEG1 [15:8], NTSEG2 [6:0], each field = value − 1.
constexpr uint32_t nbtp(const CanBitTiming& t) {
  return ((t.sjw - 1u) << 25) | ((t.brp - 1u) << 16) | ((t.tseg1 - 1u) << 8) | (t.tseg2 - 1u);
}
/// FDCAN_DBTP: DBRP [20:16], DTSEG1 [12:8], DTSEG2 [7:4], DSJW [3:0], each value − 1; TDC [23] on request
/// (transmitter delay compensation, needed above about 1 Mbit/s).
constexpr uint32_t dbtp(const CanBitTiming& t, bool tdc) {
  return (tdc ? (1u << 23) : 0u) | ((t.brp - 1u) << 16) | ((t.tseg1 - 1u) << 8) | ((t.tseg2 - 1u) << 4) | (t.sjw - 1u);
}

/// CAN-FD data length codes: 0..8 bytes map 1:1, then 12, 16, 20, 24, 32, 48, 64 (DLC 9..15).
constexpr uint8_t canFdDlc(uint32_t bytes) {
  if (bytes <= 8u) return static_cast<uint8_t>(bytes);
  if (bytes <= 12u) return 9;
  if (bytes <= 16u) return 10;
  if (bytes <= 20u) return 11;
  if (bytes <= 24u) return 12;
  if (bytes <= 32u) return 13;
  if (bytes <= 48u) return 14;
  return 15;
}
constexpr uint32_t canFdBytes(uint8_t dlc) {
  constexpr uint8_t kLen[16] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64};
  return kLen[dlc & 0xFu];
}

}  // namespace phalanx::mcu::stm32g4
