// Phalanx firmware on the STM32G474 board: clocks to 170 MHz, the drivers of board.h behind the hal interfaces,
// the firmware core and the device app, ticking at 1 kHz from SysTick; the independent watchdog is refreshed by
// the tick, so a stuck tick resets the MCU with every output at its reset (off) state.
//
// Device settings (docs/params.md) are kept in the last two pages of bank 2 (flash_pages.h): a `param save` erases
// and programs one of them one step per tick (fw::SettingsStore::stepSave), the erase running in the background
// while the tick executes from bank 1, so the watchdog is refreshed every tick throughout.
//
// The tick's duration is measured in CPU cycles with the DWT cycle counter and exposed through the board
// diagnostic parameters (0x0080.., phalanx/fw_mcu/board_diag.h), like the emulated board's instruction counts.
#include <cstdint>

#include "board.h"
#include "flash_pages.h"
#include "phalanx/fw/core.h"
#include "phalanx/fw/settings_store.h"
#include "phalanx/fw_mcu/app_registry.h"
#include "phalanx/fw_mcu/board_diag.h"
#include "phalanx/mcu/cortex_m.h"
#include "phalanx/mcu/stm32g4_clock.h"
#include "phalanx/mcu/tick_stats.h"
#include "pin_plan.h"
#include "regs.h"

#ifndef PHALANX_BUILD_ID
#define PHALANX_BUILD_ID 0u
#endif

namespace {

using namespace phalanx;
using namespace phalanx::mcu;
using namespace phalanx::mcu::g474;

constexpr uint32_t kTickHz = 1000;
constexpr uint32_t kReload = stm32g4::systickReload(kSysclkHz, kTickHz);
static_assert(kReload == 169999u, "1 kHz SysTick at 170 MHz");
constexpr uint32_t kCyclesPerTick = kSysclkHz / kTickHz;
// The image's pins (its PWM + direction lines, encoders and analog inputs, plus the fixed ones) are distinct, and
// each of its analog channels is an STM32G474 ADC input on the pin the plan says, on no pin the image uses otherwise.
static_assert(imagePinsDistinct(fw_mcu::kAppPwmCount, fw_mcu::kAppEncoderCount, fw_mcu::kAppAdcCount),
              "pin_plan.h: this app's channels claim a pin twice");
static_assert(checkImageAnalogPlan(fw_mcu::kAppPwmCount, fw_mcu::kAppEncoderCount, fw_mcu::kAppAdcCount).ok(),
              "pin_plan.h: this app's analog channels are not valid STM32G474 ADC inputs on free pins");
static_assert(fw_mcu::kAppPwmCount <= BridgePwm::kMaxChannels && fw_mcu::kAppAdcCount <= AdcScan::kMaxChannels &&
                  fw_mcu::kAppEncoderCount <= TimerEncoders::kMaxChannels,
              "the board has fewer PWM, ADC or encoder channels than this app needs");
constexpr uint8_t kPrioEstop = 0x00;  // highest: the e-stop edge cuts the bridges even during a tick
constexpr uint8_t kPrioTick = 0x80;   // SysTick and the USART TX DMA share a level: never preempt each other

using Stats = TickStats<2048, 32>;  // 32-cycle bins up to 65536 cycles (0.39 ms)

class Diagnostics final : public fw_mcu::DiagSource {
 public:
  bool diagGet(uint16_t id, float& v) const override {
    namespace p = fw_mcu::diag_param;
    switch (id) {
      case p::kTickCount: v = static_cast<float>(tick.count()); return true;
      case p::kTickWorst: v = static_cast<float>(tick.worst()); return true;
      case p::kTickMedian: v = static_cast<float>(tick.median()); return true;
      case p::kTickP99: v = static_cast<float>(tick.quantile(0.99f)); return true;
      case p::kTickWorstTimer: v = static_cast<float>(tick.worst()); return true;
      case p::kTickUnitNs: v = 1e9f / static_cast<float>(kSysclkHz); return true;
      case p::kOverruns: v = static_cast<float>(overruns); return true;
      case p::kLinkKind: v = 0.0f; return true;
      case p::kResetStats: v = 0.0f; return true;
      default: return false;
    }
  }
  bool diagSet(uint16_t id, float) override {
    if (id != fw_mcu::diag_param::kResetStats) return false;
    reset_requested = true;
    return true;
  }
  Stats tick;
  uint32_t overruns = 0;
  bool reset_requested = false;
};

CycleClock g_clock;
BridgePwm g_pwm;
AdcScan g_adc;
TimerEncoders g_enc;
BoardGpio g_gpio;
UsartLink g_link;
FdcanPort g_can;
hal::Board g_board;
fw_mcu::StaticObject<Diagnostics> g_diag;
fw_mcu::StaticObject<fw_mcu::AppType> g_app;
fw_mcu::StaticObject<fw_mcu::DiagApp> g_diag_app;
MmioFlashBus g_flash_bus;
fw_mcu::StaticObject<g474::FlashPages> g_settings_flash;
fw_mcu::StaticObject<fw::SettingsStore> g_settings;
fw_mcu::StaticObject<fw::FirmwareCore> g_core;
volatile bool g_running = false;
volatile const char* g_fatal_reason = nullptr;  // inspect with a debugger after a fault

}  // namespace

