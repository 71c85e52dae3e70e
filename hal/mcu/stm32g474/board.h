#pragma once
/// STM32G474 drivers behind the hal interfaces, register level (regs.h). Board: the project's G474 motor board —
/// 24 MHz crystal, up to eight PH/EN H-bridge drivers (PWM on TIM1/TIM8 channels, direction on PD0..PD7, one
/// drive-enable line), Hall, strain-gauge and current-sense amplifiers on ADC1..ADC5, up to six quadrature
/// encoders (TIM2..TIM5, TIM20, LPTIM1), a
/// normally-closed e-stop on PC13, the host on USART1 at 2 Mbaud (USB-serial bridge) and CAN-FD on FDCAN1.
/// Pin choices are in pin_plan.h and docs/firmware-mcu.md; they are this project's, not checked against a schematic.
#include <cstddef>
#include <cstdint>

#include "phalanx/hal/hal.h"
#include "phalanx/mcu/stm32g4_adc_dma.h"
#include "phalanx/mcu/stm32g4_timer.h"

namespace phalanx::mcu::g474 {

constexpr uint32_t kHseHz = 24000000u;     ///< board crystal
constexpr uint32_t kSysclkHz = 170000000u;  ///< AHB = APB1 = APB2 = timers = SYSCLK
constexpr uint32_t kPwmHz = 20000u;         ///< above hearing; DRV887x-class bridges switch it comfortably
constexpr uint32_t kUartBaud = 2000000u;    ///< 200 kB/s: a 1 kHz command + telemetry stream uses 66 %
constexpr uint32_t kIwdgTimeoutUs = 5000u;  ///< five missed ticks reset the MCU (outputs default off)

/// HSE 24 MHz → PLL (M 6, N 85, R 2) → 170 MHz SYSCLK in range 1 boost mode, 4 flash wait states, ART caches
/// on, AHB/APB prescalers 1. Follows RM0440 §6.1.5 (boost entry with the AHB prescaler at 2 for ≥ 1 µs).
void clockInit();

/// Power stage off now: both advanced timers' main output enable cleared (outputs to their idle low level) and
/// the drive-enable line low. Register writes only: safe from any fault handler.
void emergencyStop();

class BridgePwm final : public hal::PwmOutputs {
 public:
  static constexpr uint8_t kMaxChannels = 8;
  void init(uint8_t channels);
  uint8_t count() const override { return n_; }
  void setDuty(uint8_t channel, float duty) override;
  void disableAll() override;

 private:
  uint8_t n_ = 0;
  uint16_t arr_ = 0;
};

class AdcScan final : public hal::AdcInputs {
 public:
  /// Analog inputs of pin_plan.h (kAnalogInputs), split over ADC1..ADC5, up to 16 ranks each.
  static constexpr uint8_t kMaxChannels = 25;
  static constexpr size_t kAdcs = 5;
  static constexpr size_t kMaxRanks = 16;
  /// Scans the first `channels` analog inputs; an ADC with no input assigned stays off.
  void init(uint8_t channels);
  uint8_t count() const override { return n_; }
  /// Latest complete conversion of app channel ch (12-bit counts), from the half of the DMA double buffer the
  /// DMA is not writing.
  int32_t read(uint8_t channel) const override;

 private:
  uint8_t n_ = 0;
  uint8_t adc_index_[kMaxChannels] = {};
  uint8_t rank_[kMaxChannels] = {};
  size_t len_[kAdcs] = {};
  volatile uint16_t buf_[kAdcs][2 * kMaxRanks] = {};  ///< per ADC a DMA double buffer of two scans
};

class TimerEncoders final : public hal::Encoders {
 public:
  /// TIM2, TIM3, TIM4, TIM5, TIM20, LPTIM1 (pin_plan.h).
  static constexpr uint8_t kMaxChannels = 6;
  void init(uint8_t channels);
  uint8_t count() const override { return n_; }
  int32_t read(uint8_t channel) const override;

 private:
  uint8_t n_ = 0;
  mutable stm32g4::EncoderExtender ext_[kMaxChannels];
};

class BoardGpio final : public hal::Gpio {
 public:
  void init();
  bool estopPressed() const override;
  void setDriveEnable(bool enabled) override;
};

/// Host byte link on USART1: RX by circular DMA into a 256-byte buffer (no interrupt per byte), TX by one-shot
/// DMA from a double buffer that the tick fills and the DMA-complete interrupt swaps.
class UsartLink final : public hal::ByteLink {
 public:
  static constexpr size_t kRxDma = 256;
  static constexpr size_t kTx = 512;
  void init();
  size_t read(uint8_t* dst, size_t max_len) override;
  size_t write(const uint8_t* src, size_t len) override;
  size_t writeSpace() const override { return kTx - fill_; }
  /// Start sending what the tick queued (called after the tick and from the DMA-complete interrupt).
  void kick();
  void onTxDmaComplete();

 private:
  uint8_t rx_dma_[kRxDma] = {};
  stm32g4::DmaRxTracker rx_track_{kRxDma};
  uint8_t tx_[2][kTx] = {};
  uint8_t fill_buf_ = 0;
  size_t fill_ = 0;
  volatile bool busy_ = false;
};

/// CAN-FD on FDCAN1 (1 Mbit/s arbitration, 5 Mbit/s data, bit-rate switching), one protocol frame body per CAN
/// frame as docs/protocol.md reserves for the CAN transport. Not yet the host link of any image.
class FdcanPort {
 public:
  void init();
  /// Queue one frame (≤ 64 bytes); false if the TX FIFO is full.
  bool send(uint16_t id, const uint8_t* data, uint8_t len);
  /// Take one received frame; 0 if none, else its length (data must hold 64 bytes).
  uint8_t receive(uint16_t& id, uint8_t* data);
};

/// Monotonic microseconds from the DWT cycle counter, extended to 64 bits (update() at least every 25 s).
class CycleClock final : public hal::Clock {
 public:
  void init();
  void update();
  uint64_t nowUs() const override;
  static uint32_t cycles();

 private:
  uint32_t last_ = 0;
  uint64_t high_ = 0;
};

void iwdgStart(uint32_t timeout_us);
void iwdgRefresh();

}  // namespace phalanx::mcu::g474
