#include "board.h"

#include <initializer_list>

#include "phalanx/glove/board.h"
#include "phalanx/mcu/stm32g4_clock.h"
#include "phalanx/mcu/stm32g4_encoder.h"
#include "phalanx/mcu/stm32g4_fdcan.h"
#include "phalanx/mcu/stm32g4_iwdg.h"
#include "phalanx/mcu/stm32g4_uart.h"
#include "pin_plan.h"
#include "regs.h"

namespace phalanx::mcu::g474 {

using namespace stm32g4;

namespace {

// Compile-time register values: a wrong frequency plan fails the build, not the board.
constexpr PllConfig kPll = pllFor(kHseHz, kSysclkHz);
static_assert(kPll.ok, "no exact PLL setting for 170 MHz from the board crystal");
constexpr int kWaitStates = flashWaitStates(kSysclkHz, needsBoost(kSysclkHz));
static_assert(kWaitStates == 4, "170 MHz boost mode needs 4 flash wait states");
constexpr PwmTiming kPwm = centerAlignedPwm(kSysclkHz, kPwmHz);
static_assert(kPwm.ok && kPwm.psc == 0, "20 kHz center-aligned PWM at 170 MHz");
constexpr UartDivisor kUart = uartDivisor(kSysclkHz, kUartBaud);
static_assert(kUart.ok && kUart.error_ppm == 0, "2 Mbaud exactly");
constexpr CanBitTiming kCanNominal = canBitTiming(kSysclkHz, 1000000u, 800u, kNominalLimits);
constexpr CanBitTiming kCanData = canBitTiming(kSysclkHz, 5000000u, 750u, kDataLimits);
static_assert(kCanNominal.ok && kCanData.ok, "CAN-FD bit timing at 170 MHz");
constexpr float kMaxDuty = 0.98f;  // leaves the bootstrap capacitors of the high-side drivers time to recharge

static_assert(firstRepeatedPin(boardPins().pins, boardPins().n) == boardPins().n,
              "pin_plan.h: a pin is claimed twice");

enum class Mode : uint32_t { kInput = 0, kOutput = 1, kAlternate = 2, kAnalog = 3 };
void pin(char port, uint32_t n, Mode mode, uint32_t af = 0, bool pull_up = false) {
  const uint32_t base = gpio(port);
  reg(base + kGpioModer) = (reg(base + kGpioModer) & ~(3u << (2 * n))) | (static_cast<uint32_t>(mode) << (2 * n));
  reg(base + kGpioOspeedr) |= 3u << (2 * n);
  reg(base + kGpioPupdr) = (reg(base + kGpioPupdr) & ~(3u << (2 * n))) | ((pull_up ? 1u : 0u) << (2 * n));
  const uint32_t afr = base + kGpioAfrl + (n >= 8 ? 4u : 0u);
  const uint32_t shift = 4u * (n % 8u);
  reg(afr) = (reg(afr) & ~(0xFu << shift)) | (af << shift);
}
void pinWrite(char port, uint32_t n, bool high) { reg(gpio(port) + kGpioBsrr) = high ? (1u << n) : (1u << (n + 16)); }
/// A pin of pin_plan.h in its alternate function (or as a plain output / input with pull-up).
void pin(const Pin& p) {
  if (p.af == kGpioOut) pin(p.port, p.n, Mode::kOutput);
  else if (p.af == kGpioIn) pin(p.port, p.n, Mode::kInput, 0, true);
  else pin(p.port, p.n, Mode::kAlternate, p.af);
}

void spin(uint32_t n) {
  for (volatile uint32_t i = 0; i < n; i = i + 1u) {
  }
}
bool waitSet(uint32_t address, uint32_t mask, uint32_t limit = 1000000u) {
  for (uint32_t i = 0; i < limit; ++i) {
    if ((reg(address) & mask) == mask) return true;
  }
  return false;
}
bool waitClear(uint32_t address, uint32_t mask, uint32_t limit = 1000000u) {
  for (uint32_t i = 0; i < limit; ++i) {
    if ((reg(address) & mask) == 0) return true;
  }
  return false;
}

// PWM channel → timer and compare register. Channels 0..3 on TIM1 CH1..CH4, 4..7 on TIM8 CH1..CH4.
uint32_t pwmTimer(uint8_t ch) { return ch < 4 ? kTim1 : kTim8; }
uint32_t pwmCcr(uint8_t ch) { return pwmTimer(ch) + kTimCcr1 + 4u * (ch % 4u); }

// ADC channel plan (board): pin_plan.h kAnalogInputs, split over ADC1..ADC5 by splitAnalogInputs(); each ADC with
// inputs gets its DMA1 channel and DMAMUX request from kAdcUnits.
static_assert(AdcScan::kMaxChannels == kAnalogInputCount, "one analog input per ADC channel of the hal");
static_assert(AdcScan::kAdcs == kAdcCount && AdcScan::kMaxRanks == kMaxRanksPerAdc, "AdcScan buffers");
static_assert(splitAnalogInputs(kAnalogInputCount).ok, "every analog input fits a 16-rank sequence");
static_assert(checkBoardAnalogPlan().ok(),
              "pin_plan.h: an analog input is not an STM32G474 ADC input on that pin, repeats one, or takes a pin "
              "the board uses");
static_assert(kAdcUnits[0].base == kAdc1 && kAdcUnits[1].base == kAdc2 && kAdcUnits[2].base == kAdc3 &&
                  kAdcUnits[3].base == kAdc4 && kAdcUnits[4].base == kAdc5 &&
                  kAdcUnits[0].common == kAdc12Common && kAdcUnits[2].common == kAdc345Common,
              "pin_plan.h kAdcUnits and regs.h agree");
static_assert(kUsartRxDmaChannel == 3 && kUsartTxDmaChannel == 4 && kDmareqUsart1RxPlan == kDmareqUsart1Rx &&
                  kDmareqUsart1TxPlan == kDmareqUsart1Tx && kAdcUnits[0].dmamux_request == kDmareqAdc1 &&
                  kAdcUnits[1].dmamux_request == kDmareqAdc2 && kAdcUnits[2].dmamux_request == kDmareqAdc3 &&
                  kAdcUnits[3].dmamux_request == kDmareqAdc4 && kAdcUnits[4].dmamux_request == kDmareqAdc5,
              "pin_plan.h DMA plan and regs.h agree");
static_assert(dmaPlanDistinct(), "pin_plan.h: a DMA1 channel or DMAMUX request is used twice");

// Every sample averages glove::board::kAdcOversampling conversions (the sensors' noise budget in
// docs/glove-plant.md assumes it).
constexpr uint32_t kAdcCfgr2 = adcCfgr2Oversampling(static_cast<uint32_t>(glove::board::kAdcOversampling));
static_assert(kAdcCfgr2 != kAdcCfgr2Invalid, "glove/board.h kAdcOversampling: a power of two in 1..256");

void adcInit(uint32_t adc, const AdcSequence& seq, const uint8_t* plan, size_t n) {
  reg(adc + kAdcCr) &= ~kAdcCrDeeppwd;
  reg(adc + kAdcCr) |= kAdcCrAdvregen;
  spin(4000);  // T_ADCVREG_STUP = 20 µs
  reg(adc + kAdcCr) |= kAdcCrAdcal;  // single-ended calibration
  waitClear(adc + kAdcCr, kAdcCrAdcal);
  spin(100);
  for (size_t i = 0; i < 4; ++i) reg(adc + kAdcSqr1 + 4u * i) = seq.sqr[i];
  uint32_t smpr[2] = {0, 0};
  for (size_t i = 0; i < n; ++i) {
    const SmprField f = smprField(plan[i]);
    smpr[f.reg] |= 0x2u << f.shift;  // 12.5 ADC clocks: source impedance of the sensor amplifiers < 1 kΩ
  }
  reg(adc + kAdcSmpr1) = smpr[0];
  reg(adc + kAdcSmpr2) = smpr[1];
  reg(adc + kAdcCfgr2) = kAdcCfgr2;  // hardware oversampling (glove/board.h kAdcOversampling)
  reg(adc + kAdcCfgr) = kAdcCfgrDmaen | kAdcCfgrDmacfg | kAdcCfgrExtenRising | (kAdcExtselTim1Trgo << 5);
  reg(adc + kAdcIsr) = kAdcIsrAdrdy;
  reg(adc + kAdcCr) |= kAdcCrAden;
  waitSet(adc + kAdcIsr, kAdcIsrAdrdy);
}

void dmaCircular(uint32_t ch, uint32_t request, uint32_t periph, void* mem, uint32_t count, uint32_t size_bits) {
  reg(kDmamux + dmamuxCcr(ch)) = request;
  reg(kDma1 + dmaCcr(ch)) = 0;
  reg(kDma1 + dmaCpar(ch)) = periph;
  reg(kDma1 + dmaCmar(ch)) = static_cast<uint32_t>(reinterpret_cast<uintptr_t>(mem));
  reg(kDma1 + dmaCndtr(ch)) = count;
  reg(kDma1 + dmaCcr(ch)) = kDmaCcrCirc | kDmaCcrMinc | size_bits | kDmaCcrPlHigh | kDmaCcrEn;
}

constexpr uint32_t kTxDmaChannel = kUsartTxDmaChannel;
constexpr uint32_t kRxDmaChannel = kUsartRxDmaChannel;

}  // namespace

void clockInit() {
  reg(kRcc + kRccApb1enr1) |= kRccApb1Pwr;
  reg(kRcc + kRccAhb1enr) |= kRccAhb1Flash;
  // Range 1 boost mode before raising the frequency above 150 MHz.
  reg(kPwr + kPwrCr5) &= ~kPwrCr5R1mode;
  reg(kRcc + kRccCr) |= kRccCrHseon;
  if (!waitSet(kRcc + kRccCr, kRccCrHserdy)) return;  // stays on HSI16: the board still runs, slowly, and says so
  reg(kRcc + kRccPllcfgr) = pllcfgrHse(kPll);
  reg(kRcc + kRccCr) |= kRccCrPllon;
  waitSet(kRcc + kRccCr, kRccCrPllrdy);
  reg(kFlash + kFlashAcr) = static_cast<uint32_t>(kWaitStates) | kFlashAcrPrften | kFlashAcrIcen | kFlashAcrDcen;
  while ((reg(kFlash + kFlashAcr) & 0xFu) != static_cast<uint32_t>(kWaitStates)) {
  }
  reg(kRcc + kRccCfgr) = (reg(kRcc + kRccCfgr) & ~kRccCfgrHpreMask) | kRccCfgrHpreDiv2;
  reg(kRcc + kRccCfgr) = (reg(kRcc + kRccCfgr) & ~0x3u) | kRccCfgrSwPll;
  while ((reg(kRcc + kRccCfgr) & kRccCfgrSwsMask) != kRccCfgrSwsPll) {
  }
  spin(200);  // ≥ 1 µs at 85 MHz before the AHB prescaler returns to 1
  reg(kRcc + kRccCfgr) &= ~kRccCfgrHpreMask;
  // Peripheral clocks used by the drivers.
  reg(kRcc + kRccAhb1enr) |= kRccAhb1Dma1 | kRccAhb1Dmamux;
  reg(kRcc + kRccAhb2enr) |= kRccAhb2GpioAll | kRccAhb2Adc12 | kRccAhb2Adc345;
  reg(kRcc + kRccApb1enr1) |= kRccApb1Tim2 | kRccApb1Tim3 | kRccApb1Tim4 | kRccApb1Tim5 | kRccApb1Lptim1 |
                              kRccApb1Fdcan;  // LPTIM1 kernel clock: RCC_CCIPR.LPTIM1SEL reset value = PCLK1
  reg(kRcc + kRccApb2enr) |= kRccApb2Syscfg | kRccApb2Tim1 | kRccApb2Tim8 | kRccApb2Tim20 | kRccApb2Usart1;
  reg(kRcc + kRccCcipr) = (reg(kRcc + kRccCcipr) & ~(0x3u << 24)) | kRccCciprFdcanPclk;
}

void emergencyStop() {
  reg(kTim1 + kTimBdtr) &= ~kTimBdtrMoe;
  reg(kTim8 + kTimBdtr) &= ~kTimBdtrMoe;
  pinWrite(kDriveEnablePin.port, kDriveEnablePin.n, false);
}

// ---------------------------------------------------------------------------------------------------------------
void BridgePwm::init(uint8_t channels) {
  n_ = channels > kMaxChannels ? kMaxChannels : channels;
  arr_ = kPwm.arr;
  for (uint32_t tim : {kTim1, kTim8}) {
    reg(tim + kTimCr1) = 0;
    reg(tim + kTimPsc) = kPwm.psc;
    reg(tim + kTimArr) = kPwm.arr;
    // CH1..CH4 PWM mode 1 with preload: OCxM at [6:4]/[14:12], OCxPE at bit 3/11 of CCMR1 and CCMR2.
    const uint32_t ccmr = (kTimOcPwm1 << 4) | (1u << 3) | (kTimOcPwm1 << 12) | (1u << 11);
    reg(tim + kTimCcmr1) = ccmr;
    reg(tim + kTimCcmr2) = ccmr;
    for (uint32_t c = 0; c < 4; ++c) reg(tim + kTimCcr1 + 4u * c) = 0;
    reg(tim + kTimCcer) = (1u << 0) | (1u << 4) | (1u << 8) | (1u << 12);  // CC1E..CC4E (PH/EN bridges: no CHxN)
    // MOE stays 0 until a duty is set: OSSR/OSSI keep the outputs driven to their idle (low) level meanwhile.
    reg(tim + kTimBdtr) = kTimBdtrOssr | kTimBdtrOssi | deadTimeDtg(nsToTicks(200, kSysclkHz)).dtg;
    reg(tim + kTimRcr) = 1;  // update (and ADC trigger) once per PWM period, at the counter underflow
    reg(tim + kTimCr1) = kTimCr1Cms1 | kTimCr1Arpe;
    reg(tim + kTimEgr) = kTimEgrUg;
  }
  reg(kTim1 + kTimCr2) = kTimCr2MmsUpdate;  // TRGO → ADC12 regular trigger: sample mid-pulse, away from edges
  for (const Pin& p : kPwmPins) pin(p);
  for (const Pin& p : kDirectionPins) pin(p);
  reg(kTim8 + kTimCr1) |= kTimCr1Cen;
  reg(kTim1 + kTimCr1) |= kTimCr1Cen;
}

void BridgePwm::setDuty(uint8_t ch, float duty) {
  if (ch >= n_ || !(duty == duty)) return;
  pinWrite(kDirectionPort, kDirectionPins[ch].n, duty < 0.0f);  // PH: direction
  reg(pwmCcr(ch)) = dutyToCcr(duty, arr_, kMaxDuty);
  reg(pwmTimer(ch) + kTimBdtr) |= kTimBdtrMoe;
}

void BridgePwm::disableAll() {
  emergencyStop();
  for (uint8_t ch = 0; ch < kMaxChannels; ++ch) reg(pwmCcr(ch)) = 0;
}

// ---------------------------------------------------------------------------------------------------------------
void AdcScan::init(uint8_t channels) {
  n_ = channels > kMaxChannels ? kMaxChannels : channels;
  const AnalogSplit split = splitAnalogInputs(n_);
  if (!split.ok) {
    n_ = 0;
    return;
  }
  for (uint8_t i = 0; i < n_; ++i) {
    adc_index_[i] = split.adc_index[i];
    rank_[i] = split.rank[i];
    pin(kAnalogInputs[i].pin.port, kAnalogInputs[i].pin.n, Mode::kAnalog);
  }
  // CKMODE = HCLK/4 = 42.5 MHz (≤ 60 MHz), synchronous to the AHB clock: RCC_CCIPR.ADC12SEL/ADC345SEL are not used.
  reg(kAdc12Common + kAdcCommonCcr) = 0x3u << 16;
  reg(kAdc345Common + kAdcCommonCcr) = 0x3u << 16;
  for (size_t a = 0; a < kAdcs; ++a) {
    len_[a] = split.len[a];
    if (len_[a] == 0) continue;
    const AdcUnit& u = kAdcUnits[a];
    adcInit(u.base, adcSequence(split.seq[a], len_[a]), split.seq[a], len_[a]);
    dmaCircular(u.dma1_channel, u.dmamux_request, u.base + kAdcDr, const_cast<uint16_t*>(buf_[a]),
                static_cast<uint32_t>(2 * len_[a]), kDmaCcrPsize16 | kDmaCcrMsize16);
    reg(u.base + kAdcCr) |= kAdcCrAdstart;  // armed: converts on every TIM1 TRGO
  }
}

int32_t AdcScan::read(uint8_t ch) const {
  if (ch >= n_) return 0;
  const size_t a = adc_index_[ch];
  const size_t w = dmaWriteIndex(2 * len_[a], reg(kDma1 + dmaCndtr(kAdcUnits[a].dma1_channel)));
  return buf_[a][stableScanOffset(len_[a], w) + rank_[ch]];
}

// ---------------------------------------------------------------------------------------------------------------
namespace {
// Encoder channel i → counting unit (pins: pin_plan.h kEncoderPins[i]). TIM1/TIM8 are the PWM timers; TIM2–TIM5
// and TIM20 count in encoder mode 3, LPTIM1 in its encoder mode (TIM15/16/17 have no encoder interface).
struct EncoderUnit {
  uint32_t base;
  bool lptim;
};
constexpr EncoderUnit kEncoderUnits[TimerEncoders::kMaxChannels] = {
    {kTim2, false}, {kTim3, false}, {kTim4, false}, {kTim5, false}, {kTim20, false}, {kLptim1, true}};
static_assert(TimerEncoders::kMaxChannels == kMaxEncoders, "one pin pair per encoder unit");
constexpr TimEncoderCcmr1 kEncCcmr1 = timEncoderCcmr1(kEncoderFilterSamples);
constexpr LptimEncoderCfgr kEncLptimCfgr = lptimEncoderCfgr(kEncoderFilterSamples);
static_assert(kEncCcmr1.ok && kEncLptimCfgr.ok, "encoder input filter");
}  // namespace

void TimerEncoders::init(uint8_t channels) {
  n_ = channels > kMaxChannels ? kMaxChannels : channels;
  for (uint8_t i = 0; i < n_; ++i) {
    const uint32_t base = kEncoderUnits[i].base;
    if (kEncoderUnits[i].lptim) {
      reg(base + kLptimCr) = 0;
      reg(base + kLptimCfgr) = kEncLptimCfgr.value;  // CFGR is written with the timer disabled
      reg(base + kLptimCr) = kLptimCrEnable;
      reg(base + kLptimArr) = 0xFFFFu;                  // ARR is written with the timer enabled; full 16 bits
      waitSet(base + kLptimIsr, kLptimIsrArrok, 10000u);
      reg(base + kLptimCr) = kLptimCrEnable | kLptimCrCntstrt;  // continuous mode, counts from the inputs
    } else {
      reg(base + kTimCr1) = 0;
      reg(base + kTimCcmr1) = kEncCcmr1.value;
      reg(base + kTimSmcr) = kTimSmcrEncoderX4;
      reg(base + kTimArr) = 0xFFFFu;  // 16 bits on every timer (TIM2/TIM5 are 32-bit); EncoderExtender extends
      reg(base + kTimCr1) = kTimCr1Cen;
    }
    pin(kEncoderPins[i][0]);
    pin(kEncoderPins[i][1]);
  }
}

int32_t TimerEncoders::read(uint8_t ch) const {
  if (ch >= n_) return 0;
  const uint32_t base = kEncoderUnits[ch].base;
  if (kEncoderUnits[ch].lptim) {
    // Unconfirmed (the count changed on every read): keep the previous value this tick; the next tick catches up.
    const ConfirmedRead r = confirmedRead([base] { return reg(base + kLptimCnt); });
    return r.ok ? ext_[ch].update(r.value) : ext_[ch].count();
  }
  return ext_[ch].update(static_cast<uint16_t>(reg(base + kTimCnt)));
}

// ---------------------------------------------------------------------------------------------------------------
void BoardGpio::init() {
  pin(kDriveEnablePin);
  pinWrite(kDriveEnablePin.port, kDriveEnablePin.n, false);
  // E-stop: normally-closed contact to ground with a pull-up, so a pressed button and a broken wire both read
  // high (pressed). EXTI13 on the rising edge stops the power stage at once; the core latches the fault on its
  // next tick.
  pin(kEstopPin);
  const uint32_t exticr = kSyscfg + syscfgExticr(13);
  reg(exticr) = (reg(exticr) & ~(0xFu << 4)) | (0x2u << 4);  // EXTI13 ← port C
  reg(kExti + kExtiRtsr1) |= 1u << 13;
  reg(kExti + kExtiImr1) |= 1u << 13;
}

bool BoardGpio::estopPressed() const { return (reg(gpio(kEstopPin.port) + kGpioIdr) & (1u << kEstopPin.n)) != 0; }
void BoardGpio::setDriveEnable(bool enabled) {
  pinWrite(kDriveEnablePin.port, kDriveEnablePin.n, enabled && !estopPressed());
}

// ---------------------------------------------------------------------------------------------------------------
void UsartLink::init() {
  pin(kUsartPins[0]);
  pin(kUsartPins[1].port, kUsartPins[1].n, Mode::kAlternate, kUsartPins[1].af, true);  // RX idles high
  reg(kUsart1 + kUsartCr1) = 0;
  reg(kUsart1 + kUsartBrr) = kUart.brr;
  reg(kUsart1 + kUsartCr3) = kUsartCr3Dmar | kUsartCr3Dmat;
  dmaCircular(kRxDmaChannel, kDmareqUsart1Rx, kUsart1 + kUsartRdr, rx_dma_, kRxDma, 0);
  reg(kDmamux + dmamuxCcr(kTxDmaChannel)) = kDmareqUsart1Tx;
  reg(kUsart1 + kUsartCr1) = kUsartCr1Ue | kUsartCr1Re | kUsartCr1Te | (kUart.over8 ? kUsartCr1Over8 : 0u);
}

size_t UsartLink::read(uint8_t* dst, size_t max_len) {
  // New bytes since the last call, straight out of the DMA's circular buffer. At 2 Mbaud the 256-byte buffer
  // wraps in 1.28 ms: the 1 kHz tick reads it every 1 ms.
  const DmaRxTracker::Spans s = rx_track_.poll(reg(kDma1 + dmaCndtr(kRxDmaChannel)));
  size_t n = 0;
  for (size_t i = 0; i < s.first_len && n < max_len; ++i) dst[n++] = rx_dma_[s.first_begin + i];
  for (size_t i = 0; i < s.second_len && n < max_len; ++i) dst[n++] = rx_dma_[i];
  return n;  // bytes beyond max_len are dropped (the core asks for at most its per-tick budget)
}

size_t UsartLink::write(const uint8_t* src, size_t len) {
  if (len > writeSpace()) return 0;
  for (size_t i = 0; i < len; ++i) tx_[fill_buf_][fill_ + i] = src[i];
  fill_ += len;
  return len;
}

void UsartLink::kick() {
  if (busy_ || fill_ == 0) return;
  const uint32_t ch = kTxDmaChannel;
  reg(kDma1 + dmaCcr(ch)) = 0;
  reg(kDma1 + dmaCpar(ch)) = kUsart1 + kUsartTdr;
  reg(kDma1 + dmaCmar(ch)) = static_cast<uint32_t>(reinterpret_cast<uintptr_t>(tx_[fill_buf_]));
  reg(kDma1 + dmaCndtr(ch)) = static_cast<uint32_t>(fill_);
  busy_ = true;
  fill_buf_ ^= 1u;
  fill_ = 0;
  reg(kDma1 + dmaCcr(ch)) = kDmaCcrDir | kDmaCcrMinc | kDmaCcrTcie | kDmaCcrEn;
}

void UsartLink::onTxDmaComplete() {
  reg(kDma1 + kDmaIfcr) = 0xFu << (4u * (kTxDmaChannel - 1u));
  busy_ = false;
  kick();
}

// ---------------------------------------------------------------------------------------------------------------
void FdcanPort::init() {
  pin(kFdcanPins[0]);
  pin(kFdcanPins[1]);
  reg(kFdcan1 + kCanCccr) |= kCanCccrInit;
  waitSet(kFdcan1 + kCanCccr, kCanCccrInit);
  reg(kFdcan1 + kCanCccr) |= kCanCccrCce;
  reg(kFdcan1 + kCanNbtp) = nbtp(kCanNominal);
  reg(kFdcan1 + kCanDbtp) = dbtp(kCanData, true);
  reg(kFdcan1 + kCanTdcr) = (kCanData.tseg1 + 1u) << 8;  // TDCO: secondary sample point at the data sample point
  reg(kFdcan1 + kCanRxgfc) = 0;                          // non-matching standard frames → RX FIFO 0
  reg(kFdcan1 + kCanCccr) |= kCanCccrFdoe | kCanCccrBrse;
  reg(kFdcan1 + kCanCccr) &= ~kCanCccrInit;
}

bool FdcanPort::send(uint16_t id, const uint8_t* data, uint8_t len) {
  const uint32_t fqs = reg(kFdcan1 + kCanTxfqs);
  if ((fqs & kCanTxfqsTfqf) != 0 || len > 64) return false;
  const uint32_t put = (fqs >> 16) & 0x3u;
  const uint32_t el = kFdcanRam + kCanRamTxBuffers + put * kCanRamElementBytes;
  const uint8_t dlc = canFdDlc(len);
  reg(el) = static_cast<uint32_t>(id & 0x7FFu) << 18;
  reg(el + 4) = (static_cast<uint32_t>(dlc) << 16) | (1u << 20) | (1u << 21);  // BRS, FDF
  const uint32_t padded = canFdBytes(dlc);
  for (uint32_t w = 0; w < padded / 4u; ++w) {
    uint32_t word = 0;
    for (uint32_t b = 0; b < 4; ++b) {
      const uint32_t i = 4u * w + b;
      word |= static_cast<uint32_t>(i < len ? data[i] : 0u) << (8u * b);
    }
    reg(el + 8u + 4u * w) = word;
  }
  reg(kFdcan1 + kCanTxbar) = 1u << put;
  return true;
}

uint8_t FdcanPort::receive(uint16_t& id, uint8_t* data) {
  const uint32_t s = reg(kFdcan1 + kCanRxf0s);
  if ((s & 0xFu) == 0) return 0;
  const uint32_t get = (s >> 8) & 0x3u;
  const uint32_t el = kFdcanRam + kCanRamRxFifo0 + get * kCanRamElementBytes;
  id = static_cast<uint16_t>((reg(el) >> 18) & 0x7FFu);
  const uint32_t len = canFdBytes(static_cast<uint8_t>((reg(el + 4) >> 16) & 0xFu));
  for (uint32_t i = 0; i < len; ++i) data[i] = static_cast<uint8_t>(reg(el + 8u + (i & ~3u)) >> (8u * (i & 3u)));
  reg(kFdcan1 + kCanRxf0a) = get;
  return static_cast<uint8_t>(len);
}

// ---------------------------------------------------------------------------------------------------------------
void CycleClock::init() {
  reg(kDemcr) |= kDemcrTrcena;
  reg(kDwtCyccnt) = 0;
  reg(kDwtCtrl) |= 1u;
  last_ = 0;
  high_ = 0;
}
uint32_t CycleClock::cycles() { return reg(kDwtCyccnt); }
void CycleClock::update() {
  const uint32_t now = cycles();
  if (now < last_) high_ += 1ull << 32;
  last_ = now;
}
uint64_t CycleClock::nowUs() const {
  const uint32_t now = cycles();
  const uint64_t high = now < last_ ? high_ + (1ull << 32) : high_;
  return (high | now) / (kSysclkHz / 1000000u);
}

void iwdgStart(uint32_t timeout_us) {
  constexpr IwdgConfig kDefault = iwdgFor(kIwdgTimeoutUs);
  static_assert(kDefault.ok, "IWDG timeout");
  const IwdgConfig c = iwdgFor(timeout_us).ok ? iwdgFor(timeout_us) : kDefault;
  reg(kIwdg + kIwdgKr) = kIwdgStart;
  reg(kIwdg + kIwdgKr) = kIwdgUnlock;
  reg(kIwdg + kIwdgPr) = c.pr;
  reg(kIwdg + kIwdgRlr) = c.rlr;
  waitClear(kIwdg + kIwdgSr, 0x7u);
  reg(kIwdg + kIwdgKr) = kIwdgRefresh;
}
void iwdgRefresh() { reg(kIwdg + kIwdgKr) = kIwdgRefresh; }

}  // namespace phalanx::mcu::g474