extern "C" void SysTick_Handler() {
  if (!g_running) return;
  Diagnostics& diag = g_diag.get();
  if (diag.reset_requested) {
    diag.tick.reset();
    diag.overruns = 0;
    diag.reset_requested = false;
  }
  g_clock.update();
  const uint32_t c0 = CycleClock::cycles();
  g_core.get().tick();
  const uint32_t cycles = CycleClock::cycles() - c0;
  diag.tick.add(cycles);
  if (cycles >= kCyclesPerTick) ++diag.overruns;
  g_link.kick();
  // CAN-FD frames are drained (not yet a protocol transport: docs/protocol.md reserves the mapping).
  uint8_t frame[64];
  uint16_t id = 0;
  for (int i = 0; i < 3 && g_can.receive(id, frame) != 0; ++i) {
  }
  iwdgRefresh();
}

extern "C" void EstopExti_Handler() {
  reg(kExti + kExtiPr1) = 1u << 13;
  emergencyStop();
}

extern "C" void UsartTxDma_Handler() { g_link.onTxDmaComplete(); }

/// Faults: power stage off first, then wait for the watchdog to reset the MCU (outputs stay off through reset).
extern "C" [[noreturn]] void phalanx_fatal(const char* why) {
  cm4::disableInterrupts();
  emergencyStop();
  g_fatal_reason = why;
  for (;;) {
  }
}

extern "C" [[noreturn]] void phalanx_board_main() {
  clockInit();
  g_clock.init();
  g_gpio.init();
  g_pwm.init(fw_mcu::kAppPwmCount);
  g_adc.init(fw_mcu::kAppAdcCount);
  g_enc.init(fw_mcu::kAppEncoderCount);
  g_link.init();
  g_can.init();
  g_board.clock = &g_clock;
  g_board.pwm = &g_pwm;
  g_board.adc = &g_adc;
  g_board.encoders = &g_enc;
  g_board.gpio = &g_gpio;
  g_board.link = &g_link;

  fw_mcu::AppType& app = fw_mcu::constructApp(g_app);
  fw_mcu::DiagApp& diag_app = g_diag_app.emplace(app, g_diag.emplace());
  fw::CoreConfig cfg;
  cfg.tick_rate_hz = kTickHz;
  cfg.firmware_build_id = PHALANX_BUILD_ID;
  // The core loads the settings at construction (memory-mapped reads, before the watchdog starts).
  cfg.settings = &g_settings.emplace(g_settings_flash.emplace(g_flash_bus, kSettingsFirstPage, kSettingsPages));
  g_core.emplace(g_board, diag_app, cfg);

  cm4::setIrqPriority(kIrqExti15_10, kPrioEstop);
  cm4::setIrqPriority(kIrqDma1Ch4, kPrioTick);
  cm4::setSysTickPriority(kPrioTick);
  cm4::enableIrq(kIrqExti15_10);
  cm4::enableIrq(kIrqDma1Ch4);
  iwdgStart(kIwdgTimeoutUs);
  g_running = true;
  cm4::startSysTick(kReload);
  for (;;) cm4::waitForInterrupt();
}
